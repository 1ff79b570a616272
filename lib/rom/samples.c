/* samples.c — crom/samples read and write, and picking the samples of a
 * frame (see samples.h). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/array.h"
#include "base/err.h"
#include "rom/samples.h"

void crom_samples_free(crom_samples *s)
{
    if (!s)
        return;
    free(s->X);
    free(s->U);
    free(s->vertex);
    free(s->source);
    free(s->time);
    for (int k = 0; k < s->nsources; k++) {
        if (s->src)
            crom_mesh_free(&s->src[k]);
        if (s->src_file)
            free(s->src_file[k]);
    }
    free(s->src);
    free(s->src_file);
    free(s->history);
    memset(s, 0, sizeof *s);
}

int crom_samples_nonzero_frames(const crom_samples *s)
{
    int n = 0;
    for (int f = 0; f < s->F; f++) {
        const float *u = s->U + (size_t)f * s->N * 3;
        for (size_t i = 0; i < (size_t)s->N * 3; i++)
            if (u[i] != 0) {
                n++;
                break;
            }
    }
    return n;
}

/* Source group name of index k among n: zero-padded, at least 3 digits. */
static void source_name(int k, int n, char *buf, size_t len)
{
    size_t digits = 3;
    for (int m = n - 1; m >= 1000; m /= 10)
        digits++;
    char num[16];
    int w = snprintf(num, sizeof num, "%d", k);
    size_t pad = w > 0 && (size_t)w < digits ? digits - (size_t)w : 0, i = 0;
    for (; i < pad && i + 1 < len; i++)
        buf[i] = '0';
    snprintf(buf + i, len - i, "%s", num);
}

int crom_samples_write(hid_t loc, const crom_samples *s)
{
    int rc = crom_h5_set_str(loc, ".", "mode", s->mode);
    if (!rc)
        rc = crom_h5_set_i64(loc, ".", "points_per_frame", s->N);
    if (!rc)
        rc = crom_h5_set_i64(loc, ".", "seed", s->seed);
    hsize_t d3[3] = {(hsize_t)s->F, (hsize_t)s->N, 3}, d1 = (hsize_t)s->F;
    if (!rc)
        rc = crom_h5_put_f32(loc, "points", 3, d3, s->X);
    if (!rc)
        rc = crom_h5_put_f32(loc, "displacements", 3, d3, s->U);
    if (!rc)
        rc = crom_h5_put_i32(loc, "vertex", 2, d3, s->vertex);
    if (!rc)
        rc = crom_h5_put_i32(loc, "frame_source", 1, &d1, s->source);
    if (!rc)
        rc = crom_h5_put_f64(loc, "frame_time", 1, &d1, s->time);
    hid_t g = rc ? -1 : crom_h5_group(loc, "sources");
    if (!rc && g < 0)
        rc = CROM_EINTERNAL;
    for (int k = 0; !rc && k < s->nsources; k++) {
        char name[32];
        source_name(k, s->nsources, name, sizeof name);
        hid_t sg = crom_h5_group(g, name);
        if (sg < 0) {
            rc = CROM_EINTERNAL;
            break;
        }
        const crom_mesh *m = &s->src[k];
        hsize_t dv[2] = {(hsize_t)m->nv, 3}, dt[2] = {(hsize_t)m->nt, 4}, dtri[2] = {(hsize_t)m->ntri, 3};
        rc = crom_h5_put_f64(sg, "vertices", 2, dv, m->X);
        if (!rc && crom_mesh_is_surface(m)) { /* a shell: its triangles and thickness */
            rc = crom_h5_put_i32(sg, "triangles", 2, dtri, m->tris);
            if (!rc)
                rc = crom_h5_set_f64(sg, "triangles", "thickness", &m->thickness, 1);
        } else if (!rc) {
            rc = crom_h5_put_i32(sg, "tets", 2, dt, m->tets);
        }
        if (!rc)
            rc = crom_h5_set_str(sg, ".", "file", s->src_file && s->src_file[k] ? s->src_file[k] : "");
        H5Gclose(sg);
    }
    if (g >= 0)
        H5Gclose(g);
    return rc;
}


/* Read a mesh stored as vertices + tets (or a shell's triangles) under
 * group g (no regions needed). */
static int read_source(hid_t g, const char *name, crom_mesh *m)
{
    hid_t sg = H5Gopen2(g, name, H5P_DEFAULT);
    if (sg < 0)
        return crom_err(CROM_EDATA, "/sources/%s is not a group", name);
    int rc = crom_mesh_read_any(sg, m);
    H5Gclose(sg);
    return rc ? crom_err_ctx("/sources/%s", name) : 0;
}

/* The file's attributes: mode, points_per_frame into *N, seed. */
static int read_header(crom_in *in, crom_samples *s, long long *N)
{
    hid_t h = in->h5;
    char *mode = NULL;
    if (crom_h5_get_str(h, ".", "mode", &mode) || crom_h5_get_i64(h, ".", "points_per_frame", N) ||
        crom_h5_get_i64(h, ".", "seed", &s->seed)) {
        free(mode);
        return crom_err(CROM_EDATA, "%s: %s", in->name, crom_errmsg());
    }
    snprintf(s->mode, sizeof s->mode, "%s", mode);
    free(mode);
    if (strcmp(s->mode, "vertices") && strcmp(s->mode, "interior"))
        return crom_err(CROM_EDATA, "%s: unknown sample mode '%s' (vertices or interior)", in->name, s->mode);
    return 0;
}

/* The per-frame datasets, their shapes checked against [F, N, 3] (N as
 * points_per_frame says). */
static int read_frames(crom_in *in, crom_samples *s, long long N)
{
    hid_t h = in->h5;
    hsize_t d[4], d2[4];
    int rc;
    if (crom_h5_read_f32(h, "points", 3, d, &s->X) || crom_h5_read_f32(h, "displacements", 3, d2, &s->U))
        return crom_err(CROM_EDATA, "%s: %s", in->name, crom_errmsg());
    if (d[2] != 3 || d2[0] != d[0] || d2[1] != d[1] || d2[2] != 3 || d[0] > 0x7fffffff ||
        d[1] > 0x7fffffff)
        return crom_err(CROM_EDATA, "%s: points and displacements must both be [F, N, 3]", in->name);
    s->F = (int)d[0];
    s->N = (int)d[1];
    if (N != s->N)
        return crom_err(CROM_EDATA, "%s: points_per_frame is %lld but the datasets hold %d points per frame",
                        in->name, N, s->N);
    if ((rc = crom_h5_read_i32(h, "vertex", 2, d2, &s->vertex)) || (d2[0] != d[0] || d2[1] != d[1]))
        return crom_err(CROM_EDATA, "%s: %s", in->name, rc ? crom_errmsg() : "vertex must be [F, N]");
    if ((rc = crom_h5_read_i32(h, "frame_source", 1, d2, &s->source)) || d2[0] != d[0])
        return crom_err(CROM_EDATA, "%s: %s", in->name, rc ? crom_errmsg() : "frame_source must be [F]");
    if ((rc = crom_h5_read_f64(h, "frame_time", 1, d2, &s->time)) || d2[0] != d[0])
        return crom_err(CROM_EDATA, "%s: %s", in->name, rc ? crom_errmsg() : "frame_time must be [F]");
    return 0;
}

/* The source meshes /sources/000 ... (named by their index) and their
 * 'file' attributes. */
static int read_sources(crom_in *in, crom_samples *s)
{
    hid_t h = in->h5;
    if (!crom_h5_has(h, "sources"))
        return crom_err(CROM_EDATA, "%s: no /sources group", in->name);
    char **names = crom_h5_list(h, "sources");
    hid_t g = H5Gopen2(h, "sources", H5P_DEFAULT);
    if (!names || g < 0) {
        if (g >= 0)
            H5Gclose(g);
        crom_h5_list_free(names);
        return crom_err(CROM_EDATA, "%s: cannot list /sources", in->name);
    }
    int ns = 0;
    while (names[ns])
        ns++;
    s->src = crom_calloc(ns ? (size_t)ns : 1, sizeof(crom_mesh));
    s->src_file = crom_calloc(ns ? (size_t)ns : 1, sizeof(char *));
    int rc = !s->src || !s->src_file ? CROM_EINTERNAL : 0;
    for (int k = 0; !rc && k < ns; k++) {
        char *end;
        long idx = strtol(names[k], &end, 10);
        if (*end || idx != k) {
            rc = crom_err(CROM_EDATA, "%s: source group /sources/%s should be named by its index %d",
                          in->name, names[k], k);
            break;
        }
        if ((rc = read_source(g, names[k], &s->src[k]))) {
            rc = crom_err(CROM_EDATA, "%s: %s", in->name, crom_errmsg());
            break;
        }
        s->nsources = k + 1;
        char path[64];
        snprintf(path, sizeof path, "sources/%s", names[k]);
        if (crom_h5_has_attr(h, path, "file"))
            crom_h5_get_str(h, path, "file", &s->src_file[k]);
        crom_err_clear();
    }
    H5Gclose(g);
    crom_h5_list_free(names);
    return rc;
}

/* Every position and displacement finite. */
static int check_values(const crom_in *in, const crom_samples *s)
{
    size_t n3 = (size_t)s->F * s->N * 3;
    for (size_t i = 0; i < n3; i++) {
        if (!isfinite(s->X[i]))
            return crom_err(CROM_EDATA, "%s: frame %zu sample %zu has a non-finite position", in->name,
                            i / 3 / s->N, i / 3 % s->N);
        if (!isfinite(s->U[i]))
            return crom_err(CROM_EDATA, "%s: frame %zu sample %zu has a non-finite displacement",
                            in->name, i / 3 / s->N, i / 3 % s->N);
    }
    return 0;
}

/* Each frame's time finite and source known; vertex samples must sit
 * where fields are sampled at their vertex (the rest position, or inside
 * its tets along a crack: crom_mesh_field_points). */
static int check_frames(const crom_in *in, const crom_samples *s)
{
    int rc = 0;
    double **fps = crom_calloc((size_t)(s->nsources ? s->nsources : 1), sizeof(double *));
    if (!fps)
        return CROM_EINTERNAL;
    for (int f = 0; !rc && f < s->F; f++) {
        if (!isfinite(s->time[f])) {
            rc = crom_err(CROM_EDATA, "%s: frame %d has a non-finite time", in->name, f);
            break;
        }
        int k = s->source[f];
        if (k < 0 || k >= s->nsources) {
            rc = crom_err(CROM_EDATA, "%s: /frame_source: frame %d names source %d, but there are %d", in->name, f,
                          k, s->nsources);
            break;
        }
        const crom_mesh *m = &s->src[k];
        if (!fps[k] && !(fps[k] = crom_mesh_field_points(m, CROM_MESH_CRACK_OFFSET, NULL))) {
            rc = CROM_EINTERNAL;
            break;
        }
        const double *fp = fps[k];
        double lo[3], hi[3], L = 0;
        crom_mesh_bbox(m, lo, hi);
        for (int c = 0; c < 3; c++)
            L = fmax(L, hi[c] - lo[c]);
        for (int i = 0; !rc && i < s->N; i++) {
            size_t j = (size_t)f * s->N + i;
            int v = s->vertex[j];
            if (v < -1 || v >= m->nv) {
                rc = crom_err(CROM_EDATA, "%s: /vertex: frame %d sample %d names vertex %d of a %d-vertex mesh",
                              in->name, f, i, v, m->nv);
                break;
            }
            for (int c = 0; v >= 0 && c < 3; c++)
                if (fabs(s->X[3 * j + c] - fp[3 * (size_t)v + c]) > 1e-6 * L + 1e-30) {
                    rc = crom_err(CROM_EDATA, "%s: frame %d sample %d is not at the position of its vertex %d",
                                  in->name, f, i, v);
                    break;
                }
        }
    }
    for (int k = 0; k < s->nsources; k++)
        free(fps[k]);
    free(fps);
    return rc;
}

int crom_samples_read(crom_in *in, crom_samples *s)
{
    memset(s, 0, sizeof *s);
    long long N = 0;
    int rc = read_header(in, s, &N);
    if (!rc)
        rc = read_frames(in, s, N);
    if (!rc)
        rc = read_sources(in, s);
    if (!rc)
        rc = check_values(in, s);
    if (!rc)
        rc = check_frames(in, s);
    if (rc) {
        crom_samples_free(s);
        return rc;
    }
    if (in->history)
        s->history = crom_strdup(in->history);
    return 0;
}

/* ------------------------------------------------------------ picking */

int crom_samples_picker_init(crom_samples_picker *p, const crom_mesh *m, int how)
{
    memset(p, 0, sizeof *p);
    p->mesh = m;
    p->how = how;
    p->perm = crom_malloc(sizeof(int) * (size_t)m->nv);
    p->cum = crom_malloc(sizeof(double) * (size_t)m->nt);
    p->fp = crom_mesh_field_points(m, CROM_MESH_CRACK_OFFSET, NULL);
    if (!p->perm || !p->cum || !p->fp) {
        crom_samples_picker_free(p);
        return CROM_EINTERNAL;
    }
    for (int i = 0; i < m->nv; i++)
        p->perm[i] = i;
    double tot = 0;
    for (int t = 0; t < m->nt; t++) {
        const int *v = m->tets + 4 * (size_t)t;
        tot += crom_mesh_tet_volume(m->X + 3 * (size_t)v[0], m->X + 3 * (size_t)v[1], m->X + 3 * (size_t)v[2],
                                    m->X + 3 * (size_t)v[3]);
        p->cum[t] = tot;
    }
    return 0;
}

/* N vertices: distinct random ones, or all in order */
static void pick_vertices(crom_samples_picker *p, int N, const double *u, crom_rng *rng, float *X, float *U,
                          int *vx)
{
    int nv = p->mesh->nv, *perm = p->perm;
    if (p->how == CROM_SAMPLES_ALL) {
        for (int i = 0; i < N; i++)
            perm[i] = i;
    } else {
        for (int i = 0; i < N; i++) {
            int j = i + (int)crom_rng_below(rng, (uint64_t)(nv - i));
            int tmp = perm[i];
            perm[i] = perm[j];
            perm[j] = tmp;
        }
    }
    for (int i = 0; i < N; i++) {
        int v = perm[i];
        vx[i] = v;
        for (int d = 0; d < 3; d++) {
            X[3 * i + d] = (float)p->fp[3 * (size_t)v + d]; /* see crom_mesh_field_points */
            U[3 * i + d] = (float)u[3 * (size_t)v + d];
        }
    }
}

/* N points uniform by volume */
static void pick_interior(crom_samples_picker *p, int N, const double *u, crom_rng *rng, float *X, float *U,
                          int *vx)
{
    const crom_mesh *m = p->mesh;
    double tot = m->nt ? p->cum[m->nt - 1] : 0;
    for (int i = 0; i < N; i++) {
        /* a tet with probability proportional to its volume */
        double target = crom_rng_uniform(rng) * tot;
        int lo = 0, hi = m->nt - 1;
        while (lo < hi) {
            int mid = (lo + hi) / 2;
            if (p->cum[mid] > target)
                hi = mid;
            else
                lo = mid + 1;
        }
        /* uniform in the tet: Dirichlet(1,1,1,1) barycentric weights */
        double b[4], sb = 0;
        for (int j = 0; j < 4; j++) {
            b[j] = -log(1.0 - crom_rng_uniform(rng));
            sb += b[j];
        }
        const int *tv = m->tets + 4 * (size_t)lo;
        double x[3] = {0, 0, 0}, uu[3] = {0, 0, 0};
        for (int j = 0; j < 4; j++) {
            double w = b[j] / sb;
            for (int d = 0; d < 3; d++) {
                x[d] += w * m->X[3 * (size_t)tv[j] + d];
                uu[d] += w * u[3 * (size_t)tv[j] + d];
            }
        }
        vx[i] = -1;
        for (int d = 0; d < 3; d++) {
            X[3 * i + d] = (float)x[d];
            U[3 * i + d] = (float)uu[d];
        }
    }
}

void crom_samples_pick(crom_samples_picker *p, int N, const double *u, crom_rng *rng, float *X, float *U,
                       int *vertex)
{
    if (p->how == CROM_SAMPLES_INTERIOR)
        pick_interior(p, N, u, rng, X, U, vertex);
    else
        pick_vertices(p, N, u, rng, X, U, vertex);
}

void crom_samples_picker_free(crom_samples_picker *p)
{
    free(p->fp);
    free(p->perm);
    free(p->cum);
    memset(p, 0, sizeof *p);
}

int crom_samples_add_frame(crom_samples *s, crom_samples_picker *p, const double *u, crom_rng *rng,
                           int source, double t)
{
    size_t need = (size_t)s->F + 1, n = (size_t)s->N;
    size_t cap[5] = {s->cap, s->cap, s->cap, s->cap, s->cap};
    int rc;
    if ((rc = crom_array_reserve((void **)&s->X, &cap[0], need, 3 * n * sizeof *s->X)) ||
        (rc = crom_array_reserve((void **)&s->U, &cap[1], need, 3 * n * sizeof *s->U)) ||
        (rc = crom_array_reserve((void **)&s->vertex, &cap[2], need, n * sizeof *s->vertex)) ||
        (rc = crom_array_reserve((void **)&s->source, &cap[3], need, sizeof *s->source)) ||
        (rc = crom_array_reserve((void **)&s->time, &cap[4], need, sizeof *s->time)))
        return crom_err_ctx("%zu frames of %zu samples", need, n);
    s->cap = cap[0]; /* the same for all five */
    size_t base = (size_t)s->F * n;
    crom_samples_pick(p, s->N, u, rng, s->X + 3 * base, s->U + 3 * base, s->vertex + base);
    s->source[s->F] = source;
    s->time[s->F] = t;
    s->F++;
    return 0;
}
