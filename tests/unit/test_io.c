/* test_io.c — crom files: HDF5 and frame-stream round trips, schema checks,
 * incomplete runs, atomic named outputs. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "check.h"
#include "cli/cli.h"
#include "base/err.h"
#include "io/io.h"
#include "mesh/mesh.h"
#include "io/schema.h"
#include "view/validate.h"

static char dir[] = "/tmp/crom-io-XXXXXX";

static int exists(const char *p)
{
    struct stat st;
    return stat(p, &st) == 0;
}

static int count_tmp(void)
{
    char cmd[256];
    snprintf(cmd, sizeof cmd, "ls -a %s | grep -c '\\.tmp$'", dir);
    FILE *f = popen(cmd, "r");
    int n = 0;
    if (f) {
        if (fscanf(f, "%d", &n) != 1)
            n = -1;
        pclose(f);
    }
    return n;
}

/* write a small series of `nframes` frames; fail_after >= 0 stops early */
static int write_series(const char *path, int kind, int nframes, int fail_after)
{
    crom_out o;
    int rc = crom_out_create(&o, path, "crom/latent", 1, NULL, "earlier stage", kind);
    if (rc)
        return rc;
    crom_h5_set_str(o.h5, ".", "model_id", "abc");
    crom_h5_set_i64(o.h5, ".", "rank", 3);
    hsize_t r = 3;
    CHECK(crom_out_field(&o, "time", 0, NULL, NULL) == 0);
    CHECK(crom_out_field(&o, "q", 1, &r, NULL) == 0);
    CHECK(crom_out_begin(&o) == 0);
    for (int f = 0; f < nframes; f++) {
        if (f == fail_after) {
            crom_err(CROM_EDATA, "step %d did not converge", f);
            crom_out_fail(&o);
            return CROM_EDATA;
        }
        double t = 0.1 * f, q[3] = {f, 2.0 * f, -1.0 * f};
        const double *vals[2] = {&t, q};
        CHECK(crom_out_frame(&o, vals) == 0);
    }
    return crom_out_commit(&o);
}

static void read_series(const char *path, int expect_frames, int expect_complete)
{
    crom_in in;
    int rc = crom_in_open(&in, path);
    CHECK_MSG(rc == 0, "open %s: %s", path, crom_errmsg());
    if (rc)
        return;
    CHECK(crom_in_expect(&in, "crom/latent", 1) == 0);
    CHECK(in.history && strstr(in.history, "earlier stage\n") == in.history);
    int ft = crom_in_field(&in, "time"), fq = crom_in_field(&in, "q");
    CHECK(ft == 0 && fq == 1 && in.frame_len == 4);
    int n = 0, ok = 1;
    while ((rc = crom_in_next(&in)) == 1) {
        const double *q = crom_in_get(&in, fq);
        ok &= fabs(crom_in_get(&in, ft)[0] - 0.1 * n) < 1e-15 && q[0] == n && q[1] == 2.0 * n &&
              q[2] == -n;
        n++;
    }
    CHECK(rc == 0);
    CHECK(ok);
    CHECK_MSG(n == expect_frames, "%s: %d frames, expected %d", path, n, expect_frames);
    CHECK_MSG(in.complete == expect_complete, "%s: complete = %d, expected %d", path, in.complete,
              expect_complete);
    crom_in_close(&in);
}

static void test_series(void)
{
    char p[256];
    /* HDF5 form */
    snprintf(p, sizeof p, "%s/a.h5", dir);
    CHECK(write_series(p, CROM_OUT_SERIES, 5, -1) == 0);
    read_series(p, 5, 1);
    /* random access */
    crom_in in;
    CHECK(crom_in_open(&in, p) == 0);
    CHECK(crom_in_seek(&in, 3) == 0 && crom_in_get(&in, 1)[1] == 6.0);
    CHECK(crom_in_seek(&in, 9) != 0);
    CHECK(crom_validate_file(&in, stderr) == 0);
    crom_in_close(&in);
    /* stream form, to a named file */
    snprintf(p, sizeof p, "%s/a.crs", dir);
    CHECK(write_series(p, CROM_OUT_SERIES_STREAM, 7, -1) == 0);
    read_series(p, 7, 1);
    CHECK(crom_in_open(&in, p) == 0);
    CHECK(in.form == CROM_IO_STREAM);
    CHECK(crom_validate_file(&in, stderr) == 0);
    crom_in_close(&in);
    /* a stream cut short (the writer died): frames so far, not complete */
    struct stat st;
    stat(p, &st);
    CHECK(truncate(p, st.st_size - 16 - 10) == 0); /* end record and part of the last frame */
    read_series(p, 6, 0);
    CHECK(crom_in_open(&in, p) == 0);
    CHECK(crom_validate_file(&in, NULL) > 0); /* --check flags it */
    crom_in_close(&in);
    /* a run that fails after 3 frames keeps them, marked incomplete */
    snprintf(p, sizeof p, "%s/fail.h5", dir);
    CHECK(write_series(p, CROM_OUT_SERIES, 6, 3) == CROM_EDATA);
    CHECK(strstr(crom_errmsg(), "did not converge") != NULL); /* the original error survives */
    CHECK(exists(p));
    read_series(p, 3, 0);
    snprintf(p, sizeof p, "%s/fail.crs", dir);
    CHECK(write_series(p, CROM_OUT_SERIES_STREAM, 6, 2) == CROM_EDATA);
    read_series(p, 2, 0);
    /* failing before any frame leaves nothing */
    snprintf(p, sizeof p, "%s/none.h5", dir);
    CHECK(write_series(p, CROM_OUT_SERIES, 6, 0) == CROM_EDATA);
    CHECK(!exists(p));
    CHECK(count_tmp() == 0);
}

static void test_plain(void)
{
    char p[256];
    snprintf(p, sizeof p, "%s/m.h5", dir);
    crom_mesh m = {0};
    double X[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
    int T[4] = {0, 1, 2, 3}, top[1] = {3};
    m.nv = 4;
    m.nt = 1;
    m.X = X;
    m.tets = T;
    crom_out o;
    CHECK(crom_out_create(&o, p, CROM_MESH_SCHEMA, 1, NULL, NULL, CROM_OUT_PLAIN) == 0);
    CHECK(!exists(p)); /* not before commit */
    CHECK(count_tmp() == 1);
    crom_mesh mm = m;
    mm.regions = NULL;
    mm.nregions = 0;
    crom_mesh_add_region(&mm, "top", "z>0.5", top, 1);
    CHECK(crom_mesh_write(o.h5, &mm) == 0);
    CHECK(crom_out_commit(&o) == 0);
    CHECK(exists(p) && count_tmp() == 0);
    struct stat st;
    stat(p, &st);
    CHECK((st.st_mode & 0044) != 0); /* readable like any file, not 0600 */
    crom_in in;
    CHECK(crom_in_open(&in, p) == 0);
    CHECK(crom_in_expect(&in, "crom/mesh", 1) == 0);
    CHECK(crom_in_expect(&in, "crom/trajectory", 1) == CROM_EDATA);
    CHECK(strstr(crom_errmsg(), "is crom/mesh v1, expected crom/trajectory") != NULL);
    CHECK(crom_in_expect(&in, "crom/mesh", 0) == CROM_EDATA);
    CHECK(strstr(crom_errmsg(), "newer than this crom understands") != NULL);
    CHECK(!crom_h5_has_attr(in.h5, ".", "complete")); /* only series carry it */
    hid_t root = H5Gopen2(in.h5, "/", H5P_DEFAULT);
    crom_mesh r;
    CHECK(crom_mesh_read(root, &r) == 0);
    CHECK(r.nv == 4 && r.nt == 1 && r.nregions == 1 && r.regions[0].idx[0] == 3);
    CHECK(!strcmp(r.regions[0].source, "z>0.5"));
    CHECK(memcmp(r.X, X, sizeof X) == 0 && memcmp(r.tets, T, sizeof T) == 0);
    crom_mesh_free(&r);
    H5Gclose(root);
    CHECK(crom_validate_file(&in, NULL) == 0);
    crom_in_close(&in);
    free(mm.regions[0].name);
    free(mm.regions[0].source);
    free(mm.regions[0].idx);
    free(mm.regions);
    /* an aborted plain output leaves nothing */
    snprintf(p, sizeof p, "%s/aborted.h5", dir);
    CHECK(crom_out_create(&o, p, CROM_MESH_SCHEMA, 1, NULL, NULL, CROM_OUT_PLAIN) == 0);
    crom_out_fail(&o);
    CHECK(!exists(p) && count_tmp() == 0);
    /* cannot create in a missing directory */
    CHECK(crom_out_create(&o, "/nonexistent-dir/x.h5", CROM_MESH_SCHEMA, 1, NULL, NULL,
                          CROM_OUT_PLAIN) == CROM_ECANTCREAT);
}

static void test_bad_inputs(void)
{
    char p[256];
    crom_in in;
    CHECK(crom_in_open(&in, "/nonexistent/file.h5") == CROM_ENOINPUT);
    snprintf(p, sizeof p, "%s/empty", dir);
    FILE *f = fopen(p, "w");
    fclose(f);
    CHECK(crom_in_open(&in, p) == CROM_EDATA && strstr(crom_errmsg(), "empty"));
    f = fopen(p, "w");
    for (int i = 0; i < 5000; i++)
        fputc((i * 7919) % 251, f);
    fclose(f);
    CHECK(crom_in_open(&in, p) == CROM_EDATA && strstr(crom_errmsg(), "not a crom file"));
    /* truncated HDF5 */
    char src[256];
    snprintf(src, sizeof src, "%s/m.h5", dir);
    f = fopen(src, "rb");
    FILE *g = fopen(p, "wb");
    for (int i = 0; i < 900; i++) {
        int c = fgetc(f);
        if (c == EOF)
            break;
        fputc(c, g);
    }
    fclose(f);
    fclose(g);
    CHECK(crom_in_open(&in, p) == CROM_EDATA && strstr(crom_errmsg(), "truncated or corrupt"));
    /* HDF5 without crom attributes */
    hid_t h = H5Fcreate(p, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    H5Fclose(h);
    CHECK(crom_in_open(&in, p) == CROM_EDATA && strstr(crom_errmsg(), "not a crom file"));
    /* stream with a corrupt header length */
    f = fopen(p, "wb");
    fwrite("CROMSTRM\1\0\0\0\0\0\0\0\xff\xff\xff\xff\xff\xff\xff\xff", 1, 24, f);
    fclose(f);
    CHECK(crom_in_open(&in, p) == CROM_EDATA && strstr(crom_errmsg(), "impossible length"));
}

/* Named targets that are devices are written in place: renaming a temporary
 * file over /dev/null would replace the device with a regular file. */
static void test_device_targets(void)
{
    struct stat st;
    CHECK(stat("/dev/null", &st) == 0 && S_ISCHR(st.st_mode));
    CHECK(write_series("/dev/null", CROM_OUT_SERIES, 3, -1) == 0);
    CHECK(write_series("/dev/null", CROM_OUT_SERIES_STREAM, 3, -1) == 0);
    crom_out o;
    CHECK(crom_out_create(&o, "/dev/null", CROM_MESH_SCHEMA, 1, NULL, NULL, CROM_OUT_PLAIN) == 0);
    CHECK(crom_out_commit(&o) == 0);
    crom_fileout fo;
    CHECK(crom_fileout_open(&fo, "/dev/null", 1) == 0);
    fputs("text", fo.f);
    CHECK(crom_fileout_commit(&fo) == 0);
    CHECK(stat("/dev/null", &st) == 0 && S_ISCHR(st.st_mode));
    char p[256];
    snprintf(p, sizeof p, "%s", dir);
    CHECK(crom_out_create(&o, p, CROM_MESH_SCHEMA, 1, NULL, NULL, CROM_OUT_PLAIN) == CROM_ECANTCREAT);
}

static void test_history_reproducible(void)
{
    setenv("SOURCE_DATE_EPOCH", "0", 1);
    char buf[64];
    crom_clock_utc(buf, sizeof buf);
    CHECK(!strcmp(buf, "1970-01-01T00:00:00Z"));
    CHECK(crom_clock_reproducible() && crom_clock_wall(3.5) == 0.0);
    unsetenv("SOURCE_DATE_EPOCH");
    CHECK(!crom_clock_reproducible() && crom_clock_wall(3.5) == 3.5);
}

int main(void)
{
    check_begin("test_io");
    if (!mkdtemp(dir))
        return 1;
    test_series();
    test_plain();
    test_bad_inputs();
    test_device_targets();
    test_history_reproducible();
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    if (system(cmd)) {
    }
    return check_done();
}
