/* replay.c — runs a harness of tests/fuzz/ without libFuzzer: each argument
 * is an input file, given to LLVMFuzzerTestOneInput once. Built with the
 * normal compiler and libcrom.a, so `make test` (and `make test SANITIZE=1`,
 * under ASan + UBSan) replays the reproducers of tests/fuzz/regress/. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerInitialize(int *argc, char ***argv);

static unsigned char *load(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        perror(path);
        exit(66);
    }
    size_t cap = 1 << 16, n = 0, k;
    unsigned char *buf = malloc(cap);
    while (buf && (k = fread(buf + n, 1, cap - n, f)) > 0)
        if ((n += k) == cap) {
            unsigned char *b = realloc(buf, cap *= 2);
            if (!b)
                free(buf);
            buf = b;
        }
    fclose(f);
    if (!buf)
        exit(70);
    *size = n;
    return buf;
}

int main(int argc, char **argv)
{
    /* every input is read before the harness starts */
    unsigned char **in = calloc((size_t)argc, sizeof *in);
    size_t *len = calloc((size_t)argc, sizeof *len);
    if (!in || !len)
        return 70;
    for (int i = 1; i < argc; i++)
        in[i] = load(argv[i], &len[i]);
    LLVMFuzzerInitialize(&argc, &argv);
    for (int i = 1; i < argc; i++) {
        fprintf(stderr, "replaying %s (%zu bytes)\n", argv[i], len[i]);
        LLVMFuzzerTestOneInput(in[i], len[i]);
        free(in[i]);
    }
    free(in);
    free(len);
    return 0;
}
