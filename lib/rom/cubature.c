/* cubature.c — cubature schemes and the reduced element kernel (see
 * cubature.h). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <cblas.h>
#include <lapacke.h>
#include <metis.h>

#include "base/err.h"
#include "rom/cubature.h"

int crom_cubature_scheme(const char *name)
{
    static const char *n[] = {"all", "random", "metis", "optimized"};
    for (int i = 0; i < 4; i++)
        if (!strcmp(name, n[i]))
            return i;
    return -1;
}

static const char *scheme_name(int s)
{
    static const char *n[] = {"all", "random", "metis", "optimized"};
    return s >= 0 && s < 4 ? n[s] : "?";
}

/* ------------------------------------------------------------ the kernel */

/* Whether the rows 3a + c of W4 (component c of the tet's four vertices)
 * are nonzero only inside one column block [lo_c, hi_c) per component, the
 * three blocks disjoint (a basis whose latent directions each move one
 * component, as a skinning basis in orthonormal coordinates: lib/rom/skin.h).
 * An empty block (a component that vanishes on the tet) has lo = hi. */
static int component_blocks(const double *W4, int r, int lo[3], int hi[3])
{
    for (int c = 0; c < 3; c++) {
        lo[c] = r;
        hi[c] = 0;
        for (int a = 0; a < 4; a++) {
            const double *row = W4 + (size_t)(3 * a + c) * r;
            int j = 0, k = r;
            while (j < r && row[j] == 0)
                j++;
            if (j == r)
                continue; /* a zero row */
            while (row[k - 1] == 0)
                k--;
            lo[c] = j < lo[c] ? j : lo[c];
            hi[c] = k > hi[c] ? k : hi[c];
        }
        if (hi[c] <= lo[c])
            lo[c] = hi[c] = 0;
        if (hi[c] - lo[c] > r / 2)
            return 0; /* dense enough: one product does it */
    }
    for (int c = 0; c < 3; c++)
        for (int d = c + 1; d < 3; d++)
            if (lo[c] < hi[c] && lo[d] < hi[d] && lo[c] < hi[d] && lo[d] < hi[c])
                return 0;
    return 1;
}

double crom_cubature_tet(const crom_material *mat, const double Xe[12], const double *W4, int r,
                         const double Dminv[9], double V, double w, const double *q, int project,
                         double *g_r, double *H_r, double *work)
{
    double *xe = work, *ge = work + 12, *He = work + 24, *HW = work + 168;
    /* x = X + W q at the four vertices: xe = Xe + W4 q (W4 is 12 × r) */
    memcpy(xe, Xe, 12 * sizeof(double));
    cblas_dgemv(CblasRowMajor, CblasNoTrans, 12, r, 1.0, W4, r, q, 1, 1.0, xe, 1);
    double E;
    if (crom_fem_tet_eval(mat, xe, Dminv, V, project, &E, g_r ? ge : NULL, H_r ? He : NULL))
        return NAN;
    if (g_r) /* g_r += w W4ᵀ ge */
        cblas_dgemv(CblasRowMajor, CblasTrans, 12, r, w, W4, r, ge, 1, 1.0, g_r, 1);
    if (H_r) { /* H_r += w W4ᵀ He W4 = w Σ_rows i W4[i]ᵀ (He W4)[i] */
        cblas_dgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, 12, r, 12, 1.0, He, 12, W4, r, 0.0, HW, r);
        int lo[3], hi[3];
        if (component_blocks(W4, r, lo, hi)) {
            /* rows 3a + c touch only the rows [lo_c, hi_c) of H_r: three
             * products over the 4 rows of each component (stride 3r) */
            for (int c = 0; c < 3; c++)
                if (hi[c] > lo[c])
                    cblas_dgemm(CblasRowMajor, CblasTrans, CblasNoTrans, hi[c] - lo[c], r, 4, w, W4 + (size_t)c * r + lo[c],
                                3 * r, HW + (size_t)c * r, 3 * r, 1.0, H_r + (size_t)lo[c] * r, r);
        } else {
            cblas_dgemm(CblasRowMajor, CblasTrans, CblasNoTrans, r, r, 12, w, W4, r, HW, r, 1.0, H_r, r);
        }
    }
    return E;
}

/* gather the [4][3][r] W block and rest positions of tet t */
static void gather(const crom_cubature *c, int t, double *Xe, double *W4)
{
    const int *e = c->mesh.tets + 4 * (size_t)t;
    size_t blk = 3 * (size_t)c->r;
    for (int a = 0; a < 4; a++) {
        memcpy(Xe + 3 * a, c->mesh.X + 3 * (size_t)e[a], 3 * sizeof(double));
        memcpy(W4 + a * blk, c->W + (size_t)e[a] * blk, blk * sizeof(double));
    }
}

void crom_cubature_gather(const crom_cubature *c, int k, double Xe[12], double *W4, double Dminv[9])
{
    gather(c, c->elem[k], Xe, W4);
    memcpy(Dminv, c->Dminv + 9 * (size_t)k, 9 * sizeof(double));
}

/* ------------------------------------------------------------- schemes */

static int scheme_all(crom_cubature *c)
{
    c->k = c->ne;
    c->elem = crom_malloc(sizeof(int) * (size_t)c->k);
    c->weight = crom_malloc(sizeof(double) * (size_t)c->k);
    if (!c->elem || !c->weight)
        return CROM_EINTERNAL;
    for (int t = 0; t < c->k; t++) {
        c->elem[t] = t;
        c->weight[t] = 1;
    }
    return 0;
}

/* The random and METIS schemes work on a set of elements: nel elements of
 * `per` vertices each (elv [nel][per]), of rest measure meas [nel] (a tet's
 * volume, a triangle's area, a hinge's stiffness factor |ē|²/(Ā1 + Ā2)),
 * numbered from offset among the cubature's elements. A solid is one set
 * (its tets); a shell two (its triangles, then its hinges), each integrated
 * on its own, so that the membrane and the bending energy keep their
 * measures. The chosen elements and weights are appended to c->elem and
 * c->weight. */
typedef struct {
    int nel, per, offset;
    const int *elv;
    const double *meas;
} elem_set;

static int append_elems(crom_cubature *c, int n)
{
    int *e = crom_realloc(c->elem, sizeof(int) * (size_t)(c->k + n));
    if (e)
        c->elem = e;
    double *w = crom_realloc(c->weight, sizeof(double) * (size_t)(c->k + n));
    if (w)
        c->weight = w;
    return e && w ? 0 : CROM_EINTERNAL;
}

/* LiCROM §5: m random vertices plus all the elements that touch them, equal
 * weights (the set's measure over the chosen elements'). pick [nv] marks
 * the chosen vertices. */
static int random_set(crom_cubature *c, const elem_set *S, const unsigned char *pick)
{
    double total = 0, vsel = 0;
    int n = 0;
    unsigned char *use = crom_calloc((size_t)S->nel + 1, 1);
    if (!use)
        return CROM_EINTERNAL;
    for (int t = 0; t < S->nel; t++) {
        const int *e = S->elv + (size_t)S->per * t;
        total += S->meas[t];
        for (int a = 0; a < S->per && !use[t]; a++)
            use[t] = pick[e[a]];
        if (use[t]) {
            n++;
            vsel += S->meas[t];
        }
    }
    int rc = append_elems(c, n);
    for (int t = 0; !rc && t < S->nel; t++)
        if (use[t]) {
            c->elem[c->k] = S->offset + t;
            c->weight[c->k++] = total / vsel;
        }
    free(use);
    return rc;
}

static int scheme_random(crom_cubature *c, const elem_set *sets, int nsets, int m, crom_rng *rng)
{
    int nv = c->mesh.nv;
    int *perm = crom_malloc(sizeof(int) * (size_t)nv);
    unsigned char *pick = crom_calloc((size_t)nv, 1);
    int rc = perm && pick ? 0 : CROM_EINTERNAL;
    if (!rc) {
        for (int i = 0; i < nv; i++)
            perm[i] = i;
        crom_rng_shuffle(rng, perm, nv);
        for (int i = 0; i < m && i < nv; i++)
            pick[perm[i]] = 1;
    }
    for (int k = 0; !rc && k < nsets; k++)
        rc = random_set(c, &sets[k], pick);
    free(perm);
    free(pick);
    return rc;
}

/* METIS partition of a set's dual graph (elements joined when they share
 * ncommon vertices) into `parts`, one representative per part: the element
 * nearest the part's measure-weighted centroid, weighted by the part's
 * measure over its own. */
static int metis_set(crom_cubature *c, const elem_set *S, int ncommon, int parts, idx_t **epart_out,
                     int **rep_out)
{
    int nel = S->nel, nv = c->mesh.nv, per = S->per;
    const double *X = c->mesh.X;
    if (parts > nel)
        parts = nel;
    idx_t *epart = crom_malloc(sizeof(idx_t) * (size_t)nel);
    idx_t *npart = crom_malloc(sizeof(idx_t) * (size_t)nv);
    idx_t *eptr = crom_malloc(sizeof(idx_t) * ((size_t)nel + 1));
    idx_t *eind = crom_malloc(sizeof(idx_t) * (size_t)per * nel);
    double *pv = crom_calloc((size_t)parts, sizeof(double)), *pc = crom_calloc(3 * (size_t)parts, sizeof(double));
    double *best = crom_malloc(sizeof(double) * (size_t)parts);
    int *rep = crom_malloc(sizeof(int) * (size_t)parts), rc = 0;
    if (!epart || !npart || !eptr || !eind || !pv || !pc || !best || !rep) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    if (parts == 1) { /* METIS divides by zero for one part (TOOLCHAIN.md) */
        for (int t = 0; t < nel; t++)
            epart[t] = 0;
    } else {
        for (int t = 0; t <= nel; t++)
            eptr[t] = (idx_t)per * t;
        for (size_t i = 0; i < (size_t)per * nel; i++)
            eind[i] = S->elv[i];
        idx_t ne = nel, nn = nv, nc = ncommon, np = parts, objval, opts[METIS_NOPTIONS];
        METIS_SetDefaultOptions(opts);
        opts[METIS_OPTION_SEED] = 1;
        if (METIS_PartMeshDual(&ne, &nn, eptr, eind, NULL, NULL, &nc, &np, NULL, opts, &objval, epart, npart) !=
            METIS_OK) {
            rc = crom_err(CROM_EINTERNAL, "METIS_PartMeshDual failed");
            goto out;
        }
    }
    for (int t = 0; t < nel; t++) {
        const int *e = S->elv + (size_t)per * t;
        int p = (int)epart[t];
        pv[p] += S->meas[t];
        for (int a = 0; a < per; a++)
            for (int k = 0; k < 3; k++)
                pc[3 * p + k] += S->meas[t] * X[3 * (size_t)e[a] + k] / per;
    }
    for (int p = 0; p < parts; p++) {
        best[p] = INFINITY;
        rep[p] = -1;
        if (pv[p] > 0)
            for (int k = 0; k < 3; k++)
                pc[3 * p + k] /= pv[p];
    }
    for (int t = 0; t < nel; t++) {
        const int *e = S->elv + (size_t)per * t;
        int p = (int)epart[t];
        double d = 0;
        for (int k = 0; k < 3; k++) {
            double x = 0;
            for (int a = 0; a < per; a++)
                x += X[3 * (size_t)e[a] + k] / per;
            d += (x - pc[3 * p + k]) * (x - pc[3 * p + k]);
        }
        if (S->meas[t] > 0 && d < best[p]) {
            best[p] = d;
            rep[p] = t;
        }
    }
    int n = 0;
    for (int p = 0; p < parts; p++)
        n += rep[p] >= 0;
    if ((rc = append_elems(c, n)))
        goto out;
    for (int p = 0; p < parts; p++)
        if (rep[p] >= 0) {
            c->elem[c->k] = S->offset + rep[p];
            c->weight[c->k++] = pv[p] / S->meas[rep[p]];
        }
    if (epart_out) { /* the caller keeps the partition */
        *epart_out = epart;
        *rep_out = rep;
        epart = NULL;
        rep = NULL;
    }
out:
    free(epart);
    free(npart);
    free(eptr);
    free(eind);
    free(pv);
    free(pc);
    free(best);
    free(rep);
    return rc;
}

typedef struct {
    int a, b, t; /* an edge a < b of triangle t */
} tri_edge;

static int tri_edge_cmp(const void *x, const void *y)
{
    const tri_edge *p = x, *q = y;
    if (p->a != q->a)
        return p->a < q->a ? -1 : 1;
    return (p->b > q->b) - (p->b < q->b);
}

/* The hinges of a shell by the METIS parts of its triangles: a hinge
 * belongs to the part of its triangle (v0, v1, v2); each part is stood for
 * by the hinges on the edges of its representative triangle, weighted
 * together by the part's stiffness factors over theirs. The edges of one
 * triangle run in three directions, so the bending of every direction is
 * sampled (one hinge per part would bend in one). */
static int metis_hinges(crom_cubature *c, const elem_set *T, const elem_set *H, const idx_t *epart,
                        const int *rep, int parts)
{
    int nt = T->nel, nh = H->nel, rc = 0;
    tri_edge *ed = crom_malloc(sizeof(tri_edge) * 3 * (size_t)nt);
    int *ht = crom_malloc(sizeof(int) * 2 * (size_t)nh);
    double *Hp = crom_calloc((size_t)parts, sizeof(double)), *Hr = crom_calloc((size_t)parts, sizeof(double));
    double *hw = crom_calloc((size_t)nh, sizeof(double));
    if (!ed || !ht || !Hp || !Hr || !hw) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    for (int t = 0; t < nt; t++)
        for (int e = 0; e < 3; e++) {
            int a = T->elv[3 * (size_t)t + e], b = T->elv[3 * (size_t)t + (e + 1) % 3];
            ed[3 * (size_t)t + e] = (tri_edge){a < b ? a : b, a < b ? b : a, t};
        }
    qsort(ed, 3 * (size_t)nt, sizeof *ed, tri_edge_cmp);
    for (int h = 0; h < nh; h++) { /* the triangles on each side: (v0, v1, v2) and (v0, v1, v3) */
        const int *v = H->elv + 4 * (size_t)h;
        tri_edge key = {v[0] < v[1] ? v[0] : v[1], v[0] < v[1] ? v[1] : v[0], 0};
        const tri_edge *f = bsearch(&key, ed, 3 * (size_t)nt, sizeof *ed, tri_edge_cmp);
        ht[2 * h] = ht[2 * h + 1] = -1;
        if (!f) {
            rc = crom_err(CROM_EINTERNAL, "hinge %d has no triangle", h);
            goto out;
        }
        while (f > ed && !tri_edge_cmp(f - 1, &key))
            f--;
        for (; f < ed + 3 * (size_t)nt && !tri_edge_cmp(f, &key); f++) {
            const int *tv = T->elv + 3 * (size_t)f->t;
            int side = tv[0] == v[3] || tv[1] == v[3] || tv[2] == v[3];
            ht[2 * h + side] = f->t;
        }
        if (ht[2 * h] < 0) {
            rc = crom_err(CROM_EINTERNAL, "hinge %d has no triangle (v0, v1, v2)", h);
            goto out;
        }
        Hp[epart[ht[2 * h]]] += H->meas[h];
    }
    /* the representatives' hinges, and their stiffness factor per part */
    for (int h = 0; h < nh; h++)
        for (int side = 0; side < 2; side++) {
            int t = ht[2 * h + side];
            if (t >= 0 && rep[epart[t]] == t)
                Hr[epart[t]] += H->meas[h];
        }
    for (int h = 0; h < nh; h++)
        for (int side = 0; side < 2; side++) {
            int t = ht[2 * h + side];
            if (t >= 0 && rep[epart[t]] == t && Hr[epart[t]] > 0)
                hw[h] += Hp[epart[t]] / Hr[epart[t]];
        }
    /* a part whose representative has no interior edge (a corner): its
     * first hinge stands for it */
    for (int p = 0; p < parts; p++)
        if (Hp[p] > 0 && !(Hr[p] > 0))
            for (int h = 0; h < nh; h++)
                if (epart[ht[2 * h]] == p && H->meas[h] > 0) {
                    hw[h] += Hp[p] / H->meas[h];
                    break;
                }
    int n = 0;
    for (int h = 0; h < nh; h++)
        n += hw[h] > 0;
    if ((rc = append_elems(c, n)))
        goto out;
    for (int h = 0; h < nh; h++)
        if (hw[h] > 0) {
            c->elem[c->k] = H->offset + h;
            c->weight[c->k++] = hw[h];
        }
out:
    free(ed);
    free(ht);
    free(Hp);
    free(Hr);
    free(hw);
    return rc;
}

/* A solid's tets in `parts` parts, one tet each; a shell's triangles in
 * `parts` parts, each stood for by a triangle and the hinges on its edges
 * (metis_hinges). */
static int scheme_metis(crom_cubature *c, const elem_set *sets, int nsets, int parts)
{
    if (parts > sets[0].nel)
        return crom_err(CROM_EUSAGE, "--count %d: the mesh has only %d %s to split into parts", parts, sets[0].nel,
                        sets[0].per == 3 ? "triangles" : "tets");
    if (nsets == 1)
        return metis_set(c, &sets[0], sets[0].per == 4 ? 3 : 2, parts, NULL, NULL);
    idx_t *epart = NULL;
    int *rep = NULL;
    int rc = metis_set(c, &sets[0], 2, parts, &epart, &rep);
    if (!rc)
        rc = metis_hinges(c, &sets[0], &sets[1], epart, rep, parts);
    free(epart);
    free(rep);
    return rc;
}

/* --------------------------------------------- optimized (greedy NNLS) */

/* Lawson–Hanson NNLS on the normal equations of the selected columns:
 * minimize ‖A w − b‖ with w >= 0, given G = AᵀA (s × s) and h = Aᵀb. w holds
 * a feasible start on entry. */
static int nnls_normal(int s, const double *G, const double *h, double *w, double *work, int *P)
{
    double *z = work, *Gp = work + s, *grad = work + s + (size_t)s * s;
    int *idx = P;
    for (int outer = 0; outer < 3 * s + 10; outer++) {
        /* gradient of ½‖Aw − b‖²: G w − h */
        for (int i = 0; i < s; i++) {
            double v = -h[i];
            for (int j = 0; j < s; j++)
                v += G[i * s + j] * w[j];
            grad[i] = v;
        }
        /* passive set: w > 0 ; add the most negative gradient among zeros */
        int add = -1;
        double most = -1e-14;
        for (int i = 0; i < s; i++)
            if (w[i] <= 0 && grad[i] < most) {
                most = grad[i];
                add = i;
            }
        int np = 0;
        for (int i = 0; i < s; i++)
            if (w[i] > 0 || i == add)
                idx[np++] = i;
        if (add < 0 && outer > 0)
            return 0;
        for (int inner = 0; inner < 3 * s + 10; inner++) {
            /* unconstrained solve on the passive set */
            for (int a = 0; a < np; a++) {
                for (int b = 0; b < np; b++)
                    Gp[a * np + b] = G[idx[a] * s + idx[b]];
                z[a] = h[idx[a]];
                Gp[a * np + a] *= 1 + 1e-12; /* a hair of regularization */
            }
            if (np == 0)
                break;
            if (LAPACKE_dposv(LAPACK_ROW_MAJOR, 'U', np, 1, Gp, np, z, 1) != 0)
                return crom_err(CROM_EINTERNAL, "NNLS: singular normal equations");
            int allpos = 1;
            for (int a = 0; a < np; a++)
                allpos &= z[a] > 0;
            if (allpos) {
                for (int i = 0; i < s; i++)
                    w[i] = 0;
                for (int a = 0; a < np; a++)
                    w[idx[a]] = z[a];
                break;
            }
            /* step toward z until a weight hits zero */
            double alpha = 1;
            for (int a = 0; a < np; a++)
                if (z[a] <= 0) {
                    double wa = w[idx[a]], t = wa / (wa - z[a]);
                    if (t < alpha)
                        alpha = t;
                }
            for (int a = 0; a < np; a++)
                w[idx[a]] += alpha * (z[a] - w[idx[a]]);
            int k = 0;
            for (int a = 0; a < np; a++)
                if (w[idx[a]] > 1e-15)
                    idx[k++] = idx[a];
                else
                    w[idx[a]] = 0;
            np = k;
        }
    }
    return 0;
}

/* The scratch of elem_force: crom_cubature_tet's, or a shell element's
 * positions, gradient and W block. */
#define ELEM_WORK(r) (168 + 24 * (size_t)(r) + 12)

/* Element e of c at latent q: its energy (NaN when not finite), and its
 * reduced force g_r += w Σ_a W_aᵀ ∂E_e/∂x_a. A solid's tet through
 * crom_cubature_tet with material mat (its rest shape recomputed; the
 * greedy fit's columns, elem_column, compute it once per tet); a shell's
 * element through its system sys. work holds ELEM_WORK(r) doubles. */
static double elem_force(const crom_cubature *c, const crom_material *mat, const crom_system *sys, int e,
                         double w, const double *q, double *g_r, double *work)
{
    int r = c->r;
    if (!sys) {
        double Xe[12], Dm[9], V, *W4 = work, *kw = work + 12 * (size_t)r;
        gather(c, e, Xe, W4);
        if (crom_fem_tet_rest(Xe, Dm, &V)) {
            crom_err_clear();
            return NAN;
        }
        return crom_cubature_tet(mat, Xe, W4, r, Dm, V, w, q, 0, g_r, NULL, kw);
    }
    int v[CROM_SYSTEM_MAXV], k = crom_system_elem_vertices(sys, e, v);
    double xe[3 * CROM_SYSTEM_MAXV], ge[3 * CROM_SYSTEM_MAXV], E, *We = work;
    size_t blk = 3 * (size_t)r;
    for (int a = 0; a < k; a++) {
        memcpy(We + a * blk, c->W + (size_t)v[a] * blk, blk * sizeof(double));
        memcpy(xe + 3 * a, c->mesh.X + 3 * (size_t)v[a], 3 * sizeof(double));
    }
    cblas_dgemv(CblasRowMajor, CblasNoTrans, 3 * k, r, 1.0, We, r, q, 1, 1.0, xe, 1);
    if (crom_system_elem_eval(sys, e, xe, 0, &E, ge, NULL))
        return NAN;
    if (g_r)
        cblas_dgemv(CblasRowMajor, CblasTrans, 3 * k, r, w, We, r, ge, 1, 1.0, g_r, 1);
    return E;
}

/* The system of a shell cubature's mesh with the material's E and ν (the
 * density does not enter elastic forces). */
static int shell_system(const crom_cubature *c, const crom_material *mat, crom_system *sys)
{
    return crom_system_init(sys, &c->mesh, mat->E, mat->nu, mat->rho);
}

/* One column of the fitting matrix for element t: per pose its reduced
 * force (ro rows: r, or rout projected by the pose's T) and its energy (1
 * row), each scaled by the pose's row scale. */
static int elem_column(const crom_cubature *c, const crom_cubature_opts *o, const crom_material *mat,
                      const crom_system *sys, int t, const double *fscale, const double *escale, double *col,
                      double *work)
{
    int r = c->r, ro = o->proj ? o->rout : r;
    double *gf = work, *kw = work + r;
    /* a solid's tet: its positions, W rows and rest shape once for every pose */
    double Xe[12], Dm[9], V = 0, *W4 = kw, *tw = kw + 12 * (size_t)r;
    if (!sys) {
        gather(c, t, Xe, W4);
        if (crom_fem_tet_rest(Xe, Dm, &V)) {
            crom_err_clear();
            return CROM_EDATA;
        }
    }
    for (int j = 0; j < o->npose; j++) {
        double *g = col + (size_t)j * (ro + 1);
        const double *q = o->poses + (size_t)j * r;
        memset(gf, 0, sizeof(double) * (size_t)r);
        double E = sys ? elem_force(c, mat, sys, t, 1.0, q, gf, kw)
                       : crom_cubature_tet(mat, Xe, W4, r, Dm, V, 1.0, q, 0, gf, NULL, tw);
        if (!isfinite(E))
            return CROM_EDATA;
        if (o->proj)
            cblas_dgemv(CblasRowMajor, CblasTrans, r, ro, fscale[j], o->proj + (size_t)j * r * ro, ro, gf, 1, 0.0, g, 1);
        else
            for (int i = 0; i < r; i++)
                g[i] = gf[i] * fscale[j];
        g[ro] = E * escale[j];
    }
    return 0;
}

/* The greedy selection of the optimized scheme (An, Kim, James 2008): the
 * fitting matrix has one row per pose and reduced force component (ro) plus
 * one for the pose's energy (m rows in all), one column per tet; tets are
 * added one at a time, each time refitting non-negative weights. */
typedef struct {
    const crom_cubature *c;
    const crom_cubature_opts *o;
    crom_material mat;
    crom_system sys, *shell; /* a shell's system (shell = &sys), else NULL */
    int nt, ro, m, K;   /* elements, rows per pose but one, rows, element budget */
    double *b;          /* [m] targets: the exact forces and energies, per pose normalized */
    double *fscale, *escale; /* [P] the poses' row scales */
    double *col, *work; /* [m] one column; elem_column's scratch */
    double *A;          /* [K][m] the selected columns */
    double *G, *hv;     /* [K][K] AᵀA and [K] Aᵀb of the selected columns */
    double *w, *res;    /* [K] weights; [m] residual b − A w */
    int *sel, *P_idx;   /* [K] selected tets; NNLS's passive set */
    unsigned char *taken; /* [nt] */
    int *cand;          /* [nt] candidate order */
    double bnorm;       /* |b| */
} greedy;

static void greedy_free(greedy *g)
{
    crom_system_free(&g->sys);
    free(g->b);
    free(g->col);
    free(g->fscale);
    free(g->escale);
    free(g->work);
    free(g->A);
    free(g->G);
    free(g->hv);
    free(g->w);
    free(g->res);
    free(g->sel);
    free(g->P_idx);
    free(g->taken);
    free(g->cand);
}

static int greedy_init(greedy *g, const crom_cubature *c, const crom_cubature_opts *o)
{
    memset(g, 0, sizeof *g);
    g->c = c;
    g->o = o;
    int r = c->r, P = o->npose, rc = crom_material_init(&g->mat, o->youngs, o->poisson, 1000);
    if (rc)
        return rc;
    if (!o->poses || P < 1)
        return crom_err(CROM_EUSAGE, "the optimized scheme needs training poses (--poses LATENT)");
    if (crom_mesh_is_surface(&c->mesh)) {
        if ((rc = shell_system(c, &g->mat, &g->sys)))
            return rc;
        g->shell = &g->sys;
    }
    g->nt = c->ne;
    g->ro = o->proj ? o->rout : r;
    g->m = P * (g->ro + 1);
    g->K = o->count > g->nt ? g->nt : o->count;
    size_t m = (size_t)g->m, K = (size_t)g->K, nt = (size_t)g->nt;
    g->b = crom_calloc(m, sizeof(double));
    g->col = crom_malloc(sizeof(double) * m);
    g->fscale = crom_malloc(sizeof(double) * (size_t)P);
    g->escale = crom_malloc(sizeof(double) * (size_t)P);
    g->work = crom_malloc(sizeof(double) * ((size_t)r + ELEM_WORK(r)));
    g->A = crom_malloc(sizeof(double) * m * K);
    g->G = crom_calloc(K * K, sizeof(double));
    g->hv = crom_calloc(K, sizeof(double));
    g->w = crom_calloc(K, sizeof(double));
    g->res = crom_malloc(sizeof(double) * m);
    g->sel = crom_malloc(sizeof(int) * K);
    g->P_idx = crom_malloc(sizeof(int) * K);
    g->taken = crom_calloc(nt, 1);
    g->cand = crom_malloc(sizeof(int) * nt);
    if (!g->b || !g->col || !g->fscale || !g->escale || !g->work || !g->A || !g->G || !g->hv || !g->w ||
        !g->res || !g->sel || !g->P_idx || !g->taken || !g->cand)
        return CROM_EINTERNAL;
    for (int i = 0; i < g->nt; i++)
        g->cand[i] = i;
    return 0;
}

/* The targets: the exact reduced forces and energies over all tets, each
 * pose's rows scaled to unit force and energy so every pose counts
 * equally; the residual starts at them. */
static int greedy_targets(greedy *g)
{
    int P = g->o->npose, ro = g->ro, rc = 0;
    for (int j = 0; j < P; j++)
        g->fscale[j] = g->escale[j] = 1;
    for (int t = 0; t < g->nt && !rc; t++) {
        rc = elem_column(g->c, g->o, &g->mat, g->shell, t, g->fscale, g->escale, g->col, g->work);
        for (int i = 0; !rc && i < g->m; i++)
            g->b[i] += g->col[i];
    }
    if (rc)
        return crom_err(CROM_EDATA, "optimized cubature: a training pose gives a non-finite elastic force");
    for (int j = 0; j < P; j++) {
        double *bj = g->b + (size_t)j * (ro + 1), n2 = 0;
        for (int i = 0; i < ro; i++)
            n2 += bj[i] * bj[i];
        g->fscale[j] = n2 > 0 ? 1 / sqrt(n2) : 0;
        g->escale[j] = fabs(bj[ro]) > 0 ? 1 / fabs(bj[ro]) : 0;
        for (int i = 0; i < ro; i++)
            bj[i] *= g->fscale[j];
        bj[ro] *= g->escale[j];
    }
    g->bnorm = cblas_dnrm2(g->m, g->b, 1);
    if (!(g->bnorm > 0))
        return crom_err(CROM_EDATA, "optimized cubature: the training poses have no elastic force (all at rest?)");
    memcpy(g->res, g->b, sizeof(double) * (size_t)g->m);
    return 0;
}

/* Score a random sample of ncand unselected tets by their correlation with
 * the residual: the best, or -1 when nothing correlates with what is left. */
static int greedy_pick(greedy *g, crom_rng *rng, int ncand)
{
    crom_rng_shuffle(rng, g->cand, g->nt);
    int bestt = -1, tried = 0;
    double bests = 0;
    for (int i = 0; i < g->nt && tried < ncand; i++) {
        int t = g->cand[i];
        if (g->taken[t])
            continue;
        tried++;
        if (elem_column(g->c, g->o, &g->mat, g->shell, t, g->fscale, g->escale, g->col, g->work))
            continue;
        double dot = cblas_ddot(g->m, g->col, 1, g->res, 1), nrm = cblas_dnrm2(g->m, g->col, 1);
        if (nrm > 0 && dot / nrm > bests) {
            bests = dot / nrm;
            bestt = t;
        }
    }
    return bestt;
}

/* Add tet t as the s-th column: grow G = AᵀA and h = Aᵀb (leading
 * dimension K), refit the s + 1 weights by NNLS and update the residual
 * b − A w; *err gets its norm relative to |b|. */
static int greedy_add(greedy *g, int s, int t, double *err)
{
    int m = g->m, K = g->K;
    g->taken[t] = 1;
    elem_column(g->c, g->o, &g->mat, g->shell, t, g->fscale, g->escale, g->A + (size_t)s * m, g->work);
    g->sel[s] = t;
    for (int i = 0; i <= s; i++) {
        double v = cblas_ddot(m, g->A + (size_t)i * m, 1, g->A + (size_t)s * m, 1);
        g->G[(size_t)i * K + s] = g->G[(size_t)s * K + i] = v;
    }
    g->hv[s] = cblas_ddot(m, g->A + (size_t)s * m, 1, g->b, 1);
    s++;
    double *Gc = crom_malloc(sizeof(double) * (size_t)s * s);
    double *nw = crom_malloc(sizeof(double) * ((size_t)s * s + 2 * (size_t)s + 1));
    int rc = Gc && nw ? 0 : CROM_EINTERNAL;
    for (int i = 0; !rc && i < s; i++) /* repacked to s × s for the solver */
        for (int j = 0; j < s; j++)
            Gc[i * s + j] = g->G[(size_t)i * K + j];
    if (!rc)
        rc = nnls_normal(s, Gc, g->hv, g->w, nw, g->P_idx);
    free(Gc);
    free(nw);
    if (rc)
        return rc;
    memcpy(g->res, g->b, sizeof(double) * (size_t)m);
    for (int i = 0; i < s; i++)
        if (g->w[i] > 0)
            cblas_daxpy(m, -g->w[i], g->A + (size_t)i * m, 1, g->res, 1);
    *err = cblas_dnrm2(m, g->res, 1) / g->bnorm;
    return 0;
}

/* The cubature: the s selected tets with positive weight. */
static int greedy_keep(const greedy *g, int s, crom_cubature *c)
{
    c->k = 0;
    for (int i = 0; i < s; i++)
        c->k += g->w[i] > 0;
    if (c->k == 0)
        return crom_err(CROM_EDATA, "optimized cubature selected no tet");
    c->elem = crom_malloc(sizeof(int) * (size_t)c->k);
    c->weight = crom_malloc(sizeof(double) * (size_t)c->k);
    if (!c->elem || !c->weight)
        return CROM_EINTERNAL;
    for (int i = 0, j = 0; i < s; i++)
        if (g->w[i] > 0) {
            c->elem[j] = g->sel[i];
            c->weight[j++] = g->w[i];
        }
    return 0;
}

static int scheme_optimized(crom_cubature *c, const crom_cubature_opts *o, crom_rng *rng)
{
    greedy g;
    int rc = greedy_init(&g, c, o);
    if (!rc)
        rc = greedy_targets(&g);
    int s = 0, ncand = o->candidates > 0 ? o->candidates : 256;
    double err = 1;
    while (!rc && s < g.K && err > o->tol) {
        int t = greedy_pick(&g, rng, ncand);
        if (t < 0)
            break;
        if (!(rc = greedy_add(&g, s, t, &err)))
            s++;
    }
    if (!rc)
        rc = greedy_keep(&g, s, c);
    greedy_free(&g);
    return rc;
}

/* ------------------------------------------------------------------ build */

static int cmp_int(const void *a, const void *b)
{
    int x = *(const int *)a, y = *(const int *)b;
    return (x > y) - (x < y);
}

int crom_cubature_build(crom_cubature *c, const crom_mesh *mesh, const double *W, int r,
                        const char *model_id, const crom_cubature_opts *o, crom_rng *rng)
{
    memset(c, 0, sizeof *c);
    int rc = crom_mesh_copy(mesh, &c->mesh);
    if (rc)
        return rc;
    int nv = mesh->nv, nt = mesh->nt, shell = crom_mesh_is_surface(mesh);
    crom_system sys = {0};
    c->r = r;
    c->ne = nt;
    snprintf(c->model_id, sizeof c->model_id, "%s", model_id);
    snprintf(c->scheme, sizeof c->scheme, "%s", scheme_name(o->scheme));
    size_t nw = (size_t)nv * 3 * r;
    c->W = crom_malloc(sizeof(double) * nw);
    c->vvol = crom_calloc((size_t)nv, sizeof(double));
    c->WtVW = crom_calloc((size_t)r * r, sizeof(double));
    c->WtV = crom_calloc((size_t)r * 3, sizeof(double));
    double *tetvol = crom_malloc(sizeof(double) * (size_t)nt), *B = crom_malloc(sizeof(double) * nw);
    if (!c->W || !c->vvol || !c->WtVW || !c->WtV || !tetvol || !B) {
        rc = CROM_EINTERNAL;
        goto fail;
    }
    memcpy(c->W, W, sizeof(double) * nw);
    for (size_t i = 0; i < nw; i++)
        if (!isfinite(W[i])) {
            rc = crom_err(CROM_EDATA, "the basis is not finite at vertex %zu", i / (3 * (size_t)r));
            goto fail;
        }
    for (int t = 0; t < nt; t++) {
        const int *e = mesh->tets + 4 * (size_t)t;
        double V = crom_mesh_tet_volume(mesh->X + 3 * (size_t)e[0], mesh->X + 3 * (size_t)e[1],
                                        mesh->X + 3 * (size_t)e[2], mesh->X + 3 * (size_t)e[3]);
        tetvol[t] = V;
        c->mesh_volume += V;
        for (int a = 0; a < 4; a++)
            c->vvol[e[a]] += V / 4;
    }
    /* the element sets of the random and METIS schemes */
    elem_set sets[2] = {{.nel = nt, .per = 4, .offset = 0, .elv = mesh->tets, .meas = tetvol}};
    int nsets = 1;
    if (shell) { /* t A / 3 per triangle corner; the elements: the system's (triangles, then hinges) */
        crom_material unit;
        crom_material_init(&unit, 1, 0.3, 1);
        if ((rc = crom_system_init(&sys, mesh, unit.E, unit.nu, unit.rho)))
            goto fail;
        c->ne = sys.nenergy;
        crom_mesh_vertex_volumes(mesh, c->vvol);
        for (int v = 0; v < nv; v++)
            c->mesh_volume += c->vvol[v];
        sets[0] = (elem_set){.nel = sys.sh.nt, .per = 3, .offset = 0, .elv = sys.sh.tris, .meas = sys.sh.area};
        sets[1] = (elem_set){.nel = sys.sh.nh, .per = 4, .offset = sys.sh.nt, .elv = sys.sh.hinges, .meas = sys.sh.hk};
        nsets = sys.sh.nh > 0 ? 2 : 1;
    }
    /* WᵀVW = BᵀB with B = V^½ W (rows 3v+c scaled by sqrt(V_v)); WᵀV */
    for (int v = 0; v < nv; v++) {
        double s = sqrt(c->vvol[v]);
        for (int k = 0; k < 3 * r; k++)
            B[(size_t)v * 3 * r + k] = s * W[(size_t)v * 3 * r + k];
        for (int i = 0; i < r; i++)
            for (int k = 0; k < 3; k++)
                c->WtV[i * 3 + k] += c->vvol[v] * W[((size_t)v * 3 + k) * r + i];
    }
    cblas_dsyrk(CblasRowMajor, CblasUpper, CblasTrans, r, 3 * nv, 1.0, B, r, 0.0, c->WtVW, r);
    for (int i = 0; i < r; i++)
        for (int j = 0; j < i; j++)
            c->WtVW[i * r + j] = c->WtVW[j * r + i];
    /* contact points: the boundary vertices (a shell's: all of them) */
    int ntri, *tri;
    if (shell) {
        ntri = mesh->ntri;
        tri = crom_malloc(sizeof(int) * 3 * (size_t)ntri);
        if (!tri) {
            rc = CROM_EINTERNAL;
            goto fail;
        }
        memcpy(tri, mesh->tris, sizeof(int) * 3 * (size_t)ntri);
    } else if ((rc = crom_mesh_boundary(mesh, &ntri, &tri, NULL))) {
        goto fail;
    }
    qsort(tri, 3 * (size_t)ntri, sizeof(int), cmp_int);
    c->surf = crom_malloc(sizeof(int) * 3 * (size_t)(ntri ? ntri : 1));
    if (!c->surf) {
        free(tri);
        rc = CROM_EINTERNAL;
        goto fail;
    }
    for (int i = 0; i < 3 * ntri; i++)
        if (i == 0 || tri[i] != tri[i - 1])
            c->surf[c->nsurf++] = tri[i];
    free(tri);
    /* the scheme */
    switch (o->scheme) {
    case CROM_CUBATURE_ALL: rc = scheme_all(c); break;
    case CROM_CUBATURE_RANDOM:
        rc = o->count < 1 ? crom_err(CROM_EUSAGE, "--count must be at least 1")
                          : scheme_random(c, sets, nsets, o->count, rng);
        break;
    case CROM_CUBATURE_METIS:
        rc = o->count < 1 ? crom_err(CROM_EUSAGE, "--count must be at least 1")
                          : scheme_metis(c, sets, nsets, o->count);
        break;
    case CROM_CUBATURE_OPTIMIZED:
        rc = o->count < 1 ? crom_err(CROM_EUSAGE, "--count must be at least 1") : scheme_optimized(c, o, rng);
        break;
    default: rc = crom_err(CROM_EUSAGE, "unknown cubature scheme");
    }
    if (rc)
        goto fail;
    crom_system_free(&sys);
    if (shell) { /* no rest shapes of tets: crom-reducedstep --model integrates the system's elements */
        free(tetvol);
        free(B);
        return 0;
    }
    c->Dminv = crom_malloc(sizeof(double) * 9 * (size_t)c->k);
    c->vol = crom_malloc(sizeof(double) * (size_t)c->k);
    if (!c->Dminv || !c->vol) {
        rc = CROM_EINTERNAL;
        goto fail;
    }
    for (int j = 0; j < c->k; j++) {
        double Xe[12];
        const int *e = mesh->tets + 4 * (size_t)c->elem[j];
        for (int a = 0; a < 4; a++)
            memcpy(Xe + 3 * a, mesh->X + 3 * (size_t)e[a], 3 * sizeof(double));
        if ((rc = crom_fem_tet_rest(Xe, c->Dminv + 9 * (size_t)j, &c->vol[j])))
            goto fail;
    }
    free(tetvol);
    free(B);
    return 0;
fail:
    crom_system_free(&sys);
    free(tetvol);
    free(B);
    crom_cubature_free(c);
    return rc;
}

int crom_cubature_error(const crom_cubature *c, const crom_material *mat, const double *poses, int npose,
                        const double *proj, int rout, double *energy_err, double *force_err)
{
    int r = c->r, ro = proj ? rout : r;
    crom_system sys, *shell = NULL;
    memset(&sys, 0, sizeof sys);
    double *fe = crom_calloc((size_t)r, sizeof(double)), *fc = crom_calloc((size_t)r, sizeof(double));
    double *pe = crom_calloc((size_t)ro, sizeof(double)), *pc = crom_calloc((size_t)ro, sizeof(double));
    double *work = crom_malloc(sizeof(double) * ELEM_WORK(r));
    int rc = fe && fc && pe && pc && work ? 0 : CROM_EINTERNAL;
    if (!rc && crom_mesh_is_surface(&c->mesh) && !(rc = shell_system(c, mat, &sys)))
        shell = &sys;
    double dE = 0, sE = 0, df = 0, sf = 0;
    for (int j = 0; j < npose && !rc; j++) {
        const double *q = poses + (size_t)j * r;
        double Ee = 0, Ec = 0;
        memset(fe, 0, sizeof(double) * (size_t)r);
        memset(fc, 0, sizeof(double) * (size_t)r);
        for (int t = 0; t < c->ne && !rc; t++) {
            double E = elem_force(c, mat, shell, t, 1.0, q, fe, work);
            if (!isfinite(E))
                rc = CROM_EDATA;
            Ee += E;
        }
        for (int k = 0; k < c->k && !rc; k++) {
            double E = elem_force(c, mat, shell, c->elem[k], c->weight[k], q, fc, work);
            if (!isfinite(E))
                rc = CROM_EDATA;
            Ec += c->weight[k] * E;
        }
        dE += fabs(Ee - Ec);
        sE += fabs(Ee);
        if (proj) { /* the latent forces Tᵀ f */
            cblas_dgemv(CblasRowMajor, CblasTrans, r, ro, 1.0, proj + (size_t)j * r * ro, ro, fe, 1, 0.0, pe, 1);
            cblas_dgemv(CblasRowMajor, CblasTrans, r, ro, 1.0, proj + (size_t)j * r * ro, ro, fc, 1, 0.0, pc, 1);
        } else {
            memcpy(pe, fe, sizeof(double) * (size_t)r);
            memcpy(pc, fc, sizeof(double) * (size_t)r);
        }
        for (int i = 0; i < ro; i++) {
            df += (pe[i] - pc[i]) * (pe[i] - pc[i]);
            sf += pe[i] * pe[i];
        }
    }
    if (!rc) {
        *energy_err = sE > 0 ? dE / sE : 0;
        *force_err = sf > 0 ? sqrt(df / sf) : 0;
    }
    crom_system_free(&sys);
    free(fe);
    free(fc);
    free(pe);
    free(pc);
    free(work);
    return rc == CROM_EDATA ? crom_err(CROM_EDATA, "a pose gives a non-finite elastic energy") : rc;
}

/* -------------------------------------------------------------- file I/O */

int crom_cubature_write(hid_t loc, const crom_cubature *c)
{
    int rc = crom_h5_set_str(loc, ".", "model_id", c->model_id);
    if (!rc)
        rc = crom_h5_set_str(loc, ".", "scheme", c->scheme);
    if (!rc)
        rc = crom_h5_set_i64(loc, ".", "rank", c->r);
    if (!rc)
        rc = crom_h5_set_f64(loc, ".", "mesh_volume", &c->mesh_volume, 1);
    if (!rc)
        rc = crom_h5_set_i64(loc, ".", "count", c->k);
    if (!rc && c->map_rank > 0)
        rc = crom_h5_set_i64(loc, ".", "map_rank", c->map_rank);
    hid_t g = crom_h5_group(loc, "mesh");
    if (!rc)
        rc = g < 0 ? CROM_EINTERNAL : crom_mesh_write(g, &c->mesh);
    if (g >= 0)
        H5Gclose(g);
    hsize_t nv = (hsize_t)c->mesh.nv, k = (hsize_t)c->k, r = (hsize_t)c->r;
    hsize_t dW[3] = {nv, 3, r}, d9[3] = {k, 3, 3}, drr[2] = {r, r}, dr3[2] = {r, 3}, ds = (hsize_t)c->nsurf;
    if (!rc)
        rc = crom_h5_put_f64(loc, "W", 3, dW, c->W);
    if (!rc)
        rc = crom_h5_put_f64(loc, "lumped_volume", 1, &nv, c->vvol);
    if (!rc)
        rc = crom_h5_put_i32(loc, "elements", 1, &k, c->elem);
    if (!rc)
        rc = crom_h5_put_f64(loc, "weights", 1, &k, c->weight);
    if (!rc && c->Dminv)
        rc = crom_h5_put_f64(loc, "Dminv", 3, d9, c->Dminv);
    if (!rc && c->vol)
        rc = crom_h5_put_f64(loc, "volume", 1, &k, c->vol);
    if (!rc)
        rc = crom_h5_put_f64(loc, "WtVW", 2, drr, c->WtVW);
    if (!rc)
        rc = crom_h5_put_f64(loc, "WtV", 2, dr3, c->WtV);
    if (!rc)
        rc = crom_h5_put_i32(loc, "surface", 1, &ds, c->surf);
    return rc;
}

int crom_cubature_read(crom_in *in, crom_cubature *c)
{
    memset(c, 0, sizeof *c);
    int rc = crom_in_expect(in, CROM_CUBATURE_SCHEMA, CROM_CUBATURE_VERSION);
    if (rc)
        return rc;
    char *s = NULL;
    long long r = 0;
    hsize_t d[4];
    hid_t g = -1;
    if ((rc = crom_h5_get_str(in->h5, ".", "model_id", &s)))
        goto fail;
    snprintf(c->model_id, sizeof c->model_id, "%s", s);
    free(s);
    s = NULL;
    if ((rc = crom_h5_get_str(in->h5, ".", "scheme", &s)))
        goto fail;
    snprintf(c->scheme, sizeof c->scheme, "%s", s);
    free(s);
    if ((rc = crom_h5_get_i64(in->h5, ".", "rank", &r)))
        goto fail;
    if (r < 1 || r > 10000) {
        rc = crom_err(CROM_EDATA, "rank %lld is out of range", r);
        goto fail;
    }
    c->r = (int)r;
    if (crom_h5_has_attr(in->h5, ".", "map_rank")) {
        long long mr = 0;
        if ((rc = crom_h5_get_i64(in->h5, ".", "map_rank", &mr)))
            goto fail;
        if (mr < 1 || mr > r) {
            rc = crom_err(CROM_EDATA, "map_rank %lld is out of range (1..%lld)", mr, r);
            goto fail;
        }
        c->map_rank = (int)mr;
    }
    g = H5Gopen2(in->h5, "mesh", H5P_DEFAULT);
    if (g < 0) {
        rc = crom_err(CROM_EDATA, "no /mesh group");
        goto fail;
    }
    rc = crom_mesh_read_any(g, &c->mesh);
    H5Gclose(g);
    if (rc) {
        crom_err_ctx("/mesh");
        goto fail;
    }
    int shell = crom_mesh_is_surface(&c->mesh);
    /* the elements a shell's cubature may name: its triangles, then at most one hinge per edge (checked
     * exactly against the system by crom_nlsim_use_cubature) */
    c->ne = shell ? c->mesh.ntri + 3 * c->mesh.ntri / 2 : c->mesh.nt;
    size_t nv = (size_t)c->mesh.nv;
    if ((rc = crom_h5_read_f64(in->h5, "W", 3, d, &c->W)))
        goto fail;
    if (d[0] != nv || d[1] != 3 || d[2] != (hsize_t)r) {
        rc = crom_err(CROM_EDATA, "W has shape [%llu,%llu,%llu], expected [%zu,3,%lld]", (unsigned long long)d[0],
                      (unsigned long long)d[1], (unsigned long long)d[2], nv, r);
        goto fail;
    }
    if ((rc = crom_h5_read_f64(in->h5, "lumped_volume", 1, d, &c->vvol)) || d[0] != nv) {
        rc = rc ? rc : crom_err(CROM_EDATA, "lumped_volume has the wrong length");
        goto fail;
    }
    if ((rc = crom_h5_read_i32(in->h5, "elements", 1, d, &c->elem)))
        goto fail;
    c->k = (int)d[0];
    if (c->k < 1) {
        rc = crom_err(CROM_EDATA, "the cubature is empty (no tets)");
        goto fail;
    }
    hsize_t k = d[0];
    if ((rc = crom_h5_read_f64(in->h5, "weights", 1, d, &c->weight)) || d[0] != k ||
        (!shell && ((rc = crom_h5_read_f64(in->h5, "Dminv", 3, d, &c->Dminv)) || d[0] != k ||
                    (rc = crom_h5_read_f64(in->h5, "volume", 1, d, &c->vol)) || d[0] != k))) {
        rc = rc ? rc : crom_err(CROM_EDATA, "weights, Dminv and volume must have one entry per cubature tet");
        goto fail;
    }
    if ((rc = crom_h5_read_f64(in->h5, "WtVW", 2, d, &c->WtVW)) || d[0] != (hsize_t)r || d[1] != (hsize_t)r ||
        (rc = crom_h5_read_f64(in->h5, "WtV", 2, d, &c->WtV)) || d[0] != (hsize_t)r || d[1] != 3) {
        rc = rc ? rc : crom_err(CROM_EDATA, "WtVW or WtV has the wrong shape for rank %lld", r);
        goto fail;
    }
    if ((rc = crom_h5_read_i32(in->h5, "surface", 1, d, &c->surf)))
        goto fail;
    c->nsurf = (int)d[0];
    for (int j = 0; j < c->k && !rc; j++)
        if (c->elem[j] < 0 || c->elem[j] >= c->ne)
            rc = crom_err(CROM_EDATA, "/elements[%d] = %d is not %s of the mesh (0..%d)", j, c->elem[j],
                          shell ? "an energy element" : "a tet", c->ne - 1);
        else if (!(c->weight[j] >= 0) || !isfinite(c->weight[j]))
            rc = crom_err(CROM_EDATA, "/weights[%d] = %g is not a non-negative finite weight", j, c->weight[j]);
        else if (!shell && (!(c->vol[j] > 0) || !isfinite(c->vol[j])))
            rc = crom_err(CROM_EDATA, "/volume[%d] = %g is not a positive finite volume", j, c->vol[j]);
    for (int j = 0; j < c->nsurf && !rc; j++)
        if (c->surf[j] < 0 || c->surf[j] >= c->mesh.nv)
            rc = crom_err(CROM_EDATA, "/surface[%d] = %d is not a vertex of the mesh (0..%d)", j, c->surf[j],
                          c->mesh.nv - 1);
    if (rc)
        goto fail;
    for (size_t i = 0; i < nv * 3 * (size_t)r; i++)
        if (!isfinite(c->W[i])) {
            rc = crom_err(CROM_EDATA, "W is not finite");
            goto fail;
        }
    if (crom_h5_get_f64(in->h5, ".", "mesh_volume", &c->mesh_volume, 1))
        c->mesh_volume = crom_mesh_volume(&c->mesh);
    crom_err_clear();
    return 0;
fail:
    crom_err_ctx("%s", in->name);
    crom_cubature_free(c);
    return rc ? rc : CROM_EDATA;
}

int crom_cubature_load(const char *path, crom_cubature *c, char **history)
{
    memset(c, 0, sizeof *c);
    crom_in in;
    int rc = crom_in_open(&in, path);
    if (rc)
        return rc;
    rc = crom_cubature_read(&in, c);
    if (!rc && history) {
        *history = in.history;
        in.history = NULL;
    }
    crom_in_close(&in);
    return rc;
}

void crom_cubature_free(crom_cubature *c)
{
    crom_mesh_free(&c->mesh);
    free(c->W);
    free(c->vvol);
    free(c->elem);
    free(c->weight);
    free(c->Dminv);
    free(c->vol);
    free(c->WtVW);
    free(c->WtV);
    free(c->surf);
    memset(c, 0, sizeof *c);
}
