/* crom-fullsim — full-space implicit FEM of a stable neo-Hookean solid: the
 * training-data generator and the ground truth reduced runs are judged by. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "cli/cli.h"
#include "io/io.h"
#include "mesh/mesh.h"
#include "phys/scenario.h"
#include "phys/sim.h"

enum { O_STREAM = 300, O_HDF5, O_STATS };

static const crom_opt out_opts[] = {
    {"output", 'o', "OUT", "Write the trajectory to OUT (default: stdout; a frame stream into a pipe, HDF5 when redirected to a file)."},
    {"stream", O_STREAM, NULL, "Write a frame stream even to a file."},
    {"hdf5", O_HDF5, NULL, "Write HDF5 even into a pipe (the next stage then starts when the run ends)."},
    {"stats", O_STATS, "CSV", "Write one line per step to CSV: Newton and CG iterations, factorizations, residual, and the wall-time split (total, assembly, factorization, solves, line search) in seconds."},
    {NULL, 0, NULL, NULL}};

static const crom_cli_optgroup groups[] = {
    {"Scenario options (the same in crom-reducedstep)", crom_scenario_opts},
    {"Output options", out_opts},
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
    "iterations and timing split (assembly, factorization, solves, line search) go to stderr.",
    groups,
    "crom-mesh box --size 0.05 | crom-fullsim --velocity 'y>0.45=0,-2,0@0:0.1' --pin 'y<-0.45' \\\n"
    "    --gravity 0,0,0 --dt 0.005 --steps 60 | crom-export --format pvd -o out/\n"
    "crom-fullsim @compress.flags -o traj.h5 box.h5",
    "crom-mesh(1), crom-export(1), crom-info(1), crom-sample(1), crom-reducedstep(1)"};

typedef struct {
    crom_scenario sc;
    const char *input, *out, *stats;
    int kind;
} args;

static int on_opt(void *ctx, int key, const char *v)
{
    args *a = ctx;
    int rc = crom_scenario_option(&a->sc, key, v);
    if (rc >= 0)
        return rc;
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
    }
    return crom_err(CROM_EINTERNAL, "unhandled option");
}

static int put_frame(crom_out *o, crom_sim *s, const crom_sim_stats *st, double *u)
{
    double K, E, W;
    int rc = crom_sim_energies(s, &K, &E, &W);
    if (rc)
        return rc;
    crom_sim_displacement(s, u);
    double step = (double)s->step, tot = K + E + W, it = st->newton, res = st->residual,
           secs = crom_clock_wall(st->t_total);
    const double *vals[] = {&s->t, &step, u, s->v, &K, &E, &W, &tot, &it, &res, &secs};
    return crom_out_frame(o, vals);
}

static int run(crom_cli *cli, args *a)
{
    crom_mesh m;
    char *hist = NULL;
    int rc = crom_mesh_load(a->input, CROM_MESH_SURFACES, &m, &hist);
    if (rc)
        return rc;
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
    if (!rc)
        rc = crom_out_begin(&o);
    double *u = crom_malloc(sizeof(double) * 3 * (size_t)m.nv);
    crom_sim_stats st = {0}, sum = {0};
    if (!u)
        rc = CROM_EINTERNAL;
    if (!rc)
        rc = put_frame(&o, &s, &st, u);
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
            rc = put_frame(&o, &s, &st, u);
        char extra[64];
        snprintf(extra, sizeof extra, "%d Newton, res %.1e", st.newton, st.residual);
        crom_cli_progress_update(&prog, k, extra);
    }
    crom_cli_progress_end(&prog);
    free(u);
    if ((rc = crom_out_finish_run(&o, &csv, rc)))
        goto out_sim;
    if (cli->verbose && a->sc.steps > 0) {
        int ns = a->sc.steps;
        crom_cli_info(cli, "%d vertices, %d %s: %d steps, %.3f s/step (assembly %.3f, factorization %.3f, "
                           "solves %.3f, line search %.3f), %.2f Newton and %.1f CG iterations and %.2f "
                           "factorizations per step",
                      m.nv, m.ntri ? m.ntri : m.nt, m.ntri ? "triangles" : "tets", ns, sum.t_total / ns, sum.t_assemble / ns, sum.t_factor / ns,
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
    crom_cli_parse(&cli, &doc, argc, argv, on_opt, &a);
    return crom_cli_exit(&cli, run(&cli, &a));
}
