/* surface.c — closed triangle surfaces: building, reading .stl/.obj,
 * checking, subdividing (see surface.h). */
#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>

#include "base/array.h"
#include "base/err.h"
#include "mesh/surface.h"

int crom_surface_add_vertex(crom_surface *s, const double p[3])
{
    int rc = crom_array_reserve((void **)&s->V, &s->capv, (size_t)s->nv + 1, 3 * sizeof *s->V);
    if (rc)
        return rc;
    memcpy(s->V + 3 * (size_t)s->nv, p, 3 * sizeof(double));
    s->nv++;
    return 0;
}

int crom_surface_add_tri(crom_surface *s, int a, int b, int c)
{
    int rc = crom_array_reserve((void **)&s->T, &s->capt, (size_t)s->nt + 1, 3 * sizeof *s->T);
    if (rc)
        return rc;
    s->T[3 * (size_t)s->nt] = a;
    s->T[3 * (size_t)s->nt + 1] = b;
    s->T[3 * (size_t)s->nt + 2] = c;
    s->nt++;
    return 0;
}

typedef struct {
    double p[3];
    int i;
} vkey;

static int vkey_cmp(const void *a, const void *b)
{
    const vkey *x = a, *y = b;
    for (int k = 0; k < 3; k++)
        if (x->p[k] != y->p[k])
            return x->p[k] < y->p[k] ? -1 : 1;
    return (x->i > y->i) - (x->i < y->i);
}

/* Merge exactly coincident vertices (STL repeats them per triangle). */
int crom_surface_weld(crom_surface *s)
{
    vkey *k = crom_malloc(sizeof(vkey) * (size_t)(s->nv ? s->nv : 1));
    int *map = crom_malloc(sizeof(int) * (size_t)(s->nv ? s->nv : 1));
    if (!k || !map) {
        free(k);
        free(map);
        return CROM_EINTERNAL;
    }
    for (int i = 0; i < s->nv; i++) {
        memcpy(k[i].p, s->V + 3 * (size_t)i, 3 * sizeof(double));
        k[i].i = i;
    }
    qsort(k, (size_t)s->nv, sizeof *k, vkey_cmp);
    int n = 0;
    for (int i = 0; i < s->nv; i++) {
        if (i == 0 || memcmp(k[i].p, k[i - 1].p, 3 * sizeof(double)) != 0) {
            memcpy(s->V + 3 * (size_t)n, k[i].p, 3 * sizeof(double));
            n++;
        }
        map[k[i].i] = n - 1;
    }
    for (size_t j = 0; j < 3 * (size_t)s->nt; j++)
        s->T[j] = map[s->T[j]];
    s->nv = n;
    free(k);
    free(map);
    return 0;
}

static int read_stl(FILE *f, const char *path, crom_surface *s)
{
    struct stat st;
    fstat(fileno(f), &st);
    unsigned char hdr[84];
    size_t got = fread(hdr, 1, 84, f);
    int binary = 0;
    if (got == 84) {
        unsigned n = (unsigned)hdr[80] | (unsigned)hdr[81] << 8 | (unsigned)hdr[82] << 16 |
                     (unsigned)hdr[83] << 24;
        binary = (off_t)84 + (off_t)50 * n == st.st_size;
        if (!binary && strncmp((char *)hdr, "solid", 5))
            return crom_err(CROM_EDATA, "%s: not an STL file (bad size for binary, no 'solid' for ASCII)",
                            path);
        if (binary) {
            for (unsigned t = 0; t < n; t++) {
                unsigned char rec[50];
                if (fread(rec, 1, 50, f) != 50)
                    return crom_err(CROM_EDATA, "%s: truncated binary STL", path);
                for (int c = 0; c < 3; c++) {
                    float xyz[3];
                    memcpy(xyz, rec + 12 + 12 * c, 12);
                    double p[3] = {xyz[0], xyz[1], xyz[2]};
                    if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2]))
                        return crom_err(CROM_EDATA, "%s: triangle %u has a non-finite vertex", path, t);
                    if (crom_surface_add_vertex(s, p))
                        return CROM_EINTERNAL;
                }
                if (crom_surface_add_tri(s, s->nv - 3, s->nv - 2, s->nv - 1))
                    return CROM_EINTERNAL;
            }
            return crom_surface_weld(s);
        }
    } else if (got < 5 || strncmp((char *)hdr, "solid", 5)) {
        return crom_err(CROM_EDATA, "%s: not an STL file", path);
    }
    rewind(f);
    char word[64];
    int nvert = 0;
    while (fscanf(f, "%63s", word) == 1) {
        if (!strcmp(word, "vertex")) {
            double p[3];
            if (fscanf(f, "%lf %lf %lf", &p[0], &p[1], &p[2]) != 3)
                return crom_err(CROM_EDATA, "%s: bad 'vertex' line in ASCII STL", path);
            if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2]))
                return crom_err(CROM_EDATA, "%s: non-finite vertex in ASCII STL", path);
            if (crom_surface_add_vertex(s, p))
                return CROM_EINTERNAL;
            nvert++;
        } else if (!strcmp(word, "endloop")) {
            if (nvert != 3)
                return crom_err(CROM_EDATA, "%s: a facet with %d vertices (STL needs 3)", path, nvert);
            if (crom_surface_add_tri(s, s->nv - 3, s->nv - 2, s->nv - 1))
                return CROM_EINTERNAL;
            nvert = 0;
        }
    }
    if (s->nt == 0)
        return crom_err(CROM_EDATA, "%s: no triangles in ASCII STL", path);
    return crom_surface_weld(s);
}

static int read_obj(FILE *f, const char *path, crom_surface *s)
{
    char line[4096];
    int lineno = 0;
    while (fgets(line, sizeof line, f)) {
        lineno++;
        char *p = line;
        while (isspace((unsigned char)*p))
            p++;
        if (p[0] == 'v' && isspace((unsigned char)p[1])) {
            double q[3];
            if (sscanf(p + 1, "%lf %lf %lf", &q[0], &q[1], &q[2]) != 3 || !isfinite(q[0]) ||
                !isfinite(q[1]) || !isfinite(q[2]))
                return crom_err(CROM_EDATA, "%s:%d: bad vertex line", path, lineno);
            if (crom_surface_add_vertex(s, q))
                return CROM_EINTERNAL;
        } else if (p[0] == 'f' && isspace((unsigned char)p[1])) {
            int idx[64], n = 0;
            char *tok = p + 1, *end;
            for (;;) {
                while (isspace((unsigned char)*tok))
                    tok++;
                if (!*tok)
                    break;
                long v = strtol(tok, &end, 10);
                if (end == tok)
                    return crom_err(CROM_EDATA, "%s:%d: bad face line", path, lineno);
                if (v < 0)
                    v = s->nv + v + 1;
                if (v < 1 || v > s->nv)
                    return crom_err(CROM_EDATA, "%s:%d: face refers to vertex %ld of %d", path,
                                    lineno, v, s->nv);
                if (n == 64)
                    return crom_err(CROM_EDATA, "%s:%d: face with too many vertices", path, lineno);
                idx[n++] = (int)v - 1;
                tok = end;
                while (*tok && !isspace((unsigned char)*tok))
                    tok++; /* skip /vt/vn */
            }
            if (n < 3)
                return crom_err(CROM_EDATA, "%s:%d: face with %d vertices", path, lineno, n);
            for (int k = 1; k + 1 < n; k++)
                if (crom_surface_add_tri(s, idx[0], idx[k], idx[k + 1]))
                    return CROM_EINTERNAL;
        }
    }
    if (s->nt == 0)
        return crom_err(CROM_EDATA, "%s: no faces in OBJ file", path);
    return 0;
}

static int ends_with(const char *s, const char *suf)
{
    size_t n = strlen(s), m = strlen(suf);
    return n >= m && !strcasecmp(s + n - m, suf);
}

int crom_surface_read(const char *path, crom_surface *out)
{
    memset(out, 0, sizeof *out);
    FILE *f = fopen(path, "rb");
    if (!f)
        return crom_err(CROM_ENOINPUT, "%s: %s", path, strerror(errno));
    int rc;
    if (ends_with(path, ".stl"))
        rc = read_stl(f, path, out);
    else if (ends_with(path, ".obj"))
        rc = read_obj(f, path, out);
    else
        rc = crom_err(CROM_EUSAGE, "%s: unknown surface format (expected .stl or .obj)", path);
    fclose(f);
    if (rc)
        crom_surface_free(out);
    return rc;
}

void crom_surface_free(crom_surface *s)
{
    free(s->V);
    free(s->T);
    memset(s, 0, sizeof *s);
}

typedef struct {
    int a, b; /* a < b */
    int dir;  /* +1 if the triangle had a->b, -1 if b->a */
} hedge;

static int hedge_cmp(const void *x, const void *y)
{
    const hedge *p = x, *q = y;
    if (p->a != q->a)
        return p->a < q->a ? -1 : 1;
    return (p->b > q->b) - (p->b < q->b);
}

/* Edges shared by two triangles in opposite directions, and (closed) no
 * boundary edge. */
static int check_edges(const crom_surface *s, const char *name, int closed)
{
    int nt = s->nt;
    const int *T = s->T;
    if (closed && nt < 4)
        return crom_err(CROM_EDATA, "%s: %d triangles cannot close a volume", name, nt);
    if (nt < 1)
        return crom_err(CROM_EDATA, "%s: the surface has no triangles", name);
    size_t ne = 3 * (size_t)nt;
    hedge *e = crom_malloc(sizeof(hedge) * ne);
    if (!e)
        return CROM_EINTERNAL;
    for (int t = 0; t < nt; t++)
        for (int k = 0; k < 3; k++) {
            int a = T[3 * t + k], b = T[3 * t + (k + 1) % 3];
            hedge *h = &e[3 * (size_t)t + k];
            if (a == b) {
                free(e);
                return crom_err(CROM_EDATA, "%s: triangle %d is degenerate (repeated vertex)", name, t);
            }
            h->a = a < b ? a : b;
            h->b = a < b ? b : a;
            h->dir = a < b ? 1 : -1;
        }
    qsort(e, ne, sizeof *e, hedge_cmp);
    int rc = 0, open = 0, nonmanifold = 0, flipped = 0;
    for (size_t i = 0; i < ne;) {
        size_t j = i + 1;
        while (j < ne && e[j].a == e[i].a && e[j].b == e[i].b)
            j++;
        if (j - i == 1)
            open++;
        else if (j - i > 2)
            nonmanifold++;
        else if (e[i].dir == e[i + 1].dir)
            flipped++;
        i = j;
    }
    if (open && closed)
        rc = crom_err(CROM_EDATA, "%s: surface is not closed (%d boundary edges); crom meshes the inside of a closed surface",
                      name, open);
    else if (nonmanifold)
        rc = crom_err(CROM_EDATA, "%s: surface is non-manifold (%d edges shared by more than two triangles)",
                      name, nonmanifold);
    else if (flipped)
        rc = crom_err(CROM_EDATA, "%s: surface is not consistently oriented (%d edges)", name, flipped);
    free(e);
    return rc;
}

int crom_surface_check_closed(const crom_surface *s, const char *name) { return check_edges(s, name, 1); }

int crom_surface_check_oriented(const crom_surface *s, const char *name) { return check_edges(s, name, 0); }

/* ------------------------------------------------- surface subdivision */

typedef struct {
    int a, b, tri;
} ekey;

static int ekey_cmp(const void *x, const void *y)
{
    const ekey *p = x, *q = y;
    if (p->a != q->a)
        return p->a < q->a ? -1 : 1;
    return (p->b > q->b) - (p->b < q->b);
}

static double max_edge(const crom_surface *s)
{
    double m = 0;
    for (int t = 0; t < s->nt; t++)
        for (int k = 0; k < 3; k++) {
            const double *p = s->V + 3 * (size_t)s->T[3 * t + k], *q = s->V + 3 * (size_t)s->T[3 * t + (k + 1) % 3];
            double d = sqrt((p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) +
                            (p[2] - q[2]) * (p[2] - q[2]));
            if (d > m)
                m = d;
        }
    return m;
}

/* One conforming 1-to-4 midpoint subdivision of every triangle. */
static int subdivide(crom_surface *s)
{
    size_t ne = 3 * (size_t)s->nt;
    ekey *e = crom_malloc(sizeof(ekey) * ne);
    int *mid = crom_malloc(sizeof(int) * ne);
    int *T = s->T, nt = s->nt, rc = 0;
    if (!e || !mid) {
        free(e);
        free(mid);
        return CROM_EINTERNAL;
    }
    for (int t = 0; t < nt; t++)
        for (int k = 0; k < 3; k++) {
            int a = T[3 * t + k], b = T[3 * t + (k + 1) % 3];
            e[3 * (size_t)t + k] = (ekey){a < b ? a : b, a < b ? b : a, 3 * t + k};
        }
    qsort(e, ne, sizeof *e, ekey_cmp);
    for (size_t i = 0; i < ne && !rc; i++) {
        if (i == 0 || ekey_cmp(&e[i], &e[i - 1])) {
            const double *p = s->V + 3 * (size_t)e[i].a, *q = s->V + 3 * (size_t)e[i].b;
            double m[3] = {(p[0] + q[0]) / 2, (p[1] + q[1]) / 2, (p[2] + q[2]) / 2};
            rc = crom_surface_add_vertex(s, m);
        }
        mid[e[i].tri] = s->nv - 1;
    }
    s->T = NULL;
    s->nt = s->capt = 0;
    for (int t = 0; t < nt && !rc; t++) {
        int a = T[3 * t], b = T[3 * t + 1], c = T[3 * t + 2];
        int ab = mid[3 * t], bc = mid[3 * t + 1], ca = mid[3 * t + 2];
        rc = crom_surface_add_tri(s, a, ab, ca) || crom_surface_add_tri(s, ab, b, bc) || crom_surface_add_tri(s, ca, bc, c) ||
             crom_surface_add_tri(s, ab, bc, ca);
    }
    free(T);
    free(e);
    free(mid);
    return rc ? CROM_EINTERNAL : 0;
}

/* Subdivide until no edge is longer than h (at most 8 levels and 4M triangles). */
int crom_surface_refine(crom_surface *s, double h)
{
    for (int level = 0; level < 8 && max_edge(s) > h; level++) {
        if ((size_t)s->nt * 4 > 4000000)
            return crom_err(CROM_EUSAGE, "the surface would need more than 4M triangles to reach --size %g", h);
        int rc = subdivide(s);
        if (rc)
            return rc;
    }
    return 0;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Median edge length of a surface (m): over its 3 nt half-edges, which is
 * the median over edges of a closed surface (each edge counted twice).
 * Returns 0 on an empty surface, -1 when out of memory. */
double crom_surface_median_edge(const crom_surface *s)
{
    if (s->nt <= 0)
        return 0;
    double *len = malloc(sizeof(double) * 3 * (size_t)s->nt);
    if (!len)
        return -1;
    for (int t = 0; t < s->nt; t++)
        for (int e = 0; e < 3; e++) {
            const double *a = s->V + 3 * (size_t)s->T[3 * t + e], *b = s->V + 3 * (size_t)s->T[3 * t + (e + 1) % 3];
            len[3 * t + e] = sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                                  (a[2] - b[2]) * (a[2] - b[2]));
        }
    qsort(len, 3 * (size_t)s->nt, sizeof *len, cmp_double);
    double med = len[3 * (size_t)s->nt / 2];
    free(len);
    return med;
}
