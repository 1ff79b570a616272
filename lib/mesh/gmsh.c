/* gmsh.c — one gmsh session (see gmsh.h). */
#include <stdio.h>

#include "base/err.h"
#include "mesh/gmsh.h"

int crom_gmsh_begin(crom_gmsh_log_fn log_fn)
{
    int ierr = 0;
    gmshInitialize(0, NULL, 0, &ierr);
    if (ierr)
        return crom_err(CROM_EINTERNAL, "gmsh could not start (error %d)", ierr);
    gmshOptionSetNumber("General.Terminal", 0, &ierr);
    gmshOptionSetNumber("General.Verbosity", log_fn ? 4 : 2, &ierr);
    gmshOptionSetNumber("General.AbortOnError", 0, &ierr);
    gmshLoggerStart(&ierr);
    return 0;
}

void crom_gmsh_end(crom_gmsh_log_fn log_fn, void *ctx)
{
    int ierr = 0;
    if (log_fn) {
        char **log = NULL;
        size_t n = 0;
        gmshLoggerGet(&log, &n, &ierr);
        for (size_t i = 0; i < n; i++) {
            char line[1024]; /* "gmsh: " and the message, cut at 1 KB */
            snprintf(line, sizeof line, "gmsh: %s", log[i]);
            log_fn(ctx, line);
            gmshFree(log[i]);
        }
        if (log)
            gmshFree(log);
    }
    gmshLoggerStop(&ierr);
    gmshFinalize(&ierr);
}

int crom_gmsh_fail(int ierr, const char *what)
{
    char *msg = NULL;
    int e2 = 0;
    gmshLoggerGetLastError(&msg, &e2);
    int rc = crom_err(CROM_EDATA, "gmsh could not %s%s%s (error %d)", what, msg && *msg ? ": " : "",
                      msg ? msg : "", ierr);
    if (msg)
        gmshFree(msg);
    return rc;
}
