/* map.c — one-mesh subspace maps x(q) = X + W q + N(q) in double (see map.h). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <cblas.h>

#include "base/err.h"
#include "rom/map.h"
#include "rom/skin.h"

#define INV_SQRT2 0.70710678118654752440
#define INV_SQRT2PI 0.39894228040143267794

void crom_map_free(crom_map *map)
{
    if (!map)
        return;
    crom_mesh_free(&map->mesh);
    free(map->x0);
    free(map->xs);
    free(map->lift);
    free(map->B);
    free(map->fa);
    free(map->fT);
    free(map->anchor);
    free(map->tan0);
    free(map->mem);
    free(map->a0);
    free(map->a1);
    free(map->z1);
    free(map->t0);
    free(map->t1);
    free(map->zs);
    free(map->ts);
    free(map->cond);
    free(map->w0);
    free(map->wc);
    free(map->b0);
    free(map->bc);
    if (map->inner)
        crom_map_free(map->inner);
    free(map->inner);
    free(map->ia);
    free(map->iT);
    free(map->ig);
    memset(map, 0, sizeof *map);
}

int crom_map_same_mesh(const crom_mesh *a, const crom_mesh *b)
{
    if (a->nv != b->nv || a->nt != b->nt || a->ntri != b->ntri)
        return 1;
    for (size_t i = 0; i < 3 * (size_t)a->nv; i++)
        if (fabs(a->X[i] - b->X[i]) > 1e-9 * (1 + fabs(a->X[i])))
            return 1;
    if (a->ntri && (memcmp(a->tris, b->tris, sizeof(int) * 3 * (size_t)a->ntri) || a->thickness != b->thickness))
        return 1;
    return a->nt && memcmp(a->tets, b->tets, sizeof(int) * 4 * (size_t)a->nt) != 0;
}

/* The layers of a network in double (map->mem, w, b), the scratch of a
 * forward pass with tangents, and the feature basis B [n][p] (unfilled). */
static int copy_layers(crom_map *map, const crom_nn_mlp *net, int p)
{
    const crom_nn_spec *sp = &net->spec;
    int L = sp->nlayers, maxw = 1; /* widest input of a layer: the latent and the hidden layers */
    size_t hsum = 0;               /* the hidden units */
    map->nlayers = L;
    map->act = sp->act;
    map->omega0 = sp->omega0;
    for (int l = 0; l <= L; l++) {
        map->width[l] = sp->width[l];
        if (l < L && sp->width[l] > maxw)
            maxw = sp->width[l];
        if (l > 0 && l < L)
            hsum += (size_t)sp->width[l];
    }
    map->p = map->p_model = p;
    size_t wr = (size_t)maxw * (size_t)(map->r + 1);
    map->mem = crom_malloc(sizeof(double) * net->nparams);
    map->a0 = crom_malloc(sizeof(double) * (size_t)maxw);
    map->a1 = crom_malloc(sizeof(double) * (size_t)maxw);
    map->z1 = crom_malloc(sizeof(double) * (size_t)maxw);
    map->t0 = crom_malloc(sizeof(double) * wr);
    map->t1 = crom_malloc(sizeof(double) * wr);
    map->zs = crom_malloc(sizeof(double) * (hsum ? hsum : 1));
    map->ts = crom_malloc(sizeof(double) * (hsum ? hsum : 1) * (size_t)map->r);
    map->B = crom_malloc(sizeof(double) * (size_t)map->n * p);
    if (!map->mem || !map->a0 || !map->a1 || !map->z1 || !map->t0 || !map->t1 || !map->zs || !map->ts || !map->B)
        return CROM_EINTERNAL;
    for (size_t i = 0; i < net->nparams; i++)
        map->mem[i] = net->params[i];
    for (int l = 0; l < L; l++) {
        map->w[l] = map->mem + net->layer[l].woff;
        map->b[l] = map->mem + net->layer[l].boff;
    }
    map->nonlinear = 1;
    return 0;
}

/* A map of one mesh: the hidden layers of its network, and its last layer
 * and linear part W (basis_v, [n][r] or NULL) laid out as the feature
 * basis B = [W | W_L | b_L]. */
static int load_net(crom_map *map, const crom_nn_mlp *net, const double *basis_v, const double *deriv_v)
{
    const crom_nn_spec *sp = &net->spec;
    int L = sp->nlayers, r = map->r, n = map->n, h = sp->width[L - 1];
    if (sp->width[L] != n)
        return crom_err(CROM_EDATA, "the map's network has %d outputs for %d vertices", sp->width[L], map->nv);
    map->rl = basis_v ? r : 0;
    map->rq = basis_v && deriv_v ? r * (r + 1) / 2 : 0;
    int rc = copy_layers(map, net, map->rl + map->rq + h + 1), o = map->rl + map->rq;
    if (rc)
        return rc;
    for (int i = 0; i < n; i++) {
        double *Bi = map->B + (size_t)i * map->p;
        if (basis_v)
            memcpy(Bi, basis_v + (size_t)i * r, sizeof(double) * (size_t)r);
        if (map->rq)
            memcpy(Bi + map->rl, deriv_v + (size_t)i * map->rq, sizeof(double) * (size_t)map->rq);
        memcpy(Bi + o, map->w[L - 1] + (size_t)i * h, sizeof(double) * (size_t)h);
        Bi[map->p - 1] = map->b[L - 1][i];
    }
    return 0;
}

/* The first layer's bias at the condition map->cond: b0 + Wc c. */
static void fold_condition(crom_map *map)
{
    int out = map->width[1];
    memcpy(map->bc, map->b0, sizeof(double) * (size_t)out);
    cblas_dgemv(CblasRowMajor, CblasNoTrans, out, map->nc, 1.0, map->wc, map->nc, map->cond, 1, 1.0, map->bc, 1);
}

/* A conditional map: the first layer split into its latent and condition
 * columns (the latent is then the network's input as for any map), c at
 * the middle of each trained range. */
static int split_conditions(crom_map *map, const crom_model *model)
{
    int r = map->r, nc = model->ncond, in = r + nc, out = map->width[1];
    map->nc = nc;
    map->cond = crom_malloc(sizeof(double) * (size_t)nc);
    map->w0 = crom_malloc(sizeof(double) * (size_t)out * r);
    map->wc = crom_malloc(sizeof(double) * (size_t)out * nc);
    map->b0 = crom_malloc(sizeof(double) * (size_t)out);
    map->bc = crom_malloc(sizeof(double) * (size_t)out);
    if (!map->cond || !map->w0 || !map->wc || !map->b0 || !map->bc)
        return CROM_EINTERNAL;
    for (int j = 0; j < out; j++) {
        memcpy(map->w0 + (size_t)j * r, map->w[0] + (size_t)j * in, sizeof(double) * (size_t)r);
        memcpy(map->wc + (size_t)j * nc, map->w[0] + (size_t)j * in + r, sizeof(double) * (size_t)nc);
    }
    memcpy(map->b0, map->b[0], sizeof(double) * (size_t)out);
    map->w[0] = map->w0;
    map->b[0] = map->bc;
    map->width[0] = r;
    for (int k = 0; k < nc; k++)
        map->cond[k] = 0.5 * (model->cond[k].lo + model->cond[k].hi);
    fold_condition(map);
    return 0;
}

/* x0 at the current c: xs plus each pin condition's c times its static
 * lift (nothing to do without one) */
static void pins_to_x0(crom_map *map)
{
    if (!map->xs)
        return;
    memcpy(map->x0, map->xs, sizeof(double) * (size_t)map->n);
    for (int k = 0; k < map->nc; k++)
        cblas_daxpy(map->n, map->cond[k], map->lift + (size_t)k * map->n, 1, map->x0, 1);
}

/* A conditional map's pin conditions: their static lifts. */
static int pin_conditions(crom_map *map, const crom_model *model)
{
    int pins = 0;
    for (int k = 0; k < model->ncond; k++)
        pins |= model->cond[k].kind == CROM_SCENARIO_COND_PIN;
    if (!pins)
        return 0;
    if (!model->lift_v)
        return crom_err(CROM_EDATA, "model %s: a pin condition without its static lifts", model->model_id);
    size_t nl = (size_t)map->nc * map->n;
    map->lift = crom_malloc(sizeof(double) * nl);
    map->xs = crom_malloc(sizeof(double) * (size_t)map->n);
    if (!map->lift || !map->xs)
        return CROM_EINTERNAL;
    memcpy(map->lift, model->lift_v, sizeof(double) * nl);
    memcpy(map->xs, map->x0, sizeof(double) * (size_t)map->n);
    pins_to_x0(map);
    return 0;
}

/* The quadratic features ½ q_i q_j (i <= j, in the order of mderiv.h) into
 * a [rq], and their Jacobian rows into T [rq][r] (either may be NULL). */
static void quadratic(int r, const double *q, double *a, double *T)
{
    for (int i = 0, c = 0; i < r; i++)
        for (int j = i; j < r; j++, c++) {
            if (a)
                a[c] = 0.5 * q[i] * q[j];
            if (T) {
                double *row = T + (size_t)c * r;
                memset(row, 0, sizeof(double) * (size_t)r);
                row[i] += 0.5 * q[j];
                row[j] += 0.5 * q[i];
            }
        }
}

/* A continuous map x = X + W(X) φ(q): φ's layers in double (its last one
 * gives the features), B = the pin mask times W at the vertices (the field
 * in float, as for an mlp basis). */
static int load_field_map(crom_map *map, const crom_model *model)
{
    const crom_nn_mlp *phi = &model->latent;
    int p = phi->spec.width[phi->spec.nlayers];
    int rc = copy_layers(map, phi, p);
    if (rc)
        return rc;
    map->phi = 1;
    crom_nn_ws ws;
    if ((rc = crom_nn_ws_init(&ws, &model->mlp, map->nv < 4096 ? map->nv : 4096, 1)))
        return rc;
    rc = crom_nn_mlp_eval(&model->mlp, &ws, (size_t)map->nv, map->mesh.X, map->B, NULL);
    crom_nn_ws_free(&ws);
    for (int v = 0; !rc && v < map->nv; v++) { /* the pin mask */
        double s = crom_model_mask(model, map->mesh.X + 3 * (size_t)v);
        if (s != 1)
            for (int k = 0; k < 3 * p; k++)
                map->B[(size_t)v * 3 * p + k] *= s;
    }
    return rc;
}

/* A skin-field x = X + W(X) φ(q): φ's layers in double, B = the skinning
 * basis at the vertices. */
static int load_skin_field(crom_map *map, const crom_model *model)
{
    int p = crom_skin_width(model), rc = copy_layers(map, &model->latent, p);
    if (rc)
        return rc;
    map->phi = 1;
    return crom_skin_eval(model, (size_t)map->nv, map->mesh.X, map->B, NULL);
}

/* A continuous map x = X + B (φ(q) − φ(0)) with φ's last layer W_L h + b_L
 * of fan-in nh < p − 1 is the same map over the last hidden layer:
 * B (φ(q) − φ(0)) = (B W_L) (h(q) − h(0)), so B becomes [B W_L | B b_L]
 * ([n][nh + 1], laid out as load_net's, the last feature anchored to 0)
 * and a reduced step touches nh + 1 features instead of p (the p x r
 * products of the Jacobian rows and the quadratic forms shrink with it). */
static int fold_last_layer(crom_map *map)
{
    int L = map->nlayers, nh = map->width[L - 1], p = map->p, q = nh + 1, n = map->n;
    if (!map->phi || q >= p)
        return 0;
    double *Bq = crom_malloc(sizeof(double) * (size_t)n * q), *Wb = crom_malloc(sizeof(double) * (size_t)p * q);
    if (!Bq || !Wb) {
        free(Bq);
        free(Wb);
        return CROM_EINTERNAL;
    }
    for (int i = 0; i < p; i++) { /* [W_L | b_L], [p][nh + 1] */
        memcpy(Wb + (size_t)i * q, map->w[L - 1] + (size_t)i * nh, sizeof(double) * (size_t)nh);
        Wb[(size_t)i * q + nh] = map->b[L - 1][i];
    }
    cblas_dgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, n, q, p, 1.0, map->B, p, Wb, q, 0.0, Bq, q);
    free(Wb);
    free(map->B);
    map->B = Bq;
    map->p = q;
    map->rl = 0;
    map->phi = 0;
    return 0;
}

/* The anchor a(0) of a nonlinear map (x(0) = X exactly) and, tangent-
 * anchored, T(0) of the network's features, at the current condition. */
static int set_anchor(crom_map *map)
{
    int r = map->r, rc;
    free(map->anchor);
    free(map->tan0);
    map->anchor = map->tan0 = NULL;
    double *zero = crom_calloc((size_t)r, sizeof(double)), *a0 = crom_malloc(sizeof(double) * (size_t)map->p);
    double *T0 = map->tangent ? crom_malloc(sizeof(double) * (size_t)map->p * r) : NULL;
    rc = zero && a0 && (T0 || !map->tangent) ? crom_map_features(map, zero, a0, T0) : CROM_EINTERNAL;
    free(zero);
    if (rc) {
        free(a0);
        free(T0);
        return rc;
    }
    map->anchor = a0;
    map->tan0 = T0;
    return 0;
}

int crom_map_init(crom_map *map, const crom_model *model, const crom_mesh *mesh)
{
    memset(map, 0, sizeof *map);
    int rc = 0, r = model->rank;
    map->r = r;
    if (model->field == CROM_MODEL_FIELD_MAP) {
        if (mesh && crom_map_same_mesh(mesh, &model->mesh))
            return crom_err(CROM_EDATA, "model %s (basis '%s') is a map of one mesh and decodes only onto its own "
                            "mesh (%d vertices, %d tets); the given mesh has %d vertices, %d tets%s",
                            model->model_id, model->basis, model->mesh.nv, model->mesh.nt, mesh->nv, mesh->nt,
                            mesh->nv == model->mesh.nv ? " at other positions" : "");
        /* the same mesh: keep the given one's regions if it has any */
        rc = crom_mesh_copy(mesh && mesh->nregions ? mesh : &model->mesh, &map->mesh);
    } else if (model->field == CROM_MODEL_FIELD_MESH || (model->field == CROM_MODEL_FIELD_SKIN && model->skin_w)) {
        rc = crom_mesh_copy(mesh ? mesh : &model->mesh, &map->mesh);
    } else if (model->field == CROM_MODEL_FIELD_MLP || model->field == CROM_MODEL_FIELD_CMAP ||
               model->field == CROM_MODEL_FIELD_SKIN) {
        if (!mesh)
            return crom_err(CROM_EUSAGE, "model %s is a neural field %s: give the mesh to lay it on",
                            model->model_id, model->field == CROM_MODEL_FIELD_CMAP ? "x(X, q)" : "W(X)");
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
    if (model->field == CROM_MODEL_FIELD_MAP) {
        rc = load_net(map, &model->mlp, model->basis_v, model->deriv_v);
        if (!rc && model->ncond)
            rc = split_conditions(map, model);
    } else if (model->field == CROM_MODEL_FIELD_CMAP) {
        if (!(rc = load_field_map(map, model)))
            rc = fold_last_layer(map);
    } else if (model->field == CROM_MODEL_FIELD_SKIN && model->latent.nparams) {
        if (!(rc = load_skin_field(map, model)))
            rc = fold_last_layer(map);
    } else { /* a linear basis: a = q, B = W(X_v) */
        map->p = map->p_model = r;
        map->B = crom_malloc(sizeof(double) * (size_t)map->n * r);
        rc = map->B ? crom_model_eval(model, (size_t)map->nv, map->mesh.X, map->B, NULL) : CROM_EINTERNAL;
    }
    if (!rc) { /* crom_map_eval's features, and the positions at q = 0 */
        map->fa = crom_malloc(sizeof(double) * (size_t)map->p);
        map->fT = crom_malloc(sizeof(double) * (size_t)map->p * r);
        map->x0 = crom_malloc(sizeof(double) * (size_t)map->n);
        if (!map->fa || !map->fT || !map->x0)
            rc = CROM_EINTERNAL;
        else
            for (int i = 0; i < map->n; i++)
                map->x0[i] = map->mesh.X[i] + (model->seed_v ? model->seed_v[i] : 0);
    }
    if (!rc && model->ncond)
        rc = pin_conditions(map, model);
    map->tangent = model->tangent_anchored && !map->phi;
    if (!rc && map->nonlinear)
        rc = set_anchor(map);
    if (rc)
        crom_map_free(map);
    return rc;
}

int crom_map_set_condition(crom_map *map, const double *c)
{
    if (!map->nc)
        return crom_err(CROM_EUSAGE, "the map has no conditions");
    for (int k = 0; k < map->nc; k++)
        if (!isfinite(c[k]))
            return crom_err(CROM_EDATA, "condition %d is not finite", k + 1);
    memcpy(map->cond, c, sizeof(double) * (size_t)map->nc);
    fold_condition(map);
    pins_to_x0(map);
    return set_anchor(map);
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

/* Forward through the hidden layers at q: the last hidden layer's
 * activations in *hout and, with J, their Jacobian dh/dq [w][r] in *tout
 * (the map's scratch); with keep, every hidden layer's pre-activation z_l
 * and dz_l/dq stay in map->zs and map->ts (crom_map_curvature). */
static void hidden_forward(crom_map *map, const double *q, int J, int keep, double **hout, double **tout)
{
    int r = map->r, L = map->nlayers;
    double *h = map->a0, *hn = map->a1, *t = map->t0, *tn = map->t1;
    size_t off = 0;
    memcpy(h, q, sizeof(double) * (size_t)r);
    if (J) {
        memset(t, 0, sizeof(double) * (size_t)r * r);
        for (int i = 0; i < r; i++)
            t[i * r + i] = 1;
    }
    for (int l = 0; l < L - 1; l++) {
        int in = map->width[l], out = map->width[l + 1];
        double *z = keep ? map->zs + off : map->z1, *tz = keep ? map->ts + off * (size_t)r : tn;
        memcpy(z, map->b[l], sizeof(double) * (size_t)out);
        cblas_dgemv(CblasRowMajor, CblasNoTrans, out, in, 1.0, map->w[l], in, h, 1, 1.0, z, 1);
        if (J)
            cblas_dgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, out, r, in, 1.0, map->w[l], in, t, r, 0.0, tz, r);
        for (int j = 0; j < out; j++) {
            double dv;
            hn[j] = act_f(map->act, map->omega0, z[j], &dv);
            if (J)
                for (int k = 0; k < r; k++)
                    tn[j * r + k] = tz[j * r + k] * dv;
        }
        off += (size_t)out;
        double *s = h;
        h = hn;
        hn = s;
        s = t;
        t = tn;
        tn = s;
    }
    *hout = h;
    *tout = t;
}

static int frame_features(crom_map *map, const double *q, double *a, double *T);
static int frame_curvature(crom_map *map, const double *q, const double *g, double *C);

int crom_map_features(crom_map *map, const double *q, double *a, double *T)
{
    int r = map->r, p = map->p;
    if (map->inner)
        return frame_features(map, q, a, T);
    if (!map->nonlinear) {
        if (a)
            memcpy(a, q, sizeof(double) * (size_t)r);
        if (T) {
            memset(T, 0, sizeof(double) * (size_t)r * r);
            for (int i = 0; i < r; i++)
                T[i * r + i] = 1;
        }
        return 0;
    }
    double *h, *t;
    int L = map->nlayers;
    hidden_forward(map, q, T != NULL, 0, &h, &t);
    int nh = map->width[L - 1], rl = map->rl;
    if (map->phi) { /* a = W_L h + b_L, T = W_L t */
        if (a) {
            memcpy(a, map->b[L - 1], sizeof(double) * (size_t)p);
            cblas_dgemv(CblasRowMajor, CblasNoTrans, p, nh, 1.0, map->w[L - 1], nh, h, 1, 1.0, a, 1);
            for (int i = 0; i < p; i++) {
                if (!isfinite(a[i]))
                    return crom_err(CROM_EDATA, "the map's network is not finite at this latent");
                if (map->anchor)
                    a[i] -= map->anchor[i];
            }
        }
        if (T)
            cblas_dgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, p, r, nh, 1.0, map->w[L - 1], nh, t, r, 0.0, T,
                        r);
        return 0;
    }
    int o = rl + map->rq; /* the network's features start here */
    if (a) {
        memcpy(a, q, sizeof(double) * (size_t)rl);
        quadratic(map->rq ? r : 0, q, a + rl, NULL);
        memcpy(a + o, h, sizeof(double) * (size_t)nh);
        a[p - 1] = 1;
        for (int i = 0; i < p; i++) {
            if (!isfinite(a[i]))
                return crom_err(CROM_EDATA, "the map's network is not finite at this latent");
            if (map->anchor)
                a[i] -= map->anchor[i];
            if (map->tan0 && i >= o) /* tangent-anchored: less T(0) q */
                a[i] -= cblas_ddot(r, map->tan0 + (size_t)i * r, 1, q, 1);
        }
    }
    if (T) {
        memset(T, 0, sizeof(double) * (size_t)rl * r);
        for (int i = 0; i < rl; i++)
            T[i * r + i] = 1;
        quadratic(map->rq ? r : 0, q, NULL, T + (size_t)rl * r);
        memcpy(T + (size_t)o * r, t, sizeof(double) * (size_t)nh * r);
        memset(T + (size_t)(p - 1) * r, 0, sizeof(double) * (size_t)r);
        if (map->tan0)
            for (size_t i = (size_t)o * r; i < (size_t)p * r; i++)
                T[i] -= map->tan0[i];
    }
    return 0;
}

/* second derivative of the activation at pre-activation v */
static inline double act_f2(crom_nn_act a, double om, double v)
{
    switch (a) {
    case CROM_NN_ELU:
        return v > 0 ? 0 : exp(v);
    case CROM_NN_SINE:
        return -om * om * sin(om * v);
    case CROM_NN_GELU: /* d²/dv² vΦ(v) = 2φ(v) + vφ'(v) = φ(v)(2 − v²) */
        return INV_SQRT2PI * exp(-0.5 * v * v) * (2 - v * v);
    default:
        return 0;
    }
}

/* With z_l = W_l h_{l−1} + b_l, h_l = σ(z_l), h_0 = q and ψ = gᵀa linear in
 * the last hidden layer, every operation but the activations is linear, so
 * ∇²ψ = Σ_l (dz_l/dq)ᵀ diag(σ''(z_l) ⊙ ∂ψ/∂h_l) (dz_l/dq): the forward pass
 * keeps z_l and dz_l/dq, the adjoint pass ∂ψ/∂h_l, from the last layer down. */
int crom_map_curvature(crom_map *map, const double *q, const double *g, double *C)
{
    if (map->inner)
        return frame_curvature(map, q, g, C);
    int r = map->r, L = map->nlayers;
    size_t rr = (size_t)r * r;
    memset(C, 0, sizeof(double) * rr);
    if (!map->nonlinear)
        return 0;
    size_t off[CROM_NN_MAX_LAYERS + 1];
    off[0] = 0;
    for (int l = 0; l < L - 1; l++)
        off[l + 1] = off[l] + (size_t)map->width[l + 1];
    double *hl, *tl;
    hidden_forward(map, q, 1, 1, &hl, &tl); /* z_l and dz_l/dq kept */
    /* u = ∂ψ/∂h of the last hidden layer: W_Lᵀ g through φ's output layer,
     * else g's entries at the features h */
    int nh = map->width[L - 1];
    double *u = map->a0, *un = map->a1, *S = map->t0;
    if (map->phi)
        cblas_dgemv(CblasRowMajor, CblasTrans, map->p, nh, 1.0, map->w[L - 1], nh, g, 1, 0.0, u, 1);
    else
        memcpy(u, g + map->rl + map->rq, sizeof(double) * (size_t)nh);
    /* the quadratic features: ∂²(½ q_i q_j) = ½ (e_i e_jᵀ + e_j e_iᵀ) */
    for (int i = 0, c = 0; map->rq && i < r; i++)
        for (int j = i; j < r; j++, c++) {
            double gc = g[map->rl + c];
            C[i * r + j] += 0.5 * gc;
            C[j * r + i] += 0.5 * gc;
        }
    for (int l = L - 2; l >= 0; l--) {
        int in = map->width[l], out = map->width[l + 1];
        const double *z = map->zs + off[l], *tz = map->ts + off[l] * r;
        for (int j = 0; j < out; j++) { /* S = diag(u σ''(z)) dz/dq; u ← u σ'(z) */
            double dv, c = u[j] * act_f2(map->act, map->omega0, z[j]);
            act_f(map->act, map->omega0, z[j], &dv);
            for (int k = 0; k < r; k++)
                S[j * r + k] = c * tz[j * r + k];
            u[j] *= dv;
        }
        cblas_dgemm(CblasRowMajor, CblasTrans, CblasNoTrans, r, r, out, 1.0, tz, r, S, r, 1.0, C, r);
        if (l > 0) { /* ∂ψ/∂h_{l−1} = W_lᵀ (σ'(z_l) ⊙ ∂ψ/∂h_l) */
            cblas_dgemv(CblasRowMajor, CblasTrans, out, in, 1.0, map->w[l], in, u, 1, 0.0, un, 1);
            double *s = u;
            u = un;
            un = s;
        }
    }
    double sum = 0;
    for (int a = 0; a < r; a++) /* exactly symmetric */
        for (int b = 0; b <= a; b++) {
            C[a * r + b] = C[b * r + a] = 0.5 * (C[a * r + b] + C[b * r + a]);
            sum += C[a * r + b];
        }
    return isfinite(sum) ? 0 : crom_err(CROM_EDATA, "the map's network is not finite at this latent");
}

void crom_map_rows(const crom_map *map, const int *idx, int nidx, const double *a, const double *T, double *x,
                   double *J)
{
    int p = map->p, r = map->r;
    const double *X = map->x0;
    if (!idx) { /* every vertex: two BLAS calls */
        int n = map->n;
        if (x) {
            memcpy(x, X, sizeof(double) * (size_t)n);
            cblas_dgemv(CblasRowMajor, CblasNoTrans, n, p, 1.0, map->B, p, a, 1, 1.0, x, 1);
        }
        if (J)
            cblas_dgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, n, r, p, 1.0, map->B, p, T, r, 0.0, J, r);
        return;
    }
    for (int k = 0; k < nidx; k++) {
        const double *Bv = map->B + (size_t)idx[k] * 3 * p;
        if (x)
            for (int c = 0; c < 3; c++)
                x[3 * k + c] = X[3 * (size_t)idx[k] + c] + cblas_ddot(p, Bv + (size_t)c * p, 1, a, 1);
        if (J)
            cblas_dgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, 3, r, p, 1.0, Bv, p, T, r, 0.0,
                        J + (size_t)k * 3 * r, r);
    }
}

int crom_map_eval(crom_map *map, const double *q, double *x, double *J)
{
    if (!x && !J)
        return 0;
    int rc = crom_map_features(map, q, map->fa, J ? map->fT : NULL);
    if (rc)
        return rc;
    crom_map_rows(map, NULL, 0, map->fa, map->fT, x, J);
    if (x)
        for (int i = 0; i < map->n; i++)
            if (!isfinite(x[i]))
                return crom_err(CROM_EDATA, "the map gives a non-finite position");
    return 0;
}

/* ---- A rigid frame x = R(θ) y(q') + t (crom_map_add_frame) ---------------- */

/* The rotation about axis ax (0 x, 1 y, 2 z) by angle th, differentiated
 * k times in th, into M [9]: the plane (i, j) of the axis carries
 * cos(th + kπ/2) and sin(th + kπ/2), the axis itself 1 (k = 0) or 0. */
static void axis_rot(int ax, double th, int k, double M[9])
{
    static const int pl[3][2] = {{1, 2}, {2, 0}, {0, 1}};
    int i = pl[ax][0], j = pl[ax][1];
    double c = cos(th + k * M_PI_2), s = sin(th + k * M_PI_2);
    memset(M, 0, sizeof(double) * 9);
    M[ax * 4] = k ? 0 : 1;
    M[i * 4] = M[j * 4] = c;
    M[i * 3 + j] = -s;
    M[j * 3 + i] = s;
}

static void mul3(const double *A, const double *B, double *C)
{
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            C[i * 3 + j] = A[i * 3] * B[j] + A[i * 3 + 1] * B[3 + j] + A[i * 3 + 2] * B[6 + j];
}

/* ∂^{k_x + k_y + k_z} R / ∂θ_1^{k_x} ∂θ_2^{k_y} ∂θ_3^{k_z} of R = R_z R_y R_x
 * (k [3]) into D [9] */
static void euler_deriv(const double th[3], const int k[3], double D[9])
{
    double Mx[9], My[9], Mz[9], T[9];
    axis_rot(0, th[0], k[0], Mx);
    axis_rot(1, th[1], k[1], My);
    axis_rot(2, th[2], k[2], Mz);
    mul3(Mz, My, T);
    mul3(T, Mx, D);
}

/* R (NULL to skip), its first derivatives dR [3][9] (NULL to skip) and its
 * second d2R [3][3][9] (NULL to skip) at θ */
static void euler(const double th[3], double *R, double *dR, double *d2R)
{
    int k[3] = {0, 0, 0};
    if (R)
        euler_deriv(th, k, R);
    for (int a = 0; a < 3; a++) {
        if (dR) {
            k[a] = 1;
            euler_deriv(th, k, dR + 9 * a);
            k[a] = 0;
        }
        for (int b = 0; d2R && b < 3; b++) {
            k[a]++;
            k[b]++;
            euler_deriv(th, k, d2R + 9 * (3 * a + b));
            k[a] = k[b] = 0;
        }
    }
}

int crom_map_add_frame(crom_map *map)
{
    if (map->inner)
        return crom_err(CROM_EUSAGE, "the map has a rigid frame already");
    if (map->nc)
        return crom_err(CROM_EUSAGE, "a rigid frame over a conditional map is not supported");
    crom_map *in = crom_malloc(sizeof *in);
    if (!in) {
        crom_map_free(map);
        return CROM_EINTERNAL;
    }
    *in = *map;
    memset(map, 0, sizeof *map);
    map->inner = in;
    int ri = in->r, pi = in->p, r = ri + 6, pb = pi + 1, p = 9 * pb + 3;
    map->r = r;
    map->nv = in->nv;
    map->n = in->n;
    map->nonlinear = 1;
    map->p = map->p_model = p;
    int rc = crom_mesh_copy(&in->mesh, &map->mesh);
    map->B = crom_calloc((size_t)map->n * p, sizeof(double));
    map->x0 = crom_malloc(sizeof(double) * (size_t)map->n);
    map->fa = crom_malloc(sizeof(double) * (size_t)p);
    map->fT = crom_malloc(sizeof(double) * (size_t)p * r);
    map->ia = crom_malloc(sizeof(double) * (size_t)pi);
    map->iT = crom_malloc(sizeof(double) * (size_t)pi * ri);
    map->ig = crom_malloc(sizeof(double) * (size_t)pi);
    if (rc || !map->B || !map->x0 || !map->fa || !map->fT || !map->ia || !map->iT || !map->ig) {
        crom_map_free(map);
        return rc ? rc : CROM_EINTERNAL;
    }
    memcpy(map->x0, in->x0, sizeof(double) * (size_t)map->n);
    for (int v = 0; v < map->nv; v++) /* row 3v + k: Σ_l R_kl (x0_l + B'_l a') + t_k */
        for (int k = 0; k < 3; k++) {
            double *row = map->B + (3 * (size_t)v + k) * p;
            for (int l = 0; l < 3; l++) {
                double *blk = row + (3 * k + l) * pb;
                blk[0] = in->x0[3 * (size_t)v + l];
                memcpy(blk + 1, in->B + (3 * (size_t)v + l) * pi, sizeof(double) * (size_t)pi);
            }
            row[9 * pb + k] = 1;
        }
    return 0;
}

static int frame_features(crom_map *map, const double *q, double *a, double *T)
{
    crom_map *in = map->inner;
    int ri = in->r, pi = in->p, r = map->r, pb = pi + 1, rc;
    if ((rc = crom_map_features(in, q, map->ia, T ? map->iT : NULL)))
        return rc;
    const double *th = q + ri, *ai = map->ia;
    double R[9], dR[27];
    euler(th, R, T ? dR : NULL, NULL);
    for (int kl = 0; a && kl < 9; kl++) {
        double *blk = a + kl * pb;
        blk[0] = R[kl] - (kl % 4 == 0);
        for (int j = 0; j < pi; j++)
            blk[1 + j] = R[kl] * ai[j];
    }
    if (a)
        memcpy(a + 9 * pb, q + ri + 3, sizeof(double) * 3);
    if (!T)
        return 0;
    memset(T, 0, sizeof(double) * (size_t)map->p * r);
    for (int kl = 0; kl < 9; kl++) {
        double *row = T + (size_t)kl * pb * r;
        for (int c = 0; c < 3; c++)
            row[ri + c] = dR[9 * c + kl];
        for (int j = 0; j < pi; j++) {
            row += r;
            const double *Tj = map->iT + (size_t)j * ri;
            for (int b = 0; b < ri; b++)
                row[b] = R[kl] * Tj[b];
            for (int c = 0; c < 3; c++)
                row[ri + c] = dR[9 * c + kl] * ai[j];
        }
    }
    for (int k = 0; k < 3; k++)
        T[((size_t)9 * pb + k) * r + ri + 3 + k] = 1;
    return 0;
}

/* ψ = gᵀa with a's rotation blocks Σ_kl R_kl (g_kl0 + Σ_j g_klj a'_j):
 * ∂²ψ/∂q'² is the inner map's curvature along u_j = Σ_kl R_kl g_klj,
 * ∂²ψ/∂θ_c∂q' = Σ_kl ∂_c R_kl Σ_j g_klj T'_j, ∂²ψ/∂θ_c∂θ_e = Σ_kl
 * ∂_ce R_kl (g_kl0 + Σ_j g_klj a'_j); t enters linearly. */
static int frame_curvature(crom_map *map, const double *q, const double *g, double *C)
{
    crom_map *in = map->inner;
    int ri = in->r, pi = in->p, r = map->r, pb = pi + 1, rc;
    if ((rc = crom_map_features(in, q, map->ia, map->iT)))
        return rc;
    double R[9], dR[27], d2R[81], *Ci = crom_malloc(sizeof(double) * (size_t)ri * ri);
    if (!Ci)
        return CROM_EINTERNAL;
    euler(q + ri, R, dR, d2R);
    memset(map->ig, 0, sizeof(double) * (size_t)pi);
    for (int kl = 0; kl < 9; kl++)
        cblas_daxpy(pi, R[kl], g + kl * pb + 1, 1, map->ig, 1);
    if ((rc = crom_map_curvature(in, q, map->ig, Ci))) {
        free(Ci);
        return rc;
    }
    memset(C, 0, sizeof(double) * (size_t)r * r);
    for (int i = 0; i < ri; i++)
        memcpy(C + (size_t)i * r, Ci + (size_t)i * ri, sizeof(double) * (size_t)ri);
    free(Ci);
    double Gkl[9]; /* g_kl0 + Σ_j g_klj a'_j */
    for (int kl = 0; kl < 9; kl++)
        Gkl[kl] = g[kl * pb] + cblas_ddot(pi, g + kl * pb + 1, 1, map->ia, 1);
    for (int c = 0; c < 3; c++) {
        memset(map->ig, 0, sizeof(double) * (size_t)pi); /* w_c = Σ_kl ∂_c R_kl g_kl· */
        for (int kl = 0; kl < 9; kl++)
            cblas_daxpy(pi, dR[9 * c + kl], g + kl * pb + 1, 1, map->ig, 1);
        for (int b = 0; b < ri; b++) {
            double s = 0;
            for (int j = 0; j < pi; j++)
                s += map->ig[j] * map->iT[(size_t)j * ri + b];
            C[(size_t)(ri + c) * r + b] = C[(size_t)b * r + ri + c] = s;
        }
        for (int e = 0; e < 3; e++) {
            double s = 0;
            for (int kl = 0; kl < 9; kl++)
                s += d2R[9 * (3 * c + e) + kl] * Gkl[kl];
            C[(size_t)(ri + c) * r + ri + e] = s;
        }
    }
    double sum = 0;
    for (size_t i = 0; i < (size_t)r * r; i++)
        sum += C[i];
    return isfinite(sum) ? 0 : crom_err(CROM_EDATA, "the map's frame is not finite at this latent");
}
