/* export.c — VTU, PVD, XDMF, MSH, OBJ, PLY and STL writers (see export.h). */
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>


#include "base/array.h"
#include "base/err.h"
#include "io/io.h"
#include "mesh/gmsh.h"
#include "phys/scenario.h"
#include "phys/shell.h"
#include "view/export.h"

static void xml_text(FILE *f, const char *s);

/* ------------------------------------------------------------- base64 */

static const char b64[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

typedef struct {
    FILE *f;
    unsigned char buf[3];
    int n;
} b64w;

static void b64_put(b64w *w, const void *data, size_t len)
{
    const unsigned char *p = data;
    for (size_t i = 0; i < len; i++) {
        w->buf[w->n++] = p[i];
        if (w->n == 3) {
            char out[4] = {b64[w->buf[0] >> 2], b64[((w->buf[0] & 3) << 4) | (w->buf[1] >> 4)],
                           b64[((w->buf[1] & 15) << 2) | (w->buf[2] >> 6)], b64[w->buf[2] & 63]};
            fwrite(out, 1, 4, w->f);
            w->n = 0;
        }
    }
}

static void b64_end(b64w *w)
{
    if (w->n == 0)
        return;
    unsigned char b1 = w->n > 1 ? w->buf[1] : 0;
    char out[4] = {b64[w->buf[0] >> 2], b64[((w->buf[0] & 3) << 4) | (b1 >> 4)],
                   w->n > 1 ? b64[(b1 & 15) << 2] : '=', '='};
    fwrite(out, 1, 4, w->f);
    w->n = 0;
}

/* One binary DataArray: UInt32 byte count header, then the data, all base64
 * as one stream (VTK's "binary" format without compression). */
static void data_array(FILE *f, const char *type, const char *name, int ncomp,
                       const void *data, size_t bytes)
{
    fprintf(f, "        <DataArray type=\"%s\" Name=\"%s\"", type, name);
    if (ncomp > 1)
        fprintf(f, " NumberOfComponents=\"%d\"", ncomp);
    fprintf(f, " format=\"binary\">\n          ");
    b64w w = {f, {0}, 0};
    uint32_t hdr = (uint32_t)bytes;
    b64_put(&w, &hdr, 4);
    b64_put(&w, data, bytes);
    b64_end(&w);
    fprintf(f, "\n        </DataArray>\n");
}

void crom_export_number(char *buf, size_t n, double x)
{
    for (int p = 15; p <= 17; p++) {
        snprintf(buf, n, "%.*g", p, x);
        if (strtod(buf, NULL) == x)
            return;
    }
}

/* The cells of m: a shell's triangles (3 vertices each), else the tets (4). */
static int cell_count(const crom_mesh *m) { return crom_mesh_is_surface(m) ? m->ntri : m->nt; }

int crom_export_vtu(FILE *f, const crom_export_frame *fr)
{
    const crom_mesh *m = fr->mesh;
    const crom_export_cells *c = fr->cells;
    int shell = crom_mesh_is_surface(m);
    size_t nt = (size_t)cell_count(m), nv = (size_t)m->nv, per = shell ? 3 : 4;
    if (per * nt * sizeof(int32_t) > UINT32_MAX || 3 * nv * sizeof(double) > UINT32_MAX)
        return crom_err(CROM_EDATA, "mesh too large for a VTU with 32-bit headers");
    int32_t *off = crom_malloc(sizeof(int32_t) * (nt ? nt : 1));
    uint8_t *types = crom_malloc(nt ? nt : 1);
    uint8_t *mask = crom_malloc(nv ? nv : 1);
    if (!off || !types || !mask) {
        free(off);
        free(types);
        free(mask);
        return CROM_EINTERNAL;
    }
    for (size_t t = 0; t < nt; t++) {
        off[t] = (int32_t)(per * (t + 1));
        types[t] = shell ? 5 : 10; /* VTK_TRIANGLE, VTK_TETRA */
    }
    fprintf(f, "<?xml version=\"1.0\"?>\n"
               "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt32\">\n"
               "  <UnstructuredGrid>\n");
    if (!isnan(fr->time)) { /* the time ParaView and meshio read from a single file */
        char t[32];
        crom_export_number(t, sizeof t, fr->time);
        fprintf(f, "    <FieldData>\n"
                   "      <DataArray type=\"Float64\" Name=\"TimeValue\" NumberOfTuples=\"1\" format=\"ascii\">%s</DataArray>\n"
                   "    </FieldData>\n", t);
    }
    fprintf(f, "    <Piece NumberOfPoints=\"%zu\" NumberOfCells=\"%zu\">\n", nv, nt);
    fprintf(f, "      <Points>\n");
    data_array(f, "Float64", "Points", 3, m->X, 3 * nv * sizeof(double));
    fprintf(f, "      </Points>\n      <Cells>\n");
    data_array(f, "Int32", "connectivity", 1, shell ? m->tris : m->tets, per * nt * sizeof(int32_t));
    data_array(f, "Int32", "offsets", 1, off, nt * sizeof(int32_t));
    data_array(f, "UInt8", "types", 1, types, nt);
    fprintf(f, "      </Cells>\n      <PointData>\n");
    if (fr->u)
        data_array(f, "Float64", "displacement", 3, fr->u, 3 * nv * sizeof(double));
    if (fr->u && fr->v)
        data_array(f, "Float64", "velocity", 3, fr->v, 3 * nv * sizeof(double));
    for (int r = 0; r < m->nregions; r++) {
        memset(mask, 0, nv);
        for (int j = 0; j < m->regions[r].n; j++)
            mask[m->regions[r].idx[j]] = 1;
        char name[96];
        snprintf(name, sizeof name, "region_%s", m->regions[r].name);
        data_array(f, "UInt8", name, 1, mask, nv);
    }
    fprintf(f, "      </PointData>\n");
    if (c) {
        fprintf(f, "      <CellData>\n");
        data_array(f, "Float64", shell ? "area" : "volume", 1, c->measure, nt * sizeof(double));
        if (fr->u) {
            data_array(f, "Float64", "J", 1, c->J, nt * sizeof(double));
            if (c->mat)
                data_array(f, "Float64", "energy_density", 1, c->psi, nt * sizeof(double));
            if (c->mat)
                data_array(f, "Float64", "von_mises_stress", 1, c->mises, nt * sizeof(double));
        }
        fprintf(f, "      </CellData>\n");
    }
    fprintf(f, "    </Piece>\n  </UnstructuredGrid>\n</VTKFile>\n");
    free(off);
    free(types);
    free(mask);
    return crom_fileout_error(f);
}

int crom_export_pvd(FILE *f, const double *time, const char *const *file, int n)
{
    fprintf(f, "<?xml version=\"1.0\"?>\n"
               "<VTKFile type=\"Collection\" version=\"1.0\" byte_order=\"LittleEndian\">\n"
               "  <Collection>\n");
    for (int i = 0; i < n; i++) {
        char t[32];
        crom_export_number(t, sizeof t, time[i]);
        fprintf(f, "    <DataSet timestep=\"%s\" group=\"\" part=\"0\" file=\"", t);
        xml_text(f, file[i]);
        fputs("\"/>\n", f);
    }
    fprintf(f, "  </Collection>\n</VTKFile>\n");
    return crom_fileout_error(f);
}

int crom_export_surface(const crom_mesh *m, int *ntri, int **tris)
{
    if (!crom_mesh_is_surface(m))
        return crom_mesh_boundary(m, ntri, tris, NULL);
    *tris = crom_malloc(sizeof(int) * 3 * (size_t)m->ntri);
    if (!*tris)
        return CROM_EINTERNAL;
    memcpy(*tris, m->tris, sizeof(int) * 3 * (size_t)m->ntri);
    *ntri = m->ntri;
    return 0;
}

int crom_export_surface_compact(const crom_mesh *m, int *ntri, int **tris, int *nsv, int **sv, int **map)
{
    int rc = crom_export_surface(m, ntri, tris);
    if (rc)
        return rc;
    *map = crom_malloc(sizeof(int) * (size_t)m->nv);
    *sv = crom_malloc(sizeof(int) * (size_t)m->nv);
    if (!*map || !*sv) {
        free(*tris);
        free(*map);
        free(*sv);
        return CROM_EINTERNAL;
    }
    for (int i = 0; i < m->nv; i++)
        (*map)[i] = -1;
    int n = 0;
    for (int k = 0; k < 3 * *ntri; k++) {
        int v = (*tris)[k];
        if ((*map)[v] < 0) {
            (*map)[v] = n;
            (*sv)[n++] = v;
        }
    }
    *nsv = n;
    return 0;
}

int crom_export_obj(FILE *f, const crom_mesh *m, const double *disp)
{
    int nt, *T, nsv, *sv, *map;
    int rc = crom_export_surface_compact(m, &nt, &T, &nsv, &sv, &map);
    if (rc)
        return rc;
    fprintf(f, "# crom surface: %d vertices, %d triangles\n", nsv, nt);
    for (int i = 0; i < nsv; i++) {
        const double *X = m->X + 3 * (size_t)sv[i];
        const double *u = disp ? disp + 3 * (size_t)sv[i] : NULL;
        fprintf(f, "v %.9g %.9g %.9g\n", X[0] + (u ? u[0] : 0), X[1] + (u ? u[1] : 0),
                X[2] + (u ? u[2] : 0));
    }
    for (int t = 0; t < nt; t++)
        fprintf(f, "f %d %d %d\n", map[T[3 * t]] + 1, map[T[3 * t + 1]] + 1, map[T[3 * t + 2]] + 1);
    free(T);
    free(sv);
    free(map);
    return crom_fileout_error(f);
}

int crom_export_ply(FILE *f, const crom_mesh *m, const double *disp)
{
    int nt, *T, nsv, *sv, *map;
    int rc = crom_export_surface_compact(m, &nt, &T, &nsv, &sv, &map);
    if (rc)
        return rc;
    fprintf(f, "ply\nformat binary_little_endian 1.0\ncomment crom surface\n"
               "element vertex %d\nproperty float x\nproperty float y\nproperty float z\n"
               "property float displacement_magnitude\nelement face %d\nproperty list uchar int vertex_indices\n"
               "end_header\n",
            nsv, nt);
    for (int i = 0; i < nsv; i++) {
        const double *X = m->X + 3 * (size_t)sv[i];
        const double *u = disp ? disp + 3 * (size_t)sv[i] : NULL;
        float rec[4] = {(float)(X[0] + (u ? u[0] : 0)), (float)(X[1] + (u ? u[1] : 0)),
                        (float)(X[2] + (u ? u[2] : 0)),
                        (float)(u ? sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]) : 0)};
        fwrite(rec, sizeof(float), 4, f);
    }
    for (int t = 0; t < nt; t++) {
        unsigned char three = 3;
        int32_t idx[3] = {map[T[3 * t]], map[T[3 * t + 1]], map[T[3 * t + 2]]};
        fwrite(&three, 1, 1, f);
        fwrite(idx, sizeof(int32_t), 3, f);
    }
    free(T);
    free(sv);
    free(map);
    return crom_fileout_error(f);
}

/* ------------------------------------------------------------------ XDMF */

int crom_export_xdmf_write_mesh(hid_t loc, const char *group, const crom_mesh *m)
{
    char name[160];
    int shell = crom_mesh_is_surface(m), nc = cell_count(m);
    hsize_t d[2] = {(hsize_t)m->nv, 3};
    snprintf(name, sizeof name, "%s/vertices", group);
    int rc = crom_h5_write_f64(loc, name, 2, d, m->X, "m", "rest positions X of the vertices");
    d[0] = (hsize_t)nc;
    d[1] = shell ? 3 : 4;
    snprintf(name, sizeof name, "%s/%s", group, shell ? "triangles" : "tets");
    if (!rc)
        rc = crom_h5_write_i32(loc, name, 2, d, shell ? m->tris : m->tets, NULL,
                               shell ? "vertex indices of the shell's triangles (0-based)"
                                     : "vertex indices of the tetrahedra (0-based)");
    crom_export_cells rest = {0};
    if (!rc)
        rc = crom_export_cells_eval(&rest, m, NULL);
    if (!rc) {
        d[0] = (hsize_t)nc;
        snprintf(name, sizeof name, "%s/%s", group, shell ? "area" : "volume");
        rc = crom_h5_write_f64(loc, name, 1, d, rest.measure, shell ? "m^2" : "m^3",
                               shell ? "rest area of each triangle" : "rest volume of each tetrahedron");
    }
    crom_export_cells_free(&rest);
    if (rc || m->nregions == 0)
        return rc;
    int *mask = crom_malloc(sizeof(int) * (size_t)(m->nv ? m->nv : 1));
    if (!mask)
        return CROM_EINTERNAL;
    for (int r = 0; r < m->nregions && !rc; r++) {
        memset(mask, 0, sizeof(int) * (size_t)m->nv);
        for (int j = 0; j < m->regions[r].n; j++)
            mask[m->regions[r].idx[j]] = 1;
        snprintf(name, sizeof name, "%s/region_%s", group, m->regions[r].name);
        d[0] = (hsize_t)m->nv;
        rc = crom_h5_write_i32(loc, name, 1, d, mask, NULL, "1 for the vertices of the region");
    }
    free(mask);
    return rc;
}

int crom_export_xdmf_write_frame(hid_t loc, const char *name, int k, int n, int ncomp, const double *data,
                                 const char *units)
{
    char path[96];
    snprintf(path, sizeof path, "%s/%05d", name, k);
    hsize_t d[2] = {(hsize_t)n, (hsize_t)ncomp};
    return crom_h5_write_f64(loc, path, ncomp > 1 ? 2 : 1, d, data, units, NULL);
}

/* text with the five XML specials escaped */
static void xml_text(FILE *f, const char *s)
{
    for (; *s; s++)
        switch (*s) {
        case '&': fputs("&amp;", f); break;
        case '<': fputs("&lt;", f); break;
        case '>': fputs("&gt;", f); break;
        case '"': fputs("&quot;", f); break;
        case '\'': fputs("&apos;", f); break;
        default: fputc(*s, f);
        }
}

static void xdmf_item(FILE *f, const char *indent, const char *type, int prec, long n0, int n1,
                      const char *h5name, const char *group, const char *name)
{
    fprintf(f, "%s<DataItem DataType=\"%s\" Precision=\"%d\" Format=\"HDF\" Dimensions=\"%ld", indent, type,
            prec, n0);
    if (n1 > 0)
        fprintf(f, " %d", n1);
    fputs("\">", f);
    xml_text(f, h5name);
    fputs(":/", f);
    if (group) {
        xml_text(f, group);
        fputc('/', f);
    }
    xml_text(f, name);
    fputs("</DataItem>\n", f);
}

/* one Attribute of Center "Node" (n = nv) or "Cell" (n = nt) */
static void xdmf_attribute(FILE *f, const char *in, const char *name, int vector, int cell, const char *type,
                           int prec, long n, const char *h5name, const char *group, const char *dset)
{
    char sub[64];
    snprintf(sub, sizeof sub, "%s  ", in);
    fprintf(f, "%s<Attribute Name=\"", in);
    xml_text(f, name);
    fprintf(f, "\" AttributeType=\"%s\" Center=\"%s\">\n", vector ? "Vector" : "Scalar", cell ? "Cell" : "Node");
    xdmf_item(f, sub, type, prec, n, vector ? 3 : 0, h5name, group, dset);
    fprintf(f, "%s</Attribute>\n", in);
}

/* one Uniform grid; k < 0: a bare mesh (no time, no fields) */
static void xdmf_grid(FILE *f, const char *in, const char *h5name, const crom_mesh *m, const char *group,
                      int k, double t, const char *const *fields, int nfields, const char *const *cfields,
                      int ncfields)
{
    char sub[64], sub2[64], name[64];
    snprintf(sub, sizeof sub, "%s  ", in);
    snprintf(sub2, sizeof sub2, "%s    ", in);
    if (k < 0) {
        fprintf(f, "%s<Grid Name=\"mesh\" GridType=\"Uniform\">\n", in);
    } else {
        char tv[32];
        crom_export_number(tv, sizeof tv, t);
        fprintf(f, "%s<Grid Name=\"frame_%05d\" GridType=\"Uniform\">\n%s<Time Value=\"%s\"/>\n", in, k, sub, tv);
    }
    int shell = crom_mesh_is_surface(m), nc = cell_count(m);
    fprintf(f, "%s<Topology TopologyType=\"%s\" NumberOfElements=\"%d\" NodesPerElement=\"%d\">\n", sub,
            shell ? "Triangle" : "Tetrahedron", nc, shell ? 3 : 4);
    xdmf_item(f, sub2, "Int", 4, nc, shell ? 3 : 4, h5name, group, shell ? "triangles" : "tets");
    fprintf(f, "%s</Topology>\n%s<Geometry GeometryType=\"XYZ\">\n", sub, sub);
    xdmf_item(f, sub2, "Float", 8, m->nv, 3, h5name, group, "vertices");
    fprintf(f, "%s</Geometry>\n", sub);
    snprintf(name, sizeof name, "%05d", k);
    for (int i = 0; i < nfields && k >= 0; i++)
        xdmf_attribute(f, sub, fields[i], 1, 0, "Float", 8, m->nv, h5name, fields[i], name);
    for (int r = 0; r < m->nregions; r++) {
        char rname[96];
        snprintf(rname, sizeof rname, "region_%s", m->regions[r].name);
        xdmf_attribute(f, sub, rname, 0, 0, "Int", 4, m->nv, h5name, group, rname);
    }
    const char *measure = shell ? "area" : "volume";
    xdmf_attribute(f, sub, measure, 0, 1, "Float", 8, nc, h5name, group, measure);
    for (int i = 0; i < ncfields && k >= 0; i++)
        xdmf_attribute(f, sub, cfields[i], 0, 1, "Float", 8, nc, h5name, cfields[i], name);
    fprintf(f, "%s</Grid>\n", in);
}

int crom_export_xdmf(FILE *f, const char *h5name, const crom_mesh *const *meshes,
                     const char *const *groups, const double *time, const int *mesh_of, int nframes,
                     const char *const *fields, int nfields, const char *const *cfields, int ncfields)
{
    fputs("<?xml version=\"1.0\"?>\n<Xdmf Version=\"3.0\">\n  <Domain>\n", f);
    if (nframes == 0) {
        xdmf_grid(f, "    ", h5name, meshes[0], groups[0], -1, 0, NULL, 0, NULL, 0);
    } else {
        fputs("    <Grid Name=\"frames\" GridType=\"Collection\" CollectionType=\"Temporal\">\n", f);
        for (int k = 0; k < nframes; k++)
            xdmf_grid(f, "      ", h5name, meshes[mesh_of[k]], groups[mesh_of[k]], k, time[k], fields, nfields,
                      cfields, ncfields);
        fputs("    </Grid>\n", f);
    }
    fputs("  </Domain>\n</Xdmf>\n", f);
    return crom_fileout_error(f);
}

/* -------------------------------------------------------- whole files */

static int ends_with(const char *s, const char *suf)
{
    size_t n = strlen(s), m = strlen(suf);
    return n >= m && !strcmp(s + n - m, suf);
}


int crom_export_mkdir(const char *path)
{
    char buf[1024];
    if (snprintf(buf, sizeof buf, "%s", path) >= (int)sizeof buf)
        return crom_err(CROM_ECANTCREAT, "%s: path too long", path);
    for (char *p = buf + 1;; p++) {
        if (*p == '/' || !*p) {
            char c = *p;
            *p = 0;
            if (mkdir(buf, 0777) != 0 && errno != EEXIST)
                return crom_err(CROM_ECANTCREAT, "cannot create directory %s: %s", buf, strerror(errno));
            if (!c)
                break;
            *p = c;
        }
    }
    struct stat st;
    if (stat(path, &st) != 0 || !S_ISDIR(st.st_mode))
        return crom_err(CROM_ECANTCREAT, "%s exists and is not a directory", path);
    return 0;
}

int crom_export_write(const char *path, const char *format, const crom_export_frame *fr)
{
    crom_fileout fo;
    int rc;
    if (!strcmp(format, "msh")) { /* crom_export_msh_finish writes the file */
        crom_export_msh w;
        if ((rc = crom_export_msh_open(&w, fr->mesh)))
            return crom_err_ctx("%s", path);
        if (fr->u && (rc = crom_export_msh_frame(&w, isnan(fr->time) ? 0 : fr->time, fr->u, fr->v))) {
            crom_export_msh_abort(&w);
            return crom_err_ctx("%s", path);
        }
        return crom_export_msh_finish(&w, path);
    }
    rc = crom_fileout_open(&fo, path, !strcmp(format, "ply"));
    if (rc)
        return rc;
    if (!strcmp(format, "vtu") || !strcmp(format, "pvd")) {
        rc = crom_export_vtu(fo.f, fr);
    } else if (!strcmp(format, "obj")) {
        rc = crom_export_obj(fo.f, fr->mesh, fr->u);
    } else if (!strcmp(format, "ply")) {
        rc = crom_export_ply(fo.f, fr->mesh, fr->u);
    } else if (!strcmp(format, "stl")) {
        rc = crom_export_stl(fo.f, fr->mesh, fr->u);
    } else {
        rc = crom_err(CROM_EUSAGE, "no writer for format '%s'", format);
    }
    if (rc) {
        crom_fileout_abort(&fo);
        return crom_err_ctx("%s", path);
    }
    return crom_fileout_commit(&fo);
}

int crom_export_series_open(crom_export_series *s, const char *out, const char *name, const char *ext, int kind)
{
    memset(s, 0, sizeof *s);
    if (strlen(out) >= sizeof s->dir || strlen(name) >= sizeof s->stem || strlen(ext) >= sizeof s->ext)
        return crom_err(CROM_EUSAGE, "%s: output name too long", out);
    snprintf(s->ext, sizeof s->ext, "%s", ext);
    if (kind != CROM_EXPORT_SERIES_PVD_FILE) {
        snprintf(s->dir, sizeof s->dir, "%s", out);
        snprintf(s->stem, sizeof s->stem, "%s", name);
        if (kind == CROM_EXPORT_SERIES_PVD_DIR)
            snprintf(s->pvd, sizeof s->pvd, "%s/%s.pvd", s->dir, s->stem);
        return crom_export_mkdir(s->dir);
    }
    /* DIR/STEM.pvd: frames in DIR/STEM/ */
    const char *base = strrchr(out, '/');
    base = base ? base + 1 : out;
    if (!ends_with(base, ".pvd") || strlen(base) == 4)
        return crom_err(CROM_EUSAGE, "-o %s: a collection needs a name before .pvd", out);
    size_t lstem = strlen(base) - 4, ldir = (size_t)(base - out);
    snprintf(s->pvd, sizeof s->pvd, "%s", out);
    snprintf(s->stem, sizeof s->stem, "%.*s", (int)lstem, base);
    snprintf(s->rel, sizeof s->rel, "%s/", s->stem);
    snprintf(s->dir, sizeof s->dir, "%.*s%s", (int)ldir, out, s->stem);
    struct stat st;
    if (stat(out, &st) == 0 && S_ISDIR(st.st_mode))
        return crom_err(CROM_ECANTCREAT, "-o %s is a directory (an older export?): remove it, or write into it with -o %s/",
                        out, out);
    return crom_export_mkdir(s->dir);
}

const char *crom_export_series_path(crom_export_series *s)
{
    snprintf(s->path, sizeof s->path, "%s/%s_%05d.%s", s->dir, s->stem, s->n, s->ext);
    return s->path;
}

int crom_export_series_add(crom_export_series *s, double t)
{
    double *nt = crom_realloc(s->time, sizeof(double) * (size_t)(s->n + 1));
    if (!nt)
        return CROM_EINTERNAL;
    s->time = nt;
    char **nf = crom_realloc(s->file, sizeof(char *) * (size_t)(s->n + 1));
    if (!nf)
        return CROM_EINTERNAL;
    s->file = nf;
    char rel[600];
    snprintf(rel, sizeof rel, "%s%s_%05d.%s", s->rel, s->stem, s->n, s->ext);
    if (!(s->file[s->n] = crom_strdup(rel)))
        return CROM_EINTERNAL;
    s->time[s->n++] = t;
    return 0;
}

int crom_export_series_write(crom_export_series *s, const char *format, const crom_export_frame *fr)
{
    int rc = crom_export_write(crom_export_series_path(s), format, fr);
    return rc ? rc : crom_export_series_add(s, fr->time);
}

int crom_export_series_finish(crom_export_series *s)
{
    if (!s->pvd[0])
        return 0;
    crom_fileout fo;
    int rc = crom_fileout_open(&fo, s->pvd, 0);
    if (rc)
        return rc;
    if ((rc = crom_export_pvd(fo.f, s->time, (const char *const *)s->file, s->n))) {
        crom_fileout_abort(&fo);
        return crom_err_ctx("%s", s->pvd);
    }
    return crom_fileout_commit(&fo);
}

void crom_export_series_free(crom_export_series *s)
{
    for (int i = 0; i < s->n; i++)
        free(s->file[i]);
    free(s->file);
    free(s->time);
    s->file = NULL;
    s->time = NULL;
    s->n = 0;
}

/* ------------------------------------------------------- XDMF series */

static const char *base_name(const char *p)
{
    const char *s = strrchr(p, '/');
    return s ? s + 1 : p;
}

static int same_file(const char *p, const char *q)
{
    struct stat a, b;
    return p && q && strcmp(p, "-") && stat(p, &a) == 0 && stat(q, &b) == 0 && a.st_dev == b.st_dev &&
           a.st_ino == b.st_ino;
}

/* The heavy data are OUT.xdmf.h5 (a name no crom file has, so they never
 * replace an input). */
static int xdmf_paths(crom_export_xdmf_series *x, const char *out, const char *name, int dir,
                      const char *const *inputs, int n)
{
    if (!dir && ends_with(out, ".xdmf")) {
        snprintf(x->xml, sizeof x->xml, "%s", out);
        const char *slash = strrchr(out, '/');
        if (slash && slash > out) { /* its directory, as for a pvd's frames */
            char parent[1024];
            snprintf(parent, sizeof parent, "%.*s", (int)(slash - out), out);
            int rc = crom_export_mkdir(parent);
            if (rc)
                return rc;
        }
    } else {
        int rc = crom_export_mkdir(out);
        if (rc)
            return rc;
        snprintf(x->xml, sizeof x->xml, "%s/%s.xdmf", out, name);
    }
    snprintf(x->h5, sizeof x->h5, "%s.h5", x->xml);
    x->h5name = base_name(x->h5);
    if (strchr(x->h5name, ':'))
        return crom_err(CROM_EUSAGE, "-o %s: XDMF cannot refer to a file name with ':' in it", out);
    for (int i = 0; i < n; i++)
        if (same_file(inputs[i], x->h5) || same_file(inputs[i], x->xml))
            return crom_err(CROM_EUSAGE, "-o %s would overwrite the input %s", out, inputs[i]);
    return 0;
}

static void xdmf_free(crom_export_xdmf_series *x)
{
    for (int i = 0; x->groups && i < x->nmesh; i++)
        free(x->groups[i]);
    free(x->groups);
    free(x->meshes);
    free(x->time);
    free(x->mesh_of);
    x->groups = NULL;
    x->meshes = NULL;
    x->time = NULL;
    x->mesh_of = NULL;
}

int crom_export_xdmf_series_open(crom_export_xdmf_series *x, const char *out, const char *name, int dir,
                                 const char *const *inputs, int ninputs, int nmesh, const char *cmdline,
                                 const char *history)
{
    memset(x, 0, sizeof *x);
    int rc = xdmf_paths(x, out, name, dir, inputs, ninputs);
    if (rc)
        return rc;
    x->nmesh = nmesh;
    x->meshes = crom_calloc((size_t)nmesh, sizeof(crom_mesh *));
    x->groups = crom_calloc((size_t)nmesh, sizeof(char *));
    if (!x->meshes || !x->groups) {
        xdmf_free(x);
        return CROM_EINTERNAL;
    }
    if ((rc = crom_out_create(&x->o, x->h5, "xdmf/heavy-data", 1, cmdline, history, CROM_OUT_PLAIN)))
        xdmf_free(x);
    return rc;
}

int crom_export_xdmf_series_mesh(crom_export_xdmf_series *x, int mi, const crom_mesh *m)
{
    if (x->meshes[mi])
        return 0;
    char g[32];
    if (mi == 0)
        snprintf(g, sizeof g, "mesh");
    else
        snprintf(g, sizeof g, "mesh_%d", mi);
    int rc;
    if (!(x->groups[mi] = crom_strdup(g)))
        return CROM_EINTERNAL;
    if ((rc = crom_export_xdmf_write_mesh(x->o.h5, g, m)))
        return rc;
    x->meshes[mi] = m;
    return 0;
}

int crom_export_xdmf_series_frame(crom_export_xdmf_series *x, int mi, const crom_export_frame *fr)
{
    const crom_mesh *m = fr->mesh;
    const crom_export_cells *c = fr->cells;
    int rc;
    if ((rc = crom_export_xdmf_series_mesh(x, mi, m)) ||
        (rc = crom_export_xdmf_write_frame(x->o.h5, "displacement", x->n, m->nv, 3, fr->u, "m")) ||
        (rc = crom_export_xdmf_write_frame(x->o.h5, "velocity", x->n, m->nv, 3, fr->v, "m/s")))
        return rc;
    int nc = cell_count(m);
    /* J, energy density, stress: a prefix of the XML's cell fields */
    x->ncells = c ? (c->mat ? 3 : 1) : 0;
    if (c && (rc = crom_export_xdmf_write_frame(x->o.h5, "J", x->n, nc, 1, c->J, "1")))
        return rc;
    if (c && c->mat && (rc = crom_export_xdmf_write_frame(x->o.h5, "energy_density", x->n, nc, 1, c->psi, "J/m^3")))
        return rc;
    if (c && c->mat &&
        (rc = crom_export_xdmf_write_frame(x->o.h5, "von_mises_stress", x->n, nc, 1, c->mises, "Pa")))
        return rc;
    if ((rc = crom_array_reserve((void **)&x->time, &x->tcap, (size_t)x->n + 1, sizeof *x->time)) ||
        (rc = crom_array_reserve((void **)&x->mesh_of, &x->mcap, (size_t)x->n + 1, sizeof *x->mesh_of)))
        return rc;
    x->time[x->n] = fr->time;
    x->mesh_of[x->n++] = mi;
    return 0;
}

void crom_export_xdmf_series_abort(crom_export_xdmf_series *x)
{
    crom_out_fail(&x->o);
    xdmf_free(x);
}

int crom_export_xdmf_series_finish(crom_export_xdmf_series *x)
{
    static const char *const fields[] = {"displacement", "velocity"};
    static const char *const cfields[] = {"J", "energy_density", "von_mises_stress"};
    int rc = 0;
    if (x->n > 0) {
        hsize_t d = (hsize_t)x->n;
        rc = crom_h5_write_f64(x->o.h5, "time", 1, &d, x->time, "s", "time of each frame");
    }
    if (rc) {
        crom_export_xdmf_series_abort(x);
        return crom_err_ctx("%s", x->h5);
    }
    if ((rc = crom_out_commit(&x->o))) {
        xdmf_free(x);
        return rc;
    }
    crom_fileout fo;
    if (!(rc = crom_fileout_open(&fo, x->xml, 0))) {
        if ((rc = crom_export_xdmf(fo.f, x->h5name, x->meshes, (const char *const *)x->groups, x->time, x->mesh_of,
                                   x->n, fields, x->n ? 2 : 0, cfields, x->ncells))) {
            crom_fileout_abort(&fo);
            crom_err_ctx("%s", x->xml);
        } else {
            rc = crom_fileout_commit(&fo);
        }
    }
    if (rc)
        unlink(x->h5);
    xdmf_free(x);
    return rc;
}

/* ------------------------------------------------------- cell fields */

/* The cells of a shell: rest area A, J = A'/A (the deformed over the rest
 * area: sqrt det(FᵀF) of the 3×2 F = Ds Dm⁻¹) and, with a material, the
 * membrane energy of shell.h per rest volume t A (J/m³) and the von Mises
 * equivalent of the membrane stress (crom_shell_tri_mises, Pa). A
 * degenerate rest triangle gets NaN for J, psi and mises and is counted. */
static long shell_measures(const crom_mesh *m, const double *u, const crom_material *mat, double *A, double *J,
                           double *psi, double *mises)
{
    crom_shell_material sm;
    int have = mat && crom_shell_material_init(&sm, mat->E, mat->nu, m->thickness, 1000) == CROM_OK;
    if (have && m->plane)
        crom_shell_material_plane(&sm);
    long bad = 0;
    if (mat && !have) /* cannot happen for a material and mesh that passed their checks: no psi then */
        crom_err_clear();
    for (int t = 0; t < m->ntri; t++) {
        double X[9], x[9], Dminv[4], F[6], n[3];
        for (int k = 0; k < 3; k++)
            for (int c = 0; c < 3; c++) {
                size_t i = 3 * (size_t)m->tris[3 * (size_t)t + k] + c;
                X[3 * k + c] = m->X[i];
                x[3 * k + c] = m->X[i] + (u ? u[i] : 0);
            }
        int ok = crom_shell_tri_rest(X, Dminv, &A[t]) == CROM_OK;
        bad += !ok;
        J[t] = psi[t] = mises[t] = NAN;
        if (!ok)
            continue;
        crom_shell_tri_F(x, Dminv, F); /* F[2i + a]: columns F e1, F e2 */
        n[0] = F[2] * F[5] - F[4] * F[3];
        n[1] = F[4] * F[1] - F[0] * F[5];
        n[2] = F[0] * F[3] - F[2] * F[1];
        J[t] = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        double E;
        if (have && crom_shell_tri_eval(&sm, x, Dminv, A[t], 0, &E, NULL, NULL) == CROM_OK)
            psi[t] = E / (m->thickness * A[t]);
        if (have)
            mises[t] = crom_shell_tri_mises(&sm, x, Dminv);
    }
    return bad;
}

int crom_export_cells_eval(crom_export_cells *c, const crom_mesh *m, const double *u)
{
    int nc = cell_count(m);
    if (nc > c->cap) {
        int cap = nc;
        double *b[4] = {crom_realloc(c->measure, sizeof(double) * (size_t)cap), NULL, NULL, NULL};
        if (b[0])
            c->measure = b[0];
        if (b[0] && (b[1] = crom_realloc(c->J, sizeof(double) * (size_t)cap)))
            c->J = b[1];
        if (b[1] && (b[2] = crom_realloc(c->psi, sizeof(double) * (size_t)cap)))
            c->psi = b[2];
        if (b[2] && (b[3] = crom_realloc(c->mises, sizeof(double) * (size_t)cap)))
            c->mises = b[3];
        if (!b[3])
            return CROM_EINTERNAL;
        c->cap = cap;
    }
    if (crom_mesh_is_surface(m))
        c->degenerate += shell_measures(m, u, c->mat, c->measure, c->J, c->psi, c->mises);
    else
        c->degenerate += crom_fem_tet_measures(m, u, c->mat, c->measure, c->J, c->psi, c->mises);
    return 0;
}

void crom_export_cells_free(crom_export_cells *c)
{
    free(c->measure);
    free(c->J);
    free(c->psi);
    free(c->mises);
    memset(c, 0, sizeof *c);
}

int crom_export_material(crom_material *m, int *known, const crom_in *in, double E, double nu)
{
    double v[2] = {E, nu};
    static const char *const attr[2] = {"youngs", "poisson"};
    *known = 0;
    if (isnan(E) && isnan(nu) && in->h5 >= 0 && crom_h5_has_attr(in->h5, ".", "scenario")) {
        /* a run with regions of other materials: one material would give their energy and stress wrong */
        char *text = NULL;
        crom_scenario sc;
        crom_scenario_defaults(&sc);
        int rc = crom_h5_get_str(in->h5, ".", "scenario", &text);
        int het = !rc && !crom_scenario_parse_text(text, &sc) && sc.nmat > 0;
        free(text);
        crom_err_clear();
        if (het) {
            *known = -1;
            return 0;
        }
    }
    for (int i = 0; i < 2; i++)
        if (isnan(v[i]) && in->h5 >= 0 && crom_h5_has_attr(in->h5, ".", attr[i]) &&
            crom_h5_get_f64(in->h5, ".", attr[i], &v[i], 1))
            return crom_err_ctx("%s", in->name);
    if (isnan(v[0]) && isnan(v[1]))
        return 0;
    if (isnan(v[0]) || isnan(v[1]))
        return crom_err(CROM_EUSAGE, "%s records no %s: give --youngs and --poisson together", in->name,
                        isnan(v[0]) ? "Young's modulus" : "Poisson ratio");
    int rc = crom_material_init(m, v[0], v[1], 1000); /* the density plays no part */
    if (!rc)
        *known = 1;
    return rc;
}

/* ---------------------------------------------------------------- gmsh
 * gmsh writes MSH and STL to a named file: it writes a temporary file
 * (named with the extension that selects the format) whose bytes are then
 * copied into the output, so outputs stay atomic and may go to stdout. The
 * session is lib/mesh/gmsh.h's. */

#define G(call, what)                                                                              \
    do {                                                                                           \
        ierr = 0;                                                                                  \
        call;                                                                                      \
        if (ierr)                                                                                  \
            return crom_gmsh_fail(ierr, what);                                                     \
    } while (0)

/* a session (lib/mesh/gmsh.h) with one empty model, set to write MSH 4.1 text */
static int gmsh_start(void)
{
    int ierr, rc = crom_gmsh_begin(NULL);
    if (rc)
        return rc;
    gmshModelAdd("crom", &ierr);
    gmshOptionSetNumber("Mesh.Binary", 0, &ierr);
    gmshOptionSetNumber("Mesh.MshFileVersion", 4.1, &ierr);
    gmshOptionSetNumber("PostProcessing.SaveMesh", 0, &ierr); /* the mesh once, by gmshWrite */
    return 0;
}

/* gmsh writes the model (and the views[0..nviews), appended) to a
 * temporary file with extension ext, whose bytes go to f */
static int gmsh_write_into(FILE *f, const char *ext, const int *views, int nviews)
{
    const char *dir = getenv("TMPDIR");
    char tmp[1100];
    snprintf(tmp, sizeof tmp, "%s/crom-export-XXXXXX.%s", dir && *dir ? dir : "/tmp", ext);
    int fd = mkstemps(tmp, (int)strlen(ext) + 1), ierr = 0, rc = 0;
    if (fd < 0)
        return crom_err(CROM_ECANTCREAT, "cannot create a temporary file %s: %s", tmp, strerror(errno));
    close(fd);
    gmshWrite(tmp, &ierr);
    for (int i = 0; i < nviews && !ierr; i++)
        gmshViewWrite(views[i], tmp, 1, &ierr);
    if (ierr)
        rc = crom_gmsh_fail(ierr, "write the file");
    FILE *in = rc ? NULL : fopen(tmp, "rb");
    if (!rc && !in)
        rc = crom_err(CROM_EIO, "cannot read back %s: %s", tmp, strerror(errno));
    char buf[65536];
    size_t n;
    while (in && (n = fread(buf, 1, sizeof buf, in)) > 0)
        if (fwrite(buf, 1, n, f) != n)
            break;
    if (in && ferror(f))
        rc = crom_fileout_error(f);
    else if (in && ferror(in))
        rc = crom_err(CROM_EIO, "cannot read back %s", tmp);
    if (in)
        fclose(in);
    unlink(tmp);
    return rc;
}

static int stl_model(const crom_mesh *m, const double *disp)
{
    int nt, *T, nsv, *sv, *map, ierr;
    int rc = crom_export_surface_compact(m, &nt, &T, &nsv, &sv, &map);
    if (rc)
        return rc;
    size_t *ntag = crom_malloc(sizeof(size_t) * (size_t)(nsv ? nsv : 1));
    size_t *etag = crom_malloc(sizeof(size_t) * (size_t)(nt ? nt : 1));
    size_t *enode = crom_malloc(sizeof(size_t) * 3 * (size_t)(nt ? nt : 1));
    double *x = crom_malloc(sizeof(double) * 3 * (size_t)(nsv ? nsv : 1));
    if (!ntag || !etag || !enode || !x) {
        rc = CROM_EINTERNAL;
    } else {
        for (int i = 0; i < nsv; i++) {
            ntag[i] = (size_t)i + 1;
            for (int c = 0; c < 3; c++)
                x[3 * i + c] = m->X[3 * (size_t)sv[i] + c] + (disp ? disp[3 * (size_t)sv[i] + c] : 0);
        }
        for (int t = 0; t < nt; t++) {
            etag[t] = (size_t)t + 1;
            for (int k = 0; k < 3; k++)
                enode[3 * t + k] = (size_t)map[T[3 * t + k]] + 1;
        }
        ierr = 0;
        gmshModelAddDiscreteEntity(2, 1, NULL, 0, &ierr);
        if (!ierr)
            gmshModelMeshAddNodes(2, 1, ntag, (size_t)nsv, x, 3 * (size_t)nsv, NULL, 0, &ierr);
        if (!ierr)
            gmshModelMeshAddElementsByType(1, 2, etag, (size_t)nt, enode, 3 * (size_t)nt, &ierr);
        if (ierr)
            rc = crom_gmsh_fail(ierr, "take the surface");
    }
    free(ntag);
    free(etag);
    free(enode);
    free(x);
    free(T);
    free(sv);
    free(map);
    return rc;
}

int crom_export_stl(FILE *f, const crom_mesh *m, const double *disp)
{
    int rc = gmsh_start();
    if (rc)
        return rc;
    rc = stl_model(m, disp);
    if (!rc)
        rc = gmsh_write_into(f, "stl", NULL, 0);
    crom_gmsh_end(NULL, NULL);
    return rc;
}

/* one discrete volume of tets (gmsh element type 4, our vertex order) or,
 * for a shell, one discrete surface of its triangles (type 2) */
static int msh_model(crom_export_msh *w, const crom_mesh *m)
{
    int shell = crom_mesh_is_surface(m), dim = shell ? 2 : 3, per = shell ? 3 : 4;
    size_t nt = (size_t)cell_count(m), nv = (size_t)m->nv;
    const int *cells = shell ? m->tris : m->tets;
    size_t *etag = crom_malloc(sizeof(size_t) * (nt ? nt : 1));
    size_t *enode = crom_malloc(sizeof(size_t) * (size_t)per * (nt ? nt : 1));
    int rc = 0, ierr = 0;
    if (!w->tags || !etag || !enode) {
        rc = CROM_EINTERNAL;
    } else {
        for (size_t i = 0; i < nv; i++)
            w->tags[i] = i + 1;
        for (size_t t = 0; t < nt; t++) {
            etag[t] = t + 1;
            for (int k = 0; k < per; k++)
                enode[per * t + k] = (size_t)cells[per * t + k] + 1;
        }
        gmshModelAddDiscreteEntity(dim, 1, NULL, 0, &ierr);
        if (!ierr)
            gmshModelMeshAddNodes(dim, 1, w->tags, nv, m->X, 3 * nv, NULL, 0, &ierr);
        if (!ierr)
            gmshModelMeshAddElementsByType(1, shell ? 2 : 4, etag, nt, enode, per * nt, &ierr);
        if (ierr)
            rc = crom_gmsh_fail(ierr, "take the mesh");
    }
    free(etag);
    free(enode);
    return rc;
}

int crom_export_msh_open(crom_export_msh *w, const crom_mesh *m)
{
    memset(w, 0, sizeof *w);
    w->nv = m->nv;
    w->tags = crom_malloc(sizeof(size_t) * (size_t)(m->nv ? m->nv : 1));
    int rc = gmsh_start();
    if (rc) {
        free(w->tags);
        w->tags = NULL;
        return rc;
    }
    rc = msh_model(w, m);
    if (rc)
        crom_export_msh_abort(w);
    return rc;
}

int crom_export_msh_frame(crom_export_msh *w, double t, const double *u, const double *v)
{
    static const char *const name[2] = {"displacement", "velocity"};
    const double *data[2] = {u, v};
    int ierr;
    for (int i = 0; i < 2; i++) {
        if (w->n == 0) /* view tags start at 0 */
            G(w->view[i] = gmshViewAdd(name[i], -1, &ierr), "add a view");
        G(gmshViewAddHomogeneousModelData(w->view[i], w->n, "crom", "NodeData", w->tags, (size_t)w->nv,
                                          (double *)data[i], 3 * (size_t)w->nv, t, 3, 0, &ierr),
          "add a frame to a view");
    }
    w->n++;
    return 0;
}

void crom_export_msh_abort(crom_export_msh *w)
{
    free(w->tags);
    w->tags = NULL;
    crom_gmsh_end(NULL, NULL);
}

int crom_export_msh_finish(crom_export_msh *w, const char *path)
{
    crom_fileout fo;
    int rc = crom_fileout_open(&fo, path, 0);
    if (!rc && (rc = gmsh_write_into(fo.f, "msh", w->view, w->n ? 2 : 0))) {
        crom_fileout_abort(&fo);
        crom_err_ctx("%s", path);
    } else if (!rc) {
        rc = crom_fileout_commit(&fo);
    }
    crom_export_msh_abort(w);
    return rc;
}

/* ---------------------------------------------------------------- sinks */

int crom_export_sink_open(crom_export_sink *k, int kind, const char *format, const char *out, const char *name,
                          int dir, const char *const *inputs, int ninputs, int nmesh, const char *cmdline,
                          const char *history)
{
    memset(k, 0, sizeof *k);
    k->kind = kind;
    k->format = format;
    k->out = out ? out : "-";
    if (kind == CROM_EXPORT_SERIES_XDMF)
        return crom_export_xdmf_series_open(&k->xdmf, out, name, dir, inputs, ninputs, nmesh, cmdline, history);
    if (kind == CROM_EXPORT_SERIES_MSH)
        return 0;
    return crom_export_series_open(&k->files, out, name, kind == CROM_EXPORT_SERIES_FILES ? format : "vtu", kind);
}

int crom_export_sink_frame(crom_export_sink *k, int mi, const crom_export_frame *fr)
{
    int rc;
    if (k->kind == CROM_EXPORT_SERIES_XDMF) {
        rc = crom_export_xdmf_series_frame(&k->xdmf, mi, fr);
    } else if (k->kind == CROM_EXPORT_SERIES_MSH) {
        if (mi != 0)
            return crom_err(CROM_EUSAGE, "%s: an MSH file holds one mesh, and this run switches meshes "
                            "(export it as pvd or xdmf)", k->out);
        if (k->n == 0 && (rc = crom_export_msh_open(&k->msh, fr->mesh)))
            return rc;
        rc = crom_export_msh_frame(&k->msh, fr->time, fr->u, fr->v);
    } else {
        rc = crom_export_series_write(&k->files, k->kind == CROM_EXPORT_SERIES_FILES ? k->format : "vtu", fr);
    }
    k->n += !rc;
    return rc;
}

void crom_export_sink_abort(crom_export_sink *k)
{
    if (k->kind == CROM_EXPORT_SERIES_XDMF)
        crom_export_xdmf_series_abort(&k->xdmf);
    else if (k->kind == CROM_EXPORT_SERIES_MSH && k->n > 0)
        crom_export_msh_abort(&k->msh);
    crom_export_series_free(&k->files);
}

int crom_export_sink_finish(crom_export_sink *k)
{
    int rc = 0;
    if (k->n == 0 && (k->kind == CROM_EXPORT_SERIES_XDMF || k->kind == CROM_EXPORT_SERIES_MSH)) {
        crom_export_sink_abort(k);
        return crom_err(CROM_EDATA, "no frames to write");
    }
    if (k->kind == CROM_EXPORT_SERIES_XDMF)
        rc = crom_export_xdmf_series_finish(&k->xdmf);
    else if (k->kind == CROM_EXPORT_SERIES_MSH)
        rc = crom_export_msh_finish(&k->msh, k->out);
    else
        rc = crom_export_series_finish(&k->files);
    crom_export_series_free(&k->files);
    return rc;
}

int crom_export_mesh(const crom_mesh *m, int kind, const char *format, const char *out, const char *name, int dir,
                     int in_dir, const char *const *inputs, int ninputs, const char *cmdline, const char *history)
{
    crom_export_cells cells = {0};
    crom_export_frame fr = {m, NULL, NULL, kind == CROM_EXPORT_SERIES_PVD_FILE ? 0 : NAN, &cells};
    int rc = crom_export_cells_eval(&cells, m, NULL);
    if (rc) {
    } else if (kind == CROM_EXPORT_SERIES_XDMF) {
        crom_export_xdmf_series x;
        if (!(rc = crom_export_xdmf_series_open(&x, out, name, dir, inputs, ninputs, 1, cmdline, history))) {
            if ((rc = crom_export_xdmf_series_mesh(&x, 0, m))) {
                crom_export_xdmf_series_abort(&x);
                crom_err_ctx("%s", x.h5);
            } else {
                rc = crom_export_xdmf_series_finish(&x);
            }
        }
    } else if (kind == CROM_EXPORT_SERIES_PVD_FILE) {
        crom_export_series s;
        if (!(rc = crom_export_series_open(&s, out, name, "vtu", kind)) && !(rc = crom_export_series_write(&s, "vtu", &fr)))
            rc = crom_export_series_finish(&s);
        crom_export_series_free(&s);
    } else {
        char path[1400];
        snprintf(path, sizeof path, "%s", out ? out : "-");
        if ((in_dir || kind == CROM_EXPORT_SERIES_PVD_DIR) && !(rc = crom_export_mkdir(out)))
            snprintf(path, sizeof path, "%s/%s.%s", out, name, kind == CROM_EXPORT_SERIES_PVD_DIR ? "vtu" : format);
        if (!rc)
            rc = crom_export_write(path, format, &fr);
    }
    crom_export_cells_free(&cells);
    return rc;
}
