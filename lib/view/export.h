/* export.h — writers of files other tools open: VTK XML unstructured grids
 * (.vtu) and collections (.pvd) for ParaView and meshio, XDMF 3 (XML + HDF5)
 * series, gmsh MSH files, surface meshes as OBJ, PLY and STL, with per-tet
 * cell data (volume, J, energy density, stress). A shell (a surface mesh,
 * mesh.h) is written as its triangles, with per-triangle cell data (area,
 * area ratio J, membrane energy density and stress). The writers of one format
 * write to an open FILE (the caller makes it atomic: crom_fileout, crom_out);
 * the whole-file functions below them (crom_export_write, series, sinks)
 * are atomic themselves. Nothing here prints. */
#ifndef CROM_EXPORT_H
#define CROM_EXPORT_H

#include <stdio.h>

#include <hdf5.h>

#include "io/io.h"
#include "mesh/mesh.h"
#include "phys/fem.h"

/* Per-cell fields of a frame (cell data), recomputed for each frame by
 * crom_export_cells_eval from its mesh and displacement. Per tet, with the
 * element kernel of fem.h: rest volume (m³), J = det F, strain-energy
 * density Ψ(F) (J/m³) and von Mises Cauchy stress (Pa); the last two only
 * with a material. Per triangle of a shell, with the membrane kernel of
 * shell.h: rest area (m²), J = deformed over rest area, and with a material
 * (its E and ν, the mesh's thickness) the membrane (stretching) energy per
 * rest volume t A (J/m³) and the von Mises equivalent of its membrane
 * stress (crom_shell_tri_mises, Pa); bending, which lives on edges, is not
 * a cell field. */
typedef struct {
    double *measure, *J, *psi, *mises; /* [cap]: measure the rest volume (tets) or area (triangles) */
    int cap;
    const crom_material *mat;          /* NULL: no psi, no mises */
    long degenerate;                   /* degenerate rest cells met (NaN fields) */
} crom_export_cells;

/* Evaluate the cell fields of mesh m (tets, or a shell's triangles)
 * displaced by u (NULL: at rest) into c (buffers grown as needed). Returns
 * 0 or CROM_EINTERNAL. */
int crom_export_cells_eval(crom_export_cells *c, const crom_mesh *m, const double *u);
/* Free the buffers (c can be evaluated again). */
void crom_export_cells_free(crom_export_cells *c);

/* One state of a body: the mesh on its rest positions, displaced by u with
 * velocity v ([nv][3] each; u == NULL: the bare mesh, v may be NULL), at
 * time `time` (NAN: none), with cell fields (NULL: none; for a bare mesh
 * only the volume is written). */
typedef struct {
    const crom_mesh *mesh;
    const double *u, *v;
    double time;
    const crom_export_cells *cells;
} crom_export_frame;

/* The material the cell fields use: E and nu when given (not NaN), else the
 * input's root attributes `youngs` and `poisson` (trajectories and reduced
 * runs carry them). *known = 0 when neither names both (a usage error when
 * only one of E, nu was given and the input lacks the other), -1 when the
 * run had regions of other materials (its `scenario` attribute; the cell
 * fields take one material, which would misstate their energy and stress)
 * and E, nu were not given. Returns 0,
 * CROM_EUSAGE (values out of range) or that error. */
int crom_export_material(crom_material *m, int *known, const crom_in *in, double E, double nu);

/* The shortest decimal text of x that reads back (strtod) as x: "%.15g",
 * "%.16g" or "%.17g", the first that does. */
void crom_export_number(char *buf, size_t n, double x);

/* A VTU of fr: the mesh on its rest positions (cells: VTK_TETRA, or
 * VTK_TRIANGLE for a shell); point data 'displacement' and 'velocity' (when
 * given) and one UInt8 mask per named region ("region_NAME"); cell data
 * 'volume' (a shell: 'area'), and with a displacement 'J', 'energy_density',
 * 'von_mises_stress' (those of fr->cells that exist; a shell's is its membrane's); the
 * frame's time as field data 'TimeValue' (when not NaN). Arrays binary,
 * base64-encoded inline. Returns 0, CROM_EDATA (too large for 32-bit
 * headers) or CROM_EIO. */
int crom_export_vtu(FILE *f, const crom_export_frame *fr);

/* A ParaView collection: file[i] (relative to the collection) at time[i].
 * Returns 0 or CROM_EIO. */
int crom_export_pvd(FILE *f, const double *time, const char *const *file, int n);

/* The surface a picture or a surface file shows, as triangles [ntri][3]
 * (malloc'ed into *tris): the boundary of a tet mesh, outward oriented
 * (crom_mesh_boundary), or a copy of a shell's own triangles. Returns 0 or
 * CROM_EINTERNAL. */
int crom_export_surface(const crom_mesh *m, int *ntri, int **tris);

/* The same triangles (mesh vertex indices) and the compact list of the
 * vertices they use: sv [nsv] (in order of first use) and map [nv] (a mesh
 * vertex's place in sv, or -1), all malloc'ed. Returns 0 or CROM_EINTERNAL. */
int crom_export_surface_compact(const crom_mesh *m, int *ntri, int **tris, int *nsv, int **sv, int **map);

/* The surface (crom_export_surface), deformed by disp ([nv][3] or NULL), as
 * Wavefront OBJ. Returns 0, CROM_EINTERNAL or CROM_EIO. */
int crom_export_obj(FILE *f, const crom_mesh *m, const double *disp);

/* The same as binary little-endian PLY, with the per-vertex float property
 * `displacement_magnitude` = |u| for colouring (not `u`, which readers take
 * for a texture coordinate). Returns as crom_export_obj. */
int crom_export_ply(FILE *f, const crom_mesh *m, const double *disp);

/* The same as an STL (ASCII, written by gmsh), outward oriented (a shell:
 * as its triangles are). Returns 0,
 * CROM_EDATA (gmsh failed, its message kept), CROM_ECANTCREAT (no temporary
 * file) or CROM_EIO. Uses gmsh's one global session: not reentrant. */
int crom_export_stl(FILE *f, const crom_mesh *m, const double *disp);

/* ----------------------------------------------------------------- MSH
 * A gmsh MSH 4.1 file (ASCII, written by gmsh through its API): the mesh as
 * one discrete volume of linear tetrahedra (node tags 1..nv, element tags
 * 1..nt; a shell: one discrete surface of its triangles) and, for a series, the views "displacement" (m) and "velocity"
 * (m/s) as NodeData, one step per frame with its time. gmsh has one global
 * session, so one crom_export_msh at a time. */
typedef struct {
    int view[2];   /* displacement, velocity (made by the first frame) */
    int n, nv;     /* frames added, vertices */
    size_t *tags;  /* [nv] node tags 1..nv */
} crom_export_msh;

/* Start gmsh (no terminal output) and put mesh m into it. Returns 0,
 * CROM_EDATA (gmsh failed) or CROM_EINTERNAL; on failure gmsh is stopped. */
int crom_export_msh_open(crom_export_msh *w, const crom_mesh *m);

/* Add one frame (time t, displacement u and velocity v, [nv][3]) as the
 * next step of the two views. Returns 0 or CROM_EDATA. */
int crom_export_msh_frame(crom_export_msh *w, double t, const double *u, const double *v);

/* Write the file to path ("-": stdout) atomically and stop gmsh. Returns 0
 * or an error naming path; gmsh is stopped either way. */
int crom_export_msh_finish(crom_export_msh *w, const char *path);

/* Stop gmsh without writing. */
void crom_export_msh_abort(crom_export_msh *w);

/* ------------------------------------------------------------------ XDMF
 * An XDMF 3 file is light XML describing grids whose arrays (heavy data) live
 * in an HDF5 file beside it. crom's layout of that HDF5 file:
 *   /mesh/vertices [nv,3] f64, /mesh/tets [nt,4] i32 and /mesh/volume [nt]
 *   f64 (a shell: /mesh/triangles [ntri,3] and /mesh/area [ntri]),
 *   /mesh/region_NAME [nv] i32 (0/1); further meshes of a run that switches
 *   meshes in /mesh_1, ...
 *   /time [F] f64; /displacement/00000 [nv,3] f64 (and /velocity/00000)
 *   per frame: one dataset per frame, so that every reader (ParaView's
 *   Xdmf3 reader, meshio's TimeSeriesReader) can reference it whole. */

/* Write mesh m as the group `group` ("mesh", "mesh_1") of the heavy-data
 * file: vertices, tets and their rest volumes (a shell: triangles and their
 * rest areas) and one 0/1 int32 mask per region. Returns 0 or an HDF5 error
 * naming the dataset. */
int crom_export_xdmf_write_mesh(hid_t loc, const char *group, const crom_mesh *m);

/* Write frame k's field `name` ([n][ncomp], per vertex or per cell) as
 * /NAME/%05d with its units. Returns 0 or an HDF5 error. */
int crom_export_xdmf_write_frame(hid_t loc, const char *name, int k, int n, int ncomp, const double *data,
                                 const char *units);

/* The XML: with nframes = 0 one Uniform grid of meshes[0] (a bare mesh);
 * otherwise a Temporal collection of nframes Uniform grids, frame k at
 * time[k] on meshes[mesh_of[k]] (group groups[mesh_of[k]]), with Node
 * attributes fields[0..nfields) (3-vectors, datasets /NAME/%05d), Cell
 * attributes cfields[0..ncfields) (scalars per cell, /NAME/%05d), and in
 * every grid the region masks and the Cell attribute 'volume' (a shell:
 * 'area') of its mesh group. A tet mesh is a Tetrahedron topology, a shell a
 * Triangle one. h5name is the heavy-data file name relative to the XML. Returns
 * 0 or CROM_EIO. */
int crom_export_xdmf(FILE *f, const char *h5name, const crom_mesh *const *meshes,
                     const char *const *groups, const double *time, const int *mesh_of, int nframes,
                     const char *const *fields, int nfields, const char *const *cfields, int ncfields);

/* -------------------------------------------------------- whole files
 * What crom-export writes, each file atomic (a temporary file renamed on
 * success, nothing left on failure). */

/* Create directory path and its parents (mkdir -p). Returns 0, or
 * CROM_ECANTCREAT naming the part that cannot be made or is not a
 * directory. */
int crom_export_mkdir(const char *path);

/* Write fr to path ("-": stdout) in format "vtu" (also "pvd": one VTU),
 * "obj", "ply" (binary: refused on a terminal), "stl" or "msh" (its mesh
 * and, with a displacement, the one frame as a series of one). Returns 0 or
 * an error naming path. */
int crom_export_write(const char *path, const char *format, const crom_export_frame *fr);

/* A numbered series of files, one per frame (STEM_00000.EXT, ...), with a
 * ParaView collection (.pvd) of them when asked. */
typedef struct {
    char dir[1024];   /* directory of the frame files */
    char pvd[1300];   /* the collection, "" for none */
    char rel[260];    /* the frames' directory relative to the collection's: "" or "STEM/" */
    char stem[256];   /* file name stem of the frames */
    char ext[8];      /* their extension */
    char path[1400];  /* path of the next frame: crom_export_series_path */
    double *time;     /* [n] times of the frames written */
    char **file;      /* [n] their names relative to the collection */
    int n;
} crom_export_series;

enum {
    CROM_EXPORT_SERIES_FILES,    /* out is a directory of NAME_%05d.EXT */
    CROM_EXPORT_SERIES_PVD_DIR,  /* the same and the collection out/NAME.pvd */
    CROM_EXPORT_SERIES_PVD_FILE  /* the collection at out = DIR/STEM.pvd, frames
                             DIR/STEM/STEM_%05d.EXT beside it (name unused) */
};

/* Start a series of the given kind (directories created as needed).
 * Returns 0, CROM_EUSAGE (a name too long, or a collection name that is
 * only ".pvd") or CROM_ECANTCREAT (a directory cannot be made, or the
 * collection's path is a directory). */
int crom_export_series_open(crom_export_series *s, const char *out, const char *name, const char *ext, int kind);

/* The path the next frame's file goes to (valid until the next call). */
const char *crom_export_series_path(crom_export_series *s);

/* Record that the next frame (at time t) was written to its path. Returns 0
 * or CROM_EINTERNAL. */
int crom_export_series_add(crom_export_series *s, double t);

/* crom_export_write of fr to the next frame's path in format, then
 * crom_export_series_add of its time. */
int crom_export_series_write(crom_export_series *s, const char *format, const crom_export_frame *fr);

/* Write the collection (if any) of the frames recorded. Returns 0 or an
 * error naming it. */
int crom_export_series_finish(crom_export_series *s);

/* Free the records (the files stay). */
void crom_export_series_free(crom_export_series *s);

/* An XDMF series being written: the heavy data in an HDF5 crom_out, the
 * XML written last (by crom_export_xdmf_series_finish). */
typedef struct {
    crom_out o;
    char xml[1200], h5[1204];
    const char *h5name;        /* the heavy-data file's name relative to the XML */
    int nmesh;
    const crom_mesh **meshes;  /* [nmesh]: written so far (else NULL) */
    char **groups;             /* [nmesh] their groups ("mesh", "mesh_1", ...) */
    double *time;              /* [n] */
    int *mesh_of;              /* [n] */
    int n;
    size_t tcap, mcap;         /* room in time and mesh_of (base/array.h) */
    int ncells;                /* per-frame cell fields written: 0, 1 (J), 2 (and energy density: a shell) or 3 */
} crom_export_xdmf_series;

/* Start an XDMF export to out: OUT.xdmf (heavy data in OUT.xdmf.h5 beside
 * it, directories created as needed) when out ends in ".xdmf" and dir is 0,
 * else the directory out (created) holding NAME.xdmf and NAME.xdmf.h5; nmesh
 * meshes may appear. inputs[0..ninputs)
 * (NULL entries skipped) are files it must not overwrite; cli and history
 * go to the heavy-data file's provenance. Returns 0, CROM_EUSAGE (a name
 * XDMF cannot refer to, or an input would be overwritten), CROM_ECANTCREAT
 * or CROM_EINTERNAL. */
int crom_export_xdmf_series_open(crom_export_xdmf_series *x, const char *out, const char *name, int dir,
                                 const char *const *inputs, int ninputs, int nmesh, const char *cmdline,
                                 const char *history);

/* Write mesh number mi (once; later calls do nothing). Returns 0 or an
 * error (HDF5, out of memory). */
int crom_export_xdmf_series_mesh(crom_export_xdmf_series *x, int mi, const crom_mesh *m);

/* Append frame fr on mesh number mi (fr->mesh, written if new): its time,
 * displacement and velocity, and its cell fields J, energy density and
 * stress (those fr->cells has; the same for every frame
 * of a series).
 * Returns 0 or an error. */
int crom_export_xdmf_series_frame(crom_export_xdmf_series *x, int mi, const crom_export_frame *fr);

/* Finish: the frame times, the heavy-data file, then the XML (a bare mesh
 * when no frame was added). On failure nothing is left of either file.
 * Frees x either way. Returns 0 or an error naming the file. */
int crom_export_xdmf_series_finish(crom_export_xdmf_series *x);

/* Give up: remove the heavy data (nothing is left) and free x. */
void crom_export_xdmf_series_abort(crom_export_xdmf_series *x);

/* Write a bare mesh m (cell data: the rest volumes, a shell's rest areas)
 * in format to out, laid out as kind says: CROM_EXPORT_SERIES_XDMF an XDMF
 * grid (crom_export_xdmf_series_open
 * with name, dir, inputs, cli, history); CROM_EXPORT_SERIES_PVD_FILE a collection
 * of one dataset at t = 0; CROM_EXPORT_SERIES_PVD_DIR, or in_dir != 0, the file
 * NAME.EXT (vtu for pvd) in the directory out; else the file out ("-":
 * stdout). Returns 0 or the writer's error. */
int crom_export_mesh(const crom_mesh *m, int kind, const char *format, const char *out, const char *name, int dir,
                     int in_dir, const char *const *inputs, int ninputs, const char *cmdline, const char *history);

/* ---------------------------------------------------------------- sinks
 * Where the frames of a series go, one interface for every series format:
 * numbered files (with or without a .pvd collection), an XDMF pair, or one
 * MSH file. */
enum { CROM_EXPORT_SERIES_XDMF = 3, CROM_EXPORT_SERIES_MSH = 4 }; /* after the kinds of crom_export_series */

typedef struct {
    int kind;            /* CROM_EXPORT_SERIES_* */
    const char *format;  /* of numbered files: vtu, obj, ply, stl */
    const char *out;     /* MSH: the file ("-": stdout) */
    crom_export_series files;
    crom_export_xdmf_series xdmf;
    crom_export_msh msh;
    int n;               /* frames written */
} crom_export_sink;

/* Start a series of the given kind at out: numbered files of `format`
 * (directory out, stem name; a .pvd as kind says), an XDMF pair
 * (crom_export_xdmf_series_open with name, dir, inputs, nmesh, cli, history), or
 * an MSH file (written when finished; gmsh starts with the first frame).
 * Returns 0 or the error of the opening. */
int crom_export_sink_open(crom_export_sink *k, int kind, const char *format, const char *out, const char *name,
                          int dir, const char *const *inputs, int ninputs, int nmesh, const char *cmdline,
                          const char *history);

/* Add frame fr, on mesh number mi of the run. Returns 0, CROM_EUSAGE (an
 * MSH holds one mesh: a frame on another), or a writer's error. */
int crom_export_sink_frame(crom_export_sink *k, int mi, const crom_export_frame *fr);

/* Finish the series: the collection, the XML, or the MSH file. Returns 0,
 * CROM_EDATA for an XDMF or MSH without frames, or a writer's error; on
 * failure nothing is left of an XDMF or MSH output. Frees k either way. */
int crom_export_sink_finish(crom_export_sink *k);

/* Give up: remove what an XDMF or MSH output wrote so far, free k. */
void crom_export_sink_abort(crom_export_sink *k);

#endif
