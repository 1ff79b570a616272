/* parse.c — numbers from text, checked (see parse.h). */
#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "base/parse.h"

/* 1 if s is a decimal number: [+-]digits[.digits][(e|E)[+-]digits], with
 * digits on at least one side of the point; nothing before or after. */
static int is_decimal(const char *s)
{
    const char *p = s;
    int digits = 0;
    if (*p == '+' || *p == '-')
        p++;
    for (; isdigit((unsigned char)*p); p++)
        digits++;
    if (*p == '.')
        for (p++; isdigit((unsigned char)*p); p++)
            digits++;
    if (!digits)
        return 0;
    if (*p == 'e' || *p == 'E') {
        p++;
        if (*p == '+' || *p == '-')
            p++;
        if (!isdigit((unsigned char)*p))
            return 0;
        while (isdigit((unsigned char)*p))
            p++;
    }
    return !*p;
}

int crom_parse_double(const char *s, const char *what, double *out)
{
    char *end;
    if (!is_decimal(s)) {
        double v = strtod(s, &end);
        if (end != s && !*end && !isfinite(v))
            return crom_err(CROM_EUSAGE, "%s: '%s' is not a finite number", what, s);
        if (end != s && !*end && strpbrk(s, "xX"))
            return crom_err(CROM_EUSAGE, "%s: '%s' is not a decimal number", what, s);
        return crom_err(CROM_EUSAGE, "%s: '%s' is not a number", what, s);
    }
    errno = 0;
    double v = strtod(s, &end);
    if (errno == ERANGE || !isfinite(v))
        return crom_err(CROM_EUSAGE, "%s: '%s' is out of the range of a double", what, s);
    if (fabs(v) > CROM_PARSE_MAX)
        return crom_err(CROM_EUSAGE, "%s: %s is out of range (at most %g in magnitude)", what, s, CROM_PARSE_MAX);
    *out = v;
    return 0;
}

int crom_parse_range(const char *s, const char *what, double lo, double hi, double *out)
{
    double v;
    int rc = crom_parse_double(s, what, &v);
    if (rc)
        return rc;
    if (!(v >= lo && v <= hi))
        return crom_err(CROM_EUSAGE, "%s: %s is out of range [%g, %g]", what, s, lo, hi);
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
    char *end = (char *)s;
    errno = 0;
    const char *d = s + (*s == '+' || *s == '-');
    long v = isdigit((unsigned char)*d) ? strtol(s, &end, 10) : 0;
    if (!isdigit((unsigned char)*d) || *end)
        return crom_err(CROM_EUSAGE, "%s: '%s' is not an integer", what, s);
    if (errno)
        return crom_err(CROM_EUSAGE, "%s: %s is out of range [%ld, %ld]", what, s, lo, hi);
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
