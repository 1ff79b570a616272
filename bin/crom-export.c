/* crom-export — write meshes and trajectories as files other tools open:
 * VTU (+ PVD for a series) for ParaView and meshio, surface OBJ and PLY. */
#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "cli.h"
#include "err.h"
#include "export.h"
#include "io.h"
#include "mesh.h"

enum { O_FORMAT = 300, O_FRAME, O_EVERY, O_NAME, O_MESH, O_MODEL };

static const crom_opt export_opts[] = {
    {"format", O_FORMAT, "FMT", "vtu, pvd, obj or ply (default: from the extension of OUT; pvd when OUT ends in '/')."},
    {"output", 'o', "OUT", "Output file; for pvd, and for obj/ply with --frame all, a directory (created if needed)."},
    {"frame", O_FRAME, "K", "Which frame of a series to write for vtu/obj/ply: an index (negative counts from the end; default -1, the last) or 'all' for one file per frame."},
    {"every", O_EVERY, "K", "With pvd or --frame all: keep every K-th frame (default 1)."},
    {"name", O_NAME, "BASE", "File name stem inside the output directory (default 'frame': frame.pvd, frame_00000.vtu, ...)."},
    {"mesh", O_MESH, "MESH", "Mesh to use instead of the one the input carries (it must have the same vertices)."},
    {NULL, 0, NULL, NULL}};

static const crom_optgroup groups[] = {{"Options", export_opts}, {NULL, NULL}};

static const crom_doc doc = {
    "crom-export",
    "write crom meshes and trajectories as VTU/PVD, OBJ or PLY",
    "crom-export --format vtu|pvd|obj|ply [options] -o OUT [MESH|TRAJ|-]",
    "Reads a crom/mesh or a crom/trajectory (HDF5 file or frame stream, from a path or stdin) "
    "and writes files ParaView, meshio and mesh viewers open.\n\n"
    "vtu: the tetrahedral mesh on its rest positions; for a trajectory frame the point data "
    "'displacement' and 'velocity' (use ParaView's Warp By Vector on 'displacement'). Every "
    "named region becomes a 0/1 point field 'region_NAME'.\n\n"
    "pvd: a directory holding one VTU per frame and a .pvd collection with the frame times, "
    "written frame by frame as a stream arrives.\n\n"
    "obj, ply: the boundary surface in its deformed position (binary PLY adds |u| per vertex).",
    groups,
    "crom-mesh box | crom-export --format vtu -o box.vtu\n"
    "crom-fullsim @compress.flags < box.h5 | crom-export --format pvd -o out/\n"
    "crom-export --format obj --frame all -o surf/ traj.h5",
    "crom-mesh(1), crom-fullsim(1), crom-info(1)"};

typedef struct {
    const char *input, *out, *format, *name, *mesh;
    long frame;
    int all, every;
} args;

static int on_opt(void *ctx, int key, const char *v)
{
    args *a = ctx;
    long n;
    switch (key) {
    case 0:
        if (a->input)
            return crom_err(CROM_EUSAGE, "unexpected operand '%s' (one input at a time)", v);
        a->input = v;
        return 0;
    case 'o': a->out = v; return 0;
    case O_FORMAT:
        if (strcmp(v, "vtu") && strcmp(v, "pvd") && strcmp(v, "obj") && strcmp(v, "ply"))
            return crom_err(CROM_EUSAGE, "--format: '%s' is not vtu, pvd, obj or ply", v);
        a->format = v;
        return 0;
    case O_FRAME:
        if (!strcmp(v, "all")) {
            a->all = 1;
            return 0;
        }
        if (crom_parse_int(v, "--frame", -1000000000L, 1000000000L, &n))
            return CROM_EUSAGE;
        a->frame = n;
        return 0;
    case O_EVERY:
        if (crom_parse_int(v, "--every", 1, 1000000000L, &n))
            return CROM_EUSAGE;
        a->every = (int)n;
        return 0;
    case O_NAME:
        if (!*v || strchr(v, '/'))
            return crom_err(CROM_EUSAGE, "--name: '%s' must be a plain file name stem", v);
        a->name = v;
        return 0;
    case O_MESH: a->mesh = v; return 0;
    }
    return crom_err(CROM_EINTERNAL, "unhandled option");
}

static int ends_with(const char *s, const char *suf)
{
    size_t n = strlen(s), m = strlen(suf);
    return n >= m && !strcmp(s + n - m, suf);
}

static void parse_args(crom_cli *cli, args *a, int argc, char **argv)
{
    memset(a, 0, sizeof *a);
    a->frame = -1;
    a->every = 1;
    a->name = "frame";
    crom_cli_parse(cli, &doc, argc, argv, on_opt, a);
    if (!a->format && a->out) {
        static const char *ext[] = {".vtu", ".pvd", ".obj", ".ply"};
        for (int i = 0; i < 4; i++)
            if (ends_with(a->out, ext[i]))
                a->format = ext[i] + 1;
        if (!a->format && ends_with(a->out, "/"))
            a->format = "pvd";
    }
    const char *err = NULL;
    if (!a->format)
        err = "no --format given and none follows from -o";
    else if (!a->out && (!strcmp(a->format, "pvd") || a->all))
        err = "pvd and --frame all write a directory: give -o DIR";
    if (err) {
        fprintf(stderr, "%s: %s\n", cli->prog, err);
        exit(crom_cli_exit(cli, CROM_EUSAGE));
    }
}

/* mkdir -p for the output directory */
static int make_dir(const char *path)
{
    char buf[1024];
    snprintf(buf, sizeof buf, "%s", path);
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

/* Write one frame (or the bare mesh: disp == NULL) to path in format fmt. */
static int write_one(const char *path, const char *fmt, const crom_mesh *m, const double *disp,
                     const double *vel)
{
    crom_fileout fo;
    int binary = !strcmp(fmt, "ply");
    int rc = crom_fileout_open(&fo, path, binary);
    if (rc)
        return rc;
    if (!strcmp(fmt, "vtu") || !strcmp(fmt, "pvd")) {
        crom_pointfield pf[2] = {{"displacement", 3, disp}, {"velocity", 3, vel}};
        rc = crom_export_vtu(fo.f, m, pf, disp ? (vel ? 2 : 1) : 0);
    } else if (!strcmp(fmt, "obj")) {
        rc = crom_export_obj(fo.f, m, disp);
    } else {
        rc = crom_export_ply(fo.f, m, disp);
    }
    if (rc) {
        crom_fileout_abort(&fo);
        return crom_err_ctx("%s", path);
    }
    return crom_fileout_commit(&fo);
}

static int run(crom_cli *cli, args *a)
{
    crom_in in;
    crom_mesh m;
    int rc = crom_in_open(&in, a->input);
    if (rc)
        return rc;
    int is_mesh = !strcmp(in.schema, "crom/mesh");
    if ((rc = crom_in_expect(&in, is_mesh ? "crom/mesh" : "crom/trajectory", 1))) {
        if (!strcmp(in.schema, "crom/latent"))
            rc = crom_err(CROM_EUSAGE, "%s is a crom/latent: decoding it needs --model (not in this version)", in.name);
        crom_in_close(&in);
        return rc;
    }
    if (a->mesh) {
        crom_in mi;
        if ((rc = crom_in_open(&mi, a->mesh)) || (rc = crom_in_expect(&mi, "crom/mesh", 1))) {
            crom_in_close(&in);
            return rc;
        }
        hid_t root = H5Gopen2(mi.h5, "/", H5P_DEFAULT);
        rc = crom_mesh_read(root, &m);
        H5Gclose(root);
        crom_in_close(&mi);
        if (rc) {
            crom_in_close(&in);
            return crom_err_ctx("%s", a->mesh);
        }
    } else {
        hid_t loc = H5Gopen2(in.h5, is_mesh ? "/" : "mesh", H5P_DEFAULT);
        rc = loc < 0 ? crom_err(CROM_EDATA, "%s has no mesh", in.name) : crom_mesh_read(loc, &m);
        if (loc >= 0)
            H5Gclose(loc);
        if (rc) {
            crom_in_close(&in);
            return crom_err_ctx("%s", in.name);
        }
    }
    int fd = -1, fv = -1;
    if (!is_mesh) {
        fd = crom_in_field(&in, "displacement");
        fv = crom_in_field(&in, "velocity");
        int ft = crom_in_field(&in, "time");
        if (fd < 0 || ft < 0) {
            rc = CROM_EDATA;
            goto out;
        }
        crom_err_clear();
        if (in.fields[fd].count != 3 * (size_t)m.nv) {
            rc = crom_err(CROM_EDATA, "%s: displacement has %zu values per frame, the mesh needs %d",
                          in.name, in.fields[fd].count, 3 * m.nv);
            goto out;
        }
    }
    int series_out = !strcmp(a->format, "pvd") || a->all;
    if (is_mesh || !series_out) {
        if (a->all || !strcmp(a->format, "pvd")) {
            if ((rc = make_dir(a->out)))
                goto out;
        }
        const double *disp = NULL, *vel = NULL;
        double *frames = NULL;
        long n = 0;
        if (!is_mesh) {
            if ((rc = crom_in_read_all(&in, &frames, &n)))
                goto out;
            long k = a->frame < 0 ? n + a->frame : a->frame;
            if (k < 0 || k >= n) {
                rc = crom_err(CROM_EUSAGE, "--frame %ld: %s has %ld frames", a->frame, in.name, n);
                free(frames);
                goto out;
            }
            disp = frames + (size_t)k * in.frame_len + in.fields[fd].offset;
            vel = fv >= 0 ? frames + (size_t)k * in.frame_len + in.fields[fv].offset : NULL;
        }
        char path[1200];
        if (series_out)
            snprintf(path, sizeof path, "%s/%s.%s", a->out, a->name,
                     !strcmp(a->format, "pvd") ? "vtu" : a->format);
        else
            snprintf(path, sizeof path, "%s", a->out ? a->out : "-");
        rc = write_one(path, a->format, &m, disp, vel);
        free(frames);
        goto out;
    }
    /* a series, frame by frame as it arrives */
    if ((rc = make_dir(a->out)))
        goto out;
    const char *ext = !strcmp(a->format, "pvd") ? "vtu" : a->format;
    double *times = NULL;
    char **files = NULL;
    int nout = 0, ft = crom_in_field(&in, "time");
    crom_progress prog;
    crom_progress_start(&prog, cli, "export", in.form == CROM_FORM_H5 ? in.nframes : 0);
    long k = 0;
    while ((rc = crom_in_next(&in)) == 1) {
        if (k++ % a->every)
            continue;
        char rel[256], path[1400];
        snprintf(rel, sizeof rel, "%s_%05d.%s", a->name, nout, ext);
        snprintf(path, sizeof path, "%s/%s", a->out, rel);
        if ((rc = write_one(path, a->format, &m, crom_in_get(&in, fd),
                            fv >= 0 ? crom_in_get(&in, fv) : NULL)))
            break;
        times = realloc(times, sizeof(double) * (size_t)(nout + 1));
        files = realloc(files, sizeof(char *) * (size_t)(nout + 1));
        times[nout] = crom_in_get(&in, ft)[0];
        files[nout] = strdup(rel);
        nout++;
        crom_progress_update(&prog, k, NULL);
    }
    crom_progress_end(&prog);
    if (rc == 0 && in.complete != 1)
        crom_cli_warn(cli, "%s is incomplete (the run stopped early): exported its %d frames", in.name, nout);
    if (rc == 0 && !strcmp(a->format, "pvd")) {
        char path[1200];
        snprintf(path, sizeof path, "%s/%s.pvd", a->out, a->name);
        crom_fileout fo;
        if (!(rc = crom_fileout_open(&fo, path, 0))) {
            if ((rc = crom_export_pvd(fo.f, times, (const char *const *)files, nout)))
                crom_fileout_abort(&fo);
            else
                rc = crom_fileout_commit(&fo);
        }
    }
    if (rc == 0)
        crom_cli_info(cli, "wrote %d frames to %s/", nout, a->out);
    for (int i = 0; i < nout; i++)
        free(files[i]);
    free(files);
    free(times);
out:
    crom_mesh_free(&m);
    crom_in_close(&in);
    return rc;
}

int main(int argc, char **argv)
{
    crom_cli cli;
    args a;
    parse_args(&cli, &a, argc, argv);
    return crom_cli_exit(&cli, run(&cli, &a));
}
