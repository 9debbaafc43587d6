/* core/io/h5_temp.c: the writers' temporaries "TARGET.tmp-<pid>" (SPEC §9, atomic output) when the process
 * is interrupted, and the process-wide HDF5 set-up.
 *
 * SIGINT/SIGTERM: a handler unlinks every temporary still being written, then re-raises the signal with
 * its default action, so Ctrl-C leaves neither a target nor a temporary behind. SIGKILL cannot be caught:
 * its temporary stays, is incomplete (no root attribute "complete", so every reader refuses it), and the
 * next writer of the same target removes it once its process is gone (wt_h5_priv_remove_stale).
 *
 * wt_interrupt_defer(1) turns the first signal into a flag the caller polls (wt_interrupt_pending) and
 * acts on at a safe point; the second signal acts as above.
 *
 * Why a global: a signal handler receives nothing but the signal number, so the paths it must unlink have
 * to live in static storage. This registry is the only mutable global of the library; it is a fixed
 * table (no allocation), written only by the thread that creates and commits writers, and read by the
 * handler with async-signal-safe calls only (unlink, signal, raise). A slot's path is complete before its
 * flag is set (signal fence), so the handler never sees half a name.
 */
#include "h5_private.h"

#include <dirent.h>
#include <errno.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <sys/types.h>
#include <unistd.h>

#define SLOTS 16
#define PATH_BYTES 4096

static char temp_path[SLOTS][PATH_BYTES];
static volatile sig_atomic_t temp_used[SLOTS];

int wt_h5_priv_temp_register(const char *path)
{
    if (!path || strlen(path) >= PATH_BYTES) return -1;
    for (int i = 0; i < SLOTS; i++)
        if (!temp_used[i]) {
            memcpy(temp_path[i], path, strlen(path) + 1);
            atomic_signal_fence(memory_order_seq_cst);
            temp_used[i] = 1;
            return i;
        }
    return -1; /* more than SLOTS writers open at once: that temporary is not cleaned on a signal */
}

void wt_h5_priv_temp_unregister(int slot)
{
    if (slot >= 0 && slot < SLOTS) temp_used[slot] = 0;
}

/* Deferred mode (wt_interrupt_defer): the first signal is only recorded, so that a long job made of
 * independent pieces (compare's cases) can stop between frames and keep what is finished; a second one
 * ends the process as usual. */
static volatile sig_atomic_t defer_on, pending;

void wt_interrupt_defer(int on)
{
    defer_on = on ? 1 : 0;
    if (!on) pending = 0;
}

int wt_interrupt_pending(void) { return pending; }

static void on_signal(int sig)
{
    if (defer_on && !pending) {
        pending = sig;
        return;
    }
    for (int i = 0; i < SLOTS; i++)
        if (temp_used[i]) unlink(temp_path[i]);
    signal(sig, SIG_DFL);
    raise(sig);
}

void wt_h5_process_init(void)
{
    /* HDF5 1.10.8: once a metadata flush has failed (disk full), every later flush of that file fails
     * ("slist already enabled?"), so the file can never be closed, and the library's atexit clean-up then
     * crashes on it (SIGSEGV in H5F__close_cb). Without that clean-up the process exits normally; files
     * that matter were closed explicitly (commit), the temporaries are unlinked by abort. */
    H5dont_atexit();
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    const int sigs[] = {SIGINT, SIGTERM, SIGHUP};
    for (int i = 0; i < 3; i++) {
        struct sigaction old;
        /* leave a signal alone when the caller ignores it (nohup, a shell's background job) */
        if (sigaction(sigs[i], NULL, &old) == 0 && old.sa_handler == SIG_IGN) continue;
        sigaction(sigs[i], &sa, NULL);
    }
}

void wt_h5_priv_remove_stale(const char *target)
{
    /* "<dir>/<base>.tmp-<pid>" of a process that no longer exists: an earlier run killed by SIGKILL */
    const char *slash = strrchr(target, '/');
    char dir[PATH_BYTES];
    const char *base = slash ? slash + 1 : target;
    size_t dl = slash ? (size_t)(slash - target) : 1;
    if (dl >= sizeof dir) return;
    if (slash) memcpy(dir, target, dl), dir[dl] = '\0';
    else strcpy(dir, ".");
    if (slash == target) strcpy(dir, "/");
    DIR *d = opendir(dir);
    if (!d) return;
    size_t bl = strlen(base);
    struct dirent *e;
    while ((e = readdir(d))) {
        if (strncmp(e->d_name, base, bl) || strncmp(e->d_name + bl, ".tmp-", 5)) continue;
        const char *p = e->d_name + bl + 5;
        char *end;
        long pid = strtol(p, &end, 10);
        if (!*p || *end || pid <= 0 || pid == (long)getpid()) continue;
        if (kill((pid_t)pid, 0) == 0 || errno != ESRCH) continue; /* alive, or not ours to judge */
        char full[2 * PATH_BYTES];
        snprintf(full, sizeof full, "%s/%s", dir, e->d_name);
        unlink(full);
    }
    closedir(d);
}
