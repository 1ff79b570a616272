/* test_rom.c — reduced dynamics on a cubature: gradient and Hessian against
 * finite differences, the Galerkin projection of the full equations
 * (independent evaluation through the full FEM assembly), cubature schemes,
 * cubature switches and their schedules, boundary conditions. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <cblas.h>
#include <lapacke.h>

#include "check.h"
#include "fixtures.h"
#include "base/err.h"
#include "mesh/cutfeat.h"
#include "mesh/meshgen.h"
#include "mesh/remesh.h"
#include "phys/fem.h"
#include "phys/system.h"
#include "rom/condsched.h"
#include "rom/cubature.h"
#include "rom/fit.h"
#include "rom/model.h"
#include "io/io.h"
#include "rom/newton.h"
#include "rom/rsim.h"
#include "rom/schedule.h"

/* An analytic basis: translations, linear fields and a few quadratic
 * bending fields, W [nv][3][r]. */
#define R 15
static void analytic_basis(const crom_mesh *m, double *W)
{
    for (int v = 0; v < m->nv; v++) {
        const double *X = m->X + 3 * v;
        double f[3][R] = {{0}};
        int j = 0;
        for (int c = 0; c < 3; c++, j++) /* translations */
            f[c][j] = 1;
        for (int c = 0; c < 3; c++) /* linear: u_c = X_k */
            for (int k = 0; k < 3; k++, j++)
                f[c][j] = X[k];
        f[1][j++] = X[0] * X[0];         /* bending in y along x */
        f[2][j++] = X[0] * X[0];         /* bending in z along x */
        f[0][j] = -X[0] * X[1];          /* a compatible axial correction */
        f[1][j++] = 0.5 * X[0] * X[0];
        for (int c = 0; c < 3; c++)
            for (int jj = 0; jj < R; jj++)
                W[((size_t)v * 3 + c) * R + jj] = f[c][jj];
    }
}

static void make(crom_mesh *m, double size, const double dims[3])
{
    fx_gen(CROM_MESHGEN_BOX, dims, size, m);
    CHECK(crom_mesh_region_spec(m, "left=x<-0.49") == 0);
    CHECK(crom_mesh_region_spec(m, "right=x>0.49") == 0);
}

static crom_rsim *g_sim;
static int g_project;
static double obj(const double *q, void *ctx)
{
    (void)ctx;
    double E;
    crom_rsim_objective(g_sim, q, &E, NULL, NULL, g_project);
    return E;
}
static void grad(const double *q, void *ctx, double *g)
{
    (void)ctx;
    double E;
    crom_rsim_objective(g_sim, q, &E, g, NULL, g_project);
}

static void test_derivatives(void)
{
    crom_mesh m;
    double dims[3] = {1, 0.3, 0.3};
    make(&m, 0.12, dims);
    double *W = malloc(sizeof(double) * 3 * R * m.nv);
    analytic_basis(&m, W);
    crom_cubature c;
    crom_cubature_opts o = {CROM_CUBATURE_RANDOM, 20, 0, 0, NULL, 0, 2.5e6, 0.25, NULL, 0};
    crom_rng rng;
    crom_rng_seed(&rng, 3);
    CHECK(crom_cubature_build(&c, &m, W, R, "test", &o, &rng) == 0);
    crom_scenario sc;
    crom_scenario_defaults(&sc);
    sc.damping = 3;
    strcpy(sc.pins[sc.npins++], "left");
    crom_scenario_option(&sc, 0x1000 + 8, "right=0.5,-1,0@0:0.3"); /* --velocity */
    crom_scenario_option(&sc, 0x1000 + 9, "y>0.1=0,0,40");          /* --force */
    crom_scenario_option(&sc, 0x1000 + 10, "0,1,0,-0.16,0.4");       /* --plane */
    /* a rod, compressed (its transverse stiffness negative) with a moving rest length */
    CHECK(crom_rod_parse("--rod", "x<-0.3/x>0.3&y>0.05=800,1.2,0.1,0.3,0.2", &sc.rod[sc.nrod++]) == 0);
    crom_rsim s;
    double q0[R], qd0[R];
    crom_rng_seed(&rng, 7);
    for (int i = 0; i < R; i++) {
        q0[i] = 0.02 * crom_rng_normal(&rng);
        qd0[i] = 0.3 * crom_rng_normal(&rng);
    }
    CHECK(crom_rsim_init(&s, &c, &sc, CROM_RSIM_NEWTON, 1e5, q0, qd0) == 0);
    crom_rsim_begin_step(&s);
    g_sim = &s;
    for (g_project = 0; g_project <= 1; g_project++) {
        double q[R], g[R], H[R * R], gfd[R], Hfd[R * R], E;
        for (int i = 0; i < R; i++)
            q[i] = q0[i] + 0.01 * crom_rng_normal(&rng);
        CHECK(crom_rsim_objective(&s, q, &E, g, H, g_project) == 0);
        check_fd_gradient(obj, NULL, q, R, 1e-6, gfd);
        check_fd_jacobian(grad, NULL, q, R, R, 1e-6, Hfd);
        double eg = check_relerr(g, gfd, R, 1e-8), eh = check_relerr(H, Hfd, R * R, 1e-8);
        fprintf(stderr, "reduced gradient vs FD %.2e, Hessian vs FD %.2e (project %d)\n", eg, eh, g_project);
        CHECK_LT(eg, 1e-6);
        if (!g_project)
            CHECK_LT(eh, 1e-5);
        /* symmetric */
        double asym = 0;
        for (int i = 0; i < R; i++)
            for (int j = 0; j < R; j++)
                asym = fmax(asym, fabs(H[i * R + j] - H[j * R + i]));
        CHECK_LT(asym, 1e-9 * fabs(H[0]));
    }
    crom_rsim_free(&s);
    crom_cubature_free(&c);
    free(W);
    crom_mesh_free(&m);
}

/* Drags (crom-live's cursor springs, rsim.h crom_rsim_drag): the step's
 * objective gains exactly k/(2 m_R) Σ m_v ‖x_v − (X_v + c − X̄_R)‖² summed
 * vertex by vertex, its gradient and Hessian agree with differences, a
 * release takes it away again and a cubature switch keeps it; a free body
 * under a drag of its whole mass moves as the implicit-Euler oscillator
 * M (x_{n+1} − 2x_n + x_{n−1})/h² = −k (x_{n+1} − c), undeformed (the
 * basis holds the translations); and a force appended to the scenario
 * after step 5 with the window [5.5 h, ∞) (crom_rsim_sync_forces) gives the
 * run that has it from the start, bit for bit. */
static void test_drag(void)
{
    crom_mesh m;
    double dims[3] = {1, 0.3, 0.3};
    make(&m, 0.12, dims);
    double *W = malloc(sizeof(double) * 3 * R * m.nv);
    analytic_basis(&m, W);
    crom_cubature c;
    crom_cubature_opts o = {CROM_CUBATURE_RANDOM, 20, 0, 0, NULL, 0, 2.5e6, 0.25, NULL, 0};
    crom_rng rng;
    crom_rng_seed(&rng, 11);
    CHECK(crom_cubature_build(&c, &m, W, R, "test", &o, &rng) == 0);
    crom_scenario sc;
    crom_scenario_defaults(&sc);
    strcpy(sc.pins[sc.npins++], "left");
    double q0[R], qd0[R];
    for (int i = 0; i < R; i++) {
        q0[i] = 0.02 * crom_rng_normal(&rng);
        qd0[i] = 0.3 * crom_rng_normal(&rng);
    }
    crom_rsim s;
    CHECK(crom_rsim_init(&s, &c, &sc, CROM_RSIM_NEWTON, 1e5, q0, qd0) == 0);
    double cpt[3] = {0.7, 0.2, -0.1}, k = 250;
    CHECK(crom_rsim_drag_set(&s, "nowhere", cpt, k) == CROM_EUSAGE);
    double bad[3] = {0, NAN, 0};
    CHECK(crom_rsim_drag_set(&s, "right", bad, k) == CROM_EUSAGE);
    CHECK(crom_rsim_drag_set(&s, "right", cpt, 0) == CROM_EUSAGE);
    CHECK(s.ndrag == 0);
    crom_err_clear();
    double q[R], E0, E1, Es = 0;
    for (int i = 0; i < R; i++)
        q[i] = q0[i] + 0.01 * crom_rng_normal(&rng);
    crom_rsim_begin_step(&s);
    CHECK(crom_rsim_objective(&s, q, &E0, NULL, NULL, 0) == 0);
    CHECK(crom_rsim_drag_set(&s, "right", cpt, k) == 0 && s.ndrag == 1);
    crom_rsim_begin_step(&s);
    CHECK(crom_rsim_objective(&s, q, &E1, NULL, NULL, 0) == 0);
    /* the spring summed vertex by vertex */
    int *idx, n;
    CHECK(crom_mesh_select(&m, "right", &idx, &n) == 0);
    double mR = 0, Xb[3] = {0, 0, 0};
    for (int j = 0; j < n; j++) {
        double mv = sc.density * c.vvol[idx[j]];
        mR += mv;
        for (int cc = 0; cc < 3; cc++)
            Xb[cc] += mv * m.X[3 * idx[j] + cc];
    }
    for (int j = 0; j < n; j++) {
        int v = idx[j];
        double mv = sc.density * c.vvol[v];
        for (int cc = 0; cc < 3; cc++) {
            double u = 0;
            for (int i = 0; i < R; i++)
                u += W[((size_t)v * 3 + cc) * R + i] * q[i];
            double e = u - (cpt[cc] - Xb[cc] / mR); /* x_v − (X_v + c − X̄) */
            Es += 0.5 * k / mR * mv * e * e;
        }
    }
    free(idx);
    fprintf(stderr, "drag: the objective's spring %.10g J, summed over its %d vertices %.10g J\n", E1 - E0, n, Es);
    CHECK(Es > 0);
    CHECK_LT(fabs((E1 - E0) - Es), 1e-10 * (fabs(E0) + Es));
    /* derivatives with the drag */
    g_sim = &s;
    g_project = 0;
    double g[R], H[R * R], gfd[R], Hfd[R * R], E;
    CHECK(crom_rsim_objective(&s, q, &E, g, H, 0) == 0);
    check_fd_gradient(obj, NULL, q, R, 1e-6, gfd);
    check_fd_jacobian(grad, NULL, q, R, R, 1e-6, Hfd);
    double eg = check_relerr(g, gfd, R, 1e-8), eh = check_relerr(H, Hfd, R * R, 1e-8);
    fprintf(stderr, "drag: gradient vs FD %.2e, Hessian vs FD %.2e\n", eg, eh);
    CHECK_LT(eg, 1e-6);
    CHECK_LT(eh, 1e-5);
    /* kept across a cubature switch, moved, released */
    CHECK(crom_rsim_set_cubature(&s, &c) == 0 && s.ndrag == 1);
    crom_rsim_begin_step(&s);
    CHECK(crom_rsim_objective(&s, q, &E, NULL, NULL, 0) == 0);
    CHECK_LT(fabs(E - E1), 1e-12 * fabs(E1));
    CHECK(crom_rsim_drag_release(&s, "left") == 0);
    CHECK(crom_rsim_drag_release(&s, NULL) == 1 && s.ndrag == 0);
    crom_rsim_begin_step(&s);
    CHECK(crom_rsim_objective(&s, q, &E, NULL, NULL, 0) == 0);
    CHECK_LT(fabs(E - E0), 1e-12 * fabs(E0));
    crom_rsim_free(&s);

    /* a free body pulled by its whole mass: the discrete oscillator */
    crom_scenario fs;
    crom_scenario_defaults(&fs);
    fs.gravity[0] = fs.gravity[1] = fs.gravity[2] = 0;
    fs.dt = 0.01;
    CHECK(crom_rsim_init(&s, &c, &fs, CROM_RSIM_NEWTON, 0, NULL, NULL) == 0);
    double M = fs.density * c.mesh_volume, kk = 40 * M, target[3] = {0.05, -0.02, 0.01};
    CHECK(crom_rsim_drag_set(&s, "x>-1", target, kk) == 0); /* every vertex */
    double xp[3] = {0, 0, 0}, xc[3] = {0, 0, 0}, worst = 0, h = fs.dt, wmax = 0;
    for (int step = 0; step < 40; step++) {
        crom_rsim_stats st;
        CHECK(crom_rsim_step(&s, &st) == 0);
        double xn[3];
        for (int cc = 0; cc < 3; cc++) { /* M x_{n+1}/h² + k x_{n+1} = M (2x_n − x_{n−1})/h² + k c */
            xn[cc] = (M * (2 * xc[cc] - xp[cc]) / (h * h) + kk * target[cc]) / (M / (h * h) + kk);
            worst = fmax(worst, fabs(s.q[cc] - xn[cc])); /* q_0..2: the translations */
            wmax = fmax(wmax, fabs(xn[cc]));
        }
        for (int i = 3; i < R; i++)
            worst = fmax(worst, fabs(s.q[i])); /* undeformed */
        memcpy(xp, xc, sizeof xp);
        memcpy(xc, xn, sizeof xc);
    }
    fprintf(stderr, "drag: a free body against the implicit-Euler oscillator over 40 steps: %.2e m (motion %.3f m)\n",
            worst, wmax);
    CHECK(wmax > 0.04);
    CHECK_LT(worst, 1e-8);
    crom_rsim_free(&s);

    /* a force appended mid-run against the same force from the start */
    crom_scenario a = sc, b = sc;
    double t5 = 5.5 * sc.dt; /* on from the step ending at 6 dt (the loads are taken at a step's end) */
    char spec[64];
    snprintf(spec, sizeof spec, "right=0,-30,10@%.17g:", t5);
    CHECK(crom_scenario_option(&b, 0x1000 + 9, spec) == 0); /* --force from the start */
    crom_rsim ra, rb;
    CHECK(crom_rsim_init(&ra, &c, &a, CROM_RSIM_NEWTON, 1e5, q0, qd0) == 0);
    CHECK(crom_rsim_init(&rb, &c, &b, CROM_RSIM_NEWTON, 1e5, q0, qd0) == 0);
    double diff = 0, moved = 0;
    for (int step = 0; step < 15; step++) {
        if (step == 5) {
            CHECK(crom_scenario_option(&a, 0x1000 + 9, spec) == 0);
            CHECK(crom_rsim_sync_forces(&ra) == 0 && ra.nforce == 1);
        }
        crom_rsim_stats st;
        CHECK(crom_rsim_step(&ra, &st) == 0);
        CHECK(crom_rsim_step(&rb, &st) == 0);
        for (int i = 0; i < R; i++) {
            diff = fmax(diff, fabs(ra.q[i] - rb.q[i]));
            moved = fmax(moved, fabs(ra.q[i] - q0[i]));
        }
    }
    fprintf(stderr, "force appended at step 5 against the same force from the start: %.2e (motion %.3g)\n", diff,
            moved);
    CHECK(diff == 0);
    crom_rsim_free(&ra);
    crom_rsim_free(&rb);
    crom_cubature_free(&c);
    free(W);
    crom_mesh_free(&m);
}

/* The value of the step's objective (rsim.c keeps its quadratic part as
 * ½aᵀQa + lᵀa + c₀ about the predictor) against its terms summed directly:
 * inertia, damping, external work, the penalty of a pin and of a moving
 * region vertex by vertex (a plain penalty: threshold 0), the elastic
 * energy by cubature. */
static void test_objective_value(void)
{
    crom_mesh m;
    double dims[3] = {1, 0.3, 0.3};
    make(&m, 0.12, dims);
    double *W = malloc(sizeof(double) * 3 * R * m.nv);
    analytic_basis(&m, W);
    crom_cubature c;
    crom_cubature_opts o = {CROM_CUBATURE_RANDOM, 20, 0, 0, NULL, 0, 2.5e6, 0.25, NULL, 0};
    crom_rng rng;
    crom_rng_seed(&rng, 5);
    CHECK(crom_cubature_build(&c, &m, W, R, "test", &o, &rng) == 0);
    crom_scenario sc;
    crom_scenario_defaults(&sc);
    sc.damping = 3;
    strcpy(sc.pins[sc.npins++], "left");
    crom_scenario_option(&sc, 0x1000 + 8, "right=0.5,-1,0.2@0:0.3"); /* --velocity */
    crom_scenario_option(&sc, 0x1000 + 9, "y>0.1=0,0,40");            /* --force */
    double q0[R], qd0[R], kappa = 1e5;
    for (int i = 0; i < R; i++) {
        q0[i] = 0.02 * crom_rng_normal(&rng);
        qd0[i] = 0.3 * crom_rng_normal(&rng);
    }
    crom_rsim s;
    CHECK(crom_rsim_init(&s, &c, &sc, CROM_RSIM_NEWTON, kappa, q0, qd0) == 0);
    s.bc_threshold = 0;
    CHECK(crom_rsim_set_cubature(&s, &c) == 0);
    double worst = 0;
    for (int step = 0; step < 3; step++) {
        crom_rsim_begin_step(&s);
        double h = sc.dt, t1 = (step + 1) * h, q[R], a[R], b[R], E, g[R];
        for (int i = 0; i < R; i++) {
            q[i] = s.q[i] + h * s.qd[i] + 0.01 * crom_rng_normal(&rng);
            a[i] = q[i] - (s.q[i] + h * s.qd[i]);
            b[i] = q[i] - s.q[i];
        }
        CHECK(crom_rsim_objective(&s, q, &E, g, NULL, 0) == 0);
        double Ein = 0, Edamp = 0, Wext = 0, Epen = 0, Eel;
        for (int i = 0; i < R; i++) {
            Wext += s.fext[i] * b[i];
            for (int j = 0; j < R; j++) {
                Ein += 0.5 / (h * h) * a[i] * s.Mr[i * R + j] * a[j];
                Edamp += 0.5 * sc.damping / h * b[i] * s.Mr[i * R + j] * b[j];
            }
        }
        for (int k = 0; k < s.nbc; k++) {
            double u[3] = {0, 0, 0};
            if (s.bc[k].bc)
                crom_bc_displacement(s.bc[k].bc, t1, u);
            for (int j = 0; j < s.bc[k].n; j++) {
                int v = s.bc[k].idx[j];
                for (int cc = 0; cc < 3; cc++) {
                    double x = -u[cc];
                    for (int i = 0; i < R; i++)
                        x += W[((size_t)v * 3 + cc) * R + i] * q[i];
                    Epen += 0.5 * kappa * sc.density * c.vvol[v] * x * x;
                }
            }
        }
        CHECK(crom_elastic_eval(&s.el, &s.mat, q, 0, &Eel, NULL, NULL) == 0);
        double Ed = Ein + Edamp - Wext + Epen + Eel;
        worst = fmax(worst, fabs(E - Ed) / fabs(Ed));
        CHECK(Epen > 0 && Edamp > 0 && Wext != 0);
        crom_rsim_stats st;
        CHECK(crom_rsim_step(&s, &st) == 0);
    }
    fprintf(stderr, "step objective against its terms summed directly: relative difference %.2e over 3 steps\n",
            worst);
    CHECK_LT(worst, 1e-12);
    crom_rsim_free(&s);
    crom_cubature_free(&c);
    free(W);
    crom_mesh_free(&m);
}

/* ---- the latent minimizer's quasi-Newton corrections (rom/newton.h) ----
 * f(x) = ½xᵀAx − bᵀx + ¼ Σ c_i x_i⁴ (convex; c_i > 0 in three coordinates,
 * so that the Hessian moves away from H_0 = A, the one at 0, in a few
 * directions, as an elastic Hessian under rotation) with H_0 factored once
 * and reused: the chord method
 * converges linearly; with the L-BFGS pairs it must take fewer iterations to
 * the same minimizer, keep its pairs across solves of the next problem (b
 * shifted, the same Hessian), and with ls_gradient start each iteration from
 * the line search's evaluation: the same iterates with half the calls. */
#define NQ 24
typedef struct {
    double A[NQ * NQ], L[NQ * NQ], b[NQ], c[NQ];
    long calls;
    int fresh;
} qn_case;

static int qn_objective(void *ctx, const double *x, double *E, double *g, double *H, int project)
{
    qn_case *p = ctx;
    p->calls++;
    double f = 0;
    for (int i = 0; i < NQ; i++) {
        double Ax = 0;
        for (int j = 0; j < NQ; j++)
            Ax += p->A[i * NQ + j] * x[j];
        f += 0.5 * x[i] * Ax - p->b[i] * x[i] + 0.25 * p->c[i] * x[i] * x[i] * x[i] * x[i];
        if (g)
            g[i] = Ax - p->b[i] + p->c[i] * x[i] * x[i] * x[i];
    }
    if (H) /* only the first (lagged) Hessian is used: A, the Hessian at 0 */
        memcpy(H, p->A, sizeof p->A);
    *E = f;
    return 0;
}

static int qn_direction(void *ctx, int it, int project, const double *x, const double *g, const double *H, double *d)
{
    qn_case *p = ctx;
    if (H) {
        memcpy(p->L, H, sizeof p->L);
        CHECK(LAPACKE_dpotrf(LAPACK_ROW_MAJOR, 'L', NQ, p->L, NQ) == 0);
        p->fresh = 0;
    }
    for (int i = 0; i < NQ; i++)
        d[i] = -g[i];
    LAPACKE_dpotrs(LAPACK_ROW_MAJOR, 'L', NQ, 1, p->L, NQ, d, 1);
    return 0;
}

static double qn_size(void *ctx, const double *d)
{
    double s = 0;
    for (int i = 0; i < NQ; i++)
        s += d[i] * d[i];
    return sqrt(s);
}

static int qn_wants(void *ctx, int it) { return ((qn_case *)ctx)->fresh; }
static void qn_stale(void *ctx) { ((qn_case *)ctx)->fresh = 1; }

/* solve from x (in: the start; out: the minimizer); returns the iterations
 * (-1 on failure) */
static int qn_solve(qn_case *p, crom_newton_memory *mem, int ls_gradient, double *x)
{
    crom_newton_problem prob = {NQ, qn_objective, qn_direction, qn_size, qn_wants, qn_stale, 0, "Newton",
                                "singular", ls_gradient};
    double g[NQ], H[NQ * NQ], d[NQ], xt[NQ], res;
    crom_newton_work w = {g, H, d, xt, mem};
    int its, conv;
    int rc = crom_newton_solve(&prob, p, &w, x, 1e-8, 300, 0, &its, &res, &conv);
    return rc || !conv ? -1 : its;
}

static void test_newton_memory(void)
{
    qn_case p;
    crom_rng rng;
    crom_rng_seed(&rng, 11);
    double B[NQ * NQ];
    for (int i = 0; i < NQ * NQ; i++)
        B[i] = crom_rng_normal(&rng);
    for (int i = 0; i < NQ; i++) {
        for (int j = 0; j < NQ; j++) {
            double s = 0;
            for (int k = 0; k < NQ; k++)
                s += B[i * NQ + k] * B[j * NQ + k];
            p.A[i * NQ + j] = s / NQ + (i == j ? 0.5 : 0);
        }
        p.b[i] = 0.5 * crom_rng_normal(&rng);
        p.c[i] = i < 3 ? 0.2 + 0.3 * crom_rng_uniform(&rng) : 0;
    }
    double xc[NQ] = {0}, xq[NQ] = {0}, xl[NQ] = {0};
    p.fresh = 1;
    int chord = qn_solve(&p, NULL, 0, xc);
    crom_newton_memory mem;
    CHECK(crom_newton_memory_init(&mem, NQ, 8) == 0);
    p.fresh = 1;
    p.calls = 0;
    int quasi = qn_solve(&p, &mem, 0, xq);
    long calls_plain = p.calls;
    /* the same with the line search's gradients: the same iterates */
    crom_newton_memory_reset(&mem);
    p.fresh = 1;
    p.calls = 0;
    int quasi_ls = qn_solve(&p, &mem, 1, xl);
    long calls_ls = p.calls;
    double dx = 0, dl = 0, gmax = 0, E, g[NQ];
    qn_objective(&p, xq, &E, g, NULL, 0);
    for (int i = 0; i < NQ; i++) {
        dx = fmax(dx, fabs(xq[i] - xc[i]));
        dl = fmax(dl, fabs(xl[i] - xq[i]));
        gmax = fmax(gmax, fabs(g[i]));
    }
    /* the next problem (b shifted) from the last minimizer, as the next time
     * step: the pairs of the first stay exact secants of its Hessian */
    for (int i = 0; i < NQ; i++)
        p.b[i] += 0.1 * crom_rng_normal(&rng);
    memcpy(xl, xq, sizeof xl);
    int again = qn_solve(&p, &mem, 1, xq);
    crom_newton_memory_reset(&mem);
    int cold = qn_solve(&p, &mem, 1, xl);
    double d2 = 0;
    for (int i = 0; i < NQ; i++)
        d2 = fmax(d2, fabs(xq[i] - xl[i]));
    fprintf(stderr, "lagged Newton on a quartic (n %d): chord %d iterations, with L-BFGS pairs %d (%ld calls; %d with "
                    "%ld calls when the line search's gradients are kept), |x_chord - x_pairs| %.1e, |g| %.1e; "
                    "the next problem with the pairs kept %d, forgotten %d\n",
            NQ, chord, quasi, calls_plain, quasi_ls, calls_ls, dx, gmax, again, cold);
    CHECK(chord > 0 && quasi > 0 && again > 0 && cold > 0);
    CHECK(quasi < chord / 2);
    CHECK_LT(dx, 1e-7); /* the correction tolerance 1e-8 with linear convergence */
    CHECK_LT(gmax, 1e-8);
    CHECK(quasi_ls == quasi && dl == 0);
    CHECK(calls_ls <= quasi + 2 && calls_plain >= 2 * quasi - 1);
    CHECK(again < cold);
    CHECK_LT(d2, 1e-7);
    crom_newton_memory_free(&mem);
    CHECK(crom_newton_memory_init(&mem, 0, 4) == CROM_EUSAGE && !mem.s);
}

/* The reused factor with its quasi-Newton pairs, the refresh schedule and
 * the extrapolated start (rsim.c) reach the steps of Newton with a fresh
 * Hessian at every iteration: a component-block basis W_v = I₃ ⊗ ψ(X)ᵀ (a
 * skinning subspace's form, quadratic ψ) on a clamped soft bar sagging far
 * under gravity, the two runs step by step. */
static void test_lagged_newton(void)
{
    enum { S = 10, RB = 3 * S };
    crom_mesh m;
    double dims[3] = {1, 0.2, 0.2};
    make(&m, 0.07, dims);
    double *W = calloc((size_t)m.nv * 3 * RB, sizeof(double));
    for (int v = 0; v < m.nv; v++) {
        const double *X = m.X + 3 * v;
        double x = X[0] + 0.5, y = X[1], z = X[2];
        double f[S] = {1, x, y, z, x * x, x * y, x * z, x * x * x, x * x * y, x * x * z};
        for (int c = 0; c < 3; c++)
            for (int k = 0; k < S; k++)
                W[((size_t)v * 3 + c) * RB + c * S + k] = f[k];
    }
    crom_cubature c;
    crom_cubature_opts o = {CROM_CUBATURE_RANDOM, 60, 0, 0, NULL, 0, 4e5, 0.45, NULL, 0};
    crom_rng rng;
    crom_rng_seed(&rng, 2);
    CHECK(crom_cubature_build(&c, &m, W, RB, "test", &o, &rng) == 0);
    crom_scenario sc;
    crom_scenario_defaults(&sc);
    sc.youngs = 4e5;
    sc.poisson = 0.45;
    sc.dt = 0.05;
    sc.tol = 1e-9;
    strcpy(sc.pins[sc.npins++], "left");
    crom_rsim lag, fresh;
    CHECK(crom_rsim_init(&lag, &c, &sc, CROM_RSIM_NEWTON, 0, NULL, NULL) == 0);
    CHECK(crom_rsim_init(&fresh, &c, &sc, CROM_RSIM_NEWTON, 0, NULL, NULL) == 0);
    CHECK(lag.el.block == 1 && lag.lagged == 1);
    fresh.lagged = 0;
    double worst = 0, qmax = 0, tip = 0;
    int it_lag = 0, it_fresh = 0;
    for (int k = 0; k < 40; k++) {
        crom_rsim_stats a, b;
        int rc1 = crom_rsim_step(&lag, &a), rc2 = crom_rsim_step(&fresh, &b);
        CHECK_MSG(rc1 == 0 && rc2 == 0, "step %d: %s", k, crom_errmsg());
        if (rc1 || rc2)
            break;
        it_lag += a.iterations;
        it_fresh += b.iterations;
        for (int i = 0; i < RB; i++) {
            worst = fmax(worst, fabs(lag.q[i] - fresh.q[i]));
            qmax = fmax(qmax, fabs(fresh.q[i]));
        }
        /* the free end's vertical displacement: u_y = ψ(X_tip)·q_y */
        double t = 0, f[S] = {1, 1, 0, 0, 1, 0, 0, 1, 0, 0};
        for (int i = 0; i < S; i++)
            t += f[i] * fresh.q[S + i];
        tip = fmin(tip, t);
    }
    fprintf(stderr, "lagged Newton with pairs vs a fresh Hessian per iteration: largest |q difference| %.2e (|q| up "
                    "to %.3g, free end down to %.3f m), %d against %d iterations in 40 steps\n",
            worst, qmax, tip, it_lag, it_fresh);
    CHECK(tip < -0.3); /* a large sag: the Hessian moves */
    CHECK_LT(worst, 1e-6 * qmax);
    crom_rsim_free(&lag);
    crom_rsim_free(&fresh);
    crom_cubature_free(&c);
    free(W);
    crom_mesh_free(&m);
}

/* Independent Galerkin step: minimize the full incremental potential over
 * x = X + W q with full assembly: g = Wᵀ∇IP, H = Wᵀ(∇²IP)W, plus the same
 * pin penalty. */
static void galerkin_step(const crom_fem *fem, const crom_mesh *m, const double *W, const double *grav,
                          double h, double kappa, const crom_mesh_region *pin, double *q, double *qd)
{
    int n = 3 * m->nv;
    double *x = malloc(sizeof(double) * n), *gf = malloc(sizeof(double) * n), *Hv = malloc(sizeof(double) * fem->nnz);
    double *HW = malloc(sizeof(double) * n * R), qn[R], qhat[R];
    for (int i = 0; i < R; i++) {
        qn[i] = q[i];
        qhat[i] = q[i] + h * qd[i];
        q[i] = qhat[i];
    }
    for (int it = 0; it < 30; it++) {
        for (int i = 0; i < n; i++)
            x[i] = m->X[i];
        cblas_dgemv(CblasRowMajor, CblasNoTrans, n, R, 1.0, W, R, q, 1, 1.0, x, 1);
        double E;
        crom_fem_opts fo = {0, 0, NULL, 1};
        crom_fem_assemble(fem, x, &fo, &E, gf, Hv);
        /* full gradient: elastic + M (x - x̂)/h² - m g, with x̂ = X + W q̂ */
        for (int v = 0; v < m->nv; v++)
            for (int c = 0; c < 3; c++) {
                double dq = 0;
                for (int j = 0; j < R; j++)
                    dq += W[((size_t)v * 3 + c) * R + j] * (q[j] - qhat[j]);
                gf[3 * v + c] += fem->mass[v] * (dq / (h * h) - grav[c]);
            }
        double g[R] = {0}, H[R * R] = {0};
        cblas_dgemv(CblasRowMajor, CblasTrans, n, R, 1.0, W, R, gf, 1, 0.0, g, 1);
        /* H = Wᵀ (K + M/h²) W: K from the CSC upper triangle */
        memset(HW, 0, sizeof(double) * n * R);
        for (int j = 0; j < n; j++)
            for (int k = fem->colptr[j]; k < fem->colptr[j + 1]; k++) {
                int i = fem->rowind[k];
                for (int a = 0; a < R; a++) {
                    HW[i * R + a] += Hv[k] * W[j * R + a];
                    if (i != j)
                        HW[j * R + a] += Hv[k] * W[i * R + a];
                }
            }
        for (int i = 0; i < n; i++)
            for (int a = 0; a < R; a++)
                HW[i * R + a] += fem->mass[i / 3] / (h * h) * W[i * R + a];
        cblas_dgemm(CblasRowMajor, CblasTrans, CblasNoTrans, R, R, n, 1.0, W, R, HW, R, 0.0, H, R);
        /* pin penalty κ/2 Σ m ‖W_v q‖² */
        for (int k = 0; pin && k < pin->n; k++) {
            int v = pin->idx[k];
            const double *Wv = W + (size_t)v * 3 * R;
            double u[3] = {0, 0, 0};
            cblas_dgemv(CblasRowMajor, CblasNoTrans, 3, R, 1.0, Wv, R, q, 1, 0.0, u, 1);
            cblas_dgemv(CblasRowMajor, CblasTrans, 3, R, kappa * fem->mass[v], Wv, R, u, 1, 1.0, g, 1);
            cblas_dgemm(CblasRowMajor, CblasTrans, CblasNoTrans, R, R, 3, kappa * fem->mass[v], Wv, R, Wv, R, 1.0, H, R);
        }
        double d[R];
        for (int i = 0; i < R; i++)
            d[i] = -g[i];
        LAPACKE_dposv(LAPACK_ROW_MAJOR, 'U', R, 1, H, R, d, 1);
        double dn = 0;
        for (int i = 0; i < R; i++) {
            q[i] += d[i];
            dn = fmax(dn, fabs(d[i]));
        }
        if (dn < 1e-14)
            break;
    }
    for (int i = 0; i < R; i++)
        qd[i] = (q[i] - qn[i]) / h;
    free(x);
    free(gf);
    free(Hv);
    free(HW);
}

static void test_galerkin(void)
{
    crom_mesh m;
    double dims[3] = {1, 0.25, 0.25};
    make(&m, 0.1, dims);
    double *W = malloc(sizeof(double) * 3 * R * m.nv);
    analytic_basis(&m, W);
    crom_cubature c;
    crom_cubature_opts o = {CROM_CUBATURE_ALL, 0, 0, 0, NULL, 0, 2.5e6, 0.25, NULL, 0};
    crom_rng rng;
    crom_rng_seed(&rng, 1);
    CHECK(crom_cubature_build(&c, &m, W, R, "test", &o, &rng) == 0);
    CHECK(c.k == m.nt);
    crom_scenario sc;
    crom_scenario_defaults(&sc);
    sc.youngs = 5e5;
    sc.dt = 0.01;
    sc.tol = 1e-13;
    strcpy(sc.pins[sc.npins++], "left");
    double kappa = 1e6;
    crom_rsim s;
    CHECK(crom_rsim_init(&s, &c, &sc, CROM_RSIM_NEWTON, kappa, NULL, NULL) == 0);
    crom_material mat;
    crom_material_init(&mat, sc.youngs, sc.poisson, sc.density);
    crom_fem fem;
    CHECK(crom_fem_init(&fem, &m, &mat) == 0);
    double q[R] = {0}, qd[R] = {0}, worst = 0, qmax = 0;
    const crom_mesh_region *pin = crom_mesh_find_region(&m, "left");
    for (int k = 0; k < 12; k++) {
        crom_rsim_stats st;
        int rc = crom_rsim_step(&s, &st);
        CHECK_MSG(rc == 0, "reduced step %d: %s", k, crom_errmsg());
        galerkin_step(&fem, &m, W, sc.gravity, sc.dt, kappa, pin, q, qd);
        for (int i = 0; i < R; i++) {
            worst = fmax(worst, fabs(s.q[i] - q[i]));
            qmax = fmax(qmax, fabs(q[i]));
        }
    }
    fprintf(stderr, "Galerkin: largest |q_reduced - q_galerkin| %.2e over 12 steps (|q| up to %.3g)\n", worst, qmax);
    CHECK(qmax > 1e-3); /* it moved */
    CHECK_LT(worst, 1e-9 * qmax);
    /* the exact reduced mass equals Wᵀ M W of the full lumped mass */
    double dm = 0, mm = 0;
    for (int i = 0; i < R; i++)
        for (int j = 0; j < R; j++) {
            double Mij = 0;
            for (int v = 0; v < m.nv; v++)
                for (int cc = 0; cc < 3; cc++)
                    Mij += fem.mass[v] * W[((size_t)v * 3 + cc) * R + i] * W[((size_t)v * 3 + cc) * R + j];
            dm = fmax(dm, fabs(Mij - s.Mr[i * R + j]));
            mm = fmax(mm, fabs(Mij));
        }
    CHECK_LT(dm, 1e-12 * mm);
    crom_fem_free(&fem);
    crom_rsim_free(&s);
    crom_cubature_free(&c);
    free(W);
    crom_mesh_free(&m);
}

static void test_schemes_and_switch(void)
{
    crom_mesh m;
    double dims[3] = {1, 0.3, 0.3};
    make(&m, 0.08, dims);
    double *W = malloc(sizeof(double) * 3 * R * m.nv);
    analytic_basis(&m, W);
    crom_rng rng;
    crom_rng_seed(&rng, 5);
    crom_material mat;
    crom_material_init(&mat, 2.5e6, 0.25, 1000);
    /* training poses: random small deformations */
    double poses[8 * R];
    for (int i = 0; i < 8 * R; i++)
        poses[i] = (i % R < 3 ? 0 : 0.02) * crom_rng_normal(&rng);
    crom_cubature all, rnd, met, opt;
    crom_cubature_opts o = {CROM_CUBATURE_ALL, 0, 0, 0, NULL, 0, 2.5e6, 0.25, NULL, 0};
    CHECK(crom_cubature_build(&all, &m, W, R, "id", &o, &rng) == 0);
    o.scheme = CROM_CUBATURE_RANDOM;
    o.count = 60;
    CHECK(crom_cubature_build(&rnd, &m, W, R, "id", &o, &rng) == 0);
    o.scheme = CROM_CUBATURE_METIS;
    o.count = 40;
    CHECK(crom_cubature_build(&met, &m, W, R, "id", &o, &rng) == 0);
    CHECK(met.k == 40);
    o.scheme = CROM_CUBATURE_OPTIMIZED;
    o.count = 60;
    o.tol = 1e-3;
    o.poses = poses;
    o.npose = 8;
    CHECK(crom_cubature_build(&opt, &m, W, R, "id", &o, &rng) == 0);
    /* weighted volumes integrate the mesh volume (random, metis exactly) */
    double vr = 0, vm = 0;
    for (int k = 0; k < rnd.k; k++)
        vr += rnd.weight[k] * rnd.vol[k];
    for (int k = 0; k < met.k; k++)
        vm += met.weight[k] * met.vol[k];
    CHECK_NEAR(vr, all.mesh_volume, 1e-12);
    CHECK_NEAR(vm, all.mesh_volume, 1e-12);
    double eE[4], eF[4];
    const crom_cubature *cs[4] = {&all, &rnd, &met, &opt};
    for (int i = 0; i < 4; i++)
        CHECK(crom_cubature_error(cs[i], &mat, poses, 8, NULL, 0, &eE[i], &eF[i]) == 0);
    fprintf(stderr, "cubature errors (energy, force): all %.1e %.1e, random(%d tets) %.3f %.3f, metis(%d) %.3f %.3f, optimized(%d) %.4f %.4f\n",
            eE[0], eF[0], rnd.k, eE[1], eF[1], met.k, eE[2], eF[2], opt.k, eE[3], eF[3]);
    CHECK_LT(eE[0], 1e-12);
    CHECK_LT(eF[0], 1e-12);
    CHECK_LT(eF[3], 0.01);   /* the optimized fit reproduces its training forces */
    CHECK(opt.k <= 60);
    CHECK_LT(eF[3], eF[1]);  /* and beats random with fewer tets */
    /* switching cubature mid-run keeps q and q̇ and the energy finite */
    crom_scenario sc;
    crom_scenario_defaults(&sc);
    strcpy(sc.pins[sc.npins++], "left");
    crom_rsim s;
    CHECK(crom_rsim_init(&s, &met, &sc, CROM_RSIM_NEWTON, 0, NULL, NULL) == 0);
    crom_rsim_stats st;
    for (int k = 0; k < 5; k++)
        CHECK(crom_rsim_step(&s, &st) == 0);
    double qb[R], qdb[R];
    memcpy(qb, s.q, sizeof qb);
    memcpy(qdb, s.qd, sizeof qdb);
    CHECK(crom_rsim_set_cubature(&s, &opt) == 0);
    CHECK(memcmp(qb, s.q, sizeof qb) == 0 && memcmp(qdb, s.qd, sizeof qdb) == 0);
    double K, E, X;
    CHECK(crom_rsim_energies(&s, &K, &E, &X) == 0);
    CHECK(isfinite(K) && isfinite(E) && isfinite(X));
    for (int k = 0; k < 5; k++)
        CHECK(crom_rsim_step(&s, &st) == 0);
    /* pinned vertices stay pinned (penalty): the constraint residual is tiny */
    CHECK(st.constraint_residual == 0); /* the step leaves it to the caller */
    double cres = crom_rsim_constraint_residual(&s);
    fprintf(stderr, "constraint residual after 10 steps %.2e m\n", cres);
    CHECK_LT(cres, 1e-4);
    /* gd (LiCROM §5) converges to newton's step where it can: a soft body,
     * where inertia keeps G = WᵀW a good preconditioner. (On stiff bodies
     * it converges slowly; the paper stops it after a fixed count.) */
    crom_rsim g;
    sc.youngs = 2e3;
    sc.max_iter = 2000;
    sc.tol = 1e-10;
    CHECK(crom_rsim_init(&g, &met, &sc, CROM_RSIM_GD, 0, NULL, NULL) == 0);
    crom_rsim nw;
    CHECK(crom_rsim_init(&nw, &met, &sc, CROM_RSIM_NEWTON, 0, NULL, NULL) == 0);
    for (int k = 0; k < 3; k++) {
        CHECK(crom_rsim_step(&g, &st) == 0);
        CHECK(crom_rsim_step(&nw, &st) == 0);
    }
    double dq = 0, qn = 0;
    for (int i = 0; i < R; i++) {
        dq += (g.q[i] - nw.q[i]) * (g.q[i] - nw.q[i]);
        qn += nw.q[i] * nw.q[i];
    }
    fprintf(stderr, "gd vs newton after 3 steps: relative difference %.2e\n", sqrt(dq / qn));
    CHECK_LT(sqrt(dq / qn), 0.05);
    crom_rsim_free(&g);
    crom_rsim_free(&nw);
    /* a cubature of another model is refused */
    snprintf(met.model_id, sizeof met.model_id, "other");
    CHECK(crom_rsim_set_cubature(&s, &met) == CROM_EDATA);
    crom_rsim_free(&s);
    for (int i = 0; i < 4; i++)
        crom_cubature_free((crom_cubature *)cs[i]);
    free(W);
    crom_mesh_free(&m);
}

/* A crack must be able to open: on a grid cut exactly along x = 0.5, with a
 * one-field basis that jumps across that plane (u_y = q H(x − 0.5), H a
 * steep step), the intact body resists the jump (its tets next to the plane
 * see the jump through their shared vertices) while the cut body lets it open
 * (the copies sample W on their own sides: crom_mesh_field_points). */
static double jump_energy(const crom_mesh *m, double offset, double q)
{
    int ns = 0;
    double *P = crom_mesh_field_points(m, offset, &ns), *W = malloc(sizeof(double) * 3 * m->nv);
    for (int v = 0; v < m->nv; v++) {
        W[3 * v] = W[3 * v + 2] = 0;
        W[3 * v + 1] = 0.5 * (1 + tanh((P[3 * v] - 0.5) / 1e-4));
    }
    crom_cubature c;
    crom_cubature_opts o = {CROM_CUBATURE_ALL, 0, 0, 0, NULL, 0, 1e5, 0.25, NULL, 0};
    crom_rng rng;
    crom_rng_seed(&rng, 1);
    CHECK(crom_cubature_build(&c, m, W, 1, "jump", &o, &rng) == 0);
    crom_scenario sc;
    crom_scenario_defaults(&sc);
    sc.youngs = 1e5;
    crom_rsim s;
    CHECK(crom_rsim_init(&s, &c, &sc, CROM_RSIM_NEWTON, 0, &q, NULL) == 0);
    double K, E, X;
    CHECK(crom_rsim_energies(&s, &K, &E, &X) == 0);
    crom_rsim_free(&s);
    crom_cubature_free(&c);
    free(P);
    free(W);
    return E;
}

/* An n×n×n Kuhn grid on [0,1]^3 (n even: no tet crosses the plane x = 0.5). */
static void kuhn_grid(crom_mesh *mp, int n)
{
    crom_mesh m;
    memset(&m, 0, sizeof m);
    int nv = (n + 1) * (n + 1) * (n + 1);
    m.nv = nv;
    m.X = malloc(sizeof(double) * 3 * nv);
    for (int k = 0; k <= n; k++)
        for (int j = 0; j <= n; j++)
            for (int i = 0; i <= n; i++) {
                double *x = m.X + 3 * (i + (n + 1) * (j + (n + 1) * k));
                x[0] = (double)i / n;
                x[1] = (double)j / n;
                x[2] = (double)k / n;
            }
    m.nt = 6 * n * n * n;
    m.tets = malloc(sizeof(int) * 4 * m.nt);
    static const int perm[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    for (int k = 0, t = 0; k < n; k++)
        for (int j = 0; j < n; j++)
            for (int i = 0; i < n; i++)
                for (int p = 0; p < 6; p++, t++) {
                    int c[3] = {i, j, k}, *e = m.tets + 4 * t;
                    e[0] = c[0] + (n + 1) * (c[1] + (n + 1) * c[2]);
                    for (int s = 0; s < 3; s++) {
                        c[perm[p][s]]++;
                        e[s + 1] = c[0] + (n + 1) * (c[1] + (n + 1) * c[2]);
                    }
                }
    CHECK(crom_mesh_orient(&m, NULL) == 0);
    *mp = m;
}

static void test_crack_opens(void)
{
    crom_mesh m;
    kuhn_grid(&m, 4);
    static const double seg[4] = {0.5, -1, 0.5, 2};
    crom_remesh_cut_opts cut = {2, 1, seg, 1, 1}; /* a wall at x = 0.5, extruded along z */
    crom_mesh cm;
    crom_remesh_cut_stats st;
    CHECK(crom_remesh_cut(&m, &cut, &cm, &st, NULL, NULL) == 0);
    CHECK(cm.nv == m.nv + 25);
    int ns = 0;
    double *P = crom_mesh_field_points(&m, 0.25, &ns);
    CHECK(ns == 0); /* an intact mesh has no duplicated vertices */
    free(P);
    P = crom_mesh_field_points(&cm, 0.25, &ns);
    CHECK(ns == 50); /* 25 vertices on the plane, two copies each */
    free(P);
    double q = 0.05, Ei = jump_energy(&m, 0.25, q), Ec = jump_energy(&cm, 0.25, q), Ec0 = jump_energy(&cm, 0, q);
    fprintf(stderr, "jump mode of 5 cm: elastic energy intact %.4g J, cut %.3g J, cut sampled at X %.4g J\n", Ei, Ec, Ec0);
    CHECK(Ei > 1);             /* the intact body resists the jump */
    CHECK_LT(Ec, 1e-6 * Ei);   /* the cut one opens freely */
    CHECK_NEAR(Ec0, Ei, 1e-9 * Ei); /* sampled at X the cut would be invisible */
    crom_mesh_free(&cm);
    crom_mesh_free(&m);
}

/* The features of a cut (lib/mesh/cutfeat.h): +1 on the left of a segment,
 * -1 on its right, a jump of 2 across it and none across its line beyond
 * its ends; in the plane perpendicular to the axis. */
static void test_cut_features(void)
{
    crom_cutfeat c = {2, 1, {{0.5, -1, 0.5, 2}}}; /* the wall x = 0.5 along z, from y = -1 to 2 */
    CHECK(crom_cutfeat_check(&c) == 0);
    double e = 1e-7, f1, f2;
    double pl[3] = {0.5 - e, 0.5, 0.3}, pr[3] = {0.5 + e, 0.5, 0.7}, on[3] = {0.5, 0.5, 0.1};
    crom_cutfeat_point(&c, pl, &f1);
    crom_cutfeat_point(&c, pr, &f2);
    CHECK_NEAR(f1, 1, 1e-6);
    CHECK_NEAR(f2, -1, 1e-6);
    crom_cutfeat_point(&c, on, &f1);
    CHECK(f1 == 1); /* on the segment: its left */
    double end[3] = {0.5, -1, 0.9}, bl[3] = {0.5 - e, 3, 0}, br[3] = {0.5 + e, 3, 0};
    crom_cutfeat_point(&c, end, &f1);
    CHECK(f1 == 0);
    crom_cutfeat_point(&c, bl, &f1);
    crom_cutfeat_point(&c, br, &f2);
    CHECK_LT(fabs(f1 - f2), 1e-6); /* beyond the end: continuous */
    CHECK_LT(fabs(f1), 0.2);
    /* the subtended angle: from (0, 0.5) the ends lie 1.5 below and above, 0.5 away */
    double p0[3] = {0, 0.5, 0}, want = 2 * atan(1.5 / 0.5) / M_PI;
    crom_cutfeat_point(&c, p0, &f1);
    CHECK_NEAR(f1, want, 1e-12);
    /* axis y: (u, v) = (x, z) */
    crom_cutfeat cy = {1, 1, {{0.5, -1, 0.5, 2}}};
    double qy[3] = {0, 123, 0.5};
    crom_cutfeat_point(&cy, qy, &f2);
    CHECK_NEAR(f2, want, 1e-12);
    crom_cutfeat bad = {1, 1, {{0.5, 0.5, 0.5, 0.5}}};
    CHECK(crom_cutfeat_check(&bad) == CROM_EUSAGE);
    bad.seg[0][2] = NAN;
    CHECK(crom_cutfeat_check(&bad) == CROM_EUSAGE);
    bad.axis = 3;
    CHECK(crom_cutfeat_check(&bad) == CROM_EUSAGE);
}

/* W at the vertices of a cut mesh, as the programs evaluate it: a mesh
 * field keeps each copy's own value (sampled off the vertex it would be an
 * interpolation, which made a reduced run of a POD basis of the cut plate
 * 63% off its own training run, against 3% exactly); a field with cut
 * features takes X at the vertex and the features of the copy's side. The
 * features of an interior training sample come from its tet's side. */
static void test_cut_fields(void)
{
    crom_mesh m, cm;
    kuhn_grid(&m, 4);
    static const double seg[4] = {0.5, -1, 0.5, 2};
    crom_remesh_cut_opts cut = {2, 1, seg, 1, 1};
    crom_remesh_cut_stats st;
    CHECK(crom_remesh_cut(&m, &cut, &cm, &st, NULL, NULL) == 0);
    int nv = cm.nv, r = 2;
    /* a mesh field with a different value at every vertex, copies included */
    double *B = malloc(sizeof(double) * 3 * r * nv), *W = malloc(sizeof(double) * 3 * r * nv);
    for (int i = 0; i < 3 * r * nv; i++)
        B[i] = sin(1.7 * i + 0.3);
    crom_model M;
    CHECK(crom_model_from_mesh(&M, "pod", &cm, B, r) == 0);
    int ns = -1;
    CHECK(crom_model_eval_mesh(&M, &cm, CROM_MESH_CRACK_OFFSET, W, NULL, &ns) == 0);
    CHECK(memcmp(W, B, sizeof(double) * 3 * r * nv) == 0);
    crom_model_free(&M);
    /* an MLP with the wall's feature: 4 -> 3r */
    crom_rng rng;
    crom_rng_seed(&rng, 7);
    int widths[] = {4, 12, 3 * r};
    crom_nn_spec spec;
    CHECK(crom_nn_spec_set(&spec, 3, widths, CROM_NN_ELU) == 0);
    crom_nn_mlp net;
    CHECK(crom_nn_mlp_init(&net, &spec, NULL, &rng) == 0);
    crom_cutfeat cf = {2, 1, {{0.5, -1, 0.5, 2}}};
    CHECK(crom_model_from_mlp(&M, &net, &cf, NULL) == 0);
    CHECK(crom_model_eval_mesh(&M, &cm, CROM_MESH_CRACK_OFFSET, W, NULL, &ns) == 0);
    CHECK(ns == 50);
    double *P = crom_mesh_field_points(&cm, CROM_MESH_CRACK_OFFSET, NULL);
    crom_nn_ws ws;
    CHECK(crom_nn_ws_init(&ws, &net, 1, 1) == 0);
    int copies = 0, maxdiff_ok = 1;
    for (int v = 0; v < nv; v++) {
        double in[4] = {cm.X[3 * v], cm.X[3 * v + 1], cm.X[3 * v + 2], 0}, y[6];
        crom_cutfeat_point(&cf, P + 3 * v, in + 3);
        CHECK(crom_nn_mlp_eval(&net, &ws, 1, in, y, NULL) == 0);
        for (int i = 0; i < 3 * r; i++)
            maxdiff_ok &= fabs(y[i] - W[3 * r * v + i]) <= 1e-12 * (1 + fabs(y[i]));
        if (fabs(cm.X[3 * v] - 0.5) < 1e-12) { /* a copy on the wall: features of its own side */
            copies++;
            CHECK(fabs(in[3]) > 0.5);
            CHECK((in[3] > 0) == (P[3 * v] < 0.5));
        }
    }
    CHECK(maxdiff_ok);
    CHECK(copies == 50);
    crom_nn_ws_free(&ws);
    free(P);
    /* on the intact mesh: the features at the vertices themselves */
    double *Wi = malloc(sizeof(double) * 3 * r * m.nv), *Wx = malloc(sizeof(double) * 3 * r * m.nv);
    CHECK(crom_model_eval_mesh(&M, &m, CROM_MESH_CRACK_OFFSET, Wi, NULL, &ns) == 0);
    CHECK(ns == 0);
    CHECK(crom_model_eval(&M, (size_t)m.nv, m.X, Wx, NULL) == 0);
    CHECK(memcmp(Wi, Wx, sizeof(double) * 3 * r * m.nv) == 0);
    free(Wi);
    free(Wx);
    crom_model_free(&M);
    /* training samples: a feature wall at x = 0.52 while the cut is at 0.5: a
     * sample at x = 0.51 lies in a tet of the right side (centroid x > 0.52)
     * and takes its features there; one at x = 0.3 keeps its own */
    crom_samples S;
    memset(&S, 0, sizeof S);
    float X[6] = {0.51f, 0.4f, 0.35f, 0.3f, 0.6f, 0.6f}, U[6] = {0};
    int vx[2] = {-1, -1}, src = 0;
    S.F = 1, S.N = 2, S.X = X, S.U = U, S.vertex = vx, S.source = &src, S.nsources = 1, S.src = &cm;
    crom_cutfeat cw = {2, 1, {{0.52, -1, 0.52, 2}}};
    float *side = crom_fit_side_points(&S, &cw);
    CHECK(side != NULL);
    double fs, fx;
    double s0[3] = {side[0], side[1], side[2]}, x0[3] = {X[0], X[1], X[2]};
    crom_cutfeat_point(&cw, s0, &fs);
    crom_cutfeat_point(&cw, x0, &fx);
    CHECK(fx > 0.5 && fs < -0.5); /* moved to its tet's side */
    CHECK(side[0] > 0.5f && side[0] < 0.75f);
    CHECK(memcmp(side + 3, X + 3, sizeof(float) * 3) == 0);
    free(side);
    crom_nn_mlp_free(&net);
    free(B);
    free(W);
    crom_mesh_free(&cm);
    crom_mesh_free(&m);
}

/* The scenario's initial velocity (uniform plus spin) projected onto the
 * subspace: the analytic basis holds translations and every linear field, so
 * v0 + ω × (X − c) is in its span and must come back exactly at every vertex,
 * with the body's momentum M v0. */
/* The random and METIS schemes on a shell: the triangles and the hinges are
 * two sets, each integrated exactly in its own measure (area; the hinge
 * stiffness factor), METIS gives COUNT triangles and the hinges on their
 * edges, and the force error of the METIS cubature falls as the parts
 * grow. */
static void test_shell_schemes(void)
{
    crom_meshgen_opts go;
    crom_meshgen_defaults(&go, CROM_MESHGEN_SHEET);
    go.size = 0.05;
    go.thickness = 0.002;
    crom_mesh m;
    CHECK(crom_meshgen_sheet(&go, &m) == 0);
    enum { RS = 4 };
    double *W = malloc(sizeof(double) * 3 * RS * m.nv);
    for (int v = 0; v < m.nv; v++) { /* bending and stretching fields of the clamped-at-y = -1/2 sheet */
        double x = m.X[3 * v], y = m.X[3 * v + 1] + 0.5;
        double f[3][RS] = {{0, 0, 0.1 * y * y, 0}, {0, 0, 0, 0}, {y * y, x * y, 0, y * y * y}};
        for (int c = 0; c < 3; c++)
            for (int k = 0; k < RS; k++)
                W[((size_t)v * 3 + c) * RS + k] = f[c][k];
    }
    crom_system sys;
    CHECK(crom_system_init(&sys, &m, 1, 0.3, 1) == 0);
    int nt = sys.sh.nt, nh = sys.sh.nh;
    double hk = 0;
    for (int h = 0; h < nh; h++)
        hk += sys.sh.hk[h];
    crom_rng rng;
    crom_rng_seed(&rng, 3);
    double poses[6 * RS];
    for (int i = 0; i < 6 * RS; i++)
        poses[i] = 0.05 * crom_rng_normal(&rng);
    crom_material mat;
    crom_material_init(&mat, 1e7, 0.3, 500);
    crom_cubature_opts o = {CROM_CUBATURE_METIS, 20, 0, 0, NULL, 0, 1e7, 0.3, NULL, 0};
    double ferr[3];
    const int counts[3] = {10, 40, 160};
    for (int pass = 0; pass < 4; pass++) {
        crom_cubature c;
        o.scheme = pass < 3 ? CROM_CUBATURE_METIS : CROM_CUBATURE_RANDOM;
        o.count = pass < 3 ? counts[pass] : 25;
        CHECK(crom_cubature_build(&c, &m, W, RS, "shell", &o, &rng) == 0);
        double area = 0, hinge = 0;
        int ntri = 0, nhin = 0;
        for (int k = 0; k < c.k; k++) {
            CHECK(c.elem[k] >= 0 && c.elem[k] < nt + nh && c.weight[k] >= 1);
            if (c.elem[k] < nt) {
                area += c.weight[k] * sys.sh.area[c.elem[k]];
                ntri++;
            } else {
                hinge += c.weight[k] * sys.sh.hk[c.elem[k] - nt];
                nhin++;
            }
        }
        CHECK_NEAR(area / sys.sh.total_area, 1, 1e-12);
        CHECK_NEAR(hinge / hk, 1, 1e-12);
        if (pass < 3) {
            CHECK(ntri == counts[pass] && nhin >= counts[pass] && nhin <= 3 * counts[pass]);
            double eE;
            CHECK(crom_cubature_error(&c, &mat, poses, 6, NULL, 0, &eE, &ferr[pass]) == 0);
        } else {
            CHECK(ntri > 25 && nhin > 25 && ntri < nt && nhin < nh);
        }
        crom_cubature_free(&c);
    }
    fprintf(stderr, "shell METIS cubature force error: %d parts %.3g, %d parts %.3g, %d parts %.3g (%d triangles, "
            "%d hinges)\n", counts[0], ferr[0], counts[1], ferr[1], counts[2], ferr[2], nt, nh);
    CHECK_LT(ferr[1], ferr[0]);
    CHECK_LT(ferr[2], ferr[1]);
    crom_system_free(&sys);
    free(W);
    crom_mesh_free(&m);
}

static void test_initial_velocity(void)
{
    crom_mesh m;
    double dims[3] = {1, 0.3, 0.3};
    make(&m, 0.12, dims);
    double *W = malloc(sizeof(double) * 3 * R * m.nv);
    analytic_basis(&m, W);
    crom_cubature c;
    crom_cubature_opts o = {CROM_CUBATURE_ALL, 0, 0, 0, NULL, 0, 2.5e6, 0.25, NULL, 0};
    CHECK(crom_cubature_build(&c, &m, W, R, "test", &o, NULL) == 0);
    crom_scenario sc;
    crom_scenario_defaults(&sc);
    double v0[3] = {1, -2, 0.5}, w[3] = {0.3, 0.7, -1.1};
    memcpy(sc.v0, v0, sizeof v0);
    memcpy(sc.spin, w, sizeof w);
    crom_rsim s;
    CHECK(crom_rsim_init(&s, &c, &sc, CROM_RSIM_NEWTON, 0, NULL, NULL) == 0);
    double cen[3] = {0, 0, 0}, vol = 0, P[3] = {0, 0, 0}, err = 0, vmax = 0;
    for (int v = 0; v < m.nv; v++) {
        vol += c.vvol[v];
        for (int k = 0; k < 3; k++)
            cen[k] += c.vvol[v] * m.X[3 * v + k];
    }
    for (int k = 0; k < 3; k++)
        cen[k] /= vol;
    for (int v = 0; v < m.nv; v++) {
        double want[3], got[3] = {0, 0, 0};
        crom_scenario_initial_velocity(&sc, cen, m.X + 3 * v, want);
        for (int k = 0; k < 3; k++) {
            for (int j = 0; j < R; j++)
                got[k] += W[((size_t)v * 3 + k) * R + j] * s.qd[j];
            err = fmax(err, fabs(got[k] - want[k]));
            vmax = fmax(vmax, fabs(want[k]));
            P[k] += sc.density * c.vvol[v] * got[k];
        }
    }
    double M = sc.density * vol;
    fprintf(stderr, "initial velocity in the subspace: max error %.2e of %.2f m/s, momentum error %.2e\n", err, vmax,
            fabs(P[0] - M) + fabs(P[1] + 2 * M) + fabs(P[2] - 0.5 * M));
    CHECK_LT(err, 1e-9 * vmax);
    CHECK_NEAR(P[0], M * 1, 1e-9 * M);
    CHECK_NEAR(P[1], M * -2, 1e-9 * M);
    CHECK_NEAR(P[2], M * 0.5, 1e-9 * M);
    crom_rsim_free(&s);
    crom_cubature_free(&c);
    free(W);
    crom_mesh_free(&m);
}

/* A cubature of every tet of an analytic basis on a small grid, written to
 * path with model_id id. */
static void write_cubature(const char *path, const char *id, int nx)
{
    crom_mesh m;
    double lo[3] = {-0.5, -0.15, -0.15};
    fx_box_mesh(&m, nx, 2, 2, lo, 1.0 / nx, 0, NULL, NULL);
    double *W = malloc(sizeof(double) * 3 * R * m.nv);
    analytic_basis(&m, W);
    crom_cubature c;
    crom_cubature_opts o = {CROM_CUBATURE_ALL, 0, 0, 0, NULL, 0, 2.5e6, 0.25, NULL, 0};
    CHECK(crom_cubature_build(&c, &m, W, R, id, &o, NULL) == 0);
    crom_out out;
    CHECK(crom_out_create(&out, path, CROM_CUBATURE_SCHEMA, CROM_CUBATURE_VERSION, "test_rom", NULL,
                          CROM_OUT_PLAIN) == 0);
    CHECK(crom_cubature_write(out.h5, &c) == 0 && crom_out_commit(&out) == 0);
    crom_cubature_free(&c);
    crom_mesh_free(&m);
    free(W);
}

static void write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    fputs(text, f);
    fclose(f);
}

/* A schedule: the initial cubature and the switches of a file, in order,
 * as the run records them; and the errors of a bad schedule, with the file
 * and line named. */
static void test_schedule(void)
{
    char dir[] = "/tmp/crom-sched-XXXXXX", a[64], b[64], other[64], f[64], cmd[96];
    CHECK(mkdtemp(dir) != NULL);
    snprintf(a, sizeof a, "%s/a.h5", dir);
    snprintf(b, sizeof b, "%s/b.h5", dir);
    snprintf(other, sizeof other, "%s/other.h5", dir);
    snprintf(f, sizeof f, "%s/sched.txt", dir);
    write_cubature(a, "0123456789abcdef", 4);
    write_cubature(b, "0123456789abcdef", 6);
    write_cubature(other, "fedcba9876543210", 4);
    char text[512];
    snprintf(text, sizeof text, "# switches\n3 %s\n\n5 %s   # back\n9 %s\n", b, a, b);
    write_text(f, text);
    crom_schedule s;
    CHECK(crom_schedule_load(&s, a, f, 10) == 0);
    CHECK(s.n == 4 && s.e[0].step == 0 && s.e[1].step == 3 && s.e[2].step == 5 && s.e[3].step == 9);
    CHECK(s.e[0].cub.k == 4 * 2 * 2 * 6 && s.e[1].cub.k == 6 * 2 * 2 * 6 && s.e[2].cub.k == s.e[0].cub.k);
    CHECK(!strcmp(s.e[3].path, b) && s.e[0].history != NULL && s.e[1].history == NULL);
    char *t = crom_schedule_text(&s), want[512];
    snprintf(want, sizeof want, "0 %s\n3 %s\n5 %s\n9 %s", a, b, a, b);
    CHECK(t && !strcmp(t, want));
    free(t);
    crom_schedule_free(&s);
    /* no schedule file: the initial cubature alone */
    CHECK(crom_schedule_load(&s, a, NULL, 10) == 0 && s.n == 1);
    crom_schedule_free(&s);
    /* errors */
    static const struct {
        const char *text;
        int code;
        const char *msg;
    } bad[] = {{"3 B\n3 A\n", CROM_EUSAGE, ":2: step 3 is out of order"},
               {"0 B\n", CROM_EUSAGE, ":1: step 0 is out of order"},
               {"\n11 B\n", CROM_EUSAGE, ":2: step 11 is beyond --steps 10"},
               {"2\n", CROM_EUSAGE, ":1: expected 'STEP CUBATURE'"},
               {"2 O\n", CROM_EDATA, "is a cubature of model fedcba9876543210"},
               {"2 B\n4 nonexistent.h5\n", CROM_ENOINPUT, ":2: nonexistent.h5"}};
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
        char txt[256] = "";
        for (const char *p = bad[i].text; *p; p++) {
            size_t n = strlen(txt);
            if (*p == 'B' || *p == 'O')
                snprintf(txt + n, sizeof txt - n, "%s", *p == 'B' ? b : other);
            else
                snprintf(txt + n, sizeof txt - n, "%c", *p);
        }
        write_text(f, txt);
        int rc = crom_schedule_load(&s, a, f, 10);
        CHECK_MSG(rc == bad[i].code && strstr(crom_errmsg(), bad[i].msg), "schedule '%s': %d %s", bad[i].text,
                  rc, crom_errmsg());
        crom_schedule_free(&s);
    }
    snprintf(cmd, sizeof cmd, "%s/none.txt", dir);
    CHECK(crom_schedule_load(&s, a, cmd, 10) == CROM_ENOINPUT && strstr(crom_errmsg(), "--schedule"));
    crom_schedule_free(&s);
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    CHECK(system(cmd) == 0);
}

/* The conditions of a run over time (crom-reducedstep --condition
 * NAME=VALUE[@T]): the middle of each range until an entry takes effect,
 * entries at their times, the last of one condition winning; bad entries
 * and conditions the model does not have are one-line errors. */
static void test_condsched(void)
{
    crom_model m;
    memset(&m, 0, sizeof m);
    strcpy(m.model_id, "0123456789abcdef");
    m.ncond = 2;
    CHECK(crom_scenario_cond_parse("--condition", "ratio:stiff=1:5", 1, &m.cond[0]) == 0);
    CHECK(crom_scenario_cond_parse("--condition", "gravity:y=-12:-8", 1, &m.cond[1]) == 0);
    crom_condsched s = {0};
    double c[2];
    CHECK(crom_condsched_at(&s, &m, 0, c) == 0 && c[0] == 3 && c[1] == -10);
    CHECK(crom_condsched_add(&s, "--condition", "gravity:y=-9") == 0);
    CHECK(crom_condsched_add(&s, "--condition", "ratio:stiff=2@0.5") == 0);
    CHECK(crom_condsched_add(&s, "--condition", "ratio:stiff=4.5@1.25") == 0);
    CHECK(crom_condsched_at(&s, &m, 0, c) == 0 && c[0] == 3 && c[1] == -9);
    CHECK(crom_condsched_at(&s, &m, 0.5, c) == 0 && c[0] == 2 && c[1] == -9);
    CHECK(crom_condsched_at(&s, &m, 1.0, c) == 0 && c[0] == 2);
    CHECK(crom_condsched_at(&s, &m, 2.0, c) == 0 && c[0] == 4.5);
    CHECK(crom_condsched_add(&s, "--condition", "ratio:stiff=2@-1") == CROM_EUSAGE &&
          strstr(crom_errmsg(), "the time must be >= 0"));
    CHECK(crom_condsched_add(&s, "--condition", "ratio:stiff=2@x") == CROM_EUSAGE);
    CHECK(crom_condsched_add(&s, "--condition", "spin:z=2") == CROM_EUSAGE);
    CHECK(s.n == 3);
    CHECK(crom_condsched_add(&s, "--condition", "gravity:x=1") == 0);
    CHECK(crom_condsched_at(&s, &m, 0, c) == CROM_EUSAGE && strstr(crom_errmsg(), "has no such condition"));
    crom_err_clear();
    s.n = 0;
    for (int i = 0; i < CROM_CONDSCHED_MAX; i++)
        CHECK(crom_condsched_add(&s, "--condition", "gravity:y=-9") == 0);
    CHECK(crom_condsched_add(&s, "--condition", "gravity:y=-9") == CROM_EUSAGE && strstr(crom_errmsg(), "at most"));
    crom_err_clear();
}

int main(void)
{
    check_begin("test_rom");
    test_condsched();
    test_crack_opens();
    test_cut_features();
    test_cut_fields();
    test_derivatives();
    test_objective_value();
    test_drag();
    test_newton_memory();
    test_lagged_newton();
    test_galerkin();
    test_schemes_and_switch();
    test_shell_schemes();
    test_initial_velocity();
    test_schedule();
    return check_done();
}
