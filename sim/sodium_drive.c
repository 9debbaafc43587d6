/* sim/sodium_drive.c: the truth's LGS spots following a sodium sequence, and the reference that follows
 * them or not (sodium_drive.h). */
#include "sodium_drive.h"

#include <math.h>

#include "../core/model/sensing.h"
#include "../core/optics/sodium.h"
#include "focus_stage.h"
#include "night.h"

struct wt_sodium_drive {
    wt_context *ctx;
    const wt_system *sys;
    wt_sodium_drive_params par;
    wt_sodium_seq *seq;      /* NULL: the set-up profile throughout */
    wt_sodium *na;           /* the profile of the last truth rebuild (the sequence's altitudes) */
    long seq_every, ref_every, gain_every; /* cadences in frames (gain_every 0: no gain estimates) */
    wt_sodium_drive_stats stats;
};

static long frames_of(double night_s, double frame_night)
{
    const long n = lround(night_s / frame_night);
    return n < 1 ? 1 : n;
}

/* a cadence of `every` frames for a mean of one period's frames: at least WT_SENSING_PIXELS_MIN_FRAMES */
static int enough_frames(wt_context *ctx, const char *key, const char *what, double night_s, long every,
                         double frame_night, const char *origin)
{
    if (every >= WT_SENSING_PIXELS_MIN_FRAMES) return WT_OK;
    return WT_ERROR(ctx, WT_ERR_CONFIG,
                    "key '%s' = %g s of night is %ld frame(s) of %g s: %s is made of the mean image of one period's "
                    "frames and needs at least %d; give at least %g s (%s)",
                    key, night_s, every, frame_night, what, WT_SENSING_PIXELS_MIN_FRAMES,
                    WT_SENSING_PIXELS_MIN_FRAMES * frame_night, origin ? origin : "");
}

int wt_sodium_drive_alloc(wt_context *ctx, const wt_system *sys, const wt_sodium_drive_params *par,
                          wt_sodium_drive **out)
{
    int st = WT_OK, nlgs = 0;
    *out = NULL;
    const int has_seq = par->sequence && par->sequence[0];
    for (int m = 0; m < sys->nsensors; m++) nlgs += sys->sensors[m].diffr && sys->sensors[m].kind == WT_SENSOR_LGS;
    if (nlgs == 0 || (!has_seq && par->reference == WT_REFERENCE_STATIC && !(par->gain_update > 0.0))) return WT_OK;
    if (par->reference != WT_REFERENCE_STATIC && par->reference != WT_REFERENCE_ORACLE &&
        par->reference != WT_REFERENCE_PIXELS)
        return WT_ERROR(ctx, WT_ERR_INVALID, "sodium drive: reference kind %d unknown", par->reference);
    const double frame_night = par->frame_time * par->compression;
    if (!(frame_night > 0.0) || par->frames <= par->first_frame ||
        (par->reference != WT_REFERENCE_STATIC && par->reference_update < frame_night * (1.0 - 1e-9)) ||
        par->sequence_update < 0.0 || (par->sequence_update > 0.0 && par->sequence_update < frame_night * (1.0 - 1e-9)) ||
        par->gain_update < 0.0 || (par->gain_update > 0.0 && par->gain_update < frame_night * (1.0 - 1e-9)))
        return WT_ERROR(ctx, WT_ERR_INVALID,
                        "sodium drive: a frame of %g s of night, frames %ld to %ld, cadences %g s (sequence), %g s "
                        "(reference) and %g s (gain): each cadence must be at least a frame (%s)",
                        frame_night, par->first_frame, par->frames, par->sequence_update, par->reference_update,
                        par->gain_update,
                        par->origin ? par->origin : "");
    wt_sodium_drive *d = NULL;
    WT_ALLOC(ctx, d, 1, "sodium drive");
    d->ctx = ctx;
    d->sys = sys;
    d->par = *par;
    d->par.sequence = NULL; /* (not kept) */
    d->seq_every = par->sequence_update > 0.0 ? frames_of(par->sequence_update, frame_night) : 1;
    d->ref_every = frames_of(par->reference_update, frame_night);
    d->gain_every = par->gain_update > 0.0 ? frames_of(par->gain_update, frame_night) : 0;
    if ((par->reference == WT_REFERENCE_PIXELS &&
         (st = enough_frames(ctx, "lgs.wfs.reference_update_s",
                             "the reference from the loop's pixels (lgs.wfs.reference = \"pixels\")",
                             par->reference_update, d->ref_every, frame_night, par->origin)) < 0) ||
        (d->gain_every > 0 && (st = enough_frames(ctx, "lgs.wfs.gain_update_s", "the matched filter's gain",
                                                  par->gain_update, d->gain_every, frame_night, par->origin)) < 0))
        goto fail;
    if (d->gain_every > 0)
        for (int m = 0; m < sys->nsensors; m++)
            if (sys->sensors[m].diffr && sys->sensors[m].kind == WT_SENSOR_LGS &&
                (st = wt_sensing_gain_start(sys->sensors[m].diffr)) < 0)
                goto fail;
    if (par->reference == WT_REFERENCE_PIXELS)
        for (int m = 0; m < sys->nsensors; m++)
            if (sys->sensors[m].diffr && sys->sensors[m].kind == WT_SENSOR_LGS &&
                (st = wt_sensing_pixels_start(sys->sensors[m].diffr)) < 0)
                goto fail;
    if (has_seq) {
        WT_TRY(wt_sodium_seq_read(ctx, par->sequence, &d->seq));
        const double t0 = wt_night_clock(par->start, par->frame_time, par->compression, par->first_frame);
        const double t1 = wt_night_clock(par->start, par->frame_time, par->compression, par->frames - 1);
        WT_TRY(wt_sodium_seq_check_covers(ctx, d->seq, t0, t1, par->origin ? par->origin : "the run"));
        WT_TRY(wt_sodium_seq_profile(ctx, d->seq, t0, &d->na));
        for (int m = 0; m < sys->nsensors; m++) {
            const wt_sensor *s = &sys->sensors[m];
            if (!s->diffr || s->kind != WT_SENSOR_LGS) continue;
            if ((st = wt_sodium_check_covers(ctx, d->na, s->altitude, par->sequence)) < 0) {
                st = WT_ERROR(ctx, WT_ERR_CONFIG, "key 'lgs.sodium_sequence' = \"%s\" (%s): %s", par->sequence, s->name,
                              wt_error_message(ctx));
                goto fail;
            }
        }
    }
    *out = d;
    return WT_OK;
fail:
    wt_sodium_drive_free(d);
    return st;
}

int wt_sodium_drive_frame(wt_sodium_drive *d, long frame, wt_reconstructor *rec, wt_focus_stage *stage)
{
    const wt_system *sys = d->sys;
    const long j = frame - d->par.first_frame;
    int st = WT_OK;
    if (d->seq && j % d->seq_every == 0) {
        const double t0 = wt_time_now();
        const double t = wt_night_clock(d->par.start, d->par.frame_time, d->par.compression, frame);
        if ((st = wt_sodium_seq_at(d->seq, t, d->na)) < 0) return st;
        if (stage && j > 0) wt_focus_stage_move(stage);
        for (int m = 0; m < sys->nsensors; m++) {
            double sg[3];
            wt_focus_stage_terms(stage, m, sg);
            if (sys->sensors[m].diffr && sys->sensors[m].kind == WT_SENSOR_LGS &&
                (st = wt_sensing_set_sodium_staged(sys->sensors[m].diffr, d->na, sg)) < 0)
                return st;
        }
        d->stats.truth_rebuilds++;
        d->stats.truth_seconds += wt_time_now() - t0;
    }
    const int pixels = d->par.reference == WT_REFERENCE_PIXELS;
    if ((d->par.reference == WT_REFERENCE_ORACLE || (pixels && j > 0)) && j % d->ref_every == 0) {
        const double t0 = wt_time_now();
        for (int m = 0; m < sys->nsensors; m++)
            if (sys->sensors[m].diffr && sys->sensors[m].kind == WT_SENSOR_LGS &&
                (st = pixels ? wt_sensing_pixels_reference(sys->sensors[m].diffr)
                             : wt_sensing_rebuild_reference(sys->sensors[m].diffr)) < 0)
                return st;
        const double t1 = wt_time_now();
        if (rec && (st = wt_reconstructor_refresh_noise(rec)) < 0) return st;
        d->stats.reference_rebuilds++;
        d->stats.reference_seconds += wt_time_now() - t0;
        d->stats.c_e_seconds += wt_time_now() - t1;
    }
    if (d->gain_every > 0 && j > 0 && j % d->gain_every == 0) {
        const double t0 = wt_time_now();
        double sa = 0.0, sc = 0.0;
        int n = 0;
        for (int m = 0; m < sys->nsensors; m++) {
            double a = 0.0, c = 0.0;
            /* a loop that does not sense (the budget's runs of a perfect tomography) has no frames to measure */
            if (!sys->sensors[m].diffr || sys->sensors[m].kind != WT_SENSOR_LGS || sys->sensors[m].diffr->gain_frames == 0)
                continue;
            if ((st = wt_sensing_gain_update(sys->sensors[m].diffr, &a, &c)) < 0)
                return WT_ERROR(d->ctx, st, "%s, frame %ld: %s", sys->sensors[m].name, frame, wt_error_message(d->ctx));
            sa += a, sc += c, n++;
        }
        if (n > 0) {
            if (rec && (st = wt_reconstructor_refresh_noise(rec)) < 0) return st;
            d->stats.gain_updates++;
            d->stats.gain_seconds += wt_time_now() - t0;
            d->stats.gain_along = sa / n, d->stats.gain_across = sc / n;
        }
    }
    return WT_OK;
}

wt_sodium_drive_stats wt_sodium_drive_get_stats(const wt_sodium_drive *d)
{
    wt_sodium_drive_stats s = d->stats;
    for (int m = 0; m < d->sys->nsensors; m++) {
        const wt_sensing *ws = d->sys->sensors[m].diffr;
        if (d->par.reference == WT_REFERENCE_PIXELS && ws) s.accumulate_seconds += ws->pix_seconds;
        if (d->gain_every > 0 && ws) s.gain_accumulate_seconds += ws->gain_seconds;
    }
    return s;
}

void wt_sodium_drive_free(wt_sodium_drive *d)
{
    if (!d) return;
    for (int m = 0; m < d->sys->nsensors; m++) {
        wt_sensing *ws = d->sys->sensors[m].diffr;
        if (ws && wt_sensing_restore(ws) < 0)
            wt_log(d->ctx, WT_LOG_WARN, "sodium drive: %s could not be restored to its set-up reference: %s",
                   d->sys->sensors[m].name, wt_error_message(d->ctx));
    }
    wt_sodium_seq_free(d->seq);
    wt_sodium_free(d->na);
    wt_free(d->ctx, d);
}
