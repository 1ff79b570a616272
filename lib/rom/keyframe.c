/* keyframe.c — in-betweens of latent keyframes (see keyframe.h). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "rom/keyframe.h"

/* The segment k (from key k to k + 1) that parameter s falls in, clamped
 * to [0, nkeys − 1] (NaN: 0), and the fraction a of it. */
static int segment(int nkeys, double s, double *a)
{
    if (!(s > 0))
        s = 0; /* NaN too */
    if (s > nkeys - 1)
        s = nkeys - 1;
    int k = (int)floor(s);
    if (k > nkeys - 2)
        k = nkeys - 2;
    *a = s - k;
    return k;
}

void crom_keyframe_latent(int nkeys, int r, const double *keys, int interp, double s, double *q)
{
    double a;
    int k = segment(nkeys, s, &a);
    const double *z0 = keys + (size_t)k * r, *z1 = z0 + r;
    if (interp != CROM_KEYFRAME_CUBIC) {
        for (int i = 0; i < r; i++)
            q[i] = (1 - a) * z0[i] + a * z1[i];
        return;
    }
    /* Catmull–Rom: tangents from the neighbours, the end keys repeated */
    const double *zm = k > 0 ? z0 - r : z0, *zp = k + 2 < nkeys ? z1 + r : z1;
    double a2 = a * a, a3 = a2 * a;
    double h00 = 2 * a3 - 3 * a2 + 1, h10 = a3 - 2 * a2 + a, h01 = -2 * a3 + 3 * a2, h11 = a3 - a2;
    for (int i = 0; i < r; i++) {
        double m0 = 0.5 * (z1[i] - zm[i]), m1 = 0.5 * (zp[i] - z0[i]);
        q[i] = h00 * z0[i] + h10 * m0 + h01 * z1[i] + h11 * m1;
    }
}

void crom_keyframe_free(crom_keyframe *k)
{
    if (!k)
        return;
    crom_map_free(&k->map);
    crom_system_free(&k->sys);
    free(k->keys);
    free(k->xkeys);
    free(k->x);
    memset(k, 0, sizeof *k);
}

int crom_keyframe_init(crom_keyframe *k, const crom_model *model, const crom_mesh *mesh, const crom_scenario *sc,
                       int nkeys, const double *keys, int interp)
{
    memset(k, 0, sizeof *k);
    int r = model->rank, rc;
    if (nkeys < 2)
        return crom_err(CROM_EUSAGE, "keyframing needs at least two keys, got %d", nkeys);
    for (size_t i = 0; i < (size_t)nkeys * r; i++)
        if (!isfinite(keys[i]))
            return crom_err(CROM_EUSAGE, "key %zu: coordinate %zu is not finite", i / r, i % r + 1);
    if ((rc = crom_map_init(&k->map, model, mesh)))
        return rc;
    const crom_mesh *m = &k->map.mesh;
    if ((rc = crom_system_init(&k->sys, m, sc->youngs, sc->poisson, sc->density)) ||
        (rc = crom_system_set_materials(&k->sys, sc, m))) {
        crom_keyframe_free(k);
        return rc;
    }
    k->nkeys = nkeys;
    k->r = r;
    k->n = k->map.n;
    k->interp = interp;
    k->keys = crom_malloc(sizeof(double) * (size_t)nkeys * r);
    k->xkeys = crom_malloc(sizeof(double) * (size_t)nkeys * k->n);
    k->x = crom_malloc(sizeof(double) * (size_t)k->n);
    if (!k->keys || !k->xkeys || !k->x) {
        crom_keyframe_free(k);
        return CROM_EINTERNAL;
    }
    memcpy(k->keys, keys, sizeof(double) * (size_t)nkeys * r);
    for (int i = 0; i < nkeys; i++)
        if ((rc = crom_map_eval(&k->map, keys + (size_t)i * r, k->xkeys + (size_t)i * k->n, NULL))) {
            crom_err_ctx("key %d", i);
            crom_keyframe_free(k);
            return rc;
        }
    return 0;
}

int crom_keyframe_eval(crom_keyframe *k, double s, double *q, double *E_latent, double *E_pos)
{
    crom_keyframe_latent(k->nkeys, k->r, k->keys, k->interp, s, q);
    int rc = crom_map_eval(&k->map, q, k->x, NULL);
    if (rc || (rc = crom_system_energy(&k->sys, k->x, E_latent)))
        return rc;
    if (!E_pos)
        return 0;
    /* the same parameter, linearly between the decoded keyframes */
    double a;
    int i = segment(k->nkeys, s, &a);
    const double *x0 = k->xkeys + (size_t)i * k->n, *x1 = x0 + k->n;
    for (int j = 0; j < k->n; j++)
        k->x[j] = (1 - a) * x0[j] + a * x1[j];
    return crom_system_energy(&k->sys, k->x, E_pos);
}
