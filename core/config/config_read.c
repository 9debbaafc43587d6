/* core/config/config_read.c: libconfig text -> wt_config, driven by one schema table.
 *
 * Implements the system description of SPEC §1 (every key of the presets) and the canonical text
 * that the MVM builder hashes (SPEC §9). One table (config_schema.c) lists every key with its type,
 * range, unit, description and destination; reading, override, validation, the canonical text and the
 * printed reference all walk that table, so a key cannot be documented one way and read another.
 * Order of work: syntax -> unknown keys -> --set overrides -> typed keys in schema order ->
 * cross-key consistency -> canonical text.
 */
#include "config_private.h"

#include "../base/names.h"
#include "../base/sha256.h"

#define WT_SH_TILT_Z_CFG 1 /* ngs.wfs.tilt = "z" (WT_SH_TILT_Z of core/op/shack_hartmann.h) */

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

static double num(const config_setting_t *s)
{
    int t = config_setting_type(s);
    return t == CONFIG_TYPE_FLOAT   ? config_setting_get_float(s)
           : t == CONFIG_TYPE_INT64 ? (double)config_setting_get_int64(s)
                                    : (double)config_setting_get_int(s);
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
    case CONFIG_TYPE_FLOAT: snprintf(buf, n, "a number %s", wt_config_priv_fmt_num(num(s), v, sizeof v)); break;
    case CONFIG_TYPE_STRING: snprintf(buf, n, "a string \"%s\"", config_setting_get_string(s)); break;
    case CONFIG_TYPE_BOOL: snprintf(buf, n, "a boolean %s", config_setting_get_bool(s) ? "true" : "false"); break;
    case CONFIG_TYPE_GROUP: snprintf(buf, n, "a group { ... }"); break;
    default: snprintf(buf, n, "a list of %d elements", config_setting_length(s)); break;
    }
}

/* libconfig's message, plus what to do about its least obvious one */
static const char *syntax_hint(const char *e)
{
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
        fabs(num(s)) >= 0x1p63 && num(s) == floor(num(s)))
        return FAIL(ps, k, s, "key '%s'%s: value %s does not fit a 64-bit integer; expected %s", ks->path, ix,
                    wt_config_priv_fmt_num(num(s), v, sizeof v), want);
    if (!ok) {
        describe(s, got, sizeof got);
        return FAIL(ps, k, s, "key '%s'%s: expected %s, got %s", ks->path, ix,
                    wt_config_priv_is_int(ks->type) ? "an integer" : "a number", got);
    }
    double x = num(s);
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
        if (!(ks->flags & F_DEFAULT) || config_lookup(ps->cf, ks->path)) continue;
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
        if ((ks->flags & F_INCR) && i > 0 && !(x > num(config_setting_get_elem(s, (unsigned)i - 1))))
            return FAIL(ps, k, e, "key '%s', element [%d]: value %s is not above the previous element %s; the list "
                        "must be strictly increasing", ks->path, i, wt_config_priv_fmt_num(x, a, sizeof a),
                        wt_config_priv_fmt_num(num(config_setting_get_elem(s, (unsigned)i - 1)), b, sizeof b));
        if (ks->type == K_INTS) ((int *)dst)[i] = (int)x;
        else ((double *)dst)[i] = x * ks->scale;
    }
    int first = k;
    while (first > 0 && wt_config_priv_keys[first - 1].count_off == ks->count_off) first--;
    int *count = (int *)((char *)cfg + ks->count_off);
    if (first == k) *count = n;
    else if (*count != n)
        return FAIL(ps, k, s, "key '%s' has %d elements but '%s' has %d; they must have the same length", ks->path, n,
                    wt_config_priv_keys[first].path, *count);
    return WT_OK;
}

/* ---------------------------------------------------------------- cross-key checks */

static int check_below_lgs(pstate *ps, const wt_config *cfg, const char *path, const double *alt, int n)
{
    char loc[512], oth[512], a[40], b[40];
    int kl = wt_config_priv_find_key("lgs.altitude_m"), kk = wt_config_priv_find_key(path);
    for (int i = 0; i < n; i++)
        if (!(alt[i] < cfg->lgs_altitude))
            return FAIL(ps, kl, ps->set[kl], "key 'lgs.altitude_m': value %s is not above '%s' element [%d] = %s "
                        "(%s): an LGS below a layer; the sodium layer must be above every atmosphere, DM and "
                        "reconstruction layer", wt_config_priv_fmt_num(cfg->lgs_altitude, a, sizeof a), path, i,
                        wt_config_priv_fmt_num(alt[i], b, sizeof b), wt_config_priv_where_elem(ps, kk, i, oth, sizeof oth));
    return WT_OK;
}

static int check_sizes(pstate *ps, const wt_config *cfg, const char *path, const wt_recon_variant_config *v)
{
    char loc[512], oth[512];
    int k = wt_config_priv_find_key(path), kj = wt_config_priv_find_key("recon.wavelet_levels");
    long long need = 1LL << cfg->wavelet_levels;
    for (int i = 0; i < v->nlayers; i++)
        if (v->size[i] < need)
            return FAIL(ps, k, config_setting_get_elem(ps->set[k], (unsigned)i),
                        "key '%s', element [%d]: value %d is smaller than 2^recon.wavelet_levels = 2^%d = %lld (%s); "
                        "a layer grid needs at least 2^J points per side", path, i, v->size[i], cfg->wavelet_levels,
                        need, wt_config_priv_where(ps, kj, ps->set[kj], oth, sizeof oth));
    return WT_OK;
}

/* recon.<name>.layer_spacing_m / layer_size / layer_oversampling: which are given decides what is chosen
 * (config_grid.c). Both given: as written. Spacing given, size left out: the size follows from the spacing.
 * Both left out: both chosen, the spacing divided by layer_oversampling. Refused: a size without its
 * spacing (it fixes neither the resolution nor the extent) and an oversampling beside a given spacing (it
 * would be ignored). */
static int resolve_grid(pstate *ps, wt_config *cfg, const char *name, wt_recon_variant_config *v)
{
    char loc[512], oth[512], sp[64], sz[64], os[64];
    snprintf(sp, sizeof sp, "recon.%s.layer_spacing_m", name);
    snprintf(sz, sizeof sz, "recon.%s.layer_size", name);
    snprintf(os, sizeof os, "recon.%s.layer_oversampling", name);
    const int ks = wt_config_priv_find_key(sp), kz = wt_config_priv_find_key(sz), ko = wt_config_priv_find_key(os);
    const int gs = ps->set[ks] != NULL, gz = ps->set[kz] != NULL, go = ps->set[ko] != NULL;
    v->grid_auto = WT_GRID_EXPLICIT;
    if (gs && go)
        return FAIL(ps, ko, ps->set[ko], "key '%s' is given with '%s' (%s): the oversampling divides only the "
                    "automatic spacing; leave out one of them", os, sp, wt_config_priv_where(ps, ks, ps->set[ks], oth, sizeof oth));
    if (!gs && gz)
        return FAIL(ps, kz, ps->set[kz], "key '%s' is given but '%s' is left out (or \"auto\"): a size alone fixes "
                    "neither the resolution nor the extent of a layer; give both, only '%s' (the size then follows "
                    "from it), or neither (both chosen from the system)", sz, sp, sp);
    if (gs && gz) return WT_OK;
    v->grid_auto = gs ? WT_GRID_AUTO_SIZE : WT_GRID_AUTO;
    int st = wt_config_priv_layer_grid(ps->ctx, cfg, name, !gs, v);
    if (st == WT_OK && !gs) st = wt_config_priv_write_list(ps, ks, v->spacing, NULL, v->nlayers);
    if (st == WT_OK) st = wt_config_priv_write_list(ps, kz, NULL, v->size, v->nlayers);
    /* the canonical text gives the chosen grid and not the oversampling: it must read back (wavetomo run
     * parses a stored one), and an oversampling beside a given spacing is refused above */
    ps->set[ko] = NULL;
    return st;
}

/* recon.sensor_points_per_subaperture left out (or "auto"): the smallest q with d/q ≤ the finest layer
 * spacing of both variants (within the 15 digits of the canonical text), at most the schema's 16; written
 * into the canonical text like the automatic grids. */
static int resolve_sensor_points(pstate *ps, wt_config *cfg)
{
    const int k = wt_config_priv_find_key("recon.sensor_points_per_subaperture");
    if (ps->set[k]) return WT_OK;
    double dmin = INFINITY;
    for (int i = 0; i < cfg->pcg3.nlayers; i++) dmin = fmin(dmin, cfg->pcg3.spacing[i]);
    for (int i = 0; i < cfg->cg9.nlayers; i++) dmin = fmin(dmin, cfg->cg9.spacing[i]);
    const double d = cfg->diameter / cfg->lgs_wfs.subapertures;
    int q = (int)ceil(d / dmin * (1.0 - 1e-12));
    cfg->sensor_points = q < 1 ? 1 : q > 16 ? 16 : q;
    const char *leaf;
    config_setting_t *g = wt_config_priv_ensure_parent(ps->cf, wt_config_priv_keys[k].path, &leaf), *s = NULL;
    if (g && config_setting_get_member(g, leaf)) config_setting_remove(g, leaf); /* the word "auto" */
    if (g) s = config_setting_add(g, leaf, CONFIG_TYPE_INT);
    if (!s || !config_setting_set_int(s, cfg->sensor_points))
        return WT_ERROR(ps->ctx, WT_ERR_NOMEM, "%s: libconfig could not add the chosen '%s'", ps->name,
                        wt_config_priv_keys[k].path);
    ps->set[k] = s;
    return WT_OK;
}

/* recon.cg9.fit_points_per_subaperture left out (or "auto"): the smallest q with d/q ≤ half the finer of the
 * finest cg9 layer spacing and the finest DM pitch (within the 15 digits of the canonical text), at most the
 * schema's 16: two samples per cell of the finest grid the fit reads or writes, so that the sampled least
 * squares ‖H a − P φ‖² approaches the integral over the pupil (docs/results.md §18); written into the
 * canonical text like the automatic grids. The E-ELT and demo presets: q = 2, the 42x42 preset: q = 4. */
static int resolve_fit_points(pstate *ps, wt_config *cfg)
{
    const int k = wt_config_priv_find_key("recon.cg9.fit_points_per_subaperture");
    if (ps->set[k]) return WT_OK;
    double fine = INFINITY;
    for (int i = 0; i < cfg->cg9.nlayers; i++) fine = fmin(fine, cfg->cg9.spacing[i]);
    for (int i = 0; i < cfg->ndms; i++) fine = fmin(fine, cfg->dm_pitch[i]);
    const double d = cfg->diameter / cfg->lgs_wfs.subapertures;
    int q = isfinite(fine) ? (int)ceil(d / (0.5 * fine) * (1.0 - 1e-12)) : 2;
    cfg->cg9.fit_sampling = q < 1 ? 1 : q > 16 ? 16 : q;
    const char *leaf;
    config_setting_t *g = wt_config_priv_ensure_parent(ps->cf, wt_config_priv_keys[k].path, &leaf), *s = NULL;
    if (g && config_setting_get_member(g, leaf)) config_setting_remove(g, leaf); /* the word "auto" */
    if (g) s = config_setting_add(g, leaf, CONFIG_TYPE_INT);
    if (!s || !config_setting_set_int(s, cfg->cg9.fit_sampling))
        return WT_ERROR(ps->ctx, WT_ERR_NOMEM, "%s: libconfig could not add the chosen '%s'", ps->name,
                        wt_config_priv_keys[k].path);
    ps->set[k] = s;
    return WT_OK;
}

/* recon.<variant>.prior left out (or "auto"): recon.prior when given, else the variant's default
 * (WT_PRIOR_DEFAULT_*, config.h); written into the canonical text like the automatic grids, so the text
 * (and an MVM's identity) says which prior each variant used. */
static int resolve_priors(pstate *ps, wt_config *cfg)
{
    static const char *const words[] = {"paper", "exact", "full"};
    const int kg = wt_config_priv_find_key("recon.prior");
    if (!ps->set[kg]) cfg->exact_prior = -1;
    for (int v = 0; v < 2; v++) {
        const int k = wt_config_priv_find_key(v ? "recon.cg9.prior" : "recon.pcg3.prior");
        wt_recon_variant_config *var = v ? &cfg->cg9 : &cfg->pcg3;
        if (ps->set[k]) continue;
        var->prior = ps->set[kg] ? cfg->exact_prior : v ? WT_PRIOR_DEFAULT_CG9 : WT_PRIOR_DEFAULT_PCG3;
        const char *leaf;
        config_setting_t *g = wt_config_priv_ensure_parent(ps->cf, wt_config_priv_keys[k].path, &leaf), *s = NULL;
        if (g && config_setting_get_member(g, leaf)) config_setting_remove(g, leaf); /* the word "auto" */
        if (g) s = config_setting_add(g, leaf, CONFIG_TYPE_STRING);
        if (!s || !config_setting_set_string(s, words[var->prior]))
            return WT_ERROR(ps->ctx, WT_ERR_NOMEM, "%s: libconfig could not add the chosen '%s'", ps->name,
                            wt_config_priv_keys[k].path);
        ps->set[k] = s;
    }
    return WT_OK;
}

/* A file's SHA-256 key (lgs.sodium_profile_sha256, recon.fft_wisdom_sha256) left out (or "auto") while its
 * file is used: the SHA-256 of the file's bytes, written into the canonical text. For the sodium profile this
 * makes the matrix hash follow the profile's contents (an MVM built with one profile is refused after the file
 * changes); for the FFT wisdom, every output records which plans ran. A file that cannot be hashed here
 * (missing, unreadable, not a regular file) leaves the key out: the code that reads the file refuses it with
 * the reason (core/model/sensing.c, core/la/fft.c), and nothing runs without it. A given value (the canonical
 * text of a telemetry or matrix file, read back where the relative path may not resolve) is kept: it records
 * the file the system was made with; the reader checks the file against it. */
static int resolve_file_sha256(pstate *ps, const char *key, int used, const char *file, char hex[65])
{
    const int k = wt_config_priv_find_key(key);
    if (ps->set[k] || !used || !file[0]) return WT_OK;
    if (wt_sha256_file(file, hex) != 0) {
        hex[0] = '\0';
        return WT_OK;
    }
    const char *leaf;
    config_setting_t *g = wt_config_priv_ensure_parent(ps->cf, wt_config_priv_keys[k].path, &leaf), *s = NULL;
    if (g && config_setting_get_member(g, leaf)) config_setting_remove(g, leaf); /* the word "auto" */
    if (g) s = config_setting_add(g, leaf, CONFIG_TYPE_STRING);
    if (!s || !config_setting_set_string(s, hex))
        return WT_ERROR(ps->ctx, WT_ERR_NOMEM, "%s: libconfig could not add the chosen '%s'", ps->name,
                        wt_config_priv_keys[k].path);
    ps->set[k] = s;
    return WT_OK;
}

/* loop.gain_levels: L + 1 values need every DM's grid (actuators + 2 guard rings per side), embedded in
 * the smallest power of two n, to hold squares (or a Daubechies scaling block) of 2^(L+1) actuators:
 * L + 1 <= log2 n (core/op/scale_gain.h). loop.gain_basis means nothing without them. */
static int check_gain_levels(pstate *ps, const wt_config *cfg)
{
    char loc[512], oth[512];
    const int k = wt_config_priv_find_key("loop.gain_levels"), kb = wt_config_priv_find_key("loop.gain_basis");
    if (cfg->ngain_levels == 0) {
        if (ps->set[kb])
            return FAIL(ps, kb, ps->set[kb], "key 'loop.gain_basis' is given without 'loop.gain_levels': it chooses "
                        "the bands of a scale-dependent gain; give the gains or leave it out");
        return WT_OK;
    }
    for (int d = 0; d < cfg->ndms; d++) {
        const int side = cfg->dm_actuators[d] + 2 * cfg->dm_guard_rings;
        int n = 1, lmax = 0;
        while (n < side) n *= 2, lmax++;
        if (cfg->ngain_levels > lmax)
            return FAIL(ps, k, ps->set[k], "key 'loop.gain_levels' has %d values, but DM %d's grid of %d actuators "
                        "per side ('dm.actuators' [%d] = %d at %s, plus 2 x 'dm.guard_rings' = %d) embeds in %d "
                        "points, whose coarsest band of %d values would need squares of %d; expected 2 ... %d values",
                        cfg->ngain_levels, d + 1, side, d, cfg->dm_actuators[d],
                        wt_config_priv_where_elem(ps, wt_config_priv_find_key("dm.actuators"), d, oth, sizeof oth), cfg->dm_guard_rings, n,
                        cfg->ngain_levels, 1 << cfg->ngain_levels, lmax);
    }
    return WT_OK;
}

static int check_consistency(pstate *ps, wt_config *cfg)
{
    char loc[512], oth[512];
    int st, k;
    double sum = 0.0;
    for (int i = 0; i < cfg->nlayers; i++) sum += cfg->layer_fraction[i];
    k = wt_config_priv_find_key("atmosphere.cn2_fractions");
    if (!(fabs(sum - 1.0) <= 0.01))
        return FAIL(ps, k, ps->set[k], "key 'atmosphere.cn2_fractions': the fractions sum to %.6g; expected 1 within 1 %% "
                    "(they are then normalised to sum exactly 1)", sum);
    for (int i = 0; i < cfg->nlayers; i++) cfg->layer_fraction[i] /= sum;
    if ((st = wt_config_priv_resolve_model(ps, cfg)) < 0) return st;
    if ((st = wt_config_priv_check_night(ps, cfg)) < 0) return st;
    if ((st = wt_config_priv_check_sodium(ps, cfg)) < 0) return st;

    k = wt_config_priv_find_key("evaluation.settle_frames");
    if (cfg->settle_frames >= cfg->frames)
        return FAIL(ps, k, ps->set[k], "key 'evaluation.settle_frames': value %d is not below 'loop.frames' = %d (%s); "
                    "no frame would be left to average", cfg->settle_frames, cfg->frames,
                    wt_config_priv_where_elem(ps, wt_config_priv_find_key("loop.frames"), -1, oth, sizeof oth));

    if (cfg->nlgs + cfg->nngs == 0)
        return wt_config_priv_fail(ps, ps->name, "'lgs.count' is 0 and 'ngs.azimuths_deg' is empty: the system has no guide star");

    if (cfg->nlgs > 0) {
        if ((st = check_below_lgs(ps, cfg, "atmosphere.altitudes_m", cfg->layer_altitude, cfg->nlayers)) < 0 ||
            (st = check_below_lgs(ps, cfg, "dm.altitudes_m", cfg->dm_altitude, cfg->ndms)) < 0 ||
            (st = check_below_lgs(ps, cfg, "recon.pcg3.layer_altitudes_m", cfg->pcg3.altitudes, cfg->pcg3.nlayers)) < 0 ||
            (st = check_below_lgs(ps, cfg, "recon.cg9.layer_altitudes_m", cfg->cg9.altitudes, cfg->cg9.nlayers)) < 0 ||
            (st = check_below_lgs(ps, cfg, "recon.atmosphere.altitudes_m", cfg->model.altitude,
                                  cfg->model.source != WT_MODEL_ORACLE ? cfg->model.nlayers : 0)) < 0)
            return st;
    }
    if ((st = resolve_grid(ps, cfg, "pcg3", &cfg->pcg3)) < 0 || (st = resolve_grid(ps, cfg, "cg9", &cfg->cg9)) < 0)
        return st;
    if ((st = check_sizes(ps, cfg, "recon.pcg3.layer_size", &cfg->pcg3)) < 0 ||
        (st = check_sizes(ps, cfg, "recon.cg9.layer_size", &cfg->cg9)) < 0)
        return st;
    if ((st = resolve_sensor_points(ps, cfg)) < 0) return st;
    {   /* the mode says which focus the removal takes out: without the removal it would be ignored */
        const int km = wt_config_priv_find_key("recon.lgs_focus_mode");
        if (ps->set[km] && !cfg->lgs_focus_removal)
            return FAIL(ps, km, ps->set[km], "key 'recon.lgs_focus_mode' is given but 'recon.lgs_focus_removal' is "
                        "false: the mode chooses which LGS focus the removal projects out; set "
                        "recon.lgs_focus_removal = true, or leave the mode out");
    }
    if ((st = resolve_fit_points(ps, cfg)) < 0) return st;
    if ((st = resolve_priors(ps, cfg)) < 0) return st;
    if ((st = resolve_file_sha256(ps, "lgs.sodium_profile_sha256",
                                  cfg->nlgs > 0 && cfg->lgs_wfs.model == WT_WFS_DIFFRACTIVE, cfg->sodium_profile,
                                  cfg->sodium_profile_sha256)) < 0 ||
        (st = resolve_file_sha256(ps, "recon.fft_wisdom_sha256", 1, cfg->fft_wisdom, cfg->fft_wisdom_sha256)) < 0)
        return st;
    if ((st = check_gain_levels(ps, cfg)) < 0) return st;

    for (int t = 0; t < 2; t++) {
        const char *pre = t ? "ngs.wfs" : "lgs.wfs";
        const wt_sensor_config *w = t ? &cfg->ngs_wfs : &cfg->lgs_wfs;
        char a[96], b[96];
        if ((t ? cfg->nngs : cfg->nlgs) == 0 || w->model != WT_WFS_DIFFRACTIVE) continue;
        snprintf(a, sizeof a, "%s.fft_size", pre);
        snprintf(b, sizeof b, "%s.pupil_samples", pre);
        k = wt_config_priv_find_key(a);
        if (w->fft_size % 2 || w->fft_size < 2 * w->pupil_samples)
            return FAIL(ps, k, ps->set[k], "key '%s' = %d: the FFT sampling is too coarse or odd for '%s' = %d; "
                        "expected an even number >= %d (2 x %s: Nyquist sampling of the wavelength over the "
                        "subaperture side)", a, w->fft_size, b, w->pupil_samples, 2 * w->pupil_samples, b);
        snprintf(a, sizeof a, "%s.window_pixels", pre);
        snprintf(b, sizeof b, "%s.pixels", pre);
        k = wt_config_priv_find_key(a);
        if (w->window_pixels > w->pixels || (w->window_pixels > 0 && (w->pixels - w->window_pixels) % 2))
            return FAIL(ps, k, ps->set[k], "key '%s' = %d: the window must fit the detector '%s' = %d with an even "
                        "difference (it is centred), or be 0 (the whole detector)", a, w->window_pixels, b, w->pixels);
        if (w->centroider == 2 && w->window_pixels != 0 && w->window_pixels != w->pixels)
            return FAIL(ps, k, ps->set[k], "key '%s' = %d: the matched filter ('%s.centroider' = \"mf\") uses every "
                        "pixel; expected 0 or '%s' = %d", a, w->window_pixels, pre, b, w->pixels);
        k = wt_config_priv_find_key(b);
        if (w->pixels > 256) /* WT_CENTROID_MAX_PIXELS of core/optics/centroid.h */
            return FAIL(ps, k, ps->set[k], "key '%s' = %d: a diffractive detector has at most 256 pixels per side",
                        b, w->pixels);
        snprintf(a, sizeof a, "%s.nea_mas", pre);
        k = wt_config_priv_find_key(a);
        if (ps->set[k])
            return FAIL(ps, k, ps->set[k], "key '%s' is a geometric-model key (it replaces the photon/read-noise "
                        "model); with '%s.model' = \"diffractive\" the noise comes from the pixels: leave it out", a, pre);
        if (t && w->tilt == WT_SH_TILT_Z_CFG) {
            k = wt_config_priv_find_key("ngs.wfs.tilt");
            return FAIL(ps, k, ps->set[k], "key 'ngs.wfs.tilt' = \"z\" concerns the geometric model; with "
                        "'ngs.wfs.model' = \"diffractive\" an NGS measures what its centroider measures (a G-tilt): "
                        "use \"g\" or the geometric model");
        }
    }

    /* the NGS sensors have no keys of their own for these */
    cfg->ngs_wfs.valid_fraction = cfg->lgs_wfs.valid_fraction;
    cfg->ngs_wfs.subapertures = 0;
    return WT_OK;
}

/* ---------------------------------------------------------------- canonical text */

/* The effective settings in schema order with one type per key (floats as floats, lists as arrays),
 * so comments, layout, key order, 42 vs 42.0 and [..] vs (..) do not change the text. Floats are
 * written by libconfig with 15 significant digits. */
/* Keys that cannot change the reconstructor's matrices (R, RÂ): the simulation truth only (wind, LGS
 * jitter, seed, noise switch; the truth's profile too unless it is the oracle's model: config_atmosphere.c), the loop, the long-exposure bookkeeping, and how an iterative solver
 * stops. Everything else is hashed into the matrix's identity (SPEC §9). The loop's gain and delay
 * enter the noise model when a variant's loop_noise_average is on, and then only. */
static int affects_matrix(const pstate *ps, const char *path)
{
    const int model = wt_config_priv_model_affects_matrix(ps, path);
    if (model >= 0) return model;
    if (!strcmp(path, "loop.gain") || !strcmp(path, "loop.delay_frames")) {
        int on = 0;
        for (int k = 0; k < WT_CONFIG_PRIV_NKEYS; k++)
            if (strstr(wt_config_priv_keys[k].path, ".loop_noise_average") && ps->set[k])
                on |= config_setting_get_bool(ps->set[k]);
        return on;
    }
    /* a diffractive LGS reference "rendered" on the simulation grid takes the grid's spacing */
    if (!strcmp(path, "sim.points_per_subaperture")) {
        const int km = wt_config_priv_find_key("lgs.wfs.model"), kr = wt_config_priv_find_key("lgs.wfs.reference_seeing");
        const char *m = km >= 0 && ps->set[km] ? config_setting_get_string(ps->set[km]) : NULL;
        const char *r = kr >= 0 && ps->set[kr] ? config_setting_get_string(ps->set[kr]) : NULL;
        return m && r && !strcmp(m, "diffractive") && !strcmp(r, "rendered");
    }
    /* a diffractive tCoG is calibrated at the operating noise when the simulation has noise (its reference
     * and gain, so its covariance: core/optics/centroid.h), so sim.noise shapes the noise model then */
    if (!strcmp(path, "sim.noise")) {
        int on = 0;
        for (const char *t = "ln"; *t; t++) {
            const int km = wt_config_priv_find_key(*t == 'l' ? "lgs.wfs.model" : "ngs.wfs.model");
            const int kc = wt_config_priv_find_key(*t == 'l' ? "lgs.wfs.centroider" : "ngs.wfs.centroider");
            const char *m = km >= 0 && ps->set[km] ? config_setting_get_string(ps->set[km]) : NULL;
            const char *c = kc >= 0 && ps->set[kc] ? config_setting_get_string(ps->set[kc]) : NULL;
            on |= m && c && !strcmp(m, "diffractive") && !strcmp(c, "tcog");
        }
        return on;
    }
    /* the diffractive sensor's keys shape the noise model only when that sensor type is diffractive */
    static const char *const diffr[] = {".model", ".centroider", ".apply_gain", ".tcog_threshold", ".window_pixels",
                                        ".background_e", ".pupil_samples", ".fft_size", ".cells_per_pixel",
                                        ".wavelength_nm", ".noise_calibration", ".calibration_"};
    /* the sodium layer in time and the loop's reference: the truth and the loop only; the set-up reference (the
     * MVM's noise model) is lgs.sodium_profile's (SPEC §12 "The sodium layer changes too") */
    if (!strncmp(path, "lgs.sodium_sequence", 19) || !strcmp(path, "lgs.wfs.reference") ||
        !strcmp(path, "lgs.wfs.reference_update_s"))
        return 0;
    /* the profile enters by its contents (lgs.sodium_profile_sha256) and by its name only when they could
     * not be hashed: the same bytes under another name give the same matrix, an edited file another */
    if (!strcmp(path, "lgs.sodium_profile")) {
        const int kh = wt_config_priv_find_key("lgs.sodium_profile_sha256");
        if (kh >= 0 && ps->set[kh]) return 0;
    }
    const int lgs_only = !strcmp(path, "lgs.uplink_fwhm_arcsec") || !strcmp(path, "lgs.wfs.reference_seeing") || !strcmp(path, "lgs.sodium_profile") ||
                         !strcmp(path, "lgs.sodium_profile_sha256");
    for (size_t i = 0; i < sizeof diffr / sizeof *diffr && !lgs_only; i++)
        if ((!strncmp(path, "lgs.wfs.", 8) || !strncmp(path, "ngs.wfs.", 8)) && strstr(path, diffr[i]))
            goto diffractive;
    if (lgs_only) goto diffractive;
    static const char *const skip[] = {"sim.", "loop.", "evaluation.settle_frames", "evaluation.wavelength_nm",
                                       "lgs.tt_jitter_arcsec", "recon.warm_start", "recon.predict",
                                       "recon.pcg3.iterations", "recon.pcg3.tolerance", "recon.pcg3.preconditioner",
                                       "recon.pcg3.coarse_levels", "recon.cg9.iterations", "recon.cg9.tolerance",
                                       "recon.cg9.preconditioner", "recon.cg9.coarse_levels",
                                       "recon.cg9.fit_iterations", "recon.cg9.fit_solver", "recon.cg9.fit_factor_precision",
                                       "recon.cg9.fit_kernels", "recon.pcg3.operator_precision",
                                       "recon.cg9.operator_precision",
                                       "recon.mvm_precision", "recon.fft_wisdom"};
    for (size_t i = 0; i < sizeof skip / sizeof *skip; i++)
        if (!strncmp(path, skip[i], strlen(skip[i]))) return 0;
    return 1;
diffractive: {
    const int k = wt_config_priv_find_key(path[0] == 'l' ? "lgs.wfs.model" : "ngs.wfs.model");
    const char *m = k >= 0 && ps->set[k] ? config_setting_get_string(ps->set[k]) : NULL;
    return m && !strcmp(m, "diffractive");
}
}

static int build_text(pstate *ps, int matrix_only, char **text)
{
    config_t out;
    char *buf = NULL;
    size_t len = 0;
    int st = WT_OK;
    config_init(&out);
    config_set_options(&out, CONFIG_OPTION_SEMICOLON_SEPARATORS);
    config_set_tab_width(&out, 2);
    for (int k = 0; k < WT_CONFIG_PRIV_NKEYS && st == WT_OK; k++) {
        const wt_config_priv_key_spec *ks = &wt_config_priv_keys[k];
        const config_setting_t *s = ps->set[k];
        if (!s || (matrix_only && !affects_matrix(ps, ks->path))) continue;
        const char *leaf;
        config_setting_t *g = wt_config_priv_ensure_parent(&out, ks->path, &leaf), *d = NULL;
        static const int ctype[] = {CONFIG_TYPE_INT, CONFIG_TYPE_INT64, CONFIG_TYPE_FLOAT, CONFIG_TYPE_BOOL,
                                    CONFIG_TYPE_STRING, CONFIG_TYPE_ARRAY, CONFIG_TYPE_ARRAY, CONFIG_TYPE_STRING};
        if (g) d = config_setting_add(g, leaf, ctype[ks->type]);
        if (!d) {
            st = WT_ERROR(ps->ctx, WT_ERR_NOMEM, "libconfig could not add '%s' to the canonical text", ks->path);
            break;
        }
        switch (ks->type) {
        case K_INT: config_setting_set_int(d, (int)config_setting_get_int64(s)); break;
        case K_INT64: config_setting_set_int64(d, config_setting_get_int64(s)); break;
        case K_FLOAT: config_setting_set_float(d, num(s)); break;
        case K_BOOL: config_setting_set_bool(d, config_setting_get_bool(s)); break;
        case K_ENUM:
        case K_STR: config_setting_set_string(d, config_setting_get_string(s)); break;
        default:
            for (int i = 0; i < config_setting_length(s); i++) {
                const config_setting_t *e = config_setting_get_elem(s, (unsigned)i);
                if (!(ks->type == K_INTS ? config_setting_set_int_elem(d, -1, (int)config_setting_get_int64(e))
                                         : config_setting_set_float_elem(d, -1, num(e))))
                    st = WT_ERROR(ps->ctx, WT_ERR_NOMEM, "libconfig could not add '%s' to the canonical text", ks->path);
            }
        }
    }
    FILE *f = st == WT_OK ? open_memstream(&buf, &len) : NULL;
    if (st == WT_OK && !f) st = WT_ERROR(ps->ctx, WT_ERR_NOMEM, "open_memstream failed for the canonical text");
    if (f) {
        config_write(&out, f);
        if (fclose(f) != 0 || !buf) st = WT_ERROR(ps->ctx, WT_ERR_NOMEM, "writing the canonical text failed");
    }
    config_destroy(&out);
    if (st == WT_OK) {
        *text = wt_malloc(ps->ctx, len + 1, 1);
        if (!*text) st = WT_ERROR(ps->ctx, WT_ERR_NOMEM, "out of memory for the canonical text (%zu bytes)", len + 1);
        else memcpy(*text, buf, len + 1);
    }
    free(buf); /* open_memstream's buffer comes from malloc, not from the context's allocator */
    return st;
}

static int build_canonical(pstate *ps, wt_config *cfg)
{
    int st = build_text(ps, 0, &cfg->canonical);
    if (st == WT_OK) st = build_text(ps, 1, &cfg->matrix_text);
    if (st == WT_OK) wt_sha256_hex(cfg->matrix_text, strlen(cfg->matrix_text), cfg->matrix_sha256);
    return st;
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
        st = WT_ERROR(ctx, WT_ERR_CONFIG, "%s: syntax error: %s%s", wt_config_priv_src_line(&ps, config_error_line(&cf), at, sizeof at),
                      e, syntax_hint(e));
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
    WT_ALLOC(ctx, cfg, 1, "the configuration");
    snprintf(cfg->path, sizeof cfg->path, "%s", ps.name);
    for (int k = 0; k < WT_CONFIG_PRIV_NKEYS; k++) WT_TRY(load_key(&ps, cfg, k));
    WT_TRY(check_consistency(&ps, cfg));
    WT_TRY(wt_config_priv_check_derived(ctx, cfg));
    WT_TRY(build_canonical(&ps, cfg));
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
