/* result.h — any simulation result as displacement frames on a mesh: a
 * crom/trajectory (its own mesh, a tet mesh or a shell surface, or a given
 * mesh of the same kind with the same vertices), or a
 * crom/latent decoded through a model's basis, u = W(X) q, onto any mesh
 * (the training mesh, a finer display mesh, another shape), or through a
 * nonlinear one-mesh map (data-free models: u = x(q) − X, velocity J(q) q̇)
 * onto its own mesh only. Used by crom-export and crom-diff so both decode
 * the same way. A rigid-body scene's trajectory is shown on its display
 * surface (lib/phys/rigidsys.h), every surface point moving with its body.
 */
#ifndef CROM_RESULT_H
#define CROM_RESULT_H

#include "io/io.h"
#include "mesh/mesh.h"

/* latitude rings of a sphere or capsule on a scene's display surface */
#define CROM_RESULT_DISPLAY_RINGS 12

typedef struct {
    crom_in in;
    int latent;         /* 1: a crom/latent decoded through W */
    crom_mesh mesh;     /* where the displacements live */
    int r;
    double *W;          /* latent: [nv][3][r] */
    struct crom_map_s *map; /* latent of a nonlinear map model: its evaluator (else NULL) */
    int frame;          /* latent of a run with a rigid frame (crom_map_add_frame): q = [q' | θ | t] */
    double *J;          /* map: [3nv][r] Jacobian scratch */
    char model_id[17];
    int ft, fu, fv;     /* frame fields: time, displacement or q, velocity or qdot */
    int fc;             /* a conditional map's latent: the field `condition` (−1: none; the map's
                         * middle condition then), laid on the map frame by frame */
    size_t outside;     /* latent: mesh vertices outside a mesh-field model */
    /* a trajectory of a rigid-body scene: mesh is its display surface
     * (crom_rigidsys_display), each frame mapped from the frame vertices */
    int scene_nv;       /* frame vertices (0: not a scene) */
    double *dbeta;      /* [nd][4] display coordinates in the body frames */
    double *uf;         /* [2][scene_nv][3] a scene map's frame-vertex u and v (scratch) */
    int *dbody;         /* [nd] body of each display vertex */
} crom_result;

/* Open path (a trajectory or a latent). mesh_path (may be NULL) names a
 * crom/mesh (or a file carrying one: trajectory, cubature) to use; model_path
 * (may be NULL) the crom/model to decode a latent. A latent needs both (its
 * model_id must match the model's), except for a map model (energy,
 * neuralmodes), which brings its mesh and accepts only a mesh with the same
 * vertices; a trajectory needs neither, and a given mesh must have its
 * vertices. A trajectory may live on a shell surface (res->mesh then has
 * triangles, mesh.h); a latent is decoded onto tet meshes, or onto the
 * shell surface its model was made on (modes, energy, neuralmodes on a
 * shell; any other shell --mesh: CROM_EUSAGE or CROM_EDATA). Returns 0 or an error naming the problem. */
int crom_result_open(crom_result *res, const char *path, const char *mesh_path,
                     const char *model_path);

/* The same for an input already open (e.g. stdin after looking at its
 * schema): takes it over (opened is left empty), closes it on failure. */
int crom_result_adopt(crom_result *res, crom_in *opened, const char *mesh_path,
                      const char *model_path);

/* Read the next frame: time, displacement u [nv][3] and velocity v [nv][3]
 * (v may be NULL). Returns 1 for a frame, 0 at the end, or an error code. */
int crom_result_next(crom_result *res, double *t, double *u, double *v);

void crom_result_close(crom_result *res);

/* Constrained equilibria (crom-fullsim --equilibria; schemas/trajectory.md)
 * read whole: the mesh, the scenario text (material, pins), and K frames of
 * r modal coordinates Z [K][r] and displacements U [K][3nv]. */
typedef struct {
    crom_mesh mesh;
    char *scenario;     /* the `scenario` attribute (flags, one per line) */
    char model_id[17];  /* the modes' model_id (`equilibria_model`) */
    int K, r;
    double *Z, *U;
} crom_result_equilibria;

/* Read path (a file, or "-"/NULL for stdin). Returns 0, CROM_EUSAGE when it
 * is no file of constrained equilibria, or the reader's errors. On failure
 * *eq holds nothing to free. */
int crom_result_equilibria_load(const char *path, crom_result_equilibria *eq);

void crom_result_equilibria_free(crom_result_equilibria *eq);

/* The one check that frame data is finite, for every program that reads
 * frames (crom-export and crom-diff through crom_result_next, crom-sample,
 * crom-encode, crom-cubature --poses, crom-reducedstep --init): every value
 * of `frame` (in->frame_len doubles packed in in's field order; NULL: the
 * current frame) is finite. Returns 0, or CROM_EDATA with "NAME: frame K has
 * a non-finite FIELD (at vertex V | at index I)". */
int crom_result_check_frame(const crom_in *in, const double *frame, long k);

/* Whether the crom/latent open at h5 is a run with a rigid frame
 * (crom-reducedstep --rigid-frame: q = [q' | θ | t], the attribute
 * rigid_frame): *frame 1 or 0. Returns 0 or the reader's error. */
int crom_result_latent_frame(hid_t h5, int *frame);

#endif
