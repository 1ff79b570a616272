/* crom-sample — point samples (X, u) of the frames of trajectories: the
 * training set of a displacement basis (crom/samples). */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "base/err.h"
#include "base/rng.h"
#include "cli/cli.h"
#include "io/io.h"
#include "mesh/mesh.h"
#include "rom/result.h"
#include "rom/samples.h"

enum { O_POINTS = 300, O_MODE, O_EVERY, O_SKIPREST };

static const crom_opt sample_opts[] = {
    {"output", 'o', "OUT", "Write the samples to OUT (default: stdout, which must not be a terminal)."},
    {"points", O_POINTS, "N|all", "Samples per frame (default 2048). 'all': every vertex of the mesh, in vertex order (what --basis pod needs; all inputs must then have the same vertex count)."},
    {"mode", O_MODE, "MODE", "vertices (default, as in LiCROM: N distinct random vertices per frame) or interior (N random points uniform by volume, u interpolated barycentrically; vertex index -1)."},
    {"every", O_EVERY, "K", "Keep every K-th frame of each input (frames 0, K, 2K, ...; default 1)."},
    {"skip-rest", O_SKIPREST, NULL, "Drop frames whose displacement is zero everywhere (such as frame 0 at rest). By default they are kept: they are legitimate data."},
    {NULL, 0, NULL, NULL}};

static const crom_cli_optgroup groups[] = {{"Options", sample_opts}, {NULL, NULL}};

static const crom_cli_doc doc = {
    "crom-sample",
    "sample (X, u) point pairs from the frames of trajectories, for training",
    "crom-sample [--points N|all] [--mode vertices|interior] [--every K] [--seed S] [-o OUT] TRAJ...",
    "Reads one or more crom/trajectory inputs (HDF5 files or frame streams; no operand or '-' "
    "is stdin), possibly of different meshes, shapes and loadings, and writes a crom/samples "
    "file: for every kept frame, N samples of the displacement field, each a rest position X and "
    "the displacement u(X) there (LiCROM §3). Fitting a neural field needs only these pairs, "
    "not the meshes.\n\n"
    "Each frame is tagged with its source: the index of its input in the order given. The "
    "source meshes are stored under /sources/000, /sources/001, ... (name order = index order) "
    "with a 'file' attribute naming the input. A thin shell (crom-mesh sheet, disk, import "
    "--thickness) is sampled at its vertices, and its triangles and thickness are kept.\n\n"
    "The same inputs and --seed give the same bytes. A --points larger than a mesh's vertex "
    "count in vertex mode is an error: use --points all or --mode interior.",
    groups,
    "crom-sample run1.h5 run2.h5 --points 2048 --seed 7 -o samples.h5\n"
    "crom-fullsim @compress.flags < box.h5 | crom-sample --every 2 | crom-fitfield -o model.h5\n"
    "crom-sample --points all run.h5 | crom-fitfield --basis pod --rank 10 -o pod.h5",
    "crom-fullsim(1), crom-fitfield(1), crom-info(1)"};

typedef struct {
    const char *out;
    const char **inputs;
    int ninputs;
    long points; /* 0: all */
    int interior, every, skip_rest;
} args;

static int on_opt(void *ctx, int key, const char *v)
{
    args *a = ctx;
    long n;
    switch (key) {
    case 0: {
        const char **ni = realloc(a->inputs, sizeof(char *) * (size_t)(a->ninputs + 1));
        if (!ni)
            return crom_err(CROM_EINTERNAL, "out of memory");
        a->inputs = ni;
        a->inputs[a->ninputs++] = v;
        return 0;
    }
    case 'o': a->out = v; return 0;
    case O_POINTS:
        if (!strcmp(v, "all")) {
            a->points = 0;
            return 0;
        }
        if (crom_parse_int(v, "--points", 1, 100000000L, &n))
            return CROM_EUSAGE;
        a->points = n;
        return 0;
    case O_MODE:
        if (!strcmp(v, "vertices"))
            a->interior = 0;
        else if (!strcmp(v, "interior"))
            a->interior = 1;
        else
            return crom_err(CROM_EUSAGE, "--mode: '%s' is not vertices or interior", v);
        return 0;
    case O_EVERY:
        if (crom_parse_int(v, "--every", 1, 1000000000L, &n))
            return CROM_EUSAGE;
        a->every = (int)n;
        return 0;
    case O_SKIPREST: a->skip_rest = 1; return 0;
    }
    return crom_err(CROM_EINTERNAL, "unhandled option");
}

static void parse_args(crom_cli *cli, args *a, int argc, char **argv)
{
    memset(a, 0, sizeof *a);
    a->points = 2048;
    a->every = 1;
    crom_cli_parse(cli, &doc, argc, argv, on_opt, a);
    int nstdin = 0;
    for (int i = 0; i < a->ninputs; i++)
        nstdin += !strcmp(a->inputs[i], "-");
    const char *err = NULL;
    if (nstdin > 1)
        err = "stdin ('-') can be given only once";
    else if (a->points == 0 && a->interior)
        err = "--points all takes every vertex: it does not combine with --mode interior";
    if (err) {
        crom_err(CROM_EUSAGE, "%s", err);
        exit(crom_cli_exit(cli, CROM_EUSAGE));
    }
}

/* Append the lines of history h that *all does not hold yet (inputs made
 * by the same earlier stages share their first lines). */
static int has_line(const char *all, const char *p, size_t len)
{
    for (const char *q = all; q && *q;) {
        const char *e = strchr(q, '\n');
        size_t ql = e ? (size_t)(e - q) : strlen(q);
        if (ql == len && !strncmp(q, p, len))
            return 1;
        q = e ? e + 1 : NULL;
    }
    return 0;
}

static void merge_history(char **all, const char *h)
{
    for (const char *p = h; p && *p;) {
        const char *e = strchr(p, '\n');
        size_t len = e ? (size_t)(e - p) : strlen(p);
        if (len && !has_line(*all, p, len)) {
            size_t old = *all ? strlen(*all) : 0;
            char *n = realloc(*all, old + len + 2);
            if (!n)
                return;
            if (old)
                n[old++] = '\n';
            memcpy(n + old, p, len);
            n[old + len] = 0;
            *all = n;
        }
        p = e ? e + 1 : NULL;
    }
}

static int sample_source(crom_cli *cli, args *a, crom_samples *s, const char *path, int k, crom_rng *rng,
                         char **history)
{
    crom_in in;
    int rc = crom_in_open(&in, path);
    if (rc)
        return rc;
    if ((rc = crom_in_expect(&in, "crom/trajectory", 1))) {
        crom_in_close(&in);
        return rc;
    }
    crom_mesh m;
    hid_t loc = H5Gopen2(in.h5, "mesh", H5P_DEFAULT);
    rc = loc < 0 ? crom_err(CROM_EDATA, "%s has no /mesh", in.name) : crom_mesh_read_any(loc, &m);
    if (loc >= 0)
        H5Gclose(loc);
    if (!rc && a->interior && crom_mesh_is_surface(&m)) {
        rc = crom_err(CROM_EUSAGE, "--mode interior samples the inside of tets; %s is a shell surface (%d "
                      "triangles): sample its vertices", in.name, m.ntri);
        crom_mesh_free(&m);
        loc = -1;
    }
    if (rc) {
        if (loc >= 0)
            crom_err_ctx("%s", in.name);
        crom_in_close(&in);
        return rc;
    }
    crom_samples_picker pk;
    memset(&pk, 0, sizeof pk);
    int fd = crom_in_field(&in, "displacement"), ft = crom_in_field(&in, "time");
    if (fd < 0 || ft < 0) {
        rc = CROM_EDATA;
        goto out;
    }
    if (in.fields[fd].count != 3 * (size_t)m.nv) {
        rc = crom_err(CROM_EDATA, "%s: displacement has %zu values per frame, its mesh needs %d",
                      in.name, in.fields[fd].count, 3 * m.nv);
        goto out;
    }
    /* the sample count */
    if (k == 0)
        s->N = a->points ? (int)a->points : m.nv;
    else if (!a->points && m.nv != s->N) {
        rc = crom_err(CROM_EUSAGE,
                      "--points all needs inputs of one vertex count: %s has %d vertices, the first input %d "
                      "(give --points N)", in.name, m.nv, s->N);
        goto out;
    }
    if (!a->interior && s->N > m.nv) {
        rc = crom_err(CROM_EUSAGE,
                      "--points %d exceeds the %d vertices of %s: use --points all or --mode interior",
                      s->N, m.nv, in.name);
        goto out;
    }
    int how = a->interior ? CROM_SAMPLES_INTERIOR : a->points ? CROM_SAMPLES_VERTICES : CROM_SAMPLES_ALL;
    if ((rc = crom_samples_picker_init(&pk, &m, how)))
        goto out;
    crom_cli_progress prog;
    crom_cli_progress_start(&prog, cli, "sample", in.form == CROM_IO_H5 ? in.nframes : 0);
    long idx = 0, kept = 0;
    while ((rc = crom_in_next(&in)) == 1) {
        long fi = idx++;
        if (fi % a->every)
            continue;
        const double *u = crom_in_get(&in, fd);
        if ((rc = crom_result_check_frame(&in, NULL, fi)))
            goto endloop;
        int zero = 1;
        for (size_t i = 0; i < 3 * (size_t)m.nv; i++)
            zero &= u[i] == 0;
        if (zero && a->skip_rest)
            continue;
        if ((rc = crom_samples_add_frame(s, &pk, u, rng, k, crom_in_get(&in, ft)[0])))
            break;
        kept++;
        crom_cli_progress_update(&prog, idx, NULL);
    }
endloop:
    crom_cli_progress_end(&prog);
    if (rc < 0)
        rc = -rc;
    if (rc)
        goto out;
    if (in.complete != 1)
        crom_cli_warn(cli, "%s is incomplete (the run stopped early): sampled its %ld frames", in.name, idx);
    if (cli->verbose)
        crom_cli_info(cli, "%s: %d vertices, kept %ld of %ld frames", in.name, m.nv, kept, idx);
    /* keep the source mesh (vertices and tets, or a shell's triangles and thickness) */
    crom_mesh *src = &s->src[k];
    memset(src, 0, sizeof *src);
    src->nv = m.nv;
    src->nt = m.nt;
    src->ntri = m.ntri;
    src->thickness = m.thickness;
    src->X = m.X;
    src->tets = m.tets;
    src->tris = m.tris;
    m.X = NULL;
    m.tets = NULL;
    m.tris = NULL;
    s->src_file[k] = crom_strdup(in.name);
    s->nsources = k + 1;
    merge_history(history, in.history);
out:
    crom_samples_picker_free(&pk);
    crom_mesh_free(&m);
    crom_in_close(&in);
    return rc;
}

static int run(crom_cli *cli, args *a)
{
    static const char *stdin_only[] = {"-"};
    const char **inputs = a->ninputs ? a->inputs : stdin_only;
    int n = a->ninputs ? a->ninputs : 1;
    crom_samples S;
    memset(&S, 0, sizeof S);
    crom_samples *s = &S;
    snprintf(s->mode, sizeof s->mode, "%s", a->interior ? "interior" : "vertices");
    s->seed = (long long)cli->seed;
    s->src = crom_calloc((size_t)n, sizeof(crom_mesh));
    s->src_file = crom_calloc((size_t)n, sizeof(char *));
    if (!s->src || !s->src_file)
        return CROM_EINTERNAL;
    crom_rng rng;
    crom_rng_seed(&rng, cli->seed);
    char *history = NULL;
    int rc = 0;
    /* every input must exist before the work starts */
    for (int k = 0; k < n && !rc; k++)
        if (strcmp(inputs[k], "-") && access(inputs[k], R_OK) != 0)
            rc = crom_err(CROM_ENOINPUT, "%s: %s", inputs[k], strerror(errno));
    for (int k = 0; k < n && !rc; k++)
        rc = sample_source(cli, a, s, inputs[k], k, &rng, &history);
    if (!rc && s->F == 0)
        rc = crom_err(CROM_EDATA, "no frames to sample (the inputs have none%s)",
                      a->skip_rest ? ", or all are at rest and --skip-rest dropped them" : "");
    if (!rc) {
        crom_out o;
        if (!(rc = crom_out_create(&o, a->out, CROM_SAMPLES_SCHEMA, CROM_SAMPLES_VERSION, cli->cmdline,
                                   history, CROM_OUT_PLAIN))) {
            rc = crom_samples_write(o.h5, s);
            if (!rc)
                rc = crom_out_commit(&o);
            else
                crom_out_fail(&o);
        }
        if (!rc && cli->verbose)
            crom_cli_info(cli, "%d frames x %d %s samples from %d source%s", s->F, s->N, s->mode,
                          s->nsources, s->nsources == 1 ? "" : "s");
    }
    free(history);
    crom_samples_free(s);
    return rc;
}

int main(int argc, char **argv)
{
    crom_cli cli;
    args a;
    parse_args(&cli, &a, argc, argv);
    int rc = run(&cli, &a);
    free(a.inputs);
    return crom_cli_exit(&cli, rc);
}
