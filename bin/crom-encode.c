/* crom-encode — latent coordinates q of every frame of a trajectory, on any
 * mesh, in a model's subspace (crom/latent). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "cli/cli.h"
#include "io/io.h"
#include "mesh/mesh.h"
#include "rom/map.h"
#include "rom/model.h"
#include "rom/project.h"
#include "rom/result.h"

enum { O_MODEL = 300, O_ENCODER, O_LSQ };

static const crom_opt encode_opts[] = {
    {"model", O_MODEL, "M", "The crom/model whose basis W the latents refer to (required)."},
    {"output", 'o', "OUT", "Write the latent trajectory to OUT (default: stdout; a frame stream into a pipe)."},
    {"encoder", O_ENCODER, "KIND", "lsq (default): mass-weighted least-squares projection onto W at the mesh's vertices. pointnet: the model's PointNet encoder on all vertices (only for models trained with --encoder pointnet)."},
    {"lsq", O_LSQ, NULL, "Same as --encoder lsq."},
    {NULL, 0, NULL, NULL}};

static const crom_cli_optgroup groups[] = {{"Options", encode_opts}, {NULL, NULL}};

static const crom_cli_doc doc = {
    "crom-encode",
    "encode the frames of a trajectory on any mesh as latent coordinates q",
    "crom-encode --model M [--encoder lsq|pointnet] [-o OUT] [TRAJ]",
    "Reads a crom/trajectory (HDF5 file or frame stream, a path or stdin) on any mesh, "
    "evaluates the model's basis W at that mesh's vertices and writes a crom/latent series with "
    "q for every frame, so that u(X) ~ W(X) q. Reduced runs start from such a state.\n\n"
    "The default projection is the least-squares fit in the mass-weighted norm of the mesh: "
    "q minimizes sum_v w_v |W(X_v) q - u_v|^2 with w_v the lumped vertex volumes (the lumped "
    "mass up to the density, which cancels), a discretization-independent approximation of "
    "the L2 norm over the body. --encoder pointnet uses the model's PointNet instead, fed with "
    "(X_v, u_v) of every vertex. qdot is always the same least-squares projection of the "
    "velocity field (the encoder is nonlinear and does not apply to velocities).\n\n"
    "Each frame's reconstruction_error is |W q - u| / |u| in that mass-weighted norm (0 for "
    "a frame at rest); the overall error sqrt(sum |W q - u|^2 / sum |u|^2) over all frames is "
    "printed on stderr as one line. The output carries the model's model_id and rank and "
    "streams into a pipe frame by frame as the input arrives.\n\n"
    "A neuralmodes map (crom-fitfield --objective neuralmodes) encodes a state by its modal "
    "coordinates, the same projection onto the map's linear modes (its correction is M-orthogonal "
    "to them), on the map's own mesh; reconstruction_error is then that of the modes alone. Other "
    "data-free maps have no encoder.",
    groups,
    "crom-encode --model model.h5 -o run.latent.h5 run.h5\n"
    "crom-fullsim @scene.flags < other_mesh.h5 | crom-encode --model model.h5 > q.h5",
    "crom-fitfield(1), crom-reducedstep(1), crom-export(1)"};

typedef struct {
    const char *input, *out, *model;
    int pointnet;
} args;

static int on_opt(void *ctx, int key, const char *v)
{
    args *a = ctx;
    switch (key) {
    case 0:
        if (a->input)
            return crom_err(CROM_EUSAGE, "unexpected operand '%s' (one trajectory at a time)", v);
        a->input = v;
        return 0;
    case 'o': a->out = v; return 0;
    case O_MODEL: a->model = v; return 0;
    case O_LSQ: a->pointnet = 0; return 0;
    case O_ENCODER:
        if (!strcmp(v, "lsq"))
            a->pointnet = 0;
        else if (!strcmp(v, "pointnet"))
            a->pointnet = 1;
        else
            return crom_err(CROM_EUSAGE, "--encoder: '%s' is not lsq or pointnet", v);
        return 0;
    }
    return crom_err(CROM_EINTERNAL, "unhandled option");
}

static void parse_args(crom_cli *cli, args *a, int argc, char **argv)
{
    memset(a, 0, sizeof *a);
    crom_cli_parse(cli, &doc, argc, argv, on_opt, a);
    if (!a->model) {
        crom_err(CROM_EUSAGE, "--model M is required (the crom/model to encode with)");
        exit(crom_cli_exit(cli, CROM_EUSAGE));
    }
}

static int run(crom_cli *cli, args *a)
{
    crom_model M;
    int rc = crom_model_load(a->model, &M);
    if (rc)
        return rc;
    if (a->pointnet && M.encoder != CROM_MODEL_ENC_POINTNET) {
        rc = crom_err(CROM_EUSAGE, "%s has no PointNet encoder (its encoder is %s): use --encoder lsq",
                      a->model, crom_model_encoder_name(M.encoder));
        crom_model_free(&M);
        return rc;
    }
    crom_in in;
    if ((rc = crom_in_open(&in, a->input))) {
        crom_model_free(&M);
        return rc;
    }
    crom_mesh m;
    memset(&m, 0, sizeof m);
    crom_project P;
    memset(&P, 0, sizeof P);
    double *pts = NULL, *q = NULL, *qd = NULL;
    crom_out o;
    int out_open = 0;
    if ((rc = crom_in_expect(&in, "crom/trajectory", 1)))
        goto out;
    hid_t loc = H5Gopen2(in.h5, "mesh", H5P_DEFAULT);
    rc = loc < 0 ? crom_err(CROM_EDATA, "%s has no /mesh", in.name) : crom_mesh_read_any(loc, &m);
    if (loc >= 0)
        H5Gclose(loc);
    if (rc) {
        if (loc >= 0)
            crom_err_ctx("%s", in.name);
        goto out;
    }
    int fd = crom_in_field(&in, "displacement"), ft = crom_in_field(&in, "time");
    if (fd < 0 || ft < 0) {
        rc = CROM_EDATA;
        goto out;
    }
    int fv = -1, fs = -1;
    for (int i = 0; i < in.nfields; i++) {
        if (!strcmp(in.fields[i].name, "velocity"))
            fv = i;
        if (!strcmp(in.fields[i].name, "step"))
            fs = i;
    }
    crom_err_clear();
    if (in.fields[fd].count != 3 * (size_t)m.nv ||
        (fv >= 0 && in.fields[fv].count != 3 * (size_t)m.nv)) {
        rc = crom_err(CROM_EDATA, "%s: displacement has %zu values per frame, its mesh needs %d",
                      in.name, in.fields[fd].count, 3 * m.nv);
        goto out;
    }
    int r = M.rank;
    size_t n3 = 3 * (size_t)m.nv;
    q = crom_malloc(sizeof(double) * r);
    qd = crom_calloc((size_t)r, sizeof(double));
    if (a->pointnet)
        pts = crom_malloc(sizeof(double) * 2 * n3);
    if (!q || !qd || (a->pointnet && !pts)) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    size_t nout = 0;
    if (!strcmp(M.basis, "neuralmodes") && M.basis_v) {
        /* a neural-modes map's latent is the modal coordinates (Wang et al.: the
         * correction y is M-orthogonal to the modes): project onto its modes */
        crom_model lin;
        if (crom_map_same_mesh(&m, &M.mesh)) {
            rc = crom_err(CROM_EUSAGE, "%s is a neuralmodes map of another mesh: its modal coordinates are taken "
                          "on its own mesh (%d vertices)", a->model, M.mesh.nv);
            goto out;
        }
        if ((rc = crom_model_from_mesh(&lin, "modes", &M.mesh, M.basis_v, M.rank)))
            goto out;
        rc = crom_project_init(&P, &lin, &m, &nout);
        crom_model_free(&lin);
        if (rc)
            goto out;
    } else if ((rc = crom_project_init(&P, &M, &m, &nout))) {
        goto out;
    }
    if (nout && cli->verbose)
        crom_cli_info(cli, "%zu of %d vertices lie outside the model's mesh: W is extended there", nout, m.nv);
    /* the output series */
    if ((rc = crom_out_create(&o, a->out, "crom/latent", 1, cli->cmdline, in.history, CROM_OUT_SERIES)))
        goto out;
    out_open = 1;
    hsize_t dr = (hsize_t)r;
    if ((rc = crom_h5_set_str(o.h5, ".", "model_id", M.model_id)) ||
        (rc = crom_h5_set_i64(o.h5, ".", "rank", r)) ||
        (rc = crom_out_field(&o, "time", 0, NULL, M.basis)) ||
        (fs >= 0 && (rc = crom_out_field(&o, "step", 0, NULL, M.basis))) ||
        (rc = crom_out_field(&o, "q", 1, &dr, M.basis)) ||
        (fv >= 0 && (rc = crom_out_field(&o, "qdot", 1, &dr, M.basis))) ||
        (rc = crom_out_field(&o, "reconstruction_error", 0, NULL, M.basis)) ||
        (rc = crom_out_begin(&o)))
        goto out;
    crom_cli_progress prog;
    crom_cli_progress_start(&prog, cli, "encode", in.form == CROM_IO_H5 ? in.nframes : 0);
    double E2 = 0, U2 = 0;
    long nf = 0;
    while ((rc = crom_in_next(&in)) == 1) {
        rc = 0;
        const double *u = crom_in_get(&in, fd);
        if ((rc = crom_result_check_frame(&in, NULL, nf)))
            break;
        if (a->pointnet) {
            for (int v = 0; v < m.nv; v++)
                for (int d = 0; d < 3; d++) {
                    pts[6 * (size_t)v + d] = m.X[3 * (size_t)v + d];
                    pts[6 * (size_t)v + 3 + d] = u[3 * (size_t)v + d];
                }
            if ((rc = crom_model_encode_pointnet(&M, (size_t)m.nv, pts, q)))
                break;
        } else {
            crom_project_apply(&P, u, q);
        }
        if (fv >= 0)
            crom_project_apply(&P, crom_in_get(&in, fv), qd);
        double e2, u2;
        crom_project_residual(&P, u, q, &e2, &u2);
        E2 += e2;
        U2 += u2;
        double fe = u2 > 0 ? sqrt(e2 / u2) : sqrt(e2);
        const double *vals[5];
        int k = 0;
        vals[k++] = crom_in_get(&in, ft);
        if (fs >= 0)
            vals[k++] = crom_in_get(&in, fs);
        vals[k++] = q;
        if (fv >= 0)
            vals[k++] = qd;
        vals[k++] = &fe;
        if ((rc = crom_out_frame(&o, vals)))
            break;
        nf++;
        crom_cli_progress_update(&prog, nf, NULL);
    }
    crom_cli_progress_end(&prog);
    if (rc < 0)
        rc = -rc;
    if (rc)
        goto out;
    if (nf == 0) {
        rc = crom_err(CROM_EDATA, "%s has no frames to encode", in.name);
        goto out;
    }
    double err = U2 > 0 ? sqrt(E2 / U2) : 0;
    if (in.complete != 1) {
        crom_cli_warn(cli, "%s is incomplete (the run stopped early): encoded its %ld frames, output marked incomplete",
                      in.name, nf);
        crom_err(CROM_EDATA, "incomplete input");
        crom_out_fail(&o);
        crom_err_clear();
    } else if ((rc = crom_out_commit(&o))) {
        out_open = 0;
        goto out;
    }
    out_open = 0;
    crom_cli_info(cli, "relative reconstruction error %.4g over %ld frames", err, nf);
out:
    if (out_open)
        crom_out_fail(&o);
    crom_project_free(&P);
    free(pts);
    free(q);
    free(qd);
    crom_mesh_free(&m);
    crom_in_close(&in);
    crom_model_free(&M);
    return rc;
}

int main(int argc, char **argv)
{
    crom_cli cli;
    args a;
    parse_args(&cli, &a, argc, argv);
    return crom_cli_exit(&cli, run(&cli, &a));
}
