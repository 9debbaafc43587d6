/* tests/fuzz/fuzz_h5_recipe.c: libFuzzer target of every HDF5 reader, on well-formed but hostile files.
 *
 * Why a second kind of target: the metadata of our files is checksummed (superblock v2+, object header
 * v2) and numeric data carries Fletcher32, so mutated bytes of a real file mostly test the checksum
 * refusals of HDF5 itself (fuzz_telemetry, fuzz_mvm). What our code must survive is a *valid* HDF5 file
 * with the wrong things in it. Here the input is a recipe: its bytes choose, for each name the readers
 * look for (config, matrix_config, slopes, slopes_ol, commands, R, RA and the root attributes complete,
 * creator, config_sha256, variant), whether it is absent, a string (fixed or variable length, the demo's
 * real text, or bytes of the input, or a declared length up to 2 GiB that is not stored), a numeric dataset (class, size, byte order, rank 0-4, dims, chunked
 * or not, Fletcher32 or not, an extent beyond what is written, values with NaN/Inf/huge), a group, or a
 * soft or external link; also the file format bounds (v0 superblock without checksums). The file is
 * built in memory with HDF5's core driver, its image taken, and given to the telemetry reading of
 * `run`, the MVM reader and every call of the generic reader (h5.h). */
#include "fuzz.h"
#include "fuzz_h5.h"

#include <hdf5.h>
#include <math.h>

#include "core/io/h5.h"
#include "core/io/mvm_file.h"
#include "core/model/system.h"

static wt_context *ctx;
static wt_config *demo;
static wt_mvm_file_system demo_fs;
static int64_t nslopes, nact;
static float *row;

typedef struct recipe {
    const uint8_t *p;
    size_t n;
} recipe;

static unsigned byte(recipe *r)
{
    if (!r->n) return 0;
    r->n--;
    return *r->p++;
}

static int64_t dim(recipe *r)
{
    unsigned b = byte(r);
    switch (b >> 5) {
    case 0: return 0;
    case 1: return nslopes;
    case 2: return nact;
    case 3: return FUZZ_NACT;
    case 4: return FUZZ_NSLOPES;
    case 5: return (int64_t)(b & 31) * 1000000007LL; /* a claimed extent far beyond the bytes */
    default: return b & 31;
    }
}

static const char *const dsets[] = {"config", "matrix_config", "slopes", "slopes_ol", "commands", "R", "RA",
                                    "eval/strehl_le"};
static const char *const attrs[] = {"complete", "creator", "config_sha256", "variant"};
enum { NDSETS = sizeof dsets / sizeof *dsets, NATTRS = sizeof attrs / sizeof *attrs };

/* A numeric file type chosen by b. */
static hid_t num_type(unsigned b)
{
    hid_t base;
    switch (b % 12) {
    case 0: base = H5T_IEEE_F32LE; break;
    case 1: base = H5T_IEEE_F64LE; break;
    case 2: base = H5T_IEEE_F32BE; break;
    case 3: base = H5T_IEEE_F64BE; break;
    case 4: base = H5T_STD_I8LE; break;
    case 5: base = H5T_STD_I16LE; break;
    case 6: base = H5T_STD_I32LE; break;
    case 7: base = H5T_STD_I64LE; break;
    case 8: base = H5T_STD_U8LE; break;
    case 9: base = H5T_STD_U32LE; break;
    case 10: base = H5T_STD_U64LE; break;
    default: base = H5T_STD_I32BE; break;
    }
    hid_t t = H5Tcopy(base);
    if (b >= 240 && H5Tget_class(t) == H5T_FLOAT) { /* a half-precision float: an IEEE layout we refuse */
        H5Tset_fields(t, 15, 10, 5, 0, 10);
        H5Tset_ebias(t, 15);
        H5Tset_size(t, 2);
        H5Tset_precision(t, 16);
    }
    return t;
}

/* The text of a string: the demo's real configuration or matrix text, the hash, a variant, or bytes. */
static char *string_value(recipe *r, char *buf, size_t cap)
{
    unsigned b = byte(r);
    switch (b & 7) {
    case 0: return demo->canonical;
    case 1: return demo->matrix_text;
    case 2: return demo->matrix_sha256;
    case 3: return (b & 8) ? "cg9" : "pcg3";
    case 4: return "wavetomo 1.0";
    default: {
        size_t k = 0, want = byte(r) % cap;
        while (k < want && r->n) buf[k++] = (char)byte(r);
        buf[k] = '\0';
        return buf;
    }
    }
}

/* declared > 0: a fixed-length string of that many bytes, never written (only a dataset can be) */
static void put_string(hid_t loc, const char *name, int attr, int vlen, const char *s, size_t declared)
{
    hid_t t = H5Tcopy(H5T_C_S1), sp = H5Screate(H5S_SCALAR), o = -1;
    H5Tset_size(t, vlen ? H5T_VARIABLE : declared && !attr ? declared : strlen(s) + 1);
    if (declared && !attr) {
        H5Dclose(H5Dcreate2(loc, name, t, sp, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT));
        H5Tclose(t), H5Sclose(sp);
        return;
    }
    const void *src = vlen ? (const void *)&s : (const void *)s;
    if (attr) {
        if ((o = H5Acreate2(loc, name, t, sp, H5P_DEFAULT, H5P_DEFAULT)) >= 0) H5Awrite(o, t, src), H5Aclose(o);
    } else if ((o = H5Dcreate2(loc, name, t, sp, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT)) >= 0)
        H5Dwrite(o, t, H5S_ALL, H5S_ALL, H5P_DEFAULT, src), H5Dclose(o);
    H5Tclose(t), H5Sclose(sp);
}

/* A numeric dataset or attribute: type, rank, dims, storage and values from the recipe. */
static void put_numeric(recipe *r, hid_t loc, const char *name, int attr, hid_t lcpl)
{
    hid_t t = num_type(byte(r)), sp = -1, dcpl = H5Pcreate(H5P_DATASET_CREATE), o = -1;
    unsigned how = byte(r);
    int rank = attr ? (int)(how & 1) : (int)(how % 6); /* 0..5: 5 is beyond WT_H5_MAX_RANK */
    hsize_t d[5] = {1, 1, 1, 1, 1}, maxd[5], chunk[5], written[5];
    double npts = 1;
    for (int i = 0; i < rank; i++) {
        d[i] = (hsize_t)dim(r);
        if (attr && d[i] > 64) d[i] = 64; /* attributes live in the object header: HDF5 would allocate all */
        maxd[i] = H5S_UNLIMITED;
        chunk[i] = d[i] ? (d[i] < 64 ? d[i] : 64) : 1;
        npts *= (double)d[i];
    }
    /* the values written: the whole extent when it is small, else nothing (an extent claimed, unstored) */
    int chunked = !attr && rank > 0 && (how & 8);
    if (npts > 1 << 20) chunked = !attr && rank > 0;
    if (chunked) {
        H5Pset_chunk(dcpl, rank, chunk);
        if (how & 16) H5Pset_fletcher32(dcpl);
    }
    memcpy(written, d, sizeof d);
    sp = H5Screate_simple(rank, d, chunked ? maxd : NULL);
    if (rank == 0) H5Sclose(sp), sp = H5Screate(H5S_SCALAR);
    o = attr ? H5Acreate2(loc, name, t, sp, H5P_DEFAULT, H5P_DEFAULT)
             : H5Dcreate2(loc, name, t, sp, lcpl, dcpl, H5P_DEFAULT);
    if (o >= 0 && npts <= 1 << 16) {
        size_t n = (size_t)npts;
        double *v = malloc((n ? n : 1) * sizeof *v);
        unsigned fill = byte(r);
        for (size_t i = 0; v && i < n; i++) {
            unsigned b = fill & 1 ? byte(r) : fill;
            v[i] = b == 251 ? NAN : b == 252 ? INFINITY : b == 253 ? -1e300 : b == 254 ? 1e-310 : (double)b - 100.0;
        }
        /* HDF5 converts (with its own overflow rules: Inf into an integer saturates) */
        if (v) {
            if (attr) H5Awrite(o, H5T_NATIVE_DOUBLE, v);
            else H5Dwrite(o, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v);
        }
        free(v);
    }
    if (o >= 0 && !attr && chunked && (how & 32)) { /* grow the extent past what was written */
        for (int i = 0; i < rank; i++) written[i] = d[i] + (i == 0 ? (hsize_t)byte(r) * 1000003u : 0);
        H5Dset_extent(o, written);
    }
    if (o >= 0) attr ? H5Aclose(o) : H5Dclose(o);
    H5Pclose(dcpl), H5Sclose(sp), H5Tclose(t);
}

/* Build the file of the recipe in memory; [out] its image (malloc'd) and size. */
static void *build(recipe *r, size_t *size)
{
    hid_t fapl = H5Pcreate(H5P_FILE_ACCESS), f = -1, lcpl = H5Pcreate(H5P_LINK_CREATE);
    unsigned fmt = byte(r);
    void *img = NULL;
    char buf[256];
    H5Pset_fapl_core(fapl, 1 << 16, 0);
    H5Pset_libver_bounds(fapl, fmt & 1 ? H5F_LIBVER_EARLIEST : H5F_LIBVER_V18, H5F_LIBVER_LATEST);
    H5Pset_create_intermediate_group(lcpl, 1);
    if ((f = H5Fcreate("fuzz-recipe.h5", H5F_ACC_TRUNC, H5P_DEFAULT, fapl)) < 0) goto out;
    for (int i = 0; i < NATTRS; i++) {
        unsigned b = byte(r);
        if (i == 0 && !(b & 0x80)) { /* mostly a proper "complete" = 1, else the reader stops at open */
            int64_t one = 1;
            hid_t sp = H5Screate(H5S_SCALAR), a = H5Acreate2(f, "complete", H5T_STD_I64LE, sp, H5P_DEFAULT, H5P_DEFAULT);
            if (a >= 0) H5Awrite(a, H5T_NATIVE_INT64, &one), H5Aclose(a);
            H5Sclose(sp);
            continue;
        }
        switch (b % 4) {
        case 0: break;
        case 1: put_string(f, attrs[i], 1, (b >> 2) & 1, string_value(r, buf, sizeof buf), 0); break;
        default: put_numeric(r, f, attrs[i], 1, lcpl); break;
        }
    }
    for (int i = 0; i < NDSETS; i++) {
        unsigned b = byte(r);
        switch (b % 8) {
        case 0: case 1: break;
        case 2: /* a string; with bit 4, one whose declared length (up to 2^31 bytes) is not stored */
            put_string(f, dsets[i], 0, (b >> 3) & 1, string_value(r, buf, sizeof buf),
                       (b & 16) ? (size_t)1 << (byte(r) % 32) : 0);
            break;
        case 3: case 4: case 5: put_numeric(r, f, dsets[i], 0, lcpl); break;
        case 6: H5Gclose(H5Gcreate2(f, dsets[i], lcpl, H5P_DEFAULT, H5P_DEFAULT)); break;
        default: /* a dangling or circular soft link, or an external link to a file that is not there */
            if (b & 8) H5Lcreate_soft(b & 16 ? dsets[i] : "/nowhere", f, dsets[i], lcpl, H5P_DEFAULT);
            else H5Lcreate_external("fuzz-absent.h5", "/R", f, dsets[i], lcpl, H5P_DEFAULT);
            break;
        }
    }
    H5Fflush(f, H5F_SCOPE_GLOBAL);
    ssize_t n = H5Fget_file_image(f, NULL, 0);
    if (n > 0 && (img = malloc((size_t)n)) && H5Fget_file_image(f, img, (size_t)n) != n) free(img), img = NULL;
    *size = n > 0 ? (size_t)n : 0;
out:
    if (f >= 0) H5Fclose(f);
    H5Pclose(fapl), H5Pclose(lcpl);
    return img;
}

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc, (void)argv;
    if (!(ctx = wt_context_alloc())) fuzz_die("wt_context_alloc", NULL);
    demo = fuzz_demo_config(ctx);
    demo_fs = fuzz_file_system(demo);
    wt_system *sys = NULL;
    if (wt_system_alloc(ctx, demo, &sys) < 0) fuzz_die("wt_system_alloc", ctx);
    nslopes = sys->nslopes, nact = sys->nact;
    wt_system_free(sys);
    if (!(row = malloc((size_t)(nslopes > nact ? nslopes : nact) * 4 * sizeof *row))) fuzz_die("malloc", NULL);
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL); /* the recipe's own failures are expected */
    fuzz_enter_sandbox();
    return 0;
}

static void telemetry(wt_h5_reader *r)
{
    char *text = NULL;
    wt_config *tcfg = NULL;
    if (wt_h5_read_string(r, "config", &text) == WT_OK && !fuzz_escapes_sandbox(text, strlen(text)) &&
        wt_config_parse(ctx, text, "fuzz-recipe.h5:config", 0, NULL, &tcfg) == WT_OK &&
        !strcmp(tcfg->matrix_sha256, demo->matrix_sha256)) {
        const char *names[3] = {"slopes", "slopes_ol", "commands"};
        for (int k = 0; k < 3; k++) {
            int64_t cols = k < 2 ? nslopes : nact, expect[2] = {-1, cols}, dims[2];
            if (wt_h5_check_shape(r, names[k], 2, expect, dims) < 0) continue;
            for (int64_t t = 0; t < dims[0] && t < 4; t++)
                if (wt_h5_read_rows(r, names[k], WT_H5_F32, t, 1, row) == WT_OK)
                    for (int64_t i = 0; i < cols; i++)
                        if (!isfinite(row[i])) abort();
        }
    }
    wt_config_free(ctx, tcfg);
    wt_free(ctx, text);
}

/* Every call of the generic reader on every name, with the memory types the library reads. */
static void generic(wt_h5_reader *r)
{
    static const int types[] = {WT_H5_F32, WT_H5_F64, WT_H5_I32, WT_H5_I64, WT_H5_U8};
    const size_t cap = (size_t)(nslopes > nact ? nslopes : nact) * 4 * sizeof(float) / 8; /* in 8-byte elements */
    for (int i = 0; i < NDSETS; i++) {
        int rank = 0;
        int64_t dims[WT_H5_MAX_RANK] = {0}, got[WT_H5_MAX_RANK];
        double dv;
        int64_t iv;
        char *s = NULL;
        (void)wt_h5_exists(r, dsets[i]);
        if (wt_h5_read_string(r, dsets[i], &s) == WT_OK) wt_free(ctx, s);
        (void)wt_h5_read_double(r, dsets[i], &dv);
        (void)wt_h5_read_int64(r, dsets[i], &iv);
        if (wt_h5_dims(r, dsets[i], &rank, dims) < 0) continue;
        for (int k = 0; k < 5; k++) {
            (void)wt_h5_read(r, dsets[i], types[k], rank, NULL, got, row, cap);
            double per_row = 1;
            for (int j = 1; j < rank; j++) per_row *= (double)dims[j];
            if (rank >= 1 && dims[0] > 0 && per_row <= (double)cap)
                (void)wt_h5_read_rows(r, dsets[i], types[k], dims[0] - 1, 1, row);
        }
        (void)wt_h5_read_rows(r, dsets[i], WT_H5_F32, -1, 1, row); /* bad arguments are refused too */
        (void)wt_h5_read_rows(r, dsets[i], WT_H5_F32, 0, 0, row);
    }
    for (int i = 0; i < NATTRS; i++) {
        char *s = NULL;
        double dv;
        int64_t iv;
        if (wt_h5_attr_read_string(r, "/", attrs[i], &s) == WT_OK) wt_free(ctx, s);
        (void)wt_h5_attr_read_double(r, "/", attrs[i], &dv);
        (void)wt_h5_attr_read_int64(r, "/", attrs[i], &iv);
        if (wt_h5_attr_read_string(r, "R", "units", &s) == WT_OK) wt_free(ctx, s);
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    recipe rc = {data, size};
    size_t n = 0;
    void *img = build(&rc, &n);
    if (!img) return 0;
    wt_h5_reader *r = NULL;
    long ids = fuzz_h5_open_ids();
    if (wt_h5_open_image(ctx, "fuzz-recipe.h5", img, n, &r) == WT_OK) {
        static float R[FUZZ_NACT * FUZZ_NSLOPES], RA[FUZZ_NACT * FUZZ_NACT];
        char variant[16];
        telemetry(r);
        if (wt_mvm_file_read_open(ctx, r, &demo_fs, FUZZ_NACT, FUZZ_NSLOPES, &(wt_mvm_file_data){.precision = WT_MVM_FILE_F32, .R = R, .RA = RA}, variant) == WT_OK) {
            for (int i = 0; i < FUZZ_NACT * FUZZ_NSLOPES; i++)
                if (!isfinite(R[i])) abort();
            if (strcmp(variant, "pcg3") && strcmp(variant, "cg9")) abort();
        }
        generic(r);
        wt_h5_close(r);
    }
    fuzz_h5_check_ids(ids);
    free(img);
    return 0;
}
