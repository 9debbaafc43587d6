/* cli/mpi.h: the one place wavetomo talks MPI (`mpirun -n K wavetomo compare|build`). The library
 * (core/) stays MPI-free: it only learns "compute part i of n" (wt_mvm_options.part_index/part_count); the
 * drivers split the work with wt_mpi_rank/size and move plain bytes with the calls below.
 *
 * MPI is entered only when the process was started by an MPI launcher (mpirun/mpiexec: OMPI_COMM_WORLD_SIZE;
 * srun and other PMI launchers: PMI_SIZE / PMIX_RANK). A plain `wavetomo compare` never calls MPI_Init:
 * OpenMPI's singleton init would cost ~0.45 s and start a helper daemon for every command, for nothing.
 *
 * Waiting: OpenMPI's blocking calls spin a core at 100 %; a rank that waits for another's result here
 * polls with MPI_Test and sleeps 2 ms between polls, so on a shared machine it leaves the core to the
 * ranks still computing.
 */
#ifndef WT_CLI_MPI_H
#define WT_CLI_MPI_H

#include <stddef.h>

typedef struct wt_mpi {
    int rank, size; /* 0 and 1 without MPI */
    int active;     /* 1: MPI_Init was called (wt_mpi_end calls MPI_Finalize) */
} wt_mpi;

/* Enter MPI when launched by mpirun/srun (see above), else rank 0 of 1. Non-zero on an MPI failure (message
 * printed). */
int wt_mpi_begin(wt_mpi *p);
/* MPI_Finalize when active. */
void wt_mpi_end(wt_mpi *p);
/* Rank and size as the launcher's environment gives them, before (or without) MPI_Init: 1 when started by an MPI
 * launcher, else 0 with *rank = 0, *size = 1. For what must differ per rank before MPI is entered (--dry-run). */
int wt_mpi_launch_rank(int *rank, int *size);
/* Give up on the whole job (another rank may be waiting for this one): MPI_Abort when active. */
void wt_mpi_abort(wt_mpi *p, int code);

/* Point-to-point bytes (any size: split into messages below 2^31 bytes), tag names the message kind. Both
 * return 0 or -1 (message printed). */
int wt_mpi_send(wt_mpi *p, const void *buf, size_t bytes, int to, int tag);
int wt_mpi_recv(wt_mpi *p, void *buf, size_t bytes, int from, int tag);
/* Broadcast bytes from rank 0 to all. */
int wt_mpi_bcast(wt_mpi *p, void *buf, size_t bytes);
/* The largest *value over all ranks, on every rank (statuses: any rank's failure seen by all). */
int wt_mpi_max_int(wt_mpi *p, int *value);

#endif
