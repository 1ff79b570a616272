/* nlrom.c — implicit Euler over the latent of a one-mesh map, Gauss–Newton
 * on the full-space incremental potential (see nlrom.h). */
#ifdef _OPENMP
#include <omp.h>
#endif
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <cblas.h>
#include <lapacke.h>

#include "cli.h"
#include "contact.h"
#include "cubature.h"
#include "err.h"
#include "linesearch.h"
#include "nlrom.h"

#define TW(r) (168 + 24 * (size_t)(r) + 12) /* per-thread tet scratch: crom_cub_tet's, J4, xe */

static void free_bcs(crom_nlbc *b, int n)
{
    for (int i = 0; b && i < n; i++)
        free(b[i].idx);
    free(b);
}

void crom_nlsim_free(crom_nlsim *s)
{
    if (!s)
        return;
    crom_fem_free(&s->fem);
    double **bufs[] = {&s->q, &s->qd, &s->x, &s->v, &s->qn, &s->xn, &s->xhat, &s->xt, &s->fext, &s->gx,
                       &s->J, &s->Jt, &s->g, &s->H, &s->Hc, &s->d, &s->qt, &s->Gm, &s->lam, &s->zero,
                       &s->tw, &s->tH, &s->tg, &s->tE, &s->wd};
    for (size_t i = 0; i < sizeof bufs / sizeof *bufs; i++)
        free(*bufs[i]);
    free(s->surf);
    free_bcs(s->bc, s->nbc);
    free_bcs(s->force, s->nforce);
    memset(s, 0, sizeof *s);
}

static int region(crom_nlsim *s, const char *ref, const crom_bc *bc, crom_nlbc *b)
{
    int rc = crom_mesh_select(&s->map->mesh, ref, &b->idx, &b->n);
    if (rc)
        return rc;
    b->bc = bc;
    for (int k = 0; k < b->n; k++)
        b->mass += s->fem.mass[b->idx[k]];
    return 0;
}

/* external load at time t: gravity plus region forces spread by mass */
static void loads(const crom_nlsim *s, double t, double *f)
{
    const double *g = s->sc->gravity;
    for (int i = 0; i < s->n; i++)
        f[i] = s->fem.mass[i / 3] * g[i % 3];
    for (int b = 0; b < s->nforce; b++) {
        const crom_nlbc *fb = &s->force[b];
        double F[3];
        crom_bc_force(fb->bc, t, F);
        for (int k = 0; k < fb->n; k++) {
            int v = fb->idx[k];
            for (int c = 0; c < 3; c++)
                f[3 * v + c] += F[c] * s->fem.mass[v] / fb->mass;
        }
    }
}

/* q̇ minimizing ‖J q̇ − v‖_M, v = v0 + ω × (X − c) */
/* H = Jᵀ M J (upper triangle) of the Jacobian in s->J: the mass-weighted
 * Gram matrix of the latent directions */
static void mass_gram(crom_nlsim *s)
{
    int r = s->r, n = s->n;
    for (int i = 0; i < n; i++) {
        double sq = sqrt(s->fem.mass[i / 3]);
        for (int k = 0; k < r; k++)
            s->Jt[(size_t)i * r + k] = sq * s->J[(size_t)i * r + k];
    }
    cblas_dsyrk(CblasRowMajor, CblasUpper, CblasTrans, r, n, 1.0, s->Jt, r, 0.0, s->H, r);
}

static int initial_velocity(crom_nlsim *s)
{
    const crom_scenario *sc = s->sc;
    int r = s->r, n = s->n;
    if (!(sc->v0[0] || sc->v0[1] || sc->v0[2] || sc->spin[0] || sc->spin[1] || sc->spin[2]))
        return 0;
    double c[3] = {0, 0, 0}, m = 0;
    const double *X = s->map->mesh.X;
    for (int v = 0; v < s->map->nv; v++) {
        m += s->fem.mass[v];
        for (int k = 0; k < 3; k++)
            c[k] += s->fem.mass[v] * X[3 * v + k];
    }
    for (int k = 0; k < 3; k++)
        c[k] /= m;
    for (int v = 0; v < s->map->nv; v++) {
        double vv[3];
        crom_scenario_initial_velocity(sc, c, X + 3 * v, vv);
        for (int k = 0; k < 3; k++)
            s->gx[3 * v + k] = s->fem.mass[v] * vv[k];
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

/* The fit of x(q) to the rest shape, ½‖x(q) − X‖²_M, and its gradient
 * Jᵀ M (x(q) − X) (J left in s->J), for the line search. */
static int rest_eval(void *ctx, const double *q, double *f, double *g)
{
    crom_nlsim *s = ctx;
    int rc = crom_map_eval(s->map, q, s->xt, g ? s->J : NULL);
    if (rc)
        return rc;
    const double *X = s->map->mesh.X;
    double e = 0;
    for (int i = 0; i < s->n; i++) {
        double d = s->xt[i] - X[i];
        s->gx[i] = s->fem.mass[i / 3] * d;
        e += 0.5 * d * s->gx[i];
    }
    *f = e;
    if (g)
        cblas_dgemv(CblasRowMajor, CblasTrans, s->n, s->r, 1.0, s->J, s->r, s->gx, 1, 0.0, g, 1);
    return 0;
}

/* Start at rest: the latent whose shape is nearest the rest shape in the
 * mass norm, q = argmin ½‖x(q) − X‖²_M, by Gauss–Newton from q = 0. A
 * data-free map's origin need not be the rest state (Sharp et al. §4.1:
 * the seed state is gone once training ends); for linear bases and maps
 * with x(0) = X this leaves q = 0. */
static int nearest_rest(crom_nlsim *s)
{
    int r = s->r, n = s->n;
    for (int it = 0; it < 100; it++) {
        double f;
        int rc = rest_eval(s, s->q, &f, s->g);
        if (rc)
            return rc;
        mass_gram(s);
        for (int k = 0; k < r; k++)
            s->d[k] = -s->g[k];
        if (LAPACKE_dposv(LAPACK_ROW_MAJOR, 'U', r, 1, s->H, r, s->d, 1) != 0)
            return crom_err(CROM_EDATA, "the map's latent directions are degenerate near the rest shape");
        double slope = cblas_ddot(r, s->g, 1, s->d, 1);
        if (!(slope < 0))
            break; /* at the minimum (x(0) = X exactly for a linear basis) */
        /* converged when the step moves no vertex by more than 1e-10 L */
        cblas_dgemv(CblasRowMajor, CblasNoTrans, n, r, 1.0, s->J, r, s->d, 1, 0.0, s->wd, 1);
        double move = 0;
        for (int i = 0; i < n; i++)
            move = fmax(move, fabs(s->wd[i]));
        if (move <= 1e-10 * s->L) {
            cblas_daxpy(r, 1.0, s->d, 1, s->q, 1);
            break;
        }
        double alpha = crom_linesearch(rest_eval, s, (size_t)r, s->q, s->d, f, slope, 64 * DBL_EPSILON * f,
                                       -slope < 1e-10 * f, s->qt, s->tg, NULL);
        if (alpha == 0)
            break; /* no decrease left that f resolves */
        memcpy(s->q, s->qt, sizeof(double) * (size_t)r);
    }
    return 0;
}

int crom_nlsim_init(crom_nlsim *s, crom_map *map, const crom_scenario *sc, double kappa, const double *q0,
                    const double *qd0, int nthreads)
{
    memset(s, 0, sizeof *s);
    int rc = crom_scenario_check(sc);
    if (rc)
        return rc;
    crom_material mat;
    if ((rc = crom_material_init(&mat, sc->youngs, sc->poisson, sc->density)))
        return rc;
    s->sc = sc;
    s->map = map;
    s->r = map->r;
    s->n = map->n;
    s->nthreads = nthreads < 1 ? 1 : nthreads > 256 ? 256 : nthreads;
    s->kappa = kappa > 0 ? kappa : 1e4 / (sc->dt * sc->dt);
    if ((rc = crom_fem_init(&s->fem, &map->mesh, &mat)))
        return rc;
    int r = s->r, n = s->n, T = s->nthreads;
    size_t rr = (size_t)r * r, nr = (size_t)n * r;
    double **vr[] = {&s->q, &s->qd, &s->qn, &s->g, &s->d, &s->qt, &s->zero};
    double **vn[] = {&s->x, &s->v, &s->xn, &s->xhat, &s->xt, &s->fext, &s->gx, &s->wd};
    double **vrr[] = {&s->H, &s->Hc, &s->Gm};
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
    s->bc = crom_calloc((size_t)(sc->npins + sc->nvel + 1), sizeof(crom_nlbc));
    s->force = crom_calloc((size_t)(sc->nforce + 1), sizeof(crom_nlbc));
    int ok = s->J && s->Jt && s->tw && s->tH && s->tg && s->tE && s->bc && s->force;
    for (size_t i = 0; i < sizeof vr / sizeof *vr; i++)
        ok = ok && *vr[i];
    for (size_t i = 0; i < sizeof vn / sizeof *vn; i++)
        ok = ok && *vn[i];
    for (size_t i = 0; i < sizeof vrr / sizeof *vrr; i++)
        ok = ok && *vrr[i];
    if (!ok) {
        crom_nlsim_free(s);
        return CROM_EINTERNAL;
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
    if (sc->nplanes) { /* contact points: the boundary vertices */
        int ntri, *tris = NULL;
        unsigned char *on = crom_calloc((size_t)map->nv, 1);
        if (!on || (rc = crom_mesh_boundary(&map->mesh, &ntri, &tris, NULL))) {
            free(on);
            crom_nlsim_free(s);
            return rc ? rc : CROM_EINTERNAL;
        }
        for (int i = 0; i < 3 * ntri; i++)
            on[tris[i]] = 1;
        free(tris);
        s->surf = crom_malloc(sizeof(int) * (size_t)map->nv);
        s->lam = crom_calloc((size_t)sc->nplanes * map->nv, sizeof(double));
        if (!s->surf || !s->lam) {
            free(on);
            crom_nlsim_free(s);
            return CROM_EINTERNAL;
        }
        for (int v = 0; v < map->nv; v++)
            if (on[v])
                s->surf[s->nsurf++] = v;
        free(on);
    }
    /* initial state */
    if (q0)
        memcpy(s->q, q0, sizeof(double) * (size_t)r);
    else if ((rc = nearest_rest(s)))
        goto fail;
    if ((rc = crom_map_eval(map, s->q, s->x, s->J)))
        goto fail;
    if (qd0)
        memcpy(s->qd, qd0, sizeof(double) * (size_t)r);
    else if ((rc = initial_velocity(s)))
        goto fail;
    if ((rc = crom_map_eval(map, s->q, NULL, s->J)))
        goto fail;
    cblas_dgemv(CblasRowMajor, CblasNoTrans, n, r, 1.0, s->J, r, s->qd, 1, 0.0, s->v, 1);
    return 0;
fail:
    crom_nlsim_free(s);
    return rc;
}

void crom_nlsim_begin_step(crom_nlsim *s)
{
    const crom_scenario *sc = s->sc;
    int n = s->n;
    double h = sc->dt;
    memcpy(s->qn, s->q, sizeof(double) * (size_t)s->r);
    memcpy(s->xn, s->x, sizeof(double) * (size_t)n);
    for (int i = 0; i < n; i++)
        s->xhat[i] = s->x[i] + h * s->v[i];
    loads(s, s->t + h, s->fext);
    for (int p = 0; p < sc->nplanes; p++)
        for (int k = 0; k < s->nsurf; k++) {
            int v = s->surf[k];
            s->lam[(size_t)p * s->nsurf + k] =
                sc->contact_stiffness * s->fem.mass[v] * crom_contact_depth(&sc->plane[p], s->xn + 3 * (size_t)v);
        }
}

/* Elastic energy, and (g, H non-NULL) its reduced gradient and Hessian
 * Σ_e J_eᵀ H_e J_e, over every tet, split over the threads. */
static int elastic(crom_nlsim *s, const double *x, double *E, double *g, double *H, int project)
{
    int r = s->r, nt = s->fem.nt, T = s->nthreads, bad = 0;
    size_t rr = (size_t)r * r;
    const crom_fem *f = &s->fem;
#pragma omp parallel num_threads(T) reduction(| : bad)
    {
        int tid = 0;
#ifdef _OPENMP
        tid = omp_get_thread_num();
#endif
        double *w = s->tw + (size_t)tid * TW(r), *J4 = w + 168 + 12 * (size_t)r, *xe = J4 + 12 * (size_t)r;
        double *tg = g ? s->tg + (size_t)tid * r : NULL, *tH = H ? s->tH + (size_t)tid * rr : NULL, Et = 0;
        if (tg)
            memset(tg, 0, sizeof(double) * (size_t)r);
        if (tH)
            memset(tH, 0, sizeof(double) * rr);
#pragma omp for schedule(static)
        for (int t = 0; t < nt; t++) {
            const int *e = f->tets + 4 * (size_t)t;
            for (int a = 0; a < 4; a++) {
                memcpy(xe + 3 * a, x + 3 * (size_t)e[a], 3 * sizeof(double));
                memcpy(J4 + (size_t)a * 3 * r, s->J + (size_t)e[a] * 3 * r, 3 * (size_t)r * sizeof(double));
            }
            double Ee = crom_cub_tet(&f->mat, xe, J4, r, f->Dminv + 9 * (size_t)t, f->vol[t], 1.0, s->zero,
                                     project, tg, tH, w);
            if (!isfinite(Ee))
                bad = 1;
            Et += Ee;
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

int crom_nlsim_objective(crom_nlsim *s, const double *q, double *Eout, double *g, double *H, int project)
{
    const crom_scenario *sc = s->sc;
    int r = s->r, n = s->n, rc;
    size_t rr = (size_t)r * r;
    double h = sc->dt, cin = 1 / (h * h), cd = sc->damping / h, t1 = s->t + h;
    const double *X = s->map->mesh.X, *m = s->fem.mass;
    double *x = s->xt, *gx = s->gx;
    if ((rc = crom_map_eval(s->map, q, x, g || H ? s->J : NULL)))
        return rc;
    double E = 0;
    /* inertia, damping, external work; wd: the diagonal of the quadratic terms */
    for (int i = 0; i < n; i++) {
        double mi = m[i / 3], a = x[i] - s->xhat[i], b = x[i] - s->xn[i];
        E += 0.5 * mi * (cin * a * a + cd * b * b) - s->fext[i] * b;
        gx[i] = mi * (cin * a + cd * b) - s->fext[i];
    }
    double *wd = H ? s->wd : NULL;
    if (wd)
        for (int i = 0; i < n; i++)
            wd[i] = m[i / 3] * (cin + cd);
    /* boundary-condition penalty */
    for (int k = 0; k < s->nbc; k++) {
        const crom_nlbc *b = &s->bc[k];
        double u[3] = {0, 0, 0};
        if (b->bc)
            crom_bc_displacement(b->bc, t1, u);
        for (int j = 0; j < b->n; j++) {
            int v = b->idx[j];
            for (int c = 0; c < 3; c++) {
                double dv = x[3 * v + c] - X[3 * v + c] - u[c];
                E += 0.5 * s->kappa * m[v] * dv * dv;
                gx[3 * v + c] += s->kappa * m[v] * dv;
                if (wd)
                    wd[3 * v + c] += s->kappa * m[v];
            }
        }
    }
    if (g)
        memset(g, 0, sizeof(double) * (size_t)r);
    if (H)
        memset(H, 0, sizeof(double) * rr);
    /* contact at the surface vertices (gradient into gx, Hessian into H) */
    for (int p = 0; p < sc->nplanes; p++)
        for (int k = 0; k < s->nsurf; k++) {
            int v = s->surf[k];
            double lam = s->lam[(size_t)p * s->nsurf + k];
            if (crom_contact_depth(&sc->plane[p], x + 3 * (size_t)v) <= 0 && !(lam > 0 && sc->plane[p].mu > 0))
                continue;
            double gc[3] = {0, 0, 0}, Hv[9] = {0};
            E += crom_contact_eval(&sc->plane[p], sc->contact_stiffness, m[v], x + 3 * (size_t)v, s->xn + 3 * (size_t)v,
                                   lam, sc->friction_eps * h, g ? gc : NULL, H ? Hv : NULL);
            for (int c = 0; c < 3; c++)
                gx[3 * v + c] += gc[c];
            if (H) { /* H += J_vᵀ Hv J_v */
                const double *Jv = s->J + (size_t)v * 3 * r;
                for (int a = 0; a < r; a++)
                    for (int c = 0; c < 3; c++) {
                        double hj = 0;
                        for (int e = 0; e < 3; e++)
                            hj += Hv[3 * c + e] * Jv[e * r + a];
                        if (hj != 0)
                            for (int b2 = 0; b2 < r; b2++)
                                H[b2 * r + a] += Jv[c * r + b2] * hj;
                    }
            }
        }
    /* elastic energy over every tet */
    double Ee;
    if (g || H) {
        if ((rc = elastic(s, x, &Ee, g, H, project)))
            return rc;
    } else {
        crom_fem_opts fo = {0, 0, NULL, s->nthreads};
        if ((rc = crom_fem_assemble(&s->fem, x, &fo, &Ee, NULL, NULL)))
            return rc;
    }
    E += Ee;
    if (g) /* g += Jᵀ gx */
        cblas_dgemv(CblasRowMajor, CblasTrans, n, r, 1.0, s->J, r, gx, 1, 1.0, g, 1);
    if (H) { /* H += Jᵀ diag(wd) J; Gm = Jᵀ M J / m */
        for (int i = 0; i < n; i++) {
            double sq = sqrt(wd[i]);
            for (int k = 0; k < r; k++)
                s->Jt[(size_t)i * r + k] = sq * s->J[(size_t)i * r + k];
        }
        cblas_dsyrk(CblasRowMajor, CblasUpper, CblasTrans, r, n, 1.0, s->Jt, r, 0.0, s->Hc, r);
        for (int a = 0; a < r; a++)
            for (int b = a; b < r; b++) {
                H[a * r + b] += s->Hc[a * r + b];
                if (b != a)
                    H[b * r + a] += s->Hc[a * r + b];
            }
        for (int i = 0; i < n; i++) {
            double sq = sqrt(m[i / 3] / s->fem.total_mass);
            for (int k = 0; k < r; k++)
                s->Jt[(size_t)i * r + k] = sq * s->J[(size_t)i * r + k];
        }
        cblas_dsyrk(CblasRowMajor, CblasUpper, CblasTrans, r, n, 1.0, s->Jt, r, 0.0, s->Gm, r);
        for (int a = 0; a < r; a++)
            for (int b = 0; b < a; b++)
                s->Gm[a * r + b] = s->Gm[b * r + a];
    }
    *Eout = E;
    return isfinite(E) ? 0 : crom_err(CROM_EDATA, "the reduced energy is not finite");
}

/* The map's curvature term of the Hessian of Φ at q, C_ab = Σ_i (∇_xΦ)_i
 * ∂²x_i/∂q_a∂q_b, by central differences of J(q)ᵀ∇_xΦ with ∇_xΦ held fixed
 * (2r evaluations of the map's Jacobian; step 1e-5 (1 + |q|_∞), so C is
 * good to about 1e-10 relative). Must follow crom_nlsim_objective at the
 * same q (its positions and non-elastic gradient). */
int crom_nlsim_curvature(crom_nlsim *s, const double *q, double *C)
{
    int r = s->r, n = s->n, rc;
    crom_fem_opts fo = {0, 0, NULL, s->nthreads};
    double *ge = s->wd, *qp = s->qt; /* scratch: wd and qt are free here */
    if ((rc = crom_fem_assemble(&s->fem, s->xt, &fo, NULL, ge, NULL)))
        return rc;
    for (int i = 0; i < n; i++)
        ge[i] += s->gx[i];
    double qmax = 0;
    for (int a = 0; a < r; a++)
        qmax = fmax(qmax, fabs(q[a]));
    double eps = 1e-5 * (1 + qmax);
    for (int b = 0; b < r; b++) {
        memcpy(qp, q, sizeof(double) * (size_t)r);
        qp[b] = q[b] + eps;
        if ((rc = crom_map_eval(s->map, qp, NULL, s->J)))
            return rc;
        cblas_dgemv(CblasRowMajor, CblasTrans, n, r, 1.0 / (2 * eps), s->J, r, ge, 1, 0.0, C + (size_t)b * r, 1);
        qp[b] = q[b] - eps;
        if ((rc = crom_map_eval(s->map, qp, NULL, s->J)))
            return rc;
        cblas_dgemv(CblasRowMajor, CblasTrans, n, r, -1.0 / (2 * eps), s->J, r, ge, 1, 1.0, C + (size_t)b * r, 1);
    }
    for (int a = 0; a < r; a++) /* symmetric (second derivatives) */
        for (int b = 0; b < a; b++)
            C[a * r + b] = C[b * r + a] = 0.5 * (C[a * r + b] + C[b * r + a]);
    return crom_map_eval(s->map, q, NULL, s->J); /* J at q again */
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

/* the step's objective and its gradient for the line search */
typedef struct {
    crom_nlsim *s;
    int project;
} obj_ctx;
static int obj_eval(void *ctx, const double *q, double *f, double *g)
{
    obj_ctx *c = ctx;
    return crom_nlsim_objective(c->s, q, f, g, NULL, c->project);
}

int crom_nlsim_step(crom_nlsim *s, crom_rstep_stats *st)
{
    const crom_scenario *sc = s->sc;
    int r = s->r, rc = 0, project = 0;
    size_t rr = (size_t)r * r;
    double h = sc->dt, t0 = crom_now();
    memset(st, 0, sizeof *st);
    st->residual = INFINITY;
    crom_nlsim_begin_step(s);
    for (int i = 0; i < r; i++)
        s->q[i] = s->qn[i] + h * s->qd[i];
    double *Hs = crom_malloc(sizeof(double) * rr), *gt = crom_malloc(sizeof(double) * (size_t)r);
    double *C = crom_malloc(sizeof(double) * rr);
    if (!Hs || !gt || !C) {
        free(Hs);
        free(gt);
        free(C);
        return CROM_EINTERNAL;
    }
    /* Gauss–Newton; when it stalls (the map's curvature matters: large
     * forces along strongly curved or nearly degenerate latent directions),
     * Newton with the curvature term, whenever that matrix is positive
     * definite and gives descent */
    int newton_after = 2;
    for (int it = 0; it < sc->max_iter && !rc;) {
        double E;
        if ((rc = crom_nlsim_objective(s, s->q, &E, s->g, s->H, project)))
            break;
        int curv = it >= newton_after && s->map->nonlinear, solved = 0;
        if (curv && (rc = crom_nlsim_curvature(s, s->q, C)))
            break;
        for (int pass = curv ? 0 : 1; pass < 2 && !solved; pass++) {
            for (int i = 0; i < r; i++)
                s->d[i] = -s->g[i];
            memcpy(Hs, s->H, sizeof(double) * rr);
            if (pass == 0)
                for (size_t i = 0; i < rr; i++)
                    Hs[i] += C[i];
            double dmax = 0; /* a nearly collapsed latent direction moves nothing: keep H invertible */
            for (int i = 0; i < r; i++)
                dmax = fmax(dmax, fabs(s->H[i * r + i]));
            for (int i = 0; i < r; i++)
                Hs[i * r + i] += 1e-12 * dmax;
            if (LAPACKE_dposv(LAPACK_ROW_MAJOR, 'U', r, 1, Hs, r, s->d, 1) != 0)
                continue;
            double sl = 0;
            for (int i = 0; i < r; i++)
                sl += s->g[i] * s->d[i];
            solved = pass == 1 || sl < 0;
        }
        if (!solved) {
            if (!project) {
                project = 1; /* indefinite: project element Hessians from now on */
                continue;
            }
            rc = crom_err(CROM_EDATA, "step %ld: the Gauss-Newton matrix is singular (the map's latent "
                          "directions are degenerate here)", s->step + 1);
            break;
        }
        double slope = 0;
        for (int i = 0; i < r; i++)
            slope += s->g[i] * s->d[i];
        if (!(slope < 0)) {
            if (!project) {
                project = 1;
                continue;
            }
            st->residual = rms_disp(s, s->d);
            st->converged = 1;
            break;
        }
        it++;
        st->iterations = it;
        st->residual = rms_disp(s, s->d);
        if (st->residual <= sc->tol) {
            for (int i = 0; i < r; i++)
                s->q[i] += s->d[i];
            st->converged = 1;
            break;
        }
        /* Armijo line search; below the energy's resolution the directional
         * derivative decides */
        double scale = fabs(E) + 1e-300;
        obj_ctx lc = {s, project};
        double alpha = crom_linesearch(obj_eval, &lc, (size_t)r, s->q, s->d, E, slope, 64 * DBL_EPSILON * scale,
                                       -slope < 1e-10 * scale, s->qt, gt, NULL);
        if (alpha == 0) {
            if (!project) {
                project = 1;
                continue;
            }
            st->converged = 1; /* no decrease possible: as converged as it gets */
            break;
        }
        memcpy(s->q, s->qt, sizeof(double) * (size_t)r);
    }
    free(Hs);
    free(gt);
    free(C);
    if (!rc && !st->converged)
        rc = crom_err(CROM_EDATA,
                      "step %ld did not converge: correction %.3g > --tol %.3g after %d Gauss-Newton iterations "
                      "(try a smaller --dt or a larger --max-iter)",
                      s->step + 1, st->residual, sc->tol, sc->max_iter);
    if (!rc)
        rc = crom_map_eval(s->map, s->q, s->x, NULL);
    if (rc)
        return rc;
    for (int i = 0; i < s->n; i++)
        s->v[i] = (s->x[i] - s->xn[i]) / h;
    for (int i = 0; i < r; i++)
        s->qd[i] = (s->q[i] - s->qn[i]) / h;
    s->t += h;
    s->step++;
    st->constraint_residual = crom_nlsim_constraint_residual(s);
    st->seconds = crom_now() - t0;
    return 0;
}

double crom_nlsim_constraint_residual(const crom_nlsim *s)
{
    const double *X = s->map->mesh.X;
    double worst = 0;
    for (int k = 0; k < s->nbc; k++) {
        double u[3] = {0, 0, 0};
        if (s->bc[k].bc)
            crom_bc_displacement(s->bc[k].bc, s->t, u);
        for (int j = 0; j < s->bc[k].n; j++) {
            int v = s->bc[k].idx[j];
            double e2 = 0;
            for (int c = 0; c < 3; c++) {
                double e = s->x[3 * v + c] - X[3 * v + c] - u[c];
                e2 += e * e;
            }
            worst = fmax(worst, sqrt(e2));
        }
    }
    return worst;
}

int crom_nlsim_energies(crom_nlsim *s, double *kinetic, double *elastic_e, double *external)
{
    const double *X = s->map->mesh.X;
    double K = 0, W = 0, *f = s->gx; /* scratch: fext belongs to the step */
    loads(s, s->t, f);
    for (int i = 0; i < s->n; i++) {
        K += 0.5 * s->fem.mass[i / 3] * s->v[i] * s->v[i];
        W -= f[i] * (s->x[i] - X[i]);
    }
    crom_fem_opts fo = {0, 0, NULL, s->nthreads};
    int rc = crom_fem_assemble(&s->fem, s->x, &fo, elastic_e, NULL, NULL);
    if (rc)
        return rc;
    *kinetic = K;
    *external = W;
    return 0;
}
