/* cli/cli.c: shared driver plumbing: options, error reporting, progress. */
#include "cli.h"
#include "mpi.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <limits.h>
#include <string.h>
#include <sys/stat.h>
#include <dirent.h>
#include <unistd.h>

#include "core/base/names.h"

#include "core/io/h5.h"
#include "core/model/estimate.h"

#include <cblas.h>
#ifdef _OPENMP
#include <omp.h>
#endif

static void log_to_stderr(void *user, int level, const char *msg)
{
    (void)user;
    static const char *names[] = {"error", "warning", "info", "debug"};
    fprintf(stderr, "wavetomo: %s: %s\n", names[level < 0 ? 0 : (level > 3 ? 3 : level)], msg);
}

int wt_cli_init(wt_cli *cli, const char *prog, void (*help)(void))
{
    memset(cli, 0, sizeof *cli);
    cli->prog = prog;
    cli->help = help;
    cli->ctx = wt_context_alloc();
    if (!cli->ctx) {
        fprintf(stderr, "%s: error: out of memory\n", prog);
        return WT_ERR_NOMEM;
    }
    wt_context_set_log_hook(cli->ctx, log_to_stderr, NULL, WT_LOG_WARN);
    return WT_OK;
}

void wt_cli_done(wt_cli *cli) { wt_context_free(cli->ctx); }

int wt_cli_usage_error(wt_cli *cli, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "%s: error: ", cli->prog);
    vfprintf(stderr, fmt, ap);
    fprintf(stderr, "\n(see '%s --help')\n", cli->prog);
    va_end(ap);
    return 2;
}

/* --max-memory SIZE: a number of bytes with an optional suffix K, M, G, T (powers of 1000, "B" allowed
 * after it: 4G = 4GB = 4e9); finite and at least 1 MB. */
static int parse_size(wt_cli *cli, const char *text, double *out)
{
    char *end = NULL;
    errno = 0;
    double v = text[0] && (isdigit((unsigned char)text[0]) || text[0] == '.') ? strtod(text, &end) : NAN;
    const char *units = "KMGT";
    const char *u = end && *end ? strchr(units, toupper((unsigned char)*end)) : NULL;
    if (u && *u) v *= pow(1000.0, (double)(u - units + 1)), end++;
    if (end && (*end == 'B' || *end == 'b')) end++;
    if (!end || *end || errno == ERANGE || !isfinite(v) || v < 1e6) {
        wt_cli_usage_error(cli, "--max-memory expects a size of at least 1M (bytes, or with K, M, G, T), got '%s'", text);
        return -1;
    }
    *out = v;
    return 0;
}

int wt_cli_common_option(wt_cli *cli, int argc, char **argv, int *i)
{
    const char *a = argv[*i];
    const char *val = NULL;
    char name[32] = {0};
    const char *eq = strchr(a, '=');
    /* accept both "--opt value" and "--opt=value" */
    if (strncmp(a, "--", 2) == 0 && eq && (size_t)(eq - a) < sizeof name) {
        memcpy(name, a, (size_t)(eq - a));
        val = eq + 1;
    } else {
        snprintf(name, sizeof name, "%s", a);
    }
    int takes_value = !strcmp(name, "--config") || !strcmp(name, "--set") || !strcmp(name, "--threads") ||
                      !strcmp(name, "--max-memory");
    if (!takes_value) {
        if (!strcmp(a, "--dry-run")) {
            cli->dry_run = 1;
            return 1;
        }
        if (!strcmp(a, "--force")) {
            cli->force = 1;
            return 1;
        }
        if (!strcmp(a, "--quiet") || !strcmp(a, "-q")) {
            cli->quiet = 1;
            wt_context_set_log_hook(cli->ctx, log_to_stderr, NULL, WT_LOG_ERROR);
            return 1;
        }
        return 0;
    }
    if (!val) {
        if (*i + 1 >= argc) {
            wt_cli_usage_error(cli, "option %s needs a value", name);
            return -1;
        }
        val = argv[++*i];
    }
    if (!strcmp(name, "--config")) return wt_cli_config_arg(cli, val, &cli->config_path);
    else if (!strcmp(name, "--max-memory")) return parse_size(cli, val, &cli->max_memory) < 0 ? -1 : 1;
    else if (!strcmp(name, "--set")) {
        if (!strchr(val, '=')) {
            wt_cli_usage_error(cli, "--set expects key=value, got '%s'", val);
            return -1;
        }
        if (cli->nset == WT_CLI_MAX_SET) {
            wt_cli_usage_error(cli, "too many --set options (at most %d)", WT_CLI_MAX_SET);
            return -1;
        }
        cli->set[cli->nset++] = val;
    } else {
        long t;
        if (wt_cli_int(cli, "--threads", val, 0, 1024, &t) < 0) return -1;
        cli->threads = (int)t;
        wt_context_set_threads(cli->ctx, (int)t);
#ifdef _OPENMP
        if (t > 0) omp_set_num_threads((int)t);
#endif
        /* OpenBLAS keeps its own pool: without this the MVM's GEMVs and the builder's BLAS use every core
         * whatever --threads says */
        if (t > 0) openblas_set_num_threads((int)t);
    }
    return 1;
}

/* "unknown option", with the nearest option the command's --help text names (the help is where every
 * command lists its options, so the suggestion and the documentation cannot disagree) or a common one */
static int unknown_option(wt_cli *cli, const char *opt)
{
    enum { MAXOPT = 96 };
    static const char *const common[] = {"--config", "--set", "--threads", "--quiet", "--help", "--max-memory", "--force"};
    char text[16384] = "", words[MAXOPT][40];
    const char *names[MAXOPT];
    int n = 0;
    for (size_t k = 0; k < sizeof common / sizeof *common; k++) names[n++] = common[k];
    FILE *tmp = cli->help ? tmpfile() : NULL;
    if (tmp) {
        fflush(stdout);
        const int saved = dup(STDOUT_FILENO);
        if (saved >= 0 && dup2(fileno(tmp), STDOUT_FILENO) >= 0) {
            cli->help();
            fflush(stdout);
            dup2(saved, STDOUT_FILENO);
            rewind(tmp);
            const size_t got = fread(text, 1, sizeof text - 1, tmp);
            text[got] = '\0';
        }
        if (saved >= 0) close(saved);
        fclose(tmp);
    }
    for (const char *p = strstr(text, "--"); p && n < MAXOPT; p = strstr(p + 2, "--")) {
        size_t len = 2;
        while ((p[len] >= 'a' && p[len] <= 'z') || p[len] == '-') len++;
        if (len < 4 || len >= sizeof words[0]) continue;
        memcpy(words[n], p, len);
        words[n][len] = '\0';
        names[n] = words[n];
        n++;
    }
    const char *eq = strchr(opt, '=');
    char word[64];
    snprintf(word, sizeof word, "%.*s", eq ? (int)(eq - opt) : (int)strlen(opt), opt);
    const int near = opt[0] == '-' ? wt_nearest_name(word, names, n) : -1;
    if (near >= 0 && strcmp(names[near], word))
        return wt_cli_usage_error(cli, "unknown option '%s' (did you mean '%s'?)", opt, names[near]);
    return wt_cli_usage_error(cli, "unknown option '%s'", opt);
}

int wt_cli_parse(wt_cli *cli, int argc, char **argv, wt_cli_option_fn fn, void *user)
{
    for (int i = 1; i < argc; i++) {
        int h = wt_cli_common_option(cli, argc, argv, &i);
        if (h < 0) return 2;
        if (h) continue;
        if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) {
            if (cli->help) cli->help();
            return 0;
        }
        h = fn ? fn(cli, argc, argv, &i, user) : 0;
        if (h < 0) return 2;
        /* a word that is no option is CONFIG, as --config gives it: every command takes either */
        if (h == 0 && argv[i][0] != '-' && argv[i][0] != '\0') h = wt_cli_config_arg(cli, argv[i], &cli->config_path);
        if (h < 0) return 2;
        if (h == 0) return unknown_option(cli, argv[i]);
    }
    return -1;
}

int wt_cli_config_arg(wt_cli *cli, const char *arg, const char **path)
{
    if (*path) {
        wt_cli_usage_error(cli, "more than one CONFIG given ('%s' and '%s')", *path, arg);
        return -1;
    }
    *path = arg;
    return 1;
}

const char *wt_cli_value(wt_cli *cli, int argc, char **argv, int *i)
{
    if (*i + 1 >= argc) {
        wt_cli_usage_error(cli, "option %s needs a value", argv[*i]);
        return NULL;
    }
    return argv[++*i];
}

/* Strict numbers: the whole text is the number, no blank before it, no overflow clamped
 * by strtol/strtoll/strtod, nothing empty. */
int wt_cli_int(wt_cli *cli, const char *name, const char *text, long lo, long hi, long *out)
{
    char *end = NULL;
    errno = 0;
    long v = text && isdigit((unsigned char)text[text[0] == '-' || text[0] == '+']) ? strtol(text, &end, 10) : 0;
    if (!end || *end || errno == ERANGE || v < lo || v > hi) {
        wt_cli_usage_error(cli, "%s expects an integer in [%ld, %ld], got '%s'%s", name, lo, hi, text ? text : "",
                           errno == ERANGE ? " (too large)" : "");
        return -1;
    }
    *out = v;
    return 0;
}

int wt_cli_double(wt_cli *cli, const char *name, const char *text, double lo, double hi, double *out)
{
    char *end = NULL;
    errno = 0;
    double v = text && text[0] && !isspace((unsigned char)text[0]) ? strtod(text, &end) : NAN;
    if (!end || *end || errno == ERANGE || !isfinite(v) || v < lo || v > hi) {
        wt_cli_usage_error(cli, "%s expects a number in [%g, %g], got '%s'", name, lo, hi, text ? text : "");
        return -1;
    }
    *out = v;
    return 0;
}

int wt_cli_split(wt_cli *cli, const char *name, char *s, char **items, int max)
{
    int n = 0;
    for (char *p = s;; n++) {
        char *c = strchr(p, ',');
        if (c) *c = '\0';
        if (!*p) {
            wt_cli_usage_error(cli, "%s: item %d of the comma-separated list is empty", name, n + 1);
            return -1;
        }
        if (n == max) {
            wt_cli_usage_error(cli, "%s: more than %d items", name, max);
            return -1;
        }
        items[n] = p;
        if (!c) return n + 1;
        p = c + 1;
    }
}

/* The absolute path `p` names, its directory resolved when the file itself does not exist yet. */
static void resolve_path(const char *p, char *out, size_t n)
{
    char buf[PATH_MAX], dir[PATH_MAX];
    if (realpath(p, buf)) {
        snprintf(out, n, "%s", buf);
        return;
    }
    const char *slash = strrchr(p, '/');
    snprintf(dir, sizeof dir, "%.*s", slash ? (int)(slash - p) : 1, slash ? (slash == p ? "/" : p) : ".");
    if (realpath(dir, buf) && strlen(buf) + strlen(p) + 2 <= n) {
        strcpy(out, buf);
        strcat(out, "/");
        strcat(out, slash ? slash + 1 : p);
    } else
        snprintf(out, n, "%s", p);
}

/* K: the output `path` (resolved into rp) is none of the inputs and no earlier output. */
static int check_not_input(wt_cli *cli, const char *path, const char *in1, const char *in2, char *rp, size_t n)
{
    const char *ins[3] = {cli->config_path, in1, in2};
    char ri[4096];
    struct stat so, si;
    int have = stat(path, &so) == 0;
    resolve_path(path, rp, n);
    for (int k = 0; k < 3; k++) {
        if (!ins[k]) continue;
        resolve_path(ins[k], ri, sizeof ri);
        int same = (have && stat(ins[k], &si) == 0 && si.st_dev == so.st_dev && si.st_ino == so.st_ino) || !strcmp(rp, ri);
        if (same)
            return WT_ERROR(cli->ctx, WT_ERR_IO, "the output '%s' is the input '%s' (%s): writing it would destroy the "
                            "input; choose another output name", path, ins[k], !strcmp(rp, ri) ? rp : "same file");
    }
    for (int k = 0; k < cli->noutputs; k++)
        if (!strcmp(cli->outputs[k], rp))
            return WT_ERROR(cli->ctx, WT_ERR_IO, "'%s' is given as two outputs (%s): one would replace the other", path, rp);
    if (cli->noutputs < 4) snprintf(cli->outputs[cli->noutputs++], sizeof cli->outputs[0], "%s", rp);
    return WT_OK;
}

int wt_cli_check_output(wt_cli *cli, const char *path, int64_t bytes, const char *in1, const char *in2)
{
    char rp[4096];
    int st = check_not_input(cli, path, in1, in2, rp, sizeof rp);
    if (st >= 0) st = wt_h5_check_replaceable(cli->ctx, path, cli->force);
    return st < 0 ? st : wt_h5_check_writable(cli->ctx, path, bytes);
}

int wt_cli_check_text_output(wt_cli *cli, const char *path, const char *signature, const char *owner)
{
    char rp[4096], head[64] = "";
    struct stat sb;
    int st = check_not_input(cli, path, NULL, NULL, rp, sizeof rp);
    if (st < 0 || cli->force || lstat(path, &sb) != 0) return st;
    if (S_ISDIR(sb.st_mode)) return WT_ERROR(cli->ctx, WT_ERR_IO, "cannot write '%s': it is a directory", path);
    size_t len = strlen(signature), got = 0;
    FILE *f = S_ISREG(sb.st_mode) ? fopen(path, "rb") : NULL;
    if (f) {
        got = fread(head, 1, len < sizeof head ? len : sizeof head, f);
        fclose(f);
    }
    /* a file of ours starts with the signature; a PNG also needs `owner` to be a wavetomo output */
    int ours = f && got == len && !memcmp(head, signature, len);
    if (ours && owner) ours = access(owner, F_OK) == 0 && wt_h5_check_replaceable(cli->ctx, owner, 0) == WT_OK;
    if (!ours)
        return WT_ERROR(cli->ctx, WT_ERR_IO, "'%s' exists and is not a wavetomo output (%s); refusing to replace it: "
                        "choose another directory, or give --force", path,
                        S_ISLNK(sb.st_mode) ? "a symbolic link" : !S_ISREG(sb.st_mode) ? "not a regular file"
                        : owner && got == len ? "no wavetomo results.h5 beside it" : "it does not start as ours");
    return WT_OK;
}

int wt_cli_resources(wt_cli *cli, const wt_estimate *e)
{
    if (cli->dry_run) {
        int rank, size;
        /* under mpirun one answer, from rank 0: every rank would print the same estimate */
        if (wt_mpi_launch_rank(&rank, &size) && rank > 0) return 0;
        printf("%s --dry-run (nothing allocated, nothing written):\n", cli->prog);
        wt_estimate_print(stdout, "", e);
        if (size > 1)
            printf("under mpirun with %d ranks: the memory is per rank (a rank runs one case or its share of the columns "
                   "at a time; ranks on one machine add up), the run time is the serial one, divided by at most %d\n",
                   size, size);
    }
    double avail = wt_memory_available(), limit = avail;
    const char *source = "available now (MemAvailable of /proc/meminfo)";
    if (cli->max_memory > 0 && (!(avail > 0) || cli->max_memory < avail))
        limit = cli->max_memory, source = "allowed by --max-memory";
    int st = wt_estimate_check(cli->ctx, cli->config_path ? cli->config_path : cli->prog, e, limit, source);
    if (cli->dry_run) {
        if (st < 0) printf("would be refused: %s\n", wt_error_message(cli->ctx));
        return 0;
    }
    if (st < 0) return wt_cli_fail(cli, st);
    if (!cli->quiet) wt_estimate_print(stderr, "  ", &(wt_estimate){.bytes = e->bytes, .seconds = e->seconds});
    return -1;
}

int wt_cli_estimate(wt_cli *cli, const wt_config *cfg, int task, int recon, int iterations)
{
    wt_estimate e;
    wt_estimate_resources(cfg, &(wt_estimate_request){.task = task, .recon = recon, .frames = cfg->frames,
                                                      .iterations = iterations}, &e);
    return wt_cli_resources(cli, &e);
}

int wt_cli_fail(wt_cli *cli, int status)
{
    const char *msg = wt_error_message(cli->ctx);
    fprintf(stderr, "%s: error: %s\n", cli->prog, msg && *msg ? msg : wt_strerror(status));
    return 1;
}

int wt_cli_run_overrides(wt_cli *cli, long frames, const char *seed)
{
    if (cli->nset + 3 > WT_CLI_MAX_SET) return wt_cli_usage_error(cli, "too many --set options");
    if (frames > 0) {
        cli->frames = frames;
        snprintf(cli->frames_set, sizeof cli->frames_set, "loop.frames=%ld", frames);
        cli->set[cli->nset++] = cli->frames_set;
    }
    if (seed) {
        char *end = NULL;
        errno = 0;
        long long s = isdigit((unsigned char)seed[0]) ? strtoll(seed, &end, 10) : -1;
        if (!end || *end || errno == ERANGE || s < 0)
            return wt_cli_usage_error(cli, "--seed expects an integer in [0, %lld], got '%s'%s", LLONG_MAX, seed,
                                      errno == ERANGE ? " (too large: seeds are 63-bit)" : "");
        snprintf(cli->seed_set, sizeof cli->seed_set, "sim.seed=%lldL", s);
        cli->set[cli->nset++] = cli->seed_set;
    }
    return 0;
}

/* A preset's name (no '/', the file absent), e.g. "demo" or "eelt-mcao.cfg", as the file of the source tree
 * (data/presets/ beside the executable's bin/, or under the working directory) or of the installation
 * (share/wavetomo/presets beside the executable's bin/): the first that exists. NULL when the name is a
 * path, exists as given, or none is found (the reader then names the file as given). */
static const char *resolve_preset(wt_cli *cli, const char *name, int *missing)
{
    *missing = 0;
    if (strchr(name, '/') || access(name, F_OK) == 0 || strlen(name) > 200) return NULL;
    char exe[4096] = "";
    const ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1);
    exe[n > 0 ? n : 0] = '\0';
    char *slash = strrchr(exe, '/');
    if (slash) *slash = '\0'; /* the executable's directory */
    const char *ext = strstr(name, ".cfg") ? "" : ".cfg";
    const char *const where[3][2] = {{exe, "/../data/presets"}, {".", "/data/presets"}, {exe, "/../share/wavetomo/presets"}};
    for (int k = 0; k < 3; k++) {
        if (!where[k][0][0]) continue;
        snprintf(cli->preset_path, sizeof cli->preset_path, "%s%s/%s%s", where[k][0], where[k][1], name, ext);
        if (access(cli->preset_path, R_OK) == 0) return cli->preset_path;
    }
    /* not found: say where presets are, and the nearest preset name */
    char names[64][128], found[4300] = "";
    const char *list[64];
    int nn = 0;
    for (int k = 0; k < 3; k++) {
        char dirpath[4200];
        snprintf(dirpath, sizeof dirpath, "%s%s", where[k][0], where[k][1]);
        DIR *d = where[k][0][0] ? opendir(dirpath) : NULL;
        if (!d) continue;
        if (!found[0]) snprintf(found, sizeof found, "%s", dirpath);
        for (struct dirent *e; (e = readdir(d)) && nn < 64;) {
            const size_t l = strlen(e->d_name);
            if (l < 5 || l > 120 || strcmp(e->d_name + l - 4, ".cfg")) continue;
            snprintf(names[nn], sizeof names[nn], "%.*s", (int)(l - 4), e->d_name);
            list[nn] = names[nn], nn++;
        }
        closedir(d);
    }
    char base[256];
    snprintf(base, sizeof base, "%.*s", (int)(strstr(name, ".cfg") ? strstr(name, ".cfg") - name : (long)strlen(name)), name);
    const int near = wt_nearest_name(base, list, nn);
    wt_error_set(cli->ctx, WT_ERR_IO, __FILE__, __LINE__,
                 "no configuration file '%s', nor a preset of that name%s%s%s (presets: %s)", name,
                 near >= 0 ? " (did you mean '" : "", near >= 0 ? list[near] : "", near >= 0 ? "'?)" : "",
                 found[0] ? found : "none found beside the executable or under ./data/presets");
    *missing = 1;
    return NULL;
}

int wt_cli_read_config(wt_cli *cli, const char *path, wt_config **cfg)
{
    if (!path) path = cli->config_path;
    if (!path) {
        wt_error_set(cli->ctx, WT_ERR_INVALID, __FILE__, __LINE__, "no configuration given (use --config FILE)");
        return WT_ERR_INVALID;
    }
    int missing;
    const char *preset = resolve_preset(cli, path, &missing);
    if (missing) return WT_ERR_IO;
    if (preset) path = preset;
    int st = wt_config_read(cli->ctx, path, cli->nset, cli->set, cfg);
    if (st == WT_ERR_CONFIG && cli->frames > 0 && strstr(wt_error_message(cli->ctx), "settle_frames") &&
        cli->nset < WT_CLI_MAX_SET) {
        /* a short run: keep the settle period inside it */
        snprintf(cli->settle_set, sizeof cli->settle_set, "evaluation.settle_frames=%ld", cli->frames / 2);
        cli->set[cli->nset++] = cli->settle_set;
        if (!cli->quiet)
            fprintf(stderr, "%s: note: --frames %ld is not above evaluation.settle_frames; using %s\n", cli->prog,
                    cli->frames, cli->settle_set);
        st = wt_config_read(cli->ctx, path, cli->nset, cli->set, cfg);
    }
    return st;
}

void wt_progress_start(wt_progress *p, const char *label, const char *unit, long total)
{
    /* a terminal gets one line rewritten in place; a log (nohup, a batch queue) a line a minute, so that a long
     * run's rate and ETA are there too without filling the log */
    p->enabled = isatty(STDERR_FILENO) ? 1 : 2;
    p->label = label;
    p->unit = unit;
    p->total = total;
    p->start = p->last = wt_time_now();
}

void wt_progress_update(wt_progress *p, long done, const char *extra)
{
    if (!p->enabled) return;
    double now = wt_time_now();
    if (p->enabled == 2 ? now - p->last < WT_PROGRESS_LOG_S : done < p->total && now - p->last < 0.2) return;
    p->last = now;
    double el = now - p->start, rate = el > 0 ? done / el : 0.0;
    double eta = rate > 0 ? (p->total - done) / rate : 0.0;
    /* "frames 34/200", or "pcg3: open loop 34/200 frames" when the label is not the unit */
    const int same = !strcmp(p->label, p->unit);
    fprintf(stderr, "%s%s %ld/%ld%s%s  %.2f %s/s  ETA %02d:%02d%s%s%s", p->enabled == 1 ? "\r" : "", p->label, done,
            p->total, same ? "" : " ", same ? "" : p->unit, rate, p->unit, (int)(eta / 60), (int)eta % 60,
            extra ? "  " : "", extra ? extra : "", p->enabled == 1 ? "\033[K" : "\n");
    fflush(stderr);
}

void wt_progress_end(wt_progress *p)
{
    if (p->enabled != 1) return;
    fprintf(stderr, "\n");
}

void wt_progress_phase(void *user, const char *phase, int64_t done, int64_t total)
{
    wt_progress_phases *pp = user;
    if (strcmp(pp->phase, phase) != 0) {
        if (pp->phase[0]) wt_progress_end(&pp->pr);
        snprintf(pp->phase, sizeof pp->phase, "%s", phase);
        wt_progress_start(&pp->pr, pp->phase, "steps", (long)total);
        if (pp->quiet) pp->pr.enabled = 0;
    }
    pp->pr.total = (long)total;
    wt_progress_update(&pp->pr, (long)done, NULL);
}

void wt_progress_phases_end(wt_progress_phases *pp)
{
    if (pp->phase[0]) wt_progress_end(&pp->pr);
}
