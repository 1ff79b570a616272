/* result.c — results as displacement frames on a mesh (see result.h). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cblas.h>

#include "base/err.h"
#include "phys/rigidsys.h"
#include "rom/map.h"
#include "rom/model.h"
#include "rom/result.h"

int crom_result_open(crom_result *res, const char *path, const char *mesh_path, const char *model_path)
{
    crom_in in;
    int rc = crom_in_open(&in, path);
    if (rc) {
        memset(res, 0, sizeof *res);
        return rc;
    }
    return crom_result_adopt(res, &in, mesh_path, model_path);
}

/* The mesh a latent of model is decoded onto, from mesh_path (or a file
 * carrying a mesh): a tet mesh, the model's own shell surface (a model
 * made on a shell lives on that shell only), or any shell for a
 * continuous field (a neural field W(X) of no mesh, e.g. trained on a
 * shell's samples); a field on a tet mesh of its own does not lay on a
 * shell. Anything else is refused with a one-line message. */
static int latent_mesh(const char *mesh_path, const crom_model *model, crom_mesh *m)
{
    int rc = crom_mesh_load(mesh_path, CROM_MESH_CARRIERS | CROM_MESH_SURFACES, m, NULL);
    int shell_model = crom_mesh_is_surface(&model->mesh);
    if (!rc && crom_mesh_is_surface(m) && !shell_model && model->mesh.nv > 0)
        rc = crom_err(CROM_EUSAGE, "%s holds a shell surface (%d triangles): model %s is a field over solids and "
                      "is decoded onto tet meshes only", mesh_path, m->ntri, model->model_id);
    else if (!rc && shell_model && crom_map_same_mesh(m, &model->mesh))
        rc = crom_err(CROM_EDATA, "model %s was made on a shell surface (%d vertices, %d triangles) and decodes only "
                      "onto it; %s has %d vertices, %d %s", model->model_id, model->mesh.nv, model->mesh.ntri,
                      mesh_path, m->nv, crom_mesh_is_surface(m) ? m->ntri : m->nt,
                      crom_mesh_is_surface(m) ? "triangles" : "tets");
    if (rc && m->X)
        crom_mesh_free(m);
    return rc;
}

/* The display surface of scene mesh sc into res (crom_rigidsys_display),
 * with scratch for the frame vertices' u and v. */
static int scene_display(crom_result *res, const crom_mesh *sc)
{
    res->scene_nv = sc->nv;
    int rc = crom_rigidsys_display(sc, CROM_RESULT_DISPLAY_RINGS, &res->mesh, &res->dbeta, &res->dbody);
    if (!rc && !(res->uf = crom_malloc(sizeof(double) * 6 * (size_t)sc->nv)))
        rc = CROM_EINTERNAL;
    return rc;
}

/* Whether the mesh at path (or a file carrying one) is the scene sc. */
static int same_scene(const char *path, const crom_mesh *sc, const char *what)
{
    crom_mesh given;
    int rc = crom_mesh_load(path, CROM_MESH_CARRIERS | CROM_MESH_SURFACES | CROM_MESH_SCENES, &given, NULL);
    int same = !rc && given.scene && !crom_map_same_mesh(sc, &given);
    if (!rc)
        crom_mesh_free(&given);
    if (!rc && !same)
        rc = crom_err(CROM_EDATA, "%s lives on a rigid-body scene, and %s is not that scene", what, path);
    return rc;
}

/* A latent of an energy map of a rigid-body scene: x(q) on the scene's
 * frame vertices, shown on its display surface (a --mesh must be the same
 * scene). */
static int latent_scene_map(crom_result *res, const crom_model *model, const char *mesh_path)
{
    int rc = mesh_path ? same_scene(mesh_path, &model->mesh, res->in.name) : 0;
    if (!rc)
        rc = crom_map_init(res->map, model, NULL);
    if (!rc)
        rc = scene_display(res, &res->map->mesh);
    res->J = rc ? NULL : crom_malloc(sizeof(double) * 3 * (size_t)res->r * (size_t)res->scene_nv);
    if (!rc && !res->J)
        rc = CROM_EINTERNAL;
    return rc;
}

/* A latent decoded by a nonlinear map: x(q) on the map's own mesh, or
 * (continuous) on the one at mesh_path; J its Jacobian's buffer. */
static int latent_map(crom_result *res, const crom_model *model, const char *mesh_path)
{
    crom_mesh given;
    memset(&given, 0, sizeof given);
    int rc = 0;
    res->map = crom_calloc(1, sizeof *res->map);
    if (!res->map)
        rc = CROM_EINTERNAL;
    if (!rc && model->mesh.scene)
        return latent_scene_map(res, model, mesh_path);
    if (!rc && mesh_path)
        rc = latent_mesh(mesh_path, model, &given);
    if (!rc) {
        rc = crom_map_init(res->map, model, mesh_path ? &given : NULL);
        if (rc && mesh_path)
            crom_err_ctx("--mesh %s", mesh_path);
    }
    if (!rc && res->frame)
        rc = crom_map_add_frame(res->map);
    crom_mesh_free(&given);
    if (!rc)
        rc = crom_mesh_copy(&res->map->mesh, &res->mesh);
    res->J = rc ? NULL : crom_malloc(sizeof(double) * 3 * (size_t)res->r * (size_t)res->mesh.nv);
    if (!rc && !res->J)
        rc = CROM_EINTERNAL;
    return rc;
}

/* A latent decoded by a linear basis: W evaluated at the field points of
 * the mesh at mesh_path (required). */
static int latent_basis(crom_result *res, const crom_model *model, const char *mesh_path)
{
    if (!mesh_path)
        return crom_err(CROM_EUSAGE, "%s is a crom/latent: decoding it needs --model and --mesh", res->in.name);
    int rc = latent_mesh(mesh_path, model, &res->mesh);
    if (rc)
        return rc;
    res->W = crom_malloc(sizeof(double) * 3 * (size_t)res->r * (size_t)res->mesh.nv);
    if (res->W && crom_mesh_is_surface(&model->mesh)) /* its own shell: W at its vertices */
        return crom_model_eval(model, (size_t)res->mesh.nv, res->mesh.X, res->W, &res->outside);
    return res->W ? crom_model_eval_mesh(model, &res->mesh, CROM_MESH_CRACK_OFFSET, res->W, &res->outside, NULL)
                  : CROM_EINTERNAL;
}

/* A crom/latent: its fields, the model at model_path (required), which
 * must be the one it names, and the decoder. */
static int adopt_latent(crom_result *res, const char *mesh_path, const char *model_path)
{
    crom_in *in = &res->in;
    res->latent = 1;
    int rc = crom_in_expect(in, "crom/latent", 1);
    if (rc)
        return rc;
    if (!model_path)
        return crom_err(CROM_EUSAGE, "%s is a crom/latent: decoding it needs --model and --mesh", in->name);
    char *id = NULL;
    if ((rc = crom_h5_get_str(in->h5, ".", "model_id", &id))) {
        crom_err_ctx("%s", in->name);
        return rc;
    }
    snprintf(res->model_id, sizeof res->model_id, "%s", id);
    free(id);
    res->ft = crom_in_field(in, "time");
    res->fu = crom_in_field(in, "q");
    if (res->ft < 0 || res->fu < 0)
        return CROM_EDATA;
    res->fv = crom_in_field(in, "qdot");
    res->fc = -1;
    for (int i = 0; i < in->nfields; i++)
        if (!strcmp(in->fields[i].name, "condition"))
            res->fc = i;
    crom_err_clear();
    crom_model model;
    if ((rc = crom_model_load(model_path, &model)))
        return rc;
    if (strcmp(model.model_id, res->model_id)) {
        rc = crom_err(CROM_EDATA, "%s holds coordinates of model %s, but --model %s is model %s", in->name,
                      res->model_id, model_path, model.model_id);
    } else {
        if ((rc = crom_result_latent_frame(in->h5, &res->frame)))
            crom_err_ctx("%s", in->name);
        res->r = model.rank + (res->frame ? 6 : 0);
        if (!rc && (int)in->fields[res->fu].count != res->r)
            rc = crom_err(CROM_EDATA, "%s: q has %zu entries, the model's rank is %d", in->name,
                          in->fields[res->fu].count, res->r);
        else if (!rc && res->fc >= 0 && (int)in->fields[res->fc].count != model.ncond)
            rc = crom_err(CROM_EDATA, "%s: a condition of %zu values, model %s has %d conditions", in->name,
                          in->fields[res->fc].count, model.model_id, model.ncond);
        else if (!rc && (crom_model_is_nonlinear(&model) || res->frame))
            rc = latent_map(res, &model, mesh_path);
        else if (!rc)
            rc = latent_basis(res, &model, mesh_path);
    }
    crom_model_free(&model);
    return rc;
}

/* A crom/trajectory: its fields and its own mesh (tets or a shell), or the
 * one at mesh_path when that has the same vertices and is of the same kind. */
static int adopt_trajectory(crom_result *res, const char *mesh_path)
{
    crom_in *in = &res->in;
    int rc = crom_in_expect(in, "crom/trajectory", 1);
    if (rc)
        return rc;
    res->ft = crom_in_field(in, "time");
    res->fu = crom_in_field(in, "displacement");
    if (res->ft < 0 || res->fu < 0)
        return CROM_EDATA;
    res->fv = crom_in_field(in, "velocity");
    crom_err_clear();
    hid_t g = H5Gopen2(in->h5, "mesh", H5P_DEFAULT);
    crom_mesh own;
    rc = g < 0 ? crom_err(CROM_EDATA, "%s has no mesh", in->name)
               : crom_mesh_read_flags(g, CROM_MESH_SURFACES | CROM_MESH_SCENES, &own);
    if (g >= 0)
        H5Gclose(g);
    if (rc) {
        if (g >= 0)
            crom_err_ctx("/mesh");
        crom_err_ctx("%s", in->name);
        return rc;
    }
    if (own.scene) { /* shown on its display surface */
        rc = mesh_path ? same_scene(mesh_path, &own, in->name) : 0;
        if (!rc && in->fields[res->fu].count != 3 * (size_t)own.nv)
            rc = crom_err(CROM_EDATA, "%s: displacement has %zu values per frame, the scene needs %d", in->name,
                          in->fields[res->fu].count, 3 * own.nv);
        if (!rc)
            rc = scene_display(res, &own);
        crom_mesh_free(&own);
        return rc;
    }
    if (mesh_path) {
        if ((rc = crom_mesh_load(mesh_path, CROM_MESH_CARRIERS | CROM_MESH_SURFACES, &res->mesh, NULL))) {
            crom_mesh_free(&own);
            return rc;
        }
        int kind = crom_mesh_is_surface(&own);
        if (crom_mesh_is_surface(&res->mesh) != kind) {
            crom_mesh_free(&own);
            return crom_err(CROM_EDATA, "%s holds a %s, but %s was computed on a %s", mesh_path,
                            kind ? "tet mesh" : "shell surface", in->name, kind ? "shell surface" : "tet mesh");
        }
        int same = res->mesh.nv == own.nv;
        for (int i = 0; same && i < 3 * own.nv; i++)
            same = fabs(res->mesh.X[i] - own.X[i]) <= 1e-9 * (1 + fabs(own.X[i]));
        crom_mesh_free(&own);
        if (!same)
            return crom_err(CROM_EDATA, "--mesh %s does not have the vertices of the mesh %s was computed on (a "
                                        "trajectory lives on its own mesh; decode a crom/latent to move between "
                                        "meshes)", mesh_path, in->name);
    } else {
        res->mesh = own;
    }
    if (in->fields[res->fu].count != 3 * (size_t)res->mesh.nv)
        return crom_err(CROM_EDATA, "%s: displacement has %zu values per frame, the mesh needs %d", in->name,
                        in->fields[res->fu].count, 3 * res->mesh.nv);
    return 0;
}

int crom_result_adopt(crom_result *res, crom_in *opened, const char *mesh_path, const char *model_path)
{
    memset(res, 0, sizeof *res);
    res->in = *opened;
    memset(opened, 0, sizeof *opened);
    opened->h5 = -1;
    int rc = !strcmp(res->in.schema, "crom/latent") ? adopt_latent(res, mesh_path, model_path)
                                                     : adopt_trajectory(res, mesh_path);
    if (rc)
        crom_result_close(res);
    return rc;
}

int crom_result_check_frame(const crom_in *in, const double *frame, long k)
{
    if (!frame)
        frame = in->frame;
    for (int f = 0; f < in->nfields; f++) {
        const crom_io_field *fd = &in->fields[f];
        for (size_t i = 0; i < fd->count; i++) {
            if (isfinite(frame[fd->offset + i]))
                continue;
            if (fd->rank == 2 && fd->dims[1] == 3)
                return crom_err(CROM_EDATA, "%s: frame %ld has a non-finite %s at vertex %zu", in->name, k,
                                fd->name, i / 3);
            if (fd->count > 1)
                return crom_err(CROM_EDATA, "%s: frame %ld has a non-finite %s at index %zu", in->name, k,
                                fd->name, i);
            return crom_err(CROM_EDATA, "%s: frame %ld has a non-finite %s", in->name, k, fd->name);
        }
    }
    return 0;
}

int crom_result_next(crom_result *res, double *t, double *u, double *v)
{
    int rc = crom_in_next(&res->in);
    if (rc != 1)
        return rc;
    if ((rc = crom_result_check_frame(&res->in, NULL, res->in.cursor - 1)))
        return rc;
    *t = crom_in_get(&res->in, res->ft)[0];
    int n = 3 * res->mesh.nv;
    if (res->scene_nv && !res->latent) { /* a scene run: frame vertices to the display surface */
        crom_rigidsys_display_map(res->mesh.nv, res->dbeta, res->dbody, crom_in_get(&res->in, res->fu), u);
        if (v && res->fv >= 0)
            crom_rigidsys_display_map(res->mesh.nv, res->dbeta, res->dbody, crom_in_get(&res->in, res->fv), v);
        else if (v)
            memset(v, 0, sizeof(double) * (size_t)n);
        return 1;
    }
    if (!res->latent) {
        memcpy(u, crom_in_get(&res->in, res->fu), sizeof(double) * (size_t)n);
        if (v) {
            if (res->fv >= 0)
                memcpy(v, crom_in_get(&res->in, res->fv), sizeof(double) * (size_t)n);
            else
                memset(v, 0, sizeof(double) * (size_t)n);
        }
        return 1;
    }
    if (res->map) { /* u = x(q) − X, v = J(q) q̇ (a scene's: at its frame vertices, then shown) */
        int sc = res->scene_nv > 0, nm = sc ? 3 * res->scene_nv : n;
        double *uu = sc ? res->uf : u, *vv = sc ? res->uf + nm : v;
        if (res->fc >= 0 && res->map->nc) { /* a conditional map at the frame's condition */
            const double *c = crom_in_get(&res->in, res->fc);
            if (memcmp(c, res->map->cond, sizeof(double) * (size_t)res->map->nc) &&
                (rc = crom_map_set_condition(res->map, c)))
                return rc;
        }
        rc = crom_map_eval(res->map, crom_in_get(&res->in, res->fu), uu, v ? res->J : NULL);
        if (rc)
            return rc;
        for (int i = 0; i < nm; i++)
            uu[i] -= res->map->mesh.X[i];
        if (v) {
            if (res->fv >= 0)
                cblas_dgemv(CblasRowMajor, CblasNoTrans, nm, res->r, 1.0, res->J, res->r,
                            crom_in_get(&res->in, res->fv), 1, 0.0, vv, 1);
            else
                memset(vv, 0, sizeof(double) * (size_t)nm);
        }
        if (sc) {
            crom_rigidsys_display_map(res->mesh.nv, res->dbeta, res->dbody, uu, u);
            if (v)
                crom_rigidsys_display_map(res->mesh.nv, res->dbeta, res->dbody, vv, v);
        }
        return 1;
    }
    /* u = W q: W is [nv·3][r] */
    cblas_dgemv(CblasRowMajor, CblasNoTrans, n, res->r, 1.0, res->W, res->r, crom_in_get(&res->in, res->fu), 1,
                0.0, u, 1);
    if (v) {
        if (res->fv >= 0)
            cblas_dgemv(CblasRowMajor, CblasNoTrans, n, res->r, 1.0, res->W, res->r,
                        crom_in_get(&res->in, res->fv), 1, 0.0, v, 1);
        else
            memset(v, 0, sizeof(double) * (size_t)n);
    }
    return 1;
}

void crom_result_close(crom_result *res)
{
    crom_in_close(&res->in);
    crom_mesh_free(&res->mesh);
    free(res->W);
    res->W = NULL;
    if (res->map)
        crom_map_free(res->map);
    free(res->map);
    res->map = NULL;
    free(res->J);
    res->J = NULL;
    free(res->dbeta);
    free(res->dbody);
    free(res->uf);
    res->dbeta = res->uf = NULL;
    res->dbody = NULL;
    res->scene_nv = 0;
}

void crom_result_equilibria_free(crom_result_equilibria *eq)
{
    if (!eq)
        return;
    crom_mesh_free(&eq->mesh);
    free(eq->scenario);
    free(eq->Z);
    free(eq->U);
    memset(eq, 0, sizeof *eq);
}

int crom_result_equilibria_load(const char *path, crom_result_equilibria *eq)
{
    memset(eq, 0, sizeof *eq);
    crom_result res;
    int rc = crom_result_open(&res, path, NULL, NULL);
    if (rc)
        return rc;
    char *id = NULL;
    int fz = -1, n = 3 * res.mesh.nv;
    long cap = 0;
    if (res.latent || !crom_h5_has_attr(res.in.h5, ".", "equilibria_model") ||
        (fz = crom_in_field(&res.in, "modal_coordinates")) < 0) {
        crom_err_clear();
        rc = crom_err(CROM_EUSAGE, "%s holds no constrained equilibria (crom-fullsim --equilibria)", res.in.name);
        goto out;
    }
    eq->r = (int)res.in.fields[fz].count;
    if ((rc = crom_h5_get_str(res.in.h5, ".", "scenario", &eq->scenario)) ||
        (rc = crom_h5_get_str(res.in.h5, ".", "equilibria_model", &id)))
        goto out;
    snprintf(eq->model_id, sizeof eq->model_id, "%s", id);
    for (;;) {
        if (eq->K == cap) {
            cap = cap ? 2 * cap : 64;
            double *z2 = crom_realloc(eq->Z, sizeof(double) * (size_t)cap * eq->r);
            if (z2)
                eq->Z = z2;
            double *u2 = z2 ? crom_realloc(eq->U, sizeof(double) * (size_t)cap * n) : NULL;
            if (u2)
                eq->U = u2;
            if (!z2 || !u2) {
                rc = CROM_EINTERNAL;
                goto out;
            }
        }
        double t;
        int got = crom_result_next(&res, &t, eq->U + (size_t)eq->K * n, NULL);
        if (got == 0)
            break;
        if (got != 1) {
            rc = got < 0 ? -got : got;
            goto out;
        }
        memcpy(eq->Z + (size_t)eq->K * eq->r, crom_in_get(&res.in, fz), sizeof(double) * (size_t)eq->r);
        eq->K++;
    }
    if (eq->K == 0)
        rc = crom_err(CROM_EDATA, "%s holds no equilibrium", res.in.name);
    if (!rc) { /* keep the mesh */
        eq->mesh = res.mesh;
        memset(&res.mesh, 0, sizeof res.mesh);
    }
out:
    free(id);
    crom_result_close(&res);
    if (rc)
        crom_result_equilibria_free(eq);
    return rc;
}

int crom_result_latent_frame(hid_t h5, int *frame)
{
    long long f = 0;
    int rc = crom_h5_has_attr(h5, ".", "rigid_frame") ? crom_h5_get_i64(h5, ".", "rigid_frame", &f) : 0;
    *frame = !rc && f != 0;
    return rc;
}
