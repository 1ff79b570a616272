/* system.h — the one interface of crom's physical systems (DESIGN.md,
 * "Physical systems"): nv vertices with lumped masses, an elastic energy
 * with gradient and Hessian (true or SPD-projected per element) over a fixed
 * upper-CSC pattern, and the elements that join the vertices. A tet mesh is
 * a stable neo-Hookean solid (fem.h); a surface mesh is a thin shell (StVK
 * membrane and hinge bending, shell.h); a rigid-body scene is bodies held by
 * penalties (rigidsys.h). What works on a system (full simulation, modes)
 * works on all of them.
 */
#ifndef CROM_SYSTEM_H
#define CROM_SYSTEM_H

#include "mesh/mesh.h"
#include "phys/fem.h"
#include "phys/rigidsys.h"
#include "phys/scenario.h"
#include "phys/shell.h"

/* the most vertices an energy element joins (a joint between two bodies) */
#define CROM_SYSTEM_MAXV CROM_RIGIDSYS_MAXV

typedef struct {
    int shell;            /* 0: a solid (fem), 1: a shell (sh) */
    int rigid;            /* 1: a rigid-body scene (rb) */
    crom_fem fem;
    crom_shell sh;
    crom_rigidsys rb;
    int nv, n, nnz;       /* vertices, 3 nv DOFs, stored Hessian entries */
    const int *colptr, *rowind; /* the upper-CSC pattern, the diagonal last in each column */
    const double *mass;   /* [nv] lumped masses (kg) */
    double total_mass;
    double volume;        /* m³: the solid's, or a shell's area times its thickness */
    int nelem, per_elem;  /* elements (tets or triangles) and their vertices (4 or 3); a scene: 0 */
    const int *elem;      /* [nelem][per_elem] */
    int nenergy;          /* energy elements: the tets, or the triangles then the hinges */
    crom_material *mats;  /* regions of other materials (crom_system_set_materials), owned */
    int *tmat;
} crom_system;

/* The system of mesh (borrowed only during the call) with Young's modulus
 * E, Poisson ratio nu and density rho (a shell takes its thickness from the
 * mesh; a scene its densities from its bodies, and E and nu are unused).
 * Returns CROM_OK or the errors of crom_material_init /
 * crom_shell_material_init, crom_fem_init / crom_shell_init /
 * crom_rigidsys_init. On failure *s
 * holds nothing to free. */
int crom_system_init(crom_system *s, const crom_mesh *mesh, double E, double nu, double rho);

/* The regions of other materials of scenario sc (--youngs REGION=E,
 * --poisson REGION=NU; crom_scenario_materials) on the mesh of s (a
 * solid's). Nothing to do without such regions. Returns 0 or CROM_EUSAGE
 * (a region not on the mesh, holding no whole tet; a shell or a scene). */
int crom_system_set_materials(crom_system *s, const crom_scenario *sc, const crom_mesh *mesh);

/* Release (NULL-safe, idempotent). */
void crom_system_free(crom_system *s);

/* Energy, gradient and upper-CSC Hessian at x[nv][3] with the options of
 * crom_fem_assemble (any output may be NULL). */
int crom_system_assemble(const crom_system *s, const double *x, const crom_fem_opts *o, double *E, double *g,
                         double *H);

/* The elastic energy at x. */
int crom_system_energy(const crom_system *s, const double *x, double *E);

/* ---- Energy elements ----------------------------------------------------
 * The elastic energy is a sum over nenergy elements, each a function of the
 * positions of 3 to CROM_SYSTEM_MAXV vertices: a solid's tets (fem.h), a
 * shell's membrane triangles (indices 0 … nt−1) then its hinges (nt …
 * nt+nh−1, shell.h), or a scene's bodies then its joints (rigidsys.h). Reduced simulation and data-free training integrate the energy
 * element by element, over all of them or a weighted cubature of them,
 * through these three calls, whatever the system. */

/* The vertices of energy element e into v[CROM_SYSTEM_MAXV]; returns their
 * count k (3, 4 or 8). */
int crom_system_elem_vertices(const crom_system *s, int e, int v[CROM_SYSTEM_MAXV]);

/* Energy, gradient g[3k] and Hessian H[3k][3k] (row-major; any of E, g, H
 * may be NULL) of energy element e at the positions xe[3k] of its vertices
 * in the order of crom_system_elem_vertices; project != 0: the element
 * Hessian projected to SPD. Returns CROM_OK or CROM_EDATA (no message) when
 * a result is not finite. */
int crom_system_elem_eval(const crom_system *s, int e, const double *xe, int project, double *E, double *g,
                          double *H);

/* The energy of element e alone at xe[3k] (NaN when not finite). */
double crom_system_elem_energy(const crom_system *s, int e, const double *xe);

/* The rest measure of element e: a tet's volume or a triangle's area (m³,
 * m²); 0 for a hinge or a scene's element. */
double crom_system_elem_measure(const crom_system *s, int e);

#endif
