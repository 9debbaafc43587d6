/* builder/cmd_build.c: `wavetomo build`: the offline MVM builder (SPEC §9). Thin driver: reads the
 * configuration, runs builder/mvm_build (CHOLMOD factorisation, column solves), writes MATRIX.h5.
 * Under mpirun every rank assembles and factorises, solves the blocks of right-hand sides
 * b % K == rank (wt_mvm_options.part_*), and rank 0 gathers the rows and writes the one file: the same
 * blocks in the same order as a serial build, so the matrix is bit for bit the serial one. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>

#include "builder/cmd_build.h"
#include "cli/cli.h"
#include "cli/mpi.h"
#include "core/io/h5.h"
#include "core/la/half.h"
#include "builder/mvm_build.h"
#include "core/model/system.h"
#include "core/model/tomography.h"
#include "core/model/estimate.h"
#include "core/model/reconstructor.h"

static void help(void)
{
    printf("usage: wavetomo build [--config] FILE [--set key=value]... [--recon pcg3|cg9] --out MATRIX.h5\n"
           "                      [--memory GB] [--threads N] [--quiet]\n"
           "\n"
           "Builds the MVM control matrix of the same MAP problem the wavelet reconstructor solves: assembles\n"
           "A~ = Gamma P W^-1, C~^-1 and D as sparse matrices, factorises A~' C~^-1 A~ + alpha D with CHOLMOD\n"
           "(the LGS tip-tilt removal and the NGS rows as a Sherman-Morrison-Woodbury correction), solves for\n"
           "every actuator and writes R (n_act x n_slopes) and R A^ (n_act x n_act) in float32 to MATRIX.h5,\n"
           "with the configuration hash that `wavetomo run` and `wavetomo sim --recon mvm` check.\n"
           "\n"
           "  --recon R    pcg3 (default: layers at the DMs, commands = layer values at the actuators) or cg9\n"
           "               (layers at the atmosphere altitudes, then the fitting step solved exactly)\n"
           "  --memory GB  peak memory the build may use (default: 90 %% of the memory available now); the\n"
           "               build estimates its peak first and refuses, saying how much it needs, above it\n"
           "  --max-memory S  the same limit as a size (4G, 512M); --dry-run  print the estimated peak memory\n"
           "               and build time (from the configuration alone) and the keys that drive them; stop\n"
           "The file is written to a temporary name and renamed when complete.\n"
           "\n"
           "MPI: `mpirun -n K wavetomo build ...` splits the column solves over K ranks (each rank assembles and\n"
           "factorises for itself, so each needs the memory of a serial build); rank 0 writes MATRIX.h5, equal\n"
           "bit for bit to the serial one. Use --threads to set the threads of each rank.\n");
}

typedef struct {
    const char *recon, *out;
    double memory_gb;
} build_args;

static int build_option(wt_cli *cli, int argc, char **argv, int *i, void *user)
{
    build_args *a = user;
    const char *o = argv[*i];
    if (!strcmp(o, "--recon") || !strcmp(o, "--out")) {
        const char *v = wt_cli_value(cli, argc, argv, i);
        if (!v) return -1;
        if (o[2] == 'r') a->recon = v;
        else a->out = v;
    } else if (!strcmp(o, "--memory")) {
        const char *v = wt_cli_value(cli, argc, argv, i);
        if (!v || wt_cli_double(cli, o, v, 1e-3, 1e6, &a->memory_gb) < 0) return -1;
    } else
        return 0;
    return 1;
}

/* MPI: rank 0 receives the rows of R and RÂ of the blocks the other ranks solved (each rank sends its own in
 * increasing order, so the messages match in order); the others send theirs. In fp16/bf16 storage the rows
 * are 16-bit with one scale each, packed row by row (core/la/half.h), so a rank's rows are the serial ones. */
static int gather_rows(wt_mpi *mp, wt_mvm *m, int block)
{
    const int64_t nact = m->nact, ns = m->nslopes, nb = block < nact ? block : (nact > 0 ? nact : 1);
    const int half = m->precision != WT_PREC_F32;
    const size_t esz = half ? sizeof *m->Rh : sizeof *m->R;
    char *R = half ? (char *)m->Rh : (char *)m->R, *RA = half ? (char *)m->RAh : (char *)m->RA;
    for (int64_t i0 = 0, b = 0; i0 < nact; i0 += nb, b++) {
        const int owner = (int)(b % mp->size);
        const int64_t cb = nact - i0 < nb ? nact - i0 : nb;
        if (mp->rank == 0 ? owner == 0 : owner != mp->rank) continue; /* rank 0 receives, the owner sends */
        struct { void *p; size_t bytes; } part[4] = {
            {R + (size_t)i0 * ns * esz, (size_t)cb * ns * esz}, {RA + (size_t)i0 * nact * esz, (size_t)cb * nact * esz},
            {half ? m->Rc + i0 : NULL, half ? (size_t)cb * sizeof *m->Rc : 0},
            {half ? m->RAc + i0 : NULL, half ? (size_t)cb * sizeof *m->RAc : 0}};
        for (int k = 0; k < 4; k++) {
            if (!part[k].bytes) continue;
            int rc = mp->rank == 0 ? wt_mpi_recv(mp, part[k].p, part[k].bytes, owner, 1 + k)
                                   : wt_mpi_send(mp, part[k].p, part[k].bytes, 0, 1 + k);
            if (rc < 0) return -1;
        }
    }
    return 0;
}

static int build_main(wt_mpi *mp, int argc, char **argv);

int wt_cmd_build(int argc, char **argv)
{
    wt_mpi mp;
    if (wt_mpi_begin(&mp)) return 1;
    int rc = build_main(&mp, argc, argv);
    wt_mpi_end(&mp);
    return rc;
}

static int build_main(wt_mpi *mp, int argc, char **argv)
{
    wt_cli cli;
    char prog[64];
    snprintf(prog, sizeof prog, mp->size > 1 ? "wavetomo build[rank %d]" : "wavetomo build", mp->rank);
    if (wt_cli_init(&cli, mp->rank ? prog : "wavetomo build", help)) return 1;
    build_args args = {"pcg3", NULL, 0.0};
    int rc = wt_cli_parse(&cli, argc, argv, build_option, &args);
    if (rc >= 0) {
        wt_cli_done(&cli);
        return rc;
    }
    if (mp->rank) cli.quiet = 1; /* rank 0 speaks for the job; the others only report their errors */
    rc = 0;
    if (strcmp(args.recon, "pcg3") && strcmp(args.recon, "cg9")) {
        rc = wt_cli_usage_error(&cli, "--recon expects pcg3 or cg9, got '%s'", args.recon);
        wt_cli_done(&cli);
        return rc;
    }
    if (!args.out || !cli.config_path) {
        rc = wt_cli_usage_error(&cli, "%s is required", !cli.config_path ? "a configuration (FILE or --config FILE)" : "--out MATRIX.h5");
        wt_cli_done(&cli);
        return rc;
    }
    wt_config *cfg = NULL;
    wt_system *sys = NULL;
    wt_mvm *m = NULL;
    wt_h5_writer *w = NULL;
    int st = wt_cli_read_config(&cli, NULL, &cfg);
    if (st < 0) goto fail;
    if (args.memory_gb > 0 && !(cli.max_memory > 0)) cli.max_memory = args.memory_gb * 1e9; /* --memory GB */
    if ((rc = wt_cli_estimate(&cli, cfg, WT_TASK_BUILD, strcmp(args.recon, "cg9") ? WT_RECON_PCG3 : WT_RECON_CG9, 0)) >= 0)
        goto cleanup;
    rc = 0;
    if ((st = wt_system_alloc(cli.ctx, cfg, &sys)) < 0) goto fail;
    int cg9 = !strcmp(args.recon, "cg9");
    /* check the output before hours of work: R is n_act x n_slopes float32 (rank 0 writes it; a refusal
     * there stops every rank) */
    double rbytes = 4.0 * (double)sys->nact * ((double)sys->nslopes + (double)sys->nact);
    if (mp->rank == 0) st = wt_cli_check_output(&cli, args.out, (int64_t)(rbytes * 1.05), NULL, NULL);
    int bad = st < 0;
    if (wt_mpi_max_int(mp, &bad) < 0) bad = 1;
    if (st < 0) goto fail;
    if (bad) goto quiet_fail;
    const wt_recon_variant_config *var = cg9 ? &cfg->cg9 : &cfg->pcg3;
    int64_t nunknowns = 0; /* a coefficient per layer grid point */
    for (int l = 0; l < var->nlayers; l++) nunknowns += (int64_t)var->size[l] * var->size[l];
    wt_mvm_options o;
    wt_mvm_options_default(&o);
    o.memory_budget = cli.max_memory > 0 ? cli.max_memory : 0.9 * wt_memory_available();
    wt_progress_phases bp = {.quiet = cli.quiet};
    o.progress = wt_progress_phase;
    o.progress_user = &bp;
    o.part_index = mp->rank, o.part_count = mp->size;
    if (!cli.quiet)
        fprintf(stderr, "wavetomo build: %s, %s: %lld unknowns, R %lld x %lld (%.2f GB float32), memory budget %.1f GB%s\n",
                cfg->path, args.recon, (long long)nunknowns, (long long)sys->nact,
                (long long)sys->nslopes, 4.0 * sys->nact * (double)sys->nslopes / 1e9, o.memory_budget / 1e9,
                mp->size > 1 ? " per rank" : "");
    if (!cli.quiet && mp->size > 1)
        fprintf(stderr, "wavetomo build: %d MPI ranks x %d threads, blocks of %d columns dealt round-robin\n", mp->size,
                wt_context_threads(cli.ctx), o.block);
    st = wt_mvm_build_variant(cli.ctx, sys, cfg, args.recon, &o, &m);
    wt_progress_phases_end(&bp);
    /* every rank learns whether all built before any waits for another's rows */
    bad = st < 0;
    if (wt_mpi_max_int(mp, &bad) < 0) bad = 1;
    if (st < 0) goto fail;
    if (bad) goto quiet_fail;
    double tg0 = wt_time_now();
    if (mp->size > 1 && gather_rows(mp, m, o.block) < 0) goto quiet_fail;
    if (mp->rank) goto cleanup;
    if (mp->size > 1 && !cli.quiet) fprintf(stderr, "wavetomo build: rows gathered on rank 0 in %.1f s\n", wt_time_now() - tg0);
    double tw0 = wt_time_now();
    if ((st = wt_h5_create(cli.ctx, args.out, &w)) < 0) goto fail;
    if ((st = wt_cli_write_provenance(&cli, w, cfg, argc, argv)) < 0) goto fail;
    if ((st = wt_cli_write_layout(w, sys)) < 0) goto fail;
    if ((st = wt_mvm_write(w, m, cfg, args.recon)) < 0) goto fail;
    st = wt_h5_commit(w);
    w = NULL;
    if (st < 0) goto fail;
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    const wt_mvm_stats *s = &m->stats;
    printf("built %s (%s): R %lld x %lld, RA %lld x %lld, float32\n", args.out, args.recon, (long long)m->nact,
           (long long)m->nslopes, (long long)m->nact, (long long)m->nact);
    printf("  %lld unknowns, nnz(A~ LGS) %lld, nnz(N) %lld, factor %.3g non-zeros (%.2f GB, %s ordering), "
           "Woodbury rank %d\n",
           (long long)s->nunknowns, (long long)s->nnz_a, (long long)s->nnz_normal, s->nnz_factor,
           s->factor_bytes / 1e9, s->ordering ? s->ordering : "?", s->rank);
    printf("  time %.1f s (assemble %.1f, normal %.1f, analyse %.1f, factorise %.1f, low-rank %.1f, fitting %.1f, "
           "solve %.1f) + write %.1f s\n",
           s->t_total, s->t_assemble, s->t_normal, s->t_analyze, s->t_factorize, s->t_lowrank, s->t_fitting,
           s->t_solve, wt_time_now() - tw0);
    printf("  peak memory %.2f GB (estimated %.2f GB)\n", ru.ru_maxrss / 1048576.0, s->peak_estimate / 1e9);
    goto cleanup;
fail:
    rc = wt_cli_fail(&cli, st);
    goto cleanup;
quiet_fail: /* another rank failed and said why, or the MPI call printed its error */
    rc = 1;
cleanup:
    wt_h5_abort(w);
    wt_mvm_free(m);
    wt_system_free(sys);
    wt_config_free(cli.ctx, cfg);
    wt_cli_done(&cli);
    return rc;
}

/* wt_mvm_options.stop: a deferred SIGINT/SIGTERM/SIGHUP (wt_interrupt_defer) is pending */
static int stop_on_signal(void *user)
{
    (void)user;
    return wt_interrupt_pending() != 0;
}

int wt_build_mvm_cached(wt_cli *cli, const char *dir, wt_config *cfg, wt_system *sys, int argc, char **argv, wt_mvm **out,
                        double *build_s)
{
    char path[2048];
    int st;
    *build_s = 0.0;
    /* the precision is not part of the system's hash (one system, several storages): it names the file */
    snprintf(path, sizeof path, "%s/cache/mvm-pcg3-%.16s%s%s.h5", dir, cfg->matrix_sha256, cfg->mvm_precision ? "-" : "",
             cfg->mvm_precision ? wt_prec_name(cfg->mvm_precision) : "");
    FILE *f = fopen(path, "rb");
    if (f) {
        fclose(f);
        if (wt_mvm_read(cli->ctx, path, cfg, sys->nact, sys->nslopes, out, NULL) == WT_OK &&
            (*out)->precision != cfg->mvm_precision) {
            wt_mvm_free(*out);
            *out = NULL;
        } else if (*out) {
            if (!cli->quiet) fprintf(stderr, "%s: mvm from the cache %s\n", cli->prog, path);
            return WT_OK;
        }
        if (!cli->quiet) fprintf(stderr, "%s: rebuilding the stale or damaged %s\n", cli->prog, path);
    }
    wt_h5_writer *w = NULL;
    if ((st = wt_h5_check_replaceable(cli->ctx, path, cli->force)) < 0) return st;
    if (!cli->quiet) fprintf(stderr, "%s: building the MVM for %s (hash %.16s)\n", cli->prog, cfg->path, cfg->matrix_sha256);
    wt_mvm_options o;
    wt_mvm_options_default(&o);
    o.stop = stop_on_signal; /* compare and budget defer SIGTERM: a build of minutes ends at its next block */
    if ((st = wt_mvm_build_variant(cli->ctx, sys, cfg, "pcg3", &o, out)) < 0) return st;
    *build_s = (*out)->stats.t_total;
    if ((st = wt_h5_create(cli->ctx, path, &w)) < 0) return st;
    if ((st = wt_cli_write_provenance(cli, w, cfg, argc, argv)) >= 0 && (st = wt_cli_write_layout(w, sys)) >= 0 &&
        (st = wt_mvm_write(w, *out, cfg, "pcg3")) >= 0) {
        st = wt_h5_commit(w);
        w = NULL;
    }
    wt_h5_abort(w);
    return st;
}
