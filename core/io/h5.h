/* core/io/h5.h: HDF5 files for results, telemetry and the MVM control matrix (SPEC §9 "HDF5 output").
 *
 * The only module that includes hdf5.h. Two opaque handles:
 *  - wt_h5_writer builds a file atomically: everything goes to "TARGET.tmp-<pid>"; wt_h5_commit writes
 *    the root attribute "complete" = 1 last, closes, fsyncs and rename()s onto TARGET; wt_h5_abort
 *    (and every failed commit) closes and unlinks the temporary. An interrupted run therefore never
 *    leaves a file at TARGET, and a copy of a temporary is refused by the reader (no "complete").
 *    Once any call on a writer fails, commit refuses: a file that misses something the caller meant
 *    to write is never published.
 *  - wt_h5_reader opens a committed file read-only and refuses a missing, non-HDF5, truncated or
 *    uncommitted file, a dataset of the wrong shape, and data whose checksum fails.
 *
 * Layout choices (why):
 *  - every non-empty numeric array (rank >= 1) is chunked with the Fletcher32 filter, so a corrupted
 *    byte of R is an error on reading rather than a wrong command (scalars and strings are stored
 *    plainly: their headers are checksummed, their bytes are not); chunks are bands of whole
 *    rows of about 1 MiB (R at the E-ELT size: 4 rows of 61356); appendable series chunk by whole
 *    frames, as many as fit in 64 KiB (at least one: a 61356-slope frame is one chunk), because the
 *    last chunk is allocated in full;
 *  - metadata uses the HDF5 1.8+ format, whose object headers and superblock carry checksums, and a
 *    file shorter than its recorded end of file is refused at open;
 *  - every numeric dataset carries string attributes "units" and "description" (required arguments);
 *    string datasets carry "description". The root group gets "creator" and "hdf5_version".
 *
 * Storage order: HDF5 is row-major (C order). A dataset of shape (rows, cols) read into memory is a
 * row-major rows x cols array, i.e. a column-major cols x rows matrix. R (n_act x n_slopes) is stored
 * with shape (n_act, n_slopes) and written by blocks of rows (one row per actuator, as the builder
 * solves for them).
 *
 * Names are paths relative to the root ("R", "eval/strehl_le"); writers create missing intermediate
 * groups. Messages name the file (the target path for writers), the dataset and what was expected.
 * HDF5's own error printing is switched off during every call here and restored on return; its
 * innermost error description is appended to our message. Handles must be used from one thread at
 * a time.
 */
#ifndef WT_H5_H
#define WT_H5_H

#include "../base/base.h"

#define WT_H5_MAX_RANK 4

/* Element types, for the file and for memory. Reading accepts only conversions that are exact for every
 * value of the file's type (float32 -> float32/float64, float64 -> float64, integers into a type that holds
 * them exactly); the rest (int32 slopes as float32, a float64 matrix as float32, float -> integer) is
 * refused naming the dataset and its type. Float data read is checked for NaN/Inf, and a dataset whose
 * stored bytes cannot hold its extent is refused (see h5_read.c). */
enum { WT_H5_F64 = 1, WT_H5_F32 = 2, WT_H5_I32 = 3, WT_H5_I64 = 4, WT_H5_U8 = 5 };
/* 16-bit floats (the MVM's storage precision, core/la/half.h): IEEE binary16 (h5py reads it as numpy
 * float16) and bfloat16 (an HDF5 float type with float32's 8-bit exponent and a 7-bit mantissa). In
 * memory they are the raw 16-bit patterns (uint16_t); a file dataset is read as one of these only when
 * its type is exactly that one, and its values are checked for Inf/NaN like other floats. */
enum { WT_H5_F16 = 6, WT_H5_BF16 = 7 };

typedef struct wt_h5_writer wt_h5_writer;
typedef struct wt_h5_reader wt_h5_reader;
typedef struct wt_h5_matrix wt_h5_matrix; /* a 2-D dataset written by blocks of rows */
typedef struct wt_h5_series wt_h5_series; /* a dataset that grows by one frame per append */

/* Call first in a program's main, before any other HDF5 use (h5_temp.c):
 *  - turns off HDF5's exit-time clean-up, which crashes (HDF5 1.10.8) on a file whose metadata flush
 *    failed on a full disk (a long-running process that hits that case keeps its memory until exit);
 *  - installs SIGINT/SIGTERM/SIGHUP handlers that unlink the temporaries of the writers still open, then
 *    die of the signal as before (signals the caller ignores stay ignored).
 * Every wt_h5_create also removes "TARGET.tmp-<pid>" files left by processes that no longer exist. */
void wt_h5_process_init(void);
/* on = 1: the first SIGINT/SIGTERM/SIGHUP after this is only recorded (a second one acts as usual);
 * wt_interrupt_pending returns its number (0: none). on = 0: back to the default, the record cleared. */
void wt_interrupt_defer(int on);
int wt_interrupt_pending(void);

/* Before writing `path`: WT_OK when it does not exist, is a wavetomo output (an HDF5 file whose root
 * attribute "creator" starts with "wavetomo"), or force is set; else WT_ERR_IO naming it: a file that is
 * not ours (a configuration, someone's data, a symbolic link) is never replaced without --force. */
int wt_h5_check_replaceable(wt_context *ctx, const char *path, int force);

/* "1.10.8": the HDF5 version this was built against (the library refuses to run with another). */
const char *wt_h5_library_version(void);

/* Before a long run: refuse (WT_ERR_IO, naming the path) when the directory of `path` is missing, not
 * a directory or not writable, when `path` is a directory, or when fewer than `bytes` bytes are free
 * there (bytes <= 0: no space check). Creates and removes a probe file "PATH.probe-<pid>". */
int wt_h5_check_writable(wt_context *ctx, const char *path, int64_t bytes);

/* ---- writing ------------------------------------------------------------------------------------ */

/* Start writing `path` (through its temporary). [out] *out, freed by commit or abort. */
int wt_h5_create(wt_context *ctx, const char *path, wt_h5_writer **out);
/* Close any matrix/series still open (a matrix must have had all its rows written), write
 * "complete" = 1, close, fsync, rename onto the target. Frees w in every case; on failure the
 * temporary is removed and nothing appears at the target. */
int wt_h5_commit(wt_h5_writer *w);
/* Drop everything: close, unlink the temporary, free w and its open matrices/series. NULL is fine. */
void wt_h5_abort(wt_h5_writer *w);
/* Flush the temporary to disk (it stays uncommitted). */
int wt_h5_flush(wt_h5_writer *w);
/* The temporary file being written ("TARGET.tmp-<pid>") and the target. */
const char *wt_h5_temp_path(const wt_h5_writer *w);
const char *wt_h5_target_path(const wt_h5_writer *w);

/* Create a group (and missing parents). Existing groups are fine. */
int wt_h5_group(wt_h5_writer *w, const char *name);

/* A numeric dataset of rank 1..WT_H5_MAX_RANK with dims[0..rank-1] >= 0 (row-major), stored as
 * file_type, converted from `data` of mem_type (float -> integer refused). units: "" for
 * dimensionless; description: non-empty. The name must not exist yet. */
int wt_h5_write(wt_h5_writer *w, const char *name, int file_type, int mem_type, int rank,
                const int64_t *dims, const void *data, const char *units, const char *description);
/* Scalar datasets. */
int wt_h5_write_double(wt_h5_writer *w, const char *name, double value, const char *units,
                       const char *description);
int wt_h5_write_int64(wt_h5_writer *w, const char *name, int64_t value, const char *units,
                      const char *description);
/* A string dataset (e.g. the whole configuration text), UTF-8, any length. */
int wt_h5_write_string(wt_h5_writer *w, const char *name, const char *text, const char *description);

/* Scalar attributes on an existing object: obj = "/" (root), a group or a dataset. An existing
 * attribute of that name is replaced. "complete" on the root is reserved for commit. */
int wt_h5_attr_write_string(wt_h5_writer *w, const char *obj, const char *name, const char *value);
int wt_h5_attr_write_double(wt_h5_writer *w, const char *obj, const char *name, double value);
int wt_h5_attr_write_int64(wt_h5_writer *w, const char *obj, const char *name, int64_t value);

/* A rows x cols dataset written by blocks of whole rows without holding it in memory (the MVM
 * matrices). Blocks may come in any order and may overlap; commit (or close) refuses a matrix with
 * rows never written. Blocks whose row0 and nrows are multiples of the chunk height (about 1 MiB
 * worth of rows, e.g. 4 rows of 61356 float32) avoid re-reading chunks. [out] *out, owned by w. */
int wt_h5_matrix_create(wt_h5_writer *w, const char *name, int file_type, int64_t rows, int64_t cols,
                        const char *units, const char *description, wt_h5_matrix **out);
/* Rows [row0, row0 + nrows) from `data`: a row-major nrows x cols array of mem_type. */
int wt_h5_matrix_write_rows(wt_h5_matrix *m, int64_t row0, int64_t nrows, int mem_type, const void *data);
/* Optional early close (frees m). Rows never written: WT_ERR_INVALID, and the writer will not commit.
 * NULL is fine. */
int wt_h5_matrix_close(wt_h5_matrix *m);

/* An appendable series: n >= 1 gives a (frames x n) dataset, n == 0 a 1-D dataset of one value per
 * frame. The first dimension is unlimited; chunks hold whole frames. [out] *out, owned by w. */
int wt_h5_series_create(wt_h5_writer *w, const char *name, int file_type, int64_t n, const char *units,
                        const char *description, wt_h5_series **out);
/* The same for frames of rank 1..WT_H5_MAX_RANK-1 and dims[0..rank-1] (row-major): a (frames, dims...) dataset;
 * frames of rank >= 2 are chunked by slices of their first dimension (a map of a stack per chunk). */
int wt_h5_series_create_shaped(wt_h5_writer *w, const char *name, int file_type, int rank, const int64_t *dims,
                               const char *units, const char *description, wt_h5_series **out);
/* Append one frame: n values (1 if n == 0) of mem_type. */
int wt_h5_series_append(wt_h5_series *s, int mem_type, const void *data);
/* Frames appended so far. */
int64_t wt_h5_series_length(const wt_h5_series *s);
/* Optional early close (frees s). NULL is fine. */
int wt_h5_series_close(wt_h5_series *s);

/* ---- reading ------------------------------------------------------------------------------------ */

/* Open a committed file. WT_ERR_IO: missing or unreadable; WT_ERR_FORMAT: not HDF5, truncated,
 * corrupt metadata, or no root attribute "complete" = 1. [out] *out, freed by wt_h5_close. */
int wt_h5_open(wt_context *ctx, const char *path, wt_h5_reader **out);
/* The same checks on a file held in memory (`size` bytes at `image`, copied; `name` stands for the file in
 * messages): the fuzz targets of tests/fuzz read HDF5 bytes without touching the disk. An image whose
 * first 8 bytes are not the HDF5 signature is refused (a user block is not supported here). */
int wt_h5_open_image(wt_context *ctx, const char *name, const void *image, size_t size, wt_h5_reader **out);
void wt_h5_close(wt_h5_reader *r);
const char *wt_h5_path(const wt_h5_reader *r);

/* 1 when `name` is a dataset or group of the file (every intermediate group existing), else 0. */
int wt_h5_exists(wt_h5_reader *r, const char *name);
/* [out] *rank (0 for a scalar) and dims[0..rank-1]; dims holds WT_H5_MAX_RANK entries. */
int wt_h5_dims(wt_h5_reader *r, const char *name, int *rank, int64_t *dims);
/* Refuse (WT_ERR_FORMAT) unless the dataset has this rank and, where expect[i] >= 0, these dims
 * (expect[i] = -1: any): "FILE: dataset 'R' has shape 9295 x 61356, expected 9295 x 61357".
 * [out] dims (may be NULL): the actual dims. */
int wt_h5_check_shape(wt_h5_reader *r, const char *name, int rank, const int64_t *expect, int64_t *dims);
/* Whole numeric dataset, shape-checked as above, converted to mem_type into `data`, which holds
 * `capacity` elements (more elements than that: WT_ERR_INVALID). A checksum failure is WT_ERR_FORMAT. */
int wt_h5_read(wt_h5_reader *r, const char *name, int mem_type, int rank, const int64_t *expect,
               int64_t *dims, void *data, size_t capacity);
/* Rows [row0, row0 + nrows) along the first dimension of a dataset of rank >= 1 (frames of a series,
 * row blocks of a matrix), as a row-major array of mem_type: nrows * (product of the other dims). */
int wt_h5_read_rows(wt_h5_reader *r, const char *name, int mem_type, int64_t row0, int64_t nrows, void *data);
/* Scalar (or one-element) numeric datasets. */
int wt_h5_read_double(wt_h5_reader *r, const char *name, double *value);
int wt_h5_read_int64(wt_h5_reader *r, const char *name, int64_t *value);
/* A string dataset (fixed or variable length). [out] *text, allocated through the context: wt_free. */
int wt_h5_read_string(wt_h5_reader *r, const char *name, char **text);

/* Attributes of obj ("/" for the root). Strings are allocated through the context: wt_free. */
/* 1 when object obj ("/" for the root) exists and has an attribute `name`, else 0. */
int wt_h5_attr_exists(wt_h5_reader *r, const char *obj, const char *name);
int wt_h5_attr_read_string(wt_h5_reader *r, const char *obj, const char *name, char **value);
int wt_h5_attr_read_double(wt_h5_reader *r, const char *obj, const char *name, double *value);
int wt_h5_attr_read_int64(wt_h5_reader *r, const char *obj, const char *name, int64_t *value);

#endif
