/* system.h — the one interface of crom's physical systems (DESIGN.md,
 * "Physical systems"): nv vertices with lumped masses, an elastic energy
 * with gradient and Hessian (true or SPD-projected per element) over a fixed
 * upper-CSC pattern, and the elements that join the vertices. A tet mesh is
 * a stable neo-Hookean solid (fem.h); a surface mesh is a thin shell (StVK
 * membrane and hinge bending, shell.h). What works on a system (full
 * simulation, modes) works on both.
 */
#ifndef CROM_SYSTEM_H
#define CROM_SYSTEM_H

#include "mesh/mesh.h"
#include "phys/fem.h"
#include "phys/shell.h"

typedef struct {
    int shell;            /* 0: a solid (fem), 1: a shell (sh) */
    crom_fem fem;
    crom_shell sh;
    int nv, n, nnz;       /* vertices, 3 nv DOFs, stored Hessian entries */
    const int *colptr, *rowind; /* the upper-CSC pattern, the diagonal last in each column */
    const double *mass;   /* [nv] lumped masses (kg) */
    double total_mass;
    int nelem, per_elem;  /* elements (tets or triangles) and their vertices (4 or 3) */
    const int *elem;      /* [nelem][per_elem] */
} crom_system;

/* The system of mesh (borrowed only during the call) with Young's modulus
 * E, Poisson ratio nu and density rho (a shell takes its thickness from the
 * mesh). Returns CROM_OK or the errors of crom_material_init /
 * crom_shell_material_init, crom_fem_init / crom_shell_init. On failure *s
 * holds nothing to free. */
int crom_system_init(crom_system *s, const crom_mesh *mesh, double E, double nu, double rho);

/* Release (NULL-safe, idempotent). */
void crom_system_free(crom_system *s);

/* Energy, gradient and upper-CSC Hessian at x[nv][3] with the options of
 * crom_fem_assemble (any output may be NULL). */
int crom_system_assemble(const crom_system *s, const double *x, const crom_fem_opts *o, double *E, double *g,
                         double *H);

/* The elastic energy at x. */
int crom_system_energy(const crom_system *s, const double *x, double *E);

#endif
