/* crom-reducedstep — simulate in a model's latent space: implicit Euler over q
 * with cubature (LiCROM §4–5), the same scenario as crom-fullsim, on any mesh,
 * switching meshes mid-run without touching the state; or over the latent z
 * of a nonlinear one-mesh map (data-free subspaces) with Gauss–Newton. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "cli/cli.h"
#include "io/io.h"
#include "mesh/mesh.h"
#include "phys/scenario.h"
#include "rom/condsched.h"
#include "rom/cubature.h"
#include "rom/indicator.h"
#include "rom/map.h"
#include "rom/model.h"
#include "rom/nlsim.h"
#include "rom/result.h"
#include "rom/rsim.h"
#include "rom/schedule.h"

enum { O_CUB = 300, O_INIT, O_SCHED, O_SOLVER, O_KAPPA, O_STATS, O_STREAM, O_HDF5, O_INITFRAME, O_BCTHR,
       O_MODEL, O_MESH, O_IND, O_INDMESH, O_INDMODEL, O_WARN, O_COND, O_FRAME };

static const crom_opt red_opts[] = {
    {"cubature", O_CUB, "CUB", "The crom/cubature to integrate over (this or --model is required): its mesh, regions and cached W. With --model: a cubature crom-cubature made for that map, whose tets replace every tet in the elastic energy."},
    {"model", O_MODEL, "MODEL", "Simulate in the subspace of a model of ONE mesh instead of a cubature: a data-free map (energy, neuralmodes: the mesh is in the model) or a linear basis laid on its mesh (pod, modes; an mlp field needs --mesh). Implicit Euler over the latent with Gauss-Newton on the full-space incremental potential, the elastic energy summed over every tet of the mesh, or over the tets of --cubature. q in the output is the map's latent z."},
    {"condition", O_COND, "NAME=VALUE[@T]", "With --model of a conditional map (crom-fitfield --condition): run it at this value of its condition NAME (ratio:REGION, gravity:AXIS or pin:REGION:AXIS; the scenario takes it too: the region's modulus, the gravity; a pin moves the map's start, and the pin's target, with its region), from time T on (default 0: from the start; repeatable: a schedule of changes). Conditions not given run at the middle of their trained range. q carries over a change; the decoded shape moves to the map at the new value."},
    {"rigid-frame", O_FRAME, NULL, "With --model: add six rigid degrees of freedom to the model's subspace, x = R(θ) x_model(q) + t (Wang et al. §5: the puppet's 5 neural modes + 6 rigid DoFs), so that a body whose model was made with a region held can move and turn freely. q in the output is [q | θ | t]: three Euler angles (rad, R = Rz Ry Rx about the mesh's origin) and a translation (m); the file records rigid_frame = 1 and crom-export and crom-diff decode it the same way. A cubature of the model serves the frame too (the elastic energy does not change under a rigid motion)."},
    {"mesh", O_MESH, "MESH", "With --model: the mesh whose regions resolve --pin, --velocity and --force (it must have the model's vertices; default: the model's own mesh and regions), or the mesh to lay an mlp field on."},
    {"init", O_INIT, "LATENT", "Start from a frame of a crom/latent (crom-encode of a full state, or an earlier run): its q and qdot (default: rest)."},
    {"init-frame", O_INITFRAME, "K", "Which frame of --init (default -1, the last)."},
    {"schedule", O_SCHED, "FILE", "Switch cubatures during the run: lines 'STEP CUBATURE' (# comments), steps increasing; before step STEP the cubature changes, q and qdot carry over unchanged (LiCROM §4)."},
    {"solver", O_SOLVER, "NAME", "newton (default: exact reduced Hessian, converged to --tol; with --model: Gauss-Newton with the map's Jacobian) or gd (LiCROM §5 descent, --max-iter iterations per step; cubatures only)."},
    {"bc-stiffness", O_KAPPA, "K", "Penalty rate of pinned and prescribed regions in 1/s^2 (default 1e4/dt^2)."},
    {"bc-threshold", O_BCTHR, "T", "The penalty acts on the latent directions that move the boundary-condition vertices: those carrying at least T times the BC regions' mass fraction of their motion (default 0.1; 0 = every direction). A learned basis is only nearly zero where its training data was pinned; penalizing every direction would freeze the body. (Cubatures only: with --model the penalty acts on the vertices themselves; a data-free map holds its training pins by construction.)"},
    {"indicator", O_IND, NULL, "Measure every stored frame with an a-posteriori error indicator that needs no full simulation: the reduced state is decoded onto a mesh of the body, the full-space residual g of its implicit Euler step is taken there (zero at the full step's solution), and the displacement it stands for, e = K0^-1 g with K0 the stiffness at rest (factored once), estimates the state's error. Stored per frame: `indicator` = |e|_M / |u|_M, `error_estimate` = the RMS of e (m), `bc_error` = the largest miss of a pinned or prescribed vertex (m); the root attribute `initial_error` holds the initial state's RMS distance from rest and from the initial velocity field. At the end one line gives sqrt(sum |e|^2 / sum |u|^2) over the frames, the measure of crom-diff. Costs a factorization of the mesh and a solve per stored frame. With --model: on the map's mesh. With --cubature: decoded by --indicator-model on the cubature's mesh (the mesh of each schedule entry in turn), or on --indicator-mesh. --stats gets the columns error_estimate and displacement_rms (m) per stored step."},
    {"indicator-mesh", O_INDMESH, "MESH", "--indicator with --cubature: measure on this mesh of the body for the whole run (any mesh with the scenario's regions, e.g. a finer one) instead of the cubature's."},
    {"indicator-model", O_INDMODEL, "MODEL", "--indicator with --cubature: the crom/model of the cubature (its model_id must match), laid on the mesh measured."},
    {"warn-above", O_WARN, "T", "With --indicator: print one warning line when the run's indicator (over all stored frames) exceeds T (default 0.2; 0 = never): the subspace is out of its depth. It reads about the true error where the motion is quasi-static, and 2-6 times it where inertia matters (README)."},
    {"stats", O_STATS, "CSV", "Write one line per step: iterations, residual, constraint residual, seconds, cubature tets, and vertex_evals, the vertex positions one evaluation of the step decodes (4 per cubature tet, plus every surface vertex per collision plane): the per-step work, which does not grow with the mesh but for collisions."},
    {"output", 'o', "OUT", "Write the latent trajectory to OUT (default stdout: a frame stream into a pipe)."},
    {"stream", O_STREAM, NULL, "Write a frame stream even to a file."},
    {"hdf5", O_HDF5, NULL, "Write HDF5 even into a pipe."},
    {NULL, 0, NULL, NULL}};

static const crom_cli_optgroup groups[] = {
    {"Scenario options (the same in crom-fullsim)", crom_scenario_opts},
    {"Reduced simulation options", red_opts},
    {NULL, NULL}};

static const crom_cli_doc doc = {
    "crom-reducedstep",
    "implicit Euler in a model's latent space, on any mesh, across mesh changes",
    "crom-reducedstep --cubature CUB [scenario options] [--init LATENT] [--schedule FILE]\n"
    "                 [--solver newton|gd] [-o OUT]\n"
    "crom-reducedstep --model MODEL [--mesh MESH] [scenario options] [--init LATENT] [-o OUT]",
    "Each step minimizes LiCROM's eq. 5 over the latent coordinates q: the kinetic term with the "
    "exact reduced mass W^T M W, the elastic energy summed over the cubature tets (eq. 8), gravity "
    "and scheduled forces projected onto the basis, pinned and prescribed-velocity regions as a "
    "stiff penalty (their largest miss is reported per frame as constraint_residual), and the "
    "frictional collision planes at every boundary vertex. The scenario flags are those of "
    "crom-fullsim, parsed by the same code; regions resolve against the cubature's mesh.\n\n"
    "--solver newton uses the exact reduced gradient and Hessian W^T H W (LiCROM §7) and stops "
    "when the correction's RMS displacement is below --tol of the body size; --solver gd is the "
    "paper's projected gradient descent.\n\n"
    "The output is a crom/latent: q, qdot, energies, iterations, residuals and the schedule entry "
    "per frame, streamed frame by frame. Decode it on any mesh with crom-export --model, compare "
    "with a full run using crom-diff.\n\n"
    "--model MODEL simulates in a subspace of one mesh given as a map x(z): the data-free maps of "
    "crom-fitfield --objective energy|neuralmodes (nonlinear), or a linear basis on its mesh. Each "
    "step minimizes the full-space incremental potential over z (Sharp et al. eq. 6): inertia "
    "1/(2h^2)|x(z) - x_n - h v_n|_M^2 with the full-space velocity, the elastic energy of every tet "
    "(or of the tets of --cubature, made by crom-cubature --model for this map), "
    "gravity and forces, pinned and prescribed regions as a stiff mass-weighted penalty, and the "
    "collision planes at the boundary vertices. Gauss-Newton with the map's exact Jacobian J (the "
    "network is evaluated in double precision) and line search; converged when the correction's "
    "RMS displacement is below --tol of the size. Positions are linear in the map's features "
    "(x = X + B a(z)), so the quadratic terms cost p x p per iteration, independent of the mesh. "
    "For a linear basis this is the same step as "
    "--cubature with --scheme all. The output's q is the latent z and kinetic_energy is that of the "
    "full-space velocity; crom-export and crom-diff decode it with --model (on the model's own mesh).",
    groups,
    "crom-reducedstep --cubature cub.h5 --velocity 'top=0,-2,0@0:0.1' --pin bottom --gravity 0,0,0 \\\n"
    "    --dt 0.01 --steps 40 -o latent.h5\n"
    "crom-reducedstep --cubature cut0.h5 --schedule cuts.txt @plate.flags -o tear.h5\n"
    "crom-reducedstep --model df.h5 --pin clamp --youngs 1e6 --dt 0.01 --steps 100 -o df_run.h5\n"
    "crom-reducedstep --model df.h5 --cubature df_cub.h5 --pin clamp --youngs 1e6 --steps 100 -o df_run.h5",
    "crom-cubature(1), crom-encode(1), crom-fullsim(1), crom-fitfield(1), crom-diff(1), crom-export(1)"};

typedef struct {
    crom_scenario sc;
    const char *cub, *init, *sched, *out, *stats, *model, *mesh, *ind_mesh, *ind_model;
    long init_frame;
    int solver, kind, bcthr_given, threads, indicator, frame;
    double kappa, bc_threshold, warn_above;
    crom_condsched cs;        /* --condition NAME=VALUE[@T], in the order given */
} args;

static int on_opt(void *ctx, int key, const char *v)
{
    args *a = ctx;
    int rc = crom_scenario_option(&a->sc, key, v);
    if (rc >= 0)
        return rc;
    switch (key) {
    case 0: return crom_err(CROM_EUSAGE, "unexpected operand '%s' (the mesh comes with --cubature or --model)", v);
    case 'o': a->out = v; return 0;
    case O_CUB: a->cub = v; return 0;
    case O_MODEL: a->model = v; return 0;
    case O_MESH: a->mesh = v; return 0;
    case O_INIT: a->init = v; return 0;
    case O_INITFRAME: return crom_parse_int(v, "--init-frame", -1000000000L, 1000000000L, &a->init_frame);
    case O_SCHED: a->sched = v; return 0;
    case O_SOLVER:
        if (!strcmp(v, "newton"))
            a->solver = CROM_RSIM_NEWTON;
        else if (!strcmp(v, "gd"))
            a->solver = CROM_RSIM_GD;
        else
            return crom_err(CROM_EUSAGE, "--solver: '%s' is not newton or gd", v);
        return 0;
    case O_KAPPA: return crom_parse_positive(v, "--bc-stiffness", &a->kappa);
    case O_BCTHR:
        a->bcthr_given = 1;
        if (crom_parse_double(v, "--bc-threshold", &a->bc_threshold) || a->bc_threshold < 0)
            return crom_err(CROM_EUSAGE, "--bc-threshold must be a number >= 0, got %s", v);
        return 0;
    case O_COND: return crom_condsched_add(&a->cs, "--condition", v);
    case O_STATS: a->stats = v; return 0;
    case O_IND: a->indicator = 1; return 0;
    case O_INDMESH: a->ind_mesh = v; return 0;
    case O_INDMODEL: a->ind_model = v; return 0;
    case O_WARN:
        if (crom_parse_double(v, "--warn-above", &a->warn_above) || !(a->warn_above >= 0))
            return crom_err(CROM_EUSAGE, "--warn-above must be a number >= 0, got %s", v);
        return 0;
    case O_FRAME: a->frame = 1; return 0;
    case O_STREAM: a->kind = CROM_OUT_SERIES_STREAM; return 0;
    case O_HDF5: a->kind = CROM_OUT_SERIES_H5; return 0;
    }
    return crom_err(CROM_EINTERNAL, "unhandled option");
}

static int read_init(const args *a, const char *model_id, int r, double *q, double *qd)
{
    crom_in in;
    int rc = crom_in_open(&in, a->init);
    if (rc)
        return rc;
    char *id = NULL;
    if ((rc = crom_in_expect(&in, "crom/latent", 1)))
        goto out;
    if ((rc = crom_h5_get_str(in.h5, ".", "model_id", &id))) {
        crom_err_ctx("%s", in.name);
        goto out;
    }
    if (strcmp(id, model_id)) {
        rc = crom_err(CROM_EDATA, "--init %s is a state of model %s, the cubature's model is %s", in.name, id, model_id);
        goto out;
    }
    int fq = crom_in_field(&in, "q"), fqd = crom_in_field(&in, "qdot");
    crom_err_clear();
    if (fq < 0 || (int)in.fields[fq].count != r) {
        rc = crom_err(CROM_EDATA, "--init %s: no q of rank %d", in.name, r);
        goto out;
    }
    double *all;
    long n;
    if ((rc = crom_in_read_all(&in, &all, &n)))
        goto out;
    long k = a->init_frame < 0 ? n + a->init_frame : a->init_frame;
    if (k < 0 || k >= n) {
        free(all);
        rc = crom_err(CROM_EUSAGE, "--init-frame %ld: %s has %ld frames", a->init_frame, in.name, n);
        goto out;
    }
    if ((rc = crom_result_check_frame(&in, all + (size_t)k * in.frame_len, k))) {
        free(all);
        goto out;
    }
    memcpy(q, all + (size_t)k * in.frame_len + in.fields[fq].offset, sizeof(double) * (size_t)r);
    if (fqd >= 0 && (int)in.fields[fqd].count == r)
        memcpy(qd, all + (size_t)k * in.frame_len + in.fields[fqd].offset, sizeof(double) * (size_t)r);
    free(all);
out:
    free(id);
    crom_in_close(&in);
    return rc;
}

/* The indicator of a run (--indicator): its measure, and the state before
 * the step being measured. */
typedef struct {
    int on, have_model;
    crom_indicator ind;
    crom_model model;         /* a run over cubatures: the basis, laid on each mesh */
    crom_mesh mesh;           /* --indicator-mesh */
    double *prev, *prevdot;   /* positions and velocities, or q and qdot */
    double rel;               /* the last frame's indicator, ind.err / ind.urms (its other measures: in ind) */
    double initial[2];        /* the initial state's RMS distance from rest (m) and its velocity's (m/s) */
} indicator;

/* One frame; cond (NULL: none) the conditional map's condition, stored
 * after the indicator's fields (start_output's order). */
static int put_values(crom_out *o, double t, long nstep, const double *q, const double *qd, double K, double E,
                      double W, const crom_rsim_stats *st, int entry, const indicator *ind, const double *cond)
{
    double step = (double)nstep, tot = K + E + W, it = st->iterations, res = st->residual,
           cres = st->constraint_residual, cub = entry, secs = crom_clock_wall(st->seconds);
    const double *vals[17] = {&t, &step, q, qd, &K, &E, &W, &tot, &it, &res, &cres, &cub, &secs};
    int k = 13;
    if (ind->on) {
        vals[k++] = &ind->rel;
        vals[k++] = &ind->ind.err;
        vals[k++] = &ind->ind.bc;
    }
    vals[k] = cond;
    return crom_out_frame(o, vals);
}

/* Start the indicator: on mesh, the map's own (model_id NULL), or for a
 * run over cubatures of model model_id and rank r on --indicator-mesh or
 * else on mesh, the cubature's, with --indicator-model laid on it. The
 * initial state (x0, v0, or q0, qd0) is measured at once. */
static int indicator_start(indicator *I, const args *a, const crom_mesh *mesh, const char *model_id, int r,
                           const double *x0, const double *v0)
{
    int rc = 0;
    if (model_id) {
        if (!a->ind_model)
            return crom_err(CROM_EUSAGE, "--indicator with --cubature needs --indicator-model MODEL (the "
                            "cubature's model) to decode the state with");
        if ((rc = crom_model_load(a->ind_model, &I->model)))
            return rc;
        I->have_model = 1;
        if (strcmp(I->model.model_id, model_id) || I->model.rank != r)
            return crom_err(CROM_EUSAGE, "--indicator-model %s (model %s, rank %d) is not the cubature's model "
                            "(%s, rank %d)", a->ind_model, I->model.model_id, I->model.rank, model_id, r);
        if (a->ind_mesh) {
            if ((rc = crom_mesh_load(a->ind_mesh, CROM_MESH_CARRIERS | CROM_MESH_SURFACES, &I->mesh, NULL)))
                return rc;
            mesh = &I->mesh;
        }
    }
    if ((rc = crom_indicator_init(&I->ind, mesh, &a->sc, I->have_model ? &I->model : NULL)))
        return rc;
    I->on = 1;
    size_t n = I->have_model ? (size_t)r : 3 * (size_t)mesh->nv;
    I->prev = crom_malloc(sizeof(double) * n);
    I->prevdot = crom_malloc(sizeof(double) * n);
    if (!I->prev || !I->prevdot)
        return CROM_EINTERNAL;
    crom_indicator_initial(&I->ind, x0, v0, &I->initial[0], &I->initial[1]);
    return 0;
}

/* A schedule switched the run to the cubature of mesh: measure there from
 * now on (unless --indicator-mesh fixed the mesh). */
static int indicator_switch(indicator *I, const args *a, const crom_mesh *mesh)
{
    if (!I->on || a->ind_mesh)
        return 0;
    int rc = crom_indicator_remesh(&I->ind, mesh, &a->sc, &I->model);
    I->on = rc == 0;
    return rc;
}

/* Measure the step that ended at t in state now (after save(prev) before it). */
static int indicator_measure(indicator *I, double t, const double *now)
{
    double err, urms, bc; /* also kept in I->ind */
    int rc = crom_indicator_step(&I->ind, t, I->prev, I->prevdot, now, &err, &urms, &bc);
    if (rc)
        return rc;
    I->rel = urms > 0 ? err / urms : 0;
    return 0;
}

/* One line of --stats: the step, and with --indicator the error estimate
 * and the displacement RMS of a stored step (empty fields otherwise). */
static void indicator_csv(crom_fileout *csv, const indicator *I, int stored, int k, const crom_rsim_stats *st,
                          int ncub)
{
    fprintf(csv->f, "%d,%d,%.3e,%.3e,%.6e,%d,%d", k, st->iterations, st->residual, st->constraint_residual,
            st->seconds, ncub, st->vertex_evals);
    if (I->on && stored)
        fprintf(csv->f, ",%.6e,%.6e", I->ind.err, I->ind.urms);
    else if (I->on)
        fputs(",,", csv->f);
    fputc('\n', csv->f);
}

static void indicator_end(crom_cli *cli, const args *a, const indicator *I)
{
    if (!I->on)
        return;
    double total = crom_indicator_total(&I->ind);
    crom_cli_info(cli, "error indicator %.4g (estimated relative displacement error; worst frame %.3g at t = %g s)",
                  total, I->ind.worst, I->ind.at);
    if (a->warn_above > 0 && total > a->warn_above)
        crom_cli_warn(cli, "the subspace is out of its depth: error indicator %.3g > --warn-above %g (worst frame "
                      "at t = %g s)", total, a->warn_above, I->ind.at);
}

static void indicator_free(indicator *I)
{
    if (I->on)
        crom_indicator_free(&I->ind);
    if (I->have_model)
        crom_model_free(&I->model);
    crom_mesh_free(&I->mesh);
    free(I->prev);
    free(I->prevdot);
}

static int put_frame(crom_out *o, crom_rsim *s, const crom_rsim_stats *st, int entry, const indicator *ind)
{
    double K, E, W;
    int rc = crom_rsim_energies(s, &K, &E, &W);
    if (rc)
        return rc;
    return put_values(o, s->t, s->step, s->q, s->qd, K, E, W, st, entry, ind, NULL);
}

/* The latent output's attributes and frame fields (kind: the model's basis,
 * NULL for a run over cubatures; units and descriptions are lib/io/schema.c's). */
static int start_output(crom_out *o, const args *a, const char *model_id, int r, const char *solver,
                        const char *kind, const indicator *ind, int ncond)
{
    int rc = crom_h5_set_str(o->h5, ".", "model_id", model_id);
    if (!rc && ind->on)
        rc = crom_h5_set_f64(o->h5, ".", "initial_error", ind->initial, 2);
    if (!rc)
        rc = crom_h5_set_i64(o->h5, ".", "rank", r);
    if (!rc && a->frame) /* --rigid-frame: q = [q' | θ | t] */
        rc = crom_h5_set_i64(o->h5, ".", "rigid_frame", 1);
    if (!rc)
        rc = crom_scenario_write_attrs(o->h5, &a->sc);
    if (!rc)
        rc = crom_h5_set_str(o->h5, ".", "solver", solver);
    hsize_t dr = (hsize_t)r;
    static const struct {
        const char *name;
        int vec;
    } f[] = {{"time", 0}, {"step", 0}, {"q", 1}, {"qdot", 1}, {"kinetic_energy", 0}, {"elastic_energy", 0},
             {"external_energy", 0}, {"total_energy", 0}, {"iterations", 0}, {"residual", 0},
             {"constraint_residual", 0}, {"cubature", 0}, {"step_seconds", 0}, {"indicator", 0}, {"error_estimate", 0},
             {"bc_error", 0}};
    size_t nf = sizeof f / sizeof *f - (ind->on ? 0 : 3);
    for (size_t i = 0; i < nf && !rc; i++)
        rc = crom_out_field(o, f[i].name, f[i].vec, &dr, kind);
    hsize_t dc = (hsize_t)ncond;
    if (!rc && ncond)
        rc = crom_out_field(o, "condition", 1, &dc, kind);
    if (!rc)
        rc = crom_out_begin(o);
    return rc;
}

/* A run in the subspace of a one-mesh model (--model): Gauss–Newton over
 * its latent on every tet of its mesh, or on the tets of --cubature (a
 * cubature crom-cubature made for this model). */
static int run_map(crom_cli *cli, args *a)
{
    crom_in in;
    int rc = crom_in_open(&in, a->model);
    if (rc)
        return rc;
    crom_model model;
    crom_mesh mesh;
    memset(&mesh, 0, sizeof mesh);
    crom_map map;
    memset(&map, 0, sizeof map);
    crom_nlsim s;
    memset(&s, 0, sizeof s);
    crom_out o;
    crom_fileout csv = {0};
    int have_out = 0;
    double *q0 = NULL, *qd0 = NULL, *xs = NULL, *vs = NULL;
    indicator ind;
    memset(&ind, 0, sizeof ind);
    char *hist = in.history;
    in.history = NULL;
    rc = crom_model_read(&in, &model);
    crom_in_close(&in);
    if (rc) {
        free(hist);
        return rc;
    }
    if (a->mesh && (rc = crom_mesh_load(a->mesh, CROM_MESH_CARRIERS | CROM_MESH_SURFACES, &mesh, NULL)))
        goto out;
    if ((rc = crom_map_init(&map, &model, a->mesh ? &mesh : NULL)) || (a->frame && (rc = crom_map_add_frame(&map))))
        goto out;
    int r = map.r;
    const crom_map *core = map.inner ? map.inner : &map; /* the model's own map (a cubature's) */
    q0 = crom_calloc((size_t)r, sizeof(double));
    qd0 = crom_calloc((size_t)r, sizeof(double));
    if (!q0 || !qd0) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    if (a->init && (rc = read_init(a, model.model_id, r, q0, qd0)))
        goto out;
    double cnow[CROM_MODEL_MAXCOND], cnext[CROM_MODEL_MAXCOND];
    if ((rc = crom_condsched_at(&a->cs, &model, 0, cnow)) ||
        (model.ncond && (rc = crom_nlsim_set_condition(&s, &map, &a->sc, model.cond, cnow))))
        goto out;
    if ((rc = crom_nlsim_init(&s, &map, &a->sc, a->kappa, a->init ? q0 : NULL, a->init ? qd0 : NULL, a->threads)))
        goto out;
    if (a->cub) {
        crom_cubature cub;
        if ((rc = crom_cubature_load(a->cub, &cub, NULL)))
            goto out;
        if (strcmp(cub.model_id, model.model_id) || cub.map_rank != (core->nonlinear ? core->r : 0) ||
            (cub.r != core->p && cub.r != core->p_model) ||
            crom_map_same_mesh(&cub.mesh, &map.mesh))
            rc = crom_err(CROM_EDATA, "--cubature %s is not a cubature of this map (model %s, rank %d, %d vertices): "
                          "make one with crom-cubature --model %s", a->cub, cub.model_id, cub.map_rank, cub.mesh.nv,
                          a->model);
        else
            rc = crom_nlsim_use_cubature(&s, cub.k, cub.elem, cub.weight);
        crom_cubature_free(&cub);
        if (rc)
            goto out;
    }
    if (a->indicator) {
        size_t n = 3 * (size_t)map.mesh.nv;
        xs = crom_malloc(sizeof(double) * n);
        vs = crom_malloc(sizeof(double) * n);
        if (!xs || !vs) {
            rc = CROM_EINTERNAL;
            goto out;
        }
        crom_nlsim_positions(&s, xs, vs);
        if ((rc = indicator_start(&ind, a, &map.mesh, NULL, 0, xs, vs)))
            goto out;
    }
    if ((rc = crom_out_create(&o, a->out, "crom/latent", 1, cli->cmdline, hist, a->kind)))
        goto out;
    have_out = 1;
    if ((rc = start_output(&o, a, model.model_id, r, "gauss-newton", model.basis, &ind, model.ncond)))
        goto out;
    crom_rsim_stats st = {0, 0, crom_nlsim_constraint_residual(&s), 0, 1, 0};
    double K, E, W;
    if (!(rc = crom_nlsim_energies(&s, &K, &E, &W)))
        rc = put_values(&o, s.t, s.step, s.q, s.qd, K, E, W, &st, 0, &ind, model.ncond ? cnow : NULL);
    if (!rc && a->stats && !(rc = crom_fileout_open(&csv, a->stats, 0)))
        fprintf(csv.f, "step,iterations,residual,constraint_residual,seconds,cubature_tets,vertex_evals%s\n",
                ind.on ? ",error_estimate,displacement_rms" : "");
    crom_cli_progress prog;
    crom_cli_progress_start(&prog, cli, "reducedstep", a->sc.steps);
    double tsum = 0;
    long iters = 0;
    for (int k = 1; k <= a->sc.steps && !rc; k++) {
        int stored = k % a->sc.every == 0;
        if (stored && ind.on)
            crom_nlsim_positions(&s, ind.prev, ind.prevdot);
        if (model.ncond) { /* a change of condition that falls in this step takes effect for it */
            crom_condsched_at(&a->cs, &model, (double)k * a->sc.dt, cnext);
            if (memcmp(cnext, cnow, sizeof(double) * (size_t)model.ncond)) {
                memcpy(cnow, cnext, sizeof cnow);
                if ((rc = crom_nlsim_set_condition(&s, &map, &a->sc, model.cond, cnow)))
                    break;
            }
        }
        if ((rc = crom_nlsim_step(&s, &st)))
            break;
        if (stored || csv.f)
            st.constraint_residual = crom_nlsim_constraint_residual(&s);
        if (stored && ind.on) {
            crom_nlsim_positions(&s, xs, NULL);
            if ((rc = indicator_measure(&ind, s.t, xs)))
                break;
        }
        tsum += st.seconds;
        iters += st.iterations;
        if (csv.f)
            indicator_csv(&csv, &ind, stored, k, &st, s.ne);
        if (stored && !(rc = crom_nlsim_energies(&s, &K, &E, &W)))
            rc = put_values(&o, s.t, s.step, s.q, s.qd, K, E, W, &st, 0, &ind, model.ncond ? cnow : NULL);
        crom_cli_progress_update(&prog, k, NULL);
    }
    crom_cli_progress_end(&prog);
    rc = crom_out_finish_run(&o, &csv, rc);
    have_out = 0;
    if (rc)
        goto out;
    if (!rc && cli->verbose && a->sc.steps > 0)
        crom_cli_info(cli, "%d steps, %s map of rank %d on %d vertices, %d of %d %s: %.3f ms/step, %.2f "
                      "Gauss-Newton iterations/step", a->sc.steps, model.basis, r, map.nv, s.ne, s.sys.nenergy,
                      s.sys.rigid ? "scene elements" : s.sys.shell ? "triangles and hinges" : "tets", 1e3 * tsum / a->sc.steps,
                      (double)iters / a->sc.steps);
    indicator_end(cli, a, &ind);
out:
    if (have_out)
        crom_out_fail(&o);
    indicator_free(&ind);
    free(xs);
    free(vs);
    crom_nlsim_free(&s);
    crom_map_free(&map);
    crom_mesh_free(&mesh);
    crom_model_free(&model);
    free(q0);
    free(qd0);
    free(hist);
    return rc;
}


static int run(crom_cli *cli, args *a)
{
    crom_schedule sch;
    int rc = crom_schedule_load(&sch, a->cub, a->sched, a->sc.steps);
    if (rc) {
        crom_schedule_free(&sch);
        return rc;
    }
    const crom_schedule_entry *e = sch.e;
    int nsch = sch.n, r = e[0].cub.r;
    double *q0 = crom_calloc((size_t)r, sizeof(double)), *qd0 = crom_calloc((size_t)r, sizeof(double));
    crom_rsim s;
    memset(&s, 0, sizeof s);
    crom_out o;
    crom_fileout csv = {0};
    int have_out = 0;
    indicator ind;
    memset(&ind, 0, sizeof ind);
    if (!q0 || !qd0) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    if (a->init && (rc = read_init(a, e[0].cub.model_id, r, q0, qd0)))
        goto out;
    if ((rc = crom_rsim_init(&s, &e[0].cub, &a->sc, a->solver, a->kappa, q0, a->init ? qd0 : NULL)))
        goto out;
    if (a->bc_threshold != 0.1) { /* rebuild with the asked threshold */
        s.bc_threshold = a->bc_threshold;
        if ((rc = crom_rsim_set_cubature(&s, &e[0].cub)))
            goto out;
    }
    if (a->indicator && (rc = indicator_start(&ind, a, &e[0].cub.mesh, e[0].cub.model_id, r, s.q, s.qd)))
        goto out;
    if (cli->verbose && s.nbc)
        crom_cli_info(cli, "boundary conditions constrain %d of %d latent directions (penalty rate %.3g 1/s^2)",
                      s.nconstrained, r, s.kappa);
    if ((rc = crom_out_create(&o, a->out, "crom/latent", 1, cli->cmdline, e[0].history, a->kind)))
        goto out;
    have_out = 1;
    char *list = crom_schedule_text(&sch);
    rc = list ? crom_h5_set_str(o.h5, ".", "cubatures", list) : CROM_EINTERNAL;
    free(list);
    if (!rc)
        rc = start_output(&o, a, e[0].cub.model_id, r, a->solver == CROM_RSIM_GD ? "gd" : "newton", NULL, &ind, 0);
    crom_rsim_stats st = {0, 0, crom_rsim_constraint_residual(&s), 0, 1, 0};
    if (!rc)
        rc = put_frame(&o, &s, &st, 0, &ind);
    if (!rc && a->stats && !(rc = crom_fileout_open(&csv, a->stats, 0)))
        fprintf(csv.f, "step,iterations,residual,constraint_residual,seconds,cubature_tets,vertex_evals%s\n",
                ind.on ? ",error_estimate,displacement_rms" : "");
    crom_cli_progress prog;
    crom_cli_progress_start(&prog, cli, "reducedstep", a->sc.steps);
    int cur = 0;
    double tsum = 0;
    for (int k = 1; k <= a->sc.steps && !rc; k++) {
        if (cur + 1 < nsch && e[cur + 1].step == k) { /* switch mesh: the state carries over */
            cur++;
            if ((rc = crom_rsim_set_cubature(&s, &e[cur].cub)) || (rc = indicator_switch(&ind, a, &e[cur].cub.mesh)))
                break;
            if (cli->verbose)
                crom_cli_info(cli, "step %d: switched to %s (%d tets)", k, e[cur].path, e[cur].cub.k);
        }
        int stored = k % a->sc.every == 0;
        if (stored && ind.on) {
            memcpy(ind.prev, s.q, sizeof(double) * (size_t)r);
            memcpy(ind.prevdot, s.qd, sizeof(double) * (size_t)r);
        }
        if ((rc = crom_rsim_step(&s, &st)))
            break;
        if (stored || csv.f) /* reported: a pass over the BC vertices, not part of the step */
            st.constraint_residual = crom_rsim_constraint_residual(&s);
        tsum += st.seconds;
        if (stored && ind.on && (rc = indicator_measure(&ind, s.t, s.q)))
            break;
        if (csv.f)
            indicator_csv(&csv, &ind, stored, k, &st, e[cur].cub.k);
        if (stored)
            rc = put_frame(&o, &s, &st, cur, &ind);
        crom_cli_progress_update(&prog, k, NULL);
    }
    crom_cli_progress_end(&prog);
    rc = crom_out_finish_run(&o, &csv, rc);
    have_out = 0;
    if (rc)
        goto out;
    if (!rc && cli->verbose && a->sc.steps > 0)
        crom_cli_info(cli, "%d steps, rank %d, %d cubature tets: %.3f ms/step", a->sc.steps, r, e[cur].cub.k,
                      1e3 * tsum / a->sc.steps);
    indicator_end(cli, a, &ind);
out:
    if (have_out)
        crom_out_fail(&o);
    indicator_free(&ind);
    crom_rsim_free(&s);
    free(q0);
    free(qd0);
    crom_schedule_free(&sch);
    return rc;
}

int main(int argc, char **argv)
{
    crom_cli cli;
    args a;
    memset(&a, 0, sizeof a);
    crom_scenario_defaults(&a.sc);
    a.kind = CROM_OUT_SERIES;
    a.init_frame = -1;
    a.bc_threshold = 0.1;
    a.warn_above = 0.2;
    crom_cli_parse(&cli, &doc, argc, argv, on_opt, &a);
    if (!a.indicator && (a.ind_mesh || a.ind_model))
        return crom_cli_exit(&cli, crom_err(CROM_EUSAGE, "%s applies to --indicator",
                                            a.ind_mesh ? "--indicator-mesh" : "--indicator-model"));
    if (a.indicator && a.model && (a.ind_mesh || a.ind_model))
        return crom_cli_exit(&cli, crom_err(CROM_EUSAGE, "--indicator with --model measures on the map's own mesh: "
                                            "%s does not apply", a.ind_mesh ? "--indicator-mesh" : "--indicator-model"));
    a.threads = cli.threads > 0 ? cli.threads : 1; /* resolved by crom_cli_parse */
    if (a.model) {
        const char *bad = a.sched ? "--schedule" : a.bcthr_given ? "--bc-threshold" : NULL;
        if (bad)
            return crom_cli_exit(&cli, crom_err(CROM_EUSAGE, "--model runs on the model's mesh: %s does not apply", bad));
        if (a.solver == CROM_RSIM_GD)
            return crom_cli_exit(&cli, crom_err(CROM_EUSAGE, "--solver gd needs a cubature; --model uses Gauss-Newton"));
    } else if (a.cs.n || a.frame) {
        return crom_cli_exit(&cli, crom_err(CROM_EUSAGE, "%s applies to --model", a.cs.n ? "--condition" : "--rigid-frame"));
    }
    if (a.model) {
        return crom_cli_exit(&cli, run_map(&cli, &a));
    }
    if (a.mesh)
        return crom_cli_exit(&cli, crom_err(CROM_EUSAGE, "--mesh applies to --model (a cubature carries its mesh)"));
    if (!a.cub)
        return crom_cli_exit(&cli, crom_err(CROM_EUSAGE, "--cubature CUB is required, or --model MODEL (see crom-reducedstep --help)"));
    return crom_cli_exit(&cli, run(&cli, &a));
}
