/* core/config/config_read.c: libconfig text -> wt_config, driven by one schema table.
 *
 * Implements the system description of SPEC §1 (every key of the presets) and the canonical text
 * that the MVM builder hashes (SPEC §9). One table (config_schema.c) lists every key with its type,
 * range, unit, description and destination; reading, override, validation, the canonical text and the
 * printed reference all walk that table, so a key cannot be documented one way and read another.
 * Order of work: syntax -> unknown keys -> --set overrides -> typed keys in schema order (this file) ->
 * cross-key consistency (config_check.c) -> canonical text (config_canonical.c).
 */
#include "config_private.h"

#include "../base/names.h"
#include "../base/sha256.h"

#include <ctype.h>
#include <errno.h>
#include <libconfig.h>
#include <limits.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

/* ---------------------------------------------------------------- text helpers */

/* "a number", "an integer", "an odd integer", "a power of two" */
static const char *noun(const wt_config_priv_key_spec *ks)
{
    return ks->flags & F_POW2 ? "a power of two"
           : ks->flags & F_ODD ? "an odd integer"
           : ks->flags & F_EVEN ? "an even integer"
           : wt_config_priv_is_int(ks->type) ? "an integer"
                                             : "a number";
}

/* What a (scalar or element) value must be: "a number > 0 [m]", "one of \"paper\", \"exact\"". */
static void expected_text(const wt_config_priv_key_spec *ks, char *buf, size_t n)
{
    char r[96];
    if (ks->type == K_BOOL) {
        snprintf(buf, n, "a boolean (true or false)");
        return;
    }
    if (ks->type == K_STR) {
        snprintf(buf, n, ks->flags & F_HEX ? "a string of 64 hexadecimal digits (a SHA-256), or \"auto\""
                                           : "a string (a file path)");
        return;
    }
    if (ks->type == K_ENUM) {
        size_t len = (size_t)snprintf(buf, n, "one of");
        const char *c = ks->choices;
        while (*c && len < n) {
            size_t w = strcspn(c, "|");
            len += (size_t)snprintf(buf + len, n - len, "%s \"%.*s\"", c == ks->choices ? "" : ",", (int)w, c);
            c += w + (c[w] == '|');
        }
        return;
    }
    wt_config_priv_range(ks, r, sizeof r);
    snprintf(buf, n, "%s%s%s%s%s%s", noun(ks), strcmp(r, "any") ? " " : "",
             strcmp(r, "any") ? r : "", *ks->unit ? " [" : "", ks->unit, *ks->unit ? "]" : "");
}


static int is_int_setting(const config_setting_t *s)
{
    return config_setting_type(s) == CONFIG_TYPE_INT || config_setting_type(s) == CONFIG_TYPE_INT64;
}

/* "an integer 3", "a string \"abc\"", "a group", ... */
static void describe(const config_setting_t *s, char *buf, size_t n)
{
    char v[40];
    switch (config_setting_type(s)) {
    case CONFIG_TYPE_INT:
    case CONFIG_TYPE_INT64: snprintf(buf, n, "an integer %lld", config_setting_get_int64(s)); break;
    case CONFIG_TYPE_FLOAT:
        snprintf(buf, n, "a number %s", wt_config_priv_fmt_num(wt_config_priv_num(s), v, sizeof v));
        break;
    case CONFIG_TYPE_STRING: snprintf(buf, n, "a string \"%s\"", config_setting_get_string(s)); break;
    case CONFIG_TYPE_BOOL: snprintf(buf, n, "a boolean %s", config_setting_get_bool(s) ? "true" : "false"); break;
    case CONFIG_TYPE_GROUP: snprintf(buf, n, "a group { ... }"); break;
    default: snprintf(buf, n, "a list of %d elements", config_setting_length(s)); break;
    }
}

/* libconfig's message, plus what to do about its least obvious one */
static const char *syntax_hint(const char *e)
{
    if (e && strstr(e, "duplicate setting"))
        return " (a group or key defined twice, e.g. a group that an @included file already defines: libconfig "
               "refuses the second. To change an included file's values, list them after the @include as "
               "overrides = [ \"group.key = value\", ... ]; they apply after the file's settings and before "
               "--set: see data/presets/eelt-mcao-nea20.cfg and docs/guide.md)";
    return e && strstr(e, "mismatched element type")
               ? " (the elements of [ ... ] share one type: write 1.0, not 1, among numbers, or use ( ... ))"
               : "";
}

/* ---------------------------------------------------------------- names and suggestions */

/* A group path is a proper prefix of some key up to a dot. */
static int is_group_path(const char *path)
{
    size_t n = strlen(path);
    for (int k = 0; k < WT_CONFIG_PRIV_NKEYS; k++)
        if (!strncmp(wt_config_priv_keys[k].path, path, n) && wt_config_priv_keys[k].path[n] == '.') return 1;
    return 0;
}

/* " (did you mean 'x'?)" or "": the nearest key or group by edit distance; else a key that only adds
 * the unit suffix (loop.rate -> loop.rate_hz); else a key of the same name in another group. */
static void suggest(const char *path, char *buf, size_t n)
{
    size_t np = strlen(path);
    const char *best = NULL, *leaf = strrchr(path, '.');
    size_t bestlen = 0;
    int bestd = INT_MAX;
    leaf = leaf ? leaf + 1 : path;
    for (int k = 0; k < WT_CONFIG_PRIV_NKEYS; k++) {
        const char *p = wt_config_priv_keys[k].path;
        for (size_t len = 0;; len++) { /* the key itself and each of its group prefixes */
            if (p[len] == '.' || p[len] == '\0') {
                int d = wt_edit_distance(path, np, p, len);
                if (d < bestd) bestd = d, best = p, bestlen = len;
            }
            if (p[len] == '\0') break;
        }
    }
    if (bestd > 2) {
        int alt = 0;
        for (int k = 0; k < WT_CONFIG_PRIV_NKEYS && !alt; k++)
            if (!strncmp(wt_config_priv_keys[k].path, path, np) && wt_config_priv_keys[k].path[np] == '_')
                alt = 1, best = wt_config_priv_keys[k].path, bestlen = strlen(best);
        if (!alt && (size_t)bestd > np / 4) {
            best = NULL;
            for (int k = 0; k < WT_CONFIG_PRIV_NKEYS && !best; k++) {
                const char *l = strrchr(wt_config_priv_keys[k].path, '.');
                if (l && !strcmp(l + 1, leaf)) best = wt_config_priv_keys[k].path, bestlen = strlen(best);
            }
        }
    }
    if (best) snprintf(buf, n, " (did you mean '%.*s'?)", (int)bestlen, best);
    else snprintf(buf, n, "; `wavetomo info --keys` lists the accepted keys");
}

/* ---------------------------------------------------------------- parse state and messages */

typedef wt_config_priv_state pstate;

#define FAIL(ps, k, s, ...) wt_config_priv_fail((ps), wt_config_priv_where((ps), (k), (s), loc, sizeof loc), __VA_ARGS__)

/* ---------------------------------------------------------------- unknown keys */

static int check_unknown(pstate *ps, const config_setting_t *g, const char *prefix)
{
    char loc[512], path[256], sg[160], got[160];
    for (int i = 0; i < config_setting_length(g); i++) {
        const config_setting_t *m = config_setting_get_elem(g, (unsigned)i);
        snprintf(path, sizeof path, "%s%s%s", prefix, *prefix ? "." : "", config_setting_name(m));
        if (wt_config_priv_find_key(path) >= 0) continue;
        if (is_group_path(path)) {
            if (!config_setting_is_group(m)) {
                describe(m, got, sizeof got);
                return FAIL(ps, -1, m, "'%s' is a group of settings; expected %s = { ... }, got %s", path, path, got);
            }
            int st = check_unknown(ps, m, path);
            if (st < 0) return st;
            continue;
        }
        suggest(path, sg, sizeof sg);
        return FAIL(ps, -1, m, "unknown %s '%s'%s", config_setting_is_group(m) ? "group" : "key", path, sg);
    }
    return WT_OK;
}

/* ---------------------------------------------------------------- overrides */

static config_setting_t *copy_setting(config_setting_t *parent, const char *name, const config_setting_t *src)
{
    int t = config_setting_type(src);
    config_setting_t *d = config_setting_add(parent, config_setting_is_group(parent) ? name : NULL, t);
    if (!d) return NULL;
    switch (t) {
    case CONFIG_TYPE_INT: config_setting_set_int(d, config_setting_get_int(src)); break;
    case CONFIG_TYPE_INT64: config_setting_set_int64(d, config_setting_get_int64(src)); break;
    case CONFIG_TYPE_FLOAT: config_setting_set_float(d, config_setting_get_float(src)); break;
    case CONFIG_TYPE_BOOL: config_setting_set_bool(d, config_setting_get_bool(src)); break;
    case CONFIG_TYPE_STRING: config_setting_set_string(d, config_setting_get_string(src)); break;
    default:
        for (int i = 0; i < config_setting_length(src); i++) {
            const config_setting_t *e = config_setting_get_elem(src, (unsigned)i);
            if (!copy_setting(d, config_setting_name(e), e)) return NULL;
        }
    }
    return d;
}

static int apply_override(pstate *ps, int i)
{
    char loc[512], key[128], sg[160];
    const char *o = ps->ov[i], *eq = o ? strchr(o, '=') : NULL;
    if (i < ps->nfile_ov) snprintf(loc, sizeof loc, "%s: overrides \"%s\"", ps->name, o ? o : "(null)");
    else snprintf(loc, sizeof loc, "--set %s", o ? o : "(null)");
    if (!eq) return wt_config_priv_fail(ps, loc, "expected key=value, e.g. --set atmosphere.r0_m=0.15");
    while (*o == ' ' || *o == '\t') o++;
    size_t kl = (size_t)(eq - o);
    while (kl > 0 && (o[kl - 1] == ' ' || o[kl - 1] == '\t')) kl--;
    if (kl >= sizeof key) kl = sizeof key - 1;
    memcpy(key, o, kl);
    key[kl] = '\0';
    int k = wt_config_priv_find_key(key);
    if (k < 0 && is_group_path(key))
        return wt_config_priv_fail(ps, loc, "'%s' is a group; set its keys one at a time (e.g. %s.<key>=<value>)", key, key);
    if (k < 0) {
        suggest(key, sg, sizeof sg);
        return wt_config_priv_fail(ps, loc, "unknown key '%s'%s", key, sg);
    }

    const char *v = eq + 1;
    while (*v == ' ' || *v == '\t') v++;
    size_t vl = strlen(v);
    while (vl > 0 && (v[vl - 1] == ' ' || v[vl - 1] == '\t' || v[vl - 1] == ';')) vl--;
    size_t cap = vl + 16;
    char *text = wt_malloc(ps->ctx, cap, 1);
    if (!text) return WT_ERROR(ps->ctx, WT_ERR_NOMEM, "out of memory parsing --set %s", ps->ov[i]);
    config_t tmp;
    int st = WT_OK, ok = 0;
    /* a bare word is retried as a string for string keys (recon.prior=exact) */
    const int words = wt_config_priv_keys[k].type == K_ENUM || wt_config_priv_keys[k].type == K_STR || (wt_config_priv_keys[k].flags & F_AUTO);
    for (int quoted = 0; !ok && quoted < 1 + (words && !memchr(v, '"', vl)); quoted++) {
        wt_config_priv_text vt;
        if (quoted) config_destroy(&tmp);
        snprintf(text, cap, quoted ? "v = \"%.*s\";" : "v = %.*s;", (int)vl, v);
        config_init(&tmp);
        /* the value's integers read exactly, as in the file (config_text.c) */
        if ((st = wt_config_priv_text_make(ps->ctx, text, loc, NULL, &vt)) < 0) break;
        ok = config_read_string(&tmp, vt.text);
        wt_config_priv_text_free(&vt);
    }
    wt_free(ps->ctx, text);
    if (st < 0) {
        config_destroy(&tmp);
        return st;
    }
    const char *leaf, *e = config_error_text(&tmp);
    config_setting_t *parent = NULL;
    if (!ok)
        st = wt_config_priv_fail(ps, loc, "cannot read the value: %s%s (numbers 0.5, lists [1.0, 2.0], strings \"text\", "
                     "booleans true/false)", e ? e : "?", syntax_hint(e));
    else if (config_setting_length(config_root_setting(&tmp)) != 1)
        st = wt_config_priv_fail(ps, loc, "expected one value after '='");
    else if (!(parent = wt_config_priv_ensure_parent(ps->cf, key, &leaf)))
        st = wt_config_priv_fail(ps, loc, "'%s' is not inside a group in the file", key);
    else {
        if (config_setting_get_member(parent, leaf)) config_setting_remove(parent, leaf);
        if (!copy_setting(parent, leaf, config_lookup(&tmp, "v")))
            st = WT_ERROR(ps->ctx, WT_ERR_NOMEM, "%s: libconfig could not add the setting", loc);
    }
    config_destroy(&tmp);
    ps->ovidx[k] = i;
    return st;
}

/* ---------------------------------------------------------------- typed keys */

static int in_range(const wt_config_priv_key_spec *ks, double v)
{
    if (!isfinite(v)) return 0;
    if ((ks->flags & F_LO_OPEN) ? v <= ks->lo : v < ks->lo) return 0;
    if ((ks->flags & F_HI_OPEN) ? v >= ks->hi : v > ks->hi) return 0;
    if ((ks->type == K_INT || ks->type == K_INTS) && (v > INT_MAX || v < INT_MIN)) return 0;
    return 1;
}

/* One scalar (or list element, elem >= 0): type and range in file units; value returned in *out. */
static int read_scalar(pstate *ps, int k, const config_setting_t *s, int elem, double *out)
{
    const wt_config_priv_key_spec *ks = &wt_config_priv_keys[k];
    char loc[512], want[160], got[200], v[40], ix[32] = "";
    if (elem >= 0) snprintf(ix, sizeof ix, ", element [%d]", elem);
    int ok = wt_config_priv_is_int(ks->type) ? is_int_setting(s) : config_setting_is_number(s);
    expected_text(ks, want, sizeof want);
    if (!ok && wt_config_priv_is_int(ks->type) && config_setting_type(s) == CONFIG_TYPE_FLOAT &&
        fabs(wt_config_priv_num(s)) >= 0x1p63 && wt_config_priv_num(s) == floor(wt_config_priv_num(s)))
        return FAIL(ps, k, s, "key '%s'%s: value %s does not fit a 64-bit integer; expected %s", ks->path, ix,
                    wt_config_priv_fmt_num(wt_config_priv_num(s), v, sizeof v), want);
    if (!ok) {
        describe(s, got, sizeof got);
        return FAIL(ps, k, s, "key '%s'%s: expected %s, got %s", ks->path, ix,
                    wt_config_priv_is_int(ks->type) ? "an integer" : "a number", got);
    }
    double x = wt_config_priv_num(s);
    if (is_int_setting(s)) snprintf(v, sizeof v, "%lld", config_setting_get_int64(s));
    else wt_config_priv_fmt_num(x, v, sizeof v);
    if ((ks->type == K_INT || ks->type == K_INTS) && (x > INT_MAX || x < INT_MIN))
        return FAIL(ps, k, s, "key '%s'%s: value %s does not fit a 32-bit integer (%d..%d); expected %s", ks->path, ix,
                    v, INT_MIN, INT_MAX, want);
    if (!in_range(ks, x))
        return FAIL(ps, k, s, "key '%s'%s: value %s is out of range; expected %s", ks->path, ix, v, want);
    long long iv = is_int_setting(s) ? config_setting_get_int64(s) : 0;
    if ((ks->flags & F_POW2) && (iv & (iv - 1)))
        return FAIL(ps, k, s, "key '%s'%s: value %s is not a power of two; expected %s", ks->path, ix, v, want);
    if ((ks->flags & F_ODD) && !(iv & 1))
        return FAIL(ps, k, s, "key '%s'%s: value %s is even; expected %s", ks->path, ix, v, want);
    if ((ks->flags & F_EVEN) && (iv & 1))
        return FAIL(ps, k, s, "key '%s'%s: value %s is odd; expected %s", ks->path, ix, v, want);
    *out = x;
    return WT_OK;
}

/* Keys with a default that the file leaves out are added to it with that value, so that they are read,
 * checked and written to the canonical text like any other. */
static int fill_defaults(pstate *ps)
{
    char loc[512], num_[40];
    for (int k = 0; k < WT_CONFIG_PRIV_NKEYS; k++) {
        const wt_config_priv_key_spec *ks = &wt_config_priv_keys[k];
        /* a list's default is another key's value (list_defaults), known once the profiles are expanded */
        if (!(ks->flags & F_DEFAULT) || wt_config_priv_is_list(ks->type) || config_lookup(ps->cf, ks->path)) continue;
        const char *leaf;
        config_setting_t *g = wt_config_priv_ensure_parent(ps->cf, ks->path, &leaf), *d = NULL;
        static const int ctype[] = {CONFIG_TYPE_INT, CONFIG_TYPE_INT64, CONFIG_TYPE_FLOAT, CONFIG_TYPE_BOOL,
                                    CONFIG_TYPE_STRING};
        if (g && !wt_config_priv_is_list(ks->type)) d = config_setting_add(g, leaf, ctype[ks->type]);
        int ok = d != NULL;
        if (ok) switch (ks->type) {
            case K_INT: ok = config_setting_set_int(d, (int)ks->def); break;
            case K_INT64: ok = config_setting_set_int64(d, (long long)ks->def); break;
            case K_FLOAT: ok = config_setting_set_float(d, ks->def); break;
            case K_BOOL: ok = config_setting_set_bool(d, ks->def != 0.0); break;
            default: {
                const char *c = ks->choices;
                for (int i = 0; i < (int)ks->def && c; i++) c = strchr(c, '|') ? strchr(c, '|') + 1 : NULL;
                size_t w = c ? strcspn(c, "|") : 0;
                snprintf(num_, sizeof num_, "%.*s", (int)w, c ? c : "");
                ok = c && config_setting_set_string(d, num_);
            }
            }
        if (!ok) {
            snprintf(loc, sizeof loc, "%s", ps->name);
            return wt_config_priv_fail(ps, loc, "cannot add the default of '%s'", ks->path);
        }
    }
    return WT_OK;
}

/* Lists whose default is another key's list: a reconstruction layer at each DM (pcg3, the paper's PCG-3) or at
 * each of the truth's layers (cg9, the paper's CG-9). Copied into the tree after the overrides and the profile
 * files, so that the canonical text holds the list as if the file had given it. */
static int list_defaults(pstate *ps)
{
    static const char *const pairs[][2] = {{"recon.pcg3.layer_altitudes_m", "dm.altitudes_m"},
                                           {"recon.cg9.layer_altitudes_m", "atmosphere.altitudes_m"}};
    for (size_t i = 0; i < sizeof pairs / sizeof *pairs; i++) {
        const int k = wt_config_priv_find_key(pairs[i][0]);
        const config_setting_t *from = config_lookup(ps->cf, pairs[i][1]);
        /* a malformed source is reported when the source itself is loaded */
        if (k < 0 || config_lookup(ps->cf, pairs[i][0]) || !from || !config_setting_is_aggregate(from) ||
            config_setting_is_group(from))
            continue;
        double v[WT_MAX_LAYERS];
        const int n = config_setting_length(from);
        if (n < 1 || n > WT_MAX_LAYERS) continue;
        for (int j = 0; j < n; j++) v[j] = wt_config_priv_num(config_setting_get_elem(from, (unsigned)j));
        int st = wt_config_priv_write_list(ps, k, v, NULL, n);
        if (st != WT_OK) return st;
    }
    return WT_OK;
}

static int load_key(pstate *ps, wt_config *cfg, int k);

/* A required key the file leaves out (after the defaults, the overrides and the profile files). */
static int is_missing(const pstate *ps, int k)
{
    const wt_config_priv_key_spec *ks = &wt_config_priv_keys[k];
    return !(ks->flags & (F_OPT | F_AUTO | F_DEFAULT)) && ks->type != K_STR && !config_lookup(ps->cf, ks->path);
}

/* Every required key the file leaves out, in one message (a new system learns them all at once); one alone is
 * reported by load_key with what it expects. */
static int report_missing(pstate *ps, wt_config *cfg, const int *missing, int n)
{
    char list[1200] = "", loc[512];
    size_t len = 0;
    if (n == 1) return load_key(ps, cfg, missing[0]);
    for (int i = 0; i < n && len < sizeof list; i++)
        len += (size_t)snprintf(list + len, sizeof list - len, "%s'%s'", i ? ", " : "", wt_config_priv_keys[missing[i]].path);
    return FAIL(ps, missing[0], NULL,
                "%d missing keys: %s; every other key has a default (`wavetomo info --keys` and docs/config.md "
                "describe each; examples/my-system.cfg is a short complete system)",
                n, list);
}

static int load_key(pstate *ps, wt_config *cfg, int k)
{
    const wt_config_priv_key_spec *ks = &wt_config_priv_keys[k];
    char loc[512], want[160], got[200], a[40], b[40];
    char *dst = (char *)cfg + ks->off;
    const config_setting_t *s = config_lookup(ps->cf, ks->path);
    /* an automatic key left out or written "auto": config_grid.c chooses it after every key is loaded */
    if (s && (ks->flags & F_AUTO) && config_setting_type(s) == CONFIG_TYPE_STRING &&
        !strcmp(config_setting_get_string(s), "auto"))
        s = NULL;
    ps->set[k] = s;
    expected_text(ks, want, sizeof want);
    if (!s) {
        if (ks->flags & F_AUTO) return WT_OK;
        /* a list whose default is another key's (list_defaults) left out with that key: the key is reported */
        if ((ks->flags & F_DEFAULT) && wt_config_priv_is_list(ks->type)) {
            *(int *)((char *)cfg + ks->count_off) = 0;
            return WT_OK;
        }
        if (ks->type == K_STR) {
            *dst = '\0';
            return WT_OK;
        }
        if (ks->flags & F_OPT) {
            /* an optional list left out has no elements; a scalar takes its default */
            if (wt_config_priv_is_list(ks->type)) *(int *)((char *)cfg + ks->count_off) = 0;
            else if (ks->type == K_FLOAT) *(double *)dst = ks->def;
            else if (ks->type == K_INT64) *(uint64_t *)dst = (uint64_t)ks->def;
            else *(int *)dst = (int)ks->def; /* K_INT, K_BOOL, K_ENUM (the index of the choice) */
            return WT_OK;
        }
        if (wt_config_priv_is_list(ks->type)) {
            return FAIL(ps, k, NULL, "missing key '%s' (a list of %d..%d elements, each %s: %s)", ks->path, ks->minlen,
                        ks->maxlen, want, ks->desc);
        }
        return FAIL(ps, k, NULL, "missing key '%s' (%s: %s)", ks->path, want, ks->desc);
    }
    double x;
    int st;
    switch (ks->type) {
    case K_BOOL:
        if (config_setting_type(s) != CONFIG_TYPE_BOOL) {
            describe(s, got, sizeof got);
            return FAIL(ps, k, s, "key '%s': expected %s, got %s", ks->path, want, got);
        }
        *(int *)dst = config_setting_get_bool(s);
        return WT_OK;
    case K_STR: {
        /* a path: relative to the configuration file's directory, like @include */
        const char *str = config_setting_type(s) == CONFIG_TYPE_STRING ? config_setting_get_string(s) : NULL;
        if (str && !*str && (ks->flags & F_EMPTY)) {
            *(char *)dst = '\0';
            return WT_OK;
        }
        if (!str || !*str) {
            describe(s, got, sizeof got);
            return FAIL(ps, k, s, "key '%s': expected %s, got %s", ks->path, want, got);
        }
        if (ks->flags & F_HEX) {
            /* a SHA-256: 64 hex digits, stored in lower case as wt_sha256_hex writes them */
            size_t i = 0;
            while (i < 64 && isxdigit((unsigned char)str[i])) i++;
            if (i != 64 || str[64])
                return FAIL(ps, k, s, "key '%s': \"%s\" is not %s", ks->path, str, want);
            for (i = 0; i < 64; i++) dst[i] = (char)tolower((unsigned char)str[i]);
            dst[64] = '\0';
            return WT_OK;
        }
        const int rel = str[0] != '/' && ps->incdir && *ps->incdir;
        /* every path key has the same capacity */
        _Static_assert(sizeof cfg->fft_wisdom == sizeof cfg->sodium_profile, "path keys' capacity");
        const size_t cap = sizeof cfg->sodium_profile;
        if ((rel ? strlen(ps->incdir) : 0) + strlen(str) + 1 > cap)
            return FAIL(ps, k, s, "key '%s': the path \"%s\" is longer than %zu characters", ks->path, str, cap - 1);
        snprintf(dst, cap, "%s%s", rel ? ps->incdir : "", str);
        return WT_OK;
    }
    case K_ENUM: {
        const char *str = config_setting_type(s) == CONFIG_TYPE_STRING ? config_setting_get_string(s) : NULL;
        if (!str) {
            describe(s, got, sizeof got);
            return FAIL(ps, k, s, "key '%s': expected %s, got %s", ks->path, want, got);
        }
        const char *c = ks->choices;
        for (int idx = 0; *c; idx++) {
            size_t w = strcspn(c, "|");
            if (strlen(str) == w && !strncmp(str, c, w)) {
                *(int *)dst = idx;
                return WT_OK;
            }
            c += w + (c[w] == '|');
        }
        return FAIL(ps, k, s, "key '%s': value \"%s\" is not accepted; expected %s", ks->path, str, want);
    }
    case K_INT:
    case K_INT64:
    case K_FLOAT:
        if ((st = read_scalar(ps, k, s, -1, &x)) < 0) return st;
        if (ks->type == K_INT) *(int *)dst = (int)x;
        else if (ks->type == K_INT64) *(uint64_t *)dst = (uint64_t)config_setting_get_int64(s);
        else *(double *)dst = x * ks->scale;
        return WT_OK;
    default: break;
    }

    /* lists: [a, b] arrays (one element type) or (a, b) lists */
    if (!config_setting_is_array(s) && !config_setting_is_list(s)) {
        describe(s, got, sizeof got);
        return FAIL(ps, k, s, "key '%s': expected a list [ ... ] of %d..%d elements, each %s%s, got %s", ks->path,
                    ks->minlen, ks->maxlen, want, ks->flags & F_AUTO ? ", or \"auto\"" : "", got);
    }
    int n = config_setting_length(s);
    if (n < ks->minlen || n > ks->maxlen)
        return FAIL(ps, k, s, "key '%s': has %d elements; expected %d..%d", ks->path, n, ks->minlen, ks->maxlen);
    for (int i = 0; i < n; i++) {
        const config_setting_t *e = config_setting_get_elem(s, (unsigned)i);
        if ((st = read_scalar(ps, k, e, i, &x)) < 0) return st;
        if ((ks->flags & F_INCR) && i > 0 && !(x > wt_config_priv_num(config_setting_get_elem(s, (unsigned)i - 1))))
            return FAIL(ps, k, e, "key '%s', element [%d]: value %s is not above the previous element %s; the list "
                        "must be strictly increasing", ks->path, i, wt_config_priv_fmt_num(x, a, sizeof a),
                        wt_config_priv_fmt_num(wt_config_priv_num(config_setting_get_elem(s, (unsigned)i - 1)), b,
                                               sizeof b));
        if (ks->type == K_INTS) ((int *)dst)[i] = (int)x;
        else ((double *)dst)[i] = x * ks->scale;
    }
    int first = k;
    while (first > 0 && wt_config_priv_keys[first - 1].count_off == ks->count_off) first--;
    int *count = (int *)((char *)cfg + ks->count_off);
    /* a required first list left out is reported with the other missing keys; its siblings set the count */
    if (first == k || (!config_lookup(ps->cf, wt_config_priv_keys[first].path) && !(wt_config_priv_keys[first].flags & F_OPT)))
        *count = n;
    else if (*count != n)
        return FAIL(ps, k, s, "key '%s' has %d elements but '%s' has %d; they must have the same length", ks->path, n,
                    wt_config_priv_keys[first].path, *count);
    return WT_OK;
}

/* ---------------------------------------------------------------- public */

static void free_file_overrides(wt_context *ctx, const char **allov, int nfile)
{
    if (!allov) return;
    for (int i = 0; i < nfile; i++) wt_free(ctx, (void *)allov[i]);
    wt_free(ctx, (void *)allov);
}

static int parse_text(wt_context *ctx, const char *text, const char *name, const char *incdir, int noverrides,
                      const char *const *overrides, wt_config **out)
{
    int st = WT_OK;
    wt_config_priv_text src = {0};
    wt_config *cfg = NULL;
    const char **allov = NULL;
    int nfile = 0; /* overrides the file carries (before any goto fail) */
    config_t cf;
    pstate ps = {.ctx = ctx, .name = name ? name : "<string>", .cf = &cf, .ov = overrides, .src = &src, .incdir = incdir};
    *out = NULL;
    for (int k = 0; k < WT_CONFIG_PRIV_NKEYS; k++) ps.ovidx[k] = -1;
    config_init(&cf);
    if (!text) {
        st = WT_ERROR(ctx, WT_ERR_INVALID, "%s: no configuration text", ps.name);
        goto fail;
    }
    if (noverrides > 0 && !overrides) {
        st = WT_ERROR(ctx, WT_ERR_INVALID, "%s: %d overrides but no override array", ps.name, noverrides);
        goto fail;
    }
    WT_TRY(wt_config_priv_text_make(ctx, text, ps.name, incdir, &src));
    if (!config_read_string(&cf, src.text)) {
        const char *e = config_error_text(&cf) ? config_error_text(&cf) : "unknown error";
        char at[1100];
        /* a duplicate after @include: name the included files, where the first definition is */
        char inc[1200] = "";
        size_t ni = 0;
        for (int i = 1; strstr(e, "duplicate setting") && i < src.nfiles && ni < sizeof inc; i++)
            ni += (size_t)snprintf(inc + ni, sizeof inc - ni, "%s'%s'", i > 1 ? ", " : " (included: ", src.files[i]);
        if (*inc && ni < sizeof inc) snprintf(inc + ni, sizeof inc - ni, ")");
        st = WT_ERROR(ctx, WT_ERR_CONFIG, "%s: syntax error: %s%s%s",
                      wt_config_priv_src_line(&ps, config_error_line(&cf), at, sizeof at), e, inc, syntax_hint(e));
        goto fail;
    }
    /* A file may carry its own overrides (a preset that @includes another and changes a few keys:
     * libconfig refuses a setting defined twice); they apply before the command line's. */
    const config_setting_t *fo = config_setting_get_member(config_root_setting(&cf), "overrides");
    if (fo) {
        if (!config_setting_is_aggregate(fo) || config_setting_is_group(fo)) {
            char at[1100];
            st = WT_ERROR(ctx, WT_ERR_CONFIG, "%s: 'overrides' must be a list of \"key=value\" strings",
                          wt_config_priv_src_line(&ps, (int)config_setting_source_line(fo), at, sizeof at));
            goto fail;
        }
        nfile = config_setting_length(fo);
    }
    if (nfile > 0) {
        WT_ALLOC(ctx, allov, (size_t)(nfile + noverrides), "the overrides");
        for (int i = 0; i < nfile; i++) {
            const config_setting_t *e = config_setting_get_elem(fo, (unsigned)i);
            allov[i] = config_setting_get_string(e);
            if (!allov[i]) {
                char at[1100];
                st = WT_ERROR(ctx, WT_ERR_CONFIG, "%s: overrides[%d] must be a \"key=value\" string",
                              wt_config_priv_src_line(&ps, (int)config_setting_source_line(e), at, sizeof at), i);
                goto fail;
            }
            WT_ALLOC(ctx, allov[i], strlen(config_setting_get_string(e)) + 1, "an override");
            strcpy((char *)allov[i], config_setting_get_string(e));
        }
        for (int i = 0; i < noverrides; i++) allov[nfile + i] = overrides[i];
        ps.ov = allov;
        ps.nfile_ov = nfile;
    }
    if (fo) config_setting_remove(config_root_setting(&cf), "overrides");
    WT_TRY(check_unknown(&ps, config_root_setting(&cf), ""));
    for (int i = 0; i < nfile + noverrides; i++) WT_TRY(apply_override(&ps, i));
    WT_TRY(fill_defaults(&ps));
    WT_TRY(wt_config_priv_expand_profiles(&ps));
    WT_TRY(list_defaults(&ps));
    WT_ALLOC(ctx, cfg, 1, "the configuration");
    snprintf(cfg->path, sizeof cfg->path, "%s", ps.name);
    int missing[WT_CONFIG_PRIV_NKEYS], nmissing = 0;
    for (int k = 0; k < WT_CONFIG_PRIV_NKEYS; k++) {
        if (is_missing(&ps, k)) missing[nmissing++] = k;
        else WT_TRY(load_key(&ps, cfg, k));
    }
    if (nmissing > 0) WT_TRY(report_missing(&ps, cfg, missing, nmissing));
    WT_TRY(wt_config_priv_check_consistency(&ps, cfg));
    WT_TRY(wt_config_priv_check_derived(ctx, cfg));
    WT_TRY(wt_config_priv_build_canonical(&ps, cfg));
    config_destroy(&cf);
    wt_config_priv_text_free(&src);
    free_file_overrides(ctx, allov, nfile);
    *out = cfg;
    return WT_OK;
fail:
    config_destroy(&cf);
    wt_config_priv_text_free(&src);
    free_file_overrides(ctx, allov, nfile);
    wt_config_free(ctx, cfg);
    return st;
}

int wt_config_parse(wt_context *ctx, const char *text, const char *name, int noverrides,
                    const char *const *overrides, wt_config **out)
{
    return parse_text(ctx, text, name, NULL, noverrides, overrides, out);
}

int wt_config_read(wt_context *ctx, const char *path, int noverrides, const char *const *overrides,
                   wt_config **out)
{
    int st = WT_OK;
    char *text = NULL, *dir = NULL;
    size_t n = 0, cap = 1 << 16;
    *out = NULL;
    FILE *f = path ? fopen(path, "rb") : NULL;
    if (!f) return WT_ERROR(ctx, WT_ERR_IO, "cannot open configuration '%s': %s", path ? path : "(null)", strerror(errno));
    WT_ALLOC(ctx, text, cap, "the configuration text");
    for (;;) {
        n += fread(text + n, 1, cap - 1 - n, f);
        if (ferror(f)) {
            st = WT_ERROR(ctx, WT_ERR_IO, "cannot read configuration '%s': %s", path, strerror(errno));
            goto fail;
        }
        if (feof(f)) break;
        char *t = wt_malloc(ctx, 2 * cap, 1);
        if (!t) {
            st = WT_ERROR(ctx, WT_ERR_NOMEM, "out of memory reading '%s'", path);
            goto fail;
        }
        memcpy(t, text, n);
        wt_free(ctx, text);
        text = t;
        cap *= 2;
    }
    text[n] = '\0';
    /* @include "x" resolves relative to the file's directory */
    const char *slash = strrchr(path, '/');
    if (slash) {
        WT_ALLOC(ctx, dir, (size_t)(slash - path) + 2, "the include directory");
        memcpy(dir, path, (size_t)(slash - path) + 1);
    }
    st = parse_text(ctx, text, path, dir, noverrides, overrides, out);
fail:
    fclose(f);
    wt_free(ctx, text);
    wt_free(ctx, dir);
    return st;
}

void wt_config_free(wt_context *ctx, wt_config *cfg)
{
    if (!cfg) return;
    wt_free(ctx, cfg->canonical);
    wt_free(ctx, cfg->matrix_text);
    wt_free(ctx, cfg);
}
