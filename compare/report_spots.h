/* compare/report_spots.h: the pictures of one diffractive sensor, written by `wavetomo info CONFIG
 * --spots DIR` and by `wavetomo compare` beside the report of a diffractive system:
 *   DIR/spots_<SENSOR>.png  the noise-free mean spot image I0 of every valid subaperture in its cell over the
 *                           pupil, truncation frames, the launch (cli/plot.h wt_plot_spots);
 *   DIR/gain_<SENSOR>.png   the centroid gain along the elongation and the truncation per subaperture;
 *   DIR/spots.md            what each picture shows, the configuration and the numbers (median NEA, worst
 *                           truncation, the gain's range).
 * Driver-level (PLplot, files); the numbers come from the sensor's set-up (core/model/sensing.h). */
#ifndef WT_COMPARE_SPOTS_H
#define WT_COMPARE_SPOTS_H

#include "cli/cli.h"

struct wt_system;

/* The first line of DIR/spots.md: a file that starts with it is ours to replace. */
#define WT_SPOTS_SIGNATURE "# wavetomo spot images"

/* The sensor to draw: the one named `name` (case-insensitive; NULL: the first diffractive LGS, else the first
 * diffractive sensor). *index: its index in sys->sensors. WT_ERR_CONFIG with a message naming cfg and the
 * keys when the system has no diffractive sensor, or `name` is not one of them (listing those it has). */
int wt_spots_pick(wt_context *ctx, const struct wt_system *sys, const char *name, int *index);

/* Whether the three files may be written in dir (as the other outputs: not an input, not a foreign file unless
 * --force; a PNG is ours when owner — compare's results.h5 — is a wavetomo output, or, without owner, when
 * dir/spots.md is ours). dir need not exist. */
int wt_spots_check_outputs(wt_cli *cli, const struct wt_system *sys, int index, const char *dir, const char *owner);

/* The sensor at a night time of the truth's sodium sequence (lgs.sodium_sequence), its tables already set to that
 * time's profile (wt_sensing_set_sodium): the pictures then show the spots the truth renders then, and the gain and
 * false slope of the centroider built on the set-up's reference (a static reference) on them. */
typedef struct wt_spots_when {
    double night_s;       /* [s] */
    const char *sequence; /* the file, for the captions */
} wt_spots_when;

/* Write the three files into dir (created with its parents), each atomically (temporary + rename). command:
 * the line spots.md quotes (NULL: `wavetomo info CONFIG --spots DIR`); when: NULL for the set-up's profile and
 * reference. Prints nothing. */
int wt_spots_write(wt_cli *cli, const struct wt_system *sys, int index, const char *dir, const char *command,
                   const wt_spots_when *when);

#endif
