/* tests/test_docs_figures.c: the figures the user docs state must be the program's. test_docs checks that the
 * commands, options and keys the docs name exist; this suite checks what the docs say of them:
 *  - the E-ELT sizes (subapertures, slopes, actuators with and without the guard ring, unknowns, R's size)
 *    and each preset's CG-9 solver (preconditioner, iterations, fitting), as stated in README.md,
 *    docs/guide.md, docs/benchmarks.md and docs/results-summary.md, against `wavetomo info` on the presets;
 *  - every default stated next to its key ("`sim.psf_pixels` (default 64") against `wavetomo info --keys`;
 *  - every relative link (file and #section) of the user docs resolves;
 *  - the README reads as an introduction: at most 150 lines, no "§", issue number or date above its links, the
 *    test command that .ci/run relies on; and no issue numbers in the user docs, the presets' comments or any
 *    command's --help.
 * A figure is found by the sentence that states it: rewording that sentence fails here with the sentence
 * wanted, so that the figure is checked again. Runs $BIN/wavetomo (else bin/wavetomo) from the top directory. */
#include <ctype.h>
#include <dirent.h>
#include <regex.h>

#include "testutil.h"

static char wt[512], dir[64];

static void setup(void) { tu_cli_setup(wt, sizeof wt, dir, sizeof dir, "wtfig"); }
static void teardown(void) { tu_cli_teardown(dir); }

/* The documents a user reads (results.md, the dated notebook, and design.md, which records why issues were
 * declined, are not among them for the issue-number check; their links are checked). */
static const char *const user_docs[] = {"README.md",        "docs/guide.md",   "docs/config.md",      "docs/formats.md",
                                        "docs/refusals.md", "docs/testing.md", "docs/python.md",      "docs/benchmarks.md",
                                        "docs/c-api.md",    "docs/SPEC.md",    "docs/python-api.md", "docs/results-summary.md",
                                        NULL};
static const char *const linked_docs[] = {"docs/design.md", "docs/results.md", NULL};

static char *slurp_cmd(const char *cmd)
{
    FILE *p = popen(cmd, "r");
    if (!p) return NULL;
    size_t cap = 1 << 16, n = 0;
    char *s = malloc(cap);
    for (;;) {
        if (n + 4096 + 1 > cap) s = realloc(s, cap *= 2);
        size_t k = fread(s + n, 1, 4096, p);
        if (k == 0) break;
        n += k;
    }
    s[n] = 0;
    if (pclose(p) != 0) {
        free(s);
        return NULL;
    }
    return s;
}

static char *slurp_file(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *s = malloc((size_t)n + 1);
    size_t got = fread(s, 1, (size_t)n, f);
    s[got] = 0;
    fclose(f);
    return s;
}

/* The text with every run of white space (line breaks of wrapped prose included) made one space. */
static char *flatten(const char *s)
{
    char *o = malloc(strlen(s) + 1), *q = o;
    for (; *s; s++) {
        if (isspace((unsigned char)*s)) {
            if (q > o && q[-1] != ' ') *q++ = ' ';
        } else {
            *q++ = *s;
        }
    }
    *q = 0;
    return o;
}

static char *info(const char *args)
{
    char cmd[1200];
    snprintf(cmd, sizeof cmd, "%s info %s 2>&1", wt, args);
    char *out = slurp_cmd(cmd);
    ck_assert_msg(out != NULL, "%s failed", cmd);
    return out;
}

/* The integers captured by `re` (extended) at its first match in text: n groups into v; 0 when no match. The
 * groups may hold thousands written plainly; a decimal figure is read by its integer and fraction parts. */
static int match_ints(const char *text, const char *re, long *v, int n)
{
    regex_t r;
    ck_assert_msg(regcomp(&r, re, REG_EXTENDED) == 0, "bad regex %s", re);
    regmatch_t m[10];
    ck_assert_int_lt(n, 10);
    int ok = regexec(&r, text, (size_t)n + 1, m, 0) == 0;
    for (int i = 0; ok && i < n; i++) v[i] = m[i + 1].rm_so >= 0 ? strtol(text + m[i + 1].rm_so, NULL, 10) : -1;
    regfree(&r);
    return ok;
}

/* The word captured by `re`'s first group at its first match, into w; 0 when no match. */
static int match_word(const char *text, const char *re, char *w, size_t nw)
{
    regex_t r;
    ck_assert_msg(regcomp(&r, re, REG_EXTENDED) == 0, "bad regex %s", re);
    regmatch_t m[2];
    int ok = regexec(&r, text, 2, m, 0) == 0 && m[1].rm_so >= 0;
    if (ok) snprintf(w, nw, "%.*s", (int)(m[1].rm_eo - m[1].rm_so), text + m[1].rm_so);
    regfree(&r);
    return ok;
}

/* What `wavetomo info` says of one system. */
typedef struct {
    long valid_lgs, slopes, act[3], act_total, unknowns_pcg3, unknowns_cg9, r_rows, r_cols, r_centi_gb;
    long cg9_iterations;
    char cg9_precond[32], cg9_fit[32];
} sizes;

static sizes sizes_of(const char *args)
{
    char *out = info(args);
    sizes z;
    memset(&z, 0, sizeof z);
    long v[4];
    ck_assert_msg(match_ints(out, "\nLGS1 +[-0-9.]+ +[-0-9.]+ +[0-9]+x[0-9]+ +([0-9]+) ", v, 1), "info %s: no LGS1 row", args);
    z.valid_lgs = v[0];
    ck_assert(match_ints(out, "total slopes: ([0-9]+)", &z.slopes, 1));
    for (int d = 0; d < 3; d++) {
        char re[80];
        snprintf(re, sizeof re, "\n%d +[0-9]+ +[0-9.]+ +[0-9]+x[0-9]+ +([0-9]+)", d + 1);
        ck_assert_msg(match_ints(out, re, &z.act[d], 1), "info %s: no row of DM %d", args, d + 1);
    }
    ck_assert(match_ints(out, "total active actuators: ([0-9]+)", &z.act_total, 1));
    const char *r = strstr(out, "MVM control matrix R: ");
    double gb = 0;
    ck_assert_msg(r && sscanf(r, "MVM control matrix R: %ld x %ld float32 = %lf GB", &z.r_rows, &z.r_cols, &gb) == 3,
                  "info %s: no size of R", args);
    z.r_centi_gb = lround(100 * gb);
    const char *r3 = strstr(out, "reconstructor pcg3:"), *r9 = strstr(out, "reconstructor cg9:");
    ck_assert_msg(r3 && r9, "info %s: no reconstructor sections", args);
    ck_assert(match_ints(r3, "total unknowns: ([0-9]+)", &z.unknowns_pcg3, 1));
    ck_assert(match_ints(r9, "total unknowns: ([0-9]+)", &z.unknowns_cg9, 1));
    ck_assert(match_word(out, "reconstructor cg9: [0-9]+ layers, PCG \\(([a-z_]+)\\)", z.cg9_precond, sizeof z.cg9_precond));
    ck_assert(match_ints(out, "reconstructor cg9: [0-9]+ layers, PCG \\([a-z_]+\\), ([0-9]+) iterations", &z.cg9_iterations, 1));
    ck_assert(match_word(out, "\n +fitting over [^\n]*, (Cholesky|CG)", z.cg9_fit, sizeof z.cg9_fit));
    free(out);
    return z;
}

static char report[8192];
static int nbad;

static void expect(const char *doc, const char *what, long stated, long actual)
{
    if (stated == actual) return;
    nbad++;
    snprintf(report + strlen(report), sizeof report - strlen(report), "%s: %s is %ld, the program says %ld\n", doc,
             what, stated, actual);
}

/* The figure(s) of the sentence `re` in doc (flattened); a sentence not found is a failure naming it. */
static int stated(const char *doc, const char *re, long *v, int n)
{
    char *text = slurp_file(doc);
    ck_assert_msg(text != NULL, "%s missing", doc);
    char *flat = flatten(text);
    int ok = match_ints(flat, re, v, n);
    free(text);
    free(flat);
    if (!ok) {
        nbad++;
        snprintf(report + strlen(report), sizeof report - strlen(report), "%s: no sentence matching /%s/\n", doc, re);
    }
    return ok;
}

START_TEST(test_eelt_sizes)
{
    report[0] = 0, nbad = 0;
    sizes e = sizes_of("data/presets/eelt-mcao.cfg --no-nnz");
    sizes p = sizes_of("data/presets/eelt-mcao.cfg --no-nnz --set dm.guard_rings=0");
    long v[6];
    if (stated("docs/guide.md", "([0-9]+) valid subapertures per LGS sensor, ([0-9]+) slopes, ([0-9]+) \\+ ([0-9]+) \\+ "
                                "([0-9]+) = ([0-9]+) active actuators with the preset's one guard ring", v, 6)) {
        expect("docs/guide.md", "valid subapertures per LGS", v[0], e.valid_lgs);
        expect("docs/guide.md", "slopes", v[1], e.slopes);
        for (int d = 0; d < 3; d++) expect("docs/guide.md", "DM actuators with the guard ring", v[2 + d], e.act[d]);
        expect("docs/guide.md", "actuators with the guard ring", v[5], e.act_total);
    }
    if (stated("docs/guide.md", "gives the paper's ([0-9]+) \\+ ([0-9]+) \\+ ([0-9]+) = ([0-9]+)", v, 4)) {
        for (int d = 0; d < 3; d++) expect("docs/guide.md", "DM actuators without the guard ring", v[d], p.act[d]);
        expect("docs/guide.md", "actuators without the guard ring", v[3], p.act_total);
    }
    if (stated("docs/guide.md", "([0-9]+) unknowns for the 3-layer PCG reconstructor and ([0-9]+) for the 9-layer", v, 2)) {
        expect("docs/guide.md", "PCG-3's unknowns", v[0], e.unknowns_pcg3);
        expect("docs/guide.md", "CG-9's unknowns", v[1], e.unknowns_cg9);
    }
    if (stated("docs/guide.md", "matrix \\(([0-9]+) × ([0-9]+) float32 = ([0-9]+)\\.([0-9][0-9]) GB\\)", v, 4)) {
        expect("docs/guide.md", "R's rows", v[0], e.r_rows);
        expect("docs/guide.md", "R's columns", v[1], e.r_cols);
        expect("docs/guide.md", "R's size [GB/100]", 100 * v[2] + v[3], e.r_centi_gb);
    }
    if (stated("docs/benchmarks.md", "GEMV of the full ([0-9]+) × ([0-9]+) matrix: ([0-9]+) actuators and the guard ring",
               v, 3)) {
        expect("docs/benchmarks.md", "R's rows", v[0], e.r_rows);
        expect("docs/benchmarks.md", "R's columns", v[1], e.r_cols);
        expect("docs/benchmarks.md", "actuators without the guard ring", v[2], p.act_total);
    }
    if (stated("README.md", "3 DMs with ([0-9]+) actuators \\(([0-9]+) with the presets' guard ring\\), ([0-9]+) slopes",
               v, 3)) {
        expect("README.md", "actuators", v[0], p.act_total);
        expect("README.md", "actuators with the guard ring", v[1], e.act_total);
        expect("README.md", "slopes", v[2], e.slopes);
    }
    ck_assert_msg(nbad == 0, "%d figures in the docs differ from `wavetomo info`:\n%s", nbad, report);
}
END_TEST

/* CG-9 as the guide describes it: the E-ELT presets' preconditioner and iterations, the demo's, the fitting */
START_TEST(test_cg9_solver)
{
    report[0] = 0, nbad = 0;
    sizes e = sizes_of("data/presets/eelt-mcao.cfg --no-nnz");
    sizes d = sizes_of("data/presets/demo.cfg --no-nnz");
    ck_assert_str_eq(e.cg9_precond, "fourier"); /* the sentences below name it in words */
    long v[2];
    char w[32] = "";
    if (stated("docs/guide.md", "on the E-ELT presets the Fourier-domain preconditioner with ([0-9]+) iterations", v, 1))
        expect("docs/guide.md", "the E-ELT CG-9's iterations", v[0], e.cg9_iterations);
    if (stated("docs/results-summary.md", "the E-ELT presets run the Fourier-domain preconditioner with ([0-9]+) iterations",
               v, 1))
        expect("docs/results-summary.md", "the E-ELT CG-9's iterations", v[0], e.cg9_iterations);
    if (stated("docs/guide.md", "on the demo [a-z_]+ with ([0-9]+)", v, 1)) {
        expect("docs/guide.md", "the demo CG-9's iterations", v[0], d.cg9_iterations);
        char *flat = flatten(slurp_file("docs/guide.md"));
        ck_assert(match_word(flat, "on the demo ([a-z_]+) with", w, sizeof w));
        free(flat);
        if (strcmp(w, d.cg9_precond)) {
            nbad++;
            snprintf(report + strlen(report), sizeof report - strlen(report),
                     "docs/guide.md: the demo's CG-9 preconditioner is %s, the program says %s\n", w, d.cg9_precond);
        }
    }
    long dummy;
    if (stated("docs/guide.md", "then the fitting over the evaluation directions, solved exactly with a (C)holesky factor",
               &dummy, 1) &&
        (strcmp(e.cg9_fit, "Cholesky") || strcmp(d.cg9_fit, "Cholesky"))) {
        nbad++;
        snprintf(report + strlen(report), sizeof report - strlen(report),
                 "docs/guide.md: the fitting is by Cholesky, the program says %s (E-ELT) and %s (demo)\n", e.cg9_fit,
                 d.cg9_fit);
    }
    ck_assert_msg(nbad == 0, "%d statements of CG-9's solver differ from `wavetomo info`:\n%s", nbad, report);
}
END_TEST

/* ---- stated defaults ---------------------------------------------------------------------------- */

/* The default `info --keys` gives key (its "default X" up to ',' or ')'), into out; 0 when it has none. */
static int key_default(const char *keys, const char *key, char *out, size_t n)
{
    char pat[300];
    snprintf(pat, sizeof pat, "\n%s ", key);
    const char *p = strstr(keys, pat);
    if (!p) return 0;
    const char *eol = strchr(p + 1, '\n');
    const char *d = NULL;
    for (const char *q = strstr(p, "default "); q && (!eol || q < eol); q = strstr(q + 1, "default ")) d = q;
    if (!d) return 0;
    d += 8;
    size_t len = strcspn(d, ",)\n");
    snprintf(out, n, "%.*s", (int)len, d);
    return 1;
}

/* A stated value and a default equal: numbers by value (the docs' "−1" with a minus sign too), words as
 * text without quotes. */
static int same_value(const char *stated_v, const char *def)
{
    char a[64], b[64];
    size_t k = 0;
    for (const char *s = stated_v; *s && k < sizeof a - 1; s++) {
        if (!strncmp(s, "\xe2\x88\x92", 3)) { /* U+2212 minus */
            a[k++] = '-';
            s += 2;
        } else if (*s != '"' && *s != '`') {
            a[k++] = *s;
        }
    }
    a[k] = 0;
    snprintf(b, sizeof b, "%s", def);
    char *ea, *eb;
    double x = strtod(a, &ea), y = strtod(b, &eb);
    if (ea != a && *ea == 0 && eb != b && *eb == 0) return x == y;
    return !strcmp(a, b);
}

/* Every "`KEY` (default V", "`KEY`, default V" and "`KEY` of night (default V" (up to 40 characters of the
 * same sentence between) of text, KEY a configuration key with a default: V must be it. Returns the number
 * compared; mismatches go to the report. */
static int check_defaults(const char *doc, const char *text, const char *keys)
{
    regex_t re;
    ck_assert_int_eq(regcomp(&re, "`([a-z][a-z0-9_]*(\\.[a-z0-9_]+)+)`[^`.;]{0,40}[ ,(]default (\xe2\x88\x92)?(`?\"?[A-Za-z0-9_.-]+\"?`?)",
                             REG_EXTENDED), 0);
    int n = 0;
    regmatch_t m[5];
    for (const char *p = text; !regexec(&re, p, 5, m, p == text ? 0 : REG_NOTBOL); p += m[0].rm_eo) {
        char key[256], val[64], def[64];
        snprintf(key, sizeof key, "%.*s", (int)(m[1].rm_eo - m[1].rm_so), p + m[1].rm_so);
        snprintf(val, sizeof val, "%s%.*s", m[3].rm_so >= 0 ? "-" : "", (int)(m[4].rm_eo - m[4].rm_so), p + m[4].rm_so);
        size_t l = strlen(val);
        while (l > 0 && val[l - 1] == '.') val[--l] = 0; /* the sentence's full stop */
        if (!key_default(keys, key, def, sizeof def)) continue;
        n++;
        if (!same_value(val, def)) {
            nbad++;
            snprintf(report + strlen(report), sizeof report - strlen(report),
                     "%s: `%s` (default %s), but `wavetomo info --keys` gives default %s\n", doc, key, val, def);
        }
    }
    regfree(&re);
    return n;
}

START_TEST(test_stated_defaults)
{
    report[0] = 0, nbad = 0;
    char *keys = info("--keys");
    char *withnl = malloc(strlen(keys) + 2);
    sprintf(withnl, "\n%s", keys);
    int n = 0;
    for (int d = 0; user_docs[d]; d++) {
        if (!strcmp(user_docs[d], "docs/config.md")) continue; /* generated from the same table */
        char *text = slurp_file(user_docs[d]);
        ck_assert_msg(text != NULL, "%s missing", user_docs[d]);
        char *flat = flatten(text);
        n += check_defaults(user_docs[d], flat, withnl);
        free(flat);
        free(text);
    }
    /* the checker itself: a wrong default is reported, a right one is not */
    int before = nbad;
    size_t rlen = strlen(report);
    ck_assert_int_eq(check_defaults("self", "`sim.psf_pixels` (default 128)", withnl), 1);
    ck_assert_int_eq(nbad, before + 1);
    ck_assert_int_eq(check_defaults("self", "`recon.atmosphere.mvm_latency_s` (default \xe2\x88\x92" "1: x)", withnl), 1);
    ck_assert_int_eq(check_defaults("self", "`recon.mvm_precision`, default `\"fp32\"`", withnl), 1);
    ck_assert_int_eq(check_defaults("self", "`sim.psf_interval_frames`-th frame after the window (default 10; 0", withnl), 1);
    ck_assert_int_eq(check_defaults("self", "`sim.psf_pixels`. Then (default 128)", withnl), 0); /* another sentence */
    ck_assert_int_eq(nbad, before + 1);
    nbad = before;
    report[rlen] = 0;
    free(withnl);
    free(keys);
    ck_assert_msg(n >= 4, "only %d defaults stated next to their keys were found in the docs", n);
    ck_assert_msg(nbad == 0, "%d defaults in the docs differ from `wavetomo info --keys`:\n%s", nbad, report);
}
END_TEST

/* ---- links -------------------------------------------------------------------------------------- */

/* GitHub's anchor of a heading: lower case, spaces to '-', ASCII punctuation other than '-' and '_' dropped. */
static void slug(const char *heading, char *out, size_t n)
{
    size_t k = 0;
    for (const char *s = heading; *s && k + 1 < n; s++) {
        unsigned char c = (unsigned char)*s;
        if (c >= 0x80 || isalnum(c) || c == '-' || c == '_') out[k++] = (char)tolower(c);
        else if (c == ' ') out[k++] = '-';
    }
    out[k] = 0;
}

/* 1 when file `path` has a heading whose anchor is `anchor`. */
static int has_anchor(const char *path, const char *anchor)
{
    char *text = slurp_file(path);
    if (!text) return 0;
    int found = 0, fence = 0;
    for (char *line = text; line && *line && !found;) {
        char *eol = strchr(line, '\n');
        if (eol) *eol = 0;
        if (!strncmp(line, "```", 3)) fence = !fence;
        if (!fence && line[0] == '#') {
            const char *h = line;
            while (*h == '#') h++;
            while (*h == ' ') h++;
            char s[512];
            slug(h, s, sizeof s);
            found = !strcmp(s, anchor);
        }
        line = eol ? eol + 1 : NULL;
    }
    free(text);
    return found;
}

/* Every relative link "](target)" of doc: the file exists (relative to the doc's directory) and its #anchor is
 * a heading of it. Returns the number of links checked. */
static int check_links(const char *doc, const char *text)
{
    char base[256];
    snprintf(base, sizeof base, "%s", doc);
    char *slash = strrchr(base, '/');
    if (slash) slash[1] = 0;
    else base[0] = 0;
    int n = 0;
    for (const char *p = strstr(text, "]("); p; p = strstr(p + 2, "](")) {
        const char *t = p + 2, *end = strchr(t, ')');
        if (!end || end - t > 400 || memchr(t, ' ', (size_t)(end - t)) || memchr(t, '\n', (size_t)(end - t))) continue;
        char target[512];
        snprintf(target, sizeof target, "%.*s", (int)(end - t), t);
        if (strstr(target, "://") || !strncmp(target, "mailto:", 7)) continue;
        char *hash = strchr(target, '#');
        char anchor[256] = "";
        if (hash) {
            snprintf(anchor, sizeof anchor, "%s", hash + 1);
            *hash = 0;
        }
        char path[800];
        snprintf(path, sizeof path, "%s%s", *target ? base : "", *target ? target : doc);
        n++;
        FILE *f = fopen(path, "r");
        if (!f) {
            nbad++;
            snprintf(report + strlen(report), sizeof report - strlen(report), "%s: link to %s: no such file\n", doc, path);
            continue;
        }
        fclose(f);
        if (*anchor && !has_anchor(path, anchor)) {
            nbad++;
            snprintf(report + strlen(report), sizeof report - strlen(report), "%s: link to %s#%s: no such section\n",
                     doc, path, anchor);
        }
    }
    return n;
}

START_TEST(test_links_resolve)
{
    report[0] = 0, nbad = 0;
    int n = 0;
    for (int pass = 0; pass < 2; pass++)
        for (const char *const *d = pass ? linked_docs : user_docs; *d; d++) {
            char *text = slurp_file(*d);
            ck_assert_msg(text != NULL, "%s missing", *d);
            n += check_links(*d, text);
            free(text);
        }
    ck_assert_msg(nbad == 0, "%d links in the docs lead nowhere:\n%s", nbad, report);
    ck_assert_msg(n > 30, "only %d links found in the docs", n);
    /* the checker itself: a heading's anchor is found, an invented one and a missing file are reported */
    char s[128];
    slug("RUN.h5 (`wavetomo sim --out`)", s, sizeof s);
    ck_assert_str_eq(s, "runh5-wavetomo-sim---out");
    ck_assert(has_anchor("docs/formats.md", "runh5-wavetomo-sim---out"));
    ck_assert(!has_anchor("README.md", "the-api")); /* not a heading */
    ck_assert_int_eq(check_links("docs/c-api.md", "[x](../README.md#the-two-commands) [y](../README.md#no-such) "
                                                  "[z](nofile.md) [w](#what-is-public)"),
                     4);
    ck_assert_int_eq(nbad, 2);
}
END_TEST

/* ---- the README and issue numbers --------------------------------------------------------------- */

START_TEST(test_readme_is_an_introduction)
{
    char *text = slurp_file("README.md");
    ck_assert_ptr_nonnull(text);
    int lines = 0;
    for (const char *p = text; *p; p++) lines += *p == '\n';
    ck_assert_msg(lines <= 150, "README.md has %d lines: at most 150 (measurements go to docs/results-summary.md, "
                                "timings to docs/benchmarks.md)", lines);
    char *links = strstr(text, "\n## Where to read on");
    ck_assert_msg(links != NULL, "README.md has no section 'Where to read on'");
    *links = 0;
    ck_assert_msg(!strstr(text, "§"), "README.md cites a section (§) above its links");
    regex_t re;
    ck_assert_int_eq(regcomp(&re, "[Ii]ssue [0-9]|20[0-9][0-9]-[0-1][0-9]-[0-3][0-9]|[0-9]:[0-5][0-9] UTC", REG_EXTENDED), 0);
    regmatch_t m[1];
    int hit = regexec(&re, text, 1, m, 0) == 0;
    ck_assert_msg(!hit, "README.md has an issue number or a date above its links: '%.40s'", hit ? text + m[0].rm_so : "");
    regfree(&re);
    /* .ci/run runs the README's test command: the two commands must still say it */
    char *two = strstr(text, "## The two commands");
    ck_assert_msg(two && strstr(two, "\nmake test "), "README.md's two commands no longer include `make test`");
    char *ci = slurp_file(".ci/run");
    ck_assert_msg(ci && strstr(ci, " make test"), ".ci/run no longer runs make test");
    free(ci);
    free(text);
}
END_TEST

/* "issue 19", "issue 20 §5": work-log references, meaningless to a user. */
static int issue_refs(const char *what, const char *text)
{
    regex_t re;
    ck_assert_int_eq(regcomp(&re, "[Ii]ssues? [0-9]+", REG_EXTENDED), 0);
    regmatch_t m[1];
    int n = 0;
    for (const char *p = text; !regexec(&re, p, 1, m, p == text ? 0 : REG_NOTBOL); p += m[0].rm_eo) {
        n++;
        snprintf(report + strlen(report), sizeof report - strlen(report), "%s: '%.*s'\n", what,
                 (int)(m[0].rm_eo - m[0].rm_so + 10), p + m[0].rm_so);
    }
    regfree(&re);
    return n;
}

START_TEST(test_no_issue_numbers)
{
    report[0] = 0;
    int bad = 0;
    for (int d = 0; user_docs[d]; d++) {
        char *text = slurp_file(user_docs[d]);
        ck_assert_ptr_nonnull(text);
        bad += issue_refs(user_docs[d], text);
        free(text);
    }
    /* the presets, whose comments document every key */
    DIR *pd = opendir("data/presets");
    ck_assert_ptr_nonnull(pd);
    int npreset = 0;
    for (struct dirent *e; (e = readdir(pd));) {
        size_t l = strlen(e->d_name);
        if (l < 5 || strcmp(e->d_name + l - 4, ".cfg")) continue;
        char path[600];
        snprintf(path, sizeof path, "data/presets/%s", e->d_name);
        char *text = slurp_file(path);
        ck_assert_ptr_nonnull(text);
        bad += issue_refs(path, text);
        npreset++;
        free(text);
    }
    closedir(pd);
    ck_assert_int_ge(npreset, 6);
    char cmd[700];
    snprintf(cmd, sizeof cmd, "%s --help", wt);
    char *help = slurp_cmd(cmd);
    ck_assert_ptr_nonnull(help);
    bad += issue_refs("wavetomo --help", help);
    /* each command of the list after "commands:" */
    int ncmd = 0;
    for (char *line = strstr(help, "commands:"); line && (line = strchr(line, '\n')) && line[1] && line[1] != '\n';
         line++) {
        char c[32];
        if (strncmp(line + 1, "  ", 2) || sscanf(line + 3, "%31[a-z]", c) != 1) continue;
        snprintf(cmd, sizeof cmd, "%s %s --help 2>&1", wt, c);
        char *h = slurp_cmd(cmd);
        ck_assert_msg(h != NULL, "%s failed", cmd);
        char what[64];
        snprintf(what, sizeof what, "wavetomo %s --help", c);
        bad += issue_refs(what, h);
        ncmd++;
        free(h);
    }
    free(help);
    ck_assert_msg(ncmd >= 8, "only %d commands found in wavetomo --help", ncmd);
    ck_assert_msg(bad == 0, "%d issue numbers in user-facing text:\n%s", bad, report);
    report[0] = 0;
    ck_assert_int_eq(issue_refs("self", "the paired mode (issue 20 §5) and issues 3"), 2);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("docs_figures");
    TCase *tc = tcase_create("docs_figures");
    tcase_add_checked_fixture(tc, setup, teardown);
    tcase_set_timeout(tc, 120);
    tcase_add_test(tc, test_eelt_sizes);
    tcase_add_test(tc, test_cg9_solver);
    tcase_add_test(tc, test_stated_defaults);
    tcase_add_test(tc, test_links_resolve);
    tcase_add_test(tc, test_readme_is_an_introduction);
    tcase_add_test(tc, test_no_issue_numbers);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
