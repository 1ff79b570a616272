/* test_h5probe.c — untrusted HDF5 input checked in a contained child:
 * corrupt global heaps that crash or hang libhdf5 1.10, datasets whose
 * declared size the file cannot back, links and layouts that leave the file.
 * Every case must come back as CROM_EDATA with a one-line message, in this
 * process, without a crash. The reproducers are built here from a small file
 * written with the HDF5 API and a few bytes changed. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include <hdf5.h>
#include <hdf5_hl.h>

#include "base/err.h"
#include "check.h"
#include "io/h5probe.h"
#include "io/io.h"

static char dir[] = "/tmp/crom-h5probe-XXXXXX";

/* crom_h5probe on a path or an image, with a replay that only opens it
 * (crom_in_open's own replay is exercised through crom_in_open below) */
typedef struct {
    const char *path;
    void *image;
    size_t len;
} source;

static hid_t open_source(void *arg)
{
    source *s = arg;
    return s->path ? H5Fopen(s->path, H5F_ACC_RDONLY, H5P_DEFAULT)
                   : H5LTopen_file_image(s->image, s->len,
                                         H5LT_FILE_IMAGE_DONT_COPY | H5LT_FILE_IMAGE_DONT_RELEASE);
}

/* a system call that failed under libhdf5, as crom_in_open's hook reports it */
static int eio_errno(void) { return EIO; }

static int probe_sys(const char *path, void *image, size_t len, const char *name, int (*sys_error)(void))
{
    source s = {path, image, len};
    if (path) {
        FILE *f = fopen(path, "rb");
        if (f) {
            fseek(f, 0, SEEK_END);
            s.len = (size_t)ftell(f);
            fclose(f);
        }
    }
    crom_h5probe_src src = {open_source, &s, s.len, NULL, sys_error};
    return crom_h5probe(&src, name);
}

static int probe(const char *path, void *image, size_t len, const char *name)
{
    return probe_sys(path, image, len, name, NULL);
}

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
    int rc = probe(p, NULL, 0, "x.h5");
    CHECK_MSG(rc == CROM_EDATA, "%s: probe returned %d, expected %d", what, rc, CROM_EDATA);
    CHECK_MSG(strstr(crom_errmsg(), needle) != NULL, "%s: message '%s' lacks '%s'", what,
              crom_errmsg(), needle);
    CHECK_MSG(!strchr(crom_errmsg(), '\n'), "%s: message has more than one line", what);
    /* the same bytes as a file image (the stdin path) */
    size_t n;
    unsigned char *b = slurp(p, &n);
    crom_err_clear();
    rc = b ? probe(NULL, b, n, "stdin") : -1;
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
    CHECK(probe(good, NULL, 0, "good.h5") == 0);
    size_t n;
    unsigned char *b = slurp(good, &n);
    CHECK(b && probe(NULL, b, n, "image") == 0);
    crom_in in;
    int rc = crom_in_open(&in, good);
    CHECK_MSG(rc == 0, "crom_in_open(good): %d %s", rc, crom_errmsg());
    if (!rc) {
        CHECK(!strcmp(in.schema, "crom/mesh"));
        crom_in_close(&in);
    }

    /* a file that fails to open: corrupt, unless a system call failed under
     * libhdf5 in the child (a device error: the errno, CROM_EIO) */
    if (b) {
        unsigned char junk[64] = "\x89HDF\r\n\x1a\n not really";
        CHECK(probe_sys(NULL, junk, sizeof junk, "junk", NULL) == CROM_EDATA);
        CHECK(probe_sys(NULL, junk, sizeof junk, "junk", eio_errno) == CROM_EIO);
        CHECK(!strcmp(crom_errmsg(), "junk: Input/output error"));
        CHECK(probe_sys(good, NULL, 0, "good.h5", eio_errno) == 0); /* asked only on failure */
    }

    /* the clean copy: a new file with the same content, opened instead of
     * the bytes that came in */
    if (b) {
        source sc = {NULL, b, n};
        crom_h5probe_copy copy = {NULL, 0};
        crom_h5probe_src src = {open_source, &sc, n, &copy, NULL};
        CHECK_MSG(crom_h5probe(&src, "image") == 0, "probe with a copy: %s", crom_errmsg());
        hid_t f = copy.buf ? H5LTopen_file_image(copy.buf, copy.len, H5LT_FILE_IMAGE_DONT_COPY |
                                                                         H5LT_FILE_IMAGE_DONT_RELEASE)
                           : -1;
        CHECK(f >= 0 && copy.buf != (void *)b);
        if (f >= 0) {
            hid_t st = H5Tcopy(H5T_C_S1);
            H5Tset_size(st, H5T_VARIABLE);
            char *v = NULL;
            hid_t a = H5Aopen(f, "schema", H5P_DEFAULT);
            CHECK(a >= 0 && H5Aread(a, st, &v) >= 0 && v && !strcmp(v, "crom/mesh"));
            H5free_memory(v);
            H5Aclose(a);
            H5Tclose(st);
            double x[12] = {0}, y[6] = {0};
            hid_t d = H5Dopen2(f, "vertices", H5P_DEFAULT);
            CHECK(d >= 0 && H5Dread(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, x) >= 0);
            H5Dclose(d);
            d = H5Dopen2(f, "chunked", H5P_DEFAULT);
            CHECK(d >= 0 && H5Dread(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, y) >= 0);
            H5Dclose(d);
            int same = 1;
            for (int i = 0; i < 12; i++)
                same &= x[i] == i && (i >= 6 || y[i] == i);
            CHECK_MSG(same, "the copy's data differ from the file's");
            H5Fclose(f);
        }
        free(copy.buf);
    }

    /* a corrupt global heap: the size of the heap object that holds the
     * schema string, made huge, crashes libhdf5 1.10.8 in H5HG_read (or
     * corrupts the heap); the collection's own size made huge makes it loop */
    long g = b ? gcol(b, n) : -1;
    CHECK(g > 0);
    if (g > 0) {
        unsigned char *c = malloc(n);
        /* sizes that send H5HG_read far outside the heap fault in the child
         * whatever the layout; 0x10xx only overruns into the next block,
         * which the child's heap checks may or may not notice, but which
         * the caller never parses (it opens the child's clean copy) */
        const long crash_at[] = {25, 26, 31, 25}, crash_val[] = {0xff, 0x7f, 0xff, 0x10};
        for (int k = 0; k < 4; k++) {
            memcpy(c, b, n);
            c[g + crash_at[k]] = (unsigned char)crash_val[k];
            spit(bad, c, n);
            char what[64];
            snprintf(what, sizeof what, "GCOL+%ld=0x%lx", crash_at[k], crash_val[k]);
            if (k < 3)
                expect_corrupt(bad, what, "corrupt");
            rc = crom_in_open(&in, bad);
            if (k < 3)
                CHECK_MSG(rc == CROM_EDATA, "crom_in_open(%s) = %d", what, rc);
            else
                CHECK_MSG(rc == CROM_EDATA || rc == 0, "crom_in_open(%s) = %d", what, rc);
            if (!rc)
                crom_in_close(&in);
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
