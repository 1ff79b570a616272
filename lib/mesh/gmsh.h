/* gmsh.h — one gmsh session: the start-up, the logger and the checked call
 * that every use of the gmsh C API in crom shares (meshing shapes and
 * surfaces, refining meshes, writing .msh files).
 *
 * gmsh keeps global state (its models, options and logger) that its C API
 * does not let a caller own: a session is begun before and ended after each
 * use and never nested. gmsh prints its messages to stdout, which would
 * corrupt a crom stream: General.Terminal is switched off and messages are
 * kept by gmsh's logger, which crom_gmsh_end hands to a caller's function
 * (a program prints them with --verbose; the library never does).
 */
#ifndef CROM_GMSH_H
#define CROM_GMSH_H

#include <gmshc.h>

/* Receives each line gmsh logged during a session. */
typedef void (*crom_gmsh_log_fn)(void *ctx, const char *line);

/* Begin a session: initialize gmsh with no terminal output, its verbosity 4
 * (log_fn given: the caller wants the messages) or 2, not aborting on
 * errors, and start the logger. Returns 0 or CROM_EINTERNAL. */
int crom_gmsh_begin(crom_gmsh_log_fn log_fn);

/* End the session: hand every logged line, as "gmsh: LINE", to log_fn (if
 * not NULL) with ctx,
 * stop the logger and finalize gmsh. */
void crom_gmsh_end(crom_gmsh_log_fn log_fn, void *ctx);

/* After a gmsh call failed with ierr: record "gmsh could not WHAT: <gmsh's
 * last error> (error IERR)" and return CROM_EDATA (gmsh fails on what it is
 * given: a surface it cannot mesh, a mesh it cannot refine). */
int crom_gmsh_fail(int ierr, const char *what);

/* The nodes of the model gmsh holds and its elements of one type (2: 3-node
 * triangles, 4: 4-node tetrahedra), with the map from node tags to node
 * indices 0 … nn−1 (tags up to maxtag; −1: no node). */
typedef struct {
    size_t nn, ne, per, maxtag;
    double *coord;   /* [nn][3] (gmsh's) */
    size_t *enodes;  /* [ne][per] node tags (gmsh's) */
    int *map;        /* [maxtag + 1] */
} crom_gmsh_mesh;

/* Read them (g cleared first; free it with crom_gmsh_mesh_free, also on
 * failure); what names the elements in messages ("triangles"). Returns 0,
 * CROM_EDATA (gmsh failed, an element names an unknown node) or
 * CROM_EINTERNAL. */
int crom_gmsh_mesh_read(int etype, const char *what, crom_gmsh_mesh *g);
void crom_gmsh_mesh_free(crom_gmsh_mesh *g);

/* Run one gmsh call with the caller's `int ierr, rc` in scope; on failure
 * set rc = crom_gmsh_fail(ierr, what) and `goto out`. */
#define CROM_GMSH(call, what)                                                                      \
    do {                                                                                           \
        ierr = 0;                                                                                  \
        call;                                                                                      \
        if (ierr) {                                                                                \
            rc = crom_gmsh_fail(ierr, what);                                                       \
            goto out;                                                                              \
        }                                                                                          \
    } while (0)

#endif
