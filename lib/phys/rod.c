/* rod.c — springs with a rest length that follows a sinusoid (see rod.h). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "base/parse.h"
#include "phys/rod.h"

int crom_rod_parse(const char *flag, const char *v, crom_rod *r)
{
    memset(r, 0, sizeof *r);
    const char *eq = strrchr(v, '='), *sl = strchr(v, '/');
    if (!eq || !sl || sl > eq)
        return crom_err(CROM_EUSAGE, "%s '%s': expected A/B=K,L0[,AMP,PERIOD[,PHASE]] (two ends, a stiffness and "
                        "a rest length)", flag, v);
    size_t la = (size_t)(sl - v), lb = (size_t)(eq - sl - 1);
    if (la == 0 || lb == 0)
        return crom_err(CROM_EUSAGE, "%s '%s': an end is empty", flag, v);
    if (la >= sizeof r->a || lb >= sizeof r->b)
        return crom_err(CROM_EUSAGE, "%s: an end is longer than %zu characters", flag, sizeof r->a - 1);
    memcpy(r->a, v, la);
    memcpy(r->b, sl + 1, lb);
    /* K, L0 ("rest" or a length), then the optional sinusoid */
    char nums[256];
    if (strlen(eq + 1) >= sizeof nums)
        return crom_err(CROM_EUSAGE, "%s: the numbers after '=' are too long", flag);
    strcpy(nums, eq + 1);
    char *c = strchr(nums, ',');
    if (!c)
        return crom_err(CROM_EUSAGE, "%s '%s': expected K,L0 after '='", flag, v);
    *c++ = 0;
    char *rest = strchr(c, ',');
    if (rest)
        *rest++ = 0;
    if (crom_parse_double(nums, flag, &r->k))
        return CROM_EUSAGE;
    if (!(r->k > 0 && r->k <= 1e15))
        return crom_err(CROM_EUSAGE, "%s: the stiffness must be positive (N/m, at most 1e15), got %g", flag, r->k);
    if (!strcmp(c, "rest"))
        r->L0 = NAN;
    else if (crom_parse_double(c, flag, &r->L0))
        return CROM_EUSAGE;
    else if (!(r->L0 >= 0 && r->L0 <= 1e6))
        return crom_err(CROM_EUSAGE, "%s: the rest length must be in [0, 1e6] m or 'rest', got %g", flag, r->L0);
    if (!rest)
        return 0;
    double d[3] = {0, 0, 0};
    int n;
    if (crom_parse_doubles_var(rest, flag, 2, 3, d, &n))
        return CROM_EUSAGE;
    r->amp = d[0];
    r->period = d[1];
    r->phase = d[2];
    if (!(fabs(r->amp) <= 1e6))
        return crom_err(CROM_EUSAGE, "%s: the amplitude must be at most 1e6 m, got %g", flag, r->amp);
    if (!(r->period > 0 && r->period <= 1e9))
        return crom_err(CROM_EUSAGE, "%s: the period must be positive (s), got %g", flag, r->period);
    if (!(fabs(r->phase) <= 1e6))
        return crom_err(CROM_EUSAGE, "%s: the phase must be a finite angle in radians, got %g", flag, r->phase);
    return 0;
}

int crom_rod_format(const crom_rod *r, char *buf, int cap)
{
    char L0[32];
    if (isnan(r->L0))
        strcpy(L0, "rest");
    else
        snprintf(L0, sizeof L0, "%.17g", r->L0);
    if (r->amp == 0 && r->period == 0)
        return snprintf(buf, (size_t)cap, "%s/%s=%.17g,%s", r->a, r->b, r->k, L0);
    return snprintf(buf, (size_t)cap, "%s/%s=%.17g,%s,%.17g,%.17g,%.17g", r->a, r->b, r->k, L0, r->amp, r->period,
                    r->phase);
}

double crom_rod_length(const crom_rod *r, double rest, double t)
{
    double L = isnan(r->L0) ? rest : r->L0;
    if (r->amp != 0)
        L += r->amp * sin(2 * M_PI * t / r->period + r->phase);
    return L;
}

double crom_rod_eval(double k, double L, const double d[3], double g[3], double H[9], int project)
{
    double l = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    double n[3] = {1, 0, 0};
    if (l > 0)
        for (int i = 0; i < 3; i++)
            n[i] = d[i] / l;
    double s = l - L;
    if (g)
        for (int i = 0; i < 3; i++)
            g[i] = k * s * n[i];
    if (H) {
        /* k [n nᵀ + (1 − L/ℓ)(I − n nᵀ)]; at ℓ = 0 the transverse part is unbounded: take it 0 */
        double t = l > 0 ? 1 - L / l : 0;
        if (project && t < 0)
            t = 0;
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++)
                H[3 * i + j] = k * ((1 - t) * n[i] * n[j] + (i == j ? t : 0));
    }
    return 0.5 * k * s * s;
}

void crom_rod_set_free(crom_rod_set *R)
{
    if (!R)
        return;
    free(R->ptr);
    free(R->idx);
    free(R->w);
    free(R->rest);
    memset(R, 0, sizeof *R);
}

int crom_rod_set_init(crom_rod_set *R, int n, const crom_rod *rods, const crom_mesh *m, const double *mass)
{
    memset(R, 0, sizeof *R);
    R->n = n;
    R->ptr = crom_calloc((size_t)2 * n + 1, sizeof(int));
    R->rest = crom_calloc((size_t)n + 1, sizeof(double));
    if (!R->ptr || !R->rest) {
        crom_rod_set_free(R);
        return CROM_EINTERNAL;
    }
    int total = 0;
    for (int e = 0; e < 2 * n; e++) {
        const char *ref = e % 2 ? rods[e / 2].b : rods[e / 2].a;
        int *v, nv, rc = crom_mesh_select(m, ref, &v, &nv);
        if (rc) {
            crom_err_ctx("--rod");
            crom_rod_set_free(R);
            return rc;
        }
        int *ni = crom_realloc(R->idx, sizeof(int) * (size_t)(total + nv));
        double *nw = ni ? crom_realloc(R->w, sizeof(double) * (size_t)(total + nv)) : NULL;
        if (ni)
            R->idx = ni;
        if (nw)
            R->w = nw;
        if (!ni || !nw) {
            free(v);
            crom_rod_set_free(R);
            return CROM_EINTERNAL;
        }
        double me = 0;
        for (int i = 0; i < nv; i++)
            me += mass[v[i]];
        if (!(me > 0)) {
            free(v);
            crom_rod_set_free(R);
            return crom_err(CROM_EUSAGE, "--rod: end '%s' has no mass", ref);
        }
        for (int i = 0; i < nv; i++) {
            R->idx[total + i] = v[i];
            R->w[total + i] = (e % 2 ? 1 : -1) * mass[v[i]] / me;
        }
        free(v);
        total += nv;
        R->ptr[e + 1] = total;
    }
    for (int k = 0; k < n; k++) {
        double d[3];
        crom_rod_set_gap(R, k, m->X, d);
        R->rest[k] = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    }
    return 0;
}

void crom_rod_set_gap(const crom_rod_set *R, int k, const double *x, double d[3])
{
    d[0] = d[1] = d[2] = 0;
    for (int j = R->ptr[2 * k]; j < R->ptr[2 * k + 2]; j++)
        for (int c = 0; c < 3; c++)
            d[c] += R->w[j] * x[3 * (size_t)R->idx[j] + c];
}

double crom_rod_set_eval(const crom_rod_set *R, const crom_rod *rods, double t, const double *x, double *g, double *Hd,
                      int project)
{
    double E = 0;
    for (int k = 0; k < R->n; k++) {
        double d[3], gd[3];
        crom_rod_set_gap(R, k, x, d);
        E += crom_rod_eval(rods[k].k, crom_rod_length(&rods[k], R->rest[k], t), d, gd, Hd ? Hd + 9 * k : NULL,
                           project);
        for (int j = R->ptr[2 * k]; g && j < R->ptr[2 * k + 2]; j++)
            for (int c = 0; c < 3; c++)
                g[3 * (size_t)R->idx[j] + c] += R->w[j] * gd[c];
    }
    return E;
}

void crom_rod_set_matvec(const crom_rod_set *R, const double *Hd, const unsigned char *fixed, const double *x, double *y)
{
    for (int k = 0; k < R->n; k++) {
        double dx[3] = {0, 0, 0}, hd[3];
        for (int j = R->ptr[2 * k]; j < R->ptr[2 * k + 2]; j++)
            for (int c = 0; c < 3; c++) {
                size_t i = 3 * (size_t)R->idx[j] + c;
                if (!fixed || !fixed[i])
                    dx[c] += R->w[j] * x[i];
            }
        for (int a = 0; a < 3; a++)
            hd[a] = Hd[9 * k + 3 * a] * dx[0] + Hd[9 * k + 3 * a + 1] * dx[1] + Hd[9 * k + 3 * a + 2] * dx[2];
        for (int j = R->ptr[2 * k]; j < R->ptr[2 * k + 2]; j++)
            for (int c = 0; c < 3; c++) {
                size_t i = 3 * (size_t)R->idx[j] + c;
                if (!fixed || !fixed[i])
                    y[i] += R->w[j] * hd[c];
            }
    }
}
