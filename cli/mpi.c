/* cli/mpi.c: MPI for the drivers (OpenMPI; see mpi.h). Every wait polls with a short sleep (no spinning). */
#include "cli/mpi.h"

#include <mpi.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

/* Largest message: MPI counts are int; stay well below 2^31 bytes. */
#define CHUNK ((size_t)1 << 30)

static int launched_by_mpi(void)
{
    return getenv("OMPI_COMM_WORLD_SIZE") || getenv("PMI_SIZE") || getenv("PMIX_RANK");
}

static int env_int(const char *a, const char *b, int fallback)
{
    const char *v = getenv(a);
    if (!v && b) v = getenv(b);
    return v ? atoi(v) : fallback;
}

int wt_mpi_launch_rank(int *rank, int *size)
{
    *rank = 0;
    *size = 1;
    if (!launched_by_mpi()) return 0;
    *rank = env_int("OMPI_COMM_WORLD_RANK", getenv("PMIX_RANK") ? "PMIX_RANK" : "PMI_RANK", 0);
    *size = env_int("OMPI_COMM_WORLD_SIZE", "PMI_SIZE", 1);
    return 1;
}

static int fail(const char *what, int code)
{
    char msg[MPI_MAX_ERROR_STRING];
    int n = 0;
    if (MPI_Error_string(code, msg, &n) != MPI_SUCCESS) snprintf(msg, sizeof msg, "code %d", code);
    fprintf(stderr, "wavetomo: error: %s failed: %s\n", what, msg);
    return -1;
}

/* Wait for one request, sleeping between tests so that a waiting rank leaves its core to the others. */
static int wait_for(MPI_Request *rq, const char *what)
{
    const struct timespec nap = {0, 2000000};
    for (;;) {
        int done = 0, rc = MPI_Test(rq, &done, MPI_STATUS_IGNORE);
        if (rc != MPI_SUCCESS) return fail(what, rc);
        if (done) return 0;
        nanosleep(&nap, NULL);
    }
}

int wt_mpi_begin(wt_mpi *p)
{
    p->rank = 0, p->size = 1, p->active = 0;
    if (!launched_by_mpi()) return 0;
    int rc = MPI_Init(NULL, NULL);
    if (rc != MPI_SUCCESS) return fail("MPI_Init", rc);
    p->active = 1;
    /* errors come back as codes (reported with the rank's message) instead of aborting silently */
    MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN);
    MPI_Comm_rank(MPI_COMM_WORLD, &p->rank);
    MPI_Comm_size(MPI_COMM_WORLD, &p->size);
    return 0;
}

void wt_mpi_end(wt_mpi *p)
{
    if (p->active) MPI_Finalize();
    p->active = 0;
}

void wt_mpi_abort(wt_mpi *p, int code)
{
    if (p->active && p->size > 1) MPI_Abort(MPI_COMM_WORLD, code);
}

int wt_mpi_send(wt_mpi *p, const void *buf, size_t bytes, int to, int tag)
{
    for (size_t off = 0; off < bytes; off += CHUNK) {
        size_t n = bytes - off < CHUNK ? bytes - off : CHUNK;
        MPI_Request rq;
        int rc = MPI_Isend((const char *)buf + off, (int)n, MPI_BYTE, to, tag, MPI_COMM_WORLD, &rq);
        if (rc != MPI_SUCCESS) return fail("MPI_Isend", rc);
        if (wait_for(&rq, "MPI_Isend") < 0) return -1;
    }
    (void)p;
    return 0;
}

int wt_mpi_recv(wt_mpi *p, void *buf, size_t bytes, int from, int tag)
{
    for (size_t off = 0; off < bytes; off += CHUNK) {
        size_t n = bytes - off < CHUNK ? bytes - off : CHUNK;
        MPI_Request rq;
        int rc = MPI_Irecv((char *)buf + off, (int)n, MPI_BYTE, from, tag, MPI_COMM_WORLD, &rq);
        if (rc != MPI_SUCCESS) return fail("MPI_Irecv", rc);
        if (wait_for(&rq, "MPI_Irecv") < 0) return -1;
    }
    (void)p;
    return 0;
}

int wt_mpi_bcast(wt_mpi *p, void *buf, size_t bytes)
{
    if (p->size <= 1) return 0;
    for (size_t off = 0; off < bytes; off += CHUNK) {
        size_t n = bytes - off < CHUNK ? bytes - off : CHUNK;
        MPI_Request rq;
        int rc = MPI_Ibcast((char *)buf + off, (int)n, MPI_BYTE, 0, MPI_COMM_WORLD, &rq);
        if (rc != MPI_SUCCESS) return fail("MPI_Ibcast", rc);
        if (wait_for(&rq, "MPI_Ibcast") < 0) return -1;
    }
    return 0;
}

int wt_mpi_max_int(wt_mpi *p, int *value)
{
    if (p->size <= 1) return 0;
    int in = *value;
    MPI_Request rq;
    int rc = MPI_Iallreduce(&in, value, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD, &rq);
    if (rc != MPI_SUCCESS) return fail("MPI_Iallreduce", rc);
    return wait_for(&rq, "MPI_Iallreduce");
}
