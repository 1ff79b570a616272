/* crom-modes — linear vibration modes of a mesh with its pins, as a
 * crom/model: the classic linear modal basis, a baseline for the reduced
 * pipeline and the linear part of Neural Modes. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "cli/cli.h"
#include "io/io.h"
#include "mesh/mesh.h"
#include "phys/fem.h"
#include "phys/mderiv.h"
#include "phys/modes.h"
#include "phys/system.h"
#include "phys/scenario.h"
#include "rom/model.h"

enum { O_COUNT = 300, O_KEEP, O_SHIFT, O_TOL, O_RIGID_TOL, O_DERIV, O_FIELDS };

static const crom_opt modes_opts[] = {
    {"count", O_COUNT, "K", "Number of modes in the basis (default 20): deformation modes, plus the rigid ones in front with --keep-rigid (then K counts them too)."},
    {"keep-rigid", O_KEEP, NULL, "Keep the rigid-body modes that were detected (zero frequency) at the front of the basis, as translations x, y, z then rotations about x, y, z through the centre of mass, as far as the pins allow them. Default: drop them, so the basis holds K deformation modes. A free body that must move as a whole in crom-reducedstep (a falling or thrown body) needs them: translations are then exact, rotations linearized (good for small angles)."},
    {"derivatives", O_DERIV, NULL, "Append the modal derivatives of the K modes (Barbic and James 2005: K Psi_ij = -(dK/du . phi_j) phi_i at rest, i <= j): a linear basis of K + K(K+1)/2 fields (fewer where a derivative depends on the others), M-orthonormal, that follows larger deflections than the modes alone (the in-plane shortening a bent beam or shell needs not to lock). The body must be pinned. /frequencies then holds each field's Rayleigh frequency, and the attribute 'derivatives' their count."},
    {"fields", O_FIELDS, "R", "With --derivatives: keep the first R fields of the basis, the K modes then the derivatives in the order (1,1), (1,2) ... (1,K), (2,2) ... (default: all of them)."},
    {"shift", O_SHIFT, "SIGMA", "Shift of the shift-invert Lanczos iteration in rad^2/s^2, negative (default -0.01 E / (rho D^2), D the bounding-box diagonal): K - SIGMA M is factored once."},
    {"tol", O_TOL, "T", "Convergence tolerance on the Ritz residuals, relative (default 1e-10)."},
    {"rigid-tol", O_RIGID_TOL, "T", "A mode is rigid when omega^2 <= T times the mean eigenvalue of M^-1 K (default 1e-12: rigid modes come out near 1e-17 of it, the first deformation mode of a rod 100 times longer than thick, meshed 4 tets across, near 6e-9)."},
    {"output", 'o', "OUT", "Write the model to OUT (default stdout)."},
    {NULL, 0, NULL, NULL}};

/* The scenario options split in two tables at start-up: those crom-modes
 * uses, and the rest (accepted, so one @FILE serves every stage). */
static crom_opt used_opts[8], ignored_opts[40];

static crom_cli_optgroup groups[] = {
    {"Material and boundary conditions (the scenario options of crom-fullsim)", used_opts},
    {"Options", modes_opts},
    {"Other scenario options (accepted and ignored: modes are computed at rest)", ignored_opts},
    {NULL, NULL}};

static const crom_cli_doc doc = {
    "crom-modes",
    "linear vibration modes of a mesh with its pins (crom/mesh to crom/model)",
    "crom-modes [--youngs E] [--poisson NU] [--density RHO] [--pin REGION ...] [--count K]\n"
    "           [--keep-rigid] [--derivatives [--fields R]] [-o OUT] [MESH|-]",
    "Computes the lowest natural frequencies and mode shapes of the generalized eigenproblem "
    "K phi = omega^2 M phi at rest: K is the stiffness of the stable neo-Hookean energy at the rest "
    "state (the same element code as crom-fullsim, unprojected; at rest it is linear elasticity "
    "with the given E and nu), M the lumped mass. A shell surface (crom-mesh sheet, disk, import "
    "--thickness) gets the modes of its StVK membrane and hinge bending with its thickness (M: rho t A "
    "/ 3 per triangle corner), and the model keeps its triangles: it decodes onto that shell only. "
    "The vertices of --pin regions are eliminated, "
    "not penalized: the problem is solved on the free degrees of freedom only. Regions given by "
    "--velocity are not held here.\n\n"
    "The lowest pairs come from ARPACK's implicitly restarted Lanczos iteration (dsaupd, M inner "
    "products) in shift-invert mode on one sparse Cholesky factor of K - sigma M (CHOLMOD with a "
    "METIS ordering), sigma slightly negative so that the factor exists for a free body too. "
    "Rigid-body modes are built, not searched for: the translations and rotations of each connected "
    "piece that its pins allow (a free body has six, one pinned at a point three, at a line one) "
    "are kept out of the iteration, and a last run from another start vector finds any copy of a "
    "repeated frequency it missed.\n\n"
    "The output is a crom/model with basis 'modes': a piecewise-linear field on the mesh whose r "
    "fields are the mode shapes, ordered by frequency, and /frequencies in Hz. As for every "
    "crom/model, W is dimensionless and q in metres: the fields are orthonormal in the mass mean "
    "(W^T M W = m I with m the body's mass, stored as the attribute 'mass'), so Phi = W / sqrt(m) "
    "is M-orthonormal. The attributes also record the material and the pins (as the flags "
    "'scenario') and how many rigid modes were found. crom-cubature and crom-reducedstep take the "
    "model like any other, so the reduced pipeline runs a classic linear modal model.\n\n"
    "An info line gives the frequency range and the rigid modes found; --verbose adds the "
    "frequencies, residuals, the shift and the timing of assembly, factorization and Lanczos.",
    groups,
    "crom-mesh box --dims 1,0.1,0.1 --size 0.02 --region clamp='x<-0.49' -o beam.h5\n"
    "crom-modes --youngs 1e6 --poisson 0 --pin clamp --count 10 -v -o modes.h5 beam.h5\n"
    "crom-cubature --model modes.h5 --scheme all beam.h5 \\\n"
    "  | crom-reducedstep --cubature - --pin clamp --youngs 1e6 --poisson 0 -o latent.h5",
    "crom-fullsim(1), crom-cubature(1), crom-reducedstep(1), crom-fitfield(1), crom-info(1)"};

typedef struct {
    crom_scenario sc;
    const char *input, *out;
    crom_modes_opts mo;
    int derivatives, fields;
} args;

/* Scenario options crom-modes uses; the others are accepted and ignored. */
static int sc_used(const char *name)
{
    static const char *used[] = {"youngs", "poisson", "density", "pin", NULL};
    for (int i = 0; used[i]; i++)
        if (!strcmp(name, used[i]))
            return 1;
    return 0;
}

static void split_scenario_opts(void)
{
    int nu = 0, ni = 0;
    for (const crom_opt *o = crom_scenario_opts; o->name; o++) {
        if (sc_used(o->name)) {
            if (nu < 7)
                used_opts[nu++] = *o;
        } else if (ni < 39)
            ignored_opts[ni++] = *o;
    }
}

static int on_opt(void *ctx, int key, const char *v)
{
    args *a = ctx;
    int rc = crom_scenario_option(&a->sc, key, v);
    if (rc >= 0)
        return rc;
    long n;
    switch (key) {
    case 0:
        if (a->input)
            return crom_err(CROM_EUSAGE, "unexpected operand '%s' (one mesh)", v);
        a->input = v;
        return 0;
    case 'o': a->out = v; return 0;
    case O_COUNT:
        if (crom_parse_int(v, "--count", 1, 1000000L, &n))
            return CROM_EUSAGE;
        a->mo.count = (int)n;
        return 0;
    case O_KEEP: a->mo.keep_rigid = 1; return 0;
    case O_DERIV: a->derivatives = 1; return 0;
    case O_FIELDS:
        if (crom_parse_int(v, "--fields", 1, 1000000L, &n))
            return CROM_EUSAGE;
        a->fields = (int)n;
        return 0;
    case O_SHIFT:
        if (crom_parse_double(v, "--shift", &a->mo.shift))
            return CROM_EUSAGE;
        return a->mo.shift < 0 ? 0 : crom_err(CROM_EUSAGE, "--shift must be negative, got %s", v);
    case O_TOL: return crom_parse_positive(v, "--tol", &a->mo.tol);
    case O_RIGID_TOL: return crom_parse_positive(v, "--rigid-tol", &a->mo.rigid_tol);
    }
    return crom_err(CROM_EINTERNAL, "unhandled option");
}

/* The material and the pins as flags (they parse back with the scenario
 * parser). */
static char *scenario_text(const crom_scenario *s)
{
    size_t cap = 256 + (size_t)s->npins * 140;
    char *t = crom_malloc(cap);
    if (!t)
        return NULL;
    size_t l = (size_t)snprintf(t, cap, "--youngs %.17g\n--poisson %.17g\n--density %.17g\n", s->youngs,
                                s->poisson, s->density);
    for (int i = 0; i < s->npins; i++)
        l += (size_t)snprintf(t + l, cap - l, "--pin %s\n", s->pins[i]);
    return t;
}

/* Write the basis phi [n][k] (M-orthonormal) with its frequencies freq [k]
 * (nderiv of the fields modal derivatives) as a modes model. */
static int write_model(crom_cli *cli, const args *a, const crom_mesh *m, const crom_modes *r, const double *phi,
                       int k, const double *freq, int nderiv, double mass, const char *hist)
{
    int rc;
    /* W = Phi sqrt(mass): orthonormal in the mass mean, dimensionless */
    double *W = crom_malloc(sizeof(double) * (size_t)r->n * k);
    if (!W)
        return CROM_EINTERNAL;
    double s = sqrt(mass);
    for (size_t i = 0; i < (size_t)r->n * k; i++)
        W[i] = phi[i] * s;
    crom_model model;
    rc = crom_model_from_mesh(&model, "modes", m, W, k);
    free(W);
    if (rc)
        return rc;
    model.frequencies = crom_malloc(sizeof(double) * (size_t)k);
    char *text = scenario_text(&a->sc);
    if (!model.frequencies || !text) {
        free(text);
        crom_model_free(&model);
        return CROM_EINTERNAL;
    }
    memcpy(model.frequencies, freq, sizeof(double) * (size_t)k);
    crom_out o;
    if ((rc = crom_out_create(&o, a->out, CROM_MODEL_SCHEMA, CROM_MODEL_VERSION, cli->cmdline, hist, CROM_OUT_PLAIN))) {
        free(text);
        crom_model_free(&model);
        return rc;
    }
    rc = crom_model_write(o.h5, &model);
    if (!rc)
        rc = crom_h5_set_str(o.h5, ".", "scenario", text);
    if (!rc)
        rc = crom_h5_set_f64(o.h5, ".", "youngs", &a->sc.youngs, 1);
    if (!rc)
        rc = crom_h5_set_f64(o.h5, ".", "poisson", &a->sc.poisson, 1);
    if (!rc)
        rc = crom_h5_set_f64(o.h5, ".", "density", &a->sc.density, 1);
    if (!rc)
        rc = crom_h5_set_f64(o.h5, ".", "mass", &mass, 1);
    if (!rc)
        rc = crom_h5_set_i64(o.h5, ".", "rigid_modes", r->nrigid);
    if (!rc)
        rc = crom_h5_set_i64(o.h5, ".", "rigid_kept", r->rigid_kept);
    if (!rc && nderiv)
        rc = crom_h5_set_i64(o.h5, ".", "derivatives", nderiv);
    if (!rc)
        rc = crom_out_commit(&o);
    else
        crom_out_fail(&o);
    free(text);
    crom_model_free(&model);
    return rc;
}

static void report(crom_cli *cli, const crom_mesh *m, int npinned, const crom_modes *r)
{
    int k = r->k;
    double total = r->t_assemble + r->t_analyze + r->t_factor + r->t_lanczos;
    char rig[160];
    if (r->nrigid)
        snprintf(rig, sizeof rig, "%d rigid mode%s detected (%s)", r->nrigid, r->nrigid > 1 ? "s" : "",
                 r->rigid_kept ? "kept in front" : "dropped; --keep-rigid keeps them");
    else
        snprintf(rig, sizeof rig, "no rigid mode");
    crom_cli_info(cli, "%d modes, %.6g to %.6g Hz; %s; %.2f s", k, r->freq[0], r->freq[k - 1], rig, total);
    if (!cli->verbose)
        return;
    crom_cli_info(cli, "%d vertices, %d tets, %d pinned: %d free degrees of freedom of %d; shift %.6g rad^2/s^2",
                  m->nv, m->nt, npinned, r->nfree, r->n, r->sigma);
    crom_cli_info(cli, "assembly %.3f s, analysis %.3f s, factorization %.3f s, Lanczos %.3f s (%ld solves, "
                       "%d restarts, basis of %d)",
                  r->t_assemble, r->t_analyze, r->t_factor, r->t_lanczos, r->solves, r->restarts, r->basis_max);
    double first = NAN;
    for (int j = 0; j < k; j++)
        if (!(r->rigid_kept && j < r->nrigid)) {
            first = r->omega2[j];
            break;
        }
    if (!isfinite(first))
        first = r->next_omega2;
    crom_cli_info(cli, "rigid: omega^2 <= %.3g rad^2/s^2 (%.0e of the mean eigenvalue %.4g); %d found, the "
                       "first deformation mode at %.4g rad^2/s^2 (%.3g times the threshold)",
                  r->rigid_threshold, r->rigid_threshold / r->lambda_mean, r->lambda_mean, r->nrigid, first,
                  first / r->rigid_threshold);
    for (int j = 0; j < k; j++)
        crom_cli_info(cli, "mode %d: %.8g Hz, omega^2 %.8g rad^2/s^2, residual %.1e%s", j + 1, r->freq[j],
                      r->omega2[j], r->residual[j], r->rigid_kept && j < r->nrigid ? " (rigid)" : "");
}

static int run(crom_cli *cli, args *a)
{
    int rc = crom_scenario_check(&a->sc);
    if (rc)
        return rc;
    crom_material mat;
    if ((rc = crom_material_init(&mat, a->sc.youngs, a->sc.poisson, a->sc.density)))
        return rc;
    crom_mesh m;
    char *hist = NULL;
    const char *name = !a->input || !strcmp(a->input, "-") ? "stdin" : a->input; /* as crom_in names it */
    if ((rc = crom_mesh_load(a->input, CROM_MESH_SURFACES, &m, &hist)))
        return rc;
    unsigned char *fixed = NULL;
    int npinned = 0;
    crom_modes r;
    memset(&r, 0, sizeof r);
    if ((rc = crom_modes_scenario_pins(&m, &a->sc, &fixed, &npinned)))
        goto out;
    a->mo.seed = cli->seed;
    a->mo.nthreads = cli->threads;
    a->mo.materials = &a->sc; /* (regions of other materials) */
    if ((rc = crom_modes_compute(&m, &mat, fixed, &a->mo, &r))) {
        if (rc == CROM_EUSAGE && strstr(crom_errmsg(), "asked for")) {
            char msg[512];
            snprintf(msg, sizeof msg, "%s", crom_errmsg());
            crom_err(rc, "--count %d: %s (%s: %d vertices, %d pinned)", a->mo.count, msg, name, m.nv, npinned);
        }
        goto out;
    }
    if (a->fields && !a->derivatives) {
        rc = crom_err(CROM_EUSAGE, "--fields applies to --derivatives (the modes alone: --count)");
        goto out;
    }
    if (a->fields && a->fields < r.k) {
        rc = crom_err(CROM_EUSAGE, "--fields %d keeps fewer fields than the %d modes (use --count)", a->fields, r.k);
        goto out;
    }
    if (a->derivatives && r.nrigid) {
        rc = crom_err(CROM_EDATA, "--derivatives: %s moves rigidly (%d rigid mode%s) and its stiffness is singular; "
                      "pin it so that it cannot", name, r.nrigid, r.nrigid > 1 ? "s" : "");
        goto out;
    }
    report(cli, &m, npinned, &r);
    double mass = mat.rho * crom_mesh_volume(&m);
    if (a->derivatives) { /* the modes and their derivatives, one linear basis */
        crom_system sys;
        double *B = NULL, *f = NULL;
        int kb = 0;
        if ((rc = crom_system_init(&sys, &m, a->sc.youngs, a->sc.poisson, a->sc.density)))
            goto out;
        rc = crom_system_set_materials(&sys, &a->sc, &m);
        if (!rc)
            rc = crom_mderiv_basis(&sys, m.X, fixed, r.phi, r.k, &B, &kb, &f);
        crom_system_free(&sys);
        int independent = kb - r.k;
        if (!rc && a->fields && a->fields < kb) { /* the first fields: B is [n][kb] row-major */
            for (int i = 0; i < r.n; i++)
                memmove(B + (size_t)i * a->fields, B + (size_t)i * kb, sizeof(double) * (size_t)a->fields);
            kb = a->fields;
        }
        if (!rc) {
            crom_cli_info(cli, "%d modal derivatives appended (%d of %d independent%s): a basis of %d fields",
                          kb - r.k, independent, r.k * (r.k + 1) / 2,
                          kb - r.k < independent ? ", the first kept by --fields" : "", kb);
            rc = write_model(cli, a, &m, &r, B, kb, f, kb - r.k, mass, hist);
        }
        free(B);
        free(f);
        goto out;
    }
    rc = write_model(cli, a, &m, &r, r.phi, r.k, r.freq, 0, mass, hist);
out:
    crom_modes_free(&r);
    free(fixed);
    free(hist);
    crom_mesh_free(&m);
    return rc;
}

int main(int argc, char **argv)
{
    crom_cli cli;
    args a;
    memset(&a, 0, sizeof a);
    crom_scenario_defaults(&a.sc);
    crom_modes_defaults(&a.mo);
    split_scenario_opts();
    crom_cli_parse(&cli, &doc, argc, argv, on_opt, &a);
    return crom_cli_exit(&cli, run(&cli, &a));
}
