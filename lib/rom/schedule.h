/* schedule.h — the cubatures a reduced run switches between (crom-reducedstep
 * --schedule; LiCROM §4: cuts, punches and swaps mid-run). Entry 0 is the
 * initial cubature, at step 0; a schedule file adds lines 'STEP CUBATURE'
 * ('#' starts a comment), steps increasing from 1 to the run's last. Before
 * step STEP the run switches to that cubature, q and q̇ carrying over: every
 * entry must be a cubature of the same model and rank. The run records its
 * schedule as the `cubatures` attribute of its output (crom_schedule_text),
 * which crom-export --follow-schedule reads back. */
#ifndef CROM_SCHEDULE_H
#define CROM_SCHEDULE_H

#include "rom/cubature.h"

typedef struct {
    long step;         /* the switch comes before this step (entry 0: 0) */
    char *path;        /* the cubature file */
    crom_cubature cub;
    char *history;     /* entry 0: the cubature file's history (else NULL) */
} crom_schedule_entry;

typedef struct {
    int n;
    crom_schedule_entry *e; /* [n] */
} crom_schedule;

/* Load the initial cubature cub and, when sched is not NULL, the schedule
 * file sched for a run of `steps` steps, reading every cubature it names.
 * Returns 0, CROM_ENOINPUT, CROM_EUSAGE (a bad line, steps out of order or
 * beyond `steps`), CROM_EDATA (a cubature of a nonlinear map, or of another
 * model or rank) or the errors of crom_cubature_load, naming the file and
 * line. s holds what was loaded even on failure: free it with
 * crom_schedule_free. */
int crom_schedule_load(crom_schedule *s, const char *cub, const char *sched, int steps);

/* "STEP PATH" per entry, one a line (malloc'ed; NULL when out of memory):
 * the run's `cubatures` attribute. */
char *crom_schedule_text(const crom_schedule *s);

void crom_schedule_free(crom_schedule *s);

#endif
