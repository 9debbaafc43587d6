/* sim/night.c: a changing night for the truth (see night.h): its knots (a night file, or the stochastic
 * model's Ornstein–Uhlenbeck walks), their linear interpolation, and the per-frame drive of the atmosphere. */
#include "night.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../core/base/numbers.h"
#include "../core/base/rng.h"

#define DEG (M_PI / 180.0) /* the configuration's degrees → radians, the same product as config_read.c's */

struct wt_night {
    wt_context *ctx;
    int nl;                /* layers */
    long nk;               /* knots */
    double *t, *r0;        /* [nk] night time [s], r0 [m] */
    double *f, *v, *d;     /* [nk * nl], knot k at k * nl: fractions (sum 1), speed [m/s], direction [rad] */
    int *line;             /* [nk] a file's line of each knot (0: drawn) */
    /* the reference state (the screens'), its wind vectors as the atmosphere computes them */
    double r0_ref, *f_ref, *vx_ref, *vy_ref;
    double dt, start, compression;
    long next;             /* the frame whose displacement dx, dy holds */
    double *dx, *dy;       /* D_ℓ(next) [m] */
    double *scale;         /* g_ℓ of the current state */
    double cur_t, cur_r0, *cur_f, *cur_v, *cur_d; /* wt_night_current */
};

/* ---------------------------------------------------------------------------------------------- */
/* Interpolation */

/* The knot k with t_k ≤ t < t_{k+1} (the last knot for t = t_last), or −1 outside [t_0, t_last]. */
static long find_knot(const wt_night *n, double t)
{
    if (!(t >= n->t[0] && t <= n->t[n->nk - 1])) return -1;
    if (t == n->t[n->nk - 1]) return n->nk - 1;
    long lo = 0, hi = n->nk - 1; /* t_lo ≤ t < t_hi */
    while (hi - lo > 1) {
        const long mid = lo + (hi - lo) / 2;
        if (n->t[mid] <= t) lo = mid;
        else hi = mid;
    }
    return lo;
}

int wt_night_state(const wt_night *n, double t, double *r0, double *fraction, double *wind_speed, double *wind_direction)
{
    if (!n) return WT_ERR_INVALID;
    const long k = isfinite(t) ? find_knot(n, t) : -1;
    if (k < 0)
        return WT_ERROR(n->ctx, WT_ERR_INVALID, "wt_night_state: night time %g s is outside the night's states, "
                        "%g s to %g s", t, n->t[0], n->t[n->nk - 1]);
    const int nl = n->nl;
    /* at a knot (w = 0, or the last knot) its own values, bit for bit; between: a + w (b − a) */
    const long k1 = k + 1 < n->nk ? k + 1 : k;
    const double w = k1 == k ? 0.0 : (t - n->t[k]) / (n->t[k1] - n->t[k]);
    if (r0) *r0 = n->r0[k] + w * (n->r0[k1] - n->r0[k]);
    const double *fa = n->f + k * nl, *fb = n->f + k1 * nl, *va = n->v + k * nl, *vb = n->v + k1 * nl;
    const double *da = n->d + k * nl, *db = n->d + k1 * nl;
    if (fraction) {
        double s = 0.0;
        for (int l = 0; l < nl; l++) s += fraction[l] = fa[l] + w * (fb[l] - fa[l]);
        if (w != 0.0)
            for (int l = 0; l < nl; l++) fraction[l] /= s;
    }
    if (wind_speed)
        for (int l = 0; l < nl; l++) wind_speed[l] = va[l] + w * (vb[l] - va[l]);
    if (wind_direction)
        for (int l = 0; l < nl; l++) {
            double dd = remainder(db[l] - da[l], 2.0 * M_PI); /* the shorter arc, in [−π, π] */
            wind_direction[l] = da[l] + w * dd;
        }
    return WT_OK;
}

void wt_night_screen_scale(int nlayers, double r0_ref, const double *fraction_ref, double r0, const double *fraction,
                           double *scale)
{
    /* Φ_ℓ ∝ f_ℓ r0^(−5/3): the screen's amplitude goes as its square root */
    const double rr = pow(r0 / r0_ref, -5.0 / 3.0);
    for (int l = 0; l < nlayers; l++)
        scale[l] = fraction_ref[l] > 0.0 ? sqrt(fraction[l] / fraction_ref[l] * rr) : 0.0;
}

/* ---------------------------------------------------------------------------------------------- */
/* The night file */

/* The last frame's night time. */
static double night_end(const wt_night_params *p) { return p->start + (double)(p->frames - 1) * p->frame_time * p->compression; }

static int file_error(wt_night *n, int status, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static int file_error(wt_night *n, int status, const char *fmt, ...)
{
    char msg[1536];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return WT_ERROR(n->ctx, status, "%s", msg);
}

/* Room for cap knots (grown by doubling while reading a file): the first nk kept. */
static void *grow(wt_night *n, void *old, size_t keep, size_t size)
{
    void *q = wt_malloc(n->ctx, size, 1);
    if (q && old) memcpy(q, old, keep);
    if (q) wt_free(n->ctx, old);
    return q;
}

static int knots_reserve(wt_night *n, long cap)
{
    const size_t nl = (size_t)n->nl, k = (size_t)n->nk, c = (size_t)cap;
    double **one[] = {&n->t, &n->r0}, **many[] = {&n->f, &n->v, &n->d};
    for (int i = 0; i < 5; i++) {
        const size_t m = i < 2 ? 1 : nl;
        double **a = i < 2 ? one[i] : many[i - 2];
        double *q = grow(n, *a, k * m * sizeof(double), c * m * sizeof(double));
        if (!q) return WT_ERROR(n->ctx, WT_ERR_NOMEM, "out of memory for %ld night states", cap);
        *a = q;
    }
    int *q = grow(n, n->line, k * sizeof(int), c * sizeof(int));
    if (!q) return WT_ERROR(n->ctx, WT_ERR_NOMEM, "out of memory for %ld night states", cap);
    n->line = q;
    return WT_OK;
}

static int read_file(wt_night *n, const wt_night_params *p)
{
    const char *path = p->file;
    const int nl = n->nl, ncol = 2 + 3 * nl;
    char tail[1200]; /* every message of a line ends with it */
    snprintf(tail, sizeof tail, "(a night file: night time [s], r0 [m], then per layer Cn2 fraction, wind speed [m/s] "
             "and wind direction [deg]: %d columns for the truth's %d layer%s%s%s)", ncol, nl, nl == 1 ? "" : "s",
             p->origin ? "; " : "", p->origin ? p->origin : "");
    FILE *fp = fopen(path, "r");
    if (!fp) return file_error(n, WT_ERR_IO, "cannot open the night file '%s': %s %s", path, strerror(errno), tail);
    int st = WT_OK, lineno = 0;
    long cap = 0, vcap = 0;
    char *line = NULL;
    size_t lcap = 0;
    double *v = NULL; /* a line's numbers (wt_read_numbers) */
    while (getline(&line, &lcap, fp) >= 0) {
        lineno++;
        const wt_numbers_where w = {path, lineno, 1, NULL, 0, tail, WT_ERR_CONFIG};
        const long nf = wt_read_numbers(n->ctx, line, &w, &v, &vcap);
        if (nf < 0) {
            st = (int)nf;
            goto out;
        }
        if (nf == 0) continue;
        if (nf != ncol) {
            st = file_error(n, WT_ERR_CONFIG, "%s:%d: %ld columns; expected %d = 2 + 3 x %d %s", path, lineno, nf, ncol,
                            nl, tail);
            goto out;
        }
        const long k = n->nk;
        if (k > 0 && !(v[0] > n->t[k - 1])) {
            st = file_error(n, WT_ERR_CONFIG, "%s:%d: night time %g s is not after the previous state's %g s (line %d): "
                            "the times must increase %s", path, lineno, v[0], n->t[k - 1], n->line[k - 1], tail);
            goto out;
        }
        if (!(v[1] > 0.0)) {
            st = file_error(n, WT_ERR_CONFIG, "%s:%d: r0 = %g m; expected r0 > 0 %s", path, lineno, v[1], tail);
            goto out;
        }
        double sum = 0.0;
        for (int l = 0; l < nl; l++) {
            const double f = v[2 + 3 * l], s = v[3 + 3 * l], d = v[4 + 3 * l];
            if (f < 0.0 || s < 0.0 || !(fabs(d) <= 360.0)) {
                st = file_error(n, WT_ERR_CONFIG, "%s:%d: layer %d (columns %d-%d): %s %g%s %s", path, lineno, l + 1,
                                3 + 3 * l, 5 + 3 * l,
                                f < 0.0 ? "the Cn2 fraction" : s < 0.0 ? "the wind speed" : "the wind direction",
                                f < 0.0 ? f : s < 0.0 ? s : d,
                                f < 0.0   ? " is negative"
                                : s < 0.0 ? " m/s is negative"
                                          : " deg is outside [-360, 360]",
                                tail);
                goto out;
            }
            if (f > 0.0 && !(n->f_ref[l] > 0.0)) {
                st = file_error(n, WT_ERR_CONFIG, "%s:%d: layer %d has the Cn2 fraction %g, but 0 in the configured "
                                "atmosphere, whose screens the night scales: a layer generated without power cannot "
                                "grow; give it a small positive fraction in the configuration %s", path, lineno, l + 1,
                                f, tail);
                goto out;
            }
            sum += f;
        }
        if (!(fabs(sum - 1.0) <= WT_NIGHT_SUM_TOL)) {
            st = file_error(n, WT_ERR_CONFIG, "%s:%d: the Cn2 fractions sum to %.9g; expected 1 within %g %s", path,
                            lineno, sum, WT_NIGHT_SUM_TOL, tail);
            goto out;
        }
        if ((long)(k + 1) * ncol > WT_NIGHT_MAX_VALUES) {
            st = file_error(n, WT_ERR_CONFIG, "%s:%d: more than %d values in the night %s", path, lineno,
                            WT_NIGHT_MAX_VALUES, tail);
            goto out;
        }
        if (k == cap && (st = knots_reserve(n, cap = cap ? 2 * cap : 64)) < 0) goto out;
        n->t[k] = v[0];
        n->r0[k] = v[1];
        for (int l = 0; l < nl; l++) {
            /* normalised as the configuration's lists are (the same sum, in the same order) */
            n->f[k * nl + l] = v[2 + 3 * l] / sum;
            n->v[k * nl + l] = v[3 + 3 * l];
            n->d[k * nl + l] = v[4 + 3 * l] * DEG;
        }
        n->line[k] = lineno;
        n->nk++;
    }
    if (ferror(fp)) {
        st = file_error(n, WT_ERR_IO, "%s: reading the night file failed: %s %s", path, strerror(errno), tail);
        goto out;
    }
    if (n->nk == 0) st = file_error(n, WT_ERR_CONFIG, "%s: no state in the night file %s", path, tail);
out:
    free(line); /* getline's buffer comes from malloc */
    wt_free(n->ctx, v);
    fclose(fp);
    return st;
}

/* ---------------------------------------------------------------------------------------------- */
/* The stochastic model */

static int draw_knots(wt_night *n, const wt_night_params *p)
{
    const int nl = n->nl;
    const double end = night_end(p);
    const double nkd = floor(end / p->step) + 2.0;
    if (!(nkd * (2 + 3 * nl) <= WT_NIGHT_MAX_VALUES))
        return WT_ERROR(n->ctx, WT_ERR_INVALID, "wt_night_alloc: %.3g knots of %g s to the run's last night time %g s "
                        "hold more than %d values: a step too small for the night%s%s", nkd, p->step, end,
                        WT_NIGHT_MAX_VALUES, p->origin ? "; " : "", p->origin ? p->origin : "");
    const long nk = (long)nkd;
    int st = knots_reserve(n, nk);
    if (st < 0) return st;
    n->nk = nk;
    const double a = exp(-p->step / p->correlation_time), b = sqrt(1.0 - a * a);
    /* one process per stream: z_0 = 0, z_{k+1} = a z_k + b ξ_k; knot k's values in place (r0 into n->r0,
     * the fractions' weights into n->f, then normalised) */
    for (int q = 0; q < 1 + 3 * nl; q++) {
        const int kind = q == 0 ? 0 : 1 + (q - 1) / nl, l = q == 0 ? 0 : (q - 1) % nl;
        const uint64_t stream = q == 0 ? 0 : 1 + (uint64_t)(kind - 1) * WT_NIGHT_MAX_LAYERS + (uint64_t)l;
        wt_rng rng;
        wt_rng_init(&rng, p->seed, stream);
        double z = 0.0;
        for (long k = 0; k < nk; k++) {
            if (k > 0) z = a * z + b * wt_rng_normal(&rng);
            switch (kind) {
            case 0: n->r0[k] = p->r0 * exp(p->r0_rms * z); break;
            case 1: n->f[k * nl + l] = n->f_ref[l] * exp(p->fraction_rms * z); break;
            case 2: n->v[k * nl + l] = p->wind_speed[l] * exp(p->wind_speed_rms * z); break;
            default: n->d[k * nl + l] = p->wind_direction[l] + p->wind_direction_rms * z; break;
            }
        }
    }
    for (long k = 0; k < nk; k++) {
        n->t[k] = (double)k * p->step;
        n->line[k] = 0;
        if (k == 0) continue; /* z = 0: the reference itself */
        double s = 0.0;
        for (int l = 0; l < nl; l++) s += n->f[k * nl + l];
        for (int l = 0; l < nl; l++) n->f[k * nl + l] /= s;
    }
    return WT_OK;
}

/* ---------------------------------------------------------------------------------------------- */
/* Set-up */

static int check_params(wt_context *ctx, const wt_night_params *p)
{
    const char *fn = "wt_night_alloc";
    if (!p) return WT_ERROR(ctx, WT_ERR_INVALID, "%s: params is NULL", fn);
    if (p->source != WT_NIGHT_FILE && p->source != WT_NIGHT_RANDOM)
        return WT_ERROR(ctx, WT_ERR_INVALID, "%s: source = %d; expected WT_NIGHT_FILE or WT_NIGHT_RANDOM", fn, p->source);
    if (p->nlayers < 1 || p->nlayers > WT_NIGHT_MAX_LAYERS)
        return WT_ERROR(ctx, WT_ERR_INVALID, "%s: nlayers = %d; expected 1 to %d", fn, p->nlayers, WT_NIGHT_MAX_LAYERS);
    if (!p->fraction || !p->wind_speed || !p->wind_direction)
        return WT_ERROR(ctx, WT_ERR_INVALID, "%s: a NULL reference array", fn);
    double s = 0.0;
    for (int l = 0; l < p->nlayers; l++) {
        if (!(p->fraction[l] >= 0.0 && isfinite(p->fraction[l])) || !(p->wind_speed[l] >= 0.0) ||
            !isfinite(p->wind_speed[l]) || !isfinite(p->wind_direction[l]))
            return WT_ERROR(ctx, WT_ERR_INVALID, "%s: reference layer %d: fraction %g, wind %g m/s towards %g rad; "
                            "expected finite values, the first two >= 0", fn, l, p->fraction[l], p->wind_speed[l],
                            p->wind_direction[l]);
        s += p->fraction[l];
    }
    if (!(s > 0.0)) return WT_ERROR(ctx, WT_ERR_INVALID, "%s: the reference fractions sum to %g", fn, s);
    if (!(p->r0 > 0.0) || !isfinite(p->r0) || !(p->frame_time > 0.0) || !isfinite(p->frame_time) ||
        !(p->compression > 0.0) || !isfinite(p->compression) || !(p->start >= 0.0) || !isfinite(p->start))
        return WT_ERROR(ctx, WT_ERR_INVALID, "%s: r0 = %g m, frame time %g s, compression %g, start %g s; expected "
                        "finite values, start >= 0 and the others > 0", fn, p->r0, p->frame_time, p->compression,
                        p->start);
    if (p->frames < 1) return WT_ERROR(ctx, WT_ERR_INVALID, "%s: frames = %ld; expected >= 1", fn, p->frames);
    if (p->source == WT_NIGHT_FILE && (!p->file || !*p->file))
        return WT_ERROR(ctx, WT_ERR_INVALID, "%s: a night from a file without a file", fn);
    if (p->source == WT_NIGHT_RANDOM) {
        if (!(p->correlation_time > 0.0) || !isfinite(p->correlation_time) || !(p->step > 0.0) || !isfinite(p->step))
            return WT_ERROR(ctx, WT_ERR_INVALID, "%s: correlation time %g s, step %g s; expected finite values > 0", fn,
                            p->correlation_time, p->step);
        const double r[] = {p->r0_rms, p->fraction_rms, p->wind_speed_rms, p->wind_direction_rms};
        for (int i = 0; i < 4; i++)
            if (!(r[i] >= 0.0) || !(r[i] <= 10.0))
                return WT_ERROR(ctx, WT_ERR_INVALID, "%s: an rms of the stochastic night is %g; expected 0 to 10", fn,
                                r[i]);
    }
    return WT_OK;
}

void wt_night_free(wt_night *n)
{
    if (!n) return;
    wt_context *ctx = n->ctx;
    double *arr[] = {n->t, n->r0, n->f, n->v, n->d, n->f_ref, n->vx_ref, n->vy_ref, n->dx, n->dy, n->scale, n->cur_f,
                     n->cur_v, n->cur_d};
    for (size_t i = 0; i < sizeof arr / sizeof *arr; i++) wt_free(ctx, arr[i]);
    wt_free(ctx, n->line);
    wt_free(ctx, n);
}

int wt_night_alloc(wt_context *ctx, const wt_night_params *p, wt_night **out)
{
    int st = WT_OK;
    wt_night *n = NULL;
    if (!out) return WT_ERROR(ctx, WT_ERR_INVALID, "wt_night_alloc: out is NULL");
    *out = NULL;
    if ((st = check_params(ctx, p)) < 0) return st;
    const int nl = p->nlayers;
    WT_ALLOC(ctx, n, 1, "the night");
    n->ctx = ctx;
    n->nl = nl;
    n->dt = p->frame_time, n->start = p->start, n->compression = p->compression;
    WT_ALLOC(ctx, n->f_ref, nl, "the night's reference");
    WT_ALLOC(ctx, n->vx_ref, nl, "the night's reference");
    WT_ALLOC(ctx, n->vy_ref, nl, "the night's reference");
    WT_ALLOC(ctx, n->dx, nl, "the night's displacements");
    WT_ALLOC(ctx, n->dy, nl, "the night's displacements");
    WT_ALLOC(ctx, n->scale, nl, "the night's screen factors");
    WT_ALLOC(ctx, n->cur_f, nl, "the night's state");
    WT_ALLOC(ctx, n->cur_v, nl, "the night's state");
    WT_ALLOC(ctx, n->cur_d, nl, "the night's state");
    double s = 0.0;
    for (int l = 0; l < nl; l++) s += p->fraction[l];
    n->r0_ref = p->r0;
    for (int l = 0; l < nl; l++) {
        n->f_ref[l] = p->fraction[l] / s; /* as the atmosphere normalises them */
        n->vx_ref[l] = p->wind_speed[l] * cos(p->wind_direction[l]);
        n->vy_ref[l] = p->wind_speed[l] * sin(p->wind_direction[l]);
    }
    if ((st = p->source == WT_NIGHT_FILE ? read_file(n, p) : draw_knots(n, p)) < 0) goto fail;
    /* the run's night times must lie within the knots */
    const double t0 = p->start, t1 = night_end(p);
    const char *src = p->source == WT_NIGHT_FILE ? p->file : "the stochastic night";
    if (!(t0 >= n->t[0]))
        st = WT_ERROR(ctx, WT_ERR_CONFIG, "%s:%d: the night's first state is at %g s, after the run's first night time "
                      "%g s%s%s", src, n->line[0], n->t[0], t0, p->origin ? "; " : "", p->origin ? p->origin : "");
    else if (!(t1 <= n->t[n->nk - 1]))
        st = WT_ERROR(ctx, WT_ERR_CONFIG, "%s:%d: the night's last state is at %g s, before the run's last night time "
                      "%g s (start %g s + (%ld frames - 1) x %g s x compression %g): the night does not cover the "
                      "run%s%s", src, n->line[n->nk - 1], n->t[n->nk - 1], t1, t0, p->frames, p->frame_time,
                      p->compression, p->origin ? "; " : "", p->origin ? p->origin : "");
    if (st < 0) goto fail;
    for (int l = 0; l < nl; l++) n->scale[l] = 1.0;
    n->cur_t = wt_night_time(n, 0);
    if ((st = wt_night_state(n, n->cur_t, &n->cur_r0, n->cur_f, n->cur_v, n->cur_d)) < 0) goto fail;
    *out = n;
    return WT_OK;
fail:
    wt_night_free(n);
    return st;
}

/* ---------------------------------------------------------------------------------------------- */
/* The drive */

int wt_night_nlayers(const wt_night *n) { return n->nl; }
double wt_night_clock(double start, double frame_time, double compression, long frame)
{
    return start + (double)frame * frame_time * compression;
}
double wt_night_time(const wt_night *n, long frame) { return wt_night_clock(n->start, n->dt, n->compression, frame); }

wt_night_sample wt_night_current(const wt_night *n)
{
    return (wt_night_sample){.t = n->cur_t, .r0 = n->cur_r0, .nlayers = n->nl, .fraction = n->cur_f,
                             .wind_speed = n->cur_v, .wind_direction = n->cur_d};
}

/* The state of frame j into cur_*. */
static int state_of(wt_night *n, long j)
{
    n->cur_t = wt_night_time(n, j);
    return wt_night_state(n, n->cur_t, &n->cur_r0, n->cur_f, n->cur_v, n->cur_d);
}

/* D += (v(t_j) − v_ref) Δt with cur_* the state of frame j. */
static void displace(wt_night *n)
{
    for (int l = 0; l < n->nl; l++) {
        n->dx[l] += (n->cur_v[l] * cos(n->cur_d[l]) - n->vx_ref[l]) * n->dt;
        n->dy[l] += (n->cur_v[l] * sin(n->cur_d[l]) - n->vy_ref[l]) * n->dt;
    }
}

int wt_night_drive(wt_night *n, wt_atmosphere *atm, long frame)
{
    if (!n) return WT_ERR_INVALID;
    if (!atm || wt_atmosphere_nlayers(atm) != n->nl)
        return WT_ERROR(n->ctx, WT_ERR_INVALID, "wt_night_drive: an atmosphere of %d layers for a night of %d",
                        atm ? wt_atmosphere_nlayers(atm) : 0, n->nl);
    if (frame < n->next)
        return WT_ERROR(n->ctx, WT_ERR_INVALID, "wt_night_drive: frame %ld after frame %ld: the frames must increase",
                        frame, n->next - 1);
    int st;
    for (; n->next < frame; n->next++) { /* frames skipped: their wind moves the layers all the same */
        if ((st = state_of(n, n->next)) < 0) return st;
        displace(n);
    }
    if ((st = state_of(n, frame)) < 0) return st;
    wt_night_screen_scale(n->nl, n->r0_ref, n->f_ref, n->cur_r0, n->cur_f, n->scale);
    wt_atmosphere_set_drift(atm, n->scale, n->dx, n->dy);
    displace(n); /* the next frame's displacement */
    n->next = frame + 1;
    return WT_OK;
}
