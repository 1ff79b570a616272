/* remesh.h — meshes for run-time topology changes (LiCROM §4–6): cut a mesh
 * along a surface, punch material out, swap in another mesh placed in the
 * same frame, refine uniformly.
 *
 * Reduced simulations switch between such meshes mid-run. The state lives in
 * the latent q, not in the mesh, so the meshes need no vertex correspondence;
 * they only share the reference frame and the named regions that boundary
 * conditions refer to. Every output is a valid crom/mesh: positively
 * oriented, compacted, validated. Functions return 0 or an error code with a
 * message (err.h); `out` is untouched on failure. Warnings (not errors) go to
 * an optional callback so that only bin/ prints.
 */
#ifndef CROM_REMESH_H
#define CROM_REMESH_H

#include "mesh/gmsh.h"
#include "mesh/mesh.h"

/* Receives one warning sentence (no program prefix, no newline). */
typedef void (*crom_remesh_warn_fn)(void *ctx, const char *msg);

/* ---------------------------------------------------------------- cut
 * The cut surface is a set of ribbons: segment k of seg (A_u, A_v, B_u, B_v)
 * lies in the plane perpendicular to `axis` and is extruded along that axis
 * through the whole mesh. (u, v) are the two other coordinates in x, y, z
 * order: (y, z) for axis x, (x, z) for axis y, (x, y) for axis z.
 * Stage K of N keeps the first K/N of each segment's length from A.
 *
 * An interior face shared by tets P and Q is cut when the segment between
 * the centroids of P and Q, projected along the axis, crosses a (partial)
 * segment (a centroid exactly on a segment's line counts as lying on its
 * left, so every tet has a side). The cut follows element faces, so it is jagged at the
 * element scale: its area exceeds the ribbon's, while its area vector
 * projected on the ribbon normal matches the ribbon's exactly when the cut
 * spans the body. Then the tets around each vertex are grouped into
 * components connected through un-cut faces; the first component (lowest
 * tet index) keeps the vertex, each further one gets a copy, which inherits
 * the vertex's region memberships. */
typedef struct {
    int axis;           /* extrusion axis: 0 x, 1 y (default), 2 z */
    int nseg;
    const double *seg;  /* [nseg][4]: A_u, A_v, B_u, B_v (m) */
    int stages, stage;  /* 0 <= stage <= stages, stages >= 1 */
} crom_remesh_cut_opts;

typedef struct {
    int faces_cut;      /* interior faces cut */
    int verts_dup;      /* vertex copies added */
    int components;     /* connected components of the result */
} crom_remesh_cut_stats;

/* Mark cut faces: (*cut)[4t + l] = 1 when face l of tet t (the face opposite
 * its vertex l) is interior and cut; *nfaces counts each cut face once.
 * *cut is malloc'ed [4 nt]. CROM_EUSAGE for bad options (axis, stage > stages,
 * zero-length or non-finite segment), CROM_EDATA for a non-manifold mesh. */
int crom_remesh_cut_faces(const crom_mesh *m, const crom_remesh_cut_opts *c, unsigned char **cut,
                          int *nfaces);

/* Duplicate vertices across the marked faces (cut as from
 * crom_remesh_cut_faces); *ndup (may be NULL) gets the number of copies. */
int crom_remesh_split(const crom_mesh *m, const unsigned char *cut, crom_mesh *out, int *ndup);

/* cut_faces + split + validation. Nothing cut (stage 0, a ribbon missing the
 * mesh): out is a copy of m and warn says so. st may be NULL. */
int crom_remesh_cut(const crom_mesh *m, const crom_remesh_cut_opts *c, crom_mesh *out,
                    crom_remesh_cut_stats *st, crom_remesh_warn_fn warn, void *ctx);

/* ---------------------------------------------------------------- punch */

enum { CROM_REMESH_PUNCH_SPHERE = 1, CROM_REMESH_PUNCH_BOX = 2 };
typedef struct {
    int kind;     /* CROM_REMESH_PUNCH_SPHERE or CROM_REMESH_PUNCH_BOX */
    double a[6];  /* sphere: CX,CY,CZ,R; box: X0,Y0,Z0,X1,Y1,Z1 */
} crom_remesh_punch_shape;

/* Remove the tets whose centroid lies in any shape (closed sphere or box),
 * drop unused vertices and renumber regions; a region left empty is removed
 * with a warning. *nremoved (may be NULL) gets the number of tets removed.
 * CROM_EUSAGE for a bad shape (R <= 0, X0 >= X1, non-finite), CROM_EDATA if
 * nothing would remain. */
int crom_remesh_punch(const crom_mesh *m, const crom_remesh_punch_shape *s, int ns, crom_mesh *out,
                      int *nremoved, crom_remesh_warn_fn warn, void *ctx);

/* ---------------------------------------------------------------- swap */

typedef struct {
    double scale;        /* uniform scale > 0 (1 = none) */
    double axis[3];      /* rotation axis (normalized here; zero = no rotation) */
    double deg;          /* rotation angle in degrees, right-handed about axis */
    double translate[3]; /* m */
    int fit;             /* scale and centre onto the reference bounding box */
} crom_remesh_xform;

/* Identity transform. */
void crom_remesh_xform_init(crom_remesh_xform *x);

/* Transform m in place: X <- R(s X) + t (scale, rotate about the origin,
 * translate). With fit, s is replaced by (largest extent of ref) / (largest
 * extent of R m) and t by ref's box centre minus the centre of s R m, plus
 * x->translate. Re-orients the tets. CROM_EUSAGE for a bad transform, ref
 * NULL with fit, or a degenerate result. */
int crom_remesh_transform(crom_mesh *m, const crom_remesh_xform *x, const crom_mesh *ref);

/* out = other transformed into the frame of in. other keeps its regions;
 * each region of in whose source is a predicate (or names such a region of
 * in) is re-evaluated on out under the same name, replacing one of other's
 * own of that name (warned). Regions from gmsh groups, and re-evaluated
 * regions that select nothing, are not transferred (warned). */
int crom_remesh_swap(const crom_mesh *in, const crom_mesh *other, const crom_remesh_xform *x,
                     crom_mesh *out, crom_remesh_warn_fn warn, void *ctx);

/* ---------------------------------------------------------------- refine */

/* Uniform 1:8 refinement, `times` times (1..6), by gmsh's mesh refinement
 * of the tets loaded as a discrete volume (gmshModelMeshRefine: a midpoint
 * on every edge, each tet into 4 corner tets and 4 of the inner octahedron).
 * Volume is preserved to round-off (straight-sided tets), every vertex is
 * kept with its index, and a midpoint belongs to a region when both ends
 * of its edge do. gmsh's messages go to log (NULL: dropped) with log_ctx. */
int crom_remesh_refine(const crom_mesh *m, int times, crom_mesh *out, crom_gmsh_log_fn log, void *log_ctx);

/* ---------------------------------------------------------------- helpers */

/* Connected components of the vertex graph (tets sharing a vertex are
 * connected); comp (may be NULL) gets each vertex's label in [0, count).
 * Returns the count, or -1 on allocation failure. */
int crom_remesh_components(const crom_mesh *m, int *comp);

/* Remove the region `name` if present (returns 1 if removed, else 0). */
int crom_remesh_remove_region(crom_mesh *m, const char *name);

#endif
