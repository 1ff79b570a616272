/* test_array.c — the growable array: nothing to do for no elements or for
 * room already there, growth by doubling (16 at first) that keeps the
 * contents, exactly what is asked when that is more than double, and
 * refusal of sizes that overflow size_t with the array left as it was. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "base/array.h"
#include "base/err.h"

int main(void)
{
    check_begin("test_array");
    /* zero: an empty array asked for no room stays empty, unallocated */
    int *a = NULL;
    size_t cap = 0;
    CHECK(crom_array_reserve((void **)&a, &cap, 0, sizeof *a) == 0);
    CHECK(a == NULL && cap == 0);

    /* growth: 16 at first, then doubling; contents kept */
    CHECK(crom_array_reserve((void **)&a, &cap, 1, sizeof *a) == 0);
    CHECK(a != NULL && cap == 16);
    size_t n = 0, grew = 0, last = cap;
    for (int i = 0; i < 1000; i++) {
        CHECK(crom_array_reserve((void **)&a, &cap, n + 1, sizeof *a) == 0);
        if (cap != last) {
            CHECK_MSG(cap == 2 * last, "capacity %zu after %zu", cap, last);
            grew++;
            last = cap;
        }
        a[n++] = 7 * i;
    }
    CHECK(cap == 1024 && grew == 6); /* 16 -> 32 -> ... -> 1024 */
    int same = 1;
    for (int i = 0; i < 1000; i++)
        same &= a[i] == 7 * i;
    CHECK(same);
    /* room already there: unchanged */
    int *before = a;
    CHECK(crom_array_reserve((void **)&a, &cap, 1024, sizeof *a) == 0);
    CHECK(a == before && cap == 1024);
    /* more than double: exactly what is asked */
    CHECK(crom_array_reserve((void **)&a, &cap, 5000, sizeof *a) == 0);
    CHECK(cap == 5000 && a[999] == 6993);

    /* overflow: need * elem beyond size_t, and a zero element size, are
     * refused with a message; the array is untouched and still owned */
    crom_err_clear();
    before = a;
    CHECK(crom_array_reserve((void **)&a, &cap, SIZE_MAX / sizeof *a + 1, sizeof *a) == CROM_EINTERNAL);
    CHECK(a == before && cap == 5000 && a[999] == 6993);
    CHECK(strstr(crom_errmsg(), "too large") != NULL);
    CHECK(crom_array_reserve((void **)&a, &cap, SIZE_MAX, 2) == CROM_EINTERNAL);
    CHECK(crom_array_reserve((void **)&a, &cap, 6000, 0) == CROM_EINTERNAL);
    CHECK(a == before && cap == 5000);
    free(a);
    return check_done();
}
