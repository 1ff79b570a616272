/* crom-keyframe — in-betweens of keyframes given as latent vectors of a
 * model (Neural Modes §5, Keyframing): a crom/latent series that
 * crom-export decodes, with the strain energy of each in-between and of
 * the linear interpolation of the keyframes' positions. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "cli/cli.h"
#include "io/io.h"
#include "phys/scenario.h"
#include "rom/equil.h"
#include "rom/keyframe.h"
#include "rom/model.h"

enum { O_MODEL = 300, O_KEY, O_KEYS, O_BETWEEN, O_INTERP, O_MESH, O_FPS };

static const crom_opt kf_opts[] = {
    {"model", O_MODEL, "M", "The crom/model whose latent coordinates the keys are given in (required)."},
    {"key", O_KEY, "Z1,...,Zr", "A keyframe: the r latent coordinates of a pose (repeatable, in order; at least two in all)."},
    {"keys", O_KEYS, "FILE", "Keyframes from a crom/latent file: each frame's q is a key (after any --key)."},
    {"between", O_BETWEEN, "N", "In-betweens from one key to the next (default 9): (K-1)(N+1)+1 frames in all."},
    {"interp", O_INTERP, "KIND", "cubic (default): the Catmull-Rom spline through the keys (C1). linear: straight from key to key."},
    {"mesh", O_MESH, "MESH", "Lay the model on MESH (a neural field needs one; default: the model's own mesh)."},
    {"fps", O_FPS, "F", "Frames per second of the output's time (default 25)."},
    {"output", 'o', "OUT", "Write the in-betweens to OUT (default: stdout; a frame stream into a pipe)."},
    {NULL, 0, NULL, NULL}};

static crom_opt mat_opts[4]; /* --youngs, --poisson, --density of the scenario options */

static crom_cli_optgroup groups[] = {
    {"Options", kf_opts},
    {"Material (default: what the model was built with; only the energies use it)", mat_opts},
    {NULL, NULL}};

static const crom_cli_doc doc = {
    "crom-keyframe",
    "interpolate keyframes given as latent vectors through a model",
    "crom-keyframe --model M --key Z --key Z [...] [--keys FILE] [--between N] [--interp cubic|linear] [-o OUT]",
    "Reads a model and two or more keyframes in its latent coordinates, interpolates the latent "
    "from key to key (Catmull-Rom by default) and writes a crom/latent series of the in-betweens, "
    "which crom-export --model M decodes into meshes and pictures like any reduced run. This is "
    "the keyframing of Neural Modes (Wang et al. 2024, section 5): in a nonlinear subspace the "
    "in-betweens x(z(s)) stay on the model's manifold of low-energy shapes, where interpolating "
    "the keyframes' positions linearly shortens bending limbs and stores strain energy.\n\n"
    "Each frame carries keyframe (its place s among the keys), q, qdot, elastic_energy (the "
    "stable neo-Hookean energy of x(q) over every element of the mesh) and lerp_energy (the energy "
    "of (1-a) x(z_k) + a x(z_k+1) at the same s, a = s - k). The mean of both over the in-betweens "
    "(the frames between keys) is printed on stderr. For a linear basis the two agree at every "
    "frame of a linear interpolation; the gap measures what the subspace's nonlinearity buys.",
    groups,
    "crom-keyframe --model nm.h5 --key 0,0,0 --key 0.3,0,0 --key -0.3,0.1,0 -o keys.latent.h5\n"
    "crom-keyframe --model nm.h5 --keys poses.latent.h5 --between 24 | crom-export --format pvd --model nm.h5 -o anim.pvd",
    "crom-export(1), crom-fitfield(1), crom-modes(1)"};

typedef struct {
    const char *model, *keys_path, *mesh, *out;
    int nkey, between, interp;
    char **key;              /* --key values, parsed once the rank is known */
    int nsc, sckey[64];      /* material flags, applied over the model's */
    const char *scval[64];
    double fps;
} args;

static int on_opt(void *ctx, int key, const char *v)
{
    args *a = ctx;
    long n;
    if (crom_scenario_opt_name(key)) {
        if (a->nsc == 64)
            return crom_err(CROM_EUSAGE, "--%s: at most 64 material flags", crom_scenario_opt_name(key));
        a->sckey[a->nsc] = key;
        a->scval[a->nsc++] = v;
        return 0;
    }
    switch (key) {
    case 0: return crom_err(CROM_EUSAGE, "unexpected operand '%s' (keys are given with --key or --keys)", v);
    case 'o': a->out = v; return 0;
    case O_MODEL: a->model = v; return 0;
    case O_KEYS: a->keys_path = v; return 0;
    case O_MESH: a->mesh = v; return 0;
    case O_KEY: {
        char **k = realloc(a->key, sizeof(char *) * (size_t)(a->nkey + 1));
        if (!k)
            return crom_err(CROM_EINTERNAL, "out of memory");
        a->key = k;
        a->key[a->nkey++] = (char *)v;
        return 0;
    }
    case O_BETWEEN:
        if (crom_parse_int(v, "--between", 0, 100000L, &n))
            return CROM_EUSAGE;
        a->between = (int)n;
        return 0;
    case O_INTERP:
        if (!strcmp(v, "cubic"))
            a->interp = CROM_KEYFRAME_CUBIC;
        else if (!strcmp(v, "linear"))
            a->interp = CROM_KEYFRAME_LINEAR;
        else
            return crom_err(CROM_EUSAGE, "--interp: '%s' is not cubic or linear", v);
        return 0;
    case O_FPS: return crom_parse_positive(v, "--fps", &a->fps);
    }
    return crom_err(CROM_EINTERNAL, "unhandled option");
}

/* The keys [*nkeys][r]: the --key flags, then the frames of --keys. */
static int gather_keys(const args *a, int r, double **keys, int *nkeys)
{
    double *Z = NULL;
    long nf = 0;
    int rc = a->keys_path ? crom_equil_latents(a->keys_path, r, &Z, &nf) : 0;
    if (rc)
        return rc;
    if (nf > 1000000L - a->nkey) {
        free(Z);
        return crom_err(CROM_EUSAGE, "%s: %ld keys, more than 10^6", a->keys_path, nf);
    }
    *nkeys = a->nkey + (int)nf;
    if (!(*keys = crom_malloc(sizeof(double) * ((size_t)*nkeys * r + 1)))) {
        free(Z);
        return CROM_EINTERNAL;
    }
    for (int i = 0; i < a->nkey && !rc; i++)
        rc = crom_parse_doubles(a->key[i], "--key", r, *keys + (size_t)i * r);
    if (!rc && nf)
        memcpy(*keys + (size_t)a->nkey * r, Z, sizeof(double) * (size_t)nf * r);
    free(Z);
    if (rc) {
        free(*keys);
        *keys = NULL;
    }
    return rc;
}

/* The material: the defaults, what the model records, then the flags. */
static int material(const args *a, const crom_model *M, crom_scenario *sc)
{
    crom_scenario_defaults(sc);
    int rc = crom_scenario_parse_text(M->scenario, sc);
    if (!rc && !M->scenario && M->youngs > 0) {
        sc->youngs = M->youngs;
        sc->poisson = M->poisson;
        sc->density = M->density > 0 ? M->density : sc->density;
    }
    for (int i = 0; i < a->nsc && !rc; i++)
        rc = crom_scenario_option(sc, a->sckey[i], a->scval[i]);
    return rc ? rc : crom_scenario_check(sc);
}

static int write_frames(crom_cli *cli, const args *a, const crom_model *M, crom_keyframe *k, crom_out *o)
{
    int r = k->r, rc;
    hsize_t dr = (hsize_t)r;
    if ((rc = crom_h5_set_str(o->h5, ".", "model_id", M->model_id)) || (rc = crom_h5_set_i64(o->h5, ".", "rank", r)) ||
        (rc = crom_out_field(o, "time", 0, NULL, M->basis)) || (rc = crom_out_field(o, "step", 0, NULL, M->basis)) ||
        (rc = crom_out_field(o, "keyframe", 0, NULL, M->basis)) || (rc = crom_out_field(o, "q", 1, &dr, M->basis)) ||
        (rc = crom_out_field(o, "qdot", 1, &dr, M->basis)) ||
        (rc = crom_out_field(o, "elastic_energy", 0, NULL, M->basis)) ||
        (rc = crom_out_field(o, "lerp_energy", 0, NULL, M->basis)) || (rc = crom_out_begin(o)))
        return rc;
    double *q = crom_malloc(sizeof(double) * r), *qp = crom_malloc(sizeof(double) * r),
           *qd = crom_calloc((size_t)r, sizeof(double));
    if (!q || !qp || !qd) {
        free(q), free(qp), free(qd);
        return CROM_EINTERNAL;
    }
    long per = a->between + 1, nf = (long)(k->nkeys - 1) * per + 1, nin = 0;
    double h = 1 / a->fps, sum_lat = 0, sum_pos = 0;
    crom_cli_progress prog;
    crom_cli_progress_start(&prog, cli, "keyframe", nf);
    for (long j = 0; j < nf && !rc; j++) {
        double s = (double)(j / per) + (double)(j % per) / per, t = j * h, step = (double)j, El, Ep;
        if ((rc = crom_keyframe_eval(k, s, q, &El, &Ep)))
            break;
        for (int i = 0; j && i < r; i++)
            qd[i] = (q[i] - qp[i]) / h;
        memcpy(qp, q, sizeof(double) * r);
        if (j % per) {
            sum_lat += El;
            sum_pos += Ep;
            nin++;
        }
        const double *vals[] = {&t, &step, &s, q, qd, &El, &Ep};
        rc = crom_out_frame(o, vals);
        crom_cli_progress_update(&prog, j + 1, NULL);
    }
    crom_cli_progress_end(&prog);
    free(q), free(qp), free(qd);
    if (rc)
        return rc < 0 ? -rc : rc;
    if (nin)
        crom_cli_info(cli, "%d keys, %ld frames (%s): mean strain energy of the %ld in-betweens %.6g J through the "
                      "model, %.6g J interpolating positions",
                      k->nkeys, nf, k->interp == CROM_KEYFRAME_CUBIC ? "cubic" : "linear", nin, sum_lat / nin,
                      sum_pos / nin);
    return 0;
}

static int run(crom_cli *cli, const args *a)
{
    crom_model M;
    crom_mesh mesh;
    memset(&mesh, 0, sizeof mesh);
    crom_keyframe k;
    memset(&k, 0, sizeof k);
    crom_scenario sc;
    double *keys = NULL;
    int nkeys = 0;
    int rc = crom_model_load(a->model, &M);
    if (rc)
        return rc;
    if ((rc = material(a, &M, &sc)) || (rc = gather_keys(a, M.rank, &keys, &nkeys)) ||
        (a->mesh && (rc = crom_mesh_load(a->mesh, CROM_MESH_SURFACES, &mesh, NULL))) ||
        (rc = crom_keyframe_init(&k, &M, a->mesh ? &mesh : NULL, &sc, nkeys, keys, a->interp)))
        goto out;
    crom_out o;
    if ((rc = crom_out_create(&o, a->out, "crom/latent", 1, cli->cmdline, NULL, CROM_OUT_SERIES)))
        goto out;
    if ((rc = crom_scenario_write_attrs(o.h5, &sc)) || (rc = write_frames(cli, a, &M, &k, &o)))
        crom_out_fail(&o);
    else
        rc = crom_out_commit(&o);
out:
    crom_keyframe_free(&k);
    free(keys);
    crom_mesh_free(&mesh);
    crom_model_free(&M);
    return rc;
}

int main(int argc, char **argv)
{
    int nm = 0;
    for (const crom_opt *o = crom_scenario_opts; o->name; o++)
        if (!strcmp(o->name, "youngs") || !strcmp(o->name, "poisson") || !strcmp(o->name, "density"))
            mat_opts[nm++] = *o;
    crom_cli cli;
    args a;
    memset(&a, 0, sizeof a);
    a.between = 9;
    a.interp = CROM_KEYFRAME_CUBIC;
    a.fps = 25;
    crom_cli_parse(&cli, &doc, argc, argv, on_opt, &a);
    if (!a.model) {
        crom_err(CROM_EUSAGE, "--model M is required (the crom/model the keys are latents of)");
        return crom_cli_exit(&cli, CROM_EUSAGE);
    }
    if (a.nkey + (a.keys_path != NULL) == 0) {
        crom_err(CROM_EUSAGE, "no keys: give two or more with --key Z1,...,Zr or a crom/latent with --keys FILE");
        return crom_cli_exit(&cli, CROM_EUSAGE);
    }
    int rc = run(&cli, &a);
    free(a.key);
    return crom_cli_exit(&cli, rc);
}
