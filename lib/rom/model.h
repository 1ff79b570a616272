/* model.h — crom/model: a subspace basis W: R^3 -> R^{3 x r} and its encoder
 * (schemas/model.md).
 *
 * The reduced kinematics are u(X) = W(X) q with W dimensionless and q in
 * metres. An evaluated W at n points is stored [n][3][r] row-major: row c of
 * the 3 x r matrix holds the c-components of the r basis fields. Two
 * representations exist, chosen by the datasets (the `basis` attribute names
 * the kind, and later kinds reuse these representations):
 *
 *   CROM_MODEL_FIELD_MLP (basis "mlp"): a neural field, an MLP 3 -> ... -> 3r
 *       whose 3r outputs are W(X) in the [3][r] order above (output c*r + j is
 *       component c of field j), with the input normalization
 *       X_hat = (X - shift) / scale stored.
 *   CROM_MODEL_FIELD_MESH (basis "pod", "modes"): a piecewise-linear field on
 *       a stored tet mesh: W at the mesh vertices, [nv][3][r], interpolated
 *       barycentrically inside each tet. A point outside the mesh takes the
 *       value at the closest point of the nearest tet (lib/mesh/locate.h),
 *       i.e. W is extended constantly along the normal direction. A
 *       basis made on a shell surface (crom-modes on a shell; its
 *       field/mesh has triangles) is evaluated at its own vertices only.
 *   CROM_MODEL_FIELD_MAP (basis "energy", "neuralmodes"): a NONLINEAR map of
 *       the latent to the positions of every vertex of ONE stored mesh (the
 *       data-free subspaces, lib/datafree/datafree.h): x(q) = X + W q + N(q),
 *       with N an MLP r -> ... -> 3nv (output 3v + c is component c of vertex
 *       v, metres, no input normalization) and W [nv][3][r] the linear modes
 *       for "neuralmodes" (absent, i.e. 0, for "energy"). It is no basis field
 *       W(X): crom_model_eval refuses it; lib/rom/map.h evaluates it (and its
 *       Jacobian) on its own mesh.
 *   CROM_MODEL_FIELD_CMAP (basis "energy-field"): a CONTINUOUS nonlinear
 *       subspace, x(X, q) = X + W(X) φ(q), trained from the energy alone
 *       (lib/datafree/datafree.h): W a neural field 3 -> 3p as for "mlp"
 *       (output c*p + j is component c of feature field j, with its input
 *       normalization) and φ an MLP r -> p (the `latent` network, linear
 *       output, same activation). It lays on any mesh like a LiCROM field
 *       (lib/rom/map.h) but is no linear basis: crom_model_eval refuses it
 *       too.
 *   CROM_MODEL_FIELD_SKIN (basis "skinning"): a LINEAR skinning-handle
 *       subspace, u(X) = Σ_h w_h(X) Q_h [X̂; 1] with H affine handles (rank
 *       12H, or 3S in orthonormal coordinates), from weights w(X) stored as an
 *       MLP 3 -> H (trained) or a piecewise-linear field on a stored mesh
 *       (eigen); lib/rom/skin.h has the layout. crom_model_eval gives its W(X)
 *       like any linear basis. With basis "skin-field" (the `latent` network
 *       present) it is a CONTINUOUS nonlinear map instead, x(X, q) = X +
 *       W(X) (φ(q) − φ(0)) with W the skinning basis (p = 12H or 3S features)
 *       and φ: r -> p trained from the energy alone (crom-fitfield
 *       --objective field --handles H); the rank is r, and crom_model_eval
 *       refuses it as it refuses energy-field.
 *
 * model_id: 16 lowercase hex digits, the 64-bit FNV-1a digest of the basis:
 * the `basis` string (with its NUL), the rank (int64), then for an MLP the
 * widths (int32), the activation name (with its NUL), input shift and scale
 * (float64) and the parameters (float32), then for a field with cut
 * features "cut" (with its NUL), the axis and K (int64) and the segments
 * (float64); for a mesh field nv and nt (int64),
 * the vertices (float64), the tets (int32) and the basis (float64); for a map
 * the widths, the activation name, the parameters, then nv and nt, the
 * vertices, the tets and (neuralmodes) the linear basis; for a continuous
 * map the field as for an MLP, then the latent network's widths (int32)
 * and parameters (float32), the pin point count (int64) and points, the
 * pin triangle count (int64) and corners, and the length (float64); for a
 * skinning model what crom_skin_digest adds (lib/rom/skin.h), then for
 * a skin-field the latent network's widths and parameters; all
 * little-endian,
 * exactly as stored. The encoder and the training record are
 * not part of it: latent coordinates and cached W depend on W alone.
 */
#ifndef CROM_MODEL_H
#define CROM_MODEL_H

#include <stddef.h>

#include <hdf5.h>

#include "io/io.h"
#include "mesh/cutfeat.h"
#include "mesh/locate.h"
#include "mesh/mesh.h"
#include "nn/nn.h"
#include "phys/scenario.h"

#define CROM_MODEL_SCHEMA "crom/model"
#define CROM_MODEL_VERSION 1

enum {
    CROM_MODEL_FIELD_MLP = 1, CROM_MODEL_FIELD_MESH = 2, CROM_MODEL_FIELD_MAP = 3, CROM_MODEL_FIELD_CMAP = 4,
    CROM_MODEL_FIELD_SKIN = 5
};
enum { CROM_MODEL_ENC_NONE = 0, CROM_MODEL_ENC_LSQ = 1, CROM_MODEL_ENC_POINTNET = 2 };

#define CROM_MODEL_MAXCOND 4 /* conditions of a conditional map */

typedef struct {
    char basis[16];      /* the `basis` attribute: mlp, pod, modes, ... */
    int field;           /* CROM_MODEL_FIELD_* */
    int rank;            /* r */
    int encoder;         /* CROM_MODEL_ENC_* */
    char model_id[17];   /* filled by read, write and crom_model_id */
    /* CROM_MODEL_FIELD_MLP (CROM_MODEL_FIELD_MAP: the map's network r -> 3nv;
     * CROM_MODEL_FIELD_CMAP: the feature field 3 -> 3p) */
    crom_nn_mlp mlp;     /* 3 -> ... -> 3r, owns its parameters */
    crom_cutfeat cut;    /* CROM_MODEL_FIELD_MLP: a field that can jump across a cut (lib/mesh/cutfeat.h):
                          * its inputs are X then cut.nseg features, 3 + K -> ... -> 3r (nseg 0: none) */
    crom_nn_mlp latent;  /* CROM_MODEL_FIELD_CMAP: φ, r -> ... -> p */
    int npin_points;     /* CROM_MODEL_FIELD_CMAP: the pin mask (lib/datafree/datafree.h): */
    double *pin_points;  /* [npin_points][3] pinned training vertices (m) */
    int npin_triangles;
    double *pin_triangles; /* [npin_triangles][3][3] pinned boundary triangles (m) */
    double pin_length;   /* its width ℓ (m) */
    /* CROM_MODEL_FIELD_SKIN (lib/rom/skin.h): weights in mlp (trained, 3 -> H or
     * H - 1, masked by the pin_* mask) or on mesh (eigen, skin_w) */
    int handles;         /* H: rank = 12 H */
    int skin_constant;   /* 1: handle 0 is the constant weight 1 */
    double skin_frame[12]; /* [3][4] F: X̂ = F [X; 1] */
    int skin_S;          /* orthonormal coordinates: S functions, rank 3 S */
    double *skin_C;      /* [4H][S] their coefficients, or NULL (handle
                          * coordinates, rank 12 H) */
    double *skin_w;      /* eigen: [nv][H] weights at the vertices of mesh */
    double *skin_eig;    /* eigen: [H] eigenvalues (1/s²), or NULL */
    /* CROM_MODEL_FIELD_MESH (and CROM_MODEL_FIELD_MAP: its mesh, with regions) */
    crom_mesh mesh;      /* vertices and tets */
    double *basis_v;     /* [nv][3][r] W at the vertices (MAP: linear part or NULL) */
    double *deriv_v;     /* neuralmodes: [nv][3][r(r+1)/2] the modal derivatives Ψ_ij (i <= j) of
                          * the quadratic part ½ Σ Ψ_ij q_i q_j, or NULL (lib/phys/mderiv.h) */
    double *lift_v;      /* a conditional map with a pin condition: [ncond][nv][3] each condition's static
                          * lift (zero but for pin conditions; lib/rom/map.h), or NULL */
    double *seed_v;      /* energy maps: [nv][3] the seed state's displacement (Sharp et al. §4.1):
                          * the map is anchored there, x(0) = X + seed_v, or NULL (at rest) */
    crom_locator loc;    /* point location on mesh */
    double *frequencies; /* [r] natural frequencies (modes), or NULL */
    /* encoder (CROM_MODEL_ENC_POINTNET): maps points (X, u) [n][6] to q in metres */
    crom_nn_pointnet enc;
    /* training record (NULL / NAN when absent) */
    int nepochs;
    double *loss;        /* [nepochs] training loss (m^2) */
    double *seconds;     /* [nepochs] cumulative wall time (s) */
    double reconstruction_error; /* relative, over the training frames */
    double training_seconds;
    /* recorded physics (modes, data-free; NULL / NAN when absent): written
     * by crom_model_write when set, read back by crom_model_read */
    char *scenario;      /* material, gravity and pins as flags, one per line */
    double youngs, poisson, density;
    /* data-free training record (lib/datafree/datafree.h; NAN / has_gravity 0 when
     * absent): read by crom_model_read, written by the trainers */
    double sigma;        /* energy maps: isometry scale (m per unit z) */
    double latent_box;   /* neuralmodes: half-width of the training box (m) */
    int latent_box_scaled; /* neuralmodes: 1 if mode k's half-width is latent_box f_1 / f_k */
    int tangent_anchored;  /* neuralmodes: 1 if y(q) = N(q) − N(0) − J_N(0) q (attribute tangent_anchored;
                            * written by the trainer's record) */
    double gravity[3];   /* the training gravity (m/s²) */
    int has_gravity;
    /* a conditional map (Sharp et al. §3.5; CROM_MODEL_FIELD_MAP, energy):
     * its network takes [q, c], the latent then ncond scenario parameters
     * (attribute `conditions`, one "NAME=LO:HI" per line, the ranges trained
     * over; crom_map_set_condition) */
    int ncond;
    crom_scenario_cond cond[CROM_MODEL_MAXCOND];
} crom_model;

/* Make a map model conditional on n scenario parameters cond [n] (after
 * crom_model_from_map with a network of rank + n inputs: the rank becomes
 * its inputs less n). CROM_EUSAGE for too many conditions or a network
 * with no latent left. */
int crom_model_set_conditions(crom_model *m, int n, const crom_scenario_cond *cond);

/* An empty model (safe to free), with NAN training figures. */
void crom_model_clear(crom_model *m);

/* Make an MLP model from a trained field (copied: widths 3 + K -> ... -> 3r),
 * the cut whose K features it takes after X (copied; NULL: none, K = 0) and
 * an optional PointNet encoder (copied; NULL: encoder "lsq"). CROM_EUSAGE if
 * the input width is not 3 + K, the output width is not a positive
 * multiple of 3 or the encoder does not output r values; CROM_EINTERNAL
 * when out of memory. */
int crom_model_from_mlp(crom_model *m, const crom_nn_mlp *W, const crom_cutfeat *cut, const crom_nn_pointnet *enc);

/* Make a mesh-field model of kind `basis` ("pod", "modes") from a mesh
 * (copied, regions dropped) and W at its vertices, basis [nv][3][r]
 * (copied). Builds the point locator. Errors as crom_locate_init. */
int crom_model_from_mesh(crom_model *m, const char *basis, const crom_mesh *mesh,
                         const double *basis_v, int rank);

/* Make a map model of kind `basis` ("energy", "neuralmodes") from a
 * network net (copied; r -> ... -> 3nv, identity input normalization), the
 * mesh it maps (copied with its regions) and, for neuralmodes, the linear
 * part basis_v [nv][3][r] (copied; NULL for none). Encoder "none".
 * CROM_EUSAGE on mismatched shapes, CROM_EINTERNAL when out of memory. */
int crom_model_from_map(crom_model *m, const char *basis, const crom_nn_mlp *net,
                        const crom_mesh *mesh, const double *basis_v);

/* 1 if `basis` names a map kind (energy, neuralmodes). */
/* The modal derivatives of a rank-r map's quadratic part: r(r+1)/2. */
int crom_model_nderiv(const crom_model *m);

int crom_model_is_map_kind(const char *basis);

/* Make a continuous map model ("energy-field") from its feature field W
 * (3 -> 3p, with its input normalization), latent network phi (r -> p) and
 * pin mask (npin points pinX [npin][3], ntri triangles triX [ntri][3][3],
 * width len), all copied. The field
 * stored is W unmasked; crom_model_mask gives the mask. CROM_EUSAGE on
 * mismatched widths. */
int crom_model_from_field_map(crom_model *m, const crom_nn_mlp *W, const crom_nn_mlp *phi, int npin,
                              const double *pinX, int ntri, const double *triX, double len);

/* Make a linear skinning model m (basis "skinning", rank p) a continuous
 * nonlinear map, basis "skin-field": x(X, q) = X + W(X) (φ(q) − φ(0)) with
 * W its skinning basis and phi (r -> p, copied) the latent network; the
 * rank becomes r. CROM_EUSAGE for another model or mismatched widths. */
int crom_model_skin_field(crom_model *m, const crom_nn_mlp *phi);

/* The pin mask s(d(X)/ℓ) at X, s the smoothstep 3t² − 2t³ (1 for t >= 1)
 * and d the distance to the nearest of npin points pinX [npin][3] and ntri
 * triangles triX [ntri][3][3] (1 if there are none): what a continuous
 * data-free map multiplies its field by so that pinned vertices stay at
 * rest (lib/datafree/datafree.h). */
double crom_model_pin_mask(const double X[3], int npin, const double *pinX, int ntri, const double *triX,
                           double len);

/* The pin mask of a continuous map at X (1 for other models). */
double crom_model_mask(const crom_model *m, const double X[3]);

/* 1 for a model nonlinear in q (CROM_MODEL_FIELD_MAP, CROM_MODEL_FIELD_CMAP, a skin-field): decoded
 * and simulated through lib/rom/map.h, with no basis W(X). */
int crom_model_is_nonlinear(const crom_model *m);

/* 1 for a model trained data-free on latents q ~ N(0, I) with an isometry
 * scale m->sigma (bases "energy", "energy-field", "skin-field"). */
int crom_model_latent_normal(const crom_model *m);

/* The mesh a field is stored on (group field/mesh of an open model file h)
 * into m->mesh: LiCROM mesh fields and skinning weights share it. Returns 0
 * or CROM_EDATA naming field/mesh. */
int crom_model_read_field_mesh(hid_t h, crom_model *m);

/* Write mesh as the group field/mesh of a model at loc: its vertices and
 * tets, or a shell's triangles with their thickness (the attribute
 * `thickness` of field/mesh/triangles), which crom_model_read_field_mesh
 * reads back. */
int crom_model_write_field_mesh(hid_t loc, const crom_mesh *mesh);

/* A network of the given spec from an open model file h: its float32
 * parameters at dataset `params` (<group>/params) and, where shift is not
 * NULL, its input normalization at datasets shift and scale (3 values
 * each), all finite, into out. Errors name `what` ("the field") and the
 * group. Returns 0, CROM_EDATA or CROM_EINTERNAL. */
int crom_model_read_net(hid_t h, const char *params, const char *shift, const char *scale, const crom_nn_spec *spec,
                        const char *what, crom_nn_mlp *out);

/* Read a crom/model input (schema and version are checked here) and validate
 * it: shapes, finite parameters, a model_id that matches the parameters.
 * Returns 0, or CROM_EDATA with a message naming the input. */
int crom_model_read(crom_in *in, crom_model *m);

/* Open path ("-" for stdin) and read the model in it. Returns as
 * crom_in_open and crom_model_read. */
int crom_model_load(const char *path, crom_model *m);

/* Write the model under loc (the root of a crom/model output): attributes
 * basis, rank, encoder, model_id, activation (mlp), reconstruction_error and
 * training_seconds (when known), and the datasets of its kind. Also stores
 * the model_id in m (hence not const). Returns 0 or an HDF5 error. */
int crom_model_write(hid_t loc, crom_model *m);

/* The model_id digest of the basis into id[17] (see above); returns id. */
const char *crom_model_id(const crom_model *m, char id[17]);

/* W at n points X [n][3] into W [n][3][r] (double). An MLP runs in float32
 * inside (crom_nn_mlp_eval); a mesh field interpolates. *noutside (may be
 * NULL) gets how many points lay outside a mesh field's mesh. Returns 0,
 * CROM_EDATA for a map model (it has no basis field), or CROM_EINTERNAL
 * (out of memory). */
int crom_model_eval(const crom_model *m, size_t n, const double *X, double *W,
                    size_t *noutside);

/* crom_model_eval with the cut features of a field (m->cut) taken at the
 * points S [n][3] instead of X (NULL: at X): a vertex on a crack face is
 * evaluated at its own position with the features of its own side. */
int crom_model_eval_sided(const crom_model *m, size_t n, const double *X, const double *S, double *W,
                          size_t *noutside);

/* W at the vertices of a mesh, [nv][3][r], as every program evaluates a
 * basis on a mesh: a mesh field on its own mesh (or a shell's basis) at
 * the vertices, exactly (the copies of a cut keep their own values); a
 * field with cut features at the vertices, with each copy's features from
 * its field point (crom_mesh_field_points with offset s); any other field
 * at the field points, where the copies a cut made sample W on their own
 * sides. Errors as crom_model_eval. */
int crom_model_eval_mesh(const crom_model *m, const crom_mesh *mesh, double s, double *W, size_t *noutside,
                         int *nshifted);

/* Encode one frame with the model's PointNet: n points pts [n][6] = (X, u) in
 * metres into q [r] (metres). CROM_EUSAGE if the model has no PointNet. */
int crom_model_encode_pointnet(const crom_model *m, size_t n, const double *pts, double *q);

/* Free everything; m becomes empty (crom_model_clear). */
void crom_model_free(crom_model *m);

/* Name of an encoder code ("none", "lsq", "pointnet"). */
const char *crom_model_encoder_name(int enc);

#endif
