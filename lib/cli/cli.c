/* cli.c — start-up, option parsing, manuals, messages and progress for crom
 * programs. */
#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <time.h>
#include <unistd.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "base/array.h"
#include "base/err.h"
#include "cli/cli.h"

extern void openblas_set_num_threads(int);

static const crom_opt common_opts[] = {
    {"help", CROM_CLI_HELP, NULL, "Print this help and exit."},
    {"version", CROM_CLI_VERSION, NULL, "Print the crom version and exit."},
    {"quiet", 'q', NULL, "Print nothing but errors; no progress bar."},
    {"verbose", 'v', NULL, "Print more about what is done (repeatable)."},
    {"seed", CROM_CLI_SEED, "S",
     "Seed of the pseudo-random numbers (default 1); the same seed and inputs give the same output bytes."},
    {"threads", CROM_CLI_THREADS, "N",
     "Threads for the parallel loops (default 1, or the environment variable CROM_THREADS; 0 = all cores). This machine kind gains little from a second core."},
    {"help-man", CROM_CLI_HELP_MAN, NULL, "Print the manual page as troff and exit."},
    {NULL, 0, NULL, NULL}};

/* ---------------------------------------------------------------- messages */

static void vmsg(const char *prog, const char *fmt, va_list ap)
{
    fprintf(stderr, "%s: ", prog);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
}

void crom_cli_info(const crom_cli *cli, const char *fmt, ...)
{
    if (cli->quiet)
        return;
    va_list ap;
    va_start(ap, fmt);
    vmsg(cli->prog, fmt, ap);
    va_end(ap);
}

void crom_cli_warn(const crom_cli *cli, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "%s: warning: ", cli->prog);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
}

void crom_cli_log_line(void *cli, const char *line)
{
    fprintf(stderr, "%s: %s\n", ((const crom_cli *)cli)->prog, line);
}

/* ------------------------------------------------------------- manual text */

/* Print s wrapped at width w with an indent. */
static void wrap(FILE *f, const char *s, int indent, int first_col, int w)
{
    int col = first_col;
    while (*s) {
        while (*s == ' ')
            s++;
        if (*s == '\n') { /* explicit newline: keep it */
            fputc('\n', f);
            for (int i = 0; i < indent; i++)
                fputc(' ', f);
            col = indent;
            s++;
            continue;
        }
        const char *e = s;
        while (*e && *e != ' ' && *e != '\n')
            e++;
        int len = (int)(e - s);
        if (col > indent && col + 1 + len > w) {
            fputc('\n', f);
            for (int i = 0; i < indent; i++)
                fputc(' ', f);
            col = indent;
        } else if (col > indent) {
            fputc(' ', f);
            col++;
        }
        fwrite(s, 1, (size_t)len, f);
        col += len;
        s = e;
    }
    fputc('\n', f);
}

static void print_opt_text(FILE *f, const crom_opt *o)
{
    char head[128];
    int n;
    if (o->key > 32 && o->key < 127)
        n = snprintf(head, sizeof head, "  -%c, --%s", o->key, o->name);
    else
        n = snprintf(head, sizeof head, "      --%s", o->name);
    if (o->arg)
        n += snprintf(head + n, sizeof head - (size_t)n, " %s", o->arg);
    fputs(head, f);
    if (n < 28) {
        for (int i = n; i < 28; i++)
            fputc(' ', f);
        wrap(f, o->help, 28, 28, 79);
    } else {
        fputc('\n', f);
        for (int i = 0; i < 28; i++)
            fputc(' ', f);
        wrap(f, o->help, 28, 28, 79);
    }
}

/* troff-escape a string: backslash and leading dots/quotes. */
static void troff(FILE *f, const char *s)
{
    int bol = 1;
    for (; *s; s++) {
        if (bol && (*s == '.' || *s == '\''))
            fputs("\\&", f);
        if (*s == '\\')
            fputs("\\e", f);
        else if (*s == '-')
            fputs("\\-", f);
        else
            fputc(*s, f);
        bol = (*s == '\n');
    }
}

/* The next paragraph of *p (paragraphs are separated by a blank line),
 * malloc'ed, advancing *p; NULL at the end (or out of memory). */
static char *next_paragraph(const char **p)
{
    if (!**p)
        return NULL;
    const char *e = strstr(*p, "\n\n");
    size_t len = e ? (size_t)(e - *p) : strlen(*p);
    char *para = malloc(len + 1);
    if (para) {
        memcpy(para, *p, len);
        para[len] = 0;
    }
    *p += len;
    while (**p == '\n')
        (*p)++;
    return para;
}

static void print_paragraphs_man(FILE *f, const char *s)
{
    for (char *para; (para = next_paragraph(&s)); free(para)) {
        fputs(".PP\n", f);
        troff(f, para);
        fputc('\n', f);
    }
}

static void print_man(const crom_cli_doc *d, FILE *f)
{
    char up[64];
    size_t i;
    for (i = 0; d->name[i] && i < sizeof up - 1; i++)
        up[i] = (char)toupper((unsigned char)d->name[i]);
    up[i] = 0;
    fprintf(f, ".TH %s 1 \"\" \"crom %s\" \"crom manual\"\n", up, CROM_VERSION);
    fputs(".SH NAME\n", f);
    troff(f, d->name);
    fputs(" \\- ", f);
    troff(f, d->summary);
    fputs("\n.SH SYNOPSIS\n.nf\n", f);
    troff(f, d->synopsis);
    fputs("\n.fi\n.SH DESCRIPTION\n", f);
    print_paragraphs_man(f, d->description);
    fputs(".SH OPTIONS\n", f);
    /* one Options heading: a group headed "Options" sits directly under
     * .SH OPTIONS, every other group gets its own .SS */
    for (const crom_cli_optgroup *g = d->groups; g && g->opts; g++) {
        if (strcasecmp(g->heading, "Options") != 0) {
            fputs(".SS ", f);
            troff(f, g->heading);
            fputc('\n', f);
        }
        for (const crom_opt *o = g->opts; o->name; o++) {
            fputs(".TP\n", f);
            if (o->key > 32 && o->key < 127)
                fprintf(f, "\\fB\\-%c\\fR, ", o->key);
            fputs("\\fB\\-\\-", f);
            troff(f, o->name);
            fputs("\\fR", f);
            if (o->arg) {
                fputs(" \\fI", f);
                troff(f, o->arg);
                fputs("\\fR", f);
            }
            fputc('\n', f);
            troff(f, o->help);
            fputc('\n', f);
        }
    }
    fputs(".SS Common options\n", f);
    for (const crom_opt *o = common_opts; o->name; o++) {
        fputs(".TP\n\\fB\\-\\-", f);
        troff(f, o->name);
        fputs("\\fR", f);
        if (o->arg)
            fprintf(f, " \\fI%s\\fR", o->arg);
        fputc('\n', f);
        troff(f, o->help);
        fputc('\n', f);
    }
    fputs(".SH EXIT STATUS\n", f);
    fputs("0 success; 64 bad command line; 65 bad input data; 66 input missing "
          "or unreadable; 70 internal error; 73 cannot create output; 74 I/O "
          "error. Named outputs are written to a temporary file and renamed "
          "only on success.\n",
          f);
    if (d->examples) {
        fputs(".SH EXAMPLES\n.nf\n", f);
        troff(f, d->examples);
        fputs("\n.fi\n", f);
    }
    if (d->see_also) {
        fputs(".SH SEE ALSO\n", f);
        troff(f, d->see_also);
        fputc('\n', f);
    }
}

void crom_cli_print_doc(const crom_cli_doc *d, FILE *f, int man)
{
    if (man) {
        print_man(d, f);
        return;
    }
    fprintf(f, "%s — %s\n\nUsage:\n", d->name, d->summary);
    const char *s = d->synopsis;
    while (*s) {
        const char *e = strchr(s, '\n');
        size_t len = e ? (size_t)(e - s) : strlen(s);
        fprintf(f, "  %.*s\n", (int)len, s);
        s += len;
        if (*s)
            s++;
    }
    fputc('\n', f);
    /* description paragraphs */
    const char *p = d->description;
    for (char *para; (para = next_paragraph(&p)); free(para)) {
        for (char *c = para; *c; c++)
            if (*c == '\n')
                *c = ' ';
        wrap(f, para, 0, 0, 79);
        fputc('\n', f);
    }
    for (const crom_cli_optgroup *g = d->groups; g && g->opts; g++) {
        fprintf(f, "%s:\n", g->heading);
        for (const crom_opt *o = g->opts; o->name; o++)
            print_opt_text(f, o);
        fputc('\n', f);
    }
    fputs("Common options:\n", f);
    for (const crom_opt *o = common_opts; o->name; o++)
        if (o->key != CROM_CLI_HELP_MAN)
            print_opt_text(f, o);
    if (d->examples) {
        fputs("\nExamples:\n", f);
        s = d->examples;
        while (*s) {
            const char *e = strchr(s, '\n');
            size_t len = e ? (size_t)(e - s) : strlen(s);
            fprintf(f, "  %.*s\n", (int)len, s);
            s += len;
            if (*s)
                s++;
        }
    }
    fputs("\nExit status: 0 ok, 64 usage, 65 bad data, 66 no input, 70 internal, "
          "73 cannot create output, 74 I/O.\n",
          f);
    if (d->see_also)
        fprintf(f, "See also: %s\n", d->see_also);
}

/* ----------------------------------------------------------- @FILE expansion */

typedef struct {
    char **v;
    int n;
    size_t cap;
} strvec;

static int sv_push(strvec *sv, const char *s, size_t len)
{
    int rc = crom_array_reserve((void **)&sv->v, &sv->cap, (size_t)sv->n + 1, sizeof *sv->v);
    if (rc)
        return rc;
    char *c = malloc(len + 1);
    if (!c)
        return crom_err(CROM_EINTERNAL, "out of memory");
    memcpy(c, s, len);
    c[len] = 0;
    sv->v[sv->n++] = c;
    return 0;
}

static int expand_arg(strvec *sv, const char *arg, int depth);

/* Tokenize a flags file: whitespace separates, '#' starts a comment to end of
 * line, quotes group. */
static int expand_file(strvec *sv, const char *path, int depth)
{
    if (depth > 8)
        return crom_err(CROM_EUSAGE, "@%s: flag files nested too deeply", path);
    FILE *f = fopen(path, "r");
    if (!f)
        return crom_err(CROM_ENOINPUT, "@%s: %s", path, strerror(errno));
    char *buf = NULL;
    size_t len = 0, cap = 0;
    int c;
    while ((c = fgetc(f)) != EOF) {
        int rc = crom_array_reserve((void **)&buf, &cap, len + 2, 1);
        if (rc) {
            free(buf);
            fclose(f);
            return rc;
        }
        buf[len++] = (char)c;
    }
    fclose(f);
    if (!buf)
        return 0;
    buf[len] = 0;
    char *tok = malloc(len + 1);
    if (!tok) {
        free(buf);
        return crom_err(CROM_EINTERNAL, "out of memory");
    }
    int rc = 0;
    for (char *p = buf; *p && !rc;) {
        while (*p && isspace((unsigned char)*p))
            p++;
        if (*p == '#') {
            while (*p && *p != '\n')
                p++;
            continue;
        }
        if (!*p)
            break;
        size_t t = 0;
        while (*p && !isspace((unsigned char)*p)) {
            if (*p == '"' || *p == '\'') {
                char q = *p++;
                while (*p && *p != q)
                    tok[t++] = *p++;
                if (*p != q) {
                    rc = crom_err(CROM_EUSAGE, "@%s: unterminated quote", path);
                    break;
                }
                p++;
            } else {
                tok[t++] = *p++;
            }
        }
        tok[t] = 0;
        if (!rc)
            rc = expand_arg(sv, tok, depth + 1);
    }
    free(tok);
    free(buf);
    return rc;
}

static int expand_arg(strvec *sv, const char *arg, int depth)
{
    if (arg[0] == '@' && arg[1])
        return expand_file(sv, arg + 1, depth);
    return sv_push(sv, arg, strlen(arg));
}

/* ------------------------------------------------------------------ parsing */

static char *shell_join(int argc, char **argv)
{
    size_t cap = 1;
    for (int i = 0; i < argc; i++)
        cap += 4 * strlen(argv[i]) + 3;
    char *s = malloc(cap), *p = s;
    if (!s)
        return NULL;
    for (int i = 0; i < argc; i++) {
        const char *a = argv[i];
        if (i == 0 && strrchr(a, '/'))
            a = strrchr(a, '/') + 1; /* the program, without its directory */
        int plain = *a != 0;
        for (const char *c = a; *c; c++)
            if (!(isalnum((unsigned char)*c) || strchr("-_./=,:@%+", *c)))
                plain = 0;
        if (i)
            *p++ = ' ';
        if (plain) {
            p += sprintf(p, "%s", a);
        } else {
            *p++ = '\'';
            for (const char *c = a; *c; c++) {
                if (*c == '\'')
                    p += sprintf(p, "'\\''");
                else
                    *p++ = *c;
            }
            *p++ = '\'';
        }
    }
    *p = 0;
    return s;
}

static const crom_opt *find_long(const crom_cli_doc *d, const char *name, size_t len)
{
    for (const crom_cli_optgroup *g = d->groups; g && g->opts; g++)
        for (const crom_opt *o = g->opts; o->name; o++)
            if (strlen(o->name) == len && !strncmp(o->name, name, len))
                return o;
    for (const crom_opt *o = common_opts; o->name; o++)
        if (strlen(o->name) == len && !strncmp(o->name, name, len))
            return o;
    return NULL;
}

static const crom_opt *find_short(const crom_cli_doc *d, char c)
{
    for (const crom_cli_optgroup *g = d->groups; g && g->opts; g++)
        for (const crom_opt *o = g->opts; o->name; o++)
            if (o->key == c)
                return o;
    for (const crom_opt *o = common_opts; o->name; o++)
        if (o->key == c)
            return o;
    return NULL;
}

static void usage_exit(crom_cli *cli)
{
    int code = crom_errcode() ? crom_errcode() : CROM_EUSAGE;
    if (code == CROM_EUSAGE)
        fprintf(stderr, "%s: %s (see %s --help)\n", cli->prog, crom_errmsg(), cli->prog);
    else
        fprintf(stderr, "%s: %s\n", cli->prog, crom_errmsg());
    exit(code);
}

/* Flush stdout and report a write that failed on the way (a full disk,
 * /dev/full, a closed descriptor): "PROG: cannot write to stdout: why" and
 * CROM_EIO, or 0 when everything written reached the descriptor. Every exit
 * of a program goes through here (crom_cli_exit and --help/--version). */
static int stdout_status(const char *prog)
{
    errno = 0;
    int flushed = fflush(stdout) == 0;
    int why = errno;
    if (flushed && !ferror(stdout))
        return 0;
    if (flushed || !why) {
        /* An earlier write failed and stdio dropped that buffer, so its
         * errno is gone. The output is already incomplete: one newline
         * written straight to the descriptor asks it why (ENOSPC, EIO). */
        why = write(1, "\n", 1) < 0 ? errno : 0;
    }
    fprintf(stderr, "%s: cannot write to stdout: %s\n", prog, why ? strerror(why) : "a write failed");
    return CROM_EIO;
}

static int common_option(crom_cli *cli, const crom_opt *o, const char *val)
{
    long n;
    int rc;
    switch (o->key) {
    case CROM_CLI_HELP:
        crom_cli_print_doc(cli->doc, stdout, 0);
        exit(stdout_status(cli->prog));
    case CROM_CLI_HELP_MAN:
        crom_cli_print_doc(cli->doc, stdout, 1);
        exit(stdout_status(cli->prog));
    case CROM_CLI_VERSION:
        printf("%s (crom) %s\n", cli->prog, CROM_VERSION);
        exit(stdout_status(cli->prog));
    case 'q':
        cli->quiet = 1;
        return 0;
    case 'v':
        cli->verbose++;
        return 0;
    case CROM_CLI_SEED: {
        char *end = (char *)val;
        errno = 0;
        unsigned long long s = isdigit((unsigned char)val[0]) ? strtoull(val, &end, 10) : 0;
        if (!isdigit((unsigned char)val[0]) || errno || *end) /* decimal only: no 0x10, no octal 010 */
            return crom_err(CROM_EUSAGE, "--seed: '%s' is not a non-negative decimal integer", val);
        cli->seed = s;
        cli->seed_given = 1;
        return 0;
    }
    case CROM_CLI_THREADS:
        if ((rc = crom_parse_int(val, "--threads", 0, 4096, &n)))
            return rc;
        cli->threads = (int)n;
        return 0;
    }
    return -1;
}

static int is_common(const crom_opt *o)
{
    return o >= common_opts && o < common_opts + sizeof common_opts / sizeof *common_opts;
}

void crom_cli_parse(crom_cli *cli, const crom_cli_doc *doc, int argc, char **argv,
                    crom_cli_opt_fn fn, void *ctx)
{
    memset(cli, 0, sizeof *cli);
    cli->prog = doc->name;
    cli->doc = doc;
    cli->threads = 1;
    cli->seed = 1;
    cli->cmdline = shell_join(argc, argv);
    /* a job's cores (pipelines/submit.sh sets CROM_THREADS from Slurm's
     * SLURM_CPUS_PER_TASK): the default that --threads overrides */
    const char *env = getenv("CROM_THREADS");
    long envn;
    if (env && *env) {
        if (crom_parse_int(env, "CROM_THREADS", 0, 4096, &envn))
            usage_exit(cli);
        cli->threads = (int)envn;
    }
    strvec sv = {0};
    int rc = 0;
    for (int i = 1; i < argc && !rc; i++)
        rc = expand_arg(&sv, argv[i], 0);
    cli->expanded = sv.v;
    cli->nexpanded = sv.n;
    if (rc)
        usage_exit(cli);
    int only_operands = 0;
    for (int i = 0; i < sv.n; i++) {
        const char *a = sv.v[i];
        const crom_opt *o = NULL;
        const char *val = NULL;
        if (only_operands || a[0] != '-' || a[1] == 0) {
            rc = fn(ctx, 0, a);
            if (rc)
                usage_exit(cli);
            continue;
        }
        if (!strcmp(a, "--")) {
            only_operands = 1;
            continue;
        }
        if (a[1] == '-') {
            const char *eq = strchr(a + 2, '=');
            size_t len = eq ? (size_t)(eq - a - 2) : strlen(a + 2);
            o = find_long(doc, a + 2, len);
            if (!o) {
                crom_err(CROM_EUSAGE, "unknown option '%.*s'", (int)len + 2, a);
                usage_exit(cli);
            }
            if (eq) {
                if (!o->arg) {
                    crom_err(CROM_EUSAGE, "option '--%s' takes no value", o->name);
                    usage_exit(cli);
                }
                val = eq + 1;
            }
        } else {
            o = find_short(doc, a[1]);
            if (!o) {
                crom_err(CROM_EUSAGE, "unknown option '%s'", a);
                usage_exit(cli);
            }
            /* clustered flags: -vv, -qv */
            for (const char *c = a + 1; !o->arg && c[1]; c++) {
                rc = is_common(o) ? common_option(cli, o, NULL) : fn(ctx, o->key, NULL);
                if (rc)
                    usage_exit(cli);
                o = find_short(doc, c[1]);
                if (!o || o->arg) {
                    crom_err(CROM_EUSAGE, "unknown or misplaced option '-%c' in '%s'", c[1], a);
                    usage_exit(cli);
                }
            }
            if (o->arg && a[2])
                val = a + 2;
        }
        if (o->arg && !val) {
            if (i + 1 >= sv.n) {
                crom_err(CROM_EUSAGE, "option '--%s' needs a value (%s)", o->name, o->arg);
                usage_exit(cli);
            }
            val = sv.v[++i];
        }
        if (is_common(o))
            rc = common_option(cli, o, val);
        else
            rc = fn(ctx, o->key, val);
        if (rc)
            usage_exit(cli);
    }
    int nt = cli->threads;
#ifdef _OPENMP
    if (nt == 0)
        nt = omp_get_num_procs();
    omp_set_num_threads(nt);
#endif
    /* BLAS stays single-threaded: our own loops own the threads (TOOLCHAIN.md). */
    openblas_set_num_threads(1);
    cli->threads = nt;
}

int crom_cli_exit(crom_cli *cli, int rc)
{
    if (rc) {
        const char *m = crom_errmsg();
        fprintf(stderr, "%s: %s\n", cli->prog, *m ? m : "failed");
        fflush(stdout); /* the first error is the one to report */
    } else {
        rc = stdout_status(cli->prog);
    }
    for (int i = 0; i < cli->nexpanded; i++)
        free(cli->expanded[i]);
    free(cli->expanded);
    free(cli->cmdline);
    cli->expanded = NULL;
    cli->cmdline = NULL;
    return rc;
}

/* ----------------------------------------------------------------- progress */

void crom_cli_progress_start(crom_cli_progress *p, const crom_cli *cli,
                             const char *label, long total)
{
    p->active = !cli->quiet && isatty(2);
    p->label = label;
    p->total = total;
    p->t0 = crom_clock_now();
    p->last = 0;
}

void crom_cli_progress_update(crom_cli_progress *p, long done, const char *extra)
{
    if (!p->active)
        return;
    double t = crom_clock_now();
    if (t - p->last < 0.2 && done < p->total)
        return;
    p->last = t;
    double el = t - p->t0, rate = done > 0 ? done / el : 0;
    double left = (rate > 0 && p->total > done) ? (p->total - done) / rate : 0;
    int width = 24, fill = p->total > 0 ? (int)(width * (double)done / (double)p->total) : 0;
    if (fill > width)
        fill = width;
    char bar[32];
    for (int i = 0; i < width; i++)
        bar[i] = i < fill ? '#' : '.';
    bar[width] = 0;
    fprintf(stderr, "\r%s [%s] %ld/%ld  %.3g/s  %.0fs left%s%s\033[K", p->label,
            bar, done, p->total, rate, left, extra ? "  " : "", extra ? extra : "");
    fflush(stderr);
}

void crom_cli_progress_end(crom_cli_progress *p)
{
    if (!p->active)
        return;
    fprintf(stderr, "\r\033[K");
    fflush(stderr);
}
