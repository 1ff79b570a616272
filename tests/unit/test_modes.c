/* test_modes.c — linear vibration modes against exact answers: a dense
 * generalized eigensolve (LAPACK dsygvd) on a small mesh, M-orthonormality
 * and eigen-residuals, rigid modes of a free body (six; fewer when pinned at
 * a point), every copy of exactly repeated eigenvalues (a square beam's
 * bending pair, two identical beams), and a clamped beam converging to
 * Euler–Bernoulli. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <lapacke.h>

#include "check.h"
#include "fixtures.h"
#include "base/err.h"
#include "phys/fem.h"
#include "mesh/mesh.h"
#include "mesh/meshgen.h"
#include "phys/modes.h"

static int make_box(double size, double dx, double dy, double dz, crom_mesh *m)
{
    const double dims[3] = {dx, dy, dz};
    return fx_gen(CROM_MESHGEN_BOX, dims, size, m);
}

/* DOF mask of the vertices with x <= xmax */
static unsigned char *pin_x(const crom_mesh *m, double xmax, int *npin)
{
    unsigned char *f = calloc(3 * (size_t)m->nv, 1);
    *npin = 0;
    for (int v = 0; v < m->nv; v++)
        if (m->X[3 * v] <= xmax) {
            memset(f + 3 * v, 1, 3);
            ++*npin;
        }
    return f;
}

/* pieces square beams side by side (axes 4nh apart along y), each nx × 2n × 2n
 * cubes of edge h along the x axis: the quadrant y, z >= 0 cut into the six
 * tets around each cube's main diagonal (one per order of stepping along x,
 * y and z), then turned three times by 90° about the x axis. The cuts of
 * the faces y = 0 and z = 0 match under that turn, so the mesh is
 * conforming and maps to itself by it: each beam bends along y and along z
 * at exactly the same frequency, and two beams have every mode twice. */
static void square_beams(int pieces, int nx, int n, double h, crom_mesh *m)
{
    int w = 2 * n + 1, per = (nx + 1) * w * w, t = 0, flipped;
    memset(m, 0, sizeof *m);
    m->nv = pieces * per;
    m->nt = 24 * pieces * nx * n * n;
    m->X = malloc(sizeof(double) * 3 * m->nv);
    m->tets = malloc(sizeof(int) * 4 * m->nt);
    for (int v = 0; v < m->nv; v++) {
        int p = v / per, i = v % per % (nx + 1), j = v % per / (nx + 1) % w - n, k = v % per / (nx + 1) / w - n;
        m->X[3 * v] = i * h;
        m->X[3 * v + 1] = (j + 4 * n * p) * h;
        m->X[3 * v + 2] = k * h;
    }
    for (int p = 0; p < pieces; p++)
        for (int turn = 0; turn < 4; turn++)
            for (int cube = 0; cube < nx * n * n; cube++)
                for (int a = 0; a < 3; a++)
                    for (int b = 0; b < 3; b++) {
                        if (b == a)
                            continue;
                        int c[3] = {cube % nx, cube / nx % n, cube / nx / n}, step[3] = {a, b, 3 - a - b};
                        int *tv = m->tets + 4 * t++;
                        for (int s = 0; s < 4; s++) {
                            int y = c[1], z = c[2];
                            for (int q = 0; q < turn; q++) { /* (y, z) -> (-z, y) */
                                int y0 = y;
                                y = -z;
                                z = y0;
                            }
                            tv[s] = p * per + ((z + n) * w + y + n) * (nx + 1) + c[0];
                            if (s < 3)
                                c[step[s]]++;
                        }
                    }
    crom_mesh_orient(m, &flipped);
}

/* The rest stiffness as a dense matrix on the free DOFs (free[] lists them)
 * and the lumped masses. */
static void dense_system(const crom_mesh *mesh, const crom_material *mat, const unsigned char *fixed,
                         int *nf, int **free_dofs, double **K, double **M)
{
    crom_fem fem;
    CHECK(crom_fem_init(&fem, mesh, mat) == 0);
    double *H = malloc(sizeof(double) * fem.nnz);
    CHECK(crom_fem_assemble(&fem, mesh->X, NULL, NULL, NULL, H) == 0);
    int n = fem.n, *map = malloc(sizeof(int) * n), c = 0;
    *free_dofs = malloc(sizeof(int) * n);
    for (int d = 0; d < n; d++) {
        map[d] = (fixed && fixed[d]) ? -1 : c;
        if (map[d] >= 0)
            (*free_dofs)[c++] = d;
    }
    *nf = c;
    *K = calloc((size_t)c * c, sizeof(double));
    *M = calloc((size_t)c * c, sizeof(double));
    for (int col = 0; col < n; col++)
        for (int k = fem.colptr[col]; k < fem.colptr[col + 1]; k++) {
            int i = map[fem.rowind[k]], j = map[col];
            if (i >= 0 && j >= 0)
                (*K)[(size_t)i * c + j] = (*K)[(size_t)j * c + i] = H[k];
        }
    for (int j = 0; j < c; j++)
        (*M)[(size_t)j * c + j] = fem.mass[(*free_dofs)[j] / 3];
    free(H);
    free(map);
    crom_fem_free(&fem);
}

/* ----------------------------------------------- dense reference (LAPACK) */

/* The eigenvalues of K φ = λ M φ on the free DOFs (their count in *nf),
 * ascending, from the dense generalized eigensolver LAPACK dsygvd. */
static double *dense_eigenvalues(const crom_mesh *mesh, const crom_material *mat,
                                 const unsigned char *fixed, int *nf)
{
    int *fd;
    double *K, *M;
    dense_system(mesh, mat, fixed, nf, &fd, &K, &M);
    double *w = malloc(sizeof(double) * *nf);
    CHECK(LAPACKE_dsygvd(LAPACK_ROW_MAJOR, 1, 'N', 'U', *nf, K, *nf, M, *nf, w) == 0);
    free(K);
    free(M);
    free(fd);
    return w;
}

static void test_dense(void)
{
    crom_mesh m;
    if (make_box(0.12, 0.6, 0.2, 0.15, &m))
        return;
    crom_material mat;
    crom_material_init(&mat, 1e6, 0.3, 1100);
    int npin;
    unsigned char *fixed = pin_x(&m, -0.3 + 1e-9, &npin);
    for (int pinned = 0; pinned < 2; pinned++) {
        const unsigned char *fx = pinned ? fixed : NULL;
        int nf;
        double *w = dense_eigenvalues(&m, &mat, fx, &nf);
        crom_modes_opts o;
        crom_modes_defaults(&o);
        o.count = 24;
        o.keep_rigid = 1;
        crom_modes r;
        int rc = crom_modes_compute(&m, &mat, fx, &o, &r);
        CHECK_MSG(rc == 0, "modes: %s", crom_errmsg());
        if (rc)
            break;
        CHECK(r.nfree == nf);
        double worst = 0, wmax = w[nf - 1];
        for (int j = 0; j < o.count; j++) {
            /* relative to the eigenvalue, absolute (vs the largest) for rigid zeros */
            double e = fabs(r.omega2[j] - w[j]) / fmax(fabs(w[j]), 1e-12 * wmax);
            if (j >= (pinned ? 0 : 6))
                worst = fmax(worst, e);
            else
                CHECK_MSG(fabs(r.omega2[j]) < 1e-10 * wmax && fabs(w[j]) < 1e-10 * wmax,
                          "rigid %d: %g (ARPACK) %g (dsygvd), largest %g", j, r.omega2[j], w[j], wmax);
        }
        fprintf(stderr, "%s, %d vertices, %d free DOFs: largest relative difference from dsygvd over %d "
                        "eigenvalues %.2e (omega^2 from %.6g to %.6g), rigid %d, %ld solves\n",
                pinned ? "pinned" : "free", m.nv, nf, o.count, worst, r.omega2[pinned ? 0 : 6],
                r.omega2[o.count - 1], r.nrigid, r.solves);
        CHECK_LT(worst, 1e-9);
        CHECK(r.nrigid == (pinned ? 0 : 6));
        crom_modes_free(&r);
        free(w);
    }
    free(fixed);
    crom_mesh_free(&m);
}

/* ------------------------------------- orthonormality and eigen-residuals */

static void test_orthonormal(void)
{
    crom_mesh m;
    if (make_box(0.06, 0.6, 0.3, 0.2, &m))
        return;
    crom_material mat;
    crom_material_init(&mat, 2.5e6, 0.45, 1000);
    int npin;
    unsigned char *fixed = pin_x(&m, -0.3 + 1e-9, &npin);
    crom_modes_opts o;
    crom_modes_defaults(&o);
    o.count = 30;
    crom_modes r;
    int rc = crom_modes_compute(&m, &mat, fixed, &o, &r);
    CHECK_MSG(rc == 0, "modes: %s", crom_errmsg());
    if (!rc) {
        crom_fem fem;
        crom_fem_init(&fem, &m, &mat);
        int k = r.k;
        double worst = 0, wres = 0, pin = 0;
        for (int a = 0; a < k; a++)
            for (int b = a; b < k; b++) {
                double s = 0;
                for (int d = 0; d < r.n; d++)
                    s += fem.mass[d / 3] * r.phi[(size_t)d * k + a] * r.phi[(size_t)d * k + b];
                worst = fmax(worst, fabs(s - (a == b)));
            }
        for (int j = 0; j < k; j++)
            wres = fmax(wres, r.residual[j]);
        for (int d = 0; d < r.n; d++)
            if (fixed[d])
                for (int j = 0; j < k; j++)
                    pin = fmax(pin, fabs(r.phi[(size_t)d * k + j]));
        int ascending = 1;
        for (int j = 1; j < k; j++)
            ascending &= r.omega2[j] >= r.omega2[j - 1];
        fprintf(stderr, "%d vertices, %d modes (%.4g to %.4g Hz): max |Phi^T M Phi - I| %.2e, max "
                        "||K phi - w^2 M phi|| / ||K phi|| %.2e, %ld solves, %d restarts\n",
                m.nv, k, r.freq[0], r.freq[k - 1], worst, wres, r.solves, r.restarts);
        CHECK_LT(worst, 1e-10);
        CHECK_LT(wres, 1e-6);
        CHECK(pin == 0);
        CHECK(ascending);
        CHECK(r.nrigid == 0);
        /* the same seed gives the same bits */
        crom_modes r2;
        CHECK(crom_modes_compute(&m, &mat, fixed, &o, &r2) == 0);
        CHECK(!memcmp(r.phi, r2.phi, sizeof(double) * (size_t)r.n * k));
        /* another seed: the same frequencies */
        o.seed = 7;
        crom_modes r3;
        CHECK(crom_modes_compute(&m, &mat, fixed, &o, &r3) == 0);
        double df = 0;
        for (int j = 0; j < k; j++)
            df = fmax(df, fabs(r3.freq[j] - r.freq[j]) / r.freq[j]);
        CHECK_LT(df, 1e-9);
        crom_modes_free(&r2);
        crom_modes_free(&r3);
        crom_fem_free(&fem);
    }
    crom_modes_free(&r);
    free(fixed);
    crom_mesh_free(&m);
}

/* ------------------------------------------------------- rigid modes */

static void test_free_body(void)
{
    crom_mesh m;
    if (make_box(0.08, 0.5, 0.3, 0.2, &m))
        return;
    crom_material mat;
    crom_material_init(&mat, 1e6, 0.25, 1000);
    crom_modes_opts o;
    crom_modes_defaults(&o);
    o.count = 10;
    o.keep_rigid = 1;
    crom_modes r;
    int rc = crom_modes_compute(&m, &mat, NULL, &o, &r);
    CHECK_MSG(rc == 0, "modes: %s", crom_errmsg());
    if (rc)
        return;
    fprintf(stderr, "free body, %d vertices: omega^2 =", m.nv);
    for (int j = 0; j < r.k; j++)
        fprintf(stderr, " %.3g", r.omega2[j]);
    double kres = 0;
    for (int j = 0; j < 6; j++)
        kres = fmax(kres, r.residual[j]);
    fprintf(stderr, "\n  rigid threshold %.3g (mean eigenvalue %.3g), %d rigid found, their largest "
                    "||K phi|| / (mean eigenvalue ||M phi||) %.2g\n",
            r.rigid_threshold, r.lambda_mean, r.nrigid, kres);
    CHECK(r.nrigid == 6);
    CHECK(r.rigid_kept == 1);
    for (int j = 0; j < 6; j++)
        CHECK(fabs(r.omega2[j]) < 1e-6 * r.omega2[6]);
    CHECK_LT(kres, 1e-12);
    CHECK(r.omega2[6] > 1e3 * r.rigid_threshold);
    /* canonical rigid block: mode 0 is the x translation 1/sqrt(total mass) */
    crom_fem fem;
    crom_fem_init(&fem, &m, &mat);
    double t = 1 / sqrt(fem.total_mass), dev = 0;
    for (int v = 0; v < m.nv; v++)
        for (int c = 0; c < 3; c++)
            dev = fmax(dev, fabs(r.phi[(size_t)(3 * v + c) * r.k + 0] - (c == 0 ? t : 0)));
    CHECK_MSG(dev < 1e-8 * t, "mode 0 differs from the x translation by %.3g (of %.3g)", dev, t);
    /* dropped: the same deformation frequencies */
    crom_modes d;
    o.keep_rigid = 0;
    o.count = 4;
    CHECK(crom_modes_compute(&m, &mat, NULL, &o, &d) == 0);
    CHECK(d.nrigid == 6 && d.rigid_kept == 0 && d.k == 4);
    for (int j = 0; j < 4; j++)
        CHECK_REL(d.omega2[j], r.omega2[6 + j], 1e-9);
    crom_modes_free(&d);
    /* pinned at one vertex: three rigid rotations about it */
    unsigned char *fixed = calloc(3 * (size_t)m.nv, 1);
    memset(fixed, 1, 3);
    o.keep_rigid = 1;
    o.count = 5;
    CHECK(crom_modes_compute(&m, &mat, fixed, &o, &d) == 0);
    fprintf(stderr, "pinned at one vertex: %d rigid detected\n", d.nrigid);
    CHECK(d.nrigid == 3);
    crom_modes_free(&d);
    free(fixed);
    crom_fem_free(&fem);
    crom_modes_free(&r);
    crom_mesh_free(&m);
}

/* ------------------------------------------------ repeated eigenvalues */

/* Exactly repeated eigenvalues, each copy of which a single-vector Lanczos
 * iteration (ARPACK) has to find by itself: a square beam clamped at one
 * end, on a mesh symmetric in y and z (each bending frequency twice), and
 * two such beams, free (twelve rigid modes, every deformation mode twice,
 * bending four times). Every copy must be there as dsygvd finds it, for
 * several start vectors. */
static void test_repeated(void)
{
    crom_material mat;
    crom_material_init(&mat, 1e6, 0.3, 1000);
    for (int pieces = 1; pieces <= 2; pieces++) {
        crom_mesh m;
        square_beams(pieces, 10, 1, 0.05, &m);
        int npin = 0, nf;
        unsigned char *fixed = pieces == 1 ? pin_x(&m, 1e-9, &npin) : NULL;
        double *w = dense_eigenvalues(&m, &mat, fixed, &nf);
        int nrig = pieces == 1 ? 0 : 12, count = nrig + 12, mult = 1;
        while (fabs(w[nrig + mult] / w[nrig] - 1) < 1e-10)
            mult++;
        CHECK_MSG(mult == 2 * pieces, "the lowest deformation mode is %d-fold, expected %d", mult, 2 * pieces);
        for (uint64_t seed = 1; seed <= 3; seed++) {
            crom_modes_opts o;
            crom_modes_defaults(&o);
            o.count = count;
            o.keep_rigid = 1;
            o.seed = seed;
            crom_modes r;
            int rc = crom_modes_compute(&m, &mat, fixed, &o, &r);
            CHECK_MSG(rc == 0, "modes: %s", crom_errmsg());
            if (rc)
                break;
            double worst = 0, split = 0, rigid = 0;
            for (int j = nrig; j < count; j++)
                worst = fmax(worst, fabs(r.omega2[j] / w[j] - 1));
            for (int j = 1; j < mult; j++)
                split = fmax(split, fabs(r.omega2[nrig + j] / r.omega2[nrig] - 1));
            for (int j = 0; j < nrig; j++)
                rigid = fmax(rigid, fabs(r.omega2[j]) + r.residual[j]);
            if (seed == 1)
                fprintf(stderr, "%d square beam%s, %d free DOFs: lowest deformation mode %d-fold (dsygvd), "
                                "found %d times (spread %.1e); largest relative difference from dsygvd "
                                "over %d modes %.2e; rigid %d (max |omega^2| + residual %.1e), %ld solves\n",
                        pieces, pieces > 1 ? "s" : "", nf, mult, mult, split, count - nrig, worst, r.nrigid,
                        rigid, r.solves);
            CHECK(r.nrigid == nrig);
            CHECK_LT(worst, 1e-9);
            CHECK_LT(split, 1e-10);
            CHECK_LT(rigid, 1e-12);
            crom_modes_free(&r);
        }
        free(w);
        free(fixed);
        crom_mesh_free(&m);
    }
}

/* ----------------------------------------- clamped beam, Euler–Bernoulli */

static void test_beam(void)
{
    /* L = 1, square cross-section b, clamped at x = -L/2, nu = 0:
     * f_n = (beta_n L)^2 / (2 pi L^2) sqrt(E I / (rho A)), I / A = b^2 / 12;
     * the square section makes each bending frequency a pair (y and z). */
    const double L = 1, b = 0.05, E = 1e6, rho = 1000;
    const double betaL[2] = {1.8751040687, 4.6940911330};
    double fEB[2];
    for (int i = 0; i < 2; i++)
        fEB[i] = betaL[i] * betaL[i] / (2 * M_PI * L * L) * sqrt(E * b * b / 12 / rho);
    const double sizes[] = {0.025, 0.0167, 0.0125, 0.01};
    double prev[2] = {INFINITY, INFINITY}, first[2] = {0, 0}, third[2] = {0, 0};
    crom_material mat;
    crom_material_init(&mat, E, 0, rho);
    for (int s = 0; s < 4; s++) {
        crom_mesh m;
        if (make_box(sizes[s], L, b, b, &m))
            return;
        int npin;
        unsigned char *fixed = pin_x(&m, -L / 2 + 1e-9, &npin);
        crom_modes_opts o;
        crom_modes_defaults(&o);
        o.count = 4;
        crom_modes r;
        int rc = crom_modes_compute(&m, &mat, fixed, &o, &r);
        CHECK_MSG(rc == 0, "modes: %s", crom_errmsg());
        if (rc)
            return;
        double err[2];
        for (int i = 0; i < 2; i++) {
            double f = 0.5 * (r.freq[2 * i] + r.freq[2 * i + 1]);
            err[i] = (f - fEB[i]) / fEB[i];
        }
        fprintf(stderr, "beam h = %.4f (%d vertices): f1 %.5f, %.5f Hz (EB %.5f), f2 %.5f, %.5f Hz (EB "
                        "%.5f): errors %+.4f, %+.4f; %ld solves, %.2f s\n",
                sizes[s], m.nv, r.freq[0], r.freq[1], fEB[0], r.freq[2], r.freq[3], fEB[1], err[0], err[1],
                r.solves, r.t_assemble + r.t_analyze + r.t_factor + r.t_lanczos);
        for (int i = 0; i < 2; i++) {
            /* linear tets are too stiff in bending: from above, shrinking */
            CHECK(err[i] > 0);
            CHECK_MSG(err[i] < prev[i], "refinement %d: error %d grew from %.4f to %.4f", s, i, prev[i],
                      err[i]);
            prev[i] = err[i];
            if (s == 0)
                first[i] = err[i];
            if (s == 2)
                third[i] = err[i];
        }
        crom_modes_free(&r);
        free(fixed);
        crom_mesh_free(&m);
    }
    /* halving h cuts the error about fourfold (eigenvalue error O(h^2)) */
    for (int i = 0; i < 2; i++)
        CHECK_MSG(first[i] / third[i] > 3, "mode %d: h halved, error only / %.2f", i + 1, first[i] / third[i]);
    /* 5.9% and 4.8% at 3,400 vertices (4 tets across the section, L/b = 20,
     * where Timoshenko's correction is below 1%) */
    CHECK_LT(prev[0], 0.065);
    CHECK_LT(prev[1], 0.055);
}

/* ------------------------------------------------------- bad requests */

static void test_errors(void)
{
    crom_mesh m;
    if (make_box(0.5, 1, 1, 1, &m))
        return;
    crom_material mat;
    crom_material_init(&mat, 1e6, 0.3, 1000);
    crom_modes_opts o;
    crom_modes_defaults(&o);
    crom_modes r;
    o.count = 3 * m.nv + 1;
    CHECK(crom_modes_compute(&m, &mat, NULL, &o, &r) == CROM_EUSAGE);
    CHECK(strstr(crom_errmsg(), "free degrees of freedom") != NULL);
    CHECK(r.phi == NULL);
    /* with rigid modes dropped, only 3nv - 6 deformation modes exist */
    o.count = 3 * m.nv - 5;
    CHECK(crom_modes_compute(&m, &mat, NULL, &o, &r) == CROM_EUSAGE);
    CHECK(strstr(crom_errmsg(), "6 rigid modes") != NULL);
    fprintf(stderr, "messages: %s\n", crom_errmsg());
    o.count = 3 * m.nv - 6;
    CHECK(crom_modes_compute(&m, &mat, NULL, &o, &r) == 0 && r.k == 3 * m.nv - 6 && r.nrigid == 6);
    /* all but two of them (and one more, for next_omega2): ARPACK with every
     * Lanczos vector the space has, against the dense solve all take */
    crom_modes a;
    o.count = 3 * m.nv - 8;
    CHECK(crom_modes_compute(&m, &mat, NULL, &o, &a) == 0 && a.k == o.count && a.nrigid == 6);
    double worst = 0;
    for (int j = 0; j < a.k && r.k; j++)
        worst = fmax(worst, fabs(a.omega2[j] / r.omega2[j] - 1));
    fprintf(stderr, "%d of %d deformation modes (ARPACK) against all (dense): largest relative difference "
                    "%.2e\n", a.k, r.k, worst);
    CHECK_LT(worst, 1e-9);
    crom_modes_free(&a);
    crom_modes_free(&r);
    unsigned char *all = malloc(3 * (size_t)m.nv);
    memset(all, 1, 3 * (size_t)m.nv);
    o.count = 1;
    CHECK(crom_modes_compute(&m, &mat, all, &o, &r) == CROM_EUSAGE);
    free(all);
    /* pin resolution */
    unsigned char *f;
    int np;
    const char *refs[] = {"x<-0.4", "nosuch"};
    CHECK(crom_modes_pins(&m, 1, refs, &f, &np) == 0 && np > 0);
    free(f);
    CHECK(crom_modes_pins(&m, 2, refs, &f, &np) == CROM_EUSAGE);
    crom_mesh_free(&m);
}

int main(void)
{
    check_begin("test_modes");
    test_dense();
    test_orthonormal();
    test_free_body();
    test_repeated();
    test_beam();
    test_errors();
    return check_done();
}
