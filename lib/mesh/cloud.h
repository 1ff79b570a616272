/* cloud.h — bodies given without a tet mesh: a closed triangle surface
 * (.stl/.obj) sampled by inside/outside tests, or a point cloud with a
 * volume per point, and the quadrature stencils that let the continuous
 * data-free objectives (crom-fitfield --objective skinning|field) integrate
 * the elastic energy over them.
 *
 * Inside a closed surface. A point p is inside when the generalized winding
 * number w(p) = Σ_t Ω_t(p) / 4π of the triangles (Ω_t the signed solid angle
 * of triangle t seen from p, Van Oosterom and Strackee 1983) exceeds 1/2 in
 * magnitude (either orientation of the surface). The body is sampled on a
 * jittered grid: one uniform point per cell of a grid of about n_in/fill
 * cells over the bounding box (fill = V / box volume), kept when inside;
 * each kept point stands for V / (points kept) of the enclosed volume V =
 * |Σ_t det(a, b, c)| / 6 (exact for a closed surface).
 *
 * Point clouds are text files: one point per line, "x y z volume" (metres,
 * cubic metres), separated by blanks or commas; '#' starts a comment.
 *
 * Stencils. Each point becomes a virtual tet: a regular tetrahedron of the
 * point's volume centred on it, randomly rotated (the linear displacement
 * over it is a finite-difference stencil of the deformation gradient at the
 * point, and its lumped masses are the point's mass). The virtual tets are
 * disjoint in connectivity (4 vertices each) and form a crom_mesh, so any
 * trainer that integrates over the tets of a mesh integrates over the body.
 * They are not a mesh OF the body: they overlap, and near the surface reach
 * outside it by up to their size.
 */
#ifndef CROM_CLOUD_H
#define CROM_CLOUD_H

#include <stdint.h>

#include "mesh/mesh.h"

typedef struct {
    int n;            /* points */
    double *X;        /* [n][3] (m) */
    double *vol;      /* [n] volume each stands for (m³) */
    double volume;    /* Σ vol */
    int nsv, nst;     /* the closed surface the points were sampled in (0 for a cloud) */
    double *SV;       /* [nsv][3] */
    int *ST;          /* [nst][3] */
} crom_cloud;

/* Sample about n points inside the closed surface in path (.stl ASCII or
 * binary, .obj) with seed. CROM_ENOINPUT (missing file), CROM_EDATA (a
 * surface that is not closed, encloses no volume, or no point fell inside),
 * CROM_EUSAGE (n < 1). The surface is kept in out. */
int crom_cloud_from_surface(const char *path, int n, uint64_t seed, crom_cloud *out);

/* Read a point cloud with volumes (text, above). CROM_ENOINPUT, or CROM_EDATA
 * naming the line: a point without a volume, a non-positive or non-finite
 * value, a line that is not 4 numbers, no point at all. */
int crom_cloud_read(const char *path, crom_cloud *out);

/* 1 if p is inside the closed surface (nv vertices V, nt triangles T). */
int crom_cloud_inside(int nv, const double *V, int nt, const int *T, const double p[3]);

/* The virtual tets of the points (above) as a mesh (4n vertices, n tets, no
 * regions), rotations drawn from seed. CROM_EDATA for a non-positive volume,
 * CROM_EINTERNAL when out of memory. */
int crom_cloud_stencils(const crom_cloud *c, uint64_t seed, crom_mesh *m);

/* What the npred pin predicates preds (crom_pred_parse text) hold: the
 * surface triangles ([ntri][3][3], malloc'ed) whose corners all satisfy one,
 * and for a predicate that holds no triangle (a cloud's, or a pin inside the
 * body) the points that satisfy it ([npin][3], malloc'ed). CROM_EUSAGE
 * for a region name (a cloud has no named regions: give a predicate) or a
 * pin that selects nothing. */
int crom_cloud_pins(const crom_cloud *c, int npred, const char *const *preds, int *npin, double **pinX, int *ntri,
                    double **triX);

void crom_cloud_free(crom_cloud *c);

#endif
