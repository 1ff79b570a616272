/* test_rigid.c — rigid bodies as frames of four lumped masses (lib/phys/
 * rigid.h): exact inertia of tet meshes against a box's closed form, the
 * frame's lumped kinetic energy equal to the body's for any affine motion,
 * points carried by the frame, the orthogonality potential zero on rigid
 * motions and its gradient and Hessian against finite differences
 * (stretched, sheared and near-rigid frames), and the pin and joint
 * penalties likewise. */
#include <lapacke.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fixtures.h"
#include "base/rng.h"
#include "phys/rigid.h"

/* ---------------------------------------------------------------- inertia */

/* ½ ∫ρ |L X + u|² dV over a tet mesh, exactly (quadratic in X: the tet's
 * second-moment formula), and over the frame's four lumped masses */
static double mesh_kinetic(const crom_mesh *m, double rho, const double L[9], const double u[3])
{
    double K = 0;
    for (int t = 0; t < m->nt; t++) {
        const int *v = m->tets + 4 * (size_t)t;
        double V = crom_mesh_tet_volume(m->X + 3 * v[0], m->X + 3 * v[1], m->X + 3 * v[2], m->X + 3 * v[3]);
        double w[4][3], s[3] = {0, 0, 0};
        for (int i = 0; i < 4; i++)
            for (int a = 0; a < 3; a++) {
                const double *X = m->X + 3 * v[i];
                w[i][a] = L[3 * a] * X[0] + L[3 * a + 1] * X[1] + L[3 * a + 2] * X[2] + u[a];
                s[a] += w[i][a];
            }
        double q = s[0] * s[0] + s[1] * s[1] + s[2] * s[2];
        for (int i = 0; i < 4; i++)
            q += w[i][0] * w[i][0] + w[i][1] * w[i][1] + w[i][2] * w[i][2];
        K += 0.5 * rho * V / 20 * q;
    }
    return K;
}

static double frame_kinetic(const crom_rigid_inertia *in, const double Y[12], const double L[9],
                            const double u[3])
{
    double K = 0;
    for (int k = 0; k < 4; k++)
        for (int a = 0; a < 3; a++) {
            const double *X = Y + 3 * k;
            double v = L[3 * a] * X[0] + L[3 * a + 1] * X[1] + L[3 * a + 2] * X[2] + u[a];
            K += 0.5 * in->m / 4 * v * v;
        }
    return K;
}

static void test_inertia_and_frame(void)
{
    /* a box [0.1, 0.7] x [-0.2, 0.2] x [0.3, 0.55] as Kuhn-split cubes: its
     * inertia from the tets is the closed form */
    crom_mesh m;
    crom_rng rng;
    crom_rng_seed(&rng, 7);
    const double lo[3] = {0.1, -0.2, 0.3};
    const double h[3] = {0.6 / 12, 0.4 / 8, 0.25 / 5};
    fx_grid(&m, 12, 8, 5, lo, h, 0, NULL, NULL, 1);
    crom_rigid_inertia it, ib;
    CHECK(crom_rigid_inertia_tets(&m, 800, &it) == 0);
    const double a[3] = {0.6, 0.4, 0.25}, c[3] = {0.4, 0, 0.425};
    crom_rigid_inertia_box(a, c, 800, &ib);
    CHECK_NEAR(it.m, ib.m, 1e-12 * ib.m);
    for (int k = 0; k < 3; k++)
        CHECK_NEAR(it.c[k], ib.c[k], 1e-13);
    CHECK_LT(check_relerr(it.S, ib.S, 9, 0), 1e-12);

    /* a jittered mesh: the frame's four masses carry its kinetic energy
     * exactly for random affine motions */
    crom_mesh j;
    fx_grid(&j, 6, 5, 4, lo, h, 0.3, &rng, NULL, 1);
    CHECK(crom_rigid_inertia_tets(&j, 1200, &it) == 0);
    double Y[12], B[9];
    CHECK(crom_rigid_frame(&it, Y) == 0);
    CHECK(crom_rigid_frame_inverse(Y, B) == 0);
    double worst = 0;
    for (int trial = 0; trial < 5; trial++) {
        double L[9], u[3];
        for (int i = 0; i < 9; i++)
            L[i] = crom_rng_normal(&rng);
        for (int i = 0; i < 3; i++)
            u[i] = crom_rng_normal(&rng);
        double Km = mesh_kinetic(&j, 1200, L, u), Kf = frame_kinetic(&it, Y, L, u);
        worst = fmax(worst, fabs(Km - Kf) / Km);
    }
    fprintf(stderr, "affine kinetic energy, frame against the mesh: largest relative difference %.1e\n", worst);
    CHECK_LT(worst, 1e-12);

    /* points ride on the frame: a rigid motion of the frame moves every
     * vertex by the same motion, and the affine map recovers it */
    double Q[9], t[3] = {0.3, -1.2, 0.7}, y[12];
    fx_random_rotation(&rng, Q);
    for (int k = 0; k < 4; k++)
        for (int i = 0; i < 3; i++)
            y[3 * k + i] = Q[3 * i] * Y[3 * k] + Q[3 * i + 1] * Y[3 * k + 1] + Q[3 * i + 2] * Y[3 * k + 2] + t[i];
    double R[9], tt[3], err = 0;
    crom_rigid_affine(Y, B, y, R, tt);
    CHECK_LT(check_relerr(R, Q, 9, 1), 1e-13);
    CHECK_LT(check_relerr(tt, t, 3, 1), 1e-13);
    for (int v = 0; v < j.nv; v++) {
        double beta[4], x[3];
        crom_rigid_coords(Y, B, j.X + 3 * v, beta);
        CHECK_NEAR(beta[0] + beta[1] + beta[2] + beta[3], 1, 1e-13);
        for (int i = 0; i < 3; i++) {
            x[i] = beta[0] * y[i] + beta[1] * y[3 + i] + beta[2] * y[6 + i] + beta[3] * y[9 + i];
            double e = Q[3 * i] * j.X[3 * v] + Q[3 * i + 1] * j.X[3 * v + 1] + Q[3 * i + 2] * j.X[3 * v + 2] + t[i];
            err = fmax(err, fabs(x[i] - e));
        }
    }
    CHECK_LT(err, 1e-13);
    /* the orthogonality potential vanishes on the rigid motion, with its gradient */
    double E, g[12];
    CHECK(crom_rigid_ortho(B, 5, y, 0, &E, g, NULL) == 0);
    CHECK_LT(E, 1e-26);
    double gn = 0;
    for (int i = 0; i < 12; i++)
        gn = fmax(gn, fabs(g[i]));
    CHECK_LT(gn, 1e-12);

    /* bad input */
    crom_rigid_inertia flat = ib;
    flat.S[8] = 0;
    CHECK(crom_rigid_frame(&flat, Y) == CROM_EDATA);
    crom_err_clear();
    CHECK(crom_rigid_inertia_tets(&j, -1, &it) == CROM_EUSAGE);
    crom_err_clear();
    crom_mesh_free(&m);
    crom_mesh_free(&j);
}

/* ------------------------------------------------------------ derivatives */

typedef struct {
    const double *B, *beta, *gamma, *target;
    double w;
    int kind; /* 0 ortho, 1 pin, 2 joint */
} ectx;

static double e_energy(const double *y, void *ctx)
{
    ectx *c = ctx;
    double E = 0;
    if (c->kind == 0)
        crom_rigid_ortho(c->B, c->w, y, 0, &E, NULL, NULL);
    else if (c->kind == 1)
        crom_rigid_pin(c->beta, c->w, y, c->target, &E, NULL, NULL);
    else
        crom_rigid_joint(c->beta, c->gamma, c->w, y, y + 12, &E, NULL, NULL);
    return E;
}

static void e_grad(const double *y, void *ctx, double *g)
{
    ectx *c = ctx;
    if (c->kind == 0)
        crom_rigid_ortho(c->B, c->w, y, 0, NULL, g, NULL);
    else if (c->kind == 1)
        crom_rigid_pin(c->beta, c->w, y, c->target, NULL, g, NULL);
    else
        crom_rigid_joint(c->beta, c->gamma, c->w, y, y + 12, NULL, g, NULL);
}

/* floor: the gradient's scale where it vanishes (a rigid frame: the FD
 * truncation error is O(h²) there, not zero) */
static void check_element(ectx *c, double *y, int n, double floor, const char *what)
{
    double g[24], gf[24], H[576], Hf[576];
    e_grad(y, c, g);
    check_fd_gradient(e_energy, c, y, n, 1e-6, gf);
    double eg = check_relerr(g, gf, n, floor);
    if (c->kind == 0)
        crom_rigid_ortho(c->B, c->w, y, 0, NULL, NULL, H);
    else if (c->kind == 1)
        crom_rigid_pin(c->beta, c->w, y, c->target, NULL, NULL, H);
    else
        crom_rigid_joint(c->beta, c->gamma, c->w, y, y + 12, NULL, NULL, H);
    check_fd_jacobian(e_grad, c, y, n, n, 1e-6, Hf);
    double eh = check_relerr(H, Hf, n * n, 1e-8);
    fprintf(stderr, "%-34s gradient %.1e  Hessian %.1e\n", what, eg, eh);
    CHECK_MSG(eg < 1e-7, "%s: gradient off by %.2e", what, eg);
    CHECK_MSG(eh < 1e-6, "%s: Hessian off by %.2e", what, eh);
}

static void test_derivatives(void)
{
    crom_rng rng;
    crom_rng_seed(&rng, 11);
    const double a[3] = {0.5, 0.2, 0.1}, c0[3] = {0.1, 0.2, -0.3};
    crom_rigid_inertia in;
    crom_rigid_inertia_box(a, c0, 1000, &in);
    double Y[12], B[9];
    CHECK(crom_rigid_frame(&in, Y) == 0);
    CHECK(crom_rigid_frame_inverse(Y, B) == 0);
    /* frames: stretched and sheared, nearly rigid, and rotated */
    double y[24], Q[9];
    fx_random_rotation(&rng, Q);
    const double amp[3] = {0.3, 1e-3, 0};
    const char *name[3] = {"orthogonality, sheared frame", "orthogonality, near-rigid frame",
                           "orthogonality, rigid frame"};
    for (int s = 0; s < 3; s++) {
        for (int k = 0; k < 4; k++)
            for (int i = 0; i < 3; i++)
                y[3 * k + i] = Q[3 * i] * Y[3 * k] + Q[3 * i + 1] * Y[3 * k + 1] + Q[3 * i + 2] * Y[3 * k + 2] +
                               amp[s] * 0.2 * crom_rng_normal(&rng);
        ectx c = {B, NULL, NULL, NULL, 3.0, 0};
        check_element(&c, y, 12, s == 2 ? 1 : 1e-8, name[s]);
        /* the projected Hessian is PSD, and equal to the true one where that is */
        double H[144], Hp[144];
        CHECK(crom_rigid_ortho(B, 3.0, y, 0, NULL, NULL, H) == 0);
        CHECK(crom_rigid_ortho(B, 3.0, y, 1, NULL, NULL, Hp) == 0);
        double hmax = 0; /* round-off is relative to the largest entries */
        for (int i = 0; i < 144; i++)
            hmax = fmax(hmax, fabs(H[i]));
        CHECK(fx_min_eig(Hp, 12) > -1e-12 * 12 * hmax);
        if (s == 2) { /* at a rigid pose the true Hessian is PSD already */
            CHECK(fx_min_eig(H, 12) > -1e-10);
            CHECK_LT(check_relerr(Hp, H, 144, 1e-12), 1e-10);
        }
    }
    /* a pinned point and a joint between two bodies */
    double X[3] = {0.3, 0.25, -0.28}, beta[4], gamma[4], target[3] = {0.2, 0.1, 0.0};
    crom_rigid_coords(Y, B, X, beta);
    for (int i = 0; i < 24; i++)
        y[i] = (i < 12 ? Y[i] : Y[i - 12] + 0.4) + 0.05 * crom_rng_normal(&rng);
    ectx pc = {B, beta, NULL, target, 7.0, 1};
    check_element(&pc, y, 12, 1e-8, "pinned point");
    const double Xb[3] = {-0.1, 0.3, -0.2};
    crom_rigid_coords(Y, B, Xb, gamma);
    ectx jc = {B, beta, gamma, NULL, 2.0, 2};
    check_element(&jc, y, 24, 1e-8, "joint between two bodies");
    /* the pinned point's energy is its distance from the target */
    double E, x[3];
    crom_rigid_pin(beta, 7.0, y, target, &E, NULL, NULL);
    for (int i = 0; i < 3; i++)
        x[i] = beta[0] * y[i] + beta[1] * y[3 + i] + beta[2] * y[6 + i] + beta[3] * y[9 + i] - target[i];
    CHECK_NEAR(E, 3.5 * (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]), 1e-14);
}

int main(void)
{
    check_begin("test_rigid");
    test_inertia_and_frame();
    test_derivatives();
    return check_done();
}
