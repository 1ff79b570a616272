/* schema.c — the table of crom's file types (see schema.h). Each `meaning`
 * of a dataset is the `description` every file of that type carries, and
 * schemas/<type>.md shows the same rows with the same words;
 * tests/prog/schemas.sh keeps the two in step. */
#include <string.h>

#include "io/schema.h"

/* ------------------------------------------------------------------ specs */

static const crom_schema_attr common_attrs[] = {
    {"schema", "str", 1, "the schema name, e.g. crom/mesh", NULL},
    {"schema_version", "i64", 1, "version of that schema the file follows", NULL},
    {"history", "str", 1, "how the file was made: one line per stage, oldest first", NULL},
    {"crom_version", "str", 1, "version of crom that wrote the file, e.g. 0.1.0", NULL},
    {NULL, NULL, 0, NULL, NULL}};

/* what every region of a mesh carries, wherever the mesh is stored */
#define REGION_DESC "sorted 0-based vertex indices of this named region"
#define REGION_SOURCE "how the region was made: the predicate text (y<-0.45), or gmsh:GROUP for a gmsh physical group"
#define VERTICES_DESC "rest positions X of the vertices"
#define TETS_DESC "0-based vertex indices of each tetrahedron, positively oriented"
#define TRIS_DESC "0-based vertex indices of each triangle of a shell surface (no tets then), consistently oriented"
#define THICKNESS_DESC "the shell's thickness (m)"
#define PLANE_DESC "1: the triangles are a 2-D solid in plane strain in z = 0 (crom-mesh --plane-strain), thickness its depth; absent or 0: a shell"
#define ORTHO_DESC "a rigid-body scene: the weight w of each body's orthogonality potential, w times the squared Frobenius norm of R^T R - I (J)"
/* a rigid-body scene (lib/mesh/scene.h), under the mesh's group P */
#define SCENE_DSETS(P)                                                                                        \
    {P "scene/shape", "i32", "nb", 0, "1", "a rigid-body scene: each body's shape, 0 box, 1 sphere, 2 capsule, 3 ring", NULL}, \
    {P "scene/size", "f64", "nb,3", 0, "m", "each body's shape size: a box's full extents; a sphere's radius; a capsule's " \
                                           "radius and axis length (along x); a ring's tube radius, radius and straight " \
                                           "length; unused entries 0", NULL},     \
    {P "scene/centre", "f64", "nb,3", 0, "m", "each body's rest centre", NULL}, \
    {P "scene/density", "f64", "nb", 0, "kg/m^3", "each body's density", NULL},                             \
    {P "scene/rotation", "f64", "nb,3,3", 0, "1", "each body's rest rotation Q, shape to world: its shape point p " \
                                                 "is at rest at centre + Q p (absent: the identity)", NULL},   \
    {P "scene/joint_bodies", "i32", "nj,2", 0, "1", "each penalty joint's bodies a, b (b = -1: pinned to the world)", NULL}, \
    {P "scene/joint_points", "f64", "nj,3", 0, "m", "each joint's rest point, held together in both bodies", NULL}, \
    {P "scene/joint_weights", "f64", "nj", 0, "N/m", "each joint's penalty weight w: energy 1/2 w gap^2", NULL}, \
    {P "scene/joint_kinds", "i32", "nj", 0, "1", "each joint's kind: 0 a point joint, 1 a slider (b's point on a's " \
                                               "axis through it; absent: all point joints)", NULL},            \
    {P "scene/joint_axes", "f64", "nj,3", 0, "1", "each slider's rest direction in body a (a unit vector; 0 for point " \
                                                "joints)", NULL},                                            \
    {P "scene/pair_bodies", "i32", "np,2", 0, "1", "each collision pair: body a's surface points against body b's " \
                                                 "signed distance", NULL},                                  \
    {P "scene/pair_weights", "f64", "np", 0, "N/m", "each pair's penalty weight w: energy 1/2 w sum min(phi, 0)^2", NULL}
#define FIELDS_DESC "the frame field names, comma-separated, in the order a frame stream packs them"

static const crom_schema_attr mesh_attrs[] = {
    {"generator", "str", 0, "what made the mesh: box, plate, sphere, cylinder, superquadric, import, sheet or disk (crom-mesh); "
                            "remesh cut, punch, swap or refine with its parameters (crom-remesh); pendulum, chain, klann or stewart (crom-scene)", NULL},
    {"target_size", "f64", 0, "target edge length given to the mesher (m)", NULL},
    {NULL, NULL, 0, NULL, NULL}};

static const crom_schema_attr mesh_objattrs[] = {
    {"source", "str", 1, REGION_SOURCE, "regions/*"},
    {"thickness", "f64", 1, THICKNESS_DESC, "triangles"},
    {"plane_strain", "i64", 0, PLANE_DESC, "triangles"},
    {"ortho_weight", "f64", 1, ORTHO_DESC, "scene"},
    {NULL, NULL, 0, NULL, NULL}};

static const crom_schema_dset mesh_dsets[] = {
    {"vertices", "f64", "nv,3", 1, "m", VERTICES_DESC, NULL},
    {"tets", "i32", "nt,4", 0, "1", TETS_DESC, NULL},
    {"triangles", "i32", "ntri,3", 0, "1", TRIS_DESC, NULL},
    {"regions/*", "i32", "?", 0, "1", REGION_DESC, NULL},
    SCENE_DSETS(""),
    {NULL, NULL, NULL, 0, NULL, NULL, NULL}};

/* the scenario a run was given, as crom_scenario_write_attrs stores it */
#define SCENARIO_ATTRS(req)                                                                              \
    {"scenario", "str", req, "the scenario as flags, one per line (replay it with @FILE)", NULL},         \
    {"dt", "f64", req, "time step h (s)", NULL},                                                         \
    {"every", "i64", req, "a frame is stored every `every` steps", NULL},                                \
    {"steps", "i64", req, "number of time steps requested", NULL},                                       \
    {"youngs", "f64", req, "Young's modulus E (Pa)", NULL},                                              \
    {"poisson", "f64", req, "Poisson ratio nu", NULL},                                                   \
    {"density", "f64", req, "mass density rho (kg/m^3)", NULL},                                          \
    {"gravity", "f64[3]", req, "gravitational acceleration g (m/s^2)", NULL},                            \
    {"tolerance", "f64", 0, "Newton stops when its correction is below tolerance times the bounding-box diagonal", NULL}

#define SERIES_ATTRS                                                                                     \
    {"complete", "i64", 1, "1 when the run finished; 0 when it stopped early (frames so far are kept)", NULL}, \
    {"frames_written", "i64", 0, "on an incomplete series in HDF5 form: the number of frames kept", NULL}

static const crom_schema_attr traj_attrs[] = {
    SERIES_ATTRS,
    SCENARIO_ATTRS(1),
    {"equilibria_model", "str", 0, "constrained equilibria (crom-fullsim --equilibria): the model_id of the modes W they "
                                   "are taken in; frame k is argmin E(x) subject to W^T M (x - X) / m = z_k, and time and "
                                   "step hold k", NULL},
    {"latent_box", "f64", 0, "constrained equilibria: the half-width A of the box of modal coordinates (m)", NULL},
    {"latent_box_scaling", "str", 0, "constrained equilibria: uniform ([-A, A] for every mode) or frequency ([-A f_1/f_k, "
                                     "A f_1/f_k] for mode k)", NULL},
    {NULL, NULL, 0, NULL, NULL}};

static const crom_schema_attr traj_objattrs[] = {
    {"fields", "str", 1, FIELDS_DESC, "frames"},
    {"source", "str", 1, REGION_SOURCE, "mesh/regions/*"},
    {"thickness", "f64", 1, THICKNESS_DESC, "mesh/triangles"},
    {"plane_strain", "i64", 0, PLANE_DESC, "mesh/triangles"},
    {"ortho_weight", "f64", 1, ORTHO_DESC, "mesh/scene"},
    {NULL, NULL, 0, NULL, NULL}};

static const crom_schema_dset traj_dsets[] = {
    {"mesh/vertices", "f64", "nv,3", 1, "m", VERTICES_DESC, NULL},
    {"mesh/tets", "i32", "nt,4", 0, "1", TETS_DESC, NULL},
    {"mesh/triangles", "i32", "ntri,3", 0, "1", TRIS_DESC, NULL},
    {"mesh/regions/*", "i32", "?", 0, "1", REGION_DESC, NULL},
    SCENE_DSETS("mesh/"),
    {"frames/time", "f64", "F", 1, "s", "simulated time of each frame", NULL},
    {"frames/step", "f64", "F", 1, "1", "time-step index of each frame (0 = initial state)", NULL},
    {"frames/displacement", "f64", "F,nv,3", 1, "m", "displacement u = x - X of every vertex", NULL},
    {"frames/velocity", "f64", "F,nv,3", 1, "m/s", "velocity of every vertex", NULL},
    {"frames/kinetic_energy", "f64", "F", 1, "J", "1/2 v^T M v", NULL},
    {"frames/elastic_energy", "f64", "F", 1, "J", "stable neo-Hookean strain energy", NULL},
    {"frames/external_energy", "f64", "F", 1, "J", "potential of gravity and applied forces, -f_ext . u, plus the rods' energy (--rod)", NULL},
    {"frames/total_energy", "f64", "F", 1, "J", "kinetic + elastic + external", NULL},
    {"frames/newton_iterations", "f64", "F", 1, "1", "Newton iterations of the step that produced the frame (0 for frame 0)", NULL},
    {"frames/residual", "f64", "F", 1, "1", "last Newton correction of that step, max-norm, relative to the bounding-box diagonal", NULL},
    {"frames/step_seconds", "f64", "F", 1, "s", "wall time of that step (0 when SOURCE_DATE_EPOCH is set)", NULL},
    {"frames/body_pose", "f64", "F,nb,3,4", 0, "1", "a rigid-body scene: each body's affine map x = R X + t of its rest "
                                                 "points X, R in the first three columns, t (m) in the last", NULL},
    {"frames/joint_gap", "f64", "F,nj", 0, "m", "a rigid-body scene: each joint's gap, the distance between x_a(P) and "
                                               "x_b(P) (a pin: from its rest point)", NULL},
    {"frames/modal_coordinates", "f64", "F,r", 0, "m", "constrained equilibria: the modal coordinates z = W^T M u / m "
                                                       "of the frame", NULL},
    {"frames/modal_forces", "f64", "F,r", 0, "N", "constrained equilibria: the generalized forces -W^T grad E that "
                                                  "hold the body at z", NULL},
    {NULL, NULL, NULL, 0, NULL, NULL, NULL}};

static const crom_schema_attr samples_attrs[] = {
    {"mode", "str", 1, "vertices (random mesh vertices) or interior (random points, barycentric interpolation)", NULL},
    {"points_per_frame", "i64", 1, "N, the number of samples in every frame", NULL},
    {"seed", "i64", 1, "seed of the random choice", NULL},
    {NULL, NULL, 0, NULL, NULL}};

static const crom_schema_attr samples_objattrs[] = {
    {"file", "str", 1, "the input the source came from: a path, or stdin", "sources/*"},
    {"thickness", "f64", 1, THICKNESS_DESC, "sources/*/triangles"},
    {"plane_strain", "i64", 0, PLANE_DESC, "sources/*/triangles"},
    {NULL, NULL, 0, NULL, NULL}};

static const crom_schema_dset samples_dsets[] = {
    {"points", "f32", "F,N,3", 1, "m", "rest positions X of the samples", NULL},
    {"displacements", "f32", "F,N,3", 1, "m", "displacement u(X) at the samples", NULL},
    {"vertex", "i32", "F,N", 1, "1", "vertex index of each sample in its source mesh, -1 for interior points", NULL},
    {"frame_source", "i32", "F", 1, "1", "which source (index into /sources) each frame comes from", NULL},
    {"frame_time", "f64", "F", 1, "s", "simulated time of each frame", NULL},
    {"sources/*/vertices", "f64", "?,3", 1, "m", "rest positions of the source trajectory's mesh", NULL},
    {"sources/*/tets", "i32", "?,4", 0, "1", "tetrahedra of that mesh (a solid's)", NULL},
    {"sources/*/triangles", "i32", "?,3", 0, "1", "a shell's triangles instead of tets", NULL},
    {NULL, NULL, NULL, 0, NULL, NULL, NULL}};

static const crom_schema_attr model_attrs[] = {
    {"basis", "str", 1, "mlp (neural field), pod or modes (piecewise-linear field on a mesh), energy or neuralmodes "
                        "(data-free maps of one mesh), energy-field (continuous data-free map), skinning (affine skinning "
                        "handles), skin-field (continuous data-free map over skinning handles)", NULL},
    {"rank", "i64", 1, "r, the number of basis fields (latent dimension)", NULL},
    {"encoder", "str", 1, "pointnet, lsq or none: how full states are turned into q", NULL},
    {"model_id", "str", 1, "hex digest of the basis parameters; cubature and latent files name it", NULL},
    {"activation", "str", 0, "hidden activation of the MLPs: elu or sine (mlp); elu, gelu or sine (energy, neuralmodes, "
                              "energy-field)", NULL},
    {"reconstruction_error", "f64", 0, "relative error ||Wq - u|| / ||u|| over the training frames (mlp, pod)", NULL},
    {"training_seconds", "f64", 0, "wall time of training (s)", NULL},
    {"scenario", "str", 0, "material, pinned regions (and gravity for energy, energy-field) as flags, one per line "
                           "(modes, energy, neuralmodes, energy-field)", NULL},
    {"youngs", "f64", 0, "Young's modulus E (Pa) of the modes or of the data-free training", NULL},
    {"poisson", "f64", 0, "Poisson ratio of the modes or of the data-free training", NULL},
    {"density", "f64", 0, "density (kg/m^3) of the modes or of the data-free training", NULL},
    {"mass", "f64", 0, "mass m of the body (kg): W / sqrt(m) is M-orthonormal (modes); the mass of the training "
                       "mesh (energy, neuralmodes, energy-field)", NULL},
    {"rigid_modes", "i64", 0, "rigid-body (zero-frequency) modes detected (modes)", NULL},
    {"rigid_kept", "i64", 0, "1 if they lead the basis, 0 if dropped (modes)", NULL},
    {"derivatives", "i64", 0, "fields of the basis that are modal derivatives, after the modes (modes --derivatives)",
     NULL},
    {"training_steps", "i64", 0, "training steps taken (energy, neuralmodes, energy-field)", NULL},
    {"sigma", "f64", 0, "isometry scale: metres of RMS displacement per unit of latent distance (energy, energy-field)", NULL},
    {"isometry_weight", "f64", 0, "weight lambda of the isometry term (energy, energy-field)", NULL},
    {"gravity", "f64[3]", 0, "gravity of the training energy (m/s^2) (energy, energy-field)", NULL},
    {"conditions", "str", 0, "a conditional energy map (crom-fitfield --condition): one NAME=LO:HI per line, the "
                             "scenario parameters (ratio:REGION, gravity:AXIS) its network takes after the latent, "
                             "and the ranges they were trained over", NULL},
    {"latent_box", "f64", 0, "half-width a of the training box of modal coordinates (m) (neuralmodes)", NULL},
    {"latent_box_scaling", "str", 0, "frequency: mode k's half-width is latent_box f_1/f_k; uniform: latent_box for every mode; any other value is refused (neuralmodes; absent: uniform)", NULL},
    {"ortho_weight", "f64", 0, "weight w_o of the M-orthogonality penalty (neuralmodes)", NULL},
    {"origin_weight", "f64", 0, "weight w_0 of the penalty on y(0) (neuralmodes written before the maps were anchored; no longer written)", NULL},
    {"modes_id", "str", 0, "model_id of the crom-modes model whose modes are the linear part (neuralmodes)", NULL},
    {"tangent_anchored", "i64", 0, "1: a neuralmodes map whose correction is y(q) = N(q) - N(0) - J_N(0) q, O(q^2), so "
                                   "that its tangent at rest is the modes' (crom-fitfield --tangent-anchor)", NULL},
    {"supervised", "str", 0, "a neuralmodes map fitted to constrained equilibria by the geometric loss (crom-fitfield "
                             "--supervised, Wang et al.'s L2 supervised baseline): how many, in which modes", NULL},
    {"seed_state", "str", 0, "an energy map grown from a seed state (crom-fitfield --seed-state): which frame of which "
                             "run", NULL},
    {"sampled_along", "str", 0, "a neuralmodes map trained with every other sample near the modal coordinates a "
                                "reduced run visited (crom-fitfield --latents), or an energy map refined near the "
                                "latents a run of its --init-model visited: how many, from which file", NULL},
    {"refined_from", "str", 0, "an energy map refined from another (crom-fitfield --init-model): that map's model_id",
     NULL},
    {"cubature_tets", "i64", 0, "tets of the random cubature drawn at every training step (energy-field)", NULL},
    {"handles", "i64", 0, "H, the affine handles of a skinning subspace (12 coordinates each)", NULL},
    {"constant_handle", "i64", 0, "1 if handle 0 is the constant weight 1 (a free body), else 0 (skinning)", NULL},
    {"latent_activation", "str", 0, "hidden activation of the latent network phi: elu, gelu or sine (skin-field)",
     NULL},
    {"skin_weights", "str", 0, "trained (an MLP weight field) or eigen (skinning eigenmodes on field/mesh) (skinning)",
     NULL},
    {"cut_axis", "str", 0, "x, y or z: the axis of the ribbons of field/cut_segments (mlp with cut features)", NULL},
    {NULL, NULL, 0, NULL, NULL}};

static const crom_schema_attr model_objattrs[] = {
    {"source", "str", 1, REGION_SOURCE, "field/mesh/regions/*"},
    {"thickness", "f64", 1, THICKNESS_DESC, "field/mesh/triangles"},
    {"plane_strain", "i64", 0, PLANE_DESC, "field/mesh/triangles"},
    {"ortho_weight", "f64", 1, ORTHO_DESC, "field/mesh/scene"},
    {NULL, NULL, 0, NULL, NULL}};

static const crom_schema_dset model_dsets[] = {
    {"field/widths", "i32", "L", 0, "1", "layer widths of the MLP, input first: R^3 -> R^(3r) (mlp; R^(3+K) with K "
                                         "cut features), R^3 -> R^(3p) (energy-field), R^r -> R^(3nv) (energy, "
                                         "neuralmodes)", NULL},
    {"field/params", "f32", "P", 0, "1", "all MLP weights and biases, layer by layer (W row-major [out][in], then b)", NULL},
    {"field/input_shift", "f64", "?", 0, "m", "input normalization: X_hat = (X - shift) / scale (mlp, energy-field); "
                                              "3 values, then 3 + K with K cut features (0 and scale 1 for each)", NULL},
    {"field/input_scale", "f64", "?", 0, "m", "input normalization scale", NULL},
    {"field/cut_segments", "f64", "?,4", 0, "m", "a field that can jump across a cut (mlp; crom-fitfield "
                                                 "--cut-segment): the K segments A_u, A_v, B_u, B_v of the cut's "
                                                 "ribbons in the plane perpendicular to cut_axis (as crom-remesh "
                                                 "cut); the field takes after X one feature per segment, the angle "
                                                 "it subtends divided by pi (lib/mesh/cutfeat.h)", NULL},
    {"field/mesh/vertices", "f64", "nv,3", 0, "m", "rest positions X of the mesh of a piecewise-linear basis (pod, modes) "
                                                   "or of a map (energy, neuralmodes)", NULL},
    {"field/mesh/tets", "i32", "nt,4", 0, "1", "tetrahedra of that mesh: 0-based vertex indices, positively oriented", NULL},
    {"field/derivatives", "f64", "nv,3,D", 0, "1/m", "modal derivatives Psi_ij (i <= j, D = r(r+1)/2) of a neuralmodes "
                                                     "map's quadratic part 1/2 sum Psi_ij z_i z_j (fitfield --derivatives)",
     NULL},
    {"field/lifts", "f64", "ncond,nv,3", 0, "1", "a conditional map's static lifts (fitfield --condition "
                                                   "pin:REGION:AXIS): per condition, the body's small-displacement "
                                                   "equilibrium at rest with that pinned region moved by 1 m along "
                                                   "its axis (zero for the other kinds); x(0, c) = X + sum_k c_k "
                                                   "lift_k", NULL},
    {"field/seed", "f64", "nv,3", 0, "m", "an energy map's seed state u_s (Sharp et al. 4.1; fitfield --seed-state): the "
                                          "map is anchored there, x(0) = X + u_s, and a reduced run starts from it", NULL},
    {"field/mesh/triangles", "i32", "ntri,3", 0, "1", "a shell's triangles instead of tets (modes, energy, neuralmodes on a "
                                                     "surface mesh), as crom/mesh", NULL},
    {"field/mesh/regions/*", "i32", "?", 0, "1", REGION_DESC, NULL},
    SCENE_DSETS("field/mesh/"),
    {"field/basis", "f64", "nv,3,r", 0, "1", "basis W at the mesh vertices, [nv][3][r] (pod, modes); the linear part W "
                                             "of the map (neuralmodes)", NULL},
    {"frequencies", "f64", "r", 0, "Hz", "natural frequencies of the linear modes (modes, neuralmodes)", NULL},
    {"encoder/point_widths", "i32", "?", 0, "1", "PointNet per-point MLP widths (6 -> ...)", NULL},
    {"encoder/head_widths", "i32", "?", 0, "1", "PointNet head MLP widths (... -> r)", NULL},
    {"encoder/params", "f32", "?", 0, "1", "all PointNet parameters: per-point MLP, then head", NULL},
    {"encoder/input_shift", "f64", "6", 0, "m", "PointNet input normalization of (X, u): (p - shift) / scale", NULL},
    {"encoder/input_scale", "f64", "6", 0, "m", "PointNet input normalization scale", NULL},
    {"training/loss", "f64", "E", 0, "m^2", "training loss per epoch: mean squared displacement error (mlp)", NULL},
    {"training/seconds", "f64", "E", 0, "s", "wall time at the end of each epoch (data-free: of each block of steps)", NULL},
    {"training/objective", "f64", "E", 0, "1", "data-free objective (energy / reference energy + weighted penalties), "
                                               "mean over each block of steps", NULL},
    {"training/energy", "f64", "E", 0, "J", "mean energy of the batch samples over each block of steps", NULL},
    {"training/penalty", "f64", "E", 0, "1", "mean unweighted penalty: squared log isometry ratio (energy, energy-field) "
                                             "or squared relative projection on the modes (neuralmodes) or the squared norm of G - I, "
                                             "G the weights' Gram matrix (skinning)", NULL},
    {"latent/widths", "i32", "?", 0, "1", "layer widths of the latent network phi: R^r -> R^p, input first (energy-field, "
                                         "skin-field)", NULL},
    {"latent/params", "f32", "?", 0, "1", "all weights and biases of phi, layer by layer (W row-major [out][in], then b) "
                                          "(energy-field, skin-field)", NULL},
    {"latent/pin_points", "f64", "?,3", 0, "m", "pinned training vertices (energy-field): the field is masked by "
                                                "smoothstep(d / pin_length), d the distance to the nearest pinned "
                                                "vertex or triangle", NULL},
    {"latent/pin_triangles", "f64", "?,3,3", 0, "m", "pinned boundary triangles of the training mesh, corners "
                                                     "(energy-field): part of the mask", NULL},
    {"latent/pin_length", "f64", "1", 0, "m", "width of the pin mask (energy-field)", NULL},
    {"skin/frame", "f64", "3,4", 0, "1/m, 1", "body frame F of a skinning subspace: X_hat = F [X; 1] (skinning)", NULL},
    {"skin/coordinates", "f64", "A,S", 0, "1", "C [4H][S]: orthonormal functions psi_s = sum_a C[a][s] phi_a of the "
                                               "handle functions (skinning)", NULL},
    {"skin/weights", "f64", "nv,H", 0, "1", "handle weights at the vertices of field/mesh (skinning, eigen)", NULL},
    {"skin/eigenvalues", "f64", "H", 0, "1/s^2", "eigenvalues of the weights: scalar stiffness against lumped mass "
                                                 "(skinning, eigen)", NULL},
    {"skin/pin_points", "f64", "?,3", 0, "m", "pinned training points: part of the weights' pin mask (skinning, "
                                              "trained)", NULL},
    {"skin/pin_triangles", "f64", "?,3,3", 0, "m", "pinned boundary triangles of the training geometry, corners: part "
                                                   "of the mask (skinning, trained)", NULL},
    {"skin/pin_length", "f64", "1", 0, "m", "width l of the weights' pin mask s(d / l), s(t) = t (2 - t) (skinning, "
                                            "trained)", NULL},
    {NULL, NULL, NULL, 0, NULL, NULL, NULL}};

static const crom_schema_attr latent_attrs[] = {
    SERIES_ATTRS,
    {"model_id", "str", 1, "model_id of the crom/model whose basis W the coordinates q refer to", NULL},
    {"rank", "i64", 1, "r, the latent dimension", NULL},
    {"solver", "str", 0, "how the reduced run solved its steps: newton or gd (over a cubature), gauss-newton (--model)", NULL},
    {"cubatures", "str", 0, "the cubatures of a run over cubatures, one line per schedule entry: the step it starts at, "
                            "then its path", NULL},
    {"initial_error", "f64[2]", 0, "crom-reducedstep --indicator: the initial state's mass-weighted RMS distance from rest "
                                "(m) and from the scenario's initial velocity field (m/s)", NULL},
    {"rigid_frame", "i64", 0, "crom-reducedstep --rigid-frame: 1 when q = [q' | θ | t], the model's latent q' then three "
                              "Euler angles (rad, R = Rz Ry Rx) and a translation (m) of x = R x_model(q') + t", NULL},
    SCENARIO_ATTRS(0),
    {NULL, NULL, 0, NULL, NULL}};

static const crom_schema_attr latent_objattrs[] = {
    {"fields", "str", 1, FIELDS_DESC, "frames"},
    {NULL, NULL, 0, NULL, NULL}};

static const crom_schema_dset latent_dsets[] = {
    {"frames/time", "f64", "F", 1, "s", "simulated time of each frame", NULL},
    {"frames/q", "f64", "F,r", 1, "m", "latent coordinates: u(X) = W(X) q, W dimensionless (mlp, pod, modes); modal "
                                       "coordinates of u = W q + y(q) (neuralmodes)", NULL},
    {"frames/q", "f64", "F,r", 1, "1", "latent z of a data-free map x(z) (energy, energy-field), dimensionless: "
                                       "trained on z ~ N(0, I)", "energy energy-field"},
    {"frames/qdot", "f64", "F,r", 0, "m/s", "latent velocity: (q_n - q_{n-1}) / h in a reduced run, the projection of "
                                            "the velocity field in crom-encode", NULL},
    {"frames/qdot", "f64", "F,r", 0, "1/s", "latent velocity (z_n - z_{n-1}) / h of a data-free map (energy, energy-field)",
     "energy energy-field"},
    {"frames/step", "f64", "F", 0, "1", "time-step index of each frame (0 = initial state)", NULL},
    {"frames/kinetic_energy", "f64", "F", 0, "J", "1/2 v^T M v of the velocity v = (x_n - x_{n-1}) / h of the decoded "
                                                  "positions; 1/2 qdot^T M_r qdot in a linear subspace", NULL},
    {"frames/elastic_energy", "f64", "F", 0, "J", "stable neo-Hookean strain energy, summed over the cubature tets with "
                                                  "their weights, or over every tet of the mesh (--model without --cubature)", NULL},
    {"frames/external_energy", "f64", "F", 0, "J", "potential of gravity and applied forces, -f_ext . u of the decoded "
                                                   "displacement, plus the rods' energy (--rod)", NULL},
    {"frames/total_energy", "f64", "F", 0, "J", "kinetic + elastic + external", NULL},
    {"frames/iterations", "f64", "F", 0, "1", "solver iterations of the step", NULL},
    {"frames/residual", "f64", "F", 0, "1", "last correction of the step: RMS displacement relative to the bounding-box "
                                            "diagonal", NULL},
    {"frames/constraint_residual", "f64", "F", 0, "m", "largest distance of a pinned/prescribed vertex from its target", NULL},
    {"frames/cubature", "f64", "F", 0, "1", "index of the schedule entry (cubature) in use", NULL},
    {"frames/step_seconds", "f64", "F", 0, "s", "wall time of the step (0 when SOURCE_DATE_EPOCH is set)", NULL},
    {"frames/wall_time", "f64", "F", 0, "s", "crom-live: wall-clock time since the run started at which the frame was "
                                             "written, against its simulated time (0 when SOURCE_DATE_EPOCH is set)", NULL},
    {"frames/late", "f64", "F", 0, "1", "crom-live: 1 when the step ended after its simulated time (it took longer "
                                        "than dt), else 0", NULL},
    {"frames/commands", "f64", "F", 0, "1", "crom-live: command lines read before the frame's step (applied or "
                                            "refused; blank and comment lines not counted): a frame with commands "
                                            "≥ N shows the N-th command (crom-view times a page's command to its "
                                            "frame so)", NULL},
    {"frames/reconstruction_error", "f64", "F", 0, "1", "|Wq - u| / |u| of the encoded frame (mass-weighted)", NULL},
    {"frames/indicator", "f64", "F", 0, "1", "crom-reducedstep --indicator: the estimated relative displacement error "
                                              "of the frame, |K0^-1 g|_M / |u|_M with g the full-space residual of its "
                                              "step decoded onto a mesh and K0 the stiffness at rest (0 at frame 0)", NULL},
    {"frames/error_estimate", "f64", "F", 0, "m", "crom-reducedstep --indicator: the mass-weighted RMS of K0^-1 g, the "
                                                  "estimated displacement error (0 at frame 0)", NULL},
    {"frames/bc_error", "f64", "F", 0, "m", "crom-reducedstep --indicator: the largest distance of a pinned or "
                                            "prescribed vertex of the decoded state from its target (0 at frame 0)", NULL},
    {"frames/condition", "f64", "F,C", 0, "1", "crom-reducedstep --model of a conditional map: the values of its "
                                               "conditions at the frame, in the order of the model's conditions "
                                               "(a modulus ratio; gravity in m/s^2); decoders lay the map at them", NULL},
    {"frames/keyframe", "f64", "F", 0, "1", "crom-keyframe: the frame's place among the keys, s in [0, K-1] (an integer "
                                           "at a key, z(s) interpolates between keys floor(s) and floor(s)+1)", NULL},
    {"frames/lerp_energy", "f64", "F", 0, "J", "crom-keyframe: strain energy of the linear interpolation of the decoded "
                                               "keyframe positions at the same s (what interpolating positions instead "
                                               "of latents would store)", NULL},
    {NULL, NULL, NULL, 0, NULL, NULL, NULL}};

static const crom_schema_attr cub_attrs[] = {
    {"model_id", "str", 1, "model_id of the crom/model whose W is cached here", NULL},
    {"scheme", "str", 1, "random, metis, optimized or all", NULL},
    {"rank", "i64", 1, "r", NULL},
    {"count", "i64", 1, "number of cubature tets", NULL},
    {"mesh_volume", "f64", 1, "volume of the mesh the cubature integrates (m^3)", NULL},
    {"w_seconds", "f64", 0, "wall time of evaluating W at the mesh vertices (s)", NULL},
    {"selection_seconds", "f64", 0, "wall time of selecting and weighting the tets (s)", NULL},
    {"map_rank", "i64", 0, "latent rank of the nonlinear map whose feature basis B is cached as W "
                           "(crom-reducedstep --model --cubature)", NULL},
    {NULL, NULL, 0, NULL, NULL}};

static const crom_schema_attr cub_objattrs[] = {
    {"source", "str", 1, REGION_SOURCE, "mesh/regions/*"},
    {"thickness", "f64", 1, THICKNESS_DESC, "mesh/triangles"},
    {"plane_strain", "i64", 0, PLANE_DESC, "mesh/triangles"},
    {NULL, NULL, 0, NULL, NULL}};

static const crom_schema_dset cub_dsets[] = {
    {"mesh/vertices", "f64", "nv,3", 1, "m", VERTICES_DESC, NULL},
    {"mesh/tets", "i32", "nt,4", 0, "1", TETS_DESC, NULL},
    {"mesh/triangles", "i32", "ntri,3", 0, "1", TRIS_DESC, NULL},
    {"mesh/regions/*", "i32", "?", 0, "1", REGION_DESC, NULL},
    {"W", "f64", "nv,3,r", 1, "1", "basis W(X) at every mesh vertex, [vertex][component][field]", NULL},
    {"lumped_volume", "f64", "nv", 1, "m^3", "sum of V_t/4 over the tets of each vertex (mass / density)", NULL},
    {"elements", "i32", "k", 1, "1", "cubature tets: indices into mesh/tets (a shell: its energy elements, the "
                                     "triangles then the hinges)", NULL},
    {"weights", "f64", "k", 1, "1", "non-negative cubature weight of each tet", NULL},
    {"Dminv", "f64", "k,3,3", 0, "1/m", "inverse rest edge matrix [X1-X0, X2-X0, X3-X0]^-1 of each cubature tet, row-major (solids)", NULL},
    {"volume", "f64", "k", 0, "m^3", "rest volume of each cubature tet (solids)", NULL},
    {"WtVW", "f64", "r,r", 1, "m^3", "sum over vertices of V_v W_v^T W_v: times density, the reduced mass matrix", NULL},
    {"WtV", "f64", "r,3", 1, "m^3", "sum over vertices of V_v W_v^T: times density and gravity, the reduced gravity force", NULL},
    {"surface", "i32", "s", 1, "1", "boundary vertices: the contact points checked against collision planes", NULL},
    {NULL, NULL, NULL, 0, NULL, NULL, NULL}};

static const crom_schema specs[] = {
    {"crom/mesh", 1, "tetrahedral mesh or shell surface with named vertex regions", mesh_attrs, mesh_objattrs, mesh_dsets, 0},
    {"crom/trajectory", 1, "full-space simulation: mesh, scenario and frames", traj_attrs, traj_objattrs, traj_dsets, 1},
    {"crom/samples", 1, "point samples (X, u) of trajectories, for training", samples_attrs, samples_objattrs,
     samples_dsets, 0},
    {"crom/model", 1, "a subspace basis W(X) (neural field or mesh field) and its encoder", model_attrs,
     model_objattrs, model_dsets, 0},
    {"crom/latent", 1, "latent trajectory q(t) in a model's subspace", latent_attrs, latent_objattrs, latent_dsets, 1},
    {"crom/cubature", 1, "cubature tets and weights with cached W for reduced simulation", cub_attrs, cub_objattrs,
     cub_dsets, 0},
    {NULL, 0, NULL, NULL, NULL, NULL, 0}};

/* ---------------------------------------------------------------- lookups */

const crom_schema *crom_schema_find(const char *name)
{
    for (const crom_schema *s = specs; name && s->schema; s++)
        if (!strcmp(s->schema, name))
            return s;
    return NULL;
}

const crom_schema *crom_schema_all(void) { return specs; }

const crom_schema_attr *crom_schema_common_attrs(void) { return common_attrs; }

int crom_schema_path_match(const char *pattern, const char *path)
{
    while (*pattern && *path) {
        if (*pattern == '*') {
            const char *end = strchr(path, '/');
            if (end == path)
                return 0; /* an empty member name */
            path = end ? end : path + strlen(path);
            pattern++;
        } else if (*pattern++ != *path++) {
            return 0;
        }
    }
    return !*pattern && !*path;
}

/* 1 if the space-separated list `kinds` holds `kind` */
static int lists(const char *kinds, const char *kind)
{
    size_t n = strlen(kind);
    for (const char *p = kinds; p && *p;) {
        const char *e = strchr(p, ' ');
        size_t len = e ? (size_t)(e - p) : strlen(p);
        if (len == n && !strncmp(p, kind, n))
            return 1;
        p = e ? e + 1 : NULL;
    }
    return 0;
}

const crom_schema_dset *crom_schema_dset_find(const crom_schema *s, const char *path, const char *kind)
{
    const crom_schema_dset *plain = NULL;
    for (const crom_schema_dset *d = s ? s->dsets : NULL; d && d->path; d++) {
        if (!crom_schema_path_match(d->path, path))
            continue;
        if (!d->kinds && !plain)
            plain = d;
        else if (d->kinds && kind && lists(d->kinds, kind))
            return d;
    }
    return plain;
}

const crom_schema_attr *crom_schema_attr_find(const crom_schema *s, const char *object, const char *name)
{
    if (!object)
        for (const crom_schema_attr *a = common_attrs; a->name; a++)
            if (!strcmp(a->name, name))
                return a;
    if (!s)
        return NULL;
    for (const crom_schema_attr *a = object ? s->objattrs : s->attrs; a && a->name; a++)
        if (!strcmp(a->name, name) && (!object || crom_schema_path_match(a->object, object)))
            return a;
    return NULL;
}
