/* h5probe.h — look at an untrusted HDF5 file in a contained child process.
 *
 * libhdf5 1.10 (Debian 12) crashes or loops forever on some corrupt files
 * (a damaged global heap behind a variable-length string attribute, a
 * damaged B-tree), and asks its metadata cache for tens of gigabytes on
 * others. crom reads files other people send, so before an input is opened
 * for real, crom_h5probe forks a child that opens it, walks every object,
 * looks every object up by name, reads every attribute with the memory types
 * crom reads them with, checks every dataset's declared size against the
 * bytes the file stores, and reads a piece of each dataset. The child runs
 * under a CPU-time limit, an alarm and (outside AddressSanitizer builds) an
 * address-space limit, with stdout and stderr on /dev/null. A crash, a
 * timeout or a refused allocation there becomes "corrupt HDF5 file" in the
 * caller, which then never hands that file to libhdf5 itself.
 *
 * What the child verifies also bounds every later allocation: an unfiltered
 * dataset must store at least the bytes its shape declares, a filtered one
 * at most 1100 times its stored bytes (deflate's ceiling is 1032:1), and no
 * dataset stores more than the file holds. So a reader that sizes a buffer
 * from a dataset's shape allocates at most about what the file holds.
 *
 * Cost: one fork and one extra open; about 1 ms for a crom file of a few
 * megabytes (README, "Untrusted input").
 */
#ifndef CROM_H5PROBE_H
#define CROM_H5PROBE_H

#include <stddef.h>

#include <hdf5.h>

/* The file to check. replay, called first in the child, opens the file
 * exactly as the caller will right after the check and makes the caller's
 * first reads (its root attributes, say), then returns the open file (or a
 * negative id). As the child is a copy of the caller and allocates nothing
 * before replay, those reads run on the very heap layout the caller's will:
 * a stray read or write that would crash the caller crashes the child
 * instead, even where it would go unnoticed in another layout. len is the
 * file's size in bytes. */
typedef struct {
    void *buf;  /* malloc'd: the caller frees it */
    size_t len;
} crom_h5probe_copy;

typedef struct {
    hid_t (*replay)(void *arg);
    void *arg;
    size_t len;
    /* when copy_out is not NULL, the child also sends back a clean copy of
     * the file (an HDF5 image) for the caller to open instead: written by
     * libhdf5 from what it decoded (attributes read and rewritten, objects
     * copied with H5Ocopy), so the caller's libhdf5 never parses the
     * untrusted bytes at all */
    crom_h5probe_copy *copy_out;
    /* when not NULL: the errno of a system call that failed under libhdf5
     * in this process (0 if none), asked in the child when the file fails
     * to open or to read: a device error is not a corrupt file */
    int (*sys_error)(void);
} crom_h5probe_src;

/* Check the file src describes; name is what messages call it. Returns 0,
 * or CROM_EDATA with a one-line message ("NAME: corrupt HDF5 file: ..."),
 * CROM_EIO when reading it failed in the system ("NAME: Input/output
 * error", from src->sys_error), or CROM_EINTERNAL when no child process can
 * be made. The time limit is
 * 20 s plus 1 s per 100 MB, or CROM_PROBE_SECONDS seconds when that
 * environment variable is a positive integer. */
int crom_h5probe(const crom_h5probe_src *src, const char *name);

#endif
