/* crom-diff — how far one simulation result is from another: relative
 * displacement error per frame and over the run. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "cli/cli.h"
#include "io/io.h"
#include "rom/result.h"

enum { O_MESH = 300, O_MODEL, O_MODEL_A, O_MODEL_B, O_CSV, O_MAX };

static const crom_opt diff_opts[] = {
    {"mesh", O_MESH, "MESH", "The mesh to compare on (a crom/mesh, or a trajectory or cubature carrying one). Default: the mesh of a trajectory among A and B."},
    {"model", O_MODEL, "MODEL", "The crom/model that decodes a crom/latent (u = W q) on the mesh."},
    {"model-a", O_MODEL_A, "MODEL", "Model for A only (when A and B are latents of different models)."},
    {"model-b", O_MODEL_B, "MODEL", "Model for B only."},
    {"csv", O_CSV, "FILE", "Also write the per-frame table as CSV."},
    {"max-error", O_MAX, "E", "Exit with status 1 when the relative error over the run exceeds E (like diff(1) for differing files)."},
    {NULL, 0, NULL, NULL}};

static const crom_cli_optgroup groups[] = {{"Options", diff_opts}, {NULL, NULL}};

static const crom_cli_doc doc = {
    "crom-diff",
    "relative displacement error between two simulation results",
    "crom-diff A B [--mesh MESH] [--model MODEL] [--csv FILE] [--max-error E]",
    "Compares two results frame by frame on one mesh: each of A and B is a crom/trajectory "
    "(displacements on its mesh) or a crom/latent decoded through a model, u = W(X) q, on the "
    "mesh. B is the reference. Frames are matched by time; frames of one that the other lacks "
    "are skipped and counted.\n\n"
    "The error of a frame is ||u_A - u_B||_M / ||u_B||_M with the lumped-mass norm of the mesh "
    "(a discretization-independent L2 norm over the body; for a shell surface, whose trajectories "
    "compare the same way, the lumped mass of its triangles, thickness x area / 3 per corner); "
    "over the run it is "
    "sqrt(sum ||u_A - u_B||^2_M / sum ||u_B||^2_M). The table goes to stdout, one line per frame "
    "(frame, time, relative error, largest vertex distance in m), then a one-line summary; with "
    "--quiet only the summary.",
    groups,
    "crom-diff reduced.h5 full.h5 --model model.h5 --mesh full.h5\n"
    "crom-diff a.h5 b.h5 --quiet --max-error 0.03",
    "crom-reducedstep(1), crom-fullsim(1), crom-encode(1)"};

typedef struct {
    const char *a, *b, *mesh, *model, *model_a, *model_b, *csv;
    double maxerr;
} args;

static int on_opt(void *ctx, int key, const char *v)
{
    args *a = ctx;
    switch (key) {
    case 0:
        if (!a->a)
            a->a = v;
        else if (!a->b)
            a->b = v;
        else
            return crom_err(CROM_EUSAGE, "unexpected operand '%s' (compare two results)", v);
        return 0;
    case O_MESH: a->mesh = v; return 0;
    case O_MODEL: a->model = v; return 0;
    case O_MODEL_A: a->model_a = v; return 0;
    case O_MODEL_B: a->model_b = v; return 0;
    case O_CSV: a->csv = v; return 0;
    case O_MAX: return crom_parse_positive(v, "--max-error", &a->maxerr);
    }
    return crom_err(CROM_EINTERNAL, "unhandled option");
}

/* The mesh both are compared on: --mesh, else a trajectory among A, B. */
static const char *mesh_source(const args *a)
{
    if (a->mesh)
        return a->mesh;
    const char *cand[2] = {a->a, a->b};
    for (int i = 0; i < 2; i++) {
        crom_in in;
        if (!strcmp(cand[i], "-"))
            continue; /* stdin can be read only once: never probe it */
        if (crom_in_open(&in, cand[i]) == 0) {
            int traj = !strcmp(in.schema, "crom/trajectory");
            crom_in_close(&in);
            if (traj)
                return cand[i];
        }
        crom_err_clear();
    }
    return NULL;
}

static int run(crom_cli *cli, args *a)
{
    if (a->a && a->b && !strcmp(a->a, "-") && !strcmp(a->b, "-"))
        return crom_err(CROM_EUSAGE, "A and B cannot both be stdin");
    const char *mesh = mesh_source(a);
    crom_result A, B;
    int rc = crom_result_open(&A, a->a, mesh, a->model_a ? a->model_a : a->model);
    if (rc)
        return rc;
    if ((rc = crom_result_open(&B, a->b, mesh, a->model_b ? a->model_b : a->model))) {
        crom_result_close(&A);
        return rc;
    }
    if (A.mesh.nv != B.mesh.nv) {
        rc = crom_err(CROM_EDATA, "%s and %s live on different meshes (%d and %d vertices): give --mesh", a->a, a->b,
                      A.mesh.nv, B.mesh.nv);
        goto out;
    }
    int nv = A.mesh.nv;
    double *m = crom_calloc((size_t)nv, sizeof(double));
    double *ua = crom_malloc(sizeof(double) * 3 * (size_t)nv), *ub = crom_malloc(sizeof(double) * 3 * (size_t)nv);
    crom_fileout csv = {0};
    if (!m || !ua || !ub) {
        rc = CROM_EINTERNAL;
        goto out2;
    }
    crom_mesh_vertex_volumes(&A.mesh, m); /* the M-norm per unit density (a shell: t A / 3 per corner) */
    if (a->csv && (rc = crom_fileout_open(&csv, a->csv, 0)))
        goto out2;
    if (csv.f)
        fprintf(csv.f, "frame,time,relative_error,max_distance_m\n");
    if (!cli->quiet)
        printf("%6s %12s %14s %14s\n", "frame", "time", "rel_error", "max_dist_m");
    double ta = 0, tb = 0, sd = 0, sb = 0, worst = 0, tworst = 0;
    long nmatch = 0, skipped = 0;
    int ra = crom_result_next(&A, &ta, ua, NULL), rb = crom_result_next(&B, &tb, ub, NULL);
    while (ra == 1 && rb == 1) {
        double tol = 1e-9 * (1 + fabs(tb));
        if (ta < tb - tol) { /* A has a frame B lacks */
            skipped++;
            ra = crom_result_next(&A, &ta, ua, NULL);
            continue;
        }
        if (tb < ta - tol) {
            skipped++;
            rb = crom_result_next(&B, &tb, ub, NULL);
            continue;
        }
        double d = 0, b = 0, dmax = 0;
        for (int v = 0; v < nv; v++) {
            double dd = 0, bb = 0;
            for (int c = 0; c < 3; c++) {
                double x = ua[3 * v + c] - ub[3 * v + c];
                dd += x * x;
                bb += ub[3 * v + c] * ub[3 * v + c];
            }
            d += m[v] * dd;
            b += m[v] * bb;
            dmax = fmax(dmax, sqrt(dd));
        }
        double rel = b > 0 ? sqrt(d / b) : (d > 0 ? INFINITY : 0);
        if (b > 0 && rel > worst) {
            worst = rel;
            tworst = tb;
        }
        sd += d;
        sb += b;
        if (!cli->quiet)
            printf("%6ld %12.6g %14.6g %14.6g\n", nmatch, tb, rel, dmax);
        if (csv.f)
            fprintf(csv.f, "%ld,%.17g,%.17g,%.17g\n", nmatch, tb, rel, dmax);
        nmatch++;
        ra = crom_result_next(&A, &ta, ua, NULL);
        rb = crom_result_next(&B, &tb, ub, NULL);
    }
    if (ra < 0 || ra > 1 || rb < 0 || rb > 1) { /* an error (negative: a truncated stream) */
        rc = ra < 0 || ra > 1 ? ra : rb;
        rc = rc < 0 ? -rc : rc;
        goto out2;
    }
    if (nmatch == 0) {
        rc = crom_err(CROM_EDATA, "%s and %s share no frame time", a->a, a->b);
        goto out2;
    }
    if (A.in.complete == 0 || B.in.complete == 0)
        crom_cli_warn(cli, "%s is incomplete (the run stopped early)", A.in.complete == 0 ? a->a : a->b);
    double total = sb > 0 ? sqrt(sd / sb) : 0;
    printf("relative displacement error %.6g over %ld frames (worst frame %.6g at t = %.6g s)%s\n", total, nmatch,
           worst, tworst, skipped ? "; unmatched frames skipped" : "");
    fflush(stdout);
    if (csv.f && (rc = crom_fileout_commit(&csv)))
        goto out2;
    if (a->maxerr > 0 && total > a->maxerr) {
        crom_cli_info(cli, "%.6g exceeds --max-error %.6g", total, a->maxerr);
        rc = 1;
    }
out2:
    if (csv.f && rc && rc != 1)
        crom_fileout_abort(&csv);
    free(m);
    free(ua);
    free(ub);
out:
    crom_result_close(&A);
    crom_result_close(&B);
    return rc;
}

int main(int argc, char **argv)
{
    crom_cli cli;
    args a = {0};
    crom_cli_parse(&cli, &doc, argc, argv, on_opt, &a);
    if (!a.a || !a.b)
        return crom_cli_exit(&cli, crom_err(CROM_EUSAGE, "give two results A and B (see crom-diff --help)"));
    int rc = run(&cli, &a);
    if (rc == 1) { /* differences beyond --max-error: not an error message */
        int wrc = crom_cli_exit(&cli, 0); /* still a failed write to stdout */
        return wrc ? wrc : 1;
    }
    return crom_cli_exit(&cli, rc);
}
