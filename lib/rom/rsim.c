/* rsim.c — reduced implicit Euler on a cubature (see rsim.h). */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <cblas.h>
#include <lapacke.h>

#include "base/clock.h"
#include "base/err.h"
#include "phys/contact.h"
#include "rom/newton.h"
#include "rom/rsim.h"

/* the reuse of the reduced Hessian's factor (see the step's problem below) */
#define SLOW_ITERS 10
#define LAG_ITERS 24
#define PAIRS 16

/* a region's sums (region_sums), emptied */
static void free_bc(crom_rsim_bc *b)
{
    free(b->idx);
    free(b->P);
    free(b->S);
    memset(b, 0, sizeof *b);
}

static void free_bcs(crom_rsim_bc *b, int n)
{
    for (int i = 0; b && i < n; i++)
        free_bc(&b[i]);
    free(b);
}

static void free_cub_data(crom_rsim *s)
{
    free(s->mats);
    free(s->kmat);
    s->mats = NULL;
    s->kmat = NULL;
    s->el.kmat = NULL;
    free(s->Mr);
    free(s->vm);
    s->vm = NULL;
    free(s->fg);
    free(s->G);
    free(s->Gfac);
    free(s->lam);
    free(s->qn);
    free(s->qhat);
    free(s->g);
    free(s->H);
    free(s->d);
    free(s->qt);
    free(s->gt);
    free(s->fext);
    free(s->Hfac);
    free(s->Q);
    free(s->Pk);
    free(s->lin);
    crom_elastic_free(&s->el);
    crom_newton_memory_free(&s->mem);
    free_bcs(s->bc, s->nbc);
    free_bcs(s->force, s->nforce);
    for (int k = 0; k < s->nrod; k++)
        free(s->rod[k].D);
    free(s->rod);
    s->rod = NULL;
    s->nrod = 0;
    for (int d = 0; d < s->ndrag; d++) /* the drags stay; their sums are the cubature's */
        free_bc(&s->drag[d].b);
    s->Mr = s->fg = s->G = s->Gfac = s->lam = NULL;
    s->qn = s->qhat = s->g = s->H = s->d = s->qt = s->gt = s->fext = s->Hfac = s->Q = s->Pk = s->lin = NULL;
    s->fac_ok = 0;
    s->bc = s->force = NULL;
    s->nbc = s->nforce = 0;
}

/* mass-weighted sums over a vertex set: P = Σ m W_vᵀW_v, S = Σ m W_vᵀ
 * (vm [nv]: the vertices' lumped masses) */
static int region_sums(const crom_cubature *c, const double *vm, const char *ref, crom_rsim_bc *b)
{
    int r = c->r, rc = crom_mesh_select(&c->mesh, ref, &b->idx, &b->n);
    if (rc)
        return rc;
    b->P = crom_calloc((size_t)r * r, sizeof(double));
    b->S = crom_calloc((size_t)r * 3, sizeof(double));
    if (!b->P || !b->S)
        return CROM_EINTERNAL;
    for (int k = 0; k < b->n; k++) {
        int v = b->idx[k];
        double m = vm[v];
        const double *Wv = c->W + (size_t)v * 3 * r; /* 3 × r */
        b->mass += m;
        cblas_dsyrk(CblasRowMajor, CblasUpper, CblasTrans, r, 3, m, Wv, r, 1.0, b->P, r);
        for (int i = 0; i < r; i++)
            for (int cc = 0; cc < 3; cc++)
                b->S[i * 3 + cc] += m * Wv[cc * r + i];
    }
    for (int i = 0; i < r; i++)
        for (int j = 0; j < i; j++)
            b->P[i * r + j] = b->P[j * r + i];
    return 0;
}

/* The lumped masses s->vm [nv] of the cubature's mesh: ρ V_v, or with
 * regions of other densities Σ ρ_t V_t / 4 over each vertex's tets, tet t
 * of material s->mats[tmat[t]] (s->dense set). */
static int vertex_masses(crom_rsim *s, const int *tmat)
{
    const crom_cubature *c = s->cub;
    const crom_scenario *sc = s->sc;
    int nv = c->mesh.nv, dense = 0;
    for (int i = 0; i < sc->nmat; i++)
        dense |= !isnan(sc->mat[i].density);
    if (!(s->vm = crom_malloc(sizeof(double) * (size_t)(nv ? nv : 1))))
        return CROM_EINTERNAL;
    s->dense = dense && tmat;
    if (!s->dense) {
        for (int v = 0; v < nv; v++)
            s->vm[v] = sc->density * c->vvol[v];
        return 0;
    }
    memset(s->vm, 0, sizeof(double) * (size_t)nv);
    for (int t = 0; t < c->mesh.nt; t++) {
        const int *e = c->mesh.tets + 4 * (size_t)t;
        const double *X = c->mesh.X;
        double V = fabs(crom_mesh_tet_volume(X + 3 * e[0], X + 3 * e[1], X + 3 * e[2], X + 3 * e[3]));
        for (int k = 0; k < 4; k++)
            s->vm[e[k]] += 0.25 * s->mats[tmat[t]].rho * V;
    }
    return 0;
}

/* The mass-weighted rest centroid of the vertices of region sums b. */
static void region_centroid(const crom_rsim *s, const crom_rsim_bc *b, double xbar[3])
{
    const double *X = s->cub->mesh.X;
    xbar[0] = xbar[1] = xbar[2] = 0;
    for (int k = 0; k < b->n; k++)
        for (int j = 0; j < 3; j++)
            xbar[j] += s->vm[b->idx[k]] * X[3 * (size_t)b->idx[k] + j] / b->mass;
}

/* A drag's region sums and rest centroid on the current cubature's mesh. */
static int drag_resolve(crom_rsim *s, crom_rsim_drag *d)
{
    const crom_cubature *c = s->cub;
    int rc = region_sums(c, s->vm, d->ref, &d->b);
    if (rc)
        return rc;
    if (!(d->b.mass > 0))
        return crom_err(CROM_EUSAGE, "region '%s' has no mass to drag", d->ref);
    region_centroid(s, &d->b, d->xbar);
    return 0;
}

/* The scenario's rods on the current cubature (crom_rsim_rod): each end's
 * region sums and rest centroid give its centroid X̄ + Sᵀq/m. */
static int rods_build(crom_rsim *s)
{
    const crom_scenario *sc = s->sc;
    const crom_cubature *c = s->cub;
    int r = s->r, rc = 0;
    if (!sc->nrod)
        return 0;
    if (!(s->rod = crom_calloc((size_t)sc->nrod, sizeof *s->rod)))
        return CROM_EINTERNAL;
    s->nrod = sc->nrod;
    for (int k = 0; k < sc->nrod && !rc; k++) {
        crom_rsim_rod *rd = &s->rod[k];
        if (!(rd->D = crom_calloc((size_t)3 * r, sizeof(double))))
            return CROM_EINTERNAL;
        for (int e = 0; e < 2 && !rc; e++) {
            const char *ref = e ? sc->rod[k].b : sc->rod[k].a;
            crom_rsim_bc b;
            memset(&b, 0, sizeof b);
            if ((rc = region_sums(c, s->vm, ref, &b))) {
                crom_err_ctx("--rod");
            } else if (!(b.mass > 0)) {
                rc = crom_err(CROM_EUSAGE, "--rod: end '%s' has no mass", ref);
            } else {
                double sg = e ? 1 : -1, xbar[3];
                region_centroid(s, &b, xbar);
                for (int a = 0; a < 3; a++)
                    rd->d0[a] += sg * xbar[a];
                for (int i = 0; i < r; i++)
                    for (int a = 0; a < 3; a++)
                        rd->D[a * r + i] += sg * b.S[i * 3 + a] / b.mass;
            }
            free_bc(&b);
        }
        rd->rest = sqrt(rd->d0[0] * rd->d0[0] + rd->d0[1] * rd->d0[1] + rd->d0[2] * rd->d0[2]);
    }
    return rc;
}

/* The rods' energy at q and time t; g [r] and H [r][r] (may be NULL) get
 * their gradient Dᵀ g_d and Hessian Dᵀ H_d D added (projected per
 * project). */
static double rods_eval(crom_rsim *s, const double *q, double t, double *g, double *H, int project)
{
    int r = s->r;
    double E = 0;
    for (int k = 0; k < s->nrod; k++) {
        const crom_rsim_rod *rd = &s->rod[k];
        double d[3], gd[3], Hd[9], HD[3 * 64];
        memcpy(d, rd->d0, sizeof d);
        cblas_dgemv(CblasRowMajor, CblasNoTrans, 3, r, 1.0, rd->D, r, q, 1, 1.0, d, 1);
        E += crom_rod_eval(s->sc->rod[k].k, crom_rod_length(&s->sc->rod[k], rd->rest, t), d, gd, H ? Hd : NULL,
                           project);
        if (g)
            cblas_dgemv(CblasRowMajor, CblasTrans, 3, r, 1.0, rd->D, r, gd, 1, 1.0, g, 1);
        for (int j0 = 0; H && j0 < r; j0 += 64) { /* H += Dᵀ Hd D in slices of 64 columns */
            int nj = r - j0 < 64 ? r - j0 : 64;
            cblas_dgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, 3, nj, 3, 1.0, Hd, 3, rd->D + j0, r, 0.0, HD,
                        nj);
            cblas_dgemm(CblasRowMajor, CblasTrans, CblasNoTrans, r, nj, 3, 1.0, rd->D, r, HD, nj, 1.0, H + j0, r);
        }
    }
    return E;
}

/* The objective's constant quadratic part Q = (1/h² + A/h) M_r + κ Σ_b P_b
 * + Σ_d k_d/m_d P_d (the drags' springs). A change of it drops the reused
 * factor and the quasi-Newton pairs built on it. */
static void quad_rebuild(crom_rsim *s)
{
    const crom_scenario *sc = s->sc;
    size_t rr = (size_t)s->r * s->r;
    double cq = 1 / (sc->dt * sc->dt) + sc->damping / sc->dt;
    for (size_t i = 0; i < rr; i++)
        s->Q[i] = cq * s->Mr[i] + s->Pk[i];
    for (int d = 0; d < s->ndrag; d++)
        cblas_daxpy((int)rr, s->drag[d].k / s->drag[d].b.mass, s->drag[d].b.P, 1, s->Q, 1);
    s->fac_ok = 0;
    crom_newton_memory_reset(&s->mem);
}

/* Which latent directions the boundary conditions constrain. With P the
 * mass-weighted sum of W_vᵀW_v over BC vertices, the generalized eigenpairs
 * P v = μ M_r v (VᵀM_rV = I) give for each direction the fraction μ of its
 * motion carried by those vertices. A learned basis is only nearly zero
 * where its training data was pinned: the directions the data determined
 * have small μ, while weakly determined ones move the pins freely. A stiff
 * penalty on all of them would freeze the body, so the penalty acts on the
 * M-orthogonal projection Πq (Π = V_c V_cᵀ M_r) onto the directions with
 * μ >= τ = threshold × (BC mass / total mass) only: P_b ← ΠᵀP_bΠ,
 * S_b ← ΠᵀS_b. threshold 0 constrains every direction (a plain penalty). */
static int constrain_directions(crom_rsim *s)
{
    int r = s->r, rc = 0;
    size_t rr = (size_t)r * r;
    double *P = crom_calloc(rr, sizeof(double)), *M = crom_malloc(sizeof(double) * rr);
    double *mu = crom_malloc(sizeof(double) * (size_t)r), *Pi = crom_calloc(rr, sizeof(double));
    double *T = crom_malloc(sizeof(double) * rr * 3);
    if (!P || !M || !mu || !Pi || !T) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    double mbc = 0, mtot = 0;
    for (int v = 0; v < s->cub->mesh.nv; v++)
        mtot += s->vm[v];
    for (int b = 0; b < s->nbc; b++) {
        for (size_t i = 0; i < rr; i++)
            P[i] += s->bc[b].P[i];
        mbc += s->bc[b].mass;
    }
    memcpy(M, s->Mr, sizeof(double) * rr);
    /* P v = μ M v: eigenvectors overwrite P (columns, M-orthonormal) */
    if (LAPACKE_dsygv(LAPACK_ROW_MAJOR, 1, 'V', 'U', r, P, r, M, r, mu) != 0) {
        rc = crom_err(CROM_EDATA, "the reduced mass matrix is not positive definite");
        goto out;
    }
    double tau = s->bc_threshold * mbc / mtot;
    s->nconstrained = 0;
    /* Π = V_c V_cᵀ M_r */
    for (int k = 0; k < r; k++) {
        if (mu[k] < tau)
            continue;
        s->nconstrained++;
        for (int i = 0; i < r; i++) {
            double vi = P[i * r + k];
            for (int j = 0; j < r; j++) {
                double vMj = 0; /* (vᵀ M)_j */
                for (int l = 0; l < r; l++)
                    vMj += P[l * r + k] * s->Mr[l * r + j];
                Pi[i * r + j] += vi * vMj;
            }
        }
    }
    for (int b = 0; b < s->nbc; b++) {
        /* P_b ← Πᵀ P_b Π, S_b ← Πᵀ S_b */
        cblas_dgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, r, r, r, 1.0, s->bc[b].P, r, Pi, r, 0.0, T, r);
        cblas_dgemm(CblasRowMajor, CblasTrans, CblasNoTrans, r, r, r, 1.0, Pi, r, T, r, 0.0, s->bc[b].P, r);
        cblas_dgemm(CblasRowMajor, CblasTrans, CblasNoTrans, r, 3, r, 1.0, Pi, r, s->bc[b].S, 3, 0.0, T, 3);
        memcpy(s->bc[b].S, T, sizeof(double) * 3 * (size_t)r);
        for (int i = 0; i < r; i++) /* keep it exactly symmetric */
            for (int j = 0; j < i; j++)
                s->bc[b].P[i * r + j] = s->bc[b].P[j * r + i] = 0.5 * (s->bc[b].P[i * r + j] + s->bc[b].P[j * r + i]);
    }
out:
    free(P);
    free(M);
    free(mu);
    free(Pi);
    free(T);
    return rc;
}

static int build(crom_rsim *s)
{
    const crom_cubature *c = s->cub;
    const crom_scenario *sc = s->sc;
    int r = c->r, rc = 0;
    double rho = sc->density;
    s->r = r;
    size_t rr = (size_t)r * r;
    s->Mr = crom_malloc(sizeof(double) * rr);
    s->fg = crom_calloc((size_t)r, sizeof(double));
    s->G = crom_calloc(rr, sizeof(double));
    s->Gfac = crom_malloc(sizeof(double) * rr);
    s->lam = crom_calloc((size_t)(sc->nplanes ? sc->nplanes : 1) * (size_t)(c->nsurf ? c->nsurf : 1), sizeof(double));
    s->qn = crom_malloc(sizeof(double) * (size_t)r);
    s->qhat = crom_malloc(sizeof(double) * (size_t)r);
    s->g = crom_malloc(sizeof(double) * (size_t)r);
    s->H = crom_malloc(sizeof(double) * rr);
    s->d = crom_malloc(sizeof(double) * (size_t)r);
    s->qt = crom_malloc(sizeof(double) * (size_t)r);
    s->gt = crom_malloc(sizeof(double) * 4 * (size_t)r);
    s->fext = crom_calloc((size_t)r, sizeof(double));
    s->Hfac = crom_malloc(sizeof(double) * rr);
    s->Q = crom_malloc(sizeof(double) * rr);
    s->Pk = crom_calloc(rr, sizeof(double));
    s->lin = crom_malloc(sizeof(double) * (size_t)r);
    s->fac_ok = 0;
    s->bc = crom_calloc((size_t)(sc->npins + sc->nvel + 1), sizeof(crom_rsim_bc));
    s->force = crom_calloc((size_t)(sc->nforce + 1), sizeof(crom_rsim_bc));
    if (!s->Mr || !s->fg || !s->G || !s->Gfac || !s->lam || !s->qn || !s->qhat || !s->g ||
        !s->H || !s->d || !s->qt || !s->gt || !s->fext || !s->Hfac || !s->Q || !s->Pk || !s->lin || !s->bc ||
        !s->force)
        return CROM_EINTERNAL;
    if ((rc = crom_elastic_init(&s->el, c)) || (rc = crom_newton_memory_init(&s->mem, r, PAIRS)))
        return rc;
    int *tmat = NULL; /* each mesh tet's material (crom_scenario_materials): the cubature tets', the masses' */
    if (sc->nmat) {
        int nmat;
        s->mats = crom_malloc(sizeof *s->mats * (CROM_SCENARIO_MAX + 1));
        s->kmat = crom_malloc(sizeof *s->kmat * (size_t)(c->k ? c->k : 1));
        if (!s->mats || !s->kmat)
            return CROM_EINTERNAL;
        if ((rc = crom_scenario_materials(sc, &c->mesh, s->mats, &nmat, &tmat)))
            return rc;
        for (int k = 0; k < c->k; k++)
            s->kmat[k] = &s->mats[tmat[c->elem[k]]];
        s->el.kmat = s->kmat;
    }
    rc = vertex_masses(s, tmat);
    free(tmat);
    if (rc)
        return rc;
    if (!s->dense) { /* one density: the cubature's volume-weighted sums */
        for (size_t i = 0; i < rr; i++)
            s->Mr[i] = rho * c->WtVW[i];
        for (int i = 0; i < r; i++)
            for (int k = 0; k < 3; k++)
                s->fg[i] += rho * c->WtV[i * 3 + k] * sc->gravity[k];
    } else { /* regions of other densities: M_r = Σ m_v W_vᵀW_v, f_g = Σ m_v W_vᵀ g */
        memset(s->Mr, 0, sizeof(double) * rr);
        for (int v = 0; v < c->mesh.nv; v++) {
            const double *Wv = c->W + (size_t)v * 3 * r;
            cblas_dsyrk(CblasRowMajor, CblasUpper, CblasTrans, r, 3, s->vm[v], Wv, r, 1.0, s->Mr, r);
            cblas_dgemv(CblasRowMajor, CblasTrans, 3, r, s->vm[v], Wv, r, sc->gravity, 1, 1.0, s->fg, 1);
        }
        for (int i = 0; i < r; i++)
            for (int j = 0; j < i; j++)
                s->Mr[i * r + j] = s->Mr[j * r + i];
    }
    double lo[3], hi[3];
    crom_mesh_bbox(&c->mesh, lo, hi);
    s->L = sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                (hi[2] - lo[2]) * (hi[2] - lo[2]));
    /* boundary conditions: pins and prescribed velocities share the penalty */
    for (int i = 0; i < sc->npins && !rc; i++) {
        rc = region_sums(c, s->vm, sc->pins[i], &s->bc[s->nbc]);
        s->nbc++;
    }
    for (int i = 0; i < sc->nvel && !rc; i++) {
        s->bc[s->nbc].bc = &sc->vel[i];
        rc = region_sums(c, s->vm, sc->vel[i].ref, &s->bc[s->nbc]);
        s->nbc++;
    }
    for (int i = 0; i < sc->nforce && !rc; i++) {
        s->force[s->nforce].bc = &sc->force[i];
        rc = region_sums(c, s->vm, sc->force[i].ref, &s->force[s->nforce]);
        s->nforce++;
    }
    if (rc) {
        crom_err_ctx("scenario");
        return CROM_EUSAGE;
    }
    if (s->nbc && s->bc_threshold > 0 && (rc = constrain_directions(s)))
        return rc;
    for (int d = 0; d < s->ndrag && !rc; d++)
        if ((rc = drag_resolve(s, &s->drag[d])))
            return crom_err_ctx("drag");
    if ((rc = rods_build(s)))
        return rc;
    /* the objective's constant quadratic part (quad_rebuild) */
    for (int b = 0; b < s->nbc; b++)
        cblas_daxpy((int)rr, s->kappa, s->bc[b].P, 1, s->Pk, 1);
    quad_rebuild(s);
    /* the gd preconditioner: G = Σ_e w_e V_e/4 Σ_{a in e} W_aᵀ W_a (LiCROM
     * eq. 10, each cubature point weighted by its share of volume), scaled by
     * ρ/h² to mass units (the cubature's estimate of M_r/h²), plus the boundary-condition penalty's
     * own quadratic term κP so that stiff constraints do not stall descent
     * (the paper keeps prescribed points fixed in the projection) */
    for (int k = 0; k < c->k; k++) {
        const int *e = c->mesh.tets + 4 * (size_t)c->elem[k];
        for (int a = 0; a < 4; a++)
            cblas_dsyrk(CblasRowMajor, CblasUpper, CblasTrans, r, 3,
                        c->weight[k] * c->vol[k] / 4 * rho / (sc->dt * sc->dt), c->W + (size_t)e[a] * 3 * r, r,
                        1.0, s->G, r);
    }
    for (int b = 0; b < s->nbc; b++)
        for (int i = 0; i < r; i++)
            for (int j = i; j < r; j++)
                s->G[i * r + j] += s->kappa * s->bc[b].P[i * r + j];
    double tr = 0;
    for (int i = 0; i < r; i++)
        tr += s->G[i * r + i];
    for (int i = 0; i < r; i++) {
        s->G[i * r + i] += 1e-12 * tr / r; /* a small cubature may not span every mode */
        for (int j = 0; j < i; j++)
            s->G[i * r + j] = s->G[j * r + i];
    }
    memcpy(s->Gfac, s->G, sizeof(double) * rr);
    if (LAPACKE_dpotrf(LAPACK_ROW_MAJOR, 'U', r, s->Gfac, r) != 0)
        return crom_err(CROM_EDATA, "the cubature's W^T W is singular");
    return 0;
}

/* The scenario's initial velocity field (uniform plus spin, the same as the
 * full simulation's) projected onto the subspace in the mass norm: the q̇ that
 * minimizes Σ_v m_v |W_v q̇ − v_v|², i.e. M_r q̇ = Σ_v m_v W_vᵀ v_v. */
static int initial_velocity(crom_rsim *s)
{
    const crom_scenario *sc = s->sc;
    const crom_cubature *c = s->cub;
    if (!sc->v0[0] && !sc->v0[1] && !sc->v0[2] && !sc->spin[0] && !sc->spin[1] && !sc->spin[2])
        return 0;
    int r = s->r, nv = c->mesh.nv;
    double cen[3] = {0, 0, 0}, vol = 0;
    for (int v = 0; v < nv; v++) {
        vol += c->vvol[v];
        for (int k = 0; k < 3; k++)
            cen[k] += c->vvol[v] * c->mesh.X[3 * v + k];
    }
    for (int k = 0; k < 3; k++)
        cen[k] /= vol;
    double *M = crom_malloc(sizeof(double) * (size_t)r * r);
    if (!M)
        return CROM_EINTERNAL;
    memcpy(M, s->Mr, sizeof(double) * (size_t)r * r);
    memset(s->qd, 0, sizeof(double) * (size_t)r);
    for (int v = 0; v < nv; v++) {
        double vel[3];
        crom_scenario_initial_velocity(sc, cen, c->mesh.X + 3 * v, vel);
        cblas_dgemv(CblasRowMajor, CblasTrans, 3, r, s->vm[v], c->W + (size_t)v * 3 * r, r, vel,
                    1, 1.0, s->qd, 1);
    }
    int info = LAPACKE_dposv(LAPACK_ROW_MAJOR, 'U', r, 1, M, r, s->qd, 1);
    free(M);
    if (info)
        return crom_err(CROM_EDATA, "the reduced mass matrix is not positive definite");
    return 0;
}

/* The linear path integrates tets; a shell's cubature serves the map path. */
static int solid_cubature(const crom_cubature *cub)
{
    return crom_mesh_is_surface(&cub->mesh)
               ? crom_err(CROM_EUSAGE, "the cubature integrates a shell surface: run it with crom-reducedstep "
                                       "--model MODEL --cubature CUB (model %s)", cub->model_id)
               : 0;
}

int crom_rsim_init(crom_rsim *s, const crom_cubature *cub, const crom_scenario *sc, int solver,
                   double kappa, const double *q0, const double *qd0)
{
    memset(s, 0, sizeof *s);
    int rc = solid_cubature(cub);
    if (rc)
        return rc;
    rc = crom_scenario_check(sc);
    if (!rc)
        rc = crom_scenario_check_regions(sc, &cub->mesh);
    if (rc)
        return rc;
    if ((rc = crom_material_init(&s->mat, sc->youngs, sc->poisson, sc->density)))
        return rc;
    s->sc = sc;
    s->cub = cub;
    s->solver = solver;
    s->lagged = 1;
    s->kappa = kappa > 0 ? kappa : 1e4 / (sc->dt * sc->dt);
    s->bc_threshold = 0.1;
    s->r = cub->r;
    s->q = crom_calloc((size_t)s->r, sizeof(double));
    s->qd = crom_calloc((size_t)s->r, sizeof(double));
    s->corr = crom_calloc((size_t)s->r, sizeof(double));
    if (!s->q || !s->qd || !s->corr) {
        crom_rsim_free(s);
        return CROM_EINTERNAL;
    }
    if (q0)
        memcpy(s->q, q0, sizeof(double) * (size_t)s->r);
    if (qd0)
        memcpy(s->qd, qd0, sizeof(double) * (size_t)s->r);
    if ((rc = build(s)) || (!qd0 && (rc = initial_velocity(s)))) {
        crom_rsim_free(s);
        return rc;
    }
    return 0;
}

int crom_rsim_set_cubature(crom_rsim *s, const crom_cubature *cub)
{
    int rc = solid_cubature(cub);
    if (rc)
        return rc;
    if (cub->r != s->r || strcmp(cub->model_id, s->cub->model_id))
        return crom_err(CROM_EDATA, "the cubature belongs to model %s (rank %d), the run uses model %s (rank %d)",
                        cub->model_id, cub->r, s->cub->model_id, s->r);
    free_cub_data(s);
    s->cub = cub;
    return build(s);
}

void crom_rsim_free(crom_rsim *s)
{
    free_cub_data(s);
    free(s->drag);
    free(s->q);
    free(s->qd);
    free(s->corr);
    memset(s, 0, sizeof *s);
}

int crom_rsim_drag_set(crom_rsim *s, const char *ref, const double c[3], double k)
{
    if (!(isfinite(c[0]) && isfinite(c[1]) && isfinite(c[2])))
        return crom_err(CROM_EUSAGE, "drag %s: the point must be finite", ref);
    if (!(k > 0) || !isfinite(k))
        return crom_err(CROM_EUSAGE, "drag %s: the stiffness must be positive (N/m)", ref);
    if (strlen(ref) >= sizeof s->drag->ref)
        return crom_err(CROM_EUSAGE, "drag: region name too long");
    int d = 0;
    while (d < s->ndrag && strcmp(s->drag[d].ref, ref))
        d++;
    if (d == s->ndrag) { /* a new one: its sums on this cubature */
        crom_rsim_drag *a = realloc(s->drag, sizeof *a * (size_t)(s->ndrag + 1));
        if (!a)
            return crom_err(CROM_EINTERNAL, "out of memory");
        s->drag = a;
        memset(&a[d], 0, sizeof a[d]);
        snprintf(a[d].ref, sizeof a[d].ref, "%s", ref);
        int rc = drag_resolve(s, &a[d]);
        if (rc) {
            free_bc(&a[d].b);
            return crom_err_ctx("drag");
        }
        s->ndrag++;
    }
    crom_rsim_drag *g = &s->drag[d];
    memcpy(g->c, c, sizeof g->c);
    if (g->k != k) {
        g->k = k;
        quad_rebuild(s);
    }
    return 0;
}

int crom_rsim_drag_release(crom_rsim *s, const char *ref)
{
    int kept = 0, n = s->ndrag;
    for (int d = 0; d < n; d++) {
        if (!ref || !strcmp(s->drag[d].ref, ref))
            free_bc(&s->drag[d].b);
        else
            s->drag[kept++] = s->drag[d];
    }
    s->ndrag = kept;
    if (kept != n)
        quad_rebuild(s);
    return n - kept;
}

int crom_rsim_sync_forces(crom_rsim *s)
{
    const crom_scenario *sc = s->sc;
    if (sc->nforce <= s->nforce)
        return 0;
    crom_rsim_bc *f = realloc(s->force, sizeof *f * (size_t)(sc->nforce + 1));
    if (!f)
        return crom_err(CROM_EINTERNAL, "out of memory");
    s->force = f;
    while (s->nforce < sc->nforce) {
        crom_rsim_bc *b = &s->force[s->nforce];
        memset(b, 0, sizeof *b);
        b->bc = &sc->force[s->nforce];
        int rc = region_sums(s->cub, s->vm, b->bc->ref, b);
        if (rc) {
            free_bc(b);
            return crom_err_ctx("force");
        }
        s->nforce++;
    }
    return 0;
}

/* reduced external load at time t: gravity plus region forces */
static void loads(const crom_rsim *s, double t, double *f)
{
    int r = s->r;
    memcpy(f, s->fg, sizeof(double) * (size_t)r);
    for (int b = 0; b < s->nforce; b++) {
        double F[3];
        crom_bc_force(s->force[b].bc, t, F);
        for (int i = 0; i < r; i++)
            for (int k = 0; k < 3; k++)
                f[i] += s->force[b].S[i * 3 + k] * F[k] / s->force[b].mass;
    }
}

/* per-step data kept in the work buffer tail */
#define FEXT(s) ((s)->fext)

void crom_rsim_begin_step(crom_rsim *s)
{
    const crom_scenario *sc = s->sc;
    const crom_cubature *c = s->cub;
    int r = s->r;
    double h = sc->dt;
    memcpy(s->qn, s->q, sizeof(double) * (size_t)r);
    for (int i = 0; i < r; i++)
        s->qhat[i] = s->q[i] + h * s->qd[i];
    loads(s, (double)(s->step + 1) * h, FEXT(s));
    /* The quadratic terms of the objective about the predictor: with
     * a = q − q̂, v = q̂ − q_n (vp), b = q − q_n = a + v and q = a + q̂,
     *   1/(2h²) aᵀM a + A/(2h) bᵀM b − fᵀb + κ/2 Σ_b (qᵀP_b q − 2qᵀS_b ū_b + m_b|ū_b|²)
     *   = ½ aᵀQ a + lᵀa + c₀,   l = (A/h) M v − f + Σ_b κ (P_b q̂ − S_b ū_b),
     *   c₀ = A/(2h) vᵀM v − fᵀv + Σ_b κ/2 (q̂ᵀP_b q̂ − 2q̂ᵀS_b ū_b + m_b|ū_b|²),
     * so that an evaluation costs one product Q a (Q from build) */
    double *vp = s->gt, *Mv = s->gt + r, cd = sc->damping / h, t1 = (double)(s->step + 1) * h;
    for (int i = 0; i < r; i++)
        vp[i] = s->qhat[i] - s->qn[i];
    cblas_dsymv(CblasRowMajor, CblasUpper, r, 1.0, s->Mr, r, vp, 1, 0.0, Mv, 1);
    cblas_dsymv(CblasRowMajor, CblasUpper, r, 1.0, s->Pk, r, s->qhat, 1, 0.0, s->lin, 1);
    s->c0 = 0.5 * cd * cblas_ddot(r, vp, 1, Mv, 1) - cblas_ddot(r, FEXT(s), 1, vp, 1) +
            0.5 * cblas_ddot(r, s->qhat, 1, s->lin, 1);
    for (int i = 0; i < r; i++)
        s->lin[i] += cd * Mv[i] - FEXT(s)[i];
    for (int k = 0; k < s->nbc; k++) {
        const crom_rsim_bc *bc = &s->bc[k];
        double u[3] = {0, 0, 0};
        if (!bc->bc)
            continue; /* a pin: ū = 0 */
        crom_bc_displacement(bc->bc, t1, u);
        cblas_dgemv(CblasRowMajor, CblasNoTrans, r, 3, -s->kappa, bc->S, 3, u, 1, 1.0, s->lin, 1);
        double Su = 0;
        for (int i = 0; i < r; i++)
            Su += s->qhat[i] * (bc->S[i * 3] * u[0] + bc->S[i * 3 + 1] * u[1] + bc->S[i * 3 + 2] * u[2]);
        s->c0 += 0.5 * s->kappa * (bc->mass * (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]) - 2 * Su);
    }
    /* the drags' springs: k/(2m) (qᵀPq − 2qᵀS d + m|d|²), d = c − X̄, about q̂ */
    for (int k = 0; k < s->ndrag; k++) {
        const crom_rsim_drag *dg = &s->drag[k];
        double w = dg->k / dg->b.mass, d[3], *Pqh = s->gt + 2 * r; /* (gt: 4r scratch; vp, Mv done) */
        for (int j = 0; j < 3; j++)
            d[j] = dg->c[j] - dg->xbar[j];
        cblas_dsymv(CblasRowMajor, CblasUpper, r, 1.0, dg->b.P, r, s->qhat, 1, 0.0, Pqh, 1);
        double qPq = cblas_ddot(r, s->qhat, 1, Pqh, 1), qSd = 0;
        for (int i = 0; i < r; i++) {
            double Sd = dg->b.S[i * 3] * d[0] + dg->b.S[i * 3 + 1] * d[1] + dg->b.S[i * 3 + 2] * d[2];
            s->lin[i] += w * (Pqh[i] - Sd);
            qSd += s->qhat[i] * Sd;
        }
        s->c0 += 0.5 * w * (qPq - 2 * qSd + dg->b.mass * (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]));
    }
    /* lagged normal forces of the contact points, from the start of the step */
    for (int p = 0; p < sc->nplanes; p++)
        for (int k = 0; k < c->nsurf; k++) {
            int v = c->surf[k];
            double x[3];
            memcpy(x, c->mesh.X + 3 * (size_t)v, sizeof x);
            cblas_dgemv(CblasRowMajor, CblasNoTrans, 3, r, 1.0, c->W + (size_t)v * 3 * r, r, s->qn, 1, 1.0, x, 1);
            s->lam[(size_t)p * c->nsurf + k] =
                sc->contact_stiffness * s->vm[v] * crom_contact_depth(&sc->plane[p], x);
        }
}

int crom_rsim_objective(crom_rsim *s, const double *q, double *Eout, double *g, double *H, int project)
{
    const crom_scenario *sc = s->sc;
    const crom_cubature *c = s->cub;
    int r = s->r;
    size_t rr = (size_t)r * r;
    double *a = s->gt, *Qa = s->gt + r;
    /* inertia, damping, loads and boundary conditions: ½aᵀQa + lᵀa + c₀ (see
     * crom_rsim_begin_step) */
    for (int i = 0; i < r; i++)
        a[i] = q[i] - s->qhat[i];
    cblas_dsymv(CblasRowMajor, CblasUpper, r, 1.0, s->Q, r, a, 1, 0.0, Qa, 1);
    double E = cblas_ddot(r, a, 1, Qa, 1) * 0.5 + cblas_ddot(r, s->lin, 1, a, 1) + s->c0;
    if (g)
        for (int i = 0; i < r; i++)
            g[i] = Qa[i] + s->lin[i];
    if (H)
        memcpy(H, s->Q, sizeof(double) * rr);
    /* elastic energy by cubature (LiCROM eq. 7-8), in the space of F */
    double Ee;
    int rc = crom_elastic_eval(&s->el, &s->mat, q, project, &Ee, g, H);
    if (rc)
        return rc;
    E += Ee + rods_eval(s, q, (double)(s->step + 1) * sc->dt, g, H, project);
    /* contact at the surface vertices */
    for (int p = 0; p < sc->nplanes; p++)
        for (int k = 0; k < c->nsurf; k++) {
            int v = c->surf[k];
            double lam = s->lam[(size_t)p * c->nsurf + k];
            const double *Wv = c->W + (size_t)v * 3 * r;
            double x[3], xp[3];
            memcpy(x, c->mesh.X + 3 * (size_t)v, sizeof x);
            cblas_dgemv(CblasRowMajor, CblasNoTrans, 3, r, 1.0, Wv, r, q, 1, 1.0, x, 1);
            if (crom_contact_depth(&sc->plane[p], x) <= 0 && !(lam > 0 && sc->plane[p].mu > 0))
                continue;
            memcpy(xp, c->mesh.X + 3 * (size_t)v, sizeof xp);
            cblas_dgemv(CblasRowMajor, CblasNoTrans, 3, r, 1.0, Wv, r, s->qn, 1, 1.0, xp, 1);
            double gc[3] = {0, 0, 0}, Hc[9] = {0}, WH[3 * 64];
            E += crom_contact_eval(&sc->plane[p], sc->contact_stiffness, s->vm[v], x, xp, lam,
                                   sc->friction_eps * sc->dt, g ? gc : NULL, H ? Hc : NULL);
            if (g)
                cblas_dgemv(CblasRowMajor, CblasTrans, 3, r, 1.0, Wv, r, gc, 1, 1.0, g, 1);
            if (H) { /* H += Wvᵀ Hc Wv, in slices of 64 columns */
                for (int j0 = 0; j0 < r; j0 += 64) {
                    int nj = r - j0 < 64 ? r - j0 : 64;
                    cblas_dgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, 3, nj, 3, 1.0, Hc, 3, Wv + j0, r, 0.0,
                                WH, nj);
                    cblas_dgemm(CblasRowMajor, CblasTrans, CblasNoTrans, r, nj, 3, 1.0, Wv, r, WH, nj, 1.0,
                                H + j0, r);
                }
            }
        }
    *Eout = E;
    return isfinite(E) ? 0 : crom_err(CROM_EDATA, "the reduced energy is not finite");
}

/* RMS displacement over the body of u = W d, relative to the size */
static double rms_disp(const crom_rsim *s, const double *d)
{
    int r = s->r;
    double *Vd = s->gt + 3 * (size_t)r; /* free outside the objective */
    cblas_dsymv(CblasRowMajor, CblasUpper, r, 1.0, s->cub->WtVW, r, d, 1, 0.0, Vd, 1);
    double v = cblas_ddot(r, d, 1, Vd, 1);
    return sqrt(fmax(v, 0) / s->cub->mesh_volume) / s->L;
}

/* The step's problem for the latent minimizer (lib/rom/newton.h): the
 * objective, the Newton (or the paper's descent) direction, the size of a
 * correction as an RMS displacement relative to the body.
 *
 * The reduced Hessian costs 4 K r² (block basis, elastic.h) to 18 K r²
 * flops over a cubature of K tets and its factor r³/3, the gradient 18 K r:
 * with r in the hundreds (skinning handles) one Hessian costs as much as
 * 20-30 iterations without one. So its Cholesky factor is kept and reused
 * across iterations and steps (the chord method; the Hessian changes little
 * from one step to the next: M/h² dominates it and the elastic part moves
 * slowly), corrected by the quasi-Newton pairs of the iterations since it
 * was made (newton.h; PAIRS of them, kept across steps: the steps'
 * objectives differ by terms linear in q). A fresh one is made at the start
 * of a step when the last step needed more than SLOW_ITERS iterations with
 * the reused one, within a step after LAG_ITERS iterations without
 * convergence, and when the reused one fails to give an acceptable step
 * (newton.h). Measured on a 222-dimensional skinning subspace over 197 tets
 * (soft bar of issue 14, dt 0.05, 100 steps, one core, under load): a
 * fresh Hessian at every iteration takes 3.9 iterations per step (6 ms);
 * the chord method alone, refreshed after 4 iterations of a step, 7.1
 * iterations and 1.2 Hessians per step (2.4-2.7 ms median); with the pairs,
 * this schedule and the extrapolated start 7.4 iterations and 0.2 Hessians
 * (0.5 ms median, 0.9 ms mean). More pairs (32) or a later refresh
 * (SLOW_ITERS 12) changed little; refreshing within the step after 8
 * iterations, or the chord method without pairs at its best refresh (12
 * iterations of a step), cost about 30% more (9.7 iterations and 0.25
 * Hessians per step for the latter). */

static int step_objective(void *ctx, const double *q, double *E, double *g, double *H, int project)
{
    return crom_rsim_objective(ctx, q, E, g, H, project);
}

static int step_wants_hessian(void *ctx, int it)
{
    crom_rsim *s = ctx;
    return !s->fac_ok || (it == 0 && s->fac_slow) || s->fac_iters >= LAG_ITERS;
}

static void step_stale(void *ctx) { ((crom_rsim *)ctx)->fac_ok = 0; }

static int step_direction(void *ctx, int it, int project, const double *q, const double *g, const double *H,
                          double *d)
{
    crom_rsim *s = ctx;
    int r = s->r;
    for (int i = 0; i < r; i++)
        d[i] = -g[i];
    if (s->solver == CROM_RSIM_GD) { /* descent: the gradient in the metric of the reduced mass */
        LAPACKE_dpotrs(LAPACK_ROW_MAJOR, 'U', r, 1, s->Gfac, r, d, 1);
        return 0;
    }
    if (H) { /* a fresh Hessian: factor it, H = UᵀU (row-major upper U is the
              * column-major lower factor: no transposed copies) */
        memcpy(s->Hfac, H, sizeof(double) * (size_t)r * r);
        s->fac_iters = 0;
        s->fac_slow = 0;
        if (!(s->fac_ok = LAPACKE_dpotrf_work(LAPACK_COL_MAJOR, 'L', r, s->Hfac, r) == 0))
            return 1;
    }
    s->fac_iters++;
    cblas_dtrsv(CblasRowMajor, CblasUpper, CblasTrans, CblasNonUnit, r, s->Hfac, r, d, 1);
    cblas_dtrsv(CblasRowMajor, CblasUpper, CblasNoTrans, CblasNonUnit, r, s->Hfac, r, d, 1);
    return 0;
}

static double step_size(void *ctx, const double *d) { return rms_disp(ctx, d); }

int crom_rsim_step(crom_rsim *s, crom_rsim_stats *st)
{
    const crom_scenario *sc = s->sc;
    int r = s->r;
    double h = sc->dt, t0 = crom_clock_now();
    memset(st, 0, sizeof *st);
    crom_rsim_begin_step(s);
    /* Newton starts from q̂ plus the last step's correction q − q̂ (h² times
     * its acceleration: a second-order extrapolation); the paper's descent
     * from q̂ */
    int newton = s->solver != CROM_RSIM_GD, lag = s->lagged && newton;
    for (int i = 0; i < r; i++)
        s->q[i] = s->qhat[i] + (newton ? s->corr[i] : 0);
    if (!lag)
        s->fac_ok = 0;
    s->fac_iters = 0; /* a reused factor gets LAG_ITERS iterations in each step */
    const crom_newton_problem prob = {r, step_objective, step_direction, step_size,
                                      lag ? step_wants_hessian : NULL, lag ? step_stale : NULL,
                                      s->solver == CROM_RSIM_GD, "Newton", "the reduced Hessian is singular", 1};
    const crom_newton_work w = {s->g, s->H, s->d, s->qt, &s->mem};
    int rc = crom_newton_solve(&prob, s, &w, s->q, sc->tol, sc->max_iter, s->step, &st->iterations,
                               &st->residual, &st->converged);
    if (rc)
        return rc;
    s->fac_slow = s->fac_iters > SLOW_ITERS;
    for (int i = 0; i < r; i++) {
        s->corr[i] = s->q[i] - s->qhat[i];
        s->qd[i] = (s->q[i] - s->qn[i]) / h;
    }
    s->step++;
    s->t = (double)s->step * h; /* exact multiples of dt (issue 12) */
    st->vertex_evals = 4 * s->cub->k + sc->nplanes * s->cub->nsurf;
    st->seconds = crom_clock_now() - t0;
    return 0;
}

double crom_rsim_constraint_residual(const crom_rsim *s)
{
    const crom_cubature *c = s->cub;
    int r = s->r;
    double worst = 0;
    for (int k = 0; k < s->nbc; k++) {
        double u[3] = {0, 0, 0};
        if (s->bc[k].bc)
            crom_bc_displacement(s->bc[k].bc, s->t, u);
        for (int j = 0; j < s->bc[k].n; j++) {
            int v = s->bc[k].idx[j];
            double w[3] = {-u[0], -u[1], -u[2]};
            cblas_dgemv(CblasRowMajor, CblasNoTrans, 3, r, 1.0, c->W + (size_t)v * 3 * r, r, s->q, 1, 1.0, w, 1);
            worst = fmax(worst, sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]));
        }
    }
    return worst;
}

int crom_rsim_energies(crom_rsim *s, double *kinetic, double *elastic, double *external)
{
    int r = s->r;
    double Ee = 0, W = 0, *f = s->gt, *Mqd = s->gt + r;
    cblas_dsymv(CblasRowMajor, CblasUpper, r, 1.0, s->Mr, r, s->qd, 1, 0.0, Mqd, 1);
    double K = 0.5 * cblas_ddot(r, s->qd, 1, Mqd, 1);
    loads(s, s->t, f);
    for (int i = 0; i < r; i++)
        W -= f[i] * s->q[i];
    int rc = crom_elastic_eval(&s->el, &s->mat, s->q, 0, &Ee, NULL, NULL);
    if (rc)
        return rc;
    *kinetic = K;
    *elastic = Ee;
    *external = W + rods_eval(s, s->q, s->t, NULL, NULL, 0);
    return 0;
}
