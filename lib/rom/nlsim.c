/* nlrom.c — implicit Euler over the latent of a one-mesh map, Gauss–Newton
 * on the full-space incremental potential (see nlrom.h). */
#ifdef _OPENMP
#include <omp.h>
#endif
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <cblas.h>
#include <lapacke.h>

#include "base/clock.h"
#include "base/err.h"
#include "base/linesearch.h"
#include "phys/contact.h"
#include "rom/cubature.h"
#include "rom/newton.h"
#include "rom/nlsim.h"

/* The reuse schedule of a linear basis's Gauss–Newton matrix (as crom_rsim
 * does, rsim.c): a fresh one at a step's start after a step of more than
 * SLOW_ITERS iterations, within a step after LAG_ITERS, and when the reused
 * one fails; PAIRS quasi-Newton pairs correct it. A step that does not
 * converge so is solved again with a fresh matrix at every iteration.
 * Measured on sheet.mk's hanging sheet in the skinning eigenmodes of 8
 * handles (rank 72, every triangle and hinge, 60 steps): at E = 1e9 the
 * median step fell from 83 ms to 0.95 ms (mean 16 ms) with the same result;
 * at E = 1e8 (a large rotation) from 98 to 5.6 ms (mean 34), where
 * crom_rsim's schedule (24 and 10) left early steps unconverged after 50
 * iterations, and 5 and 4 cost more (20 ms median). */
#define SLOW_ITERS 6
#define LAG_ITERS 8
#define PAIRS 16

/* Elements join up to MV vertices (a scene's joints and contacts: 8); the
 * element lists hold MV slots each, −1 after the last vertex. */
#define MV CROM_SYSTEM_MAXV
/* per-thread element scratch: crom_cubature_tet's (168 + 12 r) or
 * elem_reduced's (WR(r)), then the Jacobian rows J_e [3 MV][r] and the
 * positions xe [3 MV] */
#define WR(r) (9 * MV * MV + 3 * MV + 3 * MV * (size_t)(r))
#define TW(r) (WR(r) + 3 * MV * (size_t)(r) + 3 * MV)

/* the vertices of an element list entry (its slots up to the first −1) */
static int elem_count(const int *e)
{
    int k = 0;
    while (k < MV && e[k] >= 0)
        k++;
    return k;
}

static void free_bcs(crom_nlsim_bc *b, int n)
{
    for (int i = 0; b && i < n; i++)
        free(b[i].idx);
    free(b);
}

void crom_nlsim_free(crom_nlsim *s)
{
    if (!s)
        return;
    crom_system_free(&s->sys);
    double **bufs[] = {&s->q,  &s->qd, &s->va, &s->Bg, &s->qn, &s->fa, &s->gx, &s->J,  &s->Jt,
                       &s->g,  &s->H,  &s->d,  &s->qt, &s->Gm, &s->lam,  &s->zero, &s->tw, &s->tH,
                       &s->tg, &s->tE, &s->a,  &s->T,  &s->an, &s->ga,   &s->A0, &s->Aq, &s->bq,
                       &s->AT, &s->xc, &s->Jc, &s->gc, &s->ge, &s->ew, &s->xt, &s->wd, &s->Bc, &s->Xc,
                       &s->Hfac};
    for (size_t i = 0; i < sizeof bufs / sizeof *bufs; i++)
        free(*bufs[i]);
    free(s->surf);
    free(s->xs);
    free(s->eidx);
    free(s->cv);
    free(s->eloc);
    free_bcs(s->bc, s->nbc);
    free_bcs(s->force, s->nforce);
    free(s->rod_d0);
    free(s->rod_rest);
    free(s->rod_D);
    crom_newton_memory_free(&s->mem);
    memset(s, 0, sizeof *s);
}

static int region(crom_nlsim *s, const char *ref, const crom_bc *bc, crom_nlsim_bc *b)
{
    int rc = crom_mesh_select(&s->map->mesh, ref, &b->idx, &b->n);
    if (rc)
        return rc;
    b->bc = bc;
    for (int k = 0; k < b->n; k++)
        b->mass += s->sys.mass[b->idx[k]];
    return 0;
}

/* The scenario's rods in the map's features: each end's mass-weighted
 * sums of its vertices' rest positions and rows of B. */
static int rods_setup(crom_nlsim *s)
{
    const crom_scenario *sc = s->sc;
    const crom_map *map = s->map;
    int p = s->p, nr = sc->nrod, rc = 0;
    s->nrod = nr;
    s->rod_d0 = crom_calloc((size_t)3 * nr + 1, sizeof(double));
    s->rod_rest = crom_calloc((size_t)nr + 1, sizeof(double));
    s->rod_D = crom_calloc((size_t)3 * nr * p + 1, sizeof(double));
    if (!s->rod_d0 || !s->rod_rest || !s->rod_D)
        return CROM_EINTERNAL;
    for (int k = 0; k < nr && !rc; k++) {
        double *d0 = s->rod_d0 + 3 * k, *D = s->rod_D + (size_t)3 * k * p, l0[3] = {0, 0, 0};
        for (int e = 0; e < 2 && !rc; e++) {
            crom_nlsim_bc b;
            memset(&b, 0, sizeof b);
            const char *ref = e ? sc->rod[k].b : sc->rod[k].a;
            if ((rc = region(s, ref, NULL, &b)))
                crom_err_ctx("--rod");
            else if (!(b.mass > 0))
                rc = crom_err(CROM_EUSAGE, "--rod: end '%s' has no mass", ref);
            for (int j = 0; !rc && j < b.n; j++) {
                int v = b.idx[j];
                double w = (e ? 1 : -1) * s->sys.mass[v] / b.mass;
                for (int c = 0; c < 3; c++) {
                    d0[c] += w * map->x0[3 * (size_t)v + c];
                    l0[c] += w * map->mesh.X[3 * (size_t)v + c];
                    cblas_daxpy(p, w, map->B + (3 * (size_t)v + c) * p, 1, D + (size_t)c * p, 1);
                }
            }
            free(b.idx);
        }
        s->rod_rest[k] = sqrt(l0[0] * l0[0] + l0[1] * l0[1] + l0[2] * l0[2]); /* the ends' distance at rest */
    }
    return rc;
}

/* The rods' energy at features a and time t; ga [p] (may be NULL) gets
 * their gradient in a, Drodᵀ g_d, and H [r][r] (may be NULL) their
 * Gauss–Newton term (Drod T)ᵀ H_d (Drod T) with T = s->T. */
static double rods_eval(crom_nlsim *s, const double *a, double t, double *ga, double *H, int project)
{
    int p = s->p, r = s->r;
    double E = 0;
    for (int k = 0; k < s->nrod; k++) {
        const double *D = s->rod_D + (size_t)3 * k * p;
        double d[3], gd[3], Hd[9];
        memcpy(d, s->rod_d0 + 3 * k, sizeof d);
        cblas_dgemv(CblasRowMajor, CblasNoTrans, 3, p, 1.0, D, p, a, 1, 1.0, d, 1);
        E += crom_rod_eval(s->sc->rod[k].k, crom_rod_length(&s->sc->rod[k], s->rod_rest[k], t), d, gd,
                           H ? Hd : NULL, project);
        if (ga)
            cblas_dgemv(CblasRowMajor, CblasTrans, 3, p, 1.0, D, p, gd, 1, 1.0, ga, 1);
        if (H) { /* DT = D T [3][r] (in Jt's room), H += DTᵀ Hd DT */
            double *DT = s->Jt, *HDT = s->Jt + 3 * (size_t)r;
            cblas_dgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, 3, r, p, 1.0, D, p, s->T, r, 0.0, DT, r);
            cblas_dgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, 3, r, 3, 1.0, Hd, 3, DT, r, 0.0, HDT, r);
            cblas_dgemm(CblasRowMajor, CblasTrans, CblasNoTrans, r, r, 3, 1.0, DT, r, HDT, r, 1.0, H, r);
        }
    }
    return E;
}

/* H = Jᵀ M J (upper triangle) of the Jacobian in s->J: the mass-weighted
 * Gram matrix of the latent directions */
static void mass_gram(crom_nlsim *s)
{
    int r = s->r, n = s->n;
    for (int i = 0; i < n; i++) {
        double sq = sqrt(s->sys.mass[i / 3]);
        for (int k = 0; k < r; k++)
            s->Jt[(size_t)i * r + k] = sq * s->J[(size_t)i * r + k];
    }
    cblas_dsyrk(CblasRowMajor, CblasUpper, CblasTrans, r, n, 1.0, s->Jt, r, 0.0, s->H, r);
}

/* q̇ minimizing ‖J q̇ − v‖_M, v = v0 + ω × (X − c) */
static int initial_velocity(crom_nlsim *s)
{
    const crom_scenario *sc = s->sc;
    int r = s->r, n = s->n;
    if (!(sc->v0[0] || sc->v0[1] || sc->v0[2] || sc->spin[0] || sc->spin[1] || sc->spin[2]))
        return 0;
    double c[3] = {0, 0, 0}, m = 0;
    const double *X = s->map->x0;
    for (int v = 0; v < s->map->nv; v++) {
        m += s->sys.mass[v];
        for (int k = 0; k < 3; k++)
            c[k] += s->sys.mass[v] * X[3 * v + k];
    }
    for (int k = 0; k < 3; k++)
        c[k] /= m;
    for (int v = 0; v < s->map->nv; v++) {
        double vv[3];
        crom_scenario_initial_velocity(sc, c, X + 3 * v, vv);
        for (int k = 0; k < 3; k++)
            s->gx[3 * v + k] = s->sys.mass[v] * vv[k];
    }
    int rc = crom_map_eval(s->map, s->q, NULL, s->J);
    if (rc)
        return rc;
    mass_gram(s);
    cblas_dgemv(CblasRowMajor, CblasTrans, n, r, 1.0, s->J, r, s->gx, 1, 0.0, s->qd, 1);
    if (LAPACKE_dposv(LAPACK_ROW_MAJOR, 'U', r, 1, s->H, r, s->qd, 1) != 0)
        return crom_err(CROM_EDATA, "the map's latent directions are degenerate at the initial state");
    return 0;
}

/* The tets of the elastic energy, their weights and the vertices they
 * touch (cv: NULL when that is every vertex). */
static int set_elastic(crom_nlsim *s, int k, const int *elem, const double *weight)
{
    int nv = s->map->nv, r = s->r;
    int *eidx = crom_malloc(sizeof(int) * (size_t)(k ? k : 1));
    int *eloc = crom_malloc(sizeof(int) * MV * (size_t)(k ? k : 1));
    double *ew = crom_malloc(sizeof(double) * (size_t)(k ? k : 1));
    int *loc = crom_malloc(sizeof(int) * (size_t)nv), *cv = crom_malloc(sizeof(int) * (size_t)nv), ncv = 0;
    if (!eidx || !eloc || !ew || !loc || !cv) {
        free(eidx), free(eloc), free(ew), free(loc), free(cv);
        return CROM_EINTERNAL;
    }
    for (int v = 0; v < nv; v++)
        loc[v] = -1;
    for (int j = 0; j < k; j++) {
        eidx[j] = elem ? elem[j] : j;
        ew[j] = weight ? weight[j] : 1;
        int ev[CROM_SYSTEM_MAXV], ke = crom_system_elem_vertices(&s->sys, eidx[j], ev);
        for (int c = 0; c < ke; c++) {
            int v = ev[c];
            if (loc[v] < 0) {
                loc[v] = ncv;
                cv[ncv++] = v;
            }
        }
    }
    int every = ncv == nv;
    for (int j = 0; j < k; j++) {
        int ev[CROM_SYSTEM_MAXV], ke = crom_system_elem_vertices(&s->sys, eidx[j], ev);
        for (int c = 0; c < MV; c++)
            eloc[MV * j + c] = c >= ke ? -1 : every ? ev[c] : loc[ev[c]];
    }
    free(loc);
    if (every) {
        free(cv);
        cv = NULL;
    }
    free(s->eidx), free(s->eloc), free(s->ew), free(s->cv), free(s->xc), free(s->Jc), free(s->gc), free(s->Bc),
        free(s->Xc), free(s->ge);
    s->Bc = s->Xc = NULL;
    s->eidx = eidx;
    s->eloc = eloc;
    s->ew = ew;
    s->cv = cv;
    s->ne = k;
    s->ncv = ncv;
    s->xc = crom_malloc(sizeof(double) * 3 * (size_t)(ncv ? ncv : 1));
    s->gc = crom_malloc(sizeof(double) * 3 * (size_t)(ncv ? ncv : 1));
    s->Jc = crom_malloc(sizeof(double) * 3 * (size_t)(ncv ? ncv : 1) * r);
    s->ge = crom_malloc(sizeof(double) * 3 * MV * (size_t)(k ? k : 1));
    if (!s->xc || !s->gc || !s->Jc || !s->ge)
        return CROM_EINTERNAL;
    if (cv) { /* the rows of B and X at the elastic vertices, contiguous: two BLAS calls per evaluation */
        int p = s->p;
        s->Bc = crom_malloc(sizeof(double) * 3 * (size_t)ncv * p);
        s->Xc = crom_malloc(sizeof(double) * 3 * (size_t)ncv);
        if (!s->Bc || !s->Xc)
            return CROM_EINTERNAL;
        for (int i = 0; i < ncv; i++) {
            memcpy(s->Bc + (size_t)i * 3 * p, s->map->B + (size_t)cv[i] * 3 * p, sizeof(double) * 3 * (size_t)p);
            memcpy(s->Xc + 3 * (size_t)i, s->map->x0 + 3 * (size_t)cv[i], sizeof(double) * 3);
        }
    }
    return 0;
}

int crom_nlsim_use_cubature(crom_nlsim *s, int k, const int *elem, const double *weight)
{
    s->fac_ok = 0; /* another objective: no reused Gauss–Newton matrix */
    if (s->lagged)
        crom_newton_memory_reset(&s->mem);
    if (k < 1)
        return crom_err(CROM_EDATA, "the cubature has no elements");
    for (int j = 0; j < k; j++) {
        if (elem[j] < 0 || elem[j] >= s->sys.nenergy)
            return crom_err(CROM_EDATA, "cubature element %d is not an element of the map's mesh (%d %s)", elem[j],
                            s->sys.nenergy,
                            s->sys.rigid ? "scene elements" : s->sys.shell ? "triangles and hinges" : "tets");
        if (!(isfinite(weight[j]) && weight[j] >= 0))
            return crom_err(CROM_EDATA, "cubature weight %d is %g: weights must be finite and >= 0", j, weight[j]);
    }
    return set_elastic(s, k, elem, weight);
}

/* B_vᵀ y for the 3 rows of vertex v, accumulated into out [p] */
static void rows_t(const crom_map *map, int v, double alpha, const double y[3], double *out)
{
    cblas_dgemv(CblasRowMajor, CblasTrans, 3, map->p, alpha, map->B + (size_t)v * 3 * map->p, map->p, y, 1, 1.0, out, 1);
}

/* The step-independent quadratic: A0 = BᵀMB and Aq = (1/h² + A/h) A0 +
 * κ Σ_bc B_vᵀ m_v B_v (full, symmetric). */
static int quadratic_setup(crom_nlsim *s)
{
    const crom_map *map = s->map;
    int n = s->n, p = s->p;
    double h = s->sc->dt, cq = 1 / (h * h) + s->sc->damping / h;
    double *Bs = crom_malloc(sizeof(double) * (size_t)n * p);
    if (!Bs)
        return CROM_EINTERNAL;
    for (int i = 0; i < n; i++) {
        double sq = sqrt(s->sys.mass[i / 3]);
        for (int k = 0; k < p; k++)
            Bs[(size_t)i * p + k] = sq * map->B[(size_t)i * p + k];
    }
    cblas_dsyrk(CblasRowMajor, CblasUpper, CblasTrans, p, n, 1.0, Bs, p, 0.0, s->A0, p);
    free(Bs);
    /* Bg [c][p] = Bᵀ M 1_c: the features' share of a uniform acceleration */
    memset(s->Bg, 0, sizeof(double) * 3 * (size_t)p);
    for (int i = 0; i < n; i++)
        cblas_daxpy(p, s->sys.mass[i / 3], map->B + (size_t)i * p, 1, s->Bg + (size_t)(i % 3) * p, 1);
    for (int i = 0; i < p; i++)
        for (int j = 0; j < i; j++)
            s->A0[i * p + j] = s->A0[j * p + i];
    for (size_t i = 0; i < (size_t)p * p; i++)
        s->Aq[i] = cq * s->A0[i];
    for (int k = 0; k < s->nbc; k++) {
        const crom_nlsim_bc *b = &s->bc[k];
        for (int j = 0; j < b->n; j++) {
            int v = b->idx[j];
            cblas_dsyrk(CblasRowMajor, CblasUpper, CblasTrans, p, 3, s->kappa * s->sys.mass[v],
                        map->B + (size_t)v * 3 * p, p, 1.0, s->Aq, p);
        }
    }
    for (int i = 0; i < p; i++)
        for (int j = 0; j < i; j++)
            s->Aq[i * p + j] = s->Aq[j * p + i];
    return 0;
}

int crom_nlsim_init(crom_nlsim *s, crom_map *map, const crom_scenario *sc, double kappa, const double *q0,
                    const double *qd0, int nthreads)
{
    memset(s, 0, sizeof *s);
    int rc = crom_scenario_check(sc);
    if (!rc)
        rc = crom_scenario_check_regions(sc, &map->mesh);
    if (rc)
        return rc;
    s->sc = sc;
    s->map = map;
    s->r = map->r;
    s->n = map->n;
    s->p = map->p;
    s->nthreads = nthreads < 1 ? 1 : nthreads > 256 ? 256 : nthreads;
    s->kappa = kappa > 0 ? kappa : 1e4 / (sc->dt * sc->dt);
    if (crom_mesh_is_scene(&map->mesh) && sc->nplanes)
        return crom_err(CROM_EUSAGE, "--plane, --sphere: collisions with the world are not simulated on rigid-body "
                        "scenes yet (a scene's vertices are its bodies' frames, not surface points)");
    if ((rc = crom_system_init(&s->sys, &map->mesh, sc->youngs, sc->poisson, sc->density)) ||
        (rc = crom_system_set_materials(&s->sys, sc, &map->mesh)))
        return rc;
    int r = s->r, n = s->n, p = s->p, T = s->nthreads;
    size_t rr = (size_t)r * r, nr = (size_t)n * r, pp = (size_t)p * p, pr = (size_t)p * r;
    double **vr[] = {&s->q, &s->qd, &s->qn, &s->g, &s->d, &s->qt, &s->zero};
    double **vn[] = {&s->xt, &s->wd, &s->gx};
    double **vrr[] = {&s->H, &s->Gm};
    double **vp[] = {&s->a, &s->an, &s->va, &s->fa, &s->ga, &s->bq, &s->Bg, &s->T, &s->AT, &s->A0, &s->Aq};
    size_t np[] = {p, p, p, p, p, p, 3 * (size_t)p, pr, pr, pp, pp};
    for (size_t i = 0; i < sizeof vp / sizeof *vp; i++)
        *vp[i] = crom_calloc(np[i], sizeof(double));
    for (size_t i = 0; i < sizeof vr / sizeof *vr; i++)
        *vr[i] = crom_calloc((size_t)r, sizeof(double));
    for (size_t i = 0; i < sizeof vn / sizeof *vn; i++)
        *vn[i] = crom_calloc((size_t)n, sizeof(double));
    for (size_t i = 0; i < sizeof vrr / sizeof *vrr; i++)
        *vrr[i] = crom_calloc(rr, sizeof(double));
    s->J = crom_malloc(sizeof(double) * nr);
    s->Jt = crom_malloc(sizeof(double) * nr);
    s->tw = crom_malloc(sizeof(double) * TW(r) * T);
    s->tH = crom_malloc(sizeof(double) * rr * T);
    s->tg = crom_malloc(sizeof(double) * (size_t)r * T);
    s->tE = crom_malloc(sizeof(double) * (size_t)T);
    s->bc = crom_calloc((size_t)(sc->npins + sc->nvel + 1), sizeof(crom_nlsim_bc));
    s->force = crom_calloc((size_t)(sc->nforce + 1), sizeof(crom_nlsim_bc));
    int ok = s->J && s->Jt && s->tw && s->tH && s->tg && s->tE && s->bc && s->force;
    for (size_t i = 0; i < sizeof vr / sizeof *vr; i++)
        ok = ok && *vr[i];
    for (size_t i = 0; i < sizeof vn / sizeof *vn; i++)
        ok = ok && *vn[i];
    for (size_t i = 0; i < sizeof vrr / sizeof *vrr; i++)
        ok = ok && *vrr[i];
    for (size_t i = 0; i < sizeof vp / sizeof *vp; i++)
        ok = ok && *vp[i];
    if (!ok) {
        crom_nlsim_free(s);
        return CROM_EINTERNAL;
    }
    if (!map->nonlinear) { /* a linear basis: reuse its Gauss–Newton matrix */
        s->lagged = 1;
        if (!(s->Hfac = crom_malloc(sizeof(double) * rr)) || crom_newton_memory_init(&s->mem, r, PAIRS)) {
            crom_nlsim_free(s);
            return CROM_EINTERNAL;
        }
    }
    double lo[3], hi[3];
    crom_mesh_bbox(&map->mesh, lo, hi);
    s->L = sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                (hi[2] - lo[2]) * (hi[2] - lo[2]));
    for (int i = 0; i < sc->npins && !rc; i++)
        rc = region(s, sc->pins[i], NULL, &s->bc[s->nbc++]);
    for (int i = 0; i < sc->nvel && !rc; i++)
        rc = region(s, sc->vel[i].ref, &sc->vel[i], &s->bc[s->nbc++]);
    for (int i = 0; i < sc->nforce && !rc; i++)
        rc = region(s, sc->force[i].ref, &sc->force[i], &s->force[s->nforce++]);
    if (rc) {
        crom_err_ctx("scenario");
        crom_nlsim_free(s);
        return CROM_EUSAGE;
    }
    if (map->inner && map->p == 9 * (map->inner->p + 1) + 3) /* a rigid frame (sandwich_frame) */
        s->frame_pb = map->inner->p + 1;
    if ((rc = rods_setup(s)) || (rc = quadratic_setup(s)) || (rc = set_elastic(s, s->sys.nenergy, NULL, NULL))) {
        crom_nlsim_free(s);
        return rc;
    }
    if (sc->nplanes) { /* contact points: the boundary vertices (every vertex of a shell) */
        int ntri = 0, *tris = NULL;
        unsigned char *on = crom_calloc((size_t)map->nv, 1);
        if (on && s->sys.shell)
            memset(on, 1, (size_t)map->nv);
        else if (!on || (rc = crom_mesh_boundary(&map->mesh, &ntri, &tris, NULL))) {
            free(on);
            crom_nlsim_free(s);
            return rc ? rc : CROM_EINTERNAL;
        }
        for (int i = 0; i < 3 * ntri; i++)
            on[tris[i]] = 1;
        free(tris);
        s->surf = crom_malloc(sizeof(int) * (size_t)map->nv);
        s->xs = crom_malloc(sizeof(double) * 3 * (size_t)map->nv);
        s->lam = crom_calloc((size_t)sc->nplanes * map->nv, sizeof(double));
        if (!s->surf || !s->xs || !s->lam) {
            free(on);
            crom_nlsim_free(s);
            return CROM_EINTERNAL;
        }
        for (int v = 0; v < map->nv; v++)
            if (on[v])
                s->surf[s->nsurf++] = v;
        free(on);
    }
    /* initial state: q0, or rest, which is q = 0 in every map (lib/map.h) */
    if (q0)
        memcpy(s->q, q0, sizeof(double) * (size_t)r);
    if (qd0)
        memcpy(s->qd, qd0, sizeof(double) * (size_t)r);
    else if ((rc = initial_velocity(s)))
        goto fail;
    /* the state's features and their velocity va = T q̇ (v = J q̇ = B va) */
    if ((rc = crom_map_features(map, s->q, s->an, s->T)))
        goto fail;
    cblas_dgemv(CblasRowMajor, CblasNoTrans, p, r, 1.0, s->T, r, s->qd, 1, 0.0, s->va, 1);
    return 0;
fail:
    crom_nlsim_free(s);
    return rc;
}

int crom_nlsim_set_condition(crom_nlsim *s, crom_map *map, crom_scenario *sc, const crom_scenario_cond *conds,
                             const double *c)
{
    int rc = 0;
    for (int k = 0; k < map->nc && !rc; k++)
        rc = crom_scenario_cond_apply(sc, &conds[k], c[k]);
    if (rc || (rc = crom_map_set_condition(map, c)) || !s->map)
        return rc;
    if (sc->nmat && (rc = crom_system_set_materials(&s->sys, sc, &map->mesh)))
        return rc;
    if (map->xs) { /* a pin condition moved x0: the cached rows of it */
        for (int i = 0; s->cv && i < s->ncv; i++)
            memcpy(s->Xc + 3 * (size_t)i, map->x0 + 3 * (size_t)s->cv[i], sizeof(double) * 3);
        free(s->rod_d0), free(s->rod_rest), free(s->rod_D);
        s->rod_d0 = s->rod_rest = s->rod_D = NULL;
        if ((rc = rods_setup(s)))
            return rc;
    }
    /* the state's features and their velocity at the new c */
    if ((rc = crom_map_features(map, s->q, s->an, s->T)))
        return rc;
    cblas_dgemv(CblasRowMajor, CblasNoTrans, s->p, s->r, 1.0, s->T, s->r, s->qd, 1, 0.0, s->va, 1);
    s->fac_ok = 0;
    return 0;
}

/* fa = Bᵀ f_ext(t): gravity through Bg, the region forces through their
 * vertices' rows */
static void feature_loads(crom_nlsim *s, double t, double *fa)
{
    int p = s->p;
    const double *g = s->sc->gravity;
    cblas_dgemv(CblasRowMajor, CblasTrans, 3, p, 1.0, s->Bg, p, g, 1, 0.0, fa, 1);
    for (int b = 0; b < s->nforce; b++) {
        const crom_nlsim_bc *fb = &s->force[b];
        double F[3];
        crom_bc_force(fb->bc, t, F);
        for (int k = 0; k < fb->n; k++) {
            int v = fb->idx[k];
            rows_t(s->map, v, s->sys.mass[v] / fb->mass, F, fa);
        }
    }
}

void crom_nlsim_begin_step(crom_nlsim *s)
{
    const crom_scenario *sc = s->sc;
    const crom_map *map = s->map;
    int p = s->p;
    double h = sc->dt, t1 = (double)(s->step + 1) * h; /* step * dt, not a running sum */
    const double *m = s->sys.mass;
    memcpy(s->qn, s->q, sizeof(double) * (size_t)s->r);
    /* the linear term b and constant of the quadratic in δ = a − a_n:
     * inertia ½/h² ‖Bδ − h B va‖²_M, external −f·Bδ, penalty
     * ½κ Σ m_v ‖B_v δ + e_v‖², e_v = B_v a_n − ū_v(t+h) */
    feature_loads(s, t1, s->bq);
    cblas_dsymv(CblasRowMajor, CblasUpper, p, -1 / h, s->A0, p, s->va, 1, -1.0, s->bq, 1);
    cblas_dsymv(CblasRowMajor, CblasUpper, p, 1.0, s->A0, p, s->va, 1, 0.0, s->fa, 1);
    double c0 = 0.5 * cblas_ddot(p, s->va, 1, s->fa, 1);
    for (int k = 0; k < s->nbc; k++) {
        const crom_nlsim_bc *b = &s->bc[k];
        double u[3] = {0, 0, 0};
        if (b->bc)
            crom_bc_displacement(b->bc, t1, u);
        for (int j = 0; j < b->n; j++) {
            int v = b->idx[j];
            double e[3];
            crom_map_rows(map, &v, 1, s->an, NULL, e, NULL);
            for (int c = 0; c < 3; c++)
                e[c] -= map->x0[3 * v + c] + u[c];
            rows_t(map, v, s->kappa * m[v], e, s->bq);
            c0 += 0.5 * s->kappa * m[v] * (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
        }
    }
    s->c0 = c0;
    /* the surface vertices at the step's start (contact's x_n) and the
     * lagged normal forces of friction */
    if (sc->nplanes)
        crom_map_rows(map, s->surf, s->nsurf, s->an, NULL, s->xs, NULL);
    for (int pl = 0; pl < sc->nplanes; pl++)
        for (int k = 0; k < s->nsurf; k++)
            s->lam[(size_t)pl * s->nsurf + k] =
                sc->contact_stiffness * m[s->surf[k]] * crom_contact_depth(&sc->plane[pl], s->xs + 3 * (size_t)k);
}

/* The elastic energy at the vertex positions in s->xc and its gradient in
 * x at the elastic vertices, s->gc = Σ_e w_e ∇_x E_e (per-tet gradients
 * over the threads, scattered in order). */
static int elastic_xgrad(crom_nlsim *s, double *E)
{
    int ne = s->ne, bad = 0;
    double Es = 0;
#pragma omp parallel for num_threads(s->nthreads) schedule(static) reduction(| : bad) reduction(+ : Es)
    for (int j = 0; j < ne; j++) {
        const int *e = s->eloc + MV * (size_t)j;
        int ke = elem_count(e);
        double xe[3 * MV], Ee, *ge = s->ge + 3 * MV * (size_t)j;
        for (int a = 0; a < ke; a++)
            memcpy(xe + 3 * a, s->xc + 3 * (size_t)e[a], 3 * sizeof(double));
        if (crom_system_elem_eval(&s->sys, s->eidx[j], xe, 0, &Ee, ge, NULL) || !isfinite(Ee))
            bad = 1;
        else
            Es += s->ew[j] * Ee;
    }
    if (bad)
        return crom_err(CROM_EDATA, "non-finite elastic energy");
    memset(s->gc, 0, sizeof(double) * 3 * (size_t)s->ncv);
    for (int j = 0; j < ne; j++) {
        const int *e = s->eloc + MV * (size_t)j;
        for (int a = 0, ke = elem_count(e); a < ke; a++)
            for (int c = 0; c < 3; c++)
                s->gc[3 * (size_t)e[a] + c] += s->ew[j] * s->ge[3 * MV * (size_t)j + 3 * a + c];
    }
    *E = Es;
    return 0;
}

/* A shell's or a scene's element's energy, and its reduced gradient tg +=
 * w J_eᵀ g_e and Hessian tH += w J_eᵀ H_e J_e (tH NULL: none) with J_e =
 * J4 [3ke][r] the map's Jacobian rows at its vertices; work holds WR(r)
 * doubles. Returns the element's energy, or NaN when it is not finite. */
static double elem_reduced(const crom_system *sys, int t, int ke, const double *xe, const double *J4, int r,
                           double w, int project, double *tg, double *tH, double *work)
{
    int m = 3 * ke;
    double Ee, *He = work, *ge = work + 9 * MV * MV, *HJ = ge + 3 * MV;
    if (crom_system_elem_eval(sys, t, xe, project, &Ee, ge, tH ? He : NULL))
        return NAN;
    if (tg)
        cblas_dgemv(CblasRowMajor, CblasTrans, m, r, w, J4, r, ge, 1, 1.0, tg, 1);
    if (tH) {
        cblas_dsymm(CblasRowMajor, CblasLeft, CblasUpper, m, r, 1.0, He, m, J4, r, 0.0, HJ, r);
        cblas_dgemm(CblasRowMajor, CblasTrans, CblasNoTrans, r, r, m, w, J4, r, HJ, r, 1.0, tH, r);
    }
    return Ee;
}

/* Elastic energy at the features in s->a, and (g, H non-NULL) its reduced
 * gradient and Hessian Σ_e w_e J_eᵀ H_e J_e, over the elastic tets, split
 * over the threads. The positions (and with g or H the Jacobian rows) of
 * their vertices are left in s->xc (s->Jc). */
static int elastic(crom_nlsim *s, double *E, double *g, double *H, int project)
{
    int r = s->r, T = s->nthreads, bad = 0, ne = s->ne;
    size_t rr = (size_t)r * r;
    const crom_system *sys = &s->sys;
    const crom_fem *f = &sys->fem;
    int jac = H != NULL; /* the gradient alone goes through x: g += Tᵀ Bᵀ Σ w_e ∇_x E_e */
    if (s->cv) { /* xc = Xc + Bc a, Jc = Bc T */
        int m3 = 3 * s->ncv, p = s->p;
        memcpy(s->xc, s->Xc, sizeof(double) * (size_t)m3);
        cblas_dgemv(CblasRowMajor, CblasNoTrans, m3, p, 1.0, s->Bc, p, s->a, 1, 1.0, s->xc, 1);
        if (jac)
            cblas_dgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, m3, r, p, 1.0, s->Bc, p, s->T, r, 0.0, s->Jc, r);
    } else {
        crom_map_rows(s->map, NULL, 0, s->a, s->T, s->xc, jac ? s->Jc : NULL);
    }
    if (g && !jac) {
        int rc, p = s->p;
        if ((rc = elastic_xgrad(s, E)))
            return rc;
        double *gf = s->AT; /* scratch [p]: Bᵀ gc, then g += Tᵀ gf */
        cblas_dgemv(CblasRowMajor, CblasTrans, 3 * s->ncv, p, 1.0, s->cv ? s->Bc : s->map->B, p, s->gc, 1, 0.0, gf,
                    1);
        cblas_dgemv(CblasRowMajor, CblasTrans, p, r, 1.0, s->T, r, gf, 1, 1.0, g, 1);
        return 0;
    }
#pragma omp parallel num_threads(T) reduction(| : bad)
    {
        int tid = 0;
#ifdef _OPENMP
        tid = omp_get_thread_num();
#endif
        double *w = s->tw + (size_t)tid * TW(r), *J4 = w + WR(r), *xe = J4 + 3 * MV * (size_t)r;
        double *tg = g ? s->tg + (size_t)tid * r : NULL, *tH = H ? s->tH + (size_t)tid * rr : NULL, Et = 0;
        if (tg)
            memset(tg, 0, sizeof(double) * (size_t)r);
        if (tH)
            memset(tH, 0, sizeof(double) * rr);
#pragma omp for schedule(static)
        for (int j = 0; j < ne; j++) {
            int t = s->eidx[j];
            const int *e = s->eloc + MV * (size_t)j;
            int ke = elem_count(e);
            for (int a = 0; a < ke; a++) {
                memcpy(xe + 3 * a, s->xc + 3 * (size_t)e[a], 3 * sizeof(double));
                if (g || H)
                    memcpy(J4 + (size_t)a * 3 * r, s->Jc + (size_t)e[a] * 3 * r, 3 * (size_t)r * sizeof(double));
            }
            double Ee;
            if (!(g || H))
                Ee = crom_system_elem_energy(sys, t, xe);
            else if (!sys->shell && !sys->rigid) /* in F-space: G = ∂F/∂q, Gᵀ (∂P/∂F) G */
                Ee = crom_cubature_tet(crom_fem_tet_material(f, t), xe, J4, r, f->Dminv + 9 * (size_t)t, f->vol[t], s->ew[j], s->zero,
                                       project, tg, tH, w);
            else
                Ee = elem_reduced(sys, t, ke, xe, J4, r, s->ew[j], project, tg, tH, w);
            if (!isfinite(Ee))
                bad = 1;
            Et += s->ew[j] * Ee;
        }
        s->tE[tid] = Et;
    }
    if (bad)
        return crom_err(CROM_EDATA, "non-finite elastic energy");
    double Es = 0;
    for (int k = 0; k < T; k++) {
        Es += s->tE[k];
        if (g)
            for (int i = 0; i < r; i++)
                g[i] += s->tg[(size_t)k * r + i];
        if (H)
            for (size_t i = 0; i < rr; i++)
                H[i] += s->tH[(size_t)k * rr + i];
    }
    *E = Es;
    return 0;
}

/* out [r][r] (upper triangle and lower) = Tᵀ A T for symmetric A [p][p] */
static void sandwich(crom_nlsim *s, const double *A, double *out, double alpha, double beta)
{
    int p = s->p, r = s->r;
    cblas_dsymm(CblasRowMajor, CblasLeft, CblasUpper, p, r, 1.0, A, p, s->T, r, 0.0, s->AT, r);
    cblas_dgemm(CblasRowMajor, CblasTrans, CblasNoTrans, r, r, p, alpha, s->T, r, s->AT, r, beta, out, r);
}

/* The same for A = A0 of a map in a rigid frame, whose features are three
 * rotation blocks k of 3 pb (rows k of R times [x0_l, B'_l], map.c) and
 * the translation t: A0 = Σ_k (e_k e_kᵀ ⊗ G) plus g (G's coupling to t_k)
 * and the mass M on t_k, the same G, g and M for every k (the rows of
 * vertex component k carry block k and t_k only). Tᵀ A0 T = Σ_k (T_kᵀ G
 * T_k + T_kᵀ g τ_kᵀ + τ_k gᵀ T_k + M τ_k τ_kᵀ), T_k the rows of block k,
 * τ_k that of t_k: a third of the dense product's work. */
static void sandwich_frame(crom_nlsim *s, double *out, double alpha, double beta)
{
    int p = s->p, r = s->r, nb = 3 * s->frame_pb, t0 = 3 * nb;
    const double *G = s->A0, *g = s->A0 + t0, M = s->A0[(size_t)t0 * p + t0];
    for (size_t i = 0; i < (size_t)r * r; i++)
        out[i] = beta == 0 ? 0 : beta * out[i];
    for (int k = 0; k < 3; k++) {
        const double *Tk = s->T + (size_t)k * nb * r, *tau = s->T + (size_t)(t0 + k) * r;
        cblas_dsymm(CblasRowMajor, CblasLeft, CblasUpper, nb, r, 1.0, G, p, Tk, r, 0.0, s->AT, r);
        /* AT += g τᵀ (rows of G T_k plus the coupling to t_k), then out += α T_kᵀ AT */
        cblas_dger(CblasRowMajor, nb, r, 1.0, g, p, tau, 1, s->AT, r);
        cblas_dgemm(CblasRowMajor, CblasTrans, CblasNoTrans, r, r, nb, alpha, Tk, r, s->AT, r, 1.0, out, r);
        /* out += α τ (gᵀ T_k + M τᵀ) */
        double *w = s->AT + (size_t)nb * r;
        cblas_dgemv(CblasRowMajor, CblasTrans, nb, r, 1.0, Tk, r, g, p, 0.0, w, 1);
        cblas_daxpy(r, M, tau, 1, w, 1);
        cblas_dger(CblasRowMajor, r, r, alpha, tau, 1, w, 1, out, r);
    }
}

int crom_nlsim_objective(crom_nlsim *s, const double *q, double *Eout, double *g, double *H, int project)
{
    const crom_scenario *sc = s->sc;
    const crom_map *map = s->map;
    int r = s->r, p = s->p, rc;
    size_t rr = (size_t)r * r;
    double h = sc->dt;
    const double *m = s->sys.mass;
    if ((rc = crom_map_features(s->map, q, s->a, g || H ? s->T : NULL)))
        return rc;
    /* the quadratic: ½ δᵀAδ + bᵀδ + c; ga = Aδ + b, its gradient in a */
    double *delta = s->AT; /* scratch, free until the sandwich below */
    for (int i = 0; i < p; i++)
        delta[i] = s->a[i] - s->an[i];
    memcpy(s->ga, s->bq, sizeof(double) * (size_t)p);
    cblas_dsymv(CblasRowMajor, CblasUpper, p, 1.0, s->Aq, p, delta, 1, 1.0, s->ga, 1);
    double E = s->c0 + 0.5 * (cblas_ddot(p, delta, 1, s->ga, 1) + cblas_ddot(p, delta, 1, s->bq, 1));
    if (g)
        memset(g, 0, sizeof(double) * (size_t)r);
    if (H)
        memset(H, 0, sizeof(double) * rr);
    /* contact at the surface vertices (gradient into ga, Hessian into H) */
    for (int k = 0; sc->nplanes && k < s->nsurf; k++) {
        int v = s->surf[k], jv = 0;
        double xv[3], *Jv = s->Jt, *HJ = s->Jt + 3 * (size_t)r; /* scratch */
        crom_map_rows(map, &v, 1, s->a, NULL, xv, NULL);
        for (int pl = 0; pl < sc->nplanes; pl++) {
            double lam = s->lam[(size_t)pl * s->nsurf + k];
            if (crom_contact_depth(&sc->plane[pl], xv) <= 0 && !(lam > 0 && sc->plane[pl].mu > 0))
                continue;
            double gcv[3] = {0, 0, 0}, Hv[9] = {0};
            E += crom_contact_eval(&sc->plane[pl], sc->contact_stiffness, m[v], xv, s->xs + 3 * (size_t)k, lam,
                                   sc->friction_eps * h, g ? gcv : NULL, H ? Hv : NULL);
            rows_t(map, v, 1.0, gcv, s->ga);
            if (H) { /* H += J_vᵀ Hv J_v */
                if (!jv++)
                    crom_map_rows(map, &v, 1, s->a, s->T, NULL, Jv);
                cblas_dgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, 3, r, 3, 1.0, Hv, 3, Jv, r, 0.0, HJ, r);
                cblas_dgemm(CblasRowMajor, CblasTrans, CblasNoTrans, r, r, 3, 1.0, Jv, r, HJ, r, 1.0, H, r);
            }
        }
    }
    /* the rods (gradient into ga) */
    E += rods_eval(s, s->a, (double)(s->step + 1) * h, s->ga, H, project);
    /* elastic energy over the elastic tets */
    double Ee = 0;
    if ((rc = elastic(s, &Ee, g, H, project)))
        return rc;
    E += Ee;
    if (g) /* g += Tᵀ ga */
        cblas_dgemv(CblasRowMajor, CblasTrans, p, r, 1.0, s->T, r, s->ga, 1, 1.0, g, 1);
    if (H) { /* H += Tᵀ A T; Gm = Tᵀ A0 T / m (with no BC penalty A = cq A0: one product serves both) */
        if (s->frame_pb)
            sandwich_frame(s, s->Gm, 1 / s->sys.total_mass, 0.0);
        else
            sandwich(s, s->A0, s->Gm, 1 / s->sys.total_mass, 0.0);
        if (s->nbc) {
            sandwich(s, s->Aq, H, 1.0, 1.0);
        } else {
            double cq = (1 / (h * h) + sc->damping / h) * s->sys.total_mass;
            for (size_t i = 0; i < rr; i++)
                H[i] += cq * s->Gm[i];
        }
        for (int i = 0; i < r; i++) /* exactly symmetric */
            for (int j = 0; j < i; j++) {
                H[i * r + j] = H[j * r + i] = 0.5 * (H[i * r + j] + H[j * r + i]);
                s->Gm[i * r + j] = s->Gm[j * r + i] = 0.5 * (s->Gm[i * r + j] + s->Gm[j * r + i]);
            }
    }
    *Eout = E;
    return isfinite(E) ? 0 : crom_err(CROM_EDATA, "the reduced energy is not finite");
}

/* The map's curvature term of the Hessian of Φ at q, C_ab = Σ_k (∇_aΦ)_k
 * ∂²a_k/∂q_a∂q_b (x is linear in the features a), exactly, by
 * crom_map_curvature with ∇_aΦ held fixed.
 * Must follow crom_nlsim_objective at the same q with g or H requested
 * (its ∇_aΦ of the non-elastic terms and the elastic vertices' positions). */
int crom_nlsim_curvature(crom_nlsim *s, const double *q, double *C)
{
    int p = s->p, rc;
    /* ∇_aΦ = ga + Σ_e w_e B_eᵀ ∇_x E_e (the elastic gradient scattered to
     * the elastic vertices first) */
    double *gt = crom_malloc(sizeof(double) * (size_t)p), Ee;
    if (!gt)
        return CROM_EINTERNAL;
    if ((rc = elastic_xgrad(s, &Ee))) {
        free(gt);
        return rc;
    }
    memcpy(gt, s->ga, sizeof(double) * (size_t)p);
    cblas_dgemv(CblasRowMajor, CblasTrans, 3 * s->ncv, p, 1.0, s->cv ? s->Bc : s->map->B, p, s->gc, 1, 1.0, gt, 1);
    rc = crom_map_curvature(s->map, q, gt, C);
    free(gt);
    return rc;
}

/* RMS displacement ‖J d‖_M / sqrt(m) relative to the size (Gm of the last
 * objective with H) */
static double rms_disp(const crom_nlsim *s, const double *d)
{
    int r = s->r;
    double v = 0;
    for (int i = 0; i < r; i++)
        for (int j = 0; j < r; j++)
            v += d[i] * s->Gm[i * r + j] * d[j];
    return sqrt(fmax(v, 0)) / s->L;
}

/* The step's problem for the latent minimizer (lib/rom/newton.h): the
 * objective, the Gauss–Newton direction with the map's curvature term once
 * Gauss–Newton has had `newton_after` iterations, the size of a correction
 * as an RMS displacement relative to the body. ctx is a step_ctx: the
 * stepper and r x r scratch for the curvature C and the factorization. */
typedef struct {
    crom_nlsim *s;
    double *C, *Hs;
} step_ctx;

static int step_objective(void *ctx, const double *q, double *E, double *g, double *H, int project)
{
    return crom_nlsim_objective(((step_ctx *)ctx)->s, q, E, g, H, project);
}

/* Newton on the exact Hessian H + C (in c->C) where it is indefinite:
 * its eigenvalues taken by absolute value, at least 1e-12 dmax (Dauphin et
 * al. 2014's saddle-free Newton), d = −V |Λ|⁻¹ Vᵀ g, a descent direction
 * that keeps the curvature the Gauss–Newton matrix leaves out. Returns 0,
 * 1 when the eigen-solve fails, CROM_EINTERNAL. */
static int abs_newton(step_ctx *c, const double *H, const double *g, double dmax, double *d)
{
    int r = c->s->r;
    double *w = crom_malloc(sizeof(double) * 2 * (size_t)r), *vg = w ? w + r : NULL;
    if (!w)
        return CROM_EINTERNAL;
    for (size_t i = 0; i < (size_t)r * r; i++)
        c->Hs[i] = H[i] + c->C[i];
    int rc = LAPACKE_dsyev(LAPACK_ROW_MAJOR, 'V', 'U', r, c->Hs, r, w) != 0;
    for (int k = 0; !rc && k < r; k++) { /* column k of Hs is eigenvector k */
        vg[k] = 0;
        for (int i = 0; i < r; i++)
            vg[k] += c->Hs[i * r + k] * g[i];
        vg[k] /= fmax(fabs(w[k]), 1e-12 * dmax);
    }
    for (int i = 0; !rc && i < r; i++) {
        d[i] = 0;
        for (int k = 0; k < r; k++)
            d[i] -= c->Hs[i * r + k] * vg[k];
    }
    free(w);
    return rc;
}

/* Gauss–Newton; when it stalls (the map's curvature matters: large forces
 * along strongly curved or nearly degenerate latent directions), Newton
 * with the curvature term, on H + C where it is positive definite and
 * gives descent, else on |H + C| (abs_newton). */
static int step_direction(void *ctx, int it, int project, const double *q, const double *g, const double *H,
                          double *d)
{
    step_ctx *c = ctx;
    crom_nlsim *s = c->s;
    int r = s->r, newton_after = 2, rc;
    size_t rr = (size_t)r * r;
    if (s->lagged) { /* a linear basis: the factor of the last fresh matrix */
        if (H) {
            double dmax = 0;
            for (int i = 0; i < r; i++)
                dmax = fmax(dmax, fabs(H[i * r + i]));
            memcpy(s->Hfac, H, sizeof(double) * rr);
            for (int i = 0; i < r; i++)
                s->Hfac[i * r + i] += 1e-12 * dmax;
            s->fac_iters = 0;
            s->fac_slow = 0;
            if (!(s->fac_ok = LAPACKE_dpotrf_work(LAPACK_COL_MAJOR, 'L', r, s->Hfac, r) == 0))
                return 1;
        }
        if (!s->fac_ok)
            return 1;
        s->fac_iters++;
        for (int i = 0; i < r; i++)
            d[i] = -g[i];
        cblas_dtrsv(CblasRowMajor, CblasUpper, CblasTrans, CblasNonUnit, r, s->Hfac, r, d, 1);
        cblas_dtrsv(CblasRowMajor, CblasUpper, CblasNoTrans, CblasNonUnit, r, s->Hfac, r, d, 1);
        return 0;
    }
    int curv = it >= newton_after && s->map->nonlinear;
    if (curv && (rc = crom_nlsim_curvature(s, q, c->C)))
        return rc;
    for (int pass = curv ? 0 : 1; pass < 2; pass++) {
        for (int i = 0; i < r; i++)
            d[i] = -g[i];
        memcpy(c->Hs, H, sizeof(double) * rr);
        if (pass == 0)
            for (size_t i = 0; i < rr; i++)
                c->Hs[i] += c->C[i];
        double dmax = 0; /* a nearly collapsed latent direction moves nothing: keep H invertible */
        for (int i = 0; i < r; i++)
            dmax = fmax(dmax, fabs(H[i * r + i]));
        for (int i = 0; i < r; i++)
            c->Hs[i * r + i] += 1e-12 * dmax;
        if (LAPACKE_dposv(LAPACK_ROW_MAJOR, 'U', r, 1, c->Hs, r, d, 1) != 0) {
            if (pass == 0 && (rc = abs_newton(c, H, g, dmax, d)) == 0)
                return 0;
            if (rc > 1)
                return rc;
            continue;
        }
        double sl = 0;
        for (int i = 0; i < r; i++)
            sl += g[i] * d[i];
        if (pass == 1 || sl < 0)
            return 0;
    }
    return 1;
}

static double step_size(void *ctx, const double *d) { return rms_disp(((step_ctx *)ctx)->s, d); }

static int step_wants_hessian(void *ctx, int it)
{
    crom_nlsim *s = ((step_ctx *)ctx)->s;
    return !s->fac_ok || (it == 0 && s->fac_slow) || s->fac_iters >= LAG_ITERS;
}

static void step_stale(void *ctx) { ((step_ctx *)ctx)->s->fac_ok = 0; }

int crom_nlsim_step(crom_nlsim *s, crom_rsim_stats *st)
{
    const crom_scenario *sc = s->sc;
    int r = s->r;
    size_t rr = (size_t)r * r;
    double h = sc->dt, t0 = crom_clock_now();
    memset(st, 0, sizeof *st);
    crom_nlsim_begin_step(s);
    /* start at the latent predictor q_n + h q̇_n, or at q_n where the map
     * curves so much that the predictor is worse (a straight line in q is
     * no straight line in x) */
    double Ep = 0, En = 0;
    int rc0 = crom_nlsim_objective(s, s->qn, &En, NULL, NULL, 0);
    for (int i = 0; i < r; i++)
        s->q[i] = s->qn[i] + h * s->qd[i];
    if (!rc0 && s->map->nonlinear && (crom_nlsim_objective(s, s->q, &Ep, NULL, NULL, 0) || !(Ep <= En))) {
        crom_err_clear();
        memcpy(s->q, s->qn, sizeof(double) * (size_t)r);
    }
    step_ctx c = {s, crom_malloc(sizeof(double) * rr), crom_malloc(sizeof(double) * rr)};
    if (!c.C || !c.Hs) {
        free(c.C);
        free(c.Hs);
        return CROM_EINTERNAL;
    }
    int rc = 0, lagged = s->lagged;
    double *q0 = crom_malloc(sizeof(double) * (size_t)r);
    if (!q0) {
        free(c.C);
        free(c.Hs);
        return CROM_EINTERNAL;
    }
    memcpy(q0, s->q, sizeof(double) * (size_t)r);
    for (int lag = lagged; lag >= 0; lag--) {
        if (lag < lagged) { /* the reused matrix did not converge: again, fresh at every iteration */
            crom_err_clear();
            memcpy(s->q, q0, sizeof(double) * (size_t)r);
            s->fac_ok = 0;
            crom_newton_memory_reset(&s->mem);
        }
        s->fac_iters = 0; /* a reused factor gets LAG_ITERS iterations in each step */
        const crom_newton_problem prob = {r, step_objective, step_direction, step_size,
                                          lag ? step_wants_hessian : NULL, lag ? step_stale : NULL, 0,
                                          "Gauss-Newton",
                                          "the Gauss-Newton matrix is singular (the map's latent directions are "
                                          "degenerate here)", lag};
        const crom_newton_work w = {s->g, s->H, s->d, s->qt, lag ? &s->mem : NULL};
        s->lagged = lag; /* step_direction reads it */
        rc = crom_newton_solve(&prob, &c, &w, s->q, sc->tol, sc->max_iter, s->step, &st->iterations,
                               &st->residual, &st->converged);
        s->fac_slow = s->fac_iters > SLOW_ITERS;
        if (rc != CROM_EDATA || !lag)
            break;
    }
    s->lagged = lagged;
    free(q0);
    free(c.C);
    free(c.Hs);
    if (!rc)
        rc = crom_map_features(s->map, s->q, s->a, NULL);
    if (rc)
        return rc;
    for (int i = 0; i < s->p; i++) {
        s->va[i] = (s->a[i] - s->an[i]) / h;
        s->an[i] = s->a[i];
    }
    for (int i = 0; i < r; i++)
        s->qd[i] = (s->q[i] - s->qn[i]) / h;
    s->step++;
    s->t = (double)s->step * h; /* exact multiples of dt (issue 12) */
    st->vertex_evals = s->ncv + sc->nplanes * s->nsurf;
    st->seconds = crom_clock_now() - t0;
    return 0;
}

double crom_nlsim_constraint_residual(const crom_nlsim *s)
{
    const double *X = s->map->x0;
    double worst = 0;
    for (int k = 0; k < s->nbc; k++) {
        double u[3] = {0, 0, 0};
        if (s->bc[k].bc)
            crom_bc_displacement(s->bc[k].bc, s->t, u);
        for (int j = 0; j < s->bc[k].n; j++) {
            int v = s->bc[k].idx[j];
            double e2 = 0, xv[3];
            crom_map_rows(s->map, &v, 1, s->an, NULL, xv, NULL);
            for (int c = 0; c < 3; c++) {
                double e = xv[c] - X[3 * v + c] - u[c];
                e2 += e * e;
            }
            worst = fmax(worst, sqrt(e2));
        }
    }
    return worst;
}

void crom_nlsim_positions(const crom_nlsim *s, double *x, double *v)
{
    const crom_map *map = s->map;
    if (x) {
        memcpy(x, map->x0, sizeof(double) * (size_t)s->n);
        cblas_dgemv(CblasRowMajor, CblasNoTrans, s->n, s->p, 1.0, map->B, s->p, s->an, 1, 1.0, x, 1);
    }
    if (v)
        cblas_dgemv(CblasRowMajor, CblasNoTrans, s->n, s->p, 1.0, map->B, s->p, s->va, 1, 0.0, v, 1);
}

/* The loads' work on the displacement at q = 0, f·(x0 − X): zero but for
 * a seeded map (map.h), whose potential is then taken from the rest shape
 * like crom-fullsim's. */
static double seed_work(const crom_nlsim *s, double t)
{
    const crom_map *map = s->map;
    const double *g = s->sc->gravity, *m = s->sys.mass;
    double w = 0;
    for (int i = 0; i < s->n; i++)
        w += m[i / 3] * g[i % 3] * (map->x0[i] - map->mesh.X[i]);
    for (int b = 0; b < s->nforce; b++) {
        const crom_nlsim_bc *fb = &s->force[b];
        double F[3];
        crom_bc_force(fb->bc, t, F);
        for (int k = 0; k < fb->n; k++)
            for (int c = 0, v = fb->idx[k]; c < 3; c++)
                w += m[v] / fb->mass * F[c] * (map->x0[3 * (size_t)v + c] - map->mesh.X[3 * (size_t)v + c]);
    }
    return w;
}

int crom_nlsim_energies(crom_nlsim *s, double *kinetic, double *elastic_e, double *external)
{
    int p = s->p;
    /* K = ½ vaᵀ BᵀMB va; W = −f·(x − X) = −(Bᵀf)·a − f·(x0 − X) */
    cblas_dsymv(CblasRowMajor, CblasUpper, p, 1.0, s->A0, p, s->va, 1, 0.0, s->fa, 1);
    double K = 0.5 * cblas_ddot(p, s->va, 1, s->fa, 1);
    feature_loads(s, s->t, s->fa);
    double W = -cblas_ddot(p, s->fa, 1, s->an, 1) - seed_work(s, s->t);
    /* the elastic energy as the steps see it: over the elastic tets */
    memcpy(s->a, s->an, sizeof(double) * (size_t)p);
    double Ee = 0;
    int rc = elastic(s, &Ee, NULL, NULL, 0);
    if (rc)
        return rc;
    *elastic_e = Ee;
    *kinetic = K;
    *external = W + rods_eval(s, s->an, s->t, NULL, NULL, 0);
    return 0;
}
