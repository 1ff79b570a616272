/* condsched.c — the conditions of a reduced run over time (condsched.h). */
#include <stdio.h>
#include <string.h>

#include "base/err.h"
#include "base/parse.h"
#include "rom/condsched.h"

int crom_condsched_add(crom_condsched *s, const char *flag, const char *v)
{
    if (s->n == CROM_CONDSCHED_MAX)
        return crom_err(CROM_EUSAGE, "%s: at most %d", flag, CROM_CONDSCHED_MAX);
    char buf[256], what[64];
    const char *at = strrchr(v, '@');
    size_t len = at ? (size_t)(at - v) : strlen(v);
    if (len >= sizeof buf)
        return crom_err(CROM_EUSAGE, "%s: too long", flag);
    memcpy(buf, v, len);
    buf[len] = 0;
    snprintf(what, sizeof what, "%s @T", flag);
    double t = 0;
    crom_scenario_cond c;
    if (crom_scenario_cond_parse(flag, buf, 0, &c) || (at && crom_parse_double(at + 1, what, &t)))
        return CROM_EUSAGE;
    if (!(t >= 0))
        return crom_err(CROM_EUSAGE, "%s %s: the time must be >= 0", flag, v);
    s->e[s->n].c = c;
    s->e[s->n].value = c.lo; /* (a value is parsed as a range of one point) */
    s->e[s->n].t = t;
    s->n++;
    return 0;
}

int crom_condsched_at(const crom_condsched *s, const crom_model *m, double t, double *c)
{
    for (int k = 0; k < m->ncond; k++)
        c[k] = 0.5 * (m->cond[k].lo + m->cond[k].hi);
    for (int i = 0; i < s->n; i++) {
        int k = 0;
        while (k < m->ncond && !crom_scenario_cond_same(&m->cond[k], &s->e[i].c))
            k++;
        if (k == m->ncond) {
            char name[200];
            crom_scenario_cond_format(&s->e[i].c, name, sizeof name);
            char *eq = strchr(name, '=');
            if (eq)
                *eq = 0;
            return crom_err(CROM_EUSAGE, "--condition %s: model %s %s", name, m->model_id,
                            m->ncond ? "has no such condition" : "is not conditional (crom-fitfield --condition)");
        }
        if (s->e[i].t <= t + 1e-12)
            c[k] = s->e[i].value;
    }
    return 0;
}
