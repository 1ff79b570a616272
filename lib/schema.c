/* schema.c — specs of crom's file types (the tables below are mirrored, with
 * more prose, in schemas/ (one .md per type); tests/prog/schemas.sh keeps the two in step)
 * and the checker behind `crom-info --check`. */
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

#include "err.h"
#include "mesh.h"
#include "schema.h"

/* ------------------------------------------------------------------ specs */

static const crom_schema_attr mesh_attrs[] = {
    {"generator", "str", 0, "what made the mesh: box, plate, sphere, cylinder, superquadric, import, remesh"},
    {"target_size", "f64", 0, "target edge length given to the mesher (m)"},
    {NULL, NULL, 0, NULL}};

static const crom_schema_dset mesh_dsets[] = {
    {"vertices", "f64", "nv,3", 1, "m", "rest positions X of the vertices"},
    {"tets", "i32", "nt,4", 1, "1", "0-based vertex indices of each tetrahedron, positively oriented"},
    {"regions/*", "i32", "?", 0, "1", "sorted 0-based vertex indices of a named region; attribute `source` says how it was made"},
    {NULL, NULL, NULL, 0, NULL, NULL}};

static const crom_schema_attr traj_attrs[] = {
    {"complete", "i64", 1, "1 when the run finished; 0 when it stopped early (frames so far are kept)"},
    {"scenario", "str", 1, "the scenario as crom-fullsim flags, one per line"},
    {"dt", "f64", 1, "time step h (s)"},
    {"every", "i64", 1, "a frame is stored every `every` steps"},
    {"steps", "i64", 1, "number of time steps requested"},
    {"youngs", "f64", 1, "Young's modulus E (Pa)"},
    {"poisson", "f64", 1, "Poisson ratio nu"},
    {"density", "f64", 1, "mass density rho (kg/m^3)"},
    {"gravity", "f64[3]", 1, "gravitational acceleration (m/s^2)"},
    {"tolerance", "f64", 0, "Newton stops when its correction is below tolerance times the bounding-box diagonal"},
    {NULL, NULL, 0, NULL}};

static const crom_schema_dset traj_dsets[] = {
    {"mesh/vertices", "f64", "nv,3", 1, "m", "the mesh the run used (crom/mesh layout under /mesh)"},
    {"mesh/tets", "i32", "nt,4", 1, "1", "tetrahedra of that mesh"},
    {"mesh/regions/*", "i32", "?", 0, "1", "named regions of that mesh"},
    {"frames/time", "f64", "F", 1, "s", "simulated time of each frame"},
    {"frames/step", "f64", "F", 1, "1", "time-step index of each frame (0 = initial state)"},
    {"frames/displacement", "f64", "F,nv,3", 1, "m", "displacement u = x - X of every vertex"},
    {"frames/velocity", "f64", "F,nv,3", 1, "m/s", "velocity of every vertex"},
    {"frames/kinetic_energy", "f64", "F", 1, "J", "1/2 v^T M v"},
    {"frames/elastic_energy", "f64", "F", 1, "J", "stable neo-Hookean strain energy"},
    {"frames/external_energy", "f64", "F", 1, "J", "potential of gravity and applied forces, -f_ext . u"},
    {"frames/total_energy", "f64", "F", 1, "J", "kinetic + elastic + external"},
    {"frames/newton_iterations", "f64", "F", 1, "1", "Newton iterations of the step that produced the frame"},
    {"frames/residual", "f64", "F", 1, "1", "last Newton correction of that step, max-norm, relative to the bounding-box diagonal"},
    {"frames/step_seconds", "f64", "F", 1, "s", "wall time of that step"},
    {NULL, NULL, NULL, 0, NULL, NULL}};

static const crom_schema_attr samples_attrs[] = {
    {"mode", "str", 1, "vertices (random mesh vertices) or interior (random points, barycentric interpolation)"},
    {"points_per_frame", "i64", 1, "N, the number of samples in every frame"},
    {"seed", "i64", 1, "seed of the random choice"},
    {NULL, NULL, 0, NULL}};

static const crom_schema_dset samples_dsets[] = {
    {"points", "f32", "F,N,3", 1, "m", "rest positions X of the samples"},
    {"displacements", "f32", "F,N,3", 1, "m", "displacement u(X) at the samples"},
    {"vertex", "i32", "F,N", 1, "1", "vertex index of each sample in its source mesh, -1 for interior points"},
    {"frame_source", "i32", "F", 1, "1", "which source (index into sources/) each frame comes from"},
    {"frame_time", "f64", "F", 1, "s", "simulated time of each frame"},
    {"sources/*/vertices", "f64", "?,3", 1, "m", "rest positions of a source trajectory's mesh"},
    {"sources/*/tets", "i32", "?,4", 1, "1", "tetrahedra of that mesh"},
    {NULL, NULL, NULL, 0, NULL, NULL}};

static const crom_schema_attr model_attrs[] = {
    {"basis", "str", 1, "mlp (neural field), pod or modes (piecewise-linear field on a mesh), energy or neuralmodes (data-free maps of one mesh), energy-field (continuous data-free map), skinning (affine skinning handles)"},
    {"rank", "i64", 1, "r, the number of basis fields (latent dimension)"},
    {"encoder", "str", 1, "pointnet, lsq or none: how full states are turned into q"},
    {"model_id", "str", 1, "hex digest of the basis parameters; cubature and latent files name it"},
    {"activation", "str", 0, "elu or sine (mlp bases)"},
    {"reconstruction_error", "f64", 0, "relative error ||Wq - u|| / ||u|| over the training frames"},
    {"training_seconds", "f64", 0, "wall time of training"},
    {"scenario", "str", 0, "material, pinned regions (and gravity for energy) as flags, one per line (modes, energy, neuralmodes)"},
    {"youngs", "f64", 0, "Young's modulus E (Pa) of the modes or of the data-free training"},
    {"poisson", "f64", 0, "Poisson ratio of the modes or of the data-free training"},
    {"density", "f64", 0, "density (kg/m^3) of the modes or of the data-free training"},
    {"mass", "f64", 0, "mass m of the body (kg): W / sqrt(m) is M-orthonormal (modes); the mass of the mapped mesh (energy, neuralmodes)"},
    {"rigid_modes", "i64", 0, "rigid-body (zero-frequency) modes detected (modes)"},
    {"rigid_kept", "i64", 0, "1 if they lead the basis, 0 if dropped (modes)"},
    {"training_steps", "i64", 0, "training steps taken (energy, neuralmodes)"},
    {"sigma", "f64", 0, "isometry scale: metres of RMS displacement per unit of latent distance (energy)"},
    {"isometry_weight", "f64", 0, "weight lambda of the isometry term (energy)"},
    {"gravity", "f64[3]", 0, "gravity of the training energy (m/s^2) (energy)"},
    {"latent_box", "f64", 0, "half-width a of the training box of modal coordinates (m) (neuralmodes)"},
    {"ortho_weight", "f64", 0, "weight of the M-orthogonality penalty (neuralmodes)"},
    {"origin_weight", "f64", 0, "weight of the penalty on y(0) (neuralmodes)"},
    {"modes_id", "str", 0, "model_id of the crom-modes model whose modes are the linear part (neuralmodes)"},
    {"cubature_tets", "i64", 0, "tets of the random cubature drawn at every training step (energy-field)"},
    {"handles", "i64", 0, "H, the affine handles of a skinning subspace (12 coordinates each)"},
    {"constant_handle", "i64", 0, "1 if handle 0 is the constant weight 1 (a free body), else 0 (skinning)"},
    {"skin_weights", "str", 0, "trained (an MLP weight field) or eigen (skinning eigenmodes on field/mesh) (skinning)"},
    {NULL, NULL, 0, NULL}};

static const crom_schema_dset model_dsets[] = {
    {"field/widths", "i32", "L", 0, "1", "layer widths of the MLP, input first: W: R^3 -> R^(3r) (mlp), N: R^r -> R^(3nv) (energy, neuralmodes)"},
    {"field/params", "f32", "P", 0, "1", "all MLP weights and biases, layer by layer (W row-major [out][in], then b)"},
    {"field/input_shift", "f64", "3", 0, "m", "input normalization: X_hat = (X - shift) / scale"},
    {"field/input_scale", "f64", "3", 0, "m", "input normalization scale"},
    {"field/mesh/vertices", "f64", "nv,3", 0, "m", "mesh of a piecewise-linear basis (pod, modes) or of a map (energy, neuralmodes)"},
    {"field/mesh/tets", "i32", "nt,4", 0, "1", "tetrahedra of that mesh"},
    {"field/mesh/regions/*", "i32", "?", 0, "1", "named regions of the mesh of a map (energy, neuralmodes): what --pin names in crom-reducedstep --model"},
    {"field/basis", "f64", "nv,3,r", 0, "1", "basis vectors at the mesh vertices (pod, modes); the linear part W of a map (neuralmodes)"},
    {"frequencies", "f64", "r", 0, "Hz", "natural frequencies of linear modes (modes, neuralmodes)"},
    {"encoder/point_widths", "i32", "?", 0, "1", "PointNet per-point MLP widths (6 -> ...)"},
    {"encoder/head_widths", "i32", "?", 0, "1", "PointNet head MLP widths (... -> r)"},
    {"encoder/params", "f32", "?", 0, "1", "all PointNet parameters"},
    {"encoder/input_shift", "f64", "6", 0, "m", "PointNet input normalization of (X, u): (p - shift) / scale"},
    {"encoder/input_scale", "f64", "6", 0, "m", "PointNet input normalization scale"},
    {"training/loss", "f64", "E", 0, "m^2", "training loss per epoch"},
    {"training/seconds", "f64", "E", 0, "s", "wall time at the end of each epoch (or block of steps)"},
    {"training/objective", "f64", "E", 0, "1", "data-free objective per block of steps (energy, neuralmodes)"},
    {"training/energy", "f64", "E", 0, "J", "mean energy of the training samples per block of steps (energy, neuralmodes)"},
    {"training/penalty", "f64", "E", 0, "1", "mean unweighted penalty per block of steps: isometry (energy) or orthogonality (neuralmodes)"},
    {"latent/widths", "i32", "?", 0, "1", "layer widths of the latent network phi: R^r -> R^p, input first (energy-field)"},
    {"latent/params", "f32", "?", 0, "1", "all weights and biases of phi, laid out as field/params (energy-field)"},
    {"latent/pin_points", "f64", "?,3", 0, "m", "pinned vertices of the training mesh: part of the pin mask (energy-field)"},
    {"latent/pin_triangles", "f64", "?,3,3", 0, "m", "pinned boundary triangles of the training mesh, corners: part of the pin mask (energy-field)"},
    {"latent/pin_length", "f64", "1", 0, "m", "width l of the pin mask smoothstep(d / l) (energy-field)"},
    {"skin/frame", "f64", "3,4", 0, "1/m, 1", "body frame F of a skinning subspace: X_hat = F [X; 1] (skinning)"},
    {"skin/coordinates", "f64", "A,S", 0, "1", "C [4H][S]: orthonormal functions psi_s = sum_a C[a][s] phi_a of the handle functions (skinning)"},
    {"skin/weights", "f64", "nv,H", 0, "1", "handle weights at the vertices of field/mesh (skinning, eigen)"},
    {"skin/eigenvalues", "f64", "H", 0, "1/s^2", "eigenvalues of the weights: scalar stiffness against lumped mass (skinning, eigen)"},
    {"skin/pin_points", "f64", "?,3", 0, "m", "pinned training points: part of the weights' pin mask (skinning, trained)"},
    {"skin/pin_triangles", "f64", "?,3,3", 0, "m", "pinned boundary triangles of the training geometry, corners: part of the mask (skinning, trained)"},
    {"skin/pin_length", "f64", "1", 0, "m", "width l of the weights' pin mask s(d / l), s(t) = t (2 - t) (skinning, trained)"},
    {NULL, NULL, NULL, 0, NULL, NULL}};

static const crom_schema_attr latent_attrs[] = {
    {"complete", "i64", 1, "1 when the run finished; 0 when it stopped early"},
    {"model_id", "str", 1, "model_id of the crom/model whose basis W the coordinates q refer to"},
    {"rank", "i64", 1, "r, the latent dimension"},
    {"dt", "f64", 0, "time step h (s)"},
    {"scenario", "str", 0, "the scenario flags, one per line (reduced runs)"},
    {NULL, NULL, 0, NULL}};

static const crom_schema_dset latent_dsets[] = {
    {"frames/time", "f64", "F", 1, "s", "simulated time of each frame"},
    {"frames/q", "f64", "F,r", 1, "m", "latent coordinates: u(X) = W(X) q (W is dimensionless)"},
    {"frames/qdot", "f64", "F,r", 0, "m/s", "latent velocity (q_n - q_{n-1}) / h"},
    {"frames/step", "f64", "F", 0, "1", "time-step index"},
    {"frames/kinetic_energy", "f64", "F", 0, "J", "reduced kinetic energy"},
    {"frames/elastic_energy", "f64", "F", 0, "J", "elastic energy by cubature"},
    {"frames/external_energy", "f64", "F", 0, "J", "potential of gravity and applied forces"},
    {"frames/total_energy", "f64", "F", 0, "J", "kinetic + elastic + external"},
    {"frames/iterations", "f64", "F", 0, "1", "solver iterations of the step"},
    {"frames/residual", "f64", "F", 0, "1", "final relative gradient norm of the step"},
    {"frames/constraint_residual", "f64", "F", 0, "m", "largest distance of a pinned/prescribed vertex from its target"},
    {"frames/cubature", "f64", "F", 0, "1", "index of the cubature (schedule entry) in use"},
    {"frames/step_seconds", "f64", "F", 0, "s", "wall time of the step"},
    {"frames/reconstruction_error", "f64", "F", 0, "1", "||Wq - u|| / ||u|| of an encoded frame (crom-encode)"},
    {NULL, NULL, NULL, 0, NULL, NULL}};

static const crom_schema_attr cub_attrs[] = {
    {"model_id", "str", 1, "model_id of the crom/model whose W is cached here"},
    {"scheme", "str", 1, "random, metis, optimized or all"},
    {"rank", "i64", 1, "r"},
    {"count", "i64", 1, "number of cubature tets"},
    {"mesh_volume", "f64", 1, "volume of the mesh the cubature integrates (m^3)"},
    {"w_seconds", "f64", 0, "wall time of evaluating W at the mesh vertices (s)"},
    {"selection_seconds", "f64", 0, "wall time of selecting and weighting the tets (s)"},
    {"map_rank", "i64", 0, "latent rank of the nonlinear map whose feature basis B is cached as W (crom-reducedstep --model --cubature)"},
    {NULL, NULL, 0, NULL}};

static const crom_schema_dset cub_dsets[] = {
    {"mesh/vertices", "f64", "nv,3", 1, "m", "the mesh the cubature integrates (crom/mesh layout under /mesh)"},
    {"mesh/tets", "i32", "nt,4", 1, "1", "its tetrahedra"},
    {"mesh/regions/*", "i32", "?", 0, "1", "its named regions: what --pin, --velocity and --force name"},
    {"W", "f64", "nv,3,r", 1, "1", "basis W(X) at every mesh vertex, [vertex][component][field]"},
    {"lumped_volume", "f64", "nv", 1, "m^3", "sum of V_t/4 over the tets of each vertex (mass / density)"},
    {"elements", "i32", "k", 1, "1", "cubature tets: indices into mesh/tets"},
    {"weights", "f64", "k", 1, "1", "non-negative cubature weight of each tet"},
    {"Dminv", "f64", "k,3,3", 1, "1/m", "inverse rest edge matrix [X1-X0, X2-X0, X3-X0]^-1 of each cubature tet, row-major"},
    {"volume", "f64", "k", 1, "m^3", "rest volume of each cubature tet"},
    {"WtVW", "f64", "r,r", 1, "m^3", "sum over vertices of V_v W_v^T W_v: times density, the reduced mass matrix"},
    {"WtV", "f64", "r,3", 1, "m^3", "sum over vertices of V_v W_v^T: times density and gravity, the reduced gravity force"},
    {"surface", "i32", "s", 1, "1", "boundary vertices: the contact points checked against collision planes"},
    {NULL, NULL, NULL, 0, NULL, NULL}};

static const crom_schema specs[] = {
    {"crom/mesh", 1, "tetrahedral mesh with named vertex regions", mesh_attrs, mesh_dsets, 0},
    {"crom/trajectory", 1, "full-space simulation: mesh, scenario and frames", traj_attrs, traj_dsets, 1},
    {"crom/samples", 1, "point samples (X, u) of trajectories, for training", samples_attrs, samples_dsets, 0},
    {"crom/model", 1, "a subspace basis W(X) (neural field or mesh field) and its encoder", model_attrs, model_dsets, 0},
    {"crom/latent", 1, "latent trajectory q(t) in a model's subspace", latent_attrs, latent_dsets, 1},
    {"crom/cubature", 1, "cubature tets and weights with cached W for reduced simulation", cub_attrs, cub_dsets, 0},
    {NULL, 0, NULL, NULL, NULL, 0}};

const crom_schema *crom_schema_find(const char *name)
{
    for (const crom_schema *s = specs; s->schema; s++)
        if (!strcmp(s->schema, name))
            return s;
    return NULL;
}

const crom_schema *const *crom_schema_all(void)
{
    static const crom_schema *list[sizeof specs / sizeof *specs];
    for (size_t i = 0; i < sizeof specs / sizeof *specs; i++)
        list[i] = specs[i].schema ? &specs[i] : NULL;
    return list;
}

/* ---------------------------------------------------------------- checker */

#define MAX_SYM 32
typedef struct {
    char name[MAX_SYM][16];
    long long val[MAX_SYM];
    int n;
    FILE *report;
    int violations;
    const char *file;
} ctx;

static void violation(ctx *c, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void violation(ctx *c, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    if (c->report) {
        fprintf(c->report, "%s: ", c->file);
        vfprintf(c->report, fmt, ap);
        fputc('\n', c->report);
    }
    va_end(ap);
    c->violations++;
}

/* Bind or compare a dimension symbol. Returns 0 if consistent. */
static int sym(ctx *c, const char *s, long long v, long long *expected)
{
    for (int i = 0; i < c->n; i++)
        if (!strcmp(c->name[i], s)) {
            *expected = c->val[i];
            return c->val[i] == v ? 0 : -1;
        }
    if (c->n < MAX_SYM) {
        snprintf(c->name[c->n], sizeof c->name[0], "%s", s);
        c->val[c->n++] = v;
    }
    return 0;
}

static void check_dset(ctx *c, hid_t root, const char *path, const crom_schema_dset *d)
{
    if (!crom_h5_has(root, path)) {
        if (d->required)
            violation(c, "missing dataset /%s (%s)", path, d->meaning);
        return;
    }
    hid_t ds = H5Dopen2(root, path, H5P_DEFAULT);
    if (ds < 0) {
        violation(c, "/%s is not a dataset", path);
        return;
    }
    hid_t t = H5Dget_type(ds), sp = H5Dget_space(ds);
    H5T_class_t cls = H5Tget_class(t);
    size_t sz = H5Tget_size(t);
    const char *want = d->type;
    int ok = (!strcmp(want, "f64") && cls == H5T_FLOAT && sz == 8) ||
             (!strcmp(want, "f32") && cls == H5T_FLOAT && sz == 4) ||
             (!strcmp(want, "i32") && cls == H5T_INTEGER && sz == 4);
    if (!ok)
        violation(c, "/%s has the wrong type (expected %s)", path, want);
    hsize_t dims[8];
    int rank = H5Sget_simple_extent_ndims(sp);
    if (rank > 8)
        rank = 8;
    H5Sget_simple_extent_dims(sp, dims, NULL);
    /* split the shape spec */
    char spec[64], *save = NULL;
    snprintf(spec, sizeof spec, "%s", d->shape);
    int k = 0;
    for (char *tok = strtok_r(spec, ",", &save); tok; tok = strtok_r(NULL, ",", &save), k++) {
        if (k >= rank)
            continue;
        if (!strcmp(tok, "?"))
            continue;
        char *end;
        long long lit = strtoll(tok, &end, 10);
        long long expected;
        if (!*end) {
            if ((long long)dims[k] != lit)
                violation(c, "/%s dimension %d is %llu, expected %lld", path, k,
                          (unsigned long long)dims[k], lit);
        } else if (sym(c, tok, (long long)dims[k], &expected)) {
            violation(c, "/%s dimension %d (%s) is %llu, but %s = %lld elsewhere in the file", path,
                      k, tok, (unsigned long long)dims[k], tok, expected);
        }
    }
    if (k != rank)
        violation(c, "/%s has rank %d, expected %d (%s)", path, rank, k, d->shape);
    /* values must be finite */
    if (ok && cls == H5T_FLOAT && rank >= 0) {
        hssize_t n = H5Sget_simple_extent_npoints(sp);
        double *buf = n > 0 ? malloc(sizeof(double) * (size_t)n) : NULL;
        if (buf && H5Dread(ds, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, buf) >= 0) {
            for (hssize_t i = 0; i < n; i++)
                if (!isfinite(buf[i])) {
                    violation(c, "/%s has a non-finite value at flat index %lld", path, (long long)i);
                    break;
                }
        } else if (n > 0) {
            violation(c, "/%s cannot be read (corrupt?)", path);
        }
        free(buf);
    }
    H5Sclose(sp);
    H5Tclose(t);
    H5Dclose(ds);
}

static void check_attr(ctx *c, hid_t root, const crom_schema_attr *a)
{
    if (!crom_h5_has_attr(root, ".", a->name)) {
        if (a->required)
            violation(c, "missing root attribute '%s' (%s)", a->name, a->meaning);
        return;
    }
    if (!strcmp(a->type, "str")) {
        char *s = NULL;
        if (crom_h5_get_str(root, ".", a->name, &s))
            violation(c, "root attribute '%s' is not a string", a->name);
        free(s);
    } else {
        int n = 1;
        const char *br = strchr(a->type, '[');
        if (br)
            n = atoi(br + 1);
        double v[16];
        if (n > 16 || crom_h5_get_f64(root, ".", a->name, v, n))
            violation(c, "root attribute '%s' is not %s", a->name, a->type);
        else
            for (int i = 0; i < n; i++)
                if (!isfinite(v[i]))
                    violation(c, "root attribute '%s' is not finite", a->name);
    }
}

int crom_schema_check(crom_in *in, FILE *report)
{
    ctx c;
    memset(&c, 0, sizeof c);
    c.report = report;
    c.file = in->name;
    const crom_schema *s = crom_schema_find(in->schema);
    if (!s) {
        violation(&c, "unknown schema '%s'", in->schema);
        return c.violations;
    }
    if (in->version > s->version) {
        violation(&c, "%s v%d is newer than this crom understands (v%d)", s->schema, in->version,
                  s->version);
        return c.violations;
    }
    if (in->version < 1)
        violation(&c, "invalid schema_version %d", in->version);
    static const char *common[] = {"history", "crom_version"};
    for (int i = 0; i < 2; i++)
        if (!crom_h5_has_attr(in->h5, ".", common[i]))
            violation(&c, "missing root attribute '%s'", common[i]);
    for (const crom_schema_attr *a = s->attrs; a && a->name; a++)
        check_attr(&c, in->h5, a);
    /* a stream carries its frames separately: bind F from what is read */
    double *frames = NULL;
    long nframes = 0;
    if (s->series) {
        if (!in->nfields)
            violation(&c, "a %s must have frame fields under /frames", s->schema);
        if (in->form == CROM_FORM_H5)
            in->cursor = 0; /* check every frame, wherever the reader stood */
        if (crom_in_read_all(in, &frames, &nframes))
            violation(&c, "frames cannot be read: %s", crom_errmsg());
        long long dummy;
        sym(&c, "F", in->form == CROM_FORM_STREAM ? 0 : nframes, &dummy);
        if (in->complete != 1)
            violation(&c, "incomplete: the run that wrote it stopped after %ld frames", nframes);
        for (long f = 0; frames && f < nframes; f++)
            for (size_t i = 0; i < in->frame_len; i++)
                if (!isfinite(frames[(size_t)f * in->frame_len + i])) {
                    violation(&c, "frame %ld has a non-finite value", f);
                    f = nframes;
                    break;
                }
    }
    for (const crom_schema_dset *d = s->dsets; d->path; d++) {
        const char *star = strchr(d->path, '*');
        if (!star) {
            check_dset(&c, in->h5, d->path, d);
            continue;
        }
        char group[128];
        snprintf(group, sizeof group, "%.*s", (int)(star - d->path - 1), d->path);
        if (!crom_h5_has(in->h5, group)) {
            if (d->required)
                violation(&c, "missing group /%s", group);
            continue;
        }
        char **names = crom_h5_list(in->h5, group);
        if (!names)
            violation(&c, "group /%s cannot be listed", group);
        for (int i = 0; names && names[i]; i++) {
            char path[256];
            snprintf(path, sizeof path, "%s/%s%s", group, names[i], star + 1);
            check_dset(&c, in->h5, path, d);
        }
        crom_h5_list_free(names);
    }
    /* semantic checks */
    if (!strcmp(s->schema, "crom/mesh") || !strcmp(s->schema, "crom/trajectory")) {
        crom_mesh m;
        hid_t loc = !strcmp(s->schema, "crom/mesh") ? H5Gopen2(in->h5, "/", H5P_DEFAULT)
                                                    : H5Gopen2(in->h5, "mesh", H5P_DEFAULT);
        if (loc >= 0) {
            if (crom_mesh_read(loc, &m))
                violation(&c, "mesh: %s", crom_errmsg());
            else
                crom_mesh_free(&m);
            H5Gclose(loc);
        }
    }
    free(frames);
    return c.violations;
}
