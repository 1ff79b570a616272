/* parse.c — numbers from text, checked (see parse.h). */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "base/parse.h"

int crom_parse_double(const char *s, const char *what, double *out)
{
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    if (end == s || *end || errno == ERANGE)
        return crom_err(CROM_EUSAGE, "%s: '%s' is not a number", what, s);
    if (!isfinite(v))
        return crom_err(CROM_EUSAGE, "%s: '%s' is not a finite number", what, s);
    *out = v;
    return 0;
}

int crom_parse_positive(const char *s, const char *what, double *out)
{
    int rc = crom_parse_double(s, what, out);
    if (rc)
        return rc;
    if (!(*out > 0))
        return crom_err(CROM_EUSAGE, "%s: must be positive, got %s", what, s);
    return 0;
}

int crom_parse_int(const char *s, const char *what, long lo, long hi, long *out)
{
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (end == s || *end || errno)
        return crom_err(CROM_EUSAGE, "%s: '%s' is not an integer", what, s);
    if (v < lo || v > hi)
        return crom_err(CROM_EUSAGE, "%s: %ld is out of range [%ld, %ld]", what, v, lo, hi);
    *out = v;
    return 0;
}

int crom_parse_doubles_var(const char *s, const char *what, int nmin, int nmax,
                           double *out, int *n)
{
    int k = 0;
    const char *p = s;
    char buf[128];
    for (;;) {
        const char *e = strchr(p, ',');
        size_t len = e ? (size_t)(e - p) : strlen(p);
        if (len >= sizeof buf)
            return crom_err(CROM_EUSAGE, "%s: value too long in '%s'", what, s);
        if (k >= nmax)
            return crom_err(CROM_EUSAGE, "%s: expected at most %d comma-separated numbers, got more in '%s'",
                            what, nmax, s);
        memcpy(buf, p, len);
        buf[len] = 0;
        int rc = crom_parse_double(buf, what, &out[k]);
        if (rc)
            return rc;
        k++;
        if (!e)
            break;
        p = e + 1;
    }
    if (k < nmin) {
        if (nmin == nmax)
            return crom_err(CROM_EUSAGE, "%s: expected %d comma-separated numbers, got %d in '%s'",
                            what, nmin, k, s);
        return crom_err(CROM_EUSAGE, "%s: expected at least %d comma-separated numbers, got %d in '%s'",
                        what, nmin, k, s);
    }
    *n = k;
    return 0;
}

int crom_parse_doubles(const char *s, const char *what, int n, double *out)
{
    int k;
    return crom_parse_doubles_var(s, what, n, n, out, &k);
}
