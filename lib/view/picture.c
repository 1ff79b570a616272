/* picture.c — pictures and strips of followed results (see picture.h). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "base/err.h"
#include "view/export.h"
#include "view/picture.h"

enum { HEAD = 34 }; /* pixels under the panels for the colour bar */

void crom_picture_view(const crom_follow_frames *rows, int nrows, int pw, int ph, double range,
                       crom_render_camera *cam, double *umax)
{
    double lo[3], hi[3], m;
    crom_follow_bounds(rows, nrows, lo, hi, &m);
    crom_render_camera_fit(cam, lo, hi, pw, ph, 1.12);
    *umax = range > 0 ? range : (m > 0 ? m : 1);
}

/* scratch of crom_render_panel for the largest mesh of the rows */
static double *panel_work(const crom_follow_frames *rows, int nrows)
{
    int maxnv = 0;
    for (int i = 0; i < nrows; i++)
        maxnv = rows[i].src.maxnv > maxnv ? rows[i].src.maxnv : maxnv;
    return crom_malloc(sizeof(double) * 4 * (size_t)(maxnv ? maxnv : 1));
}

static void draw(crom_image *im, const crom_render_camera *cam, int x0, int y0, int pw, int ph, const crom_follow_frames *r,
                 int f, double umax, const char *label, double *work)
{
    const crom_mesh *m = crom_follow_frame_mesh(r, f);
    crom_render_panel(im, cam, x0, y0, pw, ph, m->nv, m->X, r->u + r->off[f], r->ntri[r->mi[f]], r->tris[r->mi[f]],
                      umax, label, work);
}

int crom_picture_frame(crom_image *im, const crom_render_camera *cam, const crom_follow_frames *r, int f, int pw, int ph,
                       double umax)
{
    double *work = panel_work(r, 1);
    if (!work || crom_image_init(im, pw, ph + HEAD)) {
        free(work);
        return CROM_EINTERNAL;
    }
    char label[64];
    snprintf(label, sizeof label, "t=%.3f s", r->t[f]);
    draw(im, cam, 0, 0, pw, ph, r, f, umax, label, work);
    crom_render_colorbar(im, 10, ph + 2, pw - 20, 10, 0, umax, "m");
    free(work);
    return 0;
}

int crom_picture_strip(crom_image *im, const crom_follow_frames *rows, const char *const *labels, int nrows,
                       int columns, int pw, int ph, double range, int *ncols)
{
    int K = columns < rows[0].nf ? columns : rows[0].nf;
    crom_render_camera cam;
    double umax;
    crom_picture_view(rows, nrows, pw, ph, range, &cam, &umax);
    double *work = panel_work(rows, nrows);
    if (!work || crom_image_init(im, K * pw, nrows * ph + HEAD)) {
        free(work);
        return CROM_EINTERNAL;
    }
    for (int c = 0; c < K; c++) {
        int f0 = K == 1 ? rows[0].nf - 1 : (int)((double)c * (rows[0].nf - 1) / (K - 1) + 0.5);
        double t = rows[0].t[f0];
        for (int r = 0; r < nrows; r++) {
            int best = 0; /* the frame nearest in time */
            for (int f = 1; f < rows[r].nf; f++)
                if (fabs(rows[r].t[f] - t) < fabs(rows[r].t[best] - t))
                    best = f;
            char label[160];
            if (c == 0)
                snprintf(label, sizeof label, "%.40s  t=%.3f", labels[r], rows[r].t[best]);
            else
                snprintf(label, sizeof label, "t=%.3f", rows[r].t[best]);
            draw(im, &cam, c * pw, r * ph, pw, ph, &rows[r], best, umax, label, work);
        }
    }
    crom_render_colorbar(im, 10, nrows * ph + 2, (K * pw) / 2, 10, 0, umax, "m  |u|");
    free(work);
    *ncols = K;
    return 0;
}

int crom_picture_mesh(crom_image *im, const crom_mesh *m, int pw, int ph)
{
    crom_render_camera cam;
    double lo[3], hi[3], *work = crom_malloc(sizeof(double) * 4 * (size_t)(m->nv ? m->nv : 1));
    int ntri, *tris = NULL, rc = 0;
    im->rgb = NULL;
    im->z = NULL;
    crom_mesh_bbox(m, lo, hi);
    crom_render_camera_fit(&cam, lo, hi, pw, ph, 1.12);
    if (!work || (rc = crom_image_init(im, pw, ph)) || (rc = crom_export_surface(m, &ntri, &tris))) {
        free(work);
        crom_image_free(im);
        return rc ? rc : CROM_EINTERNAL;
    }
    crom_render_panel(im, &cam, 0, 0, pw, ph, m->nv, m->X, NULL, ntri, tris, 1, NULL, work);
    free(work);
    free(tris);
    return 0;
}

int crom_picture_write(const crom_follow_frames *r, int all, long frame, const char *out, const char *name, int pw,
                       int ph, double range, long *count)
{
    crom_render_camera cam;
    double umax;
    crom_picture_view(r, 1, pw, ph, range, &cam, &umax);
    long first = 0, last = r->nf - 1, k = frame < 0 ? r->nf + frame : frame;
    crom_export_series s = {0};
    crom_image im = {0};
    int rc = 0;
    *count = 0;
    if (!all && (k < 0 || k >= r->nf))
        rc = crom_err(CROM_EUSAGE, "--frame %ld: %s has %d frames", frame, r->src.res[0].in.name, r->nf);
    else if (!all)
        first = last = k;
    else
        rc = crom_export_series_open(&s, out, name, "png", CROM_EXPORT_SERIES_FILES);
    for (long f = first; f <= last && !rc; f++) {
        crom_image_free(&im);
        if (!(rc = crom_picture_frame(&im, &cam, r, (int)f, pw, ph, umax)))
            rc = crom_image_save(&im, all ? crom_export_series_path(&s) : (out ? out : "-"));
        if (!rc && all)
            rc = crom_export_series_add(&s, r->t[f]);
        *count += !rc;
    }
    crom_image_free(&im);
    crom_export_series_free(&s);
    return rc;
}
