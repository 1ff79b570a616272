/* indicator.c — the a-posteriori error indicator of reduced runs (see
 * indicator.h). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "rom/indicator.h"

int crom_indicator_init(crom_indicator *ind, const crom_mesh *mesh, const crom_scenario *sc,
                        const crom_model *model)
{
    memset(ind, 0, sizeof *ind);
    if (crom_mesh_is_surface(mesh)) /* measured: 4e10 on a hanging sheet */
        return crom_err(CROM_EUSAGE, "--indicator measures solids: a flat shell's stiffness at rest has no membrane "
                        "resistance out of its plane, so K0^-1 g does not estimate its error");
    int rc = crom_sim_init(&ind->sim, mesh, sc);
    if (rc)
        return rc;
    size_t n = 3 * (size_t)mesh->nv;
    ind->nv = mesh->nv;
    ind->xp = crom_malloc(sizeof(double) * n);
    ind->vp = crom_malloc(sizeof(double) * n);
    ind->x = crom_malloc(sizeof(double) * n);
    ind->v = crom_malloc(sizeof(double) * n);
    if (!ind->xp || !ind->vp || !ind->x || !ind->v) {
        crom_indicator_free(ind);
        return CROM_EINTERNAL;
    }
    if (!model)
        return 0;
    ind->r = model->rank;
    size_t outside = 0;
    ind->W = crom_malloc(sizeof(double) * n * (size_t)model->rank);
    rc = ind->W ? crom_model_eval_mesh(model, mesh, CROM_MESH_CRACK_OFFSET, ind->W, &outside, NULL) : CROM_EINTERNAL;
    if (!rc && outside)
        rc = crom_err(CROM_EDATA, "%zu of the %d vertices lie outside the model's mesh field", outside, mesh->nv);
    if (rc)
        crom_indicator_free(ind);
    return rc;
}

/* positions X + W q (velocities: W q, with X NULL) */
static void decode(const crom_indicator *ind, const double *X, const double *q, double *x)
{
    size_t n = 3 * (size_t)ind->nv;
    int r = ind->r;
    for (size_t i = 0; i < n; i++) {
        const double *w = ind->W + i * (size_t)r;
        double s = 0;
        for (int k = 0; k < r; k++)
            s += w[k] * q[k];
        x[i] = (X ? X[i] : 0) + s;
    }
}

int crom_indicator_step(crom_indicator *ind, double t1, const double *prev, const double *prevdot,
                        const double *now, double *err, double *urms, double *bc)
{
    if (ind->W) {
        const double *X = ind->sim.mesh->X;
        decode(ind, X, prev, ind->xp);
        decode(ind, NULL, prevdot, ind->vp);
        decode(ind, X, now, ind->x);
        prev = ind->xp;
        prevdot = ind->vp;
        now = ind->x;
    }
    int rc = crom_sim_residual(&ind->sim, t1, prev, prevdot, now, err, urms, bc);
    if (rc)
        return rc;
    ind->err = *err;
    ind->urms = *urms;
    ind->bc = *bc;
    ind->se += *err * *err;
    ind->su += *urms * *urms;
    if (*urms > 0 && *err / *urms > ind->worst) {
        ind->worst = *err / *urms;
        ind->at = t1;
    }
    return 0;
}

double crom_indicator_total(const crom_indicator *ind)
{
    return ind->su > 0 ? sqrt(ind->se / ind->su) : 0;
}

int crom_indicator_remesh(crom_indicator *ind, const crom_mesh *mesh, const crom_scenario *sc,
                          const crom_model *model)
{
    crom_indicator keep = *ind;
    crom_indicator_free(ind);
    int rc = crom_indicator_init(ind, mesh, sc, model);
    if (rc)
        return rc;
    ind->se = keep.se;
    ind->su = keep.su;
    ind->worst = keep.worst;
    ind->at = keep.at;
    return 0;
}

void crom_indicator_initial(crom_indicator *ind, const double *x0, const double *v0, double *ex, double *ev)
{
    const crom_sim *s = &ind->sim; /* fresh from crom_sim_init: rest and the initial velocity field */
    const double *X = s->mesh->X;
    if (ind->W) {
        decode(ind, X, x0, ind->x);
        decode(ind, NULL, v0, ind->v);
        x0 = ind->x;
        v0 = ind->v;
    }
    double m = 0, dx = 0, dv = 0;
    for (int i = 0; i < s->nv; i++) {
        double mi = s->sys.mass[i];
        m += mi;
        for (int c = 0; c < 3; c++) {
            size_t k = 3 * (size_t)i + (size_t)c;
            dx += mi * (x0[k] - X[k]) * (x0[k] - X[k]);
            dv += mi * (v0[k] - s->v[k]) * (v0[k] - s->v[k]);
        }
    }
    *ex = m > 0 ? sqrt(dx / m) : 0;
    *ev = m > 0 ? sqrt(dv / m) : 0;
}

void crom_indicator_free(crom_indicator *ind)
{
    crom_sim_free(&ind->sim);
    free(ind->W);
    free(ind->xp);
    free(ind->vp);
    free(ind->x);
    free(ind->v);
    memset(ind, 0, sizeof *ind);
}
