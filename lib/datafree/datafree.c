/* datafree.c — energy-trained and Neural-Modes subspaces (see datafree.h). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cblas.h>

#include "base/clock.h"
#include "base/err.h"
#include "base/rng.h"
#include "datafree/datafree.h"
#include "datafree/dffield.h"
#include "datafree/dfloss.h"
#include "io/io.h"
#include "phys/mderiv.h"
#include "phys/modes.h"

void crom_datafree_defaults(crom_datafree_opts *o, int objective)
{
    memset(o, 0, sizeof *o);
    int field = objective == CROM_DATAFREE_FIELD, nm = objective == CROM_DATAFREE_NEURALMODES;
    o->objective = objective;
    o->rank = nm ? 0 : 8;
    o->depth = field ? 4 : 6;
    o->width = 64;
    o->act = nm ? CROM_NN_GELU : CROM_NN_ELU;
    /* the one-mesh maps: many small steps at a larger rate (issue 14's
     * measurements, datafree.h); the field: as trained before */
    o->steps = field ? 2000 : 4000;
    o->lr = field ? 1e-3 : 3e-3;
    o->batch = field ? 32 : 8;
    o->lambda = field ? 1 : 0.03;
    o->ramp = 0.5;
    o->ortho_weight = 1e4;
    o->box_scaled = 1;
    o->features = 32;
    o->field_depth = 4;
    o->field_width = 64;
    o->tets = field ? 512 : 0;
    o->optimizer = CROM_DATAFREE_ADAM;
    o->resample = 10;
    o->tangent_weight = 0.03;
    o->tangent_floor = 0.03;
    o->tangent_radius = 0.1;
    o->pin_length = 0;
    o->threads = 1;
    o->seed = 1;
}

/* ============================================================ the loss */

void crom_datafree_ctx_free(crom_datafree_ctx *c)
{
    if (!c)
        return;
    crom_system_free(&c->sys);
    crom_nn_ws_free(&c->ws);
    free(c->mw);
    free(c->MWm);
    free(c->Y);
    free(c->G);
    free(c->dY);
    free(c->E);
    free(c->xb);
    free(c->zf);
    free(c->dyf);
    free(c->bad);
    free(c->cb);
    free(c->half);
    free(c->tg);
    free(c->cond);
    free(c->cond_mat);
    free(c->Ec);
    free(c->dxf);
    free(c->dcond);
    free(c->pinoff);
    free(c->lift);
    memset(c, 0, sizeof *c);
}

int crom_datafree_set_condition(crom_datafree_ctx *c, const double *cond)
{
    const crom_datafree_problem *p = &c->P;
    memcpy(c->grav, p->gravity, sizeof c->grav);
    for (int k = 0; k < p->ncond; k++) {
        double v = cond[k];
        if (!isfinite(v))
            return crom_err(CROM_EDATA, "condition %d is not finite", k + 1);
        c->cond[k] = v;
        if (p->cond[k].kind == CROM_SCENARIO_COND_GRAVITY) {
            c->grav[p->cond[k].axis] = v;
            continue;
        }
        if (p->cond[k].kind == CROM_SCENARIO_COND_PIN)
            continue;
        crom_material *m = &c->sys.mats[c->cond_mat[k]];
        if (!(v > 0) || crom_material_init(m, v * p->mat.E, m->nu, m->rho))
            return crom_err(CROM_EDATA, "ratio %g of region '%s': not a material", v, p->cond[k].ref);
    }
    if (c->pinoff) { /* the pins where c holds them, and the body's static lift */
        memset(c->pinoff, 0, sizeof(double) * (size_t)c->n);
        for (int k = 0; k < p->ncond; k++)
            if (p->cond[k].kind == CROM_SCENARIO_COND_PIN)
                cblas_daxpy(c->n, c->cond[k], c->lift + (size_t)k * c->n, 1, c->pinoff, 1);
    }
    return 0;
}

/* Pin condition k's unit move, e [3nv] (zeroed): 1 on the axis of its
 * region's vertices, every one of which must be pinned along it. */
static int pin_move(const crom_datafree_problem *p, int k, double *e)
{
    const crom_scenario_cond *cd = &p->cond[k];
    int *idx = NULL, nidx = 0, rc = crom_mesh_select(p->mesh, cd->ref, &idx, &nidx);
    if (rc)
        return crom_err_ctx("--condition pin:%s:%c", cd->ref, 'x' + cd->axis);
    for (int j = 0; !rc && j < nidx; j++) {
        size_t i = 3 * (size_t)idx[j] + cd->axis;
        if (!(p->fixed && p->fixed[i]))
            rc = crom_err(CROM_EUSAGE, "--condition pin:%s:%c: the region is not pinned (give --pin %s)", cd->ref,
                          'x' + cd->axis, cd->ref);
        e[i] = 1;
    }
    free(idx);
    return rc;
}

/* The static lift of each pin condition (phys/mderiv.h): the body's
 * small-displacement equilibrium with the region moved by 1 m along its
 * axis, at the middle of the ranges; zero for the other conditions. */
static int pin_lifts(crom_datafree_ctx *c, const crom_datafree_problem *p)
{
    int n = c->n, nc = p->ncond;
    double *e = crom_calloc((size_t)n * nc, sizeof(double));
    c->lift = crom_calloc((size_t)n * nc, sizeof(double));
    c->pinoff = crom_calloc((size_t)n, sizeof(double));
    if (!e || !c->lift || !c->pinoff) {
        free(e);
        return CROM_EINTERNAL;
    }
    int rc = 0;
    for (int k = 0; !rc && k < nc; k++)
        if (p->cond[k].kind == CROM_SCENARIO_COND_PIN)
            rc = pin_move(p, k, e + (size_t)k * n);
    if (rc) {
        free(e);
        return rc;
    }
    rc = crom_mderiv_lift(&c->sys, p->mesh->X, p->fixed, nc, e, c->lift);
    free(e); /* (the other conditions' columns: a zero move, a zero lift) */
    return rc ? crom_err_ctx("--condition pin") : 0;
}

/* A conditional problem's materials: each ratio's place in sys.mats, and
 * c at the middle of the ranges. */
static int cond_init(crom_datafree_ctx *c, const crom_datafree_problem *p, size_t rows)
{
    int nc = p->ncond;
    memcpy(c->grav, p->gravity, sizeof c->grav);
    if (!nc)
        return 0;
    if (c->o.objective != CROM_DATAFREE_ENERGY)
        return crom_err(CROM_EUSAGE, "--condition: only the energy objective is conditional");
    c->cond = crom_malloc(sizeof(double) * (size_t)nc);
    c->cond_mat = crom_malloc(sizeof(int) * (size_t)nc);
    c->Ec = crom_calloc((size_t)c->maxbatch * nc, sizeof(double));
    c->dxf = crom_malloc(sizeof(float) * rows * (size_t)c->in);
    c->dcond = crom_calloc((size_t)nc, sizeof(double));
    if (!c->cond || !c->cond_mat || !c->Ec || !c->dxf || !c->dcond)
        return CROM_EINTERNAL;
    double mid[CROM_MODEL_MAXCOND] = {0};
    for (int k = 0; k < nc; k++) {
        c->cond_mat[k] = -1;
        mid[k] = 0.5 * (p->cond[k].lo + p->cond[k].hi);
        if (p->cond[k].kind != CROM_SCENARIO_COND_RATIO)
            continue;
        for (int i = 0; p->materials && i < p->materials->nmat; i++)
            if (!strcmp(p->materials->mat[i].ref, p->cond[k].ref))
                c->cond_mat[k] = i + 1;
        if (c->cond_mat[k] < 0 || !c->sys.mats)
            return crom_err(CROM_EUSAGE, "--condition ratio:%s: the region has no material of its own",
                            p->cond[k].ref);
    }
    int rc = crom_datafree_set_condition(c, mid), pins = 0;
    for (int k = 0; k < nc; k++)
        pins |= p->cond[k].kind == CROM_SCENARIO_COND_PIN;
    if (rc || !pins || (rc = pin_lifts(c, p))) /* (at the middle's materials) */
        return rc;
    return crom_datafree_set_condition(c, mid);
}

/* neuralmodes: M W / m, the box (half-width a for every mode, or a f_1 /
 * f_k for mode k: the same linear energy ½ m ω_k² a_k² at every edge) and
 * the energy unit E_ref = ½ m ω² a² (E V if that is zero). */
static void modes_box(crom_datafree_ctx *c, const crom_datafree_problem *p, const crom_datafree_opts *o, double EV)
{
    int r = c->r, n = c->n;
    for (int i = 0; i < n; i++)
        for (int k = 0; k < r; k++)
            c->MWm[(size_t)i * r + k] = c->mw[i] * p->modes[(size_t)i * r + k];
    double fmax = 0, fmin = INFINITY;
    for (int k = 0; p->freq && k < r; k++) {
        fmax = fmax > p->freq[k] ? fmax : p->freq[k];
        if (p->freq[k] > 0)
            fmin = fmin < p->freq[k] ? fmin : p->freq[k];
    }
    int scaled = o->box_scaled && isfinite(fmin);
    for (int k = 0; k < r; k++)
        c->half[k] = scaled ? crom_modes_box_half(p->freq, r, o->box, k) : o->box;
    double w = 2 * M_PI * (scaled ? fmin : fmax);
    c->Eref = 0.5 * c->mass * w * w * o->box * o->box;
    if (!(c->Eref > 0) || !isfinite(c->Eref))
        c->Eref = EV;
}

/* A scene's size: the bounding-box diagonal of its frame vertices and its
 * joints' points (a pendulum's reaches its pivot). */
static double scene_size(const crom_mesh *m)
{
    const crom_scene *sc = m->scene;
    double lo[3], hi[3], d2 = 0;
    crom_mesh_bbox(m, lo, hi);
    for (int j = 0; j < sc->nj; j++)
        for (int k = 0; k < 3; k++) {
            lo[k] = fmin(lo[k], sc->joints[j].point[k]);
            hi[k] = fmax(hi[k], sc->joints[j].point[k]);
        }
    for (int k = 0; k < 3; k++)
        d2 += (hi[k] - lo[k]) * (hi[k] - lo[k]);
    return sqrt(d2);
}

int crom_datafree_ctx_init(crom_datafree_ctx *c, const crom_datafree_problem *p, const crom_datafree_opts *o,
                           const crom_nn_mlp *net, int maxbatch)
{
    memset(c, 0, sizeof *c);
    c->P = *p;
    c->o = *o;
    c->net = net;
    const crom_nn_spec *sp = &net->spec;
    int r = sp->width[0] - p->ncond, n = 3 * p->mesh->nv, nm = o->objective == CROM_DATAFREE_NEURALMODES;
    if (p->ncond < 0 || p->ncond > CROM_MODEL_MAXCOND || r < 1)
        return crom_err(CROM_EUSAGE, "%d conditions for a network of %d inputs", p->ncond, sp->width[0]);
    if (sp->width[sp->nlayers] != n)
        return crom_err(CROM_EUSAGE, "the map's network outputs %d values, the mesh has 3nv = %d",
                        sp->width[sp->nlayers], n);
    if (maxbatch < 1)
        return crom_err(CROM_EUSAGE, "batch of %d samples", maxbatch);
    if (nm && !p->modes)
        return crom_err(CROM_EUSAGE, "neuralmodes needs linear modes");
    if (!nm && !(o->sigma > 0))
        return crom_err(CROM_EUSAGE, "sigma must be positive");
    if (nm && !(o->box > 0))
        return crom_err(CROM_EUSAGE, "the latent box must be positive");
    c->r = r;
    c->in = sp->width[0];
    c->n = n;
    c->maxbatch = maxbatch;
    c->B0 = !nm && o->tangent_weight > 0 ? r : 0; /* the secants along the r axes */
    if (c->B0 && !(o->tangent_floor > 0 && o->tangent_floor <= 1))
        return crom_err(CROM_EUSAGE, "--tangent-floor %g: the collapse floor must be in (0, 1]", o->tangent_floor);
    c->nthreads = crom_dftrain_threads(o->threads);
    int ta = nm && o->tangent_anchor;
    /* the batch, the tangent samples, the anchor (then, tangent-anchored, ±ε z_b) */
    size_t rows = (size_t)maxbatch + c->B0 + 1 + (ta ? 2 * (size_t)maxbatch : 0);
    int rc = (crom_mesh_is_surface(p->mesh) || crom_mesh_is_scene(p->mesh)) && o->tets > 0
                 ? crom_err(CROM_EUSAGE, "--tets %d: a random cubature of tets applies to solids; a shell's or a "
                                         "scene's map integrates every element", o->tets)
                 : crom_system_init(&c->sys, p->mesh, p->mat.E, p->mat.nu, p->mat.rho);
    if (!rc && p->materials)
        rc = crom_system_set_materials(&c->sys, p->materials, p->mesh);
    if (!rc)
        rc = crom_nn_ws_init(&c->ws, net, (int)rows, 1);
    if (!rc)
        rc = cond_init(c, p, rows);
    if (rc) {
        crom_datafree_ctx_free(c);
        return rc;
    }
    c->mw = crom_malloc(sizeof(double) * (size_t)n);
    c->MWm = nm ? crom_malloc(sizeof(double) * (size_t)n * r) : NULL;
    c->Y = crom_malloc(sizeof(double) * rows * n);
    c->G = crom_malloc(sizeof(double) * (size_t)maxbatch * n);
    c->dY = crom_malloc(sizeof(double) * rows * n);
    c->E = crom_malloc(sizeof(double) * (size_t)maxbatch);
    c->xb = crom_malloc(sizeof(double) * (size_t)c->nthreads * n);
    c->zf = crom_malloc(sizeof(float) * rows * (size_t)c->in);
    c->dyf = crom_malloc(sizeof(float) * rows * n);
    c->bad = crom_malloc(sizeof(int) * (size_t)maxbatch);
    c->cb = crom_malloc(sizeof(double) * (size_t)(r > c->B0 ? r : c->B0));
    c->half = crom_malloc(sizeof(double) * (size_t)r);
    c->tg = crom_malloc(sizeof(double) * (3 * (size_t)r * r + r));
    if (!c->tg || !c->cb || !c->half || !c->mw || (nm && !c->MWm) || !c->Y || !c->G || !c->dY || !c->E || !c->xb || !c->zf ||
        !c->dyf || !c->bad) {
        crom_datafree_ctx_free(c);
        return CROM_EINTERNAL;
    }
    c->mass = c->sys.total_mass;
    for (int i = 0; i < n; i++)
        c->mw[i] = c->sys.mass[i / 3] / c->mass;
    double EV = p->mat.E * c->sys.volume;
    if (c->sys.rigid) /* a scene has no modulus: its weight lifted by its size */
        EV = c->mass * 9.81 * scene_size(p->mesh);
    c->Eref = EV;
    if (nm)
        modes_box(c, p, o, EV);
    if (nm && p->nsup > 0) { /* the equilibria must be in these modes: W^T M u* / m = z */
        double dev = 0, zs = 0;
        for (int k = 0; k < p->nsup; k++) {
            cblas_dgemv(CblasRowMajor, CblasTrans, n, r, 1.0, c->MWm, r, p->sup_u + (size_t)k * n, 1, 0.0, c->cb, 1);
            for (int a = 0; a < r; a++) {
                double zk = p->sup_z[(size_t)k * r + a];
                dev = fmax(dev, fabs(c->cb[a] - zk));
                zs = fmax(zs, fabs(zk));
            }
        }
        if (!(dev <= 1e-6 * zs + 1e-15)) {
            crom_datafree_ctx_free(c);
            return crom_err(CROM_EUSAGE, "the equilibria were not taken in these modes: W^T M u* / m is %.3g m from "
                            "their modal coordinates", dev);
        }
    }
    return 0;
}

/* Sampling along a run: the largest move of a sample from the visited
 * point it is drawn near, relative to max(a_k, |z_k|) (datafree.h). */
#define VISIT_JITTER 0.15

void crom_datafree_visit_draw(int normal, int B, int B0, int r, const double *z, const double *half, long nvisit,
                              const double *visit_z, double *out)
{
    for (int b = 0; b < B; b++) {
        const double *zb = z + (size_t)b * r;
        double *y = out + (size_t)b * r;
        if (b % 2 == 0) {
            memcpy(y, zb, sizeof(double) * (size_t)r);
            continue;
        }
        /* the visited point, picked by the draw's first coordinate (so the batch stays fixed while L-BFGS
         * iterates on it): Φ(z_0) of a normal draw, or a uniform one in the box */
        double u = (normal ? 0.5 * erfc(-zb[0] / sqrt(2.0)) : 0.5 * (zb[0] / half[0] + 1)) * (double)nvisit;
        long k = (long)u;
        k = k < 0 ? 0 : k >= nvisit ? nvisit - 1 : k;
        const double *v = visit_z + (size_t)k * r;
        for (int a = 0; a < r; a++) { /* (coordinate 0's jitter from the rest of its draw, in [-1, 1]) */
            double w = a ? (normal ? zb[a] : zb[a] / half[a]) : 2 * (u - (double)k) - 1;
            y[a] = v[a] + VISIT_JITTER * w * (normal ? 1 : fmax(half[a], fabs(v[a])));
        }
    }
    memcpy(out + (size_t)B * r, z + (size_t)B * r, sizeof(double) * (size_t)B0 * r); /* the samples after the batch */
}

/* The step of the central difference that stands for J_N(0) z in a
 * tangent-anchored map's training (relative to z; datafree.h). */
#define TANGENT_EPS 1e-2

static int tangent_anchored(const crom_datafree_ctx *c)
{
    return c->o.objective == CROM_DATAFREE_NEURALMODES && c->o.tangent_anchor;
}

/* The network at the batch, the tangent samples, then z = 0: the anchor
 * N(0) that every sample is taken relative to (lib/rom/map.h), Y_b = N(z_b)
 * − N(0); pinned outputs do not exist (the mask is part of the map). */
static int map_outputs(crom_datafree_ctx *c, int B, const double *z)
{
    int r = c->r, n = c->n, Bt = B + c->B0, ta = tangent_anchored(c), in = c->in, rows = Bt + 1 + (ta ? 2 * B : 0);
    const unsigned char *fixed = c->P.fixed;
    for (int b = 0; b < Bt; b++)
        for (int k = 0; k < r; k++)
            c->zf[(size_t)b * in + k] = (float)z[(size_t)b * r + k];
    memset(c->zf + (size_t)Bt * in, 0, sizeof(float) * (size_t)r);
    for (int b = 0; ta && b < B; b++) /* rows Bt + 1 + b: +ε z_b; Bt + 1 + B + b: −ε z_b */
        for (int k = 0; k < r; k++) {
            float v = (float)(TANGENT_EPS * z[(size_t)b * r + k]);
            c->zf[(size_t)(Bt + 1 + b) * in + k] = v;
            c->zf[(size_t)(Bt + 1 + B + b) * in + k] = -v;
        }
    for (int b = 0; b < rows; b++) /* a conditional map: the batch's c on every row, the anchor's too */
        for (int k = r; k < in; k++)
            c->zf[(size_t)b * in + k] = (float)c->cond[k - r];
    int rc = crom_nn_mlp_forward(c->net, &c->ws, rows, c->zf, NULL);
    if (rc)
        return rc;
    const float *Yf = crom_nn_ws_output(&c->ws), *Y0 = Yf + (size_t)Bt * n;
    for (int b = 0; b < Bt; b++)
        for (int i = 0; i < n; i++)
            c->Y[(size_t)b * n + i] = (double)Yf[(size_t)b * n + i] - (double)Y0[i];
    for (int b = 0; ta && b < B; b++) { /* − J_N(0) z_b, by the central difference */
        const float *Yp = Yf + (size_t)(Bt + 1 + b) * n, *Ym = Yf + (size_t)(Bt + 1 + B + b) * n;
        for (int i = 0; i < n; i++)
            c->Y[(size_t)b * n + i] -= ((double)Yp[i] - (double)Ym[i]) / (2 * TANGENT_EPS);
    }
    if (fixed)
        for (int b = 0; b < Bt; b++)
            for (int i = 0; i < n; i++)
                if (fixed[i])
                    c->Y[(size_t)b * n + i] = 0;
    return 0;
}

/* Sample b's potential energy E_b and its gradient G_b at x = X + u_s + W z_b +
 * ρ Y_b (x scratch [n]; u_s the seed state, or 0): the elastic energy over every tet (tets NULL) or
 * the K drawn ones, and (energy objective) gravity, −Σ_v m_v g·u_v.
 * Returns 1 where it is not defined. */
static int sample_energy(crom_datafree_ctx *c, int b, const double *zb, double rho, int K, const int *tets, double *x)
{
    int r = c->r, n = c->n, nm = c->o.objective == CROM_DATAFREE_NEURALMODES, bad;
    const unsigned char *fixed = c->P.fixed;
    const double *X = c->P.mesh->X, *Y = c->Y + (size_t)b * n, *g = c->grav, *Wm = c->P.modes;
    const crom_system *sys = &c->sys;
    const crom_fem *fem = &sys->fem;
    double *G = c->G + (size_t)b * n, Eb = 0;
    const double *Psi = nm ? c->P.deriv : NULL;
    for (int i = 0; i < n; i++) {
        double u = rho * Y[i];
        if (nm)
            for (int k = 0; k < r; k++)
                u += Wm[(size_t)i * r + k] * zb[k];
        for (int k = 0, cq = 0; Psi && k < r; k++) /* ½ Σ_{k<=l} Ψ_kl z_k z_l */
            for (int l = k; l < r; l++, cq++)
                u += 0.5 * Psi[((size_t)i * r * (r + 1)) / 2 + cq] * zb[k] * zb[l];
        x[i] = X[i] + (c->P.seed ? c->P.seed[i] : 0) + (c->pinoff ? c->pinoff[i] : 0) + u;
    }
    if (!tets) { /* (a pin condition needs the force on the pinned DOFs too) */
        crom_fem_opts fo = {0, 0, c->pinoff ? NULL : fixed, 1};
        bad = crom_system_assemble(sys, x, &fo, &Eb, G, NULL);
    } else { /* K random tets, each standing for nt/K of them */
        memset(G, 0, sizeof(double) * (size_t)n);
        bad = crom_dfloss_tets(fem, K, tets, (double)fem->nt / K, NULL, x, NULL, &Eb, G);
    }
    if (!nm) /* gravity: -Σ m_v g·u_v */
        for (int i = 0; i < n; i++) {
            if (fixed && fixed[i])
                continue;
            double mg = sys->mass[i / 3] * g[i % 3];
            Eb -= mg * (x[i] - X[i]);
            G[i] -= mg;
        }
    for (int k = 0; !bad && k < c->P.ncond; k++) /* ∂E_b/∂c_k of a pin: along its lift, pinned DOFs too */
        if (c->P.cond[k].kind == CROM_SCENARIO_COND_PIN)
            c->Ec[(size_t)b * c->P.ncond + k] = cblas_ddot(n, G, 1, c->lift + (size_t)k * n, 1);
    for (int i = 0; fixed && (tets || c->pinoff) && i < n; i++)
        if (fixed[i])
            G[i] = 0;
    c->E[b] = Eb;
    for (int k = 0; !bad && k < c->P.ncond; k++) { /* ∂E_b/∂c_k: the energy is linear in both */
        double d = 0;
        if (c->P.cond[k].kind == CROM_SCENARIO_COND_PIN)
            continue;
        if (c->P.cond[k].kind == CROM_SCENARIO_COND_GRAVITY) {
            for (int v = 0; v < n / 3; v++)
                if (!(fixed && fixed[3 * v]))
                    d -= sys->mass[v] * (x[3 * v + c->P.cond[k].axis] - X[3 * v + c->P.cond[k].axis]);
        } else { /* the region's tets' energy over the ratio (Ψ is linear in E at a fixed ν) */
            for (int t = 0; t < fem->nt; t++)
                if (sys->tmat[t] == c->cond_mat[k]) {
                    double xe[12];
                    crom_fem_tet_positions(fem, x, t, xe);
                    d += crom_system_elem_energy(sys, t, xe);
                }
            d /= c->cond[k];
        }
        c->Ec[(size_t)b * c->P.ncond + k] = d;
    }
    return bad;
}

/* The energy term 1/B Σ_b E_b / E_ref and its gradient dY_b = ρ s G_b. */
static void energy_term(crom_datafree_ctx *c, int B, double rho, double *obj, double *Em)
{
    int n = c->n;
    double scale = 1.0 / (B * c->Eref);
    for (int b = 0; b < B; b++) {
        *Em += c->E[b] / B;
        *obj += c->E[b] * scale;
        const double *G = c->G + (size_t)b * n;
        double *dY = c->dY + (size_t)b * n;
        for (int i = 0; i < n; i++)
            dY[i] = rho * scale * G[i];
    }
}

/* Supervised: the geometric term 1/B Σ_b |u(z_b) − u*_b|²_M / (m a²) of
 * the map's displacement u = W z + (½ Σ Ψ z z) + Y_b against equilibrium
 * sup[b], and its gradient dY_b (the energy is only recorded). */
static void data_term(crom_datafree_ctx *c, int B, const double *z, double *obj, double *Em)
{
    int r = c->r, n = c->n;
    const double *Wm = c->P.modes, *Psi = c->P.deriv;
    double a2 = c->o.box * c->o.box;
    for (int b = 0; b < B; b++) {
        const double *zb = z + (size_t)b * r, *us = c->P.sup_u + (size_t)c->sup[b] * n, *Y = c->Y + (size_t)b * n;
        double *dY = c->dY + (size_t)b * n, e2 = 0;
        *Em += c->E[b] / B;
        for (int i = 0; i < n; i++) {
            double u = Y[i];
            for (int k = 0; k < r; k++)
                u += Wm[(size_t)i * r + k] * zb[k];
            for (int k = 0, cq = 0; Psi && k < r; k++)
                for (int l = k; l < r; l++, cq++)
                    u += 0.5 * Psi[((size_t)i * r * (r + 1)) / 2 + cq] * zb[k] * zb[l];
            double d = u - us[i];
            e2 += c->mw[i] * d * d;
            dY[i] = 2 * c->mw[i] * d / (B * a2);
        }
        *obj += e2 / (B * a2);
    }
}

/* The isometry over the pairs of the batch: λ mean_{b<c} ℓ², ℓ = ½ log D²
 * − log(σ |z_b − z_c|) (the anchor cancels in the differences). */
static void isometry_term(crom_datafree_ctx *c, int B, const double *z, double *obj, double *pen)
{
    int r = c->r, n = c->n;
    double npairs = 0.5 * B * (B - 1), lam = c->o.lambda, ls = log(c->o.sigma);
    for (int b = 0; b < B; b++)
        for (int e = b + 1; e < B; e++) {
            const double *Yb = c->Y + (size_t)b * n, *Ye = c->Y + (size_t)e * n;
            double dz = 0, D2 = 0;
            for (int k = 0; k < r; k++) {
                double d = z[(size_t)b * r + k] - z[(size_t)e * r + k];
                dz += d * d;
            }
            for (int i = 0; i < n; i++) {
                double d = Yb[i] - Ye[i];
                D2 += c->mw[i] * d * d;
            }
            if (!(D2 > 0) || !(dz > 0))
                continue;
            double l = 0.5 * log(D2) - 0.5 * log(dz) - ls;
            *pen += l * l / npairs;
            *obj += lam * l * l / npairs;
            double coef = lam / npairs * 2 * l / D2;
            double *dYb = c->dY + (size_t)b * n, *dYe = c->dY + (size_t)e * n;
            for (int i = 0; i < n; i++) {
                double v = coef * c->mw[i] * (Yb[i] - Ye[i]);
                dYb[i] += v;
                dYe[i] -= v;
            }
        }
}

/* The collapse floor at rest: λ_0 Σ_k h(μ_k) (crom_dfloss_rest_floor)
 * over the Gram matrix G_kl = Σ_i (m_i/m) Y_k[i] Y_l[i] of the r tangent
 * samples, the secants z = ε e_k from rest; dL/dY_k = 2 Σ_l A_kl M Y_l / m.
 * It leaves the map free while every normalized eigenvalue is above the
 * floor τ, and keeps a latent direction from collapsing at rest, where
 * every run starts. */
static void tangent_term(crom_datafree_ctx *c, int B, double *obj, double *tan)
{
    int r = c->r, n = c->n, B0 = c->B0;
    double *Gr = c->tg, *A = Gr + (size_t)r * r, *work = A + (size_t)r * r;
    const double *Ys = c->Y + (size_t)B * n;
    double *dYs = c->dY + (size_t)B * n; /* scratch first: √(m_i/m) Y_k[i] */
    for (int k = 0; k < B0; k++)
        for (int i = 0; i < n; i++)
            dYs[(size_t)k * n + i] = sqrt(c->mw[i]) * Ys[(size_t)k * n + i];
    cblas_dsyrk(CblasRowMajor, CblasUpper, CblasNoTrans, B0, n, 1.0, dYs, n, 0.0, Gr, B0);
    double h = crom_dfloss_rest_floor(B0, Gr, c->o.tangent_floor, c->o.tangent_weight, A, work);
    memset(dYs, 0, sizeof(double) * (size_t)B0 * n);
    if (!isfinite(h)) /* (no motion along an axis at all: the energy decides) */
        return;
    *tan += h;
    *obj += c->o.tangent_weight * h;
    cblas_dgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, B0, n, B0, 2.0, A, B0, Ys, n, 0.0, dYs, n);
    for (int k = 0; k < B0; k++)
        for (int i = 0; i < n; i++)
            dYs[(size_t)k * n + i] *= c->mw[i];
}

/* neuralmodes: the M-orthogonality of y(z) − y(0) to the modes, w_o/B
 * Σ_b ‖Wᵀ M Y_b / m‖² / a². */
static void ortho_term(crom_datafree_ctx *c, int B, double *obj, double *pen)
{
    int r = c->r, n = c->n;
    double a2 = c->o.box * c->o.box, wo = c->o.ortho_weight, *cp = c->cb;
    for (int b = 0; b < B; b++) {
        const double *Yb = c->Y + (size_t)b * n;
        cblas_dgemv(CblasRowMajor, CblasTrans, n, r, 1.0, c->MWm, r, Yb, 1, 0.0, cp, 1);
        double o2 = 0;
        for (int k = 0; k < r; k++)
            o2 += cp[k] * cp[k];
        o2 /= a2;
        *pen += o2 / B;
        *obj += wo * o2 / B;
        /* d/dY_b of wo/B ‖c‖²/a² = 2 wo/(B a²) M W c / m */
        cblas_dgemv(CblasRowMajor, CblasNoTrans, n, r, 2 * wo / (B * a2), c->MWm, r, cp, 1, 1.0,
                    c->dY + (size_t)b * n, 1);
    }
}

int crom_datafree_loss(crom_datafree_ctx *c, int B, const double *z, double rho, int K, const int *tets,
                       crom_dftrain_terms *t, float *grad)
{
    int r = c->r, nm = c->o.objective == CROM_DATAFREE_NEURALMODES, rows = B + c->B0 + 1, rc;
    if (B < 1 || B > c->maxbatch)
        return crom_err(CROM_EUSAGE, "batch of %d samples (at most %d)", B, c->maxbatch);
    for (int k = 0; tets && k < K; k++)
        if (tets[k] < 0 || tets[k] >= c->sys.fem.nt)
            return crom_err(CROM_EUSAGE, "tet %d out of range", tets[k]);
    if (tets && K < 1)
        return crom_err(CROM_EUSAGE, "a cubature of %d tets", K);
    rho = nm ? 1 : rho < 0 ? 0 : rho > 1 ? 1 : rho;
    if ((rc = map_outputs(c, B, z)))
        return rc;
#pragma omp parallel for num_threads(c->nthreads) schedule(static)
    for (int b = 0; b < B; b++)
        c->bad[b] = sample_energy(c, b, z + (size_t)b * r, rho, K, tets, c->xb + (size_t)crom_dfloss_thread() * c->n);
    if ((rc = crom_dfloss_check(B, c->bad, c->E, "sample")))
        return rc;
    double obj = 0, Em = 0, pen = 0, tan = 0;
    if (nm && c->P.nsup > 0) {
        if (!c->sup)
            return crom_err(CROM_EUSAGE, "a supervised loss needs the batch's equilibria");
        data_term(c, B, z, &obj, &Em);
    } else {
        energy_term(c, B, rho, &obj, &Em);
    }
    if (!nm && B >= 2)
        isometry_term(c, B, z, &obj, &pen);
    if (c->B0 > 0)
        tangent_term(c, B, &obj, &tan);
    if (nm)
        ortho_term(c, B, &obj, &pen);
    if ((rc = crom_dfloss_terms(t, obj, Em, pen, tan, "data-free")))
        return rc;
    if (!grad)
        return 0;
    /* through the anchor: dL/dN(z_b) = dY_b, dL/dN(0) = −Σ_b dY_b; tangent-
     * anchored also dL/dN(±ε z_b) = ∓dY_b / 2ε */
    crom_dfloss_anchor_grad(rows, c->n, c->dY, c->P.fixed, c->dyf);
    int ta = tangent_anchored(c), all = rows + (ta ? 2 * B : 0);
    for (int b = 0; ta && b < B; b++) {
        float *fp = c->dyf + (size_t)(rows + b) * c->n, *fm = c->dyf + (size_t)(rows + B + b) * c->n;
        const float *db = c->dyf + (size_t)b * c->n;
        for (int i = 0; i < c->n; i++) {
            fp[i] = (float)(-db[i] / (2 * TANGENT_EPS));
            fm[i] = -fp[i];
        }
    }
    memset(grad, 0, sizeof(float) * c->net->nparams);
    if ((rc = crom_nn_mlp_backward(c->net, &c->ws, all, c->dyf, grad, c->P.ncond ? c->dxf : NULL)))
        return rc;
    for (int k = 0; k < c->P.ncond; k++) { /* dL/dc: through every row's input, and the energy's own */
        double d = 0;
        for (int b = 0; b < all; b++)
            d += c->dxf[(size_t)b * c->in + r + k];
        for (int b = 0; b < B && !(nm && c->P.nsup > 0); b++)
            d += c->Ec[(size_t)b * c->P.ncond + k] / (B * c->Eref);
        c->dcond[k] = d;
    }
    return 0;
}

/* ============================================================ training */

/* Check the problem and the options of a map, and fill in sigma and box
 * (0.05 and 0.2 times the bounding-box diagonal) where they are unset. */
static int check_map(const crom_datafree_problem *p, crom_datafree_opts *o)
{
    const crom_mesh *mesh = p->mesh;
    int nv = mesh->nv, n = 3 * nv, nm = o->objective == CROM_DATAFREE_NEURALMODES, r = o->rank;
    if (o->objective != CROM_DATAFREE_ENERGY && !nm)
        return crom_err(CROM_EUSAGE, "unknown data-free objective %d", o->objective);
    int nfree = 0;
    for (int i = 0; i < n; i++)
        nfree += !(p->fixed && p->fixed[i]);
    if (r < 1)
        return crom_err(CROM_EUSAGE, "--rank %d must be positive", r);
    if (r > nfree)
        return crom_err(CROM_EUSAGE, "--rank %d: a %d-dimensional latent for a body with only %d free degrees of "
                        "freedom (%d vertices, %d pinned DOFs)", r, r, nfree, nv, n - nfree);
    if (nfree == 0)
        return crom_err(CROM_EUSAGE, "every degree of freedom is pinned");
    double gn = fabs(p->gravity[0]) + fabs(p->gravity[1]) + fabs(p->gravity[2]);
    int held = 0; /* a scene held to the world by a penalty joint */
    for (int j = 0; p->mesh->scene && j < p->mesh->scene->nj; j++)
        held |= p->mesh->scene->joints[j].b < 0 && p->mesh->scene->joints[j].weight > 0;
    if (!nm && gn > 0 && nfree == n && !held)
        return crom_err(CROM_EUSAGE, "a free body under gravity has no lowest energy (it falls forever): pin a "
                        "region (--pin) or train with --gravity 0,0,0");
    if ((o->steps < 1 && !(nm && o->steps == 0)) || o->batch < 1 || o->depth < 2 || o->width < 1)
        return crom_err(CROM_EUSAGE, "steps, batch, depth and width must be positive (depth >= 2; neuralmodes: "
                                     "steps may be 0)");
    if (!nm && o->batch < 2)
        return crom_err(CROM_EUSAGE, "--batch %d: the isometry term needs pairs (at least 2 samples)", o->batch);
    if (nm && p->nvisit > 0 && o->batch < 2)
        return crom_err(CROM_EUSAGE, "--batch %d: sampling along a run (--latents) draws every other sample near it "
                        "(at least 2 samples)", o->batch);
    double diag = crom_dftrain_diag(mesh);
    if (!(o->sigma > 0))
        o->sigma = 0.05 * diag;
    if (!(o->box > 0))
        o->box = 0.2 * diag;
    if (!isfinite(o->sigma) || !isfinite(o->lambda) || o->lambda < 0 || !isfinite(o->box) ||
        !isfinite(o->ortho_weight) || o->ortho_weight < 0 ||
        !(o->lr > 0) || !isfinite(o->lr) || !(o->ramp >= 0 && o->ramp <= 1))
        return crom_err(CROM_EUSAGE, "non-finite or negative training weight");
    if (o->depth > CROM_NN_MAX_LAYERS)
        return crom_err(CROM_EUSAGE, "--depth %d: at most %d layers", o->depth, CROM_NN_MAX_LAYERS);
    return 0;
}

/* A map in training: the options as used, its network (over params) and
 * gradient, the loss, and the random streams of the initialization and
 * of the samples. */
typedef struct {
    crom_datafree_opts o;
    crom_nn_mlp net;
    float *params, *grad;
    size_t np;
    crom_datafree_ctx ctx;
    crom_rng irng, srng;
    int nsup;          /* supervised: the equilibria, */
    int *sup;          /* [batch] those of the batch */
    double *zs;        /* [batch][r] and their modal coordinates (or the batch drawn along a run) */
    const double *sup_z;
    long nvisit;       /* sampling along a run: the coordinates visited */
    const double *visit_z;
} map_trainer;

static void map_free(map_trainer *T)
{
    free(T->sup);
    free(T->zs);
    crom_datafree_ctx_free(&T->ctx);
    crom_nn_mlp_free(&T->net);
    free(T->params);
    free(T->grad);
}

/* The network r -> width x (depth - 1) -> 3nv, its initialization and the
 * loss. */
static int map_setup(map_trainer *T, const crom_datafree_problem *p)
{
    const crom_datafree_opts *o = &T->o;
    int n = 3 * p->mesh->nv, nm = o->objective == CROM_DATAFREE_NEURALMODES, rc;
    crom_nn_spec spec;
    if ((rc = crom_dftrain_spec(&spec, o->rank + p->ncond, o->width, o->depth, n, o->act)))
        return rc;
    T->np = crom_nn_spec_nparams(&spec);
    T->params = crom_calloc(T->np, sizeof(float));
    T->grad = crom_calloc(T->np, sizeof(float));
    if (!T->params || !T->grad)
        return CROM_EINTERNAL;
    crom_dftrain_seed(o->seed, &T->irng, &T->srng);
    if ((rc = crom_nn_mlp_init(&T->net, &spec, T->params, &T->irng)))
        return rc;
    if (p->init) { /* a trained map's network (refined along a run) */
        if (nm)
            return crom_err(CROM_EUSAGE, "a network to start from is for the energy objective");
        if (!crom_nn_mlp_has_spec(p->init, &spec))
            return crom_err(CROM_EUSAGE, "the map to start from has another shape (rank, conditions, --width, "
                                         "--depth, activation)");
        memcpy(T->params, p->init->params, sizeof(float) * T->np);
    }
    /* the last layer: pinned outputs stay exactly 0; neuralmodes starts
     * from the linear modes (y = 0) */
    crom_nn_layer *ly = &T->net.layer[T->net.spec.nlayers - 1];
    for (int i = 0; i < n; i++)
        if (nm || (p->fixed && p->fixed[i])) {
            memset(ly->W + (size_t)i * ly->in, 0, sizeof(float) * (size_t)ly->in);
            ly->b[i] = 0;
        }
    if (nm && p->nsup > 0) {
        T->nsup = p->nsup;
        T->sup_z = p->sup_z;
        T->sup = crom_malloc(sizeof(int) * (size_t)o->batch);
        T->zs = crom_malloc(sizeof(double) * (size_t)o->batch * o->rank);
        if (!T->sup || !T->zs)
            return CROM_EINTERNAL;
        T->ctx.sup = T->sup;
    } else if (p->nvisit > 0) {
        if (!nm && !p->init)
            return crom_err(CROM_EUSAGE, "an energy map samples along a run of the map it starts from: give it");
        T->nvisit = p->nvisit;
        T->visit_z = p->visit_z;
        /* (energy: the batch, then the collapse floor's r secants) */
        if (!(T->zs = crom_malloc(sizeof(double) * (size_t)(o->batch + o->rank) * o->rank)))
            return CROM_EINTERNAL;
    }
    rc = crom_datafree_ctx_init(&T->ctx, p, o, &T->net, o->batch);
    T->ctx.sup = T->sup;
    return rc;
}

static int map_loss(void *ctx, const double *z, double rho, int K, const int *tets, crom_dftrain_terms *t)
{
    map_trainer *T = ctx;
    int r = T->o.rank;
    if (T->nsup) { /* supervised: the loop's uniform draw of coordinate 0 picks the equilibrium (the same
                    * batch while L-BFGS iterates on it) */
        for (int b = 0; b < T->o.batch; b++) {
            double u = 0.5 * (z[(size_t)b * r] / T->ctx.half[0] + 1);
            int k = (int)(u * T->nsup);
            T->sup[b] = k < 0 ? 0 : k >= T->nsup ? T->nsup - 1 : k;
            memcpy(T->zs + (size_t)b * r, T->sup_z + (size_t)T->sup[b] * r, sizeof(double) * (size_t)r);
        }
        z = T->zs;
    } else if (T->nvisit) { /* along a run (datafree.h) */
        int en = T->o.objective == CROM_DATAFREE_ENERGY;
        crom_datafree_visit_draw(en, T->o.batch, en ? T->ctx.B0 : 0, r, z, T->ctx.half, T->nvisit, T->visit_z, T->zs);
        z = T->zs;
    }
    if (T->ctx.P.ncond) { /* the batch's condition, from its own latents (datafree.h) */
        double cv[CROM_MODEL_MAXCOND];
        int B = T->o.batch;
        for (int k = 0; k < T->ctx.P.ncond; k++) {
            double s = 0;
            for (int b = 0; b < B; b++)
                s += ((k / r + b) % 2 && k >= r ? -1 : 1) * z[(size_t)b * r + k % r];
            double u = 0.5 * erfc(-s / sqrt(2.0 * B)); /* Φ(s/√B) */
            const crom_scenario_cond *cd = &T->ctx.P.cond[k];
            cv[k] = cd->lo + u * (cd->hi - cd->lo);
        }
        int rc = crom_datafree_set_condition(&T->ctx, cv);
        if (rc)
            return rc;
    }
    return crom_datafree_loss(&T->ctx, T->o.batch, z, rho, K, tets, t, T->grad);
}

/* Train the map: z ~ N(0, I) (energy, ρ ramped) or uniform in the box
 * (neuralmodes, ρ = 1), over every tet or a random cubature of o.tets. */
static int map_train(map_trainer *T, const crom_datafree_problem *p, crom_dftrain_log *log)
{
    const crom_datafree_opts *o = &T->o;
    int nm = o->objective == CROM_DATAFREE_NEURALMODES, nt = p->mesh->nt;
    int K = o->tets > 0 && o->tets < nt ? o->tets : 0; /* a random cubature, or every tet */
    log->sigma = o->sigma;
    log->box = o->box;
    log->Eref = T->ctx.Eref;
    if (nm && o->steps == 0) /* no training: y = 0, the map is its linear (and quadratic) part */
        return 0;
    crom_dftrain_loop L = {
        .loss = map_loss, .ctx = T, .nblocks = 1, .params = {T->params}, .grad = {T->grad}, .nparams = {T->np},
        .rng = &T->srng, .batch = o->batch, .tangent = T->ctx.B0, .r = o->rank, .scale = nm ? T->ctx.half : NULL,
        .uniform = nm, .tangent_radius = o->tangent_radius, .K = K, .nt = nt, .ramp = nm || p->init ? 0 : o->ramp,
        .steps = o->steps, .minutes = o->minutes, .lr = o->lr, .lbfgs = o->optimizer == CROM_DATAFREE_LBFGS,
        .resample = o->resample, .hint = " (try a smaller --lr)", .progress = o->progress,
        .progress_ctx = o->progress_ctx};
    return crom_dftrain_run(&L, log);
}

/* The trained map as a model (neuralmodes: with W and the frequencies). */
static int map_store(const map_trainer *T, const crom_datafree_problem *p, crom_model *out)
{
    int nm = T->o.objective == CROM_DATAFREE_NEURALMODES, r = T->o.rank;
    int rc = crom_model_from_map(out, nm ? "neuralmodes" : "energy", &T->net, p->mesh, nm ? p->modes : NULL);
    if (!rc && p->ncond && !(rc = crom_model_set_conditions(out, p->ncond, p->cond)))
        crom_model_id(out, out->model_id);
    if (!rc && nm && p->deriv) {
        size_t nd = (size_t)p->mesh->nv * 3 * ((size_t)r * (r + 1) / 2);
        if (!(out->deriv_v = crom_malloc(sizeof(double) * nd))) {
            crom_model_free(out);
            return CROM_EINTERNAL;
        }
        memcpy(out->deriv_v, p->deriv, sizeof(double) * nd);
        crom_model_id(out, out->model_id);
    }
    if (!rc && T->ctx.lift) { /* the pin conditions' static lifts (map.h) */
        size_t nl = (size_t)p->ncond * 3 * p->mesh->nv;
        if (!(out->lift_v = crom_malloc(sizeof(double) * nl))) {
            crom_model_free(out);
            return CROM_EINTERNAL;
        }
        memcpy(out->lift_v, T->ctx.lift, sizeof(double) * nl);
        crom_model_id(out, out->model_id);
    }
    if (!rc && p->seed) { /* anchored at the seed state (map.h) */
        size_t ns = (size_t)p->mesh->nv * 3;
        if (!(out->seed_v = crom_malloc(sizeof(double) * ns))) {
            crom_model_free(out);
            return CROM_EINTERNAL;
        }
        memcpy(out->seed_v, p->seed, sizeof(double) * ns);
        crom_model_id(out, out->model_id);
    }
    if (rc || !nm || !p->freq)
        return rc;
    out->frequencies = crom_malloc(sizeof(double) * (size_t)r);
    if (!out->frequencies) {
        crom_model_free(out);
        return CROM_EINTERNAL;
    }
    memcpy(out->frequencies, p->freq, sizeof(double) * (size_t)r);
    crom_model_id(out, out->model_id);
    return 0;
}

int crom_datafree_train(const crom_datafree_problem *p, const crom_datafree_opts *o, crom_model *out,
                        crom_dftrain_log *log)
{
    crom_model_clear(out);
    memset(log, 0, sizeof *log);
    if (p->seed && o->objective != CROM_DATAFREE_ENERGY)
        return crom_err(CROM_EUSAGE, "a seed state is for the energy objective (Sharp et al. §4.1)");
    if (o->objective == CROM_DATAFREE_FIELD)
        return crom_dffield_train(p, o, out, log);
    double t0 = crom_clock_now();
    map_trainer T;
    memset(&T, 0, sizeof T);
    T.o = *o;
    int rc = check_map(p, &T.o);
    if (!rc)
        rc = map_setup(&T, p);
    if (!rc)
        rc = map_train(&T, p, log);
    if (!rc)
        rc = map_store(&T, p, out);
    if (!rc)
        out->training_seconds = crom_clock_wall(crom_clock_now() - t0);
    map_free(&T);
    if (rc)
        crom_dftrain_log_free(log);
    return rc;
}

/* ============================================================ record */

int crom_datafree_write_record(hid_t loc, const crom_datafree_opts *o, const crom_datafree_problem *p,
                               const crom_dftrain_log *log, double mass, const char *modes_id)
{
    int rc = crom_h5_set_f64(loc, ".", "mass", &mass, 1);
    long long steps = log->steps;
    if (!rc)
        rc = crom_h5_set_i64(loc, ".", "training_steps", steps);
    if (o->objective == CROM_DATAFREE_ENERGY || o->objective == CROM_DATAFREE_FIELD) {
        if (!rc)
            rc = crom_h5_set_f64(loc, ".", "sigma", &log->sigma, 1);
        if (!rc)
            rc = crom_h5_set_f64(loc, ".", "isometry_weight", &o->lambda, 1);
        if (!rc)
            rc = crom_h5_set_f64(loc, ".", "gravity", p->gravity, 3);
        if (!rc && o->objective == CROM_DATAFREE_FIELD) {
            long long k = o->tets;
            rc = crom_h5_set_i64(loc, ".", "cubature_tets", k);
        }
    } else {
        if (!rc)
            rc = crom_h5_set_f64(loc, ".", "latent_box", &log->box, 1);
        if (!rc)
            rc = crom_h5_set_str(loc, ".", "latent_box_scaling", o->box_scaled ? "frequency" : "uniform");
        if (!rc && o->tangent_anchor)
            rc = crom_h5_set_i64(loc, ".", "tangent_anchored", 1);
        if (!rc)
            rc = crom_h5_set_f64(loc, ".", "ortho_weight", &o->ortho_weight, 1);
        if (!rc && modes_id)
            rc = crom_h5_set_str(loc, ".", "modes_id", modes_id);
    }
    if (!rc)
        rc = crom_dftrain_log_write(loc, log);
    return rc;
}
