/* core/base/names.h: the nearest name to a misspelt one, for "did you mean" in messages (configuration
 * keys, commands, options).
 *
 * Levenshtein distance (insertions, deletions, substitutions, each 1). A name is suggested when it is the
 * nearest and within max(2, len/4) edits of the word: close enough that the intent is clear, far enough to
 * catch a dropped or doubled letter and a transposition (2 edits). */
#ifndef WT_NAMES_H
#define WT_NAMES_H

#include <stddef.h>

/* The edit distance between a[0..na) and b[0..nb); INT_MAX when either is longer than 127. */
int wt_edit_distance(const char *a, size_t na, const char *b, size_t nb);

/* The index of the name in names[0..n) nearest to word within the threshold above, or −1. */
int wt_nearest_name(const char *word, const char *const *names, int n);

#endif
