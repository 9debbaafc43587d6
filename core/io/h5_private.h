/* core/io/h5_private.h: helpers shared by the HDF5 files: h5_common.c (the plumbing: errors, types,
 * properties, attributes, checks of a new dataset) is called by the reader (h5_read.c), the row-block
 * matrices and series (h5_stream.c) and the atomic writer (h5_write.c, which closes the matrices and series
 * still open at commit through a function pointer, wt_h5_priv_piece); calls go one way:
 * h5_common ← h5_write ← h5_stream, h5_common ← h5_read, h5_temp ← h5_write.
 *
 * Private to core/io/h5*.c: not installed and included by nothing else, so hdf5.h stays inside the
 * h5 module (SPEC §9 "HDF5 output"). Of the handle structs only the writer's is here (h5_write.c and
 * h5_stream.c both reach into it); each other one lives in the one file that uses it. Error convention
 * of all three files: every public call brackets its HDF5 calls with wt_h5_priv_quiet_on/off (HDF5's
 * automatic stack printing off inside, restored on return) and folds HDF5's innermost error
 * description into our message (H5ERR).
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

int wt_h5_priv_type_ok(int t);           /* t is one of WT_H5_F64..WT_H5_BF16 */
int wt_h5_priv_type_float(int t);        /* WT_H5_F64 or WT_H5_F32 */
int wt_h5_priv_type_half(int t);         /* WT_H5_F16 or WT_H5_BF16 */
const char *wt_h5_priv_type_name(int t); /* "float64", ..., "?" for an unknown t */
hid_t wt_h5_priv_mem_type(int t);        /* native HDF5 type of t, -1 for an unknown t */
size_t wt_h5_priv_type_size(int t);      /* bytes of an element of t, 0 for an unknown t */
hid_t wt_h5_priv_file_type(int t);       /* little-endian file type of t, -1 for an unknown t */
/* The two above return a new type id for the 16-bit floats: give every returned id back here. */
void wt_h5_priv_type_release(int t, hid_t id);

/* A copy of s through ctx's allocator; NULL when out of memory. */
char *wt_h5_priv_dupstr(wt_context *ctx, const char *s);

/* 1 when every prefix of `name` is a link (so H5Lexists never sees a missing parent), else 0. */
int wt_h5_priv_path_exists(hid_t file, const char *name);

/* File access properties of every file we create or open; -1 on failure. */
hid_t wt_h5_priv_file_access(void);

/* A fixed-length, NUL-terminated string type of `len` characters; -1 on failure. The readers' memory type
 * for a fixed-length string (files written before strings were variable-length, and other writers'). */
hid_t wt_h5_priv_string_type(size_t len, H5T_cset_t cset);
/* The type every string is written with: variable-length UTF-8, which h5py hands back as str (attributes;
 * datasets through .asstr(), docs/python.md) where a fixed-length one comes back as bytes; -1 on failure.
 * Its memory buffer is a `const char *` per element. */
hid_t wt_h5_priv_vlen_string_type(void);

#define WT_H5_PRIV_CHUNK_BYTES ((size_t)1 << 20) /* fixed-size datasets: ~1 MiB bands of rows */

/* Creation properties of a numeric dataset: chunks of at most `target` bytes cut from `cdims` by
 * shrinking at most its `nshrink` leading dims (dims returned in `chunk`), contiguous when empty; -1 on
 * failure. */
hid_t wt_h5_priv_numeric_dcpl(int rank, const hsize_t *cdims, size_t elem, size_t target, int nshrink, int empty,
                              hsize_t *chunk);

/* Replace attribute `name` of obj by a scalar of file type ft holding *value of memory type mt; < 0 on
 * failure. The string version stores a variable-length UTF-8 string. */
herr_t wt_h5_priv_put_attr(hid_t obj, const char *name, hid_t ft, hid_t mt, const void *value);
herr_t wt_h5_priv_put_attr_string(hid_t obj, const char *name, const char *value);

/* ---- the writer (h5_write.c) and its row-block matrices and series (h5_stream.c) ---------------------- */

/* A dataset written piece by piece (h5_stream.c's matrices and series), open in its writer until it is
 * closed or the writer commits/aborts. The writer knows only this header, so it closes what is open
 * through `close` without calling into h5_stream.c: calls go one way, h5_stream → h5_write → h5_common. */
typedef struct wt_h5_priv_piece {
    struct wt_h5_priv_piece *next;
    /* unlink from the writer, close (flushing cached chunks), free; check: refuse an unfinished piece */
    int (*close)(struct wt_h5_priv_piece *p, int check);
} wt_h5_priv_piece;

struct wt_h5_writer {
    wt_context *ctx;
    hid_t file, lcpl;
    char *target, *temp;
    int created; /* the temporary is ours to unlink */
    int temp_slot; /* its slot in the signal-time registry (h5_temp.c), -1 if none */
    int status;  /* first failure; commit refuses when < 0 */
    char first_error[512];
    wt_h5_priv_piece *open; /* matrices and series still open, closed by commit/abort */
};

/* h5_common.c: put p at the head of w's open pieces / take it out (no-op when absent). */
void wt_h5_priv_piece_link(wt_h5_writer *w, wt_h5_priv_piece *p);
void wt_h5_priv_piece_unlink(wt_h5_writer *w, wt_h5_priv_piece *p);

/* h5_temp.c: the temporaries unlinked on SIGINT/SIGTERM; register returns a slot (-1: table full). */
int wt_h5_priv_temp_register(const char *path);
void wt_h5_priv_temp_unregister(int slot);
/* Remove "TARGET.tmp-<pid>" files of processes that no longer exist. */
void wt_h5_priv_remove_stale(const char *target);

/* h5_common.c: remember st as the writer's first failure (with the context's message) when it is one; returns st. */
int wt_h5_priv_poison(wt_h5_writer *w, int st);

/* Body of the public writer calls: quiet HDF5 around the work; the writer remembers its first failure. */
#define WRITER_CALL(handle, writer, expr)       \
    do {                                        \
        int st;                                 \
        if (!(handle)) return WT_ERR_INVALID;   \
        QUIET(expr);                            \
        return wt_h5_priv_poison((writer), st); \
    } while (0)

/* h5_common.c: a new numeric dataset's name and documentation (units required when need_units). */
int wt_h5_priv_check_new(wt_h5_writer *w, const char *name, const char *units, const char *desc, int need_units);
/* Known element types, and no float data into an integer dataset. */
int wt_h5_priv_check_types(wt_h5_writer *w, const char *name, int ft, int mt);
/* The units (when not NULL) and description attributes of obj. */
int wt_h5_priv_set_doc(wt_h5_writer *w, hid_t obj, const char *name, const char *units, const char *desc);

#endif
