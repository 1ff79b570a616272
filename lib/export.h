/* export.h — writers of files other tools open: VTK XML unstructured grids
 * (.vtu) and collections (.pvd) for ParaView and meshio, XDMF 3 (XML + HDF5)
 * series, surface meshes as OBJ and PLY. All text/binary writers write to an
 * open FILE; the caller makes it atomic (crom_fileout, crom_out). */
#ifndef CROM_EXPORT_H
#define CROM_EXPORT_H

#include <stdio.h>

#include <hdf5.h>

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

/* ------------------------------------------------------------------ XDMF
 * An XDMF 3 file is light XML describing grids whose arrays (heavy data) live
 * in an HDF5 file beside it. crom's layout of that HDF5 file:
 *   /mesh/vertices [nv,3] f64, /mesh/tets [nt,4] i32, /mesh/region_NAME [nv]
 *   i32 (0/1); further meshes of a run that switches meshes in /mesh_1, ...
 *   /time [F] f64; /displacement/00000 [nv,3] f64 (and /velocity/00000)
 *   per frame: one dataset per frame, so that every reader (ParaView's
 *   Xdmf3 reader, meshio's TimeSeriesReader) can reference it whole. */

/* Write mesh m as the group `group` ("mesh", "mesh_1") of the heavy-data
 * file: vertices, tets and one 0/1 int32 mask per region. */
int crom_xdmf_write_mesh(hid_t loc, const char *group, const crom_mesh *m);

/* Write frame k's point field `name` ([nv][3]) as /NAME/%05d. */
int crom_xdmf_write_frame(hid_t loc, const char *name, int k, int nv, const double *data);

/* The XML: with nframes = 0 one Uniform grid of meshes[0] (a bare mesh);
 * otherwise a Temporal collection of nframes Uniform grids, frame k at
 * time[k] on meshes[mesh_of[k]] (group groups[mesh_of[k]]), with Node
 * attributes fields[0..nfields) (3-vectors, datasets /NAME/%05d) and the
 * region masks. h5name is the heavy-data file name relative to the XML. */
int crom_export_xdmf(FILE *f, const char *h5name, const crom_mesh *const *meshes,
                     const char *const *groups, const double *time, const int *mesh_of, int nframes,
                     const char *const *fields, int nfields);

#endif
