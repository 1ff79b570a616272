/* test_plane.c — 2-D solids in plane strain (shell.h,
 * crom_shell_material_plane; issue 19 item 3):
 *   - the system of a plane mesh (triangles in z = 0, half of them
 *     clockwise) has gradient and Hessian that agree with central
 *     differences of its energy, exact and projected (the projected one
 *     positive semi-definite);
 *   - an in-plane rigid motion stores no energy whichever way a triangle
 *     runs; a uniform in-plane stretch stores t A Ψ(F) of the 3-D material
 *     with F₃₃ = 1; a z displacement alone stores the z springs' ½ kz z²
 *     per corner and no more (z is decoupled from x, y);
 *   - a clamped cantilever (1 × 0.1 m) under a small tip load deflects as
 *     Timoshenko's plane-strain beam, P L³ / (3 E' I) + P L / (κ G A) with
 *     E' = E / (1 − ν²), converging under refinement (within 5% at the
 *     finest of three meshes), and its z stays 0 exactly. */
#include <lapacke.h>

#include "check.h"
#include "fixtures.h"
#include "base/err.h"
#include "base/rng.h"
#include "phys/shell.h"
#include "phys/sim.h"
#include "phys/system.h"

/* An nx × ny grid of L × h quads in z = 0, each split into four triangles
 * about its centre; odd quads' triangles listed clockwise. */
static void plane_grid(crom_mesh *m, int nx, int ny, double L, double h, double t)
{
    memset(m, 0, sizeof *m);
    int ng = (nx + 1) * (ny + 1), nq = nx * ny;
    m->nv = ng + nq;
    m->X = calloc(3 * (size_t)m->nv, sizeof(double));
    m->tris = malloc(sizeof(int) * 12 * (size_t)nq);
    m->tets = malloc(sizeof(int) * 4);
    for (int j = 0; j <= ny; j++)
        for (int i = 0; i <= nx; i++) {
            m->X[3 * (j * (nx + 1) + i)] = L * i / nx;
            m->X[3 * (j * (nx + 1) + i) + 1] = h * j / ny;
        }
    for (int j = 0; j < ny; j++)
        for (int i = 0; i < nx; i++) {
            int q = j * nx + i, c = ng + q, a = j * (nx + 1) + i, corner[4] = {a, a + 1, a + nx + 2, a + nx + 1};
            m->X[3 * c] = L * (i + 0.5) / nx;
            m->X[3 * c + 1] = h * (j + 0.5) / ny;
            for (int k = 0; k < 4; k++) {
                int *tr = m->tris + 3 * (size_t)m->ntri++;
                tr[0] = corner[k];
                tr[1] = (q % 2) ? c : corner[(k + 1) % 4];
                tr[2] = (q % 2) ? corner[(k + 1) % 4] : c;
            }
        }
    m->thickness = t;
    m->plane = 1;
}

static crom_system *g_sys;
static double sys_E(const double *x, void *c)
{
    (void)c;
    double E = NAN;
    crom_system_energy(g_sys, x, &E);
    return E;
}

static void test_derivatives(void)
{
    crom_mesh m;
    plane_grid(&m, 3, 2, 0.3, 0.2, 0.05);
    crom_system s;
    CHECK(crom_system_init(&s, &m, 1e6, 0.35, 1000) == 0 && s.shell && s.sh.mat.plane && s.sh.nh == 0);
    crom_rng rng;
    crom_rng_seed(&rng, 9);
    int n = s.n;
    double *x = malloc(sizeof(double) * n), *g = malloc(sizeof(double) * n), *gf = malloc(sizeof(double) * n);
    double *H = malloc(sizeof(double) * s.nnz), *Hd = calloc((size_t)n * n, sizeof(double));
    for (int i = 0; i < n; i++)
        x[i] = m.X[i] + 0.03 * (crom_rng_uniform(&rng) - 0.5);
    for (int project = 0; project < 2; project++) {
        crom_fem_opts fo = {project, 0, NULL, 1};
        double E;
        CHECK(crom_system_assemble(&s, x, &fo, &E, g, H) == 0);
        g_sys = &s;
        check_fd_gradient(sys_E, NULL, x, n, 1e-6, gf);
        double eg = check_relerr(g, gf, n, 1e-9);
        /* dense Hessian from the upper CSC, against differences of the gradient */
        memset(Hd, 0, sizeof(double) * (size_t)n * n);
        for (int j = 0; j < n; j++)
            for (int l = s.colptr[j]; l < s.colptr[j + 1]; l++)
                Hd[(size_t)s.rowind[l] * n + j] = Hd[(size_t)j * n + s.rowind[l]] = H[l];
        double eh = 0, hs = 0;
        for (int j = 0; j < n; j++) {
            double xj = x[j], *gp = malloc(sizeof(double) * n), *gm = malloc(sizeof(double) * n);
            x[j] = xj + 1e-6;
            crom_system_assemble(&s, x, &fo, NULL, gp, NULL);
            x[j] = xj - 1e-6;
            crom_system_assemble(&s, x, &fo, NULL, gm, NULL);
            x[j] = xj;
            for (int i = 0; i < n; i++) {
                eh = fmax(eh, fabs((gp[i] - gm[i]) / 2e-6 - Hd[(size_t)i * n + j]));
                hs = fmax(hs, fabs(Hd[(size_t)i * n + j]));
            }
            free(gp), free(gm);
        }
        fprintf(stderr, "plane strain (%s Hessians): gradient vs FD %.2e, Hessian vs FD %.2e of %.2e\n",
                project ? "projected" : "true", eg, eh, hs);
        CHECK_LT(eg, 1e-6);
        if (!project)
            CHECK_LT(eh, 1e-5 * hs);
        else
            CHECK_LT(-1e-9 * hs, fx_min_eig(Hd, n));
    }
    /* rigid in-plane motion: no energy; a stretch: t A Ψ(F); z alone: the springs */
    double th = 0.7, c = cos(th), sn = sin(th), E;
    for (int v = 0; v < m.nv; v++) {
        const double *X = m.X + 3 * v;
        x[3 * v] = c * X[0] - sn * X[1] + 0.3;
        x[3 * v + 1] = sn * X[0] + c * X[1] - 0.2;
        x[3 * v + 2] = 0;
    }
    CHECK(crom_system_energy(&s, x, &E) == 0);
    CHECK_LT(fabs(E), 1e-9);
    for (int v = 0; v < m.nv; v++) {
        x[3 * v] = 1.1 * m.X[3 * v];
        x[3 * v + 1] = 0.95 * m.X[3 * v + 1];
    }
    crom_material mat;
    crom_material_init(&mat, 1e6, 0.35, 1000);
    const double F3[9] = {1.1, 0, 0, 0, 0.95, 0, 0, 0, 1};
    CHECK(crom_system_energy(&s, x, &E) == 0);
    CHECK_REL(E, 0.05 * 0.3 * 0.2 * crom_fem_psi(&mat, F3), 1e-12);
    double zz = 0;
    for (int v = 0; v < m.nv; v++) {
        x[3 * v] = m.X[3 * v];
        x[3 * v + 1] = m.X[3 * v + 1];
        x[3 * v + 2] = 0.01 * (v % 3);
    }
    for (int t = 0; t < m.ntri; t++)
        for (int k = 0; k < 3; k++)
            zz += 0.5 * s.sh.mat.kz * pow(x[3 * m.tris[3 * t + k] + 2], 2);
    CHECK(crom_system_energy(&s, x, &E) == 0);
    CHECK_REL(E, zz, 1e-12);
    free(x), free(g), free(gf), free(H), free(Hd);
    crom_system_free(&s);
    crom_mesh_free(&m);
}

/* tip deflection of the plane-strain cantilever on an nx × ny grid over
 * Timoshenko's */
static double cantilever_ratio(int ny, double *zmax)
{
    const double L = 1, h = 0.1, t = 0.1, E = 1e7, nu = 0.3, P = 10;
    crom_mesh m;
    plane_grid(&m, 10 * ny, ny, L, h, t);
    CHECK(crom_mesh_region_spec(&m, "clamp=x<1e-9") == 0 && crom_mesh_region_spec(&m, "tip=x>0.999999") == 0);
    crom_scenario sc;
    crom_scenario_defaults(&sc);
    char text[256];
    snprintf(text, sizeof text, "--youngs %g\n--poisson %g\n--gravity 0,0,0\n--dt 1e3\n--steps 1\n--tol 1e-11\n"
             "--pin clamp\n--force tip=0,%g,0\n", E, nu, -P);
    CHECK(crom_scenario_parse_text(text, &sc) == 0);
    crom_sim s;
    crom_sim_stats st;
    double ratio = NAN;
    *zmax = NAN;
    if (crom_sim_init(&s, &m, &sc) == 0 && crom_sim_step(&s, &st) == 0) {
        double w = 0, k = 0;
        *zmax = 0;
        for (int v = 0; v < m.nv; v++) {
            if (m.X[3 * v] > L - 1e-9) {
                w -= s.x[3 * v + 1] - m.X[3 * v + 1];
                k++;
            }
            *zmax = fmax(*zmax, fabs(s.x[3 * v + 2]));
        }
        double Ep = E / (1 - nu * nu), Iz = t * h * h * h / 12, G = E / (2 * (1 + nu));
        double want = P * L * L * L / (3 * Ep * Iz) + P * L / (5.0 / 6 * G * t * h);
        ratio = (w / k) / want;
    } else {
        CHECK_MSG(0, "cantilever: %s", crom_errmsg());
    }
    crom_sim_free(&s);
    crom_mesh_free(&m);
    return ratio;
}

static void test_cantilever(void)
{
    double r[3], z[3];
    int ny[3] = {2, 4, 8};
    for (int k = 0; k < 3; k++) {
        r[k] = cantilever_ratio(ny[k], &z[k]);
        fprintf(stderr, "plane-strain cantilever, %d x %d quads: tip deflection / Timoshenko %.4f (largest |z| %g)\n",
                10 * ny[k], ny[k], r[k], z[k]);
        CHECK(z[k] == 0);
    }
    CHECK_LT(fabs(r[2] - 1), 0.05);
    CHECK_LT(fabs(r[2] - 1), fabs(r[1] - 1));
    CHECK_LT(fabs(r[1] - 1), fabs(r[0] - 1));
}

int main(void)
{
    check_begin("test_plane");
    test_derivatives();
    test_cantilever();
    return check_done();
}
