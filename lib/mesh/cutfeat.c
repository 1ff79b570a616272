/* cutfeat.c — features that let a smooth field jump across a cut
 * (see cutfeat.h). */
#include "mesh/cutfeat.h"

#include <math.h>

#include "base/err.h"

int crom_cutfeat_check(const crom_cutfeat *c)
{
    if (c->axis < 0 || c->axis > 2)
        return crom_err(CROM_EUSAGE, "the cut's axis must be x, y or z");
    if (c->nseg < 0 || c->nseg > CROM_CUTFEAT_MAX)
        return crom_err(CROM_EUSAGE, "a cut has 0 to %d segments, got %d", CROM_CUTFEAT_MAX, c->nseg);
    for (int k = 0; k < c->nseg; k++) {
        const double *s = c->seg[k];
        for (int i = 0; i < 4; i++)
            if (!isfinite(s[i]))
                return crom_err(CROM_EUSAGE, "cut segment %d has a non-finite end", k + 1);
        if (s[0] == s[2] && s[1] == s[3])
            return crom_err(CROM_EUSAGE, "cut segment %d has zero length", k + 1);
    }
    return 0;
}

/* The in-plane coordinates (u, v) of X: the other two axes in x, y, z order. */
static void in_plane(int axis, const double X[3], double *u, double *v)
{
    *u = X[axis == 0 ? 1 : 0];
    *v = X[axis == 2 ? 1 : 2];
}

void crom_cutfeat_point(const crom_cutfeat *c, const double X[3], double *f)
{
    double u, v;
    in_plane(c->axis, X, &u, &v);
    for (int k = 0; k < c->nseg; k++) {
        const double *s = c->seg[k];
        double au = s[0] - u, av = s[1] - v, bu = s[2] - u, bv = s[3] - v;
        double cr = au * bv - av * bu, dot = au * bu + av * bv;
        /* on the segment (cr == 0, dot < 0): the left side, +1 (atan2 of -0 would give -π) */
        f[k] = atan2(cr == 0 ? 0.0 : cr, dot) / M_PI;
    }
}

void crom_cutfeat_inputs_f(const crom_cutfeat *c, size_t n, const float *X, const float *S, float *in)
{
    int w = 3 + c->nseg;
    double f[CROM_CUTFEAT_MAX];
    const float *P = S ? S : X;
    for (size_t i = 0; i < n; i++) {
        double x[3] = {P[3 * i], P[3 * i + 1], P[3 * i + 2]};
        crom_cutfeat_point(c, x, f);
        float *o = in + (size_t)w * i;
        o[0] = X[3 * i];
        o[1] = X[3 * i + 1];
        o[2] = X[3 * i + 2];
        for (int k = 0; k < c->nseg; k++)
            o[3 + k] = (float)f[k];
    }
}

void crom_cutfeat_inputs_d(const crom_cutfeat *c, size_t n, const double *X, const double *S, double *in)
{
    int w = 3 + c->nseg;
    const double *P = S ? S : X;
    for (size_t i = 0; i < n; i++) {
        double *o = in + (size_t)w * i;
        o[0] = X[3 * i];
        o[1] = X[3 * i + 1];
        o[2] = X[3 * i + 2];
        crom_cutfeat_point(c, P + 3 * i, o + 3);
    }
}
