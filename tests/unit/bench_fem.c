/* bench_fem.c — timing of the fem assembly on a structured grid of ~100K
 * tets (not a test: speed is measured, never asserted).
 *
 *   cc -std=c17 -D_DEFAULT_SOURCE -O2 -march=x86-64-v2 -fopenmp -Ilib \
 *      -I/usr/include/hdf5/serial tests/unit/bench_fem.c lib/phys/fem.c lib/base/err.c \
 *      lib/base/rng.c -lm -o /tmp/bench_fem && /tmp/bench_fem [NX NY NZ]
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "check.h"
#include "base/err.h"
#include "bench.h"
#include "fixtures.h"
#include "phys/fem.h"
#include "base/rng.h"

static void bench(const char *name, const crom_fem *fem, const double *x,
                  const crom_fem_opts *o, int energy, int grad, int hess,
                  double *gbuf, double *Hbuf)
{
    enum { REPS = 7 };
    double t[REPS], E;
    for (int r = 0; r < REPS; r++) {
        double t0 = bench_now();
        int rc = crom_fem_assemble(fem, x, o, energy ? &E : NULL, grad ? gbuf : NULL,
                                   hess ? Hbuf : NULL);
        t[r] = bench_now() - t0;
        if (rc) {
            fprintf(stderr, "bench_fem: %s\n", crom_errmsg());
            exit(1);
        }
    }
    qsort(t, REPS, sizeof t[0], bench_cmp);
    printf("%-44s min %7.1f ms  median %7.1f ms  %6.0f ns/tet\n", name, 1e3 * t[0],
           1e3 * t[REPS / 2], 1e9 * t[0] / fem->nt);
}

int main(int argc, char **argv)
{
    int nx = 26, ny = 26, nz = 25;
    if (argc == 4) {
        nx = atoi(argv[1]);
        ny = atoi(argv[2]);
        nz = atoi(argv[3]);
    }
    crom_mesh mesh;
    const double h[3] = {0.01, 0.01, 0.01};
    fx_grid(&mesh, nx, ny, nz, NULL, h, 0, NULL, NULL, 1);
    crom_material mat;
    crom_material_init(&mat, 2.5e6, 0.25, 1000);
    crom_fem fem;
    double t0 = bench_now();
    if (crom_fem_init(&fem, &mesh, &mat)) {
        fprintf(stderr, "bench_fem: %s\n", crom_errmsg());
        return 1;
    }
    printf("mesh: %d vertices, %d tets, Hessian %d x %d with %d upper entries, "
           "%d colours; crom_fem_init %.1f ms\n", fem.nv, fem.nt, fem.n, fem.n,
           fem.nnz, fem.ncolors, 1e3 * (bench_now() - t0));

    /* a compressed, twisted, noisy state so that the projection is busy */
    crom_rng r;
    crom_rng_seed(&r, 1);
    double *x = malloc(sizeof(double) * fem.n);
    for (int v = 0; v < fem.nv; v++) {
        const double *X = mesh.X + 3 * v;
        x[3 * v] = 0.8 * X[0] + 0.2 * X[2];
        x[3 * v + 1] = 0.9 * X[1];
        x[3 * v + 2] = 0.85 * X[2];
        for (int c = 0; c < 3; c++)
            x[3 * v + c] += 0.001 * crom_rng_normal(&r);
    }
    int nindef = 0;
    for (int t = 0; t < fem.nt; t++) {
        double xe[12], F[9], lam[9], Q[81];
        crom_fem_tet_positions(&fem, x, t, xe);
        crom_fem_tet_F(xe, fem.Dminv + 9 * (size_t)t, F);
        crom_fem_dPdF_eig(&mat, F, lam, Q);
        int neg = 0;
        for (int i = 0; i < 9; i++)
            neg |= lam[i] < 0;
        nindef += neg;
    }
    printf("state: %.0f%% of the elements have an indefinite dP/dF\n",
           100.0 * nindef / fem.nt);

    double *g = malloc(sizeof(double) * fem.n), *H = malloc(sizeof(double) * fem.nnz);
    crom_fem_opts o1 = {.nthreads = 1}, p1 = {.project = 1, .nthreads = 1};
    crom_fem_opts p2 = {.project = 1, .nthreads = 2};
    crom_fem_opts pm = {.project = 1, .mass_scale = 1e4, .nthreads = 1};
    bench("energy, 1 thread", &fem, x, &o1, 1, 0, 0, g, H);
    bench("energy + gradient, 1 thread", &fem, x, &o1, 1, 1, 0, g, H);
    bench("energy + gradient + Hessian, 1 thread", &fem, x, &o1, 1, 1, 1, g, H);
    bench("energy + gradient + projected H, 1 thread", &fem, x, &p1, 1, 1, 1, g, H);
    bench("  ... + mass term, 1 thread", &fem, x, &pm, 1, 1, 1, g, H);
    bench("energy + gradient + projected H, 2 threads", &fem, x, &p2, 1, 1, 1, g, H);

    /* the element kernel alone, without scatter */
    {
        double t1 = bench_now(), acc = 0;
        for (int t = 0; t < fem.nt; t++) {
            double xe[12], ge[12], He[144], E;
            crom_fem_tet_positions(&fem, x, t, xe);
            crom_fem_tet_eval(&mat, xe, fem.Dminv + 9 * (size_t)t, fem.vol[t], 1, &E, ge, He);
            acc += E + He[17];
        }
        double dt = bench_now() - t1;
        printf("%-44s     %7.1f ms              %6.0f ns/tet (%g)\n",
               "crom_fem_tet_eval loop (projected, full H)", 1e3 * dt, 1e9 * dt / fem.nt, acc);
    }
    free(x);
    free(g);
    free(H);
    crom_fem_free(&fem);
    free(mesh.X);
    free(mesh.tets);
    return 0;
}
