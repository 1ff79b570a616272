/* mesh.c — tetrahedral meshes: geometry, orientation, quality, boundary,
 * named regions, and the crom/mesh layout in HDF5. */
#include <ctype.h>
#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "io/io.h"
#include "mesh/mesh.h"

/* ---------------------------------------------------------------- geometry */

double crom_mesh_tet_volume(const double *a, const double *b, const double *c, const double *d)
{
    double u[3], v[3], w[3];
    for (int i = 0; i < 3; i++) {
        u[i] = b[i] - a[i];
        v[i] = c[i] - a[i];
        w[i] = d[i] - a[i];
    }
    return (u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0]) +
            u[2] * (v[0] * w[1] - v[1] * w[0])) / 6.0;
}

double crom_mesh_tet_quality(const double *a, const double *b, const double *c, const double *d)
{
    const double *p[4] = {a, b, c, d};
    double l2 = 0;
    for (int i = 0; i < 4; i++)
        for (int j = i + 1; j < 4; j++)
            for (int k = 0; k < 3; k++)
                l2 += (p[i][k] - p[j][k]) * (p[i][k] - p[j][k]);
    double V = crom_mesh_tet_volume(a, b, c, d);
    if (l2 <= 0)
        return 0;
    double q = 12.0 * pow(3.0 * fabs(V), 2.0 / 3.0) / l2;
    return V < 0 ? -q : q;
}

#define VX(m, i) ((m)->X + 3 * (size_t)(i))

/* Area of triangle (a, b, c). */
static double tri_area(const double *a, const double *b, const double *c)
{
    double u[3], v[3];
    for (int k = 0; k < 3; k++)
        u[k] = b[k] - a[k], v[k] = c[k] - a[k];
    return 0.5 * hypot(hypot(u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2]), u[0] * v[1] - u[1] * v[0]);
}

double crom_mesh_volume(const crom_mesh *m)
{
    double V = 0;
    for (int t = 0; t < m->ntri; t++) {
        const int *e = m->tris + 3 * (size_t)t;
        V += m->thickness * tri_area(VX(m, e[0]), VX(m, e[1]), VX(m, e[2]));
    }
    for (int t = 0; t < m->nt; t++) {
        const int *e = m->tets + 4 * (size_t)t;
        V += crom_mesh_tet_volume(VX(m, e[0]), VX(m, e[1]), VX(m, e[2]), VX(m, e[3]));
    }
    return V;
}

void crom_mesh_quality(const crom_mesh *m, double *worst, double *mean, int *worst_tet)
{
    double w = INFINITY, s = 0;
    int wt = -1;
    for (int t = 0; t < m->nt; t++) {
        const int *e = m->tets + 4 * (size_t)t;
        double q = crom_mesh_tet_quality(VX(m, e[0]), VX(m, e[1]), VX(m, e[2]), VX(m, e[3]));
        s += q;
        if (q < w) {
            w = q;
            wt = t;
        }
    }
    if (worst)
        *worst = m->nt ? w : 0;
    if (mean)
        *mean = m->nt ? s / m->nt : 0;
    if (worst_tet)
        *worst_tet = wt;
}

/* The bounding box of nv points. */
static void points_bbox(const double *X, int nv, double lo[3], double hi[3])
{
    for (int k = 0; k < 3; k++) {
        lo[k] = INFINITY;
        hi[k] = -INFINITY;
    }
    for (int i = 0; i < nv; i++)
        for (int k = 0; k < 3; k++) {
            double x = X[3 * (size_t)i + k];
            if (x < lo[k])
                lo[k] = x;
            if (x > hi[k])
                hi[k] = x;
        }
}

void crom_mesh_bbox(const crom_mesh *m, double lo[3], double hi[3])
{
    points_bbox(m->X, m->nv, lo, hi);
}

double crom_mesh_points_diagonal(const double *X, int nv)
{
    double lo[3], hi[3], d2 = 0;
    if (nv < 1)
        return 0;
    points_bbox(X, nv, lo, hi);
    for (int k = 0; k < 3; k++)
        d2 += (hi[k] - lo[k]) * (hi[k] - lo[k]);
    return sqrt(d2);
}

double crom_mesh_vertex_volumes(const crom_mesh *m, double *w)
{
    double total = 0;
    memset(w, 0, sizeof(double) * (size_t)m->nv);
    for (int t = 0; t < m->ntri; t++) { /* a shell: thickness x area / 3 per corner */
        const int *v = m->tris + 3 * (size_t)t;
        double V = m->thickness * tri_area(VX(m, v[0]), VX(m, v[1]), VX(m, v[2]));
        total += V;
        for (int k = 0; k < 3; k++)
            w[v[k]] += V / 3;
    }
    for (int t = 0; t < m->nt; t++) {
        const int *v = m->tets + 4 * (size_t)t;
        double V = crom_mesh_tet_volume(m->X + 3 * (size_t)v[0], m->X + 3 * (size_t)v[1],
                                        m->X + 3 * (size_t)v[2], m->X + 3 * (size_t)v[3]);
        total += V;
        for (int k = 0; k < 4; k++)
            w[v[k]] += V / 4;
    }
    return total;
}

static double degenerate_tol(const crom_mesh *m)
{
    double lo[3], hi[3];
    crom_mesh_bbox(m, lo, hi);
    double L = fmax(hi[0] - lo[0], fmax(hi[1] - lo[1], hi[2] - lo[2]));
    return 1e-14 * L * L * L;
}

int crom_mesh_orient(crom_mesh *m, int *nflipped)
{
    double tol = degenerate_tol(m);
    int nf = 0;
    for (int t = 0; t < m->nt; t++) {
        int *e = m->tets + 4 * (size_t)t;
        double V = crom_mesh_tet_volume(VX(m, e[0]), VX(m, e[1]), VX(m, e[2]), VX(m, e[3]));
        if (fabs(V) <= tol)
            return crom_err(CROM_EDATA, "tet %d is degenerate (volume %.3g m^3)", t, V);
        if (V < 0) {
            int tmp = e[2];
            e[2] = e[3];
            e[3] = tmp;
            nf++;
        }
    }
    if (nflipped)
        *nflipped = nf;
    return 0;
}

int crom_mesh_compact(crom_mesh *m)
{
    int *map = crom_malloc(sizeof(int) * (size_t)(m->nv ? m->nv : 1));
    if (!map)
        return CROM_EINTERNAL;
    for (int i = 0; i < m->nv; i++)
        map[i] = -1;
    for (size_t k = 0; k < 4 * (size_t)m->nt; k++)
        map[m->tets[k]] = 0;
    for (size_t k = 0; k < 3 * (size_t)m->ntri; k++)
        map[m->tris[k]] = 0;
    int n = 0;
    for (int i = 0; i < m->nv; i++)
        if (map[i] == 0) {
            map[i] = n;
            memmove(m->X + 3 * (size_t)n, m->X + 3 * (size_t)i, 3 * sizeof(double));
            n++;
        }
    for (size_t k = 0; k < 4 * (size_t)m->nt; k++)
        m->tets[k] = map[m->tets[k]];
    for (size_t k = 0; k < 3 * (size_t)m->ntri; k++)
        m->tris[k] = map[m->tris[k]];
    for (int r = 0; r < m->nregions; r++) {
        crom_mesh_region *g = &m->regions[r];
        int k = 0;
        for (int j = 0; j < g->n; j++)
            if (map[g->idx[j]] >= 0)
                g->idx[k++] = map[g->idx[j]];
        g->n = k; /* order preserved: map is monotone */
    }
    m->nv = n;
    free(map);
    return 0;
}

static int validate_surface(const crom_mesh *m)
{
    if (m->nt)
        return crom_err(CROM_EDATA, "mesh has both tets (%d) and triangles (%d)", m->nt, m->ntri);
    if (m->nv < 3)
        return crom_err(CROM_EDATA, "surface mesh has %d vertices; a shell needs at least 3", m->nv);
    if (!isfinite(m->thickness) || !(m->thickness > 0))
        return crom_err(CROM_EDATA, "shell thickness %g m: it must be positive and finite", m->thickness);
    for (int t = 0; t < m->ntri; t++) {
        const int *e = m->tris + 3 * (size_t)t;
        for (int k = 0; k < 3; k++) {
            if (e[k] < 0 || e[k] >= m->nv)
                return crom_err(CROM_EDATA, "triangle %d refers to vertex %d, but there are %d vertices", t, e[k],
                                m->nv);
            if (e[k] == e[(k + 1) % 3])
                return crom_err(CROM_EDATA, "triangle %d repeats vertex %d", t, e[k]);
        }
    }
    return 0;
}

/* every region index in [0, nv) */
static int validate_regions(const crom_mesh *m)
{
    for (int r = 0; r < m->nregions; r++)
        for (int j = 0; j < m->regions[r].n; j++)
            if (m->regions[r].idx[j] < 0 || m->regions[r].idx[j] >= m->nv)
                return crom_err(CROM_EDATA, "region '%s' refers to vertex %d, but there are %d vertices",
                                m->regions[r].name, m->regions[r].idx[j], m->nv);
    return 0;
}

static int validate_scene(const crom_mesh *m)
{
    if (m->nt || m->ntri)
        return crom_err(CROM_EDATA, "a rigid-body scene has tets (%d) or triangles (%d)", m->nt, m->ntri);
    int rc = crom_scene_validate(m->scene);
    if (!rc && m->nv != 4 * m->scene->nb)
        rc = crom_err(CROM_EDATA, "a scene of %d bodies has %d vertices; it needs 4 frame vertices per body",
                      m->scene->nb, m->nv);
    for (size_t i = 0; !rc && i < 3 * (size_t)m->nv; i++)
        if (!isfinite(m->X[i]))
            rc = crom_err(CROM_EDATA, "vertex %zu has a non-finite coordinate", i / 3);
    return rc ? rc : validate_regions(m);
}

int crom_mesh_validate(const crom_mesh *m)
{
    if (m->scene)
        return validate_scene(m);
    if (m->ntri > 0 || m->tris) {
        for (size_t i = 0; i < 3 * (size_t)m->nv; i++)
            if (!isfinite(m->X[i]))
                return crom_err(CROM_EDATA, "vertex %zu has a non-finite coordinate", i / 3);
        int rc = validate_surface(m);
        return rc ? rc : validate_regions(m);
    }
    if (m->nv < 4 || m->nt < 1)
        return crom_err(CROM_EDATA, "mesh has %d vertices and %d tets; a solid needs at least 4 and 1",
                        m->nv, m->nt);
    for (size_t i = 0; i < 3 * (size_t)m->nv; i++)
        if (!isfinite(m->X[i]))
            return crom_err(CROM_EDATA, "vertex %zu has a non-finite coordinate", i / 3);
    for (size_t k = 0; k < 4 * (size_t)m->nt; k++)
        if (m->tets[k] < 0 || m->tets[k] >= m->nv)
            return crom_err(CROM_EDATA, "tet %zu refers to vertex %d, but there are %d vertices",
                            k / 4, m->tets[k], m->nv);
    double tol = degenerate_tol(m);
    for (int t = 0; t < m->nt; t++) {
        const int *e = m->tets + 4 * (size_t)t;
        double V = crom_mesh_tet_volume(VX(m, e[0]), VX(m, e[1]), VX(m, e[2]), VX(m, e[3]));
        if (!(V > tol))
            return crom_err(CROM_EDATA, "tet %d has non-positive volume %.3g m^3 (tets must be positively oriented)",
                            t, V);
    }
    return validate_regions(m);
}

/* ---------------------------------------------------------------- boundary */

typedef struct {
    int v[3]; /* sorted */
    int tet, local;
} face_key;

static int face_cmp(const void *pa, const void *pb)
{
    const face_key *a = pa, *b = pb;
    for (int i = 0; i < 3; i++)
        if (a->v[i] != b->v[i])
            return a->v[i] < b->v[i] ? -1 : 1;
    return 0;
}

/* outward faces of a positively oriented tet */
static const int tet_faces[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};

int crom_mesh_boundary(const crom_mesh *m, int *ntri, int **tris, int **tri_tet)
{
    size_t nf = 4 * (size_t)m->nt;
    face_key *f = crom_malloc(sizeof(face_key) * (nf ? nf : 1));
    if (!f)
        return CROM_EINTERNAL;
    for (int t = 0; t < m->nt; t++)
        for (int l = 0; l < 4; l++) {
            face_key *k = &f[4 * (size_t)t + l];
            int a = m->tets[4 * (size_t)t + tet_faces[l][0]], b = m->tets[4 * (size_t)t + tet_faces[l][1]],
                c = m->tets[4 * (size_t)t + tet_faces[l][2]], s;
            if (a > b) { s = a; a = b; b = s; }
            if (b > c) { s = b; b = c; c = s; }
            if (a > b) { s = a; a = b; b = s; }
            k->v[0] = a;
            k->v[1] = b;
            k->v[2] = c;
            k->tet = t;
            k->local = l;
        }
    qsort(f, nf, sizeof *f, face_cmp);
    int n = 0;
    for (size_t i = 0; i < nf;) {
        size_t j = i + 1;
        while (j < nf && !face_cmp(&f[i], &f[j]))
            j++;
        if (j - i == 1)
            f[n++] = f[i];
        i = j;
    }
    int *T = crom_malloc(sizeof(int) * 3 * (size_t)(n ? n : 1));
    int *TT = tri_tet ? crom_malloc(sizeof(int) * (size_t)(n ? n : 1)) : NULL;
    if (!T || (tri_tet && !TT)) {
        free(f);
        free(T);
        free(TT);
        return CROM_EINTERNAL;
    }
    for (int i = 0; i < n; i++) {
        const int *e = m->tets + 4 * (size_t)f[i].tet;
        for (int c = 0; c < 3; c++)
            T[3 * i + c] = e[tet_faces[f[i].local][c]];
        if (TT)
            TT[i] = f[i].tet;
    }
    free(f);
    *ntri = n;
    *tris = T;
    if (tri_tet)
        *tri_tet = TT;
    return 0;
}

/* ----------------------------------------------------------- field points */

typedef struct {
    double x[3];
    int v;
} vpos;

static int vpos_cmp(const void *a, const void *b)
{
    const vpos *p = a, *q = b;
    for (int i = 0; i < 3; i++)
        if (p->x[i] != q->x[i])
            return p->x[i] < q->x[i] ? -1 : 1;
    return (p->v > q->v) - (p->v < q->v);
}

double *crom_mesh_field_points(const crom_mesh *m, double s, int *nshifted)
{
    int nv = m->nv, nt = m->nt;
    double *P = crom_malloc(sizeof(double) * 3 * (size_t)nv), *ctr = crom_calloc(3 * (size_t)nv, sizeof(double));
    int *cnt = crom_calloc((size_t)nv, sizeof(int));
    vpos *k = crom_malloc(sizeof(vpos) * (size_t)nv);
    unsigned char *dup = crom_calloc((size_t)nv, 1);
    if (!P || !ctr || !cnt || !k || !dup) {
        free(P);
        P = NULL;
        goto out;
    }
    memcpy(P, m->X, sizeof(double) * 3 * (size_t)nv);
    for (int v = 0; v < nv; v++) {
        memcpy(k[v].x, m->X + 3 * (size_t)v, 3 * sizeof(double));
        k[v].v = v;
    }
    qsort(k, (size_t)nv, sizeof *k, vpos_cmp);
    for (int i = 1; i < nv; i++)
        if (!memcmp(k[i].x, k[i - 1].x, 3 * sizeof(double)))
            dup[k[i].v] = dup[k[i - 1].v] = 1;
    /* centroid of each duplicated vertex's own tets */
    for (int t = 0; t < nt; t++) {
        const int *e = m->tets + 4 * (size_t)t;
        double c[3] = {0, 0, 0};
        for (int a = 0; a < 4; a++)
            for (int i = 0; i < 3; i++)
                c[i] += 0.25 * m->X[3 * (size_t)e[a] + i];
        for (int a = 0; a < 4; a++)
            if (dup[e[a]]) {
                for (int i = 0; i < 3; i++)
                    ctr[3 * (size_t)e[a] + i] += c[i];
                cnt[e[a]]++;
            }
    }
    int n = 0;
    for (int v = 0; v < nv; v++)
        if (dup[v] && cnt[v]) {
            for (int i = 0; i < 3; i++)
                P[3 * (size_t)v + i] += s * (ctr[3 * (size_t)v + i] / cnt[v] - P[3 * (size_t)v + i]);
            n++;
        }
    if (nshifted)
        *nshifted = n;
out:
    free(ctr);
    free(cnt);
    free(k);
    free(dup);
    return P;
}

/* ------------------------------------------------------------ copy & free */

static void free_regions(crom_mesh_region *r, int n)
{
    for (int i = 0; i < n; i++) {
        free(r[i].name);
        free(r[i].source);
        free(r[i].idx);
    }
    free(r);
}

void crom_mesh_free(crom_mesh *m)
{
    free(m->X);
    free(m->tets);
    free(m->tris);
    free_regions(m->regions, m->nregions);
    crom_scene_free(m->scene);
    free(m->scene);
    memset(m, 0, sizeof *m);
}

int crom_mesh_copy(const crom_mesh *s, crom_mesh *d)
{
    memset(d, 0, sizeof *d);
    d->nv = s->nv;
    d->nt = s->nt;
    d->ntri = s->ntri;
    d->thickness = s->thickness;
    d->plane = s->plane;
    d->X = crom_malloc(sizeof(double) * 3 * (size_t)s->nv);
    d->tets = crom_malloc(sizeof(int) * 4 * (size_t)(s->nt ? s->nt : 1));
    d->tris = s->ntri ? crom_malloc(sizeof(int) * 3 * (size_t)s->ntri) : NULL;
    if (!d->X || !d->tets || (s->ntri && !d->tris)) {
        crom_mesh_free(d);
        return CROM_EINTERNAL;
    }
    memcpy(d->X, s->X, sizeof(double) * 3 * (size_t)s->nv);
    if (s->nt)
        memcpy(d->tets, s->tets, sizeof(int) * 4 * (size_t)s->nt);
    if (s->ntri)
        memcpy(d->tris, s->tris, sizeof(int) * 3 * (size_t)s->ntri);
    if (s->scene && (!(d->scene = crom_malloc(sizeof *d->scene)) || crom_scene_copy(s->scene, d->scene))) {
        free(d->scene);
        d->scene = NULL;
        crom_mesh_free(d);
        return CROM_EINTERNAL;
    }
    for (int r = 0; r < s->nregions; r++) {
        int rc = crom_mesh_add_region(d, s->regions[r].name, s->regions[r].source,
                                      s->regions[r].idx, s->regions[r].n);
        if (rc) {
            crom_mesh_free(d);
            return rc;
        }
    }
    return 0;
}

/* ---------------------------------------------------------------- regions */

const crom_mesh_region *crom_mesh_find_region(const crom_mesh *m, const char *name)
{
    for (int r = 0; r < m->nregions; r++)
        if (!strcmp(m->regions[r].name, name))
            return &m->regions[r];
    return NULL;
}

static int int_cmp(const void *a, const void *b)
{
    int x = *(const int *)a, y = *(const int *)b;
    return (x > y) - (x < y);
}

static int valid_name(const char *s)
{
    if (!*s || strlen(s) > 64)
        return 0;
    for (; *s; s++)
        if (!(isalnum((unsigned char)*s) || *s == '_' || *s == '-' || *s == '.'))
            return 0;
    return 1;
}

int crom_mesh_add_region(crom_mesh *m, const char *name, const char *source,
                         const int *idx, int n)
{
    if (!valid_name(name))
        return crom_err(CROM_EUSAGE, "region name '%s' is not allowed (use letters, digits, '_', '-', '.')",
                        name);
    int *v = crom_malloc(sizeof(int) * (size_t)(n ? n : 1));
    if (!v)
        return CROM_EINTERNAL;
    memcpy(v, idx, sizeof(int) * (size_t)n);
    qsort(v, (size_t)n, sizeof(int), int_cmp);
    int k = 0;
    for (int i = 0; i < n; i++)
        if (i == 0 || v[i] != v[i - 1])
            v[k++] = v[i];
    crom_mesh_region *slot = (crom_mesh_region *)crom_mesh_find_region(m, name);
    if (!slot) {
        crom_mesh_region *nr = crom_realloc(m->regions, sizeof(crom_mesh_region) * (size_t)(m->nregions + 1));
        if (!nr) {
            free(v);
            return CROM_EINTERNAL;
        }
        m->regions = nr;
        slot = &m->regions[m->nregions++];
        memset(slot, 0, sizeof *slot);
        slot->name = crom_strdup(name);
    } else {
        free(slot->idx);
        free(slot->source);
    }
    slot->source = crom_strdup(source ? source : "");
    slot->idx = v;
    slot->n = k;
    return 0;
}

static int select_pred(const crom_mesh *m, const char *text, int **idx, int *n)
{
    crom_pred p;
    int rc = crom_pred_parse(text, &p);
    if (rc)
        return rc;
    int *v = crom_malloc(sizeof(int) * (size_t)(m->nv ? m->nv : 1)), k = 0;
    if (!v)
        return CROM_EINTERNAL;
    for (int i = 0; i < m->nv; i++)
        if (crom_pred_eval(&p, VX(m, i)))
            v[k++] = i;
    *idx = v;
    *n = k;
    return 0;
}

int crom_mesh_region_spec(crom_mesh *m, const char *spec)
{
    const char *eq = strchr(spec, '=');
    if (!eq || eq == spec)
        return crom_err(CROM_EUSAGE, "--region '%s': expected NAME=PREDICATE", spec);
    char name[80];
    size_t len = (size_t)(eq - spec);
    if (len >= sizeof name)
        return crom_err(CROM_EUSAGE, "--region '%s': name too long", spec);
    memcpy(name, spec, len);
    name[len] = 0;
    /* PRED is a predicate, or the name of a region the mesh already has
     * (a gmsh physical group of an imported file) */
    int *idx, n, rc = crom_mesh_select(m, eq + 1, &idx, &n);
    if (rc)
        return crom_err_ctx("--region %s", name);
    rc = crom_mesh_add_region(m, name, eq + 1, idx, n);
    free(idx);
    return rc;
}

int crom_mesh_select(const crom_mesh *m, const char *ref, int **idx, int *n)
{
    if (ref[0] == '#') { /* one vertex by its index */
        char *end;
        errno = 0;
        long v = isdigit((unsigned char)ref[1]) ? strtol(ref + 1, &end, 10) : -1;
        if (v < 0 || errno || *end)
            return crom_err(CROM_EUSAGE, "'%s': a vertex is #N, N a non-negative decimal index", ref);
        if (v >= m->nv)
            return crom_err(CROM_EUSAGE, "vertex %s: the mesh has %d vertices (#0 to #%d)", ref, m->nv, m->nv - 1);
        if (!(*idx = crom_malloc(sizeof(int))))
            return CROM_EINTERNAL;
        **idx = (int)v;
        *n = 1;
        return 0;
    }
    const crom_mesh_region *r = crom_mesh_find_region(m, ref);
    if (r) {
        if (r->n == 0)
            return crom_err(CROM_EUSAGE, "region '%s' is empty", ref);
        *idx = crom_malloc(sizeof(int) * (size_t)r->n);
        if (!*idx)
            return CROM_EINTERNAL;
        memcpy(*idx, r->idx, sizeof(int) * (size_t)r->n);
        *n = r->n;
        return 0;
    }
    if (!crom_pred_is(ref) && valid_name(ref)) {
        char known[512] = "";
        size_t off = 0;
        for (int i = 0; i < m->nregions && off < sizeof known - 80; i++)
            off += (size_t)snprintf(known + off, sizeof known - off, "%s%s", i ? ", " : "",
                                    m->regions[i].name);
        return crom_err(CROM_EUSAGE, "unknown region '%s' (the mesh has: %s)", ref,
                        m->nregions ? known : "no named regions");
    }
    int rc = select_pred(m, ref, idx, n);
    if (rc)
        return rc;
    if (*n == 0) {
        free(*idx);
        *idx = NULL;
        return crom_err(CROM_EUSAGE, "predicate '%s' selects no vertex", ref);
    }
    return 0;
}

/* ------------------------------------------------------------------ files */

int crom_mesh_write(hid_t loc, const crom_mesh *m)
{
    hsize_t dv[2] = {(hsize_t)m->nv, 3}, dt[2] = {(hsize_t)m->nt, 4}, dtri[2] = {(hsize_t)m->ntri, 3};
    int rc = crom_h5_put_f64(loc, "vertices", 2, dv, m->X);
    if (!rc && m->scene) {
        rc = crom_scene_write(loc, m->scene);
    } else if (!rc && crom_mesh_is_surface(m)) {
        rc = crom_h5_put_i32(loc, "triangles", 2, dtri, m->tris);
        if (!rc)
            rc = crom_h5_set_f64(loc, "triangles", "thickness", &m->thickness, 1);
        if (!rc && m->plane)
            rc = crom_h5_set_i64(loc, "triangles", "plane_strain", 1);
    } else if (!rc) {
        rc = crom_h5_put_i32(loc, "tets", 2, dt, m->tets);
    }
    if (rc)
        return rc;
    hid_t g = crom_h5_group(loc, "regions");
    if (g < 0)
        return CROM_EINTERNAL;
    for (int r = 0; r < m->nregions && !rc; r++) {
        hsize_t d = (hsize_t)m->regions[r].n;
        rc = crom_h5_put_i32(g, m->regions[r].name, 1, &d, m->regions[r].idx);
        if (!rc)
            rc = crom_h5_set_str(g, m->regions[r].name, "source", m->regions[r].source);
    }
    H5Gclose(g);
    return rc;
}

/* The programs that take a shell, named where a tet-only path refuses one. */
#define SHELL_PROGRAMS                                                                                     \
    "crom-fullsim, crom-modes, crom-sample, crom-encode, crom-cubature, crom-reducedstep --model, crom-diff, " \
    "crom-export, crom-info"

static int read_mesh(hid_t loc, crom_mesh *m);

/* The programs that take a rigid-body scene. */
#define SCENE_PROGRAMS                                                                                    \
    "crom-fullsim, crom-export, crom-diff, crom-info, crom-fitfield --objective energy, crom-reducedstep --model"

int crom_mesh_read(hid_t loc, crom_mesh *m)
{
    return crom_mesh_read_flags(loc, 0, m);
}

int crom_mesh_read_any(hid_t loc, crom_mesh *m)
{
    return crom_mesh_read_flags(loc, CROM_MESH_SURFACES, m);
}

/* Refuse what flags does not take (mesh freed then). */
static int check_kind(const char *name, int flags, crom_mesh *m)
{
    int rc = 0;
    if (m->scene && !(flags & CROM_MESH_SCENES))
        rc = crom_err(CROM_EUSAGE, "%s is a rigid-body scene (%d bodies); this program does not take scenes yet "
                      "(scenes: " SCENE_PROGRAMS ")", name ? name : "the mesh", m->scene->nb);
    else if (crom_mesh_is_surface(m) && !(flags & CROM_MESH_SURFACES))
        rc = crom_err(CROM_EUSAGE, "%s is a shell surface (%d triangles); this program takes tet meshes (shells: "
                      SHELL_PROGRAMS ")", name ? name : "the mesh", m->ntri);
    if (rc)
        crom_mesh_free(m);
    return rc;
}

int crom_mesh_read_flags(hid_t loc, int flags, crom_mesh *m)
{
    int rc = read_mesh(loc, m);
    return rc ? rc : check_kind(NULL, flags, m);
}

static int read_mesh(hid_t loc, crom_mesh *m)
{
    memset(m, 0, sizeof *m);
    hsize_t dv[2], dt[2];
    int rc = crom_h5_read_f64(loc, "vertices", 2, dv, &m->X);
    if (!rc && dv[1] != 3)
        rc = crom_err(CROM_EDATA, "'vertices' has %llu columns, expected 3", (unsigned long long)dv[1]);
    int surface = !rc && !crom_h5_has(loc, "tets") && crom_h5_has(loc, "triangles");
    int scene = !rc && !crom_h5_has(loc, "tets") && !surface && crom_h5_has(loc, "scene");
    if (!rc && scene) { /* a rigid-body scene: its bodies, joints and pairs; no elements */
        m->scene = crom_calloc(1, sizeof *m->scene);
        rc = m->scene ? crom_scene_read(loc, m->scene) : CROM_EINTERNAL;
        if (!rc && dv[0] > INT32_MAX / 3)
            rc = crom_err(CROM_EDATA, "mesh too large");
        if (!rc)
            m->tets = crom_malloc(sizeof(int) * 4);
    } else if (!rc && surface) { /* a shell: triangles and their thickness */
        rc = crom_h5_read_i32(loc, "triangles", 2, dt, &m->tris);
        if (!rc && dt[1] != 3)
            rc = crom_err(CROM_EDATA, "'triangles' has %llu columns, expected 3", (unsigned long long)dt[1]);
        if (!rc && dt[0] == 0)
            rc = crom_err(CROM_EDATA, "'triangles' is empty");
        if (!rc && !crom_h5_has_attr(loc, "triangles", "thickness"))
            rc = crom_err(CROM_EDATA, "'triangles' has no thickness attribute (a shell's thickness, m)");
        if (!rc)
            rc = crom_h5_get_f64(loc, "triangles", "thickness", &m->thickness, 1);
        if (!rc && crom_h5_has_attr(loc, "triangles", "plane_strain")) {
            long long pl = 0;
            if ((rc = crom_h5_get_i64(loc, "triangles", "plane_strain", &pl)) || (pl != 0 && pl != 1))
                rc = crom_err(CROM_EDATA, "'triangles': plane_strain must be 0 or 1");
            m->plane = (int)pl;
        }
        if (!rc && (dv[0] > INT32_MAX / 3 || dt[0] > INT32_MAX / 3))
            rc = crom_err(CROM_EDATA, "mesh too large");
        if (!rc)
            m->tets = crom_malloc(sizeof(int) * 4);
    } else if (!rc) {
        rc = crom_h5_read_i32(loc, "tets", 2, dt, &m->tets);
        if (!rc && dt[1] != 4)
            rc = crom_err(CROM_EDATA, "'tets' has %llu columns, expected 4", (unsigned long long)dt[1]);
        if (!rc && (dv[0] > INT32_MAX / 3 || dt[0] > INT32_MAX / 4))
            rc = crom_err(CROM_EDATA, "mesh too large");
    }
    if (rc) {
        crom_mesh_free(m);
        return rc;
    }
    m->nv = (int)dv[0];
    if (scene)
        ;
    else if (surface)
        m->ntri = (int)dt[0];
    else
        m->nt = (int)dt[0];
    if (crom_h5_has(loc, "regions")) {
        char **names = crom_h5_list(loc, "regions");
        if (!names)
            rc = CROM_EDATA;
        for (int i = 0; names && names[i] && !rc; i++) {
            char path[128];
            snprintf(path, sizeof path, "regions/%s", names[i]);
            hsize_t d;
            int *idx;
            rc = crom_h5_read_i32(loc, path, 1, &d, &idx);
            if (rc)
                break;
            char *src = NULL;
            if (crom_h5_has_attr(loc, path, "source"))
                crom_h5_get_str(loc, path, "source", &src);
            rc = crom_mesh_add_region(m, names[i], src, idx, (int)d);
            free(src);
            free(idx);
        }
        crom_h5_list_free(names);
    }
    if (!rc)
        rc = crom_mesh_validate(m);
    if (rc)
        crom_mesh_free(m);
    return rc;
}

int crom_mesh_load(const char *path, int flags, crom_mesh *m, char **history)
{
    int carriers = flags & CROM_MESH_CARRIERS;
    crom_in in;
    int rc = crom_in_open(&in, path);
    if (rc)
        return rc;
    const char *group = "/";
    if (!carriers || !strcmp(in.schema, "crom/mesh"))
        rc = crom_in_expect(&in, CROM_MESH_SCHEMA, CROM_MESH_VERSION);
    else if (!strcmp(in.schema, "crom/trajectory") || !strcmp(in.schema, "crom/cubature"))
        rc = crom_in_expect(&in, in.schema, 1), group = "mesh";
    else
        rc = crom_err(CROM_EDATA, "%s is %s v%d, expected a crom/mesh (or a file carrying one)", in.name,
                      in.schema, in.version);
    if (!rc) {
        hid_t g = H5Gopen2(in.h5, group, H5P_DEFAULT);
        rc = g < 0 ? crom_err(CROM_EDATA, "%s has no mesh", in.name) : read_mesh(g, m);
        if (g >= 0)
            H5Gclose(g);
        if (rc && g >= 0 && strcmp(group, "/"))
            crom_err_ctx("/%s", group);
        if (rc && g >= 0)
            crom_err_ctx("%s", in.name);
    }
    if (!rc)
        rc = check_kind(in.name, flags, m);
    if (!rc && history) {
        *history = in.history;
        in.history = NULL;
    }
    crom_in_close(&in);
    return rc;
}
