/* test_h5probe.c — untrusted HDF5 input checked in a contained child:
 * corrupt global heaps that crash or hang libhdf5 1.10, datasets whose
 * declared size the file cannot back, links and layouts that leave the file.
 * Every case must come back as CROM_EDATA with a one-line message, in this
 * process, without a crash. The reproducers are built here from a small file
 * written with the HDF5 API and a few bytes changed. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include <hdf5.h>

#include "base/err.h"
#include "check.h"
#include "io/h5probe.h"
#include "io/io.h"

static char dir[] = "/tmp/crom-h5probe-XXXXXX";

static void path_of(char *p, size_t n, const char *name) { snprintf(p, n, "%s/%s", dir, name); }

/* A file like a crom file: a variable-length string attribute `schema` at
 * the root (stored in the global heap), a small dataset, a chunked one. */
static void write_good(const char *p, int external_link, int unwritten_big)
{
    hid_t f = H5Fcreate(p, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    hid_t st = H5Tcopy(H5T_C_S1);
    H5Tset_size(st, H5T_VARIABLE);
    hid_t sc = H5Screate(H5S_SCALAR);
    hid_t a = H5Acreate2(f, "schema", st, sc, H5P_DEFAULT, H5P_DEFAULT);
    const char *v = "crom/mesh";
    H5Awrite(a, st, &v);
    H5Aclose(a);
    long long one = 1;
    a = H5Acreate2(f, "schema_version", H5T_STD_I64LE, sc, H5P_DEFAULT, H5P_DEFAULT);
    H5Awrite(a, H5T_NATIVE_LLONG, &one);
    H5Aclose(a);
    double x[12];
    for (int i = 0; i < 12; i++)
        x[i] = i;
    hsize_t d[2] = {4, 3};
    hid_t s = H5Screate_simple(2, d, NULL);
    hid_t ds = H5Dcreate2(f, "vertices", H5T_IEEE_F64LE, s, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    H5Dwrite(ds, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, x);
    H5Dclose(ds);
    H5Sclose(s);
    hsize_t big[2] = {unwritten_big ? 100000000 : 2, 3}, chunk[2] = {1, 3};
    s = H5Screate_simple(2, big, NULL);
    hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
    H5Pset_chunk(dcpl, 2, chunk);
    ds = H5Dcreate2(f, "chunked", H5T_IEEE_F64LE, s, H5P_DEFAULT, dcpl, H5P_DEFAULT);
    if (!unwritten_big)
        H5Dwrite(ds, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, x);
    H5Dclose(ds);
    H5Pclose(dcpl);
    H5Sclose(s);
    if (external_link)
        H5Lcreate_external("other.h5", "/x", f, "elsewhere", H5P_DEFAULT, H5P_DEFAULT);
    H5Sclose(sc);
    H5Tclose(st);
    H5Fclose(f);
}

static unsigned char *slurp(const char *p, size_t *n)
{
    FILE *f = fopen(p, "rb");
    if (!f)
        return NULL;
    fseek(f, 0, SEEK_END);
    *n = (size_t)ftell(f);
    rewind(f);
    unsigned char *b = malloc(*n);
    if (b && fread(b, 1, *n, f) != *n) {
        free(b);
        b = NULL;
    }
    fclose(f);
    return b;
}

static void spit(const char *p, const unsigned char *b, size_t n)
{
    FILE *f = fopen(p, "wb");
    if (f) {
        fwrite(b, 1, n, f);
        fclose(f);
    }
}

/* The byte offset of the global heap collection ("GCOL") in b. */
static long gcol(const unsigned char *b, size_t n)
{
    for (size_t i = 0; i + 4 <= n; i++)
        if (!memcmp(b + i, "GCOL", 4))
            return (long)i;
    return -1;
}

static void expect_corrupt(const char *p, const char *what, const char *needle)
{
    crom_err_clear();
    int rc = crom_h5probe(p, NULL, 0, "x.h5");
    CHECK_MSG(rc == CROM_EDATA, "%s: probe returned %d, expected %d", what, rc, CROM_EDATA);
    CHECK_MSG(strstr(crom_errmsg(), needle) != NULL, "%s: message '%s' lacks '%s'", what,
              crom_errmsg(), needle);
    CHECK_MSG(!strchr(crom_errmsg(), '\n'), "%s: message has more than one line", what);
    /* the same bytes as a file image (the stdin path) */
    size_t n;
    unsigned char *b = slurp(p, &n);
    crom_err_clear();
    rc = b ? crom_h5probe(NULL, b, n, "stdin") : -1;
    CHECK_MSG(rc == CROM_EDATA, "%s (image): probe returned %d", what, rc);
    free(b);
}

int main(void)
{
    check_begin("test_h5probe");
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
    if (!mkdtemp(dir))
        return 1;
    setenv("CROM_PROBE_SECONDS", "2", 1);
    char good[256], bad[256];
    path_of(good, sizeof good, "good.h5");
    path_of(bad, sizeof bad, "bad.h5");
    write_good(good, 0, 0);

    /* a sound file passes, from a path and as an image, and crom_in_open
     * gets past the probe to its own reading */
    CHECK(crom_h5probe(good, NULL, 0, "good.h5") == 0);
    size_t n;
    unsigned char *b = slurp(good, &n);
    CHECK(b && crom_h5probe(NULL, b, n, "image") == 0);
    crom_in in;
    int rc = crom_in_open(&in, good);
    CHECK_MSG(rc == 0, "crom_in_open(good): %d %s", rc, crom_errmsg());
    if (!rc) {
        CHECK(!strcmp(in.schema, "crom/mesh"));
        crom_in_close(&in);
    }

    /* a corrupt global heap: the size of the heap object that holds the
     * schema string, made huge, crashes libhdf5 1.10.8 in H5HG_read (or
     * corrupts the heap); the collection's own size made huge makes it loop */
    long g = b ? gcol(b, n) : -1;
    CHECK(g > 0);
    if (g > 0) {
        unsigned char *c = malloc(n);
        const long crash_at[] = {25, 26, 29, 31}, crash_val[] = {0xff, 0x7f, 0x10, 0xff};
        for (int k = 0; k < 4; k++) {
            memcpy(c, b, n);
            c[g + crash_at[k]] = (unsigned char)crash_val[k];
            spit(bad, c, n);
            char what[64];
            snprintf(what, sizeof what, "GCOL+%ld=0x%lx", crash_at[k], crash_val[k]);
            expect_corrupt(bad, what, "corrupt HDF5 file");
            rc = crom_in_open(&in, bad);
            CHECK_MSG(rc == CROM_EDATA, "crom_in_open(%s) = %d", what, rc);
        }
        memcpy(c, b, n);
        c[g + 24] = 0x00; /* the object's size made 0: H5HG_read never ends */
        spit(bad, c, n);
        time_t t0 = time(NULL);
        expect_corrupt(bad, "GCOL object size 0", "did not finish within 2 s");
        CHECK_MSG(time(NULL) - t0 <= 10, "the hang took %ld s to stop", (long)(time(NULL) - t0));
        /* truncated: half the file */
        spit(bad, b, n / 2);
        expect_corrupt(bad, "truncated", "truncated or corrupt");
        free(c);
    }
    free(b);

    /* a dataset declared [1e8, 3] with nothing stored: refused before
     * anyone allocates 2.4 GB for it */
    write_good(bad, 0, 1);
    expect_corrupt(bad, "unwritten [1e8,3]", "declares 2400000000 bytes but the file stores 0");

    /* a link to another file */
    write_good(bad, 1, 0);
    expect_corrupt(bad, "external link", "link to another file");

    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    if (system(cmd)) {
    }
    return check_done();
}
