/* test_fem.c — stable neo-Hookean material, element kernel, analytic SPD
 * projection (against LAPACK), small-strain moduli, and mesh assembly. */
#include <lapacke.h>
#include <stdint.h>

#include "check.h"
#include "fixtures.h"
#include "base/err.h"
#include "phys/fem.h"
#include "base/rng.h"

/* ---- helpers ------------------------------------------------------------ */

static void matmul3(const double A[9], const double B[9], double C[9])
{
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            C[3 * i + j] = A[3 * i] * B[j] + A[3 * i + 1] * B[3 + j] + A[3 * i + 2] * B[6 + j];
}

static double det3(const double A[9])
{
    return A[0] * (A[4] * A[8] - A[5] * A[7]) - A[1] * (A[3] * A[8] - A[5] * A[6]) +
           A[2] * (A[3] * A[7] - A[4] * A[6]);
}

/* F = R1 diag(s) R2 */
static void F_from_sigma(crom_rng *r, const double s[3], double F[9])
{
    double R1[9], R2[9], D[9] = {s[0], 0, 0, 0, s[1], 0, 0, 0, s[2]}, T[9];
    fx_random_rotation(r, R1);
    fx_random_rotation(r, R2);
    matmul3(R1, D, T);
    matmul3(T, R2, F);
}

#define NFTEST 24
/* The i-th test deformation gradient: rest, stretch, compression, shear,
 * inverted, repeated / degenerate singular values, random. */
static void test_F(int i, crom_rng *r, double F[9])
{
    static const double Id[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    memcpy(F, Id, sizeof Id);
    switch (i) {
    case 0: return;                                          /* rest */
    case 1: F[0] = F[4] = F[8] = 2; return;                  /* 2I */
    case 2: F[0] = F[4] = F[8] = 0.5; return;                /* 0.5 I */
    case 3: F[0] = 1.5; F[4] = 1.2; F[8] = 1.1; return;      /* stretch */
    case 4: F[0] = 0.6; F[4] = 0.7; F[8] = 0.8; return;      /* compress */
    case 5: F[1] = 0.7; return;                              /* shear */
    case 6: F[8] = -0.5; return;                             /* inverted */
    case 7: F[8] = -1; return;                               /* reflection */
    case 8: F[8] = 1 + 1e-9; return;                         /* near-repeated */
    case 9: { double s[3] = {2, 2, 0.5}; F_from_sigma(r, s, F); return; }
    case 10: { double s[3] = {0.3, 0.3, -0.3}; F_from_sigma(r, s, F); return; }
    case 11: { double s[3] = {1.3, 1e-7, -1e-7}; F_from_sigma(r, s, F); return; }
    case 12: { double s[3] = {1, 1, 1}; F_from_sigma(r, s, F); return; } /* rotation */
    case 13: { double s[3] = {0.9, 0.9, 0}; F_from_sigma(r, s, F); return; }
    default:
        for (int k = 0; k < 9; k++)
            F[k] = Id[k] + (i < 19 ? 0.3 : 0.8) * crom_rng_normal(r);
        if (i % 2) /* invert half of them */
            for (int k = 0; k < 3; k++)
                F[6 + k] = -F[6 + k];
        return;
    }
}

/* Reference projection: LAPACK eigen-decomposition, clamp, rebuild; also
 * returns the smallest eigenvalue of the input. */
static double lapack_project(const double A[81], double Ap[81])
{
    double Z[81], w[9];
    memcpy(Z, A, sizeof Z);
    int info = LAPACKE_dsyev(LAPACK_ROW_MAJOR, 'V', 'U', 9, Z, 9, w);
    if (info)
        fprintf(stderr, "dsyev info %d\n", info);
    memset(Ap, 0, sizeof(double) * 81);
    for (int k = 0; k < 9; k++) {
        double l = w[k] > 0 ? w[k] : 0;
        for (int i = 0; i < 9; i++)
            for (int j = 0; j < 9; j++)
                Ap[9 * i + j] += l * Z[9 * i + k] * Z[9 * j + k];
    }
    return w[0];
}

static double norm(const double *a, int n)
{
    double s = 0;
    for (int i = 0; i < n; i++)
        s += a[i] * a[i];
    return sqrt(s);
}

static double maxabs(const double *a, int n)
{
    double s = 0;
    for (int i = 0; i < n; i++)
        if (fabs(a[i]) > s)
            s = fabs(a[i]);
    return s;
}

static double maxdiff(const double *a, const double *b, int n)
{
    double s = 0;
    for (int i = 0; i < n; i++)
        if (fabs(a[i] - b[i]) > s)
            s = fabs(a[i] - b[i]);
    return s;
}

/* ---- material ----------------------------------------------------------- */

static void test_material(void)
{
    crom_material m;
    CHECK(crom_material_init(&m, 1e6, 0.25, 1000) == CROM_OK);
    double muL = 1e6 / 2.5, lamL = 1e6 * 0.25 / (1.25 * 0.5);
    CHECK_REL(m.mu_lame, muL, 1e-14);
    CHECK_REL(m.lambda_lame, lamL, 1e-14);
    CHECK_REL(m.mu, 4.0 / 3.0 * muL, 1e-14);
    CHECK_REL(m.lambda, lamL + 5.0 / 6.0 * muL, 1e-13);
    CHECK_REL(m.alpha, 1 + 3 * m.mu / (4 * m.lambda), 1e-15);

    /* negative Poisson ratio: λL < 0, but the SNH λ stays positive */
    CHECK(crom_material_init(&m, 1e6, -0.95, 1000) == CROM_OK);
    CHECK_LT(m.lambda_lame, 0);
    CHECK_LT(0, m.lambda);
    CHECK(isfinite(m.alpha));
    CHECK_REL(m.lambda, m.lambda_lame + 5.0 / 6.0 * m.mu_lame, 1e-12);
    /* nearly incompressible: large but finite */
    CHECK(crom_material_init(&m, 1e6, 0.4999, 1000) == CROM_OK);
    CHECK(isfinite(m.lambda) && m.lambda > 1e9);

    static const struct {
        double E, nu, rho;
        const char *word;
    } bad[] = {
        {0, 0.25, 1000, "E ="},         {-1e6, 0.25, 1000, "E ="},
        {NAN, 0.25, 1000, "E ="},       {INFINITY, 0.25, 1000, "E ="},
        {1e6, 0.5, 1000, "nu ="},       {1e6, -1, 1000, "nu ="},
        {1e6, 0.7, 1000, "nu ="},       {1e6, -3, 1000, "nu ="},
        {1e6, NAN, 1000, "nu ="},       {1e6, 0.25, 0, "rho ="},
        {1e6, 0.25, -1, "rho ="},       {1e6, 0.25, NAN, "rho ="},
        {1e6, 0.25, INFINITY, "rho ="},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        crom_err_clear();
        int rc = crom_material_init(&m, bad[i].E, bad[i].nu, bad[i].rho);
        CHECK_MSG(rc == CROM_EUSAGE, "bad material %zu: rc %d", i, rc);
        CHECK_MSG(strstr(crom_errmsg(), bad[i].word) != NULL,
                  "bad material %zu: message '%s' lacks '%s'", i, crom_errmsg(),
                  bad[i].word);
    }
}

/* ---- material point ------------------------------------------------------ */

static double psi_fn(const double *F, void *ctx) { return crom_fem_psi(ctx, F); }
static void pk1_fn(const double *F, void *ctx, double *P) { crom_fem_pk1(ctx, F, P); }

static void test_stress(void)
{
    crom_material m;
    crom_material_init(&m, 1e6, 0.45, 1000);
    crom_rng r;
    crom_rng_seed(&r, 11);
    double worst_P = 0, worst_A = 0;
    for (int i = 0; i < NFTEST; i++) {
        double F[9], P[9], Pfd[9], A[81], Afd[81];
        test_F(i, &r, F);
        crom_fem_pk1(&m, F, P);
        check_fd_gradient(psi_fn, &m, F, 9, 1e-6, Pfd);
        double e = check_relerr(P, Pfd, 9, m.mu);
        CHECK_MSG(e < 1e-6, "F case %d: P vs FD relerr %.3g", i, e);
        worst_P = fmax(worst_P, e);
        crom_fem_dPdF(&m, F, 0, A);
        check_fd_jacobian(pk1_fn, &m, F, 9, 9, 1e-6, Afd);
        e = check_relerr(A, Afd, 81, m.mu);
        CHECK_MSG(e < 1e-5, "F case %d: dP/dF vs FD relerr %.3g", i, e);
        worst_A = fmax(worst_A, e);
        for (int a = 0; a < 9; a++)
            for (int b = 0; b < a; b++)
                CHECK_NEAR(A[9 * a + b], A[9 * b + a], 1e-12 * m.lambda);
    }
    printf("P vs FD of Psi: worst relerr %.2e; dP/dF vs FD of P: %.2e\n", worst_P, worst_A);

    /* rest: zero energy, zero stress */
    double Id[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1}, P[9];
    CHECK_NEAR(crom_fem_psi(&m, Id), 0, 1e-20 * m.mu);
    crom_fem_pk1(&m, Id, P);
    CHECK(maxabs(P, 9) <= 1e-15 * m.mu);
    /* energy finite and positive for inverted and collapsed F */
    double Finv[9] = {1, 0, 0, 0, 1, 0, 0, 0, -1}, Z[9] = {0};
    CHECK(isfinite(crom_fem_psi(&m, Finv)) && crom_fem_psi(&m, Finv) > 0);
    CHECK(isfinite(crom_fem_psi(&m, Z)) && crom_fem_psi(&m, Z) > 0);
}

/* ---- SVD ------------------------------------------------------------------ */

static void test_svd(void)
{
    crom_rng r;
    crom_rng_seed(&r, 5);
    double worst = 0;
    int ninverted = 0;
    for (int i = 0; i < 2000 + NFTEST + 4; i++) {
        double F[9], U[9], V[9], s[3];
        if (i < NFTEST)
            test_F(i, &r, F);
        else if (i == NFTEST) /* zero */
            memset(F, 0, sizeof F);
        else if (i == NFTEST + 1) { /* rank one */
            double a[3] = {1, 2, -1}, b[3] = {0.5, -1, 3};
            for (int k = 0; k < 9; k++)
                F[k] = a[k / 3] * b[k % 3];
        } else if (i == NFTEST + 2) { /* huge */
            test_F(20, &r, F);
            for (int k = 0; k < 9; k++)
                F[k] *= 1e160;
        } else if (i == NFTEST + 3) { /* tiny */
            test_F(21, &r, F);
            for (int k = 0; k < 9; k++)
                F[k] *= 1e-160;
        } else {
            double sg[3];
            for (int k = 0; k < 3; k++) /* clustered singular values */
                sg[k] = (i % 3 == 0) ? 1 + 1e-8 * crom_rng_normal(&r)
                                     : exp(2 * crom_rng_normal(&r));
            if (i % 5 == 1) /* exactly repeated pairs and triples */
                sg[1] = sg[0];
            if (i % 5 == 2)
                sg[2] = sg[1];
            if (i % 7 == 3)
                sg[2] = sg[1] = sg[0];
            if (i % 2)
                sg[2] = -sg[2];
            F_from_sigma(&r, sg, F);
        }
        CHECK(crom_fem_svd3(F, U, s, V) == CROM_OK);
        double D[9] = {s[0], 0, 0, 0, s[1], 0, 0, 0, s[2]}, T[9], Fr[9], VT[9];
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++)
                VT[3 * a + b] = V[3 * b + a];
        matmul3(U, D, T);
        matmul3(T, VT, Fr);
        double nF = norm(F, 9), e = 0;
        for (int k = 0; k < 9; k++)
            e += (Fr[k] - F[k]) * (Fr[k] - F[k]);
        e = nF > 0 ? sqrt(e) / nF : sqrt(e);
        worst = fmax(worst, e);
        CHECK_MSG(e < 1e-14, "svd case %d: ‖UΣVᵀ − F‖/‖F‖ = %.3g", i, e);
        double UtU[9], UT[9];
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++)
                UT[3 * a + b] = U[3 * b + a];
        matmul3(UT, U, UtU);
        double VtV[9];
        matmul3(VT, V, VtV);
        for (int k = 0; k < 9; k++) {
            CHECK_NEAR(UtU[k], k % 4 == 0, 1e-14);
            CHECK_NEAR(VtV[k], k % 4 == 0, 1e-14);
        }
        CHECK_NEAR(det3(U), 1, 1e-14);
        CHECK_NEAR(det3(V), 1, 1e-14);
        CHECK_MSG(s[0] >= s[1] && s[1] >= fabs(s[2]), "svd case %d: sigma %.17g %.17g %.17g",
                  i, s[0], s[1], s[2]);
        {   /* singular values against LAPACK */
            double Fc[9], sl[3], uu[9], vv[9], sup[2];
            memcpy(Fc, F, sizeof Fc);
            LAPACKE_dgesvd(LAPACK_ROW_MAJOR, 'N', 'N', 3, 3, Fc, 3, sl, uu, 3, vv, 3, sup);
            for (int k = 0; k < 3; k++)
                CHECK_MSG(fabs(fabs(s[k]) - sl[k]) <= 1e-14 * sl[0], "svd case %d: sigma %d "
                          "%.17g vs LAPACK %.17g", i, k, s[k], sl[k]);
        }
        double dF = det3(F);
        if (fabs(dF) > 1e-10 * nF * nF * nF) {
            CHECK_MSG((s[2] < 0) == (dF < 0), "svd case %d: sign of σ2 %g vs det %g", i,
                      s[2], dF);
            ninverted += s[2] < 0;
        }
    }
    CHECK(ninverted > 500);
    printf("svd: worst reconstruction error %.2e\n", worst);
    double F[9] = {NAN, 0, 0, 0, 1, 0, 0, 0, 1}, U[9], V[9], s[3];
    CHECK(crom_fem_svd3(F, U, s, V) == CROM_EDATA);
}

/* ---- analytic eigensystem and projection -------------------------------- */

static void test_projection(void)
{
    static const double nus[3] = {0.25, 0.45, -0.3};
    crom_rng r;
    crom_rng_seed(&r, 7);
    double worst_proj = 0, worst_rec = 0, worst_eig = 0;
    int nneg = 0, ncases = 0;
    for (int in = 0; in < 3; in++) {
        crom_material m;
        crom_material_init(&m, 1e6, nus[in], 1000);
        for (int i = 0; i < NFTEST + 200; i++) {
            double F[9];
            if (i < NFTEST)
                test_F(i, &r, F);
            else {
                double s[3];
                for (int k = 0; k < 3; k++)
                    s[k] = 0.2 + 2 * crom_rng_uniform(&r);
                if (i % 4 == 0)
                    s[1] = s[0]; /* repeated */
                if (i % 2)
                    s[2] = -s[2];
                F_from_sigma(&r, s, F);
            }
            double A[81], Ap[81], Aref[81], lam[9], Q[81];
            crom_fem_dPdF(&m, F, 0, A);
            crom_fem_dPdF(&m, F, 1, Ap);
            double lmin = lapack_project(A, Aref);
            double nA = norm(A, 81);
            ncases++;
            nneg += lmin < -1e-9 * nA;

            /* relative to ‖A‖ (‖A⁺‖ can vanish) */
            double e = 0;
            for (int k = 0; k < 81; k++)
                e += (Ap[k] - Aref[k]) * (Ap[k] - Aref[k]);
            e = sqrt(e) / (nA > 0 ? nA : 1);
            worst_proj = fmax(worst_proj, e);
            CHECK_MSG(e < 1e-9, "nu %g F case %d: analytic vs LAPACK projection %.3g",
                      nus[in], i, e);
            double mp = fx_min_eig(Ap, 9);
            CHECK_MSG(mp >= -1e-12 * nA, "nu %g F case %d: projected min eig %.3g",
                      nus[in], i, mp);

            /* eigensystem: Σ λ q qᵀ = A, orthonormal, same spectrum as dsyev */
            crom_fem_dPdF_eig(&m, F, lam, Q);
            double Ar[81] = {0};
            for (int k = 0; k < 9; k++)
                for (int a = 0; a < 9; a++)
                    for (int b = 0; b < 9; b++)
                        Ar[9 * a + b] += lam[k] * Q[9 * k + a] * Q[9 * k + b];
            e = 0;
            for (int k = 0; k < 81; k++)
                e += (Ar[k] - A[k]) * (Ar[k] - A[k]);
            e = sqrt(e) / (nA > 0 ? nA : 1);
            worst_rec = fmax(worst_rec, e);
            CHECK_MSG(e < 1e-12, "nu %g F case %d: eigen reconstruction %.3g", nus[in], i, e);
            for (int k = 0; k < 9; k++)
                for (int l = 0; l <= k; l++) {
                    double d = 0;
                    for (int a = 0; a < 9; a++)
                        d += Q[9 * k + a] * Q[9 * l + a];
                    CHECK_NEAR(d, k == l, 1e-13);
                }
            double Z[81], w[9], ls[9];
            memcpy(Z, A, sizeof Z);
            LAPACKE_dsyev(LAPACK_ROW_MAJOR, 'N', 'U', 9, Z, 9, w);
            memcpy(ls, lam, sizeof ls);
            for (int a = 1; a < 9; a++) /* insertion sort */
                for (int b = a; b > 0 && ls[b] < ls[b - 1]; b--) {
                    double t = ls[b];
                    ls[b] = ls[b - 1];
                    ls[b - 1] = t;
                }
            double lmax = fmax(fabs(w[0]), fabs(w[8]));
            for (int k = 0; k < 9; k++) {
                double d = fabs(ls[k] - w[k]) / (lmax > 0 ? lmax : 1);
                worst_eig = fmax(worst_eig, d);
                CHECK_MSG(d < 1e-12, "nu %g F case %d: eigenvalue %d: %.15g vs %.15g",
                          nus[in], i, k, ls[k], w[k]);
            }
        }
    }
    CHECK(nneg > ncases / 4); /* the projection was exercised */
    printf("projection vs LAPACK: worst %.2e (%d of %d cases indefinite); "
           "eigen reconstruction %.2e; eigenvalues %.2e\n",
           worst_proj, nneg, ncases, worst_rec, worst_eig);
}

/* ---- one tetrahedron ------------------------------------------------------ */

typedef struct {
    const crom_material *m;
    const double *Dminv;
    double V;
} tet_ctx;

static double tet_E_fn(const double *x, void *ctx)
{
    tet_ctx *c = ctx;
    return crom_fem_tet_energy(c->m, x, c->Dminv, c->V);
}

static void tet_g_fn(const double *x, void *ctx, double *g)
{
    tet_ctx *c = ctx;
    crom_fem_tet_eval(c->m, x, c->Dminv, c->V, 0, NULL, g, NULL);
}

/* B (9×12): ∂F/∂x for the test's own reference contraction. */
static void build_B(const double Dminv[9], double B[108])
{
    double G[4][3];
    for (int b = 0; b < 3; b++) {
        G[1][b] = Dminv[b];
        G[2][b] = Dminv[3 + b];
        G[3][b] = Dminv[6 + b];
        G[0][b] = -(G[1][b] + G[2][b] + G[3][b]);
    }
    memset(B, 0, sizeof(double) * 108);
    for (int c = 0; c < 3; c++)
        for (int b = 0; b < 3; b++)
            for (int k = 0; k < 4; k++)
                B[12 * (3 * c + b) + 3 * k + c] = G[k][b];
}

static void test_tet(void)
{
    crom_material m;
    crom_material_init(&m, 2.5e6, 0.25, 1000);
    crom_rng r;
    crom_rng_seed(&r, 3);
    const double L = 0.1; /* edge length (m) */
    double X[12] = {0, 0, 0, L, 0, 0, 0, L, 0, 0, 0, L};
    for (int i = 0; i < 12; i++)
        X[i] += 0.1 * L * crom_rng_normal(&r);
    double Dminv[9], V;
    CHECK(crom_fem_tet_rest(X, Dminv, &V) == CROM_OK);
    {
        double Dm[9], P[9];
        for (int a = 0; a < 3; a++)
            for (int j = 0; j < 3; j++)
                Dm[3 * a + j] = X[3 * (j + 1) + a] - X[a];
        CHECK_REL(V, det3(Dm) / 6, 1e-14);
        matmul3(Dm, Dminv, P);
        for (int k = 0; k < 9; k++)
            CHECK_NEAR(P[k], k % 4 == 0, 1e-13);
    }
    tet_ctx ctx = {&m, Dminv, V};
    double gscale = V * m.mu / L, Hscale = V * m.mu / (L * L);

    /* rest: zero energy and force */
    double E, g[12], H[144];
    CHECK(crom_fem_tet_eval(&m, X, Dminv, V, 0, &E, g, H) == CROM_OK);
    CHECK_NEAR(E, 0, 1e-12 * V * m.mu);
    CHECK(maxabs(g, 12) <= 1e-10 * gscale);
    {   /* and far from the origin (translation invariance in floating point) */
        double xs[12];
        for (int i = 0; i < 12; i++)
            xs[i] = X[i] + (i % 3 == 0 ? 1e3 : i % 3 == 1 ? -2e3 : 5e2);
        CHECK(crom_fem_tet_eval(&m, xs, Dminv, V, 0, &E, g, NULL) == CROM_OK);
        CHECK_NEAR(E, 0, 1e-12 * V * m.mu);
        CHECK_MSG(maxabs(g, 12) <= 1e-8 * gscale, "translated rest force %.3g",
                  maxabs(g, 12) / gscale);
    }

    static const char *names[] = {"rest+", "stretched", "compressed", "sheared",
                                  "inverted", "random", "random inverted", "flat"};
    double worst_g = 0, worst_H = 0;
    for (int cfg = 0; cfg < 8; cfg++) {
        double A[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1}, noise = 0.05;
        switch (cfg) {
        case 0: noise = 1e-3; break;
        case 1: A[0] = 1.6; A[4] = 1.3; break;
        case 2: A[0] = 0.5; A[4] = 0.7; A[8] = 0.6; break;
        case 3: A[1] = 0.8; A[5] = -0.4; break;
        case 4: A[8] = -0.7; break;
        case 5: fx_random_rotation(&r, A); noise = 0.3; break;
        case 6: fx_random_rotation(&r, A); for (int k = 6; k < 9; k++) A[k] = -A[k]; noise = 0.3; break;
        case 7: A[8] = 0.01; break;
        }
        double x[12];
        for (int k = 0; k < 4; k++)
            for (int a = 0; a < 3; a++)
                x[3 * k + a] = A[3 * a] * X[3 * k] + A[3 * a + 1] * X[3 * k + 1] +
                               A[3 * a + 2] * X[3 * k + 2] + noise * L * crom_rng_normal(&r);
        double gfd[12], Hfd[144], Hp[144];
        CHECK(crom_fem_tet_eval(&m, x, Dminv, V, 0, &E, g, H) == CROM_OK);
        CHECK_NEAR(E, tet_E_fn(x, &ctx), 1e-14 * fabs(E));
        check_fd_gradient(tet_E_fn, &ctx, x, 12, 1e-6 * L, gfd);
        double eg = check_relerr(g, gfd, 12, gscale);
        check_fd_jacobian(tet_g_fn, &ctx, x, 12, 12, 1e-6 * L, Hfd);
        double eH = check_relerr(H, Hfd, 144, Hscale);
        CHECK_MSG(eg < 1e-6, "tet %s: gradient vs FD relerr %.3g", names[cfg], eg);
        CHECK_MSG(eH < 1e-5, "tet %s: Hessian vs FD relerr %.3g", names[cfg], eH);
        worst_g = fmax(worst_g, eg);
        worst_H = fmax(worst_H, eH);
        printf("tet %-16s E = %-12.5g gradient relerr %.2e Hessian relerr %.2e\n",
               names[cfg], E, eg, eH);

        /* projected element Hessian = V Bᵀ (LAPACK-projected dP/dF) B, PSD */
        CHECK(crom_fem_tet_eval(&m, x, Dminv, V, 1, NULL, NULL, Hp) == CROM_OK);
        double F[9], Ad[81], Aref[81], B[108], Href[144] = {0};
        crom_fem_tet_F(x, Dminv, F);
        crom_fem_dPdF(&m, F, 0, Ad);
        lapack_project(Ad, Aref);
        build_B(Dminv, B);
        for (int i = 0; i < 12; i++)
            for (int j = 0; j < 12; j++)
                for (int a = 0; a < 9; a++)
                    for (int b = 0; b < 9; b++)
                        Href[12 * i + j] += V * B[12 * a + i] * Aref[9 * a + b] * B[12 * b + j];
        double e = maxdiff(Hp, Href, 144) / maxabs(H, 144);
        CHECK_MSG(e < 1e-9, "tet %s: projected Hessian vs LAPACK %.3g", names[cfg], e);
        double me = fx_min_eig(Hp, 12);
        CHECK_MSG(me >= -1e-11 * maxabs(H, 144), "tet %s: projected min eig %.3g",
                  names[cfg], me);
        /* rotation invariance: E(Rx + t) = E(x), g → R g, H → R H Rᵀ */
        double R[9], xr[12], gr[12], Hr[144], Er;
        fx_random_rotation(&r, R);
        for (int k = 0; k < 4; k++)
            for (int a = 0; a < 3; a++)
                xr[3 * k + a] = R[3 * a] * x[3 * k] + R[3 * a + 1] * x[3 * k + 1] +
                                R[3 * a + 2] * x[3 * k + 2] + 0.37 * (a + 1);
        crom_fem_tet_eval(&m, xr, Dminv, V, 0, &Er, gr, Hr);
        CHECK_NEAR(Er, E, 1e-10 * (fabs(E) + V * m.mu * 1e-6));
        double Rg[12], RHRt[144];
        for (int k = 0; k < 4; k++)
            for (int a = 0; a < 3; a++)
                Rg[3 * k + a] = R[3 * a] * g[3 * k] + R[3 * a + 1] * g[3 * k + 1] +
                                R[3 * a + 2] * g[3 * k + 2];
        CHECK(check_relerr(gr, Rg, 12, gscale) < 1e-10);
        for (int i = 0; i < 12; i++)
            for (int j = 0; j < 12; j++) {
                double s = 0;
                int ki = i / 3, a = i % 3, kj = j / 3, b = j % 3;
                for (int c = 0; c < 3; c++)
                    for (int d = 0; d < 3; d++)
                        s += R[3 * a + c] * H[12 * (3 * ki + c) + 3 * kj + d] * R[3 * b + d];
                RHRt[12 * i + j] = s;
            }
        CHECK(check_relerr(Hr, RHRt, 144, Hscale) < 1e-10);
    }
    printf("tet: worst gradient relerr %.2e, Hessian relerr %.2e\n", worst_g, worst_H);

    /* bad rest shapes and non-finite positions */
    double Xflat[12], Xinv[12];
    memcpy(Xflat, X, sizeof Xflat);
    for (int a = 0; a < 3; a++) /* vertex 3 onto the plane of 0, 1, 2 */
        Xflat[9 + a] = 0.3 * X[a] + 0.3 * X[3 + a] + 0.4 * X[6 + a];
    CHECK(crom_fem_tet_rest(Xflat, Dminv, &V) == CROM_EDATA);
    memcpy(Xinv, X, sizeof Xinv);
    for (int a = 0; a < 3; a++) { /* swap vertices 1 and 2 */
        Xinv[3 + a] = X[6 + a];
        Xinv[6 + a] = X[3 + a];
    }
    CHECK(crom_fem_tet_rest(Xinv, Dminv, &V) == CROM_EDATA);
    CHECK(crom_fem_tet_rest(X, Dminv, &V) == CROM_OK);
    double xn[12];
    memcpy(xn, X, sizeof xn);
    xn[4] = INFINITY;
    crom_err_clear();
    CHECK(crom_fem_tet_eval(&m, xn, Dminv, V, 1, &E, g, H) == CROM_EDATA);
    CHECK(strstr(crom_errmsg(), "non-finite") != NULL);
}

/* ---- small-strain moduli ------------------------------------------------- */

static void test_linear_limit(void)
{
    static const double table[][2] = {{1e6, 0.25}, {1e6, 0.45}, {2.5e6, 0.0},
                                      {5e5, -0.3}, {3e4, 0.49}, {1e7, -0.9}};
    const double eps = 1e-5;
    for (size_t i = 0; i < sizeof table / sizeof table[0]; i++) {
        double E = table[i][0], nu = table[i][1];
        crom_material m;
        CHECK(crom_material_init(&m, E, nu, 1000) == CROM_OK);
        /* uniaxial stress: F = diag(1+ε, 1+δ, 1+δ) with P_yy = 0 (= ∂Ψ/∂δ / 2,
         * so the energy is minimal over the lateral stretch); Newton on δ. */
        double delta = 0, F[9] = {0}, P[9], A[81];
        for (int it = 0; it < 30; it++) {
            F[0] = 1 + eps;
            F[4] = F[8] = 1 + delta;
            crom_fem_pk1(&m, F, P);
            crom_fem_dPdF(&m, F, 0, A);
            double dr = A[9 * 4 + 4] + A[9 * 4 + 8];
            double step = P[4] / dr;
            delta -= step;
            if (fabs(step) < 1e-14 * eps)
                break;
        }
        F[4] = F[8] = 1 + delta;
        crom_fem_pk1(&m, F, P);
        CHECK(fabs(P[4]) < 1e-9 * E * eps && fabs(P[8]) < 1e-9 * E * eps);
        double E_meas = P[0] / eps, nu_meas = -delta / eps;
        double psi = crom_fem_psi(&m, F);
        CHECK_REL(E_meas, E, 1e-4);
        CHECK_NEAR(nu_meas, nu, 1e-4);
        CHECK_REL(psi, 0.5 * E * eps * eps, 1e-3);
        /* simple shear: P_xy / γ = μL */
        double S[9] = {1, eps, 0, 0, 1, 0, 0, 0, 1};
        crom_fem_pk1(&m, S, P);
        CHECK_REL(P[1] / eps, m.mu_lame, 1e-4);
        printf("small strain E = %-8g nu = %-5g: E error %.2e, nu error %.2e, "
               "mu error %.2e, energy error %.2e\n", E, nu, fabs(E_meas / E - 1),
               fabs(nu_meas - nu), fabs(P[1] / eps / m.mu_lame - 1),
               fabs(psi / (0.5 * E * eps * eps) - 1));
    }
}

/* ---- meshes ----------------------------------------------------------------- */

static void free_mesh(crom_mesh *m)
{
    free(m->X);
    free(m->tets);
}

typedef struct {
    const crom_fem *fem;
    crom_fem_opts opt;
} mesh_ctx;

static double mesh_E_fn(const double *x, void *ctx)
{
    double E = NAN;
    crom_fem_energy(((mesh_ctx *)ctx)->fem, x, &E);
    return E;
}

static void mesh_g_fn(const double *x, void *ctx, double *g)
{
    mesh_ctx *c = ctx;
    crom_fem_assemble(c->fem, x, &c->opt, NULL, g, NULL);
}

/* Dense symmetric n×n from the upper CSC. */
static void csc_to_dense(const crom_fem *fem, const double *Hval, double *D)
{
    int n = fem->n;
    memset(D, 0, sizeof(double) * n * n);
    for (int s = 0; s < n; s++)
        for (int p = fem->colptr[s]; p < fem->colptr[s + 1]; p++) {
            int rr = fem->rowind[p];
            D[(size_t)rr * n + s] = D[(size_t)s * n + rr] = Hval[p];
        }
}

static void test_mesh(void)
{
    crom_material m;
    crom_material_init(&m, 1e6, 0.4, 1200);
    const double h[3] = {0.1, 0.12, 0.09};
    crom_mesh mesh;
    fx_grid(&mesh, 3, 3, 3, NULL, h, 0, NULL, NULL, 1);
    crom_fem fem;
    CHECK(crom_fem_init(&fem, &mesh, &m) == CROM_OK);
    int n = fem.n, nnz = fem.nnz, nv = fem.nv;
    double vol = 27 * h[0] * h[1] * h[2];
    CHECK_REL(fem.volume, vol, 1e-13);
    double msum = 0;
    for (int v = 0; v < nv; v++)
        msum += fem.mass[v];
    CHECK_REL(msum, m.rho * vol, 1e-13);
    CHECK_REL(fem.total_mass, m.rho * vol, 1e-13);
    double *m3 = malloc(sizeof(double) * n);
    crom_fem_mass_diag(&fem, m3);
    CHECK(m3[3 * 5 + 2] == fem.mass[5]);

    /* pattern: sorted rows, upper triangle, diagonal last, exactly the DOF
     * pairs of vertices that share a tet */
    unsigned char *adj = calloc((size_t)nv * nv, 1);
    for (int t = 0; t < fem.nt; t++)
        for (int k = 0; k < 4; k++)
            for (int l = 0; l < 4; l++)
                adj[mesh.tets[4 * t + k] * nv + mesh.tets[4 * t + l]] = 1;
    int expect = 0, ok = fem.colptr[0] == 0 && fem.colptr[n] == nnz;
    for (int s = 0; s < n; s++) {
        for (int rr = 0; rr <= s; rr++)
            expect += adj[(rr / 3) * nv + s / 3];
        ok &= fem.colptr[s + 1] > fem.colptr[s];
        ok &= fem.rowind[fem.colptr[s + 1] - 1] == s;
        for (int p = fem.colptr[s]; p < fem.colptr[s + 1]; p++) {
            ok &= fem.rowind[p] <= s && adj[(fem.rowind[p] / 3) * nv + s / 3];
            if (p > fem.colptr[s])
                ok &= fem.rowind[p] > fem.rowind[p - 1];
        }
    }
    CHECK(ok);
    CHECK(nnz == expect);
    free(adj);

    /* a strongly deformed state with some inverted tets */
    crom_rng r;
    crom_rng_seed(&r, 2024);
    double *x = malloc(sizeof(double) * n), *g = malloc(sizeof(double) * n);
    double *gfd = malloc(sizeof(double) * n), *H = malloc(sizeof(double) * nnz);
    double *D = malloc(sizeof(double) * n * n), *Dfd = malloc(sizeof(double) * n * n);
    for (int v = 0; v < nv; v++) {
        const double *X = mesh.X + 3 * v;
        double th = 3 * X[2];
        x[3 * v] = 1.2 * (cos(th) * X[0] - sin(th) * X[1]);
        x[3 * v + 1] = sin(th) * X[0] + cos(th) * X[1];
        x[3 * v + 2] = 0.8 * X[2];
        for (int c = 0; c < 3; c++)
            x[3 * v + c] += 0.35 * h[c] * crom_rng_normal(&r);
    }
    int ninv = 0;
    for (int t = 0; t < fem.nt; t++) {
        double xe[12], F[9];
        crom_fem_tet_positions(&fem, x, t, xe);
        crom_fem_tet_F(xe, fem.Dminv + 9 * t, F);
        ninv += det3(F) < 0;
    }
    CHECK(ninv > 0);
    double E, E2;
    mesh_ctx ctx = {&fem, {0}};
    CHECK(crom_fem_assemble(&fem, x, NULL, &E, g, H) == CROM_OK);
    CHECK(isfinite(E));
    CHECK(crom_fem_energy(&fem, x, &E2) == CROM_OK);
    CHECK_REL(E2, E, 1e-14);
    double gscale = m.mu * vol / 3 / h[0] / 27, Hscale = gscale / h[0];
    check_fd_gradient(mesh_E_fn, &ctx, x, n, 1e-7, gfd);
    double eg = check_relerr(g, gfd, n, gscale);
    CHECK_MSG(eg < 1e-6, "mesh gradient vs FD relerr %.3g", eg);
    csc_to_dense(&fem, H, D);
    check_fd_jacobian(mesh_g_fn, &ctx, x, n, n, 1e-7, Dfd);
    double eH = check_relerr(D, Dfd, n * n, Hscale);
    CHECK_MSG(eH < 1e-5, "mesh Hessian vs FD relerr %.3g", eH);
    printf("mesh (%d tets, %d inverted, %d colours): gradient relerr %.2e, "
           "Hessian relerr %.2e, nnz %d\n", fem.nt, ninv, fem.ncolors, eg, eH, nnz);

    /* regions of other materials (crom_fem_set_materials): every other tet
     * five times stiffer and more nearly incompressible; the gradient and
     * Hessian still agree with differences of the energy, and the energy is
     * the sum of the tets' energies, each with its own material */
    {
        crom_material mats[2] = {m, m};
        crom_material_init(&mats[1], 5e6, 0.3, 1200);
        int *tm = malloc(sizeof(int) * fem.nt);
        for (int t = 0; t < fem.nt; t++)
            tm[t] = (t / 3) % 2;
        crom_material wrong = mats[1];
        wrong.rho = 1000;
        CHECK(crom_fem_set_materials(&fem, &wrong, 1, tm) == CROM_EUSAGE); /* another density */
        crom_err_clear();
        CHECK(crom_fem_set_materials(&fem, mats, 2, tm) == CROM_OK);
        double Eh, *Eth = malloc(sizeof(double) * fem.nt), Ehs = 0;
        CHECK(crom_fem_assemble(&fem, x, NULL, &Eh, g, H) == CROM_OK);
        CHECK(Eh > 1.5 * E);
        CHECK(crom_fem_tet_energies(&fem, x, NULL, fem.nt, Eth) == CROM_OK);
        for (int t = 0; t < fem.nt; t++) {
            double xe[12];
            crom_fem_tet_positions(&fem, x, t, xe);
            CHECK(Eth[t] == crom_fem_tet_energy(&mats[tm[t]], xe, fem.Dminv + 9 * t, fem.vol[t]));
            Ehs += Eth[t];
        }
        CHECK_REL(Ehs, Eh, 1e-12);
        check_fd_gradient(mesh_E_fn, &ctx, x, n, 1e-7, gfd);
        double egh = check_relerr(g, gfd, n, 5 * gscale);
        CHECK_MSG(egh < 1e-6, "two materials: gradient vs FD relerr %.3g", egh);
        csc_to_dense(&fem, H, D);
        check_fd_jacobian(mesh_g_fn, &ctx, x, n, n, 1e-7, Dfd);
        double eHh = check_relerr(D, Dfd, n * n, 5 * Hscale);
        CHECK_MSG(eHh < 1e-5, "two materials: Hessian vs FD relerr %.3g", eHh);
        printf("two materials: energy %.4g (one: %.4g), gradient relerr %.2e, Hessian relerr %.2e\n", Eh, E, egh, eHh);
        CHECK(crom_fem_set_materials(&fem, NULL, 0, NULL) == CROM_OK);
        free(tm);
        free(Eth);
    }

    /* per-tet energies */
    double *Et = malloc(sizeof(double) * fem.nt), Esum = 0;
    CHECK(crom_fem_tet_energies(&fem, x, NULL, fem.nt, Et) == CROM_OK);
    for (int t = 0; t < fem.nt; t++)
        Esum += Et[t];
    CHECK_REL(Esum, E, 1e-12);
    int sub[3] = {17, 5, 100};
    double Es[3];
    CHECK(crom_fem_tet_energies(&fem, x, sub, 3, Es) == CROM_OK);
    for (int i = 0; i < 3; i++)
        CHECK(Es[i] == Et[sub[i]]);
    int badidx[2] = {3, fem.nt};
    CHECK(crom_fem_tet_energies(&fem, x, badidx, 2, Es) == CROM_EUSAGE);
    free(Et);

    /* projected sparse Hessian = dense sum of projected element Hessians */
    crom_fem_opts po = {.project = 1};
    CHECK(crom_fem_assemble(&fem, x, &po, NULL, NULL, H) == CROM_OK);
    csc_to_dense(&fem, H, D);
    memset(Dfd, 0, sizeof(double) * n * n);
    for (int t = 0; t < fem.nt; t++) {
        double xe[12], He[144];
        const int *tv = fem.tets + 4 * t;
        crom_fem_tet_positions(&fem, x, t, xe);
        crom_fem_tet_eval(&m, xe, fem.Dminv + 9 * t, fem.vol[t], 1, NULL, NULL, He);
        for (int i = 0; i < 12; i++)
            for (int j = 0; j < 12; j++)
                Dfd[(size_t)(3 * tv[i / 3] + i % 3) * n + 3 * tv[j / 3] + j % 3] += He[12 * i + j];
    }
    double e = maxdiff(D, Dfd, n * n) / maxabs(Dfd, n * n);
    CHECK_MSG(e < 1e-13, "sparse vs dense projected Hessian %.3g", e);
    double me_unproj, me_proj;
    {
        double *Hu = malloc(sizeof(double) * nnz), *Du = malloc(sizeof(double) * n * n);
        crom_fem_assemble(&fem, x, NULL, NULL, NULL, Hu);
        csc_to_dense(&fem, Hu, Du);
        me_unproj = fx_min_eig(Du, n);
        free(Hu);
        free(Du);
    }
    me_proj = fx_min_eig(D, n);
    CHECK_LT(me_unproj, 0);
    CHECK(me_proj >= -1e-12 * maxabs(D, n * n));
    printf("assembled Hessian min eigenvalue: %.3g unprojected, %.3g projected\n",
           me_unproj, me_proj);

    /* mass term: projected + M/h² is SPD (dense Cholesky), and adds exactly
     * scale·m_v on the diagonal */
    double *H2 = malloc(sizeof(double) * nnz);
    crom_fem_opts mo = {.project = 1, .mass_scale = 1e4};
    CHECK(crom_fem_assemble(&fem, x, &mo, NULL, NULL, H2) == CROM_OK);
    ok = 1;
    for (int s = 0; s < n; s++)
        for (int p = fem.colptr[s]; p < fem.colptr[s + 1]; p++) {
            double want = H[p] + (fem.rowind[p] == s ? 1e4 * fem.mass[s / 3] : 0);
            ok &= fabs(H2[p] - want) <= 1e-14 * fabs(want);
        }
    CHECK(ok);
    csc_to_dense(&fem, H2, D);
    CHECK(LAPACKE_dpotrf(LAPACK_ROW_MAJOR, 'U', n, D, n) == 0);

    /* fixed DOFs: the bottom face (z = 0) and a few scattered ones */
    unsigned char *fixed = calloc(n, 1);
    int nfixed = 0;
    for (int v = 0; v < nv; v++)
        for (int c = 0; c < 3; c++)
            if (mesh.X[3 * v + 2] == 0 || (3 * v + c) % 7 == 3)
                fixed[3 * v + c] = 1, nfixed++;
    double *gf = malloc(sizeof(double) * n), *Hf = malloc(sizeof(double) * nnz), Ef;
    crom_fem_opts fo = {.project = 1, .mass_scale = 1e4, .fixed = fixed};
    CHECK(crom_fem_assemble(&fem, x, &fo, &Ef, gf, Hf) == CROM_OK);
    crom_fem_assemble(&fem, x, &mo, NULL, g, NULL);
    CHECK(Ef == E);
    ok = 1;
    for (int rr = 0; rr < n; rr++)
        ok &= fixed[rr] ? gf[rr] == 0 : gf[rr] == g[rr];
    for (int s = 0; s < n; s++)
        for (int p = fem.colptr[s]; p < fem.colptr[s + 1]; p++) {
            int rr = fem.rowind[p];
            if (fixed[rr] || fixed[s])
                ok &= Hf[p] == (rr == s ? 1.0 : 0.0);
            else
                ok &= Hf[p] == H2[p];
        }
    CHECK(ok);
    CHECK(nfixed > 40);
    csc_to_dense(&fem, Hf, D);
    CHECK(LAPACKE_dpotrf(LAPACK_ROW_MAJOR, 'U', n, D, n) == 0);

    /* threads: 1 thread is deterministic; 2 and 3 threads give the same
     * gradient and Hessian bits (colour order) and energy to round-off */
    double *g1 = malloc(sizeof(double) * n), *H1 = malloc(sizeof(double) * nnz);
    double *gb = malloc(sizeof(double) * n), *Hb = malloc(sizeof(double) * nnz);
    double E1, Eb, E3;
    crom_fem_opts t1 = fo, t2 = fo, t3 = fo;
    t1.nthreads = 1;
    t2.nthreads = 2;
    t3.nthreads = 3;
    crom_fem_assemble(&fem, x, &t1, &E1, g1, H1);
    crom_fem_assemble(&fem, x, &t1, &Eb, gb, Hb);
    CHECK(E1 == Eb && !memcmp(g1, gb, sizeof(double) * n) &&
          !memcmp(H1, Hb, sizeof(double) * nnz));
    CHECK(crom_fem_assemble(&fem, x, &t2, &Eb, gb, Hb) == CROM_OK);
    CHECK_REL(Eb, E1, 1e-13);
    CHECK(maxdiff(gb, g1, n) <= 1e-13 * maxabs(g1, n));
    CHECK(maxdiff(Hb, H1, nnz) <= 1e-13 * maxabs(H1, nnz));
    crom_fem_assemble(&fem, x, &t3, &E3, g, H2);
    CHECK(!memcmp(g, gb, sizeof(double) * n) && !memcmp(H2, Hb, sizeof(double) * nnz));
    CHECK_REL(E3, E1, 1e-13);

    /* non-finite state -> CROM_EDATA naming a tet */
    x[3 * 21 + 1] = NAN;
    crom_err_clear();
    CHECK(crom_fem_assemble(&fem, x, &po, &E, g, H) == CROM_EDATA);
    CHECK(strstr(crom_errmsg(), "tet") != NULL);
    crom_err_clear();
    CHECK(crom_fem_assemble(&fem, x, &t2, &E, g, H) == CROM_EDATA);
    CHECK(strstr(crom_errmsg(), "tet") != NULL);
    CHECK(crom_fem_energy(&fem, x, &E) == CROM_EDATA);

    free(g1); free(H1); free(gb); free(Hb); free(gf); free(Hf); free(fixed);
    free(H2); free(x); free(g); free(gfd); free(H); free(D); free(Dfd); free(m3);
    crom_fem_free(&fem);
    crom_fem_free(&fem); /* idempotent */

    /* bad rest meshes */
    crom_mesh bad;
    fx_grid(&bad, 1, 1, 1, NULL, h, 0, NULL, NULL, 1);
    int t = 1, tmp = bad.tets[4 * t + 1];
    bad.tets[4 * t + 1] = bad.tets[4 * t + 2];
    bad.tets[4 * t + 2] = tmp;
    crom_err_clear();
    CHECK(crom_fem_init(&fem, &bad, &m) == CROM_EDATA);
    CHECK(strstr(crom_errmsg(), "tet 1 ") != NULL);
    bad.tets[4 * t + 2] = bad.tets[4 * t + 1];
    bad.tets[4 * t + 1] = tmp;
    for (int c = 0; c < 3; c++) /* collapse tet 4 onto a plane */
        bad.X[3 * bad.tets[4 * 4 + 3] + c] = 0.5 * (bad.X[3 * bad.tets[4 * 4] + c] +
                                                    bad.X[3 * bad.tets[4 * 4 + 1] + c]);
    crom_err_clear();
    CHECK(crom_fem_init(&fem, &bad, &m) == CROM_EDATA);
    CHECK(strstr(crom_errmsg(), "degenerate") != NULL);
    free_mesh(&bad);
    fx_grid(&bad, 1, 1, 1, NULL, h, 0, NULL, NULL, 1);
    bad.tets[7] = 99;
    CHECK(crom_fem_init(&fem, &bad, &m) == CROM_EDATA);
    bad.tets[7] = bad.tets[6];
    CHECK(crom_fem_init(&fem, &bad, &m) == CROM_EDATA);
    free_mesh(&bad);
    free_mesh(&mesh);
}

/* A double fan: 2·nq² tets sharing an apex above and one below, so more than
 * 64 colours are needed and the serial overflow path of the threaded
 * assembly is used. */
static void test_fan(void)
{
    const int nq = 6, ng = nq + 1;
    crom_mesh mesh = {0};
    mesh.nv = ng * ng + 2;
    mesh.nt = 4 * nq * nq;
    mesh.X = malloc(sizeof(double) * 3 * mesh.nv);
    mesh.tets = malloc(sizeof(int) * 4 * mesh.nt);
    for (int j = 0; j < ng; j++)
        for (int i = 0; i < ng; i++) {
            double *X = mesh.X + 3 * (j * ng + i);
            X[0] = i - 0.5 * nq;
            X[1] = j - 0.5 * nq;
            X[2] = 0;
        }
    int top = ng * ng, bot = top + 1;
    double *Xt = mesh.X + 3 * top, *Xb = mesh.X + 3 * bot;
    Xt[0] = Xt[1] = Xb[0] = Xb[1] = 0.1;
    Xt[2] = 2;
    Xb[2] = -2;
    int t = 0;
    for (int j = 0; j < nq; j++)
        for (int i = 0; i < nq; i++) {
            int a = j * ng + i, b = a + 1, c = a + ng, d = c + 1;
            int tri[2][3] = {{a, b, d}, {a, d, c}}; /* counter-clockwise from +z */
            for (int s = 0; s < 2; s++) {
                int *tv = mesh.tets + 4 * t++;
                tv[0] = tri[s][0], tv[1] = tri[s][1], tv[2] = tri[s][2], tv[3] = top;
                tv = mesh.tets + 4 * t++;
                tv[0] = tri[s][0], tv[1] = tri[s][2], tv[2] = tri[s][1], tv[3] = bot;
            }
        }
    crom_material m;
    crom_material_init(&m, 1e5, 0.3, 1000);
    crom_fem fem;
    CHECK(crom_fem_init(&fem, &mesh, &m) == CROM_OK);
    CHECK(fem.ncolors == 64 && fem.color_ptr[64] < fem.nt); /* overflow used */
    CHECK_REL(fem.volume, 2 * (nq * nq * 2.0) / 3, 1e-13);
    crom_rng r;
    crom_rng_seed(&r, 9);
    double *x = malloc(sizeof(double) * fem.n);
    for (int i = 0; i < fem.n; i++)
        x[i] = mesh.X[i] + 0.2 * crom_rng_normal(&r);
    double *g1 = malloc(sizeof(double) * fem.n), *g2 = malloc(sizeof(double) * fem.n);
    double *H1 = malloc(sizeof(double) * fem.nnz), *H2 = malloc(sizeof(double) * fem.nnz);
    double E1, E2;
    crom_fem_opts o1 = {.project = 1, .nthreads = 1}, o2 = {.project = 1, .nthreads = 2};
    CHECK(crom_fem_assemble(&fem, x, &o1, &E1, g1, H1) == CROM_OK);
    CHECK(crom_fem_assemble(&fem, x, &o2, &E2, g2, H2) == CROM_OK);
    CHECK_REL(E2, E1, 1e-13);
    CHECK(maxdiff(g1, g2, fem.n) <= 1e-13 * maxabs(g1, fem.n));
    CHECK(maxdiff(H1, H2, fem.nnz) <= 1e-13 * maxabs(H1, fem.nnz));
    free(x); free(g1); free(g2); free(H1); free(H2);
    crom_fem_free(&fem);
    free_mesh(&mesh);
}

int main(void)
{
    check_begin("test_fem");
    test_material();
    test_stress();
    test_svd();
    test_projection();
    test_tet();
    test_linear_limit();
    test_mesh();
    test_fan();
    return check_done();
}
