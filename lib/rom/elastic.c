/* elastic.c — the elastic energy of a linear subspace over a cubature, in
 * the space of deformation gradients (see elastic.h). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <cblas.h>

#include "base/err.h"
#include "rom/elastic.h"

void crom_elastic_free(crom_elastic *e)
{
    free(e->G);
    free(e->F0);
    free(e->wV);
    free(e->Y);
    free(e->A);
    free(e->Hb);
    free(e->Fq);
    free(e->Pm);
    memset(e, 0, sizeof *e);
}

/* ∂N_a/∂X_j of the four corners of a tet from its Dm⁻¹ (fem.c's F = Ds Dm⁻¹,
 * Ds = [x1 − x0, x2 − x0, x3 − x0]): dN[a][j] */
static void shape_gradients(const double Dminv[9], double dN[4][3])
{
    for (int j = 0; j < 3; j++) {
        dN[0][j] = 0;
        for (int a = 1; a < 4; a++) {
            dN[a][j] = Dminv[3 * (a - 1) + j];
            dN[0][j] -= dN[a][j];
        }
    }
}

/* 1 if W_v = I₃ ⊗ ψ_vᵀ (r = 3S) at every corner of every cubature tet:
 * row c of W_v is ψ_v in columns [cS, (c+1)S) and zero elsewhere */
static int component_block(const crom_cubature *c)
{
    int r = c->r;
    if (r % 3 || r < 3)
        return 0;
    int S = r / 3;
    for (int k = 0; k < c->k; k++) {
        const int *t = c->mesh.tets + 4 * (size_t)c->elem[k];
        for (int a = 0; a < 4; a++) {
            const double *Wv = c->W + (size_t)t[a] * 3 * r;
            for (int comp = 0; comp < 3; comp++)
                for (int col = 0; col < r; col++) {
                    double w = Wv[comp * r + col], want = col / S == comp ? Wv[col % S] : 0;
                    if (w != want)
                        return 0;
                }
        }
    }
    return 1;
}

int crom_elastic_init(crom_elastic *e, const crom_cubature *c)
{
    memset(e, 0, sizeof *e);
    e->r = c->r;
    e->k = c->k;
    e->block = component_block(c);
    e->S = e->block ? c->r / 3 : 0;
    e->m = e->block ? e->S : c->r;
    e->rows = e->block ? 3 : 9;
    size_t per = (size_t)e->rows * e->m, k = (size_t)(c->k > 0 ? c->k : 1);
    e->G = crom_calloc(k * per, sizeof(double));
    /* block: Y holds the three blocks (c, d >= c) of a block row side by side */
    e->Y = crom_malloc(sizeof(double) * k * per * (e->block ? 3 : 1));
    e->F0 = crom_malloc(sizeof(double) * 9 * k);
    e->wV = crom_malloc(sizeof(double) * k);
    e->A = crom_malloc(sizeof(double) * 81 * k);
    e->Hb = crom_malloc(sizeof(double) * (size_t)(e->block ? 3 * e->S * e->S : 1));
    e->Fq = crom_malloc(sizeof(double) * 9 * k);
    e->Pm = crom_malloc(sizeof(double) * 9 * k);
    if (!e->G || !e->Y || !e->F0 || !e->wV || !e->A || !e->Hb || !e->Fq || !e->Pm) {
        crom_elastic_free(e);
        return CROM_EINTERNAL;
    }
    int r = c->r;
    for (int q = 0; q < c->k; q++) {
        const int *t = c->mesh.tets + 4 * (size_t)c->elem[q];
        double dN[4][3];
        shape_gradients(c->Dminv + 9 * (size_t)q, dN);
        e->wV[q] = c->weight[q] * c->vol[q];
        double *F0 = e->F0 + 9 * (size_t)q, *G = e->G + (size_t)q * per;
        memset(F0, 0, 9 * sizeof(double));
        for (int a = 0; a < 4; a++) {
            const double *X = c->mesh.X + 3 * (size_t)t[a], *Wv = c->W + (size_t)t[a] * 3 * r;
            for (int comp = 0; comp < 3; comp++)
                for (int j = 0; j < 3; j++)
                    F0[3 * comp + j] += dN[a][j] * X[comp];
            if (e->block) /* B[j][s] = Σ_a ∂N_a/∂X_j ψ_a[s], ψ_a = row 0 of W_a */
                for (int j = 0; j < 3; j++)
                    cblas_daxpy(e->S, dN[a][j], Wv, 1, G + (size_t)j * e->S, 1);
            else /* G[3c + j][:] = Σ_a ∂N_a/∂X_j W_a[c][:] */
                for (int comp = 0; comp < 3; comp++)
                    for (int j = 0; j < 3; j++)
                        cblas_daxpy(r, dN[a][j], Wv + (size_t)comp * r, 1, G + (size_t)(3 * comp + j) * r, 1);
        }
    }
    return 0;
}

/* G q of every tet, in one product over the cubature: Fq[9t + 3c + j] =
 * (G_t q)[3c + j]; for a block basis Fq[(3t + j) 3 + c] = (B_t q_c)[j], with
 * q_c = q[cS, (c+1)S) the coordinates of component c */
static void all_Gq(crom_elastic *e, const double *q)
{
    int K = e->k;
    if (e->block) /* three products B q_c: faster than one of three columns */
        for (int c = 0; c < 3; c++)
            cblas_dgemv(CblasRowMajor, CblasNoTrans, 3 * K, e->S, 1.0, e->G, e->S, q + (size_t)c * e->S, 1, 0.0,
                        e->Fq + c, 3);
    else
        cblas_dgemv(CblasRowMajor, CblasNoTrans, 9 * K, e->r, 1.0, e->G, e->r, q, 1, 0.0, e->Fq, 1);
}

/* F of tet t from all_Gq's products */
static void tet_F(const crom_elastic *e, int t, double F[9])
{
    const double *F0 = e->F0 + 9 * (size_t)t, *Fq = e->Fq + 9 * (size_t)t;
    if (e->block)
        for (int c = 0; c < 3; c++)
            for (int j = 0; j < 3; j++)
                F[3 * c + j] = F0[3 * c + j] + Fq[3 * j + c];
    else
        for (int i = 0; i < 9; i++)
            F[i] = F0[i] + Fq[i];
}

/* H += Σ_t G_tᵀ A_t G_t (A_t = w V ∂P/∂F of tet t, in e->A): one product
 * over all tets, or for a block basis one per block row c, Bᵀ [Y_cc Y_c,c+1
 * … Y_c2] over all tets with Y_cd = A_t[c rows][d cols] B_t, the blocks
 * below the diagonal being the transposes of those above */
static void add_hessian(crom_elastic *e, double *H)
{
    int r = e->r, K = e->k;
    if (!e->block) {
        for (int t = 0; t < K; t++) /* Y_t = A_t G_t */
            cblas_dgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, 9, r, 9, 1.0, e->A + 81 * (size_t)t, 9,
                        e->G + (size_t)t * 9 * r, r, 0.0, e->Y + (size_t)t * 9 * r, r);
        cblas_dgemm(CblasRowMajor, CblasTrans, CblasNoTrans, r, r, 9 * K, 1.0, e->G, r, e->Y, r, 1.0, H, r);
        return;
    }
    int S = e->S;
    for (int c = 0; c < 3; c++) {
        int nb = 3 - c, ld = nb * S; /* blocks d = c..2 side by side: Y [3K][nb S] */
        for (int t = 0; t < K; t++) {
            const double *A = e->A + 81 * (size_t)t, *B = e->G + (size_t)t * 3 * S;
            for (int d = c; d < 3; d++)
                for (int j = 0; j < 3; j++) {
                    double *y = e->Y + ((size_t)3 * t + j) * ld + (size_t)(d - c) * S;
                    const double *a = A + 9 * (3 * c + j) + 3 * d; /* row j of block (c, d) */
                    for (int s = 0; s < S; s++)
                        y[s] = a[0] * B[s] + a[1] * B[S + s] + a[2] * B[2 * S + s];
                }
        }
        cblas_dgemm(CblasRowMajor, CblasTrans, CblasNoTrans, S, ld, 3 * K, 1.0, e->G, S, e->Y, ld, 0.0, e->Hb, ld);
        for (int i = 0; i < S; i++)
            for (int d = c; d < 3; d++)
                for (int j = 0; j < S; j++) {
                    double v = e->Hb[(size_t)i * ld + (size_t)(d - c) * S + j];
                    H[(size_t)(c * S + i) * r + d * S + j] += v;
                    if (d != c)
                        H[(size_t)(d * S + j) * r + c * S + i] += v;
                }
    }
}

int crom_elastic_eval(crom_elastic *e, const crom_material *mat, const double *q, int project, double *E,
                      double *g, double *H)
{
    double Et = 0;
    all_Gq(e, q);
    for (int t = 0; t < e->k; t++) {
        double F[9], P[9], wV = e->wV[t];
        const crom_material *m = e->kmat ? e->kmat[t] : mat;
        tet_F(e, t, F);
        double psi = crom_fem_psi(m, F);
        if (!isfinite(psi))
            return crom_err(CROM_EDATA, "cubature tet %d: non-finite elastic energy", t);
        Et += wV * psi;
        if (g) { /* w V P, laid out as Fq */
            double *Pm = e->Pm + 9 * (size_t)t;
            crom_fem_pk1(m, F, P);
            if (e->block)
                for (int c = 0; c < 3; c++)
                    for (int j = 0; j < 3; j++)
                        Pm[3 * j + c] = wV * P[3 * c + j];
            else
                for (int i = 0; i < 9; i++)
                    Pm[i] = wV * P[i];
        }
        if (H) {
            double *A = e->A + 81 * (size_t)t;
            crom_fem_dPdF(m, F, project, A);
            for (int i = 0; i < 81; i++) {
                A[i] *= wV;
                if (!isfinite(A[i]))
                    return crom_err(CROM_EDATA, "cubature tet %d: non-finite elastic Hessian", t);
            }
        }
    }
    if (g && e->k > 0) { /* g += Σ_t G_tᵀ w V vec P: g_c += Σ_t B_tᵀ (w V P_t)[c][:] for a block basis */
        if (e->block)
            for (int c = 0; c < 3; c++)
                cblas_dgemv(CblasRowMajor, CblasTrans, 3 * e->k, e->S, 1.0, e->G, e->S, e->Pm + c, 3, 1.0,
                            g + (size_t)c * e->S, 1);
        else
            cblas_dgemv(CblasRowMajor, CblasTrans, 9 * e->k, e->r, 1.0, e->G, e->r, e->Pm, 1, 1.0, g, 1);
    }
    if (g)
        for (int i = 0; i < e->r; i++)
            if (!isfinite(g[i]))
                return crom_err(CROM_EDATA, "non-finite elastic force");
    if (H && e->k > 0)
        add_hessian(e, H);
    *E = Et;
    return 0;
}
