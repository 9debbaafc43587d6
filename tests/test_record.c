/* tests/test_record.c: what `sim --telemetry` records (sim/record.h): with sim.telemetry_maps_interval_frames
 * the residual maps of every N-th frame, whose rms over the pupil is that frame's residual rms in RUN.h5
 * (frame/rms), and the commands of those frames, which are the per-frame telemetry's; without the key, no maps. */
#include "core/io/h5.h"
#include "testutil.h"

#define DEMO "data/presets/demo.cfg"

static char dir[64], wt[512];
static void setup(void) { tu_cli_setup(wt, sizeof wt, dir, sizeof dir, "wt_record_"); }
static void teardown(void) { tu_cli_teardown(dir); }

START_TEST(test_maps_rms_is_frame_rms)
{
    enum { frames = 11, every = 4, nrec = 3 }; /* frames 0, 4, 8 */
    ck_assert_int_eq(tu_run(wt, dir,
                            "sim " DEMO " --frames %d --set evaluation.settle_frames=2 --set sim.psf_interval_frames=0 "
                            "--set sim.telemetry_maps_interval_frames=%d --threads 2 --quiet --out %s/run.h5 "
                            "--telemetry %s/tel.h5",
                            frames, every, dir, dir),
                     0);
    wt_context *ctx = tu_context();
    char path[256];
    wt_h5_reader *t, *r;
    snprintf(path, sizeof path, "%s/tel.h5", dir);
    ck_assert_msg(wt_h5_open(ctx, path, &t) == WT_OK, "%s", wt_error_message(ctx));
    snprintf(path, sizeof path, "%s/run.h5", dir);
    ck_assert_msg(wt_h5_open(ctx, path, &r) == WT_OK, "%s", wt_error_message(ctx));
    int64_t dm[4], dc[2];
    int rank;
    ck_assert_int_eq(wt_h5_dims(t, "maps/residual", &rank, dm), WT_OK);
    ck_assert_int_eq(rank, 4);
    ck_assert_int_eq(dm[0], nrec);
    ck_assert_int_eq(wt_h5_dims(t, "commands", &rank, dc), WT_OK);
    const int64_t nd = dm[1], np = dm[2] * dm[3], nact = dc[1];
    ck_assert_int_eq(dc[0], frames);
    uint8_t *mask = malloc((size_t)np);
    float *maps = malloc((size_t)(nrec * nd * np) * sizeof *maps), *rms = malloc((size_t)(frames * nd) * sizeof *rms);
    float *cmd = malloc((size_t)(nrec * nact) * sizeof *cmd), *all = malloc((size_t)(frames * nact) * sizeof *all);
    int64_t fr[nrec];
    ck_assert_int_eq(wt_h5_read(t, "maps/pupil", WT_H5_U8, 2, dm + 2, NULL, mask, (size_t)np), WT_OK);
    ck_assert_int_eq(wt_h5_read(t, "maps/residual", WT_H5_F32, 4, dm, NULL, maps, (size_t)(nrec * nd * np)), WT_OK);
    ck_assert_int_eq(wt_h5_read(t, "maps/frame", WT_H5_I64, 1, dm, NULL, fr, nrec), WT_OK);
    ck_assert_int_eq(wt_h5_read(t, "maps/commands", WT_H5_F32, 2, NULL, NULL, cmd, (size_t)(nrec * nact)), WT_OK);
    ck_assert_int_eq(wt_h5_read(t, "commands", WT_H5_F32, 2, dc, NULL, all, (size_t)(frames * nact)), WT_OK);
    ck_assert_int_eq(wt_h5_read(r, "frame/rms", WT_H5_F32, 2, NULL, NULL, rms, (size_t)(frames * nd)), WT_OK);
    for (int k = 0; k < nrec; k++) {
        ck_assert_int_eq(fr[k], (int64_t)k * every);
        /* the commands of the recorded frames are the per-frame telemetry's, bit for bit */
        ck_assert(!memcmp(cmd + k * nact, all + fr[k] * nact, (size_t)nact * sizeof *cmd));
        for (int64_t j = 0; j < nd; j++) {
            const float *m = maps + (k * nd + j) * np;
            double s = 0.0, s2 = 0.0;
            int64_t c = 0;
            for (int64_t i = 0; i < np; i++) {
                if (!mask[i]) {
                    ck_assert(m[i] == 0.0f);
                    continue;
                }
                s += m[i], s2 += (double)m[i] * m[i], c++;
            }
            /* piston removed before the float32 rounding: the mean is at rounding level of the values */
            const double sigma = sqrt(s2 / c);
            ck_assert_msg(fabs(s / c) <= 1e-6 * sigma, "frame %lld direction %lld: mean %g of rms %g", (long long)fr[k],
                          (long long)j, s / c, sigma);
            /* float32 maps and float32 frame/rms [nm]: each value rounded at 2^-24 relative, 1e-5 is far above */
            ck_assert_rel(sigma * 1e9, (double)rms[fr[k] * nd + j], 1e-5, 0.0);
        }
    }
    free(mask), free(maps), free(rms), free(cmd), free(all);
    wt_h5_close(t);
    wt_h5_close(r);

    /* left out: no maps (and the telemetry as before) */
    ck_assert_int_eq(tu_run(wt, dir,
                            "sim " DEMO " --frames 4 --set evaluation.settle_frames=2 --set sim.psf_interval_frames=0 "
                            "--threads 2 --quiet --out %s/run0.h5 --telemetry %s/tel0.h5",
                            dir, dir),
                     0);
    snprintf(path, sizeof path, "%s/tel0.h5", dir);
    ck_assert_int_eq(wt_h5_open(ctx, path, &t), WT_OK);
    ck_assert(!wt_h5_exists(t, "maps"));
    ck_assert(wt_h5_exists(t, "commands"));
    wt_h5_close(t);
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("record");
    TCase *tc = tcase_create("core");
    tcase_add_checked_fixture(tc, setup, teardown);
    tcase_set_timeout(tc, 120);
    tcase_add_test(tc, test_maps_rms_is_frame_rms);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
