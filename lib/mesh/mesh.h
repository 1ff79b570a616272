/* mesh.h — tetrahedral meshes and triangle surfaces (thin shells) with named
 * vertex regions (crom/mesh).
 *
 * Positions are rest positions X in metres, row-major [nv][3]; tets are 0-based
 * vertex indices [nt][4], positively oriented: det[x1-x0, x2-x0, x3-x0] > 0.
 * A surface mesh (a shell or cloth, lib/phys/shell.h) has no tets (nt = 0)
 * but triangles [ntri][3], consistently oriented, and a thickness (m).
 * Regions are named, sorted vertex-index sets (from predicates or gmsh physical
 * groups).
 */
#ifndef CROM_MESH_H
#define CROM_MESH_H

#include <stddef.h>

#include "mesh/pred.h"
#include "mesh/scene.h"

typedef struct {
    char *name;   /* region name: [A-Za-z0-9_.-]+ */
    char *source; /* how it was made: the predicate text, or "gmsh:GROUP" */
    int n;        /* number of vertices */
    int *idx;     /* sorted, unique 0-based vertex indices */
} crom_mesh_region;

typedef struct {
    int nv, nt;
    double *X;    /* [nv][3] rest positions (m) */
    int *tets;    /* [nt][4] vertex indices, positively oriented */
    int nregions;
    crom_mesh_region *regions;
    int ntri;         /* a surface mesh: triangles instead of tets (nt = 0) */
    int *tris;        /* [ntri][3] vertex indices, consistently oriented */
    double thickness; /* of the shell (m); 0 for a solid */
    int plane;        /* a surface mesh in z = 0 that is a 2-D solid in plane strain (thickness: its depth;
                       * shell.h, crom_shell_material_plane), not a shell */
    crom_scene *scene; /* a rigid-body scene (scene.h): nv = 4 frame vertices per body, no tets or
                        * triangles; NULL for a solid or a shell */
} crom_mesh;

/* 1 for a surface (shell) mesh: triangles, no tets */
static inline int crom_mesh_is_surface(const crom_mesh *m) { return m->ntri > 0; }
/* 1 for a rigid-body scene */
static inline int crom_mesh_is_scene(const crom_mesh *m) { return m->scene != NULL; }


#include <hdf5.h>

/* ------------------------------------------------------------ geometry */

/* Signed volume of tet (a,b,c,d): det[b-a, c-a, d-a] / 6. */
double crom_mesh_tet_volume(const double *a, const double *b, const double *c, const double *d);

/* Mean-ratio quality 12·(3|V|)^(2/3) / Σ edge² in (0, 1] (1 = regular),
 * negated for inverted tets. */
double crom_mesh_tet_quality(const double *a, const double *b, const double *c, const double *d);

/* Sum of the signed tet volumes (m³); a shell: thickness × area. */
double crom_mesh_volume(const crom_mesh *m);

/* Worst and mean quality; *worst_tet gets the index of the worst one. */
void crom_mesh_quality(const crom_mesh *m, double *worst, double *mean, int *worst_tet);

/* Axis-aligned bounding box of the vertices. */
void crom_mesh_bbox(const crom_mesh *m, double lo[3], double hi[3]);

/* The bounding-box diagonal of nv points X[nv][3] (m; 0 when nv < 1): the
 * body size that tolerances and default scales are relative to. */
double crom_mesh_points_diagonal(const double *X, int nv);

/* Lumped vertex volumes: w[v] = sum over the tets t using v of V_t / 4 (m^3)
 * (a shell: thickness × area / 3 over its triangles), so the lumped mass is
 * rho w. Returns the total volume. */
double crom_mesh_vertex_volumes(const crom_mesh *m, double *w);

/* Make every tet positively oriented (swap two vertices of negative ones).
 * Returns CROM_EDATA if a tet is degenerate (|V| <= 1e-14·bbox³). */
int crom_mesh_orient(crom_mesh *m, int *nflipped);

/* Drop vertices no tet uses, renumbering tets and regions. */
int crom_mesh_compact(crom_mesh *m);

/* Check a mesh read from anywhere: finite coordinates, indices in range,
 * positive volumes (a surface: no repeated vertex in a triangle, a positive
 * finite thickness), region indices in range. Returns 0 or CROM_EDATA with
 * the first problem named. */
int crom_mesh_validate(const crom_mesh *m);

/* Boundary triangles (faces used by one tet), outward-oriented: tris gets
 * [ntri][3] vertex indices (malloc'ed), tri_tet (may be NULL) the owning tet. */
int crom_mesh_boundary(const crom_mesh *m, int *ntri, int **tris, int **tri_tet);

/* Where a continuous field (a basis W(X)) is sampled for each vertex
 * [nv][3] (malloc'ed): the rest position X, except for vertices that share
 * their position with another — the copies a cut made (crom-remesh cut) —
 * each of which samples a fraction s (CROM_MESH_CRACK_OFFSET) of the way
 * toward the centroid of its own tets. At X both copies of a crack vertex would get
 * the same displacement and the crack could never open; on their own sides
 * they follow the jump a basis learned from cut data, while an intact body
 * still sees the jump through its shared vertices. Vertex sampling uses
 * this, and every program evaluates a basis on a mesh through
 * crom_model_eval_mesh (lib/rom/model.h), which samples a neural field
 * here (a field with cut features takes only its features here, X at the
 * vertex) and a mesh field on its own mesh at the vertices themselves, so
 * sampling, training, cubature, encoding and decoding agree. *nshifted
 * (may be NULL) gets how many vertices moved; NULL when out of memory.
 *
 * The default s = 1 samples at the centroid of the copy's own tets: a cut
 * follows element faces, so it is jagged at the element scale, and a copy
 * moved only part of the way may still lie across the cut's mean surface,
 * where the field learned the other side's motion. On the Y-cut plate of
 * pipelines/tearing.mk the best fit of the same basis to the full cut run
 * (crom-encode, crom-diff) is 15.8% off at s = 0.25 and 4.2% at s = 1. */
#define CROM_MESH_CRACK_OFFSET 1.0
double *crom_mesh_field_points(const crom_mesh *m, double s, int *nshifted);

/* Deep copy. */
int crom_mesh_copy(const crom_mesh *src, crom_mesh *dst);

void crom_mesh_free(crom_mesh *m);

/* ------------------------------------------------------------ regions
 * Regions are made from predicates (mesh/pred.h) or gmsh physical groups. */

/* The region named `name`, or NULL. */
const crom_mesh_region *crom_mesh_find_region(const crom_mesh *m, const char *name);

/* Add (or replace) a region from an index list (sorted and de-duplicated
 * here). Names must match [A-Za-z0-9_.-]+. */
int crom_mesh_add_region(crom_mesh *m, const char *name, const char *source,
                         const int *idx, int n);

/* Add region from "NAME=PRED"; CROM_EUSAGE if it selects no vertex. */
int crom_mesh_region_spec(crom_mesh *m, const char *spec);

/* Resolve a reference to vertices: a stored region name, an inline
 * predicate, or one vertex by its index, "#N". *idx is malloc'ed. CROM_EUSAGE for an unknown name (listing the
 * known ones) or an empty selection. */
int crom_mesh_select(const crom_mesh *m, const char *ref, int **idx, int *n);

/* ------------------------------------------------------------ files */

/* Write vertices, tets (a surface: triangles with their thickness) and
 * regions under loc (the root of a crom/mesh file, or the /mesh group of a
 * trajectory). */
int crom_mesh_write(hid_t loc, const crom_mesh *m);

/* Read and validate a tet mesh stored under loc; a surface mesh is refused
 * (CROM_EUSAGE, "the mesh is a shell surface ..."). crom_mesh_read_any
 * takes both. */
int crom_mesh_read(hid_t loc, crom_mesh *m);
int crom_mesh_read_any(hid_t loc, crom_mesh *m);
/* … taking what flags allows: CROM_MESH_SURFACES, CROM_MESH_SCENES (below);
 * crom_mesh_read is flags 0, crom_mesh_read_any CROM_MESH_SURFACES. */
int crom_mesh_read_flags(hid_t loc, int flags, crom_mesh *m);

/* Read the crom/mesh at path (NULL or "-": stdin) or, when flags has
 * CROM_MESH_CARRIERS (1), also the /mesh of a crom/trajectory or
 * crom/cubature. A surface mesh is refused (CROM_EUSAGE, "... is a shell
 * surface; this program takes tet meshes") unless flags has
 * CROM_MESH_SURFACES, and a scene unless it has CROM_MESH_SCENES. When history is not NULL it takes over the input's
 * history attribute (malloc'ed; NULL if it had none), for the output's
 * provenance. */
#define CROM_MESH_CARRIERS 1
#define CROM_MESH_SURFACES 2
#define CROM_MESH_SCENES 4 /* also accept a rigid-body scene (scene.h) */
int crom_mesh_load(const char *path, int flags, crom_mesh *m, char **history);

#define CROM_MESH_SCHEMA "crom/mesh"
#define CROM_MESH_VERSION 1

#endif
