/* array.h — growable arrays (base layer): the one way crom code makes room
 * for more elements in a malloc'ed array whose final length it does not know
 * in advance (a file read to its end, points kept by a test, text built up
 * line by line).
 *
 *     double *X = NULL;   size_t cap = 0, n = 0;
 *     ...
 *     if ((rc = crom_array_reserve((void **)&X, &cap, n + 1, 3 * sizeof *X)))
 *         goto fail;      // X and cap are as they were; free X there
 *     memcpy(X + 3 * n++, p, 3 * sizeof *X);
 */
#ifndef CROM_ARRAY_H
#define CROM_ARRAY_H

#include <stddef.h>

/* Make room for `need` elements of `elem` bytes in the array *p (any object
 * pointer, passed as void **), which has room for *cap: nothing when
 * need <= *cap, else the array is reallocated to hold max(need, 2 *cap, 16)
 * elements (so n appends cost O(n)), its contents kept, and *cap updated.
 * Returns 0, or CROM_EINTERNAL with a message when need * elem overflows
 * size_t, elem is 0, or memory runs out; *p and *cap are then unchanged
 * (the caller still owns and frees *p). */
int crom_array_reserve(void **p, size_t *cap, size_t need, size_t elem);

#endif
