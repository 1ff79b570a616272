/* locate.h — point location in tetrahedral meshes and barycentric
 * interpolation of vertex fields.
 *
 * A locator hashes every tet's bounding box into a uniform grid of about one
 * cell per tet, so finding the tet that contains a point tests the few tets
 * registered in the point's cell: O(1) expected for meshes of reasonable
 * quality. A point that no tet contains (outside the mesh, or in a gap of a
 * non-convex mesh) is mapped to the NEAREST tet: the tet whose closest point
 * to it is nearest (found by searching grid shells outwards), with the
 * barycentric coordinates of that closest point, i.e. coordinates clamped onto
 * the tet (all in [0, 1], summing to 1). So interpolating a vertex field
 * outside the mesh extends it by its value at the nearest boundary point.
 *
 * The locator borrows the mesh's arrays (X, tets): keep the mesh alive and
 * unchanged while the locator is used. Queries are read-only and may run in
 * several threads at once.
 */
#ifndef CROM_LOCATE_H
#define CROM_LOCATE_H

#include <stddef.h>

#include "mesh/mesh.h"

typedef struct {
    const double *X;   /* [nv][3] the mesh's rest positions (borrowed) */
    const int *tets;   /* [nt][4] (borrowed) */
    int nv, nt;
    double lo[3];      /* grid origin */
    double h[3];       /* cell size per axis */
    int n[3];          /* cells per axis */
    int *start;        /* [ncells + 1] CSR offsets into items */
    int *items;        /* tet indices per cell */
    double *Tinv;      /* [nt][9] inverse of [X1-X0, X2-X0, X3-X0] (row-major) */
} crom_locator;

/* Build a locator for mesh m (validated, nt >= 1). Returns 0, CROM_EDATA for
 * a degenerate tet, or CROM_EINTERNAL when out of memory. */
int crom_locate_init(crom_locator *L, const crom_mesh *m);

/* Free what init allocated; L becomes empty (safe on a zeroed locator). */
void crom_locate_free(crom_locator *L);

/* Locate point p: *tet gets the containing tet and bary[4] its barycentric
 * coordinates (weights of the tet's vertices 0..3, summing to 1). Returns 1 if
 * a tet contains p (every coordinate >= -1e-12), 0 if p is outside every tet
 * (then the nearest tet and the clamped coordinates of its closest point).
 * *dist (may be NULL) gets the distance from p to that tet (0 inside). */
int crom_locate_point(const crom_locator *L, const double p[3], int *tet,
                      double bary[4], double *dist);

/* Barycentric coordinates of p in tet t (unclamped; may be negative). */
void crom_locate_bary(const crom_locator *L, int t, const double p[3], double bary[4]);

/* Interpolate a vertex field f [nv][dim] at n points P [n][3] into out
 * [n][dim] (row-major), locating each point as crom_locate_point does.
 * *noutside (may be NULL) gets how many points lay outside every tet. */
void crom_locate_interp(const crom_locator *L, size_t n, const double *P,
                        int dim, const double *f, double *out, size_t *noutside);

/* Squared distance from p to the triangle (a, b, c). */
double crom_locate_tri_dist2(const double a[3], const double b[3], const double c[3], const double p[3]);

#endif
