/* core/io/mvm_file.c: MATRIX.h5, written by `wavetomo build`, read by `wavetomo run` and
 * `wavetomo sim --recon mvm` (SPEC §9). */
#include "mvm_file.h"

#include <cblas.h>
#include <string.h>

#include "../base/sha256.h"

int wt_mvm_file_write(wt_h5_writer *w, const wt_mvm_file_system *sys, int64_t nact, int64_t nslopes, const float *Rm,
                      const float *RA, const wt_mvm_file_record *rec)
{
    int st;
    wt_h5_matrix *R = NULL;
    const int64_t block = 256;
    if ((st = wt_h5_matrix_create(w, "R", WT_H5_F32, nact, nslopes, "m/rad",
                                  "control matrix: commands [m] = R x slopes [rad]; row = actuator (layout/actuator_index), "
                                  "column = slope (layout/sensor_slope_offset)",
                                  &R)) < 0)
        return st;
    for (int64_t r = 0; r < nact; r += block) {
        int64_t nr = nact - r < block ? nact - r : block;
        if ((st = wt_h5_matrix_write_rows(R, r, nr, WT_H5_F32, Rm + (size_t)r * (size_t)nslopes)) < 0) return st;
    }
    int64_t d[2] = {nact, nact};
    if ((st = wt_h5_write(w, "RA", WT_H5_F32, WT_H5_F32, 2, d, RA, "",
                          "R A^: R times the DM-to-slope interaction, so that R s_ol = R s + RA a (POLC)")) < 0)
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

int wt_mvm_file_read(wt_context *ctx, const char *path, const wt_mvm_file_system *sys, int64_t nact, int64_t nslopes, float *R,
                     float *RA, char *variant_out)
{
    wt_h5_reader *r = NULL;
    int st = wt_h5_open(ctx, path, &r);
    if (st < 0) return st;
    st = wt_mvm_file_read_open(ctx, r, sys, nact, nslopes, R, RA, variant_out);
    wt_h5_close(r);
    return st;
}

int wt_mvm_file_read_open(wt_context *ctx, wt_h5_reader *r, const wt_mvm_file_system *sys, int64_t nact, int64_t nslopes,
                          float *R, float *RA, char *variant_out)
{
    int st;
    const char *path = wt_h5_path(r);
    char *hash = NULL, *variant = NULL, *text = NULL, own[65];
    if ((st = wt_h5_attr_read_string(r, "/", "config_sha256", &hash)) < 0) goto fail;
    if (strcmp(hash, sys->sha256) != 0) {
        st = WT_ERROR(ctx, WT_ERR_FORMAT,
                      "%s: the matrix was built for another system (config_sha256 %.12s…, this configuration %.12s…); "
                      "rebuild it with `wavetomo build` for %s",
                      path, hash, sys->sha256, sys->path);
        goto fail;
    }
    /* provenance (issue 10, J): the stored configuration text must still give the stored hash (an edited
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
    if ((st = wt_h5_read(r, "R", WT_H5_F32, 2, er, NULL, R, (size_t)nact * (size_t)nslopes)) < 0) goto fail;
    if ((st = wt_h5_read(r, "RA", WT_H5_F32, 2, ea, NULL, RA, (size_t)nact * (size_t)nact)) < 0) goto fail;
    strncpy(variant_out, variant, 15);
    variant_out[15] = '\0';
fail:
    wt_free(ctx, hash);
    wt_free(ctx, text);
    wt_free(ctx, variant);
    return st;
}
