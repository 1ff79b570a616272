/* cloud.c — point samplings of bodies with no tet mesh (see cloud.h). */
#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/array.h"
#include "base/err.h"
#include "base/rng.h"
#include "mesh/cloud.h"
#include "mesh/surface.h"

void crom_cloud_free(crom_cloud *c)
{
    if (!c)
        return;
    free(c->X);
    free(c->vol);
    free(c->SV);
    free(c->ST);
    memset(c, 0, sizeof *c);
}

/* Signed solid angle of triangle (a, b, c) seen from p (Van Oosterom and
 * Strackee 1983): tan(Ω/2) = det[a b c] / (|a||b||c| + (a·b)|c| + (b·c)|a|
 * + (c·a)|b|), with a, b, c relative to p. */
static double solid_angle(const double *A, const double *B, const double *C, const double p[3])
{
    double a[3], b[3], c[3];
    for (int k = 0; k < 3; k++) {
        a[k] = A[k] - p[k];
        b[k] = B[k] - p[k];
        c[k] = C[k] - p[k];
    }
    double la = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]), lb = sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
    double lc = sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
    double det = a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0]);
    double ab = a[0] * b[0] + a[1] * b[1] + a[2] * b[2], bc = b[0] * c[0] + b[1] * c[1] + b[2] * c[2];
    double ca = c[0] * a[0] + c[1] * a[1] + c[2] * a[2];
    return 2 * atan2(det, la * lb * lc + ab * lc + bc * la + ca * lb);
}

int crom_cloud_inside(int nv, const double *V, int nt, const int *T, const double p[3])
{
    (void)nv;
    double w = 0;
    for (int t = 0; t < nt; t++)
        w += solid_angle(V + 3 * (size_t)T[3 * t], V + 3 * (size_t)T[3 * t + 1], V + 3 * (size_t)T[3 * t + 2], p);
    return fabs(w) > 2 * M_PI; /* |winding number| > 1/2 */
}

int crom_cloud_from_surface(const char *path, int n, uint64_t seed, crom_cloud *out)
{
    memset(out, 0, sizeof *out);
    if (n < 1)
        return crom_err(CROM_EUSAGE, "%d sample points: at least one is needed", n);
    crom_surface s;
    int rc = crom_surface_read(path, &s);
    if (rc)
        return rc;
    if ((rc = crom_surface_check_closed(&s, path))) {
        crom_surface_free(&s);
        return rc;
    }
    out->nsv = s.nv;
    out->SV = s.V;
    out->nst = s.nt;
    out->ST = s.T;
    double vol = 0, lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int t = 0; t < out->nst; t++) {
        const double *a = out->SV + 3 * (size_t)out->ST[3 * t], *b = out->SV + 3 * (size_t)out->ST[3 * t + 1];
        const double *c = out->SV + 3 * (size_t)out->ST[3 * t + 2];
        vol += (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
                a[2] * (b[0] * c[1] - b[1] * c[0])) / 6;
    }
    for (int v = 0; v < out->nsv; v++)
        for (int k = 0; k < 3; k++) {
            lo[k] = fmin(lo[k], out->SV[3 * (size_t)v + k]);
            hi[k] = fmax(hi[k], out->SV[3 * (size_t)v + k]);
        }
    vol = fabs(vol);
    double box = (hi[0] - lo[0]) * (hi[1] - lo[1]) * (hi[2] - lo[2]);
    if (!(vol > 1e-12 * box) || !isfinite(vol)) {
        crom_cloud_free(out);
        return crom_err(CROM_EDATA, "%s encloses no volume", path);
    }
    /* a jittered grid of about n / fill cells over the box */
    double h = cbrt(vol / n), cell[3]; /* n cells inside: n / fill over the box */
    int nc[3];
    for (int k = 0; k < 3; k++) {
        double L = hi[k] - lo[k];
        nc[k] = L > 0 ? (int)ceil(L / h) : 1;
        if (nc[k] < 1)
            nc[k] = 1;
        cell[k] = L / nc[k];
    }
    size_t ncell = (size_t)nc[0] * nc[1] * nc[2], cap = 0;
    if ((rc = crom_array_reserve((void **)&out->X, &cap, (size_t)n + n / 2 + 16, 3 * sizeof *out->X))) {
        crom_cloud_free(out);
        return rc;
    }
    crom_rng rng;
    crom_rng_seed(&rng, seed);
    for (size_t c = 0; c < ncell; c++) {
        size_t i = c % nc[0], j = (c / nc[0]) % nc[1], k = c / ((size_t)nc[0] * nc[1]);
        double p[3] = {lo[0] + (i + crom_rng_uniform(&rng)) * cell[0], lo[1] + (j + crom_rng_uniform(&rng)) * cell[1],
                       lo[2] + (k + crom_rng_uniform(&rng)) * cell[2]};
        if (!crom_cloud_inside(out->nsv, out->SV, out->nst, out->ST, p))
            continue;
        if ((rc = crom_array_reserve((void **)&out->X, &cap, (size_t)out->n + 1, 3 * sizeof *out->X))) {
            crom_cloud_free(out);
            return rc;
        }
        memcpy(out->X + 3 * (size_t)out->n++, p, sizeof p);
    }
    if (out->n == 0) {
        crom_cloud_free(out);
        return crom_err(CROM_EDATA, "%s: no sample point fell inside the surface", path);
    }
    out->vol = crom_malloc(sizeof(double) * (size_t)out->n);
    if (!out->vol) {
        crom_cloud_free(out);
        return CROM_EINTERNAL;
    }
    for (int i = 0; i < out->n; i++)
        out->vol[i] = vol / out->n;
    out->volume = vol;
    return 0;
}

int crom_cloud_read(const char *path, crom_cloud *out)
{
    memset(out, 0, sizeof *out);
    FILE *f = fopen(path, "r");
    if (!f)
        return crom_err(CROM_ENOINPUT, "%s: %s", path, strerror(errno));
    char line[1024];
    int lineno = 0, rc = 0;
    size_t cap = 0, vcap = 0;
    while (fgets(line, sizeof line, f)) {
        lineno++;
        if (!strchr(line, '\n') && !feof(f)) {
            rc = crom_err(CROM_EDATA, "%s:%d: line too long", path, lineno);
            break;
        }
        char *hash = strchr(line, '#');
        if (hash)
            *hash = 0;
        double v[5];
        int k = 0;
        char *p = line;
        for (;;) {
            while (*p && (isspace((unsigned char)*p) || *p == ','))
                p++;
            if (!*p)
                break;
            char *end;
            errno = 0;
            double d = strtod(p, &end);
            if (end == p) {
                rc = crom_err(CROM_EDATA, "%s:%d: '%.20s' is not a number", path, lineno, p);
                break;
            }
            if (k < 5)
                v[k] = d;
            k++;
            p = end;
        }
        if (rc)
            break;
        if (k == 0)
            continue;
        if (k == 3) {
            rc = crom_err(CROM_EDATA, "%s:%d: a point without a volume: a point cloud needs x y z volume on "
                          "each line", path, lineno);
            break;
        }
        if (k != 4) {
            rc = crom_err(CROM_EDATA, "%s:%d: %d numbers, expected x y z volume", path, lineno, k);
            break;
        }
        if (!isfinite(v[0]) || !isfinite(v[1]) || !isfinite(v[2]) || !isfinite(v[3]) || !(v[3] > 0)) {
            rc = crom_err(CROM_EDATA, "%s:%d: coordinates must be finite and the volume positive", path, lineno);
            break;
        }
        if ((rc = crom_array_reserve((void **)&out->X, &cap, (size_t)out->n + 1, 3 * sizeof *out->X)) ||
            (rc = crom_array_reserve((void **)&out->vol, &vcap, (size_t)out->n + 1, sizeof *out->vol)))
            break;
        memcpy(out->X + 3 * (size_t)out->n, v, sizeof(double) * 3);
        out->vol[out->n++] = v[3];
        out->volume += v[3];
    }
    fclose(f);
    if (!rc && out->n == 0)
        rc = crom_err(CROM_EDATA, "%s holds no point", path);
    if (rc)
        crom_cloud_free(out);
    return rc;
}

/* A uniformly random rotation (from a uniform unit quaternion, Shoemake). */
static void random_rotation(crom_rng *rng, double R[9])
{
    double u1 = crom_rng_uniform(rng), u2 = 2 * M_PI * crom_rng_uniform(rng), u3 = 2 * M_PI * crom_rng_uniform(rng);
    double a = sqrt(1 - u1), b = sqrt(u1);
    double w = a * sin(u2), x = a * cos(u2), y = b * sin(u3), z = b * cos(u3);
    R[0] = 1 - 2 * (y * y + z * z);
    R[1] = 2 * (x * y - z * w);
    R[2] = 2 * (x * z + y * w);
    R[3] = 2 * (x * y + z * w);
    R[4] = 1 - 2 * (x * x + z * z);
    R[5] = 2 * (y * z - x * w);
    R[6] = 2 * (x * z - y * w);
    R[7] = 2 * (y * z + x * w);
    R[8] = 1 - 2 * (x * x + y * y);
}

int crom_cloud_stencils(const crom_cloud *c, uint64_t seed, crom_mesh *m)
{
    memset(m, 0, sizeof *m);
    /* a regular tet of volume 8/3 centred at 0, positively oriented */
    static const double T0[4][3] = {{1, 1, 1}, {-1, 1, -1}, {1, -1, -1}, {-1, -1, 1}};
    m->nv = 4 * c->n;
    m->nt = c->n;
    m->X = crom_malloc(sizeof(double) * 3 * (size_t)m->nv);
    m->tets = crom_malloc(sizeof(int) * 4 * (size_t)m->nt);
    if (!m->X || !m->tets) {
        crom_mesh_free(m);
        return CROM_EINTERNAL;
    }
    crom_rng rng;
    crom_rng_seed(&rng, seed);
    for (int i = 0; i < c->n; i++) {
        if (!(c->vol[i] > 0)) {
            crom_mesh_free(m);
            return crom_err(CROM_EDATA, "point %d has volume %g", i, c->vol[i]);
        }
        double s = cbrt(3 * c->vol[i] / 8), R[9];
        random_rotation(&rng, R);
        for (int a = 0; a < 4; a++) {
            double *x = m->X + 3 * (4 * (size_t)i + a);
            for (int k = 0; k < 3; k++)
                x[k] = c->X[3 * (size_t)i + k] + s * (R[3 * k] * T0[a][0] + R[3 * k + 1] * T0[a][1] + R[3 * k + 2] * T0[a][2]);
            m->tets[4 * (size_t)i + a] = 4 * i + a;
        }
    }
    return 0;
}

int crom_cloud_pins(const crom_cloud *c, int npred, const char *const *preds, int *npin, double **pinX, int *ntri,
                    double **triX)
{
    *npin = *ntri = 0;
    *pinX = *triX = NULL;
    if (npred < 1)
        return 0;
    crom_pred *P = crom_malloc(sizeof(crom_pred) * (size_t)npred);
    double *pp = crom_malloc(sizeof(double) * 3 * (size_t)(c->n ? c->n : 1));
    double *tt = crom_malloc(sizeof(double) * 9 * (size_t)(c->nst ? c->nst : 1));
    int rc = 0;
    if (!P || !pp || !tt) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    for (int k = 0; k < npred; k++) {
        if (!crom_pred_is(preds[k])) {
            rc = crom_err(CROM_EUSAGE, "--pin %s: a surface or point cloud has no named regions; give a predicate "
                          "such as 'x<-0.49'", preds[k]);
            goto out;
        }
        if ((rc = crom_pred_parse(preds[k], &P[k])))
            goto out;
    }
    for (int k = 0; k < npred; k++) {
        int hits = 0;
        for (int i = 0; i < c->n; i++)
            hits += crom_pred_eval(&P[k], c->X + 3 * (size_t)i);
        for (int t = 0; t < c->nst; t++) {
            int all = 1;
            for (int a = 0; a < 3; a++)
                all &= crom_pred_eval(&P[k], c->SV + 3 * (size_t)c->ST[3 * t + a]);
            hits += all;
        }
        if (!hits) {
            rc = crom_err(CROM_EUSAGE, "--pin %s selects no point of the body", preds[k]);
            goto out;
        }
    }
    /* the surface's triangles inside a pin; the points of a pin that holds
     * no triangle (a cloud's, or an interior one) */
    unsigned char *bytri = crom_calloc((size_t)npred, 1);
    if (!bytri) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    for (int t = 0; t < c->nst; t++)
        for (int k = 0; k < npred; k++) {
            int all = 1;
            for (int a = 0; a < 3; a++)
                all &= crom_pred_eval(&P[k], c->SV + 3 * (size_t)c->ST[3 * t + a]);
            if (all) {
                for (int a = 0; a < 3; a++)
                    memcpy(tt + 9 * (size_t)*ntri + 3 * a, c->SV + 3 * (size_t)c->ST[3 * t + a], sizeof(double) * 3);
                (*ntri)++;
                bytri[k] = 1;
                break;
            }
        }
    for (int i = 0; i < c->n; i++)
        for (int k = 0; k < npred; k++)
            if (!bytri[k] && crom_pred_eval(&P[k], c->X + 3 * (size_t)i)) {
                memcpy(pp + 3 * (size_t)(*npin)++, c->X + 3 * (size_t)i, sizeof(double) * 3);
                break;
            }
    free(bytri);
    *pinX = pp;
    *triX = tt;
    pp = tt = NULL;
out:
    free(P);
    free(pp);
    free(tt);
    return rc;
}
