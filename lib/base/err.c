/* err.c — per-thread error message and code. */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"

static _Thread_local char err_msg[1024];
static _Thread_local int err_code;

int crom_err(int code, const char *fmt, ...)
{
    /* formatted aside first: callers may pass crom_errmsg() as an argument
     * ("%s: %s", name, crom_errmsg()), which vsnprintf must not overwrite
     * while it reads it */
    char msg[sizeof err_msg];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    memcpy(err_msg, msg, sizeof msg);
    err_code = code;
    return code;
}

int crom_err_ctx(const char *fmt, ...)
{
    char prefix[512], old[sizeof err_msg];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(prefix, sizeof prefix, fmt, ap);
    va_end(ap);
    memcpy(old, err_msg, sizeof old);
    size_t lp = strlen(prefix), lo = strlen(old);
    if (lp + 2 + lo >= sizeof err_msg)
        lo = sizeof err_msg - lp - 3;
    memcpy(err_msg, prefix, lp);
    memcpy(err_msg + lp, ": ", 2);
    memcpy(err_msg + lp + 2, old, lo);
    err_msg[lp + 2 + lo] = 0;
    if (!err_code)
        err_code = CROM_EINTERNAL;
    return err_code;
}

const char *crom_errmsg(void) { return err_msg; }
int crom_errcode(void) { return err_code; }

void crom_err_clear(void)
{
    err_msg[0] = 0;
    err_code = 0;
}

void *crom_malloc(size_t n)
{
    void *p = malloc(n ? n : 1);
    if (!p)
        crom_err(CROM_EINTERNAL, "out of memory (%zu bytes)", n);
    return p;
}

void *crom_calloc(size_t n, size_t size)
{
    void *p = calloc(n ? n : 1, size ? size : 1);
    if (!p)
        crom_err(CROM_EINTERNAL, "out of memory (%zu x %zu bytes)", n, size);
    return p;
}

void *crom_realloc(void *p, size_t n)
{
    void *q = realloc(p, n ? n : 1);
    if (!q)
        crom_err(CROM_EINTERNAL, "out of memory (%zu bytes)", n);
    return q;
}

char *crom_strdup(const char *s)
{
    size_t n = strlen(s) + 1;
    char *p = crom_malloc(n);
    if (p)
        memcpy(p, s, n);
    return p;
}
