/* live.h — a reduced run steered while it runs (crom-live; LiCROM's
 * interactive application, ../shared/seeds/000_*.txt Fig. 3): commands, one
 * per line, change the loads of a reduced simulation on a cubature (rsim.h)
 * between its steps.
 *
 *   drag REF X,Y,Z [K]     pull REF (a region, a predicate, or one vertex
 *                          "#N") toward the point (m) with a spring of
 *                          stiffness K N/m (default: the run's), implicit in
 *                          the step (crom_rsim_drag_set); again to move it
 *   release [REF]          end the drag of REF (default: every drag)
 *   force REF FX,FY,FZ     a total force (N) on REF, spread by mass, from the
 *                          next step on (0,0,0 ends it); the same as the
 *                          offline --force REF=F@T0: with T0 halfway into
 *                          that step (crom_live_force_window)
 *   pin REF / unpin REF    hold REF at rest (the BC penalty) / let it go
 *   schedule CUBATURE      switch to another cubature of the same model (a
 *                          cut, punched or swapped mesh; as --schedule)
 *   condition NAME=VALUE   a conditional model's parameter (none is
 *                          conditional yet: refused)
 *   step N                 (scripted runs, crom-live --no-clock) take N steps
 *   quit                   end the run
 *
 * Blank lines and lines starting with '#' are nothing. A bad line is one
 * CROM_EUSAGE message and changes nothing: the run goes on. */
#ifndef CROM_LIVE_H
#define CROM_LIVE_H

#include "phys/scenario.h"
#include "rom/cubature.h"
#include "rom/rsim.h"

typedef enum {
    CROM_LIVE_NONE, /* blank or comment */
    CROM_LIVE_DRAG,
    CROM_LIVE_RELEASE,
    CROM_LIVE_FORCE,
    CROM_LIVE_PIN,
    CROM_LIVE_UNPIN,
    CROM_LIVE_SCHEDULE,
    CROM_LIVE_CONDITION,
    CROM_LIVE_STEP,
    CROM_LIVE_QUIT
} crom_live_kind;

typedef struct {
    crom_live_kind kind;
    char ref[128];   /* region, predicate or #N; the cubature's path (schedule); NAME=VALUE (condition) */
    double v[3];     /* drag point (m) or force (N) */
    double k;        /* drag stiffness (N/m); 0: the run's default */
    long n;          /* steps */
} crom_live_cmd;

/* Parse one line. Returns 0 (kind NONE for nothing) or CROM_EUSAGE with a
 * message naming what is wrong (an unknown command, a missing or
 * non-finite number, a bad count). */
int crom_live_parse(const char *line, crom_live_cmd *c);

/* The running simulation the commands act on. The scenario is the run's
 * own copy (forces and pins change in it); cubatures loaded by `schedule`
 * are kept until the end (the simulation borrows the one in use). */
typedef struct {
    crom_scenario sc;
    crom_rsim sim;
    crom_cubature **cubs; /* [ncubs]: [0] the first (borrowed), then those loaded (owned) */
    int ncubs, cur;
    double drag_k;        /* the default drag stiffness (N/m) */
    int nlive;            /* forces of the scenario set by commands (its last nlive) */
    int first_live;       /* index of the first of them */
} crom_live;

/* Start on cubature cub (borrowed) with scenario sc (copied), solver and
 * BC penalty as crom_rsim_init, from rest; drag_k the default stiffness of
 * a drag (<= 0: 10 m g / L, m the body's mass and L its size: the body's
 * weight stretches the spring by a tenth of its size). Returns as
 * crom_rsim_init. */
int crom_live_init(crom_live *L, const crom_cubature *cub, const crom_scenario *sc, int solver, double kappa,
                   double drag_k);

/* Apply command c (not STEP or QUIT, which the caller handles). Returns 0
 * or an error code with a message; on error nothing has changed. */
int crom_live_apply(crom_live *L, const crom_live_cmd *c);

/* The time T0 from which a force given now acts: halfway into the next
 * step, so that its load (taken at a step's end) is on from that step and
 * `--force REF=F@T0:` offline gives the same run. */
double crom_live_force_window(const crom_live *L);

void crom_live_free(crom_live *L);

#endif
