/* tests/test_pupil.c: illuminated fractions, valid-subaperture and point masks of the annular pupil. */
#include "testutil.h"

#include "core/op/pupil.h"

/* The fraction is analytic: only rounding separates it from the exact area (a few ulp of the
 * terms, which are O(s²) or O(R²) for a square of side s and pupil radius R). With R/s ≤ 100 the
 * rounding stays below 1e-11 relative. */
#define FRAC_EXACT_TOL 1e-11

START_TEST(test_fraction_inside_outside)
{
    /* wholly inside the annulus (corners at radius 10 .. 10.52 m, between 5.88 and 21 m) */
    ck_assert_rel(wt_pupil_fraction(42.0, 0.28, 10.0, 0.0, 0.5), 1.0, 1e-14, 0.0);
    /* wholly outside the rim, and wholly inside the central obstruction */
    ck_assert(wt_pupil_fraction(42.0, 0.28, 21.0, 0.0, 0.5) == 0.0);
    ck_assert(wt_pupil_fraction(42.0, 0.28, 15.0, 15.0, 0.5) == 0.0); /* corner radius 21.2 > 21 */
    ck_assert(wt_pupil_fraction(42.0, 0.28, -0.5, -0.5, 1.0) == 0.0);
    /* degenerate squares */
    ck_assert(wt_pupil_fraction(42.0, 0.28, 10.0, 0.0, 0.0) == 0.0);
}
END_TEST

START_TEST(test_fraction_segment_and_quarter)
{
    /* A square containing the whole circle segment x ≥ R − h of a unit disk:
     * area = R² acos((R − h)/R) − (R − h) sqrt(2Rh − h²). */
    const double R = 1.0, h = 0.3, s = 1.5;
    double seg = R * R * acos((R - h) / R) - (R - h) * sqrt(2 * R * h - h * h);
    ck_assert_rel(wt_pupil_fraction(2 * R, 0.0, R - h, -0.75, s), seg / (s * s), FRAC_EXACT_TOL, 0.0);
    /* a segment cut by the side y = 0.2 as well: the part of the disk with x ≥ 0.7 and y ≤ 0.2 equals
     * half the segment + the strip 0 ≤ y ≤ 0.2 of it, ∫_0^0.2 (sqrt(1 − y²) − 0.7) dy */
    double strip = 0.5 * (0.2 * sqrt(1 - 0.04) + asin(0.2)) - 0.7 * 0.2;
    ck_assert_rel(wt_pupil_fraction(2 * R, 0.0, R - h, -1.3, s), (0.5 * seg + strip) / (s * s), FRAC_EXACT_TOL, 0.0);
    /* quarter disk */
    ck_assert_rel(wt_pupil_fraction(2.0, 0.0, 0.0, 0.0, 1.0), M_PI / 4, FRAC_EXACT_TOL, 0.0);
    /* a 13 m square, inside the 42 m rim, around the whole 11.76 m obstruction */
    double ri = 0.5 * 0.28 * 42.0;
    ck_assert_rel(wt_pupil_fraction(42.0, 0.28, -6.5, -6.5, 13.0), (169.0 - M_PI * ri * ri) / 169.0, FRAC_EXACT_TOL, 0.0);
}
END_TEST

/* Rigorous bracket from an independent method: split the square into g x g cells; a cell whose nearest
 * point to the centre is ≥ r_in and farthest ≤ R is surely lit, one whose farthest < r_in or nearest
 * > R surely dark. lower = Σ surely-lit areas ≤ exact ≤ upper = Σ not-surely-dark areas. */
static void bracket(double D, double eps, double x0, double y0, double s, int g, double *lo, double *hi)
{
    double R2 = 0.25 * D * D, r2 = 0.25 * eps * eps * D * D, h = s / g, nl = 0, nh = 0;
    for (int j = 0; j < g; j++) {
        double ya = y0 + j * h, yb = ya + h;
        double ny = (ya > 0) ? ya : (yb < 0 ? -yb : 0), fy = fmax(fabs(ya), fabs(yb));
        for (int i = 0; i < g; i++) {
            double xa = x0 + i * h, xb = xa + h;
            double nx = (xa > 0) ? xa : (xb < 0 ? -xb : 0), fx = fmax(fabs(xa), fabs(xb));
            double near2 = nx * nx + ny * ny, far2 = fx * fx + fy * fy;
            if (near2 >= r2 && far2 <= R2) nl += 1;
            if (!(far2 < r2 || near2 > R2)) nh += 1;
        }
    }
    *lo = nl / ((double)g * g);
    *hi = nh / ((double)g * g);
}

START_TEST(test_fraction_bracketed)
{
    wt_rng r;
    wt_rng_init(&r, 1234, 0);
    int straddling = 0;
    for (int t = 0; t < 40; t++) {
        /* squares of side 0.5 m near the rim (radius 21) or the obstruction edge (radius 5.88) */
        double rad = (t % 2 ? 21.0 : 5.88) + (wt_rng_uniform(&r) - 0.5) * 0.8;
        double phi = 2 * M_PI * wt_rng_uniform(&r);
        double x0 = rad * cos(phi) - 0.25, y0 = rad * sin(phi) - 0.25;
        double f = wt_pupil_fraction(42.0, 0.28, x0, y0, 0.5), lo, hi;
        bracket(42.0, 0.28, x0, y0, 0.5, 400, &lo, &hi);
        ck_assert_msg(f >= lo - 1e-12 && f <= hi + 1e-12, "square (%g, %g): fraction %.6f outside [%.6f, %.6f]", x0, y0,
                      f, lo, hi);
        straddling += f > 0.01 && f < 0.99;
    }
    ck_assert_int_ge(straddling, 10); /* the test exercised partial squares */
}
END_TEST

START_TEST(test_small_pupil_by_hand)
{
    /* D = 4, n = 4, d = 1, no obstruction. Edge-middle cells ([1,2] x [0,1]) are lit
     * 0.732 + (π − 2.960) = 0.913; corner cells ([1,2]²) 0.315; the four central cells 1. */
    uint8_t v[16], c[25];
    ck_assert_int_eq(wt_pupil_valid_subapertures(4.0, 0.0, 4, 0.3, v), 16);
    ck_assert_int_eq(wt_pupil_valid_subapertures(4.0, 0.0, 4, 0.95, v), 4);
    ck_assert(v[5] && v[6] && v[9] && v[10]);
    ck_assert_int_eq(wt_pupil_valid_subapertures(4.0, 0.0, 4, 0.5, v), 12);
    ck_assert(!v[0] && !v[3] && !v[12] && !v[15] && v[1] && v[4]);
    ck_assert_rel(wt_pupil_fraction(4.0, 0.0, 1.0, 1.0, 1.0),
                  0.5 * (sqrt(3.0) + 4 * M_PI / 3) - 0.5 * (sqrt(3.0) + 4 * M_PI / 6) - (sqrt(3.0) - 1), FRAC_EXACT_TOL, 0);
    /* the cross of 12 cells touches every corner of the 5 x 5 grid but the four outer ones */
    wt_pupil_corner_mask(4, v, c);
    int nc = 0;
    for (int k = 0; k < 25; k++) nc += c[k];
    ck_assert_int_eq(nc, 21);
    ck_assert(!c[0] && !c[4] && !c[20] && !c[24] && c[12]);
    ck_assert_int_eq(wt_pupil_valid_subapertures(4.0, 0.0, 0, 0.5, v), WT_ERR_INVALID);
}
END_TEST

START_TEST(test_eelt_count)
{
    /* SPEC §1: D = 42 m, obstruction 0.28 of the diameter, 84 x 84, valid if ≥ 50 % lit → 5112. */
    const int n = 84;
    uint8_t *v = malloc(n * n), *c = malloc((n + 1) * (n + 1));
    ck_assert_int_eq(wt_pupil_valid_subapertures(42.0, 0.28, n, 0.5, v), 5112);
    /* the nearest fractions are 0.4929 and 0.5126: ≥ vs > cannot matter */
    uint8_t *v2 = malloc(n * n);
    ck_assert_int_eq(wt_pupil_valid_subapertures(42.0, 0.28, n, 0.5 + 1e-9, v2), 5112);
    ck_assert_int_eq(wt_pupil_valid_subapertures(42.0, 0.28, n, 0.4929, v2), 5112 + 8);
    /* four-fold symmetry of the mask */
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            ck_assert_int_eq(v[i + n * j], v[(n - 1 - i) + n * j]);
            ck_assert_int_eq(v[i + n * j], v[j + n * i]);
        }
    /* corners of the valid subapertures (Fried phase points); 5328 agrees with an independent
     * Python evaluation of the same definition */
    wt_pupil_corner_mask(n, v, c);
    int nc = 0;
    for (int k = 0; k < (n + 1) * (n + 1); k++) nc += c[k];
    ck_assert_int_eq(nc, 5328);
    free(v);
    free(v2);
    free(c);
}
END_TEST

START_TEST(test_mask_points)
{
    /* 3 x 3 points at spacing 1: the centre and the four edge midpoints lie within radius 1
     * (the rim is inclusive); an obstruction of radius 0.5 removes the centre. */
    wt_grid g = wt_grid_centred(3, 1.0);
    uint8_t m[9];
    ck_assert_int_eq(wt_pupil_mask_points(2.0, 0.0, &g, m), 5);
    ck_assert(m[4] && m[1] && m[3] && m[5] && m[7] && !m[0]);
    ck_assert_int_eq(wt_pupil_mask_points(2.0, 0.5, &g, m), 4);
    ck_assert(!m[4]);
    /* SPEC §1: 5525 active actuators at h = 0 (85 x 85 at 0.5 m within radius 21 m) */
    wt_grid e = wt_grid_centred(85, 0.5);
    uint8_t *me = malloc(85 * 85);
    ck_assert_int_eq(wt_pupil_mask_points(42.0, 0.0, &e, me), 5525);
    free(me);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("pupil");
    TCase *tc = tcase_create("core");
    tcase_add_test(tc, test_fraction_inside_outside);
    tcase_add_test(tc, test_fraction_segment_and_quarter);
    tcase_add_test(tc, test_fraction_bracketed);
    tcase_add_test(tc, test_small_pupil_by_hand);
    tcase_add_test(tc, test_eelt_count);
    tcase_add_test(tc, test_mask_points);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
