/* crom-cubature — choose the tets a reduced simulation integrates over, with
 * weights, and cache the model's basis W on the mesh (crom/cubature). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "cli/cli.h"
#include "io/io.h"
#include "rom/cubature.h"
#include "rom/map.h"
#include "rom/metrics.h"
#include "rom/model.h"
#include "rom/result.h"

enum { O_MODEL = 300, O_SCHEME, O_COUNT, O_POSES, O_TOL, O_CAND, O_YOUNGS, O_POISSON, O_MAXPOSE, O_SHRINK };

static const crom_opt cub_opts[] = {
    {"model", O_MODEL, "MODEL", "The crom/model whose basis W is cached (required). A nonlinear map (energy, neuralmodes) is cached through its features x = X + B a(q); the result serves crom-reducedstep --model MODEL --cubature, and the mesh operand may be left out (the map's own mesh)."},
    {"scheme", O_SCHEME, "NAME", "random (LiCROM §5: COUNT random vertices and their tets, equal weights), metis (COUNT parts, one tet each; a shell: COUNT parts of its triangles, each one triangle and the hinges on its edges), optimized (NNLS fit of at most COUNT tets to the forces of --poses), all (every tet, weight 1). Default random."},
    {"count", O_COUNT, "K", "Vertices (random), parts (metis) or the tet budget (optimized). Default 400 (random), 300 (metis), 200 (optimized)."},
    {"poses", O_POSES, "LATENT", "crom/latent training poses for --scheme optimized (e.g. crom-encode of the training trajectories), and for the error report of any scheme. Repeatable: latent coordinates do not depend on the mesh, so the poses of every training run can serve any mesh."},
    {"max-poses", O_MAXPOSE, "N", "Use at most N poses, evenly spaced (default 40); for a map without --poses, draw N latent samples of its training distribution (default 100)."},
    {"tol", O_TOL, "T", "optimized: stop adding tets once the relative force error on the poses is below T (default 0.01)."},
    {"candidates", O_CAND, "N", "optimized: tets scored per greedy pick (default 256)."},
    {"youngs", O_YOUNGS, "E", "optimized: Young's modulus of the forces fitted (default 2.5e6)."},
    {"poisson", O_POISSON, "NU", "optimized: Poisson ratio of the forces fitted (default 0.25)."},
    {"crack-offset", O_SHRINK, "S", "Vertices that share their rest position with another (the copies crom-remesh cut makes along a crack) sample W a fraction S of the way toward the centroid of their own tets (default 1: at that centroid, which lies on the copy's side of a cut that follows element faces; 0 = at X). At X both copies would get the same displacement and the crack could never open; on their own sides they follow the jump a basis learned from cut data."},
    {"output", 'o', "OUT", "Write the cubature to OUT (default stdout)."},
    {NULL, 0, NULL, NULL}};

static const crom_cli_optgroup groups[] = {{"Options", cub_opts}, {NULL, NULL}};

static const crom_cli_doc doc = {
    "crom-cubature",
    "pick and weight cubature tets for reduced simulation, caching W on the mesh",
    "crom-cubature --model MODEL [--scheme random|metis|optimized|all] [--count K]\n"
    "              [--poses LATENT] [-o OUT] [MESH|-]",
    "Evaluates the model's basis W(X) at every vertex of the mesh (the only network inference a "
    "reduced run needs), computes the exact reduced mass W^T M W per unit density, and selects the "
    "tets whose weighted energies stand in for the elastic energy integral (LiCROM eq. 8). The "
    "output carries the mesh with its regions, so crom-reducedstep resolves --pin, --velocity and "
    "--force (names or predicates) without the mesh, and every boundary vertex as a contact "
    "point.\n\n"
    "The input may be a crom/mesh or a crom/trajectory (its mesh is used). With --poses the "
    "relative elastic-energy and reduced-force errors of the cubature against the exact integral "
    "over all tets are printed; --scheme optimized needs poses and fits non-negative weights to "
    "them (An, Kim, James 2008).\n\n"
    "For a nonlinear map model (crom-fitfield --objective energy or neuralmodes) the positions are "
    "linear in the map's features, x(q) = X + B a(q) (the last hidden layer of its network, its "
    "linear modes and a constant): the cubature caches B instead of W, and the optimized scheme fits "
    "the latent forces T(q)^T B_e^T f_e(x(q)), T = da/dq, at latent samples of the model's training "
    "distribution (N(0, I) for an energy map, its box for neural modes; or --poses), with the "
    "material the model records. crom-reducedstep --model MODEL --cubature CUB then integrates the "
    "elastic energy over these tets only.\n\n"
    "On a shell surface (a model made on that shell: crom-modes, crom-fitfield --objective "
    "energy|neuralmodes) the elements are the shell's membrane triangles and bending hinges: "
    "optimized fits both to the shell's element forces (with the mesh's thickness); random and "
    "metis treat the triangles and the hinges as two sets, each weighted by its own measure "
    "(area; the hinge stiffness factor |e|^2 / (A1 + A2)); metis splits the triangles into COUNT "
    "parts, each stood for by one triangle and the hinges on its edges. The cubature serves "
    "crom-reducedstep --model MODEL --cubature CUB.",
    groups,
    "crom-cubature --model model.h5 --scheme metis --count 200 -o cub.h5 box.h5\n"
    "crom-encode --model model.h5 < train.h5 > poses.h5\n"
    "crom-cubature --model model.h5 --scheme optimized --poses poses.h5 -o cub.h5 box.h5\n"
    "crom-cubature --model df.h5 --scheme optimized --count 200 -o df_cub.h5",
    "crom-reducedstep(1), crom-fitfield(1), crom-encode(1), crom-remesh(1)"};

typedef struct {
    const char *model, *poses[64], *input, *out;
    int nposes;
    crom_cubature_opts o;
    int count_given, maxpose, maxpose_given, material_given;
    double crack_offset;
} args;

static int on_opt(void *ctx, int key, const char *v)
{
    args *a = ctx;
    long n;
    switch (key) {
    case 0:
        if (a->input)
            return crom_err(CROM_EUSAGE, "unexpected operand '%s' (one mesh)", v);
        a->input = v;
        return 0;
    case 'o': a->out = v; return 0;
    case O_MODEL: a->model = v; return 0;
    case O_POSES:
        if (a->nposes == 64)
            return crom_err(CROM_EUSAGE, "--poses: at most 64 files");
        a->poses[a->nposes++] = v;
        return 0;
    case O_SCHEME:
        if ((a->o.scheme = crom_cubature_scheme(v)) < 0)
            return crom_err(CROM_EUSAGE, "--scheme: '%s' is not random, metis, optimized or all", v);
        return 0;
    case O_COUNT:
        if (crom_parse_int(v, "--count", 1, 100000000L, &n))
            return CROM_EUSAGE;
        a->o.count = (int)n;
        a->count_given = 1;
        return 0;
    case O_MAXPOSE:
        if (crom_parse_int(v, "--max-poses", 1, 100000L, &n))
            return CROM_EUSAGE;
        a->maxpose = (int)n;
        a->maxpose_given = 1;
        return 0;
    case O_TOL: return crom_parse_positive(v, "--tol", &a->o.tol);
    case O_CAND:
        if (crom_parse_int(v, "--candidates", 1, 100000000L, &n))
            return CROM_EUSAGE;
        a->o.candidates = (int)n;
        return 0;
    case O_YOUNGS: a->material_given = 1; return crom_parse_positive(v, "--youngs", &a->o.youngs);
    case O_SHRINK:
        if (crom_parse_double(v, "--crack-offset", &a->crack_offset) || !(a->crack_offset >= 0 && a->crack_offset <= 1))
            return crom_err(CROM_EUSAGE, "--crack-offset must be in [0, 1], got %s", v);
        return 0;
    case O_POISSON: a->material_given = 1; return crom_parse_double(v, "--poisson", &a->o.poisson);
    }
    return crom_err(CROM_EINTERNAL, "unhandled option");
}

/* The mesh of a crom/mesh or crom/trajectory input. */
static int read_mesh(const char *path, crom_mesh *m, char **hist)
{
    crom_in in;
    int rc = crom_in_open(&in, path);
    if (rc)
        return rc;
    int traj = !strcmp(in.schema, "crom/trajectory");
    if (!traj && (rc = crom_in_expect(&in, CROM_MESH_SCHEMA, CROM_MESH_VERSION))) {
        crom_err(CROM_EDATA, "%s is %s v%d, expected crom/mesh (or a crom/trajectory)", in.name, in.schema, in.version);
        crom_in_close(&in);
        return CROM_EDATA;
    }
    if (traj && (rc = crom_in_expect(&in, "crom/trajectory", 1))) {
        crom_in_close(&in);
        return rc;
    }
    hid_t g = H5Gopen2(in.h5, traj ? "mesh" : "/", H5P_DEFAULT);
    rc = crom_mesh_read_any(g, m);
    H5Gclose(g);
    if (rc)
        crom_err_ctx("%s", in.name);
    else {
        *hist = in.history;
        in.history = NULL;
    }
    crom_in_close(&in);
    return rc;
}

/* Latent poses q of a crom/latent, at most maxpose evenly spaced. */
static int read_poses(const char *path, const char *model_id, int r, int maxpose, double **poses, int *np)
{
    crom_in in;
    int rc = crom_in_open(&in, path);
    if (rc)
        return rc;
    if ((rc = crom_in_expect(&in, "crom/latent", 1)))
        goto out;
    char *id = NULL;
    if ((rc = crom_h5_get_str(in.h5, ".", "model_id", &id))) {
        crom_err_ctx("%s", in.name);
        goto out;
    }
    if (strcmp(id, model_id)) {
        rc = crom_err(CROM_EDATA, "%s holds poses of model %s, not of --model (%s)", in.name, id, model_id);
        free(id);
        goto out;
    }
    free(id);
    int fq = crom_in_field(&in, "q");
    if (fq < 0) {
        rc = CROM_EDATA;
        goto out;
    }
    if ((int)in.fields[fq].count != r) {
        rc = crom_err(CROM_EDATA, "%s: q has %zu entries, the model's rank is %d", in.name, in.fields[fq].count, r);
        goto out;
    }
    double *all;
    long n;
    if ((rc = crom_in_read_all(&in, &all, &n)))
        goto out;
    if (n < 1) {
        free(all);
        rc = crom_err(CROM_EDATA, "%s has no frames", in.name);
        goto out;
    }
    for (long f = 0; f < n; f++)
        if ((rc = crom_result_check_frame(&in, all + (size_t)f * in.frame_len, f))) {
            free(all);
            goto out;
        }
    int k = n < maxpose ? (int)n : maxpose;
    *poses = crom_malloc(sizeof(double) * (size_t)k * r);
    if (!*poses) {
        free(all);
        rc = CROM_EINTERNAL;
        goto out;
    }
    for (int j = 0; j < k; j++) {
        long f = k == 1 ? n - 1 : (long)((double)j * (double)(n - 1) / (k - 1) + 0.5);
        memcpy(*poses + (size_t)j * r, all + (size_t)f * in.frame_len + in.fields[fq].offset, sizeof(double) * (size_t)r);
    }
    *np = k;
    free(all);
out:
    crom_in_close(&in);
    return rc;
}

/* A nonlinear map model (energy, neuralmodes, energy-field, skin-field) is integrated
 * through its features: x = X + B a(q) (lib/rom/map.h), so the cubature caches
 * B as its basis and fits, at latent samples q_j of the model's training
 * distribution (or the --poses given in *poses), the latent forces
 * T(q_j)ᵀ B_eᵀ f_e of each tet. Replaces the poses and their count with
 * the feature poses a(q_j) and sets *proj to the T(q_j). */
static int map_poses(crom_cli *cli, args *a, const crom_model *model, crom_map *map,
                     double **poses, int *np, double **proj)
{
    int r = model->rank, p = map->p, rc = 0;
    if (!*poses) { /* samples of the training distribution */
        double lo[3], hi[3];
        crom_mesh_bbox(&map->mesh, lo, hi);
        double diag = sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                           (hi[2] - lo[2]) * (hi[2] - lo[2]));
        crom_metrics_opts mo;
        crom_metrics_defaults(&mo);
        crom_metrics_training_dist(model, diag, &mo);
        crom_rng rng;
        crom_rng_seed(&rng, cli->seed ^ 0x5eed);
        *np = a->maxpose_given ? a->maxpose : 100;
        if (!(*poses = crom_malloc(sizeof(double) * (size_t)*np * r)))
            return CROM_EINTERNAL;
        for (int j = 0; j < *np; j++)
            crom_metrics_sample(&rng, &mo, r, *poses + (size_t)j * r);
        crom_cli_info(cli, "poses: %d latent samples of the model's training distribution", *np);
    }
    double *fp = crom_malloc(sizeof(double) * (size_t)*np * p), *T = crom_malloc(sizeof(double) * (size_t)*np * p * r);
    if (!fp || !T) {
        free(fp);
        free(T);
        return CROM_EINTERNAL;
    }
    for (int j = 0; j < *np && !rc; j++)
        rc = crom_map_features(map, *poses + (size_t)j * r, fp + (size_t)j * p, T + (size_t)j * p * r);
    free(*poses);
    *poses = fp;
    *proj = T;
    if (rc)
        crom_err_ctx("a latent pose");
    return rc;
}

static int run(crom_cli *cli, args *a)
{
    crom_mesh m;
    crom_model model;
    crom_map map;
    char *hist = NULL;
    double *W = NULL, *poses = NULL, *proj = NULL;
    int np = 0;
    memset(&m, 0, sizeof m);
    memset(&map, 0, sizeof map);
    crom_model_clear(&model);
    int rc = crom_model_load(a->model, &model);
    if (rc)
        return rc;
    int is_map = crom_model_is_nonlinear(&model), own_mesh = model.field == CROM_MODEL_FIELD_MAP;
    if (a->input || !own_mesh)
        rc = read_mesh(a->input, &m, &hist);
    else
        rc = crom_mesh_copy(&model.mesh, &m); /* a map's own mesh */
    if (rc)
        goto out;
    if (crom_mesh_is_surface(&m) && model.mesh.nv > 0 && !crom_mesh_is_surface(&model.mesh)) {
        rc = crom_err(CROM_EUSAGE, "%s is a shell surface: model %s (basis '%s') is a field over solids; a shell's "
                      "cubature needs a model made on that shell (crom-modes, crom-fitfield --objective "
                      "energy|neuralmodes)", a->input ? a->input : "the mesh", model.model_id, model.basis);
        goto out;
    }
    if (is_map && !a->material_given && isfinite(model.youngs) && isfinite(model.poisson)) {
        a->o.youngs = model.youngs;
        a->o.poisson = model.poisson;
    }
    int r = model.rank;
    /* poses of every file, then at most --max-poses of them evenly spaced */
    for (int f = 0; f < a->nposes && !rc; f++) {
        double *p1 = NULL;
        int n1 = 0;
        if ((rc = read_poses(a->poses[f], model.model_id, r, 1000000, &p1, &n1)))
            break;
        double *np2 = crom_realloc(poses, sizeof(double) * (size_t)(np + n1) * r);
        if (!np2) {
            free(p1);
            rc = CROM_EINTERNAL;
            break;
        }
        poses = np2;
        memcpy(poses + (size_t)np * r, p1, sizeof(double) * (size_t)n1 * r);
        np += n1;
        free(p1);
    }
    if (rc)
        goto out;
    if (np > a->maxpose) {
        for (int j = 0; j < a->maxpose; j++) {
            long f = a->maxpose == 1 ? np - 1 : (long)((double)j * (np - 1) / (a->maxpose - 1) + 0.5);
            memmove(poses + (size_t)j * r, poses + (size_t)f * r, sizeof(double) * (size_t)r);
        }
        np = a->maxpose;
    }
    double t0 = crom_clock_now(), tW;
    if (is_map) {
        if ((rc = crom_map_init(&map, &model, &m)) ||
            (rc = map_poses(cli, a, &model, &map, &poses, &np, &proj)))
            goto out;
        tW = crom_clock_now() - t0;
    } else {
        if (a->o.scheme == CROM_CUBATURE_OPTIMIZED && !poses) {
            rc = crom_err(CROM_EUSAGE, "--scheme optimized needs --poses LATENT (training poses of the model)");
            goto out;
        }
        W = crom_malloc(sizeof(double) * 3 * (size_t)r * (size_t)m.nv);
        size_t outside = 0;
        int nshift = 0;
        if (!W) {
            rc = CROM_EINTERNAL;
            goto out;
        }
        rc = crom_model_eval_mesh(&model, &m, a->crack_offset, W, &outside, &nshift); /* see --crack-offset */
        if (rc)
            goto out;
        if (nshift)
            crom_cli_info(cli, "%d vertices along cracks sample W on their own side (--crack-offset %g)", nshift,
                          a->crack_offset);
        tW = crom_clock_now() - t0;
        if (outside)
            crom_cli_warn(cli, "%zu of %d vertices lie outside the model's mesh: W is extended there", outside, m.nv);
    }
    a->o.poses = poses;
    a->o.npose = np;
    a->o.proj = proj;
    a->o.rout = r;
    int rb = is_map ? map.p : r; /* the basis cached: W, or the map's feature basis */
    crom_rng rng;
    crom_rng_seed(&rng, cli->seed);
    crom_cubature c;
    t0 = crom_clock_now();
    if ((rc = crom_cubature_build(&c, &m, is_map ? map.B : W, rb, model.model_id, &a->o, &rng)))
        goto out;
    c.map_rank = is_map ? r : 0;
    double tsel = crom_clock_now() - t0;
    crom_cli_info(cli, "%s: %d of %d %s (%.1f%%), W on %d vertices in %.1f ms, selection in %.1f ms",
                  c.scheme, c.k, c.ne, crom_mesh_is_surface(&m) ? "triangles and hinges" : "tets",
                  100.0 * c.k / c.ne, m.nv, 1e3 * tW, 1e3 * tsel);
    if (poses) {
        crom_material mat;
        double eE, eF;
        if (!(rc = crom_material_init(&mat, a->o.youngs, a->o.poisson, 1000)) &&
            !(rc = crom_cubature_error(&c, &mat, poses, np, proj, r, &eE, &eF)))
            crom_cli_info(cli, "relative error on %d poses: elastic energy %.4f, reduced force %.4f", np, eE, eF);
    }
    crom_out o;
    if (!rc && !(rc = crom_out_create(&o, a->out, CROM_CUBATURE_SCHEMA, CROM_CUBATURE_VERSION, cli->cmdline,
                                      hist, CROM_OUT_PLAIN))) {
        double wsec = crom_clock_wall(tW), ssec = crom_clock_wall(tsel);
        rc = crom_cubature_write(o.h5, &c);
        if (!rc)
            rc = crom_h5_set_f64(o.h5, ".", "w_seconds", &wsec, 1);
        if (!rc)
            rc = crom_h5_set_f64(o.h5, ".", "selection_seconds", &ssec, 1);
        if (!rc)
            rc = crom_out_commit(&o);
        else
            crom_out_fail(&o);
    }
    crom_cubature_free(&c);
out:
    free(W);
    free(poses);
    free(proj);
    crom_map_free(&map);
    free(hist);
    crom_model_free(&model);
    crom_mesh_free(&m);
    return rc;
}

int main(int argc, char **argv)
{
    crom_cli cli;
    args a;
    memset(&a, 0, sizeof a);
    a.o.scheme = CROM_CUBATURE_RANDOM;
    a.o.tol = 0.01;
    a.o.candidates = 256;
    a.o.youngs = 2.5e6;
    a.o.poisson = 0.25;
    a.maxpose = 40;
    a.crack_offset = CROM_MESH_CRACK_OFFSET;
    crom_cli_parse(&cli, &doc, argc, argv, on_opt, &a);
    if (!a.model)
        return crom_cli_exit(&cli, crom_err(CROM_EUSAGE, "--model MODEL is required (see crom-cubature --help)"));
    if (!a.count_given)
        a.o.count = a.o.scheme == CROM_CUBATURE_METIS ? 300 : a.o.scheme == CROM_CUBATURE_OPTIMIZED ? 200 : 400;
    return crom_cli_exit(&cli, run(&cli, &a));
}
