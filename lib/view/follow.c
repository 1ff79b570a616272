/* follow.c — a result read on the mesh each frame lives on (see follow.h). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/array.h"
#include "base/err.h"
#include "view/export.h"
#include "view/follow.h"

void crom_follow_close(crom_follow *s)
{
    for (int i = 0; i < s->n; i++) {
        crom_result_close(&s->res[i]);
        if (s->u)
            free(s->u[i]);
        if (s->v)
            free(s->v[i]);
    }
    free(s->res);
    free(s->u);
    free(s->v);
    memset(s, 0, sizeof *s);
}

/* The cubature files of a latent's schedule: its 'cubatures' attribute, one
 * "STEP PATH" line per entry (entry 0 the initial --cubature). */
static int schedule_paths(crom_in *in, char ***paths, int *n)
{
    *paths = NULL;
    *n = 0;
    if (in->h5 < 0 || !crom_h5_has_attr(in->h5, ".", "cubatures"))
        return 0;
    char *txt = NULL;
    if (crom_h5_get_str(in->h5, ".", "cubatures", &txt))
        return crom_err_ctx("%s", in->name);
    int cap = 1;
    for (const char *p = txt; *p; p++)
        cap += *p == '\n';
    char **list = crom_calloc((size_t)cap, sizeof(char *));
    if (!list) {
        free(txt);
        return CROM_EINTERNAL;
    }
    int k = 0, rc = 0;
    char *save = NULL;
    for (char *line = strtok_r(txt, "\n", &save); line && !rc; line = strtok_r(NULL, "\n", &save)) {
        long step;
        int pos = 0;
        if (sscanf(line, "%ld %n", &step, &pos) != 1 || !line[pos]) {
            rc = crom_err(CROM_EDATA, "%s: bad 'cubatures' entry '%s'", in->name, line);
            break;
        }
        if (!(list[k++] = crom_strdup(line + pos)))
            rc = CROM_EINTERNAL;
    }
    free(txt);
    if (rc) {
        for (int i = 0; i < k; i++)
            free(list[i]);
        free(list);
        return rc;
    }
    *paths = list;
    *n = k;
    return 0;
}

int crom_follow_adopt(crom_follow *s, crom_in *opened, const char *path, const char *mesh,
                      const char *model, int follow)
{
    memset(s, 0, sizeof *s);
    s->fcub = -1;
    char **paths = NULL;
    int np = 0, rc = 0;
    follow = follow && !strcmp(opened->schema, "crom/latent");
    if (follow && (rc = schedule_paths(opened, &paths, &np))) {
        crom_in_close(opened);
        return rc;
    }
    if (follow && np > 1 && (!path || !strcmp(path, "-"))) {
        crom_in_close(opened);
        rc = crom_err(CROM_EUSAGE, "--follow-schedule reads the latent once per mesh: give it as a file, not stdin");
        goto out;
    }
    s->n = np > 1 ? np : 1;
    s->res = crom_calloc((size_t)s->n, sizeof(crom_result));
    s->u = crom_calloc((size_t)s->n, sizeof(double *));
    s->v = crom_calloc((size_t)s->n, sizeof(double *));
    if (!s->res || !s->u || !s->v) {
        crom_in_close(opened);
        s->n = 0;
        crom_follow_close(s);
        rc = CROM_EINTERNAL;
        goto out;
    }
    const char *mesh0 = mesh ? mesh : (np > 0 ? paths[0] : NULL);
    int opened_n = 0;
    rc = crom_result_adopt(&s->res[0], opened, mesh0, model);
    if (!rc)
        opened_n = 1;
    for (int i = 1; i < s->n && !rc; i++) {
        if (!(rc = crom_result_open(&s->res[i], path, paths[i], model)))
            opened_n = i + 1;
        else
            crom_err_ctx("schedule entry %d", i);
    }
    if (!rc && s->n > 1) {
        s->fcub = crom_in_field(&s->res[0].in, "cubature");
        if (s->fcub < 0)
            rc = crom_err(CROM_EDATA, "%s has a schedule but no per-frame 'cubature' field", s->res[0].in.name);
    }
    for (int i = 0; i < s->n && !rc; i++) {
        size_t n3 = 3 * (size_t)s->res[i].mesh.nv;
        s->u[i] = crom_malloc(sizeof(double) * (n3 ? n3 : 1));
        s->v[i] = crom_malloc(sizeof(double) * (n3 ? n3 : 1));
        if (!s->u[i] || !s->v[i])
            rc = CROM_EINTERNAL;
        if (s->res[i].mesh.nv > s->maxnv)
            s->maxnv = s->res[i].mesh.nv;
    }
    if (rc) {
        int n = s->n;
        s->n = opened_n; /* close only what was opened */
        for (int i = opened_n; i < n; i++) {
            free(s->u[i]);
            free(s->v[i]);
        }
        crom_follow_close(s);
    }
out:
    for (int i = 0; i < np; i++)
        free(paths[i]);
    free(paths);
    return rc;
}

int crom_follow_next(crom_follow *s, double *t)
{
    int rc = 0;
    for (int i = 0; i < s->n; i++) {
        double ti;
        int r = crom_result_next(&s->res[i], &ti, s->u[i], s->v[i]);
        if (i == 0) {
            rc = r;
            *t = ti;
        } else if (r != rc) {
            return r > 1 ? r : crom_err(CROM_EDATA, "%s changed while it was read", s->res[0].in.name);
        }
    }
    s->cur = 0;
    if (rc == 1 && s->n > 1) {
        double c = crom_in_get(&s->res[0].in, s->fcub)[0];
        if (!(c >= 0 && c < s->n))
            return crom_err(CROM_EDATA, "%s: a frame uses schedule entry %g of %d", s->res[0].in.name, c, s->n);
        s->cur = (int)c;
    }
    return rc;
}

int crom_follow_pick(crom_follow *s, long frame, int *mi, double *t, double *u, double *v, long *nframes)
{
    size_t maxn3 = 3 * (size_t)(s->maxnv ? s->maxnv : 1);
    /* negative: keep the last -frame frames in a ring */
    long keep = frame < 0 ? -frame : 1, nread = 0;
    double *ring = crom_malloc(sizeof(double) * 2 * maxn3 * (size_t)keep);
    double *ring_t = crom_malloc(sizeof(double) * (size_t)keep);
    int *ring_mi = crom_malloc(sizeof(int) * (size_t)keep);
    int r = 0, rc = 0;
    double ti;
    if (!ring || !ring_t || !ring_mi)
        rc = CROM_EINTERNAL;
    while (!rc && (r = crom_follow_next(s, &ti)) == 1) {
        long slot = frame >= 0 ? 0 : nread % keep;
        if (frame < 0 || nread == frame) {
            size_t n3 = 3 * (size_t)s->res[s->cur].mesh.nv;
            memcpy(ring + (size_t)slot * 2 * maxn3, s->u[s->cur], sizeof(double) * n3);
            memcpy(ring + (size_t)slot * 2 * maxn3 + maxn3, s->v[s->cur], sizeof(double) * n3);
            ring_mi[slot] = s->cur;
            ring_t[slot] = ti;
        }
        nread++;
    }
    if (!rc && r > 1)
        rc = r;
    *nframes = nread;
    if (!rc && ((frame >= 0 && frame >= nread) || (frame < 0 && -frame > nread)))
        rc = crom_err(CROM_EUSAGE, "--frame %ld: %s has %ld frames", frame, s->res[0].in.name, nread);
    if (!rc) {
        long slot = frame >= 0 ? 0 : (nread + frame) % keep;
        const double *w = ring + (size_t)slot * 2 * maxn3;
        *mi = ring_mi[slot];
        *t = ring_t[slot];
        size_t n3 = 3 * (size_t)s->res[*mi].mesh.nv;
        memcpy(u, w, sizeof(double) * n3);
        memcpy(v, w + maxn3, sizeof(double) * n3);
    }
    free(ring);
    free(ring_t);
    free(ring_mi);
    return rc;
}

size_t crom_follow_outside(const crom_follow *s, int i) { return s->res[i].outside; }

/* ------------------------------------------------ a whole result in memory */

void crom_follow_frames_free(crom_follow_frames *r)
{
    for (int i = 0; i < r->src.n; i++)
        if (r->tris)
            free(r->tris[i]);
    crom_follow_close(&r->src);
    free(r->t);
    free(r->u);
    free(r->off);
    free(r->mi);
    free(r->ntri);
    free(r->tris);
    memset(r, 0, sizeof *r);
}

const crom_mesh *crom_follow_frame_mesh(const crom_follow_frames *r, int f)
{
    return &r->src.res[r->mi[f]].mesh;
}

/* room for one more frame of n3 doubles (cap: the arrays' capacities) */
static int grow(crom_follow_frames *r, size_t cap[4], size_t used, size_t n3)
{
    size_t nf = (size_t)r->nf + 1;
    int rc;
    if ((rc = crom_array_reserve((void **)&r->t, &cap[0], nf, sizeof *r->t)) ||
        (rc = crom_array_reserve((void **)&r->off, &cap[1], nf, sizeof *r->off)) ||
        (rc = crom_array_reserve((void **)&r->mi, &cap[2], nf, sizeof *r->mi)))
        return rc;
    return crom_array_reserve((void **)&r->u, &cap[3], used + n3, sizeof *r->u);
}

int crom_follow_load(crom_follow_frames *r, crom_follow *src, int every)
{
    memset(r, 0, sizeof *r);
    r->src = *src;
    memset(src, 0, sizeof *src);
    size_t cap[4] = {0}, used = 0;
    r->ntri = crom_calloc((size_t)r->src.n, sizeof(int));
    r->tris = crom_calloc((size_t)r->src.n, sizeof(int *));
    if (!r->ntri || !r->tris)
        return CROM_EINTERNAL;
    int rc;
    double t;
    long k = 0;
    while ((rc = crom_follow_next(&r->src, &t)) == 1) {
        if (k++ % every)
            continue;
        size_t n3 = 3 * (size_t)r->src.res[r->src.cur].mesh.nv;
        if ((rc = grow(r, cap, used, n3)))
            return rc;
        memcpy(r->u + used, r->src.u[r->src.cur], sizeof(double) * n3);
        r->t[r->nf] = t;
        r->off[r->nf] = used;
        r->mi[r->nf] = r->src.cur;
        r->nf++;
        used += n3;
    }
    if (rc)
        return rc;
    if (r->nf == 0)
        return crom_err(CROM_EDATA, "%s has no frames", r->src.res[0].in.name);
    for (int i = 0; i < r->src.n; i++)
        if ((rc = crom_export_surface(&r->src.res[i].mesh, &r->ntri[i], &r->tris[i])))
            return rc;
    return 0;
}

void crom_follow_bounds(const crom_follow_frames *rows, int nrows, double lo[3], double hi[3], double *umax)
{
    double m = 0;
    for (int c = 0; c < 3; c++) {
        lo[c] = INFINITY;
        hi[c] = -INFINITY;
    }
    for (int r = 0; r < nrows; r++) {
        for (int f = -1; f < rows[r].nf; f++) {
            const crom_mesh *mesh = f < 0 ? &rows[r].src.res[0].mesh : crom_follow_frame_mesh(&rows[r], f);
            const double *u = f < 0 ? NULL : rows[r].u + rows[r].off[f];
            for (int i = 0; i < mesh->nv; i++) {
                double d2 = 0;
                for (int c = 0; c < 3; c++) {
                    double d = u ? u[3 * i + c] : 0;
                    double x = mesh->X[3 * i + c] + d;
                    lo[c] = fmin(lo[c], x);
                    hi[c] = fmax(hi[c], x);
                    d2 += d * d;
                }
                m = fmax(m, sqrt(d2));
            }
        }
    }
    *umax = m;
}

int crom_follow_load_path(crom_follow_frames *r, const char *path, const char *mesh, const char *model, int follow,
                          int every)
{
    crom_in in;
    crom_follow s;
    int rc;
    memset(r, 0, sizeof *r);
    if ((rc = crom_in_open(&in, path)) ||
        (rc = crom_follow_adopt(&s, &in, path, strcmp(in.schema, "crom/latent") ? NULL : mesh, model, follow)))
        return rc;
    return crom_follow_load(r, &s, every);
}
