/* indicator.h — an a-posteriori error indicator for reduced runs that
 * needs no full simulation (issue 18): decode the reduced state onto a mesh
 * of the body and measure the full-space residual of the implicit Euler
 * step there (crom_sim_residual, lib/phys/sim.h), plus how far the pinned
 * and prescribed vertices are from their targets, and how well the initial
 * state is represented.
 *
 * The residual is a force; the indicator is the displacement it stands
 * for under the stiffness at rest, an estimate of the state's distance from
 * the full step's solution. On a sagging bar it ranks six runs (trained,
 * other shapes, other materials) in the order of their true error, reading
 * 2-6 times high (README; tests/prog/indicator.sh).
 */
#ifndef CROM_INDICATOR_H
#define CROM_INDICATOR_H

#include "mesh/mesh.h"
#include "phys/scenario.h"
#include "phys/sim.h"
#include "rom/model.h"

typedef struct {
    crom_sim sim;        /* the full-space step on the mesh (never stepped) */
    int nv, r;
    double *W;           /* a linear basis laid on the mesh [nv][3][r], or NULL: positions given */
    double *xp, *vp, *x, *v;
    double err, urms, bc;   /* of the last step measured (crom_indicator_step) */
    double se, su;          /* over the steps measured: Σ err², Σ urms² */
    double worst, at;       /* the largest err / urms of a step, and its time */
} crom_indicator;

/* Measure on mesh (borrowed for the indicator's life) under scenario sc
 * (borrowed): regions resolve against mesh (CROM_EUSAGE naming a missing
 * one). model (may be NULL: positions are given to crom_indicator_step) is a
 * linear basis laid on mesh, r its rank; CROM_EDATA when vertices of mesh
 * lie outside a mesh-field model; CROM_EUSAGE for a shell surface (a flat
 * shell's rest stiffness has no membrane resistance out of its plane: the
 * estimate read 4e10 on a hanging sheet). On failure *ind holds nothing to
 * free. */
int crom_indicator_init(crom_indicator *ind, const crom_mesh *mesh, const crom_scenario *sc,
                        const crom_model *model);

/* The step ending at t1 from the state before it (positions xprev,
 * velocities vprev, or latent qprev, qdprev of a linear basis) to the state
 * after it (x or q): crom_sim_residual's *err (the estimated RMS
 * displacement error, m), *urms (the RMS displacement, m) and *bc (the
 * largest miss of a pinned or prescribed DOF, m). The latent pairs are used
 * when the indicator has a basis. */
int crom_indicator_step(crom_indicator *ind, double t1, const double *prev, const double *prevdot,
                        const double *now, double *err, double *urms, double *bc);

/* The run's indicator so far, sqrt(Σ err² / Σ urms²) over the steps
 * measured: crom-diff's measure of the error (0 before any step). */
double crom_indicator_total(const crom_indicator *ind);

/* Measure on another mesh from now on (a schedule's mesh switch), with the
 * run's sums kept; as crom_indicator_init otherwise (on failure *ind holds
 * nothing to free). */
int crom_indicator_remesh(crom_indicator *ind, const crom_mesh *mesh, const crom_scenario *sc,
                          const crom_model *model);

/* How well the initial state (positions x0 or latent q0, velocities v0 or
 * qd0) represents the scenario's: mass-weighted RMS distance from rest (m)
 * and from the initial velocity field (m/s). */
void crom_indicator_initial(crom_indicator *ind, const double *x0, const double *v0, double *ex, double *ev);

void crom_indicator_free(crom_indicator *ind);

#endif
