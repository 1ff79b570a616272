/* h5probe.c — an untrusted HDF5 file opened first in a contained child (see h5probe.h). */
#include <errno.h>
#include <fcntl.h>
#include <malloc.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <hdf5_hl.h>

#include "base/err.h"
#include "io/h5probe.h"

#if defined(__SANITIZE_ADDRESS__)
#define PROBE_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define PROBE_ASAN 1
#endif
#endif

/* Child exit statuses; anything else (a signal, a sanitizer's exit 1) means
 * libhdf5 failed in a way the caller must not repeat. */
enum { PROBE_OK = 0, PROBE_NOOPEN = 40, PROBE_BAD = 41 };

#define READ_PIECE 4096u               /* elements read per dataset, at most */
#define ATTR_MAX ((hsize_t)64 << 20)   /* bytes an attribute may declare */
#define FILTER_RATIO 1100              /* above deflate's 1032:1 ceiling */

typedef struct {
    hid_t file;
    unsigned long long fsize;
    char why[200];
} walk;

static herr_t fail(walk *w, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static herr_t fail(walk *w, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(w->why, sizeof w->why, fmt, ap);
    va_end(ap);
    return -1;
}

/* The memory type crom reads data of file type ft with (io.c): doubles for
 * floats, 64-bit integers for integers, strings as stored; other classes in
 * their native form. Reference types are not read (-1 with *skip set). */
static hid_t mem_type(hid_t ft, int *skip)
{
    *skip = 0;
    switch (H5Tget_class(ft)) {
    case H5T_FLOAT:
        return H5Tcopy(H5T_NATIVE_DOUBLE);
    case H5T_INTEGER:
        return H5Tcopy(H5T_NATIVE_LLONG);
    case H5T_STRING: {
        hid_t mt = H5Tcopy(H5T_C_S1);
        if (H5Tis_variable_str(ft) > 0)
            H5Tset_size(mt, H5T_VARIABLE);
        else
            H5Tset_size(mt, H5Tget_size(ft));
        H5Tset_cset(mt, H5Tget_cset(ft));
        return mt;
    }
    case H5T_REFERENCE:
        *skip = 1;
        return -1;
    default:
        return H5Tget_native_type(ft, H5T_DIR_DEFAULT);
    }
}

/* Release what a read of a variable-length type allocated. */
static void reclaim(hid_t mt, hid_t space, void *buf)
{
    if (H5Tdetect_class(mt, H5T_VLEN) > 0 || H5Tis_variable_str(mt) > 0)
        H5Dvlen_reclaim(mt, space, H5P_DEFAULT, buf);
}

static herr_t check_attr(hid_t loc, const char *name, const H5A_info_t *info, void *data)
{
    walk *w = data;
    hid_t a = H5Aopen(loc, name, H5P_DEFAULT);
    if (a < 0)
        return fail(w, "cannot open attribute '%s'", name);
    hid_t ft = H5Aget_type(a), sp = H5Aget_space(a);
    herr_t r = 0;
    int skip = 0;
    hid_t mt = ft >= 0 ? mem_type(ft, &skip) : -1;
    hssize_t np = sp >= 0 ? H5Sget_simple_extent_npoints(sp) : -1;
    if (ft < 0 || sp < 0 || np < 0 || (mt < 0 && !skip))
        r = fail(w, "attribute '%s' has a corrupt type or shape", name);
    else if (!skip && np > 0) {
        size_t es = H5Tget_size(mt);
        if (es == 0 || (hsize_t)np > ATTR_MAX / es)
            r = fail(w, "attribute '%s' declares %lld values of %zu bytes", name, (long long)np, es);
        else {
            void *buf = calloc((size_t)np, es);
            if (!buf)
                r = fail(w, "out of memory reading attribute '%s'", name);
            else if (H5Aread(a, mt, buf) < 0)
                r = fail(w, "cannot read attribute '%s'", name);
            else
                reclaim(mt, sp, buf);
            free(buf);
        }
    }
    if (mt >= 0)
        H5Tclose(mt);
    if (ft >= 0)
        H5Tclose(ft);
    if (sp >= 0)
        H5Sclose(sp);
    H5Aclose(a);
    return r;
}

/* Read the first elements of d (at most READ_PIECE) with crom's memory type,
 * which exercises the type conversion and the storage behind it. */
static herr_t read_piece(walk *w, hid_t d, hid_t ft, hid_t sp, const char *name)
{
    int skip = 0, rank = H5Sget_simple_extent_ndims(sp);
    hid_t mt = mem_type(ft, &skip);
    if (skip)
        return 0;
    if (mt < 0 || rank < 0 || rank > H5S_MAX_RANK)
        return fail(w, "'%s' has a corrupt type or shape", name);
    hsize_t dims[H5S_MAX_RANK], start[H5S_MAX_RANK] = {0}, count[H5S_MAX_RANK];
    H5Sget_simple_extent_dims(sp, dims, NULL);
    hsize_t n = 1;
    for (int i = rank - 1; i >= 0; i--) {
        count[i] = dims[i];
        if (dims[i] == 0) {
            H5Tclose(mt);
            return 0;
        }
        if (n * count[i] > READ_PIECE)
            count[i] = READ_PIECE / n ? READ_PIECE / n : 1;
        n *= count[i];
    }
    herr_t r = 0;
    size_t es = H5Tget_size(mt);
    void *buf = es ? calloc((size_t)n, es) : NULL;
    hid_t fs = H5Scopy(sp), ms = H5Screate_simple(1, &n, NULL);
    if (!buf)
        r = fail(w, "'%s' has a corrupt type", name);
    else if (rank > 0 && H5Sselect_hyperslab(fs, H5S_SELECT_SET, start, NULL, count, NULL) < 0)
        r = fail(w, "'%s' has a corrupt shape", name);
    else if (H5Dread(d, mt, ms, fs, H5P_DEFAULT, buf) < 0)
        r = fail(w, "cannot read dataset '%s'", name);
    else
        reclaim(mt, ms, buf);
    free(buf);
    H5Sclose(ms);
    H5Sclose(fs);
    H5Tclose(mt);
    return r;
}

/* A dataset: a layout crom can read from this file alone, a declared size
 * the stored bytes can back, stored bytes the file can hold, and a piece
 * that reads. */
static herr_t check_dset(walk *w, hid_t d, const char *name)
{
    hid_t ft = H5Dget_type(d), sp = H5Dget_space(d), dcpl = H5Dget_create_plist(d);
    herr_t r = 0;
    hssize_t np = sp >= 0 ? H5Sget_simple_extent_npoints(sp) : -1;
    size_t es = ft >= 0 ? H5Tget_size(ft) : 0;
    H5D_layout_t layout = dcpl >= 0 ? H5Pget_layout(dcpl) : H5D_LAYOUT_ERROR;
    int nfilters = dcpl >= 0 ? H5Pget_nfilters(dcpl) : -1;
    if (ft < 0 || sp < 0 || dcpl < 0 || np < 0 || es == 0 || nfilters < 0 ||
        layout == H5D_LAYOUT_ERROR)
        r = fail(w, "dataset '%s' has a corrupt type, shape or layout", name);
    else if (layout == H5D_VIRTUAL || H5Pget_external_count(dcpl) != 0)
        r = fail(w, "dataset '%s' keeps its data in other files", name);
    else {
        double declared = (double)np * (double)es;
        hsize_t stored = H5Dget_storage_size(d);
        haddr_t off = layout == H5D_CONTIGUOUS ? H5Dget_offset(d) : HADDR_UNDEF;
        if ((double)stored > (double)w->fsize)
            r = fail(w, "dataset '%s' claims %llu stored bytes in a file of %llu", name,
                     (unsigned long long)stored, w->fsize);
        else if (off != HADDR_UNDEF && (off > w->fsize || stored > w->fsize - off))
            r = fail(w, "dataset '%s' lies past the end of the file", name);
        else if (nfilters == 0 ? declared > (double)stored
                               : declared > FILTER_RATIO * (double)stored + 4096.0)
            r = fail(w, "dataset '%s' declares %.0f bytes but the file stores %llu", name,
                     declared, (unsigned long long)stored);
        else
            r = read_piece(w, d, ft, sp, name);
    }
    if (dcpl >= 0)
        H5Pclose(dcpl);
    if (sp >= 0)
        H5Sclose(sp);
    if (ft >= 0)
        H5Tclose(ft);
    return r;
}

/* One object of the walk, opened again by its path (which exercises the
 * lookup by name the readers use, not only the iteration). */
static herr_t check_object(hid_t root, const char *name, const H5O_info_t *info, void *data)
{
    walk *w = data;
    hid_t o = H5Oopen(w->file, name, H5P_DEFAULT);
    if (o < 0)
        return fail(w, "cannot open '%s' by name", name);
    hsize_t idx = 0;
    herr_t r = H5Aiterate2(o, H5_INDEX_NAME, H5_ITER_INC, &idx, check_attr, w);
    if (r < 0 && !w->why[0])
        r = fail(w, "cannot list the attributes of '%s'", name);
    if (r >= 0 && info->type == H5O_TYPE_DATASET)
        r = check_dset(w, o, name);
    H5Oclose(o);
    return r < 0 ? -1 : 0;
}

/* Links that leave the file (external links) would make a reader open
 * another file; crom never writes them. */
static herr_t check_link(hid_t g, const char *name, const H5L_info_t *info, void *data)
{
    if (info->type == H5L_TYPE_EXTERNAL || info->type >= H5L_TYPE_UD_MIN)
        return fail(data, "'%s' is a link to another file", name);
    return 0;
}

/* The child: never returns. */
static void child(const char *path, const void *image, size_t len, unsigned secs, int out)
{
    static const int sigs[] = {SIGSEGV, SIGBUS, SIGABRT, SIGFPE, SIGILL, SIGALRM, SIGXCPU};
    for (size_t i = 0; i < sizeof sigs / sizeof sigs[0]; i++)
        signal(sigs[i], SIG_DFL);
    int null = open("/dev/null", O_RDWR);
    if (null >= 0) {
        dup2(null, 1);
        dup2(null, 2);
    }
    struct rlimit cpu = {secs, secs + 1};
    setrlimit(RLIMIT_CPU, &cpu);
#ifndef PROBE_ASAN
    /* 2 GiB beyond what the process maps now (it is a copy of the caller) */
    unsigned long pages = 0;
    FILE *f = fopen("/proc/self/statm", "r");
    if (f) {
        if (fscanf(f, "%lu", &pages) != 1)
            pages = 0;
        fclose(f);
    }
    if (pages) {
        rlim_t as = (rlim_t)pages * (rlim_t)sysconf(_SC_PAGESIZE) + ((rlim_t)2 << 30);
        struct rlimit mem = {as, as};
        setrlimit(RLIMIT_AS, &mem);
    }
#endif
    alarm(secs);
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
    walk w = {.fsize = len};
    w.file = image ? H5LTopen_file_image((void *)image, len,
                                         H5LT_FILE_IMAGE_DONT_COPY | H5LT_FILE_IMAGE_DONT_RELEASE)
                   : H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT);
    if (w.file < 0)
        _exit(PROBE_NOOPEN);
    herr_t r = H5Lvisit(w.file, H5_INDEX_NAME, H5_ITER_INC, check_link, &w);
    if (r >= 0)
        r = H5Ovisit2(w.file, H5_INDEX_NAME, H5_ITER_INC, check_object, &w, H5O_INFO_BASIC);
    if (r < 0) {
        if (!w.why[0])
            snprintf(w.why, sizeof w.why, "its groups cannot be walked");
        ssize_t k = write(out, w.why, strlen(w.why));
        (void)k;
        _exit(PROBE_BAD);
    }
    /* Closing frees everything the walk made, and malloc_trim consolidates
     * the heap, where glibc's consistency checks catch a corrupting read
     * that did not crash on its own (it aborts here, not in the caller). */
    if (H5Fclose(w.file) < 0 || H5close() < 0)
        _exit(PROBE_BAD);
    malloc_trim(0);
    _exit(PROBE_OK);
}

static unsigned probe_seconds(size_t len)
{
    const char *e = getenv("CROM_PROBE_SECONDS");
    if (e) {
        char *end;
        long s = strtol(e, &end, 10);
        if (end != e && !*end && s > 0 && s < 86400)
            return (unsigned)s;
    }
    return 20u + (unsigned)(len / 100000000u);
}

int crom_h5probe(const char *path, const void *image, size_t len, const char *name)
{
    if (!image) {
        struct stat st;
        if (stat(path, &st) != 0)
            return crom_err(CROM_ENOINPUT, "%s: %s", name, strerror(errno));
        len = (size_t)st.st_size;
    }
    unsigned secs = probe_seconds(len);
    int fd[2];
    if (pipe(fd) != 0)
        return crom_err(CROM_EINTERNAL, "cannot check %s: pipe: %s", name, strerror(errno));
    pid_t pid = fork();
    if (pid < 0) {
        close(fd[0]);
        close(fd[1]);
        return crom_err(CROM_EINTERNAL, "cannot check %s: fork: %s", name, strerror(errno));
    }
    if (pid == 0) {
        close(fd[0]);
        child(path, image, len, secs, fd[1]);
    }
    close(fd[1]);
    char why[200];
    size_t n = 0;
    for (;;) {
        ssize_t k = read(fd[0], why + n, sizeof why - 1 - n);
        if (k > 0 && (n += (size_t)k) < sizeof why - 1)
            continue;
        if (k < 0 && errno == EINTR)
            continue;
        break;
    }
    why[n] = 0;
    close(fd[0]);
    int status;
    while (waitpid(pid, &status, 0) < 0)
        if (errno != EINTR)
            return crom_err(CROM_EINTERNAL, "cannot check %s: waitpid: %s", name, strerror(errno));
    if (WIFEXITED(status) && WEXITSTATUS(status) == PROBE_OK)
        return 0;
    if (WIFEXITED(status) && WEXITSTATUS(status) == PROBE_NOOPEN)
        return crom_err(CROM_EDATA, "%s: HDF5 file is truncated or corrupt", name);
    if (WIFEXITED(status) && WEXITSTATUS(status) == PROBE_BAD)
        return crom_err(CROM_EDATA, "%s: corrupt HDF5 file: %s", name, why);
    if (WIFSIGNALED(status) && (WTERMSIG(status) == SIGALRM || WTERMSIG(status) == SIGXCPU ||
                                WTERMSIG(status) == SIGKILL))
        return crom_err(CROM_EDATA, "%s: corrupt HDF5 file: reading it did not finish within %u s "
                        "(or its memory limit)", name, secs);
    if (WIFSIGNALED(status))
        return crom_err(CROM_EDATA, "%s: corrupt HDF5 file: libhdf5 failed on it (signal %d, "
                        "in a separate process)", name, WTERMSIG(status));
    return crom_err(CROM_EDATA, "%s: corrupt HDF5 file: libhdf5 failed on it (exit %d, "
                    "in a separate process)", name, WEXITSTATUS(status));
}
