/* modes.c — linear vibration modes, the lowest eigenpairs of K φ = λ M φ
 * at rest (the "linear modes" of modal analysis that Neural Modes, Wang et
 * al. 2024, §1–2, start from): ARPACK's implicitly restarted Lanczos
 * iteration in shift-invert mode on one CHOLMOD factor of K − σM, in the
 * M-orthogonal complement of the rigid motions, which are built rather
 * than searched for (see modes.h). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <arpack/arpack.h>
#include <cblas.h>
#include <lapacke.h>

#include "base/clock.h"
#include "base/err.h"
#include "base/rng.h"
#include "phys/modes.h"
#include "phys/system.h"
#include "phys/chol.h"

void crom_modes_defaults(crom_modes_opts *o)
{
    memset(o, 0, sizeof *o);
    o->count = 20;
    o->tol = 1e-10;
    o->rigid_tol = 1e-12;
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
    for (int v = 0; m->plane && v < m->nv; v++) /* a 2-D solid: every z held (not counted as pinned) */
        f[3 * (size_t)v + 2] = 1;
    *fixed = f;
    *npinned = c;
    return 0;
}

int crom_modes_scenario_pins(const crom_mesh *m, const crom_scenario *sc, unsigned char **fixed, int *npinned)
{
    const char *refs[CROM_SCENARIO_MAX];
    for (int i = 0; i < sc->npins; i++)
        refs[i] = sc->pins[i];
    return crom_modes_pins(m, sc->npins, refs, fixed, npinned);
}

/* ------------------------------------------------------- rigid motions */

/* Rigid motion a at a DOF (coordinate k of the vertex at X): a < 3 the unit
 * translation along axis a, a >= 3 the infinitesimal rotation
 * e_{a−3} × (X − c) about the point c, divided by len. */
static double rigid_motion(int a, const double X[3], int k, const double c[3], double len)
{
    if (a < 3)
        return k == a;
    int ax = a - 3;
    double d[3] = {X[0] - c[0], X[1] - c[1], X[2] - c[2]};
    /* e_x × d = (0, −d_z, d_y), and cyclically */
    if (k == (ax + 1) % 3)
        return -d[(ax + 2) % 3] / len;
    if (k == (ax + 2) % 3)
        return d[(ax + 1) % 3] / len;
    return 0;
}

/* The parent of v in a union-find forest, with path halving. */
static int uf_root(int *parent, int v)
{
    while (parent[v] != v)
        v = parent[v] = parent[parent[v]];
    return v;
}

/* The connected pieces of a mesh (vertices joined by elements) and the rigid
 * motions the pins leave each of them. */
typedef struct {
    int np;             /* pieces */
    int *piece;         /* [nv] the piece of each vertex, −1: on no tet */
    double *c;          /* [np][5] centre of mass (3), radius of gyration, mass */
    double *G;          /* [np][6][6] the constraints' Gram matrix, then its eigenvectors */
    int *nnull, *first; /* [np] motions each piece admits; [np + 1] the index of its first */
} pieces;

static void pieces_free(pieces *pc)
{
    free(pc->piece);
    free(pc->c);
    free(pc->G);
    free(pc->nnull);
    free(pc->first);
}

/* The pieces, by union-find over the elements (tets, or a shell's
 * triangles); piece[v] numbered at the piece's root, in vertex order. */
static int find_pieces(const crom_mesh *mesh, const crom_system *fem, pieces *pc)
{
    int nv = fem->nv;
    int *root = crom_malloc(sizeof(int) * (size_t)nv);
    pc->piece = crom_malloc(sizeof(int) * (size_t)nv);
    if (!root || !pc->piece) {
        free(root);
        return CROM_EINTERNAL;
    }
    for (int v = 0; v < nv; v++)
        root[v] = v;
    int pe = fem->per_elem;
    for (int t = 0; t < fem->nelem; t++)
        for (int a = 1; a < pe; a++) {
            int r0 = uf_root(root, fem->elem[pe * (size_t)t]), r1 = uf_root(root, fem->elem[pe * (size_t)t + a]);
            if (r0 != r1)
                root[r1] = r0;
        }
    int *piece = pc->piece;
    for (int v = 0; v < nv; v++)
        piece[v] = -1;
    for (int v = 0; v < nv; v++)
        if (fem->mass[v] > 0) {
            int r = uf_root(root, v);
            if (piece[r] < 0)
                piece[r] = pc->np++;
            piece[v] = piece[r];
        }
    free(root);
    return 0;
}

/* Per piece: its centre of mass, radius of gyration (the rotations'
 * scale) and mass into c. */
static int piece_frames(const crom_mesh *mesh, const crom_system *fem, pieces *pc)
{
    int nv = fem->nv, np = pc->np;
    const int *piece = pc->piece;
    double *c = pc->c = crom_calloc(5 * (size_t)np, sizeof(double));
    if (!c)
        return CROM_EINTERNAL;
    for (int v = 0; v < nv; v++)
        if (piece[v] >= 0) {
            double *ck = c + 5 * (size_t)piece[v];
            for (int t = 0; t < 3; t++)
                ck[t] += fem->mass[v] * mesh->X[3 * (size_t)v + t];
            ck[4] += fem->mass[v];
        }
    for (int p = 0; p < np; p++)
        for (int t = 0; t < 3; t++)
            c[5 * (size_t)p + t] /= c[5 * (size_t)p + 4];
    for (int v = 0; v < nv; v++)
        if (piece[v] >= 0) {
            double *ck = c + 5 * (size_t)piece[v];
            for (int t = 0; t < 3; t++)
                ck[3] += fem->mass[v] * (mesh->X[3 * (size_t)v + t] - ck[t]) * (mesh->X[3 * (size_t)v + t] - ck[t]);
        }
    for (int p = 0; p < np; p++)
        c[5 * (size_t)p + 3] = sqrt(c[5 * (size_t)p + 3] / c[5 * (size_t)p + 4]);
    return 0;
}

/* Per piece: the Gram matrix Gᵀ G of the six generators' values at its
 * fixed DOFs, and its null space: its eigenvectors (columns of the
 * row-major G after dsyev, ascending) of eigenvalue below 1e-9 of the
 * largest, nnull of them, numbered from first. */
static int piece_freedoms(const crom_mesh *mesh, const unsigned char *fixed, int nv, pieces *pc)
{
    int np = pc->np;
    const int *piece = pc->piece;
    const double *c = pc->c;
    double *G = pc->G = crom_calloc(36 * (size_t)np, sizeof(double));
    pc->nnull = crom_calloc((size_t)np, sizeof(int));
    pc->first = crom_calloc((size_t)np + 1, sizeof(int));
    if (!G || !pc->nnull || !pc->first)
        return CROM_EINTERNAL;
    for (int d = 0; fixed && d < 3 * nv; d++) {
        int p = piece[d / 3];
        if (!fixed[d] || p < 0)
            continue;
        const double *ck = c + 5 * (size_t)p;
        double g[6];
        for (int a = 0; a < 6; a++)
            g[a] = rigid_motion(a, mesh->X + 3 * (size_t)(d / 3), d % 3, ck, ck[3]);
        for (int a = 0; a < 6; a++)
            for (int b = 0; b < 6; b++)
                G[36 * (size_t)p + 6 * a + b] += g[a] * g[b];
    }
    for (int p = 0; p < np; p++) {
        double w[6], *Gp = G + 36 * (size_t)p;
        if (LAPACKE_dsyev(LAPACK_ROW_MAJOR, 'V', 'U', 6, Gp, 6, w) != 0)
            return crom_err(CROM_EINTERNAL, "LAPACK dsyev failed on the pins' rigid constraints");
        while (pc->nnull[p] < 6 && w[pc->nnull[p]] <= 1e-9 * w[5])
            pc->nnull[p]++;
        pc->first[p + 1] = pc->first[p] + pc->nnull[p];
    }
    return 0;
}

int crom_modes_orthonormalize(double *V, int n, int ncol, const double *m, int keep)
{
    int kept = 0;
    for (int c = 0; c < ncol; c++) {
        double *v = V + (size_t)c * n, before = 0, after = 0;
        for (int d = 0; d < n; d++)
            before += m[d] * v[d] * v[d];
        for (int pass = 0; pass < 2; pass++)
            for (int j = 0; j < kept; j++) {
                const double *u = V + (size_t)j * n;
                double dot = 0;
                for (int d = 0; d < n; d++)
                    dot += m[d] * u[d] * v[d];
                for (int d = 0; d < n; d++)
                    v[d] -= dot * u[d];
            }
        for (int d = 0; d < n; d++)
            after += m[d] * v[d] * v[d];
        if (!(after > 1e-16 * before) || !(after > 0)) {
            if (c < keep)
                return -1;
            continue;
        }
        double s = 1 / sqrt(after);
        double *dst = V + (size_t)kept * n;
        for (int d = 0; d < n; d++)
            dst[d] = s * v[d];
        kept++;
    }
    return kept;
}

/* The columns of R [nr][n] M-orthonormal (masses mf) within each piece
 * (the pieces' columns are disjoint). */
static int m_orthonormalize(double *R, int n, const double *mf, const pieces *pc)
{
    for (int p = 0; p < pc->np; p++) {
        int k = pc->first[p + 1] - pc->first[p];
        if (crom_modes_orthonormalize(R + (size_t)pc->first[p] * n, n, k, mf, k) < 0)
            return crom_err(CROM_EINTERNAL, "a rigid motion allowed by the pins vanishes on the free DOFs");
    }
    return 0;
}

/* The rigid motions the pins leave free, as nr M-orthonormal columns R
 * [nr][n] on the n free DOFs (dof[j] their global index, mf their masses).
 * Each connected piece of the mesh (vertices joined by elements) moves as
 * u(X) = t + ω × (X − c), c its centre of mass: the six parameters (t, ω)
 * that make u vanish on the piece's fixed DOFs are the null space of the
 * 6×6 matrix Gᵀ G, G holding the six generators' values at those DOFs (its
 * eigenvalues below 1e-9 of the largest count as zero). Their motions on the
 * free DOFs are M-orthonormalized by Gram–Schmidt, twice. A free body gets
 * six, one pinned at a vertex the three rotations about it, one pinned
 * along a line the rotation about the line, each further free piece six. */
static int rigid_basis(const crom_mesh *mesh, const crom_system *fem, const unsigned char *fixed, int n,
                       const int *dof, const double *mf, double **Rout, int *nrout)
{
    pieces pc;
    memset(&pc, 0, sizeof pc);
    double *R = NULL;
    *Rout = NULL;
    *nrout = 0;
    int rc = find_pieces(mesh, fem, &pc);
    if (!rc)
        rc = piece_frames(mesh, fem, &pc);
    if (!rc)
        rc = piece_freedoms(mesh, fixed, fem->nv, &pc);
    int nr = rc ? 0 : pc.first[pc.np];
    if (nr > 0 && !(R = crom_calloc((size_t)n * nr, sizeof(double))))
        rc = CROM_EINTERNAL;
    /* each piece's admitted motions, on its free DOFs */
    for (int j = 0; !rc && j < n && nr > 0; j++) {
        int v = dof[j] / 3, p = pc.piece[v];
        const double *ck = pc.c + 5 * (size_t)p, *Gp = pc.G + 36 * (size_t)p;
        for (int a = 0; a < 6; a++) {
            double g = rigid_motion(a, mesh->X + 3 * (size_t)v, dof[j] % 3, ck, ck[3]);
            for (int q = 0; q < pc.nnull[p]; q++)
                R[(size_t)(pc.first[p] + q) * n + j] += Gp[6 * a + q] * g;
        }
    }
    if (!rc)
        rc = m_orthonormalize(R, n, mf, &pc);
    pieces_free(&pc);
    if (rc) {
        free(R);
        return rc;
    }
    *Rout = R;
    *nrout = nr;
    return 0;
}

int crom_modes_rigid(const crom_mesh *mesh, const crom_system *sys, const unsigned char *fixed, double **R,
                     int *nr)
{
    int n = sys->n, nf = 0, rc;
    *R = NULL;
    *nr = 0;
    int *dof = crom_malloc(sizeof(int) * (size_t)n);
    double *mf = crom_malloc(sizeof(double) * (size_t)n), *Rf = NULL;
    if (!dof || !mf) {
        free(dof), free(mf);
        return CROM_EINTERNAL;
    }
    for (int i = 0; i < n; i++)
        if (!(fixed && fixed[i]) && sys->mass[i / 3] > 0) {
            dof[nf] = i;
            mf[nf++] = sys->mass[i / 3];
        }
    int k = 0;
    if (!(rc = rigid_basis(mesh, sys, fixed, nf, dof, mf, &Rf, &k)) && k > 0) {
        if (!(*R = crom_calloc((size_t)n * k, sizeof(double))))
            rc = CROM_EINTERNAL;
        for (int q = 0; !rc && q < k; q++) /* Rf: column q over the free DOFs at Rf[q nf + j] */
            for (int j = 0; j < nf; j++)
                (*R)[(size_t)dof[j] * k + q] = Rf[(size_t)q * nf + j];
        if (!rc)
            *nr = k;
    }
    free(dof), free(mf), free(Rf);
    return rc;
}

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
                c[i] = rigid_motion(cand, X3 + 3 * (size_t)i, comp[i], xc, 1);
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

/* ------------------------------------------------------------ eigensolves */

/* The eigenproblem on the free DOFs: the masses, the factor of K − σM, and
 * the rigid motions to keep out of it. */
typedef struct {
    int n;             /* free DOFs */
    const double *m;   /* [n] lumped mass of each free DOF */
    crom_chol *chol;   /* factor of K − σM */
    int nr;            /* rigid motions */
    const double *R;   /* [nr][n] M-orthonormal columns */
    double *mx, *h;    /* scratch: [n] and [nr] */
    long solves;       /* solves with the factor */
} eigprob;

/* x ← (I − R Rᵀ M) x, the part of x M-orthogonal to the rigid motions. */
static void project_rigid(eigprob *P, double *x)
{
    if (P->nr == 0)
        return;
    for (int i = 0; i < P->n; i++)
        P->mx[i] = P->m[i] * x[i];
    cblas_dgemv(CblasColMajor, CblasTrans, P->n, P->nr, 1.0, P->R, P->n, P->mx, 1, 0.0, P->h, 1);
    cblas_dgemv(CblasColMajor, CblasNoTrans, P->n, P->nr, -1.0, P->R, P->n, P->h, 1, 1.0, x, 1);
}

/* What dsaupd's and dseupd's error codes mean (ARPACK's documentation). */
static const char *arpack_info(int info)
{
    switch (info) {
    case 1: return "the maximum number of iterations was taken";
    case 3: return "no shifts could be applied during an implicit restart (more Lanczos vectors may help)";
    case -8: return "the tridiagonal eigensolve failed";
    case -9: return "the start vector is zero";
    case -14: return "no Ritz value converged";
    case -17: return "dseupd counted a different number of converged Ritz values than dsaupd";
    case -9999: return "no Lanczos factorization could be built";
    default: return info < 0 ? "a bad argument" : "an unexpected status";
    }
}

/* The nev eigenpairs of K φ = λ M φ nearest above σ in the M-orthogonal
 * complement of the rigid motions, by ARPACK's implicitly restarted Lanczos
 * iteration (dsaupd, then dseupd for the vectors) in its generalized
 * shift-invert mode 3: OP = (K − σM)⁻¹ M, self-adjoint in the M inner
 * product B = M, whose largest eigenvalues θ = 1/(λ − σ) ("LM") are the
 * lowest λ. The start vector (uniform from seed) and every OP x are
 * projected with I − R Rᵀ M, so no rigid motion (θ = −1/σ, the largest)
 * enters the Krylov space and each copy of a repeated λ is one ARPACK must
 * find by itself, with ncv Lanczos vectors and residuals
 * ‖OP y − θ y‖_M <= tol·θ. lam gets λ ascending, Y [nev][n] the
 * M-orthonormal eigenvectors, *iters ARPACK's restart count. CROM_EINTERNAL
 * after max_solves solves or when ARPACK fails. ARPACK keeps its state in
 * Fortran SAVE variables: one call at a time per process. */
static int arpack_lowest(eigprob *P, int nev, int ncv, double sigma, double tol, long max_solves,
                         uint64_t seed, double *lam, double *Y, int *iters)
{
    int n = P->n, lworkl = ncv * (ncv + 8), rc = 0;
    double *resid = crom_malloc(sizeof(double) * (size_t)n), *V = crom_malloc(sizeof(double) * (size_t)n * ncv);
    double *workd = crom_malloc(sizeof(double) * 3 * (size_t)n), *workl = crom_malloc(sizeof(double) * (size_t)lworkl);
    double *d = crom_malloc(sizeof(double) * (size_t)nev), *Z = crom_malloc(sizeof(double) * (size_t)n * nev);
    int *sel = crom_calloc((size_t)ncv, sizeof(int)), *order = crom_malloc(sizeof(int) * (size_t)nev);
    if (!resid || !V || !workd || !workl || !d || !Z || !sel || !order) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    crom_rng rng;
    crom_rng_seed(&rng, seed);
    for (int i = 0; i < n; i++)
        resid[i] = crom_rng_uniform(&rng) - 0.5;
    project_rigid(P, resid);
    int ido = 0, info = 1, iparam[11] = {0}, ipntr[14] = {0};
    iparam[0] = 1;       /* exact shifts */
    iparam[2] = 1000000; /* iterations: max_solves is the limit */
    iparam[6] = 3;       /* shift-invert */
    for (;;) {
        dsaupd_c(&ido, "G", n, "LM", nev, tol, resid, ncv, V, n, iparam, ipntr, workd, workl, lworkl, &info);
        if (ido == 99 || info < 0)
            break;
        const double *x = workd + ipntr[0] - 1;
        double *y = workd + ipntr[1] - 1;
        if (ido == 2) { /* y = M x */
            for (int i = 0; i < n; i++)
                y[i] = P->m[i] * x[i];
            continue;
        }
        if (ido != -1 && ido != 1) {
            rc = crom_err(CROM_EINTERNAL, "ARPACK dsaupd asked for operation %d", ido);
            goto out;
        }
        if (P->solves >= max_solves) {
            rc = crom_err(CROM_EINTERNAL, "ARPACK dsaupd did not converge to %d modes within %ld solves "
                                          "(%d Lanczos vectors)", nev, P->solves, ncv);
            goto out;
        }
        /* y = (K − σM)⁻¹ M x; ido 1 hands M x over at ipntr[2] */
        const double *mx = P->mx;
        if (ido == 1)
            mx = workd + ipntr[2] - 1;
        else
            for (int i = 0; i < n; i++)
                P->mx[i] = P->m[i] * x[i];
        if ((rc = crom_chol_solve(P->chol, mx, y)))
            goto out;
        P->solves++;
        project_rigid(P, y);
    }
    if (info != 0) {
        rc = crom_err(CROM_EINTERNAL, "ARPACK dsaupd failed with info %d: %s (%d modes, %d Lanczos vectors)",
                      info, arpack_info(info), nev, ncv);
        goto out;
    }
    *iters = iparam[2];
    dseupd_c(1, "A", sel, d, Z, n, sigma, "G", n, "LM", nev, tol, resid, ncv, V, n, iparam, ipntr, workd,
             workl, lworkl, &info);
    if (info != 0 || iparam[4] < nev) {
        rc = crom_err(CROM_EINTERNAL, "ARPACK dseupd failed with info %d: %s (%d of %d modes)", info,
                      arpack_info(info), iparam[4], nev);
        goto out;
    }
    /* ascending λ (dseupd's order is its own) */
    for (int j = 0; j < nev; j++) {
        int i = j;
        for (; i > 0 && d[order[i - 1]] > d[j]; i--)
            order[i] = order[i - 1];
        order[i] = j;
    }
    for (int j = 0; j < nev; j++) {
        lam[j] = d[order[j]];
        memcpy(Y + (size_t)j * n, Z + (size_t)order[j] * n, sizeof(double) * (size_t)n);
        project_rigid(P, Y + (size_t)j * n);
    }
out:
    free(resid);
    free(V);
    free(workd);
    free(workl);
    free(d);
    free(Z);
    free(sel);
    free(order);
    return rc;
}

/* Free DOFs up to which a dense eigensolve stands in for ARPACK. */
enum { DENSE_MAX = 3000 };

/* The same nev pairs from a dense eigensolve (LAPACK dsyevr), for when they
 * are every mode of the complement, which ARPACK cannot give (it needs
 * nev < ncv <= its dimension): C = M^−½ K M^−½, with the rigid directions
 * Q = M^½ R moved above its spectrum, (I − QQᵀ) C (I − QQᵀ) + s QQᵀ with
 * s = 1 + max row sum of |C| > ‖C‖₂; its lowest eigenvectors z give
 * φ = M^−½ z. */
static int dense_lowest(const crom_sym *K, eigprob *P, int nev, double *lam, double *Y)
{
    int n = P->n, nr = P->nr, found = 0, rc = 0;
    if (n > DENSE_MAX)
        return crom_err(CROM_EUSAGE, "every deformation mode asked for: that takes a dense eigensolve, done "
                                     "up to %d free degrees of freedom (the body has %d)", DENSE_MAX, n);
    double *C = crom_calloc((size_t)n * n, sizeof(double)), *scale = crom_malloc(sizeof(double) * (size_t)n);
    double *Q = crom_malloc(sizeof(double) * ((size_t)n * nr + 1)), *W = crom_malloc(sizeof(double) * ((size_t)n * nr + 1));
    double *B = crom_malloc(sizeof(double) * ((size_t)nr * nr + 1)), *w = crom_malloc(sizeof(double) * (size_t)n);
    int *isuppz = crom_malloc(sizeof(int) * 2 * (size_t)n);
    if (!C || !scale || !Q || !W || !B || !w || !isuppz) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    for (int i = 0; i < n; i++)
        scale[i] = 1 / sqrt(P->m[i]);
    double shift = 0;
    for (int j = 0; j < n; j++)
        for (int k = K->colptr[j]; k < K->colptr[j + 1]; k++) {
            int i = K->rowind[k];
            C[(size_t)j * n + i] = C[(size_t)i * n + j] = K->val[k] * scale[i] * scale[j];
        }
    for (int j = 0; j < n; j++) {
        double rs = 0;
        for (int i = 0; i < n; i++)
            rs += fabs(C[(size_t)j * n + i]);
        shift = fmax(shift, rs);
    }
    shift = 1 + shift;
    if (nr > 0) {
        for (int q = 0; q < nr; q++)
            for (int i = 0; i < n; i++)
                Q[(size_t)q * n + i] = P->R[(size_t)q * n + i] / scale[i];
        /* W = C Q, B = Qᵀ W + s I; C ← C − Q Wᵀ − W Qᵀ + Q B Qᵀ (upper triangle) */
        cblas_dsymm(CblasColMajor, CblasLeft, CblasUpper, n, nr, 1.0, C, n, Q, n, 0.0, W, n);
        cblas_dgemm(CblasColMajor, CblasTrans, CblasNoTrans, nr, nr, n, 1.0, Q, n, W, n, 0.0, B, nr);
        for (int q = 0; q < nr; q++)
            B[(size_t)q * nr + q] += shift;
        cblas_dsyr2k(CblasColMajor, CblasUpper, CblasNoTrans, n, nr, -1.0, Q, n, W, n, 1.0, C, n);
        cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, n, nr, nr, 1.0, Q, n, B, nr, 0.0, W, n);
        cblas_dgemm(CblasColMajor, CblasNoTrans, CblasTrans, n, n, nr, 1.0, W, n, Q, n, 1.0, C, n);
    }
    if (LAPACKE_dsyevr(LAPACK_COL_MAJOR, 'V', 'I', 'U', n, C, n, 0, 0, 1, nev, 0, &found, w, Y, n, isuppz) != 0 ||
        found != nev) {
        rc = crom_err(CROM_EINTERNAL, "LAPACK dsyevr failed on the dense %d x %d eigenproblem", n, n);
        goto out;
    }
    for (int j = 0; j < nev; j++) {
        lam[j] = w[j];
        for (int i = 0; i < n; i++)
            Y[(size_t)j * n + i] *= scale[i];
        project_rigid(P, Y + (size_t)j * n);
    }
out:
    free(C);
    free(scale);
    free(Q);
    free(W);
    free(B);
    free(w);
    free(isuppz);
    return rc;
}

/* Lanczos vectors for nev pairs in a space of dimension nc: max(2 nev + 1,
 * nev + 20), or basis if larger, at most nc. */
static int lanczos_size(int nev, int basis, int nc)
{
    int ncv = 2 * nev + 1 > nev + 20 ? 2 * nev + 1 : nev + 20;
    if (basis > ncv)
        ncv = basis;
    return ncv < nc ? ncv : nc;
}

/* Fill in the copies of repeated eigenvalues that ARPACK missed among the
 * nev pairs lam, Y it found. A single-vector Krylov space holds one
 * direction of each eigenspace; round-off has to bring in the others, and
 * the iteration may converge first (one start vector in 40 on a square
 * beam). So the lowest pair of the complement of the rigid motions and of
 * all nev found ones is computed from another start vector: a missed copy
 * is there, below the largest found λ, and takes its place (the largest
 * goes); this repeats until the complement has nothing below. */
static int fill_missed(eigprob *P, const crom_modes_opts *o, double sigma, long max_solves, int nev,
                       double *lam, double *Y)
{
    int n = P->n, nr = P->nr, nc = n - nr - nev, rc = 0, iters;
    if (nc < 2)
        return 0; /* ARPACK needs nev < ncv <= nc */
    double *RF = crom_malloc(sizeof(double) * (size_t)n * (nr + nev)), *h = crom_malloc(sizeof(double) * (size_t)(nr + nev));
    double *y = crom_malloc(sizeof(double) * (size_t)n);
    if (!RF || !h || !y) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    for (int round = 0; round < nev; round++) {
        if (nr > 0)
            memcpy(RF, P->R, sizeof(double) * (size_t)n * nr);
        memcpy(RF + (size_t)n * nr, Y, sizeof(double) * (size_t)n * nev);
        eigprob Q = {n, P->m, P->chol, nr + nev, RF, P->mx, h, 0};
        double mu;
        rc = arpack_lowest(&Q, 1, lanczos_size(1, 0, nc), sigma, o->tol, max_solves - P->solves,
                           o->seed + 1 + (uint64_t)round, &mu, y, &iters);
        P->solves += Q.solves;
        if (rc || !(mu < lam[nev - 1] - 1e-9 * fabs(lam[nev - 1])))
            break;
        int j = nev - 1;
        for (; j > 0 && lam[j - 1] > mu; j--) {
            lam[j] = lam[j - 1];
            memcpy(Y + (size_t)j * n, Y + (size_t)(j - 1) * n, sizeof(double) * (size_t)n);
        }
        lam[j] = mu;
        memcpy(Y + (size_t)j * n, y, sizeof(double) * (size_t)n);
    }
out:
    free(RF);
    free(h);
    free(y);
    return rc;
}

/* The nev lowest pairs of the complement of the rigid motions (nc = n − nr
 * its dimension) into lam[nev] and Y[nev][n]: ARPACK, then the check for
 * missed copies; a dense solve when nev is all of them. */
static int lowest_modes(eigprob *P, const crom_sym *K, const crom_modes_opts *o, double sigma, int nev,
                        double *lam, double *Y, crom_modes *out)
{
    int nc = P->n - P->nr;
    if (nev >= nc) {
        out->basis_max = nc;
        return dense_lowest(K, P, nev, lam, Y);
    }
    int ncv = lanczos_size(nev, o->basis, nc);
    long max_solves = o->max_solves > 0 ? o->max_solves : 200L * (o->count + 6) + 2000;
    out->basis_max = ncv;
    int rc = arpack_lowest(P, nev, ncv, sigma, o->tol, max_solves, o->seed, lam, Y, &out->restarts);
    return rc ? rc : fill_missed(P, o, sigma, max_solves, nev, lam, Y);
}

/* ------------------------------------------------------------- driver */

/* One crom_modes_compute: the operator, the free-DOF system (K_ff at rest
 * in upper CSC, the masses), its shifted factor, the rigid motions, the
 * lowest pairs of their complement and the result's modes on the free
 * DOFs. */
typedef struct {
    crom_modes_opts o;
    crom_system fem;  /* the solid or shell */
    int nf, nnz;      /* free DOFs; entries of K_ff */
    int whole;        /* each vertex has all of its DOFs free or none */
    int *dof, *comp;  /* [nf] global index and coordinate of each free DOF */
    int *cp, *ri;     /* K_ff's pattern */
    double *Kf, *Af;  /* [nnz] K_ff, and K_ff − σM for the factor */
    double *mf, *X3;  /* [nf] masses; [nf][3] rest position of each free DOF's vertex */
    double xc[3];     /* the body's centre of mass */
    crom_chol *chol;  /* the factor of K_ff − σM */
    double sigma;
    double *R;        /* [nr][nf] the rigid motions the pins leave free */
    int nr;
    eigprob P;
    double *lam, *Y;  /* [have], [have][nf] the lowest pairs of the complement */
    int have, z;      /* pairs found; the zero-energy ones among them */
    int nkr;          /* rigid modes among the result's */
    double *Phi;      /* the result's modes on the free DOFs */
} modesrun;

static void modesrun_free(modesrun *M)
{
    crom_chol_free(M->chol);
    free(M->P.mx);
    free(M->P.h);
    free(M->R);
    free(M->lam);
    free(M->Y);
    free(M->Phi);
    free(M->dof);
    free(M->cp);
    free(M->ri);
    free(M->Kf);
    free(M->Af);
    free(M->mf);
    free(M->X3);
    free(M->comp);
    crom_system_free(&M->fem);
}

/* K_ff (upper CSC: cp, ri, Kf) of the nf free DOFs from the full Hessian
 * Hval (map: DOF -> free index or −1), their masses, coordinates and
 * vertices' rest positions, and the body's centre of mass (for the
 * canonical rigid rotations); out->lambda_mean (mean of K_dd / m_d) and
 * rigid_threshold. CROM_EDATA for a non-positive diagonal. */
static int gather_free(modesrun *M, const crom_mesh *mesh, const int *map, const double *Hval, crom_modes *out)
{
    const crom_system *fem = &M->fem;
    int N = fem->n, nf = M->nf;
    M->dof = crom_malloc(sizeof(int) * (size_t)nf);
    M->cp = crom_calloc((size_t)nf + 1, sizeof(int));
    M->mf = crom_malloc(sizeof(double) * (size_t)nf);
    M->X3 = crom_malloc(sizeof(double) * 3 * (size_t)nf);
    M->comp = crom_malloc(sizeof(int) * (size_t)nf);
    if (!M->dof || !M->cp || !M->mf || !M->X3 || !M->comp)
        return CROM_EINTERNAL;
    int *cp = M->cp, nnz = 0;
    for (int c = 0; c < N; c++) {
        if (map[c] < 0)
            continue;
        for (int k = fem->colptr[c]; k < fem->colptr[c + 1]; k++)
            nnz += map[fem->rowind[k]] >= 0;
        cp[map[c] + 1] = nnz;
    }
    M->nnz = nnz;
    M->ri = crom_malloc(sizeof(int) * (size_t)(nnz ? nnz : 1));
    M->Kf = crom_malloc(sizeof(double) * (size_t)(nnz ? nnz : 1));
    M->Af = crom_malloc(sizeof(double) * (size_t)(nnz ? nnz : 1));
    if (!M->ri || !M->Kf || !M->Af)
        return CROM_EINTERNAL;
    double lsum = 0, mtot = 0, *xc = M->xc;
    for (int c = 0, e = 0; c < N; c++) {
        int j = map[c];
        if (j < 0)
            continue;
        M->dof[j] = c;
        M->mf[j] = fem->mass[c / 3];
        M->comp[j] = c % 3;
        memcpy(M->X3 + 3 * (size_t)j, mesh->X + 3 * (size_t)(c / 3), 3 * sizeof(double));
        for (int k = fem->colptr[c]; k < fem->colptr[c + 1]; k++) {
            int r = map[fem->rowind[k]];
            if (r < 0)
                continue;
            M->ri[e] = r;
            M->Kf[e++] = Hval[k];
        }
        double kdd = M->Kf[cp[j + 1] - 1]; /* the diagonal is last */
        if (!(kdd > 0))
            return crom_err(CROM_EDATA, "the rest stiffness has a non-positive diagonal at vertex %d", c / 3);
        lsum += kdd / M->mf[j];
    }
    for (int v = 0; v < fem->nv; v++) {
        mtot += fem->mass[v];
        for (int t = 0; t < 3; t++)
            xc[t] += fem->mass[v] * mesh->X[3 * (size_t)v + t];
    }
    for (int t = 0; t < 3; t++)
        xc[t] /= mtot;
    out->lambda_mean = lsum / nf;
    out->rigid_threshold = M->o.rigid_tol * out->lambda_mean;
    return 0;
}

/* The free DOFs (not fixed, on some tet) and their system at rest, from
 * the unprojected Hessian (no mass, no fixed DOFs); out->n and nfree.
 * CROM_EUSAGE when nothing is free or fewer DOFs than modes asked for. */
static int free_system(modesrun *M, const crom_mesh *mesh, const unsigned char *fixed, crom_modes *out)
{
    int N = M->fem.n, rc;
    double *Hval = crom_malloc(sizeof(double) * (size_t)M->fem.nnz);
    int *map = crom_malloc(sizeof(int) * (size_t)N);
    if (!Hval || !map) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    crom_fem_opts fo = {0, 0, NULL, M->o.nthreads};
    if ((rc = crom_system_assemble(&M->fem, mesh->X, &fo, NULL, NULL, Hval)))
        goto out;
    int nf = 0, whole = 1;
    for (int d = 0; d < N; d++) {
        int f = !(fixed && fixed[d]) && M->fem.mass[d / 3] > 0;
        map[d] = f ? nf++ : -1;
    }
    for (int v = 0; v < M->fem.nv && whole; v++)
        whole = (map[3 * v] < 0) == (map[3 * v + 1] < 0) && (map[3 * v] < 0) == (map[3 * v + 2] < 0);
    out->n = N;
    out->nfree = nf;
    if (nf == 0) {
        rc = crom_err(CROM_EUSAGE, "every degree of freedom is pinned: there is nothing to vibrate");
        goto out;
    }
    if (M->o.count > nf) {
        rc = crom_err(CROM_EUSAGE, "%d modes asked for, but the body has only %d free degrees of freedom",
                      M->o.count, nf);
        goto out;
    }
    M->nf = nf;
    M->whole = whole;
    rc = gather_free(M, mesh, map, Hval, out);
out:
    free(Hval);
    free(map);
    return rc;
}

/* The factor of K_ff − σM: σ is o.shift or, when 0, a small fraction of
 * the lowest frequencies' scale E/(ρ D²), moved tenfold further (up to
 * three times) when round-off beats it. CROM_EDATA when the shifted
 * stiffness is not positive definite. */
static int factor_shifted(modesrun *M, const crom_mesh *mesh, const crom_material *mat)
{
    int nf = M->nf, rc;
    double sigma = M->o.shift;
    if (sigma == 0) {
        double lo[3], hi[3], D2 = 0;
        crom_mesh_bbox(mesh, lo, hi);
        for (int t = 0; t < 3; t++)
            D2 += (hi[t] - lo[t]) * (hi[t] - lo[t]);
        sigma = -0.01 * mat->E / (mat->rho * D2);
    }
    M->chol = crom_chol_analyze(nf, M->cp, M->ri, M->whole ? 3 : 1);
    if (!M->chol)
        return crom_errcode() ? crom_errcode() : CROM_EINTERNAL;
    for (int attempt = 0;; attempt++) {
        memcpy(M->Af, M->Kf, sizeof(double) * (size_t)M->nnz);
        for (int j = 0; j < nf; j++)
            M->Af[M->cp[j + 1] - 1] -= sigma * M->mf[j];
        if (!(rc = crom_chol_factor(M->chol, M->Af)))
            break;
        if (rc != CROM_EDATA || attempt == 3 || M->o.shift != 0) {
            if (rc == CROM_EDATA)
                rc = crom_err(CROM_EDATA, "the rest stiffness shifted by %g M is not positive definite "
                                          "(is the mesh valid?)", -sigma);
            return rc;
        }
        sigma *= 10; /* round-off beat a tiny shift: move it further */
    }
    M->sigma = sigma;
    return 0;
}

/* The rigid motions, built, and the lowest pairs of their complement, as
 * many as the result needs: o.count deformation modes after the z
 * zero-energy ones among them (dropped), or o.count in all after the
 * nr + z rigid ones (kept); one more to see where the zero block ends and
 * for next_omega2. */
static int lowest_pairs(modesrun *M, const crom_mesh *mesh, const unsigned char *fixed, crom_modes *out)
{
    const crom_modes_opts *o = &M->o;
    int nf = M->nf, rc;
    if ((rc = rigid_basis(mesh, &M->fem, fixed, nf, M->dof, M->mf, &M->R, &M->nr)))
        return rc;
    int nr = M->nr;
    M->P = (eigprob){nf, M->mf, M->chol, nr, M->R, crom_malloc(sizeof(double) * (size_t)nf),
                     crom_malloc(sizeof(double) * ((size_t)nr + 1)), 0};
    if (!M->P.mx || !M->P.h)
        return CROM_EINTERNAL;
    crom_sym K = {nf, M->cp, M->ri, M->Kf};
    int nc = nf - nr, k = o->count;
    double thr = out->rigid_threshold;
    for (;;) {
        int z = M->z;
        if (!o->keep_rigid && k + z > nc)
            return crom_err(CROM_EUSAGE,
                            "%d deformation modes asked for, but the body has only %d (%d free degrees "
                            "of freedom, %d rigid modes)",
                            k, nc - z, nf, nr + z);
        int req = o->keep_rigid ? (k - nr > z ? k - nr : z) : k + z;
        int need = req < nc ? req + 1 : nc;
        if (need == nc && req < nc && nf > DENSE_MAX)
            need = req; /* the one more is not worth a dense solve */
        if (need <= M->have)
            break;
        free(M->lam);
        free(M->Y);
        M->lam = crom_malloc(sizeof(double) * (size_t)need);
        M->Y = crom_malloc(sizeof(double) * (size_t)nf * need);
        if (!M->lam || !M->Y)
            return CROM_EINTERNAL;
        if ((rc = lowest_modes(&M->P, &K, o, M->sigma, need, M->lam, M->Y, out)))
            return rc;
        M->have = need;
        M->z = 0;
        while (M->z < M->have && M->lam[M->z] <= thr)
            M->z++;
    }
    out->solves = M->P.solves;
    return 0;
}

/* The result's k modes on the free DOFs into Phi, with out->omega2 and
 * next_omega2: when kept, the rigid block first (ω² 0 for the built
 * motions, λ for the zero-energy modes found), canonical; then the
 * deformation modes. */
static int order_result(modesrun *M, crom_modes *out)
{
    int nf = M->nf, nr = M->nr, z = M->z, k = M->o.count, keep = M->o.keep_rigid, rc;
    const double *lam = M->lam;
    int nrigid = nr + z, nkr = keep ? (nrigid < k ? nrigid : k) : 0;
    int skip = keep ? nrigid : 0; /* Y[z + j − skip] is result j >= nkr */
    M->nkr = nkr;
    double *Phi = M->Phi = crom_malloc(sizeof(double) * (size_t)nf * (k > nrigid ? k : nrigid));
    out->omega2 = crom_malloc(sizeof(double) * (size_t)k);
    out->freq = crom_malloc(sizeof(double) * (size_t)k);
    out->residual = crom_malloc(sizeof(double) * (size_t)k);
    out->phi = crom_calloc((size_t)M->fem.n * k, sizeof(double));
    if (!Phi || !out->omega2 || !out->freq || !out->residual || !out->phi)
        return CROM_EINTERNAL;
    out->nrigid = nrigid;
    out->rigid_kept = keep && nrigid > 0;
    for (int j = nkr; j < k; j++) {
        memcpy(Phi + (size_t)j * nf, M->Y + (size_t)(z + j - skip) * nf, sizeof(double) * (size_t)nf);
        out->omega2[j] = lam[z + j - skip];
    }
    if (k >= skip && z + k - skip < M->have)
        out->next_omega2 = lam[z + k - skip];
    if (nkr > 0) {
        /* all nrigid of them (even beyond k), then the first nkr */
        if (nr > 0)
            memcpy(Phi, M->R, sizeof(double) * (size_t)nf * nr);
        if (z > 0)
            memcpy(Phi + (size_t)nf * nr, M->Y, sizeof(double) * (size_t)nf * z);
        if ((rc = canonical_rigid(nf, M->mf, M->X3, M->comp, M->xc, Phi, nf, nrigid)))
            return rc;
        /* their ω², ascending: the z found (<= thr, maybe below 0) among nr zeros */
        for (int j = 0, a = 0, b = 0; j < nrigid; j++) {
            double w = a < z && (b == nr || lam[a] < 0) ? lam[a++] : (b++, 0.0);
            if (j < k)
                out->omega2[j] = w;
            else if (j == k)
                out->next_omega2 = w;
        }
    }
    return 0;
}

/* Each mode of Phi M-normalized (already so up to round-off) and signed
 * so that its largest entry is positive, its residual ‖Kφ − ω²Mφ‖ relative
 * to ‖Kφ‖ (to λ_mean ‖Mφ‖ for the rigid block) and its frequency into out,
 * and the mode scattered into out->phi. */
static int finish_modes(modesrun *M, crom_modes *out)
{
    int nf = M->nf, k = M->o.count;
    const double *mf = M->mf;
    crom_sym K = {nf, M->cp, M->ri, M->Kf};
    double *kx = crom_malloc(sizeof(double) * (size_t)nf);
    if (!kx)
        return CROM_EINTERNAL;
    for (int j = 0; j < k; j++) {
        double *x = M->Phi + (size_t)j * nf;
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
        double w = out->omega2[j], rn = 0, kn = 0, mn = 0;
        for (int i = 0; i < nf; i++) {
            double r = kx[i] - w * mf[i] * x[i];
            rn += r * r;
            kn += kx[i] * kx[i];
            mn += mf[i] * mf[i] * x[i] * x[i];
        }
        out->residual[j] = j < M->nkr ? sqrt(rn) / (out->lambda_mean * sqrt(mn)) : sqrt(rn) / sqrt(kn);
        out->freq[j] = sqrt(w > 0 ? w : 0) / (2 * M_PI);
        for (int i = 0; i < nf; i++)
            out->phi[(size_t)M->dof[i] * k + j] = x[i];
    }
    free(kx);
    return 0;
}

int crom_modes_compute(const crom_mesh *mesh, const crom_material *mat, const unsigned char *fixed,
                       const crom_modes_opts *opt, crom_modes *out)
{
    modesrun M;
    memset(&M, 0, sizeof M);
    crom_modes_opts *o = &M.o;
    if (opt)
        *o = *opt;
    else
        crom_modes_defaults(o);
    memset(out, 0, sizeof *out);
    out->next_omega2 = NAN;
    if (o->count < 1)
        return crom_err(CROM_EUSAGE, "the number of modes must be positive, got %d", o->count);
    if (!(o->tol > 0))
        o->tol = 1e-10;
    if (!(o->rigid_tol > 0))
        o->rigid_tol = 1e-12;
    if (!isfinite(o->shift) || o->shift > 0)
        return crom_err(CROM_EUSAGE, "the shift must be negative, got %g", o->shift);

    double t0 = crom_clock_now();
    int rc = crom_system_init(&M.fem, mesh, mat->E, mat->nu, mat->rho);
    if (rc)
        return rc;
    if (o->materials && (rc = crom_system_set_materials(&M.fem, o->materials, mesh)))
        goto out;
    if ((rc = free_system(&M, mesh, fixed, out)))
        goto out;
    out->t_assemble = crom_clock_now() - t0;
    if ((rc = factor_shifted(&M, mesh, mat)))
        goto out;
    out->sigma = M.sigma;
    crom_chol_stats(M.chol, &out->t_analyze, &out->t_factor, NULL, NULL, NULL);
    double tl = crom_clock_now();
    if ((rc = lowest_pairs(&M, mesh, fixed, out)))
        goto out;
    crom_chol_stats(M.chol, NULL, NULL, &out->t_solve, NULL, NULL);
    if ((rc = order_result(&M, out)) || (rc = finish_modes(&M, out)))
        goto out;
    out->k = o->count;
    out->t_lanczos = crom_clock_now() - tl;
out:
    if (rc) {
        crom_modes_free(out);
        out->next_omega2 = NAN;
    }
    modesrun_free(&M);
    return rc;
}

/* ----------------------------------------- a given generalized problem */

int crom_modes_lowest(const crom_sym *K, const double *m, int nr, const double *R, int nev, double sigma,
                      const crom_modes_opts *opt, double *lam, double *Y, long *solves)
{
    crom_modes_opts o;
    if (opt)
        o = *opt;
    else
        crom_modes_defaults(&o);
    if (!(o.tol > 0))
        o.tol = 1e-10;
    o.count = nev;
    int n = K->n, rc = 0;
    if (nev < 1 || nev > n - nr)
        return crom_err(CROM_EUSAGE, "%d eigenpairs asked for in a space of dimension %d", nev, n - nr);
    if (!(sigma < 0) || !isfinite(sigma))
        return crom_err(CROM_EUSAGE, "the shift must be negative, got %g", sigma);
    int nnz = K->colptr[n];
    double *A = crom_malloc(sizeof(double) * (size_t)(nnz ? nnz : 1));
    eigprob P = {n, m, NULL, nr, R, crom_malloc(sizeof(double) * (size_t)n), crom_malloc(sizeof(double) * ((size_t)nr + 1)),
                 0};
    crom_chol *chol = NULL;
    if (!A || !P.mx || !P.h) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    if (!(chol = crom_chol_analyze(n, K->colptr, K->rowind, 1))) {
        rc = crom_errcode() ? crom_errcode() : CROM_EINTERNAL;
        goto out;
    }
    for (int attempt = 0;; attempt++) {
        memcpy(A, K->val, sizeof(double) * (size_t)nnz);
        for (int j = 0; j < n; j++)
            A[K->colptr[j + 1] - 1] -= sigma * m[j]; /* the diagonal is last */
        if (!(rc = crom_chol_factor(chol, A)))
            break;
        if (rc != CROM_EDATA || attempt == 3) {
            if (rc == CROM_EDATA)
                rc = crom_err(CROM_EDATA, "the matrix shifted by %g M is not positive definite", -sigma);
            goto out;
        }
        sigma *= 10; /* round-off beat a tiny shift: move it further */
    }
    P.chol = chol;
    crom_modes stats;
    memset(&stats, 0, sizeof stats);
    rc = lowest_modes(&P, K, &o, sigma, nev, lam, Y, &stats);
out:
    if (solves)
        *solves = P.solves;
    crom_chol_free(chol);
    free(A);
    free(P.mx);
    free(P.h);
    return rc;
}

double crom_modes_box_half(const double *freq, int r, double A, int k)
{
    double fmin = INFINITY;
    for (int j = 0; j < r; j++)
        if (freq[j] > 0 && freq[j] < fmin)
            fmin = freq[j];
    return isfinite(fmin) && freq[k] > 0 ? A * fmin / freq[k] : A;
}
