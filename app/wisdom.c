/* app/wisdom.c: `wavetomo wisdom`: measure the reconstructors' FFT plans on this machine once and store them in
 * an FFTW wisdom file, which recon.fft_wisdom then names (core/la/fft.h; docs/design.md "FFT plans"). */
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "app/commands.h"
#include "cli/cli.h"
#include "core/la/fft.h"

static void help(void)
{
    printf("usage: wavetomo wisdom [--config] CONFIG --out FILE [--set key=value]... [--dry-run] [--quiet] [--force]\n"
           "\n"
           "Measures (FFTW_MEASURE) the FFTs that the reconstructors of CONFIG run every iteration — the n x n\n"
           "real transform pair of each layer size of a variant with the full prior (recon.<variant>.prior =\n"
           "\"full\"), which the fourier preconditioner shares — and writes the chosen plans to FILE as FFTW wisdom\n"
           "(through a temporary file and rename). Then\n"
           "\n"
           "    --set recon.fft_wisdom=\"FILE\"   (or the key in the configuration)\n"
           "\n"
           "plans those transforms from FILE alone: faster than FFTW_ESTIMATE's (about 1.6x at 128 x 128 on the\n"
           "E-ELT's host), the same plans and bits every run with the same file, whose SHA-256 every output\n"
           "records (recon.fft_wisdom_sha256). The plans are this machine's and this FFTW's: make the file on the\n"
           "machine that runs. A configuration whose sizes FILE lacks is refused when it sets up.\n"
           "\n"
           "  --out FILE    the wisdom file (an existing file is replaced only when it is FFTW wisdom, or --force)\n"
           "  --set k=v     override a configuration key (repeatable)\n"
           "  --dry-run     print the sizes it would measure; measure and write nothing\n"
           "  --quiet       no progress lines\n");
}

typedef struct {
    const char *out;
} wisdom_args;

static int wisdom_option(wt_cli *cli, int argc, char **argv, int *i, void *user)
{
    wisdom_args *a = user;
    if (!strcmp(argv[*i], "--out")) {
        if (!(a->out = wt_cli_value(cli, argc, argv, i))) return -1;
    } else return 0; /* CONFIG (positional or --config) is the common options' */
    return 1;
}

int wt_cmd_wisdom(int argc, char **argv)
{
    wt_cli cli;
    if (wt_cli_init(&cli, "wavetomo wisdom", help)) return 1;
    wisdom_args args = {NULL};
    int rc = wt_cli_parse(&cli, argc, argv, wisdom_option, &args);
    if (rc >= 0) {
        wt_cli_done(&cli);
        return rc;
    }
    if (!args.out) {
        rc = wt_cli_usage_error(&cli, "--out FILE is required (the wisdom file to write)");
        wt_cli_done(&cli);
        return rc;
    }
    wt_config *cfg = NULL;
    wt_fft_wisdom *w = NULL;
    int st = wt_cli_read_config(&cli, NULL, &cfg);
    if (st < 0) goto out;
    if ((st = wt_cli_check_text_output(&cli, args.out, "(fftw-", NULL)) < 0) goto out;
    if ((st = wt_fft_wisdom_learner(cli.ctx, &w)) < 0) goto out;
    int sizes[2 * WT_MAX_LAYERS], nsizes = 0;
    for (int k = 0; k < 2; k++) {
        const wt_recon_variant_config *v = k ? &cfg->cg9 : &cfg->pcg3;
        if (v->prior != WT_CFG_PRIOR_FULL) continue;
        for (int l = 0; l < v->nlayers; l++) {
            int seen = 0;
            for (int j = 0; j < nsizes; j++) seen |= sizes[j] == v->size[l];
            if (!seen) sizes[nsizes++] = v->size[l];
        }
    }
    if (nsizes == 0) {
        st = WT_ERROR(cli.ctx, WT_ERR_CONFIG, "%s: neither reconstructor has the full prior (recon.pcg3.prior, "
                      "recon.cg9.prior): they plan no FFT, there is no wisdom to measure", cfg->path);
        goto out;
    }
    if (cli.dry_run) {
        printf("would measure for %s, FFTW %s:", cfg->path, wt_fft_version());
        for (int j = 0; j < nsizes; j++) printf(" %dx%d", sizes[j], sizes[j]);
        printf(" (the r2c + c2r pair of each size; under a second each)\n");
        goto out;
    }
    for (int j = 0; j < nsizes; j++) {
        const double t0 = wt_time_now();
        if (!cli.quiet) fprintf(stderr, "wavetomo wisdom: %d x %d real FFT pair: ", sizes[j], sizes[j]);
        if ((st = wt_fft_wisdom_learn(cli.ctx, w, sizes[j])) < 0) goto out;
        if (!cli.quiet) fprintf(stderr, "measured in %.1f s\n", wt_time_now() - t0);
    }
    if ((st = wt_fft_wisdom_write(cli.ctx, w, args.out)) < 0) goto out;
    printf("wrote %s: FFTW %s wisdom for", args.out, wt_fft_version());
    for (int j = 0; j < nsizes; j++) printf(" %dx%d", sizes[j], sizes[j]);
    char abs[4096];
    /* the key's relative paths are the configuration's directory's: suggest the absolute one */
    printf(" (SHA-256 %s); use it with --set recon.fft_wisdom=\"%s\"\n", wt_fft_wisdom_sha256(w),
           realpath(args.out, abs) ? abs : args.out);
out:
    if (st < 0) rc = wt_cli_fail(&cli, st);
    else rc = 0;
    wt_fft_wisdom_free(w);
    wt_config_free(cli.ctx, cfg);
    wt_cli_done(&cli);
    return rc;
}
