/* remesh.c — cut, punch, swap and refine tetrahedral meshes (see remesh.h). */
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>


#include "base/array.h"
#include "base/err.h"
#include "mesh/remesh.h"

#define VX(m, i) ((m)->X + 3 * (size_t)(i))

static void warnf(crom_remesh_warn_fn warn, void *ctx, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

static void warnf(crom_remesh_warn_fn warn, void *ctx, const char *fmt, ...)
{
    if (!warn)
        return;
    char buf[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    warn(ctx, buf);
}

static void centroid(const crom_mesh *m, int t, double c[3])
{
    const int *e = m->tets + 4 * (size_t)t;
    for (int k = 0; k < 3; k++)
        c[k] = (VX(m, e[0])[k] + VX(m, e[1])[k] + VX(m, e[2])[k] + VX(m, e[3])[k]) / 4;
}

/* ------------------------------------------------------- face neighbours */

typedef struct {
    int v[3]; /* sorted vertex indices of the face */
    int slot; /* 4 t + l: face l (opposite vertex l) of tet t */
} fkey;

static int fkey_cmp(const void *pa, const void *pb)
{
    const fkey *a = pa, *b = pb;
    for (int i = 0; i < 3; i++)
        if (a->v[i] != b->v[i])
            return a->v[i] < b->v[i] ? -1 : 1;
    return (a->slot > b->slot) - (a->slot < b->slot);
}

/* nbr[4t + l] = the slot on the other side of face l of tet t, or -1 on the
 * boundary. CROM_EDATA if a face is shared by more than two tets. */
static int tet_neighbors(const crom_mesh *m, int **nbr_out)
{
    size_t nf = 4 * (size_t)m->nt;
    fkey *f = crom_malloc(sizeof(fkey) * (nf ? nf : 1));
    int *nbr = crom_malloc(sizeof(int) * (nf ? nf : 1));
    if (!f || !nbr) {
        free(f);
        free(nbr);
        return CROM_EINTERNAL;
    }
    for (size_t s = 0; s < nf; s++) {
        const int *e = m->tets + 4 * (s / 4);
        int l = (int)(s % 4), k = 0, tmp;
        for (int c = 0; c < 4; c++)
            if (c != l)
                f[s].v[k++] = e[c];
        int *v = f[s].v;
        if (v[0] > v[1]) { tmp = v[0]; v[0] = v[1]; v[1] = tmp; }
        if (v[1] > v[2]) { tmp = v[1]; v[1] = v[2]; v[2] = tmp; }
        if (v[0] > v[1]) { tmp = v[0]; v[0] = v[1]; v[1] = tmp; }
        f[s].slot = (int)s;
        nbr[s] = -1;
    }
    qsort(f, nf, sizeof *f, fkey_cmp);
    int rc = 0;
    for (size_t i = 0; i < nf;) {
        size_t j = i + 1;
        while (j < nf && !memcmp(f[i].v, f[j].v, sizeof f[i].v))
            j++;
        if (j - i > 2) {
            rc = crom_err(CROM_EDATA, "face (%d, %d, %d) is shared by %zu tets (a valid solid has at most 2)",
                          f[i].v[0], f[i].v[1], f[i].v[2], j - i);
            break;
        }
        if (j - i == 2) {
            nbr[f[i].slot] = f[i + 1].slot;
            nbr[f[i + 1].slot] = f[i].slot;
        }
        i = j;
    }
    free(f);
    if (rc)
        free(nbr);
    else
        *nbr_out = nbr;
    return rc;
}

/* ------------------------------------------------------------- union-find */

static int uf_find(int *p, int i)
{
    while (p[i] != i) {
        p[i] = p[p[i]];
        i = p[i];
    }
    return i;
}

static void uf_union(int *p, int a, int b)
{
    a = uf_find(p, a);
    b = uf_find(p, b);
    if (a != b) {
        if (a < b)
            p[b] = a;
        else
            p[a] = b;
    }
}

int crom_remesh_components(const crom_mesh *m, int *comp)
{
    int *p = crom_malloc(sizeof(int) * (size_t)(m->nv ? m->nv : 1));
    unsigned char *used = crom_calloc((size_t)(m->nv ? m->nv : 1), 1);
    if (!p || !used) {
        free(p);
        free(used);
        return -1;
    }
    for (int i = 0; i < m->nv; i++)
        p[i] = i;
    for (int t = 0; t < m->nt; t++) {
        const int *e = m->tets + 4 * (size_t)t;
        for (int c = 0; c < 4; c++)
            used[e[c]] = 1;
        for (int c = 1; c < 4; c++)
            uf_union(p, e[0], e[c]);
    }
    /* label roots in vertex order; unused vertices get -1 */
    int n = 0;
    int *label = crom_malloc(sizeof(int) * (size_t)(m->nv ? m->nv : 1));
    if (!label) {
        free(p);
        free(used);
        return -1;
    }
    for (int i = 0; i < m->nv; i++)
        label[i] = -1;
    for (int i = 0; i < m->nv; i++) {
        if (!used[i])
            continue;
        int r = uf_find(p, i);
        if (label[r] < 0)
            label[r] = n++;
        if (comp)
            comp[i] = label[r];
    }
    if (comp)
        for (int i = 0; i < m->nv; i++)
            if (!used[i])
                comp[i] = -1;
    free(label);
    free(p);
    free(used);
    return n;
}

int crom_remesh_remove_region(crom_mesh *m, const char *name)
{
    for (int r = 0; r < m->nregions; r++)
        if (!strcmp(m->regions[r].name, name)) {
            free(m->regions[r].name);
            free(m->regions[r].source);
            free(m->regions[r].idx);
            memmove(&m->regions[r], &m->regions[r + 1],
                    sizeof(crom_mesh_region) * (size_t)(m->nregions - r - 1));
            m->nregions--;
            return 1;
        }
    return 0;
}

/* Finish an output mesh: drop unused vertices, orient, validate. */
static int finish(crom_mesh *out)
{
    int rc = crom_mesh_compact(out);
    if (!rc)
        rc = crom_mesh_orient(out, NULL);
    if (!rc)
        rc = crom_mesh_validate(out);
    return rc;
}

/* ------------------------------------------------------------------- cut */

static int check_cut(const crom_remesh_cut_opts *c)
{
    if (c->axis < 0 || c->axis > 2)
        return crom_err(CROM_EUSAGE, "cut axis must be x, y or z");
    if (c->nseg < 1 || !c->seg)
        return crom_err(CROM_EUSAGE, "cut needs at least one --segment");
    if (c->stages < 1)
        return crom_err(CROM_EUSAGE, "--stages must be at least 1, got %d", c->stages);
    if (c->stage < 0 || c->stage > c->stages)
        return crom_err(CROM_EUSAGE, "--stage %d is not in 0..%d (--stages)", c->stage, c->stages);
    for (int k = 0; k < c->nseg; k++) {
        const double *s = c->seg + 4 * (size_t)k;
        for (int i = 0; i < 4; i++)
            if (!isfinite(s[i]))
                return crom_err(CROM_EUSAGE, "--segment %d has a non-finite coordinate", k + 1);
        if (s[0] == s[2] && s[1] == s[3])
            return crom_err(CROM_EUSAGE, "--segment %d has zero length (%g,%g to %g,%g)", k + 1, s[0],
                            s[1], s[2], s[3]);
    }
    return 0;
}

static double orient2(const double a[2], const double b[2], const double c[2])
{
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

static int sgn(double x)
{
    return (x > 0) - (x < 0);
}

/* 1 when segment p-q crosses the ribbon a-b: p and q on opposite sides of
 * the line ab, and a, b not strictly on the same side of pq. A centroid
 * exactly on the line counts as lying on its left (orient >= 0), so that
 * every tet has a side and a ribbon through centroids (symmetric meshes)
 * still separates the body. */
static int crosses(const double p[2], const double q[2], const double a[2], const double b[2])
{
    int d1 = orient2(a, b, p) >= 0, d2 = orient2(a, b, q) >= 0;
    if (d1 == d2)
        return 0;
    int e1 = sgn(orient2(p, q, a)), e2 = sgn(orient2(p, q, b));
    return e1 * e2 <= 0;
}

int crom_remesh_cut_faces(const crom_mesh *m, const crom_remesh_cut_opts *c, unsigned char **cut_out,
                          int *nfaces)
{
    int rc = check_cut(c);
    if (rc)
        return rc;
    int iu = c->axis == 0 ? 1 : 0, iv = c->axis == 2 ? 1 : 2;
    int *nbr = NULL;
    if ((rc = tet_neighbors(m, &nbr)))
        return rc;
    size_t nf = 4 * (size_t)m->nt;
    unsigned char *cut = crom_calloc(nf ? nf : 1, 1);
    double *cp = crom_malloc(sizeof(double) * 2 * (size_t)(m->nt ? m->nt : 1));
    double *rib = crom_malloc(sizeof(double) * 4 * (size_t)c->nseg);
    if (!cut || !cp || !rib) {
        free(nbr);
        free(cut);
        free(cp);
        free(rib);
        return CROM_EINTERNAL;
    }
    for (int t = 0; t < m->nt; t++) {
        double x[3];
        centroid(m, t, x);
        cp[2 * t] = x[iu];
        cp[2 * t + 1] = x[iv];
    }
    /* the partial ribbons: the first stage/stages of each segment */
    double frac = (double)c->stage / c->stages;
    for (int k = 0; k < c->nseg; k++) {
        const double *s = c->seg + 4 * (size_t)k;
        rib[4 * k] = s[0];
        rib[4 * k + 1] = s[1];
        rib[4 * k + 2] = c->stage == c->stages ? s[2] : s[0] + frac * (s[2] - s[0]);
        rib[4 * k + 3] = c->stage == c->stages ? s[3] : s[1] + frac * (s[3] - s[1]);
    }
    int n = 0;
    for (size_t s = 0; s < nf && c->stage > 0; s++) {
        int o = nbr[s];
        if (o < 0 || (size_t)o < s)
            continue;
        const double *p = cp + 2 * (s / 4), *q = cp + 2 * ((size_t)o / 4);
        for (int k = 0; k < c->nseg; k++)
            if (crosses(p, q, rib + 4 * k, rib + 4 * k + 2)) {
                cut[s] = cut[o] = 1;
                n++;
                break;
            }
    }
    free(nbr);
    free(cp);
    free(rib);
    *cut_out = cut;
    *nfaces = n;
    return 0;
}

/* A mesh being split along cut faces: the vertex stars, and the vertex
 * (kept or copy) each slot of them gets. */
typedef struct {
    int *start, *star; /* the star of each vertex: CSR of slots 4t + c (tet t, corner c), in increasing tet order */
    int maxdeg;        /* the largest star */
    int *newidx;       /* [4 nt] per star entry: the vertex it gets */
    int *orig;         /* [nnew − nv] the vertex each copy copies */
    int nnew;          /* vertices after the split */
    size_t cap;        /* orig's capacity */
} splitting;

static void splitting_free(splitting *sp)
{
    free(sp->start);
    free(sp->star);
    free(sp->newidx);
    free(sp->orig);
}

/* The vertex stars of m and the buffer for their new indices. */
static int vertex_stars(const crom_mesh *m, splitting *sp)
{
    size_t nslot = 4 * (size_t)m->nt;
    int *start = sp->start = crom_calloc((size_t)m->nv + 1, sizeof(int));
    sp->star = crom_malloc(sizeof(int) * (nslot ? nslot : 1));
    sp->newidx = crom_malloc(sizeof(int) * (nslot ? nslot : 1));
    if (!start || !sp->star || !sp->newidx)
        return CROM_EINTERNAL;
    for (size_t s = 0; s < nslot; s++)
        start[m->tets[s] + 1]++;
    for (int v = 0; v < m->nv; v++) {
        if (start[v + 1] > sp->maxdeg)
            sp->maxdeg = start[v + 1];
        start[v + 1] += start[v];
    }
    int *fill = crom_malloc(sizeof(int) * (size_t)(m->nv ? m->nv : 1));
    if (!fill)
        return CROM_EINTERNAL;
    memcpy(fill, start, sizeof(int) * (size_t)m->nv);
    for (size_t s = 0; s < nslot; s++)
        sp->star[fill[m->tets[s]]++] = (int)s;
    free(fill);
    return 0;
}

/* Each star grouped into components joined by un-cut faces (nbr: the tet
 * neighbours): the component of the lowest tet keeps v, the others get
 * copies, numbered from nv on in vertex order. */
static int group_stars(const crom_mesh *m, const unsigned char *cut, const int *nbr, splitting *sp)
{
    int *parent = crom_malloc(sizeof(int) * (size_t)(sp->maxdeg ? sp->maxdeg : 1));
    if (!parent)
        return CROM_EINTERNAL;
    const int *star = sp->star;
    int *newidx = sp->newidx;
    sp->nnew = m->nv;
    for (int v = 0; v < m->nv; v++) {
        int b = sp->start[v], deg = sp->start[v + 1] - b;
        for (int i = 0; i < deg; i++)
            parent[i] = i;
        for (int i = 0; i < deg; i++) {
            int t = star[b + i] / 4, corner = star[b + i] % 4;
            for (int l = 0; l < 4; l++) {
                int s = 4 * t + l;
                if (l == corner || cut[s] || nbr[s] < 0)
                    continue;
                int t2 = nbr[s] / 4;
                for (int j = 0; j < deg; j++)
                    if (star[b + j] / 4 == t2) {
                        uf_union(parent, i, j);
                        break;
                    }
            }
        }
        for (int i = 0; i < deg; i++) {
            int r = uf_find(parent, i);
            if (r != i) {
                newidx[b + i] = newidx[b + r]; /* r < i: assigned already */
            } else if (i == 0) {
                newidx[b + i] = v;
            } else {
                int rc = crom_array_reserve((void **)&sp->orig, &sp->cap, (size_t)(sp->nnew - m->nv) + 1,
                                            sizeof *sp->orig);
                if (rc) {
                    free(parent);
                    return rc;
                }
                sp->orig[sp->nnew - m->nv] = v;
                newidx[b + i] = sp->nnew++;
            }
        }
    }
    free(parent);
    return 0;
}

/* The split mesh into out: m's vertices then the copies, the tets with
 * their slots' new vertices; copies inherit their vertex's regions. */
static int split_mesh(const crom_mesh *m, const splitting *sp, crom_mesh *out)
{
    int nd = sp->nnew - m->nv, rc = 0;
    size_t nslot = 4 * (size_t)m->nt;
    memset(out, 0, sizeof *out);
    out->nv = sp->nnew;
    out->nt = m->nt;
    out->X = crom_malloc(sizeof(double) * 3 * (size_t)sp->nnew);
    out->tets = crom_malloc(sizeof(int) * (nslot ? nslot : 1));
    if (!out->X || !out->tets) {
        crom_mesh_free(out);
        return CROM_EINTERNAL;
    }
    memcpy(out->X, m->X, sizeof(double) * 3 * (size_t)m->nv);
    for (int i = 0; i < nd; i++)
        memcpy(out->X + 3 * ((size_t)m->nv + i), VX(m, sp->orig[i]), 3 * sizeof(double));
    for (int v = 0; v < m->nv; v++)
        for (int i = sp->start[v]; i < sp->start[v + 1]; i++)
            out->tets[sp->star[i]] = sp->newidx[i];
    for (int r = 0; r < m->nregions && !rc; r++) {
        const crom_mesh_region *g = &m->regions[r];
        unsigned char *in = crom_calloc((size_t)(m->nv ? m->nv : 1), 1);
        int *idx = crom_malloc(sizeof(int) * (size_t)(g->n + nd + 1)), k = 0;
        if (!in || !idx)
            rc = CROM_EINTERNAL;
        for (int j = 0; !rc && j < g->n; j++) {
            in[g->idx[j]] = 1;
            idx[k++] = g->idx[j];
        }
        for (int i = 0; !rc && i < nd; i++)
            if (in[sp->orig[i]])
                idx[k++] = m->nv + i;
        if (!rc)
            rc = crom_mesh_add_region(out, g->name, g->source, idx, k);
        free(in);
        free(idx);
    }
    if (!rc)
        rc = finish(out);
    if (rc)
        crom_mesh_free(out);
    return rc;
}

int crom_remesh_split(const crom_mesh *m, const unsigned char *cut, crom_mesh *out, int *ndup)
{
    splitting sp;
    memset(&sp, 0, sizeof sp);
    int *nbr = NULL, rc = tet_neighbors(m, &nbr);
    if (rc)
        return rc;
    if (!(rc = vertex_stars(m, &sp)) && !(rc = group_stars(m, cut, nbr, &sp)) && !(rc = split_mesh(m, &sp, out)) &&
        ndup)
        *ndup = sp.nnew - m->nv;
    free(nbr);
    splitting_free(&sp);
    return rc;
}

int crom_remesh_cut(const crom_mesh *m, const crom_remesh_cut_opts *c, crom_mesh *out,
                    crom_remesh_cut_stats *st, crom_remesh_warn_fn warn, void *ctx)
{
    unsigned char *cut = NULL;
    int nf = 0, nd = 0, rc = crom_remesh_cut_faces(m, c, &cut, &nf);
    if (rc)
        return rc;
    rc = crom_remesh_split(m, cut, out, &nd);
    free(cut);
    if (rc)
        return rc;
    if (nf == 0)
        warnf(warn, ctx, c->stage == 0 ? "stage 0 cuts nothing: the output is the input mesh"
                                       : "the cut crosses no interior face: the output is the input mesh");
    if (st) {
        st->faces_cut = nf;
        st->verts_dup = nd;
        st->components = crom_remesh_components(out, NULL);
    }
    return 0;
}

/* ----------------------------------------------------------------- punch */

static int check_shape(const crom_remesh_punch_shape *s, int i)
{
    int n = s->kind == CROM_REMESH_PUNCH_SPHERE ? 4 : s->kind == CROM_REMESH_PUNCH_BOX ? 6 : 0;
    if (!n)
        return crom_err(CROM_EUSAGE, "punch shape %d: unknown kind", i + 1);
    for (int k = 0; k < n; k++)
        if (!isfinite(s->a[k]))
            return crom_err(CROM_EUSAGE, "punch shape %d has a non-finite number", i + 1);
    if (s->kind == CROM_REMESH_PUNCH_SPHERE && !(s->a[3] > 0))
        return crom_err(CROM_EUSAGE, "--sphere radius must be positive, got %g", s->a[3]);
    if (s->kind == CROM_REMESH_PUNCH_BOX)
        for (int k = 0; k < 3; k++)
            if (!(s->a[k] < s->a[k + 3]))
                return crom_err(CROM_EUSAGE, "--box needs X0<X1, Y0<Y1, Z0<Z1, got %g,%g,%g,%g,%g,%g",
                                s->a[0], s->a[1], s->a[2], s->a[3], s->a[4], s->a[5]);
    return 0;
}

static int inside(const crom_remesh_punch_shape *s, const double x[3])
{
    if (s->kind == CROM_REMESH_PUNCH_SPHERE) {
        double d2 = 0;
        for (int k = 0; k < 3; k++)
            d2 += (x[k] - s->a[k]) * (x[k] - s->a[k]);
        return d2 <= s->a[3] * s->a[3];
    }
    for (int k = 0; k < 3; k++)
        if (x[k] < s->a[k] || x[k] > s->a[k + 3])
            return 0;
    return 1;
}

int crom_remesh_punch(const crom_mesh *m, const crom_remesh_punch_shape *s, int ns, crom_mesh *out,
                      int *nremoved, crom_remesh_warn_fn warn, void *ctx)
{
    if (ns < 1)
        return crom_err(CROM_EUSAGE, "punch needs at least one --sphere or --box");
    for (int i = 0; i < ns; i++) {
        int rc = check_shape(&s[i], i);
        if (rc)
            return rc;
    }
    crom_mesh r;
    int rc = crom_mesh_copy(m, &r);
    if (rc)
        return rc;
    int k = 0;
    for (int t = 0; t < m->nt; t++) {
        double c[3];
        centroid(m, t, c);
        int hit = 0;
        for (int i = 0; i < ns && !hit; i++)
            hit = inside(&s[i], c);
        if (!hit)
            memcpy(r.tets + 4 * (size_t)k++, m->tets + 4 * (size_t)t, 4 * sizeof(int));
    }
    if (k == 0) {
        crom_mesh_free(&r);
        return crom_err(CROM_EDATA, "punching removes all %d tets: nothing would remain", m->nt);
    }
    r.nt = k;
    if ((rc = crom_mesh_compact(&r))) {
        crom_mesh_free(&r);
        return rc;
    }
    if (k == m->nt)
        warnf(warn, ctx, "no tet centroid lies in the punched shapes: the output is the input mesh");
    for (int g = 0; g < r.nregions;) {
        if (r.regions[g].n == 0) {
            warnf(warn, ctx, "region '%s' lost all its vertices and is dropped", r.regions[g].name);
            crom_remesh_remove_region(&r, r.regions[g].name);
        } else {
            g++;
        }
    }
    if ((rc = finish(&r))) {
        crom_mesh_free(&r);
        return rc;
    }
    if (nremoved)
        *nremoved = m->nt - k;
    *out = r;
    return 0;
}

/* ------------------------------------------------------------------ swap */

void crom_remesh_xform_init(crom_remesh_xform *x)
{
    memset(x, 0, sizeof *x);
    x->scale = 1;
}

/* Rotation matrix about the unit axis n by deg degrees (Rodrigues), with
 * exact cosines and sines at multiples of 90°. */
static void rotation(const double n[3], double deg, double R[3][3])
{
    double r = fmod(deg, 360.0), c, s;
    if (r < 0)
        r += 360;
    if (r == 0) {
        c = 1, s = 0;
    } else if (r == 90) {
        c = 0, s = 1;
    } else if (r == 180) {
        c = -1, s = 0;
    } else if (r == 270) {
        c = 0, s = -1;
    } else {
        c = cos(r * M_PI / 180);
        s = sin(r * M_PI / 180);
    }
    double x = n[0], y = n[1], z = n[2], C = 1 - c;
    R[0][0] = c + x * x * C;
    R[0][1] = x * y * C - z * s;
    R[0][2] = x * z * C + y * s;
    R[1][0] = y * x * C + z * s;
    R[1][1] = c + y * y * C;
    R[1][2] = y * z * C - x * s;
    R[2][0] = z * x * C - y * s;
    R[2][1] = z * y * C + x * s;
    R[2][2] = c + z * z * C;
}

int crom_remesh_transform(crom_mesh *m, const crom_remesh_xform *x, const crom_mesh *ref)
{
    if (!x->fit && (!(x->scale > 0) || !isfinite(x->scale)))
        return crom_err(CROM_EUSAGE, "--scale must be a positive number, got %g", x->scale);
    if (!isfinite(x->deg))
        return crom_err(CROM_EUSAGE, "--rotate: the angle is not finite");
    for (int k = 0; k < 3; k++)
        if (!isfinite(x->axis[k]) || !isfinite(x->translate[k]))
            return crom_err(CROM_EUSAGE, "--rotate/--translate: non-finite number");
    if (x->fit && !ref)
        return crom_err(CROM_EUSAGE, "--fit needs a reference mesh");
    double len = sqrt(x->axis[0] * x->axis[0] + x->axis[1] * x->axis[1] + x->axis[2] * x->axis[2]);
    double R[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    if (x->deg != 0) {
        if (!(len > 0))
            return crom_err(CROM_EUSAGE, "--rotate: the axis must be non-zero");
        double n[3] = {x->axis[0] / len, x->axis[1] / len, x->axis[2] / len};
        rotation(n, x->deg, R);
    }
    for (int i = 0; i < m->nv; i++) {
        double *p = VX(m, i), q[3];
        for (int a = 0; a < 3; a++)
            q[a] = R[a][0] * p[0] + R[a][1] * p[1] + R[a][2] * p[2];
        memcpy(p, q, sizeof q);
    }
    double s = x->scale, t[3] = {x->translate[0], x->translate[1], x->translate[2]};
    if (x->fit) {
        double lo[3], hi[3], rlo[3], rhi[3], e = 0, re = 0;
        crom_mesh_bbox(m, lo, hi);
        crom_mesh_bbox(ref, rlo, rhi);
        for (int k = 0; k < 3; k++) {
            e = fmax(e, hi[k] - lo[k]);
            re = fmax(re, rhi[k] - rlo[k]);
        }
        if (!(e > 0) || !(re > 0) || !isfinite(re / e))
            return crom_err(CROM_EDATA, "--fit: a mesh has an empty bounding box");
        s = re / e;
        for (int k = 0; k < 3; k++)
            t[k] += (rlo[k] + rhi[k]) / 2 - s * (lo[k] + hi[k]) / 2;
    }
    for (int i = 0; i < m->nv; i++)
        for (int k = 0; k < 3; k++) {
            double v = s * VX(m, i)[k] + t[k];
            if (!isfinite(v))
                return crom_err(CROM_EUSAGE, "the transform sends vertex %d to a non-finite position", i);
            VX(m, i)[k] = v;
        }
    return crom_mesh_orient(m, NULL);
}

int crom_remesh_swap(const crom_mesh *in, const crom_mesh *other, const crom_remesh_xform *x,
                     crom_mesh *out, crom_remesh_warn_fn warn, void *ctx)
{
    crom_mesh r;
    int rc = crom_mesh_copy(other, &r);
    if (rc)
        return rc;
    if ((rc = crom_remesh_transform(&r, x, in))) {
        crom_mesh_free(&r);
        return rc;
    }
    int *idx = crom_malloc(sizeof(int) * (size_t)(r.nv ? r.nv : 1));
    if (!idx) {
        crom_mesh_free(&r);
        return CROM_EINTERNAL;
    }
    for (int g = 0; g < in->nregions && !rc; g++) {
        const crom_mesh_region *reg = &in->regions[g];
        /* follow a region defined as another region of `in` to its predicate */
        const char *src = reg->source ? reg->source : "";
        for (int depth = 0; depth < 8 && !crom_pred_is(src); depth++) {
            const crom_mesh_region *up = crom_mesh_find_region(in, src);
            if (!up || up == reg)
                break;
            src = up->source ? up->source : "";
        }
        if (!strncmp(src, "gmsh:", 5)) {
            warnf(warn, ctx, "region '%s' comes from gmsh group '%s' and cannot be transferred to the swapped mesh",
                  reg->name, src + 5);
            continue;
        }
        crom_pred p;
        if (!crom_pred_is(src) || crom_pred_parse(src, &p)) {
            crom_err_clear();
            warnf(warn, ctx, "region '%s' (source '%s') is not a predicate and cannot be transferred",
                  reg->name, src);
            continue;
        }
        int n = 0;
        for (int i = 0; i < r.nv; i++)
            if (crom_pred_eval(&p, VX(&r, i)))
                idx[n++] = i;
        if (n == 0) {
            warnf(warn, ctx, "region '%s' (%s) selects no vertex of the swapped mesh: skipped", reg->name,
                  src);
            continue;
        }
        if (crom_mesh_find_region(&r, reg->name))
            warnf(warn, ctx, "region '%s' of the swapped mesh is replaced by the input's (%s)", reg->name,
                  src);
        rc = crom_mesh_add_region(&r, reg->name, src, idx, n);
    }
    free(idx);
    if (!rc)
        rc = finish(&r);
    if (rc) {
        crom_mesh_free(&r);
        return rc;
    }
    *out = r;
    return 0;
}

/* ---------------------------------------------------------------- refine */

#define GMSH(call, what) CROM_GMSH(call, what)

/* The refined mesh into out (its X and tets) from gmsh's nn nodes (tags
 * ntags, coordinates coord) and ne tets (node tags enodes): the original
 * vertices of m (tags 1..nv, unmoved) keep their index; new ones follow
 * in gmsh's order. */
static int renumber_refined(const crom_mesh *m, const size_t *ntags, size_t nn, const double *coord,
                            const size_t *enodes, size_t ne, crom_mesh *out)
{
    size_t nv = (size_t)m->nv, maxtag = 0;
    for (size_t i = 0; i < nn; i++)
        if (ntags[i] > maxtag)
            maxtag = ntags[i];
    if (maxtag > (size_t)INT32_MAX / 4)
        return crom_err(CROM_EUSAGE, "refined mesh too large");
    int *map = crom_malloc(sizeof(int) * (maxtag + 1)), rc = 0;
    out->X = crom_malloc(sizeof(double) * 3 * nn);
    out->tets = crom_malloc(sizeof(int) * 4 * ne);
    if (!map || !out->X || !out->tets) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    for (size_t i = 0; i <= maxtag; i++)
        map[i] = -1;
    memcpy(out->X, m->X, sizeof(double) * 3 * nv);
    int next = (int)nv;
    for (size_t i = 0; i < nn; i++) {
        size_t tag = ntags[i];
        if (tag >= 1 && tag <= nv) {
            if (memcmp(coord + 3 * i, m->X + 3 * (tag - 1), 3 * sizeof(double))) {
                rc = crom_err(CROM_EINTERNAL, "gmsh moved vertex %zu while refining", tag - 1);
                goto out;
            }
            map[tag] = (int)tag - 1;
        } else {
            map[tag] = next;
            memcpy(out->X + 3 * (size_t)next, coord + 3 * i, 3 * sizeof(double));
            next++;
        }
    }
    if ((size_t)next != nn) {
        rc = crom_err(CROM_EINTERNAL, "gmsh lost vertices while refining");
        goto out;
    }
    for (size_t k = 0; k < 4 * ne; k++) {
        if (enodes[k] > maxtag || map[enodes[k]] < 0) {
            rc = crom_err(CROM_EINTERNAL, "gmsh refined tet refers to an unknown node");
            goto out;
        }
        out->tets[k] = map[enodes[k]];
    }
    out->nv = (int)nn;
    out->nt = (int)ne;
out:
    free(map);
    return rc;
}

/* One 1:8 refinement of m by gmsh into out (regions not yet set): the
 * original vertices keep their indices 0..nv-1, midpoints follow. */
static int gmsh_refine_once(const crom_mesh *m, int step, crom_mesh *out)
{
    int ierr = 0, rc = 0;
    size_t nv = (size_t)m->nv, nt = (size_t)m->nt;
    size_t *vtag = crom_malloc(sizeof(size_t) * nv), *etag = crom_malloc(sizeof(size_t) * nt);
    size_t *enode = crom_malloc(sizeof(size_t) * 4 * nt);
    size_t *ntags = NULL, nn = 0, nc = 0, np = 0, *etags = NULL, ne = 0, *enodes = NULL, nen = 0;
    double *coord = NULL, *param = NULL;
    char model[32];
    memset(out, 0, sizeof *out);
    if (!vtag || !etag || !enode) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    for (size_t i = 0; i < nv; i++)
        vtag[i] = i + 1;
    for (size_t t = 0; t < nt; t++) {
        etag[t] = t + 1;
        for (int c = 0; c < 4; c++)
            enode[4 * t + c] = (size_t)m->tets[4 * t + c] + 1;
    }
    snprintf(model, sizeof model, "refine%d", step);
    GMSH(gmshModelAdd(model, &ierr), "add a model");
    GMSH(gmshModelAddDiscreteEntity(3, 1, NULL, 0, &ierr), "add a discrete volume");
    GMSH(gmshModelMeshAddNodes(3, 1, vtag, nv, m->X, 3 * nv, NULL, 0, &ierr), "add the vertices");
    GMSH(gmshModelMeshAddElementsByType(1, 4, etag, nt, enode, 4 * nt, &ierr), "add the tets");
    GMSH(gmshModelMeshRefine(&ierr), "refine the mesh");
    GMSH(gmshModelMeshGetNodes(&ntags, &nn, &coord, &nc, &param, &np, -1, -1, 0, 0, &ierr),
         "read the refined vertices");
    GMSH(gmshModelMeshGetElementsByType(4, &etags, &ne, &enodes, &nen, -1, 0, 1, &ierr),
         "read the refined tets");
    if (ne != 8 * nt || nn < nv) {
        rc = crom_err(CROM_EINTERNAL, "gmsh refined %zu tets into %zu with %zu vertices (expected %zu tets)",
                      nt, ne, nn, 8 * nt);
        goto out;
    }
    rc = renumber_refined(m, ntags, nn, coord, enodes, ne, out);
out:
    ierr = 0;
    gmshModelRemove(&ierr);
    if (ntags)
        gmshFree(ntags);
    if (coord)
        gmshFree(coord);
    if (param)
        gmshFree(param);
    if (etags)
        gmshFree(etags);
    if (enodes)
        gmshFree(enodes);
    free(vtag);
    free(etag);
    free(enode);
    if (rc)
        crom_mesh_free(out);
    return rc;
}

/* Regions of the refined mesh r from those of its parent m: each new vertex
 * w is the midpoint of an edge (a, b) of m, and a and b are the only
 * vertices of m that share an edge of r with w (in a red refinement the
 * other edges from w end at midpoints). Checked here, with the midpoint. */
static int refine_regions(const crom_mesh *m, crom_mesh *r)
{
    int nv = m->nv, nw = r->nv - nv, rc = 0;
    int *ends = crom_malloc(sizeof(int) * 2 * (size_t)(nw ? nw : 1));
    int *cnt = crom_calloc((size_t)(nw ? nw : 1), sizeof(int));
    if (!ends || !cnt) {
        free(ends);
        free(cnt);
        return CROM_EINTERNAL;
    }
    for (int t = 0; t < r->nt && !rc; t++) {
        const int *e = r->tets + 4 * (size_t)t;
        for (int i = 0; i < 4; i++)
            for (int j = 0; j < 4; j++) {
                int w = e[i] - nv, o = e[j];
                if (i == j || w < 0 || o >= nv)
                    continue;
                if ((cnt[w] > 0 && ends[2 * w] == o) || (cnt[w] > 1 && ends[2 * w + 1] == o))
                    continue;
                if (cnt[w] == 2) {
                    rc = crom_err(CROM_EINTERNAL, "refined vertex %d is joined to more than two original vertices",
                                  w + nv);
                    break;
                }
                ends[2 * w + cnt[w]++] = o;
            }
    }
    double lo[3], hi[3];
    crom_mesh_bbox(m, lo, hi);
    double L = fmax(hi[0] - lo[0], fmax(hi[1] - lo[1], hi[2] - lo[2]));
    for (int w = 0; w < nw && !rc; w++) {
        if (cnt[w] != 2) {
            rc = crom_err(CROM_EINTERNAL, "refined vertex %d is joined to %d original vertices, expected 2",
                          w + nv, cnt[w]);
            break;
        }
        const double *a = VX(m, ends[2 * w]), *b = VX(m, ends[2 * w + 1]), *x = VX(r, w + nv);
        for (int k = 0; k < 3; k++)
            if (fabs(x[k] - (a[k] + b[k]) / 2) > 1e-12 * L) {
                rc = crom_err(CROM_EINTERNAL, "refined vertex %d is not the midpoint of its edge", w + nv);
                break;
            }
    }
    unsigned char *in = crom_malloc((size_t)(nv ? nv : 1));
    int *idx = NULL;
    if (!in)
        rc = rc ? rc : CROM_EINTERNAL;
    for (int g = 0; g < m->nregions && !rc; g++) {
        const crom_mesh_region *reg = &m->regions[g];
        memset(in, 0, (size_t)nv);
        idx = crom_malloc(sizeof(int) * (size_t)(reg->n + nw + 1));
        if (!idx) {
            rc = CROM_EINTERNAL;
            break;
        }
        int k = 0;
        for (int j = 0; j < reg->n; j++) {
            in[reg->idx[j]] = 1;
            idx[k++] = reg->idx[j];
        }
        for (int w = 0; w < nw; w++)
            if (in[ends[2 * w]] && in[ends[2 * w + 1]])
                idx[k++] = w + nv;
        rc = crom_mesh_add_region(r, reg->name, reg->source, idx, k);
        free(idx);
    }
    free(in);
    free(ends);
    free(cnt);
    return rc;
}

int crom_remesh_refine(const crom_mesh *m, int times, crom_mesh *out, crom_gmsh_log_fn log, void *log_ctx)
{
    if (times < 1 || times > 6)
        return crom_err(CROM_EUSAGE, "--times must be in 1..6, got %d", times);
    if ((double)m->nt * pow(8, times) > (double)INT32_MAX / 4)
        return crom_err(CROM_EUSAGE, "refining %d tets %d times gives too many tets", m->nt, times);
    int ierr = 0, rc = 0;
    crom_mesh cur;
    if ((rc = crom_mesh_copy(m, &cur)))
        return rc;
    if ((rc = crom_gmsh_begin(log))) {
        crom_mesh_free(&cur);
        return rc;
    }
    /* straight edges: midpoints exactly halfway (no geometry to snap to) */
    gmshOptionSetNumber("Mesh.SecondOrderLinear", 1, &ierr);
    gmshOptionSetNumber("Mesh.AlgoSubdivide", 0, &ierr);
    for (int step = 0; step < times && !rc; step++) {
        crom_mesh next;
        rc = gmsh_refine_once(&cur, step, &next);
        if (!rc && (rc = refine_regions(&cur, &next)))
            crom_mesh_free(&next);
        if (!rc) {
            crom_mesh_free(&cur);
            cur = next;
        }
    }
    crom_gmsh_end(log, log_ctx);
    if (!rc)
        rc = finish(&cur);
    if (rc) {
        crom_mesh_free(&cur);
        return rc;
    }
    *out = cur;
    return 0;
}
