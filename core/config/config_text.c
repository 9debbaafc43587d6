/* core/config/config_text.c: the configuration text as libconfig must see it (SPEC §1): @include expanded
 * here, and integer literals made exact.
 *
 * Why not let libconfig do both: libconfig 1.5 reads an integer literal without the L suffix with
 * atoi(), so 4294967317 silently becomes 21 (loop.frames) and a seed above 2^31 wraps; with the suffix it
 * uses atoll(), which clamps beyond 2^63. And its @include of a directory or of a missing file gives only
 * "cannot open include file" without saying which. So this pass scans the text the way libconfig's
 * scanner does (comments, strings, names, numbers) and
 *   - appends L to every decimal or hex integer literal outside the 32-bit range, so libconfig reads it
 *     as a 64-bit integer exactly and the typed reader refuses what does not fit its C type, naming
 *     the key;
 *   - rewrites a literal beyond the 64-bit range as a float literal of the same value, which the typed
 *     reader refuses for an integer key ("does not fit a 64-bit integer") and reads exactly for a float
 *     key;
 *   - replaces each `@include "file"` line by the file's text (recursively, depth <= 10, file names
 *     relative to the include directory as libconfig does), refusing an include that is missing, not a
 *     regular file or unreadable with FILE:LINE and the reason.
 * Line numbers of the expanded text map back to (file, line) through wt_config_priv_src.
 */
#include "config_private.h"

#include <ctype.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define MAX_DEPTH 10

typedef struct tbuf {
    wt_context *ctx;
    char *p;
    size_t n, cap;
} tbuf;

static int put(tbuf *b, const char *s, size_t n)
{
    if (b->n + n + 1 > b->cap) {
        size_t cap = b->cap ? b->cap : 4096;
        while (cap < b->n + n + 1) cap *= 2;
        char *q = wt_malloc(b->ctx, cap, 1);
        if (!q) return WT_ERROR(b->ctx, WT_ERR_NOMEM, "out of memory for the configuration text (%zu bytes)", cap);
        if (b->n) memcpy(q, b->p, b->n);
        wt_free(b->ctx, b->p);
        b->p = q;
        b->cap = cap;
    }
    memcpy(b->p + b->n, s, n);
    b->n += n;
    b->p[b->n] = '\0';
    return WT_OK;
}

static int lines_in(const char *s, size_t n)
{
    int c = 0;
    for (size_t i = 0; i < n; i++) c += s[i] == '\n';
    return c;
}

/* Record that expanded line `line` onward comes from file `file` at line `src_line`. */
static int map_add(wt_config_priv_text *t, int line, int file, int src_line)
{
    if (t->nmap == t->capmap) {
        int cap = t->capmap ? 2 * t->capmap : 16;
        wt_config_priv_linemap *m = wt_malloc(t->ctx, (size_t)cap, sizeof *m);
        if (!m) return WT_ERROR(t->ctx, WT_ERR_NOMEM, "out of memory for the configuration line map");
        if (t->nmap) memcpy(m, t->map, (size_t)t->nmap * sizeof *m);
        wt_free(t->ctx, t->map);
        t->map = m;
        t->capmap = cap;
    }
    t->map[t->nmap++] = (wt_config_priv_linemap){line, file, src_line};
    return WT_OK;
}

static int add_file(wt_config_priv_text *t, const char *name)
{
    if (t->nfiles == WT_CONFIG_PRIV_MAX_FILES)
        return WT_ERROR(t->ctx, WT_ERR_CONFIG, "%s: more than %d configuration files (@include)", name,
                        WT_CONFIG_PRIV_MAX_FILES);
    size_t l = strlen(name) + 1;
    char *c = wt_malloc(t->ctx, l, 1);
    if (!c) return WT_ERROR(t->ctx, WT_ERR_NOMEM, "out of memory for a file name");
    memcpy(c, name, l);
    t->files[t->nfiles] = c;
    return t->nfiles++;
}

/* One numeric literal at s[0..len): append it to b, exact for libconfig (see the file comment). */
static int put_number(tbuf *b, const char *s, size_t len, int force_wide)
{
    char lit[128], out[160];
    int hex = 0, suffix = 0;
    const size_t len0 = len;
    if (len >= sizeof lit) return put(b, s, len); /* libconfig will refuse or read it as a float */
    memcpy(lit, s, len);
    lit[len] = '\0';
    while (len > 0 && (lit[len - 1] == 'L' || lit[len - 1] == 'l')) lit[--len] = '\0', suffix = 1;
    const char *d = lit + (lit[0] == '+' || lit[0] == '-');
    if (d[0] == '0' && (d[1] == 'x' || d[1] == 'X')) hex = 1;
    else if (strpbrk(d, ".eE")) return put(b, s, len0); /* a float */
    if (!*d || strspn(d + 2 * hex, hex ? "0123456789abcdefABCDEF" : "0123456789") != strlen(d + 2 * hex))
        return put(b, s, len0); /* not a plain literal: libconfig's error */
    errno = 0;
    long long v = 0;
    int over = 0;
    if (hex) {
        unsigned long long u = strtoull(d, NULL, 16);
        over = errno == ERANGE || u > (unsigned long long)LLONG_MAX;
        v = over ? 0 : (long long)u;
        if (lit[0] == '-') v = -v;
    } else {
        v = strtoll(lit, NULL, 10);
        over = errno == ERANGE;
    }
    if (over) { /* beyond 64 bits: the same value as a float literal */
        double x = hex ? (double)strtoull(d, NULL, 16) : strtod(lit, NULL);
        if (hex && lit[0] == '-') x = -x;
        snprintf(out, sizeof out, "%.17g", x);
        if (!strpbrk(out, ".eEin")) strncat(out, ".0", sizeof out - strlen(out) - 1);
        return put(b, out, strlen(out));
    }
    /* libconfig reads a hex literal without L as 32 bits unsigned into an int: 0x80000000 and above wrap */
    int wide = force_wide || v > INT_MAX || v < INT_MIN;
    snprintf(out, sizeof out, "%s%s", lit, suffix || wide ? "L" : "");
    return put(b, out, strlen(out));
}

static int expand(wt_config_priv_text *t, tbuf *b, const char *text, int file, const char *incdir, int depth);

/* `@include "name"` at line (1-based) `line` of file `file`: the included text, expanded. */
static int include(wt_config_priv_text *t, tbuf *b, const char *name, int file, int line, const char *incdir,
                   int depth)
{
    char path[4096];
    struct stat sb;
    const char *inc = t->files[file];
    if (depth >= MAX_DEPTH)
        return WT_ERROR(t->ctx, WT_ERR_CONFIG, "%s:%d: @include \"%s\": includes nested deeper than %d (does a file "
                        "include itself?)", inc, line, name, MAX_DEPTH);
    if (name[0] != '/' && incdir && *incdir)
        snprintf(path, sizeof path, "%s%s%s", incdir, incdir[strlen(incdir) - 1] == '/' ? "" : "/", name);
    else snprintf(path, sizeof path, "%s", name);
    /* O_NONBLOCK: opening a FIFO without a writer would block for ever before fstat can refuse it (seen
     * while writing tests/fuzz/fuzz_config); it changes nothing for the regular files that are read */
    int fd = open(path, O_RDONLY | O_NONBLOCK);
    const char *why = NULL;
    if (fd < 0) why = strerror(errno);
    else if (fstat(fd, &sb) != 0) why = strerror(errno);
    else if (S_ISDIR(sb.st_mode)) why = "it is a directory, not a configuration file";
    else if (!S_ISREG(sb.st_mode)) why = "it is not a regular file";
    else if (sb.st_size > (1 << 24)) why = "it is larger than 16 MiB: not a configuration file";
    if (why) {
        if (fd >= 0) close(fd);
        return WT_ERROR(t->ctx, WT_ERR_CONFIG, "%s:%d: @include \"%s\": cannot read '%s': %s", inc, line, name, path, why);
    }
    size_t n = (size_t)sb.st_size, got = 0;
    char *txt = wt_malloc(t->ctx, n + 1, 1);
    int st = txt ? WT_OK : WT_ERROR(t->ctx, WT_ERR_NOMEM, "out of memory reading '%s'", path);
    while (st == WT_OK && got < n) {
        ssize_t r = read(fd, txt + got, n - got);
        if (r < 0 && errno == EINTR) continue;
        if (r <= 0) {
            st = WT_ERROR(t->ctx, WT_ERR_CONFIG, "%s:%d: @include \"%s\": cannot read '%s': %s", inc, line, name, path,
                          r < 0 ? strerror(errno) : "the file shrank while being read");
            break;
        }
        got += (size_t)r;
    }
    close(fd);
    if (st == WT_OK) {
        txt[n] = '\0';
        if (memchr(txt, '\0', n))
            st = WT_ERROR(t->ctx, WT_ERR_CONFIG, "%s:%d: @include \"%s\": '%s' holds a NUL byte: not a configuration "
                          "file", inc, line, name, path);
    }
    int f = st == WT_OK ? add_file(t, path) : st;
    if (f < 0) st = f;
    if (st == WT_OK) st = map_add(t, t->line, f, 1);
    if (st == WT_OK) st = expand(t, b, txt, f, incdir, depth + 1);
    wt_free(t->ctx, txt);
    return st;
}

static int is_name_start(int c) { return isalpha(c) || c == '*'; }
static int is_name_char(int c) { return isalnum(c) || c == '-' || c == '_' || c == '*'; }

enum { T_COMMENT, T_STRING, T_NAME, T_NUMBER, T_OTHER };

/* End of the token that starts at p (not at a newline), with its kind, as libconfig's scanner cuts it. */
static const char *token_end(const char *p, int *kind)
{
    if (*p == '#' || (p[0] == '/' && p[1] == '/')) {
        *kind = T_COMMENT;
        while (*p && *p != '\n') p++;
    } else if (p[0] == '/' && p[1] == '*') {
        *kind = T_COMMENT;
        const char *e = strstr(p + 2, "*/");
        p = e ? e + 2 : p + strlen(p);
    } else if (*p == '"') {
        *kind = T_STRING;
        for (p++; *p && *p != '"'; p++)
            if (*p == '\\' && p[1]) p++;
        if (*p == '"') p++;
    } else if (is_name_start((unsigned char)*p)) {
        *kind = T_NAME;
        while (is_name_char((unsigned char)*p)) p++;
    } else if (isdigit((unsigned char)*p) ||
               ((*p == '-' || *p == '+' || *p == '.') && (isdigit((unsigned char)p[1]) || p[1] == '.'))) {
        *kind = T_NUMBER;
        int hex = p[*p == '-' || *p == '+'] == '0' && (p[1 + (*p == '-' || *p == '+')] | 0x20) == 'x';
        p++;
        while (isalnum((unsigned char)*p) || *p == '.' || ((*p == '+' || *p == '-') && !hex && (p[-1] | 0x20) == 'e'))
            p++;
    } else {
        *kind = T_OTHER;
        p++;
    }
    return p;
}

/* An array [ ... ] holds one element type in libconfig: when one integer of it needs 64 bits, all of its
 * integers get the L (else "mismatched element type" for [17, 13, 4294967317]). */
static int array_is_wide(const char *p)
{
    for (p++; *p && *p != ']';) {
        int kind;
        const char *e = token_end(p, &kind);
        if (kind == T_NUMBER) {
            char lit[64];
            size_t n = (size_t)(e - p) < sizeof lit ? (size_t)(e - p) : sizeof lit - 1;
            memcpy(lit, p, n);
            lit[n] = '\0';
            if (!strpbrk(lit, ".eE") || ((lit[0] == '0' || lit[1] == '0') && strpbrk(lit, "xX"))) {
                if (strchr(lit, 'L') || strchr(lit, 'l')) return 1;
                errno = 0;
                int hex = strpbrk(lit, "xX") != NULL;
                long long v = hex ? (long long)strtoull(lit + (lit[0] == '-' || lit[0] == '+'), NULL, 16)
                                  : strtoll(lit, NULL, 10);
                if (errno == ERANGE || v > INT_MAX || v < INT_MIN) return 1;
            }
        }
        p = e;
    }
    return 0;
}

static int expand(wt_config_priv_text *t, tbuf *b, const char *text, int file, const char *incdir, int depth)
{
    const char *p = text;
    int line = 1, st, wide = 0;
    while (*p) {
        /* @include at the start of a line (after blanks), as libconfig's scanner matches it */
        const char *ls = p;
        while (*ls == ' ' || *ls == '\t') ls++;
        if ((p == text || p[-1] == '\n') && !strncmp(ls, "@include", 8) && (ls[8] == ' ' || ls[8] == '\t')) {
            const char *s = ls + 8;
            while (*s == ' ' || *s == '\t') s++;
            const char *e = *s == '"' ? strchr(s + 1, '"') : NULL;
            const char *eol = strchr(ls, '\n');
            if (!e || (eol && e > eol) || (size_t)(e - s - 1) >= 1024)
                return WT_ERROR(t->ctx, WT_ERR_CONFIG, "%s:%d: @include expects a quoted file name: @include \"file\"",
                                t->files[file], line);
            char name[1024];
            memcpy(name, s + 1, (size_t)(e - s - 1));
            name[e - s - 1] = '\0';
            if ((st = include(t, b, name, file, line, incdir, depth)) < 0) return st;
            /* the rest of the include line is dropped, as libconfig does; resume in this file */
            p = eol ? eol : e + 1 + strlen(e + 1);
            /* the included text may end without a newline: keep the rest on a line of its own */
            if (b->n && b->p[b->n - 1] != '\n') {
                if ((st = put(b, "\n", 1)) < 0) return st;
                t->line++;
            }
            if ((st = map_add(t, t->line, file, line)) < 0) return st;
            continue;
        }
        /* one line, token by token */
        while (*p && *p != '\n') {
            int kind;
            const char *q = p;
            p = token_end(q, &kind);
            if (kind == T_NUMBER) st = put_number(b, q, (size_t)(p - q), wide);
            else st = put(b, q, (size_t)(p - q));
            if (st < 0) return st;
            if (kind == T_OTHER && *q == '[') wide = array_is_wide(q);
            if (kind == T_OTHER && *q == ']') wide = 0;
            int nl = lines_in(q, (size_t)(p - q)); /* block comments and strings may span lines */
            line += nl, t->line += nl;
        }
        if (*p == '\n') {
            if ((st = put(b, "\n", 1)) < 0) return st;
            p++, line++, t->line++;
        }
    }
    return WT_OK;
}

int wt_config_priv_text_make(wt_context *ctx, const char *text, const char *name, const char *incdir,
                             wt_config_priv_text *t)
{
    memset(t, 0, sizeof *t);
    t->ctx = ctx;
    t->line = 1;
    tbuf b = {.ctx = ctx};
    int st = add_file(t, name);
    if (st >= 0) st = map_add(t, 1, 0, 1);
    if (st >= 0) st = put(&b, "", 0);
    if (st >= 0) st = expand(t, &b, text, 0, incdir, 0);
    if (st < 0) {
        wt_free(ctx, b.p);
        wt_config_priv_text_free(t);
        return st;
    }
    t->text = b.p;
    return WT_OK;
}

void wt_config_priv_text_free(wt_config_priv_text *t)
{
    if (!t->ctx) return;
    for (int i = 0; i < t->nfiles; i++) wt_free(t->ctx, t->files[i]);
    wt_free(t->ctx, t->map);
    wt_free(t->ctx, t->text);
    memset(t, 0, sizeof *t);
}

const char *wt_config_priv_src(const wt_config_priv_text *t, int line, int *src_line)
{
    int i = t->nmap - 1;
    while (i > 0 && t->map[i].line > line) i--;
    if (t->nmap == 0) {
        *src_line = line;
        return NULL;
    }
    *src_line = t->map[i].src_line + (line - t->map[i].line);
    return t->files[t->map[i].file];
}
