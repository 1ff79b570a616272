/* model.c — crom/model read, write, evaluation and identity (see model.h). */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "rom/model.h"
#include "rom/skin.h"

void crom_model_clear(crom_model *m)
{
    memset(m, 0, sizeof *m);
    m->reconstruction_error = NAN;
    m->training_seconds = NAN;
    m->youngs = m->poisson = m->density = NAN;
    m->sigma = m->latent_box = NAN;
}

void crom_model_free(crom_model *m)
{
    if (!m)
        return;
    crom_nn_mlp_free(&m->mlp);
    crom_nn_mlp_free(&m->latent);
    free(m->pin_points);
    free(m->pin_triangles);
    crom_locate_free(&m->loc);
    crom_mesh_free(&m->mesh);
    free(m->basis_v);
    free(m->deriv_v);
    free(m->seed_v);
    free(m->lift_v);
    free(m->frequencies);
    free(m->skin_w);
    free(m->skin_eig);
    free(m->skin_C);
    crom_nn_pointnet_free(&m->enc);
    free(m->loss);
    free(m->seconds);
    free(m->scenario);
    crom_model_clear(m);
}

const char *crom_model_encoder_name(int enc)
{
    return enc == CROM_MODEL_ENC_POINTNET ? "pointnet" : enc == CROM_MODEL_ENC_LSQ ? "lsq" : "none";
}

/* ------------------------------------------------------------------ id */

typedef struct {
    uint64_t h;
} fnv;

static void fnv_bytes(fnv *s, const void *p, size_t n)
{
    const unsigned char *b = p;
    uint64_t h = s->h;
    for (size_t i = 0; i < n; i++) {
        h ^= b[i];
        h *= 0x100000001b3ULL;
    }
    s->h = h;
}

static void fnv_i64(fnv *s, long long v)
{
    int64_t x = v;
    fnv_bytes(s, &x, 8);
}

/* The latent network φ of a continuous map: widths (int32), parameters. */
static void fnv_latent(fnv *s, const crom_nn_mlp *phi)
{
    const crom_nn_spec *lp = &phi->spec;
    for (int l = 0; l <= lp->nlayers; l++) {
        int32_t w = lp->width[l];
        fnv_bytes(s, &w, 4);
    }
    fnv_bytes(s, phi->params, sizeof(float) * phi->nparams);
}

/* A shell's triangles and thickness (nothing for a tet mesh, whose ids
 * stay what they were). */
static void surface_id(fnv *s, const crom_mesh *m)
{
    if (!crom_mesh_is_surface(m))
        return;
    fnv_i64(s, m->ntri);
    fnv_bytes(s, m->tris, sizeof(int) * 3 * (size_t)m->ntri);
    fnv_bytes(s, &m->thickness, sizeof m->thickness);
}

int crom_model_nderiv(const crom_model *m)
{
    return m->rank * (m->rank + 1) / 2;
}

const char *crom_model_id(const crom_model *m, char id[17])
{
    fnv s = {0xcbf29ce484222325ULL};
    fnv_bytes(&s, m->basis, strlen(m->basis) + 1);
    fnv_i64(&s, m->rank);
    if (crom_model_is_nonlinear(m)) /* a map anchored at rest, x(0) = X (lib/rom/map.h) */
        fnv_bytes(&s, "anchored", 9);
    if (m->field == CROM_MODEL_FIELD_SKIN) {
        s.h = crom_skin_digest(m, s.h);
        if (m->latent.nparams) /* skin-field: φ after the skinning basis */
            fnv_latent(&s, &m->latent);
    } else if (m->field == CROM_MODEL_FIELD_MLP || m->field == CROM_MODEL_FIELD_CMAP) {
        const crom_nn_spec *sp = &m->mlp.spec;
        for (int l = 0; l <= sp->nlayers; l++) {
            int32_t w = sp->width[l];
            fnv_bytes(&s, &w, 4);
        }
        const char *act = crom_nn_act_name(sp->act);
        fnv_bytes(&s, act, strlen(act) + 1);
        for (int i = 0; i < sp->width[0]; i++) {
            double v = m->mlp.shift[i];
            fnv_bytes(&s, &v, 8);
        }
        for (int i = 0; i < sp->width[0]; i++) {
            double v = m->mlp.scale[i];
            fnv_bytes(&s, &v, 8);
        }
        fnv_bytes(&s, m->mlp.params, sizeof(float) * m->mlp.nparams);
        if (m->cut.nseg) {
            fnv_bytes(&s, "cut", 4);
            fnv_i64(&s, m->cut.axis);
            fnv_i64(&s, m->cut.nseg);
            fnv_bytes(&s, m->cut.seg, sizeof(double) * 4 * (size_t)m->cut.nseg);
        }
        if (m->field == CROM_MODEL_FIELD_CMAP) {
            fnv_latent(&s, &m->latent);
            fnv_i64(&s, m->npin_points);
            if (m->npin_points)
                fnv_bytes(&s, m->pin_points, sizeof(double) * 3 * (size_t)m->npin_points);
            fnv_i64(&s, m->npin_triangles);
            if (m->npin_triangles)
                fnv_bytes(&s, m->pin_triangles, sizeof(double) * 9 * (size_t)m->npin_triangles);
            fnv_bytes(&s, &m->pin_length, 8);
        }
    } else if (m->field == CROM_MODEL_FIELD_MAP) {
        const crom_nn_spec *sp = &m->mlp.spec;
        for (int l = 0; l <= sp->nlayers; l++) {
            int32_t w = sp->width[l];
            fnv_bytes(&s, &w, 4);
        }
        const char *act = crom_nn_act_name(sp->act);
        fnv_bytes(&s, act, strlen(act) + 1);
        fnv_bytes(&s, m->mlp.params, sizeof(float) * m->mlp.nparams);
        fnv_i64(&s, m->mesh.nv);
        fnv_i64(&s, m->mesh.nt);
        fnv_bytes(&s, m->mesh.X, sizeof(double) * 3 * (size_t)m->mesh.nv);
        fnv_bytes(&s, m->mesh.tets, sizeof(int) * 4 * (size_t)m->mesh.nt);
        surface_id(&s, &m->mesh);
        if (m->basis_v)
            fnv_bytes(&s, m->basis_v, sizeof(double) * 3 * (size_t)m->rank * m->mesh.nv);
        if (m->deriv_v)
            fnv_bytes(&s, m->deriv_v, sizeof(double) * 3 * (size_t)crom_model_nderiv(m) * m->mesh.nv);
        if (m->seed_v)
            fnv_bytes(&s, m->seed_v, sizeof(double) * 3 * (size_t)m->mesh.nv);
        if (m->lift_v)
            fnv_bytes(&s, m->lift_v, sizeof(double) * 3 * (size_t)m->mesh.nv * m->ncond);
        for (int k = 0; k < m->ncond; k++) { /* a conditional map's inputs after q */
            char c[200];
            crom_scenario_cond_format(&m->cond[k], c, sizeof c);
            fnv_bytes(&s, c, strlen(c) + 1);
        }
    } else if (m->field == CROM_MODEL_FIELD_MESH) {
        fnv_i64(&s, m->mesh.nv);
        fnv_i64(&s, m->mesh.nt);
        fnv_bytes(&s, m->mesh.X, sizeof(double) * 3 * (size_t)m->mesh.nv);
        fnv_bytes(&s, m->mesh.tets, sizeof(int) * 4 * (size_t)m->mesh.nt);
        surface_id(&s, &m->mesh);
        fnv_bytes(&s, m->basis_v, sizeof(double) * 3 * (size_t)m->rank * m->mesh.nv);
    }
    snprintf(id, 17, "%016llx", (unsigned long long)s.h);
    return id;
}

/* --------------------------------------------------------- construction */

static int copy_pointnet(crom_nn_pointnet *dst, const crom_nn_pointnet *src)
{
    return crom_nn_pointnet_from_params(dst, &src->point.spec, &src->head.spec, src->params,
                                        src->nparams, src->point.shift, src->point.scale);
}

int crom_model_from_mlp(crom_model *m, const crom_nn_mlp *W, const crom_cutfeat *cut, const crom_nn_pointnet *enc)
{
    crom_model_clear(m);
    int out = W->spec.width[W->spec.nlayers], K = cut ? cut->nseg : 0;
    if (cut && crom_cutfeat_check(cut))
        return CROM_EUSAGE;
    if (W->spec.width[0] != 3 + K || out < 3 || out % 3)
        return crom_err(CROM_EUSAGE, "a field MLP maps 3 inputs and %d cut features to 3r outputs (got %d -> %d)", K,
                        W->spec.width[0], out);
    if (cut)
        m->cut = *cut;
    snprintf(m->basis, sizeof m->basis, "mlp");
    m->field = CROM_MODEL_FIELD_MLP;
    m->rank = out / 3;
    m->encoder = enc ? CROM_MODEL_ENC_POINTNET : CROM_MODEL_ENC_LSQ;
    int rc = crom_nn_mlp_from_params(&m->mlp, &W->spec, W->params, W->nparams, W->shift, W->scale);
    if (!rc && enc) {
        if (enc->head.spec.width[enc->head.spec.nlayers] != m->rank || enc->point.spec.width[0] != 6)
            rc = crom_err(CROM_EUSAGE, "the encoder must map (X, u) points to %d latents", m->rank);
        else
            rc = copy_pointnet(&m->enc, enc);
    }
    if (rc)
        crom_model_free(m);
    else
        crom_model_id(m, m->model_id);
    return rc;
}

int crom_model_from_mesh(crom_model *m, const char *basis, const crom_mesh *mesh,
                         const double *basis_v, int rank)
{
    crom_model_clear(m);
    if (rank < 1)
        return crom_err(CROM_EUSAGE, "rank %d must be positive", rank);
    snprintf(m->basis, sizeof m->basis, "%s", basis);
    m->field = CROM_MODEL_FIELD_MESH;
    m->rank = rank;
    m->encoder = CROM_MODEL_ENC_LSQ;
    m->mesh.nv = mesh->nv;
    m->mesh.nt = mesh->nt;
    m->mesh.ntri = mesh->ntri;
    m->mesh.thickness = mesh->thickness;
    size_t nb = (size_t)mesh->nv * 3 * rank;
    m->mesh.X = crom_malloc(sizeof(double) * 3 * (size_t)mesh->nv);
    m->mesh.tets = crom_malloc(sizeof(int) * 4 * (size_t)(mesh->nt ? mesh->nt : 1));
    m->mesh.tris = mesh->ntri ? crom_malloc(sizeof(int) * 3 * (size_t)mesh->ntri) : NULL;
    m->basis_v = crom_malloc(sizeof(double) * nb);
    if (!m->mesh.X || !m->mesh.tets || (mesh->ntri && !m->mesh.tris) || !m->basis_v) {
        crom_model_free(m);
        return CROM_EINTERNAL;
    }
    memcpy(m->mesh.X, mesh->X, sizeof(double) * 3 * (size_t)mesh->nv);
    if (mesh->nt)
        memcpy(m->mesh.tets, mesh->tets, sizeof(int) * 4 * (size_t)mesh->nt);
    if (mesh->ntri)
        memcpy(m->mesh.tris, mesh->tris, sizeof(int) * 3 * (size_t)mesh->ntri);
    memcpy(m->basis_v, basis_v, sizeof(double) * nb);
    if (mesh->scene && (!(m->mesh.scene = crom_malloc(sizeof *m->mesh.scene)) ||
                        crom_scene_copy(mesh->scene, m->mesh.scene))) { /* a scene's basis: its frame vertices */
        free(m->mesh.scene);
        m->mesh.scene = NULL;
        crom_model_free(m);
        return CROM_EINTERNAL;
    }
    int rc = crom_mesh_is_surface(&m->mesh) || m->mesh.scene ? 0 : crom_locate_init(&m->loc, &m->mesh);
    if (rc)
        crom_model_free(m);
    else
        crom_model_id(m, m->model_id);
    return rc;
}

int crom_model_is_map_kind(const char *basis)
{
    return basis && (!strcmp(basis, "energy") || !strcmp(basis, "neuralmodes"));
}

int crom_model_from_map(crom_model *m, const char *basis, const crom_nn_mlp *net,
                        const crom_mesh *mesh, const double *basis_v)
{
    crom_model_clear(m);
    const crom_nn_spec *sp = &net->spec;
    int r = sp->width[0], out = sp->width[sp->nlayers];
    if (!crom_model_is_map_kind(basis))
        return crom_err(CROM_EUSAGE, "'%s' is not a map kind (energy, neuralmodes)", basis);
    if (r < 1 || out != 3 * mesh->nv)
        return crom_err(CROM_EUSAGE, "a map network goes r -> 3nv = %d, got %d -> %d", 3 * mesh->nv, r, out);
    snprintf(m->basis, sizeof m->basis, "%s", basis);
    m->field = CROM_MODEL_FIELD_MAP;
    m->rank = r;
    m->encoder = CROM_MODEL_ENC_NONE;
    int rc = crom_nn_mlp_from_params(&m->mlp, sp, net->params, net->nparams, NULL, NULL);
    if (!rc)
        rc = crom_mesh_copy(mesh, &m->mesh);
    if (!rc && basis_v) {
        size_t nb = (size_t)mesh->nv * 3 * r;
        m->basis_v = crom_malloc(sizeof(double) * nb);
        if (!m->basis_v)
            rc = CROM_EINTERNAL;
        else
            memcpy(m->basis_v, basis_v, sizeof(double) * nb);
    }
    if (rc)
        crom_model_free(m);
    else
        crom_model_id(m, m->model_id);
    return rc;
}

/* ----------------------------------------------------------------- write */

int crom_model_is_nonlinear(const crom_model *m)
{
    return m->field == CROM_MODEL_FIELD_MAP || m->field == CROM_MODEL_FIELD_CMAP ||
           (m->field == CROM_MODEL_FIELD_SKIN && m->latent.nparams > 0);
}

int crom_model_latent_normal(const crom_model *m)
{
    return !strcmp(m->basis, "energy") || !strcmp(m->basis, "energy-field") || !strcmp(m->basis, "skin-field");
}

int crom_model_skin_field(crom_model *m, const crom_nn_mlp *phi)
{
    const crom_nn_spec *ps = &phi->spec;
    if (m->field != CROM_MODEL_FIELD_SKIN || m->latent.nparams)
        return crom_err(CROM_EUSAGE, "model %s is not a linear skinning model", m->model_id);
    if (ps->width[ps->nlayers] != m->rank)
        return crom_err(CROM_EUSAGE, "the latent network gives %d features, the skinning basis has %d",
                        ps->width[ps->nlayers], m->rank);
    int rc = crom_nn_mlp_from_params(&m->latent, ps, phi->params, phi->nparams, NULL, NULL);
    if (rc)
        return rc;
    snprintf(m->basis, sizeof m->basis, "skin-field");
    m->rank = ps->width[0];
    m->encoder = CROM_MODEL_ENC_NONE;
    crom_model_id(m, m->model_id);
    return 0;
}

double crom_model_pin_mask(const double X[3], int npin, const double *pinX, int ntri, const double *triX, double len)
{
    if (npin < 1 && ntri < 1)
        return 1;
    double d2 = INFINITY;
    for (int k = 0; k < npin; k++) {
        const double *P = pinX + 3 * (size_t)k;
        double d = (X[0] - P[0]) * (X[0] - P[0]) + (X[1] - P[1]) * (X[1] - P[1]) + (X[2] - P[2]) * (X[2] - P[2]);
        d2 = d < d2 ? d : d2;
    }
    for (int k = 0; k < ntri && d2 > 0; k++) {
        const double *T = triX + 9 * (size_t)k;
        double d = crom_locate_tri_dist2(T, T + 3, T + 6, X);
        d2 = d < d2 ? d : d2;
    }
    double t = sqrt(d2) / len;
    return t >= 1 ? 1 : t * t * (3 - 2 * t);
}

double crom_model_mask(const crom_model *m, const double X[3])
{
    if (m->field != CROM_MODEL_FIELD_CMAP)
        return 1;
    return crom_model_pin_mask(X, m->npin_points, m->pin_points, m->npin_triangles, m->pin_triangles,
                               m->pin_length);
}

int crom_model_from_field_map(crom_model *m, const crom_nn_mlp *W, const crom_nn_mlp *phi, int npin,
                              const double *pinX, int ntri, const double *triX, double len)
{
    crom_model_clear(m);
    const crom_nn_spec *ws = &W->spec, *ps = &phi->spec;
    int p = ps->width[ps->nlayers];
    if (ws->width[0] != 3 || ws->width[ws->nlayers] != 3 * p)
        return crom_err(CROM_EUSAGE, "the feature field goes %d -> %d, expected 3 -> 3p = %d", ws->width[0],
                        ws->width[ws->nlayers], 3 * p);
    snprintf(m->basis, sizeof m->basis, "energy-field");
    m->field = CROM_MODEL_FIELD_CMAP;
    m->rank = ps->width[0];
    m->encoder = CROM_MODEL_ENC_NONE;
    int rc = crom_nn_mlp_from_params(&m->mlp, ws, W->params, W->nparams, W->shift, W->scale);
    if (!rc)
        rc = crom_nn_mlp_from_params(&m->latent, ps, phi->params, phi->nparams, NULL, NULL);
    m->pin_length = len;
    if (!rc && npin > 0) {
        m->pin_points = crom_malloc(sizeof(double) * 3 * (size_t)npin);
        if (!m->pin_points)
            rc = CROM_EINTERNAL;
        else {
            memcpy(m->pin_points, pinX, sizeof(double) * 3 * (size_t)npin);
            m->npin_points = npin;
        }
    }
    if (!rc && ntri > 0) {
        m->pin_triangles = crom_malloc(sizeof(double) * 9 * (size_t)ntri);
        if (!m->pin_triangles)
            rc = CROM_EINTERNAL;
        else {
            memcpy(m->pin_triangles, triX, sizeof(double) * 9 * (size_t)ntri);
            m->npin_triangles = ntri;
        }
    }
    if (rc) {
        crom_model_free(m);
        return rc;
    }
    crom_model_id(m, m->model_id);
    return 0;
}

static int write_widths(hid_t loc, const char *name, const crom_nn_spec *s)
{
    int w[CROM_NN_MAX_LAYERS + 1];
    for (int l = 0; l <= s->nlayers; l++)
        w[l] = s->width[l];
    hsize_t d = (hsize_t)s->nlayers + 1;
    return crom_h5_put_i32(loc, name, 1, &d, w);
}

/* The root attributes: what the model is, and the record of its training
 * and material when known. */
int crom_model_set_conditions(crom_model *m, int n, const crom_scenario_cond *cond)
{
    if (m->field != CROM_MODEL_FIELD_MAP || n < 0 || n > CROM_MODEL_MAXCOND)
        return crom_err(CROM_EUSAGE, "%d conditions: a map takes at most %d", n, CROM_MODEL_MAXCOND);
    int r = m->mlp.spec.width[0] - n;
    if (r < 1)
        return crom_err(CROM_EUSAGE, "a network of %d inputs has no latent left after %d conditions",
                        m->mlp.spec.width[0], n);
    m->rank = r;
    m->ncond = n;
    memcpy(m->cond, cond, sizeof *cond * (size_t)n);
    return 0;
}

/* The `conditions` attribute: one "NAME=LO:HI" per line (NULL: none). */
static char *conditions_text(const crom_model *m)
{
    if (!m->ncond)
        return NULL;
    char *t = crom_malloc((size_t)m->ncond * 200 + 1);
    if (!t)
        return NULL;
    t[0] = 0;
    for (int k = 0; k < m->ncond; k++) {
        size_t l = strlen(t);
        crom_scenario_cond_format(&m->cond[k], t + l, 198);
        strcat(t, "\n");
    }
    return t;
}

static int read_conditions(hid_t h, crom_model *m)
{
    if (!crom_h5_has_attr(h, ".", "conditions"))
        return 0;
    char *t = NULL;
    int rc = crom_h5_get_str(h, ".", "conditions", &t);
    for (char *line = t, *e; !rc && line && *line; line = e + 1) {
        e = strchr(line, '\n');
        if (!e)
            e = line + strlen(line) - 1;
        else
            *e = 0;
        if (!*line)
            continue;
        if (m->ncond == CROM_MODEL_MAXCOND)
            rc = crom_err(CROM_EDATA, "conditions: more than %d", CROM_MODEL_MAXCOND);
        else if (crom_scenario_cond_parse("conditions", line, 1, &m->cond[m->ncond++]))
            rc = CROM_EDATA;
    }
    free(t);
    return rc;
}

static int write_attrs(hid_t loc, const crom_model *m)
{
    int rc = crom_h5_set_str(loc, ".", "basis", m->basis);
    if (!rc)
        rc = crom_h5_set_i64(loc, ".", "rank", m->rank);
    if (!rc)
        rc = crom_h5_set_str(loc, ".", "encoder", crom_model_encoder_name(m->encoder));
    if (!rc)
        rc = crom_h5_set_str(loc, ".", "model_id", m->model_id);
    if (!rc && isfinite(m->reconstruction_error))
        rc = crom_h5_set_f64(loc, ".", "reconstruction_error", &m->reconstruction_error, 1);
    if (!rc && isfinite(m->training_seconds))
        rc = crom_h5_set_f64(loc, ".", "training_seconds", &m->training_seconds, 1);
    if (!rc && m->scenario)
        rc = crom_h5_set_str(loc, ".", "scenario", m->scenario);
    if (!rc && isfinite(m->youngs))
        rc = crom_h5_set_f64(loc, ".", "youngs", &m->youngs, 1);
    if (!rc && isfinite(m->poisson))
        rc = crom_h5_set_f64(loc, ".", "poisson", &m->poisson, 1);
    if (!rc && isfinite(m->density))
        rc = crom_h5_set_f64(loc, ".", "density", &m->density, 1);
    if (!rc && m->ncond) {
        char *t = conditions_text(m);
        rc = t ? crom_h5_set_str(loc, ".", "conditions", t) : CROM_EINTERNAL;
        free(t);
    }
    return rc;
}

/* CROM_MODEL_FIELD_MAP: the network r -> 3nv, its mesh (with regions), the
 * linear modes and their frequencies when present. */
static int write_map(hid_t loc, const crom_model *m)
{
    hsize_t np = m->mlp.nparams, dr = (hsize_t)m->rank;
    int rc = crom_h5_set_str(loc, ".", "activation", crom_nn_act_name(m->mlp.spec.act));
    if (!rc)
        rc = write_widths(loc, "field/widths", &m->mlp.spec);
    if (!rc)
        rc = crom_h5_put_f32(loc, "field/params", 1, &np, m->mlp.params);
    if (!rc) {
        hid_t g = crom_h5_group(loc, "field/mesh");
        rc = g < 0 ? CROM_EINTERNAL : crom_mesh_write(g, &m->mesh);
        if (g >= 0)
            H5Gclose(g);
    }
    if (!rc && m->basis_v) {
        hsize_t db[3] = {(hsize_t)m->mesh.nv, 3, (hsize_t)m->rank};
        rc = crom_h5_put_f64(loc, "field/basis", 3, db, m->basis_v);
    }
    if (!rc && m->deriv_v) {
        hsize_t dd[3] = {(hsize_t)m->mesh.nv, 3, (hsize_t)crom_model_nderiv(m)};
        rc = crom_h5_put_f64(loc, "field/derivatives", 3, dd, m->deriv_v);
    }
    if (!rc && m->seed_v) {
        hsize_t ds[2] = {(hsize_t)m->mesh.nv, 3};
        rc = crom_h5_put_f64(loc, "field/seed", 2, ds, m->seed_v);
    }
    if (!rc && m->lift_v) {
        hsize_t dl[3] = {(hsize_t)m->ncond, (hsize_t)m->mesh.nv, 3};
        rc = crom_h5_put_f64(loc, "field/lifts", 3, dl, m->lift_v);
    }
    if (!rc && m->frequencies)
        rc = crom_h5_put_f64(loc, "frequencies", 1, &dr, m->frequencies);
    return rc;
}

/* The latent network φ of a continuous map: widths and parameters. */
static int write_latent(hid_t loc, const crom_nn_mlp *phi)
{
    hsize_t nl = phi->nparams;
    int rc = write_widths(loc, "latent/widths", &phi->spec);
    if (!rc)
        rc = crom_h5_put_f32(loc, "latent/params", 1, &nl, phi->params);
    return rc;
}

/* CROM_MODEL_FIELD_MLP and _CMAP: the neural field with its input
 * normalization; for CMAP also the latent network and the pin mask. */
static int write_mlp(hid_t loc, const crom_model *m)
{
    const crom_nn_mlp *W = &m->mlp;
    double sh[3 + CROM_CUTFEAT_MAX], sc[3 + CROM_CUTFEAT_MAX];
    int din = W->spec.width[0];
    for (int i = 0; i < din && i < 3 + CROM_CUTFEAT_MAX; i++) {
        sh[i] = W->shift[i];
        sc[i] = W->scale[i];
    }
    hsize_t np = W->nparams, d3 = (hsize_t)din;
    int rc = crom_h5_set_str(loc, ".", "activation", crom_nn_act_name(W->spec.act));
    if (!rc)
        rc = write_widths(loc, "field/widths", &W->spec);
    if (!rc)
        rc = crom_h5_put_f32(loc, "field/params", 1, &np, W->params);
    if (!rc)
        rc = crom_h5_put_f64(loc, "field/input_shift", 1, &d3, sh);
    if (!rc)
        rc = crom_h5_put_f64(loc, "field/input_scale", 1, &d3, sc);
    if (!rc && m->cut.nseg) {
        hsize_t dc[2] = {(hsize_t)m->cut.nseg, 4};
        char ax[2] = {(char)('x' + m->cut.axis), 0};
        rc = crom_h5_put_f64(loc, "field/cut_segments", 2, dc, &m->cut.seg[0][0]);
        if (!rc)
            rc = crom_h5_set_str(loc, ".", "cut_axis", ax);
    }
    if (rc || m->field != CROM_MODEL_FIELD_CMAP)
        return rc;
    rc = write_latent(loc, &m->latent);
    hsize_t dp[2] = {(hsize_t)m->npin_points, 3}, d1 = 1;
    if (!rc && m->npin_points)
        rc = crom_h5_put_f64(loc, "latent/pin_points", 2, dp, m->pin_points);
    hsize_t dt[3] = {(hsize_t)m->npin_triangles, 3, 3};
    if (!rc && m->npin_triangles)
        rc = crom_h5_put_f64(loc, "latent/pin_triangles", 3, dt, m->pin_triangles);
    if (!rc)
        rc = crom_h5_put_f64(loc, "latent/pin_length", 1, &d1, &m->pin_length);
    return rc;
}

/* CROM_MODEL_FIELD_MESH: the mesh (vertices and tets) and W at its
 * vertices, with the frequencies of modes. */
int crom_model_write_field_mesh(hid_t loc, const crom_mesh *mesh)
{
    hsize_t dv[2] = {(hsize_t)mesh->nv, 3}, dt[2] = {(hsize_t)mesh->nt, 4}, dtri[2] = {(hsize_t)mesh->ntri, 3};
    int rc = crom_h5_put_f64(loc, "field/mesh/vertices", 2, dv, mesh->X);
    if (!rc && crom_mesh_is_surface(mesh)) { /* a shell: its triangles and thickness, as crom/mesh */
        rc = crom_h5_put_i32(loc, "field/mesh/triangles", 2, dtri, mesh->tris);
        if (!rc)
            rc = crom_h5_set_f64(loc, "field/mesh/triangles", "thickness", &mesh->thickness, 1);
    } else if (!rc) {
        rc = crom_h5_put_i32(loc, "field/mesh/tets", 2, dt, mesh->tets);
    }
    return rc;
}

static int write_mesh_field(hid_t loc, const crom_model *m)
{
    hsize_t db[3] = {(hsize_t)m->mesh.nv, 3, (hsize_t)m->rank}, dr = (hsize_t)m->rank;
    int rc = crom_model_write_field_mesh(loc, &m->mesh);
    if (!rc)
        rc = crom_h5_put_f64(loc, "field/basis", 3, db, m->basis_v);
    if (!rc && m->frequencies)
        rc = crom_h5_put_f64(loc, "frequencies", 1, &dr, m->frequencies);
    return rc;
}

/* The PointNet encoder: both networks' widths, the parameters and the
 * input normalization. */
static int write_encoder(hid_t loc, const crom_nn_pointnet *P)
{
    double sh[6], sc[6];
    for (int i = 0; i < 6; i++) {
        sh[i] = P->point.shift[i];
        sc[i] = P->point.scale[i];
    }
    hsize_t np = P->nparams, d6 = 6;
    int rc = write_widths(loc, "encoder/point_widths", &P->point.spec);
    if (!rc)
        rc = write_widths(loc, "encoder/head_widths", &P->head.spec);
    if (!rc)
        rc = crom_h5_put_f32(loc, "encoder/params", 1, &np, P->params);
    if (!rc)
        rc = crom_h5_put_f64(loc, "encoder/input_shift", 1, &d6, sh);
    if (!rc)
        rc = crom_h5_put_f64(loc, "encoder/input_scale", 1, &d6, sc);
    return rc;
}

int crom_model_write(hid_t loc, crom_model *m)
{
    crom_model_id(m, m->model_id);
    int rc = write_attrs(loc, m);
    if (rc)
        return rc;
    if (m->field == CROM_MODEL_FIELD_SKIN) {
        rc = crom_skin_write(loc, m);
        if (!rc && m->latent.nparams) /* skin-field: φ, with its own activation */
            rc = crom_h5_set_str(loc, ".", "latent_activation", crom_nn_act_name(m->latent.spec.act));
        if (!rc && m->latent.nparams)
            rc = write_latent(loc, &m->latent);
    } else if (m->field == CROM_MODEL_FIELD_MAP)
        rc = write_map(loc, m);
    else if (m->field == CROM_MODEL_FIELD_MLP || m->field == CROM_MODEL_FIELD_CMAP)
        rc = write_mlp(loc, m);
    else
        rc = write_mesh_field(loc, m);
    if (!rc && m->encoder == CROM_MODEL_ENC_POINTNET)
        rc = write_encoder(loc, &m->enc);
    if (!rc && m->nepochs > 0) { /* the training record */
        hsize_t de = (hsize_t)m->nepochs;
        rc = crom_h5_put_f64(loc, "training/loss", 1, &de, m->loss);
        if (!rc)
            rc = crom_h5_put_f64(loc, "training/seconds", 1, &de, m->seconds);
    }
    return rc;
}

/* ------------------------------------------------------------------ read */

static int read_widths(hid_t h, const char *name, int *w, int *n)
{
    hsize_t d;
    int *v = NULL;
    int rc = crom_h5_read_i32(h, name, 1, &d, &v);
    if (rc)
        return rc;
    if (d < 2 || d > CROM_NN_MAX_LAYERS + 1) {
        free(v);
        return crom_err(CROM_EDATA, "%s has %llu entries (2..%d expected)", name,
                        (unsigned long long)d, CROM_NN_MAX_LAYERS + 1);
    }
    memcpy(w, v, sizeof(int) * d);
    *n = (int)d;
    free(v);
    return 0;
}

static int read_vec(hid_t h, const char *name, int n, double *out, int required)
{
    if (!crom_h5_has(h, name)) {
        if (required)
            return crom_err(CROM_EDATA, "missing dataset '%s'", name);
        return 1;
    }
    hsize_t d;
    double *v = NULL;
    int rc = crom_h5_read_f64(h, name, 1, &d, &v);
    if (!rc && d != (hsize_t)n)
        rc = crom_err(CROM_EDATA, "%s has %llu entries, expected %d", name, (unsigned long long)d, n);
    if (!rc)
        memcpy(out, v, sizeof(double) * n);
    free(v);
    return rc;
}

static int all_finite_f(const float *p, size_t n)
{
    for (size_t i = 0; i < n; i++)
        if (!isfinite(p[i]))
            return 0;
    return 1;
}

static int all_finite_d(const double *p, size_t n)
{
    for (size_t i = 0; i < n; i++)
        if (!isfinite(p[i]))
            return 0;
    return 1;
}

int crom_model_read_net(hid_t h, const char *params, const char *shift, const char *scale, const crom_nn_spec *spec,
                        const char *what, crom_nn_mlp *out)
{
    hsize_t np;
    enum { MAXIN = 3 + CROM_CUTFEAT_MAX };
    float *par = NULL, fsh[MAXIN], fsc[MAXIN];
    double sh[MAXIN], sc[MAXIN];
    int din = spec->width[0];
    if (shift && din > MAXIN)
        return crom_err(CROM_EDATA, "%s takes %d inputs, at most %d are known", what, din, (int)MAXIN);
    int rc = crom_h5_read_f32(h, params, 1, &np, &par);
    if (!rc && shift && !(rc = read_vec(h, shift, din, sh, 1)))
        rc = read_vec(h, scale, din, sc, 1);
    if (!rc && (!all_finite_f(par, np) || (shift && (!all_finite_d(sh, din) || !all_finite_d(sc, din)))))
        rc = crom_err(CROM_EDATA, "%s has non-finite parameters", what);
    for (int i = 0; shift && !rc && i < din; i++) {
        fsh[i] = (float)sh[i];
        fsc[i] = (float)sc[i];
    }
    if (!rc && crom_nn_mlp_from_params(out, spec, par, np, shift ? fsh : NULL, shift ? fsc : NULL)) {
        char group[64];
        size_t len = strcspn(params, "/");
        snprintf(group, sizeof group, "%.*s", (int)(len < sizeof group ? len : sizeof group - 1), params);
        rc = crom_err_ctx(group);
    }
    free(par);
    return rc;
}

/* The latent network φ: r -> p of a continuous map (activation a) into
 * m->latent, its output width into *p. */
static int read_latent(hid_t h, crom_model *m, crom_nn_act a, int *p)
{
    int lw[CROM_NN_MAX_LAYERS + 1], nl, rc;
    crom_nn_spec ls;
    if ((rc = read_widths(h, "latent/widths", lw, &nl)))
        return rc;
    if (crom_nn_spec_set(&ls, nl, lw, a))
        return crom_err(CROM_EDATA, "latent/widths: %s", crom_errmsg());
    if (lw[0] != m->rank)
        return crom_err(CROM_EDATA, "latent/widths start at %d, the rank is %d", lw[0], m->rank);
    if ((rc = crom_model_read_net(h, "latent/params", NULL, NULL, &ls, "the latent network", &m->latent)))
        return rc;
    *p = lw[nl - 1];
    return 0;
}

/* skin-field: φ (its activation in latent_activation, elu by default), then
 * the skinning basis it maps into, whose width must be φ's output. */
static int read_skin_field(hid_t h, crom_model *m, const char *act)
{
    char *lact = NULL;
    crom_nn_act a = CROM_NN_ELU;
    if (crom_h5_has_attr(h, ".", "latent_activation") && !crom_h5_get_str(h, ".", "latent_activation", &lact) &&
        (crom_nn_act_parse(lact, &a) || (a != CROM_NN_ELU && a != CROM_NN_SINE && a != CROM_NN_GELU))) {
        int rc = crom_err(CROM_EDATA, "unknown latent_activation '%s' (elu, gelu or sine)", lact);
        free(lact);
        return rc;
    }
    free(lact);
    int p, rc = read_latent(h, m, a, &p);
    if (!rc)
        rc = crom_skin_read(h, m, act);
    if (!rc && crom_skin_width(m) != p)
        rc = crom_err(CROM_EDATA, "the latent network gives %d features, the skinning basis has %d", p,
                      crom_skin_width(m));
    return rc;
}

/* The cut a field takes features of (field/cut_segments, attribute
 * cut_axis), if any, into m->cut. */
static int read_cut(hid_t h, crom_model *m)
{
    int has = crom_h5_has(h, "field/cut_segments"), hasax = crom_h5_has_attr(h, ".", "cut_axis");
    if (!has && !hasax)
        return 0;
    if (!has || !hasax)
        return crom_err(CROM_EDATA, "a field with cut features needs both field/cut_segments and the attribute "
                        "cut_axis");
    char *ax = NULL;
    hsize_t d[2];
    double *seg = NULL;
    int rc = crom_h5_get_str(h, ".", "cut_axis", &ax);
    if (!rc && (strlen(ax) != 1 || ax[0] < 'x' || ax[0] > 'z'))
        rc = crom_err(CROM_EDATA, "cut_axis '%s' is not x, y or z", ax);
    if (!rc)
        rc = crom_h5_read_f64(h, "field/cut_segments", 2, d, &seg);
    if (!rc && (d[1] != 4 || d[0] < 1 || d[0] > CROM_CUTFEAT_MAX))
        rc = crom_err(CROM_EDATA, "field/cut_segments must be [K][4] with 1 <= K <= %d", CROM_CUTFEAT_MAX);
    if (!rc) {
        m->cut.axis = ax[0] - 'x';
        m->cut.nseg = (int)d[0];
        memcpy(m->cut.seg, seg, sizeof(double) * 4 * d[0]);
        if (crom_cutfeat_check(&m->cut))
            rc = crom_err(CROM_EDATA, "field/cut_segments: %s", crom_errmsg());
    }
    free(ax);
    free(seg);
    return rc;
}

static int read_mlp(hid_t h, crom_model *m, char *act)
{
    int w[CROM_NN_MAX_LAYERS + 1], nw;
    int rc = read_widths(h, "field/widths", w, &nw);
    if (rc)
        return rc;
    crom_nn_act a;
    if (crom_nn_act_parse(act, &a) || (a != CROM_NN_ELU && a != CROM_NN_SINE && a != CROM_NN_GELU))
        return crom_err(CROM_EDATA, "unknown activation '%s' (elu or sine)", act);
    crom_nn_spec spec;
    if (crom_nn_spec_set(&spec, nw, w, a))
        return crom_err(CROM_EDATA, "field/widths: %s", crom_errmsg());
    int p = m->rank;
    if (m->field == CROM_MODEL_FIELD_CMAP) { /* the latent network φ: r -> p first */
        if ((rc = read_latent(h, m, a, &p)))
            return rc;
        hsize_t d[2];
        double *len = NULL;
        if ((rc = crom_h5_read_f64(h, "latent/pin_length", 1, d, &len)))
            return rc;
        m->pin_length = d[0] == 1 ? len[0] : NAN;
        free(len);
        if (!(m->pin_length > 0) || !isfinite(m->pin_length))
            return crom_err(CROM_EDATA, "latent/pin_length must be one positive length");
        if (crom_h5_has(h, "latent/pin_points")) {
            if ((rc = crom_h5_read_f64(h, "latent/pin_points", 2, d, &m->pin_points)))
                return rc;
            if (d[1] != 3 || !all_finite_d(m->pin_points, 3 * (size_t)d[0]))
                return crom_err(CROM_EDATA, "latent/pin_points must be finite [n][3]");
            m->npin_points = (int)d[0];
        }
        if (crom_h5_has(h, "latent/pin_triangles")) {
            hsize_t d3[3];
            if ((rc = crom_h5_read_f64(h, "latent/pin_triangles", 3, d3, &m->pin_triangles)))
                return rc;
            if (d3[1] != 3 || d3[2] != 3 || !all_finite_d(m->pin_triangles, 9 * (size_t)d3[0]))
                return crom_err(CROM_EDATA, "latent/pin_triangles must be finite [n][3][3]");
            m->npin_triangles = (int)d3[0];
        }
    }
    if (m->field == CROM_MODEL_FIELD_MLP && (rc = read_cut(h, m)))
        return rc;
    if (w[0] != 3 + m->cut.nseg || w[nw - 1] != 3 * p)
        return crom_err(CROM_EDATA, "field/widths go %d -> %d, expected %d -> %d", w[0], w[nw - 1], 3 + m->cut.nseg,
                        3 * p);
    return crom_model_read_net(h, "field/params", "field/input_shift", "field/input_scale", &spec, "the field",
                               &m->mlp);
}

int crom_model_read_field_mesh(hid_t h, crom_model *m)
{
    hid_t g = H5Gopen2(h, "field/mesh", H5P_DEFAULT);
    if (g < 0)
        return crom_err(CROM_EDATA, "missing group field/mesh");
    int rc = crom_mesh_read_any(g, &m->mesh);
    H5Gclose(g);
    return rc ? crom_err_ctx("field/mesh") : 0;
}

static int read_mesh_field(hid_t h, crom_model *m)
{
    int rc = crom_model_read_field_mesh(h, m);
    if (rc)
        return rc;
    hsize_t d[3];
    if ((rc = crom_h5_read_f64(h, "field/basis", 3, d, &m->basis_v)))
        return rc;
    if (d[0] != (hsize_t)m->mesh.nv || d[1] != 3 || d[2] != (hsize_t)m->rank)
        return crom_err(CROM_EDATA, "field/basis is [%llu, %llu, %llu], expected [%d, 3, %d]",
                        (unsigned long long)d[0], (unsigned long long)d[1],
                        (unsigned long long)d[2], m->mesh.nv, m->rank);
    if (!all_finite_d(m->basis_v, (size_t)m->mesh.nv * 3 * m->rank))
        return crom_err(CROM_EDATA, "field/basis has non-finite values");
    if (crom_h5_has(h, "frequencies")) {
        m->frequencies = crom_malloc(sizeof(double) * (size_t)m->rank);
        if (!m->frequencies)
            return CROM_EINTERNAL;
        if ((rc = read_vec(h, "frequencies", m->rank, m->frequencies, 1)))
            return rc;
    }
    return crom_mesh_is_surface(&m->mesh) ? 0 : crom_locate_init(&m->loc, &m->mesh);
}

/* A map: the network r -> 3nv, its mesh (with regions), the linear part
 * (required for neuralmodes) and the frequencies (optional). */
static int read_map(hid_t h, crom_model *m, const char *act)
{
    hid_t g = H5Gopen2(h, "field/mesh", H5P_DEFAULT);
    if (g < 0)
        return crom_err(CROM_EDATA, "missing group field/mesh");
    int rc = crom_mesh_read_flags(g, CROM_MESH_SURFACES | CROM_MESH_SCENES, &m->mesh); /* energy maps of scenes */
    H5Gclose(g);
    if (rc)
        return crom_err_ctx("field/mesh");
    int w[CROM_NN_MAX_LAYERS + 1], nw;
    if ((rc = read_widths(h, "field/widths", w, &nw)))
        return rc;
    crom_nn_act a;
    if (crom_nn_act_parse(act, &a) || (a != CROM_NN_ELU && a != CROM_NN_SINE && a != CROM_NN_GELU))
        return crom_err(CROM_EDATA, "unknown activation '%s' (elu, gelu or sine)", act);
    crom_nn_spec spec;
    if (crom_nn_spec_set(&spec, nw, w, a))
        return crom_err(CROM_EDATA, "field/widths: %s", crom_errmsg());
    if (w[0] != m->rank + m->ncond || w[nw - 1] != 3 * m->mesh.nv)
        return crom_err(CROM_EDATA, "field/widths go %d -> %d, expected r + conditions -> 3nv = %d -> %d", w[0],
                        w[nw - 1], m->rank + m->ncond, 3 * m->mesh.nv);
    if ((rc = crom_model_read_net(h, "field/params", NULL, NULL, &spec, "the map", &m->mlp)))
        return rc;
    if (crom_h5_has(h, "field/basis")) {
        hsize_t d[3];
        if ((rc = crom_h5_read_f64(h, "field/basis", 3, d, &m->basis_v)))
            return rc;
        if (d[0] != (hsize_t)m->mesh.nv || d[1] != 3 || d[2] != (hsize_t)m->rank)
            return crom_err(CROM_EDATA, "field/basis is [%llu, %llu, %llu], expected [%d, 3, %d]",
                            (unsigned long long)d[0], (unsigned long long)d[1], (unsigned long long)d[2],
                            m->mesh.nv, m->rank);
        if (!all_finite_d(m->basis_v, (size_t)m->mesh.nv * 3 * m->rank))
            return crom_err(CROM_EDATA, "field/basis has non-finite values");
    } else if (!strcmp(m->basis, "neuralmodes")) {
        return crom_err(CROM_EDATA, "a neuralmodes map needs its linear modes field/basis");
    }
    if (crom_h5_has(h, "field/derivatives")) {
        hsize_t d[3];
        int nd = crom_model_nderiv(m);
        if (strcmp(m->basis, "neuralmodes"))
            return crom_err(CROM_EDATA, "field/derivatives belongs to a neuralmodes map, not to basis '%s'", m->basis);
        if ((rc = crom_h5_read_f64(h, "field/derivatives", 3, d, &m->deriv_v)))
            return rc;
        if (d[0] != (hsize_t)m->mesh.nv || d[1] != 3 || d[2] != (hsize_t)nd)
            return crom_err(CROM_EDATA, "field/derivatives is [%llu, %llu, %llu], expected [%d, 3, %d]",
                            (unsigned long long)d[0], (unsigned long long)d[1], (unsigned long long)d[2],
                            m->mesh.nv, nd);
        if (!all_finite_d(m->deriv_v, (size_t)m->mesh.nv * 3 * nd))
            return crom_err(CROM_EDATA, "field/derivatives has non-finite values");
    }
    if (crom_h5_has(h, "field/seed")) {
        hsize_t d[2];
        if (strcmp(m->basis, "energy"))
            return crom_err(CROM_EDATA, "field/seed belongs to an energy map, not to basis '%s'", m->basis);
        if ((rc = crom_h5_read_f64(h, "field/seed", 2, d, &m->seed_v)))
            return rc;
        if (d[0] != (hsize_t)m->mesh.nv || d[1] != 3)
            return crom_err(CROM_EDATA, "field/seed is [%llu, %llu], expected [%d, 3]", (unsigned long long)d[0],
                            (unsigned long long)d[1], m->mesh.nv);
        if (!all_finite_d(m->seed_v, (size_t)m->mesh.nv * 3))
            return crom_err(CROM_EDATA, "field/seed has non-finite values");
    }
    int pins = 0;
    for (int k = 0; k < m->ncond; k++)
        pins |= m->cond[k].kind == CROM_SCENARIO_COND_PIN;
    if (crom_h5_has(h, "field/lifts")) {
        hsize_t d[3];
        if (!pins)
            return crom_err(CROM_EDATA, "field/lifts belongs to a map with a pin condition");
        if ((rc = crom_h5_read_f64(h, "field/lifts", 3, d, &m->lift_v)))
            return rc;
        if (d[0] != (hsize_t)m->ncond || d[1] != (hsize_t)m->mesh.nv || d[2] != 3)
            return crom_err(CROM_EDATA, "field/lifts is [%llu, %llu, %llu], expected [%d, %d, 3]",
                            (unsigned long long)d[0], (unsigned long long)d[1], (unsigned long long)d[2], m->ncond,
                            m->mesh.nv);
        if (!all_finite_d(m->lift_v, (size_t)m->ncond * m->mesh.nv * 3))
            return crom_err(CROM_EDATA, "field/lifts has non-finite values");
    } else if (pins) {
        return crom_err(CROM_EDATA, "a map with a pin condition needs its static lifts field/lifts");
    }
    if (crom_h5_has(h, "frequencies")) {
        m->frequencies = crom_malloc(sizeof(double) * (size_t)m->rank);
        if (!m->frequencies)
            return CROM_EINTERNAL;
        if ((rc = read_vec(h, "frequencies", m->rank, m->frequencies, 1)))
            return rc;
    }
    return 0;
}

static int read_encoder(hid_t h, crom_model *m)
{
    int pw[CROM_NN_MAX_LAYERS + 1], hw[CROM_NN_MAX_LAYERS + 1], npw, nhw;
    int rc = read_widths(h, "encoder/point_widths", pw, &npw);
    if (!rc)
        rc = read_widths(h, "encoder/head_widths", hw, &nhw);
    if (rc)
        return rc;
    crom_nn_spec ps, hs;
    if (crom_nn_pointnet_spec(&ps, &hs, npw, pw, nhw, hw))
        return crom_err(CROM_EDATA, "encoder: %s", crom_errmsg());
    if (pw[0] != 6 || hw[nhw - 1] != m->rank)
        return crom_err(CROM_EDATA, "the encoder maps %d inputs to %d latents, expected 6 -> %d",
                        pw[0], hw[nhw - 1], m->rank);
    hsize_t np;
    float *params = NULL;
    double sh[6] = {0, 0, 0, 0, 0, 0}, sc[6] = {1, 1, 1, 1, 1, 1};
    if ((rc = crom_h5_read_f32(h, "encoder/params", 1, &np, &params)))
        return rc;
    int r1 = read_vec(h, "encoder/input_shift", 6, sh, 0);
    int r2 = read_vec(h, "encoder/input_scale", 6, sc, 0);
    if ((r1 && r1 != 1) || (r2 && r2 != 1)) {
        free(params);
        return r1 && r1 != 1 ? r1 : r2;
    }
    if (!all_finite_f(params, np) || !all_finite_d(sh, 6) || !all_finite_d(sc, 6)) {
        free(params);
        return crom_err(CROM_EDATA, "the encoder has non-finite parameters");
    }
    float fsh[6], fsc[6];
    for (int i = 0; i < 6; i++) {
        fsh[i] = (float)sh[i];
        fsc[i] = (float)sc[i];
    }
    rc = crom_nn_pointnet_from_params(&m->enc, &ps, &hs, params, np, fsh, fsc);
    free(params);
    return rc ? crom_err_ctx("encoder") : 0;
}

int crom_model_read(crom_in *in, crom_model *m)
{
    crom_model_clear(m);
    int rc = crom_in_expect(in, CROM_MODEL_SCHEMA, CROM_MODEL_VERSION);
    if (rc)
        return rc;
    hid_t h = in->h5;
    char *basis = NULL, *enc = NULL, *id = NULL, *act = NULL;
    long long rank = 0;
    if ((rc = crom_h5_get_str(h, ".", "basis", &basis)) ||
        (rc = crom_h5_get_i64(h, ".", "rank", &rank)) ||
        (rc = crom_h5_get_str(h, ".", "encoder", &enc)) ||
        (rc = crom_h5_get_str(h, ".", "model_id", &id))) {
        rc = crom_err(CROM_EDATA, "%s: %s", in->name, crom_errmsg());
        goto out;
    }
    snprintf(m->basis, sizeof m->basis, "%s", basis);
    if (rank < 1 || rank > 100000) {
        rc = crom_err(CROM_EDATA, "%s: rank %lld is not valid", in->name, rank);
        goto out;
    }
    m->rank = (int)rank;
    if (!strcmp(enc, "pointnet"))
        m->encoder = CROM_MODEL_ENC_POINTNET;
    else if (!strcmp(enc, "lsq"))
        m->encoder = CROM_MODEL_ENC_LSQ;
    else if (!strcmp(enc, "none"))
        m->encoder = CROM_MODEL_ENC_NONE;
    else {
        rc = crom_err(CROM_EDATA, "%s: unknown encoder '%s' (pointnet, lsq or none)", in->name, enc);
        goto out;
    }
    /* representation: by kind, or by the datasets present for later kinds */
    if (crom_model_is_map_kind(basis))
        m->field = CROM_MODEL_FIELD_MAP;
    else if (!strcmp(basis, "energy-field"))
        m->field = CROM_MODEL_FIELD_CMAP;
    else if (!strcmp(basis, "skinning") || !strcmp(basis, "skin-field"))
        m->field = CROM_MODEL_FIELD_SKIN;
    else if (!strcmp(basis, "mlp") || (strcmp(basis, "pod") && strcmp(basis, "modes") &&
                                       crom_h5_has(h, "field/params")))
        m->field = CROM_MODEL_FIELD_MLP;
    else if (!strcmp(basis, "pod") || !strcmp(basis, "modes") || crom_h5_has(h, "field/basis"))
        m->field = CROM_MODEL_FIELD_MESH;
    else {
        rc = crom_err(CROM_EDATA, "%s: basis '%s' has neither field/params nor field/basis",
                      in->name, basis);
        goto out;
    }
    if (m->field == CROM_MODEL_FIELD_SKIN) {
        if (crom_h5_has_attr(h, ".", "activation"))
            crom_h5_get_str(h, ".", "activation", &act);
        rc = strcmp(basis, "skin-field") ? crom_skin_read(h, m, act) : read_skin_field(h, m, act);
    } else if (m->field == CROM_MODEL_FIELD_MAP) {
        if (crom_h5_has_attr(h, ".", "activation"))
            crom_h5_get_str(h, ".", "activation", &act);
        rc = read_conditions(h, m);
        if (!rc)
            rc = read_map(h, m, act ? act : "elu");
    } else if (m->field == CROM_MODEL_FIELD_MLP || m->field == CROM_MODEL_FIELD_CMAP) {
        if (crom_h5_has_attr(h, ".", "activation"))
            crom_h5_get_str(h, ".", "activation", &act);
        rc = read_mlp(h, m, act ? act : "elu");
    } else {
        rc = read_mesh_field(h, m);
    }
    if (!rc && m->encoder == CROM_MODEL_ENC_POINTNET)
        rc = read_encoder(h, m);
    if (rc) {
        rc = crom_err(CROM_EDATA, "%s: %s", in->name, crom_errmsg());
        goto out;
    }
    if (crom_h5_has_attr(h, ".", "reconstruction_error"))
        crom_h5_get_f64(h, ".", "reconstruction_error", &m->reconstruction_error, 1);
    if (crom_h5_has_attr(h, ".", "training_seconds"))
        crom_h5_get_f64(h, ".", "training_seconds", &m->training_seconds, 1);
    if (crom_h5_has_attr(h, ".", "scenario"))
        crom_h5_get_str(h, ".", "scenario", &m->scenario);
    if (crom_h5_has_attr(h, ".", "youngs"))
        crom_h5_get_f64(h, ".", "youngs", &m->youngs, 1);
    if (crom_h5_has_attr(h, ".", "poisson"))
        crom_h5_get_f64(h, ".", "poisson", &m->poisson, 1);
    if (crom_h5_has_attr(h, ".", "density"))
        crom_h5_get_f64(h, ".", "density", &m->density, 1);
    if (crom_h5_has_attr(h, ".", "sigma"))
        crom_h5_get_f64(h, ".", "sigma", &m->sigma, 1);
    if (crom_h5_has_attr(h, ".", "latent_box"))
        crom_h5_get_f64(h, ".", "latent_box", &m->latent_box, 1);
    if (crom_h5_has_attr(h, ".", "latent_box_scaling")) { /* it decides where crom-metrics samples */
        char *s = NULL;
        if (!crom_h5_get_str(h, ".", "latent_box_scaling", &s) && strcmp(s, "frequency") && strcmp(s, "uniform"))
            rc = crom_err(CROM_EDATA, "%s: unknown latent_box_scaling '%s' (frequency or uniform)", in->name, s);
        m->latent_box_scaled = s && !strcmp(s, "frequency");
        free(s);
        if (rc)
            goto out;
    }
    if (crom_h5_has_attr(h, ".", "gravity") && !crom_h5_get_f64(h, ".", "gravity", m->gravity, 3))
        m->has_gravity = 1;
    if (crom_h5_has_attr(h, ".", "tangent_anchored")) { /* it changes the map */
        long long v = 0;
        if (crom_h5_get_i64(h, ".", "tangent_anchored", &v) || (v != 0 && v != 1) ||
            (v && strcmp(m->basis, "neuralmodes"))) {
            rc = crom_err(CROM_EDATA, "%s: tangent_anchored must be 0 or 1, and only on a neuralmodes map", in->name);
            goto out;
        }
        m->tangent_anchored = (int)v;
    }
    crom_err_clear();
    crom_model_id(m, m->model_id);
    if (strcmp(id, m->model_id)) {
        rc = crom_err(CROM_EDATA, "%s: model_id %s does not match the basis parameters (digest %s): "
                      "the file was changed or is corrupt", in->name, id, m->model_id);
        goto out;
    }
out:
    free(basis);
    free(enc);
    free(id);
    free(act);
    if (rc)
        crom_model_free(m);
    return rc;
}

int crom_model_load(const char *path, crom_model *m)
{
    crom_in in;
    crom_model_clear(m);
    int rc = crom_in_open(&in, path);
    if (rc)
        return rc;
    rc = crom_model_read(&in, m);
    crom_in_close(&in);
    return rc;
}

/* ------------------------------------------------------------ evaluation */

int crom_model_eval(const crom_model *m, size_t n, const double *X, double *W,
                    size_t *noutside)
{
    return crom_model_eval_sided(m, n, X, NULL, W, noutside);
}

/* 1 if the n points X are mesh's vertices (to round-off). */
static int at_vertices(const crom_mesh *mesh, size_t n, const double *X)
{
    int same = n == (size_t)mesh->nv;
    for (size_t i = 0; same && i < 3 * n; i++)
        same = fabs(X[i] - mesh->X[i]) <= 1e-9 * (1 + fabs(X[i]));
    return same;
}

int crom_model_eval_mesh(const crom_model *m, const crom_mesh *mesh, double s, double *W, size_t *noutside,
                         int *nshifted)
{
    if (nshifted)
        *nshifted = 0;
    size_t n = (size_t)mesh->nv;
    if (crom_mesh_is_surface(mesh) ||
        (m->field == CROM_MODEL_FIELD_MESH && at_vertices(&m->mesh, n, mesh->X)))
        return crom_model_eval(m, n, mesh->X, W, noutside);
    double *P = crom_mesh_field_points(mesh, s, nshifted);
    if (!P)
        return CROM_EINTERNAL;
    int rc = m->field == CROM_MODEL_FIELD_MLP && m->cut.nseg ? crom_model_eval_sided(m, n, mesh->X, P, W, noutside)
                                                             : crom_model_eval(m, n, P, W, noutside);
    free(P);
    return rc;
}

int crom_model_eval_sided(const crom_model *m, size_t n, const double *X, const double *S, double *W,
                          size_t *noutside)
{
    if (noutside)
        *noutside = 0;
    if (n == 0)
        return 0;
    if (m->field == CROM_MODEL_FIELD_MESH) {
        /* at its own vertices a mesh field is its values, exactly (zero at
         * the pins: interpolation would leave round-off there); a shell's
         * basis lives at its own vertices only */
        if (at_vertices(&m->mesh, n, X)) {
            memcpy(W, m->basis_v, sizeof(double) * 3 * (size_t)m->rank * n);
            return 0;
        }
        if (crom_mesh_is_surface(&m->mesh))
            return crom_err(CROM_EDATA, "model %s (basis '%s') was made on a shell surface of %d vertices and is "
                            "evaluated only at them, got %zu other points", m->model_id, m->basis, m->mesh.nv, n);
        crom_locate_interp(&m->loc, n, X, 3 * m->rank, m->basis_v, W, noutside);
        return 0;
    }
    if (m->field == CROM_MODEL_FIELD_SKIN && !m->latent.nparams)
        return crom_skin_eval(m, n, X, W, noutside);
    if (m->field == CROM_MODEL_FIELD_SKIN || m->field == CROM_MODEL_FIELD_CMAP)
        return crom_err(CROM_EDATA, "model %s is a continuous nonlinear map x(X, q) (basis '%s'), not a basis "
                        "field W(X): it has no encoding; simulate it with crom-reducedstep --model --mesh",
                        m->model_id, m->basis);
    if (m->field == CROM_MODEL_FIELD_MAP)
        return crom_err(CROM_EDATA, "model %s is a nonlinear map of one mesh (basis '%s'), not a basis field "
                        "W(X): it has no encoding; simulate it with crom-reducedstep --model",
                        m->model_id, m->basis);
    if (m->field != CROM_MODEL_FIELD_MLP)
        return crom_err(CROM_EINTERNAL, "model has no basis");
    crom_nn_ws ws;
    int rc = crom_nn_ws_init(&ws, &m->mlp, n < 4096 ? (int)n : 4096, 1);
    if (rc)
        return rc;
    if (!m->cut.nseg) {
        rc = crom_nn_mlp_eval(&m->mlp, &ws, n, X, W, NULL);
        crom_nn_ws_free(&ws);
        return rc;
    }
    /* X and its cut features, a chunk at a time */
    size_t chunk = 4096, din = 3 + (size_t)m->cut.nseg, out = 3 * (size_t)m->rank;
    double *in = crom_malloc(sizeof(double) * din * (n < chunk ? n : chunk));
    rc = in ? 0 : CROM_EINTERNAL;
    for (size_t s = 0; !rc && s < n; s += chunk) {
        size_t k = n - s < chunk ? n - s : chunk;
        crom_cutfeat_inputs_d(&m->cut, k, X + 3 * s, S ? S + 3 * s : NULL, in);
        rc = crom_nn_mlp_eval(&m->mlp, &ws, k, in, W + out * s, NULL);
    }
    free(in);
    crom_nn_ws_free(&ws);
    return rc;
}

int crom_model_encode_pointnet(const crom_model *m, size_t n, const double *pts, double *q)
{
    if (m->encoder != CROM_MODEL_ENC_POINTNET || !m->enc.params)
        return crom_err(CROM_EUSAGE, "the model has no PointNet encoder (its encoder is %s)",
                        crom_model_encoder_name(m->encoder));
    crom_nn_pointnet_ws ws;
    int rc = crom_nn_pointnet_ws_init(&ws, &m->enc, 1, n < 4096 ? (int)n : 4096, 1);
    if (rc)
        return rc;
    rc = crom_nn_pointnet_encode(&m->enc, &ws, n, pts, q);
    crom_nn_pointnet_ws_free(&ws);
    return rc;
}
