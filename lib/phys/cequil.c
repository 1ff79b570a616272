/* cequil.c — constrained equilibria at given modal coordinates (see cequil.h). */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <cblas.h>
#include <lapacke.h>

#include "base/err.h"
#include "base/linesearch.h"
#include "mesh/mesh.h"
#include "phys/cequil.h"
#include "phys/modes.h"

void crom_cequil_defaults(crom_cequil_opts *o)
{
    o->max_iter = 200;
    o->tol = 1e-8;
    o->mu = 0;
}

void crom_cequil_free(crom_cequil *c)
{
    if (!c)
        return;
    crom_chol_free(c->chol);
    free(c->B);
    free(c->V);
    free(c->H);
    free(c->g);
    free(c->d);
    free(c->a);
    free(c->Y);
    free(c->S);
    free(c->xt);
    free(c->work);
    free(c->lam);
    memset(c, 0, sizeof *c);
}

int crom_cequil_init(crom_cequil *c, const crom_system *sys, const crom_mesh *mesh, const unsigned char *fixed,
                     int r, const double *W, const crom_cequil_opts *o)
{
    memset(c, 0, sizeof *c);
    int n = sys->n;
    if (r < 1 || r > n)
        return crom_err(CROM_EUSAGE, "%d modal coordinates for %d degrees of freedom", r, n);
    if (mesh->nv != sys->nv)
        return crom_err(CROM_EUSAGE, "the mesh has %d vertices, the system %d", mesh->nv, sys->nv);
    if (o->max_iter < 1 || !(o->tol > 0) || !isfinite(o->tol) || !(o->mu >= 0) || !isfinite(o->mu))
        return crom_err(CROM_EUSAGE, "constrained equilibria: bad options (max_iter %d, tol %g, mu %g)", o->max_iter,
                        o->tol, o->mu);
    double *R = NULL;
    int nr = 0, rc = crom_modes_rigid(mesh, sys, fixed, &R, &nr);
    if (rc)
        return rc;
    const double *X = mesh->X;
    c->sys = sys;
    c->fixed = fixed;
    c->X = X;
    c->n = n;
    c->r = r;
    c->nc = r + nr;
    c->o = *o;
    c->L = crom_mesh_points_diagonal(X, n / 3);
    size_t nr_ = (size_t)n * c->nc;
    int nc = c->nc;
    c->B = crom_malloc(sizeof(double) * nr_);
    c->V = crom_malloc(sizeof(double) * nr_);
    c->H = crom_malloc(sizeof(double) * (size_t)sys->nnz);
    c->g = crom_malloc(sizeof(double) * (size_t)n);
    c->d = crom_malloc(sizeof(double) * (size_t)n);
    c->a = crom_malloc(sizeof(double) * (size_t)n);
    c->Y = crom_malloc(sizeof(double) * nr_);
    c->S = crom_malloc(sizeof(double) * (size_t)nc * nc);
    c->xt = crom_malloc(sizeof(double) * (size_t)n);
    c->work = crom_malloc(sizeof(double) * (size_t)n);
    c->lam = crom_malloc(sizeof(double) * (size_t)nc);
    if (!c->B || !c->V || !c->H || !c->g || !c->d || !c->a || !c->Y || !c->S || !c->xt || !c->work || !c->lam) {
        free(R);
        crom_cequil_free(c);
        return CROM_EINTERNAL;
    }
    /* B = [M W / m | M R] and V = [W | R], column-major [nc][n] (the solves'
     * layout), so that Bᵀ V = I; check W */
    double m = sys->total_mass;
    for (int i = 0; i < n; i++) {
        for (int k = 0; k < r; k++) {
            double w = W[(size_t)i * r + k];
            if (fixed && fixed[i] && w != 0) {
                free(R);
                crom_cequil_free(c);
                return crom_err(CROM_EUSAGE, "mode %d moves pinned degree of freedom %d (vertex %d)", k + 1, i,
                                i / 3);
            }
            c->V[(size_t)k * n + i] = w;
            c->B[(size_t)k * n + i] = sys->mass[i / 3] * w / m;
        }
        for (int k = 0; k < nr; k++) {
            c->V[(size_t)(r + k) * n + i] = R[(size_t)i * nr + k];
            c->B[(size_t)(r + k) * n + i] = sys->mass[i / 3] * R[(size_t)i * nr + k];
        }
    }
    free(R);
    for (int k = 0; k < nc; k++)
        for (int l = 0; l < nc; l++) {
            double s = 0;
            for (int i = 0; i < n; i++)
                s += c->V[(size_t)l * n + i] * c->B[(size_t)k * n + i];
            if (!(fabs(s - (k == l)) <= 1e-6)) {
                crom_cequil_free(c);
                return k < r && l < r
                           ? crom_err(CROM_EUSAGE, "the modes are not M-orthonormal (W^T M W / m entry (%d, %d) is "
                                                   "%.3g): give crom-modes' modes", k + 1, l + 1, s)
                           : crom_err(CROM_EUSAGE, "the modes are not M-orthogonal to the rigid motions the pins "
                                                   "leave free (entry %.3g): give crom-modes' modes of this mesh "
                                                   "with these pins", s);
            }
        }
    c->chol = crom_chol_analyze(n, sys->colptr, sys->rowind, 3);
    if (!c->chol) {
        crom_cequil_free(c);
        return CROM_EINTERNAL;
    }
    c->mu = o->mu;
    if (!(c->mu > 0)) { /* 1e-8 of the mean K_ii / m_i at rest over the free DOFs */
        crom_fem_opts fo = {0, 0, fixed, 1};
        rc = crom_system_assemble(sys, X, &fo, NULL, NULL, c->H);
        if (rc) {
            crom_cequil_free(c);
            return rc;
        }
        double s = 0;
        int cnt = 0;
        for (int j = 0; j < n; j++)
            if (!(fixed && fixed[j]) && sys->mass[j / 3] > 0) {
                s += c->H[sys->colptr[j + 1] - 1] / sys->mass[j / 3];
                cnt++;
            }
        c->mu = cnt ? 1e-8 * s / cnt : 1;
        if (!(c->mu > 0) || !isfinite(c->mu))
            c->mu = 1;
    }
    return 0;
}

static int energy_fn(void *ctx, const double *x, double *f, double *g)
{
    crom_cequil *c = ctx;
    crom_fem_opts fo = {0, 0, c->fixed, 1};
    return crom_system_assemble(c->sys, x, &fo, f, g, NULL);
}

/* The Newton direction Δ (in c->d) and multipliers λ at the current g and
 * factored H: a = −H⁻¹g, Y = H⁻¹B, (BᵀY)λ = Bᵀa, Δ = a − Yλ. */
static int kkt_direction(crom_cequil *c)
{
    int n = c->n, nc = c->nc, rc;
    for (int i = 0; i < n; i++)
        c->work[i] = -c->g[i];
    if ((rc = crom_chol_solve(c->chol, c->work, c->a)) ||
        (rc = crom_chol_solve_many(c->chol, nc, c->B, c->Y)))
        return rc;
    /* S = Bᵀ Y (nc×nc, SPD), λ = S⁻¹ Bᵀ a */
    cblas_dgemm(CblasColMajor, CblasTrans, CblasNoTrans, nc, nc, n, 1.0, c->B, n, c->Y, n, 0.0, c->S, nc);
    cblas_dgemv(CblasColMajor, CblasTrans, n, nc, 1.0, c->B, n, c->a, 1, 0.0, c->lam, 1);
    if (LAPACKE_dposv(LAPACK_COL_MAJOR, 'U', nc, 1, c->S, nc, c->lam, nc) != 0)
        return crom_err(CROM_EDATA, "the modal constraint's Schur complement is not positive definite");
    memcpy(c->d, c->a, sizeof(double) * (size_t)n);
    cblas_dgemv(CblasColMajor, CblasNoTrans, n, nc, -1.0, c->Y, n, c->lam, 1, 1.0, c->d, 1);
    return 0;
}

int crom_cequil_solve(crom_cequil *c, const double *z, double *x, double *lambda, crom_cequil_stats *st)
{
    int n = c->n, r = c->r, rc = 0;
    const crom_system *sys = c->sys;
    crom_cequil_stats s0 = {0, 0, INFINITY, NAN};
    if (!st)
        st = &s0;
    *st = s0;
    for (int k = 0; k < r; k++)
        if (!isfinite(z[k]))
            return crom_err(CROM_EUSAGE, "modal coordinate %d is not finite", k + 1);
    /* feasible start: pinned DOFs at rest, then x += W (z − Bᵀ(x − X)) */
    for (int i = 0; i < n; i++) {
        if (!isfinite(x[i]))
            return crom_err(CROM_EUSAGE, "the start is not finite");
        if (c->fixed && c->fixed[i])
            x[i] = c->X[i];
        c->work[i] = x[i] - c->X[i];
    }
    for (int k = 0; k < c->nc; k++) { /* the rigid motions' targets are 0 */
        double zk = 0;
        for (int i = 0; i < n; i++)
            zk += c->B[(size_t)k * n + i] * c->work[i];
        c->lam[k] = (k < r ? z[k] : 0) - zk;
    }
    for (int k = 0; k < c->nc; k++)
        for (int i = 0; i < n; i++)
            x[i] += c->V[(size_t)k * n + i] * c->lam[k];
    /* Newton on the true Hessian plus μM (quadratic convergence), shifted by
     * τM where its factorization fails (Levenberg: τ grows tenfold until it
     * succeeds, and is relaxed fourfold per iteration); SPD-projected element
     * Hessians for the rest of the solve if a direction does not descend */
    crom_fem_opts fo = {0, c->mu, c->fixed, 1};
    double E = NAN, shift = 0;
    for (int it = 0;; it++) {
        if ((rc = crom_system_assemble(sys, x, &fo, &E, c->g, c->H)))
            return crom_err(CROM_EDATA, "the energy is not defined at the start or along the solve (an inverted "
                                        "element) at Newton iteration %d", it);
        if (it == c->o.max_iter)
            break;
        int tries = 0;
        double added = 0, tau = shift;
        for (;;) {
            if (tau > added) { /* shift by τ M (Levenberg) */
                for (int j = 0; j < n; j++)
                    if (!(c->fixed && c->fixed[j]))
                        c->H[sys->colptr[j + 1] - 1] += (tau - added) * sys->mass[j / 3];
                added = tau;
            }
            if ((rc = crom_chol_factor(c->chol, c->H)) != CROM_EDATA || tries++ >= 30)
                break;
            crom_err_clear();
            tau = tau > 0 ? 10 * tau : 1e6 * c->mu; /* 1e-2 of the mean K_ii / m_i for the default μ */
        }
        shift = added / 4;
        if (rc)
            return rc;
        if ((rc = kkt_direction(c)))
            return rc;
        double dmax = 0, slope = 0;
        for (int i = 0; i < n; i++) {
            dmax = fmax(dmax, fabs(c->d[i]));
            slope += c->g[i] * c->d[i];
        }
        st->newton = it + 1;
        st->residual = dmax / c->L;
        if (!isfinite(st->residual))
            return crom_err(CROM_EDATA, "the constrained solve became non-finite");
        /* converged: the correction is below tol of the body size, or the
         * energy it could still gain, −gᵀΔ, is below 1e-12 of E (a thin
         * shell's nearly isometric bendings leave directions so flat that
         * the configuration is fixed only to the round-off of its energy) */
        if (st->residual <= c->o.tol || -slope <= 1e-12 * fabs(E)) {
            for (int i = 0; i < n; i++)
                x[i] += c->d[i];
            if ((rc = crom_system_assemble(sys, x, &fo, &E, c->g, NULL)))
                return crom_err(CROM_EDATA, "the energy is not defined at the equilibrium");
            st->energy = E;
            if (lambda)
                for (int k = 0; k < r; k++) { /* −Wᵀ g */
                    double s = 0;
                    for (int i = 0; i < n; i++)
                        s += c->V[(size_t)k * n + i] * c->g[i];
                    lambda[k] = -s;
                }
            return 0;
        }
        if (!(slope < 0)) {
            if (fo.project) /* H is SPD and Δ feasible: only round-off gives this */
                break;
            fo.project = 1; /* the true Hessian is definite but the direction does not descend */
            continue;
        }
        double noise = 64 * DBL_EPSILON * fabs(E);
        int tiny = -slope < 1e-8 * fabs(E);
        double alpha = crom_linesearch(energy_fn, c, (size_t)n, x, c->d, E, slope, noise, tiny, c->xt, c->work,
                                       &st->cuts);
        if (!(alpha > 0))
            break;
        memcpy(x, c->xt, sizeof(double) * (size_t)n);
    }
    st->energy = E;
    return crom_err(CROM_EDATA, "the constrained equilibrium did not converge: correction %.3g of the body size "
                                "after %d Newton iterations (tolerance %.3g)", st->residual, st->newton, c->o.tol);
}

double crom_cequil_unbalanced(const crom_system *sys, const unsigned char *fixed, int r, const double *W,
                              const double *x, double *g, double *f)
{
    crom_fem_opts fo = {0, 0, fixed, 1};
    int n = sys->n, nfree = 0;
    if (crom_system_assemble(sys, x, &fo, NULL, g, NULL)) {
        crom_err_clear();
        return NAN;
    }
    double m = sys->total_mass, s2 = 0, *wg = crom_malloc(sizeof(double) * (size_t)r);
    if (!wg)
        return NAN;
    cblas_dgemv(CblasRowMajor, CblasTrans, n, r, 1.0, W, r, g, 1, 0.0, wg, 1);
    for (int v = 0; v < n / 3; v++) {
        int free_v = 0;
        for (int k = 0; k < 3; k++) {
            int i = 3 * v + k;
            double fi = 0;
            if (!(fixed && fixed[i])) { /* g_i − m_i W_i (Wᵀ g) / m */
                fi = g[i];
                for (int a = 0; a < r; a++)
                    fi -= sys->mass[v] * W[(size_t)i * r + a] * wg[a] / m;
                free_v = 1;
            }
            if (f)
                f[i] = fi;
            s2 += fi * fi;
        }
        nfree += free_v;
    }
    free(wg);
    return nfree ? sqrt(s2 / nfree) : 0;
}
