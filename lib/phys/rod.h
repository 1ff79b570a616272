/* rod.h — a rod (a spring) between two parts of a body whose rest length
 * may follow a sinusoid in time: the actuators of Neural Modes' puppet
 * (Wang et al. 2024, §5: six rods whose rest lengths follow sinusoids
 * drive the body), given by the scenario's --rod (scenario.h).
 *
 * Each end is a region (a name, a predicate, or one vertex "#N") and
 * stands for its mass-weighted centroid c = Σ m_v x_v / Σ m_v, so a rod's
 * force spreads over its ends' vertices by mass. With d = c_B − c_A and
 * ℓ = |d|, the rod stores
 *     E = ½ k (ℓ − L(t))²,      L(t) = L0 + a sin(2π t / T + φ),
 * with gradient ∂E/∂d = k (ℓ − L) n (n = d/ℓ; ∂E/∂c_B = −∂E/∂c_A) and
 * Hessian ∂²E/∂d² = k [n nᵀ + (1 − L/ℓ)(I − n nᵀ)], whose transverse
 * part is negative when the rod is compressed (ℓ < L); the projected
 * Hessian clamps that part at zero. Each simulator (full, reduced over a
 * cubature, reduced through a map) writes c_A and c_B in its own
 * coordinates and chains these derivatives through them. */
#ifndef CROM_ROD_H
#define CROM_ROD_H

#include "mesh/mesh.h"

typedef struct {
    char a[128], b[128]; /* the two ends: regions, predicates, or vertices "#N" */
    double k;            /* stiffness (N/m) */
    double L0;           /* mean rest length (m); NaN: the ends' distance at rest */
    double amp;          /* amplitude a (m) of the rest length's sinusoid; 0: constant */
    double period;       /* T (s) */
    double phase;        /* φ (rad) */
} crom_rod;

/* Parse the value "A/B=K,L0[,AMP,PERIOD[,PHASE]]" of flag (named in
 * messages) into r: L0 a length or "rest". The ends are split at the first
 * '/', the numbers follow the last '='. Returns 0 or CROM_EUSAGE naming
 * what is wrong (an empty end, K not positive, L0 negative, AMP without a
 * positive PERIOD, a value not finite). */
int crom_rod_parse(const char *flag, const char *v, crom_rod *r);

/* The flag value of r, as crom_rod_parse reads it back, into buf (cap
 * bytes, snprintf's way); returns the length it needs. */
int crom_rod_format(const crom_rod *r, char *buf, int cap);

/* The rest length L(t) of r, with rest the ends' distance at rest (used
 * when r->L0 is NaN). */
double crom_rod_length(const crom_rod *r, double rest, double t);

/* The energy ½ k (|d| − L)² of a rod of stiffness k and rest length L
 * whose ends are d = c_B − c_A apart; g [3] (may be NULL) its gradient in
 * d, H [3][3] (may be NULL) its Hessian, projected to positive
 * semi-definite when project != 0. At d = 0 the direction is undefined:
 * n is taken as the x axis. */
double crom_rod_eval(double k, double L, const double d[3], double g[3], double H[9], int project);

/* ---- Rods on a mesh, in full space ---------------------------------------
 * The rods of a scenario resolved on a mesh: each end's vertices with their
 * weights m_v / m_end, so that d = c_B − c_A = Σ w_v x_v over both ends (the
 * weights of end A negative). What crom_sim and the error indicator use. */
typedef struct {
    int n;             /* rods */
    int *ptr;          /* [2n+1] CSR over the ends: A of rod k is 2k, B is 2k+1 */
    int *idx;          /* the ends' vertices */
    double *w;         /* their signed weights */
    double *rest;      /* [n] the ends' distance at rest (m) */
} crom_rod_set;

/* Resolve rods [n] on mesh m with lumped masses mass [nv]. Returns 0,
 * CROM_EUSAGE (an end not on the mesh, or without mass; the message names
 * the end) or CROM_EINTERNAL. On failure *R holds nothing to free. */
int crom_rod_set_init(crom_rod_set *R, int n, const crom_rod *rods, const crom_mesh *m, const double *mass);

void crom_rod_set_free(crom_rod_set *R);

/* The gap d = c_B − c_A of rod k at positions x [nv][3]. */
void crom_rod_set_gap(const crom_rod_set *R, int k, const double *x, double d[3]);

/* The rods' energy at positions x and time t; g [3nv] (may be NULL) gets
 * their gradient added; Hd [n][9] (may be NULL) each rod's Hessian in its
 * gap (projected per project), for crom_rod_set_matvec. */
double crom_rod_set_eval(const crom_rod_set *R, const crom_rod *rods, double t, const double *x, double *g, double *Hd,
                      int project);

/* y += Σ_k J_kᵀ Hd_k J_k x, J_k = ∂d_k/∂x, over the DOFs that fixed [3nv]
 * (may be NULL) does not mark: the rods' part of the Hessian, which joins
 * every vertex of one end to every vertex of the other and so stays out of
 * the sparse pattern. */
void crom_rod_set_matvec(const crom_rod_set *R, const double *Hd, const unsigned char *fixed, const double *x, double *y);

#endif
