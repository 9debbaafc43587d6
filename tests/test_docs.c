/* tests/test_docs.c: the documentation cannot drift from the program (issue 21 §4). Every command, every
 * option given to a command and every configuration key that README.md and the user docs name must exist
 * (the binary's own --help and `info --keys` are the truth), and docs/config.md must be exactly what
 * docs/config.sh makes of `wavetomo info --keys`. Runs $BIN/wavetomo (else bin/wavetomo) from the
 * repository's top directory, like the other command-line suites. */
#include <ctype.h>
#include <regex.h>

#include "testutil.h"

/* The documents a user reads. results.md (a dated log of what was measured, with the commands of the day)
 * and SPEC.md (the physics, no keys) are not checked. */
static const char *const docs[] = {"README.md",          "docs/guide.md",  "docs/config.md", "docs/formats.md",
                                   "docs/refusals.md",   "docs/testing.md", "docs/python.md", "docs/benchmarks.md",
                                   "docs/design.md",     "docs/c-api.md",  "docs/python-api.md", NULL};

static char wt[512], dir[64];

static void setup(void) { tu_cli_setup(wt, sizeof wt, dir, sizeof dir, "wtdocs"); }
static void teardown(void) { tu_cli_teardown(dir); }

/* Whole output of a shell command (stdout), NUL-terminated; NULL when it does not run. */
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
    int st = pclose(p);
    if (st != 0) {
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

/* A word list as one string "\nw1\nw2\n...\n", so membership is a strstr of "\nword\n". */
static int has_word(const char *list, const char *w)
{
    char pat[256];
    snprintf(pat, sizeof pat, "\n%s\n", w);
    return strstr(list, pat) != NULL;
}

/* The commands: the lines of `wavetomo --help` after "commands:" that start with two spaces and a word. */
static char *command_list(void)
{
    char cmd[700];
    snprintf(cmd, sizeof cmd, "%s --help", wt);
    char *help = slurp_cmd(cmd);
    ck_assert_msg(help != NULL, "%s --help failed", wt);
    char *out = calloc(1, 1024);
    strcat(out, "\n");
    char *p = strstr(help, "commands:");
    ck_assert_ptr_nonnull(p);
    for (char *line = strchr(p, '\n'); line && line[1]; line = strchr(line + 1, '\n')) {
        if (line[1] == '\n') break; /* the blank line ends the list */
        if (!strncmp(line + 1, "  ", 2) && islower((unsigned char)line[3])) {
            char w[32];
            if (sscanf(line + 3, "%31[a-z]", w) == 1 && strlen(out) + strlen(w) + 2 < 1024) {
                strcat(out, w);
                strcat(out, "\n");
            }
        }
    }
    free(help);
    ck_assert_msg(has_word(out, "sim") && has_word(out, "compare"), "no commands found in %s --help", wt);
    return out;
}

/* Every configuration key: the first column of `wavetomo info --keys`. */
static char *key_list(void)
{
    char cmd[700];
    snprintf(cmd, sizeof cmd, "%s info --keys", wt);
    char *keys = slurp_cmd(cmd);
    ck_assert_msg(keys != NULL, "%s info --keys failed", wt);
    size_t cap = strlen(keys) + 2;
    char *out = calloc(1, cap);
    strcat(out, "\n");
    for (char *line = keys; *line;) {
        char *eol = strchr(line, '\n');
        size_t len = strcspn(line, " \n");
        if (len > 0) {
            strncat(out, line, len);
            strcat(out, "\n");
        }
        if (!eol) break;
        line = eol + 1;
    }
    free(keys);
    return out;
}

/* A documented key is valid when it is a key, or a section that starts keys ("lgs.wfs"); "*.wfs.x" stands for
 * lgs.wfs.x or ngs.wfs.x and "recon.<variant>.x" for recon.pcg3.x or recon.cg9.x. */
static int key_known(const char *keys, const char *k)
{
    if (!strncmp(k, "*.", 2)) {
        char a[256], b[256];
        snprintf(a, sizeof a, "lgs.%s", k + 2);
        snprintf(b, sizeof b, "ngs.%s", k + 2);
        return key_known(keys, a) || key_known(keys, b);
    }
    const char *v = strstr(k, "<variant>");
    if (v) {
        char a[256], b[256];
        snprintf(a, sizeof a, "%.*spcg3%s", (int)(v - k), k, v + 9);
        snprintf(b, sizeof b, "%.*scg9%s", (int)(v - k), k, v + 9);
        return key_known(keys, a) || key_known(keys, b);
    }
    if (has_word(keys, k)) return 1;
    char pat[260];
    snprintf(pat, sizeof pat, "\n%s.", k);
    return strstr(keys, pat) != NULL;
}

/* opt appears in help as a whole option ("--frame" is not found in "--frames") */
static int has_option(const char *help, const char *opt)
{
    size_t n = strlen(opt);
    for (const char *p = strstr(help, opt); p; p = strstr(p + 1, opt))
        if (!isalnum((unsigned char)p[n]) && p[n] != '-' && p[n] != '_') return 1;
    return 0;
}

static int line_of(const char *text, const char *at)
{
    int n = 1;
    for (const char *p = text; p < at; p++) n += *p == '\n';
    return n;
}

/* `wavetomo CMD --help` and the global help, once per command */
static struct {
    char cmd[32];
    char *text;
} helps[32];
static int nhelp;

static const char *help_of(const char *c)
{
    for (int i = 0; i < nhelp; i++)
        if (!strcmp(helps[i].cmd, c)) return helps[i].text;
    ck_assert_int_lt(nhelp, 32);
    char helpcmd[1200];
    snprintf(helpcmd, sizeof helpcmd, "%s %s --help 2>&1; %s --help", wt, c, wt);
    helps[nhelp].text = slurp_cmd(helpcmd);
    ck_assert_ptr_nonnull(helps[nhelp].text);
    snprintf(helps[nhelp].cmd, sizeof helps[nhelp].cmd, "%s", c);
    return helps[nhelp++].text;
}

START_TEST(test_config_md_is_generated)
{
    char cmd[700];
    snprintf(cmd, sizeof cmd, "bash docs/config.sh %s", wt);
    char *want = slurp_cmd(cmd);
    ck_assert_msg(want != NULL, "docs/config.sh failed");
    char *have = slurp_file("docs/config.md");
    ck_assert_msg(have != NULL, "docs/config.md missing");
    ck_assert_msg(!strcmp(want, have), "docs/config.md differs from `wavetomo info --keys`: run `make docs` and commit it");
    free(want);
    free(have);
}
END_TEST

START_TEST(test_commands_and_options_exist)
{
    char *cmds = command_list();
    regex_t re;
    /* "bin/wavetomo CMD" or "`wavetomo CMD": an invocation, not the project's name in prose */
    ck_assert_int_eq(regcomp(&re, "(bin/|`)wavetomo +([a-z]+)", REG_EXTENDED), 0);
    int bad = 0, seen = 0;
    char report[4096] = "";
    for (int d = 0; docs[d]; d++) {
        char *text = slurp_file(docs[d]);
        ck_assert_msg(text != NULL, "%s missing", docs[d]);
        regmatch_t m[3];
        for (const char *p = text; !regexec(&re, p, 3, m, p == text ? 0 : REG_NOTBOL); p += m[0].rm_eo) {
            char c[32] = "";
            snprintf(c, sizeof c, "%.*s", (int)(m[2].rm_eo - m[2].rm_so), p + m[2].rm_so);
            seen++;
            if (!has_word(cmds, c)) {
                bad++;
                snprintf(report + strlen(report), sizeof report - strlen(report), "%s:%d: no command '%s'\n",
                         docs[d], line_of(text, p + m[0].rm_so), c);
                continue;
            }
            /* the options of an invocation line (and its "\" continuations), comments cut */
            const char *help = help_of(c);
            const char *q = p + m[0].rm_eo;
            for (;;) {
                const char *eol = strchr(q, '\n');
                size_t len = eol ? (size_t)(eol - q) : strlen(q);
                const char *hash = memchr(q, '#', len);
                size_t use = hash ? (size_t)(hash - q) : len;
                for (size_t i = 0; i + 2 < use; i++) {
                    if (q[i] == '-' && q[i + 1] == '-' && islower((unsigned char)q[i + 2]) && (i == 0 || q[i - 1] == ' ')) {
                        char opt[64];
                        size_t k = 0;
                        while (i + k < use && k < 63 && (isalnum((unsigned char)q[i + k]) || q[i + k] == '-')) {
                            opt[k] = q[i + k];
                            k++;
                        }
                        opt[k] = 0;
                        if (!has_option(help, opt)) {
                            bad++;
                            snprintf(report + strlen(report), sizeof report - strlen(report),
                                     "%s:%d: wavetomo %s has no option %s\n", docs[d], line_of(text, q), c, opt);
                        }
                    }
                }
                if (!eol || len == 0 || q[len - 1] != '\\') break;
                q = eol + 1;
            }
        }
        free(text);
    }
    regfree(&re);
    free(cmds);
    for (int i = 0; i < nhelp; i++) free(helps[i].text);
    nhelp = 0;
    ck_assert_msg(seen > 30, "only %d command invocations found in the docs", seen);
    ck_assert_msg(bad == 0, "%d unknown commands or options in the docs:\n%s", bad, report);
}
END_TEST

START_TEST(test_keys_exist)
{
    char *keys = key_list();
    regex_t re;
    /* section.key(.key...) of the configuration's top-level sections, "*." and "<variant>" forms included */
    ck_assert_int_eq(regcomp(&re,
                             "(^|[^A-Za-z0-9_./-])((\\*|telescope|atmosphere|lgs|ngs|dm|recon|loop|sim|evaluation)"
                             "(\\.([a-z0-9_]+|<variant>))+)",
                             REG_EXTENDED),
                     0);
    static const char *const not_keys[] = {"c", "h", "h5", "png", "md", "cfg", "txt", "sh", "tsv", NULL};
    int bad = 0, seen = 0;
    char report[4096] = "";
    for (int d = 0; docs[d]; d++) {
        char *text = slurp_file(docs[d]);
        ck_assert_msg(text != NULL, "%s missing", docs[d]);
        regmatch_t m[3];
        for (const char *p = text; !regexec(&re, p, 3, m, p == text ? 0 : REG_NOTBOL); p += m[0].rm_eo) {
            char k[256];
            snprintf(k, sizeof k, "%.*s", (int)(m[2].rm_eo - m[2].rm_so), p + m[2].rm_so);
            const char *last = strrchr(k, '.') + 1;
            int file = 0;
            for (int i = 0; not_keys[i]; i++) file |= !strcmp(last, not_keys[i]);
            if (file) continue;
            seen++;
            if (!key_known(keys, k)) {
                bad++;
                snprintf(report + strlen(report), sizeof report - strlen(report), "%s:%d: no key '%s'\n", docs[d],
                         line_of(text, p + m[2].rm_so), k);
            }
        }
        free(text);
    }
    regfree(&re);
    free(keys);
    ck_assert_msg(seen > 100, "only %d key names found in the docs", seen);
    ck_assert_msg(bad == 0, "%d unknown configuration keys in the docs:\n%s", bad, report);
}
END_TEST

/* The checker itself must catch what it is for: a made-up key and a made-up option are reported. */
START_TEST(test_checker_catches_inventions)
{
    char *keys = key_list();
    ck_assert(key_known(keys, "lgs.wfs.photons"));
    ck_assert(key_known(keys, "lgs.wfs"));
    ck_assert(key_known(keys, "*.wfs.centroider"));
    ck_assert(key_known(keys, "recon.<variant>.layer_oversampling"));
    ck_assert(!key_known(keys, "lgs.wfs.photon"));
    ck_assert(!key_known(keys, "recon.<variant>.no_such_key"));
    ck_assert(!key_known(keys, "lgs.wf"));
    free(keys);
    char *cmds = command_list();
    ck_assert(has_word(cmds, "budget") && !has_word(cmds, "simulate"));
    free(cmds);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("docs");
    TCase *tc = tcase_create("docs");
    tcase_add_checked_fixture(tc, setup, teardown);
    tcase_set_timeout(tc, 120);
    tcase_add_test(tc, test_config_md_is_generated);
    tcase_add_test(tc, test_commands_and_options_exist);
    tcase_add_test(tc, test_keys_exist);
    tcase_add_test(tc, test_checker_catches_inventions);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
