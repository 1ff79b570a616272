/* dffield.c — a continuous data-free subspace x(X, z) = X + W(X) φ(z),
 * trained from the energy integrated by a random cubature of the mesh
 * (crom-fitfield --objective field; see dffield.h). */
#ifdef _OPENMP
#include <omp.h>
#endif
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <cblas.h>

#include "base/clock.h"
#include "base/err.h"
#include "base/rng.h"
#include "datafree/dffield.h"
#include "mesh/locate.h"

void crom_dffield_ctx_free(crom_dffield_ctx *c)
{
    if (!c)
        return;
    crom_fem_free(&c->fem);
    crom_nn_ws_free(&c->wsW);
    crom_nn_ws_free(&c->wsP);
    void *bufs[] = {c->loc, c->vs, c->xf, c->F, c->Phi, c->zf, c->gu, c->dF, c->dPhi, c->dFf, c->dPf, c->mloc,
                    c->E, c->bad, c->G, c->S, c->tmp, c->xb, c->pinX, c->mask, c->triX};
    for (size_t i = 0; i < sizeof bufs / sizeof *bufs; i++)
        free(bufs[i]);
    memset(c, 0, sizeof *c);
}

int crom_dffield_ctx_init(crom_dffield_ctx *c, const crom_datafree_problem *p, const crom_datafree_opts *o,
                          const crom_nn_mlp *W, const crom_nn_mlp *phi, int maxbatch, int maxtets)
{
    memset(c, 0, sizeof *c);
    c->P = *p;
    c->o = *o;
    c->W = W;
    c->phi = phi;
    const crom_nn_spec *ps = &phi->spec, *ws = &W->spec;
    int r = ps->width[0], pf = ps->width[ps->nlayers], nv = p->mesh->nv;
    if (ws->width[0] != 3 || ws->width[ws->nlayers] != 3 * pf)
        return crom_err(CROM_EUSAGE, "the feature field goes %d -> %d, expected 3 -> 3p = %d", ws->width[0],
                        ws->width[ws->nlayers], 3 * pf);
    if (maxbatch < 2 || maxtets < 1)
        return crom_err(CROM_EUSAGE, "batch of %d samples, %d tets", maxbatch, maxtets);
    if (!(o->sigma > 0))
        return crom_err(CROM_EUSAGE, "sigma must be positive");
    c->r = r;
    c->p = pf;
    c->maxbatch = maxbatch;
    c->B0 = o->tangent_weight > 0 ? o->tangent_samples : 0;
    if (c->B0 < 0)
        return crom_err(CROM_EUSAGE, "%d tangent samples", c->B0);
    c->maxtets = maxtets;
    c->nthreads = o->threads < 1 ? 1 : o->threads > 256 ? 256 : o->threads;
    int rc = crom_fem_init(&c->fem, p->mesh, &p->mat);
    if (rc) {
        crom_dffield_ctx_free(c);
        return rc;
    }
    /* the pinned vertices (any pinned DOF) and the mask they make */
    c->pinX = crom_malloc(sizeof(double) * 3 * (size_t)(nv ? nv : 1));
    c->mask = crom_malloc(sizeof(double) * (size_t)(nv ? nv : 1));
    if (!c->pinX || !c->mask) {
        crom_dffield_ctx_free(c);
        return CROM_EINTERNAL;
    }
    for (int v = 0; v < nv; v++)
        if (p->fixed && (p->fixed[3 * v] || p->fixed[3 * v + 1] || p->fixed[3 * v + 2]))
            memcpy(c->pinX + 3 * (size_t)c->npins++, p->mesh->X + 3 * (size_t)v, sizeof(double) * 3);
    c->pin_length = o->pin_length;
    if (!(c->pin_length > 0)) { /* twice the mean edge */
        double s = 0;
        for (int k = 0; k < p->mesh->nt; k++)
            for (int a = 0; a < 4; a++)
                for (int b = a + 1; b < 4; b++) {
                    const double *xa = p->mesh->X + 3 * (size_t)p->mesh->tets[4 * (size_t)k + a];
                    const double *xb = p->mesh->X + 3 * (size_t)p->mesh->tets[4 * (size_t)k + b];
                    s += sqrt((xa[0] - xb[0]) * (xa[0] - xb[0]) + (xa[1] - xb[1]) * (xa[1] - xb[1]) +
                              (xa[2] - xb[2]) * (xa[2] - xb[2]));
                }
        c->pin_length = 2 * s / (6.0 * (p->mesh->nt ? p->mesh->nt : 1));
    }
    if (c->npins) { /* the boundary triangles with three pinned vertices */
        int nb, *tri = NULL;
        if ((rc = crom_mesh_boundary(p->mesh, &nb, &tri, NULL))) {
            crom_dffield_ctx_free(c);
            return rc;
        }
        c->triX = crom_malloc(sizeof(double) * 9 * (size_t)(nb ? nb : 1));
        if (!c->triX) {
            free(tri);
            crom_dffield_ctx_free(c);
            return CROM_EINTERNAL;
        }
        for (int k = 0; k < nb; k++) {
            int all = 1;
            for (int a = 0; a < 3; a++) {
                int v = tri[3 * k + a];
                all &= p->fixed[3 * v] || p->fixed[3 * v + 1] || p->fixed[3 * v + 2];
            }
            if (all) {
                for (int a = 0; a < 3; a++)
                    memcpy(c->triX + 9 * (size_t)c->ntri + 3 * a, p->mesh->X + 3 * (size_t)tri[3 * k + a],
                           sizeof(double) * 3);
                c->ntri++;
            }
        }
        free(tri);
    }
    for (int v = 0; v < nv; v++)
        c->mask[v] = crom_model_pin_mask(p->mesh->X + 3 * (size_t)v, c->npins, c->pinX, c->ntri, c->triX, c->pin_length);
    c->maxrows = 4 * maxtets;
    /* rows of φ: the batch, the tangent samples and z = 0 */
    size_t R = (size_t)c->maxrows, B = (size_t)maxbatch + c->B0 + 1, P = (size_t)pf;
    if ((rc = crom_nn_ws_init(&c->wsW, W, c->maxrows, 1)) || (rc = crom_nn_ws_init(&c->wsP, phi, (int)B, 1))) {
        crom_dffield_ctx_free(c);
        return rc;
    }
    c->loc = crom_malloc(sizeof(int) * (size_t)nv);
    c->vs = crom_malloc(sizeof(int) * R);
    c->xf = crom_malloc(sizeof(float) * 3 * R);
    c->F = crom_malloc(sizeof(double) * 3 * R * P);
    c->Phi = crom_malloc(sizeof(double) * B * P);
    c->zf = crom_malloc(sizeof(float) * B * (size_t)r);
    c->gu = crom_malloc(sizeof(double) * B * 3 * R);
    c->dF = crom_malloc(sizeof(double) * 3 * R * P);
    c->dPhi = crom_malloc(sizeof(double) * B * P);
    c->dFf = crom_malloc(sizeof(float) * 3 * R * P);
    c->dPf = crom_malloc(sizeof(float) * B * P);
    c->mloc = crom_malloc(sizeof(double) * R);
    c->E = crom_malloc(sizeof(double) * B);
    c->bad = crom_malloc(sizeof(int) * B);
    c->G = crom_malloc(sizeof(double) * P * P);
    c->S = crom_malloc(sizeof(double) * P * P);
    c->tmp = crom_malloc(sizeof(double) * 3 * R * P);
    c->xb = crom_malloc(sizeof(double) * (size_t)c->nthreads * 3 * R);
    if (!c->loc || !c->vs || !c->xf || !c->F || !c->Phi || !c->zf || !c->gu || !c->dF || !c->dPhi || !c->dFf ||
        !c->dPf || !c->mloc || !c->E || !c->bad || !c->G || !c->S || !c->tmp || !c->xb) {
        crom_dffield_ctx_free(c);
        return CROM_EINTERNAL;
    }
    for (int v = 0; v < nv; v++)
        c->loc[v] = -1;
    c->mass = c->fem.total_mass;
    c->Eref = p->mat.E * c->fem.volume;
    return 0;
}

/* local index of vertex v, adding it to the list */
static int local(crom_dffield_ctx *c, int v)
{
    if (c->loc[v] < 0) {
        c->loc[v] = c->ns;
        c->vs[c->ns++] = v;
    }
    return c->loc[v];
}

int crom_dffield_loss(crom_dffield_ctx *c, int B, const double *z, double rho, int K, const int *tets,
                      crom_dftrain_terms *t, float *gW, float *gP)
{
    int r = c->r, p = c->p, nt = c->fem.nt, B0 = c->B0, rc;
    const double *X = c->P.mesh->X, *g = c->P.gravity;
    const crom_fem *fem = &c->fem;
    if (B < 2 || B > c->maxbatch || K < 1 || K > c->maxtets)
        return crom_err(CROM_EUSAGE, "batch of %d samples, %d tets (at most %d, %d)", B, K, c->maxbatch, c->maxtets);
    rho = rho < 0 ? 0 : rho > 1 ? 1 : rho;
    /* the vertices of the sampled tets */
    c->ns = 0;
    for (int k = 0; k < K; k++) {
        if (tets[k] < 0 || tets[k] >= nt)
            return crom_err(CROM_EUSAGE, "tet %d out of range", tets[k]);
        for (int a = 0; a < 4; a++)
            local(c, fem->tets[4 * (size_t)tets[k] + a]);
    }
    int ntv = c->ns, ns = c->ns, m3 = 3 * ns;
    for (int i = 0; i < ns; i++)
        for (int d = 0; d < 3; d++)
            c->xf[3 * i + d] = (float)X[3 * (size_t)c->vs[i] + d];
    /* W at the vertices: F [ns][3][p], i.e. a [3ns][p] matrix; φ of the batch */
    if ((rc = crom_nn_mlp_forward(c->W, &c->wsW, ns, c->xf, NULL)))
        goto out;
    const float *Ff = crom_nn_ws_output(&c->wsW);
    for (size_t i = 0; i < (size_t)m3 * p; i++) /* masked at the pins */
        c->F[i] = c->mask[c->vs[i / (3 * (size_t)p)]] * Ff[i];
    /* φ of the batch, of the tangent samples and of z = 0, the anchor
     * (lib/map.h): the samples are taken relative to it, Φ_b = φ(z_b) − φ(0) */
    for (int i = 0; i < (B + B0) * r; i++)
        c->zf[i] = (float)z[i];
    memset(c->zf + (size_t)(B + B0) * r, 0, sizeof(float) * (size_t)r);
    if ((rc = crom_nn_mlp_forward(c->phi, &c->wsP, B + B0 + 1, c->zf, NULL)))
        goto out;
    const float *Pf = crom_nn_ws_output(&c->wsP), *P0 = Pf + (size_t)(B + B0) * p;
    for (int i = 0; i < (B + B0) * p; i++)
        c->Phi[i] = (double)Pf[i] - (double)P0[i % p];
    /* the cubature: each sampled tet stands for nt/K of them (an unbiased
     * estimate of the integral); lumped masses of the sampled tets */
    double wK = (double)nt / K, rho0 = c->P.mat.rho, mhat = 0;
    memset(c->mloc, 0, sizeof(double) * (size_t)ns);
    for (int k = 0; k < K; k++)
        for (int a = 0; a < 4; a++)
            c->mloc[c->loc[fem->tets[4 * (size_t)tets[k] + a]]] += wK * rho0 * fem->vol[tets[k]] / 4;
    for (int i = 0; i < ntv; i++)
        mhat += c->mloc[i];
    /* U = ρ Φ Fᵀ: displacements [B][3ns]; energies and their gradients gu */
    cblas_dgemm(CblasRowMajor, CblasNoTrans, CblasTrans, B, m3, p, rho, c->Phi, p, c->F, p, 0.0, c->gu, m3);
#pragma omp parallel for num_threads(c->nthreads) schedule(static)
    for (int b = 0; b < B; b++) {
        int tid = 0;
#ifdef _OPENMP
        tid = omp_get_thread_num();
#endif
        double *u = c->xb + (size_t)tid * 3 * c->maxrows, *gb = c->gu + (size_t)b * m3, Eb = 0;
        memcpy(u, gb, sizeof(double) * (size_t)m3);
        memset(gb, 0, sizeof(double) * (size_t)m3);
        c->bad[b] = 0;
        for (int k = 0; k < K; k++) {
            int tt = tets[k], l[4];
            double xe[12], ge[12], Ee;
            for (int a = 0; a < 4; a++) {
                int v = fem->tets[4 * (size_t)tt + a];
                l[a] = c->loc[v];
                for (int d = 0; d < 3; d++)
                    xe[3 * a + d] = X[3 * (size_t)v + d] + u[3 * l[a] + d];
            }
            if (crom_fem_tet_eval(&fem->mat, xe, fem->Dminv + 9 * (size_t)tt, fem->vol[tt], 0, &Ee, ge, NULL)) {
                c->bad[b] = 1;
                break;
            }
            Eb += wK * Ee;
            for (int a = 0; a < 4; a++)
                for (int d = 0; d < 3; d++)
                    gb[3 * l[a] + d] += wK * ge[3 * a + d];
        }
        for (int i = 0; i < ntv; i++) /* gravity: −Σ m g·u */
            for (int d = 0; d < 3; d++) {
                Eb -= c->mloc[i] * g[d] * u[3 * i + d];
                gb[3 * i + d] -= c->mloc[i] * g[d];
            }
        c->E[b] = Eb;
    }
    for (int b = 0; b < B; b++)
        if (c->bad[b] || !isfinite(c->E[b])) {
            rc = crom_err(CROM_EDATA, "sample %d of the batch has a non-finite energy", b);
            goto out;
        }
    double obj = 0, Em = 0, pen = 0, tan = 0, scale = 1.0 / (B * c->Eref);
    for (int b = 0; b < B; b++) {
        Em += c->E[b] / B;
        obj += c->E[b] * scale;
    }
    /* energy: dL/dΦ = ρ s GU F, dL/dF = ρ s GUᵀ Φ */
    cblas_dgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, B, p, m3, rho * scale, c->gu, m3, c->F, p, 0.0, c->dPhi,
                p);
    cblas_dgemm(CblasRowMajor, CblasTrans, CblasNoTrans, m3, p, B, rho * scale, c->gu, m3, c->Phi, p, 0.0, c->dF, p);
    memset(c->dPhi + (size_t)B * p, 0, sizeof(double) * (size_t)B0 * p);
    /* isometry over the pairs: D² = ΔΦᵀ G ΔΦ / m̂, G = Σ_v m_v F_vᵀ F_v */
    if (mhat > 0) {
        for (int i = 0; i < m3; i++) {
            double s = sqrt(c->mloc[i / 3]);
            for (int j = 0; j < p; j++)
                c->tmp[(size_t)i * p + j] = s * c->F[(size_t)i * p + j];
        }
        cblas_dsyrk(CblasRowMajor, CblasUpper, CblasTrans, p, m3, 1.0, c->tmp, p, 0.0, c->G, p);
        for (int i = 0; i < p; i++)
            for (int j = 0; j < i; j++)
                c->G[i * p + j] = c->G[j * p + i];
        memset(c->S, 0, sizeof(double) * (size_t)p * p);
        double npairs = 0.5 * B * (B - 1), lam = c->o.lambda, ls = log(c->o.sigma);
        double *dphi = c->tmp, *Gd = c->tmp + p; /* scratch: tmp is free again */
        for (int b = 0; b < B; b++)
            for (int e = b + 1; e < B; e++) {
                double dz = 0;
                for (int k = 0; k < r; k++) {
                    double d = z[(size_t)b * r + k] - z[(size_t)e * r + k];
                    dz += d * d;
                }
                for (int j = 0; j < p; j++)
                    dphi[j] = c->Phi[(size_t)b * p + j] - c->Phi[(size_t)e * p + j];
                cblas_dsymv(CblasRowMajor, CblasUpper, p, 1.0 / mhat, c->G, p, dphi, 1, 0.0, Gd, 1);
                double D2 = cblas_ddot(p, dphi, 1, Gd, 1);
                if (!(D2 > 0) || !(dz > 0))
                    continue;
                double l = 0.5 * log(D2) - 0.5 * log(dz) - ls;
                pen += l * l / npairs;
                obj += lam * l * l / npairs;
                double coef = lam * l / (npairs * D2); /* dL/dD² */
                cblas_daxpy(p, 2 * coef, Gd, 1, c->dPhi + (size_t)b * p, 1);
                cblas_daxpy(p, -2 * coef, Gd, 1, c->dPhi + (size_t)e * p, 1);
                cblas_dsyr(CblasRowMajor, CblasUpper, p, coef / mhat, dphi, 1, c->S, p);
            }
        /* the tangent at rest, conformal: λ_0 mean_s (ℓ_s − ℓ̄)², ℓ_s = ½ log
         * D_s² − log |z_s|, D_s² = Φ_sᵀ G Φ_s / m̂ the displacement of a small
         * sample from rest, ℓ̄ their mean (as in datafree.c) */
        double lam0 = c->o.tangent_weight, lbar = 0, *lsb = c->E + B; /* E has room past the batch */
        int ok = 1;
        for (int b = B; b < B + B0; b++) {
            const double *ph = c->Phi + (size_t)b * p;
            double dz = 0;
            for (int k = 0; k < r; k++)
                dz += z[(size_t)b * r + k] * z[(size_t)b * r + k];
            cblas_dsymv(CblasRowMajor, CblasUpper, p, 1.0 / mhat, c->G, p, ph, 1, 0.0, Gd, 1);
            double D2 = cblas_ddot(p, ph, 1, Gd, 1);
            ok &= D2 > 0 && dz > 0;
            lsb[b - B] = 0.5 * log(D2) - 0.5 * log(dz);
            lbar += lsb[b - B] / B0;
        }
        for (int b = B; ok && b < B + B0; b++) {
            const double *ph = c->Phi + (size_t)b * p;
            cblas_dsymv(CblasRowMajor, CblasUpper, p, 1.0 / mhat, c->G, p, ph, 1, 0.0, Gd, 1);
            double D2 = cblas_ddot(p, ph, 1, Gd, 1), l = lsb[b - B] - lbar;
            tan += l * l / B0;
            obj += lam0 * l * l / B0;
            double coef = lam0 * l / (B0 * D2);
            cblas_daxpy(p, 2 * coef, Gd, 1, c->dPhi + (size_t)b * p, 1);
            cblas_dsyr(CblasRowMajor, CblasUpper, p, coef / mhat, ph, 1, c->S, p);
        }
        for (int i = 0; i < p; i++)
            for (int j = 0; j < i; j++)
                c->S[i * p + j] = c->S[j * p + i];
        /* dL/dF_v += 2 m_v F_v S */
        cblas_dgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, m3, p, p, 1.0, c->F, p, c->S, p, 0.0, c->tmp, p);
        for (int i = 0; i < m3; i++)
            cblas_daxpy(p, 2 * c->mloc[i / 3], c->tmp + (size_t)i * p, 1, c->dF + (size_t)i * p, 1);
    }
    if (t) {
        t->objective = obj;
        t->energy = Em;
        t->penalty = pen;
        t->tangent = tan;
    }
    if (!isfinite(obj)) {
        rc = crom_err(CROM_EDATA, "the data-free objective is not finite");
        goto out;
    }
    if (gW) {
        for (size_t i = 0; i < (size_t)m3 * p; i++) /* through the mask */
            c->dFf[i] = (float)(c->mask[c->vs[i / (3 * (size_t)p)]] * c->dF[i]);
        memset(gW, 0, sizeof(float) * c->W->nparams);
        if ((rc = crom_nn_mlp_backward(c->W, &c->wsW, ns, c->dFf, gW, NULL)))
            goto out;
    }
    if (gP) { /* through the anchor: dL/dφ(0) = −Σ_b dL/dΦ_b */
        float *d0 = c->dPf + (size_t)(B + B0) * p;
        memset(d0, 0, sizeof(float) * (size_t)p);
        for (int i = 0; i < (B + B0) * p; i++) {
            c->dPf[i] = (float)c->dPhi[i];
            d0[i % p] -= c->dPf[i];
        }
        memset(gP, 0, sizeof(float) * c->phi->nparams);
        rc = crom_nn_mlp_backward(c->phi, &c->wsP, B + B0 + 1, c->dPf, gP, NULL);
    }
out:
    for (int i = 0; i < c->ns; i++)
        c->loc[c->vs[i]] = -1;
    return rc;
}

/* ============================================================ training */

/* Scale the field's last layer so that W(X) (φ(z) − φ(0)) starts at the isometry
 * scale: RMS displacement σ over random vertices and z ~ N(0, I) (a
 * default-initialized pair of networks moves the body by metres, which
 * training would first have to undo). */
static int init_scale(crom_dffield_ctx *c, crom_nn_mlp *W, crom_nn_mlp *phi, crom_rng *rng)
{
    int nv = c->P.mesh->nv, n = c->maxrows < nv ? c->maxrows : nv, B = c->maxbatch, p = c->p, rc;
    for (int i = 0; i < n; i++) {
        int v = n == nv ? i : (int)crom_rng_below(rng, (uint64_t)nv);
        for (int d = 0; d < 3; d++)
            c->xf[3 * i + d] = (float)c->P.mesh->X[3 * (size_t)v + d];
    }
    for (int i = 0; i < B * c->r; i++)
        c->zf[i] = (float)crom_rng_normal(rng);
    memset(c->zf + (size_t)B * c->r, 0, sizeof(float) * (size_t)c->r); /* the anchor */
    if ((rc = crom_nn_mlp_forward(W, &c->wsW, n, c->xf, NULL)))
        return rc;
    const float *F = crom_nn_ws_output(&c->wsW);
    for (size_t i = 0; i < (size_t)3 * n * p; i++) /* unmasked: the scale of W itself */
        c->F[i] = F[i];
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
    crom_dftrain_scale_last(W, (float)(c->o.sigma / rms));
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
    crom_nn_mlp W, phi;
    float *gW, *gP;
    crom_dffield_ctx ctx;
    int K;                   /* tets of the cubature */
    crom_rng irng, srng;
} field_trainer;

static void field_free(field_trainer *T)
{
    crom_dffield_ctx_free(&T->ctx);
    crom_nn_mlp_free(&T->W);
    crom_nn_mlp_free(&T->phi);
    free(T->gW);
    free(T->gP);
}

/* The networks: W 3 -> field_width x (field_depth - 1) -> 3p with the input
 * normalized to the bounding box, φ r -> width x (depth - 1) -> p; the
 * loss; W scaled to the isometry. */
static int field_setup(field_trainer *T, const crom_datafree_problem *p)
{
    const crom_datafree_opts *o = &T->o;
    int nt = p->mesh->nt, pf = o->features, rc;
    T->K = o->tets < nt ? o->tets : nt;
    crom_nn_spec wspec, pspec;
    if ((rc = crom_dftrain_spec(&wspec, 3, o->field_width, o->field_depth, 3 * pf, o->act)) ||
        (rc = crom_dftrain_spec(&pspec, o->rank, o->width, o->depth, pf, o->act)))
        return rc;
    crom_rng_seed(&T->irng, o->seed);
    crom_rng_seed(&T->srng, o->seed ^ 0x5eed5a3b1e5ULL);
    if ((rc = crom_nn_mlp_init(&T->W, &wspec, NULL, &T->irng)) ||
        (rc = crom_nn_mlp_init(&T->phi, &pspec, NULL, &T->irng)) || (rc = crom_dftrain_norm_box(&T->W, p->mesh)))
        return rc;
    if ((rc = crom_dffield_ctx_init(&T->ctx, p, o, &T->W, &T->phi, o->batch, T->K)) ||
        (rc = init_scale(&T->ctx, &T->W, &T->phi, &T->srng)))
        return rc;
    T->gW = crom_malloc(sizeof(float) * T->W.nparams);
    T->gP = crom_malloc(sizeof(float) * T->phi.nparams);
    return T->gW && T->gP ? 0 : CROM_EINTERNAL;
}

static int field_loss(void *ctx, const double *z, double rho, int K, const int *tets, crom_dftrain_terms *t)
{
    field_trainer *T = ctx;
    return crom_dffield_loss(&T->ctx, T->o.batch, z, rho, K, tets, t, T->gW, T->gP);
}

/* Train both networks with Adam: z ~ N(0, I), ρ ramped, a fresh random
 * cubature each step. */
static int field_train(field_trainer *T, const crom_datafree_problem *p, crom_dftrain_log *log)
{
    const crom_datafree_opts *o = &T->o;
    log->sigma = o->sigma;
    log->Eref = T->ctx.Eref;
    crom_dftrain_loop L = {
        .loss = field_loss, .ctx = T, .nblocks = 2, .params = {T->W.params, T->phi.params}, .grad = {T->gW, T->gP},
        .nparams = {T->W.nparams, T->phi.nparams}, .rng = &T->srng, .batch = o->batch, .tangent = T->ctx.B0,
        .r = o->rank, .tangent_radius = o->tangent_radius, .K = T->K, .nt = p->mesh->nt, .ramp = o->ramp,
        .steps = o->steps, .minutes = o->minutes, .lr = o->lr, .hint = " (try a smaller --lr)",
        .progress = o->progress, .progress_ctx = o->progress_ctx};
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
