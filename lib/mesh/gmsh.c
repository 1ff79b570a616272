/* gmsh.c — one gmsh session (see gmsh.h). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

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

int crom_gmsh_mesh_read(int etype, const char *what, crom_gmsh_mesh *g)
{
    memset(g, 0, sizeof *g);
    int ierr = 0, rc = 0;
    size_t *ntags = NULL, nc = 0, np = 0, *etags = NULL, nen = 0;
    double *param = NULL;
    g->per = etype == 2 ? 3 : 4;
    CROM_GMSH(gmshModelMeshGetNodes(&ntags, &g->nn, &g->coord, &nc, &param, &np, -1, -1, 0, 0, &ierr),
              "read the nodes");
    char msg[64];
    snprintf(msg, sizeof msg, "read the %s", what);
    CROM_GMSH(gmshModelMeshGetElementsByType(etype, &etags, &g->ne, &g->enodes, &nen, -1, 0, 1, &ierr), msg);
    for (size_t i = 0; i < g->nn; i++)
        g->maxtag = ntags[i] > g->maxtag ? ntags[i] : g->maxtag;
    if (!(g->map = crom_malloc(sizeof(int) * (g->maxtag + 1)))) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    for (size_t i = 0; i <= g->maxtag; i++)
        g->map[i] = -1;
    for (size_t i = 0; i < g->nn; i++)
        g->map[ntags[i]] = (int)i;
    for (size_t k = 0; k < g->per * g->ne; k++)
        if (g->enodes[k] > g->maxtag || g->map[g->enodes[k]] < 0) {
            rc = crom_err(CROM_EDATA, "gmsh: one of the %s refers to an unknown node", what);
            goto out;
        }
out:
    if (ntags)
        gmshFree(ntags);
    if (param)
        gmshFree(param);
    if (etags)
        gmshFree(etags);
    return rc;
}

void crom_gmsh_mesh_free(crom_gmsh_mesh *g)
{
    if (g->coord)
        gmshFree(g->coord);
    if (g->enodes)
        gmshFree(g->enodes);
    free(g->map);
    memset(g, 0, sizeof *g);
}
