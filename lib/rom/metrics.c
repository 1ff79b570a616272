/* metrics.c — energy, isometry and mode-collapse measures of a subspace
 * (see metrics.h). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <cblas.h>
#include <lapacke.h>

#include "base/err.h"
#include "base/rng.h"
#include "phys/modes.h"
#include "rom/metrics.h"

void crom_metrics_defaults(crom_metrics_opts *o)
{
    memset(o, 0, sizeof *o);
    o->samples = 256;
    o->dist = CROM_METRICS_NORMAL;
    o->radius = 1;
    o->sigma = 1;
    o->pairs_of = 100;
    o->seed = 1;
}

void crom_metrics_free(crom_metrics *m)
{
    if (!m)
        return;
    free(m->gram_eig);
    free(m->corr_eig);
    m->gram_eig = m->corr_eig = NULL;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static double quantile(const double *sorted, long n, double p)
{
    if (n <= 0)
        return NAN;
    double k = p * (double)(n - 1);
    long i = (long)floor(k);
    if (i >= n - 1)
        return sorted[n - 1];
    double f = k - (double)i;
    return sorted[i] * (1 - f) + sorted[i + 1] * f;
}

void crom_metrics_sample(crom_rng *rng, const crom_metrics_opts *o, int r, double *q)
{
    double s = 0;
    for (int k = 0; k < r; k++) {
        double a = o->box_freq ? crom_modes_box_half(o->box_freq, r, o->radius, k) : o->radius;
        q[k] = o->dist == CROM_METRICS_BOX ? a * (2 * crom_rng_uniform(rng) - 1) : crom_rng_normal(rng);
        s += q[k] * q[k];
    }
    if (o->dist == CROM_METRICS_NORMAL)
        for (int k = 0; k < r; k++)
            q[k] *= o->radius;
    else if (o->dist == CROM_METRICS_SPHERE)
        for (int k = 0; k < r; k++)
            q[k] *= o->radius / sqrt(s);
}

/* elastic energy, and potential of gravity -Σ m g·u, of positions x */
static int energies(const crom_system *fem, const double *X, const double *x, const double g[3], double *Eel,
                    double *Egr, double *rms)
{
    crom_fem_opts fo = {0, 0, NULL, 1};
    int rc = crom_system_assemble(fem, x, &fo, Eel, NULL, NULL);
    if (rc)
        return rc;
    double pg = 0, u2 = 0;
    for (int i = 0; i < 3 * fem->nv; i++) {
        double u = x[i] - X[i];
        pg -= fem->mass[i / 3] * g[i % 3] * u;
        u2 += fem->mass[i / 3] * u * u;
    }
    *Egr = pg;
    *rms = sqrt(u2 / fem->total_mass);
    return 0;
}

/* What the three measures share: the map on its mesh operator, the
 * comparison basis (or NULL), gravity, the options, and the first P
 * samples, kept for the pairs. */
typedef struct {
    crom_map *map, *compare;
    const crom_system *fem;
    const double *g;
    const crom_metrics_opts *o;
    int P;           /* samples kept */
    double *xs, *qs; /* [P][n], [P][r] their positions and latents */
} measure;

/* Energy over the samples: of each latent sample q of o's distribution,
 * the elastic and potential energies and the RMS displacement of x(q)
 * (the first P samples kept), and with a comparison basis the energy of a
 * random direction of it at the same RMS displacement. */
static int energy_samples(measure *M, crom_metrics *out)
{
    const crom_system *fem = M->fem;
    const crom_metrics_opts *o = M->o;
    crom_map *map = M->map, *compare = M->compare;
    int r = map->r, n = map->n, S = out->samples, P = M->P, rc = 0;
    const double *X = map->mesh.X;
    double *x = crom_malloc(sizeof(double) * (size_t)n), *q = crom_malloc(sizeof(double) * (size_t)r);
    int rc2 = compare ? compare->r : 1;
    double *c = crom_malloc(sizeof(double) * (size_t)rc2), *uc = crom_malloc(sizeof(double) * (size_t)n);
    if (!x || !q || !c || !uc) {
        rc = CROM_EINTERNAL;
        goto done;
    }
    crom_rng rng, crng;
    crom_rng_seed(&rng, o->seed);
    crom_rng_seed(&crng, o->seed ^ 0xc0ffee);
    double se = 0, sp = 0, sr = 0, sc = 0, emin = INFINITY, emax = -INFINITY, rmax = 0;
    for (int s = 0; s < S; s++) {
        crom_metrics_sample(&rng, o, r, q);
        if ((rc = crom_map_eval(map, q, x, NULL)))
            goto done;
        double Eel, Egr, rms;
        if ((rc = energies(fem, X, x, M->g, &Eel, &Egr, &rms)))
            goto done;
        se += Eel;
        sp += Eel + Egr;
        sr += rms;
        emin = fmin(emin, Eel);
        emax = fmax(emax, Eel);
        rmax = fmax(rmax, rms);
        if (s < P) {
            memcpy(M->xs + (size_t)s * n, x, sizeof(double) * (size_t)n);
            memcpy(M->qs + (size_t)s * r, q, sizeof(double) * (size_t)r);
        }
        if (compare) {
            /* a random direction of the other basis at the same RMS displacement */
            double u2 = 0;
            for (int k = 0; k < compare->r; k++)
                c[k] = crom_rng_normal(&crng);
            cblas_dgemv(CblasRowMajor, CblasNoTrans, n, compare->r, 1.0, compare->B, compare->r, c, 1, 0.0, uc, 1);
            for (int i = 0; i < n; i++)
                u2 += fem->mass[i / 3] * uc[i] * uc[i];
            double t = u2 > 0 ? rms / sqrt(u2 / fem->total_mass) : 0, Ec, Eg2, r2;
            for (int i = 0; i < n; i++)
                x[i] = X[i] + t * uc[i];
            if ((rc = energies(fem, X, x, M->g, &Ec, &Eg2, &r2)))
                goto done;
            sc += Ec;
        }
    }
    out->energy_mean = se / S;
    out->potential_mean = sp / S;
    out->rms_mean = sr / S;
    out->rms_max = rmax;
    out->energy_min = emin;
    out->energy_max = emax;
    if (compare)
        out->cmp_energy_mean = sc / S;
done:
    free(x);
    free(q);
    free(c);
    free(uc);
    return rc;
}

/* Isometry over the pairs of the P kept samples (Sharp et al. eqs. 2-3):
 * the quantiles of |x(q) - x(q')|_M / sqrt(m) / (σ |q - q'|) and the mean
 * squared log-ratio. */
static int isometry(const measure *M, crom_metrics *out)
{
    const crom_system *fem = M->fem;
    int r = M->map->r, n = M->map->n, P = M->P;
    long np = (long)P * (P - 1) / 2, k = 0;
    double *ratio = crom_malloc(sizeof(double) * (size_t)(np > 0 ? np : 1));
    if (!ratio)
        return CROM_EINTERNAL;
    double lsq = 0;
    for (int a = 0; a < P; a++)
        for (int b = a + 1; b < P; b++) {
            double D2 = 0, dq = 0;
            for (int i = 0; i < n; i++) {
                double d = M->xs[(size_t)a * n + i] - M->xs[(size_t)b * n + i];
                D2 += fem->mass[i / 3] * d * d;
            }
            for (int j = 0; j < r; j++) {
                double d = M->qs[(size_t)a * r + j] - M->qs[(size_t)b * r + j];
                dq += d * d;
            }
            if (!(dq > 0))
                continue;
            double ra = sqrt(D2 / fem->total_mass) / (M->o->sigma * sqrt(dq));
            ratio[k++] = ra;
            double l = ra > 0 ? log(ra) : -745;
            lsq += l * l;
        }
    out->npairs = k;
    qsort(ratio, (size_t)k, sizeof(double), cmp_double);
    out->iso_q05 = quantile(ratio, k, 0.05);
    out->iso_median = quantile(ratio, k, 0.5);
    out->iso_q95 = quantile(ratio, k, 0.95);
    out->iso_logsq = k ? lsq / k : NAN;
    free(ratio);
    return 0;
}

/* Collapse (Neural Modes §4.4): G = JᵀMJ / m at q = 0, the eigenvalues of
 * r G / tr G and of the correlation matrix D^-1/2 G D^-1/2. */
static int collapse(const measure *M, crom_metrics *out)
{
    const crom_system *fem = M->fem;
    int r = M->map->r, n = M->map->n, rc = 0;
    double *q = crom_calloc((size_t)r, sizeof(double)), *J = crom_malloc(sizeof(double) * (size_t)n * r);
    double *G = crom_malloc(sizeof(double) * (size_t)r * r), *C = crom_malloc(sizeof(double) * (size_t)r * r);
    if (!q || !J || !G || !C) {
        rc = CROM_EINTERNAL;
        goto done;
    }
    if ((rc = crom_map_eval(M->map, q, NULL, J)))
        goto done;
    for (int i = 0; i < n; i++) {
        double s = sqrt(fem->mass[i / 3] / fem->total_mass);
        for (int j = 0; j < r; j++)
            J[(size_t)i * r + j] *= s;
    }
    cblas_dsyrk(CblasRowMajor, CblasUpper, CblasTrans, r, n, 1.0, J, r, 0.0, G, r);
    double tr = 0;
    for (int a = 0; a < r; a++) {
        tr += G[a * r + a];
        for (int b = 0; b < a; b++)
            G[a * r + b] = G[b * r + a];
    }
    out->gram_trace = tr;
    for (int a = 0; a < r; a++)
        for (int b = 0; b < r; b++) {
            double da = G[a * r + a], db = G[b * r + b];
            C[a * r + b] = da > 0 && db > 0 ? G[a * r + b] / sqrt(da * db) : (a == b);
        }
    for (int i = 0; i < r * r; i++)
        G[i] *= tr > 0 ? r / tr : 0;
    if (LAPACKE_dsyev(LAPACK_ROW_MAJOR, 'N', 'U', r, G, r, out->gram_eig) != 0 ||
        LAPACKE_dsyev(LAPACK_ROW_MAJOR, 'N', 'U', r, C, r, out->corr_eig) != 0)
        rc = crom_err(CROM_EINTERNAL, "eigenvalues of the latent Gram matrix failed");
done:
    free(q);
    free(J);
    free(G);
    free(C);
    return rc;
}

int crom_metrics_compute(crom_map *map, const crom_system *fem, const double g[3], const crom_metrics_opts *o,
                         crom_map *compare, crom_metrics *out)
{
    memset(out, 0, sizeof *out);
    int r = map->r, n = map->n, S = o->samples < 1 ? 1 : o->samples, rc = 0;
    out->r = r;
    out->samples = S;
    out->cmp_energy_mean = NAN;
    if (fem->nv != map->nv)
        return crom_err(CROM_EUSAGE, "the mesh operator has %d vertices, the map %d", fem->nv, map->nv);
    if (compare && (compare->nonlinear || compare->nv != map->nv ||
                    crom_map_same_mesh(&compare->mesh, &map->mesh)))
        return crom_err(CROM_EUSAGE, "the comparison subspace must be a linear basis of the same mesh");
    int P = S < o->pairs_of ? S : o->pairs_of;
    measure M = {map, compare, fem, g, o, P, crom_malloc(sizeof(double) * (size_t)P * n),
                 crom_malloc(sizeof(double) * (size_t)P * r)};
    out->gram_eig = crom_malloc(sizeof(double) * (size_t)r);
    out->corr_eig = crom_malloc(sizeof(double) * (size_t)r);
    if (!M.xs || !M.qs || !out->gram_eig || !out->corr_eig)
        rc = CROM_EINTERNAL;
    if (!rc)
        rc = energy_samples(&M, out);
    if (!rc)
        rc = isometry(&M, out);
    if (!rc)
        rc = collapse(&M, out);
    free(M.xs);
    free(M.qs);
    if (rc)
        crom_metrics_free(out);
    return rc;
}

void crom_metrics_training_dist(const crom_model *m, double diag, crom_metrics_opts *o)
{
    if (crom_model_latent_normal(m)) {
        o->dist = CROM_METRICS_NORMAL;
        o->radius = 1;
    } else if (!strcmp(m->basis, "neuralmodes") && m->latent_box > 0) {
        o->dist = CROM_METRICS_BOX;
        o->radius = m->latent_box;
        o->box_freq = m->latent_box_scaled ? m->frequencies : NULL;
    } else {
        o->dist = CROM_METRICS_SPHERE;
        o->radius = 0.05 * diag;
    }
}

/* ============================================== against constrained equilibria */

/* Per-element von Mises stress (Pa) of the displacement u and the
 * elements' rest measures: a solid's tets, a shell's membrane triangles. */
static int element_stress(const crom_system *sys, const crom_mesh *mesh, const crom_material *mat, const double *u,
                          double *x, double *w, double *s)
{
    int n = sys->n;
    if (!sys->shell) {
        crom_fem_tet_measures(mesh, u, mat, w, NULL, NULL, s);
        return 0;
    }
    for (int i = 0; i < n; i++)
        x[i] = mesh->X[i] + u[i];
    const crom_shell *sh = &sys->sh;
    for (int t = 0; t < sh->nt; t++) {
        double xe[9];
        for (int a = 0; a < 3; a++)
            memcpy(xe + 3 * a, x + 3 * (size_t)sh->tris[3 * t + a], sizeof(double) * 3);
        w[t] = sh->area[t];
        s[t] = crom_shell_tri_mises(&sh->mat, xe, sh->Dminv + 4 * (size_t)t);
    }
    return 0;
}

/* The largest |Wᵀ M u / m − z| over the r modal coordinates, W the map's
 * linear part (its first r feature columns). */
static double modal_dev(const crom_map *map, const crom_system *sys, const double *u, const double *z)
{
    double dev = 0;
    for (int a = 0; a < map->r; a++) {
        double za = 0;
        for (int i = 0; i < map->n; i++)
            za += sys->mass[i / 3] * map->B[(size_t)i * map->p + a] * u[i];
        dev = fmax(dev, fabs(za / sys->total_mass - z[a]));
    }
    return dev;
}

int crom_metrics_equilibria(crom_map *map, const crom_system *sys, const crom_material *mat,
                            const unsigned char *fixed, int K, const double *Z, const double *U, crom_metrics_eq *out)
{
    memset(out, 0, sizeof *out);
    int r = map->r, n = map->n, ne = sys->shell ? sys->sh.nt : sys->fem.nt;
    if (sys->nv != map->nv)
        return crom_err(CROM_EUSAGE, "the system has %d vertices, the map %d", sys->nv, map->nv);
    if (K < 1)
        return crom_err(CROM_EUSAGE, "no equilibria to measure");
    if (map->nonlinear ? map->rl != r : map->p != r)
        return crom_err(CROM_EUSAGE, "the subspace has no linear modal part W (it is not linear modes or a "
                                     "neuralmodes map): its latent is not the modal coordinates z");
    double *x = crom_malloc(sizeof(double) * (size_t)n), *u = crom_malloc(sizeof(double) * (size_t)n);
    double *g = crom_malloc(sizeof(double) * (size_t)n), *gs = crom_malloc(sizeof(double) * (size_t)n);
    double *w = crom_malloc(sizeof(double) * (size_t)ne), *s = crom_malloc(sizeof(double) * (size_t)ne);
    double *sg = crom_malloc(sizeof(double) * (size_t)ne), *xt = crom_malloc(sizeof(double) * (size_t)n);
    int rc = 0;
    if (!x || !u || !g || !gs || !w || !s || !sg || !xt)
        rc = CROM_EINTERNAL;
    double zscale = 0;
    for (size_t i = 0; i < (size_t)K * r; i++)
        zscale = fmax(zscale, fabs(Z[i]));
    crom_fem_opts fo = {0, 0, fixed, 1};
    for (int k = 0; k < K && !rc; k++) {
        const double *zk = Z + (size_t)k * r, *us = U + (size_t)k * n;
        /* do the map's modes give the equilibrium's z? */
        out->zmax_dev = fmax(out->zmax_dev, modal_dev(map, sys, us, zk));
        if (!(out->zmax_dev <= 1e-6 * zscale + 1e-15)) {
            rc = crom_err(CROM_EUSAGE, "the subspace's modes are not those of the equilibria: W^T M u* / m is %.3g m "
                                       "from z (equilibrium %d)", out->zmax_dev, k);
            break;
        }
        if ((rc = crom_map_eval(map, zk, x, NULL)))
            break;
        for (int i = 0; i < n; i++)
            u[i] = x[i] - map->mesh.X[i];
        out->zmap_dev = fmax(out->zmap_dev, modal_dev(map, sys, u, zk)); /* the subspace's own coordinates */
        /* energies and forces, of the subspace and of the equilibrium */
        double E, Es, f2 = 0, fs2 = 0, d2 = 0, s2 = 0;
        int nfree = 0;
        if ((rc = crom_system_assemble(sys, x, &fo, &E, g, NULL)))
            break;
        for (int i = 0; i < n; i++)
            xt[i] = map->mesh.X[i] + us[i];
        if ((rc = crom_system_assemble(sys, xt, &fo, &Es, gs, NULL)))
            break;
        for (int v = 0; v < sys->nv; v++) {
            int fr = 0;
            for (int c = 0; c < 3; c++) {
                int i = 3 * v + c;
                double du = x[i] - xt[i];
                d2 += sys->mass[v] * du * du;
                s2 += sys->mass[v] * us[i] * us[i];
                if (fixed && fixed[i])
                    continue;
                fr = 1;
                f2 += (g[i] - gs[i]) * (g[i] - gs[i]);
                fs2 += gs[i] * gs[i];
            }
            nfree += fr;
        }
        out->energy += E / K;
        out->energy_gt += Es / K;
        out->below += E < Es - 1e-9 * fabs(Es);
        out->energy_max = fmax(out->energy_max, E);
        out->energy_gt_max = fmax(out->energy_gt_max, Es);
        out->force_err += (nfree ? sqrt(f2 / nfree) : 0) / K;
        out->force_gt += (nfree ? sqrt(fs2 / nfree) : 0) / K;
        out->disp_err += (s2 > 0 ? sqrt(d2 / s2) : 0) / K;
        /* stresses */
        element_stress(sys, &map->mesh, mat, u, xt, w, s);
        element_stress(sys, &map->mesh, mat, us, xt, w, sg);
        double W0 = 0, S = 0, Sg = 0, Sd = 0;
        for (int e = 0; e < ne; e++) {
            if (!isfinite(s[e]) || !isfinite(sg[e])) {
                rc = crom_err(CROM_EDATA, "equilibrium %d: the stress of element %d is not defined (inverted)", k, e);
                break;
            }
            W0 += w[e];
            S += w[e] * s[e];
            Sg += w[e] * sg[e];
            Sd += w[e] * fabs(s[e] - sg[e]);
            out->stress_max = fmax(out->stress_max, s[e]);
            out->stress_gt_max = fmax(out->stress_gt_max, sg[e]);
        }
        out->stress += S / W0 / K;
        out->stress_gt += Sg / W0 / K;
        out->stress_err += (Sg > 0 ? Sd / Sg : 0) / K;
        out->count = k + 1;
    }
    free(x), free(u), free(g), free(gs), free(w), free(s), free(sg), free(xt);
    return rc;
}
