/* app/info.c: `wavetomo info`: the derived sizes of a configured system. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "app/commands.h"
#include "cli/cli.h"
#include "compare/report_spots.h"
#include "core/model/sensing.h"
#include "core/optics/sodium.h"
#include "core/la/half.h"
#include "core/model/fitting.h"
#include "core/model/system.h"
#include "core/model/params.h"
#include "core/model/profile.h"
#include "core/model/tomography.h"
#include "core/model/estimate.h"
#include "core/model/reconstructor.h"
#include "core/op/noise.h"

static void help(void)
{
    printf("usage: wavetomo info [--config] CONFIG [--set key=value]... [--no-nnz] [--threads N]\n"
           "                     [--spots DIR [--sensor NAME] [--time T]]\n"
           "       wavetomo info --keys\n"
           "\n"
           "Prints the derived sizes of the system described by CONFIG: valid subapertures and slopes\n"
           "per sensor, active actuators per DM, reconstruction unknowns per layer of each\n"
           "reconstructor (pcg3, cg9), non-zeros of the sparse operators (Γ, P, ΓP, Ã = ΓPW⁻¹, C̃⁻¹,\n"
           "D), and the size of the MVM control matrix.\n"
           "\n"
           "  --keys        print every configuration key with its type, range and unit\n"
           "  --spots DIR   draw one diffractive sensor (the first diffractive LGS, or --sensor) into DIR (created):\n"
           "                spots_<SENSOR>.png, the noise-free mean spot image of every valid subaperture in its\n"
           "                cell over the pupil (grey, each scaled to its peak; frames: truncation > 0.1/1/10 %%;\n"
           "                the launch); gain_<SENSOR>.png, the centroid gain along the elongation (for the\n"
           "                matched filter, whose gain is 1: a whole-detector CoG's) and the truncation per\n"
           "                subaperture; spots.md, what they show with the median NEA and worst truncation.\n"
           "                A system without a diffractive sensor is refused (lgs.wfs.model = \"diffractive\")\n"
           "  --sensor NAME the sensor --spots draws (LGS1, NGS2, ...)\n"
           "  --time T      --spots of an LGS at night time T [s] of the truth's sodium sequence (lgs.sodium_sequence):\n"
           "                the spots the truth renders then, and the gain and false slope (its reading of a spot\n"
           "                that holds still) of the centroider built on the set-up's reference, i.e. what a static\n"
           "                reference does with the layer of time T; run it at two times to see the change\n"
           "  --no-nnz      skip the (few-second) symbolic count of the non-zeros of Ã\n"
           "  --set k=v     override a configuration key (repeatable)\n"
           "  --dry-run     print the estimated peak memory and run time of info itself; stop\n"
           "  --max-memory S refuse when that estimate exceeds S bytes (4G, 512M; default MemAvailable)\n");
}

#define WT_DEG (M_PI / 180.0) /* radians per degree */

/* The model m compressed onto variant v's layers: fractions and wind components [m/s] (core/model/profile.h). */
static void model_wind(const wt_model_atmosphere_config *m, const wt_recon_variant_config *v, double *frac,
                       double *wx, double *wy)
{
    double vx[WT_MAX_LAYERS], vy[WT_MAX_LAYERS];
    for (int k = 0; k < m->nlayers; k++) {
        vx[k] = m->wind_speed[k] * cos(m->wind_direction[k]);
        vy[k] = m->wind_speed[k] * sin(m->wind_direction[k]);
    }
    wt_profile_compress(m->nlayers, m->altitude, m->fraction, vx, vy, v->nlayers, v->altitudes, frac, wx, wy);
}

/* The simulated atmosphere and where the reconstructors' comes from (SPEC §12: two separate objects). */
static void print_atmospheres(const wt_config *cfg)
{
    printf("\natmosphere (the simulation's truth): %d layers, r0 %g m at 500 nm, L0 %g m%s%s%s\n", cfg->nlayers, cfg->r0,
           cfg->L0, cfg->atm_profile[0] ? "; profile " : "", cfg->atm_profile, cfg->atm_profile[0] ? " (atmosphere.profile)" : "");
    printf("  %-5s %10s %12s %10s %10s\n", "layer", "altitude_m", "Cn2_fraction", "wind_mps", "towards_deg");
    for (int l = 0; l < cfg->nlayers; l++)
        printf("  %-5d %10.0f %12.6f %10.1f %10.1f\n", l + 1, cfg->layer_altitude[l], cfg->layer_fraction[l],
               cfg->wind_speed[l], cfg->wind_direction[l] / WT_DEG);
    const wt_night_config *nc = &cfg->night;
    if (nc->source != WT_NIGHT_CFG_NONE)
        printf("a changing night (atmosphere.night): %s%s, night time %g s to %g s (compression %g); the table above is "
               "its reference, the state the screens are made with\n",
               nc->source == WT_NIGHT_CFG_FILE ? "the states of " : "the stochastic model", nc->file, nc->start,
               nc->start + (double)(cfg->frames - 1) * (1.0 / cfg->rate) * nc->compression, nc->compression);
    const wt_model_atmosphere_config *m = &cfg->model;
    const int err = m->error_ground_fraction != 0.0 || m->error_r0_scale != 1.0 || m->error_high_shift != 0.0 ||
                    m->error_wind_speed_scale != 1.0 || m->error_wind_direction != 0.0;
    if (m->source == WT_MODEL_ORACLE && !err)
        printf("reconstructors' atmosphere: oracle (recon.atmosphere.source): the truth above, compressed onto each "
               "variant's layers below\n");
    else {
        if (err)
            printf("reconstructors' atmosphere with a controlled error (recon.atmosphere.error_*): ground fraction "
                   "%+g (layers up to %g m), r0 x %g, layers from %g m moved %+g m, wind speed x %g, direction %+g "
                   "deg\n", m->error_ground_fraction, m->error_ground_top, m->error_r0_scale, m->error_high_bottom,
                   m->error_high_shift, m->error_wind_speed_scale, m->error_wind_direction / WT_DEG);
        if (m->source == WT_MODEL_LEARNED)
            printf("reconstructors' atmosphere: learned (recon.atmosphere.source): an estimate from the loop's own LGS "
                   "slopes every %g s of night (r0 and the Cn2 on the learning grid, "
                   "recon.atmosphere.learn_grid; L0 stays the start's, the wind "
                   "%s); the MVM's in the loop %s after it; it starts from:\n", m->update_s,
                   m->learn_wind ? "of each pcg3/cg9 layer aligned on its own estimates (learn_wind)" : "too",
                   m->mvm_latency_s >= 0.0 ? "mvm_latency_s" : "its measured build time");
        printf("%sreconstructors' atmosphere: %s (recon.atmosphere)%s%s: %d layers, r0 %g m, L0 %g m, compressed onto "
               "each variant's layers below\n", m->source == WT_MODEL_LEARNED ? "  " : "",
               m->source == WT_MODEL_ORACLE ? "oracle" : "given", m->profile[0] ? ", profile " : "", m->profile,
               m->nlayers, m->r0, m->L0);
        printf("  %-5s %10s %12s %10s %10s\n", "layer", "altitude_m", "Cn2_fraction", "wind_mps", "towards_deg");
        for (int l = 0; l < m->nlayers; l++)
            printf("  %-5d %10.0f %12.6f %10.1f %10.1f\n", l + 1, m->altitude[l], m->fraction[l], m->wind_speed[l],
                   m->wind_direction[l] / WT_DEG);
    }
}

/* The LGS slopes' part that no layer grid of this variant holds (σ_g, core/model/tomography_model.c): with an
 * LGS noise below it and recon.subgrid_error off, more light can make the reconstruction worse. */
static void print_subgrid(const wt_system *sys, const wt_tomography *t, const wt_tomography_params *tp)
{
    const wt_model_atmosphere_config *m = &sys->cfg->model;
    double var[2 * WT_MAX_GS], gmin = INFINITY, gmax = 0.0, nea = INFINITY;
    wt_tomography_subgrid_variances(t, m->r0, m->nlayers, m->altitude, m->fraction, var);
    for (int k = 0; k < sys->nsensors; k++) {
        if (sys->sensors[k].kind != WT_SENSOR_LGS) continue;
        gmin = fmin(gmin, sqrt(var[k]));
        gmax = fmax(gmax, sqrt(var[k]));
        nea = fmin(nea, sqrt(sys->sensors[k].sigma2));
    }
    if (!(gmax > 0.0)) return;
    const double mas = 1e3 / WT_ARCSEC;
    char range[48];
    if (gmax - gmin > 0.005 * gmax) snprintf(range, sizeof range, "%.1f-%.1f", gmin * mas, gmax * mas);
    else snprintf(range, sizeof range, "%.1f", gmax * mas);
    printf("  LGS slopes' sub-grid model error: %s mas per axis (the turbulence beyond the layer grids' Nyquist); %s\n",
           range,
           tp->subgrid_error ? "the LGS noise weight floored at it (recon.subgrid_error = true)"
           : nea < gmax ? "above the LGS noise and not in the weight: more light can make this reconstructor worse "
                          "(recon.subgrid_error = true floors the weight at it)"
                        : "below the LGS noise (recon.subgrid_error = false)");
}

static void print_variant(wt_cli *cli, const wt_system *sys, const wt_recon_variant_config *v, const char *name,
                          int count_nnz, int *st_out)
{
    wt_tomography *t = NULL;
    wt_tomography_params tp;
    wt_tomography_params_from_config(sys->cfg, &tp);
    int st = wt_tomography_alloc(cli->ctx, sys, v, name, &tp, &t);
    if (st < 0) {
        *st_out = st;
        return;
    }
    char solver[48];
    if (v->preconditioner == WT_PRECOND_NONE) snprintf(solver, sizeof solver, "CG");
    else snprintf(solver, sizeof solver, "PCG (%s)", wt_precond_kind_name(v->preconditioner));
    printf("\nreconstructor %s: %d layers, %s, %d iterations%s%s%s%s\n", name, v->nlayers, solver, v->iterations,
           v->fit_iterations > 0 ? " + fitting" : "",
           v->operator_precision == 1 ? "; its operator in single precision (recon." : "",
           v->operator_precision == 1 ? name : "", v->operator_precision == 1 ? ".operator_precision = \"fp32\")" : "");
    /* the model compressed onto this variant's layers (SPEC §12): the prior's fractions (floored) and the wind */
    double frac[WT_MAX_LAYERS], wx[WT_MAX_LAYERS], wy[WT_MAX_LAYERS];
    model_wind(&sys->cfg->model, v, frac, wx, wy);
    printf("  %-5s %10s %12s %9s %10s   %s\n", "layer", "altitude_m", "grid", "spacing_m", "unknowns",
           "model: Cn2 fraction, wind [m/s] towards [deg]");
    for (int l = 0; l < v->nlayers; l++) {
        const wt_grid *g = wt_tomography_layer_grid(t, l);
        char gs[32];
        snprintf(gs, sizeof gs, "%dx%d", g->nx, g->ny);
        char how[160] = "";
        if (v->grid_auto == WT_GRID_AUTO) {
            char base[48];
            if (v->grid_base_dm[l] < 0) snprintf(base, sizeof base, "d = %g m", v->grid_base[l]);
            else snprintf(base, sizeof base, "DM %d pitch %g m", v->grid_base_dm[l] + 1, v->grid_base[l]);
            snprintf(how, sizeof how, "   (automatic: %s, oversampling %g)", base, v->oversampling);
        } else if (v->grid_auto == WT_GRID_AUTO_SIZE)
            snprintf(how, sizeof how, "   (automatic size for the given spacing)");
        char floor[48] = "";
        if (wt_tomography_layer_fraction(t, l) != frac[l])
            snprintf(floor, sizeof floor, " (prior %.4f: floor)", wt_tomography_layer_fraction(t, l));
        printf("  %-5d %10.0f %12s %9.3g %10lld   %.4f%s %5.1f %6.1f%s\n", l + 1, wt_tomography_layer_altitude(t, l),
               gs, g->dx, (long long)wt_grid_size(g), frac[l], floor, hypot(wx[l], wy[l]),
               fmod(atan2(wy[l], wx[l]) / WT_DEG + 360.0, 360.0), how);
    }
    long long n = (long long)wt_tomography_nunknowns(t);
    if (v->prior == WT_CFG_PRIOR_FULL)
        printf("  total unknowns: %lld; prior: full von Karman covariance per layer, applied by FFT "
               "(recon.%s.prior = \"full\"; an MVM of it has a dense normal matrix, %.3g GB)\n", n, name,
               8.0 * (double)n * (double)n / 1e9);
    else
        printf("  total unknowns: %lld; prior: %s diagonal D, %lld non-zeros (recon.%s.prior = \"%s\")\n", n,
               v->prior == WT_CFG_PRIOR_EXACT ? "exact" : "the paper's", n, name,
               v->prior == WT_CFG_PRIOR_EXACT ? "exact" : "paper");
    print_subgrid(sys, t, &tp);
    if (count_nnz) {
        int64_t gp[2 * WT_MAX_GS], a[2 * WT_MAX_GS];
        st = wt_tomography_count_nnz(t, gp, a);
        if (st < 0) {
            *st_out = st;
            wt_tomography_free(t);
            return;
        }
        long long tg = 0, ta = 0;
        printf("  %-6s %14s %16s\n", "sensor", "nnz(Gamma P)", "nnz(A~=GammaPW^-1)");
        for (int m = 0; m < sys->nsensors; m++) {
            printf("  %-6s %14lld %16lld\n", sys->sensors[m].name, (long long)gp[m], (long long)a[m]);
            tg += gp[m];
            ta += a[m];
        }
        printf("  %-6s %14lld %16lld  (%.2f GB as CSC with 64-bit indices)\n", "total", tg, ta, ta * 16.0 / 1e9);
    }
    if (v->fit_iterations > 0) {
        wt_fitting *f = NULL;
        wt_fitting_params fp = {.regularization = v->fit_regularization, .sampling = v->fit_sampling};
        st = wt_fitting_alloc_for(cli->ctx, t, &fp, &f);
        if (st < 0) {
            *st_out = st;
            wt_tomography_free(t);
            return;
        }
        printf("  fitting over %d directions, sampled %s %.3g m (recon.cg9.fit_points_per_subaperture %d), Tikhonov "
               "epsilon %.3g (relative %g), %s\n", sys->neval, v->fit_sampling == 1 ? "at the Fried corners," : "every",
               sys->d / v->fit_sampling, v->fit_sampling,
               wt_fitting_epsilon(f), v->fit_regularization,
               v->fit_solver == WT_FIT_CHOLESKY ? (v->fit_factor_precision ? "Cholesky (factor read in fp32)"
                                                                            : "Cholesky (factor read in fp64)")
                                                : "CG");
        wt_fitting_free(f);
    }
    wt_tomography_free(t);
}

/* --time T: the sensor's tables set to the sequence's profile at night time T (the truth then) */
static int spots_at_time(wt_cli *cli, wt_system *sys, int index, double t)
{
    const wt_sensor *s = &sys->sensors[index];
    const wt_config *cfg = sys->cfg;
    if (s->kind != WT_SENSOR_LGS || !cfg->sodium_sequence[0])
        return WT_ERROR(cli->ctx, WT_ERR_CONFIG, "%s: --time %g draws an LGS at a night time of the truth's sodium "
                        "sequence, and %s; give lgs.sodium_sequence (e.g. --set 'lgs.sodium_sequence=\"../sodium/"
                        "drift-1km-10min.txt\"') and an LGS (--sensor LGS1)",
                        cfg->path, t, s->kind != WT_SENSOR_LGS ? "the sensor drawn is an NGS" : "there is none");
    wt_sodium_seq *seq = NULL;
    wt_sodium *na = NULL;
    char what[128];
    snprintf(what, sizeof what, "--time %g", t);
    int st = wt_sodium_seq_read(cli->ctx, cfg->sodium_sequence, &seq);
    if (st >= 0) st = wt_sodium_seq_check_covers(cli->ctx, seq, t, t, what);
    if (st >= 0) st = wt_sodium_seq_profile(cli->ctx, seq, t, &na);
    if (st >= 0) st = wt_sensing_set_sodium(s->diffr, na);
    wt_sodium_free(na);
    wt_sodium_seq_free(seq);
    return st;
}

typedef struct {
    int count_nnz, keys;
    const char *spots, *sensor, *time; /* --spots DIR, --sensor NAME, --time T */
} info_args;

static int info_option(wt_cli *cli, int argc, char **argv, int *i, void *user)
{
    (void)argc;
    info_args *a = user;
    if (!strcmp(argv[*i], "--keys")) a->keys = 1;
    else if (!strcmp(argv[*i], "--no-nnz")) a->count_nnz = 0;
    else if (!strcmp(argv[*i], "--spots") || !strcmp(argv[*i], "--sensor") || !strcmp(argv[*i], "--time")) {
        const char *v = wt_cli_value(cli, argc, argv, i);
        if (!v) return -1;
        if (!strcmp(argv[*i - 1], "--spots")) a->spots = v;
        else if (!strcmp(argv[*i - 1], "--time")) a->time = v;
        else a->sensor = v;
    }
    else return 0; /* CONFIG (positional or --config) is the common options' */
    return 1;
}

int wt_cmd_info(int argc, char **argv)
{
    wt_cli cli;
    if (wt_cli_init(&cli, "wavetomo info", help)) return 1;
    info_args args = {1, 0, NULL, NULL, NULL};
    int rc = wt_cli_parse(&cli, argc, argv, info_option, &args);
    if (rc >= 0 || args.keys) {
        if (args.keys && rc < 0) {
            wt_config_print_reference(stdout);
            rc = 0;
        }
        wt_cli_done(&cli);
        return rc;
    }
    rc = 0;
    int count_nnz = args.count_nnz, spots_sensor = -1;
    wt_config *cfg = NULL;
    wt_system *sys = NULL;
    if ((args.sensor || args.time) && !args.spots) {
        rc = wt_cli_usage_error(&cli, args.sensor ? "--sensor names the sensor --spots draws; give --spots DIR"
                                                  : "--time is the night time --spots draws; give --spots DIR");
        wt_cli_done(&cli);
        return rc;
    }
    double night_s = 0.0;
    if (args.time && wt_cli_double(&cli, "--time", args.time, -1e9, 1e9, &night_s) < 0) {
        wt_cli_done(&cli);
        return 2;
    }
    int st = wt_cli_read_config(&cli, NULL, &cfg);
    if (st < 0) goto out;
    if ((rc = wt_cli_estimate(&cli, cfg, WT_TASK_INFO, WT_RECON_NONE, 0)) >= 0) goto out;
    rc = 0;
    st = wt_system_alloc(cli.ctx, cfg, &sys);
    if (st < 0) goto out;
    /* --spots: refused before anything is printed or written (no diffractive sensor, a foreign file in DIR) */
    if (args.spots && ((st = wt_spots_pick(cli.ctx, sys, args.sensor, &spots_sensor)) < 0 ||
                       (st = wt_spots_check_outputs(&cli, sys, spots_sensor, args.spots, NULL)) < 0))
        goto out;
    if (args.time && (st = spots_at_time(&cli, sys, spots_sensor, night_s)) < 0) goto out;

    printf("system: %s\n", cfg->path);
    printf("telescope: D = %g m, obstruction %g; Shack-Hartmann sampling %dx%d, d = %g m\n", cfg->diameter,
           cfg->obstruction, sys->n, sys->n, sys->d);
    printf("\n%-6s %8s %8s %10s %9s %12s %12s\n", "sensor", "x_arcsec", "y_arcsec", "subaps", "valid", "slopes",
           "sigma_mas");
    for (int m = 0; m < sys->nsensors; m++) {
        const wt_sensor *s = &sys->sensors[m];
        char sub[16];
        snprintf(sub, sizeof sub, "%dx%d", s->subapertures, s->subapertures);
        printf("%-6s %8.1f %8.1f %10s %9d %12d %12.1f\n", s->name, s->theta_x / WT_ARCSEC, s->theta_y / WT_ARCSEC, sub,
               s->nsub, s->nslopes, sqrt(s->sigma2) / WT_ARCSEC * 1e3);
    }
    printf("total slopes: %lld (Fried corner points used: %lld)\n", (long long)sys->nslopes, (long long)sys->ncorners);
    if (cfg->lit_sensor_model)
        printf("reconstructor's sensor model: lit-area average read at %d x %d points per subaperture (%g m)\n",
               cfg->sensor_points, cfg->sensor_points, sys->d / cfg->sensor_points);
    else printf("reconstructor's sensor model: Fried (corner differences)\n");
    if (cfg->fft_wisdom[0])
        printf("reconstructors' FFT plans: measured, from the wisdom %s (SHA-256 %.12s...; recon.fft_wisdom)\n",
               cfg->fft_wisdom, cfg->fft_wisdom_sha256[0] ? cfg->fft_wisdom_sha256 : "(unreadable)");
    else printf("reconstructors' FFT plans: FFTW_ESTIMATE (the same on every machine; recon.fft_wisdom for measured ones)\n");
    for (int m = 0; m < sys->nsensors; m++) {
        const wt_sensor *s = &sys->sensors[m];
        const wt_sensing *ws = s->diffr;
        if (!ws) continue;
        const wt_sensor_config *w = s->kind == WT_SENSOR_LGS ? &cfg->lgs_wfs : &cfg->ngs_wfs;
        static const char *const cen[] = {"cog", "tcog", "mf"};
        printf("%s diffractive: %s, %dx%d pixels of %g arcsec, n_p %d, N %d, %g nm; median NEA %.1f mas; worst "
               "truncation %.1f %% (subaperture %d at %.2f, %.2f m); set-up %.2f s\n",
               s->name, cen[w->centroider], ws->ns, ws->ns, w->pixel / WT_ARCSEC, ws->np, w->fft_size,
               w->wavelength * 1e9, ws->nea_median / WT_ARCSEC * 1e3, 100.0 * ws->worst_trunc, ws->worst_sub,
               ws->xc[ws->worst_sub], ws->yc[ws->worst_sub], ws->setup_seconds);
    }
    if (cfg->nlgs > 0 && cfg->lgs_gain_update > 0.0)
        printf("LGS matched filters' gain measured on the loop's own pixels every %g s of night and divided out "
               "(lgs.wfs.gain_update_s)\n", cfg->lgs_gain_update);

    if (args.spots) {
        char cmd[4096] = "wavetomo";
        for (int i = 0; i < argc; i++) /* argv[0] is the subcommand */
            snprintf(cmd + strlen(cmd), sizeof cmd - strlen(cmd), " %s", argv[i]);
        const double t0 = wt_time_now();
        const wt_spots_when when = {.night_s = night_s, .sequence = cfg->sodium_sequence};
        if ((st = wt_spots_write(&cli, sys, spots_sensor, args.spots, cmd, args.time ? &when : NULL)) < 0) goto out;
        const char *nm = sys->sensors[spots_sensor].name;
        printf("%s pictures: %s/spots_%s.png, %s/gain_%s.png, %s/spots.md (%.1f s)\n", nm, args.spots, nm, args.spots,
               nm, args.spots, wt_time_now() - t0);
    }

    printf("\n%-4s %10s %8s %10s %8s\n", "DM", "altitude_m", "pitch_m", "grid", "active");
    for (int k = 0; k < sys->dm->ndms; k++) {
        char g[16];
        snprintf(g, sizeof g, "%dx%d", sys->dm->grid[k].nx, sys->dm->grid[k].ny);
        printf("%-4d %10.0f %8.3g %10s %8d\n", k + 1, sys->dm->altitude[k], sys->dm->grid[k].dx, g, sys->dm->nactive[k]);
    }
    printf("total active actuators: %lld\n", (long long)sys->nact);
    printf("evaluation: %d directions (%dx%d, %.1f arcsec spacing) at %.0f nm\n", sys->neval, cfg->eval_grid,
           cfg->eval_grid, cfg->eval_spacing / WT_ARCSEC, cfg->eval_wavelength * 1e9);
    printf("loop: %.0f Hz, delay %d frames, ", cfg->rate, cfg->delay);
    if (cfg->ngain_levels == 0) {
        printf("integrator gain %g\n", cfg->gain);
    } else if (cfg->gain_basis == 0) { /* loop.gain_levels (core/op/scale_gain.h): V_j bilinear on squares of 2^(L+1-j) */
        const int L = cfg->ngain_levels - 1;
        printf("integrator gain per scale of the DM commands (bilinear bands, squares of N actuators):");
        for (int j = 0; j <= L; j++) printf(" %d: %g%s", 2 << (L - j), cfg->gain_levels[j], j < L ? "," : "\n");
    } else { /* Daubechies: band j > 0 is detail level L + 1 - j, features of 2^level pitches */
        const int L = cfg->ngain_levels - 1;
        printf("integrator gain per scale of the DM commands (Daubechies-%d DWT, %d levels): scaling %g", cfg->wavelet_order,
               L, cfg->gain_levels[0]);
        for (int j = 1; j <= L; j++) printf(", %d pitches %g", 1 << (L + 1 - j), cfg->gain_levels[j]);
        printf("\n");
    }

    int64_t nnz_c = 0;
    for (int m = 0; m < sys->nsensors; m++) nnz_c += 4LL * sys->sensors[m].nsub;
    printf("noise weight C~^-1: %lld non-zeros (2x2 blocks)\n", (long long)nnz_c);

    const double esize = cfg->mvm_precision == WT_PREC_F32 ? 4.0 : 2.0; /* recon.mvm_precision */
    double r_bytes = esize * (double)sys->nact * (double)sys->nslopes;
    double ra_bytes = esize * (double)sys->nact * (double)sys->nact;
    printf("MVM control matrix R: %lld x %lld %s = %.3g GB; R*A^ (POLC): %lld x %lld = %.3g GB\n",
           (long long)sys->nact, (long long)sys->nslopes,
           cfg->mvm_precision == WT_PREC_F16 ? "float16" : cfg->mvm_precision == WT_PREC_BF16 ? "bfloat16" : "float32",
           r_bytes / 1e9,
           (long long)sys->nact, (long long)sys->nact, ra_bytes / 1e9);

    print_atmospheres(cfg);
    print_variant(&cli, sys, &cfg->pcg3, "pcg3", count_nnz, &st);
    if (st < 0) goto out;
    print_variant(&cli, sys, &cfg->cg9, "cg9", count_nnz, &st);
out:
    if (st < 0) rc = wt_cli_fail(&cli, st);
    wt_system_free(sys);
    wt_config_free(cli.ctx, cfg);
    wt_cli_done(&cli);
    return rc;
}
