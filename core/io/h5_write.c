/* core/io/h5_write.c: the atomic HDF5 writer: datasets, attributes, groups, commit (the row-block matrices
 * and appendable series it also writes are in h5_stream.c, registered here as open pieces that commit
 * closes through a function pointer; the plumbing all h5 files share is h5_common.c).
 *
 * Implements the file side of SPEC §9 (R and RÂ as float32, written to a temporary and renamed so an
 * interrupted build never leaves a file that looks complete) and the telemetry/result files of the
 * simulator. Every public function brackets its HDF5 calls with quiet_on/quiet_off: HDF5's automatic
 * stack printing is off inside, restored on return, and the innermost HDF5 error description is
 * folded into our message (H5ERR). Writers remember their first failure and refuse to commit.
 * The reader is h5_read.c; what the h5 files share is declared in h5_private.h.
 */
#define _GNU_SOURCE /* memfd_create (discard_writes) */
#include "h5_private.h"

#include <errno.h>
#include <fcntl.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>

/* ---- writability probe -------------------------------------------------------------------------- */

int wt_h5_check_writable(wt_context *ctx, const char *path, int64_t bytes)
{
    int st = WT_OK;
    char *dir = NULL, *probe = NULL;
    struct stat sb;
    if (!path || !*path) return WT_ERROR(ctx, WT_ERR_INVALID, "wt_h5_check_writable: empty output path");
    WT_ALLOC(ctx, dir, strlen(path) + 2, "a directory name");
    const char *slash = strrchr(path, '/');
    if (!slash)
        strcpy(dir, ".");
    else if (slash == path)
        strcpy(dir, "/");
    else
        memcpy(dir, path, (size_t)(slash - path));
    if (stat(dir, &sb) != 0)
        FAIL(ctx, WT_ERR_IO, "cannot write '%s': directory '%s' %s", path, dir,
             errno == ENOENT ? "does not exist" : strerror(errno));
    if (!S_ISDIR(sb.st_mode)) FAIL(ctx, WT_ERR_IO, "cannot write '%s': '%s' is not a directory", path, dir);
    if (stat(path, &sb) == 0 && S_ISDIR(sb.st_mode))
        FAIL(ctx, WT_ERR_IO, "cannot write '%s': it is a directory, expected a file name", path);
    WT_ALLOC(ctx, probe, strlen(path) + 32, "a probe file name");
    snprintf(probe, strlen(path) + 32, "%s.probe-%ld", path, (long)getpid());
    int fd = open(probe, O_WRONLY | O_CREAT | O_EXCL, 0600);
    if (fd < 0)
        FAIL(ctx, WT_ERR_IO, "cannot write '%s': creating a file in directory '%s' failed: %s", path, dir,
             strerror(errno));
    close(fd);
    unlink(probe);
    struct statvfs vs;
    if (bytes > 0 && statvfs(dir, &vs) == 0 && (double)vs.f_bavail * (double)vs.f_frsize < (double)bytes)
        FAIL(ctx, WT_ERR_IO, "cannot write '%s': it needs %.2f GB, only %.2f GB are free in '%s'", path,
             1e-9 * (double)bytes, 1e-9 * (double)vs.f_bavail * (double)vs.f_frsize, dir);
fail:
    wt_free(ctx, probe);
    wt_free(ctx, dir);
    return st;
}

/* 1 when `path` is an HDF5 file whose root attribute "creator" starts with "wavetomo": a variable-length
 * string, or a fixed-length one in the files of earlier builds. */
static int is_ours(const char *path)
{
    if (H5Fis_hdf5(path) <= 0) return 0;
    hid_t f = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT), a = -1, t = -1, space = -1, mt = -1;
    int ours = 0;
    char buf[64] = {0}, *vl = NULL;
    if (f >= 0 && H5Aexists(f, "creator") > 0 && (a = H5Aopen(f, "creator", H5P_DEFAULT)) >= 0 &&
        (t = H5Aget_type(a)) >= 0 && H5Tget_class(t) == H5T_STRING && (space = H5Aget_space(a)) >= 0 &&
        H5Sget_simple_extent_npoints(space) == 1) {
        if (H5Tis_variable_str(t) > 0) {
            if ((mt = H5Tcopy(H5T_C_S1)) >= 0 && H5Tset_size(mt, H5T_VARIABLE) >= 0 &&
                H5Tset_cset(mt, H5Tget_cset(t)) >= 0 && H5Aread(a, mt, &vl) >= 0 && vl)
                ours = !strncmp(vl, "wavetomo", 8);
            if (vl) H5Dvlen_reclaim(mt, space, H5P_DEFAULT, &vl);
        } else if (H5Tget_size(t) < sizeof buf && H5Aread(a, t, buf) >= 0) {
            ours = !strncmp(buf, "wavetomo", 8);
        }
    }
    wt_h5_priv_drop(mt);
    wt_h5_priv_drop(space);
    wt_h5_priv_drop(t);
    wt_h5_priv_drop(a);
    wt_h5_priv_drop(f);
    return ours;
}

int wt_h5_check_replaceable(wt_context *ctx, const char *path, int force)
{
    struct stat sb;
    if (!path || force || lstat(path, &sb) != 0) return WT_OK;
    if (S_ISDIR(sb.st_mode)) return WT_ERROR(ctx, WT_ERR_IO, "cannot write '%s': it is a directory", path);
    wt_h5_priv_quiet q = wt_h5_priv_quiet_on();
    int ours = S_ISREG(sb.st_mode) && is_ours(path);
    wt_h5_priv_quiet_off(q);
    if (!ours)
        return WT_ERROR(ctx, WT_ERR_IO,
                        "'%s' exists and is not a wavetomo output (%s); refusing to replace it: choose another "
                        "name, or give --force", path,
                        S_ISLNK(sb.st_mode) ? "a symbolic link" : !S_ISREG(sb.st_mode) ? "not a regular file"
                                                                                     : "no HDF5 root attribute creator = \"wavetomo ...\"");
    return WT_OK;
}

const char *wt_h5_library_version(void)
{
#define WT_H5_STR_(x) #x
#define WT_H5_STR(x) WT_H5_STR_(x)
    return WT_H5_STR(H5_VERS_MAJOR) "." WT_H5_STR(H5_VERS_MINOR) "." WT_H5_STR(H5_VERS_RELEASE);
}

/* ---- writer ------------------------------------------------------------------------------------- */

/* A temporary that is being thrown away after a write error (disk full, file too large): HDF5 1.10 still
 * flushes its metadata cache on H5Fclose, that flush fails again, the close fails and leaves the file in
 * HDF5's table, and the library's own clean-up at exit then crashes inside H5F__close_cb.
 * Pointing the file's descriptor at an anonymous memory file first lets that last flush and truncate
 * succeed into memory that is freed with it (/dev/null would refuse the truncate), so the close completes
 * once and releases everything; the temporary is unlinked right after. Only on the discard path, and only
 * the descriptor of our sec2 file. */
static void discard_writes(hid_t file)
{
    void *handle = NULL;
    if (file < 0 || H5Fget_vfd_handle(file, H5P_DEFAULT, &handle) < 0 || !handle) return;
    int fd = *(int *)handle, mem = memfd_create("wavetomo-discard", MFD_CLOEXEC);
    if (mem < 0) return;
    if (fd >= 0) dup2(mem, fd);
    close(mem);
}

/* Close everything; unlink the temporary when asked and when it is ours; free w. */
static void writer_destroy(wt_h5_writer *w, int remove_temp)
{
    if (!w) return;
    if (remove_temp) discard_writes(w->file); /* the file is thrown away: nothing of it needs to reach the disk */
    while (w->open) w->open->close(w->open, 0);
    wt_h5_priv_drop(w->lcpl);
    wt_h5_priv_drop(w->file);
    if (remove_temp && w->created && w->temp) unlink(w->temp);
    wt_h5_priv_temp_unregister(w->temp_slot);
    wt_free(w->ctx, w->temp);
    wt_free(w->ctx, w->target);
    wt_free(w->ctx, w);
}

static int create_impl(wt_context *ctx, const char *path, wt_h5_writer **out)
{
    int st = WT_OK;
    wt_h5_writer *w = NULL;
    hid_t fapl = -1;
    if (!out) return WT_ERROR(ctx, WT_ERR_INVALID, "wt_h5_create: out is NULL");
    *out = NULL;
    if (!path || !*path) return WT_ERROR(ctx, WT_ERR_INVALID, "wt_h5_create: empty output path");
    WT_ALLOC(ctx, w, 1, "an HDF5 writer");
    w->ctx = ctx;
    w->file = w->lcpl = -1;
    w->temp_slot = -1;
    size_t tn = strlen(path) + 32;
    w->target = wt_h5_priv_dupstr(ctx, path);
    w->temp = wt_malloc(ctx, tn, 1);
    if (!w->target || !w->temp) FAIL(ctx, WT_ERR_NOMEM, "out of memory for the file names of '%s'", path);
    snprintf(w->temp, tn, "%s.tmp-%ld", path, (long)getpid());
    wt_h5_priv_remove_stale(path); /* temporaries of earlier runs that were killed (SIGKILL) */
    if ((fapl = wt_h5_priv_file_access()) < 0)
        H5FAIL(ctx, WT_ERR_LIBRARY, "%s: cannot set up file access properties", path);
    /* registered before it exists: a signal between H5Fcreate and the registration would leave it behind
     * (seen under load by the bad-input suite's SIGTERM case); the name carries our pid, so unlinking it
     * before it is created removes nothing of anyone else's */
    w->temp_slot = wt_h5_priv_temp_register(w->temp); /* unlinked on SIGINT/SIGTERM (h5_temp.c) */
    if ((w->file = H5Fcreate(w->temp, H5F_ACC_TRUNC, H5P_DEFAULT, fapl)) < 0)
        H5FAIL(ctx, WT_ERR_IO, "%s: cannot create the temporary file '%s' (H5Fcreate)", path, w->temp);
    w->created = 1;
    if ((w->lcpl = H5Pcreate(H5P_LINK_CREATE)) < 0 || H5Pset_create_intermediate_group(w->lcpl, 1) < 0 ||
        H5Pset_char_encoding(w->lcpl, H5T_CSET_UTF8) < 0)
        H5FAIL(ctx, WT_ERR_LIBRARY, "%s: cannot set up link creation properties", path);
    if (wt_h5_priv_put_attr_string(w->file, "creator", "wavetomo " WT_VERSION) < 0 ||
        wt_h5_priv_put_attr_string(w->file, "hdf5_version", wt_h5_library_version()) < 0)
        H5FAIL(ctx, WT_ERR_IO, "%s: cannot write the root attributes", path);
    wt_h5_priv_drop(fapl);
    *out = w;
    return WT_OK;
fail:
    wt_h5_priv_drop(fapl);
    writer_destroy(w, 1);
    return st;
}

int wt_h5_create(wt_context *ctx, const char *path, wt_h5_writer **out)
{
    int st;
    QUIET(create_impl(ctx, path, out));
    return st;
}

static int commit_impl(wt_h5_writer *w)
{
    wt_context *ctx = w->ctx;
    int st = WT_OK;
    const int64_t one = 1;
    while (w->open) wt_h5_priv_poison(w, w->open->close(w->open, 1));
    if (w->status < 0) FAIL(ctx, w->status, "%s: not written, an earlier call failed: %s", w->target, w->first_error);
    if (wt_h5_priv_put_attr(w->file, "complete", H5T_STD_I64LE, H5T_NATIVE_INT64, &one) < 0)
        H5FAIL(ctx, WT_ERR_IO, "%s: cannot write the root attribute 'complete'", w->target);
    /* Flush first: a failure here (disk full) goes to the discard path, which closes the file cleanly. A
     * failed H5Fclose instead leaves a half-destroyed file in HDF5's table that even a second close (or
     * the library's exit-time clean-up) crashes on: after this flush the close has next to nothing left
     * to write. */
    if (H5Fflush(w->file, H5F_SCOPE_LOCAL) < 0)
        H5FAIL(ctx, WT_ERR_IO, "%s: writing the temporary '%s' failed (H5Fflush; disk full?)", w->target, w->temp);
    herr_t r = H5Fclose(w->file);
    w->file = -1;
    if (r < 0)
        H5FAIL(ctx, WT_ERR_IO, "%s: closing the temporary '%s' failed (H5Fclose; disk full?)", w->target, w->temp);
    /* the data must be on disk before the name points at it, or a crash could publish a hollow file */
    int fd = open(w->temp, O_RDONLY), synced = fd >= 0 && fsync(fd) == 0;
    if (fd >= 0) close(fd);
    if (!synced) FAIL(ctx, WT_ERR_IO, "%s: cannot fsync the temporary '%s': %s", w->target, w->temp, strerror(errno));
    if (rename(w->temp, w->target) != 0)
        FAIL(ctx, WT_ERR_IO, "%s: cannot rename the temporary '%s' onto it: %s", w->target, w->temp, strerror(errno));
    w->created = 0;
    writer_destroy(w, 0);
    return WT_OK;
fail:
    writer_destroy(w, 1);
    return st;
}

int wt_h5_commit(wt_h5_writer *w)
{
    int st;
    if (!w) return WT_ERR_INVALID;
    QUIET(commit_impl(w));
    return st;
}

void wt_h5_abort(wt_h5_writer *w)
{
    wt_h5_priv_quiet q = wt_h5_priv_quiet_on();
    writer_destroy(w, 1);
    wt_h5_priv_quiet_off(q);
}

int wt_h5_flush(wt_h5_writer *w)
{
    int st = WT_OK;
    if (!w) return WT_ERR_INVALID;
    wt_h5_priv_quiet q = wt_h5_priv_quiet_on();
    if (H5Fflush(w->file, H5F_SCOPE_GLOBAL) < 0)
        st = wt_h5_priv_poison(w, H5ERR(w->ctx, WT_ERR_IO, "%s: H5Fflush of the temporary '%s' failed", w->target,
                                        w->temp));
    wt_h5_priv_quiet_off(q);
    return st;
}

const char *wt_h5_temp_path(const wt_h5_writer *w) { return w ? w->temp : NULL; }
const char *wt_h5_target_path(const wt_h5_writer *w) { return w ? w->target : NULL; }


static int write_impl(wt_h5_writer *w, const char *name, int ft, int mt, int rank, const int64_t *dims,
                      const void *data, const char *units, const char *desc)
{
    int st = WT_OK;
    hid_t space = -1, dcpl = -1, d = -1, ftid = -1, mtid = -1;
    hsize_t hd[WT_H5_MAX_RANK], chunk[WT_H5_MAX_RANK];
    WT_TRY(wt_h5_priv_check_new(w, name, units, desc, 1));
    WT_TRY(wt_h5_priv_check_types(w, name, ft, mt));
    if (rank < 1 || rank > WT_H5_MAX_RANK || !dims)
        return WT_ERROR(w->ctx, WT_ERR_INVALID, "%s: dataset '%s': rank %d, expected 1..%d", w->target, name, rank,
                        WT_H5_MAX_RANK);
    int64_t total = 1;
    for (int i = 0; i < rank; i++) {
        if (dims[i] < 0 || (dims[i] > 0 && total > INT64_MAX / dims[i]))
            return WT_ERROR(w->ctx, WT_ERR_INVALID, "%s: dataset '%s': dimension %d is %lld", w->target, name, i,
                            (long long)dims[i]);
        total *= dims[i];
        hd[i] = (hsize_t)dims[i];
    }
    if (total > 0 && !data) return WT_ERROR(w->ctx, WT_ERR_INVALID, "%s: dataset '%s': data is NULL", w->target, name);
    if ((space = H5Screate_simple(rank, hd, NULL)) < 0 ||
        (dcpl = wt_h5_priv_numeric_dcpl(rank, hd, wt_h5_priv_type_size(ft), WT_H5_PRIV_CHUNK_BYTES, rank, total == 0,
                                        chunk)) < 0 ||
        (ftid = wt_h5_priv_file_type(ft)) < 0 || (mtid = wt_h5_priv_mem_type(mt)) < 0 ||
        (d = H5Dcreate2(w->file, name, ftid, space, w->lcpl, dcpl, H5P_DEFAULT)) < 0)
        H5FAIL(w->ctx, WT_ERR_LIBRARY, "%s: cannot create dataset '%s' (H5Dcreate2)", w->target, name);
    if (total > 0 && H5Dwrite(d, mtid, H5S_ALL, H5S_ALL, H5P_DEFAULT, data) < 0)
        H5FAIL(w->ctx, WT_ERR_IO, "%s: writing dataset '%s' failed (H5Dwrite)", w->target, name);
    WT_TRY(wt_h5_priv_set_doc(w, d, name, units, desc));
    if (H5Dclose(d) < 0) st = H5ERR(w->ctx, WT_ERR_IO, "%s: closing dataset '%s' failed", w->target, name);
    d = -1;
fail:
    wt_h5_priv_drop(d);
    wt_h5_priv_drop(dcpl);
    wt_h5_priv_drop(space);
    wt_h5_priv_type_release(ft, ftid);
    wt_h5_priv_type_release(mt, mtid);
    return st;
}

int wt_h5_write(wt_h5_writer *w, const char *name, int file_type, int mem_type, int rank, const int64_t *dims,
                const void *data, const char *units, const char *description)
{
    WRITER_CALL(w, w, write_impl(w, name, file_type, mem_type, rank, dims, data, units, description));
}

/* A scalar dataset: numeric (ft >= 0, units required) or a string (ft < 0, text in value). */
static int scalar_impl(wt_h5_writer *w, const char *name, hid_t ft, hid_t mt, const void *value, const char *units,
                       const char *desc)
{
    int st = WT_OK;
    hid_t space = -1, d = -1, t = -1;
    int is_string = ft < 0;
    const char *text = NULL;
    WT_TRY(wt_h5_priv_check_new(w, name, units, desc, !is_string));
    if (is_string) {
        if (!value) return WT_ERROR(w->ctx, WT_ERR_INVALID, "%s: string dataset '%s' is NULL", w->target, name);
        if ((t = wt_h5_priv_vlen_string_type()) < 0)
            H5FAIL(w->ctx, WT_ERR_LIBRARY, "%s: cannot make a string type for '%s'", w->target, name);
        ft = mt = t;
        text = value;
        value = &text; /* a variable-length string's buffer is its pointer */
    }
    if ((space = H5Screate(H5S_SCALAR)) < 0 ||
        (d = H5Dcreate2(w->file, name, ft, space, w->lcpl, H5P_DEFAULT, H5P_DEFAULT)) < 0)
        H5FAIL(w->ctx, WT_ERR_LIBRARY, "%s: cannot create dataset '%s' (H5Dcreate2)", w->target, name);
    if (H5Dwrite(d, mt, H5S_ALL, H5S_ALL, H5P_DEFAULT, value) < 0)
        H5FAIL(w->ctx, WT_ERR_IO, "%s: writing dataset '%s' failed (H5Dwrite)", w->target, name);
    st = wt_h5_priv_set_doc(w, d, name, is_string ? NULL : units, desc);
fail:
    wt_h5_priv_drop(d);
    wt_h5_priv_drop(space);
    wt_h5_priv_drop(t);
    return st;
}

int wt_h5_write_double(wt_h5_writer *w, const char *name, double value, const char *units, const char *description)
{
    WRITER_CALL(w, w, scalar_impl(w, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, &value, units, description));
}

int wt_h5_write_int64(wt_h5_writer *w, const char *name, int64_t value, const char *units, const char *description)
{
    WRITER_CALL(w, w, scalar_impl(w, name, H5T_STD_I64LE, H5T_NATIVE_INT64, &value, units, description));
}

int wt_h5_write_string(wt_h5_writer *w, const char *name, const char *text, const char *description)
{
    WRITER_CALL(w, w, scalar_impl(w, name, -1, -1, text, NULL, description));
}

static int group_impl(wt_h5_writer *w, const char *name)
{
    if (!name || !*name) return WT_ERROR(w->ctx, WT_ERR_INVALID, "%s: empty group name", w->target);
    if (wt_h5_priv_path_exists(w->file, name)) {
        H5O_info_t info;
        if (H5Oget_info_by_name(w->file, name, &info, H5P_DEFAULT) < 0 || info.type != H5O_TYPE_GROUP)
            return WT_ERROR(w->ctx, WT_ERR_INVALID, "%s: '%s' exists and is not a group", w->target, name);
        return WT_OK;
    }
    hid_t g = H5Gcreate2(w->file, name, w->lcpl, H5P_DEFAULT, H5P_DEFAULT);
    if (g < 0) return H5ERR(w->ctx, WT_ERR_LIBRARY, "%s: cannot create group '%s' (H5Gcreate2)", w->target, name);
    H5Gclose(g);
    return WT_OK;
}

int wt_h5_group(wt_h5_writer *w, const char *name) { WRITER_CALL(w, w, group_impl(w, name)); }

/* Attribute on an existing object; ft < 0 means a string in value. */
static int attr_impl(wt_h5_writer *w, const char *obj, const char *name, hid_t ft, hid_t mt, const void *value)
{
    if (!obj || !name || !*name || !value)
        return WT_ERROR(w->ctx, WT_ERR_INVALID, "%s: attribute with a NULL or empty object, name or value", w->target);
    if (strcmp(obj, "/") == 0 && strcmp(name, "complete") == 0)
        return WT_ERROR(w->ctx, WT_ERR_INVALID, "%s: root attribute 'complete' is written by commit only", w->target);
    if (!wt_h5_priv_path_exists(w->file, obj))
        return WT_ERROR(w->ctx, WT_ERR_INVALID, "%s: cannot set attribute '%s' on '%s': no such group or dataset",
                        w->target, name, obj);
    hid_t o = H5Oopen(w->file, obj, H5P_DEFAULT);
    herr_t r = o < 0 ? -1 : ft < 0 ? wt_h5_priv_put_attr_string(o, name, value) : wt_h5_priv_put_attr(o, name, ft, mt, value);
    wt_h5_priv_drop(o);
    if (r < 0) return H5ERR(w->ctx, WT_ERR_IO, "%s: cannot write attribute '%s' of '%s'", w->target, name, obj);
    return WT_OK;
}

int wt_h5_attr_write_string(wt_h5_writer *w, const char *obj, const char *name, const char *value)
{
    WRITER_CALL(w, w, attr_impl(w, obj, name, -1, -1, value));
}

int wt_h5_attr_write_double(wt_h5_writer *w, const char *obj, const char *name, double value)
{
    WRITER_CALL(w, w, attr_impl(w, obj, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, &value));
}

int wt_h5_attr_write_int64(wt_h5_writer *w, const char *obj, const char *name, int64_t value)
{
    WRITER_CALL(w, w, attr_impl(w, obj, name, H5T_STD_I64LE, H5T_NATIVE_INT64, &value));
}
