/* test_keyframe.c — in-betweens of latent keyframes (rom/keyframe.h):
 *   - both interpolations pass through every key exactly and stay in the
 *     keys' box when linear; the Catmull–Rom spline is C¹ at interior keys
 *     (one-sided difference quotients agree to O(ε)) and reproduces keys
 *     on a line exactly between interior keys, with the segment's
 *     parameter clamped outside [0, K−1];
 *   - on a linear basis (a pod model of a box), the energy of the decoded
 *     latent is the system's energy of X + W q, and equals the energy of
 *     interpolated positions at every s of a linear interpolation (x is
 *     linear in q), but not of a cubic one between three keys;
 *   - fewer than two keys or a non-finite key is refused. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "base/rng.h"
#include "check.h"
#include "fixtures.h"
#include "rom/keyframe.h"

static void test_latent(void)
{
    enum { K = 5, R = 3 };
    double keys[K * R], q[R], a[R], b[R];
    crom_rng rng;
    crom_rng_seed(&rng, 7);
    for (int i = 0; i < K * R; i++)
        keys[i] = crom_rng_uniform(&rng) * 2 - 1;
    for (int interp = 0; interp < 2; interp++)
        for (int k = 0; k < K; k++) {
            crom_keyframe_latent(K, R, keys, interp, k, q);
            for (int i = 0; i < R; i++)
                CHECK(q[i] == keys[k * R + i]);
        }
    /* linear: the midpoint, and within the two keys' box */
    crom_keyframe_latent(K, R, keys, CROM_KEYFRAME_LINEAR, 1.5, q);
    for (int i = 0; i < R; i++)
        CHECK_NEAR(q[i], 0.5 * (keys[R + i] + keys[2 * R + i]), 1e-15);
    /* cubic: C¹ at the interior keys */
    double h = 1e-6, worst = 0;
    for (int k = 1; k < K - 1; k++) {
        crom_keyframe_latent(K, R, keys, CROM_KEYFRAME_CUBIC, k - h, a);
        crom_keyframe_latent(K, R, keys, CROM_KEYFRAME_CUBIC, k + h, b);
        for (int i = 0; i < R; i++) {
            double left = (keys[k * R + i] - a[i]) / h, right = (b[i] - keys[k * R + i]) / h;
            double tangent = 0.5 * (keys[(k + 1) * R + i] - keys[(k - 1) * R + i]);
            worst = fmax(worst, fmax(fabs(left - tangent), fabs(right - tangent)));
        }
    }
    CHECK_LT(worst, 1e-5);
    /* keys on a line: the spline is the line between interior keys */
    double line[K * R];
    for (int k = 0; k < K; k++)
        for (int i = 0; i < R; i++)
            line[k * R + i] = 0.3 * i - 0.7 + (0.25 + i) * k;
    for (double s = 1; s <= K - 2; s += 0.125) {
        crom_keyframe_latent(K, R, line, CROM_KEYFRAME_CUBIC, s, q);
        for (int i = 0; i < R; i++)
            CHECK_NEAR(q[i], 0.3 * i - 0.7 + (0.25 + i) * s, 1e-14);
    }
    /* clamped outside [0, K−1], NaN to the first key */
    crom_keyframe_latent(K, R, keys, CROM_KEYFRAME_CUBIC, 10, q);
    CHECK(q[0] == keys[(K - 1) * R]);
    crom_keyframe_latent(K, R, keys, CROM_KEYFRAME_LINEAR, NAN, q);
    CHECK(q[0] == keys[0]);
}

static void test_energies(void)
{
    crom_mesh m;
    crom_rng rng;
    crom_rng_seed(&rng, 3);
    const double lo[3] = {0, 0, 0};
    fx_box_mesh(&m, 4, 2, 2, lo, 0.25, 0, &rng, NULL);
    enum { R = 2 };
    size_t n = 3 * (size_t)m.nv;
    double *W = malloc(sizeof(double) * n * R);
    for (int v = 0; v < m.nv; v++) { /* bending and twisting fields */
        const double *X = m.X + 3 * v;
        for (int c = 0; c < 3; c++) {
            W[(3 * (size_t)v + c) * R + 0] = c == 1 ? X[0] * X[0] : 0;
            W[(3 * (size_t)v + c) * R + 1] = c == 1 ? -X[0] * (X[2] - 0.25) : c == 2 ? X[0] * (X[1] - 0.25) : 0;
        }
    }
    crom_model M;
    CHECK(crom_model_from_mesh(&M, "pod", &m, W, R) == 0);
    crom_scenario sc;
    crom_scenario_defaults(&sc);
    sc.youngs = 1e5;
    const double keys[] = {0.3, 0, -0.2, 0.5, 0.1, -0.4};
    crom_keyframe k;
    for (int interp = 0; interp < 2; interp++) {
        CHECK(crom_keyframe_init(&k, &M, NULL, &sc, 3, keys, interp) == 0);
        double worst = 0, gap = 0, q[R], El, Ep;
        for (double s = 0; s <= 2; s += 0.1) {
            CHECK(crom_keyframe_eval(&k, s, q, &El, &Ep) == 0);
            worst = fmax(worst, fabs(El - Ep) / fmax(El, 1e-30));
            gap = fmax(gap, fabs(El - Ep) / El);
        }
        if (interp == CROM_KEYFRAME_LINEAR)
            CHECK_LT(worst, 1e-9);
        else
            CHECK_LT(1e-3, gap);
        /* the energy is the system's at X + W q */
        CHECK(crom_keyframe_eval(&k, 1.3, q, &El, NULL) == 0);
        double *x = malloc(sizeof(double) * n), E;
        for (size_t i = 0; i < n; i++)
            x[i] = m.X[i] + W[i * R] * q[0] + W[i * R + 1] * q[1];
        crom_system sys;
        CHECK(crom_system_init(&sys, &m, sc.youngs, sc.poisson, sc.density) == 0);
        CHECK(crom_system_energy(&sys, x, &E) == 0);
        CHECK_REL(El, E, 1e-12);
        CHECK_LT(0, E);
        crom_system_free(&sys);
        free(x);
        crom_keyframe_free(&k);
    }
    /* refused: one key, a non-finite key */
    CHECK(crom_keyframe_init(&k, &M, NULL, &sc, 1, keys, 0) == CROM_EUSAGE);
    const double bad[] = {0, 0, NAN, 1};
    CHECK(crom_keyframe_init(&k, &M, NULL, &sc, 2, bad, 0) == CROM_EUSAGE);
    CHECK(strstr(crom_errmsg(), "not finite") != NULL);
    crom_err_clear();
    crom_model_free(&M);
    crom_mesh_free(&m);
    free(W);
}

int main(void)
{
    check_begin("keyframe");
    test_latent();
    test_energies();
    return check_done();
}
