/* mderiv.c — modal derivatives as a linear basis (mderiv.h). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "mesh/mesh.h"
#include "phys/chol.h"
#include "phys/mderiv.h"
#include "phys/modes.h"
#include "phys/sym.h"

/* The factor of K at rest (the fixed DOFs decoupled: identity rows and
 * columns) in *ch, and K's values in K [nnz]. */
static int factor_rest(const crom_system *s, const double *X, const unsigned char *fixed, double *K, crom_chol **ch)
{
    crom_fem_opts fk = {0, 0, fixed, 1};
    int rc = crom_system_assemble(s, X, &fk, NULL, NULL, K);
    if (rc)
        return rc;
    if (!(*ch = crom_chol_analyze(s->n, s->colptr, s->rowind, 3)))
        return crom_errcode() ? crom_errcode() : CROM_EINTERNAL;
    if ((rc = crom_chol_factor(*ch, K)) == CROM_EDATA)
        rc = crom_err(CROM_EDATA, "modal derivatives: the stiffness at rest is singular on the free degrees of "
                                  "freedom (pin the body so that it cannot move rigidly)");
    return rc;
}

/* The right-hand sides −(∂K/∂u · φ_j) φ_i, i >= j, into B [nd][n]
 * (column-major, in the order of mderiv.h). */
static int rhs(const crom_system *s, const double *X, const unsigned char *fixed, const double *phi, int k,
               double *B, double *Hp, double *Hm, double *x, double *y)
{
    int n = s->n, col = 0, rc;
    double L = crom_mesh_points_diagonal(X, n / 3);
    crom_fem_opts fh = {0, 0, NULL, 1};
    for (int j = 0; j < k; j++) {
        double amax = 0;
        for (int d = 0; d < n; d++)
            amax = fmax(amax, fabs(phi[(size_t)d * k + j]));
        if (!(amax > 0))
            return crom_err(CROM_EDATA, "modal derivatives: mode %d is zero", j + 1);
        double eps = 1e-5 * L / amax;
        for (int sg = 0; sg < 2; sg++) {
            for (int d = 0; d < n; d++)
                x[d] = X[d] + (sg ? -eps : eps) * phi[(size_t)d * k + j];
            if ((rc = crom_system_assemble(s, x, &fh, NULL, NULL, sg ? Hm : Hp)))
                return rc;
        }
        for (int l = 0; l < s->nnz; l++)
            Hp[l] = (Hp[l] - Hm[l]) / (2 * eps);
        crom_sym D = {n, s->colptr, s->rowind, Hp};
        for (int i = j; i < k; i++, col++) {
            for (int d = 0; d < n; d++)
                x[d] = phi[(size_t)d * k + i];
            crom_sym_matvec(&D, x, y);
            double *b = B + (size_t)col * n;
            for (int d = 0; d < n; d++)
                b[d] = fixed && fixed[d] ? 0 : -y[d];
        }
    }
    return 0;
}

/* The derivatives into B [nd][n] (column-major), and the stiffness at
 * rest into K [nnz]. */
static int derivatives(const crom_system *s, const double *X, const unsigned char *fixed, const double *phi, int k,
                       double *B, double *K)
{
    int n = s->n, nd = k * (k + 1) / 2, rc;
    double *Hp = crom_malloc(sizeof(double) * (size_t)s->nnz), *Hm = crom_malloc(sizeof(double) * (size_t)s->nnz);
    double *x = crom_malloc(sizeof(double) * (size_t)n), *y = crom_malloc(sizeof(double) * (size_t)n);
    crom_chol *ch = NULL;
    if (!Hp || !Hm || !x || !y)
        rc = CROM_EINTERNAL;
    else if (!(rc = factor_rest(s, X, fixed, K, &ch)) && !(rc = rhs(s, X, fixed, phi, k, B, Hp, Hm, x, y)))
        rc = crom_chol_solve_many(ch, nd, B, B);
    for (size_t i = 0; !rc && i < (size_t)n * nd; i++)
        if (!isfinite(B[i]))
            rc = crom_err(CROM_EDATA, "modal derivatives: a derivative is not finite");
    crom_chol_free(ch);
    free(Hp), free(Hm), free(x), free(y);
    return rc;
}

int crom_mderiv_compute(const crom_system *s, const double *X, const unsigned char *fixed, const double *phi, int k,
                        double *psi)
{
    if (k < 1)
        return crom_err(CROM_EUSAGE, "modal derivatives of %d modes", k);
    int n = s->n, nd = k * (k + 1) / 2;
    double *B = crom_malloc(sizeof(double) * (size_t)n * nd), *K = crom_malloc(sizeof(double) * (size_t)s->nnz);
    int rc = B && K ? derivatives(s, X, fixed, phi, k, B, K) : CROM_EINTERNAL;
    for (int c = 0; !rc && c < nd; c++)
        for (int d = 0; d < n; d++)
            psi[(size_t)d * nd + c] = B[(size_t)c * n + d];
    free(B), free(K);
    return rc;
}

int crom_mderiv_lift(const crom_system *s, const double *X, const unsigned char *fixed, int nl, const double *e,
                     double *u)
{
    int n = s->n, rc;
    double *K = crom_malloc(sizeof(double) * (size_t)s->nnz), *Kf = crom_malloc(sizeof(double) * (size_t)s->nnz);
    double *ep = crom_malloc(sizeof(double) * (size_t)n), *y = crom_malloc(sizeof(double) * (size_t)n);
    crom_chol *ch = NULL;
    crom_fem_opts whole = {0, 0, NULL, 1};
    if (!K || !Kf || !ep || !y)
        rc = CROM_EINTERNAL;
    else if (!(rc = crom_system_assemble(s, X, &whole, NULL, NULL, Kf)))
        rc = factor_rest(s, X, fixed, K, &ch);
    crom_sym Ks = {n, s->colptr, s->rowind, Kf};
    for (int l = 0; !rc && l < nl; l++) { /* b = e on the fixed DOFs, −K e on the free ones */
        double *b = u + (size_t)l * n;
        for (int d = 0; d < n; d++)
            ep[d] = fixed && fixed[d] ? e[(size_t)l * n + d] : 0;
        crom_sym_matvec(&Ks, ep, y);
        for (int d = 0; d < n; d++)
            b[d] = fixed && fixed[d] ? ep[d] : -y[d];
    }
    if (!rc)
        rc = crom_chol_solve_many(ch, nl, u, u);
    for (size_t i = 0; !rc && i < (size_t)n * nl; i++)
        if (!isfinite(u[i]))
            rc = crom_err(CROM_EDATA, "a pin's static lift is not finite");
    if (rc == CROM_EDATA && crom_errmsg() && strstr(crom_errmsg(), "modal derivatives: the stiffness"))
        rc = crom_err(CROM_EDATA, "the stiffness at rest is singular on the free degrees of freedom (pin the body so "
                                  "that it cannot move rigidly)");
    crom_chol_free(ch);
    free(K), free(Kf), free(ep), free(y);
    return rc;
}

int crom_mderiv_basis(const crom_system *s, const double *X, const unsigned char *fixed, const double *phi, int k,
                      double **out, int *kout, double **freq)
{
    *out = *freq = NULL;
    *kout = 0;
    if (k < 1)
        return crom_err(CROM_EUSAGE, "modal derivatives of %d modes", k);
    int n = s->n, nd = k * (k + 1) / 2, ncol = k + nd, rc;
    double *K = crom_malloc(sizeof(double) * (size_t)s->nnz), *V = crom_malloc(sizeof(double) * (size_t)n * ncol);
    double *m = crom_malloc(sizeof(double) * (size_t)n), *y = crom_malloc(sizeof(double) * (size_t)n);
    double *W = NULL, *f = NULL;
    if (!K || !V || !m || !y) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    /* the modes first, then the derivatives */
    for (int i = 0; i < k; i++)
        for (int d = 0; d < n; d++)
            V[(size_t)i * n + d] = phi[(size_t)d * k + i];
    if ((rc = derivatives(s, X, fixed, phi, k, V + (size_t)k * n, K)))
        goto out;
    for (int d = 0; d < n; d++)
        m[d] = s->mass[d / 3];
    int kept = crom_modes_orthonormalize(V, n, ncol, m, k);
    if (kept < k) {
        rc = crom_err(CROM_EDATA, "modal derivatives: a mode vanishes on the free degrees of freedom");
        goto out;
    }
    W = crom_malloc(sizeof(double) * (size_t)n * kept);
    f = crom_malloc(sizeof(double) * (size_t)kept);
    if (!W || !f) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    crom_sym Ks = {n, s->colptr, s->rowind, K}; /* K at rest (identity at the fixed DOFs, where v = 0) */
    for (int c = 0; c < kept; c++) {
        const double *v = V + (size_t)c * n;
        crom_sym_matvec(&Ks, v, y);
        double w2 = 0;
        for (int d = 0; d < n; d++) {
            W[(size_t)d * kept + c] = v[d];
            w2 += v[d] * y[d];
        }
        f[c] = sqrt(fmax(w2, 0)) / (2 * M_PI);
    }
    *out = W;
    *freq = f;
    *kout = kept;
    W = f = NULL;
out:
    free(K), free(V), free(m), free(y), free(W), free(f);
    return rc;
}
