/* core/io/h5_stream.c: the HDF5 datasets written piece by piece through the atomic writer of h5_write.c
 * (registered in it as wt_h5_priv_piece, which it closes at commit/abort without calling this file):
 * row-block matrices (R and RÂ of SPEC §9, written a block of rows at a time, a matrix with unwritten
 * rows refused at commit) and appendable series (the simulator's telemetry, one frame per call).
 * Same conventions as h5_write.c (h5_private.h): every public call is a WRITER_CALL, so HDF5 is quiet
 * inside and the writer remembers its first failure.
 */
#include "h5_private.h"

#define SERIES_CHUNK_BYTES ((size_t)1 << 16) /* series: the last chunk is allocated whole, keep it small */
#define PROBE_FRAMES ((hsize_t)1 << 24)      /* stands for "many frames" when sizing series chunks */

struct wt_h5_matrix {
    wt_h5_priv_piece piece; /* first: the writer's handle on it */
    wt_h5_writer *w;
    hid_t dset;
    char *name;
    int64_t rows, cols, ndone;
    uint8_t *done; /* rows written: commit refuses a matrix with holes */
};

struct wt_h5_series {
    wt_h5_priv_piece piece; /* first: the writer's handle on it */
    wt_h5_writer *w;
    hid_t dset;
    char *name;
    int64_t n, len;            /* values per frame, frames appended */
    int frank;                 /* rank of a frame (0: one value) */
    hsize_t fdims[WT_H5_MAX_RANK]; /* its dims */
};

static int matrix_close(wt_h5_matrix *m, int check);
static int series_close(wt_h5_series *s);
static int matrix_piece_close(wt_h5_priv_piece *p, int check) { return matrix_close((wt_h5_matrix *)p, check); }
static int series_piece_close(wt_h5_priv_piece *p, int check)
{
    (void)check; /* a series is complete at any length */
    return series_close((wt_h5_series *)p);
}

/* Float data into an integer dataset loses the fraction silently in HDF5: refuse it. */
static int check_data(wt_h5_writer *w, const char *name, hid_t dset, int mt, const void *data)
{
    if (!wt_h5_priv_type_ok(mt) || !data)
        return WT_ERROR(w->ctx, WT_ERR_INVALID, "%s: dataset '%s': unknown type %d or NULL data", w->target, name, mt);
    hid_t ft = H5Dget_type(dset);
    int file_float = ft >= 0 && H5Tget_class(ft) == H5T_FLOAT;
    int file_half = file_float && H5Tget_size(ft) == 2, same = 0;
    if (wt_h5_priv_type_half(mt)) {
        hid_t t = wt_h5_priv_mem_type(mt);
        same = t >= 0 && H5Tequal(ft, t) > 0;
        wt_h5_priv_type_release(mt, t);
    }
    wt_h5_priv_drop(ft);
    if (wt_h5_priv_type_float(mt) && !file_float)
        return WT_ERROR(w->ctx, WT_ERR_INVALID, "%s: dataset '%s': %s data refused for an integer dataset (lossy)",
                        w->target, name, wt_h5_priv_type_name(mt));
    if ((file_half || wt_h5_priv_type_half(mt)) && !same)
        return WT_ERROR(w->ctx, WT_ERR_INVALID, "%s: dataset '%s': %s data refused: a 16-bit float dataset is written "
                        "only from its own type", w->target, name, wt_h5_priv_type_name(mt));
    return WT_OK;
}

/* ---- row-block matrices ------------------------------------------------------------------------- */

static int matrix_create_impl(wt_h5_writer *w, const char *name, int ft, int64_t rows, int64_t cols, const char *units,
                              const char *desc, wt_h5_matrix **out)
{
    int st = WT_OK;
    wt_h5_matrix *m = NULL;
    hid_t space = -1, dcpl = -1, dapl = -1, ftid = -1;
    hsize_t hd[2] = {(hsize_t)rows, (hsize_t)cols}, chunk[2];
    if (!out) return WT_ERROR(w->ctx, WT_ERR_INVALID, "%s: wt_h5_matrix_create: out is NULL", w->target);
    *out = NULL;
    WT_TRY(wt_h5_priv_check_new(w, name, units, desc, 1));
    WT_TRY(wt_h5_priv_check_types(w, name, ft, ft));
    if (rows < 1 || cols < 1)
        return WT_ERROR(w->ctx, WT_ERR_INVALID, "%s: matrix '%s' of %lld x %lld, expected positive dims", w->target,
                        name, (long long)rows, (long long)cols);
    WT_ALLOC(w->ctx, m, 1, "an HDF5 matrix handle");
    m->w = w;
    m->dset = -1;
    m->rows = rows;
    m->cols = cols;
    WT_ALLOC(w->ctx, m->done, rows, "the row map of an HDF5 matrix");
    if (!(m->name = wt_h5_priv_dupstr(w->ctx, name))) FAIL(w->ctx, WT_ERR_NOMEM, "out of memory for a dataset name");
    if ((space = H5Screate_simple(2, hd, NULL)) < 0 ||
        (dcpl = wt_h5_priv_numeric_dcpl(2, hd, wt_h5_priv_type_size(ft), WT_H5_PRIV_CHUNK_BYTES, 2, 0, chunk)) < 0 ||
        (dapl = H5Pcreate(H5P_DATASET_ACCESS)) < 0)
        H5FAIL(w->ctx, WT_ERR_LIBRARY, "%s: cannot set up matrix '%s'", w->target, name);
    /* room for two chunks, so the chunk a misaligned block ends in is still cached for the next block */
    size_t cbytes = (size_t)(chunk[0] * chunk[1]) * wt_h5_priv_type_size(ft);
    size_t cache = 2 * cbytes + WT_H5_PRIV_CHUNK_BYTES;
    if (H5Pset_chunk_cache(dapl, H5D_CHUNK_CACHE_NSLOTS_DEFAULT, cache, H5D_CHUNK_CACHE_W0_DEFAULT) < 0 ||
        (ftid = wt_h5_priv_file_type(ft)) < 0 ||
        (m->dset = H5Dcreate2(w->file, name, ftid, space, w->lcpl, dcpl, dapl)) < 0)
        H5FAIL(w->ctx, WT_ERR_LIBRARY, "%s: cannot create matrix '%s' (H5Dcreate2)", w->target, name);
    WT_TRY(wt_h5_priv_set_doc(w, m->dset, name, units, desc));
    m->piece.close = matrix_piece_close;
    wt_h5_priv_piece_link(w, &m->piece);
    *out = m;
    m = NULL;
fail:
    if (m) {
        wt_h5_priv_drop(m->dset);
        wt_free(w->ctx, m->name);
        wt_free(w->ctx, m->done);
        wt_free(w->ctx, m);
    }
    wt_h5_priv_drop(dapl);
    wt_h5_priv_drop(dcpl);
    wt_h5_priv_drop(space);
    wt_h5_priv_type_release(ft, ftid);
    return st;
}

int wt_h5_matrix_create(wt_h5_writer *w, const char *name, int file_type, int64_t rows, int64_t cols, const char *units,
                        const char *description, wt_h5_matrix **out)
{
    WRITER_CALL(w, w, matrix_create_impl(w, name, file_type, rows, cols, units, description, out));
}

static int matrix_write_impl(wt_h5_matrix *m, int64_t row0, int64_t nrows, int mt, const void *data)
{
    wt_h5_writer *w = m->w;
    int st = WT_OK;
    hid_t fs = -1, ms = -1, mtid = -1;
    WT_TRY(check_data(w, m->name, m->dset, mt, data));
    if (row0 < 0 || nrows < 1 || row0 > m->rows - nrows)
        return WT_ERROR(w->ctx, WT_ERR_INVALID, "%s: matrix '%s': rows %lld..%lld, expected within 0..%lld", w->target,
                        m->name, (long long)row0, (long long)(row0 + nrows - 1), (long long)(m->rows - 1));
    hsize_t start[2] = {(hsize_t)row0, 0}, count[2] = {(hsize_t)nrows, (hsize_t)m->cols};
    if ((fs = H5Dget_space(m->dset)) < 0 || H5Sselect_hyperslab(fs, H5S_SELECT_SET, start, NULL, count, NULL) < 0 ||
        (ms = H5Screate_simple(2, count, NULL)) < 0 || (mtid = wt_h5_priv_mem_type(mt)) < 0)
        H5FAIL(w->ctx, WT_ERR_LIBRARY, "%s: matrix '%s': cannot select rows %lld..%lld", w->target, m->name,
               (long long)row0, (long long)(row0 + nrows - 1));
    if (H5Dwrite(m->dset, mtid, ms, fs, H5P_DEFAULT, data) < 0)
        H5FAIL(w->ctx, WT_ERR_IO, "%s: writing rows %lld..%lld of matrix '%s' failed (H5Dwrite)", w->target,
               (long long)row0, (long long)(row0 + nrows - 1), m->name);
    for (int64_t i = row0; i < row0 + nrows; i++) {
        m->ndone += !m->done[i];
        m->done[i] = 1;
    }
fail:
    wt_h5_priv_drop(ms);
    wt_h5_priv_drop(fs);
    wt_h5_priv_type_release(mt, mtid);
    return st;
}

int wt_h5_matrix_write_rows(wt_h5_matrix *m, int64_t row0, int64_t nrows, int mem_type, const void *data)
{
    WRITER_CALL(m, m->w, matrix_write_impl(m, row0, nrows, mem_type, data));
}

static int matrix_close(wt_h5_matrix *m, int check)
{
    wt_h5_writer *w = m->w;
    int st = WT_OK;
    wt_h5_priv_piece_unlink(w, &m->piece);
    if (check && m->ndone < m->rows) {
        int64_t first = 0;
        while (m->done[first]) first++;
        st = WT_ERROR(w->ctx, WT_ERR_INVALID,
                      "%s: matrix '%s' has %lld rows, only %lld were written (first missing: %lld)", w->target, m->name,
                      (long long)m->rows, (long long)m->ndone, (long long)first);
    }
    if (H5Dclose(m->dset) < 0 && st == WT_OK && check)
        st = H5ERR(w->ctx, WT_ERR_IO, "%s: closing matrix '%s' failed (disk full?)", w->target, m->name);
    wt_free(w->ctx, m->name);
    wt_free(w->ctx, m->done);
    wt_free(w->ctx, m);
    return st;
}

int wt_h5_matrix_close(wt_h5_matrix *m)
{
    int st;
    if (!m) return WT_OK;
    wt_h5_writer *w = m->w;
    QUIET(matrix_close(m, 1));
    return wt_h5_priv_poison(w, st);
}

/* ---- appendable series -------------------------------------------------------------------------- */

/* A frame of rank frank (0: one value) and dims fdims; a chunk holds whole frames, or for frames of rank ≥ 2 as
 * many of a frame's first-dimension slices as fit (one map of a stack of maps per frame). */
static int series_create_impl(wt_h5_writer *w, const char *name, int ft, int frank, const int64_t *fdims,
                              const char *units, const char *desc, wt_h5_series **out)
{
    int st = WT_OK;
    wt_h5_series *s = NULL;
    hid_t space = -1, dcpl = -1;
    const int rank = frank + 1;
    int64_t n = frank ? 1 : 0;
    hsize_t hd[WT_H5_MAX_RANK] = {0}, maxd[WT_H5_MAX_RANK] = {H5S_UNLIMITED}, cd[WT_H5_MAX_RANK] = {PROBE_FRAMES};
    hsize_t chunk[WT_H5_MAX_RANK];
    if (frank < 0 || rank > WT_H5_MAX_RANK)
        return WT_ERROR(w->ctx, WT_ERR_INVALID, "%s: series '%s' of frames of rank %d", w->target, name, frank);
    for (int i = 0; i < frank; i++) {
        if (fdims[i] < 0)
            return WT_ERROR(w->ctx, WT_ERR_INVALID, "%s: series '%s' of %lld values per frame", w->target, name,
                            (long long)fdims[i]);
        hd[i + 1] = maxd[i + 1] = cd[i + 1] = (hsize_t)fdims[i];
        n *= fdims[i];
    }
    if (!out) return WT_ERROR(w->ctx, WT_ERR_INVALID, "%s: wt_h5_series_create: out is NULL", w->target);
    *out = NULL;
    WT_TRY(wt_h5_priv_check_new(w, name, units, desc, 1));
    WT_TRY(wt_h5_priv_check_types(w, name, ft, ft));
    if (wt_h5_priv_type_half(ft))
        return WT_ERROR(w->ctx, WT_ERR_INVALID, "%s: series '%s': 16-bit floats are for matrices only", w->target, name);
    WT_ALLOC(w->ctx, s, 1, "an HDF5 series handle");
    s->w = w;
    s->dset = -1;
    s->n = n;
    s->frank = frank;
    for (int i = 0; i < frank; i++) s->fdims[i] = (hsize_t)fdims[i];
    if (!(s->name = wt_h5_priv_dupstr(w->ctx, name))) FAIL(w->ctx, WT_ERR_NOMEM, "out of memory for a dataset name");
    if ((space = H5Screate_simple(rank, hd, maxd)) < 0 ||
        (dcpl = wt_h5_priv_numeric_dcpl(rank, cd, wt_h5_priv_type_size(ft), SERIES_CHUNK_BYTES,
                                        frank >= 2 ? 2 : 1, 0, chunk)) < 0 ||
        (s->dset = H5Dcreate2(w->file, name, wt_h5_priv_file_type(ft), space, w->lcpl, dcpl, H5P_DEFAULT)) < 0)
        H5FAIL(w->ctx, WT_ERR_LIBRARY, "%s: cannot create series '%s' (H5Dcreate2)", w->target, name);
    WT_TRY(wt_h5_priv_set_doc(w, s->dset, name, units, desc));
    s->piece.close = series_piece_close;
    wt_h5_priv_piece_link(w, &s->piece);
    *out = s;
    s = NULL;
fail:
    if (s) {
        wt_h5_priv_drop(s->dset);
        wt_free(w->ctx, s->name);
        wt_free(w->ctx, s);
    }
    wt_h5_priv_drop(dcpl);
    wt_h5_priv_drop(space);
    return st;
}

int wt_h5_series_create(wt_h5_writer *w, const char *name, int file_type, int64_t n, const char *units,
                        const char *description, wt_h5_series **out)
{
    const int64_t d[1] = {n};
    WRITER_CALL(w, w, series_create_impl(w, name, file_type, n != 0 ? 1 : 0, d, units, description, out));
}

int wt_h5_series_create_shaped(wt_h5_writer *w, const char *name, int file_type, int rank, const int64_t *dims,
                               const char *units, const char *description, wt_h5_series **out)
{
    WRITER_CALL(w, w, series_create_impl(w, name, file_type, rank, dims, units, description, out));
}

static int series_append_impl(wt_h5_series *s, int mt, const void *data)
{
    wt_h5_writer *w = s->w;
    int st = WT_OK;
    hid_t fs = -1, ms = -1;
    WT_TRY(check_data(w, s->name, s->dset, mt, data));
    hsize_t ext[WT_H5_MAX_RANK] = {(hsize_t)s->len + 1}, start[WT_H5_MAX_RANK] = {(hsize_t)s->len};
    hsize_t count[WT_H5_MAX_RANK] = {1};
    const int rank = s->frank + 1;
    for (int i = 0; i < s->frank; i++) ext[i + 1] = count[i + 1] = s->fdims[i];
    if (H5Dset_extent(s->dset, ext) < 0 || (fs = H5Dget_space(s->dset)) < 0 ||
        H5Sselect_hyperslab(fs, H5S_SELECT_SET, start, NULL, count, NULL) < 0 ||
        (ms = H5Screate_simple(rank, count, NULL)) < 0)
        H5FAIL(w->ctx, WT_ERR_LIBRARY, "%s: series '%s': cannot extend to %lld frames", w->target, s->name,
               (long long)s->len + 1);
    if (H5Dwrite(s->dset, wt_h5_priv_mem_type(mt), ms, fs, H5P_DEFAULT, data) < 0)
        H5FAIL(w->ctx, WT_ERR_IO, "%s: writing frame %lld of series '%s' failed (H5Dwrite)", w->target,
               (long long)s->len, s->name);
    s->len++;
fail:
    wt_h5_priv_drop(ms);
    wt_h5_priv_drop(fs);
    return st;
}

int wt_h5_series_append(wt_h5_series *s, int mem_type, const void *data)
{
    WRITER_CALL(s, s->w, series_append_impl(s, mem_type, data));
}

int64_t wt_h5_series_length(const wt_h5_series *s) { return s ? s->len : 0; }

static int series_close(wt_h5_series *s)
{
    wt_h5_writer *w = s->w;
    int st = WT_OK;
    wt_h5_priv_piece_unlink(w, &s->piece);
    if (H5Dclose(s->dset) < 0)
        st = H5ERR(w->ctx, WT_ERR_IO, "%s: closing series '%s' failed (disk full?)", w->target, s->name);
    wt_free(w->ctx, s->name);
    wt_free(w->ctx, s);
    return st;
}

int wt_h5_series_close(wt_h5_series *s)
{
    int st;
    if (!s) return WT_OK;
    wt_h5_writer *w = s->w;
    QUIET(series_close(s));
    return wt_h5_priv_poison(w, st);
}
