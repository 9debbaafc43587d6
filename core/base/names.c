/* core/base/names.c: edit distance and the nearest name (names.h). */
#include "names.h"

#include <limits.h>
#include <string.h>

int wt_edit_distance(const char *a, size_t na, const char *b, size_t nb)
{
    int row[128];
    if (na > 127 || nb > 127) return INT_MAX;
    for (size_t j = 0; j <= nb; j++) row[j] = (int)j;
    for (size_t i = 1; i <= na; i++) {
        int diag = row[0];
        row[0] = (int)i;
        for (size_t j = 1; j <= nb; j++) {
            int up = row[j], best = diag + (a[i - 1] != b[j - 1]);
            if (up + 1 < best) best = up + 1;
            if (row[j - 1] + 1 < best) best = row[j - 1] + 1;
            diag = up;
            row[j] = best;
        }
    }
    return row[nb];
}

int wt_nearest_name(const char *word, const char *const *names, int n)
{
    const size_t nw = strlen(word);
    int best = -1, bestd = INT_MAX;
    for (int k = 0; k < n; k++) {
        const int d = wt_edit_distance(word, nw, names[k], strlen(names[k]));
        if (d < bestd) bestd = d, best = k;
    }
    const int limit = nw / 4 > 2 ? (int)(nw / 4) : 2;
    return bestd <= limit ? best : -1;
}
