/* project.h — a displacement field on a mesh as latent coordinates of a
 * linear basis: the least-squares fit in the mass-weighted norm of the mesh
 * (crom-encode; LiCROM's projection of full states onto the subspace),
 *
 *   q = argmin_q Σ_v w_v |W(X_v) q − f_v|²  =  G⁻¹ Σ_v w_v W_vᵀ f_v,
 *   G = Σ_v w_v W_vᵀ W_v,
 *
 * with w_v the lumped vertex volumes over the mesh's volume (the lumped mass
 * up to the density, which cancels): a discretization-independent
 * approximation of the L² norm over the body. W is evaluated at the mesh's
 * field points (crom_mesh_field_points, so the two sides of a cut are told
 * apart). */
#ifndef CROM_PROJECT_H
#define CROM_PROJECT_H

#include <stddef.h>

#include "mesh/mesh.h"
#include "rom/model.h"

typedef struct {
    int nv, r;
    double *W;  /* [nv][3][r] the basis at the vertices */
    double *w;  /* [nv] weights: lumped vertex volumes / total volume */
    double *L;  /* [r][r] Cholesky factor of G (column-major, lower) */
    double *wf; /* [3 nv] scratch */
} crom_project;

/* Set up the projection onto the basis of model (linear: crom_model_eval)
 * at the vertices of mesh. *noutside (may be NULL) gets how many vertices
 * lie outside a mesh-field model's mesh (W is extended there). Returns 0,
 * CROM_EDATA when the basis is (nearly) zero on part of its span or
 * rank-deficient at these vertices, the errors of crom_model_eval, or
 * CROM_EINTERNAL. p is left empty on failure. */
int crom_project_init(crom_project *p, const crom_model *model, const crom_mesh *mesh, size_t *noutside);

/* q [r] for the field f [nv][3] (uses p's scratch: one thread at a time). */
void crom_project_apply(crom_project *p, const double *f, double *q);

/* The weighted squared norms Σ_v w_v |W_v q − f_v|² into *e2 and
 * Σ_v w_v |f_v|² into *f2. */
void crom_project_residual(const crom_project *p, const double *f, const double *q, double *e2, double *f2);

void crom_project_free(crom_project *p);

#endif
