/* chol.c — CHOLMOD factorization with a METIS block ordering, and
 * factor-preconditioned CG (see chol.h). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <cholmod.h>
#include <metis.h>

#include "base/clock.h"
#include "base/err.h"
#include "phys/chol.h"

struct crom_chol {
    cholmod_common cc;
    cholmod_factor *L;
    cholmod_sparse A;   /* header over the caller's arrays (values set per factor) */
    int n;
    double t_analyze, t_factor, t_solve;
    long nfactor, nsolve;
    cholmod_dense *X, *Y, *E, B; /* workspaces for cholmod_solve2 */
};

/* METIS nested dissection of the vertex graph (the pattern's 3×3 blocks),
 * expanded to DOFs. perm[k] = DOF placed k-th. */
static int block_ordering(int n, const int *colptr, const int *rowind, int block, int *perm)
{
    int nb = n / block;
    /* adjacency of blocks from the upper triangle: collect both directions */
    idx_t *deg = calloc((size_t)nb + 1, sizeof(idx_t));
    if (!deg)
        return crom_err(CROM_EINTERNAL, "out of memory");
    for (int j = 0; j < n; j += block)
        for (int k = colptr[j]; k < colptr[j + 1]; k++) {
            int bi = rowind[k] / block, bj = j / block;
            if (bi != bj && rowind[k] % block == 0) {
                deg[bi + 1]++;
                deg[bj + 1]++;
            }
        }
    for (int b = 0; b < nb; b++)
        deg[b + 1] += deg[b];
    idx_t *adj = malloc(sizeof(idx_t) * (size_t)(deg[nb] ? deg[nb] : 1));
    idx_t *fill = malloc(sizeof(idx_t) * (size_t)nb);
    idx_t *mperm = malloc(sizeof(idx_t) * (size_t)nb), *iperm = malloc(sizeof(idx_t) * (size_t)nb);
    int rc = 0;
    if (!adj || !fill || !mperm || !iperm) {
        rc = crom_err(CROM_EINTERNAL, "out of memory");
        goto out;
    }
    memcpy(fill, deg, sizeof(idx_t) * (size_t)nb);
    for (int j = 0; j < n; j += block)
        for (int k = colptr[j]; k < colptr[j + 1]; k++) {
            int bi = rowind[k] / block, bj = j / block;
            if (bi != bj && rowind[k] % block == 0) {
                adj[fill[bi]++] = bj;
                adj[fill[bj]++] = bi;
            }
        }
    if (nb > 1 && deg[nb] > 0) {
        idx_t nvtx = nb, opts[METIS_NOPTIONS];
        METIS_SetDefaultOptions(opts);
        opts[METIS_OPTION_SEED] = 1; /* repeatable */
        if (METIS_NodeND(&nvtx, deg, adj, NULL, opts, mperm, iperm) != METIS_OK) {
            rc = crom_err(CROM_EINTERNAL, "METIS_NodeND failed");
            goto out;
        }
    } else {
        for (int b = 0; b < nb; b++)
            mperm[b] = b;
    }
    for (int k = 0; k < nb; k++)
        for (int c = 0; c < block; c++)
            perm[block * k + c] = block * (int)mperm[k] + c;
out:
    free(deg);
    free(adj);
    free(fill);
    free(mperm);
    free(iperm);
    return rc;
}

crom_chol *crom_chol_analyze(int n, const int *colptr, const int *rowind, int block)
{
    if (block < 1 || n % block) {
        crom_err(CROM_EINTERNAL, "crom_chol_analyze: n = %d is not a multiple of block %d", n, block);
        return NULL;
    }
    crom_chol *c = calloc(1, sizeof *c);
    if (!c) {
        crom_err(CROM_EINTERNAL, "out of memory");
        return NULL;
    }
    double t0 = crom_clock_now();
    cholmod_start(&c->cc);
    c->cc.print = 0;
    c->cc.error_handler = NULL;
    c->cc.supernodal = CHOLMOD_SUPERNODAL;
    c->cc.nmethods = 1;
    c->cc.method[0].ordering = CHOLMOD_GIVEN;
    c->cc.postorder = 1;
    c->n = n;
    c->A.nrow = c->A.ncol = (size_t)n;
    c->A.nzmax = (size_t)colptr[n];
    c->A.p = (void *)colptr;
    c->A.i = (void *)rowind;
    c->A.stype = 1;
    c->A.itype = CHOLMOD_INT;
    c->A.xtype = CHOLMOD_REAL;
    c->A.dtype = CHOLMOD_DOUBLE;
    c->A.sorted = 1;
    c->A.packed = 1;
    int *perm = malloc(sizeof(int) * (size_t)n);
    if (!perm || block_ordering(n, colptr, rowind, block, perm)) {
        free(perm);
        cholmod_finish(&c->cc);
        free(c);
        if (!crom_errcode())
            crom_err(CROM_EINTERNAL, "out of memory");
        return NULL;
    }
    /* the pattern alone: analyze with a pattern-only header */
    c->A.xtype = CHOLMOD_PATTERN;
    c->L = cholmod_analyze_p(&c->A, perm, NULL, 0, &c->cc);
    c->A.xtype = CHOLMOD_REAL;
    free(perm);
    if (!c->L || c->cc.status < CHOLMOD_OK) {
        crom_err(CROM_EINTERNAL, "CHOLMOD analysis failed (status %d)", c->cc.status);
        cholmod_finish(&c->cc);
        free(c);
        return NULL;
    }
    c->B.nrow = (size_t)n;
    c->B.ncol = 1;
    c->B.nzmax = (size_t)n;
    c->B.d = (size_t)n;
    c->B.xtype = CHOLMOD_REAL;
    c->B.dtype = CHOLMOD_DOUBLE;
    c->t_analyze = crom_clock_now() - t0;
    return c;
}

int crom_chol_factor(crom_chol *c, const double *val)
{
    double t0 = crom_clock_now();
    c->A.x = (void *)val;
    int ok = cholmod_factorize(&c->A, c->L, &c->cc);
    c->t_factor += crom_clock_now() - t0;
    c->nfactor++;
    if (!ok || c->cc.status == CHOLMOD_NOT_POSDEF)
        return crom_err(CROM_EDATA, "matrix is not positive definite (CHOLMOD stopped at column %zu)",
                        (size_t)c->L->minor);
    if (c->cc.status < CHOLMOD_OK)
        return crom_err(CROM_EINTERNAL, "CHOLMOD factorization failed (status %d)", c->cc.status);
    return 0;
}

int crom_chol_solve(crom_chol *c, const double *b, double *x)
{
    double t0 = crom_clock_now();
    c->B.x = (void *)b;
    if (!cholmod_solve2(CHOLMOD_A, c->L, &c->B, NULL, &c->X, NULL, &c->Y, &c->E, &c->cc))
        return crom_err(CROM_EINTERNAL, "CHOLMOD solve failed (status %d)", c->cc.status);
    memcpy(x, c->X->x, sizeof(double) * (size_t)c->n);
    c->t_solve += crom_clock_now() - t0;
    c->nsolve++;
    return 0;
}

int crom_chol_solve_many(crom_chol *c, int nrhs, const double *b, double *x)
{
    double t0 = crom_clock_now();
    cholmod_dense B = c->B;
    B.ncol = (size_t)nrhs;
    B.nzmax = B.d * (size_t)nrhs;
    B.x = (void *)b;
    if (!cholmod_solve2(CHOLMOD_A, c->L, &B, NULL, &c->X, NULL, &c->Y, &c->E, &c->cc))
        return crom_err(CROM_EINTERNAL, "CHOLMOD solve failed (status %d)", c->cc.status);
    memcpy(x, c->X->x, sizeof(double) * (size_t)c->n * (size_t)nrhs);
    c->t_solve += crom_clock_now() - t0;
    c->nsolve += nrhs;
    return 0;
}

void crom_chol_stats(const crom_chol *c, double *ta, double *tf, double *ts, long *nf, long *ns)
{
    if (ta) *ta = c->t_analyze;
    if (tf) *tf = c->t_factor;
    if (ts) *ts = c->t_solve;
    if (nf) *nf = c->nfactor;
    if (ns) *ns = c->nsolve;
}

void crom_chol_free(crom_chol *c)
{
    if (!c)
        return;
    cholmod_free_factor(&c->L, &c->cc);
    cholmod_free_dense(&c->X, &c->cc);
    cholmod_free_dense(&c->Y, &c->cc);
    cholmod_free_dense(&c->E, &c->cc);
    cholmod_finish(&c->cc);
    free(c);
}

static double dot(const double *a, const double *b, int n)
{
    double s = 0;
    for (int i = 0; i < n; i++)
        s += a[i] * b[i];
    return s;
}

static void sym_apply(void *ctx, const double *x, double *y) { crom_sym_matvec(ctx, x, y); }

int crom_chol_pcg(const crom_sym *A, crom_chol *c, const double *b, double *x, double rtol,
             int maxit, double *work)
{
    return crom_chol_pcg_op(A->n, sym_apply, (void *)A, c, b, x, rtol, maxit, work);
}

int crom_chol_pcg_op(int n, void (*apply)(void *ctx, const double *x, double *y), void *ctx, crom_chol *c,
                     const double *b, double *x, double rtol, int maxit, double *work)
{
    double *r = work, *z = work + n, *p = work + 2 * (size_t)n, *Ap = work + 3 * (size_t)n;
    double bn = sqrt(dot(b, b, n));
    if (bn == 0) {
        memset(x, 0, sizeof(double) * (size_t)n);
        return 0;
    }
    apply(ctx, x, Ap);
    for (int i = 0; i < n; i++)
        r[i] = b[i] - Ap[i];
    if (sqrt(dot(r, r, n)) <= rtol * bn)
        return 0;
    int rc = crom_chol_solve(c, r, z);
    if (rc)
        return -rc;
    memcpy(p, z, sizeof(double) * (size_t)n);
    double rz = dot(r, z, n);
    for (int it = 1; it <= maxit; it++) {
        apply(ctx, p, Ap);
        double pAp = dot(p, Ap, n);
        if (!(pAp > 0))
            return -1;
        double a = rz / pAp;
        for (int i = 0; i < n; i++) {
            x[i] += a * p[i];
            r[i] -= a * Ap[i];
        }
        if (sqrt(dot(r, r, n)) <= rtol * bn)
            return it;
        if ((rc = crom_chol_solve(c, r, z)))
            return -rc;
        double rz1 = dot(r, z, n);
        double beta = rz1 / rz;
        rz = rz1;
        for (int i = 0; i < n; i++)
            p[i] = z[i] + beta * p[i];
    }
    return -1;
}
