/* core/io/h5_read.c: the checked HDF5 reader: open, shapes, whole datasets, row blocks, scalars, attributes.
 *
 * Implements the reading side of SPEC §9: a file is accepted only when it is HDF5, opens whole and
 * carries the root attribute "complete" = 1 that only a writer's commit (h5_write.c) sets, so a truncated
 * file or a copied temporary is refused; every dataset is checked against the shape and element type
 * the caller expects, and a Fletcher32 checksum failure is an error rather than a wrong number.
 * HDF5's printing is off during every call (wt_h5_priv_quiet_on/off, see h5_private.h).
 *
 * Bad-input policy (G: types, H: values, I: extents):
 *  - G: a numeric read accepts only a conversion that is exact for every value of the file's type:
 *    float32 -> float32/float64, float64 -> float64, an integer into a float whose mantissa holds it
 *    (up to 24 bits into float32, 32 into float64), an integer into an integer type that holds its whole
 *    range. The rest (int32 slopes read as float32, a float64 matrix read as float32, any float into an
 *    integer, non-IEEE sizes) is refused naming the dataset and the type found;
 *  - H: every float array read is scanned once for NaN/Inf, naming the dataset and the first bad
 *    element (row and column for a matrix or a series: the row is the frame);
 *  - I: a dataset whose stored bytes cannot hold its extent (a header that claims 10^9 frames; unwritten
 *    chunks would read back as zeros) is refused by the shape check, before anyone allocates for it.
 */
#include "h5_private.h"

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

struct wt_h5_reader {
    wt_context *ctx;
    hid_t file;
    char *path;
};

/* Body of the public reader calls: quiet HDF5 around the work. */
#define READER_CALL(r, expr)             \
    do {                                 \
        int st;                          \
        if (!(r)) return WT_ERR_INVALID; \
        QUIET(expr);                     \
        return st;                       \
    } while (0)

/* ---- values and shapes -------------------------------------------------------------------------- */

/* "9295 x 61356", "any" for a negative entry, "a scalar" for rank 0. */
static const char *shape_text(char *buf, size_t n, int rank, const int64_t *d)
{
    size_t k = 0;
    buf[0] = '\0';
    if (rank == 0) return snprintf(buf, n, "a scalar"), buf;
    for (int i = 0; i < rank && k < n; i++) {
        const char *sep = i ? " x " : "";
        if (!d || d[i] < 0)
            k += (size_t)snprintf(buf + k, n - k, "%sany", sep);
        else
            k += (size_t)snprintf(buf + k, n - k, "%s%lld", sep, (long long)d[i]);
    }
    return buf;
}

/* Read a one-element string from a dataset or attribute, fixed or variable length. */
static int get_string(wt_context *ctx, const char *file, const char *what, hid_t obj, int is_attr, char **out)
{
    int st = WT_OK;
    hid_t ft = -1, mt = -1, space = -1;
    char *buf = NULL, *vl = NULL;
    ft = is_attr ? H5Aget_type(obj) : H5Dget_type(obj);
    space = is_attr ? H5Aget_space(obj) : H5Dget_space(obj);
    if (ft < 0 || space < 0) H5FAIL(ctx, WT_ERR_FORMAT, "%s: cannot read the type of %s", file, what);
    if (H5Tget_class(ft) != H5T_STRING || H5Sget_simple_extent_npoints(space) != 1)
        FAIL(ctx, WT_ERR_FORMAT, "%s: %s is not a single string", file, what);
    int var = H5Tis_variable_str(ft) > 0;
    size_t size = var ? 0 : H5Tget_size(ft);
    /* I: the declared length is allocated below; a header may declare gigabytes that the file does not
     * store (an unwritten 2^31-byte string in a 1.5 KB file, seen while writing tests/fuzz/fuzz_h5_recipe) */
    hsize_t stored = var ? 0 : is_attr ? H5Aget_storage_size(obj) : H5Dget_storage_size(obj);
    if (!var && size > stored)
        FAIL(ctx, WT_ERR_FORMAT, "%s: %s declares a string of %zu bytes but the file stores %llu bytes of it", file,
             what, size, (unsigned long long)stored);
    if ((mt = wt_h5_priv_string_type(size, H5Tget_cset(ft))) < 0 || (var && H5Tset_size(mt, H5T_VARIABLE) < 0))
        H5FAIL(ctx, WT_ERR_LIBRARY, "%s: cannot make a string type for %s", file, what);
    void *dst = var ? (void *)&vl : NULL;
    if (!var) {
        WT_ALLOC(ctx, buf, size + 1, "a string read from HDF5");
        dst = buf;
    }
    herr_t r = is_attr ? H5Aread(obj, mt, dst) : H5Dread(obj, mt, H5S_ALL, H5S_ALL, H5P_DEFAULT, dst);
    if (r < 0) H5FAIL(ctx, WT_ERR_FORMAT, "%s: reading %s failed (%s)", file, what, is_attr ? "H5Aread" : "H5Dread");
    if (var) {
        WT_ALLOC(ctx, buf, (vl ? strlen(vl) : 0) + 1, "a string read from HDF5");
        if (vl) strcpy(buf, vl);
    }
    *out = buf;
    buf = NULL;
fail:
    if (vl) H5Dvlen_reclaim(mt, space, H5P_DEFAULT, &vl);
    wt_free(ctx, buf);
    wt_h5_priv_drop(mt);
    wt_h5_priv_drop(ft);
    wt_h5_priv_drop(space);
    return st;
}

/* Read one numeric value (scalar or one element) from a dataset or attribute as type t. */
static int get_number(wt_context *ctx, const char *file, const char *what, hid_t obj, int is_attr, int t, void *value)
{
    int st = WT_OK;
    hid_t ft = is_attr ? H5Aget_type(obj) : H5Dget_type(obj);
    hid_t space = is_attr ? H5Aget_space(obj) : H5Dget_space(obj);
    if (ft < 0 || space < 0) H5FAIL(ctx, WT_ERR_FORMAT, "%s: cannot read the type of %s", file, what);
    H5T_class_t c = H5Tget_class(ft);
    hssize_t np = H5Sget_simple_extent_npoints(space);
    if ((c != H5T_FLOAT && c != H5T_INTEGER) || np != 1)
        FAIL(ctx, WT_ERR_FORMAT, "%s: %s holds %lld %s value(s), expected one number", file, what, (long long)np,
             c == H5T_STRING ? "string" : c == H5T_FLOAT ? "float" : c == H5T_INTEGER ? "integer" : "non-numeric");
    if (c == H5T_FLOAT && !wt_h5_priv_type_float(t))
        FAIL(ctx, WT_ERR_FORMAT, "%s: %s is floating point, refused as %s", file, what, wt_h5_priv_type_name(t));
    if (wt_h5_priv_type_half(t)) FAIL(ctx, WT_ERR_INVALID, "%s: %s: single values are not read as 16-bit floats", file, what);
    if ((is_attr ? H5Aread(obj, wt_h5_priv_mem_type(t), value)
                 : H5Dread(obj, wt_h5_priv_mem_type(t), H5S_ALL, H5S_ALL, H5P_DEFAULT, value)) < 0)
        H5FAIL(ctx, WT_ERR_FORMAT, "%s: reading %s failed", file, what);
fail:
    wt_h5_priv_drop(ft);
    wt_h5_priv_drop(space);
    return st;
}

/* ---- reader ------------------------------------------------------------------------------------- */

static int read_one(wt_h5_reader *r, const char *obj, const char *name, int t, void *value);

/* The part of opening shared by a path and a memory image: H5Fopen with `fapl`, then "complete" = 1. */
static int open_with(wt_context *ctx, const char *name, const char *fname, hid_t fapl, wt_h5_reader **out)
{
    int st = WT_OK;
    wt_h5_reader *r = NULL;
    int64_t complete = 0;
    WT_ALLOC(ctx, r, 1, "an HDF5 reader");
    r->ctx = ctx;
    r->file = -1;
    if (!(r->path = wt_h5_priv_dupstr(ctx, name)))
        FAIL(ctx, WT_ERR_NOMEM, "out of memory for the file name '%s'", name);
    if ((r->file = H5Fopen(fname, H5F_ACC_RDONLY, fapl)) < 0)
        H5FAIL(ctx, WT_ERR_FORMAT, "%s: cannot open as HDF5, the file is truncated or corrupt (H5Fopen)", name);
    if (H5Aexists(r->file, "complete") <= 0)
        FAIL(ctx, WT_ERR_FORMAT, "%s: incomplete file: no root attribute 'complete' (its writer never committed "
             "it: an interrupted run or a copied temporary)", name);
    WT_TRY(read_one(r, "/", "complete", WT_H5_I64, &complete));
    if (complete != 1)
        FAIL(ctx, WT_ERR_FORMAT, "%s: incomplete file: root attribute 'complete' is %lld, expected 1", name,
             (long long)complete);
    *out = r;
    return WT_OK;
fail:
    wt_h5_close(r);
    return st;
}

static int open_impl(wt_context *ctx, const char *path, wt_h5_reader **out)
{
    int st = WT_OK;
    hid_t fapl = -1;
    struct stat sb;
    if (!out) return WT_ERROR(ctx, WT_ERR_INVALID, "wt_h5_open: out is NULL");
    *out = NULL;
    if (!path || !*path) return WT_ERROR(ctx, WT_ERR_INVALID, "wt_h5_open: empty file name");
    if (stat(path, &sb) != 0) return WT_ERROR(ctx, WT_ERR_IO, "cannot open '%s': %s", path, strerror(errno));
    if (S_ISDIR(sb.st_mode)) return WT_ERROR(ctx, WT_ERR_IO, "cannot open '%s': it is a directory", path);
    if (access(path, R_OK) != 0) return WT_ERROR(ctx, WT_ERR_IO, "cannot read '%s': %s", path, strerror(errno));
    if (H5Fis_hdf5(path) <= 0)
        return WT_ERROR(ctx, WT_ERR_FORMAT, "%s: not an HDF5 file (no HDF5 signature; %lld bytes)", path,
                        (long long)sb.st_size);
    if ((fapl = wt_h5_priv_file_access()) < 0)
        H5FAIL(ctx, WT_ERR_LIBRARY, "%s: cannot set up file access properties", path);
    st = open_with(ctx, path, path, fapl, out);
fail:
    wt_h5_priv_drop(fapl);
    return st;
}

/* A memory image through the core driver, without a backing store (nothing is read from or written to
 * disk; HDF5 works on its own copy of the bytes). */
static int open_image_impl(wt_context *ctx, const char *name, const void *image, size_t size, wt_h5_reader **out)
{
    int st = WT_OK;
    hid_t fapl = -1;
    if (!out) return WT_ERROR(ctx, WT_ERR_INVALID, "wt_h5_open_image: out is NULL");
    *out = NULL;
    if (!name || !*name) return WT_ERROR(ctx, WT_ERR_INVALID, "wt_h5_open_image: empty name");
    if (!image || size < 8 || memcmp(image, "\211HDF\r\n\032\n", 8) != 0)
        return WT_ERROR(ctx, WT_ERR_FORMAT, "%s: not an HDF5 file (no HDF5 signature; %zu bytes)", name, size);
    if ((fapl = wt_h5_priv_file_access()) < 0 || H5Pset_fapl_core(fapl, 1 << 16, 0) < 0 ||
        H5Pset_file_image(fapl, (void *)(uintptr_t)image, size) < 0)
        H5FAIL(ctx, WT_ERR_LIBRARY, "%s: cannot set up file access properties for a memory image", name);
    st = open_with(ctx, name, name, fapl, out);
fail:
    wt_h5_priv_drop(fapl);
    return st;
}

int wt_h5_open_image(wt_context *ctx, const char *name, const void *image, size_t size, wt_h5_reader **out)
{
    int st;
    QUIET(open_image_impl(ctx, name, image, size, out));
    return st;
}

int wt_h5_open(wt_context *ctx, const char *path, wt_h5_reader **out)
{
    int st;
    QUIET(open_impl(ctx, path, out));
    return st;
}

void wt_h5_close(wt_h5_reader *r)
{
    if (!r) return;
    wt_h5_priv_quiet q = wt_h5_priv_quiet_on();
    wt_h5_priv_drop(r->file);
    wt_h5_priv_quiet_off(q);
    wt_free(r->ctx, r->path);
    wt_free(r->ctx, r);
}

const char *wt_h5_path(const wt_h5_reader *r) { return r ? r->path : NULL; }

int wt_h5_exists(wt_h5_reader *r, const char *name)
{
    if (!r || !name) return 0;
    wt_h5_priv_quiet q = wt_h5_priv_quiet_on();
    int e = wt_h5_priv_path_exists(r->file, name);
    wt_h5_priv_quiet_off(q);
    return e;
}

int wt_h5_attr_exists(wt_h5_reader *r, const char *obj, const char *name)
{
    if (!r || !obj || !name) return 0;
    wt_h5_priv_quiet q = wt_h5_priv_quiet_on();
    int e = (!strcmp(obj, "/") || wt_h5_priv_path_exists(r->file, obj)) &&
            H5Aexists_by_name(r->file, obj, name, H5P_DEFAULT) > 0;
    wt_h5_priv_quiet_off(q);
    return e;
}

/* Open dataset `name`; [out] its rank and dims. */
static int open_dataset(wt_h5_reader *r, const char *name, hid_t *dset, int *rank, int64_t *dims)
{
    hid_t d = -1, space = -1;
    int st = WT_OK;
    *dset = -1;
    if (!name || !wt_h5_priv_path_exists(r->file, name))
        return WT_ERROR(r->ctx, WT_ERR_FORMAT, "%s: no dataset '%s'", r->path, name ? name : "(null)");
    if ((d = H5Dopen2(r->file, name, H5P_DEFAULT)) < 0 || (space = H5Dget_space(d)) < 0)
        H5FAIL(r->ctx, WT_ERR_FORMAT, "%s: '%s' is not a readable dataset (H5Dopen2)", r->path, name);
    int nd = H5Sget_simple_extent_ndims(space);
    hsize_t hd[WT_H5_MAX_RANK];
    if (nd < 0 || nd > WT_H5_MAX_RANK)
        FAIL(r->ctx, WT_ERR_FORMAT, "%s: dataset '%s' has rank %d, at most %d is supported", r->path, name, nd,
             WT_H5_MAX_RANK);
    H5Sget_simple_extent_dims(space, hd, NULL);
    *rank = nd;
    for (int i = 0; i < nd; i++) dims[i] = (int64_t)hd[i];
    *dset = d;
    d = -1;
fail:
    wt_h5_priv_drop(space);
    wt_h5_priv_drop(d);
    return st;
}

int wt_h5_dims(wt_h5_reader *r, const char *name, int *rank, int64_t *dims)
{
    int st, s2;
    hid_t d = -1;
    if (!r) return WT_ERR_INVALID;
    if (!rank || !dims) return WT_ERROR(r->ctx, WT_ERR_INVALID, "wt_h5_dims: rank or dims is NULL");
    QUIET((s2 = open_dataset(r, name, &d, rank, dims), wt_h5_priv_drop(d), s2));
    return st;
}

/* I: a numeric dataset stores at least the bytes its extent claims (a header that claims 10^9 frames is
 * refused before anyone allocates for them; unwritten chunks would read back as zeros), and no more than
 * the file holds (a chunk index claiming a 3.5 GB chunk in a 13 kB file made HDF5 allocate 3.5 GB for it:
 * tests/fuzz/fuzz_mvm). */
static int check_stored(wt_h5_reader *r, const char *name, hid_t d)
{
    hid_t ft = H5Dget_type(d), space = H5Dget_space(d);
    H5T_class_t c = ft < 0 ? H5T_NO_CLASS : H5Tget_class(ft);
    int st = WT_OK;
    if (c == H5T_FLOAT || c == H5T_INTEGER) {
        hssize_t np = space < 0 ? -1 : H5Sget_simple_extent_npoints(space);
        double need = (double)np * (double)H5Tget_size(ft), have = (double)H5Dget_storage_size(d);
        if (np < 0)
            st = WT_ERROR(r->ctx, WT_ERR_FORMAT, "%s: dataset '%s': cannot read its extent", r->path, name);
        else if (have < need)
            st = WT_ERROR(r->ctx, WT_ERR_FORMAT,
                          "%s: dataset '%s' claims %lld elements (%.0f bytes) but the file stores %.0f bytes of it: "
                          "a header edited or a write cut short (unwritten parts would read as zeros)",
                          r->path, name, (long long)np, need, have);
        else {
            hsize_t fsize = 0;
            if (H5Fget_filesize(r->file, &fsize) < 0 || have > (double)fsize)
                st = WT_ERROR(r->ctx, WT_ERR_FORMAT, "%s: dataset '%s' claims to store %.0f bytes in a file of %.0f "
                              "bytes: a corrupt chunk index", r->path, name, have, (double)fsize);
        }
    }
    wt_h5_priv_drop(space);
    wt_h5_priv_drop(ft);
    return st;
}

static int shape_impl(wt_h5_reader *r, const char *name, hid_t *dset, int rank, const int64_t *expect, int64_t *dims)
{
    int nd = 0, st;
    int64_t got[WT_H5_MAX_RANK] = {0};
    char a[128], b[128];
    if ((st = open_dataset(r, name, dset, &nd, got)) < 0) return st;
    int ok = nd == rank;
    for (int i = 0; ok && i < rank; i++) ok = !expect || expect[i] < 0 || expect[i] == got[i];
    if (!ok) {
        wt_h5_priv_drop(*dset);
        *dset = -1;
        return WT_ERROR(r->ctx, WT_ERR_FORMAT, "%s: dataset '%s' has shape %s, expected %s", r->path, name,
                        shape_text(a, sizeof a, nd, got), shape_text(b, sizeof b, rank, expect));
    }
    if ((st = check_stored(r, name, *dset)) < 0) {
        wt_h5_priv_drop(*dset);
        *dset = -1;
        return st;
    }
    if (dims)
        for (int i = 0; i < rank; i++) dims[i] = got[i];
    return WT_OK;
}

int wt_h5_check_shape(wt_h5_reader *r, const char *name, int rank, const int64_t *expect, int64_t *dims)
{
    int st, s2;
    hid_t d = -1;
    if (!r) return WT_ERR_INVALID;
    QUIET((s2 = shape_impl(r, name, &d, rank, expect, dims), wt_h5_priv_drop(d), s2));
    return st;
}

/* "float32", "int16", "uint64", "float16", "a string", ...: the file type as a user would name it. */
static const char *file_type_text(hid_t ft, char *buf, size_t n)
{
    H5T_class_t c = ft < 0 ? H5T_NO_CLASS : H5Tget_class(ft);
    size_t bits = ft < 0 ? 0 : 8 * H5Tget_size(ft);
    if (c == H5T_FLOAT && bits == 16 && H5Tget_ebias(ft) == 127) snprintf(buf, n, "bfloat16");
    else if (c == H5T_FLOAT) snprintf(buf, n, "float%zu", bits);
    else if (c == H5T_INTEGER) snprintf(buf, n, "%sint%zu", H5Tget_sign(ft) == H5T_SGN_NONE ? "u" : "", bits);
    else if (c == H5T_STRING) snprintf(buf, n, "a string");
    else snprintf(buf, n, "HDF5 type class %d", (int)c);
    return buf;
}

/* The conversions accepted (G in the file comment): exact for every value of the file type. */
static int exact_conversion(hid_t ft, int mt)
{
    H5T_class_t c = H5Tget_class(ft);
    size_t fs = H5Tget_size(ft), ms = wt_h5_priv_type_size(mt);
    int fsigned = c == H5T_INTEGER && H5Tget_sign(ft) != H5T_SGN_NONE;
    if (wt_h5_priv_type_half(mt)) {
        /* the stored bits as they are: the file type must be exactly this 16-bit float */
        hid_t t = wt_h5_priv_mem_type(mt);
        int same = t >= 0 && H5Tequal(ft, t) > 0;
        wt_h5_priv_type_release(mt, t);
        return same;
    }
    if (c == H5T_FLOAT) return (fs == 4 || fs == 8) && wt_h5_priv_type_float(mt) && fs <= ms;
    if (c != H5T_INTEGER) return 0;
    size_t bits = 8 * fs - (size_t)fsigned; /* magnitude bits */
    if (mt == WT_H5_F32) return bits <= 24;
    if (mt == WT_H5_F64) return bits <= 53;
    if (mt == WT_H5_U8) return !fsigned && fs == 1;
    /* signed memory types: an unsigned file type needs one more bit */
    return fsigned ? fs <= ms : fs < ms;
}

/* Numbers only, with an exact conversion. */
static int check_readable(wt_h5_reader *r, const char *name, hid_t d, int mt)
{
    char tn[64];
    if (!wt_h5_priv_type_ok(mt))
        return WT_ERROR(r->ctx, WT_ERR_INVALID, "%s: dataset '%s': unknown memory type %d", r->path, name, mt);
    hid_t ft = H5Dget_type(d), space = -1;
    H5T_class_t c = ft < 0 ? H5T_NO_CLASS : H5Tget_class(ft);
    int st = WT_OK;
    if (c != H5T_FLOAT && c != H5T_INTEGER)
        st = WT_ERROR(r->ctx, WT_ERR_FORMAT, "%s: dataset '%s' holds %s, not numbers", r->path, name,
                      file_type_text(ft, tn, sizeof tn));
    else if (!exact_conversion(ft, mt))
        st = WT_ERROR(r->ctx, WT_ERR_FORMAT,
                      "%s: dataset '%s' is %s, refused as %s: the conversion is not exact for every value (accepted: "
                      "float32 or float64 for float64, float32 for float32, float16 and bfloat16 only as themselves, "
                      "integers that the memory type holds exactly)", r->path, name, file_type_text(ft, tn, sizeof tn), wt_h5_priv_type_name(mt));
    wt_h5_priv_drop(space);
    wt_h5_priv_drop(ft);
    return st;
}

/* H: the first NaN/Inf of n values of type mt read from dataset `name`, whose rows hold `cols` values
 * each (cols = 0: a vector) and whose first row is row0. */
static int check_finite(wt_h5_reader *r, const char *name, int mt, const void *data, int64_t n, int64_t cols,
                        int64_t row0)
{
    if (!wt_h5_priv_type_float(mt) && !wt_h5_priv_type_half(mt)) return WT_OK;
    for (int64_t i = 0; i < n; i++) {
        double v;
        if (wt_h5_priv_type_half(mt)) {
            /* all-ones exponent: bits 10-14 of fp16, 7-14 of bf16; a NaN has mantissa bits too */
            const uint16_t h = ((const uint16_t *)data)[i], e = mt == WT_H5_F16 ? 0x7c00 : 0x7f80;
            v = (h & e) != e ? 0.0 : (h & (uint16_t)(0x7fff & ~e)) ? NAN : INFINITY;
        } else {
            v = mt == WT_H5_F32 ? (double)((const float *)data)[i] : ((const double *)data)[i];
        }
        if (isfinite(v)) continue;
        const char *what = isnan(v) ? "NaN" : "Inf";
        if (cols > 0)
            return WT_ERROR(r->ctx, WT_ERR_NUMERIC,
                            "%s: dataset '%s' holds %s at row %lld (frame %lld of a time series), column %lld",
                            r->path, name, what, (long long)(row0 + i / cols), (long long)(row0 + i / cols),
                            (long long)(i % cols));
        return WT_ERROR(r->ctx, WT_ERR_NUMERIC, "%s: dataset '%s' holds %s at element %lld", r->path, name, what,
                        (long long)i);
    }
    return WT_OK;
}

/* Elements of dims[from..nd): 0 when any of them is 0, UINT64_MAX when the product passes INT64_MAX (a
 * file's claim that no buffer can hold; wrapping would let it pass a capacity check). */
static uint64_t elements(int from, int nd, const int64_t *dims)
{
    for (int i = from; i < nd; i++)
        if (dims[i] == 0) return 0;
    uint64_t n = 1;
    for (int i = from; i < nd; i++) {
        if ((uint64_t)dims[i] > (uint64_t)INT64_MAX / n) return UINT64_MAX;
        n *= (uint64_t)dims[i];
    }
    return n;
}

static int read_impl(wt_h5_reader *r, const char *name, int mt, int rank, const int64_t *expect, int64_t *dims,
                     void *data, size_t capacity)
{
    int st;
    hid_t d = -1, mtid = -1;
    int64_t got[WT_H5_MAX_RANK] = {0};
    WT_TRY(shape_impl(r, name, &d, rank, expect, got));
    WT_TRY(check_readable(r, name, d, mt));
    const uint64_t total = elements(0, rank, got);
    if (total > capacity || (total > 0 && !data))
        FAIL(r->ctx, WT_ERR_INVALID, "%s: dataset '%s' has %llu elements, the buffer holds %zu", r->path, name,
             (unsigned long long)total, data ? capacity : 0);
    if (total > 0 && ((mtid = wt_h5_priv_mem_type(mt)) < 0 || H5Dread(d, mtid, H5S_ALL, H5S_ALL, H5P_DEFAULT, data) < 0))
        H5FAIL(r->ctx, WT_ERR_FORMAT, "%s: reading dataset '%s' failed: corrupt data (checksum) or truncated file "
               "(H5Dread)", r->path, name);
    WT_TRY(check_finite(r, name, mt, data, (int64_t)total, rank >= 2 && got[0] > 0 ? (int64_t)(total / (uint64_t)got[0]) : 0, 0));
    if (dims)
        for (int i = 0; i < rank; i++) dims[i] = got[i];
fail:
    wt_h5_priv_drop(d);
    wt_h5_priv_type_release(mt, mtid);
    return st;
}

int wt_h5_read(wt_h5_reader *r, const char *name, int mem_type, int rank, const int64_t *expect, int64_t *dims,
               void *data, size_t capacity)
{
    READER_CALL(r, read_impl(r, name, mem_type, rank, expect, dims, data, capacity));
}

static int read_rows_impl(wt_h5_reader *r, const char *name, int mt, int64_t row0, int64_t nrows, void *data)
{
    int st, nd = 0;
    hid_t d = -1, fs = -1, ms = -1, mtid = -1;
    int64_t got[WT_H5_MAX_RANK] = {0};
    hsize_t start[WT_H5_MAX_RANK] = {0}, count[WT_H5_MAX_RANK];
    WT_TRY(open_dataset(r, name, &d, &nd, got));
    WT_TRY(check_readable(r, name, d, mt));
    WT_TRY(check_stored(r, name, d));
    if (nd < 1 || !data || row0 < 0 || nrows < 1 || row0 > got[0] - nrows)
        FAIL(r->ctx, WT_ERR_INVALID, "%s: dataset '%s' has %lld rows, rows %lld..%lld requested", r->path, name,
             nd < 1 ? 0LL : (long long)got[0], (long long)row0, (long long)(row0 + nrows - 1));
    const uint64_t cols = elements(1, nd, got);
    if (cols > (uint64_t)INT64_MAX / (uint64_t)nrows)
        FAIL(r->ctx, WT_ERR_FORMAT, "%s: dataset '%s' claims rows of %s elements: more than any buffer holds", r->path,
             name, cols == UINT64_MAX ? "over 2^63" : "too many");
    start[0] = (hsize_t)row0;
    count[0] = (hsize_t)nrows;
    for (int i = 1; i < nd; i++) count[i] = (hsize_t)got[i];
    /* memory space of the selection's own shape: a flat one sends HDF5 down a ~30x slower path */
    if ((fs = H5Dget_space(d)) < 0 || H5Sselect_hyperslab(fs, H5S_SELECT_SET, start, NULL, count, NULL) < 0 ||
        (ms = H5Screate_simple(nd, count, NULL)) < 0 || (mtid = wt_h5_priv_mem_type(mt)) < 0)
        H5FAIL(r->ctx, WT_ERR_LIBRARY, "%s: dataset '%s': cannot select rows", r->path, name);
    if (H5Dread(d, mtid, ms, fs, H5P_DEFAULT, data) < 0)
        H5FAIL(r->ctx, WT_ERR_FORMAT, "%s: reading rows %lld..%lld of dataset '%s' failed: corrupt data (checksum) "
               "or truncated file (H5Dread)", r->path, (long long)row0, (long long)(row0 + nrows - 1), name);
    WT_TRY(check_finite(r, name, mt, data, nrows * (int64_t)cols, (int64_t)cols, row0));
fail:
    wt_h5_priv_drop(ms);
    wt_h5_priv_drop(fs);
    wt_h5_priv_drop(d);
    wt_h5_priv_type_release(mt, mtid);
    return st;
}

int wt_h5_read_rows(wt_h5_reader *r, const char *name, int mem_type, int64_t row0, int64_t nrows, void *data)
{
    READER_CALL(r, read_rows_impl(r, name, mem_type, row0, nrows, data));
}

/* One value or a string from dataset `name` (obj == NULL) or from attribute `name` of `obj`. */
static int read_one(wt_h5_reader *r, const char *obj, const char *name, int t, void *value)
{
    int st = WT_OK, nd;
    hid_t o = -1, a = -1;
    int64_t dims[WT_H5_MAX_RANK];
    char what[512];
    if (!name || !value) return WT_ERROR(r->ctx, WT_ERR_INVALID, "%s: NULL name or output", r->path);
    if (!obj) {
        snprintf(what, sizeof what, "dataset '%s'", name);
        WT_TRY(open_dataset(r, name, &o, &nd, dims));
    } else {
        snprintf(what, sizeof what, "attribute '%s' of '%s'", name, obj);
        if (!wt_h5_priv_path_exists(r->file, obj) || (o = H5Oopen(r->file, obj, H5P_DEFAULT)) < 0)
            FAIL(r->ctx, WT_ERR_FORMAT, "%s: no group or dataset '%s' (looking for its attribute '%s')", r->path, obj,
                 name);
        if (H5Aexists(o, name) <= 0 || (a = H5Aopen(o, name, H5P_DEFAULT)) < 0)
            FAIL(r->ctx, WT_ERR_FORMAT, "%s: '%s' has no attribute '%s'", r->path, obj, name);
    }
    hid_t src = obj ? a : o;
    st = t ? get_number(r->ctx, r->path, what, src, obj != NULL, t, value)
           : get_string(r->ctx, r->path, what, src, obj != NULL, value);
fail:
    wt_h5_priv_drop(a);
    wt_h5_priv_drop(o);
    return st;
}

int wt_h5_read_double(wt_h5_reader *r, const char *name, double *value)
{
    READER_CALL(r, read_one(r, NULL, name, WT_H5_F64, value));
}
int wt_h5_read_int64(wt_h5_reader *r, const char *name, int64_t *value)
{
    READER_CALL(r, read_one(r, NULL, name, WT_H5_I64, value));
}
int wt_h5_read_string(wt_h5_reader *r, const char *name, char **text)
{
    READER_CALL(r, read_one(r, NULL, name, 0, text));
}

int wt_h5_attr_read_string(wt_h5_reader *r, const char *obj, const char *name, char **value)
{
    READER_CALL(r, read_one(r, obj ? obj : "/", name, 0, value));
}

int wt_h5_attr_read_double(wt_h5_reader *r, const char *obj, const char *name, double *value)
{
    READER_CALL(r, read_one(r, obj ? obj : "/", name, WT_H5_F64, value));
}

int wt_h5_attr_read_int64(wt_h5_reader *r, const char *obj, const char *name, int64_t *value)
{
    READER_CALL(r, read_one(r, obj ? obj : "/", name, WT_H5_I64, value));
}

