/* tests/test_strehl.c: image quality of a residual (SPEC §8; sim/strehl.h): the piston-removed
 * rms of a known OPD, the Maréchal Strehl exp(−(2πσ/λ)²), and the long-exposure averages. */
#include "sim/strehl.h"
#include "testutil.h"

/* φ = c + b sin(2π x / P) over whole periods: the mean is c, the piston-removed rms b/√2; points
 * outside the mask carry garbage that must be ignored. */
START_TEST(test_rms_of_known_opd)
{
    const int n = 64, periods = 4;
    const double b = 150e-9, c = 3e-6;
    double opd[64 * 64];
    uint8_t mask[64 * 64];
    for (int iy = 0; iy < n; iy++)
        for (int ix = 0; ix < n; ix++) {
            int i = ix + n * iy, in = iy < n / 2; /* the lower half of the rows */
            mask[i] = (uint8_t)in;
            opd[i] = in ? c + b * sin(2.0 * M_PI * periods * ix / n) : 1e3;
        }
    const double rms = wt_strehl_rms(opd, mask, n * n);
    ck_assert_rel(rms, b / sqrt(2.0), 1e-12, 0.0);
    /* Maréchal at 2.2 µm */
    const double lambda = 2.2e-6, s = wt_strehl_marechal(rms, lambda);
    ck_assert_rel(s, exp(-pow(2.0 * M_PI * b / sqrt(2.0) / lambda, 2)), 1e-12, 0.0);
    ck_assert_double_eq(wt_strehl_marechal(0.0, lambda), 1.0);
    /* a pure piston has no error */
    for (int i = 0; i < n * n; i++) opd[i] = mask[i] ? c : opd[i];
    ck_assert_double_le(wt_strehl_rms(opd, mask, n * n), 1e-12 * c);
}
END_TEST

/* LE Strehl = mean of the short-exposure Strehl; WFE = √(mean σ²), per direction. */
START_TEST(test_long_exposure)
{
    wt_strehl_le le;
    wt_strehl_le_init(&le, 2);
    const double lambda = 1.65e-6, f1[2] = {100e-9, 0.0}, f2[2] = {200e-9, 50e-9};
    ck_assert_double_eq(wt_strehl_le_strehl(&le, 0), 0.0);
    wt_strehl_le_add(&le, f1, lambda);
    wt_strehl_le_add(&le, f2, lambda);
    ck_assert_int_eq(le.frames, 2);
    for (int j = 0; j < 2; j++) {
        double s = 0.5 * (wt_strehl_marechal(f1[j], lambda) + wt_strehl_marechal(f2[j], lambda));
        ck_assert_rel(wt_strehl_le_strehl(&le, j), s, 1e-14, 0.0);
        ck_assert_rel(wt_strehl_le_wfe(&le, j), sqrt(0.5 * (f1[j] * f1[j] + f2[j] * f2[j])), 1e-14, 0.0);
    }
    /* the mean of the Strehls is not the Strehl of the mean error (Jensen): the LE Strehl is the larger */
    ck_assert_double_gt(wt_strehl_le_strehl(&le, 0), wt_strehl_marechal(wt_strehl_le_wfe(&le, 0), lambda));
}
END_TEST

/* The batched rms equals one wt_strehl_rms per map bit for bit (any reordering of a sum would show in
 * the last bits): 11 maps (over one chunk of WT_STREHL_CHAINS), a mask with holes, pistons of different
 * sizes, and an empty mask (0). */
START_TEST(test_rms_many_equals_single)
{
    enum { N = 2000, M = 11 };
    static double maps[M][N];
    static uint8_t mask[N], none[N];
    wt_rng rng;
    wt_rng_init(&rng, 3, 0);
    for (int i = 0; i < N; i++) mask[i] = (uint8_t)(i % 7 != 3 && i % 11 != 0);
    const double *p[M];
    for (int j = 0; j < M; j++) {
        for (int i = 0; i < N; i++) maps[j][i] = 1e-6 * j + 1e-7 * wt_rng_normal(&rng);
        p[j] = maps[j];
    }
    double many[M], none_rms[M];
    wt_strehl_rms_many(p, mask, N, M, many);
    for (int j = 0; j < M; j++) {
        const double one = wt_strehl_rms(maps[j], mask, N);
        ck_assert_msg(memcmp(&one, &many[j], sizeof one) == 0, "map %d: %.17g vs %.17g", j, one, many[j]);
        ck_assert_double_gt(one, 5e-8);
    }
    wt_strehl_rms_many(p, none, N, M, none_rms);
    for (int j = 0; j < M; j++) ck_assert_double_eq(none_rms[j], 0.0);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("strehl");
    TCase *tc = tcase_create("core");
    tcase_add_test(tc, test_rms_of_known_opd);
    tcase_add_test(tc, test_long_exposure);
    tcase_add_test(tc, test_rms_many_equals_single);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
