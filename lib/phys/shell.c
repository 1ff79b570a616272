/* shell.c — constant-strain StVK membrane triangles, discrete-shell hinge
 * bending, and their assembly over a triangle mesh (shell.h).
 *
 * References
 *   [GHDS03] Grinspun, Hirani, Desbrun, Schröder 2003, "Discrete Shells"
 *            (the hinge energy (θ − θ̄)² |ē| / h̄_e).
 *   [SOA23]  Sharp, Romero, Jacobson, Vouga, Kry, Levin, Solomon 2023,
 *            "Data-Free Learning of Reduced-Order Kinematics", §5.1 ("Cloth
 *            model": StVK stretching on faces, [GHDS03] bending on edges).
 */
#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "phys/shell.h"
#include "phys/sym.h"

#define TRI_UP 45   /* upper entries of a 9×9 element Hessian */
#define HINGE_UP 78 /* of a 12×12 one */

int crom_shell_material_init(crom_shell_material *m, double E, double nu, double thickness, double rho)
{
    memset(m, 0, sizeof *m);
    if (!isfinite(E) || E <= 0)
        return crom_err(CROM_EUSAGE, "Young's modulus must be positive and finite (got %g)", E);
    if (!isfinite(nu) || nu <= -1 || nu > 0.5)
        return crom_err(CROM_EUSAGE, "Poisson ratio must be in (-1, 0.5] (got %g)", nu);
    if (!isfinite(thickness) || thickness <= 0)
        return crom_err(CROM_EUSAGE, "shell thickness must be positive and finite (got %g)", thickness);
    if (!isfinite(rho) || rho <= 0)
        return crom_err(CROM_EUSAGE, "density must be positive and finite (got %g)", rho);
    m->E = E;
    m->nu = nu;
    m->thickness = thickness;
    m->rho = rho;
    m->mu = E / (2 * (1 + nu));
    m->lambda_ps = E * nu / (1 - nu * nu);
    m->D = E * thickness * thickness * thickness / (12 * (1 - nu * nu));
    return CROM_OK;
}

void crom_shell_material_plane(crom_shell_material *m)
{
    m->plane = 1;
    crom_material_init(&m->solid, m->E, m->nu < 0.5 ? m->nu : 0.4999, m->rho);
    m->kz = 100 * m->E * m->thickness / 6;
    m->D = 0;
}

/* ---- small vector helpers ---------------------------------------------- */

static inline double dot3(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static inline void cross3(const double *a, const double *b, double *o)
{
    o[0] = a[1] * b[2] - a[2] * b[1];
    o[1] = a[2] * b[0] - a[0] * b[2];
    o[2] = a[0] * b[1] - a[1] * b[0];
}

/* ---- membrane ----------------------------------------------------------- */

int crom_shell_tri_rest(const double X[9], double Dminv[4], double *A)
{
    double e1[3], e2[3], e3[3], n[3], u[3], w[3];
    for (int c = 0; c < 3; c++) {
        e1[c] = X[3 + c] - X[c];
        e2[c] = X[6 + c] - X[c];
        e3[c] = e2[c] - e1[c];
    }
    cross3(e1, e2, n);
    double l1 = sqrt(dot3(e1, e1)), a2 = sqrt(dot3(n, n));
    double lmax2 = fmax(dot3(e1, e1), fmax(dot3(e2, e2), dot3(e3, e3)));
    *A = 0.5 * a2;
    if (!isfinite(a2) || !isfinite(lmax2) || !(0.5 * a2 > 1e-12 * lmax2))
        return CROM_EDATA;
    for (int c = 0; c < 3; c++)
        u[c] = e1[c] / l1;
    cross3(n, u, w); /* in-plane, perpendicular to e1, towards X2 */
    for (int c = 0; c < 3; c++)
        w[c] /= a2;
    /* Dm = [[l1, e2·u], [0, e2·w]] (columns: the two edges in the frame) */
    double d01 = dot3(e2, u), d11 = dot3(e2, w), det = l1 * d11;
    Dminv[0] = 1 / l1;
    Dminv[1] = -d01 / det;
    Dminv[2] = 0;
    Dminv[3] = 1 / d11;
    return CROM_OK;
}

void crom_shell_tri_F(const double x[9], const double Dminv[4], double F[6])
{
    for (int i = 0; i < 3; i++) {
        double d0 = x[3 + i] - x[i], d1 = x[6 + i] - x[i];
        F[2 * i] = d0 * Dminv[0] + d1 * Dminv[2];
        F[2 * i + 1] = d0 * Dminv[1] + d1 * Dminv[3];
    }
}

/* The right Cauchy–Green tensor C = FᵀF [2][2] of F [3][2]. */
static void cauchy_green(const double F[6], double C2[4])
{
    for (int a = 0; a < 2; a++)
        for (int b = 0; b < 2; b++) {
            C2[2 * a + b] = 0;
            for (int i = 0; i < 3; i++)
                C2[2 * a + b] += F[2 * i + a] * F[2 * i + b];
        }
}

/* The plane-strain F = [[F2, 0], [0, 1]] of a plane triangle (F2: rows x, y of its 3×2 F). */
static void plane_F(const double x[9], const double Dminv[4], double F3[9])
{
    double F[6];
    crom_shell_tri_F(x, Dminv, F);
    const double f[9] = {F[0], F[1], 0, F[2], F[3], 0, 0, 0, 1};
    memcpy(F3, f, sizeof f);
}

/* A plane-strain triangle: t A Ψ(F) and the z springs (shell.h). */
static int plane_eval(const crom_shell_material *m, const double x[9], const double Dminv[4], double A, int project,
                      double *E, double g[9], double H[81])
{
    double F3[9], W = m->thickness * A, sum = 0;
    plane_F(x, Dminv, F3);
    double beta[3][2] = {{-Dminv[0] - Dminv[2], -Dminv[1] - Dminv[3]}, {Dminv[0], Dminv[1]}, {Dminv[2], Dminv[3]}};
    if (E) {
        *E = W * crom_fem_psi(&m->solid, F3);
        for (int v = 0; v < 3; v++)
            *E += 0.5 * m->kz * x[3 * v + 2] * x[3 * v + 2];
        sum += *E;
    }
    if (g) {
        double P[9];
        crom_fem_pk1(&m->solid, F3, P);
        for (int v = 0; v < 3; v++) {
            for (int i = 0; i < 2; i++)
                g[3 * v + i] = W * (P[3 * i] * beta[v][0] + P[3 * i + 1] * beta[v][1]);
            g[3 * v + 2] = m->kz * x[3 * v + 2];
            sum += g[3 * v] + g[3 * v + 1] + g[3 * v + 2];
        }
    }
    if (H) {
        double C[81]; /* the in-plane block of dP/dF (projected: a block of a PSD matrix is PSD) */
        crom_fem_dPdF(&m->solid, F3, project, C);
        memset(H, 0, sizeof(double) * 81);
        for (int v = 0; v < 3; v++)
            for (int i = 0; i < 2; i++)
                for (int w = 0; w < 3; w++)
                    for (int j = 0; j < 2; j++) {
                        double h = 0;
                        for (int a = 0; a < 2; a++)
                            for (int b = 0; b < 2; b++)
                                h += beta[v][a] * beta[w][b] * C[(3 * i + a) * 9 + 3 * j + b];
                        H[(3 * v + i) * 9 + 3 * w + j] = W * h;
                        sum += h;
                    }
        for (int v = 0; v < 3; v++)
            H[(3 * v + 2) * 9 + 3 * v + 2] = m->kz;
    }
    return isfinite(sum) ? CROM_OK : CROM_EDATA;
}

/* von Mises of the plane-strain Cauchy stress σ = P Fᵀ / J (3×3). */
static double plane_mises(const crom_shell_material *m, const double x[9], const double Dminv[4])
{
    double F3[9], P[9], s[9];
    plane_F(x, Dminv, F3);
    crom_fem_pk1(&m->solid, F3, P);
    double J = F3[0] * F3[4] - F3[1] * F3[3];
    if (!(J > 0))
        return NAN;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            s[3 * i + j] = (P[3 * i] * F3[3 * j] + P[3 * i + 1] * F3[3 * j + 1] + P[3 * i + 2] * F3[3 * j + 2]) / J;
    double d0 = s[0] - s[4], d1 = s[4] - s[8], d2 = s[8] - s[0];
    return sqrt(0.5 * (d0 * d0 + d1 * d1 + d2 * d2) + 3 * (s[1] * s[1] + s[2] * s[2] + s[5] * s[5]));
}

double crom_shell_tri_mises(const crom_shell_material *m, const double x[9], const double Dminv[4])
{
    if (m->plane)
        return plane_mises(m, x, Dminv);
    double F[6], C2[4], S[4];
    crom_shell_tri_F(x, Dminv, F);
    cauchy_green(F, C2);
    double e0 = 0.5 * (C2[0] - 1), e1 = 0.5 * C2[1], e3 = 0.5 * (C2[3] - 1), tr = e0 + e3;
    S[0] = 2 * m->mu * e0 + m->lambda_ps * tr;
    S[1] = S[2] = 2 * m->mu * e1;
    S[3] = 2 * m->mu * e3 + m->lambda_ps * tr;
    double detC = C2[0] * C2[3] - C2[1] * C2[2], J = sqrt(detC);
    /* σ = F S Fᵀ / J has the nonzero eigenvalues of S C / J: tr σ = tr(S C) / J, σ1 σ2 = det S */
    double trSC = S[0] * C2[0] + S[1] * C2[2] + S[2] * C2[1] + S[3] * C2[3];
    double I1 = trSC / J, I2 = S[0] * S[3] - S[1] * S[2], v = I1 * I1 - 3 * I2;
    return J > 0 ? sqrt(v > 0 ? v : 0) : NAN;
}

int crom_shell_tri_eval(const crom_shell_material *m, const double x[9], const double Dminv[4], double A,
                        int project, double *E, double g[9], double H[81])
{
    if (m->plane)
        return plane_eval(m, x, Dminv, A, project, E, g, H);
    double F[6], C2[4] = {0}, Eg[4], S[4], W = m->thickness * A, mu = m->mu, lam = m->lambda_ps;
    crom_shell_tri_F(x, Dminv, F);
    for (int a = 0; a < 2; a++)
        for (int b = 0; b < 2; b++)
            for (int i = 0; i < 3; i++)
                C2[2 * a + b] += F[2 * i + a] * F[2 * i + b];
    Eg[0] = 0.5 * (C2[0] - 1);
    Eg[1] = Eg[2] = 0.5 * C2[1];
    Eg[3] = 0.5 * (C2[3] - 1);
    double tr = Eg[0] + Eg[3], sum = 0;
    for (int k = 0; k < 4; k++)
        S[k] = 2 * mu * Eg[k] + (k == 0 || k == 3 ? lam * tr : 0);
    if (E) {
        *E = W * (mu * (Eg[0] * Eg[0] + 2 * Eg[1] * Eg[1] + Eg[3] * Eg[3]) + 0.5 * lam * tr * tr);
        sum += *E;
    }
    /* ∂F_ia/∂x_{v,j} = δij β[v][a] */
    double beta[3][2] = {{-Dminv[0] - Dminv[2], -Dminv[1] - Dminv[3]}, {Dminv[0], Dminv[1]}, {Dminv[2], Dminv[3]}};
    if (g) {
        double P[6]; /* P = F S */
        for (int i = 0; i < 3; i++)
            for (int a = 0; a < 2; a++)
                P[2 * i + a] = F[2 * i] * S[a] + F[2 * i + 1] * S[2 + a];
        for (int v = 0; v < 3; v++)
            for (int i = 0; i < 3; i++) {
                g[3 * v + i] = W * (P[2 * i] * beta[v][0] + P[2 * i + 1] * beta[v][1]);
                sum += g[3 * v + i];
            }
    }
    if (H) {
        /* ∂²Ψ/∂F_ia∂F_jb = δij S_ab + μ F_ib F_ja + μ δab (FFᵀ)_ij + λ̃ F_ia F_jb */
        double Ct[36];
        for (int i = 0; i < 3; i++)
            for (int a = 0; a < 2; a++)
                for (int j = 0; j < 3; j++)
                    for (int b = 0; b < 2; b++) {
                        double FFt = F[2 * i] * F[2 * j] + F[2 * i + 1] * F[2 * j + 1];
                        Ct[(2 * i + a) * 6 + 2 * j + b] = (i == j ? S[2 * a + b] : 0) + mu * F[2 * i + b] * F[2 * j + a] +
                                                          (a == b ? mu * FFt : 0) + lam * F[2 * i + a] * F[2 * j + b];
                    }
        if (project && crom_sym_dense_project(Ct, 6))
            return CROM_EDATA;
        for (int v = 0; v < 3; v++)
            for (int i = 0; i < 3; i++)
                for (int w = 0; w < 3; w++)
                    for (int j = 0; j < 3; j++) {
                        double h = 0;
                        for (int a = 0; a < 2; a++)
                            for (int b = 0; b < 2; b++)
                                h += beta[v][a] * beta[w][b] * Ct[(2 * i + a) * 6 + 2 * j + b];
                        H[(3 * v + i) * 9 + 3 * w + j] = W * h;
                        sum += h;
                    }
    }
    return isfinite(sum) ? CROM_OK : CROM_EDATA;
}

/* ---- hinge -------------------------------------------------------------- */

/* M (9×9) += s [v]× placed at block (p, q), and its transpose at (q, p) */
static void add_skew(double *M, int p, int q, double s, const double *v)
{
    const double K[9] = {0, -v[2], v[1], v[2], 0, -v[0], -v[1], v[0], 0};
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            M[(3 * p + i) * 9 + 3 * q + j] += s * K[3 * i + j];
            M[(3 * q + j) * 9 + 3 * p + i] += s * K[3 * i + j];
        }
}

int crom_shell_hinge_angle(const double x[12], double *theta, double g[12], double H[144])
{
    double a[3], b[3], c[3];
    for (int k = 0; k < 3; k++) {
        a[k] = x[3 + k] - x[k];
        b[k] = x[6 + k] - x[k];
        c[k] = x[9 + k] - x[k];
    }
    double bxc[3], cxa[3], axb[3];
    cross3(b, c, bxc);
    cross3(c, a, cxa);
    cross3(a, b, axb);
    double L2 = dot3(a, a), L = sqrt(L2), Dt = dot3(a, bxc);
    double ab = dot3(a, b), ac = dot3(a, c), bc = dot3(b, c);
    double U = -L * Dt, V = ab * ac - L2 * bc, R = U * U + V * V;
    if (!(R > 0) || !isfinite(R))
        return CROM_EDATA;
    *theta = atan2(U, V);
    if (!g && !H)
        return CROM_OK;
    /* gradients in y = (a, b, c) */
    double gD[9], gL[9] = {0}, gU[9], gV[9];
    memcpy(gD, bxc, sizeof bxc);
    memcpy(gD + 3, cxa, sizeof cxa);
    memcpy(gD + 6, axb, sizeof axb);
    for (int k = 0; k < 3; k++) {
        gL[k] = a[k] / L;
        gV[k] = b[k] * ac + c[k] * ab - 2 * a[k] * bc;
        gV[3 + k] = a[k] * ac - L2 * c[k];
        gV[6 + k] = a[k] * ab - L2 * b[k];
    }
    for (int k = 0; k < 9; k++)
        gU[k] = -(Dt * gL[k] + L * gD[k]);
    double tU = V / R, tV = -U / R, gy[9];
    for (int k = 0; k < 9; k++)
        gy[k] = tU * gU[k] + tV * gV[k];
    double Hy[81];
    if (H) {
        double HU[81] = {0}, HV[81] = {0};
        /* ∇²U = −(D ∇²L + ∇L∇Dᵀ + ∇D∇Lᵀ + L ∇²D) */
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++)
                HU[i * 9 + j] = -Dt * ((i == j) - a[i] * a[j] / L2) / L;
        for (int i = 0; i < 9; i++)
            for (int j = 0; j < 9; j++)
                HU[i * 9 + j] -= gL[i] * gD[j] + gD[i] * gL[j];
        add_skew(HU, 0, 1, L, c);  /* ∇²D: (a,b) −[c]×, (a,c) [b]×, (b,c) −[a]× */
        add_skew(HU, 0, 2, -L, b);
        add_skew(HU, 1, 2, L, a);
        /* ∇²V: (a,a) bcᵀ + cbᵀ − 2(b·c)I; (a,b) (a·c)I + caᵀ − 2acᵀ;
         * (a,c) (a·b)I + baᵀ − 2abᵀ; (b,c) aaᵀ − |a|²I */
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) {
                double d = i == j;
                HV[i * 9 + j] = b[i] * c[j] + c[i] * b[j] - 2 * bc * d;
                double vab = ac * d + c[i] * a[j] - 2 * a[i] * c[j];
                double vac = ab * d + b[i] * a[j] - 2 * a[i] * b[j];
                double vbc = a[i] * a[j] - L2 * d;
                HV[i * 9 + 3 + j] = vab;
                HV[(3 + j) * 9 + i] = vab;
                HV[i * 9 + 6 + j] = vac;
                HV[(6 + j) * 9 + i] = vac;
                HV[(3 + i) * 9 + 6 + j] = vbc;
                HV[(6 + j) * 9 + 3 + i] = vbc;
            }
        double R2 = R * R, tUU = -2 * U * V / R2, tVV = 2 * U * V / R2, tUV = (U * U - V * V) / R2;
        for (int i = 0; i < 9; i++)
            for (int j = 0; j < 9; j++)
                Hy[i * 9 + j] = tU * HU[i * 9 + j] + tV * HV[i * 9 + j] + tUU * gU[i] * gU[j] + tVV * gV[i] * gV[j] +
                                tUV * (gU[i] * gV[j] + gV[i] * gU[j]);
    }
    /* back to x: a = x1 − x0, b = x2 − x0, c = x3 − x0 */
    double sum = *theta;
    if (g) {
        for (int k = 0; k < 3; k++) {
            g[k] = -(gy[k] + gy[3 + k] + gy[6 + k]);
            for (int p = 0; p < 3; p++)
                g[3 * (p + 1) + k] = gy[3 * p + k];
        }
        for (int k = 0; k < 12; k++)
            sum += g[k];
    }
    if (H) { /* blocks (v, w) >= 1 are Hy's; row and column 0 minus the sums of the others */
        for (int i = 0; i < 9; i++)
            for (int j = 0; j < 9; j++)
                H[(3 + i) * 12 + 3 + j] = Hy[i * 9 + j];
        for (int i = 0; i < 9; i++)
            for (int k = 0; k < 3; k++) {
                double h = -(Hy[i * 9 + k] + Hy[i * 9 + 3 + k] + Hy[i * 9 + 6 + k]);
                H[(3 + i) * 12 + k] = H[k * 12 + 3 + i] = h;
            }
        for (int r = 0; r < 3; r++)
            for (int k = 0; k < 3; k++)
                H[r * 12 + k] = -(H[r * 12 + 3 + k] + H[r * 12 + 6 + k] + H[r * 12 + 9 + k]);
        for (int i = 0; i < 144; i++)
            sum += H[i];
    }
    return isfinite(sum) ? CROM_OK : CROM_EDATA;
}

int crom_shell_hinge_rest(const double X[12], double *theta0, double *w)
{
    double a[3], b[3], c[3], n1[3], n2[3];
    for (int k = 0; k < 3; k++) {
        a[k] = X[3 + k] - X[k];
        b[k] = X[6 + k] - X[k];
        c[k] = X[9 + k] - X[k];
    }
    cross3(a, b, n1);
    cross3(c, a, n2);
    double A12 = 0.5 * (sqrt(dot3(n1, n1)) + sqrt(dot3(n2, n2)));
    if (!(A12 > 0) || crom_shell_hinge_angle(X, theta0, NULL, NULL))
        return CROM_EDATA;
    *w = dot3(a, a) / A12;
    return isfinite(*w) ? CROM_OK : CROM_EDATA;
}

int crom_shell_hinge_eval(double k, double theta0, const double x[12], int project, double *E, double g[12],
                          double H[144])
{
    double th, gt[12], Ht[144];
    int rc = crom_shell_hinge_angle(x, &th, g || H ? gt : NULL, H && !project ? Ht : NULL);
    if (rc)
        return rc;
    double d = remainder(th - theta0, 2 * M_PI);
    if (E)
        *E = k * d * d;
    if (g)
        for (int i = 0; i < 12; i++)
            g[i] = 2 * k * d * gt[i];
    if (H)
        for (int i = 0; i < 12; i++)
            for (int j = 0; j < 12; j++)
                H[i * 12 + j] = 2 * k * (gt[i] * gt[j] + (project ? 0 : d * Ht[i * 12 + j]));
    return CROM_OK;
}

/* ---- a shell mesh ------------------------------------------------------- */

void crom_shell_free(crom_shell *s)
{
    if (!s)
        return;
    free(s->tris);
    free(s->Dminv);
    free(s->area);
    free(s->hinges);
    free(s->theta0);
    free(s->hk);
    free(s->mass);
    free(s->colptr);
    free(s->rowind);
    free(s->tscatter);
    free(s->hscatter);
    memset(s, 0, sizeof *s);
}

typedef struct {
    int lo, hi; /* vertices of the edge, lo < hi */
    int tri, k; /* the triangle and its local edge k: (t[k], t[(k+1)%3]) */
} edge_rec;

static int edge_cmp(const void *pa, const void *pb)
{
    const edge_rec *a = pa, *b = pb;
    if (a->lo != b->lo)
        return a->lo < b->lo ? -1 : 1;
    if (a->hi != b->hi)
        return a->hi < b->hi ? -1 : 1;
    return a->tri < b->tri ? -1 : a->tri > b->tri;
}

/* The hinges: every edge shared by two triangles (crom_shell_init's checks),
 * their rest angles and stiffnesses from the rest positions X0 */
static int build_hinges(crom_shell *s, const double *X0)
{
    int nt = s->nt, ne = 3 * nt, nh = 0;
    edge_rec *e = crom_malloc(sizeof *e * (size_t)ne);
    if (!e)
        return CROM_EINTERNAL;
    for (int t = 0; t < nt; t++)
        for (int k = 0; k < 3; k++) {
            int u = s->tris[3 * t + k], v = s->tris[3 * t + (k + 1) % 3];
            e[3 * t + k] = (edge_rec){u < v ? u : v, u < v ? v : u, t, k};
        }
    qsort(e, (size_t)ne, sizeof *e, edge_cmp);
    int rc = CROM_OK;
    s->boundary_edges = 0;
    for (int i = 0; i < ne && !rc;) {
        int j = i + 1;
        while (j < ne && e[j].lo == e[i].lo && e[j].hi == e[i].hi)
            j++;
        if (j - i > 2)
            rc = crom_err(CROM_EDATA, "the surface is not manifold: edge %d-%d is shared by %d triangles (%d, %d, "
                          "%d, ...)", e[i].lo, e[i].hi, j - i, e[i].tri, e[i + 1].tri, e[i + 2].tri);
        else if (j - i == 1)
            s->boundary_edges++;
        else if (s->tris[3 * e[i].tri + e[i].k] == s->tris[3 * e[i + 1].tri + e[i + 1].k])
            rc = crom_err(CROM_EDATA, "the surface is not consistently oriented: triangles %d and %d run along "
                          "edge %d-%d in the same direction", e[i].tri, e[i + 1].tri, e[i].lo, e[i].hi);
        else
            nh++;
        i = j;
    }
    if (!rc) {
        s->hinges = crom_malloc(sizeof(int) * 4 * (size_t)(nh ? nh : 1));
        s->theta0 = crom_malloc(sizeof(double) * (size_t)(nh ? nh : 1));
        s->hk = crom_malloc(sizeof(double) * (size_t)(nh ? nh : 1));
        if (!s->hinges || !s->theta0 || !s->hk)
            rc = CROM_EINTERNAL;
    }
    s->nh = 0;
    for (int i = 0; i < ne && !rc;) {
        int j = i + 1;
        while (j < ne && e[j].lo == e[i].lo && e[j].hi == e[i].hi)
            j++;
        if (j - i == 2) {
            const int *t1 = s->tris + 3 * e[i].tri, *t2 = s->tris + 3 * e[i + 1].tri;
            int k1 = e[i].k, k2 = e[i + 1].k, *h = s->hinges + 4 * (size_t)s->nh;
            h[0] = t1[k1]; /* (v0, v1, v2) = triangle 1 from its edge; v3 opposite in triangle 2 */
            h[1] = t1[(k1 + 1) % 3];
            h[2] = t1[(k1 + 2) % 3];
            h[3] = t2[(k2 + 2) % 3];
            double X[12], w;
            for (int v = 0; v < 4; v++)
                memcpy(X + 3 * v, X0 + 3 * (size_t)h[v], sizeof(double) * 3);
            if (crom_shell_hinge_rest(X, &s->theta0[s->nh], &w))
                rc = crom_err(CROM_EDATA, "the hinge at edge %d-%d (triangles %d and %d) is degenerate", h[0], h[1],
                              e[i].tri, e[i + 1].tri);
            s->hk[s->nh++] = 0.5 * s->mat.D * w;
        }
        i = j;
    }
    free(e);
    return rc;
}

/* index of row r in column c of the pattern (it is there) */
static int entry(const crom_shell *s, int r, int c)
{
    return crom_sym_entry(s->colptr, s->rowind, r, c);
}

/* scatter[k] for the upper entries (p <= q, row-major) of an element of nvert vertices */
static void element_scatter(const crom_shell *s, const int *vs, int nvert, int *scatter)
{
    int n = 3 * nvert, k = 0;
    for (int p = 0; p < n; p++)
        for (int q = p; q < n; q++) {
            int gp = 3 * vs[p / 3] + p % 3, gq = 3 * vs[q / 3] + q % 3;
            scatter[k++] = gp <= gq ? entry(s, gp, gq) : entry(s, gq, gp);
        }
}

/* the vertices of shell element e: triangle e, or hinge e − nt */
static int elem_verts(const void *ctx, int e, int *v)
{
    const crom_shell *s = ctx;
    int m = e < s->nt ? 3 : 4;
    memcpy(v, e < s->nt ? s->tris + 3 * (size_t)e : s->hinges + 4 * (size_t)(e - s->nt), sizeof(int) * (size_t)m);
    return m;
}

/* The CSC pattern of the upper triangle: 3×3 blocks for the vertex pairs
 * of every triangle and hinge, rows sorted (the diagonal last) */
static int build_pattern(crom_shell *s)
{
    s->n = 3 * s->nv;
    if (crom_sym_block_pattern(s->nv, s->nt + s->nh, elem_verts, s, &s->colptr, &s->rowind, &s->nnz))
        return CROM_EINTERNAL;
    s->tscatter = crom_malloc(sizeof(int) * TRI_UP * (size_t)(s->nt ? s->nt : 1));
    s->hscatter = crom_malloc(sizeof(int) * HINGE_UP * (size_t)(s->nh ? s->nh : 1));
    if (!s->tscatter || !s->hscatter)
        return CROM_EINTERNAL;
    for (int t = 0; t < s->nt; t++)
        element_scatter(s, s->tris + 3 * (size_t)t, 3, s->tscatter + TRI_UP * (size_t)t);
    for (int h = 0; h < s->nh; h++)
        element_scatter(s, s->hinges + 4 * (size_t)h, 4, s->hscatter + HINGE_UP * (size_t)h);
    return CROM_OK;
}

int crom_shell_init(crom_shell *s, int nv, const double *X, int nt, const int *tris,
                    const crom_shell_material *mat)
{
    memset(s, 0, sizeof *s);
    if (!X || !tris || nv <= 0 || nt <= 0 || !mat)
        return crom_err(CROM_EUSAGE, "crom_shell_init: empty surface or no material");
    if (nv > 2147483647 / 3)
        return crom_err(CROM_EDATA, "surface too large (%d vertices)", nv);
    for (int v = 0; v < nv; v++)
        for (int c = 0; c < 3; c++)
            if (!isfinite(X[3 * (size_t)v + c]))
                return crom_err(CROM_EDATA, "vertex %d has a non-finite rest position", v);
    for (int t = 0; t < nt; t++) {
        const int *tv = tris + 3 * (size_t)t;
        for (int k = 0; k < 3; k++) {
            if (tv[k] < 0 || tv[k] >= nv)
                return crom_err(CROM_EDATA, "triangle %d: vertex index %d out of range [0, %d)", t, tv[k], nv);
            for (int l = 0; l < k; l++)
                if (tv[l] == tv[k])
                    return crom_err(CROM_EDATA, "triangle %d: repeated vertex %d", t, tv[k]);
        }
    }
    int rc;
    s->nv = nv;
    s->nt = nt;
    s->mat = *mat;
    s->tris = crom_malloc(sizeof(int) * 3 * (size_t)nt);
    s->Dminv = crom_malloc(sizeof(double) * 4 * (size_t)nt);
    s->area = crom_malloc(sizeof(double) * (size_t)nt);
    s->mass = crom_calloc((size_t)nv, sizeof(double));
    if (!s->tris || !s->Dminv || !s->area || !s->mass) {
        rc = CROM_EINTERNAL;
        goto fail;
    }
    memcpy(s->tris, tris, sizeof(int) * 3 * (size_t)nt);
    for (int t = 0; t < nt; t++) {
        const int *tv = tris + 3 * (size_t)t;
        double Xe[9];
        for (int k = 0; k < 3; k++)
            memcpy(Xe + 3 * k, X + 3 * (size_t)tv[k], sizeof(double) * 3);
        if (crom_shell_tri_rest(Xe, s->Dminv + 4 * (size_t)t, &s->area[t])) {
            rc = crom_err(CROM_EDATA, "rest triangle %d (vertices %d %d %d) is degenerate: area %g", t, tv[0], tv[1],
                          tv[2], s->area[t]);
            goto fail;
        }
        if (mat->plane) { /* a 2-D solid: in the plane z = 0, its rest frame turning as x, y do */
            double F3[9], *Di = s->Dminv + 4 * (size_t)t;
            if (Xe[2] != 0 || Xe[5] != 0 || Xe[8] != 0) {
                rc = crom_err(CROM_EDATA, "plane-strain triangle %d is not in the plane z = 0", t);
                goto fail;
            }
            plane_F(Xe, Di, F3);
            if (F3[0] * F3[4] - F3[1] * F3[3] < 0)
                Di[1] = -Di[1], Di[3] = -Di[3];
        }
        s->total_area += s->area[t];
        double mv = mat->rho * mat->thickness * s->area[t] / 3;
        for (int k = 0; k < 3; k++)
            s->mass[tv[k]] += mv;
    }
    s->total_mass = mat->rho * mat->thickness * s->total_area;
    if ((!mat->plane && (rc = build_hinges(s, X))) || (rc = build_pattern(s)))
        goto fail;
    return CROM_OK;
fail:
    crom_shell_free(s);
    return rc;
}

static void gather(const double *x, const int *vs, int m, double *xe)
{
    for (int i = 0; i < m; i++)
        memcpy(xe + 3 * i, x + 3 * (size_t)vs[i], sizeof(double) * 3);
}

int crom_shell_assemble(const crom_shell *s, const double *x, const crom_fem_opts *opt, double *E, double *grad,
                        double *Hval)
{
    static const crom_fem_opts none = {0, 0, NULL, 0};
    if (!opt)
        opt = &none;
    int project = opt->project;
    double Et = 0;
    if (grad)
        memset(grad, 0, sizeof(double) * (size_t)s->n);
    if (Hval)
        memset(Hval, 0, sizeof(double) * (size_t)s->nnz);
    for (int t = 0; t < s->nt; t++) {
        const int *vs = s->tris + 3 * (size_t)t;
        double xe[9], Ee, g[9], H[81];
        gather(x, vs, 3, xe);
        if (crom_shell_tri_eval(&s->mat, xe, s->Dminv + 4 * (size_t)t, s->area[t], project, &Ee, grad ? g : NULL,
                                Hval ? H : NULL))
            return crom_err(CROM_EDATA, "triangle %d: non-finite membrane energy", t);
        Et += Ee;
        for (int i = 0; grad && i < 9; i++)
            grad[3 * vs[i / 3] + i % 3] += g[i];
        if (Hval) {
            const int *sc = s->tscatter + TRI_UP * (size_t)t;
            for (int p = 0, k = 0; p < 9; p++)
                for (int q = p; q < 9; q++)
                    Hval[sc[k++]] += H[9 * p + q];
        }
    }
    for (int h = 0; h < s->nh; h++) {
        const int *vs = s->hinges + 4 * (size_t)h;
        double xe[12], Ee, g[12], H[144];
        gather(x, vs, 4, xe);
        if (crom_shell_hinge_eval(s->hk[h], s->theta0[h], xe, project, &Ee, grad ? g : NULL, Hval ? H : NULL))
            return crom_err(CROM_EDATA, "hinge %d (edge %d-%d): non-finite bending energy", h, vs[0], vs[1]);
        Et += Ee;
        for (int i = 0; grad && i < 12; i++)
            grad[3 * vs[i / 3] + i % 3] += g[i];
        if (Hval) {
            const int *sc = s->hscatter + HINGE_UP * (size_t)h;
            for (int p = 0, k = 0; p < 12; p++)
                for (int q = p; q < 12; q++)
                    Hval[sc[k++]] += H[12 * p + q];
        }
    }
    crom_sym_dirichlet_mass(s->n, s->colptr, s->rowind, opt->fixed, s->mass, opt->mass_scale, grad, Hval);
    if (E)
        *E = Et;
    return CROM_OK;
}
