/* core/config/config_state.c: the parse state's helpers (config_private.h): a key's index, where a setting
 * was given (FILE:LINE, an override), the error text, and the tree edits that write a chosen value into the
 * canonical text. Shared by config_read.c (reading, overrides, validation) and config_atmosphere.c (profile
 * files, the reconstructors' atmosphere), which call each other only through it. */
#include "config_private.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>

int wt_config_priv_find_key(const char *path)
{
    for (int k = 0; k < WT_CONFIG_PRIV_NKEYS; k++)
        if (!strcmp(wt_config_priv_keys[k].path, path)) return k;
    return -1;
}

int wt_config_key_doc(const char *path, const char **unit, const char **description)
{
    const int k = path ? wt_config_priv_find_key(path) : -1;
    if (unit) *unit = k >= 0 ? wt_config_priv_keys[k].unit : NULL;
    if (description) *description = k >= 0 ? wt_config_priv_keys[k].desc : NULL;
    return k >= 0 ? WT_OK : WT_ERR_INVALID;
}

int wt_config_priv_fail(wt_config_priv_state *ps, const char *loc, const char *fmt, ...)
{
    char msg[1536];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return WT_ERROR(ps->ctx, WT_ERR_CONFIG, "%s: %s", loc, msg);
}

/* "FILE:LINE" of line `line` of the text libconfig read (an included file names itself). */
const char *wt_config_priv_src_line(const wt_config_priv_state *ps, int line, char *buf, size_t n)
{
    int l = line;
    const char *f = ps->src ? wt_config_priv_src(ps->src, line, &l) : NULL;
    snprintf(buf, n, "%s:%d", f ? f : ps->name, l);
    return buf;
}

/* "FILE:LINE" of setting s of key k, "--set k=v" when an override set it, "FILE" when absent. */
const char *wt_config_priv_where(const wt_config_priv_state *ps, int k, const config_setting_t *s, char *buf, size_t n)
{
    if (k >= 0 && ps->ovidx[k] >= 0 && ps->ovidx[k] < ps->nfile_ov)
        snprintf(buf, n, "%s: overrides \"%s\"", ps->name, ps->ov[ps->ovidx[k]]);
    else if (k >= 0 && ps->ovidx[k] >= 0) snprintf(buf, n, "--set %s", ps->ov[ps->ovidx[k]]);
    else if (s && config_setting_source_line(s) > 0) wt_config_priv_src_line(ps, (int)config_setting_source_line(s), buf, n);
    else snprintf(buf, n, "%s", ps->name);
    return buf;
}

/* Creates the groups along path in cf (all but the last component); returns the parent group. */
config_setting_t *wt_config_priv_ensure_parent(config_t *cf, const char *path, const char **leaf)
{
    char part[128];
    config_setting_t *g = config_root_setting(cf);
    const char *p = path, *dot;
    while ((dot = strchr(p, '.'))) {
        size_t w = (size_t)(dot - p) < sizeof part ? (size_t)(dot - p) : sizeof part - 1;
        memcpy(part, p, w);
        part[w] = '\0';
        config_setting_t *m = config_setting_get_member(g, part);
        if (!m) m = config_setting_add(g, part, CONFIG_TYPE_GROUP);
        if (!m || !config_setting_is_group(m)) return NULL;
        g = m;
        p = dot + 1;
    }
    *leaf = p;
    return g;
}

/* Key k's list element i (or the scalar, i < 0): location text for the second key in a message. */
const char *wt_config_priv_where_elem(const wt_config_priv_state *ps, int k, int i, char *buf, size_t n)
{
    const config_setting_t *s = ps->set[k];
    if (s && i >= 0 && config_setting_length(s) > i) s = config_setting_get_elem(s, (unsigned)i);
    return wt_config_priv_where(ps, k, s, buf, n);
}

/* A chosen list written into the file's tree, as if given: it is then in the canonical text and the matrix
 * hash like any key (an MVM built on a chosen grid is refused when the choice would change). */
int wt_config_priv_write_list(wt_config_priv_state *ps, int k, const double *f, const int *iv, int n)
{
    const char *leaf;
    config_setting_t *g = wt_config_priv_ensure_parent(ps->cf, wt_config_priv_keys[k].path, &leaf), *d = NULL;
    if (g && config_setting_get_member(g, leaf)) config_setting_remove(g, leaf); /* the word "auto" */
    if (g) d = config_setting_add(g, leaf, CONFIG_TYPE_ARRAY);
    for (int i = 0; d && i < n; i++)
        if (!(f ? config_setting_set_float_elem(d, -1, f[i]) : config_setting_set_int_elem(d, -1, iv[i]))) d = NULL;
    if (!d)
        return WT_ERROR(ps->ctx, WT_ERR_NOMEM, "%s: libconfig could not add the chosen '%s'", ps->name,
                        wt_config_priv_keys[k].path);
    ps->set[k] = d;
    return WT_OK;
}
