/* wavetomo/version.h: the library's version, at compile time (macros) and at run time (wt_version).
 *
 * Part of the public, stable interface (docs/c-api.md). The shared library's soname carries the major
 * version: libwavetomo.so.MAJOR. A program can compare the header it was compiled against with the
 * library it runs on:  strcmp(wt_version(), WT_VERSION_STRING) == 0, or the numbers.
 */
#ifndef WAVETOMO_VERSION_H
#define WAVETOMO_VERSION_H

#define WT_VERSION_MAJOR 0
#define WT_VERSION_MINOR 2
#define WT_VERSION_PATCH 0

/* "MAJOR.MINOR.PATCH", built from the three numbers above so that they cannot disagree */
#define WT_VERSION_STR_(x) #x
#define WT_VERSION_XSTR_(x) WT_VERSION_STR_(x)
#define WT_VERSION_STRING                                                                   \
    WT_VERSION_XSTR_(WT_VERSION_MAJOR) "." WT_VERSION_XSTR_(WT_VERSION_MINOR) "." WT_VERSION_XSTR_( \
        WT_VERSION_PATCH)
/* MAJOR * 10000 + MINOR * 100 + PATCH: for #if tests */
#define WT_VERSION_NUMBER (WT_VERSION_MAJOR * 10000 + WT_VERSION_MINOR * 100 + WT_VERSION_PATCH)

#ifdef __cplusplus
extern "C" {
#endif

/* The version of the library linked at run time: a static string "MAJOR.MINOR.PATCH" (never NULL). */
const char *wt_version(void);
/* The same as WT_VERSION_NUMBER, of the library linked at run time. */
int wt_version_number(void);

#ifdef __cplusplus
}
#endif

#endif
