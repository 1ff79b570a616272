/* crom-metrics — how good is a subspace: the energy of its random samples
 * (against a linear basis at the same displacements), how isometric it is,
 * and whether latent dimensions collapsed (Neural Modes §4.4). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "cli/cli.h"
#include "io/io.h"
#include "mesh/mesh.h"
#include "phys/system.h"
#include "phys/scenario.h"
#include "rom/map.h"
#include "rom/metrics.h"
#include "rom/model.h"
#include "rom/result.h"
#include "phys/modes.h"

enum { O_MESH = 300, O_COMPARE, O_SAMPLES, O_SPHERE, O_BOX, O_NORMAL, O_SIGMA, O_PAIRS, O_THRESH, O_EQUIL };

static const crom_opt met_opts[] = {
    {"mesh", O_MESH, "MESH", "The mesh to lay the subspace on: required for a neural field (mlp); for pod and modes another mesh interpolates them; a data-free map (energy, neuralmodes) lives on its own mesh, which is the default and the only mesh accepted."},
    {"compare", O_COMPARE, "MODEL", "Also measure a LINEAR basis of the same mesh (e.g. crom-modes) at the same displacement magnitudes: for each sample, a random direction of MODEL scaled to the sample's RMS displacement from rest."},
    {"samples", O_SAMPLES, "N", "Random latent samples (default 256)."},
    {"sphere", O_SPHERE, "R", "Draw q uniformly on the sphere |q| = R."},
    {"box", O_BOX, "A", "Draw q uniformly in the box [-A, A]^r (default for neuralmodes: its training box, whose half-width is A f_1/f_k for mode k when it was trained with --box-scaling frequency)."},
    {"normal", O_NORMAL, "S", "Draw q from N(0, S^2 I) (default for energy maps: S = 1, their training distribution)."},
    {"sigma", O_SIGMA, "S", "Isometry scale in metres of RMS displacement per unit of q (default: the model's sigma for energy maps and continuous fields, 1 otherwise: q in metres)."},
    {"pairs-of", O_PAIRS, "N", "The isometry ratio is measured over all pairs of the first N samples (default 100)."},
    {"collapse-threshold", O_THRESH, "T", "A normalized Gram eigenvalue below T counts as a collapsed dimension (default 0.01)."},
    {"equilibria", O_EQUIL, "EQ", "Instead: measure the modal subspace MODEL (linear modes, or a neuralmodes map, on their own mesh) against the constrained equilibria of EQ (crom-fullsim --equilibria, in the same modes) at their modal coordinates: elastic energy, von Mises stress, nodal forces and displacement (Wang et al., Neural Modes, Table 2). Material and pins come from EQ."},
    {NULL, 0, NULL, NULL}};

static const crom_cli_optgroup groups[] = {
    {"Options", met_opts},
    {"Scenario options (material and gravity are used; default: what the model records)", crom_scenario_opts},
    {NULL, NULL}};

static const crom_cli_doc doc = {
    "crom-metrics",
    "energy, isometry and mode-collapse measures of a subspace",
    "crom-metrics [--samples N] [--sphere R | --box A | --normal S] [--compare MODEL] [--mesh MESH]\n"
    "             [--youngs E --poisson NU --density RHO --gravity G] MODEL|-",
    "Measures the subspace of a crom/model laid on one mesh: its map x(q) = X + W q (linear bases) "
    "or x(q) = X + W q + N(q) (data-free maps), on random latent samples q. Prints, one per line:\n\n"
    "elastic_energy: the mean (min, max) stable neo-Hookean energy of the samples, and "
    "potential_energy with gravity added; rms_displacement: their RMS displacement from rest "
    "sqrt(u^T M u / m); with --compare, the mean elastic energy of the other (linear) basis at the "
    "same displacement magnitudes, and the ratio (below 1: the subspace reaches the same "
    "displacements with less energy).\n\n"
    "isometry: quantiles over pairs of samples of |x(q) - x(q')|_M / sqrt(m) / (sigma |q - q'|) "
    "(1 for a map that is an isometry up to the scale sigma, Sharp et al. eq. 2) and the mean "
    "squared log-ratio (their eq. 3).\n\n"
    "gram_eigenvalues: the mode-collapse test of Neural Modes §4.4: the eigenvalues, ascending, of "
    "r G / tr G with G = J^T M J / m the Gram matrix of the latent directions J = dx/dq at q = 0. "
    "They are all 1 for M-orthogonal directions of equal length (linear modes); a value near 0 is a "
    "collapsed dimension (a direction that is nearly a combination of the others, or does not move "
    "the body). correlation_eigenvalues: the same for the correlation matrix D^-1/2 G D^-1/2. "
    "collapse: how many fall below --collapse-threshold.\n\n"
    "The material comes from the model (data-free maps and modes record it) unless given; gravity "
    "from the model's scenario (energy maps), else 0.\n\n"
    "With --equilibria EQ it measures instead a modal subspace (x(z) = X + W z, or a neuralmodes map) "
    "against the constrained equilibria x*(z_k) of crom-fullsim --equilibria, at their modal "
    "coordinates z_k (Wang et al., Neural Modes, Table 2 and A1), one per line: elastic_energy (the "
    "subspace's mean and largest, and the equilibria's: a subspace cannot go below them), "
    "von_mises_stress (mean over samples of the area- or volume-weighted mean element stress, a "
    "shell's membrane stress; largest element stress; and the relative weighted error), "
    "nodal_force_error (mean over samples of the RMS over free vertices of |f - f*|, f = -grad E), "
    "displacement_error (mean |u - u*|_M / |u*|_M). A warning counts the equilibria where the "
    "subspace stores less energy than the solve found: there Newton stopped in a local minimum that "
    "is not the least energy at that z.",
    groups,
    "crom-metrics df.h5\n"
    "crom-metrics --compare modes.h5 --samples 512 df.h5\n"
    "crom-metrics --box 0.1 nm.h5\n"
    "crom-metrics --mesh bar.h5 --youngs 1e6 --sphere 0.05 model.h5\n"
    "crom-metrics --equilibria eq-test.h5 nm.h5",
    "crom-fitfield(1), crom-modes(1), crom-reducedstep(1), crom-info(1)"};

typedef struct {
    const char *model, *mesh, *compare, *equilibria;
    crom_metrics_opts mo;
    int dist_given, sigma_given, material_given, gravity_given;
    double threshold;
    crom_scenario sc;
} args;

static int on_opt(void *ctx, int key, const char *v)
{
    args *a = ctx;
    const char *scn = crom_scenario_opt_name(key);
    if (scn) {
        if (!strcmp(scn, "youngs") || !strcmp(scn, "poisson") || !strcmp(scn, "density"))
            a->material_given = 1;
        if (!strcmp(scn, "gravity"))
            a->gravity_given = 1;
        return crom_scenario_option(&a->sc, key, v);
    }
    long n;
    switch (key) {
    case 0:
        if (a->model)
            return crom_err(CROM_EUSAGE, "unexpected operand '%s' (one model)", v);
        a->model = v;
        return 0;
    case O_MESH: a->mesh = v; return 0;
    case O_COMPARE: a->compare = v; return 0;
    case O_SAMPLES:
        if (crom_parse_int(v, "--samples", 2, 100000000L, &n))
            return CROM_EUSAGE;
        a->mo.samples = (int)n;
        return 0;
    case O_PAIRS:
        if (crom_parse_int(v, "--pairs-of", 2, 100000L, &n))
            return CROM_EUSAGE;
        a->mo.pairs_of = (int)n;
        return 0;
    case O_SPHERE: case O_BOX: case O_NORMAL:
        if (a->dist_given)
            return crom_err(CROM_EUSAGE, "give one of --sphere, --box, --normal");
        a->dist_given = 1;
        a->mo.dist = key == O_SPHERE ? CROM_METRICS_SPHERE : key == O_BOX ? CROM_METRICS_BOX : CROM_METRICS_NORMAL;
        return crom_parse_positive(v, key == O_SPHERE ? "--sphere" : key == O_BOX ? "--box" : "--normal",
                                   &a->mo.radius);
    case O_SIGMA: a->sigma_given = 1; return crom_parse_positive(v, "--sigma", &a->mo.sigma);
    case O_THRESH: return crom_parse_positive(v, "--collapse-threshold", &a->threshold);
    case O_EQUIL: a->equilibria = v; return 0;
    }
    return crom_err(CROM_EINTERNAL, "unhandled option");
}

static void print_eigs(const char *name, const double *e, int r)
{
    printf("%s:", name);
    for (int k = 0; k < r; k++)
        printf(" %.4g", e[k]);
    printf("\n");
}

/* --equilibria: the subspace against constrained equilibria */
static int run_equilibria(crom_cli *cli, args *a, crom_model *model)
{
    if (a->mesh || a->compare || a->dist_given || a->sigma_given || a->material_given || a->gravity_given)
        return crom_err(CROM_EUSAGE, "--equilibria measures the model on the equilibria's mesh with their material: "
                                     "--mesh, --compare, the sampling flags and the scenario flags do not apply");
    crom_result_equilibria eq;
    crom_map map;
    memset(&map, 0, sizeof map);
    crom_system sys;
    memset(&sys, 0, sizeof sys);
    crom_scenario sc;
    crom_scenario_defaults(&sc);
    unsigned char *fixed = NULL;
    int npinned = 0;
    int rc = crom_result_equilibria_load(a->equilibria, &eq);
    if (rc)
        return rc;
    if ((rc = crom_scenario_parse_text(eq.scenario, &sc)) ||
        (rc = crom_modes_scenario_pins(&eq.mesh, &sc, &fixed, &npinned)) || (rc = crom_map_init(&map, model, NULL)))
        goto out;
    if (map.r != eq.r || crom_map_same_mesh(&map.mesh, &eq.mesh)) {
        rc = crom_err(CROM_EUSAGE, "%s (rank %d) does not live on the mesh of %s or has not its %d modal coordinates",
                      a->model, map.r, a->equilibria, eq.r);
        goto out;
    }
    crom_material mat;
    if ((rc = crom_material_init(&mat, sc.youngs, sc.poisson, sc.density)) ||
        (rc = crom_system_init(&sys, &eq.mesh, sc.youngs, sc.poisson, sc.density)))
        goto out;
    crom_metrics_eq e;
    if ((rc = crom_metrics_equilibria(&map, &sys, &mat, fixed, eq.K, eq.Z, eq.U, &e)))
        goto out;
    printf("model: %s, basis %s, rank %d, model_id %s\n", a->model, model->basis, model->rank, model->model_id);
    printf("equilibria: %s, %d in %d modal coordinates, %d vertices (%d pinned), E %.6g Pa, nu %.6g; the modes "
           "agree to %.2g m; the subspace's own modal coordinates are within %.3g m of z\n", a->equilibria, e.count,
           eq.r, eq.mesh.nv, npinned, sc.youngs, sc.poisson, e.zmax_dev, e.zmap_dev);
    printf("elastic_energy: mean %.6g J, max %.6g J; equilibria mean %.6g J, max %.6g J; ratio %.4g\n", e.energy,
           e.energy_max, e.energy_gt, e.energy_gt_max, e.energy_gt > 0 ? e.energy / e.energy_gt : NAN);
    if (e.below)
        crom_cli_warn(cli, "at %d of %d equilibria the subspace stores less energy: those solves found a higher local "
                      "minimum, not the least energy at their z", e.below, e.count);
    printf("von_mises_stress: mean %.6g Pa, max %.6g Pa; equilibria mean %.6g Pa, max %.6g Pa; relative error "
           "%.4g\n", e.stress, e.stress_max, e.stress_gt, e.stress_gt_max, e.stress_err);
    printf("nodal_force_error: %.6g N RMS (the equilibria's forces: %.6g N RMS)\n", e.force_err, e.force_gt);
    printf("displacement_error: %.4g\n", e.disp_err);
out:
    crom_result_equilibria_free(&eq);
    crom_map_free(&map);
    crom_system_free(&sys);
    free(fixed);
    return rc;
}

static int run(crom_cli *cli, args *a)
{
    crom_model model, cmpm;
    crom_model_clear(&model);
    crom_model_clear(&cmpm);
    crom_mesh mesh;
    memset(&mesh, 0, sizeof mesh);
    crom_map map, cmap;
    memset(&map, 0, sizeof map);
    memset(&cmap, 0, sizeof cmap);
    crom_system fem;
    memset(&fem, 0, sizeof fem);
    crom_metrics res;
    memset(&res, 0, sizeof res);
    int rc;
    if ((rc = crom_model_load(a->model, &model)))
        goto out;
    if (a->equilibria) {
        rc = run_equilibria(cli, a, &model);
        goto out;
    }
    if (a->mesh && (rc = crom_mesh_load(a->mesh, 1, &mesh, NULL)))
        goto out;
    if ((rc = crom_map_init(&map, &model, a->mesh ? &mesh : NULL)))
        goto out;
    if (a->compare) {
        if ((rc = crom_model_load(a->compare, &cmpm))) {
            crom_err_ctx("--compare");
            goto out;
        }
        if (crom_model_is_nonlinear(&cmpm)) {
            rc = crom_err(CROM_EUSAGE, "--compare %s is a nonlinear map ('%s'); the comparison needs a linear basis "
                          "(modes, pod, mlp)", a->compare, cmpm.basis);
            goto out;
        }
        if ((rc = crom_map_init(&cmap, &cmpm, &map.mesh)))
            goto out;
    }
    /* material and gravity: flags, else the model's record */
    crom_scenario rec;
    crom_scenario_defaults(&rec);
    rec.gravity[0] = rec.gravity[1] = rec.gravity[2] = 0;
    if (model.scenario && (rc = crom_scenario_parse_text(model.scenario, &rec)))
        goto out;
    const char *matsrc = "given";
    if (!a->material_given) {
        if (isfinite(model.youngs) && isfinite(model.poisson) && isfinite(model.density)) {
            a->sc.youngs = model.youngs;
            a->sc.poisson = model.poisson;
            a->sc.density = model.density;
            matsrc = "recorded in the model";
        } else {
            matsrc = "defaults: the model records none";
        }
    }
    if (!a->gravity_given)
        memcpy(a->sc.gravity, model.has_gravity ? model.gravity : rec.gravity, sizeof model.gravity);
    crom_material mat;
    if ((rc = crom_scenario_check(&a->sc)) || (rc = crom_material_init(&mat, a->sc.youngs, a->sc.poisson, a->sc.density)))
        goto out;
    if ((rc = crom_system_init(&fem, &map.mesh, mat.E, mat.nu, mat.rho)))
        goto out;
    /* the latent distribution and the isometry scale */
    double lo[3], hi[3];
    crom_mesh_bbox(&map.mesh, lo, hi);
    double diag = sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                       (hi[2] - lo[2]) * (hi[2] - lo[2]));
    if (!a->dist_given)
        crom_metrics_training_dist(&model, diag, &a->mo);
    if (!a->sigma_given)
        a->mo.sigma = crom_model_latent_normal(&model) && model.sigma > 0 ? model.sigma : 1;
    a->mo.seed = cli->seed;
    if ((rc = crom_metrics_compute(&map, &fem, a->sc.gravity, &a->mo, a->compare ? &cmap : NULL, &res)))
        goto out;
    static const char *dn[] = {"q ~ N(0, S^2 I), S", "q on the sphere |q| =", "q in the box [-A, A]^r, A"};
    printf("model: %s, basis %s, rank %d, model_id %s, %d vertices, %d %s\n", a->model, model.basis, model.rank,
           model.model_id, map.nv, map.mesh.ntri ? map.mesh.ntri : map.mesh.nt, map.mesh.ntri ? "triangles" : "tets");
    printf("material: E %.6g Pa, nu %.6g, rho %.6g kg/m^3 (%s); gravity %.6g,%.6g,%.6g m/s^2; mass %.6g kg\n",
           a->sc.youngs, a->sc.poisson, a->sc.density, matsrc, a->sc.gravity[0], a->sc.gravity[1], a->sc.gravity[2],
           fem.total_mass);
    printf("samples: %d, %s %.6g%s\n", res.samples, dn[a->mo.dist], a->mo.radius,
           a->mo.box_freq ? " for the lowest mode, A f_1/f_k for mode k (the training box)" : "");
    printf("elastic_energy: mean %.6g J, min %.6g J, max %.6g J\n", res.energy_mean, res.energy_min, res.energy_max);
    printf("potential_energy: mean %.6g J (elastic + gravity)\n", res.potential_mean);
    printf("rms_displacement: mean %.6g m, max %.6g m\n", res.rms_mean, res.rms_max);
    if (a->compare)
        printf("compare: %s (basis %s, rank %d) at the same RMS displacements: elastic_energy mean %.6g J, "
               "ratio %.4g\n", a->compare, cmpm.basis, cmpm.rank, res.cmp_energy_mean,
               res.cmp_energy_mean > 0 ? res.energy_mean / res.cmp_energy_mean : NAN);
    printf("isometry: ratio |x(q) - x(q')|_M / sqrt(m) / (sigma |q - q'|) over %ld pairs: q05 %.4g, median %.4g, "
           "q95 %.4g; mean squared log %.4g (sigma %.6g m)\n", res.npairs, res.iso_q05, res.iso_median, res.iso_q95,
           res.iso_logsq, a->mo.sigma);
    print_eigs("gram_eigenvalues", res.gram_eig, res.r);
    print_eigs("correlation_eigenvalues", res.corr_eig, res.r);
    int ncol = 0;
    for (int k = 0; k < res.r; k++)
        ncol += res.gram_eig[k] < a->threshold;
    printf("collapse: %d of %d dimensions below %.3g (smallest normalized eigenvalue %.4g; tr J^T M J / m = %.6g "
           "m^2)\n", ncol, res.r, a->threshold, res.gram_eig[0], res.gram_trace);
    if (cli->verbose)
        crom_cli_info(cli, "material %s", matsrc);
out:
    crom_metrics_free(&res);
    crom_system_free(&fem);
    crom_map_free(&map);
    crom_map_free(&cmap);
    crom_model_free(&model);
    crom_model_free(&cmpm);
    crom_mesh_free(&mesh);
    return rc;
}

int main(int argc, char **argv)
{
    crom_cli cli;
    args a;
    memset(&a, 0, sizeof a);
    crom_metrics_defaults(&a.mo);
    crom_scenario_defaults(&a.sc);
    a.threshold = 0.01;
    crom_cli_parse(&cli, &doc, argc, argv, on_opt, &a);
    if (crom_scenario_uniform(&a.sc, "crom-metrics"))
        return crom_cli_exit(&cli, CROM_EUSAGE);
    return crom_cli_exit(&cli, run(&cli, &a));
}
