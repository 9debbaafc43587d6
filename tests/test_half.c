/* tests/test_half.c: 16-bit storage of the MVM (core/la/half.h): exact conversions, round to nearest
 * even, the GEMV error bound of half.h, thread independence, and the container's conversion. */
#include <math.h>

#include "core/la/half.h"
#include "core/solve/mvm.h"
#include "testutil.h"

static const int precs[2] = {WT_PREC_F16, WT_PREC_BF16};

/* Every 16-bit pattern is a float32 value that converts back to itself (NaN to a NaN). */
START_TEST(test_round_trip_every_pattern)
{
    for (int p = 0; p < 2; p++)
        for (uint32_t h = 0; h < 65536; h++) {
            float v = wt_half_to_float(precs[p], (uint16_t)h);
            uint16_t back = wt_half_from_float(precs[p], v);
            if (isnan(v))
                ck_assert_msg(isnan(wt_half_to_float(precs[p], back)), "%s %04x: NaN lost", wt_prec_name(precs[p]), h);
            else
                ck_assert_msg(back == h, "%s %04x -> %g -> %04x", wt_prec_name(precs[p]), h, (double)v, back);
            ck_assert_int_eq(wt_half_is_nonfinite(precs[p], (uint16_t)h), !isfinite(v));
        }
}
END_TEST

/* Round to nearest, ties to even, at the edges that matter: the largest finite value, overflow, the
 * subnormal range, and exact ties. */
START_TEST(test_rounding_edges)
{
    const int F = WT_PREC_F16, B = WT_PREC_BF16;
    ck_assert_uint_eq(wt_half_from_float(F, 65504.0f), 0x7bff);
    ck_assert_uint_eq(wt_half_from_float(F, 65519.0f), 0x7bff);
    ck_assert_uint_eq(wt_half_from_float(F, 65520.0f), 0x7c00); /* tie between 65504 (odd) and 2^16: even = Inf */
    ck_assert_uint_eq(wt_half_from_float(F, -1e30f), 0xfc00);
    ck_assert_uint_eq(wt_half_from_float(F, 0x1p-24f), 0x0001);   /* smallest subnormal */
    ck_assert_uint_eq(wt_half_from_float(F, 0x1p-25f), 0x0000);   /* tie with 0: even */
    ck_assert_uint_eq(wt_half_from_float(F, 0x1.8p-24f), 0x0002); /* tie 1.5 -> 2 */
    ck_assert_uint_eq(wt_half_from_float(F, 0x1.8p-23f), 0x0003); /* 3 exactly */
    ck_assert_uint_eq(wt_half_from_float(F, 0x1.ffcp-15f), 0x0400); /* rounds up into the smallest normal */
    ck_assert_uint_eq(wt_half_from_float(F, 1.0f + 0x1p-11f), 0x3c00);      /* tie -> even 1.0 */
    ck_assert_uint_eq(wt_half_from_float(F, 1.0f + 0x1.8p-10f), 0x3c02);    /* tie between 1+2^-10 and 1+2^-9 */
    ck_assert_uint_eq(wt_half_from_float(B, 1.0f + 0x1p-8f), 0x3f80);       /* tie -> even */
    ck_assert_uint_eq(wt_half_from_float(B, 1.0f + 0x1.8p-7f), 0x3f82);
    ck_assert_uint_eq(wt_half_from_float(B, 3.4028235e38f), 0x7f80);        /* FLT_MAX rounds to Inf */
    ck_assert_uint_eq(wt_half_from_float(B, -0.0f), 0x8000);
}
END_TEST

/* Against an independent oracle: the compiler's own _Float16 conversion (libgcc, correctly rounded), on
 * random floats over the whole fp16 range; and, for both formats, the nearest-value property. */
START_TEST(test_rounding_random)
{
    uint64_t s = 12345;
    for (int i = 0; i < 200000; i++) {
        s = s * 6364136223846793005ULL + 1442695040888963407ULL;
        const uint32_t bits = (uint32_t)(s >> 32);
        /* exponents spread over 2^-30 .. 2^17 */
        const float v = ldexpf(1.0f + (float)(bits & 0xffffff) / 16777216.0f, (int)((bits >> 24) % 48) - 30) *
                        ((bits & 0x80000000u) ? -1.0f : 1.0f);
#ifdef __FLT16_MAX__
        const _Float16 ref = (_Float16)v;
        uint16_t rb;
        memcpy(&rb, &ref, 2);
        ck_assert_msg(wt_half_from_float(WT_PREC_F16, v) == rb, "fp16(%a) = %04x, compiler %04x", (double)v,
                      wt_half_from_float(WT_PREC_F16, v), rb);
#endif
        for (int p = 0; p < 2; p++) {
            const uint16_t h = wt_half_from_float(precs[p], v);
            const float r = wt_half_to_float(precs[p], h);
            if (!isfinite(r)) continue;
            /* no neighbour of h is closer to v */
            const float up = wt_half_to_float(precs[p], (uint16_t)(h + 1)), dn = wt_half_to_float(precs[p], (uint16_t)(h - 1));
            const double e = fabs((double)r - v);
            if (isfinite(up) && (h & 0x7fff) != 0x7fff) ck_assert(e <= fabs((double)up - v));
            if ((h & 0x7fff) != 0) ck_assert(e <= fabs((double)dn - v));
        }
    }
}
END_TEST

/* y = c H x against the exact R x in double: within half.h's bound
 *   u Σ|R_ij x_j| + 2^-25 c_i Σ|x_j| (fp16 subnormals) + γ_k (1 + u) Σ|R_ij x_j| (float32 products and sums,
 *   k = n/32 + 33 additions along any path of the 32-lane sum),
 * for rows of very different sizes (1e-9 .. 1e3), a zero row and a row with tiny entries; the same bits
 * with 1 and 2 threads, and for a row alone; beta accumulates. */
START_TEST(test_gemv_bound)
{
    const int64_t rows = 141, cols = 1237; /* 2 full blocks of 64 rows + 13: 4-row kernel and its tail */
    float *A = malloc(sizeof(float) * (size_t)(rows * cols)), *x = malloc(sizeof(float) * (size_t)cols);
    uint16_t *H = malloc(sizeof(uint16_t) * (size_t)(rows * cols));
    float c[141], y1[141], y2[141], yb[141];
    uint64_t s = 99;
    for (int64_t i = 0; i < rows; i++) {
        const float mag = i == 0 ? 0.0f : powf(10.0f, (float)(i % 13) - 9.0f);
        for (int64_t j = 0; j < cols; j++) {
            s = s * 6364136223846793005ULL + 1442695040888963407ULL;
            float u = (float)((s >> 40) & 0xffffff) / 16777216.0f - 0.5f;
            /* row 5: most entries 1e-7 of its largest, inside fp16's subnormal range after scaling */
            A[i * cols + j] = mag * u * ((i == 5 && j > 0) ? 1e-7f : 1.0f);
        }
    }
    for (int64_t j = 0; j < cols; j++) {
        s = s * 6364136223846793005ULL + 1442695040888963407ULL;
        x[j] = (float)((s >> 40) & 0xffffff) / 16777216.0f - 0.5f;
    }
    const double k = (double)cols / 32 + 33, gk = k * 0x1p-24 / (1 - k * 0x1p-24);
    for (int p = 0; p < 2; p++) {
        const double u = precs[p] == WT_PREC_F16 ? 0x1p-11 : 0x1p-8;
        wt_half_pack(precs[p], rows, cols, A, H, c, 2);
        wt_half_gemv(precs[p], rows, cols, H, c, x, 0.0f, y1, 1);
        wt_half_gemv(precs[p], rows, cols, H, c, x, 0.0f, y2, 2);
        ck_assert(!memcmp(y1, y2, sizeof y1));
        /* a row alone (the one-row kernel) gives the bits it gets among others (the four-row kernel):
         * the same lanes in the same order */
        for (int64_t i = 0; i < rows; i++) {
            float yi;
            wt_half_gemv(precs[p], 1, cols, H + i * cols, c + i, x, 0.0f, &yi, 1);
            ck_assert_msg(yi == y1[i], "%s row %lld alone %a, in the block %a", wt_prec_name(precs[p]), (long long)i,
                          (double)yi, (double)y1[i]);
        }
        for (int64_t i = 0; i < rows; i++) {
            double exact = 0, sabs = 0, xabs = 0;
            for (int64_t j = 0; j < cols; j++) {
                exact += (double)A[i * cols + j] * x[j];
                sabs += fabs((double)A[i * cols + j] * x[j]);
                xabs += fabs(x[j]);
            }
            const double bound = (u + gk * (1 + u)) * sabs + (precs[p] == WT_PREC_F16 ? 0x1p-25 * c[i] * xabs : 0.0);
            ck_assert_msg(fabs(y1[i] - exact) <= bound, "%s row %lld: |%g - %g| > %g", wt_prec_name(precs[p]),
                          (long long)i, (double)y1[i], exact, bound);
            /* the bound is not vacuous: the storage error is seen at its scale on the big rows */
            if (i == 0) ck_assert(y1[i] == 0.0f);
        }
        for (int64_t i = 0; i < rows; i++) yb[i] = 1.0f;
        wt_half_gemv(precs[p], rows, cols, H, c, x, 2.0f, yb, 2);
        for (int64_t i = 0; i < rows; i++) ck_assert(yb[i] == 2.0f + y1[i]);
    }
    free(A);
    free(x);
    free(H);
}
END_TEST

/* The container: fp16 apply within the bound of the fp32 apply, with and without the POLC term; a
 * non-finite matrix entry is refused before anything is converted. */
START_TEST(test_mvm_precision)
{
    wt_context *ctx = tu_context();
    const int64_t na = 30, ns = 500;
    float s[500], a[30], y32[30], y16[30];
    for (int p = 0; p < 2; p++) {
        wt_mvm *m;
        ck_assert_int_eq(wt_mvm_alloc(ctx, WT_MVM_LAYER_VALUES, na, ns, &m), WT_OK);
        uint64_t r = 7;
        for (int64_t i = 0; i < na * ns; i++) {
            r = r * 6364136223846793005ULL + 1442695040888963407ULL;
            m->R[i] = (float)((r >> 40) & 0xffff) / 65536.0f - 0.5f;
        }
        for (int64_t i = 0; i < na * na; i++) m->RA[i] = (float)(i % 7) * 0.1f - 0.3f;
        for (int j = 0; j < 500; j++) s[j] = (float)sin(0.1 * j);
        for (int j = 0; j < 30; j++) a[j] = (float)cos(0.3 * j);
        wt_mvm_apply(m, s, a, y32);
        double sabs[30] = {0};
        for (int64_t i = 0; i < na; i++) {
            for (int64_t j = 0; j < ns; j++) sabs[i] += fabs((double)m->R[i * ns + j] * s[j]);
            for (int64_t j = 0; j < na; j++) sabs[i] += fabs((double)m->RA[i * na + j] * a[j]);
        }
        ck_assert_int_eq(wt_mvm_set_precision(m, precs[p]), WT_OK);
        ck_assert_ptr_null(m->R);
        ck_assert_int_eq(m->precision, precs[p]);
        wt_mvm_apply(m, s, a, y16);
        const double u = precs[p] == WT_PREC_F16 ? 0x1p-11 : 0x1p-8;
        double worst = 0;
        for (int64_t i = 0; i < na; i++) {
            ck_assert_msg(fabs((double)y16[i] - y32[i]) <= (u + 1e-5) * sabs[i], "row %lld", (long long)i);
            worst = fmax(worst, fabs((double)y16[i] - y32[i]) / sabs[i]);
        }
        ck_assert(worst > 0); /* 16 bits were really used */
        ck_assert_int_eq(wt_mvm_set_precision(m, WT_PREC_F16 + WT_PREC_BF16 - precs[p]), WT_ERR_INVALID);
        wt_mvm_free(m);

        ck_assert_int_eq(wt_mvm_alloc(ctx, WT_MVM_LAYER_VALUES, 2, 3, &m), WT_OK);
        for (int i = 0; i < 6; i++) m->R[i] = 1.0f;
        for (int i = 0; i < 4; i++) m->RA[i] = 1.0f;
        m->R[4] = NAN;
        ck_assert_int_eq(wt_mvm_set_precision(m, precs[p]), WT_ERR_NUMERIC);
        ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "R[1, 1]"));
        ck_assert_ptr_nonnull(m->R);
        wt_mvm_free(m);
    }
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("half");
    TCase *tc = tcase_create("half");
    tcase_set_timeout(tc, 60);
    tcase_add_test(tc, test_round_trip_every_pattern);
    tcase_add_test(tc, test_rounding_edges);
    tcase_add_test(tc, test_rounding_random);
    tcase_add_test(tc, test_gemv_bound);
    tcase_add_test(tc, test_mvm_precision);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
