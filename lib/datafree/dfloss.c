/* dfloss.c — the pieces the data-free losses share (see dfloss.h). */
#ifdef _OPENMP
#include <omp.h>
#endif
#include <math.h>
#include <lapacke.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "datafree/dfloss.h"

/* ============================================================ the cubature */

int crom_dfloss_cub_init(crom_dfloss_cub *c, int nv, int maxrows)
{
    memset(c, 0, sizeof *c);
    c->nv = nv;
    c->maxrows = maxrows;
    c->loc = crom_malloc(sizeof(int) * (size_t)(nv ? nv : 1));
    c->vs = crom_malloc(sizeof(int) * (size_t)(maxrows ? maxrows : 1));
    c->mloc = crom_malloc(sizeof(double) * (size_t)(maxrows ? maxrows : 1));
    if (!c->loc || !c->vs || !c->mloc) {
        crom_dfloss_cub_free(c);
        return CROM_EINTERNAL;
    }
    for (int v = 0; v < nv; v++)
        c->loc[v] = -1;
    return 0;
}

void crom_dfloss_cub_free(crom_dfloss_cub *c)
{
    free(c->loc);
    free(c->vs);
    free(c->mloc);
    memset(c, 0, sizeof *c);
}

void crom_dfloss_cub_clear(crom_dfloss_cub *c)
{
    for (int i = 0; i < c->ns; i++)
        c->loc[c->vs[i]] = -1;
    c->ns = 0;
}

int crom_dfloss_cub_draw(crom_dfloss_cub *c, const crom_fem *fem, double rho, int K, const int *tets)
{
    crom_dfloss_cub_clear(c);
    for (int k = 0; k < K; k++) {
        if (tets[k] < 0 || tets[k] >= fem->nt) {
            int t = tets[k];
            crom_dfloss_cub_clear(c);
            return crom_err(CROM_EUSAGE, "tet %d out of range", t);
        }
        for (int a = 0; a < 4; a++) {
            int v = fem->tets[4 * (size_t)tets[k] + a];
            if (c->loc[v] >= 0)
                continue;
            if (c->ns >= c->maxrows) {
                crom_dfloss_cub_clear(c);
                return crom_err(CROM_EUSAGE, "more than %d vertices", c->maxrows);
            }
            c->loc[v] = c->ns;
            c->vs[c->ns++] = v;
        }
    }
    /* each drawn tet stands for nt/K of them; lumped masses of the drawn tets */
    c->wK = (double)fem->nt / K;
    c->mhat = 0;
    memset(c->mloc, 0, sizeof(double) * (size_t)c->ns);
    for (int k = 0; k < K; k++)
        for (int a = 0; a < 4; a++)
            c->mloc[c->loc[fem->tets[4 * (size_t)tets[k] + a]]] += c->wK * rho * fem->vol[tets[k]] / 4;
    for (int i = 0; i < c->ns; i++)
        c->mhat += c->mloc[i];
    return 0;
}

int crom_dfloss_tets(const crom_fem *fem, int K, const int *tets, double wK, const double *X, const double *u,
                     const int *loc, double *E, double *g)
{
    double Eb = 0;
    int bad = 0;
    for (int k = 0; k < K; k++) {
        int tt = tets[k], l[4];
        double xe[12], ge[12], Ee;
        for (int a = 0; a < 4; a++) {
            int v = fem->tets[4 * (size_t)tt + a];
            l[a] = loc ? loc[v] : v;
            for (int d = 0; d < 3; d++)
                xe[3 * a + d] = X ? X[3 * (size_t)v + d] + u[3 * (size_t)l[a] + d] : u[3 * (size_t)l[a] + d];
        }
        if (crom_fem_tet_eval(crom_fem_tet_material(fem, tt), xe, fem->Dminv + 9 * (size_t)tt, fem->vol[tt], 0, &Ee, ge, NULL)) {
            bad = 1;
            break;
        }
        Eb += wK * Ee;
        for (int a = 0; a < 4; a++)
            for (int d = 0; d < 3; d++)
                g[3 * (size_t)l[a] + d] += wK * ge[3 * a + d];
    }
    *E = Eb;
    return bad;
}

int crom_dfloss_check(int B, const int *bad, const double *E, const char *what)
{
    for (int b = 0; b < B; b++)
        if (bad[b] || !isfinite(E[b]))
            return crom_err(CROM_EDATA, "%s %d of the batch has a non-finite energy", what, b);
    return 0;
}

int crom_dfloss_terms(crom_dftrain_terms *t, double obj, double energy, double penalty, double tangent,
                      const char *what)
{
    if (t) {
        t->objective = obj;
        t->energy = energy;
        t->penalty = penalty;
        t->tangent = tangent;
    }
    return isfinite(obj) ? 0 : crom_err(CROM_EDATA, "the %s objective is not finite", what);
}

/* ============================================================ the anchor */

void crom_dfloss_anchor_grad(int rows, int n, const double *d, const unsigned char *mask, float *out)
{
    float *d0 = out + (size_t)(rows - 1) * n;
    memset(d0, 0, sizeof(float) * (size_t)n);
    for (int b = 0; b < rows - 1; b++)
        for (int i = 0; i < n; i++) {
            double v = mask && mask[i] ? 0.0 : d[(size_t)b * n + i];
            out[(size_t)b * n + i] = (float)v;
            d0[i] -= (float)v;
        }
}

int crom_dfloss_thread(void)
{
#ifdef _OPENMP
    return omp_get_thread_num();
#else
    return 0;
#endif
}

/* ============================================================ pins */

int crom_dfloss_pinned(const unsigned char *fixed, int v)
{
    return fixed && (fixed[3 * (size_t)v] || fixed[3 * (size_t)v + 1] || fixed[3 * (size_t)v + 2]);
}

int crom_dfloss_pinned_part(const crom_mesh *m, const unsigned char *fixed, int extra_pins, int extra_tris,
                            int *npins, double **pinX, int *ntri, double **triX)
{
    int nv = m->nv, np = 0, nb = 0, *tri = NULL, rc;
    *npins = *ntri = 0;
    for (int v = 0; v < nv; v++)
        np += crom_dfloss_pinned(fixed, v);
    if (np && (rc = crom_mesh_boundary(m, &nb, &tri, NULL)))
        return rc;
    *pinX = crom_malloc(sizeof(double) * 3 * ((size_t)np + (size_t)extra_pins + 1));
    *triX = crom_malloc(sizeof(double) * 9 * ((size_t)nb + (size_t)extra_tris + 1));
    if (!*pinX || !*triX) {
        free(tri);
        return CROM_EINTERNAL;
    }
    for (int v = 0; v < nv; v++)
        if (crom_dfloss_pinned(fixed, v))
            memcpy(*pinX + 3 * (size_t)(*npins)++, m->X + 3 * (size_t)v, sizeof(double) * 3);
    for (int k = 0; k < nb; k++) {
        int all = 1;
        for (int a = 0; a < 3; a++)
            all &= crom_dfloss_pinned(fixed, tri[3 * k + a]);
        if (!all)
            continue;
        for (int a = 0; a < 3; a++)
            memcpy(*triX + 9 * (size_t)*ntri + 3 * a, m->X + 3 * (size_t)tri[3 * k + a], sizeof(double) * 3);
        (*ntri)++;
    }
    free(tri);
    return 0;
}

double crom_dfloss_rest_floor(int r, const double *G, double tau, double w, double *A, double *work)
{
    double *V = work, *lam = work + (size_t)r * r, T = 0, val = 0, s = 0;
    memset(A, 0, sizeof(double) * (size_t)r * r);
    for (int k = 0; k < r; k++)
        T += G[(size_t)k * r + k];
    if (!(T > 0) || !isfinite(T))
        return NAN;
    memcpy(V, G, sizeof(double) * (size_t)r * r);
    if (LAPACKE_dsyev(LAPACK_ROW_MAJOR, 'V', 'U', r, V, r, lam) != 0)
        return NAN;
    for (int k = 0; k < r; k++) {
        double mu = fmax(r * lam[k] / T, 1e-300);
        if (mu >= tau)
            continue;
        double l = log(mu / tau), hp = 2 * l / mu; /* h(μ), h'(μ) */
        val += l * l;
        s += hp * lam[k];
        double f = r / T; /* dμ_k/dλ_k */
        for (int i = 0; i < r; i++)
            for (int j = 0; j < r; j++)
                A[(size_t)i * r + j] += w * f * hp * V[(size_t)i * r + k] * V[(size_t)j * r + k];
    }
    for (int i = 0; i < r; i++) /* through T */
        A[(size_t)i * r + i] -= w * (r / (T * T)) * s;
    return val;
}

int crom_dfloss_materials(crom_fem *fem, const crom_scenario *sc, const crom_mesh *m, crom_material **mats,
                          int **tmat)
{
    *mats = NULL;
    *tmat = NULL;
    if (!sc || !sc->nmat)
        return 0;
    int nmat, rc;
    if (!(*mats = crom_malloc(sizeof **mats * (CROM_SCENARIO_MAX + 1))))
        return CROM_EINTERNAL;
    if ((rc = crom_scenario_materials(sc, m, *mats, &nmat, tmat)) || (rc = crom_fem_set_materials(fem, *mats, nmat, *tmat))) {
        free(*mats);
        free(*tmat);
        *mats = NULL;
        *tmat = NULL;
    }
    return rc;
}
