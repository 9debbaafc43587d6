/* core/io/h5_private.h: helpers shared by the HDF5 writer (h5.c) and reader (h5_read.c).
 *
 * Private to core/io/h5*.c: not installed and included by nothing else, so hdf5.h stays inside the
 * h5 module (SPEC §9 "HDF5 output"). The handle structs are not here: each lives in the one file that
 * uses it. Error convention of both files: every public call brackets its HDF5 calls with
 * wt_h5_priv_quiet_on/off (HDF5's automatic stack printing off inside, restored on return) and folds
 * HDF5's innermost error description into our message (H5ERR).
 */
#ifndef WT_H5_PRIVATE_H
#define WT_H5_PRIVATE_H

#include "h5.h"

#include <hdf5.h>

/* ---- HDF5 error handling ------------------------------------------------------------------------ */

/* HDF5's automatic error printer, saved by quiet_on and put back by quiet_off. */
typedef struct wt_h5_priv_quiet {
    H5E_auto2_t func;
    void *data;
} wt_h5_priv_quiet;

wt_h5_priv_quiet wt_h5_priv_quiet_on(void);
void wt_h5_priv_quiet_off(wt_h5_priv_quiet q);

/* st = expr with HDF5's printing off (needs an `int st`). */
#define QUIET(expr)                                  \
    do {                                             \
        wt_h5_priv_quiet q_ = wt_h5_priv_quiet_on(); \
        st = (expr);                                 \
        wt_h5_priv_quiet_off(q_);                    \
    } while (0)

/* Record `status` with our message plus HDF5's innermost description, then clear HDF5's stack. */
int wt_h5_priv_error(wt_context *ctx, int status, const char *src, int line, const char *fmt, ...)
    __attribute__((format(printf, 5, 6)));
#define H5ERR(ctx, status, ...) wt_h5_priv_error((ctx), (status), __FILE__, __LINE__, __VA_ARGS__)

/* Record an error and jump to the function's `fail` label (needs an `int st`); H5FAIL adds HDF5's detail. */
#define FAIL(ctx, status, ...)                       \
    do {                                             \
        st = WT_ERROR((ctx), (status), __VA_ARGS__); \
        goto fail;                                   \
    } while (0)
#define H5FAIL(ctx, status, ...)                  \
    do {                                          \
        st = H5ERR((ctx), (status), __VA_ARGS__); \
        goto fail;                                \
    } while (0)

/* Close any HDF5 id we created; ignores invalid ids (cleanup paths). */
void wt_h5_priv_drop(hid_t id);

/* ---- types, names, files ------------------------------------------------------------------------ */

int wt_h5_priv_type_ok(int t);           /* t is one of WT_H5_F64..WT_H5_U8 */
int wt_h5_priv_type_float(int t);        /* WT_H5_F64 or WT_H5_F32 */
const char *wt_h5_priv_type_name(int t); /* "float64", ..., "?" for an unknown t */
hid_t wt_h5_priv_mem_type(int t);        /* native HDF5 type of t, -1 for an unknown t */

/* A copy of s through ctx's allocator; NULL when out of memory. */
char *wt_h5_priv_dupstr(wt_context *ctx, const char *s);

/* 1 when every prefix of `name` is a link (so H5Lexists never sees a missing parent), else 0. */
int wt_h5_priv_path_exists(hid_t file, const char *name);

/* File access properties of every file we create or open; -1 on failure. */
hid_t wt_h5_priv_file_access(void);

/* A fixed-length, NUL-terminated string type of `len` characters; -1 on failure. */
hid_t wt_h5_priv_string_type(size_t len, H5T_cset_t cset);

#endif
