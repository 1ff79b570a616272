/* crom-fullsim — full-space implicit FEM of a stable neo-Hookean solid: the
 * training-data generator and the ground truth reduced runs are judged by. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "cli/cli.h"
#include "io/io.h"
#include "mesh/mesh.h"
#include "base/rng.h"
#include "phys/cequil.h"
#include "phys/modes.h"
#include "phys/scenario.h"
#include "phys/sim.h"
#include "rom/map.h"
#include "rom/equil.h"
#include "rom/model.h"

enum { O_STREAM = 300, O_HDF5, O_STATS, O_EQUIL, O_GRID, O_RANDOM, O_LATENTS, O_BOX, O_BOXSC };

static const crom_opt out_opts[] = {
    {"output", 'o', "OUT", "Write the trajectory to OUT (default: stdout; a frame stream into a pipe, HDF5 when redirected to a file)."},
    {"stream", O_STREAM, NULL, "Write a frame stream even to a file."},
    {"hdf5", O_HDF5, NULL, "Write HDF5 even into a pipe (the next stage then starts when the run ends)."},
    {"stats", O_STATS, "CSV", "Write one line per step to CSV: Newton and CG iterations, factorizations, residual, and the wall-time split (total, assembly, factorization, solves, line search) in seconds."},
    {NULL, 0, NULL, NULL}};

static const crom_opt eq_opts[] = {
    {"equilibria", O_EQUIL, "MODEL", "Instead of a run: the constrained equilibria in the linear modes of MODEL (crom-modes, or the modes of a neuralmodes map), the ground truth of Neural Modes: frame k is argmin E(x) subject to W^T M (x - X) / m = z_k, for modal coordinates z_k on a grid or drawn at random in a box. The elastic energy alone: no gravity, forces, planes or velocities; --pin as the modes had it."},
    {"grid", O_GRID, "N", "--equilibria: N points per modal axis, N^r equilibria in the box (Wang et al.: 9 for training, 11 for testing)."},
    {"random", O_RANDOM, "N", "--equilibria: N equilibria at z uniform in the box (--seed)."},
    {"latents", O_LATENTS, "LATENT", "--equilibria: one equilibrium per frame of LATENT (a crom/latent of a modal subspace in MODEL's modes, e.g. a crom-reducedstep --model run of a neuralmodes map), at its coordinates q = z: the ground truth along the states that run visited."},
    {"box", O_BOX, "A", "--equilibria: the box's half-width in metres of RMS displacement (default: a neuralmodes map's training box, else 0.2 times the bounding-box diagonal)."},
    {"box-scaling", O_BOXSC, "KIND", "--equilibria: uniform ([-A, A] for every mode; the default but for a neuralmodes map trained with frequency scaling) or frequency ([-A f_1/f_k, A f_1/f_k] for mode k)."},
    {NULL, 0, NULL, NULL}};

static const crom_cli_optgroup groups[] = {
    {"Scenario options (the same in crom-reducedstep)", crom_scenario_opts},
    {"Output options", out_opts},
    {"Constrained equilibria", eq_opts},
    {NULL, NULL}};

static const crom_cli_doc doc = {
    "crom-fullsim",
    "implicit FEM of a stable neo-Hookean solid (crom/mesh to crom/trajectory)",
    "crom-fullsim [scenario options] [-o OUT] [MESH|-]",
    "Simulates the mesh with linear tetrahedra, the stable neo-Hookean energy (Smith, de Goes, "
    "Kim 2018) with Lame parameters matched to Young's modulus and Poisson ratio at small "
    "strain, lumped mass, gravity, pinned and prescribed-velocity regions, scheduled forces and "
    "frictional collision planes.\n\n"
    "Each implicit Euler step minimizes the incremental potential 1/(2h^2)|x - x_n - h v_n|_M^2 "
    "+ E(x) - f.x (LiCROM eq. 5 in full space) by Newton's method with SPD-projected element "
    "Hessians and a backtracking line search, until the step's displacement error is below --tol "
    "times the body's size. Linear systems are solved by CG preconditioned with a sparse Cholesky "
    "factor (CHOLMOD, METIS ordering analyzed once per mesh) that is reused across iterations and "
    "steps and refreshed when CG slows down.\n\n"
    "The output holds the mesh, the scenario (as flags that parse back to it) and one frame per "
    "--every steps, frame 0 being the initial state: displacement, velocity, kinetic, elastic, "
    "external and total energy, Newton iterations, final residual and wall time of the step. "
    "Frames stream to the next stage as they are computed. A run that fails (a step that does not "
    "converge) keeps the frames done so far, marked incomplete. With --verbose each step's "
    "iterations and timing split (assembly, factorization, solves, line search) go to stderr.\n\n"
    "With --equilibria MODEL it computes, instead of a run, the constrained equilibria x*(z) = argmin "
    "E(x) subject to W^T M (x - X) / m = z in MODEL's linear modes W (Wang et al., Neural Modes, eq. 9): "
    "the configurations a neural-modes subspace is trained to reach, by Newton's method on the KKT "
    "system (lib/phys/cequil.h) from X + W z, or, along --latents, from the previous equilibrium (the "
    "other start when the first fails). Newton finds a local minimum: far from rest, where X + W z "
    "inverts elements, continuation along a path (--latents) finds lower ones. Frame k holds the "
    "equilibrium at z_k (modal_coordinates), its energy, the modal forces that hold it there and the "
    "Newton iterations; time and step hold k. crom-metrics --equilibria measures a subspace against "
    "them, crom-fitfield --objective neuralmodes --supervised fits the supervised baseline to them.",
    groups,
    "crom-mesh box --size 0.05 | crom-fullsim --velocity 'y>0.45=0,-2,0@0:0.1' --pin 'y<-0.45' \\\n"
    "    --gravity 0,0,0 --dt 0.005 --steps 60 | crom-export --format pvd -o out/\n"
    "crom-fullsim @compress.flags -o traj.h5 box.h5\n"
    "crom-fullsim --equilibria modes.h5 --grid 9 --box 0.1 --youngs 1e9 -o eq.h5 square.h5",
    "crom-mesh(1), crom-export(1), crom-info(1), crom-sample(1), crom-reducedstep(1)"};

typedef struct {
    crom_scenario sc;
    const char *input, *out, *stats, *equilibria, *latents;
    int kind, grid, random, box_scaling; /* box_scaling: -1 unset, 0 uniform, 1 frequency */
    int tol_given, iter_given, gravity_given;
    double box;
} args;

static int on_opt(void *ctx, int key, const char *v)
{
    args *a = ctx;
    const char *scn = crom_scenario_opt_name(key);
    if (scn) {
        a->tol_given |= !strcmp(scn, "tol");
        a->iter_given |= !strcmp(scn, "max-iter");
        a->gravity_given |= !strcmp(scn, "gravity");
    }
    int rc = crom_scenario_option(&a->sc, key, v);
    if (rc >= 0)
        return rc;
    long n;
    static const char *const boxsc[] = {"uniform", "frequency"};
    switch (key) {
    case 0:
        if (a->input)
            return crom_err(CROM_EUSAGE, "unexpected operand '%s' (one mesh)", v);
        a->input = v;
        return 0;
    case 'o': a->out = v; return 0;
    case O_STREAM: a->kind = CROM_OUT_SERIES_STREAM; return 0;
    case O_HDF5: a->kind = CROM_OUT_SERIES_H5; return 0;
    case O_STATS: a->stats = v; return 0;
    case O_EQUIL: a->equilibria = v; return 0;
    case O_LATENTS:
        if (a->grid || a->random || a->latents)
            return crom_err(CROM_EUSAGE, "give one of --grid, --random and --latents");
        a->latents = v;
        return 0;
    case O_GRID: case O_RANDOM:
        if (a->grid || a->random || a->latents)
            return crom_err(CROM_EUSAGE, "give one of --grid, --random and --latents");
        if (crom_parse_int(v, key == O_GRID ? "--grid" : "--random", key == O_GRID ? 2 : 1, 1000000L, &n))
            return CROM_EUSAGE;
        *(key == O_GRID ? &a->grid : &a->random) = (int)n;
        return 0;
    case O_BOX: return crom_parse_positive(v, "--box", &a->box);
    case O_BOXSC:
        for (int i = 0; i < 2; i++)
            if (!strcmp(v, boxsc[i])) {
                a->box_scaling = i;
                return 0;
            }
        return crom_err(CROM_EUSAGE, "--box-scaling '%s': uniform or frequency", v);
    }
    return crom_err(CROM_EINTERNAL, "unhandled option");
}

/* A frame; a rigid-body scene also gets each body's [R|t] into pose
 * [nb][12] and the joint gaps into gap [nj] (frame fields body_pose,
 * joint_gap). */
static int put_frame(crom_out *o, crom_sim *s, const crom_sim_stats *st, double *u, double *pose, double *gap)
{
    double K, E, W;
    int rc = crom_sim_energies(s, &K, &E, &W);
    if (rc)
        return rc;
    crom_sim_displacement(s, u);
    double step = (double)s->step, tot = K + E + W, it = st->newton, res = st->residual,
           secs = crom_clock_wall(st->t_total);
    const crom_rigidsys *rb = &s->sys.rb;
    for (int b = 0; s->sys.rigid && b < rb->nb; b++) {
        double R[9], t[3], *P = pose + 12 * (size_t)b;
        crom_rigidsys_pose(rb, b, s->x, R, t);
        for (int i = 0; i < 3; i++) {
            memcpy(P + 4 * i, R + 3 * i, 3 * sizeof(double));
            P[4 * i + 3] = t[i];
        }
    }
    if (s->sys.rigid)
        crom_rigidsys_joint_gaps(rb, s->x, gap);
    const double *vals[] = {&s->t, &step, u, s->v, &K, &E, &W, &tot, &it, &res, &secs, pose, gap};
    return crom_out_frame(o, vals);
}

/* ------------------------------------------------------------ equilibria */

static int run_equilibria(crom_cli *cli, args *a, crom_mesh *m, char *hist)
{
    crom_scenario *sc = &a->sc;
    if (sc->nvel || sc->nforce || sc->nplanes || sc->nrod || a->gravity_given || sc->v0[0] || sc->v0[1] ||
        sc->v0[2] || sc->spin[0] || sc->spin[1] || sc->spin[2])
        return crom_err(CROM_EUSAGE, "--equilibria minimizes the elastic energy alone: --gravity, --velocity, "
                                     "--force, --rod, --plane, --sphere and initial velocities do not apply");
    if (!a->grid && !a->random && !a->latents)
        return crom_err(CROM_EUSAGE, "--equilibria needs --grid N, --random N or --latents LATENT");
    sc->gravity[0] = sc->gravity[1] = sc->gravity[2] = 0;
    crom_model model;
    crom_model_clear(&model);
    crom_map map;
    memset(&map, 0, sizeof map);
    crom_system sys;
    memset(&sys, 0, sizeof sys);
    crom_cequil ce;
    memset(&ce, 0, sizeof ce);
    unsigned char *fixed = NULL;
    double *W = NULL, *x = NULL, *xprev = NULL, *u = NULL, *zero = NULL, *Zl = NULL, *half = NULL, A = 0;
    int npinned = 0, r = 0, n = 3 * m->nv, have_prev = 0, scaled = 0;
    long count = a->random;
    int rc = crom_modes_scenario_pins(m, sc, &fixed, &npinned);
    if (!rc)
        rc = crom_system_init(&sys, m, sc->youngs, sc->poisson, sc->density);
    if (!rc)
        rc = crom_system_set_materials(&sys, sc, m);
    if (!rc && (rc = crom_model_load(a->equilibria, &model)))
        crom_err_ctx("--equilibria");
    if (!rc && (rc = crom_equil_modes(&model, m, &map, &W)))
        crom_err_ctx("--equilibria %s", a->equilibria);
    if (rc)
        goto out;
    r = map.r;
    if (!(half = crom_malloc(sizeof(double) * 3 * (size_t)r))) { /* half, z, the modal forces */
        rc = CROM_EINTERNAL;
        goto out;
    }
    double *z = half + r, *lam = half + 2 * r;
    if ((rc = crom_equil_box(&model, m, a->box, a->box_scaling, half, &A, &scaled)))
        goto out;
    if (a->latents && (rc = crom_equil_latents(a->latents, r, &Zl, &count))) {
        crom_err_ctx("--latents");
        goto out;
    }
    if (a->grid) {
        double c = pow(a->grid, r);
        if (c > 1e6) {
            rc = crom_err(CROM_EUSAGE, "--grid %d over %d modes is %.3g equilibria (at most 1e6)", a->grid, r, c);
            goto out;
        }
        count = (long)c;
    }
    crom_cequil_opts co;
    crom_cequil_defaults(&co);
    if (a->tol_given)
        co.tol = sc->tol;
    if (a->iter_given)
        co.max_iter = sc->max_iter;
    if ((rc = crom_cequil_init(&ce, &sys, m, fixed, r, W, &co)))
        goto out;
    x = crom_malloc(sizeof(double) * (size_t)n);
    xprev = crom_malloc(sizeof(double) * (size_t)n);
    u = crom_malloc(sizeof(double) * (size_t)n);
    zero = crom_calloc((size_t)n, sizeof(double));
    if (!x || !xprev || !u || !zero) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    crom_out o;
    if ((rc = crom_out_create(&o, a->out, "crom/trajectory", 1, cli->cmdline, hist, a->kind)))
        goto out;
    hid_t g = crom_h5_group(o.h5, "mesh");
    rc = g < 0 ? CROM_EINTERNAL : crom_mesh_write(g, m);
    if (g >= 0)
        H5Gclose(g);
    sc->steps = (int)(count - 1 < 0 ? 0 : count - 1);
    if (!rc)
        rc = crom_scenario_write_attrs(o.h5, sc);
    if (!rc)
        rc = crom_h5_set_str(o.h5, ".", "equilibria_model", model.model_id);
    if (!rc)
        rc = crom_h5_set_f64(o.h5, ".", "latent_box", &A, 1);
    if (!rc)
        rc = crom_h5_set_str(o.h5, ".", "latent_box_scaling", scaled ? "frequency" : "uniform");
    hsize_t dims[2] = {(hsize_t)m->nv, 3}, rd[1] = {(hsize_t)r};
    static const char *const f[] = {"time", "step", "displacement", "velocity", "kinetic_energy", "elastic_energy",
                                    "external_energy", "total_energy", "newton_iterations", "residual",
                                    "step_seconds", "modal_coordinates", "modal_forces"};
    for (int i = 0; i < 13 && !rc; i++)
        rc = crom_out_field(&o, f[i], (i == 2 || i == 3) ? 2 : i >= 11 ? 1 : 0, i >= 11 ? rd : dims, NULL);
    if (!rc)
        rc = crom_out_begin(&o);
    crom_rng rng;
    crom_rng_seed(&rng, (uint64_t)cli->seed);
    crom_cli_progress prog;
    crom_cli_progress_start(&prog, cli, "equilibria", count);
    long newton = 0;
    for (long k = 0; k < count && !rc; k++) {
        crom_equil_point(a->grid, r, half, Zl, k, &rng, z);
        crom_cequil_stats st;
        double t0 = crom_clock_now();
        /* from X + W z; along a path (--latents) from the previous equilibrium first */
        if ((rc = crom_equil_solve(&ce, m->X, W, z, have_prev ? xprev : NULL, a->latents != NULL, x, lam, &st))) {
            crom_err_ctx("equilibrium %ld", k);
            break;
        }
        memcpy(xprev, x, sizeof(double) * (size_t)n);
        have_prev = 1;
        newton += st.newton;
        for (int i = 0; i < n; i++)
            u[i] = x[i] - m->X[i];
        double t = (double)k, it = st.newton, res = st.residual, secs = crom_clock_wall(crom_clock_now() - t0), zk = 0;
        const double *vals[] = {&t, &t, u, zero, &zk, &st.energy, &zk, &st.energy, &it, &res, &secs, z, lam};
        rc = crom_out_frame(&o, vals);
        char extra[64];
        snprintf(extra, sizeof extra, "%d Newton, E %.3g J", st.newton, st.energy);
        crom_cli_progress_update(&prog, k + 1, extra);
    }
    crom_cli_progress_end(&prog);
    rc = crom_out_finish_run(&o, NULL, rc);
    if (!rc && cli->verbose)
        crom_cli_info(cli, "%ld constrained equilibria in %d modes of %s (%d vertices, %d pinned): %.1f Newton "
                           "iterations each", count, r, a->equilibria, m->nv, npinned, (double)newton / count);
out:
    crom_cequil_free(&ce);
    crom_system_free(&sys);
    crom_map_free(&map);
    crom_model_free(&model);
    free(fixed), free(W), free(x), free(xprev), free(u), free(zero), free(Zl), free(half);
    return rc;
}

static int run(crom_cli *cli, args *a)
{
    crom_mesh m;
    char *hist = NULL;
    int rc = crom_mesh_load(a->input, CROM_MESH_SURFACES | CROM_MESH_SCENES, &m, &hist);
    if (rc)
        return rc;
    if (a->equilibria && m.scene) {
        free(hist);
        crom_mesh_free(&m);
        return crom_err(CROM_EUSAGE, "--equilibria takes a solid or a shell, not a rigid-body scene");
    }
    if (a->equilibria) {
        rc = run_equilibria(cli, a, &m, hist);
        free(hist);
        crom_mesh_free(&m);
        return rc;
    }
    if (a->grid || a->random || a->latents || a->box > 0 || a->box_scaling >= 0) {
        free(hist);
        crom_mesh_free(&m);
        return crom_err(CROM_EUSAGE, "--grid, --random, --latents, --box and --box-scaling apply to --equilibria");
    }
    crom_sim s;
    if ((rc = crom_sim_init(&s, &m, &a->sc))) {
        crom_mesh_free(&m);
        free(hist);
        return rc;
    }
    crom_out o;
    rc = crom_out_create(&o, a->out, "crom/trajectory", 1, cli->cmdline, hist, a->kind);
    free(hist);
    if (rc)
        goto out_sim;
    hid_t g = crom_h5_group(o.h5, "mesh");
    rc = g < 0 ? CROM_EINTERNAL : crom_mesh_write(g, &m);
    if (g >= 0)
        H5Gclose(g);
    if (!rc)
        rc = crom_scenario_write_attrs(o.h5, &a->sc);
    hsize_t dims[2] = {(hsize_t)m.nv, 3};
    /* the frame fields, in order; their units and descriptions are lib/io/schema.c's */
    static const char *const f[] = {"time", "step", "displacement", "velocity", "kinetic_energy", "elastic_energy",
                                    "external_energy", "total_energy", "newton_iterations", "residual",
                                    "step_seconds"};
    for (int i = 0; i < 11 && !rc; i++)
        rc = crom_out_field(&o, f[i], (i == 2 || i == 3) ? 2 : 0, dims, NULL);
    int nb = m.scene ? m.scene->nb : 0, nj = m.scene ? m.scene->nj : 0;
    hsize_t pdims[3] = {(hsize_t)nb, 3, 4}, jdims[1] = {(hsize_t)nj};
    if (!rc && nb)
        rc = crom_out_field(&o, "body_pose", 3, pdims, NULL);
    if (!rc && nj)
        rc = crom_out_field(&o, "joint_gap", 1, jdims, NULL);
    if (!rc)
        rc = crom_out_begin(&o);
    double *u = crom_malloc(sizeof(double) * 3 * (size_t)m.nv);
    double *pose = crom_malloc(sizeof(double) * (12 * (size_t)nb + 1)), *gap = crom_malloc(sizeof(double) * ((size_t)nj + 1));
    crom_sim_stats st = {0}, sum = {0};
    if (!u || !pose || !gap)
        rc = CROM_EINTERNAL;
    if (!rc)
        rc = put_frame(&o, &s, &st, u, pose, gap);
    crom_fileout csv = {0};
    if (!rc && a->stats && !(rc = crom_fileout_open(&csv, a->stats, 0)))
        fprintf(csv.f, "step,newton,cg,factorizations,residual,seconds,assembly,factorization,solves,line_search\n");
    crom_cli_progress prog;
    crom_cli_progress_start(&prog, cli, "fullsim", a->sc.steps);
    for (int k = 1; k <= a->sc.steps && !rc; k++) {
        if ((rc = crom_sim_step(&s, &st)))
            break;
        sum.newton += st.newton;
        sum.cg += st.cg;
        sum.factorizations += st.factorizations;
        sum.t_assemble += st.t_assemble;
        sum.t_factor += st.t_factor;
        sum.t_solve += st.t_solve;
        sum.t_linesearch += st.t_linesearch;
        sum.t_total += st.t_total;
        if (cli->verbose > 1)
            crom_cli_info(cli, "step %d: t %.4g s, %d Newton, %d CG, %d factorizations, residual %.2e, %.3f s "
                               "(assembly %.3f, factor %.3f, solve %.3f, line search %.3f)",
                          k, s.t, st.newton, st.cg, st.factorizations, st.residual, st.t_total,
                          st.t_assemble, st.t_factor, st.t_solve, st.t_linesearch);
        if (csv.f)
            fprintf(csv.f, "%d,%d,%d,%d,%.3e,%.6f,%.6f,%.6f,%.6f,%.6f\n", k, st.newton, st.cg,
                    st.factorizations, st.residual, st.t_total, st.t_assemble, st.t_factor, st.t_solve,
                    st.t_linesearch);
        if (k % a->sc.every == 0)
            rc = put_frame(&o, &s, &st, u, pose, gap);
        char extra[64];
        snprintf(extra, sizeof extra, "%d Newton, res %.1e", st.newton, st.residual);
        crom_cli_progress_update(&prog, k, extra);
    }
    crom_cli_progress_end(&prog);
    free(u);
    free(pose);
    free(gap);
    if ((rc = crom_out_finish_run(&o, &csv, rc)))
        goto out_sim;
    if (cli->verbose && a->sc.steps > 0) {
        int ns = a->sc.steps;
        crom_cli_info(cli, "%d vertices, %d %s: %d steps, %.3f s/step (assembly %.3f, factorization %.3f, "
                           "solves %.3f, line search %.3f), %.2f Newton and %.1f CG iterations and %.2f "
                           "factorizations per step",
                      m.nv, m.scene ? m.scene->nb : m.ntri ? m.ntri : m.nt,
                      m.scene ? "rigid bodies" : m.ntri ? "triangles" : "tets", ns, sum.t_total / ns, sum.t_assemble / ns, sum.t_factor / ns,
                      sum.t_solve / ns, sum.t_linesearch / ns, (double)sum.newton / ns,
                      (double)sum.cg / ns, (double)sum.factorizations / ns);
    }
out_sim:
    crom_sim_free(&s);
    crom_mesh_free(&m);
    return rc;
}

int main(int argc, char **argv)
{
    crom_cli cli;
    args a;
    memset(&a, 0, sizeof a);
    crom_scenario_defaults(&a.sc);
    a.kind = CROM_OUT_SERIES;
    a.box_scaling = -1;
    crom_cli_parse(&cli, &doc, argc, argv, on_opt, &a);
    return crom_cli_exit(&cli, run(&cli, &a));
}
