/* render.c — software rasterizer of shaded, coloured surfaces (render.h). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "view/render.h"

static void normalize(double v[3])
{
    double n = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for (int i = 0; i < 3; i++)
        v[i] /= n;
}

static void cross(const double a[3], const double b[3], double c[3])
{
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

void crom_render_camera_fit(crom_render_camera *cam, const double lo[3], const double hi[3], int vw, int vh,
                            double margin)
{
    double up0[3] = {0, 1, 0};
    for (int i = 0; i < 3; i++)
        cam->center[i] = 0.5 * (lo[i] + hi[i]);
    cam->fwd[0] = 1;
    cam->fwd[1] = 0.8;
    cam->fwd[2] = 1.5;
    normalize(cam->fwd);
    cross(up0, cam->fwd, cam->right);
    normalize(cam->right);
    cross(cam->fwd, cam->right, cam->up);
    /* the projected extent of the box's corners */
    double ex = 1e-12, ey = 1e-12;
    for (int c = 0; c < 8; c++) {
        double p[3] = {(c & 1) ? hi[0] : lo[0], (c & 2) ? hi[1] : lo[1], (c & 4) ? hi[2] : lo[2]};
        double px = 0, py = 0;
        for (int i = 0; i < 3; i++) {
            px += (p[i] - cam->center[i]) * cam->right[i];
            py += (p[i] - cam->center[i]) * cam->up[i];
        }
        ex = fmax(ex, fabs(px));
        ey = fmax(ey, fabs(py));
    }
    cam->pixels_per_m = fmin(vw / (2 * ex * margin), vh / (2 * ey * margin));
}

/* blue → teal → green → yellow, roughly perceptual */
static void ramp(double t, double c[3])
{
    static const double k[6][3] = {{0.23, 0.30, 0.75}, {0.16, 0.50, 0.80}, {0.13, 0.66, 0.60},
                                   {0.40, 0.76, 0.35}, {0.80, 0.82, 0.20}, {0.99, 0.85, 0.15}};
    if (!(t > 0))
        t = 0;
    if (t > 1)
        t = 1;
    double f = t * 5;
    int i = (int)f;
    if (i > 4)
        i = 4;
    f -= i;
    for (int j = 0; j < 3; j++)
        c[j] = k[i][j] * (1 - f) + k[i + 1][j] * f;
}

void crom_render_mesh(crom_image *im, const crom_render_camera *cam, int x0, int y0, int vw, int vh,
                      const double *x, int nt, const int *tris, const double *s, double smin,
                      double smax)
{
    double light[3] = {0.3, 0.9, 0.6};
    normalize(light);
    double cx = x0 + 0.5 * vw, cy = y0 + 0.5 * vh, k = cam->pixels_per_m;
    for (int t = 0; t < nt; t++) {
        double P[3][3], val[3], n[3], e1[3], e2[3];
        const int *tri = tris + 3 * (size_t)t;
        for (int a = 0; a < 3; a++) {
            const double *p = x + 3 * (size_t)tri[a];
            double q[3] = {p[0] - cam->center[0], p[1] - cam->center[1], p[2] - cam->center[2]};
            P[a][0] = cx + k * (q[0] * cam->right[0] + q[1] * cam->right[1] + q[2] * cam->right[2]);
            P[a][1] = cy - k * (q[0] * cam->up[0] + q[1] * cam->up[1] + q[2] * cam->up[2]);
            P[a][2] = q[0] * cam->fwd[0] + q[1] * cam->fwd[1] + q[2] * cam->fwd[2];
            val[a] = s ? (s[tri[a]] - smin) / (smax > smin ? smax - smin : 1) : -1;
        }
        for (int i = 0; i < 3; i++) {
            e1[i] = x[3 * (size_t)tri[1] + i] - x[3 * (size_t)tri[0] + i];
            e2[i] = x[3 * (size_t)tri[2] + i] - x[3 * (size_t)tri[0] + i];
        }
        cross(e1, e2, n);
        double nn = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        if (!(nn > 0))
            continue;
        double lam = fabs(n[0] * light[0] + n[1] * light[1] + n[2] * light[2]) / nn;
        double shade = 0.35 + 0.65 * lam;
        double area = (P[1][0] - P[0][0]) * (P[2][1] - P[0][1]) - (P[2][0] - P[0][0]) * (P[1][1] - P[0][1]);
        if (fabs(area) < 1e-12)
            continue;
        int xmin = (int)floor(fmin(P[0][0], fmin(P[1][0], P[2][0]))), xmax = (int)ceil(fmax(P[0][0], fmax(P[1][0], P[2][0])));
        int ymin = (int)floor(fmin(P[0][1], fmin(P[1][1], P[2][1]))), ymax = (int)ceil(fmax(P[0][1], fmax(P[1][1], P[2][1])));
        if (xmin < x0)
            xmin = x0;
        if (ymin < y0)
            ymin = y0;
        if (xmax > x0 + vw - 1)
            xmax = x0 + vw - 1;
        if (ymax > y0 + vh - 1)
            ymax = y0 + vh - 1;
        for (int py = ymin; py <= ymax; py++)
            for (int px = xmin; px <= xmax; px++) {
                double fx = px + 0.5, fy = py + 0.5;
                double w0 = ((P[1][0] - fx) * (P[2][1] - fy) - (P[2][0] - fx) * (P[1][1] - fy)) / area;
                double w1 = ((P[2][0] - fx) * (P[0][1] - fy) - (P[0][0] - fx) * (P[2][1] - fy)) / area;
                double w2 = 1 - w0 - w1;
                if (w0 < 0 || w1 < 0 || w2 < 0)
                    continue;
                float z = (float)(w0 * P[0][2] + w1 * P[1][2] + w2 * P[2][2]);
                size_t idx = (size_t)py * im->w + px;
                if (z <= im->z[idx])
                    continue;
                im->z[idx] = z;
                double c[3] = {0.7, 0.7, 0.7};
                if (s)
                    ramp(w0 * val[0] + w1 * val[1] + w2 * val[2], c);
                for (int j = 0; j < 3; j++) {
                    double v = 255 * c[j] * shade;
                    im->rgb[3 * idx + j] = (unsigned char)(v > 255 ? 255 : v);
                }
            }
    }
}

void crom_render_colorbar(crom_image *im, int x, int y, int w, int h, double smin, double smax,
                          const char *unit)
{
    for (int px = 0; px < w; px++) {
        double c[3];
        ramp((double)px / (w - 1), c);
        for (int py = 0; py < h; py++) {
            int X = x + px, Y = y + py;
            if (X < 0 || Y < 0 || X >= im->w || Y >= im->h)
                continue;
            for (int j = 0; j < 3; j++)
                im->rgb[3 * ((size_t)Y * im->w + X) + j] = (unsigned char)(255 * c[j]);
        }
    }
    char lo[64], hi[64];
    snprintf(lo, sizeof lo, "%.3g", smin);
    snprintf(hi, sizeof hi, "%.3g %s", smax, unit ? unit : "");
    crom_image_text(im, x, y + h + 3, lo, 1);
    crom_image_text(im, x + w - 6 * (int)strlen(hi), y + h + 3, hi, 1);
}

void crom_render_panel(crom_image *im, const crom_render_camera *cam, int x0, int y0, int vw, int vh,
                       int n, const double *X, const double *u, int nt, const int *tris, double umax,
                       const char *label, double *work)
{
    double *x = work, *s = work + 3 * (size_t)n; /* work: 4n doubles */
    for (int i = 0; i < n; i++) {
        double m = 0;
        for (int c = 0; c < 3; c++) {
            double d = u ? u[3 * i + c] : 0;
            x[3 * i + c] = X[3 * i + c] + d;
            m += d * d;
        }
        s[i] = sqrt(m);
    }
    crom_render_mesh(im, cam, x0, y0, vw, vh, x, nt, tris, s, 0, umax > 0 ? umax : 1);
    if (label)
        crom_image_text(im, x0 + 6, y0 + 6, label, 2);
}
