/* app/wavetomo.c: the `wavetomo` executable: git-style dispatch to the subcommands (app/commands.h), the
 * top of the drivers: nothing calls back into it. */
#include <stdio.h>
#include <string.h>

#include "app/commands.h"
#include "builder/cmd_build.h"
#include "compare/cmd_compare.h"
#include "runtime/cmd_run.h"
#include "sim/cmd_sim.h"
#include "cli/cli.h"
#include "core/base/names.h"
#include "core/io/h5.h"

static void usage(FILE *f)
{
    fprintf(f,
            "usage: wavetomo [--version] [--help] <command> [options]\n"
            "\n"
            "Wavelet tomography for multi-conjugate adaptive optics (Helin & Yudytskiy), with an MVM\n"
            "reference, for ELT-size systems.\n"
            "\n"
            "commands:\n"
            "  info CONFIG      derived sizes of a system: subapertures, slopes, actuators, unknowns,\n"
            "                   non-zeros of the operators, MVM matrix size (--keys: config reference)\n"
            "  sim              closed-loop simulation of one reconstructor (pcg3, cg9, mvm, none)\n"
            "  build            offline MVM builder: CHOLMOD factorisation -> control matrix MATRIX.h5\n"
            "  run              apply a stored MVM or the wavelet PCG to every frame of a telemetry file\n"
            "  learn            identify r0 and the Cn2 profile from the pseudo-open-loop slopes of a telemetry file\n"
            "  compare          side-by-side closed-loop comparison (MVM, PCG-3, CG-9) with a report\n"
            "  budget           error budget: fitting, tomography, noise, servo lag, tip-tilt, rim (SPEC §11)\n"
            "  bench CONFIG     time the reconstructor kernels (normal operator, PCG iteration)\n"
            "  wisdom CONFIG    measure this machine's FFT plans once -> FFTW wisdom file for recon.fft_wisdom\n"
            "\n"
            "Every command takes --set key=value (any config key, repeatable), --threads N (OpenMP and OpenBLAS),\n"
            "--force (replace an existing file that is not a wavetomo output) and --help.\n"
            "CONFIG is a file or a preset's name (demo, demo-diffractive, eelt-mcao, eelt-mcao-eso35, ...), looked up\n"
            "in data/presets/ beside the executable's directory (the source tree), in ./data/presets/, then in\n"
            "share/wavetomo/presets/ beside it (after make install). eelt-mcao is the paper's E-ELT system.\n");
}

int main(int argc, char **argv)
{
    wt_h5_process_init(); /* before any HDF5 use: see core/io/h5.h (a full disk must not crash the exit) */
    if (argc < 2) {
        usage(stderr);
        return 2;
    }
    const char *cmd = argv[1];
    if (!strcmp(cmd, "--help") || !strcmp(cmd, "-h") || !strcmp(cmd, "help")) {
        usage(stdout);
        return 0;
    }
    if (!strcmp(cmd, "--version") || !strcmp(cmd, "version")) {
        printf("wavetomo %s\n", WT_VERSION);
        return 0;
    }
    static const struct {
        const char *name;
        int (*fn)(int, char **);
    } cmds[] = {{"info", wt_cmd_info},       {"bench", wt_cmd_bench}, {"wisdom", wt_cmd_wisdom},
                {"sim", wt_cmd_sim},         {"build", wt_cmd_build}, {"run", wt_cmd_run},
                {"learn", wt_cmd_learn},     {"compare", wt_cmd_compare}, {"budget", wt_cmd_budget}};
    enum { NCMD = sizeof cmds / sizeof *cmds };
    const char *names[NCMD];
    for (int k = 0; k < NCMD; k++) {
        if (!strcmp(cmd, cmds[k].name)) return cmds[k].fn(argc - 1, argv + 1);
        names[k] = cmds[k].name;
    }
    const int near = wt_nearest_name(cmd, names, NCMD);
    if (near >= 0) fprintf(stderr, "wavetomo: error: unknown command '%s' (did you mean '%s'?)\n\n", cmd, names[near]);
    else fprintf(stderr, "wavetomo: error: unknown command '%s'\n\n", cmd);
    usage(stderr);
    return 2;
}
