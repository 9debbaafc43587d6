/* core/config/config_private.h: what the two files of the configuration reader share (SPEC §1, §9; see
 * config.h).
 *
 * Private to the files of core/config: config_schema.c (the key table and the printed reference), config_read.c
 * (reading, --set overrides, the typed keys), config_check.c (the cross-key checks and the values chosen from
 * several keys), config_canonical.c (the canonical text and the matrix identity), config_state.c (the parse
 * state's helpers), config_atmosphere.c, config_derived.c, config_grid.c and config_text.c; included by nothing else.
 */
#ifndef WT_CONFIG_PRIVATE_H
#define WT_CONFIG_PRIVATE_H

#include "config.h"

#include <libconfig.h>
#include <stddef.h>

enum { K_INT, K_INT64, K_FLOAT, K_BOOL, K_ENUM, K_FLOATS, K_INTS, K_STR /* a path: char[1024] */ };
/* F_OPT: may be absent (then `def` is stored and the key is left out of the canonical text);
 * F_DEFAULT: may be absent, and then behaves exactly as if `def` had been written in the file (it appears
 * in the canonical text and the matrix hash, so a later change of default is seen by stored matrices). */
/* F_AUTO: may be absent or "auto" (layer grids, sensor points, the sodium profile's hash); then config_grid.c chooses the value from the system
 * and it is written into the canonical text and the matrix hash as if the file had given it. */
/* F_HEX: a K_STR that is not a path but 64 hexadecimal digits (a SHA-256), stored in a char[65]. */
/* F_EVEN: an even integer (sim.psf_pixels: an image centred on pixel n/2). */
/* F_EMPTY: a K_STR path that may be "", which means the same as left out (recon.fft_wisdom: a stored
 * configuration's file turned off with --set). */
enum { F_OPT = 1, F_LO_OPEN = 2, F_HI_OPEN = 4, F_POW2 = 8, F_ODD = 16, F_INCR = 32, F_DEFAULT = 64, F_AUTO = 128,
       F_HEX = 256, F_EVEN = 512, F_EMPTY = 1024 };

typedef struct wt_config_priv_key_spec {
    const char *path;    /* dotted libconfig path */
    int type;            /* K_* */
    int flags;           /* F_* */
    double lo, hi;       /* accepted range in file units (of each element for lists) */
    const char *unit;    /* unit of the file value, "" if none */
    double scale;        /* file unit -> internal unit (arcsec -> rad, nm -> m, ...) */
    size_t off;          /* destination in wt_config */
    size_t count_off;    /* lists: int element count in wt_config; lists sharing it have equal lengths */
    int minlen, maxlen;  /* lists: accepted lengths */
    const char *choices; /* enums: "a|b|c"; the stored int is the index */
    double def;          /* optional keys: value stored when absent */
    const char *desc;
} wt_config_priv_key_spec;

/* The keys in schema order (the order of the canonical text). The count is a constant because the parse
 * state keeps one slot per key; config_schema.c fails to compile when it and the table disagree. */
enum { WT_CONFIG_PRIV_NKEYS = 176 };
extern const wt_config_priv_key_spec wt_config_priv_keys[];

static inline int wt_config_priv_is_list(int t) { return t == K_FLOATS || t == K_INTS; }
static inline int wt_config_priv_is_int(int t) { return t == K_INT || t == K_INT64 || t == K_INTS; }
/* A number setting's value as a double (an int64 rounded to the nearest double) */
static inline double wt_config_priv_num(const config_setting_t *s)
{
    int t = config_setting_type(s);
    return t == CONFIG_TYPE_FLOAT   ? config_setting_get_float(s)
           : t == CONFIG_TYPE_INT64 ? (double)config_setting_get_int64(s)
                                    : (double)config_setting_get_int(s);
}

/* Shortest %g text that reads back as the same double; returns buf. */
const char *wt_config_priv_fmt_num(double v, char *buf, size_t n);

/* The bounds alone: "> 0", "in [0, 1)", ">= 4", "any"; booleans and enums list their words. */
void wt_config_priv_range(const wt_config_priv_key_spec *ks, char *buf, size_t n);

/* ---------------------------------------------------------------- config_state.c: the parse state */

/* What reading one configuration knows besides wt_config: the libconfig tree, the overrides, where each key was
 * set (config_read.c fills it; config_atmosphere.c reads and extends the same tree). */
typedef struct wt_config_priv_state {
    wt_context *ctx;
    const char *name;
    config_t *cf;
    const char *const *ov;
    int nfile_ov;                                    /* the first nfile_ov of ov come from the file */
    const struct wt_config_priv_text *src;           /* the expanded text: its lines map to FILE:LINE */
    int ovidx[WT_CONFIG_PRIV_NKEYS];                 /* override that set key k last, or -1 */
    const config_setting_t *set[WT_CONFIG_PRIV_NKEYS];
    const char *incdir;                              /* the configuration file's directory (NULL: working dir.) */
} wt_config_priv_state;

/* The index of key `path` in wt_config_priv_keys, or -1. */
int wt_config_priv_find_key(const char *path);
/* WT_ERR_CONFIG with the message "LOC: text". */
int wt_config_priv_fail(wt_config_priv_state *ps, const char *loc, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
/* "FILE:LINE" of line `line` of the text libconfig read (an included file names itself); returns buf. */
const char *wt_config_priv_src_line(const wt_config_priv_state *ps, int line, char *buf, size_t n);
/* "FILE:LINE" of setting s of key k, "--set k=v" when an override set it, "FILE" when absent; returns buf. */
const char *wt_config_priv_where(const wt_config_priv_state *ps, int k, const config_setting_t *s, char *buf, size_t n);
/* The same for element i of key k's list (i < 0: the key). */
const char *wt_config_priv_where_elem(const wt_config_priv_state *ps, int k, int i, char *buf, size_t n);
/* The groups along path created in cf (all but the last component); returns the parent group, *leaf the rest. */
config_setting_t *wt_config_priv_ensure_parent(config_t *cf, const char *path, const char **leaf);
/* A list written into the tree as if the file had given it (f: floats, else iv: integers), replacing what was
 * there; ps->set[k] points at it, so it is in the canonical text and the matrix hash like any key. */
int wt_config_priv_write_list(wt_config_priv_state *ps, int k, const double *f, const int *iv, int n);

/* ---------------------------------------------------------------- config_check.c, config_canonical.c */

/* The cross-key checks, and the values chosen from several keys (layer grids, sensor and fit points, priors, the
 * files' SHA-256) written into the tree; after every key is loaded. WT_ERR_CONFIG naming the keys and their lines. */
int wt_config_priv_check_consistency(wt_config_priv_state *ps, wt_config *cfg);
/* cfg->canonical, cfg->matrix_text and cfg->matrix_sha256 from the keys set (ps->set); last. Allocates the texts. */
int wt_config_priv_build_canonical(wt_config_priv_state *ps, wt_config *cfg);

/* ---------------------------------------------------------------- config_atmosphere.c */

/* atmosphere.profile, recon.atmosphere.profile (a profile file: config_atmosphere.c says its format): read and
 * checked with FILE:LINE messages, then written into the tree as the group's altitudes_m, cn2_fractions,
 * wind_speed_mps (and wind_direction_deg when the file has them), which the file then must not give itself. Runs
 * before the keys are loaded, so the lists are loaded, checked and written into the canonical text like given
 * ones (the text reads back without the file). */
int wt_config_priv_expand_profiles(wt_config_priv_state *ps);
/* recon.atmosphere (SPEC §12): the source's keys checked against each other; "oracle" copies the truth's
 * profile into cfg->model, "given" normalises the user's fractions, "learned" is refused (not available yet);
 * then the controlled model error of recon.atmosphere.error_* (r0, ground fraction, high layers' altitudes, wind;
 * its values of no error are left out of the canonical text).
 * The profile files' keys are left out of the canonical text (their lists are in it). Runs after every key
 * is loaded and the truth's fractions are normalised. */
int wt_config_priv_resolve_model(wt_config_priv_state *ps, wt_config *cfg);
/* atmosphere.night.* (SPEC §12 "A changing night"): the keys of the night's source checked against each other
 * (a file for "file", the walk's keys only for "random", none without a night). Runs after every key is loaded. */
int wt_config_priv_check_night(wt_config_priv_state *ps, const wt_config *cfg);
/* lgs.sodium_sequence*, lgs.wfs.reference*: a diffractive LGS, the keys that go together, cadences of at least a
 * frame's night time (the sequence file itself is read by the loop, which knows the run's night times). */
int wt_config_priv_check_sodium(wt_config_priv_state *ps, const wt_config *cfg);
/* Whether key `path` of the reconstructor's atmosphere enters the matrix identity: 1 / 0, or -1 when the key
 * is not one of the atmosphere's (the caller decides). The matrix is made from the model: the truth's profile
 * counts only through the oracle. */
int wt_config_priv_model_affects_matrix(const wt_config_priv_state *ps, const char *path);
/* 1 when recon.predict is set true: the predictor is then in the matrix (its lead, the model's wind) */
int wt_config_priv_predicting(const wt_config_priv_state *ps);

/* ---------------------------------------------------------------- config_derived.c */

/* Quantities derived from several keys (shift per frame, screen size, unknowns) against what the code
 * can run; the message names every key involved. */
int wt_config_priv_check_derived(wt_context *ctx, const wt_config *cfg);

/* ---------------------------------------------------------------- config_grid.c */

/* The automatic layer grids of variant v ("pcg3" or "cg9"; every other key of cfg loaded and checked
 * against the LGS altitude): with auto_spacing, v->spacing[l] = (DM pitch, or min(d, DM pitch) for cg9) /
 * v->oversampling, rounded to the 15 digits the canonical text keeps, and grid_base/grid_base_dm; then
 * v->size[l] = the smallest power of two >= max(4, 2^J) whose layer grid covers every footprint at the
 * layer's altitude (see config_grid.c). WT_ERR_CONFIG naming the keys when that exceeds 8192 points. */
int wt_config_priv_layer_grid(wt_context *ctx, const wt_config *cfg, const char *name, int auto_spacing,
                              wt_recon_variant_config *v);

/* ---------------------------------------------------------------- config_text.c */

/* The text handed to libconfig: @include lines replaced by the files' text and integer literals made
 * exact (L appended beyond 32 bits, a float literal beyond 64 bits); see config_text.c. */
#define WT_CONFIG_PRIV_MAX_FILES 32
typedef struct wt_config_priv_linemap {
    int line;     /* first line of the expanded text of this run */
    int file;     /* index into files */
    int src_line; /* its line in that file */
} wt_config_priv_linemap;

typedef struct wt_config_priv_text {
    wt_context *ctx;
    char *text;                                  /* the expanded text (owned) */
    char *files[WT_CONFIG_PRIV_MAX_FILES];       /* [0] = the name given, then each included path (owned) */
    int nfiles;
    wt_config_priv_linemap *map;                 /* runs of lines, in order of the expanded text (owned) */
    int nmap, capmap;
    int line;                                    /* current line of the expanded text while building */
} wt_config_priv_text;

/* Expand `text` (read from `name`; @include names resolve against incdir when relative, the working
 * directory when incdir is NULL). On error *t is left empty and the message names FILE:LINE. */
int wt_config_priv_text_make(wt_context *ctx, const char *text, const char *name, const char *incdir,
                             wt_config_priv_text *t);
void wt_config_priv_text_free(wt_config_priv_text *t);
/* The file (NULL if unknown) and line that expanded line `line` came from. */
const char *wt_config_priv_src(const wt_config_priv_text *t, int line, int *src_line);

#endif
