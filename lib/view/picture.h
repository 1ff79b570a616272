/* picture.h — PNG pictures of results read with follow.h: one panel per
 * frame and strips of several results side by side at the same times, all
 * from one fixed camera on one colour scale of |u| (rendered by render.h). */
#ifndef CROM_PICTURE_H
#define CROM_PICTURE_H

#include "view/follow.h"
#include "view/render.h"

/* The camera and colour range shared by every picture of rows[0..nrows):
 * the camera frames every frame's deformed shape in a pw × ph panel; *umax
 * is range when range > 0, else the largest |u| shown (1 if nothing
 * moves). */
void crom_picture_view(const crom_follow_frames *rows, int nrows, int pw, int ph, double range,
                       crom_render_camera *cam, double *umax);

/* The picture of frame f of r: a pw × (ph + 34) image (allocated into im;
 * free it with crom_image_free) holding the panel labelled "t=... s" and a
 * colour bar of [0, umax] m under it. Returns 0 or CROM_EINTERNAL. */
int crom_picture_frame(crom_image *im, const crom_render_camera *cam, const crom_follow_frames *r, int f, int pw, int ph,
                       double umax);

/* The pictures of r's frames (crom_picture_frame, on r's own view): with
 * all != 0 one per frame, out/NAME_00000.png, ... (the directory created),
 * else only frame `frame` (negative: from the end) to the file out ("-":
 * stdout). *count says how many were written. Returns 0, CROM_EUSAGE (no
 * such frame) or a write error. */
int crom_picture_write(const crom_follow_frames *r, int all, long frame, const char *out, const char *name, int pw,
                       int ph, double range, long *count);

/* A strip: one row per result rows[i] (its first panel labelled labels[i]),
 * `columns` columns at times evenly spaced over rows[0]'s frames (each row
 * shows its frame nearest in time), a colour bar under them, on the view of
 * crom_picture_view(range). At most as many columns as rows[0] has frames;
 * *ncols says how many. Allocates im. Returns 0 or CROM_EINTERNAL. */
int crom_picture_strip(crom_image *im, const crom_follow_frames *rows, const char *const *labels, int nrows,
                       int columns, int pw, int ph, double range, int *ncols);

/* A bare mesh at rest (its surface: the boundary of a tet mesh, a shell's
 * triangles), grey, filling a pw × ph image (allocated into im). Returns 0
 * or CROM_EINTERNAL. */
int crom_picture_mesh(crom_image *im, const crom_mesh *m, int pw, int ph);

#endif
