/* cli.h — what every crom program shares: start-up, option parsing, the
 * manual (for --help and the man page, from one source), messages, progress.
 *
 * This is the only library module that prints: it is the programs' side of
 * the library. A program defines a crom_cli_doc (its manual) and option
 * tables, calls crom_cli_parse() with a handler, then does its work and ends
 * with `return crom_cli_exit(&cli, rc);`.
 */
#ifndef CROM_CLI_H
#define CROM_CLI_H

#include <stdint.h>
#include <stdio.h>

#include "base/clock.h"
#include "base/opt.h"
#include "base/parse.h"

/* A group of options under a heading; a table ends with {0}. */
typedef struct {
    const char *heading;  /* e.g. "Scenario options" */
    const crom_opt *opts; /* terminated by an entry with name == NULL */
} crom_cli_optgroup;

/* A program's manual: --help prints it, --help-man prints it as troff. */
typedef struct {
    const char *name;        /* "crom-mesh" */
    const char *summary;     /* one line: what the program does */
    const char *synopsis;    /* usage lines, '\n'-separated */
    const char *description; /* paragraphs separated by blank lines */
    const crom_cli_optgroup *groups; /* terminated by {0} */
    const char *examples;    /* command lines, '\n'-separated, or NULL */
    const char *see_also;    /* "crom-info(1), crom-export(1)" or NULL */
} crom_cli_doc;

/* Called for each option (key, value or NULL) and each operand (key 0). It
 * returns 0 or an error code after recording a message with crom_err(). */
typedef int (*crom_cli_opt_fn)(void *ctx, int key, const char *value);

typedef struct {
    const char *prog;  /* program name used in messages */
    const crom_cli_doc *doc;
    int quiet;         /* --quiet: no info lines, no progress */
    int verbose;       /* --verbose (count) */
    int threads;       /* --threads N (default 1; 0 = all cores) */
    uint64_t seed;     /* --seed S (default 1) */
    int seed_given;
    char *cmdline;     /* the command line, shell-quoted, for `history` */
    char **expanded;   /* argv after @FILE expansion (owned) */
    int nexpanded;
} crom_cli;

/* Options every program accepts, listed in every manual. */
enum {
    CROM_CLI_HELP = 1000, CROM_CLI_HELP_MAN, CROM_CLI_VERSION, CROM_CLI_QUIET,
    CROM_CLI_VERBOSE, CROM_CLI_SEED, CROM_CLI_THREADS
};

/* Parse argv: expands @FILE arguments (whitespace-separated flags, '#'
 * comments, single/double quotes), handles the common options itself
 * (--help and --version print and exit 0), hands the rest to fn. On a usage
 * error it prints "PROG: message" plus a hint and exits 64. */
void crom_cli_parse(crom_cli *cli, const crom_cli_doc *doc, int argc, char **argv,
                    crom_cli_opt_fn fn, void *ctx);

/* Print "PROG: <last library error>" if rc != 0, free the cli, and return rc
 * (so main can `return crom_cli_exit(&cli, rc)`). When rc is 0 it flushes
 * stdout first: a write to stdout that failed (a full disk, /dev/full)
 * prints "PROG: cannot write to stdout: REASON" and returns CROM_EIO (74).
 * --help, --help-man and --version check stdout the same way. */
int crom_cli_exit(crom_cli *cli, int rc);

/* "PROG: message" on stderr, unless --quiet (info) / always (warn). */
void crom_cli_info(const crom_cli *cli, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));
void crom_cli_warn(const crom_cli *cli, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));

/* "PROG: line" on stderr, for a library's log callback (ctx is the
 * crom_cli *): e.g. gmsh's messages with -vv. */
void crom_cli_log_line(void *cli, const char *line);

/* Print the manual (man = 0: --help text; man = 1: troff). */
void crom_cli_print_doc(const crom_cli_doc *doc, FILE *f, int man);

/* --- progress --- */

typedef struct {
    int active;        /* only when stderr is a terminal and not --quiet */
    const char *label;
    long total;
    double t0, last;
} crom_cli_progress;

void crom_cli_progress_start(crom_cli_progress *p, const crom_cli *cli,
                             const char *label, long total);
/* done of total finished; extra is a short status text or NULL. */
void crom_cli_progress_update(crom_cli_progress *p, long done, const char *extra);
void crom_cli_progress_end(crom_cli_progress *p);

#endif
