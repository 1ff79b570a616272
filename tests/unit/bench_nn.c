/* bench_nn.c — throughput of the LiCROM field MLP (3 -> 60 x4 -> 60, r = 20)
 * and of the PointNet encoder, forward + backward, on one core.
 * Not a test (speed is never asserted); build and run by hand:
 *   cc -std=c17 -D_DEFAULT_SOURCE -O2 -march=x86-64-v2 -fopenmp -Ilib \
 *      tests/unit/bench_nn.c lib/nn/nn.c lib/base/err.c lib/base/rng.c -lopenblas -lm -o /tmp/bench_nn
 *   /tmp/bench_nn [batch] [reps] [field|pointnet|all] [threads]
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <cblas.h>

#include "base/err.h"
#include "bench.h"
#include "nn/nn.h"
#include "base/rng.h"

static void die(void)
{
    fprintf(stderr, "bench_nn: %s\n", crom_errmsg());
    exit(1);
}

int main(int argc, char **argv)
{
    int B = argc > 1 ? atoi(argv[1]) : 16 * 4096;
    int reps = argc > 2 ? atoi(argv[2]) : 10;
    const char *only = argc > 3 ? argv[3] : "";
    int nthr = argc > 4 ? atoi(argv[4]) : 1;
    openblas_set_num_threads(1);

    /* the field W: R^3 -> R^{3 x 20} */
    const int widths[] = {3, 60, 60, 60, 60, 60};
    crom_nn_spec spec;
    crom_nn_mlp net;
    crom_nn_ws ws;
    crom_rng rng;
    crom_rng_seed(&rng, 1);
    if (crom_nn_spec_set(&spec, 6, widths, CROM_NN_ELU) ||
        crom_nn_mlp_init(&net, &spec, NULL, &rng) || crom_nn_ws_init(&ws, &net, B, nthr))
        die();
    float *x = malloc(sizeof(float) * (size_t)B * 3);
    float *y = malloc(sizeof(float) * (size_t)B * 60);
    float *g = calloc(net.nparams, sizeof(float));
    for (size_t i = 0; i < (size_t)B * 3; i++)
        x[i] = (float)(2 * crom_rng_uniform(&rng) - 1);
    for (size_t i = 0; i < (size_t)B * 60; i++)
        y[i] = (float)(1e-3 * crom_rng_normal(&rng));
    double tf = 0, tb = 0;
    for (int k = 0; k <= reps && strcmp(only, "pointnet"); k++) {
        double t0 = bench_now();
        if (crom_nn_mlp_forward(&net, &ws, B, x, NULL))
            die();
        double t1 = bench_now();
        if (crom_nn_mlp_backward(&net, &ws, B, y, g, NULL))
            die();
        double t2 = bench_now();
        if (k > 0) { /* the first round warms up */
            tf += t1 - t0;
            tb += t2 - t1;
        }
    }
    double flops = 0; /* multiply-adds x 2, forward; backward is twice that */
    for (int l = 0; l < spec.nlayers; l++)
        flops += 2.0 * spec.width[l] * spec.width[l + 1];
    printf("field 3-60x4-60 (%zu params), batch %d, %d reps, %d thread(s):\n", net.nparams, B, reps, nthr);
    printf("  forward  %8.2f ms  %10.3g points/s  %5.1f GFlop/s\n", 1e3 * tf / reps,
           B * reps / tf, flops * B * reps / tf * 1e-9);
    printf("  backward %8.2f ms  %10.3g points/s  %5.1f GFlop/s\n", 1e3 * tb / reps,
           B * reps / tb, 2 * flops * B * reps / tb * 1e-9);
    printf("  fwd+bwd  %8.2f ms  %10.3g points/s\n", 1e3 * (tf + tb) / reps,
           B * reps / (tf + tb));

    /* eval in double (simulator path) */
    double *xd = malloc(sizeof(double) * (size_t)B * 3), *yd = malloc(sizeof(double) * (size_t)B * 60);
    for (size_t i = 0; i < (size_t)B * 3; i++)
        xd[i] = x[i];
    double t0 = bench_now();
    for (int k = 0; k < reps; k++)
        if (crom_nn_mlp_eval(&net, &ws, (size_t)B, xd, yd, NULL))
            die();
    double te = bench_now() - t0;
    printf("  eval (double in/out) %8.2f ms  %10.3g points/s\n", 1e3 * te / reps, B * reps / te);

    if (!strcmp(only, "field"))
        return 0;
    /* PointNet 6-64-128-256 | 256-128-64-20 on 16 frames x 2500 points */
    const int pw[] = {6, 64, 128, 256}, hw[] = {256, 128, 64, 20};
    int F = 16, P = 2500;
    crom_nn_spec ps, hs;
    crom_nn_pointnet pn;
    crom_nn_pointnet_ws pws;
    if (crom_nn_pointnet_spec(&ps, &hs, 4, pw, 4, hw) ||
        crom_nn_pointnet_init(&pn, &ps, &hs, NULL, &rng) ||
        crom_nn_pointnet_ws_init(&pws, &pn, F, P, nthr))
        die();
    float *pts = malloc(sizeof(float) * (size_t)F * P * 6), q[16 * 20], dq[16 * 20];
    float *pg = calloc(pn.nparams, sizeof(float));
    for (size_t i = 0; i < (size_t)F * P * 6; i++)
        pts[i] = (float)(2 * crom_rng_uniform(&rng) - 1);
    for (int i = 0; i < F * 20; i++)
        dq[i] = (float)crom_rng_normal(&rng);
    tf = tb = 0;
    int preps = reps > 3 ? reps / 2 : reps;
    for (int k = 0; k <= preps; k++) {
        double a = bench_now();
        if (crom_nn_pointnet_forward(&pn, &pws, F, P, pts, q))
            die();
        double b = bench_now();
        if (crom_nn_pointnet_backward(&pn, &pws, F, P, dq, pg, NULL))
            die();
        double c = bench_now();
        if (k > 0) {
            tf += b - a;
            tb += c - b;
        }
    }
    printf("PointNet 6-64-128-256 | 256-128-64-20 (%zu params), %d frames x %d points:\n",
           pn.nparams, F, P);
    printf("  forward  %8.2f ms  backward %8.2f ms  (%10.3g points/s fwd+bwd)\n",
           1e3 * tf / preps, 1e3 * tb / preps, (double)F * P * preps / (tf + tb));

    crom_nn_pointnet_ws_free(&pws);
    crom_nn_pointnet_free(&pn);
    crom_nn_ws_free(&ws);
    crom_nn_mlp_free(&net);
    free(x); free(y); free(g); free(xd); free(yd); free(pts); free(pg);
    return 0;
}
