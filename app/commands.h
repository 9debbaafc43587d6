/* app/commands.h: the subcommands that live with the dispatcher (app/wavetomo.c): the inspection and
 * machine-tuning tools.
 * Every other subcommand is declared by its folder's header (builder/cmd_build.h, runtime/cmd_run.h,
 * sim/cmd_sim.h, compare/cmd_compare.h). Each parses its own options with cli/cli.h, calls the library and returns the
 * process exit code (0 success, 1 failure with a message, 2 usage error). */
#ifndef WT_APP_COMMANDS_H
#define WT_APP_COMMANDS_H

int wt_cmd_info(int argc, char **argv);  /* app/info.c: the derived sizes of a system, its spots */
int wt_cmd_wisdom(int argc, char **argv); /* app/wisdom.c: measured FFT plans for recon.fft_wisdom */

#endif
