/* sym.c — symmetric sparse matrices stored as their upper triangle, and
 * the SPD projection of small dense element matrices (see sym.h). */
#include <lapacke.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "phys/sym.h"

void crom_sym_matvec(const crom_sym *A, const double *x, double *y)
{
    int n = A->n;
    memset(y, 0, sizeof(double) * (size_t)n);
    for (int j = 0; j < n; j++) {
        double xj = x[j], yj = 0;
        for (int k = A->colptr[j]; k < A->colptr[j + 1]; k++) {
            int i = A->rowind[k];
            double a = A->val[k];
            y[i] += a * xj;
            if (i != j)
                yj += a * x[i];
        }
        y[j] += yj;
    }
}

int crom_sym_dense_project(double *M, int n)
{
    double w[CROM_SYM_DENSE_MAX], Q[CROM_SYM_DENSE_MAX * CROM_SYM_DENSE_MAX];
    if (n < 1 || n > CROM_SYM_DENSE_MAX)
        return 1;
    memcpy(Q, M, sizeof(double) * (size_t)n * n);
    if (LAPACKE_dpotrf(LAPACK_ROW_MAJOR, 'U', n, Q, n) == 0)
        return 0;
    memcpy(Q, M, sizeof(double) * (size_t)n * n);
    if (LAPACKE_dsyev(LAPACK_ROW_MAJOR, 'V', 'U', n, Q, n, w) != 0)
        return 1;
    if (w[0] >= 0)
        return 0;
    memset(M, 0, sizeof(double) * (size_t)n * n);
    for (int k = 0; k < n; k++) {
        if (w[k] <= 0)
            continue;
        for (int i = 0; i < n; i++)
            for (int j = 0; j < n; j++)
                M[i * n + j] += w[k] * Q[i * n + k] * Q[j * n + k];
    }
    return 0;
}

static int pair_cmp(const void *pa, const void *pb)
{
    const long long *a = pa, *b = pb;
    return *a < *b ? -1 : *a > *b;
}

int crom_sym_block_pattern(int nv, int nelem, int (*verts)(const void *ctx, int e, int *v), const void *ctx,
                           int **colptr, int **rowind, int *nnz)
{
    *colptr = NULL;
    *rowind = NULL;
    size_t cap = (size_t)nv, k = 0;
    int v[8];
    for (int e = 0; e < nelem; e++) {
        size_t m = (size_t)verts(ctx, e, v);
        cap += m * (m - 1) / 2;
    }
    long long *pr = crom_malloc(sizeof *pr * (cap ? cap : 1));
    int *cnt = crom_calloc((size_t)nv + 1, sizeof(int));
    if (!pr || !cnt) {
        free(pr), free(cnt);
        return CROM_EINTERNAL;
    }
    for (int i = 0; i < nv; i++) /* every diagonal block */
        pr[k++] = (long long)i * nv + i;
    for (int e = 0; e < nelem; e++) {
        int m = verts(ctx, e, v);
        for (int i = 0; i < m; i++)
            for (int j = i + 1; j < m; j++) {
                int lo = v[i] < v[j] ? v[i] : v[j], hi = v[i] < v[j] ? v[j] : v[i];
                pr[k++] = (long long)hi * nv + lo; /* column-major: (column hi, row lo) */
            }
    }
    qsort(pr, k, sizeof *pr, pair_cmp);
    size_t u = 0;
    for (size_t i = 0; i < k; i++)
        if (!u || pr[i] != pr[u - 1])
            pr[u++] = pr[i];
    /* per vertex column block: its neighbours lo <= hi in order */
    for (size_t i = 0; i < u; i++)
        cnt[pr[i] / nv + 1]++;
    for (int i = 0; i < nv; i++)
        cnt[i + 1] += cnt[i];
    size_t nz = 0;
    for (int i = 0; i < nv; i++) /* (blocks − 1) full 3×3 off-diagonal blocks and the 6 of the diagonal */
        nz += 9 * (size_t)(cnt[i + 1] - cnt[i] - 1) + 6;
    int *cp = crom_malloc(sizeof(int) * (3 * (size_t)nv + 1)), *ri = crom_malloc(sizeof(int) * (nz ? nz : 1));
    if (!cp || !ri || nz > (size_t)2147483647) {
        free(pr), free(cnt), free(cp), free(ri);
        return CROM_EINTERNAL;
    }
    int z = 0;
    for (int i = 0; i < nv; i++)
        for (int d = 0; d < 3; d++) {
            cp[3 * i + d] = z;
            for (int b = cnt[i]; b < cnt[i + 1]; b++) {
                int lo = (int)(pr[b] % nv);
                for (int c = 0; c < 3 && (lo < i || c <= d); c++)
                    ri[z++] = 3 * lo + c;
            }
        }
    cp[3 * nv] = z;
    free(pr);
    free(cnt);
    *colptr = cp;
    *rowind = ri;
    *nnz = z;
    return 0;
}

int crom_sym_entry(const int *colptr, const int *rowind, int r, int c)
{
    int lo = colptr[c], hi = colptr[c + 1] - 1;
    while (lo < hi) {
        int mid = (lo + hi) / 2;
        if (rowind[mid] < r)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

void crom_sym_dirichlet_mass(int n, const int *colptr, const int *rowind, const unsigned char *fixed,
                             const double *mass, double mass_scale, double *g, double *H)
{
    for (int i = 0; g && fixed && i < n; i++)
        if (fixed[i])
            g[i] = 0;
    for (int c = 0; H && c < n; c++)
        for (int k = colptr[c]; k < colptr[c + 1]; k++) {
            int r = rowind[k];
            if (fixed && (fixed[r] || fixed[c]))
                H[k] = r == c;
            else if (r == c)
                H[k] += mass_scale * mass[c / 3];
        }
}
