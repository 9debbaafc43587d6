/* tests/fuzz/fuzz_config.c: libFuzzer target of the configuration reader (core/config/config*.c, SPEC §1).
 *
 * Input: the libconfig text, then up to 8 `--set` overrides, separated by NUL bytes ("TEXT\0k=v\0k=v").
 * The text goes through wt_config_parse exactly as a file's text does (@include expansion and the exact
 * integer pass of config_text.c, libconfig, the file's own `overrides`, the command-line overrides,
 * typed keys, consistency, derived sizes, the canonical text and its hash). @include names resolve in
 * the sandbox directory (build/fuzz/sandbox: a copy of the presets, a fragment, a directory, a file
 * including itself, an empty file, a NUL byte, a FIFO nobody writes); an input whose @include could leave it is skipped. */
#include "fuzz.h"

static wt_context *ctx;

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc, (void)argv;
    fuzz_enter_sandbox();
    if (!(ctx = wt_context_alloc())) fuzz_die("wt_context_alloc", NULL);
    return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size > (1 << 16) || fuzz_escapes_sandbox((const char *)data, size)) return 0;
    char *buf = malloc(size + 1);
    if (!buf) return 0;
    memcpy(buf, data, size);
    buf[size] = '\0';
    const char *ov[8];
    int nov = 0;
    for (char *p = buf + strlen(buf); p < buf + size && nov < 8; p += strlen(p)) ov[nov++] = ++p;
    wt_config *cfg = NULL;
    int st = wt_config_parse(ctx, buf, "fuzz.cfg", nov, ov, &cfg);
    if (st == WT_OK) {
        /* what the callers rely on from an accepted configuration */
        if (!cfg || !cfg->canonical || strlen(cfg->matrix_sha256) != 64) abort();
        wt_config_free(ctx, cfg);
    } else if (cfg || !*wt_error_message(ctx)) {
        abort(); /* a refusal leaves no configuration and always says why */
    }
    free(buf);
    return 0;
}
