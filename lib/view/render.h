/* render.h — headless pictures of deformed bodies: a z-buffered rasterizer of
 * a triangle surface, shaded and coloured by a scalar (|u|), seen by a fixed
 * orthographic camera, with a tiny bitmap font for labels, written as PNG
 * (libpng). Enough for a quick look at a run without ParaView. */
#ifndef CROM_RENDER_H
#define CROM_RENDER_H

#include <stdio.h>

typedef struct {
    int w, h;
    unsigned char *rgb; /* [h][w][3] */
    float *z;           /* [h][w] depth (larger is nearer) */
} crom_image;

/* A fixed orthographic view: the camera looks along -dir at center. */
typedef struct {
    double center[3];
    double right[3], up[3], fwd[3]; /* orthonormal, fwd points at the viewer */
    double pixels_per_m;
} crom_camera;

/* Allocate a w × h image cleared to white. Returns 0 or CROM_EINTERNAL. */
int crom_image_init(crom_image *im, int w, int h);
void crom_image_free(crom_image *im);

/* A camera looking at the box [lo, hi] from the direction (1, 0.8, 1.5)
 * (y up), framing it with the given margin (e.g. 1.3 for room to deform) in
 * a viewport of vw × vh pixels. */
void crom_camera_fit(crom_camera *cam, const double lo[3], const double hi[3], int vw, int vh,
                     double margin);

/* Draw the triangles tris [nt][3] of the points x [n][3] into the viewport
 * starting at column x0, row y0 of size vw × vh: flat Lambert shading,
 * colour from s [n] mapped over [smin, smax] (a blue-to-yellow ramp); s may
 * be NULL (grey). */
void crom_render_mesh(crom_image *im, const crom_camera *cam, int x0, int y0, int vw, int vh,
                      const double *x, int nt, const int *tris, const double *s, double smin,
                      double smax);

/* Write text (upper-case letters, digits, . , : = - + / ( ) % and space;
 * lower case is drawn as upper case) with its top-left corner at (x, y), in
 * pixel blocks of the given scale. */
void crom_image_text(crom_image *im, int x, int y, const char *s, int scale);

/* A horizontal colour bar for [smin, smax] with its range written under it. */
void crom_image_colorbar(crom_image *im, int x, int y, int w, int h, double smin, double smax,
                         const char *unit);

/* One panel: the boundary surface tris [nt][3] of rest positions X [n][3]
 * displaced by u [n][3] (NULL: at rest), coloured by |u| over [0, umax],
 * with an optional label at the panel's top-left. */
void crom_render_panel(crom_image *im, const crom_camera *cam, int x0, int y0, int vw, int vh,
                       int n, const double *X, const double *u, int nt, const int *tris, double umax,
                       const char *label, double *work);

/* Write the image as an 8-bit RGB PNG. Returns 0 or CROM_EIO. */
int crom_image_write_png(const crom_image *im, FILE *f);

/* Write the image as PNG to path ("-": stdout, refused when a terminal),
 * atomically (crom_fileout). Returns 0, CROM_ECANTCREAT or CROM_EIO. */
int crom_image_save(const crom_image *im, const char *path);

#endif
