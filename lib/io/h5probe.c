/* h5probe.c — an untrusted HDF5 file opened first in a contained child (see h5probe.h). */
#define _GNU_SOURCE /* memfd_create */
#include <errno.h>
#include <fcntl.h>
#include <malloc.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
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
enum { PROBE_OK = 0, PROBE_NOOPEN = 40, PROBE_BAD = 41, PROBE_SYSERR = 42 };

#define READ_PIECE 4096u               /* elements read per dataset, at most */
#define ATTR_MAX ((hsize_t)64 << 20)   /* bytes an attribute may declare */
#define FILTER_RATIO 1100              /* above deflate's 1032:1 ceiling */
#define ABSENT "crom-probe: no such name"  /* a name no crom file has */

typedef struct {
    hid_t file;
    hid_t dxpl; /* reads with a small conversion buffer (the default 1 MB
                 * costs page faults in the fresh child) */
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

/* The memory type crom reads data of file type ft with (io.c): float or
 * double for floats, int or long long for integers (by size: converting
 * anything else exercises the conversion a reader would run), strings as
 * stored; other classes in their native form. Reference types are not read
 * (-1 with *skip set). */
static hid_t mem_type(hid_t ft, int *skip)
{
    *skip = 0;
    switch (H5Tget_class(ft)) {
    case H5T_FLOAT:
        return H5Tcopy(H5Tget_size(ft) == 4 ? H5T_NATIVE_FLOAT : H5T_NATIVE_DOUBLE);
    case H5T_INTEGER:
        return H5Tcopy(H5Tget_size(ft) == 4 ? H5T_NATIVE_INT : H5T_NATIVE_LLONG);
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
    herr_t r = H5Aexists(loc, name) > 0 ? 0 : fail(w, "cannot find attribute '%s' by name", name);
    int skip = 0;
    hid_t mt = ft >= 0 ? mem_type(ft, &skip) : -1;
    hssize_t np = sp >= 0 ? H5Sget_simple_extent_npoints(sp) : -1;
    if (r < 0)
        ;
    else if (ft < 0 || sp < 0 || np < 0 || (mt < 0 && !skip))
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
    else if (H5Dread(d, mt, ms, fs, w->dxpl, buf) < 0)
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

/* Readers ask for names that may not be there: a lookup of an absent name
 * goes through every attribute message (and every link of a group) by the
 * search path, which decodes them differently from an iteration; it comes
 * first, as in a reader, before anything else has decoded them. */
static herr_t search(walk *w, hid_t o, int group, const char *name)
{
    if (H5Aexists(o, ABSENT) < 0)
        return fail(w, "cannot search the attributes of '%s'", name);
    if (group && H5Lexists(o, ABSENT, H5P_DEFAULT) < 0)
        return fail(w, "cannot search the links of '%s'", name);
    return 0;
}

/* One object of the walk, opened again by its path (which exercises the
 * lookup by name the readers use, not only the iteration). */
static herr_t check_object(hid_t root, const char *name, const H5O_info_t *info, void *data)
{
    walk *w = data;
    hid_t o = H5Oopen(w->file, name, H5P_DEFAULT);
    if (o < 0)
        return fail(w, "cannot open '%s' by name", name);
    herr_t r = search(w, o, info->type == H5O_TYPE_GROUP, name);
    hsize_t idx = 0;
    if (r >= 0 && H5Aiterate2(o, H5_INDEX_NAME, H5_ITER_INC, &idx, check_attr, w) < 0)
        r = w->why[0] ? -1 : fail(w, "cannot list the attributes of '%s'", name);
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

/* ------------------------------------------------------- the clean copy
 * What the caller opens: a new file, written by libhdf5 in the child from
 * what it decoded of the input (attributes read and written again, objects
 * copied with H5Ocopy, which decodes and re-encodes their headers). A
 * corrupt length or offset that went through the walk without a fault is
 * either refused there or comes out as a well-formed value. */

static herr_t copy_attr(hid_t loc, const char *name, const H5A_info_t *info, void *data)
{
    hid_t dst = *(hid_t *)data;
    hid_t a = H5Aopen(loc, name, H5P_DEFAULT);
    hid_t ft = a >= 0 ? H5Aget_type(a) : -1, sp = a >= 0 ? H5Aget_space(a) : -1;
    hid_t mt = ft >= 0 ? H5Tget_native_type(ft, H5T_DIR_DEFAULT) : -1;
    hssize_t np = sp >= 0 ? H5Sget_simple_extent_npoints(sp) : -1;
    size_t es = mt >= 0 ? H5Tget_size(mt) : 0;
    herr_t r = -1;
    void *buf = np >= 0 && es && (hsize_t)np <= ATTR_MAX / es ? calloc(np ? (size_t)np : 1, es) : NULL;
    if (buf && H5Aread(a, mt, buf) >= 0) {
        hid_t b = H5Acreate2(dst, name, ft, sp, H5P_DEFAULT, H5P_DEFAULT);
        if (b >= 0 && H5Awrite(b, mt, buf) >= 0)
            r = 0;
        if (b >= 0)
            H5Aclose(b);
        reclaim(mt, sp, buf);
    }
    free(buf);
    if (mt >= 0)
        H5Tclose(mt);
    if (sp >= 0)
        H5Sclose(sp);
    if (ft >= 0)
        H5Tclose(ft);
    if (a >= 0)
        H5Aclose(a);
    return r;
}

typedef struct {
    walk *w;
    hid_t dst;
} copying;

static herr_t copy_link(hid_t g, const char *name, const H5L_info_t *info, void *data)
{
    copying *c = data;
    if (info->type == H5L_TYPE_HARD)
        return H5Ocopy(g, name, c->dst, name, H5P_DEFAULT, H5P_DEFAULT) < 0
                   ? fail(c->w, "cannot copy '%s'", name) : 0;
    if (info->type == H5L_TYPE_SOFT && info->u.val_size > 0 && info->u.val_size < 4096) {
        char target[4096];
        if (H5Lget_val(g, name, target, sizeof target, H5P_DEFAULT) >= 0 &&
            H5Lcreate_soft(target, c->dst, name, H5P_DEFAULT, H5P_DEFAULT) >= 0)
            return 0;
    }
    return fail(c->w, "cannot copy the link '%s'", name);
}

/* Write the clean copy of w->file to the file out (a memfd the caller
 * reads after the child has left: a pipe would take a context switch per
 * 64 KiB). Returns 0, or -1 with w->why set. */
static int send_copy(walk *w, int out)
{
    hid_t fapl = H5Pcreate(H5P_FILE_ACCESS);
    /* (grown in one step of about the input's size: small steps cost a
     * realloc and a copy each) */
    H5Pset_fapl_core(fapl, (size_t)w->fsize + ((size_t)1 << 20), 0);
    hid_t dst = H5Fcreate("crom-probe-copy", H5F_ACC_EXCL, H5P_DEFAULT, fapl);
    H5Pclose(fapl);
    if (dst < 0)
        return fail(w, "cannot make a copy in memory");
    copying c = {w, dst};
    hid_t root = H5Oopen(w->file, "/", H5P_DEFAULT), droot = H5Oopen(dst, "/", H5P_DEFAULT);
    hsize_t idx = 0;
    herr_t r = root < 0 || droot < 0 ? -1 : H5Aiterate2(root, H5_INDEX_NAME, H5_ITER_INC, &idx, copy_attr, &droot);
    if (r < 0)
        fail(w, "cannot copy the root attributes");
    idx = 0;
    if (r >= 0)
        r = H5Literate(w->file, H5_INDEX_NAME, H5_ITER_INC, &idx, copy_link, &c);
    if (root >= 0)
        H5Oclose(root);
    if (droot >= 0)
        H5Oclose(droot);
    ssize_t n = r >= 0 && H5Fflush(dst, H5F_SCOPE_GLOBAL) >= 0 ? H5Fget_file_image(dst, NULL, 0) : -1;
    char *img = n > 0 ? malloc((size_t)n) : NULL;
    if (r >= 0 && (!img || H5Fget_file_image(dst, img, (size_t)n) != n))
        r = fail(w, "cannot make a copy in memory");
    H5Fclose(dst);
    if (r < 0) {
        free(img);
        return -1;
    }
    for (size_t done = 0, total = (size_t)n; done < total;) {
        ssize_t k = write(out, img + done, total - done);
        if (k < 0 && errno == EINTR)
            continue;
        if (k <= 0)
            _exit(PROBE_NOOPEN); /* (the caller went away) */
        done += (size_t)k;
    }
    free(img);
    return 0;
}

/* If a system call failed under libhdf5 (src->sys_error), exit the child
 * with PROBE_SYSERR and its errno, in decimal, on out: a device error is
 * no corrupt file. Else exit with status code, or return for code < 0. */
static void leave(const crom_h5probe_src *src, int out, int code)
{
    int e = src->sys_error ? src->sys_error() : 0;
    if (e > 0) {
        char num[16];
        int n = snprintf(num, sizeof num, "%d", e);
        ssize_t k = write(out, num, (size_t)n);
        (void)k;
        _exit(PROBE_SYSERR);
    }
    if (code >= 0)
        _exit(code);
}

/* The child: never returns. */
static void child(const crom_h5probe_src *src, unsigned secs, int out, int copyfd)
{
    /* Until the replay below nothing here allocates, so the heap the replay
     * runs on is the caller's own, byte for byte (see h5probe.h). */
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
    char statm[64] = {0};
    int fd = open("/proc/self/statm", O_RDONLY);
    if (fd >= 0) {
        ssize_t k = read(fd, statm, sizeof statm - 1);
        (void)k;
        close(fd);
    }
    unsigned long long pages = strtoull(statm, NULL, 10);
    if (pages) {
        rlim_t as = (rlim_t)pages * (rlim_t)sysconf(_SC_PAGESIZE) + ((rlim_t)2 << 30);
        struct rlimit mem = {as, as};
        setrlimit(RLIMIT_AS, &mem);
    }
#endif
    alarm(secs);
    walk w = {.fsize = src->len};
    w.file = src->replay(src->arg);
    if (w.file < 0)
        leave(src, out, PROBE_NOOPEN);
    w.dxpl = H5Pcreate(H5P_DATASET_XFER);
    H5Pset_buffer(w.dxpl, (size_t)READ_PIECE * 16, NULL, NULL);
    hid_t root = H5Oopen(w.file, "/", H5P_DEFAULT);
    herr_t r = root < 0 ? fail(&w, "cannot open the root group") : search(&w, root, 1, "/");
    if (root >= 0)
        H5Oclose(root);
    if (r >= 0)
        r = H5Lvisit(w.file, H5_INDEX_NAME, H5_ITER_INC, check_link, &w);
    if (r >= 0)
        r = H5Ovisit2(w.file, H5_INDEX_NAME, H5_ITER_INC, check_object, &w, H5O_INFO_BASIC);
    if (r >= 0 && copyfd >= 0)
        r = send_copy(&w, copyfd);
    if (r < 0) {
        if (!w.why[0])
            snprintf(w.why, sizeof w.why, "its groups cannot be walked");
        leave(src, out, -1); /* (returns for no system error) */
        ssize_t k = write(out, w.why, strlen(w.why));
        (void)k;
        _exit(PROBE_BAD);
    }
    /* Closing frees everything the walk made, and malloc_trim consolidates
     * the heap, where glibc's consistency checks catch a corrupting read
     * that did not crash on its own (it aborts here, not in the caller).
     * H5garbage_collect hands HDF5's free lists back to malloc first. Only
     * this file is closed: H5close would also flush the caller's open
     * outputs, from this copy of the process, into their files. */
    if (H5Fclose(w.file) < 0 || H5garbage_collect() < 0)
        _exit(PROBE_NOOPEN);
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

/* The clean copy the child left in fd (bounded: a copy is about as large as
 * the file it copies). */
static int read_copy(int fd, size_t len, crom_h5probe_copy *out, const char *name)
{
    struct stat st;
    size_t most = 4 * len + ((size_t)16 << 20);
    if (fstat(fd, &st) != 0 || st.st_size <= 0)
        return crom_err(CROM_EINTERNAL, "%s: the checked copy is missing", name);
    if ((size_t)st.st_size > most)
        return crom_err(CROM_EDATA, "%s: corrupt HDF5 file: its copy grew to %lld bytes", name,
                        (long long)st.st_size);
    unsigned char *b = crom_malloc((size_t)st.st_size);
    if (!b)
        return CROM_EINTERNAL;
    size_t got = 0;
    while (got < (size_t)st.st_size) {
        ssize_t k = pread(fd, b + got, (size_t)st.st_size - got, (off_t)got);
        if (k < 0 && errno == EINTR)
            continue;
        if (k <= 0) {
            free(b);
            return crom_err(CROM_EINTERNAL, "%s: the checked copy cannot be read", name);
        }
        got += (size_t)k;
    }
    out->buf = b;
    out->len = got;
    return 0;
}

int crom_h5probe(const crom_h5probe_src *src, const char *name)
{
    size_t len = src->len;
    unsigned secs = probe_seconds(len);
    int fd[2];
    if (pipe(fd) != 0)
        return crom_err(CROM_EINTERNAL, "cannot check %s: pipe: %s", name, strerror(errno));
    int copyfd = -1;
    if (src->copy_out && (copyfd = memfd_create("crom-probe-copy", MFD_CLOEXEC)) < 0) {
        close(fd[0]);
        close(fd[1]);
        return crom_err(CROM_EINTERNAL, "cannot check %s: memfd_create: %s", name, strerror(errno));
    }
    pid_t pid = fork();
    if (pid < 0) {
        close(fd[0]);
        close(fd[1]);
        if (copyfd >= 0)
            close(copyfd);
        return crom_err(CROM_EINTERNAL, "cannot check %s: fork: %s", name, strerror(errno));
    }
    if (pid == 0) {
        close(fd[0]);
        child(src, secs, fd[1], copyfd);
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
    if (WIFEXITED(status) && WEXITSTATUS(status) == PROBE_OK) {
        if (copyfd < 0)
            return 0;
        int rc = read_copy(copyfd, len, src->copy_out, name);
        close(copyfd);
        return rc;
    }
    if (copyfd >= 0)
        close(copyfd);
    if (WIFEXITED(status) && WEXITSTATUS(status) == PROBE_NOOPEN)
        return crom_err(CROM_EDATA, "%s: HDF5 file is truncated or corrupt", name);
    if (WIFEXITED(status) && WEXITSTATUS(status) == PROBE_BAD)
        return crom_err(CROM_EDATA, "%s: corrupt HDF5 file: %s", name, why);
    if (WIFEXITED(status) && WEXITSTATUS(status) == PROBE_SYSERR && atoi(why) > 0)
        return crom_err(CROM_EIO, "%s: %s", name, strerror(atoi(why)));
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
