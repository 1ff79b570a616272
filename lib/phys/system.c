/* system.c — a solid or a shell behind one interface (system.h). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "phys/material.h"
#include "phys/system.h"

int crom_system_init(crom_system *s, const crom_mesh *mesh, double E, double nu, double rho)
{
    memset(s, 0, sizeof *s);
    int rc;
    if (crom_mesh_is_scene(mesh)) {
        if ((rc = crom_rigidsys_init(&s->rb, mesh)))
            return rc;
        s->rigid = 1;
        s->nv = s->rb.nv;
        s->n = s->rb.n;
        s->nnz = s->rb.nnz;
        s->colptr = s->rb.colptr;
        s->rowind = s->rb.rowind;
        s->mass = s->rb.mass;
        s->total_mass = s->rb.total_mass;
        s->volume = s->rb.volume;
        s->per_elem = 4;
        s->nenergy = s->rb.nel;
        return CROM_OK;
    }
    if (crom_mesh_is_surface(mesh)) {
        crom_shell_material sm;
        if ((rc = crom_shell_material_init(&sm, E, nu, mesh->thickness, rho)))
            return rc;
        if (mesh->plane) /* a 2-D solid in plane strain */
            crom_shell_material_plane(&sm);
        if ((rc = crom_shell_init(&s->sh, mesh->nv, mesh->X, mesh->ntri, mesh->tris, &sm)))
            return rc;
        s->shell = 1;
        s->nv = s->sh.nv;
        s->n = s->sh.n;
        s->nnz = s->sh.nnz;
        s->colptr = s->sh.colptr;
        s->rowind = s->sh.rowind;
        s->mass = s->sh.mass;
        s->total_mass = s->sh.total_mass;
        s->volume = s->sh.total_area * sm.thickness;
        s->nelem = s->sh.nt;
        s->per_elem = 3;
        s->elem = s->sh.tris;
        s->nenergy = s->sh.nt + s->sh.nh;
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
    s->volume = s->fem.volume;
    s->nelem = s->fem.nt;
    s->per_elem = 4;
    s->elem = s->fem.tets;
    s->nenergy = s->fem.nt;
    return CROM_OK;
}

int crom_system_set_materials(crom_system *s, const crom_scenario *sc, const crom_mesh *mesh)
{
    if (!sc->nmat)
        return 0;
    crom_material *mats = crom_malloc(sizeof *mats * (CROM_SCENARIO_MAX + 1));
    int nmat, *tmat = NULL, rc = mats ? crom_scenario_materials(sc, mesh, mats, &nmat, &tmat) : CROM_EINTERNAL;
    if (!rc && (s->shell || s->rigid || mesh->nt != s->fem.nt))
        rc = crom_err(CROM_EUSAGE, "regions of other materials are for tet meshes");
    if (!rc)
        rc = crom_fem_set_materials(&s->fem, mats, nmat, tmat);
    if (rc) {
        free(mats);
        free(tmat);
        return rc;
    }
    free(s->mats);
    free(s->tmat);
    s->mats = mats;
    s->tmat = tmat;
    s->total_mass = s->fem.total_mass; /* (a region's density changes the lumped masses) */
    return 0;
}

void crom_system_free(crom_system *s)
{
    if (!s)
        return;
    free(s->mats);
    free(s->tmat);
    crom_fem_free(&s->fem);
    crom_shell_free(&s->sh);
    crom_rigidsys_free(&s->rb);
    memset(s, 0, sizeof *s);
}

int crom_system_assemble(const crom_system *s, const double *x, const crom_fem_opts *o, double *E, double *g,
                         double *H)
{
    if (s->rigid)
        return crom_rigidsys_assemble(&s->rb, x, o, E, g, H);
    return s->shell ? crom_shell_assemble(&s->sh, x, o, E, g, H) : crom_fem_assemble(&s->fem, x, o, E, g, H);
}

int crom_system_energy(const crom_system *s, const double *x, double *E)
{
    if (s->rigid)
        return crom_rigidsys_assemble(&s->rb, x, NULL, E, NULL, NULL);
    return s->shell ? crom_shell_assemble(&s->sh, x, NULL, E, NULL, NULL) : crom_fem_energy(&s->fem, x, E);
}

int crom_system_elem_vertices(const crom_system *s, int e, int v[CROM_SYSTEM_MAXV])
{
    if (s->rigid)
        return crom_rigidsys_elem_vertices(&s->rb, e, v);
    if (!s->shell) {
        memcpy(v, s->fem.tets + 4 * (size_t)e, 4 * sizeof(int));
        return 4;
    }
    if (e < s->sh.nt) {
        memcpy(v, s->sh.tris + 3 * (size_t)e, 3 * sizeof(int));
        return 3;
    }
    memcpy(v, s->sh.hinges + 4 * (size_t)(e - s->sh.nt), 4 * sizeof(int));
    return 4;
}

int crom_system_elem_eval(const crom_system *s, int e, const double *xe, int project, double *E, double *g,
                          double *H)
{
    int rc;
    if (s->rigid)
        return crom_rigidsys_elem_eval(&s->rb, e, xe, project, E, g, H);
    if (!s->shell) {
        const crom_fem *f = &s->fem;
        rc = crom_fem_tet_eval(crom_fem_tet_material(f, e), xe, f->Dminv + 9 * (size_t)e, f->vol[e], project, E, g, H);
        if (rc)
            crom_err_clear(); /* the caller names the element */
        return rc ? CROM_EDATA : CROM_OK;
    }
    const crom_shell *sh = &s->sh;
    if (e < sh->nt)
        rc = crom_shell_tri_eval(&sh->mat, xe, sh->Dminv + 4 * (size_t)e, sh->area[e], project, E, g, H);
    else
        rc = crom_shell_hinge_eval(sh->hk[e - sh->nt], sh->theta0[e - sh->nt], xe, project, E, g, H);
    return rc ? CROM_EDATA : CROM_OK;
}

double crom_system_elem_energy(const crom_system *s, int e, const double *xe)
{
    if (!s->shell && !s->rigid) {
        const crom_fem *f = &s->fem;
        return crom_fem_tet_energy(crom_fem_tet_material(f, e), xe, f->Dminv + 9 * (size_t)e, f->vol[e]);
    }
    double E;
    return crom_system_elem_eval(s, e, xe, 0, &E, NULL, NULL) ? NAN : E;
}

double crom_system_elem_measure(const crom_system *s, int e)
{
    if (s->rigid)
        return 0;
    if (!s->shell)
        return s->fem.vol[e];
    return e < s->sh.nt ? s->sh.area[e] : 0;
}
