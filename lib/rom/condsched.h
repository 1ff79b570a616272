/* condsched.h — the conditions a reduced run of a conditional map takes
 * over time (crom-reducedstep --model MAP --condition NAME=VALUE[@T];
 * Sharp et al. §3.5: "c can change at run time"). Each entry sets one of
 * the map's conditions (phys/scenario.h: ratio:REGION, gravity:AXIS,
 * pin:REGION:AXIS) to VALUE from time T on; a condition not given runs at
 * the middle of its trained range. The run applies a change through
 * crom_nlsim_set_condition (rom/nlsim.h). */
#ifndef CROM_CONDSCHED_H
#define CROM_CONDSCHED_H

#include "phys/scenario.h"
#include "rom/model.h"

#define CROM_CONDSCHED_MAX 32

typedef struct {
    int n;
    struct {
        crom_scenario_cond c; /* which condition (its name; the range unused) */
        double value;         /* its value */
        double t;             /* from this time on (s) */
    } e[CROM_CONDSCHED_MAX];
} crom_condsched;

/* Add the entry "NAME=VALUE[@T]" (v) of flag (named in messages) to s.
 * CROM_EUSAGE for a bad name or number, a negative time or more than
 * CROM_CONDSCHED_MAX entries. */
int crom_condsched_add(crom_condsched *s, const char *flag, const char *v);

/* The values c [m->ncond] of model m's conditions at time t: each
 * condition's last entry with a time <= t (entries of one condition are
 * taken in the order given: the last wins), else the middle of its range.
 * CROM_EUSAGE for an entry naming a condition m does not have. */
int crom_condsched_at(const crom_condsched *s, const crom_model *m, double t, double *c);

#endif
