/* fuzz.h — what crom's libFuzzer harnesses share (tests/fuzz/README.md).
 *
 * Each harness defines LLVMFuzzerTestOneInput for one reader of lib/. Most
 * readers take a path, so the input bytes are written to a scratch file
 * first: one per process, in /dev/shm when it is there (else $TMPDIR or
 * /tmp), removed at exit. A harness frees everything the reader returned, so
 * LeakSanitizer reports any leak of the reader itself.
 *
 * The same harnesses are linked with replay.c (no libFuzzer) to replay the
 * reproducers of tests/fuzz/regress/ in `make test`.
 */
#ifndef CROM_FUZZ_H
#define CROM_FUZZ_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerInitialize(int *argc, char ***argv);

static char fuzz_path_buf[512];

__attribute__((unused)) static void fuzz_unlink(void)
{
    if (fuzz_path_buf[0])
        unlink(fuzz_path_buf);
}

/* The scratch file's name, ending in ext (".stl", ".h5", ...). */
__attribute__((unused)) static const char *fuzz_path(const char *ext)
{
    if (!fuzz_path_buf[0]) {
        const char *dir = access("/dev/shm", W_OK) == 0 ? "/dev/shm" : getenv("TMPDIR");
        snprintf(fuzz_path_buf, sizeof fuzz_path_buf, "%s/crom-fuzz-%d%s", dir && *dir ? dir : "/tmp",
                 (int)getpid(), ext);
        atexit(fuzz_unlink);
    }
    return fuzz_path_buf;
}

/* Write the input to the scratch file; returns its path (aborts if it cannot:
 * a harness that silently tests nothing would pass). */
__attribute__((unused)) static const char *fuzz_write(const uint8_t *data, size_t size, const char *ext)
{
    const char *path = fuzz_path(ext);
    FILE *f = fopen(path, "wb");
    if (!f || (size && fwrite(data, 1, size, f) != size) || fclose(f) != 0) {
        perror(path);
        abort();
    }
    return path;
}

/* Programs print; the library must not. Anything printed on stdout by a
 * reader is thrown away (stdout of a fuzzer is its own log). */
__attribute__((unused)) static void fuzz_quiet_stdout(void)
{
    if (!freopen("/dev/null", "w", stdout))
        abort();
}

#endif
