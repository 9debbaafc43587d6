/* runtime/rtc.c: the per-frame reconstructor API (include/wavetomo/rtc.h): set-up from a configuration
 * or a stored MVM, then frames of pseudo-open-loop control around the reconstructors of core/model and
 * the MVM of core/solve. The numerics are theirs; this file checks the boundary. The control law (the delay's
 * command queue, the integrator with loop.gain or the scale-dependent loop.gain_levels) is runtime/control.h's,
 * the one sim/loop.c steps. An instance is a state (one loop) on a counted, read-only plan that
 * wt_rtc_share lets several states hold: one R in memory for several loops or threads. */
#include "rtc_internal.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "../core/io/h5.h"
#include "control.h"
#include "../core/model/interaction.h"
#include "../core/model/params.h"
#include "../core/model/reconstructor.h"
#include "../core/solve/mvm.h"

/* The plan: what several loops may share (FFTW's plan to their executes), read-only once built: the system,
 * Â's operator (its workspace is each state's) and the stored R and RÂ. Counted: every instance holds it,
 * the last close frees it, with the context it was built with. Built and released from one thread at a time
 * (as open and close). pcg3 / cg9 keep their operators in the state: their tomography, preconditioner and
 * fitting carry per-solve workspace and the warm start beside the matrices. */
typedef struct rtc_plan {
    int refs;
    wt_context *ctx;        /* the context of the open that built it (its allocator frees the plan) */
    wt_config *own_cfg;     /* parsed by a public open; NULL when the caller's */
    wt_system *own_sys;     /* built by a public open; NULL when the caller's */
    const wt_system *sys;
    int kind;               /* WT_RECON_PCG3, _CG9, _MVM or _NONE */
    char recon[16];         /* "pcg3", "cg9", "mvm-pcg3", "mvm-cg9", "none" */
    int iterations;         /* pcg3 / cg9: the (P)CG count of every state's reconstructor (< 0: the variant's) */
    wt_interaction *ia;     /* Â (s_ol = s + Â a_t; wt_rtc_interaction); NULL for an only-OL instance */
    wt_mvm *mvm;            /* the MVM: R and R Â */
} rtc_plan;

/* One loop on a plan: its control law, warm start and workspace. */
struct wt_rtc {
    wt_context *ctx;
    rtc_plan *plan;
    const wt_system *sys;   /* the plan's, as are the next four */
    const wt_interaction *ia;
    const wt_mvm *mvm;
    int64_t ns, na;
    wt_reconstructor *rec;  /* pcg3 / cg9 / none (r = 0): this loop's operators and warm start */
    double *ia_grids, *ia_phase; /* Â's workspace */
    wt_control *ctl;        /* the control law; its clock counts the POLC frames (WT_RTC_RAW frames do not tick) */
    int64_t frames;         /* all frames since open or reset (named in messages) */
    double *s, *a, *r;      /* the frame in double: slopes (then s_ol), applied a_t, reconstruction r (and the
                             * f32 entry's commands) */
    float *sf, *af, *rf;    /* float32: the MVM's GEMV operands, the f32 entry's conversions */
    double frame_time;      /* wall time of the last frame [s] */
};

static const char *nonfinite(double v) { return isnan(v) ? "NaN" : "Inf"; }

/* "slope 17 (LGS2 s_y of valid subaperture 5)": what index i of a frame is */
static void describe_slope(const wt_system *sys, int64_t i, char *buf, size_t n)
{
    for (int m = 0; m < sys->nsensors; m++) {
        const wt_sensor *s = &sys->sensors[m];
        if (i < s->offset || i >= s->offset + s->nslopes) continue;
        const int64_t k = i - s->offset;
        snprintf(buf, n, "%s s_%c of valid subaperture %lld", s->name, k < s->nsub ? 'x' : 'y',
                 (long long)(k < s->nsub ? k : k - s->nsub));
        return;
    }
    snprintf(buf, n, "?");
}

static void describe_actuator(const wt_system *sys, int64_t i, char *buf, size_t n)
{
    const wt_dm *dm = sys->dm;
    for (int k = 0; k < dm->ndms; k++)
        if (i >= dm->offset[k] && i < dm->offset[k] + dm->nactive[k]) {
            snprintf(buf, n, "DM %d active actuator %lld", k + 1, (long long)(i - dm->offset[k]));
            return;
        }
    snprintf(buf, n, "?");
}

static void plan_release(rtc_plan *p)
{
    if (!p || --p->refs > 0) return;
    wt_context *ctx = p->ctx;
    wt_interaction_free(p->ia);
    wt_mvm_free(p->mvm);
    wt_system_free(p->own_sys);
    wt_config_free(ctx, p->own_cfg);
    wt_free(ctx, p);
}

/* A loop on plan p (taking a reference to it), its state allocated with ctx. */
static int state_alloc(wt_context *ctx, rtc_plan *p, wt_rtc **out)
{
    int st = WT_OK;
    wt_rtc *rtc = NULL;
    *out = NULL;
    WT_ALLOC(ctx, rtc, 1, "per-frame reconstructor");
    rtc->ctx = ctx;
    rtc->sys = p->sys;
    rtc->ia = p->ia;
    rtc->mvm = p->mvm;
    rtc->ns = p->sys->nslopes;
    rtc->na = p->sys->nact;
    if (p->kind != WT_RECON_MVM) {
        wt_reconstructor_params rp;
        wt_reconstructor_params_from_config(p->sys->cfg, p->kind, p->iterations, &rp);
        WT_TRY(wt_reconstructor_alloc(ctx, p->sys, p->kind, &rp, &rtc->rec));
    }
    if (p->ia) {
        WT_ALLOC(ctx, rtc->ia_grids, wt_interaction_grids_size(p->ia), "interaction workspace");
        WT_ALLOC(ctx, rtc->ia_phase, wt_interaction_phase_size(p->ia), "interaction workspace");
    }
    {
        wt_control_params cp = wt_control_params_from_config(p->sys->cfg);
        cp.direct = rtc->rec && wt_reconstructor_integrates(rtc->rec);
        WT_TRY(wt_control_alloc(ctx, p->sys, &cp, &rtc->ctl));
    }
    WT_ALLOC(ctx, rtc->s, rtc->ns, "slopes");
    WT_ALLOC(ctx, rtc->a, rtc->na, "applied commands");
    WT_ALLOC(ctx, rtc->r, rtc->na, "reconstruction");
    WT_ALLOC(ctx, rtc->sf, rtc->ns, "float32 slopes");
    WT_ALLOC(ctx, rtc->af, rtc->na, "float32 applied commands");
    WT_ALLOC(ctx, rtc->rf, rtc->na, "float32 reconstruction");
    rtc->plan = p;
    p->refs++;
    *out = rtc;
    return WT_OK;
fail:
    wt_rtc_close(rtc);
    return st;
}

int wt_rtc_open_system(wt_context *ctx, const wt_system *sys, int kind, const char *matrix, int iterations,
                       int only_ol, wt_rtc **out)
{
    int st = WT_OK;
    rtc_plan *p = NULL;
    if (!out) return WT_ERROR(ctx, WT_ERR_INVALID, "wt_rtc_open: no place for the instance (out is NULL)");
    *out = NULL;
    if (!ctx || !sys) return WT_ERROR(ctx, WT_ERR_INVALID, "wt_rtc_open: NULL context or system");
    if (kind != WT_RECON_PCG3 && kind != WT_RECON_CG9 && kind != WT_RECON_MVM && kind != WT_RECON_NONE)
        return WT_ERROR(ctx, WT_ERR_INVALID, "wt_rtc_open: reconstructor %s: expected pcg3, cg9, none or a stored MVM",
                        wt_reconstructor_name(kind));
    if ((kind == WT_RECON_MVM) != (matrix != NULL))
        return WT_ERROR(ctx, WT_ERR_INVALID, "wt_rtc_open: %s", matrix ? "a matrix file is for the MVM only"
                                                                       : "the MVM needs its matrix file");
    { /* (as the simulator's loop: the matrix holds the predictor, the commands' integrator runs on it) */
        const int e = wt_reconstructor_check_mvm_predict(ctx, sys->cfg, kind, 0);
        if (e < 0) return e;
    }
    WT_ALLOC(ctx, p, 1, "per-frame reconstructor's plan");
    p->refs = 1; /* this function's, released below: the state holds the plan from then on */
    p->ctx = ctx;
    p->sys = sys;
    p->kind = kind;
    p->iterations = iterations;
    if (kind == WT_RECON_MVM) {
        char variant[16] = "";
        WT_TRY(wt_mvm_read(ctx, matrix, sys->cfg, sys->nact, sys->nslopes, &p->mvm, variant));
        snprintf(p->recon, sizeof p->recon, "mvm-%.8s", variant);
    } else {
        snprintf(p->recon, sizeof p->recon, "%s", wt_reconstructor_name(kind));
    }
    /* Â: the POLC term of pcg3 / cg9 frames, and wt_rtc_interaction for every kind (the MVM's frames use R Â) */
    if (!only_ol) WT_TRY(wt_interaction_alloc(ctx, sys, &p->ia));
    st = state_alloc(ctx, p, out);
fail:
    plan_release(p);
    return st;
}

int wt_rtc_share(wt_context *ctx, const wt_rtc *src, wt_rtc **out)
{
    if (!out) return WT_ERROR(ctx, WT_ERR_INVALID, "wt_rtc_share: no place for the instance (out is NULL)");
    *out = NULL;
    if (!ctx) return WT_ERR_INVALID; /* nowhere to say why */
    if (!src) return WT_ERROR(ctx, WT_ERR_INVALID, "wt_rtc_share: no instance to share (src is NULL)");
    return state_alloc(ctx, src->plan, out);
}

/* The public opens: the system of a parsed configuration, then the instance on it, which owns both. */
static int open_owned(wt_context *ctx, wt_config *cfg, int kind, const char *matrix, wt_rtc **out)
{
    wt_system *sys = NULL;
    int st = wt_system_alloc(ctx, cfg, &sys);
    if (st >= 0) st = wt_rtc_open_system(ctx, sys, kind, matrix, -1, 0, out);
    if (st < 0) {
        wt_system_free(sys);
        wt_config_free(ctx, cfg);
        return st;
    }
    (*out)->plan->own_sys = sys;
    (*out)->plan->own_cfg = cfg;
    return st;
}

static int recon_kind(wt_context *ctx, const char *recon, int *kind)
{
    *kind = recon ? wt_reconstructor_kind(recon) : -1;
    if (*kind == WT_RECON_PCG3 || *kind == WT_RECON_CG9 || *kind == WT_RECON_NONE) return WT_OK;
    return WT_ERROR(ctx, WT_ERR_INVALID,
                    "wt_rtc_open: reconstructor '%s': expected \"pcg3\" or \"cg9\" (or \"none\": the system alone)%s",
                    recon ? recon : "(NULL)", *kind == WT_RECON_MVM ? " (open a stored MVM with wt_rtc_open_mvm)" : "");
}

static int check_open_args(wt_context *ctx, const void *what, const char *name, int nset, const char *const *set,
                           wt_rtc **out)
{
    if (!out) return WT_ERROR(ctx, WT_ERR_INVALID, "wt_rtc_open: no place for the instance (out is NULL)");
    *out = NULL;
    if (!ctx) return WT_ERR_INVALID; /* nowhere to say why */
    if (!what) return WT_ERROR(ctx, WT_ERR_INVALID, "wt_rtc_open: no %s given (NULL)", name);
    if (nset < 0 || (nset > 0 && !set))
        return WT_ERROR(ctx, WT_ERR_INVALID, "wt_rtc_open: %d overrides but %s", nset,
                        nset < 0 ? "a negative count" : "no array (NULL)");
    return WT_OK;
}

int wt_rtc_open(wt_context *ctx, const char *recon, const char *config_file, int nset, const char *const *set,
                wt_rtc **out)
{
    int st, kind;
    wt_config *cfg = NULL;
    if ((st = check_open_args(ctx, config_file, "configuration file", nset, set, out)) < 0) return st;
    if ((st = recon_kind(ctx, recon, &kind)) < 0) return st;
    if ((st = wt_config_read(ctx, config_file, nset, set, &cfg)) < 0) return st;
    return open_owned(ctx, cfg, kind, NULL, out);
}

int wt_rtc_open_text(wt_context *ctx, const char *recon, const char *config_text, int nset,
                     const char *const *set, wt_rtc **out)
{
    int st, kind;
    wt_config *cfg = NULL;
    if ((st = check_open_args(ctx, config_text, "configuration text", nset, set, out)) < 0) return st;
    if ((st = recon_kind(ctx, recon, &kind)) < 0) return st;
    if ((st = wt_config_parse(ctx, config_text, "(configuration text)", nset, set, &cfg)) < 0) return st;
    return open_owned(ctx, cfg, kind, NULL, out);
}

int wt_rtc_open_mvm(wt_context *ctx, const char *matrix_file, const char *config_file, int nset,
                    const char *const *set, wt_rtc **out)
{
    int st;
    wt_config *cfg = NULL;
    if ((st = check_open_args(ctx, matrix_file, "matrix file", nset, set, out)) < 0) return st;
    if (config_file) {
        if ((st = wt_config_read(ctx, config_file, nset, set, &cfg)) < 0) return st;
    } else {
        /* the configuration the matrix was built with (its provenance, dataset "config") */
        wt_h5_reader *r = NULL;
        char *text = NULL, name[1100];
        if ((st = wt_h5_open(ctx, matrix_file, &r)) < 0) return st;
        st = wt_h5_read_string(r, "config", &text);
        wt_h5_close(r);
        if (st < 0) return st;
        snprintf(name, sizeof name, "%s:config", matrix_file);
        st = wt_config_parse(ctx, text, name, nset, set, &cfg);
        wt_free(ctx, text);
        if (st < 0) return st;
    }
    return open_owned(ctx, cfg, WT_RECON_MVM, matrix_file, out);
}

void wt_rtc_close(wt_rtc *rtc)
{
    if (!rtc) return;
    wt_context *ctx = rtc->ctx;
    wt_control_free(rtc->ctl);
    wt_free(ctx, rtc->s);
    wt_free(ctx, rtc->a);
    wt_free(ctx, rtc->r);
    wt_free(ctx, rtc->sf);
    wt_free(ctx, rtc->af);
    wt_free(ctx, rtc->rf);
    wt_free(ctx, rtc->ia_grids);
    wt_free(ctx, rtc->ia_phase);
    wt_reconstructor_free(rtc->rec);
    plan_release(rtc->plan);
    wt_free(ctx, rtc);
}

void wt_rtc_reset(wt_rtc *rtc)
{
    if (!rtc) return;
    wt_control_reset(rtc->ctl);
    if (rtc->rec) wt_reconstructor_reset(rtc->rec), wt_reconstructor_reset_integrator(rtc->rec);
    rtc->frames = 0;
    rtc->frame_time = 0.0;
}

/* The boundary of a frame: the instance, the buffers, their sizes, the flags. */
static int check_frame(wt_rtc *rtc, const void *slopes, int64_t nslopes, unsigned flags, const void *commands,
                       int64_t nactuators)
{
    if (!rtc) return WT_ERR_INVALID; /* no context to say why */
    if (!slopes || !commands)
        return WT_ERROR(rtc->ctx, WT_ERR_INVALID, "frame %lld: %s buffer is NULL", (long long)rtc->frames,
                        slopes ? "the commands" : "the slopes");
    if (nslopes != rtc->ns || nactuators != rtc->na)
        return WT_ERROR(rtc->ctx, WT_ERR_INVALID,
                        "frame %lld: %lld slopes and %lld commands given, the system (%s) has %lld slopes and %lld "
                        "commands",
                        (long long)rtc->frames, (long long)nslopes, (long long)nactuators, rtc->sys->source,
                        (long long)rtc->ns, (long long)rtc->na);
    if (flags & ~(unsigned)(WT_RTC_RAW | WT_RTC_SLOPES_OL))
        return WT_ERROR(rtc->ctx, WT_ERR_INVALID, "frame %lld: unknown flags 0x%x", (long long)rtc->frames,
                        flags & ~(unsigned)(WT_RTC_RAW | WT_RTC_SLOPES_OL));
    if (rtc->rec && !rtc->ia && !(flags & WT_RTC_SLOPES_OL))
        return WT_ERROR(rtc->ctx, WT_ERR_INVALID,
                        "frame %lld: this instance was opened for pseudo-open-loop slopes only (WT_RTC_SLOPES_OL)",
                        (long long)rtc->frames);
    return WT_OK;
}

#define CHECK_FINITE(rtc, x, n, what, describe)                                                                 \
    do {                                                                                                      \
        for (int64_t i_ = 0; i_ < (n); i_++)                                                                  \
            if (!isfinite((x)[i_])) {                                                                         \
                char d_[96];                                                                                  \
                describe((rtc)->sys, i_, d_, sizeof d_);                                                      \
                return WT_ERROR((rtc)->ctx, WT_ERR_NUMERIC, "frame %lld: %s %lld (%s) is %s",                 \
                                (long long)(rtc)->frames, (what), (long long)i_, d_, nonfinite((double)(x)[i_])); \
            }                                                                                                 \
    } while (0)

/* After r (double, na) of a frame with a_t: the commands of the frame (RAW: r itself; else the control law's
 * a_{t+d}, queued) */
static const double *finish(wt_rtc *rtc, const double *a_t, unsigned flags)
{
    if (flags & WT_RTC_RAW) return rtc->r;
    return wt_control_step(rtc->ctl, rtc->r, a_t);
}

/* r = R s_ol in double for the iterative reconstructors; s (the caller's slopes, or rtc->s holding a
 * converted copy) and a_t. */
static int reconstruct(wt_rtc *rtc, const double *s, const double *a_t, unsigned flags)
{
    if (s != rtc->s) memcpy(rtc->s, s, (size_t)rtc->ns * sizeof *rtc->s);
    if (!(flags & WT_RTC_SLOPES_OL))
        wt_interaction_apply_ws(rtc->ia, 1.0, a_t, rtc->s, rtc->ia_grids, rtc->ia_phase, wt_context_threads(rtc->ctx));
    return wt_reconstructor_apply(rtc->rec, rtc->s, rtc->r);
}

int wt_rtc_frame(wt_rtc *rtc, const double *slopes, int64_t nslopes, const double *applied, unsigned flags,
                 double *commands, int64_t nactuators)
{
    int st = check_frame(rtc, slopes, nslopes, flags, commands, nactuators);
    if (st < 0) return st;
    const double t0 = wt_time_now();
    CHECK_FINITE(rtc, slopes, rtc->ns, "slope", describe_slope);
    if (applied) CHECK_FINITE(rtc, applied, rtc->na, "applied command", describe_actuator);
    const double *a_t = applied ? applied : wt_control_applied(rtc->ctl);
    if (rtc->mvm) {
        /* r = R s + (R Â) a_t in float32, the stored POLC form (`wavetomo run`), or R s_ol */
        for (int64_t i = 0; i < rtc->ns; i++) rtc->sf[i] = (float)slopes[i];
        if (!(flags & WT_RTC_SLOPES_OL))
            for (int64_t k = 0; k < rtc->na; k++) rtc->af[k] = (float)a_t[k];
        wt_mvm_apply(rtc->mvm, rtc->sf, (flags & WT_RTC_SLOPES_OL) ? NULL : rtc->af, rtc->rf);
        for (int64_t k = 0; k < rtc->na; k++) rtc->r[k] = rtc->rf[k];
    } else if ((st = reconstruct(rtc, slopes, a_t, flags)) < 0) {
        return st;
    }
    const double *c = finish(rtc, a_t, flags);
    memcpy(commands, c, (size_t)rtc->na * sizeof *commands);
    rtc->frames++;
    rtc->frame_time = wt_time_now() - t0;
    return st;
}

int wt_rtc_frame_f32(wt_rtc *rtc, const float *slopes, int64_t nslopes, const float *applied, unsigned flags,
                     float *commands, int64_t nactuators)
{
    int st = check_frame(rtc, slopes, nslopes, flags, commands, nactuators);
    if (st < 0) return st;
    const double t0 = wt_time_now();
    CHECK_FINITE(rtc, slopes, rtc->ns, "slope", describe_slope);
    if (applied) CHECK_FINITE(rtc, applied, rtc->na, "applied command", describe_actuator);
    const int polc_term = !(flags & WT_RTC_SLOPES_OL);
    if (rtc->mvm && (flags & WT_RTC_RAW) && (applied || !polc_term)) {
        /* the caller's floats straight into the GEMVs: R s + (R Â) a, or R s_ol (`wavetomo run --matrix`) */
        wt_mvm_apply(rtc->mvm, slopes, polc_term ? applied : NULL, commands);
        rtc->frames++;
        rtc->frame_time = wt_time_now() - t0;
        return WT_OK;
    }
    /* otherwise the double frame on converted copies (the queue holds doubles) */
    const double *a_t = wt_control_applied(rtc->ctl);
    if (applied) {
        for (int64_t k = 0; k < rtc->na; k++) rtc->a[k] = applied[k];
        a_t = rtc->a;
    }
    if (rtc->mvm) {
        if (polc_term)
            for (int64_t k = 0; k < rtc->na; k++) rtc->af[k] = (float)a_t[k];
        wt_mvm_apply(rtc->mvm, slopes, polc_term ? rtc->af : NULL, rtc->rf);
        for (int64_t k = 0; k < rtc->na; k++) rtc->r[k] = rtc->rf[k];
    } else {
        for (int64_t i = 0; i < rtc->ns; i++) rtc->s[i] = slopes[i];
        if ((st = reconstruct(rtc, rtc->s, a_t, flags)) < 0) return st;
    }
    const double *c = finish(rtc, a_t, flags);
    for (int64_t k = 0; k < rtc->na; k++) commands[k] = (float)c[k];
    rtc->frames++;
    rtc->frame_time = wt_time_now() - t0;
    return st;
}

/* The boundary of an interaction call: the operator was built, the sizes are the system's, the input is
 * finite (the frame's checks and messages). */
static int check_interaction(wt_rtc *rtc, const char *fn, const void *in, int64_t nin, int64_t want_in, const void *out,
                             int64_t nout, int64_t want_out)
{
    if (!rtc) return WT_ERR_INVALID; /* no context to say why */
    if (!rtc->ia)
        return WT_ERROR(rtc->ctx, WT_ERR_INVALID, "%s: this instance was opened for pseudo-open-loop slopes only (no Â)",
                        fn);
    if (!in || !out) return WT_ERROR(rtc->ctx, WT_ERR_INVALID, "%s: %s buffer is NULL", fn, in ? "the output" : "the input");
    if (nin != want_in || nout != want_out)
        return WT_ERROR(rtc->ctx, WT_ERR_INVALID, "%s: %lld values in and %lld out given, the system (%s) needs %lld and %lld",
                        fn, (long long)nin, (long long)nout, rtc->sys->source, (long long)want_in, (long long)want_out);
    return WT_OK;
}

/* Refuses the first NaN/Inf of an input of n values, naming it as a slope or a command (0: all finite). */
static int check_finite(wt_rtc *rtc, const char *fn, const double *v, int64_t n, int slopes)
{
    for (int64_t i = 0; i < n; i++)
        if (!isfinite(v[i])) {
            char d[96];
            if (slopes) describe_slope(rtc->sys, i, d, sizeof d);
            else describe_actuator(rtc->sys, i, d, sizeof d);
            return WT_ERROR(rtc->ctx, WT_ERR_NUMERIC, "%s: %s %lld (%s) is %s", fn, slopes ? "slope" : "command",
                            (long long)i, d, nonfinite(v[i]));
        }
    return WT_OK;
}

int wt_rtc_interaction(wt_rtc *rtc, const double *commands, int64_t nactuators, double *slopes, int64_t nslopes)
{
    int st = check_interaction(rtc, "wt_rtc_interaction", commands, nactuators, rtc ? rtc->na : 0, slopes, nslopes,
                               rtc ? rtc->ns : 0);
    if (st < 0 || (st = check_finite(rtc, "wt_rtc_interaction", commands, rtc->na, 0)) < 0) return st;
    /* s = 0 + Â a: the frame's s_ol = s + Â a_t with s = 0, in the same operations */
    memset(slopes, 0, (size_t)rtc->ns * sizeof *slopes);
    wt_interaction_apply_ws(rtc->ia, 1.0, commands, slopes, rtc->ia_grids, rtc->ia_phase, wt_context_threads(rtc->ctx));
    return WT_OK;
}

int wt_rtc_interaction_t(wt_rtc *rtc, const double *slopes, int64_t nslopes, double *commands, int64_t nactuators)
{
    int st = check_interaction(rtc, "wt_rtc_interaction_t", slopes, nslopes, rtc ? rtc->ns : 0, commands, nactuators,
                               rtc ? rtc->na : 0);
    if (st < 0 || (st = check_finite(rtc, "wt_rtc_interaction_t", slopes, rtc->ns, 1)) < 0) return st;
    memset(commands, 0, (size_t)rtc->na * sizeof *commands);
    wt_interaction_apply_t_ws(rtc->ia, 1.0, slopes, commands, rtc->ia_grids, rtc->ia_phase);
    return WT_OK;
}

const char *wt_rtc_config(const wt_rtc *rtc) { return rtc->sys->cfg->canonical; }

int64_t wt_rtc_nslopes(const wt_rtc *rtc) { return rtc->ns; }
int64_t wt_rtc_nactuators(const wt_rtc *rtc) { return rtc->na; }
int wt_rtc_nsensors(const wt_rtc *rtc) { return rtc->sys->nsensors; }
int wt_rtc_ndms(const wt_rtc *rtc) { return rtc->sys->dm->ndms; }
const char *wt_rtc_recon(const wt_rtc *rtc) { return rtc->plan->recon; }
int wt_rtc_delay(const wt_rtc *rtc) { return wt_control_delay(rtc->ctl); }
double wt_rtc_gain(const wt_rtc *rtc) { return wt_control_gain(rtc->ctl); }
double wt_rtc_rate(const wt_rtc *rtc) { return rtc->sys->cfg->rate; }
int64_t wt_rtc_frames(const wt_rtc *rtc) { return rtc->frames; }
double wt_rtc_frame_time(const wt_rtc *rtc) { return rtc->frame_time; }

int wt_rtc_sensor_info(const wt_rtc *rtc, int m, wt_rtc_sensor *info)
{
    if (m < 0 || m >= rtc->sys->nsensors || !info)
        return WT_ERROR(rtc->ctx, WT_ERR_INVALID, "wt_rtc_sensor_info: sensor %d of %d%s", m, rtc->sys->nsensors,
                        info ? "" : " (info is NULL)");
    const wt_sensor *s = &rtc->sys->sensors[m];
    memset(info, 0, sizeof *info);
    snprintf(info->name, sizeof info->name, "%s", s->name);
    info->kind = s->kind == WT_SENSOR_LGS ? WT_RTC_LGS : WT_RTC_NGS;
    info->nsub = s->nsub;
    info->offset = s->offset;
    info->theta_x = s->theta_x;
    info->theta_y = s->theta_y;
    info->altitude = s->altitude;
    return WT_OK;
}

int wt_rtc_subapertures(const wt_rtc *rtc, int m, double *xy)
{
    if (m < 0 || m >= rtc->sys->nsensors || !xy)
        return WT_ERROR(rtc->ctx, WT_ERR_INVALID, "wt_rtc_subapertures: sensor %d of %d%s", m, rtc->sys->nsensors,
                        xy ? "" : " (xy is NULL)");
    const wt_sensor *s = &rtc->sys->sensors[m];
    for (int k = 0; k < s->nsub; k++) wt_shack_hartmann_centre(s->sh, k, &xy[2 * k], &xy[2 * k + 1]);
    return WT_OK;
}

int wt_rtc_dm_info(const wt_rtc *rtc, int k, wt_rtc_dm *info)
{
    const wt_dm *dm = rtc->sys->dm;
    if (k < 0 || k >= dm->ndms || !info)
        return WT_ERROR(rtc->ctx, WT_ERR_INVALID, "wt_rtc_dm_info: DM %d of %d%s", k, dm->ndms,
                        info ? "" : " (info is NULL)");
    memset(info, 0, sizeof *info);
    info->altitude = dm->altitude[k];
    info->pitch = dm->grid[k].dx;
    info->nactive = dm->nactive[k];
    info->offset = dm->offset[k];
    info->nx = dm->grid[k].nx;
    info->ny = dm->grid[k].ny;
    info->x0 = dm->grid[k].x0;
    info->y0 = dm->grid[k].y0;
    return WT_OK;
}

/* The command order of core/op/dm.h: DM by DM, active actuators in grid-index order (as the "layout"
 * group of the output files, cli/output.c). */
int wt_rtc_actuators(const wt_rtc *rtc, double *xy, int32_t *index)
{
    if (!xy) return WT_ERROR(rtc->ctx, WT_ERR_INVALID, "wt_rtc_actuators: xy is NULL");
    const wt_dm *dm = rtc->sys->dm;
    int64_t q = 0;
    for (int k = 0; k < dm->ndms; k++) {
        const wt_grid *g = &dm->grid[k];
        for (int iy = 0; iy < g->ny; iy++)
            for (int ix = 0; ix < g->nx; ix++) {
                if (!dm->active[k][ix + (int64_t)g->nx * iy]) continue;
                xy[2 * q] = g->x0 + ix * g->dx;
                xy[2 * q + 1] = g->y0 + iy * g->dx;
                if (index) index[3 * q] = k, index[3 * q + 1] = ix, index[3 * q + 2] = iy;
                q++;
            }
    }
    return WT_OK;
}
