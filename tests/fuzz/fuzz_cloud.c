/* fuzz_cloud.c — point clouds (lib/mesh/cloud.c crom_cloud_read): the input
 * is a text file of "x y z volume" lines, as crom-fitfield --cloud reads. A
 * cloud that reads must hold finite positive volumes. */
#include <math.h>

#include "base/err.h"
#include "mesh/cloud.h"

#include "fuzz.h"

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc;
    (void)argv;
    fuzz_quiet_stdout();
    return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    const char *path = fuzz_write(data, size, ".xyz");
    crom_cloud c;
    if (crom_cloud_read(path, &c) == 0) {
        for (int i = 0; i < c.n; i++)
            if (!(c.vol[i] > 0) || !isfinite(c.vol[i])) {
                fprintf(stderr, "point %d has volume %g\n", i, c.vol[i]);
                abort();
            }
    }
    crom_cloud_free(&c);
    crom_err_clear();
    return 0;
}
