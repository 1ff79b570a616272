/* cubature.h — which tetrahedra a reduced simulation integrates over, with
 * what weights (crom/cubature), and everything else it needs from the mesh:
 * the basis W cached at every mesh vertex (so regions, inline predicates and
 * contact points resolve exactly), lumped volumes, and the exact reduced
 * mass per unit density WᵀVW (LiCROM §4–5).
 *
 * Schemes:
 *   all        every tet, weight 1 (the Galerkin projection of the full FEM);
 *   random     LiCROM §5: m random vertices and all their incident tets,
 *              equal weights scaled so the tets' weighted volume is the
 *              mesh's;
 *   metis      METIS partition of the tets into k parts, one representative
 *              tet per part (nearest the part's centroid) weighted by the
 *              part's volume;
 *   optimized  non-negative least squares (An, Kim, James 2008): tets picked
 *              greedily and weighted to reproduce the reduced elastic forces
 *              (and energies) of training poses. */
#ifndef CROM_CUBATURE_H
#define CROM_CUBATURE_H

#include "base/rng.h"
#include "io/io.h"
#include "mesh/mesh.h"
#include "phys/fem.h"
#include "phys/system.h"

#define CROM_CUBATURE_SCHEMA "crom/cubature"
#define CROM_CUBATURE_VERSION 1

typedef struct {
    char model_id[17];
    char scheme[16];
    int r;
    crom_mesh mesh;        /* the mesh the cubature integrates (with regions) */
    double *W;             /* [nv][3][r] basis at every vertex */
    double *vvol;          /* [nv] lumped volume: Σ V_t/4 over incident tets (m³) */
    double mesh_volume;    /* m³ */
    int k;                 /* cubature tets */
    int *elem;             /* [k] tet indices into mesh.tets */
    double *weight;        /* [k] */
    double *Dminv;         /* [k][9] rest-shape inverses */
    double *vol;           /* [k] rest volumes (m³) */
    double *WtVW;          /* [r][r] Σ_v V_v W_vᵀ W_v; times ρ = reduced mass */
    double *WtV;           /* [r][3] Σ_v V_v W_vᵀ; times ρ g = reduced gravity */
    int nsurf;
    int *surf;             /* [nsurf] boundary vertices (contact points) */
    int map_rank;          /* > 0: W is the feature basis B of a nonlinear map
                            * of this latent rank (crom-reducedstep --model
                            * --cubature); 0: a linear basis */
    int ne;                /* elements the cubature chooses from: the mesh's tets, or a
                            * shell's energy elements (triangles, then hinges: system.h) */
} crom_cubature;

enum { CROM_CUBATURE_ALL, CROM_CUBATURE_RANDOM, CROM_CUBATURE_METIS, CROM_CUBATURE_OPTIMIZED };

typedef struct {
    int scheme;
    int count;             /* random: vertices; metis: parts (a shell: of its triangles); optimized: max elements */
    double tol;            /* optimized: stop at this relative force error */
    int candidates;        /* optimized: tets scored per greedy pick */
    const double *poses;   /* optimized: [npose][r] latent training poses (m) */
    int npose;
    double youngs, poisson;/* optimized: material of the forces fitted */
    /* optimized, for the feature basis of a nonlinear map (lib/rom/map.h): per
     * pose the Jacobian T = da/dq [r][rout] of its features, so the forces
     * fitted are the map's latent forces Tᵀ f_a (rout per pose) rather
     * than the r feature forces; NULL: fit the r forces */
    const double *proj;
    int rout;
} crom_cubature_opts;

/* Scheme name to CROM_CUBATURE_ALL ..., or -1. */
int crom_cubature_scheme(const char *name);

/* Build a cubature for mesh (copied) with W [nv][3][r] at its vertices
 * (copied). On a shell surface the elements are the energy elements of its
 * system (membrane triangles, then hinges: lib/phys/system.h; optimized
 * fits the shell's forces, with the mesh's thickness; random and metis
 * treat the triangles and the hinges as two sets, each weighted by its own
 * measure: area, and the hinge stiffness factor |ē|²/(Ā1 + Ā2); metis
 * stands for each of count parts of the triangles by one triangle and the
 * hinges on its edges), and the
 * cubature has no Dminv or volume: it serves crom-reducedstep --model only
 * (crom_nlsim_use_cubature). Returns 0, CROM_EUSAGE (bad count, optimized
 * without poses), CROM_EDATA (degenerate mesh, non-finite W) or
 * CROM_EINTERNAL. */
int crom_cubature_build(crom_cubature *c, const crom_mesh *mesh, const double *W, int r,
                        const char *model_id, const crom_cubature_opts *o, crom_rng *rng);

/* The data of cubature tet k for crom_cubature_tet: rest positions Xe[12] of its
 * corners, the [4][3][r] block of W at them, and its Dm⁻¹. */
void crom_cubature_gather(const crom_cubature *c, int k, double Xe[12], double *W4, double Dminv[9]);


/* Relative errors of the cubature against the exact integral over all tets
 * at poses [npose][r]: elastic energy (|Σ_pose ΔE| / Σ|E|) and reduced force
 * (‖Δf‖/‖f‖ over all poses stacked; with proj non-NULL the forces Tᵀ f of
 * crom_cubature_opts.proj, rout per pose). */
int crom_cubature_error(const crom_cubature *c, const crom_material *mat, const double *poses,
                        int npose, const double *proj, int rout, double *energy_err, double *force_err);

int crom_cubature_write(hid_t loc, const crom_cubature *c);
/* Read and check (shapes, indices, finite values) a crom/cubature input. */
int crom_cubature_read(crom_in *in, crom_cubature *c);

/* The same from path (NULL or "-": stdin); when history is not NULL it
 * takes over the file's history attribute (malloc'ed; NULL if none). */
int crom_cubature_load(const char *path, crom_cubature *c, char **history);
void crom_cubature_free(crom_cubature *c);

/* Element gradient of V·Ψ at positions X + W q projected to the basis:
 * g_r[r] += w Σ_a W_aᵀ ∂(VΨ)/∂x_a, and (when H_r is non-NULL) the reduced
 * Hessian H_r[r][r] += w Σ_ab W_aᵀ H_ab W_b (full, row-major). Xe are the
 * tet's rest positions, W4 the [4][3][r] block of its vertices, work holds
 * 168 + 12r doubles. Returns V·Ψ (unweighted), or NaN with CROM_EDATA
 * recorded when the element is not finite. */
double crom_cubature_tet(const crom_material *mat, const double Xe[12], const double *W4, int r,
                         const double Dminv[9], double V, double w, const double *q, int project,
                         double *g_r, double *H_r, double *work);

#endif
