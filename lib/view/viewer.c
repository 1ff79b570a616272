/* viewer.c — the surface and frame messages of crom-view and the check of
 * a page's commands (see viewer.h). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "view/export.h"
#include "view/viewer.h"

int crom_viewer_surface_init(crom_viewer_surface *s, const crom_cubature *c)
{
    memset(s, 0, sizeof *s);
    if (c->map_rank > 0)
        return crom_err(CROM_EUSAGE, "a cubature of a nonlinear map (model %s): the viewer decodes linear subspaces "
                        "only, as crom-live runs them", c->model_id);
    if (crom_mesh_is_scene(&c->mesh))
        return crom_err(CROM_EUSAGE, "a rigid-body scene has no surface to draw");
    int nt = 0, ns = 0, *T = NULL, *sv = NULL, *map = NULL;
    int rc = crom_export_surface_compact(&c->mesh, &nt, &T, &ns, &sv, &map);
    if (rc)
        return rc;
    int r = c->r;
    s->r = r;
    s->ns = ns;
    s->nt = nt;
    s->vid = sv;
    sv = NULL;
    s->X = crom_malloc(sizeof *s->X * 3 * (size_t)(ns ? ns : 1));
    s->W = crom_malloc(sizeof *s->W * 3 * (size_t)r * (size_t)(ns ? ns : 1));
    s->tri = crom_malloc(sizeof *s->tri * 3 * (size_t)(nt ? nt : 1));
    if (!s->X || !s->W || !s->tri) {
        free(T);
        free(map);
        crom_viewer_surface_free(s);
        return CROM_EINTERNAL;
    }
    for (int d = 0; d < 3; d++) {
        s->lo[d] = ns ? 1e300 : 0;
        s->hi[d] = ns ? -1e300 : 0;
    }
    for (int i = 0; i < ns; i++) {
        const double *X = c->mesh.X + 3 * (size_t)s->vid[i];
        const double *W = c->W + 3 * (size_t)r * (size_t)s->vid[i];
        for (int d = 0; d < 3; d++) {
            s->X[3 * i + d] = (float)X[d];
            s->lo[d] = X[d] < s->lo[d] ? X[d] : s->lo[d];
            s->hi[d] = X[d] > s->hi[d] ? X[d] : s->hi[d];
        }
        for (int k = 0; k < 3 * r; k++)
            s->W[3 * (size_t)r * i + k] = (float)W[k];
    }
    for (int k = 0; k < 3 * nt; k++)
        s->tri[k] = (uint32_t)map[T[k]];
    free(T);
    free(map);
    return 0;
}

void crom_viewer_surface_free(crom_viewer_surface *s)
{
    free(s->vid);
    free(s->X);
    free(s->W);
    free(s->tri);
    memset(s, 0, sizeof *s);
}

void crom_viewer_decode(const crom_viewer_surface *s, const double *q, double *x)
{
    int r = s->r;
    for (int i = 0; i < s->ns; i++)
        for (int d = 0; d < 3; d++) {
            const float *w = s->W + (size_t)r * (3 * (size_t)i + d);
            double v = s->X[3 * i + d];
            for (int k = 0; k < r; k++)
                v += (double)w[k] * q[k];
            x[3 * i + d] = v;
        }
}

/* little-endian stores, whatever the host's order */
static unsigned char *put_u32(unsigned char *p, uint32_t v)
{
    for (int b = 0; b < 4; b++)
        p[b] = (unsigned char)(v >> (8 * b));
    return p + 4;
}

static unsigned char *put_f32(unsigned char *p, float f)
{
    uint32_t v;
    memcpy(&v, &f, 4);
    return put_u32(p, v);
}

static unsigned char *put_f64(unsigned char *p, double f)
{
    uint64_t v;
    memcpy(&v, &f, 8);
    for (int b = 0; b < 8; b++)
        p[b] = (unsigned char)(v >> (8 * b));
    return p + 8;
}

int crom_viewer_surface_msg(const crom_viewer_surface *s, int index, size_t pre, unsigned char **buf, size_t *len)
{
    size_t ns = (size_t)s->ns, nt = (size_t)s->nt, r = (size_t)s->r;
    size_t n = 4 + 4 * 4 + 6 * 4 + 4 * (3 * ns + 3 * r * ns + 3 * nt + ns);
    unsigned char *b = crom_malloc(pre + n), *p;
    if (!b)
        return CROM_EINTERNAL;
    p = b + pre;
    memcpy(p, "SURF", 4);
    p = put_u32(p + 4, (uint32_t)index);
    p = put_u32(p, (uint32_t)ns);
    p = put_u32(p, (uint32_t)nt);
    p = put_u32(p, (uint32_t)r);
    for (int d = 0; d < 3; d++)
        p = put_f32(p, (float)s->lo[d]);
    for (int d = 0; d < 3; d++)
        p = put_f32(p, (float)s->hi[d]);
    for (size_t i = 0; i < 3 * ns; i++)
        p = put_f32(p, s->X[i]);
    for (size_t i = 0; i < 3 * r * ns; i++)
        p = put_f32(p, s->W[i]);
    for (size_t i = 0; i < 3 * nt; i++)
        p = put_u32(p, s->tri[i]);
    for (size_t i = 0; i < ns; i++)
        p = put_u32(p, (uint32_t)s->vid[i]);
    *buf = b;
    *len = n;
    return 0;
}

size_t crom_viewer_frame_size(int r) { return 48 + 8 * (size_t)r; }

size_t crom_viewer_frame_msg(unsigned char *buf, int r, const crom_viewer_frame *f)
{
    unsigned char *p = buf;
    memcpy(p, "FRAM", 4);
    p = put_u32(p + 4, (uint32_t)r);
    p = put_u32(p, (uint32_t)f->cubature);
    p = put_u32(p, (uint32_t)f->late);
    p = put_f64(p, f->step);
    p = put_f64(p, f->time);
    p = put_f64(p, f->wall_time);
    for (int k = 0; k < r; k++)
        p = put_f64(p, f->q[k]);
    p = put_f64(p, f->commands);
    return (size_t)(p - buf);
}

int crom_viewer_check(const crom_mesh *m, const char *line, const char *const *offered, int noffered,
                      crom_live_cmd *c, char *out, size_t cap)
{
    out[0] = 0;
    int rc = crom_live_parse(line, c);
    if (rc || c->kind == CROM_LIVE_NONE)
        return rc;
    const char *v = NULL; /* the command's name, for messages */
    switch (c->kind) {
    case CROM_LIVE_STEP: v = "step"; break;
    case CROM_LIVE_QUIT: v = "quit"; break;
    default: break;
    }
    if (v)
        return crom_err(CROM_EUSAGE, "%s: the run's command, not a viewer's", v);
    if (c->kind == CROM_LIVE_SCHEDULE) {
        int ok = 0;
        for (int i = 0; i < noffered && !ok; i++)
            ok = !strcmp(offered[i], c->ref);
        if (!ok)
            return crom_err(CROM_EUSAGE, "schedule %s: not a cubature this viewer offers (crom-view --offer)", c->ref);
    }
    int has_ref = c->kind == CROM_LIVE_DRAG || c->kind == CROM_LIVE_FORCE || c->kind == CROM_LIVE_PIN ||
                  c->kind == CROM_LIVE_UNPIN || (c->kind == CROM_LIVE_RELEASE && c->ref[0]);
    if (has_ref) {
        int *idx = NULL, n = 0;
        rc = crom_mesh_select(m, c->ref, &idx, &n);
        free(idx);
        if (rc)
            return rc;
    }
    int k;
    char x[4][32];
    for (int i = 0; i < 3; i++)
        crom_export_number(x[i], sizeof x[i], c->v[i]); /* (the shortest that reads back as the same number) */
    crom_export_number(x[3], sizeof x[3], c->k);
    switch (c->kind) {
    case CROM_LIVE_DRAG:
        k = snprintf(out, cap, "drag %s %s,%s,%s%s%s", c->ref, x[0], x[1], x[2], c->k > 0 ? " " : "", c->k > 0 ? x[3] : "");
        break;
    case CROM_LIVE_FORCE: k = snprintf(out, cap, "force %s %s,%s,%s", c->ref, x[0], x[1], x[2]); break;
    case CROM_LIVE_RELEASE: k = snprintf(out, cap, "release%s%s", c->ref[0] ? " " : "", c->ref); break;
    case CROM_LIVE_PIN: k = snprintf(out, cap, "pin %s", c->ref); break;
    case CROM_LIVE_UNPIN: k = snprintf(out, cap, "unpin %s", c->ref); break;
    case CROM_LIVE_SCHEDULE: k = snprintf(out, cap, "schedule %s", c->ref); break;
    case CROM_LIVE_CONDITION: k = snprintf(out, cap, "condition %s", c->ref); break;
    default: return crom_err(CROM_EINTERNAL, "unhandled command");
    }
    if (k < 0 || (size_t)k >= cap)
        return crom_err(CROM_EUSAGE, "command too long");
    return 0;
}

/* s as a JSON string at b + n (quotes included); returns the new length,
 * or cap when it does not fit */
static size_t json_str(char *b, size_t n, size_t cap, const char *s)
{
    if (n + 2 >= cap)
        return cap;
    b[n++] = '"';
    for (; *s; s++) {
        unsigned char ch = (unsigned char)*s;
        if (n + 8 >= cap)
            return cap;
        if (ch == '"' || ch == '\\') {
            b[n++] = '\\';
            b[n++] = (char)ch;
        } else if (ch < 0x20)
            n += (size_t)snprintf(b + n, cap - n, "\\u%04x", ch);
        else
            b[n++] = (char)ch;
    }
    b[n++] = '"';
    b[n] = 0;
    return n;
}

int crom_viewer_hello(char *buf, size_t cap, const char *cub, const char *model_id, int r, int nv,
                      const char *const *offers, int noffers)
{
    size_t n = (size_t)snprintf(buf, cap, "{\"cubature\":");
    n = json_str(buf, n, cap, cub);
    if (n < cap)
        n += (size_t)snprintf(buf + n, cap - n, ",\"model\":");
    if (n < cap)
        n = json_str(buf, n, cap, model_id);
    if (n < cap)
        n += (size_t)snprintf(buf + n, cap - n, ",\"rank\":%d,\"vertices\":%d,\"offers\":[", r, nv);
    for (int i = 0; i < noffers && n < cap; i++) {
        if (i && n + 1 < cap)
            buf[n++] = ',';
        n = json_str(buf, n, cap, offers[i]);
    }
    if (n < cap)
        n += (size_t)snprintf(buf + n, cap - n, "]}");
    if (n >= cap)
        return crom_err(CROM_EUSAGE, "the cubatures' paths are too long for the page's greeting");
    return 0;
}

void crom_viewer_switches_init(crom_viewer_switches *w)
{
    memset(w, 0, sizeof *w);
    w->nas = 1; /* the stream's cubature 0 is the first offer */
}

int crom_viewer_switch_passed(crom_viewer_switches *w, int o, long seq)
{
    if (w->npend == CROM_VIEWER_SWITCHES)
        return crom_err(CROM_EUSAGE, "too many switches under way");
    w->pend[w->npend] = o;
    w->pend_seq[w->npend++] = seq;
    return 0;
}

static void pop(crom_viewer_switches *w)
{
    w->npend--;
    memmove(w->pend, w->pend + 1, sizeof *w->pend * (size_t)w->npend);
    memmove(w->pend_seq, w->pend_seq + 1, sizeof *w->pend_seq * (size_t)w->npend);
}

int crom_viewer_switch_frame(crom_viewer_switches *w, int k, long seq, int *refused, int *nrefused)
{
    *nrefused = 0;
    int cap = (int)(sizeof w->as / sizeof *w->as);
    while (k >= w->nas && w->npend && w->nas < cap) { /* a switch the run took */
        w->as[w->nas++] = w->pend[0];
        pop(w);
    }
    while (w->npend && seq > w->pend_seq[0] + CROM_VIEWER_SWITCH_FRAMES) { /* one it refused */
        refused[(*nrefused)++] = w->pend[0];
        pop(w);
    }
    return k >= 0 && k < w->nas ? w->as[k] : -1;
}

void crom_viewer_drags_note(crom_viewer_drags *d, const crom_live_cmd *c)
{
    int i = 0;
    while (i < d->n && strcmp(d->ref[i], c->ref))
        i++;
    if (c->kind == CROM_LIVE_DRAG && i == d->n && d->n < 8)
        snprintf(d->ref[d->n++], sizeof d->ref[0], "%s", c->ref);
    else if (c->kind == CROM_LIVE_RELEASE && !c->ref[0])
        d->n = 0;
    else if (c->kind == CROM_LIVE_RELEASE && i < d->n) {
        d->n--;
        memmove(d->ref[i], d->ref[i + 1], sizeof d->ref[0] * (size_t)(d->n - i));
    }
}

int crom_viewer_stream_open(crom_in *in, const char *cub, const char *model_id, int r, int *fq, int *fld)
{
    int rc = crom_in_open(in, NULL);
    if (rc)
        return rc;
    rc = crom_in_expect(in, "crom/latent", 1);
    char *id = NULL;
    if (!rc && (rc = crom_h5_get_str(in->h5, ".", "model_id", &id)) == 0 && strcmp(id, model_id))
        rc = crom_err(CROM_EDATA, "stdin: a run of model %s, %s is of model %s", id, cub, model_id);
    free(id);
    if (!rc && in->form != CROM_IO_STREAM)
        rc = crom_err(CROM_EUSAGE, "stdin: an HDF5 file; crom-view shows a live run's frame stream (crom-live | crom-view)");
    if (!rc && (*fq = crom_in_field(in, "q")) < 0)
        rc = CROM_EDATA;
    if (!rc && in->fields[*fq].count != (size_t)r)
        rc = crom_err(CROM_EDATA, "stdin: q has %zu numbers, the model's rank is %d", in->fields[*fq].count, r);
    static const char *const names[CROM_VIEWER_NFIELDS] = {"time", "step", "wall_time", "late", "cubature", "commands"};
    for (int i = 0; !rc && i < CROM_VIEWER_NFIELDS; i++) {
        fld[i] = crom_in_field(in, names[i]);
        crom_err_clear(); /* (all but time may be absent) */
    }
    if (!rc && fld[0] < 0)
        rc = crom_err(CROM_EDATA, "stdin: frames without time");
    if (rc)
        crom_in_close(in);
    return rc;
}
