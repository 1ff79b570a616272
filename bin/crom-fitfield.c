/* crom-fitfield — learn a displacement basis W(X) (crom/model) from point
 * samples (crom/samples): a neural field, or a classic POD basis. */
#ifdef _OPENMP
#include <omp.h>
#endif
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "err.h"
#include "fit.h"
#include "io.h"
#include "model.h"
#include "samples.h"

enum { O_RANK = 300, O_ENCODER, O_BASIS, O_EPOCHS, O_MINUTES, O_LR, O_BATCH, O_PPS, O_ENCPTS,
       O_ACT, O_WIDTH, O_DEPTH, O_TIK };

static const crom_opt fit_opts[] = {
    {"output", 'o', "OUT", "Write the model to OUT (default: stdout, which must not be a terminal)."},
    {"rank", O_RANK, "R", "Number of basis fields r, the latent dimension (default 20). At most the number of frames with a non-zero displacement (for pod: the numerical rank of the snapshots)."},
    {"basis", O_BASIS, "KIND", "mlp (default): a neural field W(X), usable on any mesh. pod: classic POD of samples of ONE mesh taken with crom-sample --points all, stored as a piecewise-linear field on that mesh."},
    {"encoder", O_ENCODER, "KIND", "How q is found for a frame during and after training (mlp only). lsq (default): the least-squares fit of W to the frame's samples, re-solved at every step (variable projection; fast). pointnet: the paper's PointNet encoder, trained jointly with W (LiCROM eq. 4) and stored in the model."},
    {NULL, 0, NULL, NULL}};

static const crom_opt train_opts[] = {
    {"epochs", O_EPOCHS, "N", "Training epochs (default 400 for lsq, 3750 for pointnet as in the paper). An epoch is one pass over the frames in batches of --batch frames. The learning rate is --lr, divided by 5 after a third of the epochs and by 50 after two thirds (LiCROM §3.1)."},
    {"minutes", O_MINUTES, "M", "Stop training after M minutes of wall time. The learning-rate schedule then follows whichever is further along: the fraction of epochs done or the fraction of the time budget used, so a run cut short by the clock still goes through all three rates. Runs limited by the clock are not byte-reproducible."},
    {"lr", O_LR, "LR", "Base learning rate of Adam (default 5e-3 for lsq, 1e-3 for pointnet as in the paper)."},
    {"batch", O_BATCH, "B", "Frames per step (default 16)."},
    {"points-per-step", O_PPS, "P", "Samples of each frame used per step (default: 128 for lsq, every sample for pointnet). For vertex samples, a step evaluates W once at a random subset of one mesh's vertices, shared by all frames of the batch; P sets its size (about P x vertices / samples-per-frame). Interior samples are evaluated frame by frame, which costs about --batch times more per step."},
    {"encoder-points", O_ENCPTS, "N", "Points per frame the PointNet encoder sees, a random subsample (default 2500, or all if fewer)."},
    {"activation", O_ACT, "ACT", "Hidden activation of W: elu (default) or sine (SIREN, omega0 = 30). With omega0 = 30 a sine field can interpolate the training points and oscillate between them: check it with crom-encode on another mesh."},
    {"width", O_WIDTH, "W", "Hidden width of the field MLP (default 60)."},
    {"depth", O_DEPTH, "D", "Dense layers of the field MLP (default 5: 3 -> 60 -> 60 -> 60 -> 60 -> 3r)."},
    {"tikhonov", O_TIK, "T", "Relative Tikhonov weight of the lsq fits: lambda = T tr(W^T W) / r (default 1e-6)."},
    {NULL, 0, NULL, NULL}};

static const crom_optgroup groups[] = {{"Options", fit_opts}, {"Training", train_opts}, {NULL, NULL}};

static const crom_doc doc = {
    "crom-fitfield",
    "learn a displacement basis W(X) from point samples",
    "crom-fitfield [--rank R] [--encoder lsq|pointnet] [--basis mlp|pod] [--epochs N] [--minutes M] [--seed S] [-o OUT] [SAMPLES]",
    "Reads a crom/samples file (a path, or stdin) and writes a crom/model: a basis W(X) of r "
    "displacement fields, so that u(X) = W(X) q for a latent q in metres (LiCROM §3).\n\n"
    "--basis mlp trains a neural field: an MLP with ELU activations (5 layers of width 60 by "
    "default) mapping a rest position to the 3 x r matrix W(X), with Adam, Xavier "
    "initialization and 16 frames per batch. With --encoder lsq every frame's q is the "
    "least-squares fit of the current W to the frame's samples (variable projection, with a "
    "tiny Tikhonov term), re-solved at every step; the gradient is that of the fit with q held "
    "fixed. Frames of one mesh share the points of a step, so W is evaluated once per point "
    "for the whole batch. With --encoder pointnet a PointNet encoder seeing a 2500-point "
    "subsample is trained jointly (LiCROM eq. 4) and kept in the model. Displacements are "
    "scaled by their RMS value during training; the model keeps q in metres. Afterwards the "
    "fields are re-expressed, exactly, in "
    "a canonical basis of their span: orthonormal over the training points (each field has RMS "
    "magnitude 1) and ordered by decreasing variance over the training frames, like POD modes.\n\n"
    "--basis pod computes the classic proper orthogonal decomposition of samples of one mesh "
    "with every vertex in every frame (crom-sample --points all): the r leading modes of the "
    "snapshots weighted by the lumped vertex volumes (orthonormal in the volume-mean inner "
    "product; the density cancels), stored as a piecewise-linear field on that mesh so the "
    "whole pipeline can run the classic linear ROM as a baseline.\n\n"
    "The relative reconstruction error ||Wq - u|| / ||u|| over all samples of all training "
    "frames (q by least squares, or by the encoder for pointnet) is printed on stderr and "
    "stored in the model with the training log (loss and wall time per epoch). A progress bar "
    "shows on a terminal. The same samples, options and --seed give the same bytes (set "
    "SOURCE_DATE_EPOCH for the stored times; --threads changes the last bits).",
    groups,
    "crom-sample run*.h5 | crom-fitfield --rank 20 -o model.h5\n"
    "crom-fitfield --encoder pointnet --epochs 3750 -o model.h5 samples.h5\n"
    "crom-sample --points all run.h5 | crom-fitfield --basis pod --rank 10 -o pod.h5",
    "crom-sample(1), crom-encode(1), crom-cubature(1), crom-info(1)"};

typedef struct {
    const char *input, *out;
    int pod;
    crom_fit_opts fit;
    int encoder_given;
} args;

static int on_opt(void *ctx, int key, const char *v)
{
    args *a = ctx;
    long n;
    double d;
    switch (key) {
    case 0:
        if (a->input)
            return crom_err(CROM_EUSAGE, "unexpected operand '%s' (one samples file)", v);
        a->input = v;
        return 0;
    case 'o': a->out = v; return 0;
    case O_RANK:
        if (crom_parse_int(v, "--rank", 1, 10000, &n))
            return CROM_EUSAGE;
        a->fit.rank = (int)n;
        return 0;
    case O_BASIS:
        if (!strcmp(v, "mlp"))
            a->pod = 0;
        else if (!strcmp(v, "pod"))
            a->pod = 1;
        else
            return crom_err(CROM_EUSAGE, "--basis: '%s' is not mlp or pod", v);
        return 0;
    case O_ENCODER:
        if (!strcmp(v, "lsq"))
            a->fit.encoder = CROM_ENC_LSQ;
        else if (!strcmp(v, "pointnet"))
            a->fit.encoder = CROM_ENC_POINTNET;
        else
            return crom_err(CROM_EUSAGE, "--encoder: '%s' is not lsq or pointnet", v);
        a->encoder_given = 1;
        return 0;
    case O_EPOCHS:
        if (crom_parse_int(v, "--epochs", 1, 100000000L, &n))
            return CROM_EUSAGE;
        a->fit.epochs = (int)n;
        return 0;
    case O_MINUTES: return crom_parse_positive(v, "--minutes", &a->fit.minutes);
    case O_LR: return crom_parse_positive(v, "--lr", &a->fit.lr);
    case O_BATCH:
        if (crom_parse_int(v, "--batch", 1, 1000000L, &n))
            return CROM_EUSAGE;
        a->fit.batch = (int)n;
        return 0;
    case O_PPS:
        if (crom_parse_int(v, "--points-per-step", 1, 100000000L, &n))
            return CROM_EUSAGE;
        a->fit.points_per_step = (int)n;
        return 0;
    case O_ENCPTS:
        if (crom_parse_int(v, "--encoder-points", 1, 100000000L, &n))
            return CROM_EUSAGE;
        a->fit.enc_points = (int)n;
        return 0;
    case O_ACT:
        if (!strcmp(v, "elu"))
            a->fit.act = CROM_NN_ELU;
        else if (!strcmp(v, "sine"))
            a->fit.act = CROM_NN_SINE;
        else
            return crom_err(CROM_EUSAGE, "--activation: '%s' is not elu or sine", v);
        return 0;
    case O_WIDTH:
        if (crom_parse_int(v, "--width", 1, 4096, &n))
            return CROM_EUSAGE;
        a->fit.width = (int)n;
        return 0;
    case O_DEPTH:
        if (crom_parse_int(v, "--depth", 2, CROM_NN_MAX_LAYERS, &n))
            return CROM_EUSAGE;
        a->fit.depth = (int)n;
        return 0;
    case O_TIK:
        if (crom_parse_double(v, "--tikhonov", &d))
            return CROM_EUSAGE;
        if (d < 0 || d > 1)
            return crom_err(CROM_EUSAGE, "--tikhonov must be in [0, 1], got %s", v);
        a->fit.tikhonov = d;
        return 0;
    }
    return crom_err(CROM_EINTERNAL, "unhandled option");
}

static void parse_args(crom_cli *cli, args *a, int argc, char **argv)
{
    memset(a, 0, sizeof *a);
    crom_fit_defaults(&a->fit);
    crom_cli_parse(cli, &doc, argc, argv, on_opt, a);
    if (a->pod && a->encoder_given && a->fit.encoder == CROM_ENC_POINTNET) {
        crom_err(CROM_EUSAGE, "--basis pod has no neural encoder: its q is the lsq projection (drop --encoder pointnet)");
        exit(crom_cli_exit(cli, CROM_EUSAGE));
    }
    a->fit.seed = cli->seed;
#ifdef _OPENMP
    a->fit.threads = cli->threads > 0 ? cli->threads : omp_get_num_procs();
#else
    a->fit.threads = 1;
#endif
}

static void on_progress(void *ctx, int epoch, double frac, double loss)
{
    char buf[64];
    snprintf(buf, sizeof buf, "epoch %d, loss %.3g m^2", epoch, loss);
    crom_progress_update(ctx, (long)(frac * 1000), buf);
}

static int run(crom_cli *cli, args *a)
{
    crom_in in;
    int rc = crom_in_open(&in, a->input);
    if (rc)
        return rc;
    crom_samples S;
    if ((rc = crom_in_expect(&in, CROM_SAMPLES_SCHEMA, CROM_SAMPLES_VERSION)) ||
        (rc = crom_samples_read(&in, &S))) {
        crom_in_close(&in);
        return rc;
    }
    crom_in_close(&in);
    crom_model m;
    crom_model_clear(&m);
    double captured = NAN, t0 = crom_now();
    crom_fit_stats stats = {0, 0, 0, 0};
    if (a->pod) {
        rc = crom_fit_pod(&S, a->fit.rank, &m, &captured);
    } else {
        crom_progress prog;
        crom_progress_start(&prog, cli, "fitfield", 1000);
        a->fit.progress = on_progress;
        a->fit.progress_ctx = &prog;
        a->fit.stats = &stats;
        rc = crom_fit_mlp(&S, &a->fit, &m);
        crom_progress_end(&prog);
    }
    if (!rc) {
        crom_out o;
        if (!(rc = crom_out_create(&o, a->out, CROM_MODEL_SCHEMA, CROM_MODEL_VERSION, cli, S.history,
                                   CROM_OUT_PLAIN))) {
            rc = crom_model_write(o.h5, &m);
            if (!rc)
                rc = crom_out_commit(&o);
            else
                crom_out_fail(&o);
        }
    }
    if (!rc) {
        if (a->pod)
            crom_cli_info(cli, "relative reconstruction error %.4g over %d frames (pod, rank %d, %.1f%% of the snapshot energy, %.1f s)",
                          m.reconstruction_error, S.F, m.rank, 100 * captured, crom_now() - t0);
        else
            crom_cli_info(cli, "relative reconstruction error %.4g over %d frames (mlp/%s, rank %d, %d epochs, %.1f s)",
                          m.reconstruction_error, S.F, crom_model_encoder_name(m.encoder), m.rank,
                          m.nepochs, crom_now() - t0);
        if (cli->verbose && !a->pod && stats.seconds > 0)
            crom_cli_info(cli, "%ld steps in %.1f s: %.3g points/s through W forward+backward, %.3g samples/s in the loss",
                          stats.steps, stats.seconds, stats.rows / stats.seconds, stats.samples / stats.seconds);
        if (cli->verbose)
            crom_cli_info(cli, "model_id %s", m.model_id);
    }
    crom_model_free(&m);
    crom_samples_free(&S);
    return rc;
}

int main(int argc, char **argv)
{
    crom_cli cli;
    args a;
    parse_args(&cli, &a, argc, argv);
    return crom_cli_exit(&cli, run(&cli, &a));
}
