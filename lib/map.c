/* map.c — one-mesh subspace maps x(q) = X + W q + N(q) in double (see map.h). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <cblas.h>

#include "err.h"
#include "map.h"

#define INV_SQRT2 0.70710678118654752440
#define INV_SQRT2PI 0.39894228040143267794

void crom_map_free(crom_map *map)
{
    if (!map)
        return;
    crom_mesh_free(&map->mesh);
    free(map->W);
    free(map->mem);
    free(map->a0);
    free(map->a1);
    free(map->z1);
    free(map->t0);
    free(map->t1);
    memset(map, 0, sizeof *map);
}

int crom_map_same_mesh(const crom_mesh *a, const crom_mesh *b)
{
    if (a->nv != b->nv || a->nt != b->nt)
        return 1;
    for (size_t i = 0; i < 3 * (size_t)a->nv; i++)
        if (fabs(a->X[i] - b->X[i]) > 1e-9 * (1 + fabs(a->X[i])))
            return 1;
    return memcmp(a->tets, b->tets, sizeof(int) * 4 * (size_t)a->nt) != 0;
}

/* Copy the network of a map model into double layers. */
static int load_net(crom_map *map, const crom_nn_mlp *net)
{
    const crom_nn_spec *sp = &net->spec;
    map->nlayers = sp->nlayers;
    map->act = sp->act;
    map->omega0 = sp->omega0;
    int maxw = 1; /* widest input of a layer: the latent and the hidden layers */
    for (int l = 0; l <= sp->nlayers; l++) {
        map->width[l] = sp->width[l];
        if (l < sp->nlayers && sp->width[l] > maxw)
            maxw = sp->width[l];
    }
    map->mem = crom_malloc(sizeof(double) * net->nparams);
    size_t wr = (size_t)maxw * (size_t)(map->r + 1);
    map->a0 = crom_malloc(sizeof(double) * (size_t)maxw);
    map->a1 = crom_malloc(sizeof(double) * (size_t)maxw);
    map->z1 = crom_malloc(sizeof(double) * (size_t)maxw);
    map->t0 = crom_malloc(sizeof(double) * wr);
    map->t1 = crom_malloc(sizeof(double) * wr);
    if (!map->mem || !map->a0 || !map->a1 || !map->z1 || !map->t0 || !map->t1)
        return CROM_EINTERNAL;
    for (size_t i = 0; i < net->nparams; i++)
        map->mem[i] = net->params[i];
    for (int l = 0; l < sp->nlayers; l++) {
        map->w[l] = map->mem + net->layer[l].woff;
        map->b[l] = map->mem + net->layer[l].boff;
    }
    map->nonlinear = 1;
    return 0;
}

int crom_map_init(crom_map *map, const crom_model *model, const crom_mesh *mesh)
{
    memset(map, 0, sizeof *map);
    int rc = 0, r = model->rank;
    map->r = r;
    if (model->field == CROM_FIELD_MAP) {
        if (mesh && crom_map_same_mesh(mesh, &model->mesh))
            return crom_err(CROM_EDATA, "model %s (basis '%s') is a map of one mesh and decodes only onto its own "
                            "mesh (%d vertices, %d tets); the given mesh has %d vertices, %d tets%s",
                            model->model_id, model->basis, model->mesh.nv, model->mesh.nt, mesh->nv, mesh->nt,
                            mesh->nv == model->mesh.nv ? " at other positions" : "");
        /* the same mesh: keep the given one's regions if it has any */
        rc = crom_mesh_copy(mesh && mesh->nregions ? mesh : &model->mesh, &map->mesh);
    } else if (model->field == CROM_FIELD_MESH) {
        rc = crom_mesh_copy(mesh ? mesh : &model->mesh, &map->mesh);
    } else if (model->field == CROM_FIELD_MLP) {
        if (!mesh)
            return crom_err(CROM_EUSAGE, "model %s is a neural field W(X): give the mesh to lay it on",
                            model->model_id);
        rc = crom_mesh_copy(mesh, &map->mesh);
    } else {
        return crom_err(CROM_EINTERNAL, "model has no basis");
    }
    if (rc) {
        crom_map_free(map);
        return rc;
    }
    map->nv = map->mesh.nv;
    map->n = 3 * map->nv;
    size_t nw = (size_t)map->n * r;
    if (model->field == CROM_FIELD_MAP) {
        if (model->basis_v) {
            map->W = crom_malloc(sizeof(double) * nw);
            if (!map->W)
                rc = CROM_EINTERNAL;
            else
                memcpy(map->W, model->basis_v, sizeof(double) * nw);
        }
        if (!rc)
            rc = load_net(map, &model->mlp);
    } else {
        map->W = crom_malloc(sizeof(double) * nw);
        rc = map->W ? crom_model_eval(model, (size_t)map->nv, map->mesh.X, map->W, NULL) : CROM_EINTERNAL;
    }
    if (rc)
        crom_map_free(map);
    return rc;
}

/* activation value and derivative at pre-activation v */
static inline double act_f(crom_nn_act a, double om, double v, double *d)
{
    switch (a) {
    case CROM_NN_ELU:
        if (v > 0) {
            *d = 1;
            return v;
        } else {
            double e = exp(v);
            *d = e;
            return e - 1;
        }
    case CROM_NN_SINE:
        *d = om * cos(om * v);
        return sin(om * v);
    case CROM_NN_GELU: {
        double Phi = 0.5 * (1 + erf(v * INV_SQRT2));
        *d = Phi + v * INV_SQRT2PI * exp(-0.5 * v * v);
        return v * Phi;
    }
    default:
        *d = 1;
        return v;
    }
}

int crom_map_eval(crom_map *map, const double *q, double *x, double *J)
{
    int r = map->r, n = map->n;
    if (x) {
        memcpy(x, map->mesh.X, sizeof(double) * (size_t)n);
        if (map->W)
            cblas_dgemv(CblasRowMajor, CblasNoTrans, n, r, 1.0, map->W, r, q, 1, 1.0, x, 1);
    }
    if (J) {
        if (map->W)
            memcpy(J, map->W, sizeof(double) * (size_t)n * r);
        else
            memset(J, 0, sizeof(double) * (size_t)n * r);
    }
    if (map->nonlinear && (x || J)) {
        /* a: activations [w]; t: tangents [w][r] (d a / d q) */
        double *a = map->a0, *an = map->a1, *z = map->z1, *t = map->t0, *tn = map->t1;
        memcpy(a, q, sizeof(double) * (size_t)r);
        if (J) {
            memset(t, 0, sizeof(double) * (size_t)r * r);
            for (int i = 0; i < r; i++)
                t[i * r + i] = 1;
        }
        int L = map->nlayers;
        for (int l = 0; l < L - 1; l++) {
            int in = map->width[l], out = map->width[l + 1];
            memcpy(z, map->b[l], sizeof(double) * (size_t)out);
            cblas_dgemv(CblasRowMajor, CblasNoTrans, out, in, 1.0, map->w[l], in, a, 1, 1.0, z, 1);
            if (J)
                cblas_dgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, out, r, in, 1.0, map->w[l], in, t, r, 0.0,
                            tn, r);
            for (int j = 0; j < out; j++) {
                double dv;
                an[j] = act_f(map->act, map->omega0, z[j], &dv);
                if (J)
                    for (int k = 0; k < r; k++)
                        tn[j * r + k] *= dv;
            }
            double *s = a;
            a = an;
            an = s;
            s = t;
            t = tn;
            tn = s;
        }
        int in = map->width[L - 1];
        if (x) { /* x += W_L a + b_L */
            cblas_daxpy(n, 1.0, map->b[L - 1], 1, x, 1);
            cblas_dgemv(CblasRowMajor, CblasNoTrans, n, in, 1.0, map->w[L - 1], in, a, 1, 1.0, x, 1);
        }
        if (J)
            cblas_dgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, n, r, in, 1.0, map->w[L - 1], in, t, r, 1.0, J,
                        r);
    }
    if (x)
        for (int i = 0; i < n; i++)
            if (!isfinite(x[i]))
                return crom_err(CROM_EDATA, "the map gives a non-finite position");
    return 0;
}
