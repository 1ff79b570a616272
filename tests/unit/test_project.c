/* test_project.c — the mass-weighted projection onto a linear basis
 * (lib/rom/project): weights are the lumped vertex volumes over the total,
 * a field in the span comes back exactly, any field's residual is
 * M-orthogonal to the basis (the normal equations), the norms are the
 * weighted sums, and a basis with a field that vanishes on the mesh is
 * refused. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fixtures.h"
#include "base/err.h"
#include "base/rng.h"
#include "mesh/mesh.h"
#include "rom/model.h"
#include "rom/project.h"

int main(void)
{
    check_begin("test_project");
    crom_rng rng;
    crom_rng_seed(&rng, 21);
    crom_mesh m;
    double lo[3] = {-0.5, -0.25, -0.25};
    fx_box_mesh(&m, 6, 3, 3, lo, 1.0 / 6, 0.2, &rng, NULL);
    int r = 3, nv = m.nv;
    size_t n3 = 3 * (size_t)nv;
    /* a linear basis stored on the mesh: field j, component c is
     * (j + 1) X_c + (c - j) X_{c+1} + 0.1 j² (independent fields) */
    double *B = malloc(sizeof(double) * n3 * r);
    for (int v = 0; v < nv; v++)
        for (int c = 0; c < 3; c++)
            for (int j = 0; j < r; j++)
                B[((size_t)v * 3 + c) * r + j] =
                    (j + 1) * m.X[3 * v + c] + (c - j) * m.X[3 * v + (c + 1) % 3] + 0.1 * j * j;
    crom_model M;
    CHECK(crom_model_from_mesh(&M, "pod", &m, B, r) == 0);
    crom_project P;
    size_t nout = 7;
    CHECK(crom_project_init(&P, &M, &m, &nout) == 0);
    CHECK(nout == 0 && P.nv == nv && P.r == r);

    /* the weights: lumped vertex volumes (Σ_t V_t/4 over the tets at v) over
     * the mesh's volume, summing to 1 */
    double *vv = calloc((size_t)nv, sizeof(double)), total = 0, wsum = 0, werr = 0;
    for (int t = 0; t < m.nt; t++) {
        const int *T = m.tets + 4 * (size_t)t;
        double V = crom_mesh_tet_volume(m.X + 3 * T[0], m.X + 3 * T[1], m.X + 3 * T[2], m.X + 3 * T[3]);
        total += V;
        for (int k = 0; k < 4; k++)
            vv[T[k]] += V / 4;
    }
    for (int v = 0; v < nv; v++) {
        wsum += P.w[v];
        werr = fmax(werr, fabs(P.w[v] - vv[v] / total));
    }
    CHECK_NEAR(wsum, 1, 1e-13);
    CHECK_LT(werr, 1e-15);
    CHECK(check_relerr(P.W, B, (int)(n3 * r), 1e-30) < 1e-12); /* W at the (uncut) vertices */

    /* a field in the span: f = W q0 gives q0 back, with no residual */
    double q0[3] = {0.02, -0.05, 0.013}, q[3], e2, f2;
    double *f = malloc(sizeof(double) * n3);
    for (size_t i = 0; i < n3; i++)
        f[i] = B[i * r] * q0[0] + B[i * r + 1] * q0[1] + B[i * r + 2] * q0[2];
    crom_project_apply(&P, f, q);
    CHECK(check_relerr(q, q0, 3, 1e-30) < 1e-9);
    crom_project_residual(&P, f, q, &e2, &f2);
    double f2hand = 0;
    for (size_t i = 0; i < n3; i++)
        f2hand += P.w[i / 3] * f[i] * f[i];
    CHECK_NEAR(f2, f2hand, 1e-15 * f2hand);
    CHECK_LT(e2, 1e-18 * f2);

    /* any field: the residual W q − f is orthogonal to the basis in the
     * weighted inner product, Σ_v w_v W_vᵀ (W_v q − f_v) = 0 */
    for (size_t i = 0; i < n3; i++)
        f[i] = 0.01 * (2 * crom_rng_uniform(&rng) - 1);
    crom_project_apply(&P, f, q);
    double g[3] = {0, 0, 0}, b[3] = {0, 0, 0};
    for (size_t i = 0; i < n3; i++) {
        double s = -f[i];
        for (int j = 0; j < r; j++)
            s += B[i * r + j] * q[j];
        for (int j = 0; j < r; j++) {
            g[j] += P.w[i / 3] * B[i * r + j] * s;
            b[j] += fabs(P.w[i / 3] * B[i * r + j] * f[i]);
        }
    }
    for (int j = 0; j < r; j++)
        CHECK_MSG(fabs(g[j]) < 1e-12 * b[j], "normal equation %d: %.3g (scale %.3g)", j, g[j], b[j]);
    /* and the residual's norm is f's minus the projection's (Pythagoras) */
    crom_project_residual(&P, f, q, &e2, &f2);
    double p2 = 0;
    for (size_t i = 0; i < n3; i++) {
        double s = 0;
        for (int j = 0; j < r; j++)
            s += B[i * r + j] * q[j];
        p2 += P.w[i / 3] * s * s;
    }
    CHECK_NEAR(e2, f2 - p2, 1e-12 * f2);
    crom_project_free(&P);
    CHECK(P.W == NULL && P.L == NULL);
    crom_model_free(&M);

    /* a basis with a field that vanishes on the mesh is refused, and p is
     * left empty */
    for (int v = 0; v < nv; v++)
        for (int c = 0; c < 3; c++)
            B[((size_t)v * 3 + c) * r + 2] = 0;
    CHECK(crom_model_from_mesh(&M, "pod", &m, B, r) == 0);
    CHECK(crom_project_init(&P, &M, &m, NULL) == CROM_EDATA);
    CHECK(strstr(crom_errmsg(), "cannot project") != NULL);
    CHECK(P.W == NULL && P.w == NULL && P.L == NULL && P.wf == NULL);
    crom_model_free(&M);
    free(B);
    free(f);
    free(vv);
    crom_mesh_free(&m);
    return check_done();
}
