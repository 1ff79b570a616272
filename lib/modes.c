/* modes.c — linear vibration modes by shift-invert block Lanczos with full
 * reorthogonalization and thick restarts (see modes.h for the method and
 * why it is ours rather than ARPACK's). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <cblas.h>
#include <lapacke.h>

#include "cli.h"
#include "err.h"
#include "modes.h"
#include "rng.h"
#include "solve.h"

void crom_modes_defaults(crom_modes_opts *o)
{
    memset(o, 0, sizeof *o);
    o->count = 20;
    o->tol = 1e-10;
    o->rigid_tol = 1e-12;
    o->block = 6;
    o->seed = 1;
}

void crom_modes_free(crom_modes *m)
{
    if (!m)
        return;
    free(m->omega2);
    free(m->freq);
    free(m->phi);
    free(m->residual);
    memset(m, 0, sizeof *m);
}

int crom_modes_pins(const crom_mesh *m, int n, const char *const *refs, unsigned char **fixed,
                    int *npinned)
{
    unsigned char *f = crom_calloc(3 * (size_t)m->nv, 1);
    if (!f)
        return CROM_EINTERNAL;
    for (int i = 0; i < n; i++) {
        int *idx, cnt, rc = crom_mesh_select(m, refs[i], &idx, &cnt);
        if (rc) {
            free(f);
            return crom_err_ctx("--pin");
        }
        for (int j = 0; j < cnt; j++)
            memset(f + 3 * (size_t)idx[j], 1, 3);
        free(idx);
    }
    int c = 0;
    for (int v = 0; v < m->nv; v++)
        c += f[3 * (size_t)v] != 0;
    *fixed = f;
    *npinned = c;
    return 0;
}

/* ------------------------------------------------------------ Lanczos */

/* The eigenproblem on the free DOFs and the state of the iteration. Vectors
 * are columns of length n stored one after another (column-major, leading
 * dimension n). */
typedef struct {
    int n;             /* free DOFs */
    const double *m;   /* [n] lumped mass of each free DOF */
    crom_chol *chol;   /* factor of K − σM */
    int b;             /* block size */
    int mcap;          /* capacity of the basis (columns of T) */
    double *V;         /* [(mcap + b) n] basis, then the next block */
    double *T;         /* [mcap mcap] Rayleigh–Ritz matrix, ld mcap */
    double *W, *MW;    /* [b n] images A v of a block, and M times them */
    double *H;         /* [(mcap + b) b] projections */
    double *R;         /* [b b] coupling of the next block to the last one */
    double *tmp;       /* [n] */
    double *MX;        /* [b n] M times a block being orthogonalized */
    double *nrm;       /* [b] column norms */
    crom_rng rng;
    long solves;
} lanczos;

/* ‖x‖_M */
static double mnorm(const lanczos *L, const double *x)
{
    double s = 0;
    for (int i = 0; i < L->n; i++)
        s += L->m[i] * x[i] * x[i];
    return sqrt(s);
}

/* One classical Gram–Schmidt pass of x against the c columns of V in the
 * M inner product (h: c scratch entries). */
static void cgs_pass(lanczos *L, int c, double *x, double *h)
{
    if (c == 0)
        return;
    for (int i = 0; i < L->n; i++)
        L->tmp[i] = L->m[i] * x[i];
    cblas_dgemv(CblasColMajor, CblasTrans, L->n, c, 1.0, L->V, L->n, L->tmp, 1, 0.0, h, 1);
    cblas_dgemv(CblasColMajor, CblasNoTrans, L->n, c, -1.0, L->V, L->n, h, 1, 1.0, x, 1);
}

/* Finish M-orthonormalizing x against the first c columns of V after one
 * Gram–Schmidt pass: more passes until one removes little (twice is enough,
 * a third for heavy cancellation). norm0 is x's norm before the first pass.
 * Returns 1 if x was kept (normalized), 0 if it lies in their span. */
static int orth_one(lanczos *L, int c, double *x, double norm0, double *h)
{
    double nrm = mnorm(L, x);
    for (int pass = 0; pass < 3 && nrm > 1e-10 * norm0; pass++) {
        double before = nrm;
        cgs_pass(L, c, x, h);
        nrm = mnorm(L, x);
        if (nrm > 0.5 * before)
            break;
    }
    if (!(nrm > 1e-10 * norm0))
        return 0;
    for (int i = 0; i < L->n; i++)
        x[i] /= nrm;
    return 1;
}

/* Make the bs columns at V[nb..] M-orthonormal to V[0..nb) and to each
 * other. passes block Gram–Schmidt passes against V[0..nb) come first (two,
 * or one when the caller has done the first), as matrix products that read
 * the basis once per block; then each column is orthogonalized against the
 * block's earlier ones (twice), with one more full pass if that cancelled
 * much. A column in the span of the others (an invariant subspace was found)
 * is replaced by a random one; a column that cannot be completed (the basis
 * spans everything) is dropped. Returns how many columns remain. */
static int orth_block(lanczos *L, int nb, int bs, int passes, double *h)
{
    int n = L->n, kept = 0;
    double *X = L->V + (size_t)nb * n;
    for (int c = 0; c < bs; c++)
        L->nrm[c] = mnorm(L, X + (size_t)c * n);
    for (int p = 0; p < passes && nb > 0; p++) {
        for (int c = 0; c < bs; c++)
            for (int i = 0; i < n; i++)
                L->MX[(size_t)c * n + i] = L->m[i] * X[(size_t)c * n + i];
        cblas_dgemm(CblasColMajor, CblasTrans, CblasNoTrans, nb, bs, n, 1.0, L->V, n, L->MX, n, 0.0, h, nb);
        cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, n, bs, nb, -1.0, L->V, n, h, nb, 1.0, X, n);
    }
    for (int c = 0; c < bs; c++) {
        double *x = L->V + (size_t)(nb + kept) * n;
        if (kept != c)
            memmove(x, L->V + (size_t)(nb + c) * n, sizeof(double) * (size_t)n);
        double n0 = L->nrm[c], before = mnorm(L, x), nrm = before;
        for (int pass = 0; pass < 2 && kept > 0; pass++)
            for (int q = 0; q < kept; q++) {
                const double *v = L->V + (size_t)(nb + q) * n;
                double sdot = 0;
                for (int i = 0; i < n; i++)
                    sdot += L->m[i] * v[i] * x[i];
                for (int i = 0; i < n; i++)
                    x[i] -= sdot * v[i];
            }
        if (kept > 0)
            nrm = mnorm(L, x);
        if (nrm < 0.5 * before && nrm > 1e-10 * n0) {
            cgs_pass(L, nb + kept, x, h); /* heavy cancellation: once more against everything */
            nrm = mnorm(L, x);
        }
        if (n0 > 0 && nrm > 1e-10 * n0) {
            for (int i = 0; i < n; i++)
                x[i] /= nrm;
            kept++;
            continue;
        }
        /* deficient: try random directions */
        int ok = 0;
        for (int t = 0; t < 3 && !ok; t++) {
            for (int i = 0; i < n; i++)
                x[i] = crom_rng_uniform(&L->rng) - 0.5;
            double r0 = mnorm(L, x);
            cgs_pass(L, nb + kept, x, h);
            ok = orth_one(L, nb + kept, x, r0, h);
        }
        if (ok)
            kept++;
    }
    return kept;
}

/* The p Ritz vectors V[0..nb) Y[:, cols] written over V[0..p), in place, by
 * row chunks. Y is nb x nb column-major, cols are its columns j0..j0+p-1. */
static int ritz_in_place(lanczos *L, int nb, const double *Y, int j0, int p)
{
    enum { CH = 256 };
    double *buf = crom_malloc(sizeof(double) * CH * (size_t)p);
    if (!buf)
        return CROM_EINTERNAL;
    for (int r0 = 0; r0 < L->n; r0 += CH) {
        int rows = L->n - r0 < CH ? L->n - r0 : CH;
        cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, rows, p, nb, 1.0, L->V + r0, L->n,
                    Y + (size_t)j0 * nb, nb, 0.0, buf, rows);
        for (int j = 0; j < p; j++)
            memcpy(L->V + (size_t)j * L->n + r0, buf + (size_t)j * rows, sizeof(double) * (size_t)rows);
    }
    free(buf);
    return 0;
}

/* Grow the basis capacity to mcap columns (keeping V and T). */
static int lanczos_grow(lanczos *L, int mcap)
{
    if (mcap <= L->mcap)
        return 0;
    size_t n = (size_t)L->n;
    double *V = crom_realloc(L->V, sizeof(double) * n * (size_t)(mcap + L->b));
    if (!V)
        return CROM_EINTERNAL;
    L->V = V;
    double *T = crom_calloc((size_t)mcap * mcap, sizeof(double));
    double *H = crom_realloc(L->H, sizeof(double) * (size_t)(mcap + L->b) * L->b);
    if (!T || !H) {
        free(T);
        if (H)
            L->H = H;
        return CROM_EINTERNAL;
    }
    L->H = H;
    for (int j = 0; j < L->mcap; j++)
        memcpy(T + (size_t)j * mcap, L->T + (size_t)j * L->mcap, sizeof(double) * (size_t)L->mcap);
    free(L->T);
    L->T = T;
    L->mcap = mcap;
    return 0;
}

/* Basis size for nev wanted pairs: nev plus room for max(nev, 6 blocks, 30)
 * more (a restart keeps half of that room, so each cycle adds at least three
 * blocks: fewer made clustered spectra stagnate), the whole space when that
 * is nearly as small; `want` (> 0) overrides it. */
static int basis_size(int nev, int b, int n, int want)
{
    if (want > 0)
        return want < nev + 2 * b ? (nev + 2 * b < n ? nev + 2 * b : n) : (want < n ? want : n);
    int room = nev > 6 * b ? nev : 6 * b;
    if (room < 30)
        room = 30;
    long m = (long)nev + room;
    return m + b >= n ? n : (int)m;
}

/* State carried between Rayleigh–Ritz rounds. */
typedef struct {
    int nb;       /* processed basis vectors (T is nb x nb) */
    int bs;       /* size of the next block, at V[nb..] */
    int bl;       /* size of the last processed block (rows of R's columns) */
    double *Y;    /* [mcap mcap] eigenvectors of T */
    double *theta;/* [mcap] its eigenvalues, ascending */
    double *res;  /* [mcap] Ritz residuals ‖A y − θ y‖_M */
} lz_state;

/* Expand the basis block by block up to mmax vectors (or until the space is
 * exhausted), then solve the Rayleigh–Ritz problem. */
static int lanczos_round(lanczos *L, lz_state *S, int mmax)
{
    int n = L->n, rc;
    while (S->bs > 0 && S->nb + S->bs <= mmax) {
        int nb = S->nb, bs = S->bs, tot = nb + bs;
        const double *blk = L->V + (size_t)nb * n;
        /* W = (K − σM)⁻¹ M V_blk, all columns in one solve */
        for (int c = 0; c < bs; c++)
            for (int i = 0; i < n; i++)
                L->MW[(size_t)c * n + i] = L->m[i] * blk[(size_t)c * n + i];
        if ((rc = crom_chol_solve_many(L->chol, bs, L->MW, L->W)))
            return rc;
        L->solves += bs;
        for (int c = 0; c < bs; c++)
            for (int i = 0; i < n; i++)
                L->MW[(size_t)c * n + i] = L->m[i] * L->W[(size_t)c * n + i];
        /* H = V[0..tot)ᵀ M W: the new columns of T */
        cblas_dgemm(CblasColMajor, CblasTrans, CblasNoTrans, tot, bs, n, 1.0, L->V, n, L->MW, n,
                    0.0, L->H, tot);
        double *T = L->T;
        int ld = L->mcap;
        for (int c = 0; c < bs; c++) {
            for (int i = 0; i < nb; i++)
                T[(size_t)(nb + c) * ld + i] = T[(size_t)i * ld + nb + c] = L->H[(size_t)c * tot + i];
            for (int i = 0; i <= c; i++) {
                double a = 0.5 * (L->H[(size_t)c * tot + nb + i] + L->H[(size_t)i * tot + nb + c]);
                T[(size_t)(nb + c) * ld + nb + i] = T[(size_t)(nb + i) * ld + nb + c] = a;
            }
        }
        /* next block: W − V H (the first Gram–Schmidt pass), then orthonormalize */
        double *next = L->V + (size_t)tot * n;
        memcpy(next, L->W, sizeof(double) * (size_t)bs * n);
        cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, n, bs, tot, -1.0, L->V, n, L->H, tot,
                    1.0, next, n);
        int kept = orth_block(L, tot, bs, 1, L->H);
        /* R = V_nextᵀ M W, so that A V_blk = V H + V_next R */
        if (kept)
            cblas_dgemm(CblasColMajor, CblasTrans, CblasNoTrans, kept, bs, n, 1.0, next, n, L->MW, n,
                        0.0, L->R, kept);
        S->nb = tot;
        S->bl = bs;
        S->bs = kept;
    }
    /* Rayleigh–Ritz */
    int nb = S->nb;
    for (int j = 0; j < nb; j++)
        memcpy(S->Y + (size_t)j * nb, L->T + (size_t)j * L->mcap, sizeof(double) * (size_t)nb);
    if (LAPACKE_dsyev(LAPACK_COL_MAJOR, 'V', 'U', nb, S->Y, nb, S->theta) != 0)
        return crom_err(CROM_EINTERNAL, "Lanczos: the Rayleigh-Ritz eigensolve failed");
    for (int j = 0; j < nb; j++) {
        double s = 0;
        for (int i = 0; i < S->bs; i++) {
            double r = 0;
            for (int c = 0; c < S->bl; c++)
                r += L->R[(size_t)c * S->bs + i] * S->Y[(size_t)j * nb + nb - S->bl + c];
            s += r * r;
        }
        S->res[j] = sqrt(s);
    }
    return 0;
}

/* Thick restart: keep the p largest Ritz pairs and the next block. */
static int lanczos_restart(lanczos *L, lz_state *S, int p)
{
    int nb = S->nb, n = L->n;
    int rc = ritz_in_place(L, nb, S->Y, nb - p, p);
    if (rc)
        return rc;
    memmove(L->V + (size_t)p * n, L->V + (size_t)nb * n, sizeof(double) * (size_t)S->bs * n);
    for (int j = 0; j < p; j++) {
        memset(L->T + (size_t)j * L->mcap, 0, sizeof(double) * (size_t)L->mcap);
        L->T[(size_t)j * L->mcap + j] = S->theta[nb - p + j];
    }
    S->nb = p;
    return 0;
}

/* ------------------------------------------------------- rigid modes */

/* Re-express the r0 M-orthonormal rigid modes P (columns of length n,
 * stride ld, at P[j]) in their span as translations x, y, z and rotations
 * about x, y, z (about xc), as far as those lie in it, M-orthonormal. X3 are
 * the rest positions of each free DOF's vertex, comp its coordinate. */
static int canonical_rigid(int n, const double *m, const double *X3, const int *comp,
                           const double xc[3], double *P, int ld, int r0)
{
    double *Q = crom_calloc((size_t)r0 * r0, sizeof(double)), *c = crom_malloc(sizeof(double) * n);
    double *Pn = crom_malloc(sizeof(double) * (size_t)n * r0), *a = crom_malloc(sizeof(double) * r0);
    if (!Q || !c || !Pn || !a) {
        free(Q);
        free(c);
        free(Pn);
        free(a);
        return CROM_EINTERNAL;
    }
    int chosen = 0;
    for (int cand = 0; cand < 6 + r0 && chosen < r0; cand++) {
        double nc = 0;
        if (cand < 6) {
            for (int i = 0; i < n; i++) {
                if (cand < 3)
                    c[i] = comp[i] == cand;
                else {
                    /* (e_axis × (X − xc)) component comp[i] */
                    int ax = cand - 3, k = comp[i];
                    double d[3];
                    for (int t = 0; t < 3; t++)
                        d[t] = X3[3 * (size_t)i + t] - xc[t];
                    double e[3] = {0, 0, 0}, u[3];
                    e[ax] = 1;
                    u[0] = e[1] * d[2] - e[2] * d[1];
                    u[1] = e[2] * d[0] - e[0] * d[2];
                    u[2] = e[0] * d[1] - e[1] * d[0];
                    c[i] = u[k];
                }
                nc += m[i] * c[i] * c[i];
            }
            nc = sqrt(nc);
            for (int j = 0; j < r0; j++) {
                double s = 0;
                for (int i = 0; i < n; i++)
                    s += P[(size_t)j * ld + i] * m[i] * c[i];
                a[j] = s;
            }
        } else { /* complete the span with the computed modes themselves */
            for (int j = 0; j < r0; j++)
                a[j] = j == cand - 6;
            nc = 1;
        }
        if (!(nc > 0))
            continue;
        for (int pass = 0; pass < 2; pass++)
            for (int q = 0; q < chosen; q++) {
                double s = 0;
                for (int j = 0; j < r0; j++)
                    s += Q[(size_t)q * r0 + j] * a[j];
                for (int j = 0; j < r0; j++)
                    a[j] -= s * Q[(size_t)q * r0 + j];
            }
        double na = 0;
        for (int j = 0; j < r0; j++)
            na += a[j] * a[j];
        na = sqrt(na);
        if (na > 0.05 * nc) {
            for (int j = 0; j < r0; j++)
                Q[(size_t)chosen * r0 + j] = a[j] / na;
            chosen++;
        }
    }
    /* P <- P Q */
    for (int q = 0; q < r0; q++)
        for (int i = 0; i < n; i++) {
            double s = 0;
            for (int j = 0; j < r0; j++)
                s += P[(size_t)j * ld + i] * Q[(size_t)q * r0 + j];
            Pn[(size_t)q * n + i] = s;
        }
    for (int q = 0; q < r0; q++)
        memcpy(P + (size_t)q * ld, Pn + (size_t)q * n, sizeof(double) * n);
    free(Q);
    free(c);
    free(Pn);
    free(a);
    return 0;
}

/* ------------------------------------------------------------- driver */

int crom_modes_compute(const crom_mesh *mesh, const crom_material *mat, const unsigned char *fixed,
                       const crom_modes_opts *opt, crom_modes *out)
{
    crom_modes_opts o;
    if (opt)
        o = *opt;
    else
        crom_modes_defaults(&o);
    memset(out, 0, sizeof *out);
    out->next_omega2 = NAN;
    if (o.count < 1)
        return crom_err(CROM_EUSAGE, "the number of modes must be positive, got %d", o.count);
    if (o.block < 1)
        o.block = 6;
    if (!(o.tol > 0))
        o.tol = 1e-10;
    if (!(o.rigid_tol > 0))
        o.rigid_tol = 1e-12;
    if (!isfinite(o.shift) || o.shift > 0)
        return crom_err(CROM_EUSAGE, "the shift must be negative, got %g", o.shift);

    crom_fem fem;
    double t0 = crom_now();
    int rc = crom_fem_init(&fem, mesh, mat);
    if (rc)
        return rc;
    int N = fem.n;
    int *map = NULL, *dof = NULL, *cp = NULL, *ri = NULL, *comp = NULL;
    double *Hval = NULL, *Kf = NULL, *Af = NULL, *mf = NULL, *X3 = NULL, *Phi = NULL;
    lanczos L;
    memset(&L, 0, sizeof L);
    lz_state S;
    memset(&S, 0, sizeof S);
    Hval = crom_malloc(sizeof(double) * (size_t)fem.nnz);
    map = crom_malloc(sizeof(int) * (size_t)N);
    if (!Hval || !map) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    /* the unprojected Hessian at rest, no mass, no fixed DOFs */
    crom_fem_opts fo = {0, 0, NULL, o.nthreads};
    if ((rc = crom_fem_assemble(&fem, mesh->X, &fo, NULL, NULL, Hval)))
        goto out;
    /* free DOFs: not fixed and on some tet */
    int nf = 0, whole = 1;
    for (int d = 0; d < N; d++) {
        int f = !(fixed && fixed[d]) && fem.mass[d / 3] > 0;
        map[d] = f ? nf++ : -1;
    }
    for (int v = 0; v < fem.nv && whole; v++)
        whole = (map[3 * v] < 0) == (map[3 * v + 1] < 0) && (map[3 * v] < 0) == (map[3 * v + 2] < 0);
    out->n = N;
    out->nfree = nf;
    if (nf == 0) {
        rc = crom_err(CROM_EUSAGE, "every degree of freedom is pinned: there is nothing to vibrate");
        goto out;
    }
    if (o.count > nf) {
        rc = crom_err(CROM_EUSAGE, "%d modes asked for, but the body has only %d free degrees of freedom",
                      o.count, nf);
        goto out;
    }
    /* the free-DOF system: K_ff (upper CSC) and the masses */
    dof = crom_malloc(sizeof(int) * (size_t)nf);
    cp = crom_calloc((size_t)nf + 1, sizeof(int));
    mf = crom_malloc(sizeof(double) * (size_t)nf);
    X3 = crom_malloc(sizeof(double) * 3 * (size_t)nf);
    comp = crom_malloc(sizeof(int) * (size_t)nf);
    if (!dof || !cp || !mf || !X3 || !comp) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    int nnz = 0;
    for (int c = 0; c < N; c++) {
        if (map[c] < 0)
            continue;
        for (int k = fem.colptr[c]; k < fem.colptr[c + 1]; k++)
            nnz += map[fem.rowind[k]] >= 0;
        cp[map[c] + 1] = nnz;
    }
    ri = crom_malloc(sizeof(int) * (size_t)(nnz ? nnz : 1));
    Kf = crom_malloc(sizeof(double) * (size_t)(nnz ? nnz : 1));
    Af = crom_malloc(sizeof(double) * (size_t)(nnz ? nnz : 1));
    if (!ri || !Kf || !Af) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    double lsum = 0, mtot = 0, xc[3] = {0, 0, 0};
    for (int c = 0, e = 0; c < N; c++) {
        int j = map[c];
        if (j < 0)
            continue;
        dof[j] = c;
        mf[j] = fem.mass[c / 3];
        comp[j] = c % 3;
        memcpy(X3 + 3 * (size_t)j, mesh->X + 3 * (size_t)(c / 3), 3 * sizeof(double));
        for (int k = fem.colptr[c]; k < fem.colptr[c + 1]; k++) {
            int r = map[fem.rowind[k]];
            if (r < 0)
                continue;
            ri[e] = r;
            Kf[e++] = Hval[k];
        }
        double kdd = Kf[cp[j + 1] - 1]; /* the diagonal is last */
        if (!(kdd > 0)) {
            rc = crom_err(CROM_EDATA, "the rest stiffness has a non-positive diagonal at vertex %d", c / 3);
            goto out;
        }
        lsum += kdd / mf[j];
    }
    /* the body's centre of mass (for the canonical rigid rotations) */
    for (int v = 0; v < fem.nv; v++) {
        mtot += fem.mass[v];
        for (int t = 0; t < 3; t++)
            xc[t] += fem.mass[v] * mesh->X[3 * (size_t)v + t];
    }
    for (int t = 0; t < 3; t++)
        xc[t] /= mtot;
    free(Hval);
    Hval = NULL;
    out->lambda_mean = lsum / nf;
    out->rigid_threshold = o.rigid_tol * out->lambda_mean;
    out->t_assemble = crom_now() - t0;

    /* shift: a small fraction of the lowest frequencies' scale E/(ρ D²) */
    double sigma = o.shift;
    if (sigma == 0) {
        double lo[3], hi[3], D2 = 0;
        crom_mesh_bbox(mesh, lo, hi);
        for (int t = 0; t < 3; t++)
            D2 += (hi[t] - lo[t]) * (hi[t] - lo[t]);
        sigma = -0.01 * mat->E / (mat->rho * D2);
    }
    L.chol = crom_chol_analyze(nf, cp, ri, whole ? 3 : 1);
    if (!L.chol) {
        rc = crom_errcode() ? crom_errcode() : CROM_EINTERNAL;
        goto out;
    }
    for (int attempt = 0;; attempt++) {
        memcpy(Af, Kf, sizeof(double) * (size_t)nnz);
        for (int j = 0; j < nf; j++)
            Af[cp[j + 1] - 1] -= sigma * mf[j];
        if (!(rc = crom_chol_factor(L.chol, Af)))
            break;
        if (rc != CROM_EDATA || attempt == 3 || o.shift != 0) {
            if (rc == CROM_EDATA)
                rc = crom_err(CROM_EDATA, "the rest stiffness shifted by %g M is not positive definite "
                                          "(is the mesh valid?)", -sigma);
            goto out;
        }
        sigma *= 10; /* round-off beat a tiny shift: move it further */
    }
    out->sigma = sigma;
    crom_chol_stats(L.chol, &out->t_analyze, &out->t_factor, NULL, NULL, NULL);
    double tl = crom_now();

    /* Lanczos */
    int b = o.block < nf ? o.block : nf;
    int nev = o.count;
    L.n = nf;
    L.m = mf;
    L.b = b;
    crom_rng_seed(&L.rng, o.seed);
    L.W = crom_malloc(sizeof(double) * (size_t)b * nf);
    L.MW = crom_malloc(sizeof(double) * (size_t)b * nf);
    L.R = crom_malloc(sizeof(double) * (size_t)b * b);
    L.tmp = crom_malloc(sizeof(double) * (size_t)nf);
    L.MX = crom_malloc(sizeof(double) * (size_t)b * nf);
    L.nrm = crom_malloc(sizeof(double) * (size_t)b);
    if (!L.W || !L.MW || !L.R || !L.tmp || !L.MX || !L.nrm) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    int mmax = basis_size(nev, b, nf, o.basis);
    if ((rc = lanczos_grow(&L, mmax)))
        goto out;
    S.Y = crom_malloc(sizeof(double) * (size_t)mmax * mmax);
    S.theta = crom_malloc(sizeof(double) * (size_t)mmax);
    S.res = crom_malloc(sizeof(double) * (size_t)mmax);
    if (!S.Y || !S.theta || !S.res) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    for (size_t i = 0; i < (size_t)b * nf; i++)
        L.V[i] = crom_rng_uniform(&L.rng) - 0.5;
    S.bs = orth_block(&L, 0, b, 2, L.H);
    long max_solves = o.max_solves > 0 ? o.max_solves : 200L * (o.count + 6) + 2000;
    int nrigid = 0;
    for (;;) {
        if ((rc = lanczos_round(&L, &S, mmax)))
            goto out;
        int nb = S.nb, conv = 0;
        for (int j = nb - 1; j >= nb - nev && j >= 0; j--)
            if (S.res[j] <= o.tol * fabs(S.theta[j]) || S.bs == 0)
                conv++;
            else
                break;
        if (nb >= nev && conv >= nev) {
            /* rigid modes among the converged: their ω² are ~0 */
            nrigid = 0;
            for (int j = nb - 1; j >= nb - nev; j--)
                nrigid += sigma + 1 / S.theta[j] <= out->rigid_threshold;
            /* all of them, and one deformation mode beyond to be sure */
            int need = o.keep_rigid ? (o.count > nrigid ? o.count : nrigid + 1) : o.count + nrigid;
            if (need > nf && o.keep_rigid)
                need = nf;
            if (need <= nev)
                break;
            if (need > nf) {
                rc = crom_err(CROM_EUSAGE,
                              "%d deformation modes asked for, but the body has only %d (%d free degrees "
                              "of freedom, %d rigid modes)",
                              o.count, nf - nrigid, nf, nrigid);
                goto out;
            }
            nev = need;
            int m2 = basis_size(nev, b, nf, o.basis);
            if (m2 > mmax) {
                double *Y = crom_realloc(S.Y, sizeof(double) * (size_t)m2 * m2);
                if (Y)
                    S.Y = Y;
                double *th = crom_realloc(S.theta, sizeof(double) * (size_t)m2);
                if (th)
                    S.theta = th;
                double *rs = crom_realloc(S.res, sizeof(double) * (size_t)m2);
                if (rs)
                    S.res = rs;
                if (!Y || !th || !rs || (rc = lanczos_grow(&L, m2))) {
                    rc = CROM_EINTERNAL;
                    goto out;
                }
                mmax = m2;
            }
            if (S.bs == 0 || S.nb + S.bs <= mmax)
                continue; /* room left (or the space is spanned): go on */
        }
        if (S.bs == 0) {
            rc = crom_err(CROM_EINTERNAL, "Lanczos: the basis spans the space but %d of %d pairs did not "
                                          "converge", nev - conv, nev);
            goto out;
        }
        if (L.solves > max_solves) {
            rc = crom_err(CROM_EINTERNAL, "Lanczos did not converge: %d of %d modes after %ld solves",
                          conv, nev, L.solves);
            goto out;
        }
        int p = nev + (mmax - nev) / 2;
        if (p > mmax - b)
            p = mmax - b;
        if (p < nev)
            p = nev;
        if (p > nb)
            p = nb;
        if ((rc = lanczos_restart(&L, &S, p)))
            goto out;
        out->restarts++;
    }
    out->solves = L.solves;
    out->basis_max = mmax;
    crom_chol_stats(L.chol, NULL, NULL, &out->t_solve, NULL, NULL);

    /* the wanted Ritz vectors, ascending ω² */
    int nb = S.nb, skip = o.keep_rigid ? 0 : nrigid, k = o.count;
    Phi = crom_malloc(sizeof(double) * (size_t)nf * k);
    out->omega2 = crom_malloc(sizeof(double) * (size_t)k);
    out->freq = crom_malloc(sizeof(double) * (size_t)k);
    out->residual = crom_malloc(sizeof(double) * (size_t)k);
    out->phi = crom_calloc((size_t)N * k, sizeof(double));
    if (!Phi || !out->omega2 || !out->freq || !out->residual || !out->phi) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    /* column nb-1-j of Y is the j-th smallest ω² */
    for (int j = 0; j < k; j++)
        cblas_dgemv(CblasColMajor, CblasNoTrans, nf, nb, 1.0, L.V, nf,
                    S.Y + (size_t)(nb - 1 - skip - j) * nb, 1, 0.0, Phi + (size_t)j * nf, 1);
    for (int j = 0; j < k; j++)
        out->omega2[j] = sigma + 1 / S.theta[nb - 1 - skip - j];
    if (nb - 1 - skip - k >= 0)
        out->next_omega2 = sigma + 1 / S.theta[nb - 1 - skip - k];
    out->nrigid = nrigid;
    out->rigid_kept = o.keep_rigid && nrigid > 0;
    int nr = o.keep_rigid ? (nrigid < k ? nrigid : k) : 0;
    if (nr > 0) {
        /* the rigid block: all nrigid of them (even beyond k), canonical */
        double *P = crom_malloc(sizeof(double) * (size_t)nf * nrigid);
        if (!P) {
            rc = CROM_EINTERNAL;
            goto out;
        }
        for (int j = 0; j < nrigid; j++)
            cblas_dgemv(CblasColMajor, CblasNoTrans, nf, nb, 1.0, L.V, nf, S.Y + (size_t)(nb - 1 - j) * nb,
                        1, 0.0, P + (size_t)j * nf, 1);
        rc = canonical_rigid(nf, mf, X3, comp, xc, P, nf, nrigid);
        if (!rc)
            memcpy(Phi, P, sizeof(double) * (size_t)nf * nr);
        free(P);
        if (rc)
            goto out;
    }
    /* M-normalize (already so up to round-off), sign, residuals, scatter */
    crom_sym K = {nf, cp, ri, Kf};
    double *kx = crom_malloc(sizeof(double) * (size_t)nf);
    if (!kx) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    for (int j = 0; j < k; j++) {
        double *x = Phi + (size_t)j * nf;
        double s = 0;
        for (int i = 0; i < nf; i++)
            s += mf[i] * x[i] * x[i];
        s = 1 / sqrt(s);
        int big = 0;
        for (int i = 0; i < nf; i++) {
            x[i] *= s;
            if (fabs(x[i]) > fabs(x[big]))
                big = i;
        }
        if (x[big] < 0)
            for (int i = 0; i < nf; i++)
                x[i] = -x[i];
        crom_sym_matvec(&K, x, kx);
        double lam = out->omega2[j], rn = 0, kn = 0, mn = 0;
        for (int i = 0; i < nf; i++) {
            double r = kx[i] - lam * mf[i] * x[i];
            rn += r * r;
            kn += kx[i] * kx[i];
            mn += mf[i] * mf[i] * x[i] * x[i];
        }
        int rigid = j < nr;
        out->residual[j] = rigid ? sqrt(rn) / (out->lambda_mean * sqrt(mn)) : sqrt(rn) / sqrt(kn);
        out->freq[j] = sqrt(lam > 0 ? lam : 0) / (2 * M_PI);
        for (int i = 0; i < nf; i++)
            out->phi[(size_t)dof[i] * k + j] = x[i];
    }
    free(kx);
    out->k = k;
    out->t_lanczos = crom_now() - tl;
out:
    if (rc) {
        crom_modes_free(out);
        out->next_omega2 = NAN;
    }
    crom_chol_free(L.chol);
    free(L.V);
    free(L.T);
    free(L.W);
    free(L.MW);
    free(L.H);
    free(L.R);
    free(L.tmp);
    free(L.MX);
    free(L.nrm);
    free(S.Y);
    free(S.theta);
    free(S.res);
    free(Phi);
    free(Hval);
    free(map);
    free(dof);
    free(cp);
    free(ri);
    free(Kf);
    free(Af);
    free(mf);
    free(X3);
    free(comp);
    crom_fem_free(&fem);
    return rc;
}
