/* equil.h — what a set of constrained equilibria needs around the solver
 * of lib/phys/cequil.h (crom-fullsim --equilibria): the linear modes of a
 * model laid on a mesh, the box of modal coordinates, the coordinates of
 * each equilibrium (a grid or uniform draws in the box, or the frames of a
 * latent run), and a solve from two starts.
 */
#ifndef CROM_EQUIL_H
#define CROM_EQUIL_H

#include "base/rng.h"
#include "mesh/mesh.h"
#include "phys/cequil.h"
#include "rom/map.h"
#include "rom/model.h"

/* The linear modes W [3nv][r] (row-major, malloc'ed into *W) of model (basis
 * "modes", or the linear part of a "neuralmodes" map) on mesh m: their own
 * values when m is the model's mesh (exact, zero at the pins), else linear
 * modes interpolated onto m; map is the model's map (free it). Returns 0 or
 * CROM_EUSAGE naming the problem (another basis; a neuralmodes map of
 * another mesh), CROM_EINTERNAL. */
int crom_equil_modes(const crom_model *model, const crom_mesh *m, crom_map *map, double **W);

/* The half-widths half[r] of the box of modal coordinates: A = box when
 * positive, else a neuralmodes map's training box, else 0.2 times the
 * bounding-box diagonal of m; scaling 1 (frequency: A f_1/f_k for mode k),
 * 0 (uniform) or -1 (the map's own, uniform for linear modes). *A and
 * *scaled get what was used. CROM_EUSAGE when frequency scaling has no
 * frequencies. */
int crom_equil_box(const crom_model *model, const crom_mesh *m, double box, int scaling, double *half, double *A,
                   int *scaled);

/* The latent q [r] of every frame of the crom/latent at path into *Z
 * [count][r] (malloc'ed); of a run with a rigid frame, q = [q' | θ | t],
 * the model's part q'. CROM_EUSAGE for another rank, CROM_EDATA for no
 * frame or a non-finite q, or the reader's errors. */
int crom_equil_latents(const char *path, int r, double **Z, long *count);

/* Modal coordinates z [r] of equilibrium k: row k of Z when it is given,
 * else point k of a grid of `grid` points per axis over [-half, half] (the
 * last axis fastest), else a uniform draw from rng. */
void crom_equil_point(int grid, int r, const double *half, const double *Z, long k, crom_rng *rng, double *z);

/* The equilibrium at z from X + W z or from xprev (may be NULL) moved to z,
 * the second start tried when the first fails (CROM_EDATA); prev_first
 * picks xprev first (continuation along a path). x [n] gets the
 * equilibrium, lam [r] its modal forces. The error names both starts. */
int crom_equil_solve(crom_cequil *ce, const double *X, const double *W, const double *z, const double *xprev,
                     int prev_first, double *x, double *lam, crom_cequil_stats *st);

#endif
