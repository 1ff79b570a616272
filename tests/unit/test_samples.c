/* test_samples.c — picking the samples of a frame (lib/rom/samples):
 * every vertex in order; distinct random vertices at their field points,
 * covering the mesh over frames and repeatable for a seed; interior points
 * uniform by volume (their mean is the body's centroid) that interpolate a
 * linear field exactly; frames appended to a sample set, also one read
 * with exactly sized arrays. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fixtures.h"
#include "base/err.h"
#include "base/rng.h"
#include "mesh/mesh.h"
#include "rom/samples.h"

/* u(X) = A X + b */
static void linear_field(const double *X, double *u)
{
    static const double A[9] = {0.01, -0.02, 0.005, 0.03, 0.0, -0.01, 0.002, 0.04, -0.03}, b[3] = {0.1, -0.2, 0.05};
    for (int c = 0; c < 3; c++)
        u[c] = A[3 * c] * X[0] + A[3 * c + 1] * X[1] + A[3 * c + 2] * X[2] + b[c];
}

int main(void)
{
    check_begin("test_samples");
    crom_rng rng;
    crom_rng_seed(&rng, 31);
    crom_mesh m;
    double lo[3] = {-0.5, -0.25, 0};
    fx_box_mesh(&m, 4, 2, 2, lo, 0.25, 0.2, &rng, NULL); /* [-0.5, 0.5] x [-0.25, 0.25] x [0, 0.5] */
    int nv = m.nv;
    double *u = malloc(sizeof(double) * 3 * (size_t)nv);
    for (int v = 0; v < nv; v++)
        linear_field(m.X + 3 * v, u + 3 * v);
    float *X = malloc(sizeof(float) * 3 * 20000), *U = malloc(sizeof(float) * 3 * 20000);
    int *vx = malloc(sizeof(int) * 20000);

    /* all: every vertex in order, at its position, with its displacement */
    crom_samples_picker p;
    CHECK(crom_samples_picker_init(&p, &m, CROM_SAMPLES_ALL) == 0);
    crom_samples_pick(&p, nv, u, &rng, X, U, vx);
    int ok = 1;
    for (int v = 0; v < nv; v++)
        for (int d = 0; d < 3; d++)
            ok &= vx[v] == v && X[3 * v + d] == (float)m.X[3 * v + d] && U[3 * v + d] == (float)u[3 * v + d];
    CHECK(ok);
    crom_samples_picker_free(&p);

    /* vertices: N distinct ones per frame; over 30 frames of nv/2 every
     * vertex is drawn (each is missed with probability 2^-30) */
    int N = nv / 2, *seen = calloc((size_t)nv, sizeof(int));
    CHECK(crom_samples_picker_init(&p, &m, CROM_SAMPLES_VERTICES) == 0);
    int distinct = 1, placed = 1;
    for (int f = 0; f < 30; f++) {
        crom_samples_pick(&p, N, u, &rng, X, U, vx);
        int *mark = calloc((size_t)nv, sizeof(int));
        for (int i = 0; i < N; i++) {
            distinct &= vx[i] >= 0 && vx[i] < nv && !mark[vx[i]];
            mark[vx[i]] = 1;
            seen[vx[i]]++;
            for (int d = 0; d < 3; d++)
                placed &= X[3 * i + d] == (float)m.X[3 * vx[i] + d] && U[3 * i + d] == (float)u[3 * vx[i] + d];
        }
        free(mark);
    }
    int all_seen = 1;
    for (int v = 0; v < nv; v++)
        all_seen &= seen[v] > 0;
    CHECK(distinct && placed && all_seen);
    crom_samples_picker_free(&p);
    /* the same seed picks the same vertices */
    int first[64], again[64];
    for (int rep = 0; rep < 2; rep++) {
        crom_rng r2;
        crom_rng_seed(&r2, 5);
        CHECK(crom_samples_picker_init(&p, &m, CROM_SAMPLES_VERTICES) == 0);
        crom_samples_pick(&p, N, u, &r2, X, U, rep ? again : first);
        crom_samples_picker_free(&p);
    }
    CHECK(!memcmp(first, again, sizeof(int) * (size_t)N));

    /* interior: vertex -1, inside the box, u interpolated exactly (a linear
     * field), and uniform by volume: the mean of 20000 points is the box's
     * centre within 4 standard errors (side / sqrt(12 n)) */
    CHECK(crom_samples_picker_init(&p, &m, CROM_SAMPLES_INTERIOR) == 0);
    int n = 20000;
    crom_samples_pick(&p, n, u, &rng, X, U, vx);
    double mean[3] = {0, 0, 0}, side[3] = {1, 0.5, 0.5}, centre[3] = {0, 0, 0.25}, uerr = 0;
    int inside = 1, minus = 1;
    for (int i = 0; i < n; i++) {
        double x[3] = {X[3 * i], X[3 * i + 1], X[3 * i + 2]}, ue[3];
        linear_field(x, ue);
        for (int d = 0; d < 3; d++) {
            mean[d] += x[d] / n;
            inside &= fabs(x[d] - centre[d]) <= side[d] / 2 + 1e-6;
            uerr = fmax(uerr, fabs(U[3 * i + d] - ue[d]));
        }
        minus &= vx[i] == -1;
    }
    CHECK(inside && minus);
    CHECK_LT(uerr, 1e-6); /* float32 rounding of X and U */
    for (int d = 0; d < 3; d++)
        CHECK_NEAR(mean[d], centre[d], 4 * side[d] / sqrt(12.0 * n));

    /* frames appended to a set: grown, tagged, contents kept; also onto a
     * set whose arrays are exactly sized (as read from a file, cap 0) */
    crom_samples S;
    memset(&S, 0, sizeof S);
    S.N = 5;
    for (int f = 0; f < 40; f++)
        CHECK(crom_samples_add_frame(&S, &p, u, &rng, f % 3, 0.01 * f) == 0);
    CHECK(S.F == 40 && S.cap == 64 && S.source[39] == 0 && S.source[38] == 2 && S.time[39] == 0.01 * 39);
    float keep = S.U[3 * 5 * 17 + 4];
    crom_samples R;
    memset(&R, 0, sizeof R);
    R.N = 5;
    R.F = 40;
    R.X = malloc(sizeof(float) * 3 * 5 * 40);
    R.U = malloc(sizeof(float) * 3 * 5 * 40);
    R.vertex = malloc(sizeof(int) * 5 * 40);
    R.source = malloc(sizeof(int) * 40);
    R.time = malloc(sizeof(double) * 40);
    memcpy(R.X, S.X, sizeof(float) * 3 * 5 * 40);
    memcpy(R.U, S.U, sizeof(float) * 3 * 5 * 40);
    memcpy(R.time, S.time, sizeof(double) * 40);
    CHECK(crom_samples_add_frame(&R, &p, u, &rng, 7, 1.5) == 0);
    CHECK(R.F == 41 && R.cap == 41 && R.source[40] == 7 && R.time[40] == 1.5 && R.U[3 * 5 * 17 + 4] == keep &&
          R.time[39] == S.time[39]);
    crom_samples_picker_free(&p);
    crom_samples_free(&S);
    crom_samples_free(&R);
    free(u);
    free(X);
    free(U);
    free(vx);
    free(seen);
    crom_mesh_free(&m);
    return check_done();
}
