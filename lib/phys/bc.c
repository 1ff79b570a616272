/* bc.c — boundary conditions on regions over time windows (see bc.h). */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "base/err.h"
#include "base/parse.h"
#include "phys/bc.h"

int crom_bc_parse(const char *flag, const char *v, crom_bc *b)
{
    const char *eq = strrchr(v, '=');
    if (!eq || eq == v)
        return crom_err(CROM_EUSAGE, "%s '%s': expected REGION=X,Y,Z[@T0:T1]", flag, v);
    size_t len = (size_t)(eq - v);
    if (len >= sizeof b->ref)
        return crom_err(CROM_EUSAGE, "%s: region too long", flag);
    memcpy(b->ref, v, len);
    b->ref[len] = 0;
    char vec[256];
    snprintf(vec, sizeof vec, "%s", eq + 1);
    b->t0 = 0;
    b->t1 = INFINITY;
    char *at = strchr(vec, '@');
    if (at) {
        *at = 0;
        char *colon = strchr(at + 1, ':');
        if (!colon)
            return crom_err(CROM_EUSAGE, "%s '%s': time window must be @T0:T1", flag, v);
        *colon = 0;
        if (crom_parse_double(at + 1, flag, &b->t0))
            return CROM_EUSAGE;
        if (*(colon + 1) && crom_parse_double(colon + 1, flag, &b->t1))
            return CROM_EUSAGE;
        if (!(b->t1 > b->t0))
            return crom_err(CROM_EUSAGE, "%s '%s': the window must have T1 > T0", flag, v);
    }
    return crom_parse_doubles(vec, flag, 3, b->v);
}

/* Time spent inside the window [t0, t1] up to time t. */
static double window(const crom_bc *b, double t)
{
    double e = t < b->t1 ? t : b->t1;
    return e > b->t0 ? e - b->t0 : 0;
}

void crom_bc_velocity(const crom_bc *b, double t, double v[3])
{
    int on = t >= b->t0 && t <= b->t1;
    for (int i = 0; i < 3; i++)
        v[i] = on ? b->v[i] : 0;
}

void crom_bc_displacement(const crom_bc *b, double t, double u[3])
{
    double w = window(b, t);
    for (int i = 0; i < 3; i++)
        u[i] = b->v[i] * w;
}

void crom_bc_force(const crom_bc *b, double t, double f[3])
{
    crom_bc_velocity(b, t, f);
}
