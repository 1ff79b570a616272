/* bench_io.c — what the contained check of an HDF5 input (lib/io/h5probe.c)
 * costs per file: crom_h5probe alone, a bare H5Fopen/H5Fclose, and the whole
 * crom_in_open/crom_in_close, on latent series of a few sizes (not a test:
 * speed is measured, never asserted). Medians of 15 runs.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "base/err.h"
#include "bench.h"
#include "io/h5probe.h"
#include "io/io.h"

static int write_series(const char *path, hsize_t r, int nframes)
{
    crom_out o;
    int rc = crom_out_create(&o, path, "crom/latent", 1, NULL, NULL, CROM_OUT_SERIES_H5);
    if (!rc)
        rc = crom_h5_set_str(o.h5, ".", "model_id", "bench");
    if (!rc)
        rc = crom_h5_set_i64(o.h5, ".", "rank", (long long)r);
    if (!rc)
        rc = crom_out_field(&o, "time", 0, NULL, NULL);
    if (!rc)
        rc = crom_out_field(&o, "q", 1, &r, NULL);
    if (!rc)
        rc = crom_out_begin(&o);
    double *q = calloc(r, sizeof *q);
    for (int f = 0; f < nframes && !rc && q; f++) {
        double t = f;
        q[f % r] = f;
        const double *vals[2] = {&t, q};
        rc = crom_out_frame(&o, vals);
    }
    free(q);
    return rc ? rc : crom_out_commit(&o);
}

enum { REPS = 15 };

static hid_t open_path(void *path) { return H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT); }

int main(void)
{
    char dir[] = "/tmp/crom-bench-io-XXXXXX";
    if (!mkdtemp(dir))
        return 1;
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
    const struct { hsize_t r; int frames; } cases[] = {{3, 100}, {3000, 100}, {3000, 1000}, {12000, 1000}};
    printf("%-28s %10s %12s %12s %14s\n", "file", "MB", "probe ms", "H5Fopen ms", "crom_in_open ms");
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        char path[128];
        snprintf(path, sizeof path, "%s/s.h5", dir);
        if (write_series(path, cases[c].r, cases[c].frames)) {
            fprintf(stderr, "bench_io: %s\n", crom_errmsg());
            return 1;
        }
        FILE *f = fopen(path, "rb");
        fseek(f, 0, SEEK_END);
        double mb = ftell(f) / 1e6;
        fclose(f);
        double tp[REPS], th[REPS], ti[REPS];
        for (int k = 0; k < REPS; k++) {
            double t0 = bench_now();
            crom_h5probe_src src = {open_path, path, (size_t)(mb * 1e6 + 0.5), NULL, NULL};
            if (crom_h5probe(&src, path)) {
                fprintf(stderr, "bench_io: %s\n", crom_errmsg());
                return 1;
            }
            tp[k] = bench_now() - t0;
            t0 = bench_now();
            hid_t h = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT);
            H5Fclose(h);
            th[k] = bench_now() - t0;
            t0 = bench_now();
            crom_in in;
            if (crom_in_open(&in, path)) {
                fprintf(stderr, "bench_io: %s\n", crom_errmsg());
                return 1;
            }
            crom_in_close(&in);
            ti[k] = bench_now() - t0;
        }
        char name[64];
        snprintf(name, sizeof name, "latent r=%llu, %d frames", (unsigned long long)cases[c].r,
                 cases[c].frames);
        printf("%-28s %10.1f %12.2f %12.2f %14.2f\n", name, mb, 1e3 * bench_median(tp, REPS), 1e3 * bench_median(th, REPS),
               1e3 * bench_median(ti, REPS));
        unlink(path);
    }
    rmdir(dir);
    return 0;
}
