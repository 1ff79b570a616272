/* eio_shim.c — an LD_PRELOAD library for tests/prog/faults.sh: pwrite(2)
 * and write(2) to a file whose name contains $CROM_EIO_MATCH fail with EIO
 * once $CROM_EIO_AFTER bytes (default 0) have been written to it, the way a
 * failing disk answers; with $CROM_EIO_READ=1, pread(2) from such a file
 * fails instead, once that many bytes have been read. Only calls made through the PLT are seen (HDF5's
 * file driver), not glibc's stdio, which calls write internally. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/types.h>
#include <unistd.h>

static long long written, nread;

static int doomed_count(int fd, size_t n, long long *count);
static int doomed(int fd, size_t n)
{
    const char *rd = getenv("CROM_EIO_READ");
    return rd && *rd == '1' ? 0 : doomed_count(fd, n, &written);
}

static int doomed_count(int fd, size_t n, long long *count)
{
    const char *match = getenv("CROM_EIO_MATCH");
    if (!match || !*match)
        return 0;
    char link[64], path[PATH_MAX];
    snprintf(link, sizeof link, "/proc/self/fd/%d", fd);
    ssize_t len = readlink(link, path, sizeof path - 1);
    if (len <= 0)
        return 0;
    path[len] = 0;
    if (!strstr(path, match))
        return 0;
    const char *after = getenv("CROM_EIO_AFTER");
    if (*count + (long long)n <= (after ? atoll(after) : 0)) {
        *count += (long long)n;
        return 0;
    }
    return 1;
}

ssize_t pwrite(int fd, const void *buf, size_t n, off_t off)
{
    static ssize_t (*real)(int, const void *, size_t, off_t);
    if (!real)
        real = (ssize_t (*)(int, const void *, size_t, off_t))dlsym(RTLD_NEXT, "pwrite");
    if (doomed(fd, n)) {
        errno = EIO;
        return -1;
    }
    return real(fd, buf, n, off);
}

ssize_t write(int fd, const void *buf, size_t n)
{
    static ssize_t (*real)(int, const void *, size_t);
    if (!real)
        real = (ssize_t (*)(int, const void *, size_t))dlsym(RTLD_NEXT, "write");
    if (doomed(fd, n)) {
        errno = EIO;
        return -1;
    }
    return real(fd, buf, n);
}

ssize_t pread(int fd, void *buf, size_t n, off_t off)
{
    static ssize_t (*real)(int, void *, size_t, off_t);
    if (!real)
        real = (ssize_t (*)(int, void *, size_t, off_t))dlsym(RTLD_NEXT, "pread");
    const char *rd = getenv("CROM_EIO_READ");
    if (rd && *rd == '1' && doomed_count(fd, n, &nread)) {
        errno = EIO;
        return -1;
    }
    return real(fd, buf, n, off);
}
