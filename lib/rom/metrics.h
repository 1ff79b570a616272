/* metrics.h — how good is a subspace of one mesh (crom-metrics): measured on
 * random latent samples of its map x(q) (lib/rom/map.h), linear or not.
 *
 *   energy      the mean stable neo-Hookean energy of the samples (and with
 *               the potential of gravity), and their mean RMS displacement
 *               from rest sqrt(uᵀMu / m); optionally, for comparison, the
 *               mean energy of another (linear) subspace of the same mesh at
 *               the SAME displacement magnitudes: for each sample, a random
 *               direction of the other basis scaled to the sample's RMS
 *               displacement;
 *   isometry    the distribution over pairs of samples of the ratio
 *               ‖x(q) − x(q')‖_M / sqrt(m) / (σ ‖q − q'‖) (Sharp et al.
 *               eq. 2; 1 everywhere for an isometric map), as quantiles and
 *               the mean squared log-ratio (their eq. 3);
 *   collapse    Wang et al. §4.4: the latent directions J = ∂x/∂q at q = 0,
 *               their Gram matrix G = JᵀMJ / m, and the eigenvalues of
 *               r G / tr G (ascending; all 1 for M-orthonormal directions
 *               of equal length, near 0 for a collapsed dimension: a
 *               direction that is (nearly) a combination of the others or
 *               does not move the body) and of the correlation matrix
 *               D^-1/2 G D^-1/2, D = diag G (the paper's "correlation
 *               matrix of latent directions").
 */
#ifndef CROM_METRICS_H
#define CROM_METRICS_H

#include <stdint.h>

#include "base/rng.h"
#include "phys/material.h"
#include "phys/system.h"
#include "rom/map.h"
#include "rom/model.h"

enum { CROM_METRICS_NORMAL = 0, CROM_METRICS_SPHERE = 1, CROM_METRICS_BOX = 2 };

typedef struct {
    int samples;     /* latent samples (256) */
    int dist;        /* CROM_METRICS_*: q ~ N(0, R² I), |q| = R, or q in [-R, R]^r */
    double radius;   /* R */
    const double *box_freq; /* BOX: frequencies f_k [r], coordinate k drawn from [-R f_1/f_k, R f_1/f_k]
                             * (f_1 the lowest positive one; NULL: [-R, R] for every k) */
    double sigma;    /* isometry scale: RMS metres per unit of q (1 for q in metres) */
    int pairs_of;    /* isometry over all pairs of the first pairs_of samples (100) */
    uint64_t seed;
} crom_metrics_opts;

typedef struct {
    int r, samples;
    double energy_mean, energy_min, energy_max; /* elastic (J) */
    double potential_mean;                      /* elastic + gravity (J) */
    double rms_mean, rms_max;                   /* RMS displacement from rest (m) */
    double cmp_energy_mean;                     /* the other subspace at the same RMS (J), or NAN */
    long npairs;
    double iso_q05, iso_median, iso_q95, iso_logsq;
    double *gram_eig, *corr_eig;                /* [r], ascending */
    double gram_trace;                          /* tr G (m² per unit q²) */
} crom_metrics;

void crom_metrics_defaults(crom_metrics_opts *o);

/* The latent distribution a model was trained on, into o->dist and
 * o->radius: N(0, I) for an energy map (energy, energy-field, skin-field), the training box for neural modes
 * (o->box_freq pointing into the model's frequencies when that box was scaled by them),
 * else the sphere of radius 0.05 diag (diag: the mesh's bounding-box
 * diagonal). */
void crom_metrics_training_dist(const crom_model *m, double diag, crom_metrics_opts *o);

/* One latent sample q [r] of the distribution of o. */
void crom_metrics_sample(crom_rng *rng, const crom_metrics_opts *o, int r, double *q);

/* Measure map on the system fem of its mesh (a solid or a shell: its
 * material gives the energy, its lumped masses M) under gravity g [3]. compare (may be NULL)
 * must be a linear map of the same mesh (CROM_EUSAGE otherwise). Returns 0,
 * CROM_EDATA for a non-finite sample, CROM_EINTERNAL. out->gram_eig and
 * corr_eig are allocated (crom_metrics_free). */
int crom_metrics_compute(crom_map *map, const crom_system *fem, const double g[3], const crom_metrics_opts *o,
                         crom_map *compare, crom_metrics *out);

void crom_metrics_free(crom_metrics *m);

/* ---- Against constrained equilibria (crom-fullsim --equilibria) ---------
 * Wang et al.'s measures of a modal subspace (Neural Modes §4, Table 2 and
 * A1): at the modal coordinates z_k of K ground-truth equilibria u*_k, the
 * subspace's configuration x(z_k) against X + u*_k. Stress is the von Mises
 * stress per element (a tet's Cauchy stress, a shell triangle's membrane
 * stress), weighted by the elements' rest volumes or areas; nodal forces
 * are the internal elastic forces f = −∇E at the free vertices. */
typedef struct {
    int count;                          /* equilibria measured */
    double energy, energy_gt;           /* mean elastic energy of the subspace, of the equilibria (J) */
    double energy_max, energy_gt_max;   /* their largest (J) */
    double stress, stress_gt;           /* mean over samples of the weighted mean von Mises stress (Pa) */
    double stress_max, stress_gt_max;   /* largest element stress over all samples (Pa) */
    double stress_err;                  /* mean over samples of Σ_e w_e |σ_e − σ*_e| / Σ_e w_e σ*_e */
    double force_err;                   /* mean over samples of the RMS over vertices of |f − f*| (N) */
    double force_gt;                    /* mean over samples of the RMS over vertices of |f*| (N) */
    double disp_err;                    /* mean over samples of |u − u*|_M / |u*|_M */
    double zmax_dev;                    /* largest |Wᵀ M u*_k / m − z_k| (m): do the files' modes agree */
    double zmap_dev;                    /* largest |Wᵀ M (x(z_k) − X) / m − z_k| (m): how far the subspace's own
                                         * configuration is from the modal coordinates it is compared at (0
                                         * for linear modes and a correction M-orthogonal to them) */
    int below;                          /* samples where the subspace stores less energy than the equilibrium
                                         * (by more than 1e-9 of it): a solve that found a higher local
                                         * minimum, not the least energy at that z */
} crom_metrics_eq;

/* Measure map (a modal subspace, q = z: linear modes or a neuralmodes map;
 * CROM_EUSAGE otherwise, and when its modes do not reproduce the z_k of
 * the equilibria to 1e-6 of the box) on the system sys of its mesh with
 * material mat, the pinned DOFs fixed (or NULL), at K equilibria: modal
 * coordinates Z [K][r] and displacements U [K][3nv]. Returns 0,
 * CROM_EDATA (a non-finite configuration), CROM_EUSAGE or CROM_EINTERNAL. */
int crom_metrics_equilibria(crom_map *map, const crom_system *sys, const crom_material *mat,
                            const unsigned char *fixed, int K, const double *Z, const double *U, crom_metrics_eq *out);

#endif
