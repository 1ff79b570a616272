/* body.h — the body a data-free subspace is trained on (crom-fitfield
 * --objective energy|neuralmodes|field|skinning), set up from the files and
 * the scenario it is given, and what the model records of it.
 *
 * The geometry is a tet mesh (a crom/mesh file; for the one-mesh maps also
 * a shell surface, lib/phys/system.h), or the virtual tets of a
 * point sampling (lib/mesh/cloud.h) of a closed triangle surface or of a
 * point cloud with volumes; a sampled body's pins must be predicates
 * ('x<-0.49'), and for skinning the points and surface triangles they hold
 * make its pin mask. The pins fix DOFs of the training geometry by region or
 * predicate (crom_modes_pins), the material is the scenario's. A
 * neuralmodes map builds on linear modes of the same mesh (crom-modes): the
 * body takes their material where none was given, and their pins. The
 * model records the material, the pins and (energy, field) the gravity as
 * scenario flags, the body's mass, and the training record (datafree.h,
 * dfskin.h).
 */
#ifndef CROM_BODY_H
#define CROM_BODY_H

#include <stdint.h>

#include "datafree/datafree.h"
#include "datafree/dfskin.h"
#include "datafree/dftrain.h"
#include "mesh/cloud.h"
#include "mesh/mesh.h"
#include "phys/material.h"
#include "phys/scenario.h"
#include "rom/model.h"
#include "rom/result.h"

/* Where the body comes from: exactly one of the three files. */
typedef struct {
    const char *mesh;        /* a crom/mesh ('-': stdin) */
    const char *surface;     /* a closed surface (.stl, .obj) */
    const char *cloud;       /* a point cloud with volumes */
    int sample_points;       /* surface: about this many points (0: 8192) */
    uint64_t seed;           /* of the sampling and of the stencils' rotations */
    int shells;              /* 1: the mesh may be a shell surface (the one-mesh maps, energy and
                              * neuralmodes, integrate any system's energy elements) */
    int scenes;              /* 1: the mesh may be a rigid-body scene (the energy objective) */
} crom_body_source;

typedef struct {
    crom_mesh mesh;          /* the training geometry: the mesh, or the virtual tets of the points */
    crom_cloud cloud;        /* the sampled body (cloud.n = 0 for a mesh) */
    char *history;           /* the mesh file's history (NULL for a sampled body) */
    crom_material mat;
    unsigned char *fixed;    /* [3nv] pinned DOFs */
    int npinned;             /* pinned vertices of the training geometry */
    int npin, ntri;          /* a sampled body: its pinned points and surface triangles */
    double *pinX, *triX;     /* [npin][3], [ntri][3][3] */
    const char *modes_path;  /* neuralmodes: where the modes came from (for messages) */
    crom_model modes;        /* neuralmodes: the linear modes */
    double *W, *freq;        /* neuralmodes: the lowest r of them [3nv][r], their frequencies [r] */
    double *deriv;           /* neuralmodes with derivatives: Ψ [3nv][r(r+1)/2] (crom_body_derivatives) */
    crom_result_equilibria eq; /* neuralmodes supervised: the equilibria fitted to (crom_body_supervise) */
    double *visit;           /* neuralmodes sampled along a run: [nvisit][r] its coordinates (crom_body_visit) */
    long nvisit;
    char visit_what[160];    /* where they came from (the model's record) */
    double *seed;            /* energy from a seed state: its displacement [3nv] (crom_body_seed) */
    crom_model init;         /* energy map or field refined along a run: the model it starts from (crom_body_refine) */
    const char *init_path;   /* and where it came from (borrowed) */
    char seed_what[200];     /* where it came from (the model's record) */
} crom_body;

/* Load the geometry of src into b (cleared first; free it with
 * crom_body_free in any case). A sampled body's pins in sc must be
 * predicates (checked before sampling). Returns 0, CROM_EUSAGE (a region
 * pin on a sampled body), or the loader's error with "--mesh", "--surface"
 * or "--cloud" as context. */
int crom_body_load(crom_body *b, const crom_body_source *src, const crom_scenario *sc);

void crom_body_free(crom_body *b);

/* The supervised baseline of a neuralmodes map (datafree.h): the
 * constrained equilibria at path (crom-fullsim --equilibria) of b's mesh
 * in rank modal coordinates, into P (nsup, sup_z, sup_u; b keeps them).
 * Returns 0, CROM_EUSAGE (not equilibria, another mesh, another rank), or
 * the reader's error with "--supervised" as context. */
int crom_body_supervise(crom_body *b, const char *path, int rank, crom_datafree_problem *P);

/* Neural modes sampled along a run (datafree.h): the modal coordinates of
 * every frame of the crom/latent at path (a reduced run of a map in the
 * same modes, e.g. of the untrained map) into P (nvisit, visit_z; b keeps
 * them). Returns 0, CROM_EUSAGE (another rank) or the reader's error with
 * "--latents" as context. */
int crom_body_visit(crom_body *b, const char *path, int rank, crom_datafree_problem *P);

/* An energy map grown from a seed state (Sharp et al. §4.1; datafree.h):
 * the displacement of frame `frame` (negative: from the end, −1 the last)
 * of the trajectory at path (e.g. crom-fullsim's equilibrium of a
 * compressed bar), on b's mesh, into P->seed (b keeps it). Returns 0,
 * CROM_EUSAGE (another mesh, no such frame) or the reader's error with
 * "--seed-state" as context. */
int crom_body_seed(crom_body *b, const char *path, long frame, crom_datafree_problem *P);

/* Refine an energy map or a continuous field (datafree.h): the model at
 * path (basis `basis`: "energy", b's mesh and the conditions of P;
 * "skin-field", its φ then refined over the same skinning basis,
 * crom_body_train_skin_field; or "energy-field", its φ and W(X), on any
 * mesh of the body) becomes P->init (and P->init_field), its seed state P->seed, and,
 * with latents (may be NULL), the latents its reduced run at that path
 * visited become P's samples along a run. Returns 0, CROM_EUSAGE (another
 * kind, mesh or conditions; a seed state given too; a run of another
 * model) or the reader's error with "--init-model" or "--latents" as
 * context. */
int crom_body_refine(crom_body *b, const char *path, const char *latents, int rank, const char *basis,
                     crom_datafree_problem *P);

/* The body's volume (the mesh's, or the sampled points') and mass (m³, kg;
 * the mass after crom_body_pins). */
double crom_body_volume(const crom_body *b);
double crom_body_mass(const crom_body *b);

/* The linear modes at path for a neuralmodes map of b, named mesh_name in
 * messages: a model of basis "modes" on the same mesh with at least *rank
 * modes (*rank <= 0: all of them, set). Then, unless material_given, sc
 * takes the modes' material (if they record one); *differs (may be NULL)
 * is set to 1 when the modes were computed with another material than sc's
 * (for a warning); and sc gets the modes' pins it does not have yet.
 * Returns 0, CROM_EDATA (another basis, another mesh), CROM_EUSAGE (too
 * few modes, too many pins), or the loader's error. */
int crom_body_load_modes(crom_body *b, const char *path, const char *mesh_name, int *rank, crom_scenario *sc,
                         int material_given, int *differs);

/* The material of sc (checked) and the DOFs its pins fix; with
 * cloud_pins, also a sampled body's pinned points and triangles. Returns
 * 0, or CROM_EUSAGE (a bad scenario, an unknown region, a pin that selects
 * nothing). */
int crom_body_pins(crom_body *b, const crom_scenario *sc, int cloud_pins);

/* The problem of a map or field of the given objective (CROM_DATAFREE_*)
 * and rank on b, after crom_body_pins (borrowing from b): gravity from sc
 * (none for neuralmodes, which takes the lowest rank modes). Returns 0,
 * CROM_EDATA (a mode moves a pinned DOF), CROM_EINTERNAL. */
int crom_body_map_problem(crom_body *b, const crom_scenario *sc, int objective, int rank,
                          crom_datafree_problem *P);

/* The modal derivatives of the modes of a neuralmodes problem P (after
 * crom_body_map_problem): Ψ of b's first rank modes on its system at rest
 * with its pins (lib/phys/mderiv.h), into b->deriv and P->deriv. Returns
 * 0, CROM_EDATA (the pins do not hold the body), CROM_EINTERNAL. */
int crom_body_derivatives(crom_body *b, crom_datafree_problem *P, int rank);

/* Train skinning weights on b (after crom_body_pins with cloud_pins):
 * crom_dfskin_train, after checking the handle count of a sampled body. */
int crom_body_train_skin(const crom_body *b, const crom_scenario *materials, const crom_dfskin_opts *o,
                         crom_model *out, crom_dftrain_log *log);

/* Orthonormal coordinates for a skinning model over b's training geometry:
 * the mesh's vertices with their lumped volumes, or the sampled points
 * with theirs (crom_skin_orthonormalize, relative tolerance tol). */
int crom_body_skin_coordinates(const crom_body *b, crom_model *m, double tol);

/* The continuous field over the skinning eigenmodes of H handles of b's
 * mesh (orthonormal coordinates, relative tolerance 1e-6): the eigensolve
 * (*solves linear solves), then φ trained from the energy of P
 * (crom_dffield_train_latent with o, its progress callback included); out
 * gets the skin-field (crom_model_skin_field) with its training time. */
int crom_body_train_skin_field(const crom_body *b, const crom_datafree_problem *P, const crom_datafree_opts *o,
                               int H, crom_model *out, crom_dftrain_log *log, long *solves);

/* Write a map or field m trained with o on problem P (and its record log)
 * to path (crom_out_create: cmdline and the body's history as history)
 * with what it records: the scenario flags of sc (gravity but for
 * neuralmodes) and its material in m, then the record of
 * crom_datafree_write_record with the body's mass (and the modes' id).
 * The file appears only whole. Returns 0, or an I/O error. */
int crom_body_write_map(const crom_body *b, const crom_scenario *sc, crom_model *m, const crom_datafree_opts *o,
                        const crom_datafree_problem *P, const crom_dftrain_log *log, const char *path,
                        const char *cmdline);

/* The same for a skinning model m: the scenario flags of sc (no gravity),
 * and crom_dfskin_write_record (log NULL for eigen weights). */
int crom_body_write_skin(const crom_body *b, const crom_scenario *sc, crom_model *m, const crom_dfskin_opts *o,
                         const crom_dftrain_log *log, const char *path, const char *cmdline);

#endif
