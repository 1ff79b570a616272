/* rigid.c — rigid bodies as frames of four lumped masses (see rigid.h). */
#include <lapacke.h>
#include <math.h>
#include <string.h>

#include "base/err.h"
#include "mesh/scene.h"
#include "phys/fem.h"
#include "phys/rigid.h"
#include "phys/sym.h"

int crom_rigid_inertia_tets(const crom_mesh *mesh, double rho, crom_rigid_inertia *in)
{
    memset(in, 0, sizeof *in);
    if (!(rho > 0) || !isfinite(rho))
        return crom_err(CROM_EUSAGE, "density must be a positive number, got %g", rho);
    /* first pass: mass and centre; second: ∫ (X − c)(X − c)ᵀ, exact for a
     * tet: V/20 (Σ_i x_i x_iᵀ + (Σ_i x_i)(Σ_i x_i)ᵀ) with x relative to c */
    double m = 0, c[3] = {0, 0, 0};
    for (int t = 0; t < mesh->nt; t++) {
        const int *v = mesh->tets + 4 * (size_t)t;
        const double *X = mesh->X;
        double V = crom_mesh_tet_volume(X + 3 * v[0], X + 3 * v[1], X + 3 * v[2], X + 3 * v[3]);
        m += rho * V;
        for (int k = 0; k < 3; k++)
            c[k] += rho * V * 0.25 * (X[3 * v[0] + k] + X[3 * v[1] + k] + X[3 * v[2] + k] + X[3 * v[3] + k]);
    }
    if (!(m > 0))
        return crom_err(CROM_EDATA, "the mesh has no volume: no rigid body");
    for (int k = 0; k < 3; k++)
        c[k] /= m;
    double S[9] = {0};
    for (int t = 0; t < mesh->nt; t++) {
        const int *v = mesh->tets + 4 * (size_t)t;
        const double *X = mesh->X;
        double V = crom_mesh_tet_volume(X + 3 * v[0], X + 3 * v[1], X + 3 * v[2], X + 3 * v[3]);
        double x[4][3], s[3] = {0, 0, 0};
        for (int i = 0; i < 4; i++)
            for (int k = 0; k < 3; k++) {
                x[i][k] = X[3 * v[i] + k] - c[k];
                s[k] += x[i][k];
            }
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++) {
                double q = s[a] * s[b];
                for (int i = 0; i < 4; i++)
                    q += x[i][a] * x[i][b];
                S[3 * a + b] += rho * V / 20 * q;
            }
    }
    in->m = m;
    memcpy(in->c, c, sizeof c);
    memcpy(in->S, S, sizeof S);
    return 0;
}

void crom_rigid_inertia_box(const double a[3], const double c[3], double rho, crom_rigid_inertia *in)
{
    memset(in, 0, sizeof *in);
    in->m = rho * a[0] * a[1] * a[2];
    for (int k = 0; k < 3; k++) {
        in->c[k] = c[k];
        in->S[4 * k] = in->m * a[k] * a[k] / 12;
    }
}

int crom_rigid_frame(const crom_rigid_inertia *in, double Y[12])
{
    /* A = (3S/m)^½ by the eigensystem of S */
    double Q[9], w[3];
    memcpy(Q, in->S, sizeof Q);
    if (!(in->m > 0) || LAPACKE_dsyev(LAPACK_ROW_MAJOR, 'V', 'U', 3, Q, 3, w) != 0 || !(w[0] > 1e-12 * w[2]))
        return crom_err(CROM_EDATA, "the body's second moment is not positive definite: it has no 3-D extent");
    double A[9] = {0};
    for (int k = 0; k < 3; k++) {
        double s = sqrt(3 * w[k] / in->m);
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++)
                A[3 * i + j] += s * Q[3 * i + k] * Q[3 * j + k];
    }
    /* a positively oriented regular tetrahedron (A is positive definite) */
    static const double e[4][3] = {{1, 1, 1}, {-1, 1, -1}, {1, -1, -1}, {-1, -1, 1}};
    for (int k = 0; k < 4; k++)
        for (int i = 0; i < 3; i++) {
            double s = 0;
            for (int j = 0; j < 3; j++)
                s += A[3 * i + j] * e[k][j] / sqrt(3.0);
            Y[3 * k + i] = in->c[i] + s;
        }
    return 0;
}

int crom_rigid_frame_inverse(const double Y[12], double B[9])
{
    double V;
    return crom_fem_tet_rest(Y, B, &V); /* the frame is a tetrahedron */
}

void crom_rigid_coords(const double Y[12], const double B[9], const double X[3], double beta[4])
{
    double d[3] = {X[0] - Y[0], X[1] - Y[1], X[2] - Y[2]};
    beta[0] = 1;
    for (int k = 0; k < 3; k++) {
        beta[k + 1] = B[3 * k] * d[0] + B[3 * k + 1] * d[1] + B[3 * k + 2] * d[2];
        beta[0] -= beta[k + 1];
    }
}

void crom_rigid_affine(const double Y[12], const double B[9], const double y[12], double R[9], double t[3])
{
    crom_fem_tet_F(y, B, R); /* R = D_y B, the frame's deformation gradient */
    for (int i = 0; i < 3; i++) /* t = y_0 − R Y_0 */
        t[i] = y[i] - (R[3 * i] * Y[0] + R[3 * i + 1] * Y[1] + R[3 * i + 2] * Y[2]);
}

/* ∂R_ij/∂y_(k,i) = b_k[j]: the frame vertex k's weight in column j of R
 * (b_0 = −Σ rows of B, b_k = row k−1 of B); R depends on y_(k,c) only
 * through row c. */
static void edge_weights(const double B[9], double b[4][3])
{
    for (int j = 0; j < 3; j++) {
        b[0][j] = -(B[j] + B[3 + j] + B[6 + j]);
        for (int k = 1; k < 4; k++)
            b[k][j] = B[3 * (k - 1) + j];
    }
}

int crom_rigid_ortho(const double B[9], double w, const double y[12], int project, double *E, double *g,
                     double *H)
{
    double R[9], b[4][3], G[9]; /* G = RᵀR − I */
    crom_fem_tet_F(y, B, R);
    for (int a = 0; a < 3; a++)
        for (int c = 0; c < 3; c++) {
            double s = -(a == c);
            for (int i = 0; i < 3; i++)
                s += R[3 * i + a] * R[3 * i + c];
            G[3 * a + c] = s;
        }
    if (E) {
        double s = 0;
        for (int i = 0; i < 9; i++)
            s += G[i] * G[i];
        *E = w * s;
    }
    if (!g && !H)
        return 0;
    edge_weights(B, b);
    if (g) { /* ∂E/∂R = 4 w R G; ∂E/∂y_(k,i) = Σ_j (∂E/∂R)_ij b_k[j] */
        double P[9];
        for (int i = 0; i < 3; i++)
            for (int a = 0; a < 3; a++) {
                double s = 0;
                for (int c = 0; c < 3; c++)
                    s += R[3 * i + c] * G[3 * c + a];
                P[3 * i + a] = 4 * w * s;
            }
        for (int k = 0; k < 4; k++)
            for (int i = 0; i < 3; i++)
                g[3 * k + i] = P[3 * i] * b[k][0] + P[3 * i + 1] * b[k][1] + P[3 * i + 2] * b[k][2];
    }
    if (!H)
        return 0;
    /* ∂²E/∂R_ia∂R_jb = 4 w (δ_ij G_ab + R_ib R_ja + δ_ab (R Rᵀ)_ij) */
    double RRt[9], HR[81];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            RRt[3 * i + j] = R[3 * i] * R[3 * j] + R[3 * i + 1] * R[3 * j + 1] + R[3 * i + 2] * R[3 * j + 2];
    for (int i = 0; i < 3; i++)
        for (int a = 0; a < 3; a++)
            for (int j = 0; j < 3; j++)
                for (int bb = 0; bb < 3; bb++)
                    HR[9 * (3 * i + a) + 3 * j + bb] =
                        4 * w * ((i == j) * G[3 * a + bb] + R[3 * i + bb] * R[3 * j + a] + (a == bb) * RRt[3 * i + j]);
    /* H[(k,i),(l,j)] = Σ_a Σ_b b_k[a] HR[(i,a),(j,b)] b_l[b] */
    for (int k = 0; k < 4; k++)
        for (int i = 0; i < 3; i++)
            for (int l = 0; l < 4; l++)
                for (int j = 0; j < 3; j++) {
                    double s = 0;
                    for (int a = 0; a < 3; a++)
                        for (int bb = 0; bb < 3; bb++)
                            s += b[k][a] * HR[9 * (3 * i + a) + 3 * j + bb] * b[l][bb];
                    H[12 * (3 * k + i) + 3 * l + j] = s;
                }
    return project ? crom_sym_dense_project(H, 12) : 0;
}

void crom_rigid_pin(const double beta[4], double w, const double y[12], const double target[3], double *E,
                    double *g, double *H)
{
    double d[3];
    for (int i = 0; i < 3; i++)
        d[i] = beta[0] * y[i] + beta[1] * y[3 + i] + beta[2] * y[6 + i] + beta[3] * y[9 + i] - target[i];
    if (E)
        *E = 0.5 * w * (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    for (int k = 0; g && k < 4; k++)
        for (int i = 0; i < 3; i++)
            g[3 * k + i] = w * beta[k] * d[i];
    if (H) {
        memset(H, 0, sizeof(double) * 144);
        for (int k = 0; k < 4; k++)
            for (int l = 0; l < 4; l++)
                for (int i = 0; i < 3; i++)
                    H[12 * (3 * k + i) + 3 * l + i] = w * beta[k] * beta[l];
    }
}

void crom_rigid_joint(const double beta[4], const double gamma[4], double w, const double ya[12],
                      const double yb[12], double *E, double *g, double *H)
{
    double c[8], d[3];
    for (int k = 0; k < 4; k++) {
        c[k] = beta[k];
        c[4 + k] = -gamma[k];
    }
    for (int i = 0; i < 3; i++) {
        d[i] = 0;
        for (int k = 0; k < 4; k++)
            d[i] += beta[k] * ya[3 * k + i] - gamma[k] * yb[3 * k + i];
    }
    if (E)
        *E = 0.5 * w * (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    for (int k = 0; g && k < 8; k++)
        for (int i = 0; i < 3; i++)
            g[3 * k + i] = w * c[k] * d[i];
    if (H) {
        memset(H, 0, sizeof(double) * 576);
        for (int k = 0; k < 8; k++)
            for (int l = 0; l < 8; l++)
                for (int i = 0; i < 3; i++)
                    H[24 * (3 * k + i) + 3 * l + i] = w * c[k] * c[l];
    }
}

/* ------------------------------------------------------------ contacts */

/* φ = |d| − r for d the offset of q from a segment along x of half-length
 * h (h = 0: a point), with gradient and Hessian (a sphere, a capsule) */
static void seg_sdf(double r, double h, const double q[3], double *phi, double *g, double *H)
{
    int inside = fabs(q[0]) < h;
    double d[3] = {inside ? 0 : q[0] - (q[0] > 0 ? h : -h), q[1], q[2]};
    double n = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (n < 1e-300)
        n = 1e-300;
    *phi = n - r;
    for (int i = 0; g && i < 3; i++)
        g[i] = d[i] / n;
    for (int i = 0; H && i < 3; i++)
        for (int j = 0; j < 3; j++)
            H[3 * i + j] = ((i == j) - d[i] * d[j] / (n * n) - (inside && i == 0 && j == 0)) / n;
}

void crom_rigid_sdf(int shape, const double size[3], const double q[3], double *phi, double *g, double *H)
{
    double gg[3], HH[9];
    if (!g)
        g = gg;
    if (!H)
        H = HH;
    memset(H, 0, 9 * sizeof(double));
    if (shape == CROM_SCENE_BOX) {
        double e[3], out = 0;
        int k = 0;
        for (int i = 0; i < 3; i++) {
            e[i] = fabs(q[i]) - size[i] / 2;
            if (e[i] > e[k])
                k = i;
            out += e[i] > 0 ? e[i] * e[i] : 0;
        }
        if (e[k] <= 0) { /* inside: the nearest face's plane */
            *phi = e[k];
            g[0] = g[1] = g[2] = 0;
            g[k] = q[k] >= 0 ? 1 : -1;
            return;
        }
        *phi = sqrt(out);
        for (int i = 0; i < 3; i++)
            g[i] = e[i] > 0 ? (q[i] >= 0 ? 1 : -1) * e[i] / *phi : 0;
        return;
    }
    if (shape == CROM_SCENE_SPHERE || shape == CROM_SCENE_CAPSULE) {
        seg_sdf(size[0], shape == CROM_SCENE_CAPSULE ? size[1] / 2 : 0, q, phi, g, H);
        return;
    }
    /* a ring: ρ = a − R the signed in-plane distance from the stadium curve
     * (a the distance of (q_x, q_y) from the segment |x| <= h), and φ =
     * |(ρ, q_z)| − r */
    double r = size[0], R = size[1], h = size[2] / 2, ga[3], Ha[9];
    double q2[3] = {q[0], q[1], 0}, a;
    seg_sdf(0, h, q2, &a, ga, Ha); /* a = |s|, ga = ∇a, Ha = ∇²a (in-plane; its z row and column are dropped) */
    ga[2] = 0;
    for (int i = 0; i < 3; i++)
        Ha[3 * i + 2] = Ha[6 + i] = 0;
    double rho = a - R, u = sqrt(rho * rho + q[2] * q[2]);
    if (u < 1e-300)
        u = 1e-300;
    *phi = u - r;
    double m0 = rho / u, m1 = q[2] / u;
    for (int i = 0; i < 3; i++)
        g[i] = m0 * ga[i] + (i == 2 ? m1 : 0);
    /* ∇²φ = Jᵀ (I − m mᵀ) J / u + m0 ∇²ρ, J = [∇ρ; e_z] */
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double Ji[2] = {ga[i], i == 2}, Jj[2] = {ga[j], j == 2};
            double P[2][2] = {{1 - m0 * m0, -m0 * m1}, {-m0 * m1, 1 - m1 * m1}};
            double v = 0;
            for (int k = 0; k < 2; k++)
                for (int l = 0; l < 2; l++)
                    v += Ji[k] * P[k][l] * Jj[l];
            H[3 * i + j] = v / u + m0 * Ha[3 * i + j];
        }
}

int crom_rigid_contact(const double beta[4], const double Bq[9], int shape, const double size[3], double w,
                       const double ya[12], const double yb[12], int project, double *E, double *g, double *H)
{
    /* R'_ij = Σ_k yb_(k,i) b_k[j] (edge_weights of Bq), d = Σ β_m ya_m − ¼ Σ yb_m,
     * ℓ_j = Σ_i R'_ij d_i */
    double b[4][3], Rp[9] = {0}, d[3], l[3];
    edge_weights(Bq, b);
    for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 3; j++)
            for (int k = 0; k < 4; k++)
                Rp[3 * i + j] += yb[3 * k + i] * b[k][j];
        d[i] = 0;
        for (int m = 0; m < 4; m++)
            d[i] += beta[m] * ya[3 * m + i] - 0.25 * yb[3 * m + i];
    }
    for (int j = 0; j < 3; j++)
        l[j] = Rp[j] * d[0] + Rp[3 + j] * d[1] + Rp[6 + j] * d[2];
    double phi, gp[3], Hp[9];
    crom_rigid_sdf(shape, size, l, &phi, gp, Hp);
    if (E)
        *E = phi < 0 ? 0.5 * w * phi * phi : 0;
    if (g)
        memset(g, 0, 24 * sizeof(double));
    if (H)
        memset(H, 0, 576 * sizeof(double));
    if (phi >= 0 || (!g && !H))
        return 0;
    /* J[j][c] = ∂ℓ_j/∂y_c over the 24 coordinates c = 3k + i (ya, then yb):
     * ∂ℓ_j/∂ya_(m,i) = R'_ij β_m, ∂ℓ_j/∂yb_(k,i) = b_k[j] d_i − ¼ R'_ij */
    double J[3][24];
    for (int j = 0; j < 3; j++)
        for (int k = 0; k < 4; k++)
            for (int i = 0; i < 3; i++) {
                J[j][3 * k + i] = Rp[3 * i + j] * beta[k];
                J[j][12 + 3 * k + i] = b[k][j] * d[i] - 0.25 * Rp[3 * i + j];
            }
    double s[24]; /* ∇_y φ = Jᵀ ∇φ */
    for (int c = 0; c < 24; c++)
        s[c] = J[0][c] * gp[0] + J[1][c] * gp[1] + J[2][c] * gp[2];
    for (int c = 0; g && c < 24; c++)
        g[c] = w * phi * s[c];
    if (!H)
        return 0;
    /* H = w (s sᵀ + φ (Jᵀ ∇²φ J + Σ_j ∂φ/∂ℓ_j ∇²ℓ_j)); ∇²ℓ_j couples
     * yb_(k,i) with ya_(m,i) by b_k[j] β_m and yb_(k,i) with yb_(n,i) by
     * −¼ (b_k[j] + b_n[j]) */
    double HJ[3][24];
    for (int a = 0; a < 3; a++)
        for (int c = 0; c < 24; c++)
            HJ[a][c] = Hp[3 * a] * J[0][c] + Hp[3 * a + 1] * J[1][c] + Hp[3 * a + 2] * J[2][c];
    for (int p = 0; p < 24; p++)
        for (int q = 0; q < 24; q++)
            H[24 * p + q] = w * (s[p] * s[q] + phi * (J[0][p] * HJ[0][q] + J[1][p] * HJ[1][q] + J[2][p] * HJ[2][q]));
    for (int k = 0; k < 4; k++) {
        double cb = gp[0] * b[k][0] + gp[1] * b[k][1] + gp[2] * b[k][2]; /* Σ_j ∂φ/∂ℓ_j b_k[j] */
        for (int i = 0; i < 3; i++) {
            int pb = 12 + 3 * k + i;
            for (int m = 0; m < 4; m++) {
                double v = w * phi * cb * beta[m];
                H[24 * pb + 3 * m + i] += v;
                H[24 * (3 * m + i) + pb] += v;
                double cn = gp[0] * b[m][0] + gp[1] * b[m][1] + gp[2] * b[m][2];
                H[24 * pb + 12 + 3 * m + i] += -0.25 * w * phi * (cb + cn);
            }
        }
    }
    return project ? crom_sym_dense_project(H, 24) : 0;
}

/* ------------------------------------------------------------- sliders */

void crom_rigid_axis_weights(const double B[9], const double a0[3], double c[4])
{
    double b[4][3];
    edge_weights(B, b);
    for (int k = 0; k < 4; k++)
        c[k] = b[k][0] * a0[0] + b[k][1] * a0[1] + b[k][2] * a0[2];
}

int crom_rigid_slider(const double beta[4], const double gamma[4], const double c[4], double w, const double ya[12],
                      const double yb[12], int project, double *E, double *g, double *H)
{
    /* in the six variables (d, u): e = d − s u, s = u·d; E = ½ w |e|² */
    double d[3], u[3], e[3], s = 0, ue = 0;
    for (int i = 0; i < 3; i++) {
        d[i] = u[i] = 0;
        for (int k = 0; k < 4; k++) {
            d[i] += gamma[k] * yb[3 * k + i] - beta[k] * ya[3 * k + i];
            u[i] += c[k] * ya[3 * k + i];
        }
        s += u[i] * d[i];
    }
    for (int i = 0; i < 3; i++) {
        e[i] = d[i] - s * u[i];
        ue += u[i] * e[i];
    }
    if (E)
        *E = 0.5 * w * (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
    /* ∂e/∂d = I − u uᵀ, ∂e/∂u = −(s I + u dᵀ): ∇_d E = w (e − u (u·e)),
     * ∇_u E = −w (s e + (u·e) d) */
    double gd[3], gu[3];
    for (int i = 0; i < 3; i++) {
        gd[i] = w * (e[i] - u[i] * ue);
        gu[i] = -w * (s * e[i] + ue * d[i]);
    }
    /* y coordinate (frame a vertex k, component i) moves d_i by −β_k and u_i
     * by c_k; (frame b vertex k, component i) moves d_i by γ_k */
    for (int k = 0; g && k < 4; k++)
        for (int i = 0; i < 3; i++) {
            g[3 * k + i] = -beta[k] * gd[i] + c[k] * gu[i];
            g[12 + 3 * k + i] = gamma[k] * gd[i];
        }
    if (!H)
        return 0;
    /* the 6×6 Hessian in (d, u): w (Jᵀ J + Σ_i e_i ∇²e_i), J = [∂e/∂d, ∂e/∂u];
     * Σ e_i ∂²e_i/∂d_j∂u_k = −(δ_jk (u·e) + u_j e_k), Σ e_i ∂²e_i/∂u_j∂u_k =
     * −(d_j e_k + d_k e_j), the d-d block 0 */
    double J[3][6], H6[6][6];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            J[i][j] = (i == j) - u[i] * u[j];
            J[i][3 + j] = -(s * (i == j) + u[i] * d[j]);
        }
    for (int p = 0; p < 6; p++)
        for (int q = 0; q < 6; q++) {
            double v = J[0][p] * J[0][q] + J[1][p] * J[1][q] + J[2][p] * J[2][q];
            if (p < 3 && q >= 3)
                v -= (p == q - 3) * ue + u[p] * e[q - 3];
            else if (p >= 3 && q < 3)
                v -= (q == p - 3) * ue + u[q] * e[p - 3];
            else if (p >= 3)
                v -= d[p - 3] * e[q - 3] + d[q - 3] * e[p - 3];
            H6[p][q] = w * v;
        }
    /* through the linear maps: coordinate (frame, vertex k, component i) has
     * weights (wd, wu) on d_i and u_i */
    for (int P = 0; P < 24; P++)
        for (int Q = 0; Q < 24; Q++) {
            int kp = (P % 12) / 3, ip = P % 3, kq = (Q % 12) / 3, iq = Q % 3;
            double dp = P < 12 ? -beta[kp] : gamma[kp], up = P < 12 ? c[kp] : 0;
            double dq = Q < 12 ? -beta[kq] : gamma[kq], uq = Q < 12 ? c[kq] : 0;
            H[24 * P + Q] = dp * dq * H6[ip][iq] + dp * uq * H6[ip][3 + iq] + up * dq * H6[3 + ip][iq] +
                            up * uq * H6[3 + ip][3 + iq];
        }
    return project ? crom_sym_dense_project(H, 24) : 0;
}
