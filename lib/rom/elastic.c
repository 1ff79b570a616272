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
    e->Y = crom_malloc(sizeof(double) * k * per);
    e->F0 = crom_malloc(sizeof(double) * 9 * k);
    e->wV = crom_malloc(sizeof(double) * k);
    e->A = crom_malloc(sizeof(double) * 81 * k);
    e->Hb = crom_malloc(sizeof(double) * (size_t)(e->block ? e->S * e->S : 1));
    if (!e->G || !e->Y || !e->F0 || !e->wV || !e->A || !e->Hb) {
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

/* F of tet q at latent q (vec F = F0 + G q, or per component with B) */
static void tet_F(const crom_elastic *e, int t, const double *q, double F[9])
{
    const double *G = e->G + (size_t)t * e->rows * e->m;
    memcpy(F, e->F0 + 9 * (size_t)t, 9 * sizeof(double));
    if (e->block) {
        for (int c = 0; c < 3; c++)
            for (int j = 0; j < 3; j++)
                F[3 * c + j] += cblas_ddot(e->S, G + (size_t)j * e->S, 1, q + (size_t)c * e->S, 1);
    } else {
        cblas_dgemv(CblasRowMajor, CblasNoTrans, 9, e->r, 1.0, G, e->r, q, 1, 1.0, F, 1);
    }
}

/* H += Σ_t G_tᵀ A_t G_t (A_t = w V ∂P/∂F of tet t, in e->A): one product
 * over all tets, or six per-component blocks for a block basis */
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
    for (int c = 0; c < 3; c++)
        for (int d = c; d < 3; d++) {
            /* Y_t = A_t[c-block rows][d-block cols] B_t: [3][S] */
            for (int t = 0; t < K; t++) {
                const double *A = e->A + 81 * (size_t)t, *B = e->G + (size_t)t * 3 * S;
                double Acd[9];
                for (int j = 0; j < 3; j++)
                    for (int l = 0; l < 3; l++)
                        Acd[3 * j + l] = A[9 * (3 * c + j) + 3 * d + l];
                cblas_dgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, 3, S, 3, 1.0, Acd, 3, B, S, 0.0,
                            e->Y + (size_t)t * 3 * S, S);
            }
            /* block (c, d) of H += Bᵀ Y over all tets, and its transpose at (d, c) */
            cblas_dgemm(CblasRowMajor, CblasTrans, CblasNoTrans, S, S, 3 * K, 1.0, e->G, S, e->Y, S, 0.0, e->Hb,
                        S);
            for (int i = 0; i < S; i++)
                for (int j = 0; j < S; j++) {
                    H[(size_t)(c * S + i) * r + d * S + j] += e->Hb[i * S + j];
                    if (d != c)
                        H[(size_t)(d * S + j) * r + c * S + i] += e->Hb[i * S + j];
                }
        }
}

int crom_elastic_eval(crom_elastic *e, const crom_material *mat, const double *q, int project, double *E,
                      double *g, double *H)
{
    double Et = 0;
    for (int t = 0; t < e->k; t++) {
        double F[9], P[9], wV = e->wV[t];
        tet_F(e, t, q, F);
        double psi = crom_fem_psi(mat, F);
        if (!isfinite(psi))
            return crom_err(CROM_EDATA, "cubature tet %d: non-finite elastic energy", t);
        Et += wV * psi;
        if (g) {
            crom_fem_pk1(mat, F, P);
            const double *G = e->G + (size_t)t * e->rows * e->m;
            if (e->block) /* g[cS + s] += w V Σ_j B[j][s] P[c][j] */
                for (int c = 0; c < 3; c++)
                    cblas_dgemv(CblasRowMajor, CblasTrans, 3, e->S, wV, G, e->S, P + 3 * c, 1, 1.0,
                                g + (size_t)c * e->S, 1);
            else
                cblas_dgemv(CblasRowMajor, CblasTrans, 9, e->r, wV, G, e->r, P, 1, 1.0, g, 1);
        }
        if (H) {
            double *A = e->A + 81 * (size_t)t;
            crom_fem_dPdF(mat, F, project, A);
            for (int i = 0; i < 81; i++) {
                A[i] *= wV;
                if (!isfinite(A[i]))
                    return crom_err(CROM_EDATA, "cubature tet %d: non-finite elastic Hessian", t);
            }
        }
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
