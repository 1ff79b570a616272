/* system.c — a solid or a shell behind one interface (system.h). */
#include <string.h>

#include "base/err.h"
#include "phys/material.h"
#include "phys/system.h"

int crom_system_init(crom_system *s, const crom_mesh *mesh, double E, double nu, double rho)
{
    memset(s, 0, sizeof *s);
    int rc;
    if (crom_mesh_is_surface(mesh)) {
        crom_shell_material sm;
        if ((rc = crom_shell_material_init(&sm, E, nu, mesh->thickness, rho)) ||
            (rc = crom_shell_init(&s->sh, mesh->nv, mesh->X, mesh->ntri, mesh->tris, &sm)))
            return rc;
        s->shell = 1;
        s->nv = s->sh.nv;
        s->n = s->sh.n;
        s->nnz = s->sh.nnz;
        s->colptr = s->sh.colptr;
        s->rowind = s->sh.rowind;
        s->mass = s->sh.mass;
        s->total_mass = s->sh.total_mass;
        s->nelem = s->sh.nt;
        s->per_elem = 3;
        s->elem = s->sh.tris;
        return CROM_OK;
    }
    crom_material mat;
    if ((rc = crom_material_init(&mat, E, nu, rho)) || (rc = crom_fem_init(&s->fem, mesh, &mat)))
        return rc;
    s->nv = s->fem.nv;
    s->n = s->fem.n;
    s->nnz = s->fem.nnz;
    s->colptr = s->fem.colptr;
    s->rowind = s->fem.rowind;
    s->mass = s->fem.mass;
    s->total_mass = s->fem.total_mass;
    s->nelem = s->fem.nt;
    s->per_elem = 4;
    s->elem = s->fem.tets;
    return CROM_OK;
}

void crom_system_free(crom_system *s)
{
    if (!s)
        return;
    crom_fem_free(&s->fem);
    crom_shell_free(&s->sh);
    memset(s, 0, sizeof *s);
}

int crom_system_assemble(const crom_system *s, const double *x, const crom_fem_opts *o, double *E, double *g,
                         double *H)
{
    return s->shell ? crom_shell_assemble(&s->sh, x, o, E, g, H) : crom_fem_assemble(&s->fem, x, o, E, g, H);
}

int crom_system_energy(const crom_system *s, const double *x, double *E)
{
    return s->shell ? crom_shell_assemble(&s->sh, x, NULL, E, NULL, NULL) : crom_fem_energy(&s->fem, x, E);
}
