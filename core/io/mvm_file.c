/* core/io/mvm_file.c: MATRIX.h5, written by `wavetomo build`, read by `wavetomo run` and
 * `wavetomo sim --recon mvm` (SPEC §9). */
#include "mvm_file.h"

#include <cblas.h>
#include <string.h>

#include "../base/sha256.h"

/* The element type of the stored matrices. */
static int h5_type(int precision)
{
    return precision == WT_MVM_FILE_F16 ? WT_H5_F16 : precision == WT_MVM_FILE_BF16 ? WT_H5_BF16 : WT_H5_F32;
}

int wt_mvm_file_write(wt_h5_writer *w, const wt_mvm_file_system *sys, int64_t nact, int64_t nslopes, const wt_mvm_file_data *md,
                      const wt_mvm_file_record *rec)
{
    int st;
    wt_h5_matrix *R = NULL;
    const int64_t block = 256;
    const int half = md->precision != WT_MVM_FILE_F32, t = h5_type(md->precision);
    const size_t esize = half ? sizeof(uint16_t) : sizeof(float);
    const char *rdoc = half ? "control matrix as 16-bit floats of R_ij / c_i (c_i: R_row_scale): commands [m] = "
                              "R_row_scale[i] x R[i, :] x slopes [rad]; row = actuator (layout/actuator_index), column "
                              "= slope (layout/sensor_slope_offset)"
                            : "control matrix: commands [m] = R x slopes [rad]; row = actuator (layout/actuator_index), "
                              "column = slope (layout/sensor_slope_offset)";
    if ((st = wt_h5_matrix_create(w, "R", t, nact, nslopes, half ? "" : "m/rad", rdoc, &R)) < 0) return st;
    const char *Rbytes = half ? (const char *)md->Rh : (const char *)md->R;
    for (int64_t r = 0; r < nact; r += block) {
        int64_t nr = nact - r < block ? nact - r : block;
        if ((st = wt_h5_matrix_write_rows(R, r, nr, t, Rbytes + (size_t)r * (size_t)nslopes * esize)) < 0) return st;
    }
    int64_t d[2] = {nact, nact};
    if ((st = wt_h5_write(w, "RA", t, t, 2, d, half ? (const void *)md->RAh : (const void *)md->RA, "",
                          half ? "R A^ as 16-bit floats of (R A^)_ik / c_k (c_k: RA_row_scale), R s_ol = R s + RA a (POLC)"
                               : "R A^: R times the DM-to-slope interaction, so that R s_ol = R s + RA a (POLC)")) < 0)
        return st;
    if (half && ((st = wt_h5_write(w, "R_row_scale", WT_H5_F32, WT_H5_F32, 1, d, md->Rc, "m/rad",
                                   "power-of-two scale c_i of row i of R")) < 0 ||
                 (st = wt_h5_write(w, "RA_row_scale", WT_H5_F32, WT_H5_F32, 1, d, md->RAc, "",
                                   "power-of-two scale of row i of RA")) < 0))
        return st;
    if ((st = wt_h5_attr_write_string(w, "/", "precision",
                                      md->precision == WT_MVM_FILE_F16    ? "fp16"
                                      : md->precision == WT_MVM_FILE_BF16 ? "bf16"
                                                                           : "fp32")) < 0)
        return st;
    if ((st = wt_h5_attr_write_string(w, "/", "config_sha256", sys->sha256)) < 0) return st;
    if ((st = wt_h5_write_string(w, "matrix_config", sys->text,
                                 "the configuration keys that define R (their SHA-256 is the root attribute "
                                 "config_sha256)")) < 0)
        return st;
    if ((st = wt_h5_attr_write_string(w, "/", "variant", rec->variant)) < 0) return st;
    if ((st = wt_h5_attr_write_double(w, "/", "alpha", sys->alpha)) < 0) return st;
    if ((st = wt_h5_attr_write_double(w, "/", "tau", sys->tau)) < 0) return st;
    if ((st = wt_h5_attr_write_string(w, "/", "cholmod_version", rec->cholmod_version)) < 0) return st;
    if ((st = wt_h5_attr_write_string(w, "/", "openblas_config", openblas_get_config())) < 0) return st;
    if ((st = wt_h5_write_int64(w, "build/unknowns", rec->nunknowns, "", "wavelet coefficients of the MAP problem")) < 0)
        return st;
    if ((st = wt_h5_write_double(w, "build/factor_nonzeros", rec->nnz_factor, "",
                                 "non-zeros of the CHOLMOD Cholesky factor of the sparse part N")) < 0)
        return st;
    if ((st = wt_h5_write_int64(w, "build/lowrank_rank", rec->rank, "",
                                "rank of the Woodbury correction (LGS tip-tilt removal and NGS rows)")) < 0)
        return st;
    if ((st = wt_h5_write_double(w, "build/time", rec->build_time, "s", "wall time of the build")) < 0) return st;
    if ((st = wt_h5_write_double(w, "build/peak_memory_estimate", rec->peak_estimate / 1e9, "GB",
                                 "estimated peak memory of the build")) < 0)
        return st;
    return wt_h5_write_string(w, "build/ordering", rec->ordering ? rec->ordering : "?",
                              "fill-reducing ordering CHOLMOD chose");
}

int wt_mvm_file_precision(wt_context *ctx, const char *path, int *precision)
{
    wt_h5_reader *r = NULL;
    char *p = NULL;
    int st;
    *precision = WT_MVM_FILE_F32;
    if ((st = wt_h5_open(ctx, path, &r)) < 0) return st;
    if (wt_h5_attr_exists(r, "/", "precision")) {
        if ((st = wt_h5_attr_read_string(r, "/", "precision", &p)) >= 0) {
            if (!strcmp(p, "fp16")) *precision = WT_MVM_FILE_F16;
            else if (!strcmp(p, "bf16")) *precision = WT_MVM_FILE_BF16;
            else if (strcmp(p, "fp32") != 0)
                st = WT_ERROR(ctx, WT_ERR_FORMAT, "%s: root attribute 'precision' is \"%.40s\", expected \"fp32\", "
                              "\"fp16\" or \"bf16\"", path, p);
        }
    }
    wt_free(ctx, p);
    wt_h5_close(r);
    return st;
}

/* A cursor over a canonical configuration text (libconfig's output: one setting per line, "name = {" opens a
 * group, "};" closes it, an array on one line). */
typedef struct setting_cursor {
    const char *p;
    char group[256]; /* dotted path of the group the cursor is in */
    char key[1300];  /* the last leaf's dotted path (room for the group and a whole line) */
    char val[1024];  /* and its value, without the ';' */
} setting_cursor;

/* The next leaf "name = value;" into c->key and c->val; 0 at the end of the text. */
static int next_setting(setting_cursor *c)
{
    char line[1024];
    while (*c->p) {
        const char *b = c->p, *e = strchr(b, '\n');
        size_t len = e ? (size_t)(e - b) : strlen(b);
        c->p += len + (e != NULL);
        while (len && (*b == ' ' || *b == '\t')) b++, len--;
        if (len >= sizeof line) len = sizeof line - 1;
        memcpy(line, b, len);
        line[len] = '\0';
        char *eq = strstr(line, " = ");
        size_t gl = strlen(c->group);
        if (!strcmp(line, "};")) {
            char *dot = strrchr(c->group, '.');
            *(dot ? dot : c->group) = '\0';
        } else if (eq && !strcmp(eq, " = {")) {
            *eq = '\0';
            snprintf(c->group + gl, sizeof c->group - gl, "%s%s", gl ? "." : "", line);
        } else if (eq) {
            *eq = '\0';
            snprintf(c->key, sizeof c->key, "%s%s%s", c->group, gl ? "." : "", line);
            snprintf(c->val, sizeof c->val, "%s", eq + 3);
            size_t vl = strlen(c->val);
            if (vl && c->val[vl - 1] == ';') c->val[vl - 1] = '\0';
            return 1;
        }
    }
    return 0;
}

/* The value of a dotted key in a canonical text, or NULL (into c). */
static const char *setting_value(const char *text, const char *key, setting_cursor *c)
{
    *c = (setting_cursor){.p = text};
    while (next_setting(c))
        if (!strcmp(c->key, key)) return c->val;
    return NULL;
}

void wt_mvm_file_text_diff(const char *a, const char *b, const char *name_a, const char *name_b, char *buf, size_t n)
{
    size_t used = 0;
    int shown = 0, more = 0;
    if (n == 0) return;
    buf[0] = '\0';
    /* a canonical text is ~3 kB; the lookups are quadratic in its lines, and a corrupt file's text is no system */
    if (!a || !b || strlen(a) > WT_MVM_FILE_DIFF_MAX_TEXT || strlen(b) > WT_MVM_FILE_DIFF_MAX_TEXT) return;
    for (int pass = 0; pass < 2; pass++) { /* a's keys looked up in b, then the keys b alone has */
        setting_cursor x = {.p = pass ? b : a}, y;
        while (next_setting(&x)) {
            const char *o = setting_value(pass ? a : b, x.key, &y);
            if (pass ? o != NULL : o != NULL && !strcmp(o, x.val)) continue;
            if (shown == 3) {
                more++;
                continue;
            }
            const char *va = pass ? "not set" : x.val, *vb = pass ? x.val : o ? o : "not set";
            int r = snprintf(buf + used, n - used, "%s%s = %s in %s, %s in %s", shown ? "; " : "", x.key, va, name_a,
                             vb, name_b);
            if (r > 0) used += (size_t)r < n - used ? (size_t)r : n - used - 1;
            shown++;
        }
    }
    if (more && used + 1 < n) snprintf(buf + used, n - used, "; and %d more key%s", more, more > 1 ? "s" : "");
}

int wt_mvm_file_read(wt_context *ctx, const char *path, const wt_mvm_file_system *sys, int64_t nact, int64_t nslopes,
                     wt_mvm_file_data *md, char *variant_out)
{
    wt_h5_reader *r = NULL;
    int st = wt_h5_open(ctx, path, &r);
    if (st < 0) return st;
    st = wt_mvm_file_read_open(ctx, r, sys, nact, nslopes, md, variant_out);
    wt_h5_close(r);
    return st;
}

int wt_mvm_file_read_open(wt_context *ctx, wt_h5_reader *r, const wt_mvm_file_system *sys, int64_t nact,
                          int64_t nslopes, wt_mvm_file_data *md, char *variant_out)
{
    int st;
    const char *path = wt_h5_path(r);
    char *hash = NULL, *variant = NULL, *text = NULL, own[65];
    if ((st = wt_h5_attr_read_string(r, "/", "config_sha256", &hash)) < 0) goto fail;
    if (strcmp(hash, sys->sha256) != 0) {
        /* name the keys that differ: the fix is then a --set, or a build with the same --set */
        char diff[1024] = "";
        if (wt_h5_exists(r, "matrix_config") && wt_h5_read_string(r, "matrix_config", &text) >= 0)
            wt_mvm_file_text_diff(text, sys->text, "the matrix", sys->path, diff, sizeof diff);
        st = WT_ERROR(ctx, WT_ERR_FORMAT,
                      "%s: the matrix was built for another system (%s%sconfig_sha256 %.12s…, this configuration "
                      "%.12s…); rebuild it with `wavetomo build` for %s (and its --set overrides)",
                      path, diff, diff[0] ? "; " : "", hash, sys->sha256, sys->path);
        goto fail;
    }
    /* provenance: the stored configuration text must still give the stored hash (an edited
     * file is refused), and the variant must be one the builder writes */
    if ((st = wt_h5_read_string(r, "matrix_config", &text)) < 0) goto fail;
    wt_sha256_hex(text, strlen(text), own);
    if (strcmp(own, hash) != 0) {
        st = WT_ERROR(ctx, WT_ERR_FORMAT,
                      "%s: dataset 'matrix_config' hashes to %.12s…, not to the root attribute config_sha256 %.12s…: "
                      "the file was edited after it was built; rebuild it with `wavetomo build`", path, own, hash);
        goto fail;
    }
    if ((st = wt_h5_attr_read_string(r, "/", "variant", &variant)) < 0) goto fail;
    if (strcmp(variant, "pcg3") != 0 && strcmp(variant, "cg9") != 0) {
        st = WT_ERROR(ctx, WT_ERR_FORMAT, "%s: root attribute 'variant' is \"%.40s\", expected \"pcg3\" or \"cg9\"",
                      path, variant);
        goto fail;
    }
    int64_t er[2] = {nact, nslopes}, ea[2] = {nact, nact};
    if ((st = wt_h5_check_shape(r, "R", 2, er, NULL)) < 0) goto fail;
    if ((st = wt_h5_check_shape(r, "RA", 2, ea, NULL)) < 0) goto fail;
    const int half = md->precision != WT_MVM_FILE_F32, t = h5_type(md->precision);
    if ((st = wt_h5_read(r, "R", t, 2, er, NULL, half ? (void *)md->Rh : (void *)md->R, (size_t)(nact * nslopes))) < 0)
        goto fail;
    if ((st = wt_h5_read(r, "RA", t, 2, ea, NULL, half ? (void *)md->RAh : (void *)md->RA, (size_t)(nact * nact))) < 0)
        goto fail;
    if (half) {
        int64_t ec[1] = {nact};
        float *sc[2] = {md->Rc, md->RAc};
        const char *names[2] = {"R_row_scale", "RA_row_scale"};
        for (int k = 0; k < 2; k++) {
            if ((st = wt_h5_read(r, names[k], WT_H5_F32, 1, ec, NULL, sc[k], (size_t)nact)) < 0) goto fail;
            for (int64_t i = 0; i < nact; i++)
                if (!(sc[k][i] > 0.0f)) {
                    st = WT_ERROR(ctx, WT_ERR_FORMAT, "%s: dataset '%s' holds %g at element %lld, expected > 0", path,
                                  names[k], (double)sc[k][i], (long long)i);
                    goto fail;
                }
        }
    }
    strncpy(variant_out, variant, 15);
    variant_out[15] = '\0';
fail:
    wt_free(ctx, hash);
    wt_free(ctx, text);
    wt_free(ctx, variant);
    return st;
}
