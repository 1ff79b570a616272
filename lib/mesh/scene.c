/* scene.c — rigid-body scenes: data, checks and the HDF5 layout (scene.h). */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "io/io.h"
#include "mesh/scene.h"

static const char *const shape_names[CROM_SCENE_COUNT] = {"box", "sphere", "capsule", "ring"};

crom_scene_body crom_scene_body_make(int shape, const double size[3], const double centre[3], double density)
{
    crom_scene_body b = {shape, {size[0], size[1], size[2]}, {centre[0], centre[1], centre[2]}, density,
                         {1, 0, 0, 0, 1, 0, 0, 0, 1}};
    return b;
}

const char *crom_scene_shape_name(int shape)
{
    return shape >= 0 && shape < CROM_SCENE_COUNT ? shape_names[shape] : "?";
}

int crom_scene_shape_parse(const char *name)
{
    for (int k = 0; k < CROM_SCENE_COUNT; k++)
        if (!strcmp(name, shape_names[k]))
            return k;
    return -1;
}

double crom_scene_body_volume(const crom_scene_body *b)
{
    const double *a = b->size;
    switch (b->shape) {
    case CROM_SCENE_BOX:
        return a[0] * a[1] * a[2];
    case CROM_SCENE_SPHERE:
        return 4.0 / 3.0 * M_PI * a[0] * a[0] * a[0];
    case CROM_SCENE_CAPSULE:
        return M_PI * a[0] * a[0] * (a[1] + 4.0 / 3.0 * a[0]);
    case CROM_SCENE_RING: /* Pappus: the tube's cross-section times the centreline's length */
        return M_PI * a[0] * a[0] * (2 * M_PI * a[1] + 2 * a[2]);
    }
    return 0;
}

static int finite3(const double *v) { return isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]); }

int crom_scene_validate(const crom_scene *s)
{
    if (s->nb < 1)
        return crom_err(CROM_EDATA, "the scene has no bodies");
    for (int i = 0; i < s->nb; i++) {
        const crom_scene_body *b = &s->bodies[i];
        if (b->shape < 0 || b->shape >= CROM_SCENE_COUNT)
            return crom_err(CROM_EDATA, "body %d has unknown shape code %d (0 box, 1 sphere, 2 capsule, 3 ring)", i,
                            b->shape);
        int nsize = b->shape == CROM_SCENE_SPHERE ? 1 : b->shape == CROM_SCENE_CAPSULE ? 2 : 3;
        for (int k = 0; k < nsize; k++)
            if (!(b->size[k] > 0 || (b->shape == CROM_SCENE_RING && k == 2 && b->size[k] == 0)) ||
                !isfinite(b->size[k]))
                return crom_err(CROM_EDATA, "body %d (%s) has size %g m: a shape's sizes must be positive and finite",
                                i, shape_names[b->shape], b->size[k]);
        if (b->shape == CROM_SCENE_RING && !(b->size[0] < b->size[1]))
            return crom_err(CROM_EDATA, "body %d (ring) has a tube of radius %g m around a curve of radius %g m: the "
                            "tube must be thinner", i, b->size[0], b->size[1]);
        const double *Q = b->rot;
        double dev = 0;
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 3; c++)
                dev = fmax(dev, fabs(Q[r] * Q[c] + Q[3 + r] * Q[3 + c] + Q[6 + r] * Q[6 + c] - (r == c)));
        double det = Q[0] * (Q[4] * Q[8] - Q[5] * Q[7]) - Q[1] * (Q[3] * Q[8] - Q[5] * Q[6]) +
                     Q[2] * (Q[3] * Q[7] - Q[4] * Q[6]);
        if (!(dev <= 1e-9) || !(det > 0))
            return crom_err(CROM_EDATA, "body %d's rotation is not a rotation (|Q^T Q - I| = %.2g, det %.3g)", i, dev,
                            det);
        if (!finite3(b->centre))
            return crom_err(CROM_EDATA, "body %d has a non-finite centre", i);
        if (!(b->density > 0) || !isfinite(b->density))
            return crom_err(CROM_EDATA, "body %d has density %g kg/m^3: it must be positive and finite", i,
                            b->density);
    }
    for (int i = 0; i < s->nj; i++) {
        const crom_scene_joint *j = &s->joints[i];
        if (j->a < 0 || j->a >= s->nb || j->b < -1 || j->b >= s->nb)
            return crom_err(CROM_EDATA, "joint %d names body %d, but the scene has bodies 0..%d (-1: the world)", i,
                            j->a < 0 || j->a >= s->nb ? j->a : j->b, s->nb - 1);
        if (j->a == j->b)
            return crom_err(CROM_EDATA, "joint %d joins body %d to itself", i, j->a);
        if (!finite3(j->point))
            return crom_err(CROM_EDATA, "joint %d has a non-finite point", i);
        if (j->kind != CROM_SCENE_POINT && j->kind != CROM_SCENE_SLIDER)
            return crom_err(CROM_EDATA, "joint %d has unknown kind %d (0 point, 1 slider)", i, j->kind);
        double an = sqrt(j->axis[0] * j->axis[0] + j->axis[1] * j->axis[1] + j->axis[2] * j->axis[2]);
        if (j->kind == CROM_SCENE_SLIDER && (j->b < 0 || !(fabs(an - 1) <= 1e-6)))
            return crom_err(CROM_EDATA, "slider joint %d: it joins two bodies along a unit axis (b = %d, |axis| = %g)",
                            i, j->b, an);
        if (!(j->weight >= 0) || !isfinite(j->weight))
            return crom_err(CROM_EDATA, "joint %d has weight %g N/m: weights must be non-negative and finite", i,
                            j->weight);
    }
    for (int i = 0; i < s->np; i++) {
        const crom_scene_pair *p = &s->pairs[i];
        if (p->a < 0 || p->a >= s->nb || p->b < 0 || p->b >= s->nb)
            return crom_err(CROM_EDATA, "collision pair %d names body %d, but the scene has bodies 0..%d", i,
                            p->a < 0 || p->a >= s->nb ? p->a : p->b, s->nb - 1);
        if (p->a == p->b)
            return crom_err(CROM_EDATA, "collision pair %d pairs body %d with itself", i, p->a);
        if (!(p->weight >= 0) || !isfinite(p->weight))
            return crom_err(CROM_EDATA, "collision pair %d has weight %g N/m: weights must be non-negative and finite",
                            i, p->weight);
    }
    if (!(s->ortho_weight >= 0) || !isfinite(s->ortho_weight))
        return crom_err(CROM_EDATA, "orthogonality weight %g J: it must be non-negative and finite", s->ortho_weight);
    return 0;
}

/* grow an array of n elements of size sz by one */
static int append(void **arr, int *n, size_t sz, const void *item)
{
    void *p = crom_realloc(*arr, sz * (size_t)(*n + 1));
    if (!p)
        return CROM_EINTERNAL;
    memcpy((char *)p + sz * (size_t)*n, item, sz);
    *arr = p;
    (*n)++;
    return 0;
}

int crom_scene_add_body(crom_scene *s, const crom_scene_body *b)
{
    return append((void **)&s->bodies, &s->nb, sizeof *b, b);
}

int crom_scene_add_joint(crom_scene *s, const crom_scene_joint *j)
{
    return append((void **)&s->joints, &s->nj, sizeof *j, j);
}

int crom_scene_add_pair(crom_scene *s, const crom_scene_pair *p)
{
    return append((void **)&s->pairs, &s->np, sizeof *p, p);
}

void crom_scene_free(crom_scene *s)
{
    if (!s)
        return;
    free(s->bodies);
    free(s->joints);
    free(s->pairs);
    memset(s, 0, sizeof *s);
}

int crom_scene_copy(const crom_scene *src, crom_scene *dst)
{
    memset(dst, 0, sizeof *dst);
    dst->ortho_weight = src->ortho_weight;
    for (int i = 0; i < src->nb; i++)
        if (crom_scene_add_body(dst, &src->bodies[i]))
            goto oom;
    for (int i = 0; i < src->nj; i++)
        if (crom_scene_add_joint(dst, &src->joints[i]))
            goto oom;
    for (int i = 0; i < src->np; i++)
        if (crom_scene_add_pair(dst, &src->pairs[i]))
            goto oom;
    return 0;
oom:
    crom_scene_free(dst);
    return CROM_EINTERNAL;
}

/* ------------------------------------------------------------------ files */

int crom_scene_write(hid_t loc, const crom_scene *s)
{
    int nb = s->nb, nj = s->nj, np = s->np, rc = 0;
    size_t nmax = (size_t)(nb > nj ? (nb > np ? nb : np) : (nj > np ? nj : np));
    int *iv = crom_malloc(sizeof(int) * 2 * (nmax ? nmax : 1));
    double *dv = crom_malloc(sizeof(double) * 3 * (nmax ? nmax : 1));
    if (!iv || !dv) {
        free(iv), free(dv);
        return CROM_EINTERNAL;
    }
    hsize_t d1 = (hsize_t)nb, d3[2] = {(hsize_t)nb, 3};
    for (int i = 0; i < nb; i++)
        iv[i] = s->bodies[i].shape;
    rc = crom_h5_put_i32(loc, "scene/shape", 1, &d1, iv);
    for (int i = 0; i < nb; i++)
        memcpy(dv + 3 * i, s->bodies[i].size, 3 * sizeof(double));
    if (!rc)
        rc = crom_h5_put_f64(loc, "scene/size", 2, d3, dv);
    for (int i = 0; i < nb; i++)
        memcpy(dv + 3 * i, s->bodies[i].centre, 3 * sizeof(double));
    if (!rc)
        rc = crom_h5_put_f64(loc, "scene/centre", 2, d3, dv);
    for (int i = 0; i < nb; i++)
        dv[i] = s->bodies[i].density;
    if (!rc)
        rc = crom_h5_put_f64(loc, "scene/density", 1, &d1, dv);
    double *rot = crom_malloc(sizeof(double) * 9 * (size_t)(nb ? nb : 1));
    hsize_t d33[3] = {(hsize_t)nb, 3, 3};
    for (int i = 0; rot && i < nb; i++)
        memcpy(rot + 9 * i, s->bodies[i].rot, 9 * sizeof(double));
    if (!rc)
        rc = rot ? crom_h5_put_f64(loc, "scene/rotation", 3, d33, rot) : CROM_EINTERNAL;
    free(rot);
    if (!rc)
        rc = crom_h5_set_f64(loc, "scene", "ortho_weight", &s->ortho_weight, 1);
    if (!rc && nj) {
        hsize_t e1 = (hsize_t)nj, e2[2] = {(hsize_t)nj, 2}, e3[2] = {(hsize_t)nj, 3};
        for (int i = 0; i < nj; i++)
            iv[2 * i] = s->joints[i].a, iv[2 * i + 1] = s->joints[i].b;
        rc = crom_h5_put_i32(loc, "scene/joint_bodies", 2, e2, iv);
        for (int i = 0; i < nj; i++)
            memcpy(dv + 3 * i, s->joints[i].point, 3 * sizeof(double));
        if (!rc)
            rc = crom_h5_put_f64(loc, "scene/joint_points", 2, e3, dv);
        for (int i = 0; i < nj; i++)
            dv[i] = s->joints[i].weight;
        if (!rc)
            rc = crom_h5_put_f64(loc, "scene/joint_weights", 1, &e1, dv);
        for (int i = 0; i < nj; i++)
            iv[i] = s->joints[i].kind;
        if (!rc)
            rc = crom_h5_put_i32(loc, "scene/joint_kinds", 1, &e1, iv);
        for (int i = 0; i < nj; i++)
            memcpy(dv + 3 * i, s->joints[i].axis, 3 * sizeof(double));
        if (!rc)
            rc = crom_h5_put_f64(loc, "scene/joint_axes", 2, e3, dv);
    }
    if (!rc && np) {
        hsize_t e1 = (hsize_t)np, e2[2] = {(hsize_t)np, 2};
        for (int i = 0; i < np; i++)
            iv[2 * i] = s->pairs[i].a, iv[2 * i + 1] = s->pairs[i].b;
        rc = crom_h5_put_i32(loc, "scene/pair_bodies", 2, e2, iv);
        for (int i = 0; i < np; i++)
            dv[i] = s->pairs[i].weight;
        if (!rc)
            rc = crom_h5_put_f64(loc, "scene/pair_weights", 1, &e1, dv);
    }
    free(iv);
    free(dv);
    return rc;
}

/* Read dataset name of shape [n] or [n, cols] (cols 0: rank 1) into *out,
 * n taken from the first call (*n < 0) or checked against it. */
static int read_rows(hid_t loc, const char *name, int isint, int cols, int *n, void **out)
{
    hsize_t d[2] = {0, 0};
    int rank = cols ? 2 : 1;
    int rc = isint ? crom_h5_read_i32(loc, name, rank, d, (int **)out)
                   : crom_h5_read_f64(loc, name, rank, d, (double **)out);
    if (rc)
        return rc;
    if ((cols && d[1] != (hsize_t)cols) || d[0] > INT32_MAX / 4 || (*n >= 0 && d[0] != (hsize_t)*n))
        return crom_err(CROM_EDATA, "'%s' has shape [%llu%s%llu], expected [%d, %d]", name, (unsigned long long)d[0],
                        cols ? ", " : "", cols ? (unsigned long long)d[1] : 0ULL, *n, cols);
    *n = (int)d[0];
    return 0;
}

int crom_scene_read(hid_t loc, crom_scene *s)
{
    memset(s, 0, sizeof *s);
    int *shape = NULL, *jb = NULL, *pb = NULL, *jk = NULL, nb = -1, nj = -1, np = -1;
    double *size = NULL, *centre = NULL, *dens = NULL, *jp = NULL, *jw = NULL, *pw = NULL, *rot = NULL, *ja = NULL;
    int rc = read_rows(loc, "scene/shape", 1, 0, &nb, (void **)&shape);
    if (!rc)
        rc = read_rows(loc, "scene/size", 0, 3, &nb, (void **)&size);
    if (!rc)
        rc = read_rows(loc, "scene/centre", 0, 3, &nb, (void **)&centre);
    if (!rc)
        rc = read_rows(loc, "scene/density", 0, 0, &nb, (void **)&dens);
    if (!rc && crom_h5_has(loc, "scene/rotation")) {
        hsize_t d[3];
        rc = crom_h5_read_f64(loc, "scene/rotation", 3, d, &rot);
        if (!rc && (d[0] != (hsize_t)nb || d[1] != 3 || d[2] != 3))
            rc = crom_err(CROM_EDATA, "'scene/rotation' has shape [%llu, %llu, %llu], expected [%d, 3, 3]",
                          (unsigned long long)d[0], (unsigned long long)d[1], (unsigned long long)d[2], nb);
    }
    if (!rc)
        rc = crom_h5_has_attr(loc, "scene", "ortho_weight")
                 ? crom_h5_get_f64(loc, "scene", "ortho_weight", &s->ortho_weight, 1)
                 : crom_err(CROM_EDATA, "'scene' has no ortho_weight attribute");
    if (!rc && crom_h5_has(loc, "scene/joint_bodies")) {
        rc = read_rows(loc, "scene/joint_bodies", 1, 2, &nj, (void **)&jb);
        if (!rc)
            rc = read_rows(loc, "scene/joint_points", 0, 3, &nj, (void **)&jp);
        if (!rc)
            rc = read_rows(loc, "scene/joint_weights", 0, 0, &nj, (void **)&jw);
        if (!rc && crom_h5_has(loc, "scene/joint_kinds")) /* absent: every joint a point joint */
            rc = read_rows(loc, "scene/joint_kinds", 1, 0, &nj, (void **)&jk);
        if (!rc && crom_h5_has(loc, "scene/joint_axes"))
            rc = read_rows(loc, "scene/joint_axes", 0, 3, &nj, (void **)&ja);
    }
    if (!rc && crom_h5_has(loc, "scene/pair_bodies")) {
        rc = read_rows(loc, "scene/pair_bodies", 1, 2, &np, (void **)&pb);
        if (!rc)
            rc = read_rows(loc, "scene/pair_weights", 0, 0, &np, (void **)&pw);
    }
    for (int i = 0; !rc && i < nb; i++) {
        crom_scene_body b = crom_scene_body_make(shape[i], size + 3 * i, centre + 3 * i, dens[i]);
        if (rot)
            memcpy(b.rot, rot + 9 * i, sizeof b.rot);
        rc = crom_scene_add_body(s, &b);
    }
    for (int i = 0; !rc && i < nj; i++) {
        crom_scene_joint j = {jb[2 * i], jb[2 * i + 1], {jp[3 * i], jp[3 * i + 1], jp[3 * i + 2]}, jw[i],
                              jk ? jk[i] : CROM_SCENE_POINT, {0, 0, 0}};
        if (ja)
            memcpy(j.axis, ja + 3 * i, sizeof j.axis);
        rc = crom_scene_add_joint(s, &j);
    }
    for (int i = 0; !rc && i < np; i++) {
        crom_scene_pair p = {pb[2 * i], pb[2 * i + 1], pw[i]};
        rc = crom_scene_add_pair(s, &p);
    }
    free(shape), free(jb), free(pb), free(jk);
    free(size), free(centre), free(dens), free(jp), free(jw), free(pw), free(rot), free(ja);
    if (!rc)
        rc = crom_scene_validate(s);
    if (rc)
        crom_scene_free(s);
    return rc;
}
