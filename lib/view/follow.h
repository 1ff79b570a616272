/* follow.h — a result read frame by frame on the mesh each frame lives on:
 * a trajectory (its own mesh), a latent decoded on one mesh, or a latent of
 * a run with a --schedule (cuts, punches, swaps) decoded on the mesh of the
 * cubature in use at each frame (one crom_result per mesh of the schedule,
 * read in lockstep). What crom-export writes and draws. */
#ifndef CROM_FOLLOW_H
#define CROM_FOLLOW_H

#include "rom/result.h"

typedef struct {
    int n;            /* meshes */
    crom_result *res; /* [n]: the same result decoded on each mesh */
    double **u, **v;  /* [n] frame buffers [nv][3] */
    int fcub;         /* the latent's per-frame 'cubature' field, or -1 */
    int cur;          /* mesh of the frame last read */
    int maxnv;        /* largest vertex count of the meshes */
} crom_follow;

/* Open a result over an input already open (taken over: closed on failure).
 * path names the input again (NULL or "-" for stdin), mesh and model are as
 * for crom_result_open (may be NULL). follow != 0 and a crom/latent whose
 * 'cubatures' attribute lists a schedule: one mesh per schedule entry (mesh,
 * if given, stands in for the first), which needs path to be a file (it is
 * read once per mesh). Returns 0, CROM_EUSAGE (the latent is stdin),
 * CROM_EDATA (a bad schedule entry or no per-frame 'cubature' field), or an
 * error of crom_result_open naming the entry. On failure *s holds nothing. */
int crom_follow_adopt(crom_follow *s, crom_in *opened, const char *path, const char *mesh,
                      const char *model, int follow);

/* Read the next frame: returns 1 (its time in *t, displacement and velocity
 * in s->u[s->cur], s->v[s->cur], on the mesh s->res[s->cur].mesh), 0 at the
 * end, or an error code (CROM_EDATA when the copies disagree or a frame names
 * a schedule entry that does not exist). */
int crom_follow_next(crom_follow *s, double *t);

/* Read to the end and keep the frame-th frame (negative: counted from the
 * end, -1 the last): its mesh index in *mi, time in *t, displacement u and
 * velocity v ([maxnv][3] each). Returns 0, CROM_EUSAGE when the result has
 * no such frame (*nframes says how many it has), or a read error. */
int crom_follow_pick(crom_follow *s, long frame, int *mi, double *t, double *u, double *v, long *nframes);

/* Vertices of mesh i lying outside the model's mesh (W is extended there). */
size_t crom_follow_outside(const crom_follow *s, int i);

/* Close every copy and free the buffers (safe on a zeroed struct). */
void crom_follow_close(crom_follow *s);

/* ------------------------------------------------ a whole result in memory */

typedef struct {
    crom_follow src;
    int nf;            /* frames kept */
    double *t, *u;     /* [nf] times; frames one after another: frame f at u + off[f] */
    size_t *off;       /* [nf] */
    int *mi;           /* [nf] mesh of frame f */
    int *ntri, **tris; /* per mesh: the surface drawn (export.h: crom_export_surface) */
} crom_follow_frames;

/* Take over src (left zeroed) and read every every-th frame of it into
 * memory, with the surface of each of its meshes (the boundary of a tet
 * mesh, a shell's triangles). Returns 0,
 * CROM_EDATA when it has no frames, CROM_EINTERNAL (out of memory) or a read
 * error; r is to be freed with crom_follow_frames_free either way. */
int crom_follow_load(crom_follow_frames *r, crom_follow *src, int every);

/* Open the result at path (NULL or "-": stdin) and crom_follow_load it:
 * mesh decodes a latent (a trajectory keeps its own mesh), model and follow
 * as for crom_follow_adopt. Returns 0 or the error of either step; r is to
 * be freed with crom_follow_frames_free either way. */
int crom_follow_load_path(crom_follow_frames *r, const char *path, const char *mesh, const char *model, int follow,
                          int every);

/* Free what crom_follow_load read and close its source (safe on a zeroed
 * struct). */
void crom_follow_frames_free(crom_follow_frames *r);

/* The mesh of frame f. */
const crom_mesh *crom_follow_frame_mesh(const crom_follow_frames *r, int f);

/* The box [lo, hi] holding every loaded frame of rows[0..nrows) in its
 * deformed position (and each first mesh at rest), and the largest |u| of
 * them all in *umax (0 when nothing moves). */
void crom_follow_bounds(const crom_follow_frames *rows, int nrows, double lo[3], double hi[3], double *umax);

#endif
