/* fuzz_flags.c — the scenario flags through the programs' parser
 * (lib/cli crom_cli_parse with the scenario options of lib/phys/scenario.c).
 *
 * fuzz_flags: the input is a command line, one argument per line (a NUL byte
 * also ends one). A nested @NAME is looked up in the current directory
 * (tests/fuzz/run.sh runs the harnesses in an empty one). fuzz_atfile (built with -DFUZZ_ATFILE): the input is a
 * flag file, given as the one argument @FILE (lib/cli's @FILE expansion:
 * whitespace, '#' comments, quotes, nested @FILEs).
 *
 * crom_cli_parse ends the process on a usage error (exit 64), as a program
 * must; the harness is linked with -Wl,--wrap=exit so that exit() during a
 * parse returns here instead (any other exit() is the real one). After a
 * parse that succeeds, the scenario is checked and its canonical text
 * (crom_scenario_text, what every output stores) must parse back to the same
 * text: a difference is a bug, and aborts. Every input is also given
 * directly to crom_scenario_parse_text, the reader of stored scenarios.
 */
#include <setjmp.h>
#include <stdnoreturn.h>

#include "base/err.h"
#include "cli/cli.h"
#include "phys/scenario.h"

#include "fuzz.h"

noreturn void __real_exit(int code);
noreturn void __wrap_exit(int code);

static jmp_buf parse_jump;
static volatile int in_parse;

noreturn void __wrap_exit(int code)
{
    if (in_parse) {
        in_parse = 0;
        longjmp(parse_jump, 1);
    }
    __real_exit(code);
}

enum { OPT_OUT = 'o', OPT_MODEL = 0x2000, OPT_RANK };

static const crom_opt prog_opts[] = {
    {"output", OPT_OUT, "FILE", "Output file."},
    {"model", OPT_MODEL, "FILE", "A model."},
    {"rank", OPT_RANK, "R", "A rank."},
    {NULL, 0, NULL, NULL}};

static const crom_cli_optgroup groups[] = {
    {"Options", prog_opts}, {"Scenario options", crom_scenario_opts}, {NULL, NULL}};

static const crom_cli_doc doc = {"crom-fuzz", "a scenario parsed by the fuzzer", "crom-fuzz [OPTIONS] MESH",
                                 "The scenario options of crom-fullsim.", groups, NULL, NULL};

typedef struct {
    crom_scenario sc;
    int noperands;
} ctx_t;

static int handler(void *vctx, int key, const char *value)
{
    ctx_t *c = vctx;
    if (key == 0) {
        c->noperands++;
        return 0;
    }
    int rc = crom_scenario_option(&c->sc, key, value);
    if (rc >= 0)
        return rc;
    if (key == OPT_RANK) {
        long n;
        return crom_parse_int(value, "--rank", 1, 10000, &n);
    }
    return 0; /* -o, --model: any value */
}

/* The canonical text of a parsed scenario parses back to the same text. */
static void round_trip(const crom_scenario *sc)
{
    char *t1 = crom_scenario_text(sc);
    if (!t1)
        abort();
    crom_scenario back;
    crom_scenario_defaults(&back);
    if (crom_scenario_parse_text(t1, &back)) {
        fprintf(stderr, "crom_scenario_text wrote text it cannot parse: %s\n---\n%s---\n", crom_errmsg(), t1);
        abort();
    }
    char *t2 = crom_scenario_text(&back);
    if (!t2 || strcmp(t1, t2)) {
        fprintf(stderr, "scenario text does not parse back to itself:\n---\n%s---\n%s---\n", t1, t2 ? t2 : "");
        abort();
    }
    free(t1);
    free(t2);
}

static crom_cli cli; /* static: survives the longjmp out of crom_cli_parse */
static ctx_t ctx;
static char *args[130];

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc;
    (void)argv;
    fuzz_quiet_stdout(); /* --help and --version print the manual */
    return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char *text = malloc(size + 1);
    if (!text)
        return 0;
    memcpy(text, data, size);
    text[size] = 0;
    int argc = 0;
    args[argc++] = "crom-fuzz";
#ifdef FUZZ_ATFILE
    const char *path = fuzz_write(data, size, ".flags");
    char at[600];
    snprintf(at, sizeof at, "@%s", path);
    args[argc++] = at;
#else
    char *copy = malloc(size + 1);
    if (!copy) {
        free(text);
        return 0;
    }
    memcpy(copy, data, size);
    copy[size] = 0;
    for (size_t i = 0, start = 0; i <= size && argc < 129; i++)
        if (i == size || copy[i] == '\n' || copy[i] == 0) {
            copy[i] = 0;
            if (i > start || i < size)
                args[argc++] = copy + start;
            start = i + 1;
        }
#endif
    args[argc] = NULL;

    crom_scenario_defaults(&ctx.sc);
    ctx.noperands = 0;
    crom_err_clear();
    if (setjmp(parse_jump) == 0) {
        in_parse = 1;
        crom_cli_parse(&cli, &doc, argc, args, handler, &ctx);
        in_parse = 0;
        if (crom_scenario_check(&ctx.sc) == 0)
            round_trip(&ctx.sc);
    }
    crom_cli_exit(&cli, 0);

    /* the same bytes as stored scenario text */
    crom_scenario sc;
    crom_scenario_defaults(&sc);
    if (crom_scenario_parse_text(text, &sc) == 0 && crom_scenario_check(&sc) == 0)
        round_trip(&sc);
    crom_err_clear();
#ifndef FUZZ_ATFILE
    free(copy);
#endif
    free(text);
    return 0;
}
