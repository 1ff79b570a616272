/* meshgen.h — tetrahedral meshes from shapes and files, through gmsh.
 *
 * Shapes are centred at the origin: box and plate (extents dims), sphere
 * (radius), cylinder (radius, height, axis y), superquadric
 * |x/a|^p + |y/b|^p + |z/c|^p <= 1 with (2a, 2b, 2c) = dims (p = 2: ellipsoid,
 * large p: box with rounded edges). Imports: a closed .stl/.obj surface
 * (meshed inside), or a .msh/.geo volume (gmsh physical groups become named
 * regions). Nothing is printed to stdout.
 */
#ifndef CROM_MESHGEN_H
#define CROM_MESHGEN_H

#include "mesh.h"

enum { CROM_SHAPE_BOX, CROM_SHAPE_PLATE, CROM_SHAPE_SPHERE, CROM_SHAPE_CYLINDER,
       CROM_SHAPE_SUPERQUADRIC, CROM_SHAPE_IMPORT };

typedef struct {
    int shape;
    double dims[3];      /* extents (m) for box/plate/superquadric */
    double radius;       /* sphere/cylinder (m) */
    double height;       /* cylinder (m) */
    double exponent;     /* superquadric p >= 1 */
    double size;         /* target edge length (m) */
    const char *file;    /* import */
    int algorithm;       /* gmsh Mesh.Algorithm3D: 1 Delaunay (default, repeatable), 10 HXT */
    int optimize;        /* run gmsh's tet optimizer (default 1) */
    int remesh;          /* .stl/.obj: let gmsh remesh the surface at size (1), or keep its
                            triangles, subdivided to at most size (0, default) */
    int verbose;         /* gmsh messages on stderr */
} crom_meshgen_opts;

/* Defaults for a shape (dims, radius, size). */
void crom_meshgen_defaults(crom_meshgen_opts *o, int shape);

/* Shape name ("box") to CROM_SHAPE_*, or -1. */
int crom_meshgen_shape(const char *name);

/* Mesh the shape or file. Tets come out positively oriented and compacted;
 * gmsh physical groups (imports) become regions. Returns 0, CROM_EUSAGE for
 * bad parameters, CROM_ENOINPUT for a missing file, CROM_EDATA for a surface
 * that is open or a file gmsh cannot mesh. */
int crom_meshgen(const crom_meshgen_opts *o, crom_mesh *m);

/* Read a triangle surface (.stl ASCII/binary or .obj): [nv][3] and [nt][3].
 * Exposed for tests. */
int crom_surface_read(const char *path, int *nv, double **V, int *nt, int **T);

/* 0 if every edge of the surface is shared by exactly two triangles with
 * opposite orientation (closed, oriented, manifold); else CROM_EDATA naming
 * the problem. */
int crom_surface_check_closed(int nv, int nt, const int *T, const char *name);

#endif
