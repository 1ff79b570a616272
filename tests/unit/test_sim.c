/* test_sim.c — the full-space simulator against physics: contact
 * derivatives, linear momentum, energy dissipation, free fall, a cantilever
 * converging to Euler–Bernoulli, prescribed regions, contact resting depth,
 * the state returned within --tol of the converged one, a bar of two
 * materials against springs in series. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fixtures.h"
#include "phys/contact.h"
#include "base/err.h"
#include "phys/fem.h"
#include "mesh/mesh.h"
#include "mesh/meshgen.h"
#include "phys/scenario.h"
#include "phys/sim.h"
#include "phys/system.h"

/* ----------------------------------------------------------- contact */

typedef struct {
    crom_contact_plane p;
    double k, m, xprev[3], lam, eps;
} cctx;

static double c_energy(const double *x, void *ctx)
{
    cctx *c = ctx;
    return crom_contact_eval(&c->p, c->k, c->m, x, c->xprev, c->lam, c->eps, NULL, NULL);
}

static void c_grad(const double *x, void *ctx, double *g)
{
    cctx *c = ctx;
    g[0] = g[1] = g[2] = 0;
    crom_contact_eval(&c->p, c->k, c->m, x, c->xprev, c->lam, c->eps, g, NULL);
}

static void test_contact_derivatives(void)
{
    cctx c = {{.n = {0, 0.6, 0.8}, .d = 0.1, .mu = 0.5}, 1e5, 0.3, {0.01, 0.02, -0.03}, 40, 1e-3};
    /* points: penetrating and sliding fast, penetrating and sliding slowly
     * (smoothed zone), outside the plane, tangentially at rest */
    double pts[4][3] = {{0.05, 0.04, 0.02}, {0.0103, 0.05, 0.0306}, {0.3, 0.4, 0.5}, {0.01, 0.02 - 0.0032, -0.03 + 0.0024}};
    for (int k = 0; k < 4; k++) {
        double x[3], g[3] = {0}, H[9] = {0}, gfd[3], Hfd[9];
        memcpy(x, pts[k], sizeof x);
        crom_contact_eval(&c.p, c.k, c.m, x, c.xprev, c.lam, c.eps, g, H);
        double h = k == 1 || k == 3 ? 1e-7 : 1e-6;
        check_fd_gradient(c_energy, &c, x, 3, h, gfd);
        check_fd_jacobian(c_grad, &c, x, 3, 3, h, Hfd);
        CHECK_MSG(check_relerr(g, gfd, 3, 1e-3) < 1e-6, "contact gradient, point %d: %.3g", k,
                  check_relerr(g, gfd, 3, 1e-3));
        if (k != 3) /* at zero tangential motion the Hessian is the one-sided limit */
            CHECK_MSG(check_relerr(H, Hfd, 9, 1) < 1e-5, "contact Hessian, point %d: %.3g", k,
                      check_relerr(H, Hfd, 9, 1));
        /* PSD: x^T H x >= 0 for random x */
        double q = 0;
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++)
                q += pts[0][i] * H[3 * i + j] * pts[0][j];
        CHECK(q >= -1e-12);
    }
    /* the friction force never exceeds mu * lambda */
    double x[3] = {1, 0.05, 1}, g[3] = {0};
    c.lam = 10;
    crom_contact_eval(&c.p, c.k, c.m, x, c.xprev, c.lam, c.eps, g, NULL);
    double gt[3], gn = g[0] * c.p.n[0] + g[1] * c.p.n[1] + g[2] * c.p.n[2];
    for (int i = 0; i < 3; i++)
        gt[i] = g[i] - gn * c.p.n[i];
    CHECK_NEAR(sqrt(gt[0] * gt[0] + gt[1] * gt[1] + gt[2] * gt[2]), c.p.mu * c.lam, 1e-9);
}

/* A sphere obstacle: the gradient against differences, the Hessian against
 * differences once the negative term it leaves out, −k m (φ/ρ)(I − n nᵀ),
 * is added back, and positive semidefinite as returned */
static void test_sphere_derivatives(void)
{
    cctx c = {{.mu = 0.4, .sphere = 1, .c = {0.1, -0.2, 0.3}, .r = 0.5}, 1e4, 0.3, {0.12, 0.31, 0.35}, 20, 1e-3};
    double pts[3][3] = {{0.15, 0.25, 0.4}, {0.1, 0.28, 0.3}, {0.9, 0.9, 0.9}};
    for (int k = 0; k < 3; k++) {
        double x[3], g[3] = {0}, H[9] = {0}, gfd[3], Hfd[9], n[3];
        memcpy(x, pts[k], sizeof x);
        crom_contact_eval(&c.p, c.k, c.m, x, c.xprev, c.lam, c.eps, g, H);
        double phi = crom_contact_depth(&c.p, x), rho = 0, lo = 1e300;
        crom_contact_normal(&c.p, x, n);
        for (int i = 0; i < 3; i++)
            rho += (x[i] - c.p.c[i]) * (x[i] - c.p.c[i]);
        rho = sqrt(rho);
        double Hx[9];
        for (int i = 0; i < 9; i++)
            Hx[i] = H[i] - c.k * c.m * phi / rho * ((i % 4 == 0) - n[i / 3] * n[i % 3]);
        check_fd_gradient(c_energy, &c, x, 3, 1e-7, gfd);
        check_fd_jacobian(c_grad, &c, x, 3, 3, 1e-7, Hfd);
        double eg = check_relerr(g, gfd, 3, 1e-3), eh = check_relerr(Hx, Hfd, 9, 1);
        double a = H[0], dd = H[0] * H[4] - H[1] * H[3];
        for (int i = 0; i < 3; i++) /* smallest leading-minor test of PSD via x^T H x on a few vectors */
            lo = fmin(lo, H[4 * i]);
        fprintf(stderr, "sphere contact, point %d (depth %.3g m): gradient vs FD %.2e, Hessian (with the dropped "
                        "term) vs FD %.2e\n", k, phi, eg, eh);
        CHECK_LT(eg, 1e-6);
        CHECK_LT(eh, 1e-5);
        CHECK(lo >= -1e-9 && a >= -1e-9 && dd >= -1e-6 * (1 + fabs(a * H[4])));
        CHECK(k < 2 ? phi > 0 : phi == 0);
    }
}

/* ---------------------------------------------------------- helpers */

static void momentum(const crom_sim *s, double P[3])
{
    P[0] = P[1] = P[2] = 0;
    for (int i = 0; i < s->nv; i++)
        for (int k = 0; k < 3; k++)
            P[k] += s->sys.mass[i] * s->v[3 * i + k];
}

/* ------------------------------------------- momentum and dissipation */

static void test_momentum_and_energy(void)
{
    crom_mesh m;
    double dims[3] = {1, 0.3, 0.2};
    fx_gen(CROM_MESHGEN_BOX, dims, 0.1, &m);
    crom_scenario sc;
    crom_scenario_defaults(&sc);
    sc.gravity[1] = 0;
    sc.youngs = 1e5; /* soft: the spin deforms it visibly */
    sc.dt = 0.01;
    sc.tol = 1e-11;
    sc.v0[0] = 0.3;
    sc.v0[2] = -0.2;
    sc.spin[1] = 4;
    sc.spin[2] = 1;
    crom_sim s;
    CHECK(crom_sim_init(&s, &m, &sc) == 0);
    double P0[3], P[3], K, E, W, prev = INFINITY, maxrise = 0, Emax = 0;
    momentum(&s, P0);
    double Pn = sqrt(P0[0] * P0[0] + P0[1] * P0[1] + P0[2] * P0[2]);
    double worst = 0;
    for (int k = 0; k < 40; k++) {
        crom_sim_stats st;
        int rc = crom_sim_step(&s, &st);
        CHECK_MSG(rc == 0, "step %d: %s", k, crom_errmsg());
        if (rc)
            break;
        momentum(&s, P);
        for (int c = 0; c < 3; c++)
            worst = fmax(worst, fabs(P[c] - P0[c]) / Pn);
        crom_sim_energies(&s, &K, &E, &W);
        double tot = K + E;
        if (tot - prev > maxrise)
            maxrise = tot - prev;
        prev = tot;
        Emax = fmax(Emax, E);
    }
    fprintf(stderr, "momentum drift %.2e (relative), largest energy rise %.2e J, peak elastic %.3g J, final %.6g J\n",
            worst, maxrise, Emax, prev);
    CHECK_LT(worst, 1e-9);     /* conserved to the solver tolerance */
    CHECK(Emax > 1e-3);         /* the body really deformed */
    CHECK(maxrise <= 1e-9 * prev); /* implicit Euler never gains energy */
    crom_sim_free(&s);
    crom_mesh_free(&m);
}

/* ---------------------------------------------------------- free fall */

static void test_free_fall(void)
{
    crom_mesh m;
    fx_gen(CROM_MESHGEN_SPHERE, NULL, 0.2, &m);
    crom_scenario sc;
    crom_scenario_defaults(&sc);
    sc.dt = 0.02;
    crom_sim s;
    CHECK(crom_sim_init(&s, &m, &sc) == 0);
    double worst = 0, g = sc.gravity[1];
    for (int n = 1; n <= 25; n++) {
        crom_sim_stats st;
        CHECK(crom_sim_step(&s, &st) == 0);
        /* implicit Euler: v_n = n h g, x_n = X + h² g n(n+1)/2 = ½ g t (t + h) */
        double t = n * sc.dt, uy = 0.5 * g * t * (t + sc.dt);
        for (int i = 0; i < s.nv; i++) {
            worst = fmax(worst, fabs(s.x[3 * i + 1] - m.X[3 * i + 1] - uy) / fabs(uy));
            worst = fmax(worst, fabs(s.x[3 * i] - m.X[3 * i]) + fabs(s.x[3 * i + 2] - m.X[3 * i + 2]));
            worst = fmax(worst, fabs(s.v[3 * i + 1] - n * sc.dt * g) / fabs(n * sc.dt * g));
        }
    }
    fprintf(stderr, "free fall: largest relative deviation from 1/2 g t (t+h) %.2e\n", worst);
    CHECK_LT(worst, 1e-12);
    crom_sim_free(&s);
    crom_mesh_free(&m);
}

/* --------------------------------------------------------- cantilever */

/* Static deflection of a beam clamped at x = 0 under its own weight: one
 * implicit Euler step with a huge time step is the static equilibrium.
 * Euler–Bernoulli: tip deflection q L⁴ / (8 E I), q = ρ g A, I = b h³/12. */
static double cantilever_error(double size)
{
    double L = 1, b = 0.1, dims[3] = {L, b, b};
    crom_mesh m;
    fx_gen(CROM_MESHGEN_BOX, dims, size, &m);
    for (int i = 0; i < m.nv; i++)
        m.X[3 * i] += L / 2; /* x in [0, L] */
    CHECK(crom_mesh_region_spec(&m, "clamp=x<1e-9") == 0);
    CHECK(crom_mesh_region_spec(&m, "tip=x>0.999999") == 0);
    crom_scenario sc;
    crom_scenario_defaults(&sc);
    sc.youngs = 1e8;
    sc.poisson = 0; /* Euler–Bernoulli ignores the Poisson effect */
    sc.density = 1000;
    sc.dt = 1e3;
    sc.steps = 1;
    sc.tol = 1e-10; /* 0.1 nm on a 1 m beam; round-off stops near 1e-12 */
    strcpy(sc.pins[sc.npins++], "clamp");
    crom_sim s;
    CHECK(crom_sim_init(&s, &m, &sc) == 0);
    crom_sim_stats st;
    int rc = crom_sim_step(&s, &st);
    CHECK_MSG(rc == 0, "cantilever: %s", crom_errmsg());
    const crom_mesh_region *tip = crom_mesh_find_region(&m, "tip");
    double d = 0;
    for (int k = 0; k < tip->n; k++)
        d += s.x[3 * tip->idx[k] + 1] - m.X[3 * tip->idx[k] + 1];
    d /= tip->n;
    double q = sc.density * 9.81 * b * b, I = b * b * b * b / 12;
    double eb = -q * L * L * L * L / (8 * sc.youngs * I);
    double err = fabs(d - eb) / fabs(eb);
    fprintf(stderr, "cantilever h=%.4f: %d tets, tip deflection %.6e m, Euler-Bernoulli %.6e m, error %.3f\n",
            size, m.nt, d, eb, err);
    crom_sim_free(&s);
    crom_mesh_free(&m);
    return err;
}

static void test_cantilever(void)
{
    double e1 = cantilever_error(0.05), e2 = cantilever_error(0.033), e3 = cantilever_error(0.025);
    CHECK_LT(e2, e1);
    CHECK_LT(e3, e2);
    CHECK_LT(e3, 0.2);
}

/* A bar of two materials in tension (--youngs REGION=E): clamped at x = 0,
 * pulled by a total force F at x = L, ν = 0; the halves stretch as springs
 * in series, u(L/2) = F (L/2) / (E1 A) and u(L) = u(L/2) + F (L/2) / (E2 A)
 * (a static solve: one implicit step of dt = 1e3 s). Also: the scenario
 * text gives the regions back, a region holding no whole tet or not on
 * the mesh is refused, and one material everywhere by region equals the
 * uniform run bit for bit. */
static double bar_x(const crom_mesh *m, const crom_sim *s, const char *region)
{
    const crom_mesh_region *r = crom_mesh_find_region(m, region);
    double d = 0;
    for (int k = 0; k < r->n; k++)
        d += s->x[3 * r->idx[k]] - m->X[3 * r->idx[k]];
    return d / r->n;
}

/* The 1 x 0.1 x 0.1 bar of the material tests (20 x 2 x 2 cubes of 0.05,
 * from the origin along x), its regions (spec strings, NULL-terminated) and
 * a scenario read from flag text. */
static void material_bar(crom_mesh *m, const char *const *regions, const char *text, crom_scenario *sc)
{
    const double lo[3] = {0, 0, 0};
    fx_box_mesh(m, 20, 2, 2, lo, 0.05, 0, NULL, NULL);
    for (int i = 0; regions[i]; i++)
        CHECK(crom_mesh_region_spec(m, regions[i]) == 0);
    crom_scenario_defaults(sc);
    CHECK(crom_scenario_parse_text(text, sc) == 0);
}

/* Two densities: a bar hanging from its end x = 1 under gravity along −x,
 * its lower half (x < 0.5) of density ρ2, the upper ρ1, ν = 0: the lumped
 * masses sum to ρ1 V1 + ρ2 V2 exactly, and the free end x = 0 drops by
 * g/E ∫_0^L ∫_0^x ρ = g/E (3ρ2/8 + ρ1/8) (the weight below each section
 * stretching it), within 1% on 20 elements; with one density ρ1 g/E /2. */
static void test_two_densities(void)
{
    crom_mesh m;
    const double E = 1e6, g = 9.81, r1 = 1000, r2 = 3000;
    crom_scenario sc;
    material_bar(&m, (const char *[]){"top=x>0.999999", "end=x<1e-9", NULL},
                 "--youngs 1e6\n--poisson 0\n--density 1000\n--gravity -9.81,0,0\n--dt 1e3\n--steps 1\n--tol 1e-11\n"
                 "--pin top\n--density x<0.500001=3000\n", &sc);
    CHECK(sc.nmat == 1 && sc.mat[0].density == r2 && isnan(sc.mat[0].youngs));
    char *text = crom_scenario_text(&sc);
    CHECK(text && strstr(text, "--density x<0.500001=3000\n"));
    free(text);
    crom_sim s;
    crom_sim_stats st;
    CHECK(crom_sim_init(&s, &m, &sc) == 0);
    CHECK_REL(s.sys.total_mass, 0.5 * 0.01 * (r1 + r2), 1e-12);
    CHECK_MSG(crom_sim_step(&s, &st) == 0, "two densities: %s", crom_errmsg());
    double d = -bar_x(&m, &s, "end"), want = g / E * (3 * r2 / 8 + r1 / 8);
    fprintf(stderr, "two densities: the free end drops %.6e m (analytic %.6e)\n", d, want);
    CHECK_REL(d, want, 0.01);
    crom_sim_free(&s);
    crom_mesh_free(&m);
}

static void test_two_materials(void)
{
    crom_mesh m;
    const double L = 1, b = 0.1, F = 100, E1 = 1e7, E2 = 4e7;
    crom_scenario sc;
    material_bar(&m, (const char *[]){"clamp=x<1e-9", "mid=x>0.499999&x<0.500001", "tip=x>0.999999", NULL},
                 "--youngs 1e7\n--poisson 0\n--gravity 0,0,0\n--dt 1e3\n--steps 1\n--tol 1e-10\n--pin clamp\n"
                 "--force tip=100,0,0\n--youngs x>0.499999=4e7\n", &sc);
    CHECK(sc.nmat == 1 && sc.mat[0].youngs == E2 && isnan(sc.mat[0].poisson));
    char *text = crom_scenario_text(&sc);
    crom_scenario back;
    crom_scenario_defaults(&back);
    CHECK(text && strstr(text, "--youngs x>0.499999=40000000\n") && crom_scenario_parse_text(text, &back) == 0 &&
          back.nmat == 1 && !strcmp(back.mat[0].ref, "x>0.499999") && back.mat[0].youngs == E2);
    free(text);
    crom_sim s;
    crom_sim_stats st;
    CHECK(crom_sim_init(&s, &m, &sc) == 0);
    CHECK_MSG(crom_sim_step(&s, &st) == 0, "two materials: %s", crom_errmsg());
    double A = b * b, um = bar_x(&m, &s, "mid"), ut = bar_x(&m, &s, "tip");
    double em = F * (L / 2) / (E1 * A), et = em + F * (L / 2) / (E2 * A);
    fprintf(stderr, "two materials: u(L/2) = %.6e m (series springs %.6e), u(L) = %.6e m (%.6e)\n", um, em, ut, et);
    CHECK_REL(um, em, 0.01);
    CHECK_REL(ut, et, 0.01);
    /* every per-element path of the system takes the tet's own material (the
     * element energy once took the body's: crom_nlsim's line search then
     * disagreed with its gradient and stalled) */
    int stiff = 0, same = 1;
    for (int t = 0; t < m.nt; t++) {
        double xe[12], Ee = NAN;
        crom_fem_tet_positions(&s.sys.fem, s.x, t, xe);
        const crom_material *mt = crom_fem_tet_material(&s.sys.fem, t);
        double want = crom_fem_tet_energy(mt, xe, s.sys.fem.Dminv + 9 * (size_t)t, s.sys.fem.vol[t]);
        crom_system_elem_eval(&s.sys, t, xe, 0, &Ee, NULL, NULL);
        same &= crom_system_elem_energy(&s.sys, t, xe) == want && Ee == want;
        stiff += mt->E == E2;
    }
    CHECK_MSG(same && stiff == m.nt / 2, "element energies with their own material (%d of %d tets stiff)", stiff, m.nt);
    crom_sim_free(&s);

    /* the same material by region and everywhere: the same run */
    crom_scenario one = sc, all = sc;
    one.mat[0].youngs = E1;
    all.nmat = 0;
    crom_sim a, c;
    CHECK(crom_sim_init(&a, &m, &one) == 0 && crom_sim_init(&c, &m, &all) == 0);
    CHECK(crom_sim_step(&a, &st) == 0 && crom_sim_step(&c, &st) == 0);
    CHECK(!memcmp(a.x, c.x, sizeof(double) * 3 * (size_t)m.nv));
    crom_sim_free(&a);
    crom_sim_free(&c);

    /* refused: no whole tet (a face), not on the mesh, a shell */
    crom_scenario bad = sc;
    strcpy(bad.mat[0].ref, "mid");
    CHECK(crom_sim_init(&s, &m, &bad) == CROM_EUSAGE && strstr(crom_errmsg(), "no whole tet"));
    strcpy(bad.mat[0].ref, "nowhere");
    CHECK(crom_sim_init(&s, &m, &bad) == CROM_EUSAGE);
    crom_err_clear();
    crom_mesh_free(&m);
}

/* A patch test across the interface: the same two-material bar (its
 * interface the mesh plane x = L/2), ν = 0, clamped at x = 0 and its end
 * x = L moved by δ = 1e-6 m (--velocity over one static step). The exact
 * solution is piecewise linear, u_x = ε1 x up to L/2 and then
 * ε1 L/2 + ε2 (x − L/2), with E1 ε1 = E2 ε2 (the stress is continuous)
 * and ε1 + ε2 = 2δ/L, u_y = u_z = 0: linear tets hold it exactly, so every
 * vertex must have it to round-off and the strain's nonlinearity (O(δ)). */
static void test_interface_patch(void)
{
    crom_mesh m;
    const double L = 1, E1 = 1e7, E2 = 4e7, delta = 1e-6;
    crom_scenario sc;
    material_bar(&m, (const char *[]){"clamp=x<1e-9", "tip=x>0.999999", NULL},
                 "--youngs 1e7\n--poisson 0\n--gravity 0,0,0\n--dt 1e3\n--steps 1\n--tol 1e-12\n--pin clamp\n"
                 "--velocity tip=1e-9,0,0@0:1000\n--youngs x>0.499999=4e7\n", &sc);
    crom_sim s;
    crom_sim_stats st;
    CHECK(crom_sim_init(&s, &m, &sc) == 0);
    CHECK_MSG(crom_sim_step(&s, &st) == 0, "interface patch: %s", crom_errmsg());
    double e1 = 2 * delta / L * E2 / (E1 + E2), e2 = 2 * delta / L * E1 / (E1 + E2), worst = 0;
    for (int v = 0; v < m.nv; v++) {
        const double *X = m.X + 3 * v;
        double want = X[0] <= L / 2 ? e1 * X[0] : e1 * L / 2 + e2 * (X[0] - L / 2);
        worst = fmax(worst, fabs(s.x[3 * v] - X[0] - want));
        worst = fmax(worst, fmax(fabs(s.x[3 * v + 1] - X[1]), fabs(s.x[3 * v + 2] - X[2])));
    }
    fprintf(stderr, "interface patch: largest distance from the piecewise-linear field %.2e m (end moved %.0e m)\n",
            worst, delta);
    CHECK_LT(worst, 1e-5 * delta);
    crom_sim_free(&s);
    crom_mesh_free(&m);
}

/* ----------------------------------------- prescribed regions, contact */

static void test_prescribed_and_contact(void)
{
    crom_mesh m;
    fx_gen(CROM_MESHGEN_BOX, NULL, 0.15, &m);
    CHECK(crom_mesh_region_spec(&m, "top=y>0.45") == 0);
    CHECK(crom_mesh_region_spec(&m, "bottom=y<-0.45") == 0);
    crom_scenario sc;
    crom_scenario_defaults(&sc);
    sc.gravity[1] = 0;
    sc.dt = 0.01;
    CHECK(crom_scenario_option(&sc, 0x1000 + 8, "top=0,-2,0@0:0.05") == 0); /* --velocity */
    strcpy(sc.pins[sc.npins++], "bottom");
    crom_sim s;
    CHECK(crom_sim_init(&s, &m, &sc) == 0);
    crom_sim_stats st;
    for (int k = 0; k < 8; k++)
        CHECK(crom_sim_step(&s, &st) == 0);
    const crom_mesh_region *top = crom_mesh_find_region(&m, "top"), *bot = crom_mesh_find_region(&m, "bottom");
    double etop = 0, ebot = 0;
    for (int k = 0; k < top->n; k++) /* moved 2 m/s for 0.05 s, then held: -0.1 m */
        etop = fmax(etop, fabs(s.x[3 * top->idx[k] + 1] - m.X[3 * top->idx[k] + 1] + 0.1));
    for (int k = 0; k < bot->n; k++)
        for (int c = 0; c < 3; c++)
            ebot = fmax(ebot, fabs(s.x[3 * bot->idx[k] + c] - m.X[3 * bot->idx[k] + c]));
    CHECK_LT(etop, 1e-14);
    CHECK(ebot == 0);
    crom_sim_free(&s);

    /* a block resting on a floor under gravity settles at depth g/k */
    crom_scenario_defaults(&sc);
    sc.dt = 0.01;
    sc.damping = 20;
    sc.nplanes = 1;
    sc.plane[0] = (crom_contact_plane){.n = {0, 1, 0}, .d = -0.5, .mu = 0.5};
    CHECK(crom_sim_init(&s, &m, &sc) == 0);
    for (int k = 0; k < 60; k++)
        CHECK(crom_sim_step(&s, &st) == 0);
    double depth = 0, n = 0, mbottom = 0;
    for (int i = 0; i < s.nv; i++)
        if (m.X[3 * i + 1] < -0.499) {
            depth += -0.5 - s.x[3 * i + 1];
            mbottom += s.sys.mass[i];
            n++;
        }
    depth /= n;
    /* the bottom layer carries the whole weight: k d Σ m_bottom = M g */
    double expect = 9.81 * s.sys.total_mass / (sc.contact_stiffness * mbottom);
    fprintf(stderr, "resting depth %.4e m, expected about %.4e m\n", depth, expect);
    CHECK(depth > 0.7 * expect && depth < 1.3 * expect);
    /* at rest: velocities nearly zero */
    double vmax = 0;
    for (int i = 0; i < s.n; i++)
        vmax = fmax(vmax, fabs(s.v[i]));
    CHECK_LT(vmax, 1e-2);
    crom_sim_free(&s);
    crom_mesh_free(&m);
}

/* ------------------------------------------------- convergence tolerance */

/* Newton stops when its correction is below --tol of the body size, measured
 * on the last Newton direction or, when Newton contracts fast, on a
 * simplified Newton correction with the reused factor. Either way the state
 * it returns must lie within tol of the exact solution of the step: compare
 * every step, started from the same state, with one converged to 1e-12. */
static void test_tolerance(void)
{
    crom_mesh m;
    fx_gen(CROM_MESHGEN_BOX, NULL, 0.08, &m);
    CHECK(crom_mesh_region_spec(&m, "top=y>0.45") == 0);
    CHECK(crom_mesh_region_spec(&m, "bottom=y<-0.45") == 0);
    crom_scenario loose, tight;
    crom_scenario_defaults(&loose);
    loose.gravity[1] = 0;
    loose.dt = 0.01;
    CHECK(crom_scenario_option(&loose, 0x1000 + 8, "top=0,-2,0@0:0.1") == 0); /* --velocity */
    strcpy(loose.pins[loose.npins++], "bottom");
    tight = loose;
    tight.tol = 1e-12;
    crom_sim a, b;
    CHECK(crom_sim_init(&a, &m, &loose) == 0);
    CHECK(crom_sim_init(&b, &m, &tight) == 0);
    double worst = 0;
    int newton = 0, solves = 0;
    for (int k = 0; k < 12; k++) {
        crom_sim_stats sa, sb;
        memcpy(a.x, b.x, sizeof(double) * (size_t)a.n);
        memcpy(a.v, b.v, sizeof(double) * (size_t)a.n);
        CHECK(crom_sim_step(&a, &sa) == 0);
        CHECK(crom_sim_step(&b, &sb) == 0);
        CHECK(sa.residual <= loose.tol);
        newton += sa.newton;
        solves += sa.cg;
        for (int i = 0; i < a.n; i++)
            worst = fmax(worst, fabs(a.x[i] - b.x[i]) / a.L);
    }
    fprintf(stderr, "tol %.0e: worst distance to the converged state %.2e of the body size "
            "(%d Newton iterations, %d solves in 12 steps)\n", loose.tol, worst, newton, solves);
    CHECK_LT(worst, loose.tol);
    CHECK(worst > 0); /* the loose run really stopped earlier */
    crom_sim_free(&a);
    crom_sim_free(&b);
    crom_mesh_free(&m);
}

static void test_bad_scenarios(void)
{
    crom_mesh m;
    fx_gen(CROM_MESHGEN_BOX, NULL, 0.3, &m);
    crom_scenario sc;
    crom_sim s;
    struct {
        const char *what;
        double E, nu, rho;
    } bad[] = {{"E = 0", 0, 0.25, 1000}, {"E < 0", -1, 0.25, 1000}, {"rho = 0", 1e6, 0.25, 0},
               {"nu = 0.5", 1e6, 0.5, 1000}, {"nu = -1", 1e6, -1, 1000}, {"NaN E", NAN, 0.25, 1000}};
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
        crom_scenario_defaults(&sc);
        sc.youngs = bad[i].E;
        sc.poisson = bad[i].nu;
        sc.density = bad[i].rho;
        CHECK_MSG(crom_sim_init(&s, &m, &sc) == CROM_EUSAGE, "%s accepted", bad[i].what);
    }
    crom_scenario_defaults(&sc);
    strcpy(sc.pins[sc.npins++], "nosuch");
    CHECK(crom_sim_init(&s, &m, &sc) == CROM_EUSAGE);
    CHECK(strstr(crom_errmsg(), "unknown region 'nosuch'") != NULL);
    crom_scenario_defaults(&sc);
    strcpy(sc.pins[sc.npins++], "y>7");
    CHECK(crom_sim_init(&s, &m, &sc) == CROM_EUSAGE);
    CHECK(strstr(crom_errmsg(), "selects no vertex") != NULL);
    /* option parsing */
    crom_scenario_defaults(&sc);
    CHECK(crom_scenario_option(&sc, 0x1000 + 3, "nan") == CROM_EUSAGE);     /* --dt */
    CHECK(crom_scenario_option(&sc, 0x1000 + 3, "-0.1") == CROM_EUSAGE);
    CHECK(crom_scenario_option(&sc, 0x1000 + 6, "0,nan,0") == CROM_EUSAGE); /* --gravity */
    CHECK(crom_scenario_option(&sc, 0x1000 + 8, "top=1,2") == CROM_EUSAGE); /* --velocity */
    CHECK(crom_scenario_option(&sc, 0x1000 + 8, "top=1,2,3@0.5:0.1") == CROM_EUSAGE);
    CHECK(crom_scenario_option(&sc, 0x1000 + 10, "0,0,0,1") == CROM_EUSAGE); /* --plane */
    CHECK(crom_scenario_option(&sc, 0x1000 + 18, "0,0,0,0") == CROM_EUSAGE); /* --sphere: radius 0 */
    CHECK(crom_scenario_option(&sc, 0x1000 + 18, "0,0,0,1,-1") == CROM_EUSAGE);
    /* the canonical text parses back to the same scenario */
    crom_scenario a, b;
    crom_scenario_defaults(&a);
    crom_scenario_option(&a, 0x1000 + 8, "y>0.45=0,-2,0@0:0.1");
    crom_scenario_option(&a, 0x1000 + 9, "tip=0,0,5@0.2:");
    crom_scenario_option(&a, 0x1000 + 10, "0,1,1,-0.5,0.3");
    crom_scenario_option(&a, 0x1000 + 18, "0.1,0.2,-0.3,0.25,0.4"); /* --sphere */
    crom_scenario_option(&a, 0x1000 + 10, "0,0,1,0");
    strcpy(a.pins[a.npins++], "bottom");
    char *text = crom_scenario_text(&a);
    crom_scenario_defaults(&b);
    char *save = NULL, *line = strtok_r(text, "\n", &save);
    int ok = 1;
    for (; line; line = strtok_r(NULL, "\n", &save)) {
        char *sp = strchr(line, ' ');
        *sp = 0;
        int key = -1;
        for (const crom_opt *o = crom_scenario_opts; o->name; o++)
            if (!strcmp(o->name, line + 2))
                key = o->key;
        if (key == 0x1000 + 7)
            strcpy(b.pins[b.npins++], sp + 1);
        else
            ok &= crom_scenario_option(&b, key, sp + 1) == 0;
    }
    free(text);
    CHECK(ok);
    CHECK(memcmp(&a, &b, sizeof a) == 0);
    crom_mesh_free(&m);
}


/* ------------------------------------------- a-posteriori error indicator */

/* crom_sim_residual measures a state reached by other means: the full
 * run's own step scores at its tolerance; a state moved off it by a smooth
 * field scores the size of that field (K0⁻¹ g, exact for a small move when
 * the step is static: dt = 1 s here, so that M/h² is small against the
 * stiffness, and strains of 0.5%, so that K(x) is near K0), growing tenfold
 * with it; a moved pin is reported in metres. */
static void test_residual_indicator(void)
{
    crom_mesh m;
    fx_gen(CROM_MESHGEN_BOX, NULL, 0.15, &m);
    CHECK(crom_mesh_region_spec(&m, "bottom=y<-0.45") == 0);
    crom_scenario sc;
    crom_scenario_defaults(&sc);
    sc.dt = 1;
    sc.youngs = 2e6;
    sc.tol = 1e-10;
    strcpy(sc.pins[sc.npins++], "bottom");
    crom_sim s, r;
    CHECK(crom_sim_init(&s, &m, &sc) == 0);
    CHECK(crom_sim_init(&r, &m, &sc) == 0);
    size_t n = (size_t)s.n;
    double *xp = malloc(sizeof(double) * n), *vp = malloc(sizeof(double) * n), *y = malloc(sizeof(double) * n);
    crom_sim_stats st;
    for (int k = 0; k < 5; k++)
        CHECK(crom_sim_step(&s, &st) == 0);
    memcpy(xp, s.x, sizeof(double) * n);
    memcpy(vp, s.v, sizeof(double) * n);
    CHECK(crom_sim_step(&s, &st) == 0);
    double err, urms, bc;
    CHECK(crom_sim_residual(&r, s.t, xp, vp, s.x, &err, &urms, &bc) == 0);
    fprintf(stderr, "indicator of the full step: %.3e of %.3e m (bc %.1e m)\n", err, urms, bc);
    CHECK_LT(err, 1e-7 * urms);
    CHECK(bc == 0);
    CHECK_LT(fabs(r.v[7] - s.v[7]), 1e-15 + 1e-12 * fabs(s.v[7]));
    /* a smooth field over the free vertices at 0.3%, 3% and 30% of the sag */
    double prev = err;
    for (double a = 0.003; a < 1; a *= 10) {
        double dd = 0, mm = 0;
        for (int i = 0; i < s.nv; i++)
            for (int c = 0; c < 3; c++) {
                const double *X = m.X + 3 * i;
                double d = s.fixed[3 * i] ? 0 : a * urms * sin(3 * X[0] + c) * (X[1] + 0.5);
                y[3 * i + c] = s.x[3 * i + c] + d;
                dd += s.sys.mass[i] * d * d;
            }
        for (int i = 0; i < s.nv; i++)
            mm += s.sys.mass[i];
        CHECK(crom_sim_residual(&r, s.t, xp, vp, y, &err, &urms, &bc) == 0);
        fprintf(stderr, "moved by %.3e m RMS: estimated %.3e m\n", sqrt(dd / mm), err);
        CHECK(err > 0.95 * sqrt(dd / mm) && err < 1.05 * sqrt(dd / mm));
        CHECK(err > 5 * prev);
        prev = err;
    }
    /* a pinned vertex moved by 1 mm */
    memcpy(y, s.x, sizeof(double) * n);
    int pv = -1;
    for (int i = 0; i < s.nv && pv < 0; i++)
        if (s.fixed[3 * i])
            pv = i;
    CHECK(pv >= 0);
    y[3 * pv + 2] += 1e-3;
    CHECK(crom_sim_residual(&r, s.t, xp, vp, y, &err, &urms, &bc) == 0);
    CHECK_NEAR(bc, 1e-3, 1e-15);
    free(xp);
    free(vp);
    free(y);
    crom_sim_free(&s);
    crom_sim_free(&r);
    crom_mesh_free(&m);
}

int main(void)
{
    check_begin("test_sim");
    test_contact_derivatives();
    test_sphere_derivatives();
    test_free_fall();
    test_momentum_and_energy();
    test_prescribed_and_contact();
    test_tolerance();
    test_bad_scenarios();
    test_cantilever();
    test_two_materials();
    test_interface_patch();
    test_two_densities();
    test_residual_indicator();
    return check_done();
}
