/* core/base/numbers.h: one line of a whitespace-separated number table in a text file (the atmosphere's
 * profile files, the night files, the sodium sequences), read the same way and refused with the same message.
 *
 * A line's text from '#' on is a comment; its fields are separated by white space (isspace), and each must be,
 * as a whole, a finite number that strtod reads within range. A refusal names the file, the line, the column
 * (and its name, when the caller gives names), the field as written and what the file holds. */
#ifndef WT_NUMBERS_H
#define WT_NUMBERS_H

#include "base.h"

/* Where a line stands and what its file holds, for the messages */
typedef struct wt_numbers_where {
    const char *path;         /* the file */
    int line;                 /* the line's number, from 1 */
    int column0;              /* the column of the text's first field: 1, or 2 after a leading word */
    const char *const *names; /* the names of columns 1..nnames (NULL: none) */
    int nnames;
    const char *expected;     /* ends every message: what the file holds, e.g. "(a night file: ...)" ("" for none) */
    int status;               /* returned for a field that is not a number (WT_ERR_CONFIG, WT_ERR_INVALID, ...) */
} wt_numbers_where;

/* The numbers of one line: returns their count (0: a blank or comment-only line), with them in (*v)[0..count),
 * *v grown with wt_malloc as needed (*cap its length; start with *v = NULL, *cap = 0; the caller frees it with
 * wt_free); or w->status with "PATH:LINE: column C (NAME): 'FIELD' is not a finite number EXPECTED", or
 * WT_ERR_NOMEM. The comment is cut from `text` and the text is left otherwise as it was. */
long wt_read_numbers(wt_context *ctx, char *text, const wt_numbers_where *w, double **v, long *cap);

#endif
