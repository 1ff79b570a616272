/* err.h — error reporting for the crom library.
 *
 * Library functions never print and never exit: on failure they record a
 * one-line message and return a status code (the sysexits-style codes
 * below). Programs in bin/ print the message as "crom-STAGE: message" and exit
 * with the code. The message is kept per thread, like errno.
 */
#ifndef CROM_ERR_H
#define CROM_ERR_H

#include <stddef.h>

enum {
    CROM_OK        = 0,
    CROM_EUSAGE    = 64,  /* bad command line */
    CROM_EDATA     = 65,  /* bad input data */
    CROM_ENOINPUT  = 66,  /* input missing or unreadable */
    CROM_EINTERNAL = 70,  /* internal error (a bug, or a library failure) */
    CROM_ECANTCREAT= 73,  /* cannot create output */
    CROM_EIO       = 74   /* I/O error */
};

/* Record a printf-style message and return `code` (so `return crom_err(...)`). */
int crom_err(int code, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));

/* Prefix the current message with "context: " and return the current code;
 * used to add a file name or stage on the way up. */
int crom_err_ctx(const char *fmt, ...) __attribute__((format(printf, 1, 2)));

/* The last message recorded in this thread ("" if none). */
const char *crom_errmsg(void);

/* The last code recorded in this thread (0 if none). */
int crom_errcode(void);

/* Forget the last error. */
void crom_err_clear(void);

/* Helper used by allocation wrappers: malloc that records an error on failure. */
void *crom_malloc(size_t n);
void *crom_calloc(size_t n, size_t size);
void *crom_realloc(void *p, size_t n);
char *crom_strdup(const char *s);

#endif
