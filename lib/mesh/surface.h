/* surface.h — triangle surfaces: what .stl and .obj files hold, what
 * crom-mesh meshes the inside of (meshgen.c) and what point clouds are
 * sampled in (cloud.c). Vertices [nv][3] in metres, triangles [nt][3] of
 * 0-based vertex indices, counter-clockwise seen from outside.
 */
#ifndef CROM_SURFACE_H
#define CROM_SURFACE_H

#include <stddef.h>

typedef struct {
    double *V;       /* [nv][3] */
    int *T;          /* [nt][3] */
    int nv, nt;
    size_t capv, capt; /* room for vertices and triangles (base/array.h) */
} crom_surface;

/* Append a vertex or a triangle (the arrays grow as needed). Return 0 or
 * CROM_EINTERNAL when out of memory. */
int crom_surface_add_vertex(crom_surface *s, const double p[3]);
int crom_surface_add_tri(crom_surface *s, int a, int b, int c);

/* Merge exactly coincident vertices (an STL file repeats them per
 * triangle), renumbering the triangles. Returns 0 or CROM_EINTERNAL. */
int crom_surface_weld(crom_surface *s);

/* Read a surface from an .stl (ASCII or binary) or .obj file into out
 * (emptied first), welded. Returns 0, CROM_ENOINPUT, CROM_EUSAGE (another
 * extension) or CROM_EDATA naming the problem. */
int crom_surface_read(const char *path, crom_surface *out);

/* 0 if every edge of the surface is shared by exactly two triangles with
 * opposite orientation (closed, oriented, manifold); else CROM_EDATA naming
 * the problem, with name (the file) in front. */
int crom_surface_check_closed(const crom_surface *s, const char *name);

/* The same, but boundary edges are allowed (an open surface: a shell's). */
int crom_surface_check_oriented(const crom_surface *s, const char *name);

/* Subdivide every triangle 1-to-4 at its edge midpoints until no edge is
 * longer than h (at most 8 times); CROM_EUSAGE when that would take more
 * than 4M triangles. */
int crom_surface_refine(crom_surface *s, double h);

/* Median edge length (m) over the 3 nt half-edges (the median over edges
 * of a closed surface); 0 for an empty surface, -1 when out of memory. */
double crom_surface_median_edge(const crom_surface *s);

void crom_surface_free(crom_surface *s);

#endif
