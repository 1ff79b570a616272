/* dffield.c — a continuous data-free subspace x(X, z) = X + W(X) φ(z),
 * trained from the energy integrated by a random cubature of the mesh
 * (crom-fitfield --objective field; see dffield.h). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <cblas.h>

#include "base/clock.h"
#include "base/err.h"
#include "base/rng.h"
#include "datafree/dffield.h"
#include "datafree/dfloss.h"

void crom_dffield_ctx_free(crom_dffield_ctx *c)
{
    if (!c)
        return;
    crom_fem_free(&c->fem);
    free(c->mats);
    free(c->tmat);
    crom_nn_ws_free(&c->wsW);
    crom_nn_ws_free(&c->wsP);
    crom_dfloss_cub_free(&c->cub);
    void *bufs[] = {c->xf, c->F, c->Phi, c->zf, c->gu, c->dF, c->dPhi, c->dFf, c->dPf, c->E, c->bad, c->G, c->S,
                    c->tmp, c->xb, c->pinX, c->mask, c->triX, c->tg};
    for (size_t i = 0; i < sizeof bufs / sizeof *bufs; i++)
        free(bufs[i]);
    memset(c, 0, sizeof *c);
}

/* The pin mask: the pinned part of the training mesh, the mask's length ℓ
 * (o->pin_length, or twice the mean edge) and s(d(X_v)/ℓ) at every vertex. */
static int pin_mask(crom_dffield_ctx *c, const crom_datafree_problem *p, const crom_datafree_opts *o)
{
    const crom_mesh *m = p->mesh;
    int nv = m->nv, rc = crom_dfloss_pinned_part(m, p->fixed, 0, 0, &c->npins, &c->pinX, &c->ntri, &c->triX);
    if (rc)
        return rc;
    c->pin_length = o->pin_length;
    if (!(c->pin_length > 0)) { /* twice the mean edge */
        double s = 0;
        for (int k = 0; k < m->nt; k++)
            for (int a = 0; a < 4; a++)
                for (int b = a + 1; b < 4; b++) {
                    const double *xa = m->X + 3 * (size_t)m->tets[4 * (size_t)k + a];
                    const double *xb = m->X + 3 * (size_t)m->tets[4 * (size_t)k + b];
                    s += sqrt((xa[0] - xb[0]) * (xa[0] - xb[0]) + (xa[1] - xb[1]) * (xa[1] - xb[1]) +
                              (xa[2] - xb[2]) * (xa[2] - xb[2]));
                }
        c->pin_length = 2 * s / (6.0 * (m->nt ? m->nt : 1));
    }
    c->mask = crom_malloc(sizeof(double) * (size_t)(nv ? nv : 1));
    if (!c->mask)
        return CROM_EINTERNAL;
    for (int v = 0; v < nv; v++)
        c->mask[v] = crom_model_pin_mask(m->X + 3 * (size_t)v, c->npins, c->pinX, c->ntri, c->triX, c->pin_length);
    return 0;
}

/* The work space: the networks' for 4 maxtets vertices and the batch, the
 * drawn tets, and the arrays of the loss. */
static int buffers(crom_dffield_ctx *c, int maxbatch)
{
    int r = c->r, nv = c->P.mesh->nv, rc;
    c->maxrows = 4 * c->maxtets;
    /* rows of φ: the batch, the tangent samples and z = 0 */
    size_t R = (size_t)c->maxrows, B = (size_t)maxbatch + c->B0 + 1, P = (size_t)c->p;
    if ((c->W && (rc = crom_nn_ws_init(&c->wsW, c->W, c->maxrows, 1))) ||
        (rc = crom_nn_ws_init(&c->wsP, c->phi, (int)B, 1)) ||
        (rc = crom_dfloss_cub_init(&c->cub, nv, c->maxrows)))
        return rc;
    c->xf = crom_malloc(sizeof(float) * 3 * R);
    c->F = crom_malloc(sizeof(double) * 3 * R * P);
    c->Phi = crom_malloc(sizeof(double) * B * P);
    c->zf = crom_malloc(sizeof(float) * B * (size_t)r);
    c->gu = crom_malloc(sizeof(double) * B * 3 * R);
    c->dF = crom_malloc(sizeof(double) * 3 * R * P);
    c->dPhi = crom_malloc(sizeof(double) * B * P);
    c->dFf = crom_malloc(sizeof(float) * 3 * R * P);
    c->dPf = crom_malloc(sizeof(float) * B * P);
    c->E = crom_malloc(sizeof(double) * B);
    c->bad = crom_malloc(sizeof(int) * B);
    c->G = crom_malloc(sizeof(double) * P * P);
    c->S = crom_malloc(sizeof(double) * P * P);
    size_t trows = 3 * R > B + 1 ? 3 * R : B + 1; /* (also the isometry's [B][p] scratch) */
    c->tmp = crom_malloc(sizeof(double) * trows * P);
    c->xb = crom_malloc(sizeof(double) * (size_t)c->nthreads * 3 * R);
    c->tg = crom_malloc(sizeof(double) * (3 * (size_t)r * r + r));
    if (!c->tg || !c->xf || !c->F || !c->Phi || !c->zf || !c->gu || !c->dF || !c->dPhi || !c->dFf || !c->dPf || !c->E ||
        !c->bad || !c->G || !c->S || !c->tmp || !c->xb)
        return CROM_EINTERNAL;
    return 0;
}

int crom_dffield_ctx_init(crom_dffield_ctx *c, const crom_datafree_problem *p, const crom_datafree_opts *o,
                          const crom_nn_mlp *W, const double *basis, const crom_nn_mlp *phi, int maxbatch,
                          int maxtets)
{
    memset(c, 0, sizeof *c);
    c->P = *p;
    c->o = *o;
    c->W = W;
    c->basis = basis;
    c->phi = phi;
    const crom_nn_spec *ps = &phi->spec;
    int pf = ps->width[ps->nlayers];
    if (!W == !basis)
        return crom_err(CROM_EUSAGE, "the features need a field W(X) or a fixed basis, not %s",
                        W ? "both" : "neither");
    if (W && (W->spec.width[0] != 3 || W->spec.width[W->spec.nlayers] != 3 * pf))
        return crom_err(CROM_EUSAGE, "the feature field goes %d -> %d, expected 3 -> 3p = %d", W->spec.width[0],
                        W->spec.width[W->spec.nlayers], 3 * pf);
    if (maxbatch < 2 || maxtets < 1)
        return crom_err(CROM_EUSAGE, "batch of %d samples, %d tets", maxbatch, maxtets);
    if (!(o->sigma > 0))
        return crom_err(CROM_EUSAGE, "sigma must be positive");
    c->r = ps->width[0];
    c->p = pf;
    c->maxbatch = maxbatch;
    c->B0 = o->tangent_weight > 0 ? c->r : 0; /* the secants along the r axes */
    if (c->B0 && !(o->tangent_floor > 0 && o->tangent_floor <= 1))
        return crom_err(CROM_EUSAGE, "--tangent-floor %g: the collapse floor must be in (0, 1]", o->tangent_floor);
    c->maxtets = maxtets;
    c->nthreads = crom_dftrain_threads(o->threads);
    int rc = crom_fem_init(&c->fem, p->mesh, &p->mat);
    if (!rc)
        rc = crom_dfloss_materials(&c->fem, p->materials, p->mesh, &c->mats, &c->tmat);
    if (!rc && W) /* (a fixed basis holds the pins itself) */
        rc = pin_mask(c, p, o);
    if (!rc)
        rc = buffers(c, maxbatch);
    if (rc) {
        crom_dffield_ctx_free(c);
        return rc;
    }
    c->mass = c->fem.total_mass;
    c->Eref = p->mat.E * c->fem.volume;
    if (basis) { /* the fixed Gram matrix BᵀMB / m, upper triangle */
        memset(c->G, 0, sizeof(double) * (size_t)c->p * c->p);
        for (int v = 0; v < p->mesh->nv; v++)
            cblas_dsyrk(CblasRowMajor, CblasUpper, CblasTrans, c->p, 3, c->fem.mass[v] / c->mass,
                        basis + (size_t)v * 3 * c->p, c->p, 1.0, c->G, c->p);
    }
    return 0;
}

/* W at the drawn vertices, masked at the pins: F [ns][3][p], i.e. a
 * [3ns][p] matrix; φ of the batch, of the tangent samples and of z = 0,
 * the anchor (lib/rom/map.h): the samples are taken relative to it, Φ_b =
 * φ(z_b) − φ(0). */
static int outputs(crom_dffield_ctx *c, int B, const double *z)
{
    int r = c->r, p = c->p, ns = c->cub.ns, Bt = B + c->B0, rc;
    const double *X = c->P.mesh->X;
    if (c->basis) { /* the fixed basis at the drawn vertices */
        for (int i = 0; i < ns; i++)
            memcpy(c->F + (size_t)i * 3 * p, c->basis + (size_t)c->cub.vs[i] * 3 * p, sizeof(double) * 3 * (size_t)p);
    } else {
        for (int i = 0; i < ns; i++)
            for (int d = 0; d < 3; d++)
                c->xf[3 * i + d] = (float)X[3 * (size_t)c->cub.vs[i] + d];
        if ((rc = crom_nn_mlp_forward(c->W, &c->wsW, ns, c->xf, NULL)))
            return rc;
        const float *Ff = crom_nn_ws_output(&c->wsW);
        for (size_t i = 0; i < (size_t)3 * ns * p; i++)
            c->F[i] = c->mask[c->cub.vs[i / (3 * (size_t)p)]] * Ff[i];
    }
    for (int i = 0; i < Bt * r; i++)
        c->zf[i] = (float)z[i];
    memset(c->zf + (size_t)Bt * r, 0, sizeof(float) * (size_t)r);
    if ((rc = crom_nn_mlp_forward(c->phi, &c->wsP, Bt + 1, c->zf, NULL)))
        return rc;
    const float *Pf = crom_nn_ws_output(&c->wsP), *P0 = Pf + (size_t)Bt * p;
    for (int i = 0; i < Bt * p; i++)
        c->Phi[i] = (double)Pf[i] - (double)P0[i % p];
    return 0;
}

/* The displacements U = ρ Φ Fᵀ [B][3ns] of the batch at the drawn
 * vertices, their energies over the drawn tets plus gravity, −Σ m g·u,
 * and the gradients gu (in place of U). */
static void energies(crom_dffield_ctx *c, int B, double rho, int K, const int *tets)
{
    int p = c->p, ns = c->cub.ns, m3 = 3 * ns;
    const double *X = c->P.mesh->X, *g = c->P.gravity, *mloc = c->cub.mloc;
    cblas_dgemm(CblasRowMajor, CblasNoTrans, CblasTrans, B, m3, p, rho, c->Phi, p, c->F, p, 0.0, c->gu, m3);
#pragma omp parallel for num_threads(c->nthreads) schedule(static)
    for (int b = 0; b < B; b++) {
        double *u = c->xb + (size_t)crom_dfloss_thread() * 3 * c->maxrows, *gb = c->gu + (size_t)b * m3, Eb;
        memcpy(u, gb, sizeof(double) * (size_t)m3);
        memset(gb, 0, sizeof(double) * (size_t)m3);
        c->bad[b] = crom_dfloss_tets(&c->fem, K, tets, c->cub.wK, X, u, c->cub.loc, &Eb, gb);
        for (int i = 0; i < ns; i++) /* gravity: −Σ m g·u */
            for (int d = 0; d < 3; d++) {
                Eb -= mloc[i] * g[d] * u[3 * i + d];
                gb[3 * i + d] -= mloc[i] * g[d];
            }
        c->E[b] = Eb;
    }
}

/* The energy term 1/B Σ_b E_b / E_ref: dL/dΦ = ρ s GU F, dL/dF = ρ s GUᵀ Φ
 * (none for the tangent samples). */
static void energy_term(crom_dffield_ctx *c, int B, double rho, double *obj, double *Em)
{
    int p = c->p, m3 = 3 * c->cub.ns;
    double scale = 1.0 / (B * c->Eref);
    for (int b = 0; b < B; b++) {
        *Em += c->E[b] / B;
        *obj += c->E[b] * scale;
    }
    cblas_dgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, B, p, m3, rho * scale, c->gu, m3, c->F, p, 0.0, c->dPhi,
                p);
    if (!c->basis) /* (no field to train over a fixed basis) */
        cblas_dgemm(CblasRowMajor, CblasTrans, CblasNoTrans, m3, p, B, rho * scale, c->gu, m3, c->Phi, p, 0.0, c->dF,
                    p);
    memset(c->dPhi + (size_t)B * p, 0, sizeof(double) * (size_t)c->B0 * p);
}

/* 1/m̂, the factor of G in D²; over a fixed basis G is the exact mean over
 * the whole body already (1). */
static double gram_scale(const crom_dffield_ctx *c) { return c->basis ? 1.0 : 1.0 / c->cub.mhat; }

/* The mass-weighted Gram matrix of the features G = Σ_v m̂_v F_vᵀ F_v (both
 * triangles), and S = 0 for the terms that use it to add to. Over a fixed
 * basis G is fixed: BᵀMB / m over the whole body (ctx_init). */
static void gram(crom_dffield_ctx *c)
{
    if (c->basis)
        return;
    int p = c->p, m3 = 3 * c->cub.ns;
    for (int i = 0; i < m3; i++) {
        double s = sqrt(c->cub.mloc[i / 3]);
        for (int j = 0; j < p; j++)
            c->tmp[(size_t)i * p + j] = s * c->F[(size_t)i * p + j];
    }
    cblas_dsyrk(CblasRowMajor, CblasUpper, CblasTrans, p, m3, 1.0, c->tmp, p, 0.0, c->G, p);
    for (int i = 0; i < p; i++)
        for (int j = 0; j < i; j++)
            c->G[i * p + j] = c->G[j * p + i];
    memset(c->S, 0, sizeof(double) * (size_t)p * p);
}

/* The isometry over the pairs: λ mean_{b<c} ℓ², ℓ = ½ log D² − log(σ |z_b −
 * z_c|), D² = ΔΦᵀ G ΔΦ / m̂; its gradient in dΦ and (through G, for a
 * trained W) in S. GΦ_b / m̂ of every sample is formed first (one product),
 * so a pair costs O(p) plus, for a trained W, the rank-one update of S. */
static void isometry_term(crom_dffield_ctx *c, int B, const double *z, double *obj, double *pen)
{
    int r = c->r, p = c->p, Bt = B + c->B0;
    double npairs = 0.5 * B * (B - 1), lam = c->o.lambda, ls = log(c->o.sigma), im = gram_scale(c);
    double *dphi = c->tmp, *GP = c->tmp + p; /* scratch: tmp is free again ([Bt][p] after dphi) */
    cblas_dsymm(CblasRowMajor, CblasRight, CblasUpper, Bt, p, im, c->G, p, c->Phi, p, 0.0, GP, p);
    for (int b = 0; b < B; b++)
        for (int e = b + 1; e < B; e++) {
            double dz = 0;
            for (int k = 0; k < r; k++) {
                double d = z[(size_t)b * r + k] - z[(size_t)e * r + k];
                dz += d * d;
            }
            const double *pb = c->Phi + (size_t)b * p, *pe = c->Phi + (size_t)e * p;
            const double *gb = GP + (size_t)b * p, *ge = GP + (size_t)e * p;
            double D2 = 0;
            for (int j = 0; j < p; j++) {
                dphi[j] = pb[j] - pe[j];
                D2 += dphi[j] * (gb[j] - ge[j]);
            }
            if (!(D2 > 0) || !(dz > 0))
                continue;
            double l = 0.5 * log(D2) - 0.5 * log(dz) - ls;
            *pen += l * l / npairs;
            *obj += lam * l * l / npairs;
            double coef = lam * l / (npairs * D2); /* dL/dD² */
            double *db = c->dPhi + (size_t)b * p, *de = c->dPhi + (size_t)e * p;
            for (int j = 0; j < p; j++) {
                double g = 2 * coef * (gb[j] - ge[j]);
                db[j] += g;
                de[j] -= g;
            }
            if (!c->basis)
                cblas_dsyr(CblasRowMajor, CblasUpper, p, coef * im, dphi, 1, c->S, p);
        }
}

/* The collapse floor at rest (as in datafree.c): λ_0 Σ_k h(μ_k) over the
 * Gram matrix G_r = Φ_s G Φ_sᵀ / m̂ of the r tangent samples, the secants
 * z = ε e_k from rest (crom_dfloss_rest_floor gives A = dL/dG_r); dL/dΦ_s =
 * 2 A Φ_s G / m̂ and, through G for a trained W, S += Φ_sᵀ A Φ_s / m̂. */
static void tangent_term(crom_dffield_ctx *c, int B, double *obj, double *tan)
{
    int p = c->p, B0 = c->B0;
    double im = gram_scale(c), *Gr = c->tg, *A = Gr + (size_t)B0 * B0, *work = A + (size_t)B0 * B0;
    const double *Ps = c->Phi + (size_t)B * p;
    double *GP = c->tmp, *dPs = c->dPhi + (size_t)B * p; /* GP: Φ_s G / m̂ [B0][p] */
    cblas_dsymm(CblasRowMajor, CblasRight, CblasUpper, B0, p, im, c->G, p, Ps, p, 0.0, GP, p);
    cblas_dgemm(CblasRowMajor, CblasNoTrans, CblasTrans, B0, B0, p, 1.0, Ps, p, GP, p, 0.0, Gr, B0);
    double h = crom_dfloss_rest_floor(B0, Gr, c->o.tangent_floor, c->o.tangent_weight, A, work);
    if (!isfinite(h)) /* (no motion along an axis at all: the energy decides) */
        return;
    *tan += h;
    *obj += c->o.tangent_weight * h;
    cblas_dgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, B0, p, B0, 2.0, A, B0, GP, p, 1.0, dPs, p);
    if (!c->basis) { /* S += im Φ_sᵀ (A Φ_s) */
        double *AP = c->tmp; /* (GP is done with) */
        cblas_dgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, B0, p, B0, 1.0, A, B0, Ps, p, 0.0, AP, p);
        cblas_dgemm(CblasRowMajor, CblasTrans, CblasNoTrans, p, p, B0, im, Ps, p, AP, p, 1.0, c->S, p);
    }
}

/* Through G: dL/dF_v += 2 m̂_v F_v S (S = dL/dG, symmetrized); nothing over
 * a fixed basis. */
static void gram_grad(crom_dffield_ctx *c)
{
    if (c->basis)
        return;
    int p = c->p, m3 = 3 * c->cub.ns;
    for (int i = 0; i < p; i++)
        for (int j = 0; j < i; j++)
            c->S[i * p + j] = c->S[j * p + i];
    cblas_dgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, m3, p, p, 1.0, c->F, p, c->S, p, 0.0, c->tmp, p);
    for (int i = 0; i < m3; i++)
        cblas_daxpy(p, 2 * c->cub.mloc[i / 3], c->tmp + (size_t)i * p, 1, c->dF + (size_t)i * p, 1);
}

/* The gradients of the parameters: W's through the mask, φ's through the
 * anchor, dL/dφ(0) = −Σ_b dL/dΦ_b. */
static int backward(crom_dffield_ctx *c, int B, float *gW, float *gP)
{
    int p = c->p, ns = c->cub.ns, rc = 0;
    if (gW && c->W) {
        for (size_t i = 0; i < (size_t)3 * ns * p; i++)
            c->dFf[i] = (float)(c->mask[c->cub.vs[i / (3 * (size_t)p)]] * c->dF[i]);
        memset(gW, 0, sizeof(float) * c->W->nparams);
        if ((rc = crom_nn_mlp_backward(c->W, &c->wsW, ns, c->dFf, gW, NULL)))
            return rc;
    }
    if (gP) {
        crom_dfloss_anchor_grad(B + c->B0 + 1, p, c->dPhi, NULL, c->dPf);
        memset(gP, 0, sizeof(float) * c->phi->nparams);
        rc = crom_nn_mlp_backward(c->phi, &c->wsP, B + c->B0 + 1, c->dPf, gP, NULL);
    }
    return rc;
}

/* The loss over the drawn tets (drawn already). */
static int drawn_loss(crom_dffield_ctx *c, int B, const double *z, double rho, int K, const int *tets,
                      crom_dftrain_terms *t, float *gW, float *gP)
{
    int rc = outputs(c, B, z);
    if (rc)
        return rc;
    energies(c, B, rho, K, tets);
    if ((rc = crom_dfloss_check(B, c->bad, c->E, "sample")))
        return rc;
    double obj = 0, Em = 0, pen = 0, tan = 0;
    energy_term(c, B, rho, &obj, &Em);
    if (c->cub.mhat > 0) {
        gram(c);
        isometry_term(c, B, z, &obj, &pen);
        if (c->B0 > 0)
            tangent_term(c, B, &obj, &tan);
        gram_grad(c);
    }
    if ((rc = crom_dfloss_terms(t, obj, Em, pen, tan, "data-free")))
        return rc;
    return backward(c, B, gW, gP);
}

int crom_dffield_loss(crom_dffield_ctx *c, int B, const double *z, double rho, int K, const int *tets,
                      crom_dftrain_terms *t, float *gW, float *gP)
{
    if (B < 2 || B > c->maxbatch || K < 1 || K > c->maxtets)
        return crom_err(CROM_EUSAGE, "batch of %d samples, %d tets (at most %d, %d)", B, K, c->maxbatch, c->maxtets);
    rho = rho < 0 ? 0 : rho > 1 ? 1 : rho;
    int rc = crom_dfloss_cub_draw(&c->cub, &c->fem, c->P.mat.rho, K, tets);
    if (!rc)
        rc = drawn_loss(c, B, z, rho, K, tets, t, gW, gP);
    crom_dfloss_cub_clear(&c->cub);
    return rc;
}

/* ============================================================ training */

/* Scale the last layer of the field (of φ over a fixed basis) so that
 * W(X) (φ(z) − φ(0)) starts at the isometry scale: RMS displacement σ over
 * random vertices and z ~ N(0, I) (a default-initialized pair of networks
 * moves the body by metres, which training would first have to undo). */
static int init_scale(crom_dffield_ctx *c, crom_nn_mlp *W, crom_nn_mlp *phi, crom_rng *rng)
{
    int nv = c->P.mesh->nv, n = c->maxrows < nv ? c->maxrows : nv, B = c->maxbatch, p = c->p, rc;
    for (int i = 0; i < n; i++) {
        int v = n == nv ? i : (int)crom_rng_below(rng, (uint64_t)nv);
        if (c->basis)
            memcpy(c->F + (size_t)i * 3 * p, c->basis + (size_t)v * 3 * p, sizeof(double) * 3 * (size_t)p);
        for (int d = 0; d < 3; d++)
            c->xf[3 * i + d] = (float)c->P.mesh->X[3 * (size_t)v + d];
    }
    for (int i = 0; i < B * c->r; i++)
        c->zf[i] = (float)crom_rng_normal(rng);
    memset(c->zf + (size_t)B * c->r, 0, sizeof(float) * (size_t)c->r); /* the anchor */
    if (!c->basis) {
        if ((rc = crom_nn_mlp_forward(W, &c->wsW, n, c->xf, NULL)))
            return rc;
        const float *F = crom_nn_ws_output(&c->wsW);
        for (size_t i = 0; i < (size_t)3 * n * p; i++) /* unmasked: the scale of W itself */
            c->F[i] = F[i];
    }
    if ((rc = crom_nn_mlp_forward(phi, &c->wsP, B + 1, c->zf, NULL)))
        return rc;
    const float *P = crom_nn_ws_output(&c->wsP), *P0 = P + (size_t)B * p;
    for (int i = 0; i < B * p; i++)
        c->Phi[i] = (double)P[i] - (double)P0[i % p];
    cblas_dgemm(CblasRowMajor, CblasNoTrans, CblasTrans, B, 3 * n, p, 1.0, c->Phi, p, c->F, p, 0.0, c->gu, 3 * n);
    double u2 = 0;
    for (size_t i = 0; i < (size_t)B * 3 * n; i++)
        u2 += c->gu[i] * c->gu[i];
    double rms = sqrt(u2 / ((double)B * n)); /* per vertex (3 components) */
    if (!(rms > 0) || !isfinite(rms))
        return crom_err(CROM_EDATA, "the initial field is zero or not finite");
    crom_dftrain_scale_last(c->basis ? phi : W, (float)(c->o.sigma / rms));
    return 0;
}

/* Check the problem and the options of the field, and fill in sigma (0.05
 * times the bounding-box diagonal) where it is unset. */
static int check_field(const crom_datafree_problem *p, crom_datafree_opts *o)
{
    int pinned = 0, r = o->rank, pf = o->features;
    for (int i = 0; p->fixed && i < 3 * p->mesh->nv; i++)
        pinned += p->fixed[i] != 0;
    if (r < 1 || pf < 1)
        return crom_err(CROM_EUSAGE, "--rank %d and --features %d must be positive", r, pf);
    double gn = fabs(p->gravity[0]) + fabs(p->gravity[1]) + fabs(p->gravity[2]);
    if (gn > 0 && pinned == 0)
        return crom_err(CROM_EUSAGE, "a free body under gravity has no lowest energy (it falls forever): pin a "
                        "region (--pin) or train with --gravity 0,0,0");
    if (o->steps < 1 || o->batch < 2 || o->depth < 2 || o->width < 1 || o->field_depth < 2 || o->field_width < 1 ||
        o->tets < 1)
        return crom_err(CROM_EUSAGE, "steps, batch (>= 2), depth (>= 2), width and tets must be positive");
    if (o->depth > CROM_NN_MAX_LAYERS || o->field_depth > CROM_NN_MAX_LAYERS)
        return crom_err(CROM_EUSAGE, "at most %d layers per network", CROM_NN_MAX_LAYERS);
    if (!(o->sigma > 0))
        o->sigma = 0.05 * crom_dftrain_diag(p->mesh);
    if (!isfinite(o->sigma) || !isfinite(o->lambda) || o->lambda < 0 || !(o->lr > 0) || !isfinite(o->lr) ||
        !(o->ramp >= 0 && o->ramp <= 1) || !isfinite(o->pin_length) || o->pin_length < 0)
        return crom_err(CROM_EUSAGE, "non-finite or negative training weight");
    return 0;
}

/* A field in training: the options as used, the networks W and φ with
 * their gradients, the loss, and the random streams of the initialization
 * and of the samples. */
typedef struct {
    crom_datafree_opts o;
    const double *basis;     /* a fixed basis [nv][3][p] in place of W, or NULL */
    int pdim;                /* its p */
    crom_nn_mlp W, phi;
    float *gW, *gP;
    crom_dffield_ctx ctx;
    int K;                   /* tets of the cubature */
    crom_rng irng, srng;
    long nvisit;             /* refining along a run (datafree.h): the latents visited, */
    const double *visit_z;
    double *zs;              /* and the batch drawn near them */
} field_trainer;

static void field_free(field_trainer *T)
{
    crom_dffield_ctx_free(&T->ctx);
    crom_nn_mlp_free(&T->W);
    crom_nn_mlp_free(&T->phi);
    free(T->gW);
    free(T->gP);
    free(T->zs);
}

/* The networks: W 3 -> field_width x (field_depth - 1) -> 3p with the input
 * normalized to the bounding box, φ r -> width x (depth - 1) -> p; the
 * loss; W scaled to the isometry. */
static int field_setup(field_trainer *T, const crom_datafree_problem *p)
{
    const crom_datafree_opts *o = &T->o;
    int nt = p->mesh->nt, pf = T->basis ? T->pdim : o->features, rc;
    T->K = o->tets < nt ? o->tets : nt;
    crom_nn_spec wspec, pspec;
    if ((!T->basis && (rc = crom_dftrain_spec(&wspec, 3, o->field_width, o->field_depth, 3 * pf, o->act))) ||
        (rc = crom_dftrain_spec(&pspec, o->rank, o->width, o->depth, pf, o->act)))
        return rc;
    crom_dftrain_seed(o->seed, &T->irng, &T->srng);
    if ((!T->basis && (rc = crom_nn_mlp_init(&T->W, &wspec, NULL, &T->irng))) ||
        (rc = crom_nn_mlp_init(&T->phi, &pspec, NULL, &T->irng)) ||
        (!T->basis && (rc = crom_dftrain_norm_box(&T->W, p->mesh))))
        return rc;
    const crom_nn_mlp *W = T->basis ? NULL : &T->W;
    if ((rc = crom_dffield_ctx_init(&T->ctx, p, o, W, T->basis, &T->phi, o->batch, T->K)) ||
        (rc = init_scale(&T->ctx, &T->W, &T->phi, &T->srng)))
        return rc;
    if (p->init) { /* refining a trained field: φ, and W unless the basis is fixed (datafree.h) */
        if (!T->basis != !!p->init_field)
            return crom_err(CROM_EUSAGE, "a field to start from needs its feature field W(X) unless the basis is "
                                         "fixed (--handles), and only then");
        if (!crom_nn_mlp_has_spec(p->init, &pspec) ||
            (p->init_field && !crom_nn_mlp_has_spec(p->init_field, &wspec)))
            return crom_err(CROM_EUSAGE, "the field to start from has another shape (rank, --width, --depth, "
                                         "--features, --field-width, --field-depth, activation)");
        memcpy(T->phi.params, p->init->params, sizeof(float) * T->phi.nparams);
        if (p->init_field) {
            memcpy(T->W.params, p->init_field->params, sizeof(float) * T->W.nparams);
            if ((rc = crom_nn_mlp_set_norm(&T->W, p->init_field->shift, p->init_field->scale)))
                return rc;
        }
    }
    if (p->nvisit > 0) {
        if (!p->init)
            return crom_err(CROM_EUSAGE, "a field samples along a run of the field it starts from: give it");
        T->nvisit = p->nvisit;
        T->visit_z = p->visit_z;
        if (!(T->zs = crom_malloc(sizeof(double) * (size_t)(o->batch + T->ctx.B0) * o->rank)))
            return CROM_EINTERNAL;
    }
    T->gW = W ? crom_malloc(sizeof(float) * T->W.nparams) : NULL;
    T->gP = crom_malloc(sizeof(float) * T->phi.nparams);
    return (T->gW || !W) && T->gP ? 0 : CROM_EINTERNAL;
}

static int field_loss(void *ctx, const double *z, double rho, int K, const int *tets, crom_dftrain_terms *t)
{
    field_trainer *T = ctx;
    if (T->nvisit) { /* every other sample near a latent the run visited */
        crom_datafree_visit_draw(1, T->o.batch, T->ctx.B0, T->o.rank, z, NULL, T->nvisit, T->visit_z, T->zs);
        z = T->zs;
    }
    return crom_dffield_loss(&T->ctx, T->o.batch, z, rho, K, tets, t, T->gW, T->gP);
}

/* Train both networks (φ alone over a fixed basis) with Adam: z ~ N(0, I),
 * ρ ramped, a fresh random cubature each step. */
static int field_train(field_trainer *T, const crom_datafree_problem *p, crom_dftrain_log *log)
{
    const crom_datafree_opts *o = &T->o;
    log->sigma = o->sigma;
    log->Eref = T->ctx.Eref;
    crom_dftrain_loop L = {
        .loss = field_loss, .ctx = T, .nblocks = 2, .params = {T->W.params, T->phi.params}, .grad = {T->gW, T->gP},
        .nparams = {T->W.nparams, T->phi.nparams}, .rng = &T->srng, .batch = o->batch, .tangent = T->ctx.B0,
        .r = o->rank, .tangent_radius = o->tangent_radius, .K = T->K, .nt = p->mesh->nt,
        .ramp = p->init ? 0 : o->ramp,
        .steps = o->steps, .minutes = o->minutes, .lr = o->lr, .hint = " (try a smaller --lr)",
        .progress = o->progress, .progress_ctx = o->progress_ctx};
    if (T->basis) { /* φ alone */
        L.nblocks = 1;
        L.params[0] = T->phi.params;
        L.grad[0] = T->gP;
        L.nparams[0] = T->phi.nparams;
    }
    return crom_dftrain_run(&L, log);
}

int crom_dffield_train(const crom_datafree_problem *p, const crom_datafree_opts *o, crom_model *out,
                       crom_dftrain_log *log)
{
    crom_model_clear(out);
    memset(log, 0, sizeof *log);
    double t0 = crom_clock_now();
    field_trainer T;
    memset(&T, 0, sizeof T);
    T.o = *o;
    int rc = check_field(p, &T.o);
    if (!rc)
        rc = field_setup(&T, p);
    if (!rc)
        rc = field_train(&T, p, log);
    if (!rc)
        rc = crom_model_from_field_map(out, &T.W, &T.phi, T.ctx.npins, T.ctx.pinX, T.ctx.ntri, T.ctx.triX,
                                       T.ctx.pin_length);
    if (!rc)
        out->training_seconds = crom_clock_wall(crom_clock_now() - t0);
    field_free(&T);
    if (rc)
        crom_dftrain_log_free(log);
    return rc;
}

void crom_dffield_latent_defaults(crom_datafree_opts *o)
{
    o->lambda = 0.03;
    o->tangent_weight = 0.1;
    o->sigma = 0;
}

int crom_dffield_train_latent(const crom_datafree_problem *p, const crom_datafree_opts *o, const double *basis,
                              int pdim, crom_nn_mlp *phi, crom_dftrain_log *log)
{
    memset(phi, 0, sizeof *phi);
    memset(log, 0, sizeof *log);
    if (!basis || pdim < 1)
        return crom_err(CROM_EUSAGE, "a fixed basis of %d features", pdim);
    field_trainer T;
    memset(&T, 0, sizeof T);
    T.o = *o;
    T.basis = basis;
    T.pdim = pdim;
    if (!(T.o.sigma > 0)) /* (the latent's default scale, crom_dffield_latent_defaults) */
        T.o.sigma = 0.15 * crom_dftrain_diag(p->mesh);
    int rc = check_field(p, &T.o);
    if (!rc)
        rc = field_setup(&T, p);
    if (!rc)
        rc = field_train(&T, p, log);
    if (!rc) { /* hand φ over */
        *phi = T.phi;
        memset(&T.phi, 0, sizeof T.phi);
    }
    field_free(&T);
    if (rc)
        crom_dftrain_log_free(log);
    return rc;
}
