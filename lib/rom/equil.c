/* equil.c — constrained equilibria around the solver (see equil.h). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "io/io.h"
#include "phys/modes.h"
#include "rom/equil.h"
#include "rom/result.h"

int crom_equil_modes(const crom_model *model, const crom_mesh *m, crom_map *map, double **W)
{
    *W = NULL;
    memset(map, 0, sizeof *map);
    int nm = !strcmp(model->basis, "neuralmodes"), rc;
    if (!nm && strcmp(model->basis, "modes"))
        return crom_err(CROM_EUSAGE, "model %s is a '%s' model; the constrained equilibria are taken in linear "
                        "vibration modes (crom-modes, or a neuralmodes map)", model->model_id, model->basis);
    /* the modes on their own mesh when it is this one (exactly, with zeros
     * at the pins), else interpolated onto it (linear modes only) */
    if ((rc = crom_map_init(map, model, NULL)))
        return rc;
    if (!nm && crom_map_same_mesh(&map->mesh, m)) {
        crom_map_free(map);
        if ((rc = crom_map_init(map, model, m)))
            return rc;
    }
    if (nm && crom_map_same_mesh(&map->mesh, m))
        return crom_err(CROM_EUSAGE, "the neuralmodes map %s lives on another mesh", model->model_id);
    int r = map->r, n = map->n;
    if (map->nonlinear ? map->rl != r : map->p != r)
        return crom_err(CROM_EINTERNAL, "the model's map has no linear part");
    if (!(*W = crom_malloc(sizeof(double) * (size_t)n * r)))
        return CROM_EINTERNAL;
    for (int i = 0; i < n; i++)
        for (int k = 0; k < r; k++)
            (*W)[(size_t)i * r + k] = map->B[(size_t)i * map->p + k];
    return 0;
}

int crom_equil_box(const crom_model *model, const crom_mesh *m, double box, int scaling, double *half, double *A,
                   int *scaled)
{
    int nm = !strcmp(model->basis, "neuralmodes"), r = model->rank;
    *A = box > 0 ? box : nm && model->latent_box > 0 ? model->latent_box : 0.2 * crom_mesh_points_diagonal(m->X, m->nv);
    *scaled = scaling >= 0 ? scaling : nm && model->latent_box_scaled;
    if (*scaled && !model->frequencies)
        return crom_err(CROM_EUSAGE, "frequency box scaling: model %s records no frequencies", model->model_id);
    for (int k = 0; k < r; k++)
        half[k] = *scaled ? crom_modes_box_half(model->frequencies, r, *A, k) : *A;
    return 0;
}

int crom_equil_latents(const char *path, int r, double **Z, long *count)
{
    crom_in in;
    double *all = NULL;
    long nf = 0;
    *Z = NULL;
    *count = 0;
    int rc = crom_in_open(&in, path), fq = -1;
    int frame = 0; /* a run with a rigid frame (crom-reducedstep --rigid-frame): q = [q' | θ | t], q' kept */
    if (rc)
        return rc;
    if (!(rc = crom_in_expect(&in, "crom/latent", 1)))
        rc = crom_result_latent_frame(in.h5, &frame);
    if (!rc && (fq = crom_in_field(&in, "q")) >= 0 && in.fields[fq].count != (size_t)r + (frame ? 6 : 0))
        rc = crom_err(CROM_EUSAGE, "%s has %zu latent coordinates, the model's rank is %d%s", in.name,
                      in.fields[fq].count, r, frame ? " (+ 6 of its rigid frame)" : "");
    if (!rc && fq < 0)
        rc = CROM_EDATA;
    if (!rc)
        rc = crom_in_read_all(&in, &all, &nf);
    if (!rc && nf < 1)
        rc = crom_err(CROM_EDATA, "%s has no frame", in.name);
    if (!rc && !(*Z = crom_malloc(sizeof(double) * (size_t)nf * r)))
        rc = CROM_EINTERNAL;
    for (long k = 0; !rc && k < nf; k++) {
        const double *q = all + (size_t)k * in.frame_len + in.fields[fq].offset;
        for (int d = 0; d < r && !rc; d++)
            if (!isfinite(q[d]))
                rc = crom_err(CROM_EDATA, "%s: frame %ld has a non-finite q", in.name, k);
        if (!rc)
            memcpy(*Z + (size_t)k * r, q, sizeof(double) * (size_t)r);
    }
    if (!rc) {
        *count = nf;
    } else {
        free(*Z);
        *Z = NULL;
    }
    free(all);
    crom_in_close(&in);
    return rc;
}

void crom_equil_point(int grid, int r, const double *half, const double *Z, long k, crom_rng *rng, double *z)
{
    if (Z) {
        memcpy(z, Z + (size_t)k * r, sizeof(double) * (size_t)r);
        return;
    }
    for (int d = r - 1; d >= 0; d--) {
        if (grid) {
            long i = k % grid;
            k /= grid;
            z[d] = half[d] * (-1 + 2.0 * (double)i / (grid - 1));
        } else {
            z[d] = half[d] * (2 * crom_rng_uniform(rng) - 1);
        }
    }
}

int crom_equil_solve(crom_cequil *ce, const double *X, const double *W, const double *z, const double *xprev,
                     int prev_first, double *x, double *lam, crom_cequil_stats *st)
{
    int n = ce->n, r = ce->r, rc = 0;
    char first[400] = "";
    prev_first = prev_first && xprev;
    for (int attempt = 0; attempt < 2; attempt++) {
        int from_prev = attempt ? !prev_first : prev_first;
        if (from_prev && !xprev)
            break;
        if (from_prev) {
            memcpy(x, xprev, sizeof(double) * (size_t)n);
        } else {
            for (int i = 0; i < n; i++) {
                x[i] = X[i];
                for (int d = 0; d < r; d++)
                    x[i] += W[(size_t)i * r + d] * z[d];
            }
        }
        if ((rc = crom_cequil_solve(ce, z, x, lam, st)) != CROM_EDATA)
            return rc;
        const char *from = from_prev ? "the previous equilibrium" : "X + W z";
        if (attempt == 0) {
            snprintf(first, sizeof first, "from %s: %s", from, crom_errmsg());
            crom_err_clear();
        } else {
            return crom_err(rc, "%s; from %s: %s", first, from, crom_errmsg());
        }
    }
    return crom_err(rc, "%s", first);
}
