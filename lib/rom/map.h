/* map.h — a subspace of ONE mesh as a map from the latent q in R^r to the
 * positions of every vertex, evaluated in double with its Jacobian:
 *
 *     x(q) = X + W q + N(q),        J(q) = dx/dq = W + dN/dq,
 *
 * (a neuralmodes map with modal derivatives adds ½ Σ_{i<=j} Ψ_ij q_i q_j,
 * lib/phys/mderiv.h),
 * the common form of every model that can be laid on a mesh:
 *   - a continuous data-free map (crom/model basis "energy-field", or
 *     "skin-field" over a skinning basis), x = X + W(X) φ(q), on any mesh:
 *     B = W(X_v) and a = φ(q);
 *   - a data-free map (crom/model basis "energy": W = 0; "neuralmodes": W the
 *     linear modes, N the learned correction y(q)) on its own mesh;
 *   - a linear basis (pod, modes, skinning, or an mlp neural field) sampled at the
 *     vertices of a mesh: N = 0 and W = W(X_v).
 *
 * Every nonlinear map is ANCHORED at the rest shape: its features are
 * taken relative to their value at q = 0, a(q) − a(0) (below), so that
 *
 *     x(q) = X + W q + N(q) − N(0),   x(X, q) = X + W(X) (φ(q) − φ(0)),
 *
 * and x(0) = X exactly, to the last bit, whatever the network: a run from
 * rest starts at q = 0 and a run with no load stays there (lib/nlrom.h).
 * An energy map trained from a seed state u_s (Sharp et al. §4.1 and Fig.
 * 3: a compressed, buckled bar has no rest shape to grow from) is anchored
 * there instead: x(q) = X + u_s + N(q) − N(0), and x0 below is X + u_s.
 * The data-free trainers (lib/datafree.h) train this same anchored map.
 *
 * The network N runs in double precision from the stored float32 weights
 * (converted once), so x(q) is smooth to round-off: Gauss–Newton on it
 * (lib/rom/nlsim.h) and finite-difference checks see no float noise. Output
 * 3v + c of N is component c of vertex v in metres; there is no input
 * normalization (the latent enters as is).
 *
 * A map holds work buffers: one map per thread.
 */
#ifndef CROM_MAP_H
#define CROM_MAP_H

#include "mesh/mesh.h"
#include "nn/nn.h"
#include "rom/model.h"

typedef struct crom_map_s {
    int r;               /* latent dimension */
    int nv, n;           /* vertices and 3 nv */
    int nonlinear;       /* 1 if N is present */
    crom_mesh mesh;      /* the mesh (owned copy, with regions) */
    double *x0;          /* [n] the positions at q = 0: X, or X + the seed state of a seeded energy map
                          * (Sharp et al. §4.1, crom-fitfield --seed-state); x(q) = x0 + B a(q) */
    /* The map as a linear basis over features a(q) in R^p:
     *     x(q) = X + B a(q),   J(q) = B T(q),  T = da/dq [p][r],
     * a = [q (if W) | ½ q_i q_j (if Ψ) | the last hidden layer h of N | 1 (if
     * N)] less its value at 0, i.e. [q | ½ q_i q_j | h(q) − h(0) | 0], and
     * B = [W | Ψ | W_L | b_L]
     * ([n][p] row-major; a continuous map: a = φ(q) − φ(0), or, when φ's last
     * hidden layer h is narrower than its output, a = [h(q) − h(0) | 0] over
     * B = [W(X_v) W_L | W(X_v) b_L]), so that everything a reduced
     * simulation needs from a few vertices costs p flops per row and
     * quadratic forms over all vertices are p x p (lib/rom/nlsim.h). A linear
     * basis has a = q, T = I, B = W. */
    int p;
    int p_model;         /* p as the model defines it (φ's outputs), before fold_last_layer in
                          * map.c re-expresses a continuous map over φ's last hidden layer
                          * when that is narrower; cubatures made before it record this one */
    double *B;           /* [n][p] */
    int rl;              /* leading features equal to q: r with a linear part, else 0 */
    int rq;              /* then the quadratic features ½ q_i q_j (i <= j) of a neuralmodes map
                          * with modal derivatives (B's columns Ψ_ij): r(r+1)/2, else 0 */
    int phi;             /* 1: the features are the network's output, a = φ(q) − φ(0)
                          * (a continuous map, x = X + W(X) (φ(q) − φ(0)): B = W(X_v)) */
    /* the hidden layers of N in double: layer l maps width[l] to width[l+1] */
    int nlayers, width[CROM_NN_MAX_LAYERS + 1];
    crom_nn_act act;     /* hidden activation; the output layer is linear */
    double omega0;
    double *w[CROM_NN_MAX_LAYERS], *b[CROM_NN_MAX_LAYERS];
    double *mem;
    /* scratch: activations and tangents of the widest hidden layer */
    double *a0, *a1, *z1, *t0, *t1;
    double *zs, *ts;     /* crom_map_curvature: every hidden layer's z and dz/dq */
    double *fa, *fT;     /* crom_map_eval's features and their Jacobian */
    double *tan0;        /* tangent-anchored neuralmodes: [p][r] T(0), subtracted from the network's features
                          * (a − T(0) q: the map's tangent at rest is W) */
    double *anchor;      /* [p] a(0), subtracted from the features of a nonlinear map (NULL: linear) */
    int tangent;         /* tan0 is kept (a tangent-anchored neuralmodes map) */
    /* a conditional map (Sharp et al. §3.5; the model's conditions): its
     * network takes [q, c]; c enters the first layer only, as the bias
     * b0 + Wc c, so B, and the features' form, do not change with c, and
     * the anchor a(0) is taken at the current c (x(0, c) = X for every c) */
    int nc;
    double *cond;        /* [nc] the current c (crom_map_set_condition; at init the ranges' midpoints) */
    double *w0;          /* [width1][r] the first layer's latent columns (map->w[0]) */
    double *wc;          /* [width1][nc] its condition columns */
    double *b0, *bc;     /* [width1] its bias, and b0 + Wc c (map->b[0]) */
    /* its pin conditions (pin:REGION:AXIS): x0 is xs (X, or X + the seed)
     * plus Σ_k c_k lift_k, lift_k the static lift of condition k (its pinned
     * region moved by 1 m along its axis and the body with it at rest,
     * the model's field/lifts; zero for the other kinds); NULL when there
     * is none */
    double *xs, *lift;
    /* a rigid frame (crom_map_add_frame): this map is x = R(θ) y(q') + t
     * over the map y = *inner, with q = [q' | θ | t]; NULL: none */
    struct crom_map_s *inner;
    double *ia, *iT, *ig; /* scratch: inner features [p'], their Jacobian [p'][r'], a covector [p'] */
} crom_map;

/* Build the map of a model. A map model (energy, neuralmodes) lives on its
 * own mesh: mesh must be NULL or have the same vertices and tets (its
 * regions are then used), else CROM_EDATA ("decodes only onto its own
 * mesh"). A mesh field (pod, modes) is sampled on mesh (NULL: its own mesh;
 * another mesh: interpolated as crom_model_eval does), and so is an eigen
 * skinning model. A neural field (mlp, trained skinning) needs a mesh
 * (CROM_EUSAGE without one). CROM_EINTERNAL when out of
 * memory. On failure *map holds nothing to free. */
int crom_map_init(crom_map *map, const crom_model *model, const crom_mesh *mesh);

/* Positions x [n] (NULL to skip) and Jacobian J [n][r] row-major (NULL to
 * skip) at latent q [r]. Returns 0 or CROM_EDATA when the result is not
 * finite. */
int crom_map_eval(crom_map *map, const double *q, double *x, double *J);

/* Features a [p] (NULL to skip) and their Jacobian T [p][r] row-major
 * (NULL to skip) at latent q [r] (see above; for a nonlinear map a is
 * anchored, a(q) − a(0), so a = 0 at q = 0). Returns 0 or CROM_EDATA when
 * a feature is not finite. */
int crom_map_features(crom_map *map, const double *q, double *a, double *T);

/* The curvature of the features along a covector: C [r][r] = Σ_k g_k
 * ∂²a_k/∂q∂q at q, for g [p] (the Hessian of gᵀa(q), exact: one forward
 * pass with tangents and one adjoint pass; zero for a linear map). Returns
 * 0 or CROM_EDATA when the network is not finite at q. */
int crom_map_curvature(crom_map *map, const double *q, const double *g, double *C);

/* Positions x [nidx][3] = x0_v + B_v a of the vertices idx [nidx] (all
 * vertices when idx is NULL, nidx then ignored) at features a [p], and
 * (J non-NULL) their Jacobian rows J [3 nidx][r] = B_v T. */
void crom_map_rows(const crom_map *map, const int *idx, int nidx, const double *a, const double *T, double *x,
                   double *J);

/* Set the condition c [nc] of a conditional map (values of the model's
 * conditions, in their order; outside the trained ranges is allowed:
 * extrapolation): the features of every q change, the anchor follows, so
 * x(0) = x0 still, and a pin condition moves x0 along its lift. CROM_EUSAGE for a map with no conditions, CROM_EDATA for
 * a non-finite value or network. */
int crom_map_set_condition(crom_map *map, const double *c);

/* Add six rigid degrees of freedom to map (Wang et al. 2024 §5: the
 * puppet's subspace is "5 DoFs corresponding to Neural Modes, and 6 DoFs
 * for rigid transformations"): the map y(q') of rank r' becomes
 *
 *     x(q', θ, t) = R(θ) y(q') + t,   R(θ) = R_z(θ_3) R_y(θ_2) R_x(θ_1),
 *
 * of rank r' + 6 (latent [q' | θ (rad) | t (m)]; x(0) = y(0) = x0). R is
 * taken about the origin of the mesh's coordinates, by Euler angles: no
 * singularity while |θ_2| < π/2. The result is linear in the features
 *     a = [ (R_kl − δ_kl, R_kl a'(q'))_{kl} | t ]   (9 (p' + 1) + 3 of them)
 * over B = [e_k ⊗ (x0_l, B'_l) | I], so everything built on the features
 * (nlsim.h's quadratic forms, rows and curvature) applies unchanged. The
 * elastic energy is invariant under the frame: a cubature of y serves x.
 * CROM_EUSAGE for a conditional map or one that has a frame already,
 * CROM_EINTERNAL when out of memory (map is then freed). */
int crom_map_add_frame(crom_map *map);

/* Release what init allocated (NULL-safe). */
void crom_map_free(crom_map *map);

/* 0 if meshes a and b have the same vertices (within 1e-9 relative) and
 * tets (or triangles and thickness); else 1. */
int crom_map_same_mesh(const crom_mesh *a, const crom_mesh *b);

#endif
