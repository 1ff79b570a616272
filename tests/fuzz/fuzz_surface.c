/* fuzz_surface.c — surface import (lib/mesh/surface.c crom_surface_read):
 * the input is an .stl file (ASCII or binary) or, built with -DFUZZ_OBJ, an
 * .obj file. A surface that reads is then checked the way crom-mesh checks
 * it (closed, oriented, manifold) and its median edge taken. */
#include "base/err.h"
#include "mesh/surface.h"

#include "fuzz.h"

#ifdef FUZZ_OBJ
#define EXT ".obj"
#else
#define EXT ".stl"
#endif

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc;
    (void)argv;
    fuzz_quiet_stdout();
    return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    const char *path = fuzz_write(data, size, EXT);
    crom_surface s = {0};
    if (crom_surface_read(path, &s) == 0) {
        for (size_t j = 0; j < 3 * (size_t)s.nt; j++)
            if (s.T[j] < 0 || s.T[j] >= s.nv) {
                fprintf(stderr, "triangle vertex %d out of range [0, %d)\n", s.T[j], s.nv);
                abort();
            }
        crom_surface_check_closed(&s, path);
        crom_surface_median_edge(&s);
    }
    crom_surface_free(&s);
    crom_err_clear();
    return 0;
}
