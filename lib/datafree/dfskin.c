/* dfskin.c — skinning weights with no data: trained (Simplicits) or the
 * lowest eigenvectors of the scalar stiffness (skinning eigenmodes); see
 * dfskin.h. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <lapacke.h>

#include "base/clock.h"
#include "base/err.h"
#include "base/rng.h"
#include "datafree/dfloss.h"
#include "datafree/dfskin.h"
#include "phys/system.h"
#include "io/io.h"
#include "phys/modes.h"
#include "rom/skin.h"

void crom_dfskin_defaults(crom_dfskin_opts *o)
{
    memset(o, 0, sizeof *o);
    o->handles = 8;
    o->depth = 4;
    o->width = 64;
    o->act = CROM_NN_ELU;
    o->steps = 2000;
    o->lr = 1e-3;
    o->batch = 16;
    o->sigma = 0;
    o->ortho_weight = 1;
    o->tets = 512;
    o->pin_length = 0;
    o->threads = 1;
    o->seed = 1;
}

static int count_free(const crom_mesh *mesh, const unsigned char *fixed, int *npinned)
{
    int nfree = 0, np = 0;
    for (int v = 0; v < mesh->nv; v++) {
        int pin = crom_dfloss_pinned(fixed, v);
        np += pin;
        nfree += !pin;
    }
    if (npinned)
        *npinned = np;
    return nfree;
}

int crom_dfskin_check_handles(const crom_mesh *mesh, const unsigned char *fixed, int H)
{
    int np, nfree = count_free(mesh, fixed, &np);
    if (H < 1)
        return crom_err(CROM_EUSAGE, "--handles %d: a skinning subspace needs at least one handle", H);
    if (nfree == 0)
        return crom_err(CROM_EUSAGE, "every vertex is pinned: there is nothing to move");
    if ((long)12 * H > 3L * nfree)
        return crom_err(CROM_EUSAGE, "--handles %d: %d latent coordinates (12 per handle) for a body with only %d free "
                        "degrees of freedom (%d vertices, %d pinned): at most %d handles", H, 12 * H, 3 * nfree,
                        mesh->nv, np, nfree / 4);
    return 0;
}

/* ============================================================ the loss */

void crom_dfskin_ctx_free(crom_dfskin_ctx *c)
{
    if (!c)
        return;
    crom_fem_free(&c->fem);
    free(c->mats);
    free(c->tmat);
    crom_nn_ws_free(&c->ws);
    crom_dfloss_cub_free(&c->cub);
    void *bufs[] = {c->pinX, c->triX, c->mask, c->bad, c->xf, c->dwf, c->w, c->xh, c->wh, c->L, c->U, c->gu, c->dw,
                    c->E, c->R, c->G, c->xb};
    for (size_t i = 0; i < sizeof bufs / sizeof *bufs; i++)
        free(bufs[i]);
    memset(c, 0, sizeof *c);
}

/* The pinned part of the training geometry: for a tet mesh its pinned
 * vertices and its boundary triangles with three pinned vertices, then the
 * given points and triangles. */
static int pinned_part(crom_dfskin_ctx *c, const crom_dfskin_problem *p)
{
    int rc = crom_dfloss_pinned_part(p->mesh, p->virtual_tets ? NULL : p->fixed, p->npin, p->ntri, &c->npins,
                                     &c->pinX, &c->ntri, &c->triX);
    if (rc)
        return rc;
    if (p->npin)
        memcpy(c->pinX + 3 * (size_t)c->npins, p->pinX, sizeof(double) * 3 * (size_t)p->npin);
    c->npins += p->npin;
    if (p->ntri)
        memcpy(c->triX + 9 * (size_t)c->ntri, p->triX, sizeof(double) * 9 * (size_t)p->ntri);
    c->ntri += p->ntri;
    return 0;
}

/* The work space: the network's for maxrows vertices, the drawn tets, the
 * arrays of the loss. */
static int buffers(crom_dfskin_ctx *c)
{
    int nv = c->P.mesh->nv, rc;
    size_t R = (size_t)c->maxrows, B = (size_t)c->maxbatch, Hs = (size_t)c->H;
    if ((rc = crom_nn_ws_init(&c->ws, c->net, c->maxrows, 1)) || (rc = crom_dfloss_cub_init(&c->cub, nv, c->maxrows)))
        return rc;
    c->mask = crom_malloc(sizeof(double) * (size_t)nv);
    c->bad = crom_malloc(sizeof(int) * B);
    c->xf = crom_malloc(sizeof(float) * 3 * R);
    c->dwf = crom_malloc(sizeof(float) * R * Hs);
    c->w = crom_malloc(sizeof(double) * R * Hs);
    c->xh = crom_malloc(sizeof(double) * R * 4);
    c->wh = crom_malloc(sizeof(double) * R * Hs);
    c->L = crom_malloc(sizeof(double) * 4 * Hs * Hs);
    c->U = crom_malloc(sizeof(double) * (size_t)c->nthreads * 3 * R);
    c->gu = crom_malloc(sizeof(double) * B * 3 * R);
    c->dw = crom_malloc(sizeof(double) * R * Hs);
    c->E = crom_malloc(sizeof(double) * B);
    c->R = crom_malloc(sizeof(double) * B);
    c->G = crom_malloc(sizeof(double) * Hs * Hs);
    c->xb = crom_malloc(sizeof(double) * Hs);
    if (!c->mask || !c->bad || !c->xf || !c->dwf || !c->w || !c->xh || !c->wh || !c->L || !c->U || !c->gu || !c->dw ||
        !c->E || !c->R || !c->G || !c->xb)
        return CROM_EINTERNAL;
    return 0;
}

int crom_dfskin_ctx_init(crom_dfskin_ctx *c, const crom_dfskin_problem *p, const crom_dfskin_opts *o,
                         const crom_nn_mlp *net, int maxbatch, int maxtets)
{
    memset(c, 0, sizeof *c);
    c->P = *p;
    c->o = *o;
    c->net = net;
    int nv = p->mesh->nv, H = o->handles, rc;
    if (maxbatch < 1 || maxtets < 1 || H < 1 || H > CROM_DFSKIN_MAXH)
        return crom_err(CROM_EUSAGE, "batch of %d poses, %d tets, %d handles (at most %d trained)", maxbatch, maxtets,
                        H, CROM_DFSKIN_MAXH);
    if (!(o->sigma > 0) || !(o->pin_length > 0) || !(o->ortho_weight >= 0))
        return crom_err(CROM_EUSAGE, "sigma and the pin length must be positive, the orthogonality weight >= 0");
    c->H = H;
    c->maxbatch = maxbatch;
    c->maxtets = maxtets;
    c->maxrows = 4 * maxtets < nv ? 4 * maxtets : nv;
    c->nthreads = crom_dftrain_threads(o->threads);
    c->pin_length = o->pin_length;
    if ((rc = crom_fem_init(&c->fem, p->mesh, &p->mat)) ||
        (rc = crom_dfloss_materials(&c->fem, p->materials, p->mesh, &c->mats, &c->tmat)) || (rc = pinned_part(c, p))) {
        crom_dfskin_ctx_free(c);
        return rc;
    }
    c->constant = c->npins == 0 && c->ntri == 0 && !(p->fixed && count_free(p->mesh, p->fixed, NULL) < nv);
    c->Ht = H - c->constant;
    const crom_nn_spec *sp = &net->spec;
    if (sp->width[0] != 3 || sp->width[sp->nlayers] != c->Ht)
        rc = crom_err(CROM_EUSAGE, "the weight network goes %d -> %d, expected 3 -> %d", sp->width[0],
                      sp->width[sp->nlayers], c->Ht);
    if (!rc)
        rc = crom_skin_frame((size_t)nv, p->mesh->X, c->fem.mass, c->F);
    if (!rc)
        rc = buffers(c);
    if (rc) {
        crom_dfskin_ctx_free(c);
        return rc;
    }
    for (int v = 0; v < nv; v++)
        c->mask[v] = crom_skin_mask_at(p->mesh->X + 3 * (size_t)v, c->npins, c->pinX, c->ntri, c->triX, c->pin_length);
    c->mass = c->fem.total_mass;
    double D = crom_dftrain_diag(p->mesh);
    c->Eref = p->mat.E * c->fem.volume / (D * D);
    return 0;
}

/* The weights w [ns][H] of the drawn vertices from the network's output
 * (mask and constant handle), and their frame coordinates xh. */
static int weights_at(crom_dfskin_ctx *c)
{
    const double *X = c->P.mesh->X;
    int H = c->H, Ht = c->Ht, k = c->constant, ns = c->cub.ns, rc;
    const int *vs = c->cub.vs;
    for (int i = 0; i < ns; i++) {
        const double *x = X + 3 * (size_t)vs[i];
        for (int d = 0; d < 3; d++)
            c->xf[3 * i + d] = (float)x[d];
        double *xh = c->xh + 4 * (size_t)i;
        for (int a = 0; a < 3; a++)
            xh[a] = c->F[4 * a] * x[0] + c->F[4 * a + 1] * x[1] + c->F[4 * a + 2] * x[2] + c->F[4 * a + 3];
        xh[3] = 1;
    }
    if ((rc = crom_nn_mlp_forward(c->net, &c->ws, ns, c->xf, NULL)))
        return rc;
    const float *wt = crom_nn_ws_output(&c->ws);
    for (int i = 0; i < ns; i++) {
        double s = c->mask[vs[i]];
        if (k)
            c->w[(size_t)i * H] = 1;
        for (int h = 0; h < Ht; h++)
            c->w[(size_t)i * H + k + h] = s * wt[(size_t)i * Ht + h];
    }
    return 0;
}

/* The Gram matrix G = Σ m̂ w wᵀ / m̂ = L Lᵀ of the weights over the drawn
 * vertices, L⁻¹ (Li), and the whitened weights ŵ_v = L⁻¹ w_v (orthonormal
 * there) that the energy sees: it depends on their span only. CROM_EDATA
 * where the weights are linearly dependent there. */
static int whiten(crom_dfskin_ctx *c)
{
    int H = c->H, ns = c->cub.ns;
    double *G = c->G, *L = c->L, *Li = c->L + (size_t)H * H, mhat = c->cub.mhat;
    memset(G, 0, sizeof(double) * (size_t)H * H);
    for (int i = 0; i < ns; i++) {
        const double *wi = c->w + (size_t)i * H;
        double f = c->cub.mloc[i] / mhat;
        for (int a = 0; a < H; a++)
            for (int b = 0; b <= a; b++)
                G[a * H + b] += f * wi[a] * wi[b];
    }
    for (int a = 0; a < H; a++)
        for (int b = 0; b < H; b++) {
            if (b > a)
                G[a * H + b] = G[b * H + a];
            L[a * H + b] = b <= a ? G[a * H + b] : 0;
        }
    if (LAPACKE_dpotrf(LAPACK_ROW_MAJOR, 'L', H, L, H) != 0)
        return crom_err(CROM_EDATA, "the skinning weights became linearly dependent over the drawn tets");
    memcpy(Li, L, sizeof(double) * (size_t)H * H);
    if (LAPACKE_dtrtri(LAPACK_ROW_MAJOR, 'L', 'N', H, Li, H) != 0)
        return crom_err(CROM_EDATA, "the skinning weights' Gram matrix is singular");
    for (int a = 0; a < H; a++)
        for (int b = a + 1; b < H; b++)
            L[a * H + b] = Li[a * H + b] = 0;
    for (int i = 0; i < ns; i++) {
        const double *wi = c->w + (size_t)i * H;
        double *wh = c->wh + (size_t)i * H;
        for (int a = 0; a < H; a++) {
            double v = 0;
            for (int b = 0; b <= a; b++)
                v += Li[a * H + b] * wi[b];
            wh[a] = v;
        }
    }
    return 0;
}

/* Pose b's displacements u_v = Σ_h ŵ_hv Q_bh x̂_v (u scratch [3ns]), its
 * energy E_b over the drawn tets and its Rayleigh quotient R_b = E_b / d_b²,
 * d_b² = Σ m̂ |u|² / m̂ its mean squared displacement, with the gradient
 * dR/du = (g − (E/d²) 2 m̂ u / m̂) / d² in gu_b. Returns 1 where it is not
 * defined. */
static int pose_energy(crom_dfskin_ctx *c, int b, const double *q, int K, const int *tets, double *u)
{
    int H = c->H, ns = c->cub.ns, m3 = 3 * ns, bad;
    double *gb = c->gu + (size_t)b * m3, Eb, mhat = c->cub.mhat;
    const double *qb = q + (size_t)b * 12 * H, *mloc = c->cub.mloc;
    for (int i = 0; i < ns; i++) {
        const double *wi = c->wh + (size_t)i * H, *xh = c->xh + 4 * (size_t)i;
        for (int d = 0; d < 3; d++) {
            double s = 0;
            for (int h = 0; h < H; h++) {
                const double *Q = qb + 12 * (size_t)h + 4 * d;
                s += wi[h] * (Q[0] * xh[0] + Q[1] * xh[1] + Q[2] * xh[2] + Q[3]);
            }
            u[3 * i + d] = s;
        }
    }
    memset(gb, 0, sizeof(double) * (size_t)m3);
    bad = crom_dfloss_tets(&c->fem, K, tets, c->cub.wK, c->P.mesh->X, u, c->cub.loc, &Eb, gb);
    double d2 = 0;
    for (int i = 0; i < ns; i++)
        d2 += mloc[i] * (u[3 * i] * u[3 * i] + u[3 * i + 1] * u[3 * i + 1] + u[3 * i + 2] * u[3 * i + 2]);
    d2 /= mhat;
    if (!(d2 > 0))
        bad = 1;
    else {
        double R = Eb / d2;
        for (int i = 0; i < ns; i++)
            for (int d = 0; d < 3; d++)
                gb[3 * i + d] = (gb[3 * i + d] - R * 2 * mloc[i] * u[3 * i + d] / mhat) / d2;
    }
    c->E[b] = Eb;
    c->R[b] = d2 > 0 ? Eb / d2 : NAN;
    return bad;
}

/* dL/dŵ_hv = s Σ_b gu_bv · (Q_bh x̂_v), into dw. */
static void whitened_grad(crom_dfskin_ctx *c, int B, const double *q, double scale)
{
    int H = c->H, ns = c->cub.ns, m3 = 3 * ns;
    for (int i = 0; i < ns; i++) {
        const double *xh = c->xh + 4 * (size_t)i;
        double *dwi = c->dw + (size_t)i * H;
        for (int h = 0; h < H; h++) {
            double acc = 0;
            for (int b = 0; b < B; b++) {
                const double *g = c->gu + (size_t)b * m3 + 3 * (size_t)i, *Q = q + (size_t)b * 12 * H + 12 * (size_t)h;
                for (int d = 0; d < 3; d++)
                    acc += g[d] * (Q[4 * d] * xh[0] + Q[4 * d + 1] * xh[1] + Q[4 * d + 2] * xh[2] + Q[4 * d + 3]);
            }
            dwi[h] = scale * acc;
        }
    }
}

/* Back through the whitening ŵ_v = L⁻¹ w_v, G = L Lᵀ: with g_v = dL/dŵ_v
 * and S = Σ_v ŵ_v g_vᵀ, dL/dw_v = L⁻ᵀ g_v − 2 m̂_v/m̂ sym(P) w_v, P = L⁻ᵀ
 * Φ(Sᵀ) L⁻¹ (Φ: the lower triangle, diagonal halved; the derivative of the
 * Cholesky factor, δL = L Φ(L⁻¹ δG L⁻ᵀ)); dw in place. */
static void unwhiten_grad(crom_dfskin_ctx *c)
{
    int H = c->H, ns = c->cub.ns;
    double *Li = c->L + (size_t)H * H, *S = Li + (size_t)H * H, *T = S + (size_t)H * H, mhat = c->cub.mhat;
    memset(S, 0, sizeof(double) * (size_t)H * H);
    for (int i = 0; i < ns; i++) {
        const double *wh = c->wh + (size_t)i * H, *g = c->dw + (size_t)i * H;
        for (int a = 0; a < H; a++)
            for (int b = 0; b < H; b++)
                S[a * H + b] += wh[a] * g[b];
    }
    for (int a = 0; a < H; a++) /* T = Φ(Sᵀ) */
        for (int b = 0; b < H; b++)
            T[a * H + b] = b < a ? S[b * H + a] : b == a ? 0.5 * S[a * H + a] : 0;
    /* P = Li ᵀ T Li, kept in S */
    for (int a = 0; a < H; a++)
        for (int b = 0; b < H; b++) {
            double v = 0;
            for (int k = 0; k < H; k++)
                v += T[a * H + k] * Li[k * H + b];
            S[a * H + b] = v;
        }
    for (int a = 0; a < H; a++)
        for (int b = 0; b < H; b++) {
            double v = 0;
            for (int k = 0; k < H; k++)
                v += Li[k * H + a] * S[k * H + b];
            T[a * H + b] = v;
        }
    for (int a = 0; a < H; a++)
        for (int b = 0; b <= a; b++)
            S[a * H + b] = S[b * H + a] = 0.5 * (T[a * H + b] + T[b * H + a]);
    for (int i = 0; i < ns; i++) {
        const double *wi = c->w + (size_t)i * H;
        double *g = c->dw + (size_t)i * H, gn[CROM_DFSKIN_MAXH], f = 2 * c->cub.mloc[i] / mhat;
        for (int a = 0; a < H; a++) {
            double v = 0;
            for (int k = a; k < H; k++)
                v += Li[k * H + a] * g[k];
            for (int b = 0; b < H; b++)
                v -= f * S[a * H + b] * wi[b];
            gn[a] = v;
        }
        memcpy(g, gn, sizeof(double) * (size_t)H);
    }
}

/* The orthogonality of the raw weights: λ ‖G − I‖², with dL/dw_v = 4λ
 * m̂_v/m̂ (G − I) w_v added to dw (it keeps G, hence the whitening, well
 * conditioned). Returns ‖G − I‖² (G becomes G − I). */
static double ortho_term(crom_dfskin_ctx *c, double *obj)
{
    int H = c->H, ns = c->cub.ns;
    double pen = 0, lam = c->o.ortho_weight, *G = c->G;
    for (int a = 0; a < H; a++)
        G[a * H + a] -= 1;
    for (int a = 0; a < H * H; a++)
        pen += G[a] * G[a];
    *obj += lam * pen;
    for (int i = 0; i < ns; i++) {
        const double *wi = c->w + (size_t)i * H;
        double f = 4 * lam * c->cub.mloc[i] / c->cub.mhat;
        for (int a = 0; a < H; a++) {
            double v = 0;
            for (int b = 0; b < H; b++)
                v += G[a * H + b] * wi[b];
            c->dw[(size_t)i * H + a] += f * v;
        }
    }
    return pen;
}

/* The loss over the drawn tets (drawn already). */
static int drawn_loss(crom_dfskin_ctx *c, int B, const double *q, int K, const int *tets, crom_dftrain_terms *t,
                      float *grad)
{
    int H = c->H, Ht = c->Ht, k0 = c->constant, ns = c->cub.ns, rc;
    if ((rc = weights_at(c)) || (rc = whiten(c)))
        return rc;
#pragma omp parallel for num_threads(c->nthreads) schedule(static)
    for (int b = 0; b < B; b++)
        c->bad[b] = pose_energy(c, b, q, K, tets, c->U + (size_t)crom_dfloss_thread() * 3 * c->maxrows);
    if ((rc = crom_dfloss_check(B, c->bad, c->E, "pose")))
        return rc;
    double obj = 0, Em = 0, scale = 1.0 / (B * c->Eref);
    for (int b = 0; b < B; b++) {
        Em += c->E[b] / B;
        obj += c->R[b] * scale;
    }
    whitened_grad(c, B, q, scale);
    unwhiten_grad(c);
    double pen = ortho_term(c, &obj);
    if ((rc = crom_dfloss_terms(t, obj, Em, pen, 0, "skinning")) || !grad)
        return rc;
    for (int i = 0; i < ns; i++) /* through the mask to the network's outputs */
        for (int h = 0; h < Ht; h++)
            c->dwf[(size_t)i * Ht + h] = (float)(c->mask[c->cub.vs[i]] * c->dw[(size_t)i * H + k0 + h]);
    memset(grad, 0, sizeof(float) * c->net->nparams);
    return crom_nn_mlp_backward(c->net, &c->ws, ns, c->dwf, grad, NULL);
}

int crom_dfskin_loss(crom_dfskin_ctx *c, int B, const double *q, int K, const int *tets, crom_dftrain_terms *t,
                     float *grad)
{
    if (B < 1 || B > c->maxbatch || K < 1 || K > c->maxtets)
        return crom_err(CROM_EUSAGE, "batch of %d poses, %d tets (at most %d, %d)", B, K, c->maxbatch, c->maxtets);
    int rc = crom_dfloss_cub_draw(&c->cub, &c->fem, c->P.mat.rho, K, tets);
    if (!rc)
        rc = drawn_loss(c, B, q, K, tets, t, grad);
    crom_dfloss_cub_clear(&c->cub);
    return rc;
}

/* ============================================================ training */

/* Scale the network's last layer so that its weights start with unit mean
 * square over (up to maxrows random) vertices, mask included. */
static int init_scale(crom_dfskin_ctx *c, crom_nn_mlp *net, crom_rng *rng)
{
    int nv = c->P.mesh->nv, n = c->maxrows < nv ? c->maxrows : nv, Ht = c->Ht, rc;
    if (Ht == 0)
        return 0;
    for (int i = 0; i < n; i++) {
        int v = n == nv ? i : (int)crom_rng_below(rng, (uint64_t)nv);
        for (int d = 0; d < 3; d++)
            c->xf[3 * i + d] = (float)c->P.mesh->X[3 * (size_t)v + d];
        c->cub.vs[i] = v;
    }
    if ((rc = crom_nn_mlp_forward(net, &c->ws, n, c->xf, NULL)))
        return rc;
    const float *w = crom_nn_ws_output(&c->ws);
    double s2 = 0, mw = 0;
    for (int i = 0; i < n; i++) {
        double m = c->fem.mass[c->cub.vs[i]], s = c->mask[c->cub.vs[i]];
        mw += m;
        for (int h = 0; h < Ht; h++)
            s2 += m * s * s * w[(size_t)i * Ht + h] * w[(size_t)i * Ht + h];
    }
    double rms = sqrt(s2 / (mw * Ht));
    if (!(rms > 0) || !isfinite(rms))
        return crom_err(CROM_EDATA, "the initial weights are zero or not finite");
    crom_dftrain_scale_last(net, (float)(1 / rms));
    return 0;
}

/* Check the problem and the options, and fill in sigma and the pin
 * length (0.01 and 0.05 times the bounding-box diagonal) where they are
 * unset; *pinned: whether anything is pinned (else handle 0 is the
 * constant). */
static int check_skin(const crom_dfskin_problem *p, crom_dfskin_opts *o, int *pinned)
{
    const crom_mesh *mesh = p->mesh;
    int H = o->handles, rc;
    if (!p->virtual_tets && (rc = crom_dfskin_check_handles(mesh, p->fixed, H)))
        return rc;
    if (H < 1)
        return crom_err(CROM_EUSAGE, "--handles %d: a skinning subspace needs at least one handle", H);
    if (o->steps < 1 || o->batch < 1 || o->depth < 2 || o->width < 1 || o->tets < 1)
        return crom_err(CROM_EUSAGE, "steps, batch, depth (>= 2), width and tets must be positive");
    if (o->depth > CROM_NN_MAX_LAYERS)
        return crom_err(CROM_EUSAGE, "--depth %d: at most %d layers", o->depth, CROM_NN_MAX_LAYERS);
    double D = crom_dftrain_diag(mesh);
    if (!(o->sigma > 0))
        o->sigma = 0.01 * D;
    if (!(o->pin_length > 0))
        o->pin_length = 0.05 * D;
    if (!isfinite(o->sigma) || !isfinite(o->pin_length) || !(o->ortho_weight >= 0) || !isfinite(o->ortho_weight) ||
        !(o->lr > 0) || !isfinite(o->lr))
        return crom_err(CROM_EUSAGE, "non-finite or negative training weight");
    /* is there a pin? then every handle is masked, else handle 0 is constant */
    *pinned = p->npin > 0 || p->ntri > 0;
    for (int i = 0; !*pinned && p->fixed && i < 3 * mesh->nv; i++)
        *pinned = p->fixed[i] != 0;
    if (H - !*pinned < 1)
        return crom_err(CROM_EUSAGE, "--handles 1 on a free body is only its constant handle (affine motions): "
                        "train at least 2");
    return 0;
}

/* Weights in training: the options as used, the network and its gradient,
 * the loss, the scales of the pose coordinates, and the random streams of
 * the initialization and of the poses. */
typedef struct {
    crom_dfskin_opts o;
    crom_nn_mlp net;
    float *grad;
    crom_dfskin_ctx ctx;
    double *scale;           /* [12H] */
    crom_rng irng, srng;
} skin_trainer;

static void skin_free(skin_trainer *T)
{
    crom_dfskin_ctx_free(&T->ctx);
    crom_nn_mlp_free(&T->net);
    free(T->grad);
    free(T->scale);
}

/* The network 3 -> width x (depth - 1) -> H' with the input normalized to
 * the bounding box, the loss, the network scaled to unit weights; the
 * scales of the pose coordinates. */
static int skin_setup(skin_trainer *T, const crom_dfskin_problem *p, int pinned)
{
    const crom_dfskin_opts *o = &T->o;
    int nt = p->mesh->nt, H = o->handles, K = o->tets < nt ? o->tets : nt, rc;
    crom_nn_spec spec;
    if ((rc = crom_dftrain_spec(&spec, 3, o->width, o->depth, H - !pinned, o->act)))
        return rc;
    crom_dftrain_seed(o->seed, &T->irng, &T->srng);
    if ((rc = crom_nn_mlp_init(&T->net, &spec, NULL, &T->irng)) || (rc = crom_dftrain_norm_box(&T->net, p->mesh)))
        return rc;
    if ((rc = crom_dfskin_ctx_init(&T->ctx, p, o, &T->net, o->batch, K)))
        return rc;
    if (T->ctx.constant == pinned)
        return crom_err(CROM_EINTERNAL, "pin detection disagrees");
    if ((rc = init_scale(&T->ctx, &T->net, &T->srng)))
        return rc;
    T->grad = crom_malloc(sizeof(float) * T->net.nparams);
    T->scale = crom_malloc(sizeof(double) * 12 * (size_t)H);
    if (!T->grad || !T->scale)
        return CROM_EINTERNAL;
    /* pose coordinates: the translations Q_h[c][3] carry 90 % of the
     * variance, the linear parts Q_h[c][0..2] (times X̂, unit variance) the
     * rest, for an RMS displacement σ. A linear part weighs a weight's
     * gradient by |Q X̂|², large far from the centre, which steers the
     * weights' variation away from the ends where a clamped body bends most
     * (measured on a clamped bar, 16 handles, 3000 steps: static sag error
     * 28 % with every coordinate of equal variance, 13-18 % at 90 %, 21 % with
     * translations alone) */
    double tfrac = 0.9;
    double qt = o->sigma * sqrt(tfrac / (3.0 * H)), ql = o->sigma * sqrt((1 - tfrac) / (9.0 * H));
    for (int i = 0; i < 12 * H; i++)
        T->scale[i] = i % 4 == 3 ? qt : ql;
    return 0;
}

static int skin_loss(void *ctx, const double *q, double rho, int K, const int *tets, crom_dftrain_terms *t)
{
    skin_trainer *T = ctx;
    return crom_dfskin_loss(&T->ctx, T->o.batch, q, K, tets, t, T->grad);
}

/* Train the weights with Adam on random poses and a fresh random cubature
 * each step. */
static int skin_train(skin_trainer *T, const crom_dfskin_problem *p, crom_dftrain_log *log)
{
    const crom_dfskin_opts *o = &T->o;
    int nt = p->mesh->nt;
    log->sigma = o->sigma;
    log->Eref = T->ctx.Eref;
    crom_dftrain_loop L = {
        .loss = skin_loss, .ctx = T, .nblocks = 1, .params = {T->net.params}, .grad = {T->grad},
        .nparams = {T->net.nparams}, .rng = &T->srng, .batch = o->batch, .r = 12 * o->handles, .scale = T->scale,
        .K = o->tets < nt ? o->tets : nt, .nt = nt, .steps = o->steps, .minutes = o->minutes, .lr = o->lr,
        .hint = " (try a smaller --lr or --sigma)", .progress = o->progress, .progress_ctx = o->progress_ctx};
    return crom_dftrain_run(&L, log);
}

int crom_dfskin_train(const crom_dfskin_problem *p, const crom_dfskin_opts *o, crom_model *out,
                      crom_dftrain_log *log)
{
    crom_model_clear(out);
    memset(log, 0, sizeof *log);
    double t0 = crom_clock_now();
    skin_trainer T;
    memset(&T, 0, sizeof T);
    T.o = *o;
    int pinned, rc = check_skin(p, &T.o, &pinned);
    if (!rc)
        rc = skin_setup(&T, p, pinned);
    if (!rc)
        rc = skin_train(&T, p, log);
    if (!rc)
        rc = crom_skin_model_mlp(out, &T.net, T.o.handles, T.ctx.constant, T.ctx.F, T.ctx.npins, T.ctx.pinX,
                                 T.ctx.ntri, T.ctx.triX, T.ctx.pin_length);
    if (!rc)
        out->training_seconds = crom_clock_wall(crom_clock_now() - t0);
    skin_free(&T);
    if (rc)
        crom_dftrain_log_free(log);
    return rc;
}

int crom_dfskin_write_record(hid_t loc, const crom_dfskin_opts *o, const crom_dftrain_log *log, double mass)
{
    int rc = crom_h5_set_f64(loc, ".", "mass", &mass, 1);
    if (rc || !log)
        return rc;
    long long steps = log->steps, k = o->tets;
    rc = crom_h5_set_i64(loc, ".", "training_steps", steps);
    if (!rc)
        rc = crom_h5_set_f64(loc, ".", "sigma", &log->sigma, 1);
    if (!rc)
        rc = crom_h5_set_f64(loc, ".", "ortho_weight", &o->ortho_weight, 1);
    if (!rc)
        rc = crom_h5_set_i64(loc, ".", "cubature_tets", k);
    if (!rc)
        rc = crom_dftrain_log_write(loc, log);
    return rc;
}

/* ============================================================ eigen */

/* The scalar stiffness K_s of the free vertices (upper CSC, diagonal last):
 * (K_s)_ij = Σ_c K_(3i+c)(3j+c) from the rest Hessian K (the system's
 * pattern: a solid's or a shell's); vmap[v] the free index of vertex v or
 * -1. */
static int scalar_stiffness(const crom_system *fem, const double *Kv, const int *vmap, int nf, int **cp_out,
                            int **ri_out, double **val_out)
{
    int nv = fem->nv, rc = 0;
    int *cp = crom_calloc((size_t)nf + 1, sizeof(int)), *pos = crom_malloc(sizeof(int) * (size_t)nv);
    int *ri = NULL;
    double *val = NULL;
    if (!cp || !pos) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    /* pattern: column j holds the free vertices i <= j sharing a tet with it,
     * the rows of DOF column 3j that are x-DOFs (3i) */
    for (int v = 0; v < nv; v++) {
        int j = vmap[v];
        if (j < 0)
            continue;
        int c = 3 * v, cnt = 0;
        for (int k = fem->colptr[c]; k < fem->colptr[c + 1]; k++)
            cnt += fem->rowind[k] % 3 == 0 && vmap[fem->rowind[k] / 3] >= 0;
        cp[j + 1] = cnt;
    }
    for (int j = 0; j < nf; j++)
        cp[j + 1] += cp[j];
    ri = crom_malloc(sizeof(int) * (size_t)(cp[nf] ? cp[nf] : 1));
    val = crom_calloc((size_t)(cp[nf] ? cp[nf] : 1), sizeof(double));
    if (!ri || !val) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    for (int v = 0; v < nv; v++)
        pos[v] = -1;
    for (int v = 0; v < nv; v++) {
        int j = vmap[v];
        if (j < 0)
            continue;
        int e = cp[j];
        /* rows ascend in each DOF column, so free rows come out ascending
         * and the diagonal (i = j) last */
        for (int k = fem->colptr[3 * v]; k < fem->colptr[3 * v + 1]; k++) {
            int r = fem->rowind[k];
            if (r % 3 == 0 && vmap[r / 3] >= 0) {
                pos[r / 3] = e;
                ri[e++] = vmap[r / 3];
            }
        }
        for (int c = 0; c < 3; c++)
            for (int k = fem->colptr[3 * v + c]; k < fem->colptr[3 * v + c + 1]; k++) {
                int r = fem->rowind[k];
                if (r % 3 == c && vmap[r / 3] >= 0)
                    val[pos[r / 3]] += Kv[k];
            }
        for (int k = fem->colptr[3 * v]; k < fem->colptr[3 * v + 1]; k++)
            if (fem->rowind[k] % 3 == 0)
                pos[fem->rowind[k] / 3] = -1;
    }
    *cp_out = cp;
    *ri_out = ri;
    *val_out = val;
    cp = ri = NULL;
    val = NULL;
out:
    free(cp);
    free(pos);
    free(ri);
    free(val);
    return rc;
}

/* The weights w [nv][H] of the eigenvectors Y [H - constant][nf] (M-
 * orthonormal over the nf free vertices, vmap[v] the free index of v or -1)
 * after the constant handle of a free body: unit RMS over the body (sm =
 * sqrt of its mass), largest entry positive; their eigenvalues in eig. */
static void eigen_weights(double sm, int nv, const int *vmap, int nf, int H, int constant, const double *Y,
                          const double *lam, double *w, double *eig)
{
    for (int h = 0; h < H; h++) {
        int e = h - constant;
        const double *y = e >= 0 ? Y + (size_t)e * nf : NULL;
        double big = 0, sign = 1;
        for (int j = 0; y && j < nf; j++)
            if (fabs(y[j]) > big) {
                big = fabs(y[j]);
                sign = y[j] < 0 ? -1 : 1;
            }
        for (int v = 0; v < nv; v++)
            if (vmap[v] >= 0)
                w[(size_t)v * H + h] = y ? sign * sm * y[vmap[v]] : 1;
        eig[h] = y ? lam[e] : 0;
    }
}

int crom_dfskin_eigen(const crom_mesh *mesh, const crom_material *mat, const crom_scenario *materials,
                      const unsigned char *fixed, int H,
                   crom_model *out, long *solves)
{
    crom_model_clear(out);
    if (solves)
        *solves = 0;
    int rc = crom_dfskin_check_handles(mesh, fixed, H);
    if (rc)
        return rc;
    crom_system fem; /* a solid or a shell: its rest Hessian and lumped masses */
    if ((rc = crom_system_init(&fem, mesh, mat->E, mat->nu, mat->rho)))
        return rc;
    if (materials && (rc = crom_system_set_materials(&fem, materials, mesh))) {
        crom_system_free(&fem);
        return rc;
    }
    int nv = mesh->nv, nf = 0, np = 0, *vmap = crom_malloc(sizeof(int) * (size_t)nv);
    int *cp = NULL, *ri = NULL;
    double *Kv = crom_malloc(sizeof(double) * (size_t)fem.nnz), *Ks = NULL, *mf = NULL, *R = NULL;
    double *lam = NULL, *Y = NULL, *w = NULL, *eig = NULL;
    if (!vmap || !Kv) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    /* the unprojected Hessian at rest: linear elasticity */
    crom_fem_opts fo = {0, 0, NULL, 1};
    if ((rc = crom_system_assemble(&fem, mesh->X, &fo, NULL, NULL, Kv)))
        goto out;
    for (int v = 0; v < nv; v++) {
        int pin = crom_dfloss_pinned(fixed, v);
        np += pin;
        vmap[v] = !pin && fem.mass[v] > 0 ? nf++ : -1;
    }
    if ((rc = scalar_stiffness(&fem, Kv, vmap, nf, &cp, &ri, &Ks)))
        goto out;
    mf = crom_malloc(sizeof(double) * (size_t)nf);
    w = crom_calloc((size_t)nv * H, sizeof(double));
    eig = crom_calloc((size_t)H, sizeof(double));
    lam = crom_malloc(sizeof(double) * (size_t)H);
    Y = crom_malloc(sizeof(double) * (size_t)nf * H);
    R = crom_malloc(sizeof(double) * (size_t)nf);
    if (!mf || !w || !eig || !lam || !Y || !R) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    double mtot = 0;
    for (int v = 0; v < nv; v++)
        if (vmap[v] >= 0) {
            mf[vmap[v]] = fem.mass[v];
            mtot += fem.mass[v];
        }
    /* a free body: the constant, built (M-orthonormal), is handle 0 */
    int constant = np == 0, nr = constant;
    for (int j = 0; j < nf; j++)
        R[j] = 1 / sqrt(mtot);
    int nev = H - constant;
    if (nev > 0) {
        double D = 0, lo[3], hi[3];
        crom_mesh_bbox(mesh, lo, hi);
        for (int k = 0; k < 3; k++)
            D += (hi[k] - lo[k]) * (hi[k] - lo[k]);
        crom_sym K = {nf, cp, ri, Ks};
        crom_modes_opts mo;
        crom_modes_defaults(&mo);
        if ((rc = crom_modes_lowest(&K, mf, nr, nr ? R : NULL, nev, -0.01 * mat->E / (mat->rho * D), &mo, lam, Y,
                                    solves)))
            goto out;
    }
    eigen_weights(sqrt(fem.total_mass), nv, vmap, nf, H, constant, Y, lam, w, eig);
    double F[12];
    if ((rc = crom_skin_frame((size_t)nv, mesh->X, fem.mass, F)))
        goto out;
    rc = crom_skin_model_mesh(out, mesh, w, H, constant, F, eig);
out:
    crom_system_free(&fem);
    free(vmap);
    free(Kv);
    free(cp);
    free(ri);
    free(Ks);
    free(mf);
    free(R);
    free(lam);
    free(Y);
    free(w);
    free(eig);
    return rc;
}
