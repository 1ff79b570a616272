/* samples.h — crom/samples files in memory: point samples (X, u) of the frames
 * of one or more trajectories, the training set of a displacement basis
 * (schemas/samples.md).
 *
 * Every frame f has N samples i with rest position X[f][i] and displacement
 * U[f][i] (float32, metres), the vertex they sit on in their source mesh (or
 * -1 for interior points), the source the frame came from and its time.
 * Sources are stored under /sources/<k> with k the zero-padded source index
 * ("000", "001", ...: name order is index order), each holding the source
 * mesh (vertices, tets) and a `file` attribute naming the input.
 */
#ifndef CROM_SAMPLES_H
#define CROM_SAMPLES_H

#include <hdf5.h>

#include "base/rng.h"
#include "io/io.h"
#include "mesh/mesh.h"

#define CROM_SAMPLES_SCHEMA "crom/samples"
#define CROM_SAMPLES_VERSION 1

typedef struct {
    int F, N;          /* frames, samples per frame */
    float *X;          /* [F][N][3] rest positions (m) */
    float *U;          /* [F][N][3] displacements (m) */
    int *vertex;       /* [F][N] source-mesh vertex, -1 for interior points */
    int *source;       /* [F] source index of each frame */
    double *time;      /* [F] simulated time of each frame (s) */
    int nsources;
    crom_mesh *src;    /* [nsources] source meshes (vertices and tets) */
    char **src_file;   /* [nsources] input each source came from */
    char mode[16];     /* "vertices" or "interior" */
    long long seed;
    char *history;     /* root history of the file read (owned), or NULL */
    size_t cap;        /* frames the arrays have room for (crom_samples_add_frame) */
} crom_samples;

/* Read and validate a crom/samples input (already opened and checked with
 * crom_in_expect): shapes, finite values, vertex and source indices in range,
 * vertex samples at their vertex's position. Returns 0 or CROM_EDATA naming
 * the first problem (e.g. "stdin: frame 3 sample 7 has a non-finite
 * displacement"). */
int crom_samples_read(crom_in *in, crom_samples *s);

/* Write the samples under loc (the root of a crom/samples output): root
 * attributes mode, points_per_frame, seed, and every dataset. */
int crom_samples_write(hid_t loc, const crom_samples *s);

/* Free everything; s becomes empty. */
void crom_samples_free(crom_samples *s);

/* Number of frames whose displacement is not identically zero. */
int crom_samples_nonzero_frames(const crom_samples *s);

/* ------------------------------------------------------------ picking
 * Where the samples of a frame sit on its mesh (crom-sample):
 *   vertices (LiCROM): N distinct random vertices, drawn by a partial
 *            Fisher–Yates shuffle of a permutation that carries over from
 *            frame to frame; X is the vertex's field point
 *            (crom_mesh_field_points, so the sides of a cut differ) and U
 *            its displacement;
 *   all:     every vertex in order (N = nv);
 *   interior: N points uniform by volume: a tet drawn with probability
 *            proportional to its volume, then Dirichlet(1,1,1,1)
 *            barycentric weights; X and U interpolated, vertex -1. */
enum { CROM_SAMPLES_VERTICES = 0, CROM_SAMPLES_ALL = 1, CROM_SAMPLES_INTERIOR = 2 };

typedef struct {
    const crom_mesh *mesh; /* borrowed */
    int how;               /* CROM_SAMPLES_VERTICES, _ALL or _INTERIOR */
    double *fp;            /* [nv][3] field points */
    int *perm;             /* [nv] the vertex permutation */
    double *cum;           /* [nt] cumulative tet volumes */
} crom_samples_picker;

/* A picker on mesh m (borrowed: keep it alive). Returns 0 or
 * CROM_EINTERNAL. */
int crom_samples_picker_init(crom_samples_picker *p, const crom_mesh *m, int how);

/* N samples of the displacement field u [nv][3] into X, U [N][3] and
 * vertex [N], with random numbers from rng. N <= nv unless interior. */
void crom_samples_pick(crom_samples_picker *p, int N, const double *u, crom_rng *rng, float *X, float *U,
                       int *vertex);

void crom_samples_picker_free(crom_samples_picker *p);

/* Append a frame of s->N samples that p picks from u, from source `source`
 * at time t, growing s's arrays (s->cap). Returns 0 or CROM_EINTERNAL. */
int crom_samples_add_frame(crom_samples *s, crom_samples_picker *p, const double *u, crom_rng *rng,
                           int source, double t);

#endif
