/* fuzz_stream.c — frame streams (schemas/stream.md) read to the end with
 * crom_in_open and crom_in_next (lib/io/io.c), as every reader of a time
 * series does.
 *
 * fuzz_stream: the input is a whole stream, header and HDF5 image included.
 * fuzz_frames (built with -DFUZZ_FRAMES): the input is what follows the
 * header, the frame and end records; the header is a fixed, valid one made
 * at start-up by crom_out (a crom/latent series with fields time, q[3],
 * qdot[3]: 7 doubles a frame), so every input exercises the framing and none
 * is spent on the HDF5 image.
 *
 * Besides not crashing: frames come in order, a stream that ends says so
 * (complete is 0 or 1 at the end), and the frame count is the cursor. */
#include "base/err.h"
#include "io/io.h"

#include "fuzz.h"

#ifdef FUZZ_FRAMES
static unsigned char *header;
static size_t header_len;

/* A valid stream header: written by crom_out to a scratch file, cut at the
 * first record (24 bytes + the image length). */
static void make_header(void)
{
    char path[600];
    snprintf(path, sizeof path, "%s.hdr", fuzz_path(".stream"));
    crom_out o;
    hsize_t r = 3;
    if (crom_out_create(&o, path, "crom/latent", 1, "crom-fuzz", NULL, CROM_OUT_SERIES_STREAM) ||
        crom_h5_set_str(o.h5, ".", "model_id", "fuzz") || crom_h5_set_i64(o.h5, ".", "rank", 3) ||
        crom_out_field(&o, "time", 0, NULL, "mlp") || crom_out_field(&o, "q", 1, &r, "mlp") ||
        crom_out_field(&o, "qdot", 1, &r, "mlp") || crom_out_begin(&o) || crom_out_commit(&o)) {
        fprintf(stderr, "fuzz_frames: cannot write a stream header: %s\n", crom_errmsg());
        abort();
    }
    FILE *f = fopen(path, "rb");
    unsigned char head[24];
    if (!f || fread(head, 1, 24, f) != 24)
        abort();
    uint64_t h;
    memcpy(&h, head + 16, 8);
    header_len = 24 + (size_t)h;
    header = malloc(header_len);
    rewind(f);
    if (!header || fread(header, 1, header_len, f) != header_len)
        abort();
    fclose(f);
    unlink(path);
}
#endif

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc;
    (void)argv;
    fuzz_quiet_stdout();
#ifdef FUZZ_FRAMES
    make_header();
#endif
    return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
#ifdef FUZZ_FRAMES
    const char *path = fuzz_path(".stream");
    FILE *f = fopen(path, "wb");
    if (!f || fwrite(header, 1, header_len, f) != header_len || (size && fwrite(data, 1, size, f) != size) ||
        fclose(f) != 0)
        abort();
#else
    const char *path = fuzz_write(data, size, ".stream");
#endif
    crom_in in;
    if (crom_in_open(&in, path) == 0) {
#ifdef FUZZ_FRAMES
        if (in.form != CROM_IO_STREAM || in.frame_len != 7 || in.nfields != 3)
            abort();
#endif
        int rc;
        long n = 0;
        while ((rc = crom_in_next(&in)) == 1) {
            n++;
            if (in.cursor != n)
                abort();
            for (int i = 0; i < in.nfields; i++)
                (void)crom_in_get(&in, i);
        }
        if (rc == 0 && in.form == CROM_IO_STREAM && in.complete != 0 && in.complete != 1) {
            fprintf(stderr, "stream ended with complete = %d\n", in.complete);
            abort();
        }
        crom_in_close(&in);
    }
    crom_err_clear();
    return 0;
}
