/* export.h — writers of files other tools open: VTK XML unstructured grids
 * (.vtu) and collections (.pvd) for ParaView and meshio, surface meshes as
 * OBJ and PLY. All write to an open FILE; the caller makes it atomic
 * (crom_fileout). */
#ifndef CROM_EXPORT_H
#define CROM_EXPORT_H

#include <stdio.h>

#include "mesh.h"

/* Per-vertex data attached to an export. */
typedef struct {
    const char *name;   /* "displacement" */
    int ncomp;          /* 1 or 3 */
    const double *data; /* [nv][ncomp] */
} crom_pointfield;

/* A VTU of the mesh on its rest positions, with the given point fields
 * (binary, base64-encoded inline) and one UInt8 mask per named region
 * ("region_NAME"). Returns 0 or CROM_EIO. */
int crom_export_vtu(FILE *f, const crom_mesh *m, const crom_pointfield *fields, int nfields);

/* A ParaView collection: file[i] at time[i]. */
int crom_export_pvd(FILE *f, const double *time, const char *const *file, int n);

/* Boundary surface, deformed by disp ([nv][3] or NULL), as Wavefront OBJ. */
int crom_export_obj(FILE *f, const crom_mesh *m, const double *disp);

/* The same as binary little-endian PLY, with per-vertex float property
 * `u` = |displacement| for colouring. */
int crom_export_ply(FILE *f, const crom_mesh *m, const double *disp);

#endif
