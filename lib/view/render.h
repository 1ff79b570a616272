/* render.h — headless pictures of deformed bodies: a z-buffered rasterizer of
 * a triangle surface, shaded and coloured by a scalar (|u|), seen by a fixed
 * orthographic camera, into an image (image.h: labels, PNG). Enough for a
 * quick look at a run without ParaView. */
#ifndef CROM_RENDER_H
#define CROM_RENDER_H

#include "view/image.h"

/* A fixed orthographic view: the camera looks along -dir at center. */
typedef struct {
    double center[3];
    double right[3], up[3], fwd[3]; /* orthonormal, fwd points at the viewer */
    double pixels_per_m;
} crom_render_camera;

/* A camera looking at the box [lo, hi] from the direction (1, 0.8, 1.5)
 * (y up), framing it with the given margin (e.g. 1.3 for room to deform) in
 * a viewport of vw × vh pixels. */
void crom_render_camera_fit(crom_render_camera *cam, const double lo[3], const double hi[3], int vw, int vh,
                            double margin);

/* Draw the triangles tris [nt][3] of the points x [n][3] into the viewport
 * starting at column x0, row y0 of size vw × vh: flat Lambert shading,
 * colour from s [n] mapped over [smin, smax] (a blue-to-yellow ramp); s may
 * be NULL (grey). Two-sided: no triangle is culled for facing away, and the
 * shading uses |n·l|, so an open surface (a shell) shows both its sides. */
void crom_render_mesh(crom_image *im, const crom_render_camera *cam, int x0, int y0, int vw, int vh,
                      const double *x, int nt, const int *tris, const double *s, double smin,
                      double smax);

/* A horizontal colour bar for [smin, smax] with its range written under it. */
void crom_render_colorbar(crom_image *im, int x, int y, int w, int h, double smin, double smax,
                          const char *unit);

/* One panel: the surface tris [nt][3] (a tet mesh's boundary, a shell's
 * triangles) of rest positions X [n][3] displaced by u [n][3] (NULL: at
 * rest), coloured by |u| over [0, umax], with an optional label at the
 * panel's top-left. */
void crom_render_panel(crom_image *im, const crom_render_camera *cam, int x0, int y0, int vw, int vh,
                       int n, const double *X, const double *u, int nt, const int *tris, double umax,
                       const char *label, double *work);

#endif
