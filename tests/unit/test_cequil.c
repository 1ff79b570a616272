/* test_cequil.c — constrained equilibria at modal coordinates
 * (lib/phys/cequil.h) on a clamped shell strip, a free square sheet and a
 * clamped solid bar: the constraint holds to round-off, the unbalanced
 * force vanishes, the energy is stationary along feasible directions and
 * below that of the linear modes at the same z, small z gives the linear
 * mode back to second order, and the modal forces are the derivative of the
 * equilibrium energy with respect to z (a finite-difference check); bad
 * modes are refused. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fixtures.h"
#include "base/err.h"
#include "base/rng.h"
#include "mesh/meshgen.h"
#include "phys/cequil.h"
#include "phys/modes.h"
#include "phys/system.h"

typedef struct {
    crom_mesh mesh;
    crom_system sys;
    unsigned char *fixed;
    double *W; /* [n][r], W^T M W / m = I, as crom-modes stores them */
    int r;
    const char *name;
} body;

static int body_modes(body *b, double E, double nu, double rho, int pinned, const char *ref, int r)
{
    const char *refs[1] = {ref};
    int npinned = 0, n = 3 * b->mesh.nv;
    crom_material mat;
    crom_material_init(&mat, E, nu, rho);
    crom_modes_opts mo;
    crom_modes_defaults(&mo);
    mo.count = r;
    crom_modes modes;
    memset(&modes, 0, sizeof modes);
    if (crom_modes_pins(&b->mesh, pinned, refs, &b->fixed, &npinned) ||
        crom_modes_compute(&b->mesh, &mat, b->fixed, &mo, &modes) || crom_system_init(&b->sys, &b->mesh, E, nu, rho))
        return 1;
    b->r = r;
    b->W = malloc(sizeof(double) * (size_t)n * r);
    double s = sqrt(b->sys.total_mass);
    for (size_t i = 0; i < (size_t)n * r; i++)
        b->W[i] = s * modes.phi[i];
    crom_modes_free(&modes);
    return 0;
}

static int sheet(body *b, double w, double size, double thick, int pinned, const char *name)
{
    memset(b, 0, sizeof *b);
    b->name = name;
    crom_meshgen_opts o;
    crom_meshgen_defaults(&o, CROM_MESHGEN_SHEET);
    o.dims[0] = w;
    o.dims[1] = 1;
    o.size = size;
    o.thickness = thick;
    if (crom_meshgen_sheet(&o, &b->mesh))
        return 1;
    return body_modes(b, 1e9, 0.3, 1000, pinned, "y<-0.45", 3);
}

static void body_free(body *b)
{
    crom_system_free(&b->sys);
    crom_mesh_free(&b->mesh);
    free(b->fixed);
    free(b->W);
}

static double modal(const body *b, const double *x, int k)
{
    double s = 0;
    for (int i = 0; i < b->sys.n; i++)
        s += b->sys.mass[i / 3] * b->W[(size_t)i * b->r + k] * (x[i] - b->mesh.X[i]);
    return s / b->sys.total_mass;
}

/* x = X + W z */
static void linear(const body *b, const double *z, double *x)
{
    for (int i = 0; i < b->sys.n; i++) {
        x[i] = b->mesh.X[i];
        for (int k = 0; k < b->r; k++)
            x[i] += b->W[(size_t)i * b->r + k] * z[k];
    }
}

static int solve(crom_cequil *c, const body *b, const double *z, double *x, double *lam, crom_cequil_stats *st)
{
    linear(b, z, x);
    int rc = crom_cequil_solve(c, z, x, lam, st);
    CHECK_MSG(rc == 0, "%s: %s", b->name, crom_errmsg());
    return rc;
}

/* z moves the body by a fraction of its size: the checks of the header. */
static void test_body(body *b, double zscale)
{
    int n = b->sys.n, r = b->r;
    crom_cequil c;
    crom_cequil_opts o;
    crom_cequil_defaults(&o);
    CHECK(crom_cequil_init(&c, &b->sys, &b->mesh, b->fixed, r, b->W, &o) == 0);
    double *x = malloc(sizeof(double) * n), *xl = malloc(sizeof(double) * n), *g = malloc(sizeof(double) * n);
    double *v = malloc(sizeof(double) * n), *xp = malloc(sizeof(double) * n), lam[8], z[8], zp[8];
    crom_cequil_stats st;
    for (int k = 0; k < r; k++)
        z[k] = zscale * (k == 0 ? 1.0 : 0.4 / (k + 1));
    if (solve(&c, b, z, x, lam, &st))
        goto out;
    /* the constraint, the pins */
    double cz = 0, pin = 0;
    for (int k = 0; k < r; k++)
        cz = fmax(cz, fabs(modal(b, x, k) - z[k]));
    for (int i = 0; i < n; i++)
        if (b->fixed && b->fixed[i])
            pin = fmax(pin, fabs(x[i] - b->mesh.X[i]));
    /* energies: the equilibrium against the linear modes at the same z */
    double Eeq = 0, Elin = 0;
    linear(b, z, xl);
    CHECK(crom_system_energy(&b->sys, x, &Eeq) == 0 && crom_system_energy(&b->sys, xl, &Elin) == 0);
    /* the unbalanced force, against that of the linear configuration */
    double feq = crom_cequil_unbalanced(&b->sys, b->fixed, r, b->W, x, g, NULL);
    double flin = crom_cequil_unbalanced(&b->sys, b->fixed, r, b->W, xl, g, NULL);
    fprintf(stderr, "%s: z = %.3g m: %d Newton iterations, |z(x*) - z| %.1e, pins %.1e, E* %.5g J against %.5g J with "
                    "the linear modes, unbalanced force %.2e N (linear %.2e N)\n",
            b->name, zscale, st.newton, cz, pin, Eeq, Elin, feq, flin);
    CHECK_LT(cz, 1e-12 * zscale + 1e-15);
    CHECK(pin == 0);
    if (!b->fixed || !memchr(b->fixed, 1, (size_t)n)) { /* a free body: no net translation of the mass */
        double t[3] = {0, 0, 0};
        for (int i = 0; i < n; i++)
            t[i % 3] += b->sys.mass[i / 3] * (x[i] - b->mesh.X[i]) / b->sys.total_mass;
        fprintf(stderr, "%s: mean displacement %.1e %.1e %.1e m\n", b->name, t[0], t[1], t[2]);
        CHECK_LT(fabs(t[0]) + fabs(t[1]) + fabs(t[2]), 1e-11);
    }
    CHECK(Eeq < Elin);
    CHECK_NEAR(st.energy, Eeq, 1e-12 * fabs(Eeq));
    CHECK_LT(feq, 1e-7 * flin);
    /* stationary along a feasible direction v (pins 0, W^T M v = 0): the
     * central difference of E is O(h^2), the one-sided one O(h) and >= 0 */
    crom_rng rng;
    crom_rng_seed(&rng, 5);
    for (int i = 0; i < n; i++)
        v[i] = b->fixed && b->fixed[i] ? 0 : crom_rng_uniform(&rng) - 0.5;
    for (int k = 0; k < r; k++) {
        double p = 0;
        for (int i = 0; i < n; i++)
            p += b->sys.mass[i / 3] * b->W[(size_t)i * r + k] * v[i];
        p /= b->sys.total_mass;
        for (int i = 0; i < n; i++)
            v[i] -= p * b->W[(size_t)i * r + k];
    }
    double vmax = 0;
    for (int i = 0; i < n; i++)
        vmax = fmax(vmax, fabs(v[i]));
    double h = 1e-6 * zscale / vmax, Ep, Em;
    for (int i = 0; i < n; i++)
        xp[i] = x[i] + h * v[i];
    CHECK(crom_system_energy(&b->sys, xp, &Ep) == 0);
    for (int i = 0; i < n; i++)
        xp[i] = x[i] - h * v[i];
    CHECK(crom_system_energy(&b->sys, xp, &Em) == 0);
    double slope = (Ep - Em) / (2 * h), curv = (Ep + Em - 2 * Eeq) / (h * h);
    fprintf(stderr, "%s: along a random feasible direction dE/dt %.2e J/unit, d2E/dt2 %.3g J/unit^2\n", b->name, slope,
            curv);
    CHECK_LT(fabs(slope) * h, 1e-3 * curv * h * h + 1e-12 * fabs(Eeq));
    CHECK(curv > 0);
    /* d E(x*(z)) / dz_k = -lambda_k: central differences of the equilibrium energy */
    double worst = 0;
    for (int k = 0; k < r; k++) {
        double dz = 1e-4 * zscale, Epk, Emk;
        memcpy(zp, z, sizeof z);
        zp[k] = z[k] + dz;
        memcpy(xp, x, sizeof(double) * n);
        CHECK(crom_cequil_solve(&c, zp, xp, NULL, &st) == 0);
        Epk = st.energy;
        zp[k] = z[k] - dz;
        memcpy(xp, x, sizeof(double) * n);
        CHECK(crom_cequil_solve(&c, zp, xp, NULL, &st) == 0);
        Emk = st.energy;
        double fd = (Epk - Emk) / (2 * dz);
        worst = fmax(worst, fabs(fd + lam[k]) / (fabs(lam[0]) + 1e-300));
    }
    fprintf(stderr, "%s: modal forces against FD of E*(z): worst relative difference %.2e\n", b->name, worst);
    CHECK_LT(worst, 1e-5);
    /* small z: the equilibrium is the linear mode to second order */
    double zs[8], dev[2];
    for (int t = 0; t < 2; t++) {
        for (int k = 0; k < r; k++)
            zs[k] = z[k] * (t ? 1e-3 : 2e-3);
        if (solve(&c, b, zs, x, NULL, &st))
            goto out;
        linear(b, zs, xl);
        dev[t] = 0;
        for (int i = 0; i < n; i++)
            dev[t] = fmax(dev[t], fabs(x[i] - xl[i]));
    }
    fprintf(stderr, "%s: |x* - (X + W z)| at 2e-3 and 1e-3 of z: %.3g, %.3g m (ratio %.2f, 4 for second order)\n",
            b->name, dev[0], dev[1], dev[0] / dev[1]);
    CHECK(dev[0] / dev[1] > 3.5 && dev[0] / dev[1] < 4.5);
out:
    crom_cequil_free(&c);
    free(x), free(xl), free(g), free(v), free(xp);
}

static void test_bad(body *b)
{
    int n = b->sys.n, r = b->r;
    crom_cequil c;
    crom_cequil_opts o;
    crom_cequil_defaults(&o);
    double *W = malloc(sizeof(double) * (size_t)n * r);
    memcpy(W, b->W, sizeof(double) * (size_t)n * r);
    for (int i = 0; i < n; i++)
        W[(size_t)i * r] *= 2;
    CHECK(crom_cequil_init(&c, &b->sys, &b->mesh, b->fixed, r, W, &o) == CROM_EUSAGE);
    CHECK(strstr(crom_errmsg(), "M-orthonormal") != NULL);
    memcpy(W, b->W, sizeof(double) * (size_t)n * r);
    for (int i = 0; i < n; i++)
        if (b->fixed[i]) {
            W[(size_t)i * r + 1] = 1e-3;
            break;
        }
    CHECK(crom_cequil_init(&c, &b->sys, &b->mesh, b->fixed, r, W, &o) == CROM_EUSAGE);
    CHECK(strstr(crom_errmsg(), "pinned") != NULL);
    o.tol = -1;
    CHECK(crom_cequil_init(&c, &b->sys, &b->mesh, b->fixed, r, b->W, &o) == CROM_EUSAGE);
    crom_cequil_defaults(&o);
    CHECK(crom_cequil_init(&c, &b->sys, &b->mesh, b->fixed, r, b->W, &o) == 0);
    double z[3] = {NAN, 0, 0};
    double *xs = malloc(sizeof(double) * n);
    linear(b, (double[]){0, 0, 0}, xs);
    CHECK(crom_cequil_solve(&c, z, xs, NULL, NULL) == CROM_EUSAGE);
    crom_cequil_free(&c);
    free(W), free(xs);
    crom_err_clear();
}

int main(void)
{
    check_begin("test_cequil");
    body b;
    /* a clamped strip 0.3 x 1 m, 1 cm thick: bending locks the linear modes */
    if (sheet(&b, 0.3, 0.05, 0.01, 1, "clamped strip") == 0) {
        test_body(&b, 0.05);
        test_bad(&b);
    } else
        CHECK_MSG(0, "strip: %s", crom_errmsg());
    body_free(&b);
    /* a free square sheet (no pins: the rigid motions are left to mu M) */
    if (sheet(&b, 1, 0.1, 0.01, 0, "free square") == 0)
        test_body(&b, 0.02);
    else
        CHECK_MSG(0, "square: %s", crom_errmsg());
    body_free(&b);
    /* a clamped solid bar of stable neo-Hookean tets */
    memset(&b, 0, sizeof b);
    b.name = "clamped bar";
    crom_rng rng;
    crom_rng_seed(&rng, 3);
    const double lo[3] = {-0.5, -0.05, -0.05};
    fx_box_mesh(&b.mesh, 10, 1, 1, lo, 0.1, 0.1, &rng, NULL);
    if (body_modes(&b, 1e6, 0.3, 1000, 1, "x<-0.45", 3) == 0)
        test_body(&b, 0.05);
    else
        CHECK_MSG(0, "bar: %s", crom_errmsg());
    body_free(&b);
    return check_done();
}
