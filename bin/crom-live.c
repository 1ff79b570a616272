/* crom-live — a reduced run steered while it runs (LiCROM's interactive
 * application): the implicit Euler step of crom-reducedstep on a cubature,
 * paced by the wall clock, reading one command per line (drag, release,
 * force, pin, unpin, schedule, step, quit; lib/rom/live.h) from stdin or a
 * FIFO between its steps, and writing every step's frame as it is made. */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <poll.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "base/array.h"
#include "base/clock.h"
#include "base/err.h"
#include "base/parse.h"
#include "cli/cli.h"
#include "io/io.h"
#include "phys/scenario.h"
#include "rom/cubature.h"
#include "rom/live.h"
#include "rom/rsim.h"

enum { O_CUB = 300, O_CMDS, O_NOCLOCK, O_DRAGK, O_KAPPA, O_STREAM, O_HDF5 };

static const crom_opt live_opts[] = {
    {"cubature", O_CUB, "CUB", "The crom/cubature to simulate on (required): its mesh, regions and cached W, as crom-reducedstep --cubature."},
    {"commands", O_CMDS, "FILE", "Read the commands from FILE, a file or a FIFO (default: stdin). The end of the input ends the run, after the steps it asked for."},
    {"no-clock", O_NOCLOCK, NULL, "Do not pace the steps by the wall clock: take steps only when a command 'step N' asks (a scripted run, as fast as it computes). The same commands give the same trajectory with and without the clock."},
    {"drag-stiffness", O_DRAGK, "K", "Default stiffness of a drag's spring in N/m (default: 10 m g / L, m the body's mass and L its size: a tenth of the size stretches it by the body's weight)."},
    {"bc-stiffness", O_KAPPA, "K", "Penalty rate of pinned regions in 1/s^2 (default 1e4/dt^2), as crom-reducedstep."},
    {"output", 'o', "OUT", "Write the frames to OUT (default stdout: a frame stream into a pipe)."},
    {"stream", O_STREAM, NULL, "Write a frame stream even to a file."},
    {"hdf5", O_HDF5, NULL, "Write HDF5 even into a pipe."},
    {NULL, 0, NULL, NULL}};

static const crom_cli_optgroup groups[] = {
    {"Scenario options (the same in crom-fullsim)", crom_scenario_opts},
    {"Live run options", live_opts},
    {NULL, NULL}};

static const crom_cli_doc doc = {
    "crom-live",
    "a reduced run steered by commands while it runs",
    "crom-live --cubature CUB [scenario options] [--commands FILE] [--no-clock] [-o OUT]",
    "Steps the reduced simulation of crom-reducedstep --cubature (the same scenario flags, the same "
    "implicit Euler step) at the scenario's --dt of wall-clock time per step, and between steps "
    "reads commands, one per line:\n\n"
    "  drag REF X,Y,Z [K]    pull REF toward the point (m) with a spring of stiffness K N/m, spread "
    "over REF by mass and implicit in the step; again to move the point\n"
    "  release [REF]         end the drag of REF (default: every drag)\n"
    "  force REF FX,FY,FZ    a total force (N) on REF from the next step on; 0,0,0 ends it\n"
    "  pin REF / unpin REF   hold REF at rest / let it go\n"
    "  schedule CUB          switch to another cubature of the same model (a cut, punched or swapped "
    "mesh), the state kept\n"
    "  condition NAME=VALUE  a conditional model's parameter (no model is conditional yet)\n"
    "  step N                let N steps pass before the next command is read\n"
    "  quit                  end the run\n\n"
    "REF is a region of the cubature's mesh, a predicate such as 'x>0.4', or one vertex '#N'. A bad "
    "command gets one line on stderr ('crom-live: line L: ...') and changes nothing; the run goes on. "
    "The end of the input ends the run after the steps it asked for; so do Ctrl-C (SIGINT) and SIGTERM, "
    "the output complete.\n\n"
    "A force given at time t acts from the next step on, as crom-reducedstep --force 'REF=F@T0:' "
    "with T0 = t + dt/2 does: a script of force and step commands run with --no-clock gives "
    "that run's trajectory to round-off.\n\n"
    "The output is a crom/latent streamed frame by frame (one per step): q, qdot, energies, "
    "iterations, and wall_time, the wall-clock time at which the frame was written, against time, "
    "the simulated time it stands for; a step that ends later than its simulated time (it took "
    "longer than dt) has late = 1, and the run says so once on stderr and counts them at the end; "
    "commands counts the command lines read before the frame's step (applied or refused), so that "
    "a frame with commands >= N is the first to show the N-th command (crom-view(1) times a page's "
    "drag to its frame so).",
    groups,
    "mkfifo cmds; crom-live --cubature cub.h5 --pin bottom --commands cmds | crom-export --model m.h5 --mesh mesh.h5 -o live.pvd\n"
    "printf 'force top 0,-20,0\\nstep 50\\ndrag #120 0.3,0.6,0 400\\nstep 50\\n' | crom-live --cubature cub.h5 --pin bottom --no-clock -o run.h5",
    "crom-reducedstep(1), crom-cubature(1), crom-export(1), crom-view(1)"};

typedef struct {
    crom_scenario sc;
    const char *cub, *cmds, *out;
    int kind, noclock, steps_given;
    double dragk, kappa;
} args;

static int on_opt(void *ctx, int key, const char *v)
{
    args *a = ctx;
    const char *sname = crom_scenario_opt_name(key);
    if (sname && !strcmp(sname, "steps"))
        a->steps_given = 1;
    int rc = crom_scenario_option(&a->sc, key, v);
    if (rc >= 0)
        return rc;
    switch (key) {
    case 0: return crom_err(CROM_EUSAGE, "unexpected operand '%s' (the mesh comes with --cubature)", v);
    case 'o': a->out = v; return 0;
    case O_CUB: a->cub = v; return 0;
    case O_CMDS: a->cmds = v; return 0;
    case O_NOCLOCK: a->noclock = 1; return 0;
    case O_DRAGK: return crom_parse_positive(v, "--drag-stiffness", &a->dragk);
    case O_KAPPA: return crom_parse_positive(v, "--bc-stiffness", &a->kappa);
    case O_STREAM: a->kind = CROM_OUT_SERIES_STREAM; return 0;
    case O_HDF5: a->kind = CROM_OUT_SERIES_H5; return 0;
    }
    return crom_err(CROM_EINTERNAL, "unhandled option");
}

/* Commands come in through a line buffer over a file descriptor, read
 * without blocking when the clock paces the run. */
typedef struct {
    int fd, eof;
    char buf[4096];
    size_t len;
    long line;
} input;

/* The next complete line into out (NUL-terminated, newline dropped), 1; 0
 * when none is buffered. A line longer than the buffer is cut into pieces
 * (each then a bad command). At the end of the input a last unterminated
 * line counts. */
static int next_line(input *in, char *out, size_t cap)
{
    char *nl = memchr(in->buf, '\n', in->len);
    size_t n = nl ? (size_t)(nl - in->buf) : in->len;
    if (!nl && !(in->eof && in->len) && in->len < sizeof in->buf)
        return 0;
    if (n >= cap)
        n = cap - 1;
    memcpy(out, in->buf, n);
    out[n] = 0;
    size_t used = nl && nl - in->buf == (ptrdiff_t)n ? n + 1 : n;
    memmove(in->buf, in->buf + used, in->len - used);
    in->len -= used;
    in->line++;
    return 1;
}

/* Read what is there (wait at most timeout seconds; < 0: block). Returns 0
 * or CROM_EIO. */
static int fill(input *in, double timeout)
{
    if (in->eof || in->len == sizeof in->buf)
        return 0;
    struct pollfd p = {in->fd, POLLIN, 0};
    int ms = timeout < 0 ? -1 : (int)ceil(timeout * 1e3);
    int k = poll(&p, 1, ms);
    if (k < 0)
        return errno == EINTR ? 0 : crom_err(CROM_EIO, "commands: %s", strerror(errno));
    if (k == 0)
        return 0;
    ssize_t r = read(in->fd, in->buf + in->len, sizeof in->buf - in->len);
    if (r < 0)
        return errno == EINTR || errno == EAGAIN ? 0 : crom_err(CROM_EIO, "commands: %s", strerror(errno));
    if (r == 0)
        in->eof = 1;
    in->len += (size_t)r;
    return 0;
}

/* a growing list of durations (s) */
typedef struct {
    double *v;
    size_t n, cap;
} times;

static int times_push(times *t, double x)
{
    int rc = crom_array_reserve((void **)&t->v, &t->cap, t->n + 1, sizeof *t->v);
    if (!rc)
        t->v[t->n++] = x;
    return rc;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* median (sorts the list) and largest; 0 for none */
static double times_median(times *t)
{
    if (!t->n)
        return 0;
    qsort(t->v, t->n, sizeof *t->v, cmp_double);
    return t->n % 2 ? t->v[t->n / 2] : 0.5 * (t->v[t->n / 2 - 1] + t->v[t->n / 2]);
}

static double times_max(const times *t)
{
    double m = 0;
    for (size_t i = 0; i < t->n; i++)
        m = t->v[i] > m ? t->v[i] : m;
    return m;
}

typedef struct {
    crom_out o;
    double t0;      /* monotonic clock at the start */
    int clock;      /* paced by the wall clock */
    long late, worst_step;
    long ncmd;      /* command lines read (applied or refused) */
    double worst_lag;
    double cmd_t;   /* when the oldest command not yet in a frame was applied (0: none) */
    times step_s, latency_s; /* every step's seconds; each command's time to its first frame */
} run_out;

static int put_frame(run_out *R, crom_live *L, const crom_rsim_stats *st)
{
    double K, E, W;
    int rc = crom_rsim_energies(&L->sim, &K, &E, &W);
    if (rc)
        return rc;
    double wall = crom_clock_now() - R->t0, lag = wall - L->sim.t;
    double late = R->clock && L->sim.step > 0 && lag > 0 ? 1 : 0; /* (without the clock: never) */
    double t = L->sim.t, step = (double)L->sim.step, tot = K + E + W, it = st->iterations, res = st->residual,
           cub = L->cur, secs = crom_clock_wall(st->seconds), w = crom_clock_wall(wall), ncmd = (double)R->ncmd;
    if (late) {
        R->late++;
        if (lag > R->worst_lag) {
            R->worst_lag = lag;
            R->worst_step = L->sim.step;
        }
    }
    const double *vals[] = {&t, &step, L->sim.q, L->sim.qd, &K, &E, &W, &tot, &it, &res, &cub, &secs, &w, &late, &ncmd};
    rc = crom_out_frame(&R->o, vals);
    if (!rc && L->sim.step > 0)
        rc = times_push(&R->step_s, st->seconds);
    if (!rc && R->cmd_t > 0) { /* from a command to the frame that first shows it */
        rc = times_push(&R->latency_s, crom_clock_now() - R->cmd_t);
        R->cmd_t = 0;
    }
    return rc;
}

static int start_output(run_out *R, const crom_cli *cli, const args *a, crom_live *L, const char *history)
{
    const crom_cubature *c = L->cubs[0];
    int rc = crom_out_create(&R->o, a->out, "crom/latent", 1, cli->cmdline, history, a->kind);
    if (rc)
        return rc;
    rc = crom_h5_set_str(R->o.h5, ".", "model_id", c->model_id);
    if (!rc)
        rc = crom_h5_set_i64(R->o.h5, ".", "rank", c->r);
    if (!rc)
        rc = crom_scenario_write_attrs(R->o.h5, &a->sc);
    if (!rc)
        rc = crom_h5_set_str(R->o.h5, ".", "solver", "newton");
    if (!rc)
        rc = crom_h5_set_str(R->o.h5, ".", "cubatures", a->cub);
    hsize_t dr = (hsize_t)c->r;
    static const struct {
        const char *name;
        int vec;
    } f[] = {{"time", 0}, {"step", 0}, {"q", 1}, {"qdot", 1}, {"kinetic_energy", 0}, {"elastic_energy", 0},
             {"external_energy", 0}, {"total_energy", 0}, {"iterations", 0}, {"residual", 0}, {"cubature", 0},
             {"step_seconds", 0}, {"wall_time", 0}, {"late", 0}, {"commands", 0}};
    for (size_t i = 0; i < sizeof f / sizeof *f && !rc; i++)
        rc = crom_out_field(&R->o, f[i].name, f[i].vec, &dr, NULL);
    if (!rc)
        rc = crom_out_begin(&R->o);
    if (rc)
        crom_out_fail(&R->o);
    return rc;
}

/* One command line: parsed and applied; a bad one is reported and the run
 * goes on. *pending gets the steps a 'step N' asks for, *quit a 'quit'. */
static void command(const crom_cli *cli, crom_live *L, run_out *R, const input *in, const char *line, long *pending,
                    int *quit)
{
    crom_live_cmd c;
    int rc = crom_live_parse(line, &c);
    if (rc || c.kind != CROM_LIVE_NONE)
        R->ncmd++;
    if (!rc && c.kind == CROM_LIVE_STEP)
        *pending += c.n;
    else if (!rc && c.kind == CROM_LIVE_QUIT)
        *quit = 1;
    else if (!rc && c.kind != CROM_LIVE_NONE)
        rc = crom_live_apply(L, &c);
    if (rc) {
        crom_cli_warn(cli, "line %ld: %s", in->line, crom_errmsg());
        crom_err_clear();
    } else if (c.kind != CROM_LIVE_NONE && c.kind != CROM_LIVE_STEP && c.kind != CROM_LIVE_QUIT) {
        if (!R->cmd_t)
            R->cmd_t = crom_clock_now();
        if (cli->verbose)
            crom_cli_info(cli, "t = %.4g s: %s", L->sim.t, line);
    }
}

/* Ctrl-C (SIGINT) or SIGTERM ends the run as 'quit' does: the frame
 * stream gets its end record; a second one ends the process at once. */
static volatile sig_atomic_t stop_asked;

static void on_stop(int sig)
{
    (void)sig;
    stop_asked = 1;
}

static int run(crom_cli *cli, args *a)
{
    crom_cubature cub;
    char *history = NULL;
    int rc = crom_cubature_load(a->cub, &cub, &history);
    if (rc)
        return rc;
    crom_live *L = crom_malloc(sizeof *L); /* (the simulation keeps the address of L->sc) */
    input in = {0};
    in.fd = 0;
    if (!L) {
        rc = CROM_EINTERNAL;
        goto out_cub;
    }
    if ((rc = crom_live_init(L, &cub, &a->sc, CROM_RSIM_NEWTON, a->kappa, a->dragk))) {
        free(L);
        L = NULL;
        goto out_cub;
    }
    if (a->cmds && strcmp(a->cmds, "-") && (in.fd = open(a->cmds, O_RDONLY | O_CLOEXEC)) < 0) {
        rc = crom_err(CROM_ENOINPUT, "%s: %s", a->cmds, strerror(errno));
        goto out;
    }
    run_out R;
    memset(&R, 0, sizeof R);
    if ((rc = start_output(&R, cli, a, L, history)))
        goto out;
    crom_rsim_stats st = {0, 0, 0, 0, 1, 0};
    R.t0 = crom_clock_now();
    R.clock = !a->noclock;
    rc = put_frame(&R, L, &st);
    long pending = 0, max = a->steps_given ? a->sc.steps : -1;
    int quit = 0;
    char line[sizeof in.buf];
    double h = a->sc.dt;
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_stop;
    sa.sa_flags = (int)SA_RESETHAND;
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    while (!rc && !quit && !stop_asked && (max < 0 || L->sim.step < max)) {
        /* commands until a step is due: with the clock, when the wall clock
         * reaches the simulated time of the state; without, when asked */
        while (!rc && !quit && !pending && !stop_asked) {
            if (!in.eof && !memchr(in.buf, '\n', in.len) && (rc = fill(&in, 0))) /* what has come */
                break;
            while (!quit && !pending && next_line(&in, line, sizeof line))
                command(cli, L, &R, &in, line, &pending, &quit);
            if (quit || pending)
                break;
            if (in.eof) {
                quit = 1; /* the end of the input: the steps asked for are done */
                break;
            }
            double wait = a->noclock ? -1 : L->sim.t - (crom_clock_now() - R.t0);
            if (!a->noclock && wait <= 0)
                break;
            rc = fill(&in, wait);
        }
        if (rc || quit || stop_asked)
            break;
        if (!a->noclock && pending) { /* 'step N' with the clock: wait for the step's time */
            double wait = L->sim.t - (crom_clock_now() - R.t0);
            if (wait > 0)
                usleep((useconds_t)(wait * 1e6));
        }
        if ((rc = crom_rsim_step(&L->sim, &st)))
            break;
        if (pending)
            pending--;
        if ((rc = put_frame(&R, L, &st)))
            break;
        if (R.late == 1 && R.worst_step == L->sim.step)
            crom_cli_warn(cli, "step %ld ended %.3g s after its simulated time: steps take longer than --dt %g s "
                          "(frames keep their simulated time; wall_time and late say when they were written)",
                          L->sim.step, R.worst_lag, h);
    }
    rc = crom_out_finish_run(&R.o, NULL, rc);
    if (!rc && R.late)
        crom_cli_info(cli, "%ld of %ld steps ended after their simulated time (worst %.3g s late, step %ld)", R.late,
                      L->sim.step, R.worst_lag, R.worst_step);
    if (!rc) {
        double med = times_median(&R.step_s);
        crom_cli_info(cli, "%ld steps, %.4g s simulated; a step %.3g ms (median; %.0f steps/s)", L->sim.step,
                      L->sim.t, 1e3 * med, med > 0 ? 1 / med : 0.0);
    }
    if (!rc && R.latency_s.n)
        crom_cli_info(cli, "from a command to the frame that shows it: %.3g ms (median of %zu), at most %.3g ms",
                      1e3 * times_median(&R.latency_s), R.latency_s.n, 1e3 * times_max(&R.latency_s));
    free(R.step_s.v);
    free(R.latency_s.v);
out:
    if (in.fd > 0)
        close(in.fd);
    crom_live_free(L);
    free(L);
out_cub:
    crom_cubature_free(&cub);
    free(history);
    return rc;
}

int main(int argc, char **argv)
{
    crom_cli cli;
    args a;
    memset(&a, 0, sizeof a);
    crom_scenario_defaults(&a.sc);
    a.kind = CROM_OUT_SERIES;
    crom_cli_parse(&cli, &doc, argc, argv, on_opt, &a);
    if (!a.cub)
        return crom_cli_exit(&cli, crom_err(CROM_EUSAGE, "--cubature CUB is required (see crom-live --help)"));
    return crom_cli_exit(&cli, run(&cli, &a));
}
