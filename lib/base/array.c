/* array.c — growable arrays (see array.h). */
#include <stdint.h>
#include <stdlib.h>

#include "base/array.h"
#include "base/err.h"

int crom_array_reserve(void **p, size_t *cap, size_t need, size_t elem)
{
    if (need <= *cap)
        return 0;
    if (elem == 0 || need > SIZE_MAX / elem)
        return crom_err(CROM_EINTERNAL, "an array of %zu elements of %zu bytes is too large", need, elem);
    size_t n = *cap <= SIZE_MAX / 2 ? 2 * *cap : SIZE_MAX;
    if (n < 16)
        n = 16;
    if (n < need)
        n = need;
    if (n > SIZE_MAX / elem) /* doubling would overflow: exactly what is needed */
        n = need;
    void *q = realloc(*p, n * elem);
    if (!q)
        return crom_err(CROM_EINTERNAL, "out of memory (an array of %zu x %zu bytes)", n, elem);
    *p = q;
    *cap = n;
    return 0;
}
