/* fem.c — stable neo-Hookean linear tetrahedra: material point, element
 * kernel with analytic SPD projection, lumped mass and sparse assembly.
 *
 * References
 *   [SNH18] Smith, de Goes, Kim 2018, "Stable Neo-Hookean Flesh Simulation".
 *   [SDK19] Smith, de Goes, Kim 2019, "Analytic Eigensystems for Isotropic
 *           Distortion Energies".
 *   [KE22]  Kim, Eberle, "Dynamic Deformables: Implementation and
 *           Production Practicalities" (SIGGRAPH course notes): the
 *           invariants I2 = ‖F‖², I3 = det F, and the eigensystem of
 *           ∂²Ψ/∂F² written with them.
 */
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "base/err.h"
#include "phys/fem.h"

#define NUP 78 /* entries of the upper triangle of a 12×12 element Hessian */

/* ---- Small dense helpers ---------------------------------------------- */

/* Cofactor matrix C = ∂(det F)/∂F (row-major). */
static inline void cofactor3(const double F[9], double C[9])
{
    C[0] = F[4] * F[8] - F[5] * F[7];
    C[1] = F[5] * F[6] - F[3] * F[8];
    C[2] = F[3] * F[7] - F[4] * F[6];
    C[3] = F[2] * F[7] - F[1] * F[8];
    C[4] = F[0] * F[8] - F[2] * F[6];
    C[5] = F[1] * F[6] - F[0] * F[7];
    C[6] = F[1] * F[5] - F[2] * F[4];
    C[7] = F[2] * F[3] - F[0] * F[5];
    C[8] = F[0] * F[4] - F[1] * F[3];
}

/* Ic − 3 = ‖F‖² − 3, summed so that it is accurate near F = I. */
static inline double Ic_minus_3(const double F[9])
{
    return (F[0] - 1) * (F[0] + 1) + (F[4] - 1) * (F[4] + 1) +
           (F[8] - 1) * (F[8] + 1) + F[1] * F[1] + F[2] * F[2] +
           F[3] * F[3] + F[5] * F[5] + F[6] * F[6] + F[7] * F[7];
}

/* ---- Energy density and its derivatives -------------------------------- */

/* The invariant derivatives of Ψ(I2 = Ic, I3 = J) [KE22]. */
typedef struct {
    double Ic, J;
    double dPsi_dIc;   /* μ/2 · Ic/(Ic+1) */
    double d2Psi_dIc2; /* μ/(2(Ic+1)²) */
    double dPsi_dJ;    /* λ(J − α) */
} snh_inv;

static inline snh_inv snh_invariants(const crom_material *m, double Ic, double J)
{
    snh_inv s;
    s.Ic = Ic;
    s.J = J;
    double r = 1 / (Ic + 1);
    s.dPsi_dIc = 0.5 * m->mu * Ic * r;
    s.d2Psi_dIc2 = 0.5 * m->mu * r * r;
    s.dPsi_dJ = m->lambda * (J - m->alpha);
    return s;
}

/* Ψ(F) of [SNH18] (the form with log(Ic + 1)) minus its rest value, with
 * (J−α)² − (1−α)² factored as (J−1)(J+1−2α) and log((Ic+1)/4) written
 * log1p((Ic−3)/4), so that small strains keep their precision. */
static inline double snh_psi(const crom_material *m, double Ic3, double J)
{
    return 0.5 * m->mu * (Ic3 - log1p(0.25 * Ic3)) +
           0.5 * m->lambda * (J - 1) * (J + 1 - 2 * m->alpha);
}

double crom_fem_psi(const crom_material *m, const double F[9])
{
    double C[9];
    cofactor3(F, C);
    double J = F[0] * C[0] + F[1] * C[1] + F[2] * C[2];
    return snh_psi(m, Ic_minus_3(F), J);
}

/* P = ∂Ψ/∂F = 2 ∂Ψ/∂Ic · F + ∂Ψ/∂J · ∂J/∂F  (∂Ic/∂F = 2F, ∂J/∂F = cof F) */
static inline void snh_pk1(const snh_inv *s, const double F[9], const double C[9],
                           double P[9])
{
    double a = 2 * s->dPsi_dIc;
    for (int i = 0; i < 9; i++)
        P[i] = a * F[i] + s->dPsi_dJ * C[i];
}

void crom_fem_pk1(const crom_material *m, const double F[9], double P[9])
{
    double C[9];
    cofactor3(F, C);
    double J = F[0] * C[0] + F[1] * C[1] + F[2] * C[2];
    snh_inv s = snh_invariants(m, Ic_minus_3(F) + 3, J);
    snh_pk1(&s, F, C, P);
}

/* Analytic ∂²Ψ/∂F² from the invariant derivatives [KE22]:
 *   A = 2 Ψ_Ic I₉ + 4 Ψ_IcIc vec(F)vec(F)ᵀ + λ vec(C)vec(C)ᵀ + Ψ_J ∂²J/∂F²,
 *   ∂²J/∂F_ab∂F_cd = ε_ace ε_bdf F_ef.
 * The last term lives in the off-diagonal 3×3 blocks (row a of F against
 * row c): since Σ_f ε_bdf v_f = −([v]_×)_bd, block (a, c) is
 * −Ψ_J ε_ace [F_e]_× with F_e the third row, and block (c, a) its
 * transpose. */
static void snh_hessian(const crom_material *m, const snh_inv *s,
                        const double F[9], const double C[9], double A[81])
{
    double a2 = 2 * s->dPsi_dIc, a4 = 4 * s->d2Psi_dIc2, lam = m->lambda;
    for (int i = 0; i < 9; i++) {
        double fi = a4 * F[i], ci = lam * C[i];
        for (int j = i; j < 9; j++)
            A[9 * i + j] = fi * F[j] + ci * C[j];
    }
    for (int i = 0; i < 9; i++)
        for (int j = 0; j < i; j++)
            A[9 * i + j] = A[9 * j + i];
    for (int i = 0; i < 9; i++)
        A[9 * i + i] += a2;
    static const int ace[3][3] = {{0, 1, 2}, {1, 2, 0}, {0, 2, 1}};
    for (int p = 0; p < 3; p++) {
        int a = ace[p][0], c = ace[p][1];
        const double *v = F + 3 * ace[p][2];
        double w = p < 2 ? -s->dPsi_dJ : s->dPsi_dJ; /* −Ψ_J ε_ace */
        double M01 = -w * v[2], M02 = w * v[1], M12 = -w * v[0]; /* w [v]_× */
        double *Bac = A + 27 * a + 3 * c, *Bca = A + 27 * c + 3 * a;
        Bac[1] += M01, Bac[2] += M02, Bac[9 + 2] += M12;
        Bac[9] -= M01, Bac[18] -= M02, Bac[18 + 1] -= M12;
        Bca[1] -= M01, Bca[2] -= M02, Bca[9 + 2] -= M12;
        Bca[9] += M01, Bca[18] += M02, Bca[18 + 1] += M12;
    }
}

/* ---- 3×3 SVD and symmetric eigensolver -------------------------------- */

/* c = a × b */
static inline void cross3(const double a[3], const double b[3], double c[3])
{
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

/* Unit vector orthogonal to the unit vector u. */
static void any_orthogonal(const double u[3], double w[3])
{
    int k = 0; /* axis where |u| is smallest */
    if (fabs(u[1]) < fabs(u[k]))
        k = 1;
    if (fabs(u[2]) < fabs(u[k]))
        k = 2;
    double e[3] = {0, 0, 0};
    e[k] = 1;
    cross3(u, e, w);
    double n = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
    w[0] /= n;
    w[1] /= n;
    w[2] /= n;
}

static inline void swap_cols(double M[9], int p, int q)
{
    for (int a = 0; a < 3; a++) {
        double t = M[3 * a + p];
        M[3 * a + p] = M[3 * a + q];
        M[3 * a + q] = t;
    }
}

/* Unit eigenvector of the symmetric S for its eigenvalue lam, assumed simple
 * and well separated: the largest cross product of two rows of S − lam I. */
static void eigvec_cross(const double S[9], double lam, double v[3])
{
    double r0[3] = {S[0] - lam, S[1], S[2]};
    double r1[3] = {S[3], S[4] - lam, S[5]};
    double r2[3] = {S[6], S[7], S[8] - lam};
    double c[3][3];
    cross3(r0, r1, c[0]);
    cross3(r0, r2, c[1]);
    cross3(r1, r2, c[2]);
    double n[3];
    int best = 0;
    for (int i = 0; i < 3; i++) {
        n[i] = c[i][0] * c[i][0] + c[i][1] * c[i][1] + c[i][2] * c[i][2];
        if (n[i] > n[best])
            best = i;
    }
    double inv = 1 / sqrt(n[best]);
    for (int a = 0; a < 3; a++)
        v[a] = c[best][a] * inv;
}

/* A good starting V (rotation, columns by decreasing eigenvalue) for the
 * eigenvectors of S = BᵀB: the eigenvalues in closed form (trigonometric
 * solution of the characteristic cubic), the eigenvector of the better
 * separated extreme one from cross products, the other two by one exact
 * 2×2 Jacobi rotation in its orthogonal complement. Leaves V = I when S is
 * nearly a multiple of I or anything is not finite; the Jacobi polish that
 * follows makes the result exact either way. */
static void svd3_guess(const double B[9], double V[9])
{
    double S[9];
    for (int i = 0; i < 3; i++)
        for (int j = i; j < 3; j++)
            S[3 * i + j] = S[3 * j + i] =
                B[i] * B[j] + B[3 + i] * B[3 + j] + B[6 + i] * B[6 + j];
    double m = (S[0] + S[4] + S[8]) / 3;
    double k00 = S[0] - m, k11 = S[4] - m, k22 = S[8] - m;
    double p = (k00 * k00 + k11 * k11 + k22 * k22 +
                2 * (S[1] * S[1] + S[2] * S[2] + S[5] * S[5])) / 6;
    if (!(p > 1e-24 * m * m))
        return;
    double q = 0.5 * (k00 * (k11 * k22 - S[5] * S[5]) - S[1] * (S[1] * k22 - S[5] * S[2]) +
                      S[2] * (S[1] * S[5] - k11 * S[2]));
    double sp = sqrt(p), r = q / (p * sp);
    r = r < -1 ? -1 : r > 1 ? 1 : r;
    double phi = acos(r) / 3, cph = cos(phi), sph = sqrt(1 - cph * cph);
    double lam1 = m + 2 * sp * cph;                              /* largest */
    double lam3 = m + 2 * sp * (-0.5 * cph - 0.8660254037844386 * sph); /* smallest */
    double lam2 = 3 * m - lam1 - lam3;
    int top = lam1 - lam2 >= lam2 - lam3; /* the isolated one is lam1 */
    double v[3], a[3], b[3];
    eigvec_cross(S, top ? lam1 : lam3, v);
    if (!isfinite(v[0] + v[1] + v[2]))
        return;
    any_orthogonal(v, a);
    cross3(v, a, b);
    double Sa[3], Sb[3];
    for (int i = 0; i < 3; i++) {
        Sa[i] = S[3 * i] * a[0] + S[3 * i + 1] * a[1] + S[3 * i + 2] * a[2];
        Sb[i] = S[3 * i] * b[0] + S[3 * i + 1] * b[1] + S[3 * i + 2] * b[2];
    }
    double saa = a[0] * Sa[0] + a[1] * Sa[1] + a[2] * Sa[2];
    double sbb = b[0] * Sb[0] + b[1] * Sb[1] + b[2] * Sb[2];
    double sab = a[0] * Sb[0] + a[1] * Sb[1] + a[2] * Sb[2];
    double c = 1, s = 0, d = sbb - saa, rr = sqrt(d * d + 4 * sab * sab);
    if (rr > 0) { /* rotate (a, b) to diagonalize the 2×2 block */
        double t = 2 * sab / (d >= 0 ? d + rr : d - rr);
        c = 1 / sqrt(1 + t * t);
        s = c * t;
    }
    double e1[3], e2[3]; /* e1 gets saa − t·sab, e2 gets sbb + t·sab */
    for (int i = 0; i < 3; i++) {
        e1[i] = c * a[i] - s * b[i];
        e2[i] = s * a[i] + c * b[i];
    }
    double l1 = c * c * saa - 2 * c * s * sab + s * s * sbb;
    double l2 = s * s * saa + 2 * c * s * sab + c * c * sbb;
    const double *hi = l1 >= l2 ? e1 : e2, *lo = l1 >= l2 ? e2 : e1;
    const double *col[3] = {top ? v : hi, top ? hi : lo, top ? lo : v};
    for (int a3 = 0; a3 < 3; a3++)
        for (int j = 0; j < 3; j++)
            V[3 * a3 + j] = col[j][a3]; /* det V = ±1, fixed by the caller */
}

/* SVD in three steps: a closed-form guess of V (svd3_guess), then one-sided
 * (Hestenes) Jacobi on the columns of B = F V until they are orthogonal to
 * working precision (usually zero or one rotation after a good guess; from
 * V = I it converges alone), then σ_i = ‖b_i‖, U from the normalized columns
 * completed to a rotation, and the sign of det F moved to σ_2. */
int crom_fem_svd3(const double F[9], double U[9], double sigma[3], double V[9])
{
    static const double I3[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    double smax = 0;
    for (int i = 0; i < 9; i++) {
        if (!isfinite(F[i])) {
            memcpy(U, I3, sizeof I3);
            memcpy(V, I3, sizeof I3);
            sigma[0] = sigma[1] = sigma[2] = NAN;
            return CROM_EDATA;
        }
        if (fabs(F[i]) > smax)
            smax = fabs(F[i]);
    }
    memcpy(V, I3, sizeof I3);
    if (smax == 0) {
        memcpy(U, I3, sizeof I3);
        sigma[0] = sigma[1] = sigma[2] = 0;
        return CROM_OK;
    }
    /* keep products of six entries (det of BᵀB) in range */
    double scale = (smax > 1e30 || smax < 1e-30) ? smax : 1;
    double Fs[9], B[9];
    for (int i = 0; i < 9; i++)
        Fs[i] = F[i] / scale;
    svd3_guess(Fs, V);
    for (int a = 0; a < 3; a++)
        for (int j = 0; j < 3; j++)
            B[3 * a + j] = Fs[3 * a] * V[j] + Fs[3 * a + 1] * V[3 + j] + Fs[3 * a + 2] * V[6 + j];

    static const int P[3] = {0, 0, 1}, Q[3] = {1, 2, 2};
    for (int sweep = 0; sweep < 10; sweep++) {
        int rotated = 0;
        for (int r = 0; r < 3; r++) {
            int p = P[r], q = Q[r];
            double alpha = 0, beta = 0, gamma = 0;
            for (int a = 0; a < 3; a++) {
                double bp = B[3 * a + p], bq = B[3 * a + q];
                alpha += bp * bp;
                beta += bq * bq;
                gamma += bp * bq;
            }
            if (gamma * gamma <= 1e-30 * alpha * beta)
                continue;
            /* tan θ = t solves t² + 2ζt − 1 = 0 with ζ = (β − α)/(2γ), the
             * root of smaller magnitude: t = 2γ / (d + sign(d) r) with
             * d = β − α, r = sqrt(d² + 4γ²) */
            double d = beta - alpha, rr = sqrt(d * d + 4 * gamma * gamma);
            double t = 2 * gamma / (d >= 0 ? d + rr : d - rr);
            double c = 1 / sqrt(1 + t * t), s = c * t;
            for (int a = 0; a < 3; a++) {
                double bp = B[3 * a + p], bq = B[3 * a + q];
                B[3 * a + p] = c * bp - s * bq;
                B[3 * a + q] = s * bp + c * bq;
                double vp = V[3 * a + p], vq = V[3 * a + q];
                V[3 * a + p] = c * vp - s * vq;
                V[3 * a + q] = s * vp + c * vq;
            }
            rotated = 1;
        }
        if (!rotated)
            break;
    }

    double n2[3];
    for (int i = 0; i < 3; i++)
        n2[i] = B[i] * B[i] + B[3 + i] * B[3 + i] + B[6 + i] * B[6 + i];
    /* sort columns by decreasing norm */
    for (int i = 0; i < 2; i++)
        for (int j = 2; j > i; j--)
            if (n2[j] > n2[j - 1]) {
                double t = n2[j];
                n2[j] = n2[j - 1];
                n2[j - 1] = t;
                swap_cols(B, j, j - 1);
                swap_cols(V, j, j - 1);
            }

    double u0[3], u1[3], u2[3];
    double s0 = sqrt(n2[0]);
    for (int a = 0; a < 3; a++)
        u0[a] = B[3 * a] / s0; /* s0 > 0 since F != 0 */
    double d01 = u0[0] * B[1] + u0[1] * B[4] + u0[2] * B[7];
    for (int a = 0; a < 3; a++)
        u1[a] = B[3 * a + 1] - d01 * u0[a];
    double n1 = sqrt(u1[0] * u1[0] + u1[1] * u1[1] + u1[2] * u1[2]);
    if (n1 > 0 && isfinite(1 / n1)) {
        for (int a = 0; a < 3; a++)
            u1[a] /= n1;
    } else {
        any_orthogonal(u0, u1);
    }
    cross3(u0, u1, u2);
    double s1 = u1[0] * B[1] + u1[1] * B[4] + u1[2] * B[7];
    double s2 = u2[0] * B[2] + u2[1] * B[5] + u2[2] * B[8];

    double detV = V[0] * (V[4] * V[8] - V[5] * V[7]) -
                  V[1] * (V[3] * V[8] - V[5] * V[6]) +
                  V[2] * (V[3] * V[7] - V[4] * V[6]);
    if (detV < 0) {
        V[2] = -V[2];
        V[5] = -V[5];
        V[8] = -V[8];
        s2 = -s2;
    }
    for (int a = 0; a < 3; a++) {
        U[3 * a] = u0[a];
        U[3 * a + 1] = u1[a];
        U[3 * a + 2] = u2[a];
    }
    /* Equal singular values can come out an ulp out of order: swap the
     * pair (in U and V, negating the third column of both to keep them
     * rotations), and keep the negative value last. */
    for (int pass = 0; pass < 3; pass++) {
        int p = pass == 1 ? 1 : 0, q = p + 1, o = 3 - p - q;
        double sp = p ? s1 : s0, sq = q == 1 ? s1 : s2;
        if (fabs(sq) <= sp)
            continue;
        swap_cols(U, p, q);
        swap_cols(V, p, q);
        for (int a = 0; a < 3; a++) {
            U[3 * a + o] = -U[3 * a + o];
            V[3 * a + o] = -V[3 * a + o];
        }
        if (p == 0) {
            s0 = s1;
            s1 = sp;
        } else {
            s1 = s2;
            s2 = sp;
            if (s1 < 0) { /* flip u1, u2: det U and the products stay */
                for (int a = 0; a < 3; a++) {
                    U[3 * a + 1] = -U[3 * a + 1];
                    U[3 * a + 2] = -U[3 * a + 2];
                }
                s1 = -s1;
                s2 = -s2;
            }
        }
    }
    sigma[0] = s0 * scale;
    sigma[1] = s1 * scale;
    sigma[2] = s2 * scale;
    return CROM_OK;
}

/* Cyclic Jacobi eigen-decomposition of a symmetric 3×3 K: K = Z diag(w) Zᵀ,
 * eigenvectors in the columns of Z. */
static void sym3_eig(const double K[9], double w[3], double Z[9])
{
    double A[9];
    memcpy(A, K, sizeof A);
    static const double I3[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    memcpy(Z, I3, sizeof I3);
    static const int P[3] = {0, 0, 1}, Q[3] = {1, 2, 2};
    for (int sweep = 0; sweep < 20; sweep++) {
        double off = A[1] * A[1] + A[2] * A[2] + A[5] * A[5];
        double dia = A[0] * A[0] + A[4] * A[4] + A[8] * A[8];
        if (off <= 1e-34 * dia || off == 0)
            break;
        for (int r = 0; r < 3; r++) {
            int p = P[r], q = Q[r], o = 3 - p - q;
            double apq = A[3 * p + q];
            if (apq == 0)
                continue;
            double theta = (A[3 * q + q] - A[3 * p + p]) / (2 * apq);
            double t = fabs(theta) < 1e150
                           ? (theta >= 0 ? 1 : -1) / (fabs(theta) + sqrt(theta * theta + 1))
                           : 0.5 / theta;
            double c = 1 / sqrt(t * t + 1), s = t * c;
            A[3 * p + p] -= t * apq;
            A[3 * q + q] += t * apq;
            A[3 * p + q] = A[3 * q + p] = 0;
            double aop = A[3 * o + p], aoq = A[3 * o + q];
            A[3 * o + p] = A[3 * p + o] = c * aop - s * aoq;
            A[3 * o + q] = A[3 * q + o] = s * aop + c * aoq;
            for (int a = 0; a < 3; a++) {
                double zp = Z[3 * a + p], zq = Z[3 * a + q];
                Z[3 * a + p] = c * zp - s * zq;
                Z[3 * a + q] = s * zp + c * zq;
            }
        }
    }
    w[0] = A[0];
    w[1] = A[4];
    w[2] = A[8];
}

/* ---- Analytic eigensystem of ∂²Ψ/∂F² [SDK19, KE22] ---------------------- */

/* Everything the eigensystem needs, from the SVD F = U Σ Vᵀ. */
typedef struct {
    double U[9], V[9], sigma[3];
    double K[9];        /* 3×3 scaling block ∂²Ψ/∂σ_i∂σ_j */
    double lam_tf[6];   /* twist_k, flip_k for k = 0, 1, 2 */
} snh_eigdata;

/* Fill the scaling block and the twist/flip eigenvalues. With I2 = Σσ²,
 * I3 = σ0σ1σ2 and k the axis not in the pair:
 *   twist_k = 2Ψ_I2 + σ_k Ψ_I3,  flip_k = 2Ψ_I2 − σ_k Ψ_I3,
 *   K_ij = 4Ψ_I2I2 σ_iσ_j + 2Ψ_I2 δ_ij + Ψ_I3I3 ∂I3/∂σ_i ∂I3/∂σ_j
 *          + Ψ_I3 ∂²I3/∂σ_i∂σ_j. */
static int snh_eigdata_fill(const crom_material *m, const snh_inv *s,
                            const double F[9], snh_eigdata *d)
{
    int rc = crom_fem_svd3(F, d->U, d->sigma, d->V);
    const double *sg = d->sigma;
    double a2 = 2 * s->dPsi_dIc, a4 = 4 * s->d2Psi_dIc2, lam = m->lambda;
    double dJ[3] = {sg[1] * sg[2], sg[0] * sg[2], sg[0] * sg[1]};
    for (int i = 0; i < 3; i++)
        for (int j = i; j < 3; j++) {
            double v = a4 * sg[i] * sg[j] + lam * dJ[i] * dJ[j];
            if (i == j)
                v += a2;
            else
                v += s->dPsi_dJ * sg[3 - i - j];
            d->K[3 * i + j] = d->K[3 * j + i] = v;
        }
    for (int k = 0; k < 3; k++) {
        d->lam_tf[2 * k] = a2 + sg[k] * s->dPsi_dJ;
        d->lam_tf[2 * k + 1] = a2 - sg[k] * s->dPsi_dJ;
    }
    return rc;
}

/* Eigenvector of a twist (sign = −1) or flip (sign = +1) mode for the pair
 * (i, j): Q = U (e_i e_jᵀ + sign e_j e_iᵀ)/√2 Vᵀ, as a row-major 3×3. */
static inline void tf_vector(const snh_eigdata *d, int k, double sign, double q[9])
{
    int i = k == 0 ? 1 : 0, j = k == 2 ? 1 : 2;
    const double *U = d->U, *V = d->V;
    for (int a = 0; a < 3; a++)
        for (int b = 0; b < 3; b++)
            q[3 * a + b] = M_SQRT1_2 * (U[3 * a + i] * V[3 * b + j] +
                                        sign * U[3 * a + j] * V[3 * b + i]);
}

/* Scaling eigenvector Q = U diag(z) Vᵀ. */
static inline void scale_vector(const snh_eigdata *d, const double z[3], double q[9])
{
    const double *U = d->U, *V = d->V;
    for (int a = 0; a < 3; a++)
        for (int b = 0; b < 3; b++)
            q[3 * a + b] = U[3 * a] * z[0] * V[3 * b] + U[3 * a + 1] * z[1] * V[3 * b + 1] +
                           U[3 * a + 2] * z[2] * V[3 * b + 2];
}

/* Upper triangle of A −= lam q qᵀ */
static inline void rank1_sub_upper(double A[81], double lam, const double q[9])
{
    for (int i = 0; i < 9; i++) {
        double li = lam * q[i];
        for (int j = i; j < 9; j++)
            A[9 * i + j] -= li * q[j];
    }
}

/* Project A (the analytic Hessian at F) onto the PSD cone by removing its
 * negative eigenpairs: A⁺ = A − Σ_{λ<0} λ q qᵀ. */
static void snh_project(const crom_material *m, const snh_inv *s,
                        const double F[9], double A[81])
{
    snh_eigdata d;
    if (snh_eigdata_fill(m, s, F, &d) != CROM_OK)
        return; /* non-finite F: A is already non-finite */
    double q[9];
    int changed = 0;
    for (int k = 0; k < 3; k++)
        for (int f = 0; f < 2; f++) {
            double lam = d.lam_tf[2 * k + f];
            if (lam < 0) {
                tf_vector(&d, k, f ? 1.0 : -1.0, q);
                rank1_sub_upper(A, lam, q);
                changed = 1;
            }
        }
    /* Sylvester's criterion: K positive definite => nothing to remove. */
    const double *K = d.K;
    double m2 = K[0] * K[4] - K[1] * K[3];
    double det = K[0] * (K[4] * K[8] - K[5] * K[7]) - K[1] * (K[3] * K[8] - K[5] * K[6]) +
                 K[2] * (K[3] * K[7] - K[4] * K[6]);
    if (!(K[0] > 0 && m2 > 0 && det > 0)) {
        double w[3], Z[9];
        sym3_eig(K, w, Z);
        for (int i = 0; i < 3; i++)
            if (w[i] < 0) {
                double z[3] = {Z[i], Z[3 + i], Z[6 + i]};
                scale_vector(&d, z, q);
                rank1_sub_upper(A, w[i], q);
                changed = 1;
            }
    }
    if (changed)
        for (int i = 0; i < 9; i++)
            for (int j = 0; j < i; j++)
                A[9 * i + j] = A[9 * j + i];
}

void crom_fem_dPdF(const crom_material *m, const double F[9], int project,
                   double dPdF[81])
{
    double C[9];
    cofactor3(F, C);
    double J = F[0] * C[0] + F[1] * C[1] + F[2] * C[2];
    snh_inv s = snh_invariants(m, Ic_minus_3(F) + 3, J);
    snh_hessian(m, &s, F, C, dPdF);
    if (project)
        snh_project(m, &s, F, dPdF);
}

void crom_fem_dPdF_eig(const crom_material *m, const double F[9], double lam[9],
                       double Q[81])
{
    double C[9];
    cofactor3(F, C);
    double J = F[0] * C[0] + F[1] * C[1] + F[2] * C[2];
    snh_inv s = snh_invariants(m, Ic_minus_3(F) + 3, J);
    snh_eigdata d;
    snh_eigdata_fill(m, &s, F, &d);
    double w[3], Z[9];
    sym3_eig(d.K, w, Z);
    for (int i = 0; i < 3; i++) {
        double z[3] = {Z[i], Z[3 + i], Z[6 + i]};
        lam[i] = w[i];
        scale_vector(&d, z, Q + 9 * i);
    }
    for (int k = 0; k < 3; k++) {
        lam[3 + 2 * k] = d.lam_tf[2 * k];
        tf_vector(&d, k, -1.0, Q + 9 * (3 + 2 * k));
        lam[4 + 2 * k] = d.lam_tf[2 * k + 1];
        tf_vector(&d, k, 1.0, Q + 9 * (4 + 2 * k));
    }
}

/* ---- One tetrahedron ---------------------------------------------------- */

int crom_fem_tet_rest(const double X[12], double Dminv[9], double *V)
{
    double Dm[9], C[9];
    for (int a = 0; a < 3; a++)
        for (int j = 0; j < 3; j++)
            Dm[3 * a + j] = X[3 * (j + 1) + a] - X[a];
    cofactor3(Dm, C);
    double det = Dm[0] * C[0] + Dm[1] * C[1] + Dm[2] * C[2];
    double len = 1;
    for (int j = 0; j < 3; j++)
        len *= sqrt(Dm[j] * Dm[j] + Dm[3 + j] * Dm[3 + j] + Dm[6 + j] * Dm[6 + j]);
    if (!isfinite(det) || !isfinite(len) || !(det > 1e-12 * len)) {
        *V = det / 6;
        return crom_err(CROM_EDATA,
                        "degenerate or inverted rest tetrahedron (volume %g)",
                        det / 6);
    }
    for (int a = 0; a < 3; a++)
        for (int b = 0; b < 3; b++)
            Dminv[3 * a + b] = C[3 * b + a] / det; /* Dm⁻¹ = Cᵀ / det */
    *V = det / 6;
    return CROM_OK;
}

/* Rows of the 4×3 shape-gradient matrix G: ∂F_cb/∂x_kc = G[k][b], with
 * G[1..3] = rows of Dm⁻¹ and G[0] = −(their sum). */
static inline void shape_grads(const double Dminv[9], double G[4][3])
{
    for (int b = 0; b < 3; b++) {
        G[1][b] = Dminv[b];
        G[2][b] = Dminv[3 + b];
        G[3][b] = Dminv[6 + b];
        G[0][b] = -(Dminv[b] + Dminv[3 + b] + Dminv[6 + b]);
    }
}

/* F = Ds Dm⁻¹ with Ds = [x1−x0, x2−x0, x3−x0] (edge vectors first, so that
 * far-from-origin coordinates lose no more than their own rounding). */
static inline void deformation_gradient(const double x[12], const double Dminv[9],
                                        double F[9])
{
    for (int c = 0; c < 3; c++) {
        double d1 = x[3 + c] - x[c], d2 = x[6 + c] - x[c], d3 = x[9 + c] - x[c];
        for (int b = 0; b < 3; b++)
            F[3 * c + b] = d1 * Dminv[b] + d2 * Dminv[3 + b] + d3 * Dminv[6 + b];
    }
}

void crom_fem_tet_F(const double x[12], const double Dminv[9], double F[9])
{
    deformation_gradient(x, Dminv, F);
}

double crom_fem_tet_energy(const crom_material *m, const double x[12],
                           const double Dminv[9], double V)
{
    double F[9];
    crom_fem_tet_F(x, Dminv, F);
    return V * crom_fem_psi(m, F);
}

int crom_fem_tet_measures(const crom_mesh *mesh, const double *u, const crom_material *m,
                          double *vol, double *J, double *psi, double *mises)
{
    int bad = 0;
    for (int t = 0; t < mesh->nt; t++) {
        double X[12], x[12], Dminv[9], V, F[9], C[9], P[9];
        for (int k = 0; k < 4; k++)
            for (int c = 0; c < 3; c++) {
                size_t i = 3 * (size_t)mesh->tets[4 * (size_t)t + k] + c;
                X[3 * k + c] = mesh->X[i];
                x[3 * k + c] = mesh->X[i] + (u ? u[i] : 0);
            }
        int ok = crom_fem_tet_rest(X, Dminv, &V) == CROM_OK;
        bad += !ok;
        if (vol)
            vol[t] = V;
        double Jt = NAN, psit = NAN, mt = NAN;
        if (ok) {
            deformation_gradient(x, Dminv, F);
            cofactor3(F, C);
            Jt = F[0] * C[0] + F[1] * C[1] + F[2] * C[2];
        }
        if (ok && m) {
            psit = crom_fem_psi(m, F);
            crom_fem_pk1(m, F, P);
        }
        if (ok && m && Jt > 0) {
            /* σ = P Fᵀ / J (symmetric for a hyperelastic law; symmetrized
             * against round-off), von Mises = sqrt(3/2 s:s), s = σ − tr σ/3 I */
            double sg[9];
            for (int i = 0; i < 3; i++)
                for (int j = 0; j < 3; j++)
                    sg[3 * i + j] = (P[3 * i] * F[3 * j] + P[3 * i + 1] * F[3 * j + 1] +
                                     P[3 * i + 2] * F[3 * j + 2]) / Jt;
            double p = (sg[0] + sg[4] + sg[8]) / 3, ss = 0;
            for (int i = 0; i < 3; i++)
                for (int j = 0; j < 3; j++) {
                    double sij = 0.5 * (sg[3 * i + j] + sg[3 * j + i]) - (i == j ? p : 0);
                    ss += sij * sij;
                }
            mt = sqrt(1.5 * ss);
        }
        if (J)
            J[t] = Jt;
        if (psi)
            psi[t] = psit;
        if (mises)
            mises[t] = mt;
    }
    return bad;
}

/* The element kernel: E = VΨ(F), g = V ∂Ψ/∂x (g_kc = V Σ_b P_cb G_kb), and the
 * upper triangle (row-major packed, i <= j) of H = V Bᵀ A B with
 * B_(cb),(kc') = δ_cc' G_kb, i.e. H_(kc),(ld) = V Σ_be G_kb A_(cb),(de) G_le.
 * Any of E, g, Hup may be NULL. Returns J (for messages). */
static double tet_kernel(const crom_material *m, const double x[12],
                         const double Dminv[9], double V, int project,
                         double *E, double g[12], double Hup[NUP])
{
    double G[4][3], F[9], C[9];
    deformation_gradient(x, Dminv, F);
    cofactor3(F, C);
    double J = F[0] * C[0] + F[1] * C[1] + F[2] * C[2];
    double Ic3 = Ic_minus_3(F);
    if (E)
        *E = V * snh_psi(m, Ic3, J);
    if (!g && !Hup)
        return J;
    shape_grads(Dminv, G);
    snh_inv s = snh_invariants(m, Ic3 + 3, J);
    if (g) {
        double P[9];
        snh_pk1(&s, F, C, P);
        for (int k = 0; k < 4; k++)
            for (int c = 0; c < 3; c++)
                g[3 * k + c] = V * (P[3 * c] * G[k][0] + P[3 * c + 1] * G[k][1] +
                                    P[3 * c + 2] * G[k][2]);
    }
    if (Hup) {
        double A[81];
        snh_hessian(m, &s, F, C, A);
        if (project)
            snh_project(m, &s, F, A);
        /* T_(cb),(ld) = Σ_e A_(cb),(de) G_le */
        double T[9][12], VG[4][3];
        for (int cb = 0; cb < 9; cb++) {
            const double *Ar = A + 9 * cb;
            for (int l = 0; l < 4; l++)
                for (int d = 0; d < 3; d++)
                    T[cb][3 * l + d] = Ar[3 * d] * G[l][0] + Ar[3 * d + 1] * G[l][1] +
                                       Ar[3 * d + 2] * G[l][2];
        }
        for (int k = 0; k < 4; k++)
            for (int b = 0; b < 3; b++)
                VG[k][b] = V * G[k][b];
        int e = 0;
        for (int i = 0; i < 12; i++) {
            int k = i / 3, c = i % 3;
            const double *T0 = T[3 * c], *T1 = T[3 * c + 1], *T2 = T[3 * c + 2];
            for (int j = i; j < 12; j++)
                Hup[e++] = VG[k][0] * T0[j] + VG[k][1] * T1[j] + VG[k][2] * T2[j];
        }
    }
    return J;
}

int crom_fem_tet_eval(const crom_material *m, const double x[12],
                      const double Dminv[9], double V, int project, double *E,
                      double g[12], double H[144])
{
    double Hup[NUP], Et = 0;
    double J = tet_kernel(m, x, Dminv, V, project, &Et, g, H ? Hup : NULL);
    double sum = Et;
    if (g)
        for (int i = 0; i < 12; i++)
            sum += g[i];
    if (H) {
        int e = 0;
        for (int i = 0; i < 12; i++)
            for (int j = i; j < 12; j++, e++) {
                H[12 * i + j] = H[12 * j + i] = Hup[e];
                sum += Hup[e];
            }
    }
    if (E)
        *E = Et;
    if (!isfinite(sum))
        return crom_err(CROM_EDATA,
                        "non-finite elastic energy or derivative (J = %g)", J);
    return CROM_OK;
}

/* ---- Mesh-level operator ------------------------------------------------ */

void crom_fem_free(crom_fem *fem)
{
    if (!fem)
        return;
    free(fem->tets);
    free(fem->Dminv);
    free(fem->vol);
    free(fem->mass);
    free(fem->colptr);
    free(fem->rowind);
    free(fem->scatter);
    free(fem->color_ptr);
    free(fem->color_tets);
    memset(fem, 0, sizeof *fem);
}

/* For each vertex j the sorted list nbr[nptr[j]..nptr[j+1]) of vertices
 * i <= j sharing a tet with j (j itself last), found through the
 * vertex -> incident tets lists. nptr [nv + 1] and nbr [nv + 12 nt] are
 * the caller's. */
static int vertex_neighbours(const crom_fem *fem, int *nptr, int *nbr)
{
    int nv = fem->nv, nt = fem->nt;
    int *vtp = crom_calloc((size_t)nv + 1, sizeof *vtp);
    int *vt = crom_malloc(sizeof *vt * 4 * (size_t)nt);
    int *stamp = crom_malloc(sizeof *stamp * (size_t)nv);
    if (!vtp || !vt || !stamp) {
        free(vtp);
        free(vt);
        free(stamp);
        return CROM_EINTERNAL;
    }
    /* vertex -> incident tets (CSR) */
    for (int t = 0; t < nt; t++)
        for (int k = 0; k < 4; k++)
            vtp[fem->tets[4 * t + k] + 1]++;
    for (int v = 0; v < nv; v++)
        vtp[v + 1] += vtp[v];
    {
        int *fill = stamp; /* reuse as a cursor */
        for (int v = 0; v < nv; v++)
            fill[v] = vtp[v];
        for (int t = 0; t < nt; t++)
            for (int k = 0; k < 4; k++)
                vt[fill[fem->tets[4 * t + k]]++] = t;
    }
    for (int v = 0; v < nv; v++)
        stamp[v] = -1;
    /* lower neighbours of each vertex, sorted, self last */
    size_t cnt = 0;
    for (int j = 0; j < nv; j++) {
        nptr[j] = (int)cnt;
        size_t start = cnt;
        for (int p = vtp[j]; p < vtp[j + 1]; p++) {
            const int *tv = fem->tets + 4 * vt[p];
            for (int k = 0; k < 4; k++) {
                int i = tv[k];
                if (i < j && stamp[i] != j) {
                    stamp[i] = j;
                    /* insertion into the sorted run [start, cnt) */
                    size_t q = cnt++;
                    while (q > start && nbr[q - 1] > i) {
                        nbr[q] = nbr[q - 1];
                        q--;
                    }
                    nbr[q] = i;
                }
            }
        }
        nbr[cnt++] = j;
    }
    nptr[nv] = (int)cnt;
    free(vtp);
    free(vt);
    free(stamp);
    return CROM_OK;
}

/* The CSC upper pattern over DOFs (colptr, rowind, n, nnz) from the
 * vertex neighbour lists: column 3j+d holds the three DOFs of each lower
 * neighbour of j, then DOFs 3j..3j+d. CROM_EDATA past INT_MAX entries. */
static int dof_pattern(crom_fem *fem, const int *nptr, const int *nbr)
{
    int nv = fem->nv, n = 3 * nv;
    fem->colptr = crom_malloc(sizeof *fem->colptr * ((size_t)n + 1));
    if (!fem->colptr)
        return CROM_EINTERNAL;
    long long nnz = 0;
    for (int j = 0; j < nv; j++) {
        int nlow = nptr[j + 1] - nptr[j] - 1;
        for (int d = 0; d < 3; d++) {
            fem->colptr[3 * j + d] = (int)nnz;
            nnz += 3LL * nlow + d + 1;
            if (nnz > INT_MAX)
                return crom_err(CROM_EDATA, "mesh too large: Hessian has more "
                                            "than %d entries", INT_MAX);
        }
    }
    fem->colptr[n] = (int)nnz;
    fem->n = n;
    fem->nnz = (int)nnz;
    fem->rowind = crom_malloc(sizeof *fem->rowind * (size_t)(nnz ? nnz : 1));
    if (!fem->rowind)
        return CROM_EINTERNAL;
    for (int j = 0; j < nv; j++)
        for (int d = 0; d < 3; d++) {
            int p = fem->colptr[3 * j + d];
            for (int q = nptr[j]; q < nptr[j + 1] - 1; q++)
                for (int c = 0; c < 3; c++)
                    fem->rowind[p++] = 3 * nbr[q] + c;
            for (int c = 0; c <= d; c++)
                fem->rowind[p++] = 3 * j + c;
        }
    return CROM_OK;
}

/* The per-tet scatter map: element upper entry (i, j), i = 3k+c,
 * j = 3l+d, lands at global (r, s) = (3v_k+c, 3v_l+d), swapped if r > s;
 * its value index is colptr[s] + 3·(position of row vertex in s's
 * neighbour list) + r%3. */
static int tet_scatter(crom_fem *fem, const int *nptr, const int *nbr)
{
    fem->scatter = crom_malloc(sizeof *fem->scatter * NUP * (size_t)fem->nt);
    if (!fem->scatter)
        return CROM_EINTERNAL;
    for (int t = 0; t < fem->nt; t++) {
        const int *tv = fem->tets + 4 * t;
        int pos[4][4]; /* pos[k][l]: index of min(vk,vl) in nbr list of max */
        for (int k = 0; k < 4; k++)
            for (int l = 0; l < 4; l++) {
                int lo = tv[k] < tv[l] ? tv[k] : tv[l];
                int hi = tv[k] < tv[l] ? tv[l] : tv[k];
                int a = nptr[hi], b = nptr[hi + 1] - 1;
                while (a < b) { /* binary search for lo */
                    int mid = (a + b) / 2;
                    if (nbr[mid] < lo)
                        a = mid + 1;
                    else
                        b = mid;
                }
                pos[k][l] = a - nptr[hi];
            }
        int *sc = fem->scatter + (size_t)NUP * (size_t)t, e = 0;
        for (int i = 0; i < 12; i++)
            for (int j = i; j < 12; j++) {
                int k = i / 3, c = i % 3, l = j / 3, d = j % 3;
                int r = 3 * tv[k] + c, s = 3 * tv[l] + d;
                if (r > s) {
                    int tmp = r;
                    r = s;
                    s = tmp;
                }
                sc[e++] = fem->colptr[s] + 3 * pos[k][l] + r % 3;
            }
    }
    return CROM_OK;
}

/* Sparse pattern: the vertex neighbour lists, then the CSC upper pattern
 * over DOFs and the per-tet scatter map. */
static int build_pattern(crom_fem *fem)
{
    int nv = fem->nv, nt = fem->nt, rc = CROM_EINTERNAL;
    int *nptr = crom_malloc(sizeof *nptr * ((size_t)nv + 1));
    int *nbr = crom_malloc(sizeof *nbr * ((size_t)nv + 12 * (size_t)nt));
    if (nptr && nbr && (rc = vertex_neighbours(fem, nptr, nbr)) == CROM_OK &&
        (rc = dof_pattern(fem, nptr, nbr)) == CROM_OK)
        rc = tet_scatter(fem, nptr, nbr);
    free(nptr);
    free(nbr);
    return rc;
}

/* Greedy colouring of tets so that tets of one colour share no vertex (the
 * threaded assembly scatters one colour at a time without conflicts). Uses
 * 64 colours; tets that find none free are left for a serial tail. Colour
 * classes keep increasing tet order. */
static int build_colors(crom_fem *fem)
{
    int nv = fem->nv, nt = fem->nt;
    uint64_t *used = crom_calloc((size_t)nv, sizeof *used);
    unsigned char *col = crom_malloc((size_t)nt);
    fem->color_ptr = crom_calloc(66, sizeof *fem->color_ptr);
    fem->color_tets = crom_malloc(sizeof *fem->color_tets * (size_t)nt);
    if (!used || !col || !fem->color_ptr || !fem->color_tets) {
        free(used);
        free(col);
        return CROM_EINTERNAL;
    }
    int ncolors = 0;
    for (int t = 0; t < nt; t++) {
        const int *tv = fem->tets + 4 * t;
        uint64_t busy = used[tv[0]] | used[tv[1]] | used[tv[2]] | used[tv[3]];
        int c = 64; /* overflow */
        if (~busy) {
            c = 0;
            while (busy >> c & 1)
                c++;
            for (int k = 0; k < 4; k++)
                used[tv[k]] |= (uint64_t)1 << c;
            if (c + 1 > ncolors)
                ncolors = c + 1;
        }
        col[t] = (unsigned char)c;
    }
    int count[65] = {0};
    for (int t = 0; t < nt; t++)
        count[col[t] == 64 ? ncolors : col[t]]++;
    fem->color_ptr[0] = 0;
    for (int c = 0; c <= ncolors; c++)
        fem->color_ptr[c + 1] = fem->color_ptr[c] + count[c];
    int cursor[65];
    for (int c = 0; c <= ncolors; c++)
        cursor[c] = fem->color_ptr[c];
    for (int t = 0; t < nt; t++)
        fem->color_tets[cursor[col[t] == 64 ? ncolors : col[t]]++] = t;
    fem->ncolors = ncolors;
    free(used);
    free(col);
    return CROM_OK;
}

int crom_fem_set_materials(crom_fem *fem, const crom_material *mats, int nmat, const int *tmat)
{
    for (int t = 0; tmat && t < fem->nt; t++)
        if (tmat[t] < 0 || tmat[t] >= nmat)
            return crom_err(CROM_EUSAGE, "tet %d: material %d of %d", t, tmat[t], nmat);
    fem->mats = tmat ? mats : NULL;
    fem->tmat = tmat;
    /* the lumped masses ρ_t V_t / 4 of each tet's own density */
    memset(fem->mass, 0, sizeof *fem->mass * (size_t)fem->nv);
    fem->total_mass = 0;
    for (int t = 0; t < fem->nt; t++) {
        double mv = 0.25 * crom_fem_tet_material(fem, t)->rho * fem->vol[t];
        for (int k = 0; k < 4; k++)
            fem->mass[fem->tets[4 * (size_t)t + k]] += mv;
        fem->total_mass += 4 * mv;
    }
    return 0;
}

int crom_fem_init(crom_fem *fem, const crom_mesh *mesh, const crom_material *mat)
{
    memset(fem, 0, sizeof *fem);
    if (!mesh || !mat || !mesh->X || !mesh->tets || mesh->nv <= 0 || mesh->nt <= 0)
        return crom_err(CROM_EUSAGE, "crom_fem_init: empty mesh or no material");
    if (mesh->nv > INT_MAX / 3)
        return crom_err(CROM_EDATA, "mesh too large (%d vertices)", mesh->nv);
    int nv = mesh->nv, nt = mesh->nt, rc;
    for (int v = 0; v < nv; v++)
        for (int c = 0; c < 3; c++)
            if (!isfinite(mesh->X[3 * v + c]))
                return crom_err(CROM_EDATA, "vertex %d has a non-finite rest position", v);
    for (int t = 0; t < nt; t++) {
        const int *tv = mesh->tets + 4 * (size_t)t;
        for (int k = 0; k < 4; k++) {
            if (tv[k] < 0 || tv[k] >= nv)
                return crom_err(CROM_EDATA, "tet %d: vertex index %d out of range [0, %d)",
                                t, tv[k], nv);
            for (int l = 0; l < k; l++)
                if (tv[l] == tv[k])
                    return crom_err(CROM_EDATA, "tet %d: repeated vertex %d", t, tv[k]);
        }
    }
    fem->nv = nv;
    fem->nt = nt;
    fem->mat = *mat;
    fem->tets = crom_malloc(sizeof *fem->tets * 4 * (size_t)nt);
    fem->Dminv = crom_malloc(sizeof *fem->Dminv * 9 * (size_t)nt);
    fem->vol = crom_malloc(sizeof *fem->vol * (size_t)nt);
    fem->mass = crom_calloc((size_t)nv, sizeof *fem->mass);
    if (!fem->tets || !fem->Dminv || !fem->vol || !fem->mass) {
        rc = CROM_EINTERNAL;
        goto fail;
    }
    memcpy(fem->tets, mesh->tets, sizeof *fem->tets * 4 * (size_t)nt);
    double volume = 0;
    for (int t = 0; t < nt; t++) {
        const int *tv = fem->tets + 4 * t;
        double X[12];
        for (int k = 0; k < 4; k++)
            for (int c = 0; c < 3; c++)
                X[3 * k + c] = mesh->X[3 * tv[k] + c];
        if (crom_fem_tet_rest(X, fem->Dminv + 9 * (size_t)t, &fem->vol[t]) != CROM_OK) {
            rc = crom_err(CROM_EDATA,
                          "rest tet %d (vertices %d %d %d %d) is degenerate or "
                          "inverted: volume %g", t, tv[0], tv[1], tv[2], tv[3],
                          fem->vol[t]);
            goto fail;
        }
        volume += fem->vol[t];
        double mv = 0.25 * mat->rho * fem->vol[t]; /* lumped mass ρV/4 */
        for (int k = 0; k < 4; k++)
            fem->mass[tv[k]] += mv;
    }
    fem->volume = volume;
    fem->total_mass = mat->rho * volume;
    if ((rc = build_pattern(fem)) != CROM_OK || (rc = build_colors(fem)) != CROM_OK)
        goto fail;
    return CROM_OK;
fail:
    crom_fem_free(fem);
    return rc;
}

void crom_fem_tet_positions(const crom_fem *fem, const double *x, int t, double xe[12])
{
    const int *tv = fem->tets + 4 * (size_t)t;
    for (int k = 0; k < 4; k++) {
        const double *xv = x + 3 * (size_t)tv[k];
        xe[3 * k] = xv[0];
        xe[3 * k + 1] = xv[1];
        xe[3 * k + 2] = xv[2];
    }
}

void crom_fem_mass_diag(const crom_fem *fem, double *m3)
{
    for (int v = 0; v < fem->nv; v++)
        m3[3 * v] = m3[3 * v + 1] = m3[3 * v + 2] = fem->mass[v];
}

/* Evaluate tet t and scatter into grad / Hval. Returns 0, or 1 if any result
 * is non-finite (then nothing is scattered; *Jbad gets J). */
static inline int assemble_tet(const crom_fem *fem, const double *x, int t,
                               int project, double *Et, double *grad,
                               double *Hval, double *Jbad)
{
    double xe[12], g[12], Hup[NUP], E;
    crom_fem_tet_positions(fem, x, t, xe);
    double J = tet_kernel(crom_fem_tet_material(fem, t), xe, fem->Dminv + 9 * (size_t)t, fem->vol[t],
                          project, &E, grad ? g : NULL, Hval ? Hup : NULL);
    double sum = E;
    if (grad)
        for (int i = 0; i < 12; i++)
            sum += g[i];
    if (Hval)
        for (int e = 0; e < NUP; e++)
            sum += Hup[e];
    if (!isfinite(sum)) {
        *Jbad = J;
        return 1;
    }
    *Et += E;
    const int *tv = fem->tets + 4 * (size_t)t;
    if (grad)
        for (int k = 0; k < 4; k++) {
            double *gv = grad + 3 * (size_t)tv[k];
            gv[0] += g[3 * k];
            gv[1] += g[3 * k + 1];
            gv[2] += g[3 * k + 2];
        }
    if (Hval) {
        const int *sc = fem->scatter + (size_t)NUP * (size_t)t;
        for (int e = 0; e < NUP; e++)
            Hval[sc[e]] += Hup[e];
    }
    return 0;
}

int crom_fem_assemble(const crom_fem *fem, const double *x,
                      const crom_fem_opts *opt, double *E, double *grad,
                      double *Hval)
{
    static const crom_fem_opts none = {0};
    if (!opt)
        opt = &none;
    if (!fem || !x)
        return crom_err(CROM_EUSAGE, "crom_fem_assemble: no operator or state");
    int nt = fem->nt, project = opt->project;
    if (grad)
        memset(grad, 0, sizeof *grad * (size_t)fem->n);
    if (Hval)
        memset(Hval, 0, sizeof *Hval * (size_t)fem->nnz);

    int nth = 1;
#ifdef _OPENMP
    nth = opt->nthreads > 0 ? opt->nthreads : omp_get_max_threads();
#endif
    if (nth > 256)
        nth = 256;
    double Etot = 0, Jbad = 0;
    int bad = INT_MAX;
    if (nth <= 1) {
        for (int t = 0; t < nt; t++)
            if (assemble_tet(fem, x, t, project, &Etot, grad, Hval, &Jbad)) {
                bad = t;
                break;
            }
    }
#ifdef _OPENMP
    else {
        /* One colour at a time: tets of a colour touch disjoint vertices, so
         * the scatter has no conflicts and every entry sums its
         * contributions in colour order whatever the thread count. */
        double part[256] = {0};
#pragma omp parallel num_threads(nth)
        {
            int tid = omp_get_thread_num(), badloc = INT_MAX;
            double Eloc = 0, Jloc = 0, Jt;
            for (int c = 0; c < fem->ncolors; c++) {
#pragma omp for schedule(static)
                for (int i = fem->color_ptr[c]; i < fem->color_ptr[c + 1]; i++) {
                    int t = fem->color_tets[i];
                    if (assemble_tet(fem, x, t, project, &Eloc, grad, Hval, &Jt) &&
                        t < badloc)
                        badloc = t, Jloc = Jt;
                }
            }
#pragma omp single
            for (int i = fem->color_ptr[fem->ncolors]; i < nt; i++) {
                int t = fem->color_tets[i];
                if (assemble_tet(fem, x, t, project, &Eloc, grad, Hval, &Jt) &&
                    t < badloc)
                    badloc = t, Jloc = Jt;
            }
            part[tid] = Eloc;
#pragma omp critical(crom_fem_bad)
            if (badloc < bad) {
                bad = badloc;
                Jbad = Jloc;
            }
        }
        for (int i = 0; i < nth; i++)
            Etot += part[i];
    }
#endif
    if (bad != INT_MAX) {
        const int *tv = fem->tets + 4 * (size_t)bad;
        return crom_err(CROM_EDATA,
                        "non-finite elastic energy or derivative at tet %d "
                        "(vertices %d %d %d %d, J = %g)", bad, tv[0], tv[1],
                        tv[2], tv[3], Jbad);
    }

    /* Diagonal mass term and Dirichlet elimination; the diagonal of column
     * s is its last entry. */
    const unsigned char *fixed = opt->fixed;
    if (Hval && opt->mass_scale != 0)
        for (int v = 0; v < fem->nv; v++) {
            double mv = opt->mass_scale * fem->mass[v];
            for (int c = 0; c < 3; c++)
                Hval[fem->colptr[3 * v + c + 1] - 1] += mv;
        }
    if (fixed) {
        if (grad)
            for (int r = 0; r < fem->n; r++)
                if (fixed[r])
                    grad[r] = 0;
        if (Hval)
            for (int s = 0; s < fem->n; s++) {
                int p0 = fem->colptr[s], p1 = fem->colptr[s + 1];
                if (fixed[s]) {
                    for (int p = p0; p < p1 - 1; p++)
                        Hval[p] = 0;
                    Hval[p1 - 1] = 1;
                } else {
                    for (int p = p0; p < p1 - 1; p++)
                        if (fixed[fem->rowind[p]])
                            Hval[p] = 0;
                }
            }
    }
    if (E)
        *E = Etot;
    return CROM_OK;
}

int crom_fem_energy(const crom_fem *fem, const double *x, double *E)
{
    return crom_fem_assemble(fem, x, NULL, E, NULL, NULL);
}

int crom_fem_tet_energies(const crom_fem *fem, const double *x, const int *idx,
                          int n, double *out)
{
    if (n < 0 || (!idx && n > fem->nt))
        return crom_err(CROM_EUSAGE, "crom_fem_tet_energies: %d tets asked, "
                        "mesh has %d", n, fem->nt);
    if (idx)
        for (int i = 0; i < n; i++)
            if (idx[i] < 0 || idx[i] >= fem->nt)
                return crom_err(CROM_EUSAGE, "tet index %d out of range [0, %d)",
                                idx[i], fem->nt);
    for (int i = 0; i < n; i++) {
        int t = idx ? idx[i] : i;
        double xe[12];
        crom_fem_tet_positions(fem, x, t, xe);
        out[i] = crom_fem_tet_energy(crom_fem_tet_material(fem, t), xe, fem->Dminv + 9 * (size_t)t,
                                     fem->vol[t]);
        if (!isfinite(out[i]))
            return crom_err(CROM_EDATA, "non-finite elastic energy at tet %d", t);
    }
    return CROM_OK;
}
