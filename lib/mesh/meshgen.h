/* meshgen.h — tetrahedral meshes from shapes and files, through gmsh.
 *
 * Shapes are centred at the origin: box and plate (extents dims), sphere
 * (radius), cylinder (radius, height, axis y), superquadric
 * |x/a|^p + |y/b|^p + |z/c|^p <= 1 with (2a, 2b, 2c) = dims (p = 2: ellipsoid,
 * large p: box with rounded edges). Imports: a closed .stl/.obj surface
 * (meshed inside), or a .msh/.geo volume (gmsh physical groups become named
 * regions). Nothing is printed: gmsh's messages go to opts.log.
 */
#ifndef CROM_MESHGEN_H
#define CROM_MESHGEN_H

#include "mesh/gmsh.h"
#include "mesh/mesh.h"

enum { CROM_MESHGEN_BOX, CROM_MESHGEN_PLATE, CROM_MESHGEN_SPHERE, CROM_MESHGEN_CYLINDER,
       CROM_MESHGEN_SUPERQUADRIC, CROM_MESHGEN_IMPORT, CROM_MESHGEN_SHEET, CROM_MESHGEN_DISK };

typedef struct {
    int shape;
    double dims[3];      /* extents (m) for box/plate/superquadric */
    double radius;       /* sphere/cylinder (m) */
    double height;       /* cylinder (m) */
    double exponent;     /* superquadric p >= 1 */
    double size;         /* target edge length (m) */
    double thickness;    /* sheet, disk, shell import: the shell's thickness (m) */
    int unstructured;    /* sheet: gmsh's 2-D mesh of the rectangle instead of rows */
    const char *file;    /* import */
    int algorithm;       /* gmsh Mesh.Algorithm3D: 1 Delaunay (default, repeatable), 10 HXT */
    int optimize;        /* run gmsh's tet optimizer (default 1) */
    int remesh;          /* .stl/.obj: let gmsh remesh the surface at size (1), or keep its
                            triangles, subdivided to at most size (0); CROM_MESHGEN_REMESH_AUTO
                            (the default): crom_meshgen_plan decides */
    crom_gmsh_log_fn log; /* receives gmsh's messages (NULL: dropped) */
    void *log_ctx;
} crom_meshgen_opts;

/* opts.remesh: decide from the surface (crom_meshgen_plan) */
#define CROM_MESHGEN_REMESH_AUTO (-1)

/* A surface whose median edge is below size / CROM_MESHGEN_REMESH_FINER is
 * "much finer" than the target: keeping its triangles would give a mesh far
 * finer (more vertices) than asked, so an automatic import remeshes it. */
#define CROM_MESHGEN_REMESH_FINER 2.0

/* What crom_meshgen_plan found about an imported .stl/.obj surface. */
typedef struct {
    int triangles;       /* triangles of the file's surface */
    double median_edge;  /* its median edge length (m) */
    int finer;           /* 1 if median_edge < size / CROM_MESHGEN_REMESH_FINER */
    int automatic;       /* 1 if remesh was CROM_MESHGEN_REMESH_AUTO and was decided here */
} crom_meshgen_plan_info;

/* Resolve o->remesh before crom_meshgen for an .stl/.obj import: read the
 * surface, measure it into *info, and when o->remesh is
 * CROM_MESHGEN_REMESH_AUTO set it to 1 if the surface is much finer than
 * o->size, else 0. Other shapes and files: only CROM_MESHGEN_REMESH_AUTO
 * becomes 0, *info is zeroed. Returns 0 or the errors of crom_surface_read
 * (mesh/surface.h). */
int crom_meshgen_plan(crom_meshgen_opts *o, crom_meshgen_plan_info *info);

/* Defaults for a shape (dims, radius, size). */
void crom_meshgen_defaults(crom_meshgen_opts *o, int shape);

/* Shape name ("box") to CROM_MESHGEN_BOX ..., or -1. */
int crom_meshgen_shape(const char *name);

/* A sheet (a shell surface, no gmsh): the rectangle dims[0] × dims[1] in
 * the xy-plane centred at the origin, in rows of near-equilateral triangles
 * of edge about o->size (rows alternate between n + 1 vertices and n + 2
 * with half-triangles at the ends, so the sides are straight), normals
 * towards +z, thickness o->thickness. */
int crom_meshgen_sheet(const crom_meshgen_opts *o, crom_mesh *m);

/* A disk (a shell surface): radius o->radius in the xy-plane centred at
 * the origin, meshed by gmsh (2-D, edges about o->size), normals towards
 * +z, thickness o->thickness. */
int crom_meshgen_disk(const crom_meshgen_opts *o, crom_mesh *m);

/* A shell from the triangles of an .stl/.obj surface (open or closed, o->file):
 * welded, subdivided until no edge exceeds o->size, thickness o->thickness.
 * CROM_EDATA when it is not an oriented manifold (an edge shared by more
 * than two triangles, or by two running the same way). */
int crom_meshgen_shell_import(const crom_meshgen_opts *o, crom_mesh *m);

/* Mesh the shape or file (a sheet: crom_meshgen_sheet, or gmsh's with
 * unstructured; a disk:
 * crom_meshgen_disk; an import with a
 * thickness: crom_meshgen_shell_import). Tets come out positively oriented and compacted;
 * gmsh physical groups (imports) become regions. Returns 0, CROM_EUSAGE for
 * bad parameters, CROM_ENOINPUT for a missing file, CROM_EDATA for a surface
 * that is open or a file gmsh cannot mesh. */
int crom_meshgen(const crom_meshgen_opts *o, crom_mesh *m);

#endif
