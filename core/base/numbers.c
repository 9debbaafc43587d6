/* core/base/numbers.c: one line of a number table (numbers.h). */
#include "numbers.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* the first room for a line's numbers (doubled as needed): a night file of 9 layers has 29 columns */
#define WT_NUMBERS_CAP0 64

/* (*v)[n] = x, growing *v */
static int push(wt_context *ctx, const wt_numbers_where *w, double **v, long *cap, long n, double x)
{
    if (n == *cap) {
        const long nc = *cap ? 2 * *cap : WT_NUMBERS_CAP0;
        double *g = wt_malloc(ctx, (size_t)nc, sizeof *g);
        if (!g) return WT_ERROR(ctx, WT_ERR_NOMEM, "%s:%d: out of memory reading %ld numbers", w->path, w->line, nc);
        if (n) memcpy(g, *v, (size_t)n * sizeof *g);
        wt_free(ctx, *v);
        *v = g, *cap = nc;
    }
    (*v)[n] = x;
    return WT_OK;
}

long wt_read_numbers(wt_context *ctx, char *text, const wt_numbers_where *w, double **v, long *cap)
{
    char *hash = strchr(text, '#');
    if (hash) *hash = '\0';
    long n = 0;
    for (char *s = text;;) {
        while (isspace((unsigned char)*s)) s++;
        if (!*s) return n;
        char *e = s;
        while (*e && !isspace((unsigned char)*e)) e++;
        const char save = *e;
        *e = '\0'; /* the field alone: strtod must read all of it, and the message quotes it */
        char *end;
        errno = 0;
        const double x = strtod(s, &end);
        if (*end || end == s || !isfinite(x) || errno == ERANGE) {
            const long c = w->column0 + n;
            const int named = w->names && c >= 1 && c <= w->nnames;
            const int st = WT_ERROR(ctx, w->status, "%s:%d: column %ld%s%s%s: '%s' is not a finite number%s%s", w->path,
                                    w->line, c, named ? " (" : "", named ? w->names[c - 1] : "", named ? ")" : "", s,
                                    w->expected && *w->expected ? " " : "", w->expected ? w->expected : "");
            *e = save;
            return st;
        }
        *e = save;
        const int st = push(ctx, w, v, cap, n, x);
        if (st < 0) return st;
        n++;
        s = e;
    }
}
