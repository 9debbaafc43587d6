/* core/io/h5_common.c: the HDF5 plumbing every other h5 file uses: HDF5's error stack folded into our
 * messages, element types, file and dataset properties, documented attributes, the checks of a new
 * dataset, and the writer's first-failure memory.
 *
 * The bottom of the h5 module: it calls no other h5 file, and they call it (h5_read.c: the reader;
 * h5_stream.c: row-block matrices and series; h5_write.c: the writer, which closes the matrices and series
 * still open at commit). Declared in h5_private.h.
 */
#include "h5_private.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>

/* ---- HDF5 error handling ------------------------------------------------------------------------ */

wt_h5_priv_quiet wt_h5_priv_quiet_on(void)
{
    wt_h5_priv_quiet q = {NULL, NULL};
    H5Eget_auto2(H5E_DEFAULT, &q.func, &q.data);
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
    return q;
}

void wt_h5_priv_quiet_off(wt_h5_priv_quiet q)
{
    H5Eclear2(H5E_DEFAULT);
    H5Eset_auto2(H5E_DEFAULT, q.func, q.data);
}

static herr_t walk_cb(unsigned n, const H5E_error2_t *e, void *user)
{
    if (n == 0 && e->desc) /* upward walk: n == 0 is where the failure was detected */
        snprintf((char *)user, 400, "%s: %s", e->func_name ? e->func_name : "?", e->desc);
    return 0;
}

int wt_h5_priv_error(wt_context *ctx, int status, const char *src, int line, const char *fmt, ...)
{
    char msg[1200], detail[400] = "";
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    H5Ewalk2(H5E_DEFAULT, H5E_WALK_UPWARD, walk_cb, detail);
    H5Eclear2(H5E_DEFAULT);
    if (detail[0]) return wt_error_set(ctx, status, src, line, "%s [HDF5 %s]", msg, detail);
    return wt_error_set(ctx, status, src, line, "%s", msg);
}

void wt_h5_priv_piece_link(wt_h5_writer *w, wt_h5_priv_piece *p)
{
    p->next = w->open;
    w->open = p;
}

void wt_h5_priv_piece_unlink(wt_h5_writer *w, wt_h5_priv_piece *p)
{
    for (wt_h5_priv_piece **q = &w->open; *q; q = &(*q)->next)
        if (*q == p) {
            *q = p->next;
            break;
        }
}

int wt_h5_priv_poison(wt_h5_writer *w, int st)
{
    if (st < 0 && w->status >= 0) {
        w->status = st;
        snprintf(w->first_error, sizeof w->first_error, "%s", wt_error_message(w->ctx));
    }
    return st;
}

void wt_h5_priv_drop(hid_t id)
{
    if (id < 0) return;
    switch (H5Iget_type(id)) {
    case H5I_FILE: H5Fclose(id); break;
    case H5I_GROUP: H5Gclose(id); break;
    case H5I_DATASET: H5Dclose(id); break;
    case H5I_DATASPACE: H5Sclose(id); break;
    case H5I_DATATYPE: H5Tclose(id); break;
    case H5I_ATTR: H5Aclose(id); break;
    case H5I_GENPROP_LST: H5Pclose(id); break;
    default: break;
    }
}

/* ---- types, names, files ------------------------------------------------------------------------ */

int wt_h5_priv_type_ok(int t) { return t >= WT_H5_F64 && t <= WT_H5_BF16; }
int wt_h5_priv_type_float(int t) { return t == WT_H5_F64 || t == WT_H5_F32; }
int wt_h5_priv_type_half(int t) { return t == WT_H5_F16 || t == WT_H5_BF16; }

/* fp16: sign bit 15, exponent bits 10-14 (bias 15), mantissa 0-9; bf16: exponent 7-14 (bias 127),
 * mantissa 0-6 — little-endian, as h5py defines float16. */
static hid_t half_type(int t)
{
    hid_t id = H5Tcopy(H5T_IEEE_F32LE);
    const int f16 = t == WT_H5_F16;
    if (id < 0) return -1;
    if (H5Tset_fields(id, 15, f16 ? 10 : 7, f16 ? 5 : 8, 0, f16 ? 10 : 7) < 0 || H5Tset_size(id, 2) < 0 ||
        H5Tset_ebias(id, f16 ? 15 : 127) < 0) {
        H5Tclose(id);
        return -1;
    }
    return id;
}

void wt_h5_priv_type_release(int t, hid_t id)
{
    if (wt_h5_priv_type_half(t) && id >= 0) H5Tclose(id);
}

const char *wt_h5_priv_type_name(int t)
{
    static const char *const names[] = {"?", "float64", "float32", "int32", "int64", "uint8", "float16", "bfloat16"};
    return wt_h5_priv_type_ok(t) ? names[t] : "?";
}

size_t wt_h5_priv_type_size(int t)
{
    static const size_t sizes[] = {0, 8, 4, 4, 8, 1, 2, 2};
    return wt_h5_priv_type_ok(t) ? sizes[t] : 0;
}

hid_t wt_h5_priv_mem_type(int t)
{
    switch (t) {
    case WT_H5_F64: return H5T_NATIVE_DOUBLE;
    case WT_H5_F32: return H5T_NATIVE_FLOAT;
    case WT_H5_I32: return H5T_NATIVE_INT32;
    case WT_H5_I64: return H5T_NATIVE_INT64;
    case WT_H5_U8: return H5T_NATIVE_UINT8;
    case WT_H5_F16:
    case WT_H5_BF16: return half_type(t);
    default: return -1;
    }
}

hid_t wt_h5_priv_file_type(int t)
{
    switch (t) {
    case WT_H5_F64: return H5T_IEEE_F64LE;
    case WT_H5_F32: return H5T_IEEE_F32LE;
    case WT_H5_I32: return H5T_STD_I32LE;
    case WT_H5_I64: return H5T_STD_I64LE;
    case WT_H5_U8: return H5T_STD_U8LE;
    case WT_H5_F16:
    case WT_H5_BF16: return half_type(t);
    default: return -1;
    }
}

char *wt_h5_priv_dupstr(wt_context *ctx, const char *s)
{
    size_t n = strlen(s);
    char *p = wt_malloc(ctx, n + 1, 1);
    if (p) memcpy(p, s, n + 1);
    return p;
}

/* 1 when every prefix of `name` is a link (so H5Lexists never sees a missing parent), else 0. */
int wt_h5_priv_path_exists(hid_t file, const char *name)
{
    char buf[1024];
    size_t n = strlen(name);
    if (strcmp(name, "/") == 0) return 1;
    if (n == 0 || n >= sizeof buf) return 0;
    memcpy(buf, name, n + 1);
    for (size_t i = 1; i <= n; i++) {
        if (buf[i] != '/' && buf[i] != '\0') continue;
        char c = buf[i];
        buf[i] = '\0';
        htri_t e = H5Lexists(file, buf, H5P_DEFAULT);
        buf[i] = c;
        if (e <= 0) {
            H5Eclear2(H5E_DEFAULT);
            return 0;
        }
    }
    return 1;
}

/* Chunk dims: start from the whole dataset and shrink the leading dims (at most `nshrink` of them)
 * until a chunk holds at most `target` bytes, so a chunk is a band of whole rows whenever a row fits
 * (series pass nshrink = 1: a frame is never split, whatever its size). */
static void choose_chunk(int rank, const hsize_t *dims, size_t elem, size_t target, int nshrink, hsize_t *chunk)
{
    for (int i = 0; i < rank; i++) chunk[i] = dims[i] > 0 ? dims[i] : 1;
    for (int i = 0; i < nshrink; i++) {
        hsize_t inner = elem;
        for (int j = i + 1; j < rank; j++) inner *= chunk[j];
        if (chunk[i] * inner <= target) break;
        hsize_t fit = target / inner;
        chunk[i] = fit > 0 ? fit : 1;
        if (inner <= target) break;
    }
}

/* Creation properties of a numeric dataset: chunked (see choose_chunk; `cdims` sizes the chunks) with
 * Fletcher32 when it holds data, contiguous when empty. Fill value 0 for partially written chunks. */
hid_t wt_h5_priv_numeric_dcpl(int rank, const hsize_t *cdims, size_t elem, size_t target, int nshrink, int empty,
                              hsize_t *chunk)
{
    hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
    if (dcpl < 0 || empty) return dcpl;
    const int zero = 0;
    choose_chunk(rank, cdims, elem, target, nshrink, chunk);
    if (H5Pset_chunk(dcpl, rank, chunk) < 0 || H5Pset_fletcher32(dcpl) < 0 ||
        H5Pset_fill_value(dcpl, H5T_NATIVE_INT, &zero) < 0) {
        H5Pclose(dcpl);
        return -1;
    }
    return dcpl;
}

/* Metadata in the 1.8+ format (checksummed headers), strong close, file locks where supported. */
hid_t wt_h5_priv_file_access(void)
{
    hid_t fapl = H5Pcreate(H5P_FILE_ACCESS);
    if (fapl < 0) return -1;
    if (H5Pset_libver_bounds(fapl, H5F_LIBVER_V18, H5F_LIBVER_LATEST) < 0 ||
        H5Pset_fclose_degree(fapl, H5F_CLOSE_STRONG) < 0 || H5Pset_file_locking(fapl, 1, 1) < 0) {
        H5Pclose(fapl);
        return -1;
    }
    return fapl;
}

hid_t wt_h5_priv_string_type(size_t len, H5T_cset_t cset)
{
    hid_t t = H5Tcopy(H5T_C_S1);
    if (t < 0) return -1;
    if (H5Tset_size(t, len + 1) < 0 || H5Tset_strpad(t, H5T_STR_NULLTERM) < 0 || H5Tset_cset(t, cset) < 0) {
        H5Tclose(t);
        return -1;
    }
    return t;
}

hid_t wt_h5_priv_vlen_string_type(void)
{
    hid_t t = H5Tcopy(H5T_C_S1);
    if (t < 0) return -1;
    if (H5Tset_size(t, H5T_VARIABLE) < 0 || H5Tset_cset(t, H5T_CSET_UTF8) < 0) {
        H5Tclose(t);
        return -1;
    }
    return t;
}

/* ---- attributes --------------------------------------------------------------------------------- */

/* Replace attribute `name` of obj by a scalar of file type ft holding *value of memory type mt. */
herr_t wt_h5_priv_put_attr(hid_t obj, const char *name, hid_t ft, hid_t mt, const void *value)
{
    hid_t space = -1, a = -1;
    herr_t r = -1;
    htri_t e = H5Aexists(obj, name);
    if (e < 0 || (e > 0 && H5Adelete(obj, name) < 0)) return -1;
    if ((space = H5Screate(H5S_SCALAR)) < 0) goto out;
    if ((a = H5Acreate2(obj, name, ft, space, H5P_DEFAULT, H5P_DEFAULT)) < 0) goto out;
    r = H5Awrite(a, mt, value);
out:
    wt_h5_priv_drop(a);
    wt_h5_priv_drop(space);
    return r;
}

herr_t wt_h5_priv_put_attr_string(hid_t obj, const char *name, const char *value)
{
    hid_t t = wt_h5_priv_vlen_string_type();
    if (t < 0) return -1;
    herr_t r = wt_h5_priv_put_attr(obj, name, t, t, &value);
    H5Tclose(t);
    return r;
}

int wt_h5_priv_check_new(wt_h5_writer *w, const char *name, const char *units, const char *desc, int need_units)
{
    if (!name || !*name) return WT_ERROR(w->ctx, WT_ERR_INVALID, "%s: empty dataset name", w->target);
    if ((need_units && !units) || !desc || !*desc)
        return WT_ERROR(w->ctx, WT_ERR_INVALID, "%s: dataset '%s' needs %s (every dataset documents itself)", w->target,
                        name, need_units && !units ? "units (\"\" if dimensionless)" : "a description");
    if (wt_h5_priv_path_exists(w->file, name))
        return WT_ERROR(w->ctx, WT_ERR_INVALID, "%s: '%s' already exists", w->target, name);
    return WT_OK;
}

int wt_h5_priv_check_types(wt_h5_writer *w, const char *name, int ft, int mt)
{
    if (!wt_h5_priv_type_ok(ft) || !wt_h5_priv_type_ok(mt))
        return WT_ERROR(w->ctx, WT_ERR_INVALID, "%s: dataset '%s': unknown element type %d", w->target, name,
                        wt_h5_priv_type_ok(ft) ? mt : ft);
    if (wt_h5_priv_type_float(mt) && !wt_h5_priv_type_float(ft))
        return WT_ERROR(w->ctx, WT_ERR_INVALID, "%s: dataset '%s': %s data refused for an %s dataset (lossy)",
                        w->target, name, wt_h5_priv_type_name(mt), wt_h5_priv_type_name(ft));
    /* 16-bit floats are stored as they are: the caller rounds (core/la/half.h), HDF5 never does */
    if ((wt_h5_priv_type_half(ft) || wt_h5_priv_type_half(mt)) && ft != mt)
        return WT_ERROR(w->ctx, WT_ERR_INVALID, "%s: dataset '%s': %s data for a %s dataset: 16-bit floats are written "
                        "only from the same type", w->target, name, wt_h5_priv_type_name(mt), wt_h5_priv_type_name(ft));
    return WT_OK;
}

int wt_h5_priv_set_doc(wt_h5_writer *w, hid_t obj, const char *name, const char *units, const char *desc)
{
    if ((units && wt_h5_priv_put_attr_string(obj, "units", units) < 0) || wt_h5_priv_put_attr_string(obj, "description", desc) < 0)
        return H5ERR(w->ctx, WT_ERR_IO, "%s: cannot write the units/description of '%s'", w->target, name);
    return WT_OK;
}
