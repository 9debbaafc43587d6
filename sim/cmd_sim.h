/* sim/cmd_sim.h: `wavetomo sim`, the closed-loop end-to-end simulation of one reconstructor (sim/cmd_sim.c).
 * Returns the process exit code. */
#ifndef WT_SIM_CMD_SIM_H
#define WT_SIM_CMD_SIM_H

int wt_cmd_sim(int argc, char **argv);

#endif
