/* schedule.c — the cubatures of a reduced run and when it switches between
 * them (see schedule.h). */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/array.h"
#include "base/err.h"
#include "rom/schedule.h"

/* One line 'STEP CUBATURE' of the file sched (line lineno), after the
 * entries of s: appended, its cubature loaded and checked against entry 0. */
static int add_entry(crom_schedule *s, size_t *cap, const char *sched, int lineno, long step, const char *path,
                     int steps)
{
    const crom_schedule_entry *last = &s->e[s->n - 1];
    if (step <= last->step || step < 1)
        return crom_err(CROM_EUSAGE, "%s:%d: step %ld is out of order (steps must increase, after %ld)", sched,
                        lineno, step, last->step);
    if (step > steps)
        return crom_err(CROM_EUSAGE, "%s:%d: step %ld is beyond --steps %d", sched, lineno, step, steps);
    int rc = crom_array_reserve((void **)&s->e, cap, (size_t)s->n + 1, sizeof *s->e);
    if (rc)
        return rc;
    crom_schedule_entry *e = &s->e[s->n++];
    memset(e, 0, sizeof *e);
    e->step = step;
    e->path = crom_strdup(path);
    if ((rc = crom_cubature_load(path, &e->cub, NULL)))
        return crom_err_ctx("%s:%d", sched, lineno);
    if (strcmp(e->cub.model_id, s->e[0].cub.model_id) || e->cub.r != s->e[0].cub.r)
        return crom_err(CROM_EDATA, "%s:%d: %s is a cubature of model %s, %s is of model %s", sched, lineno, path,
                        e->cub.model_id, s->e[0].path, s->e[0].cub.model_id);
    return 0;
}

int crom_schedule_load(crom_schedule *s, const char *cub, const char *sched, int steps)
{
    memset(s, 0, sizeof *s);
    size_t cap = 0;
    int rc = crom_array_reserve((void **)&s->e, &cap, 1, sizeof *s->e);
    if (rc)
        return rc;
    memset(s->e, 0, sizeof *s->e);
    s->n = 1;
    rc = crom_cubature_load(cub, &s->e[0].cub, &s->e[0].history);
    if (!rc && s->e[0].cub.map_rank)
        rc = crom_err(CROM_EDATA, "%s is a cubature of a nonlinear map (model %s): run it with --model MODEL "
                      "--cubature %s", cub, s->e[0].cub.model_id, cub);
    s->e[0].path = crom_strdup(cub);
    if (rc || !sched)
        return rc;
    FILE *f = fopen(sched, "r");
    if (!f)
        return crom_err(CROM_ENOINPUT, "--schedule %s: %s", sched, strerror(errno));
    char line[2048];
    int lineno = 0;
    while (!rc && fgets(line, sizeof line, f)) {
        lineno++;
        char *hash = strchr(line, '#');
        if (hash)
            *hash = 0;
        char path[1500];
        long step;
        int k = sscanf(line, "%ld %1499s", &step, path);
        if (k <= 0)
            continue;
        if (k != 2)
            rc = crom_err(CROM_EUSAGE, "%s:%d: expected 'STEP CUBATURE'", sched, lineno);
        else
            rc = add_entry(s, &cap, sched, lineno, step, path, steps);
    }
    fclose(f);
    return rc;
}

char *crom_schedule_text(const crom_schedule *s)
{
    size_t len = 1;
    for (int i = 0; i < s->n; i++)
        len += strlen(s->e[i].path) + 32;
    char *list = crom_calloc(len, 1);
    for (int i = 0; list && i < s->n; i++)
        snprintf(list + strlen(list), len - strlen(list), "%s%ld %s", i ? "\n" : "", s->e[i].step, s->e[i].path);
    return list;
}

void crom_schedule_free(crom_schedule *s)
{
    for (int i = 0; i < s->n; i++) {
        crom_cubature_free(&s->e[i].cub);
        free(s->e[i].path);
        free(s->e[i].history);
    }
    free(s->e);
    memset(s, 0, sizeof *s);
}
