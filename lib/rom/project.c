/* project.c — mass-weighted least-squares projection onto a linear basis
 * (see project.h). */
#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <cblas.h>

#include "base/err.h"
#include "rom/project.h"

/* G = Σ_v w_v W_vᵀ W_v (as (√w W)ᵀ(√w W)), regularized by 1e-13 of its
 * mean diagonal, and its Cholesky factor into p->L. */
static int factor_gram(crom_project *p)
{
    int r = p->r;
    size_t n3 = 3 * (size_t)p->nv;
    double *sW = crom_malloc(sizeof(double) * n3 * r);
    if (!sW)
        return CROM_EINTERNAL;
    for (size_t i = 0; i < n3; i++) {
        double s = sqrt(p->w[i / 3]);
        for (int j = 0; j < r; j++)
            sW[i * r + j] = s * p->W[i * r + j];
    }
    cblas_dsyrk(CblasRowMajor, CblasUpper, CblasTrans, r, (int)n3, 1.0, sW, r, 0.0, p->L, r);
    free(sW);
    double tr = 0, dmin = INFINITY;
    for (int a = 0; a < r; a++) {
        tr += p->L[a * r + a];
        dmin = fmin(dmin, p->L[a * r + a]);
    }
    if (!(tr > 0) || !(dmin > 1e-10 * tr / r))
        return crom_err(CROM_EDATA, "the basis is (nearly) zero on part of its span at this mesh's "
                                    "vertices: cannot project onto it");
    for (int a = 0; a < r; a++)
        p->L[a * r + a] += 1e-13 * tr / r;
    if (LAPACKE_dpotrf_work(LAPACK_COL_MAJOR, 'L', r, p->L, r) != 0)
        return crom_err(CROM_EDATA, "the basis is rank-deficient at this mesh's vertices: cannot "
                                    "project onto it");
    return 0;
}

int crom_project_init(crom_project *p, const crom_model *model, const crom_mesh *mesh, size_t *noutside)
{
    memset(p, 0, sizeof *p);
    p->nv = mesh->nv;
    p->r = model->rank;
    size_t n3 = 3 * (size_t)mesh->nv, nout = 0;
    int r = p->r, rc = 0;
    p->W = crom_malloc(sizeof(double) * n3 * r);
    p->w = crom_malloc(sizeof(double) * (size_t)mesh->nv);
    p->L = crom_calloc((size_t)r * r, sizeof(double));
    p->wf = crom_malloc(sizeof(double) * n3);
    if (!p->W || !p->w || !p->L || !p->wf)
        rc = CROM_EINTERNAL;
    if (!rc) /* see crom_mesh_field_points */
        rc = crom_model_eval_mesh(model, mesh, CROM_MESH_CRACK_OFFSET, p->W, &nout, NULL);
    if (!rc) {
        double vol = crom_mesh_vertex_volumes(mesh, p->w);
        for (int v = 0; v < mesh->nv; v++)
            p->w[v] /= vol;
        rc = factor_gram(p);
    }
    if (rc)
        crom_project_free(p);
    else if (noutside)
        *noutside = nout;
    return rc;
}

void crom_project_apply(crom_project *p, const double *f, double *q)
{
    size_t n3 = 3 * (size_t)p->nv;
    for (size_t i = 0; i < n3; i++)
        p->wf[i] = p->w[i / 3] * f[i];
    cblas_dgemv(CblasRowMajor, CblasTrans, (int)n3, p->r, 1.0, p->W, p->r, p->wf, 1, 0.0, q, 1);
    LAPACKE_dpotrs_work(LAPACK_COL_MAJOR, 'L', p->r, 1, p->L, p->r, q, p->r);
}

void crom_project_residual(const crom_project *p, const double *f, const double *q, double *e2, double *f2)
{
    double e = 0, n = 0;
    for (size_t i = 0; i < 3 * (size_t)p->nv; i++) {
        double s = -f[i];
        const double *W = p->W + i * p->r;
        for (int j = 0; j < p->r; j++)
            s += W[j] * q[j];
        e += p->w[i / 3] * s * s;
        n += p->w[i / 3] * f[i] * f[i];
    }
    *e2 = e;
    *f2 = n;
}

void crom_project_free(crom_project *p)
{
    free(p->W);
    free(p->w);
    free(p->L);
    free(p->wf);
    memset(p, 0, sizeof *p);
}
