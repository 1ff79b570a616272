/* rigidsys.h — the physical system of a rigid-body scene (issue 17; Sharp
 * et al. 2023 §5.1): the scene's bodies as frames of four lumped masses
 * (rigid.h), their energy a sum of elements over the frame vertices:
 *   - per body, the orthogonality potential w_o ‖RᵀR − I‖²_F;
 *   - per joint to the world, a pin ½ w |x(P) − P|²;
 *   - per joint between bodies a and b, ½ w |x_a(P) − x_b(P)|² (Sharp eq.
 *     9, w_eq |C_eq(q)|²), P the joint's rest point; a slider: ½ w times
 *     the squared distance of b's point from a's axis through P (rigid.h);
 *   - per collision pair (a, b) and per sample point of a's surface (the
 *     vertices of a's display surface at CROM_RIGIDSYS_CONTACT_RINGS), a
 *     contact ½ w min(φ_b, 0)² against b's signed distance (rigid.h).
 * Elements are listed in that order (bodies, joints in scene order, then
 * the contacts pair by pair). A joint or a contact joins two bodies' 8
 * vertices: the system interface's elements have up to CROM_RIGIDSYS_MAXV
 * vertices. */
#ifndef CROM_RIGIDSYS_H
#define CROM_RIGIDSYS_H

#include "mesh/mesh.h"
#include "phys/fem.h"
#include "phys/rigid.h"

#define CROM_RIGIDSYS_MAXV 8
/* latitude rings (a ring: stations per half) of the contact sample points */
#define CROM_RIGIDSYS_CONTACT_RINGS 8

enum { CROM_RIGIDSYS_ORTHO, CROM_RIGIDSYS_PIN, CROM_RIGIDSYS_JOINT, CROM_RIGIDSYS_CONTACT, CROM_RIGIDSYS_SLIDER };

typedef struct {
    int kind;           /* CROM_RIGIDSYS_ORTHO, _PIN, _JOINT, _CONTACT or _SLIDER */
    int a, b;           /* bodies (b: joints and contacts: the body whose shape is hit) */
    double beta[4];     /* the point's coordinates in frame a (pins, joints, contacts) */
    double gamma[4];    /* … in frame b (joints, sliders) */
    double c[4];        /* a slider's axis weights in frame a (rigid.h) */
    double target[3];   /* a pin's world position (m) */
    double w;           /* weight: J (ortho) or N/m */
} crom_rigidsys_elem;

typedef struct {
    int nb, nv, n, nnz;   /* bodies, 4 nb frame vertices, 3 nv DOFs, stored Hessian entries */
    int *colptr, *rowind; /* upper-CSC pattern, the diagonal last in each column */
    double *mass;         /* [nv] m_b / 4 per frame vertex (kg) */
    double total_mass, volume;
    double *Y, *B;        /* [nb][12] rest frames, [nb][9] their inverse edge matrices */
    double *Bq;           /* [nb][9] B Q, Q the body's rest rotation (contacts) */
    double *reach;        /* [nb] the largest distance of a point of the body's shape from its centre (m) */
    const crom_scene_body *body; /* [nb] the scene's bodies (borrowed from the mesh) */
    int nj, ncontact;     /* joints, contact elements */
    int nel;
    crom_rigidsys_elem *el;
} crom_rigidsys;

/* The mass distribution of a scene body (its shape, density and centre):
 * box, sphere, or capsule (a cylinder with hemispherical caps). */
void crom_rigidsys_body_inertia(const crom_scene_body *b, crom_rigid_inertia *in);

/* The rest frame vertices X [4 nb][3] of a scene's bodies (rigid.h's
 * crom_rigid_frame of each body's inertia). */
int crom_rigidsys_frames(const crom_scene *sc, double *X);

/* A scene mesh (mesh.h) of scene sc (taken over: freed on failure too):
 * the frame vertices, and a region per body named names[b] (NULL:
 * "body<b>") holding its four vertices. */
int crom_rigidsys_scene_mesh(crom_scene *sc, const char *const *names, crom_mesh *m);

/* The system of scene mesh m (borrowed for the system's life: its bodies'
 * shapes): masses, frames (which must be those of crom_rigidsys_frames:
 * CROM_EDATA otherwise), elements, pattern. */
int crom_rigidsys_init(crom_rigidsys *s, const crom_mesh *m);
void crom_rigidsys_free(crom_rigidsys *s);

/* Energy, gradient and upper-CSC Hessian at x [nv][3] with the options of
 * crom_fem_assemble (any output may be NULL). */
int crom_rigidsys_assemble(const crom_rigidsys *s, const double *x, const crom_fem_opts *o, double *E, double *g,
                           double *H);

/* The vertices of element e into v (4 or 8 of them; returned). */
int crom_rigidsys_elem_vertices(const crom_rigidsys *s, int e, int *v);

/* Energy, gradient g[3k] and Hessian H[3k][3k] of element e at the
 * positions xe[3k] of its vertices (crom_system_elem_eval's contract). */
int crom_rigidsys_elem_eval(const crom_rigidsys *s, int e, const double *xe, int project, double *E, double *g,
                            double *H);

/* The affine map [R|t] of body b at positions x [nv][3]: R [9] row-major,
 * t [3], x(X) = R X + t. */
void crom_rigidsys_pose(const crom_rigidsys *s, int b, const double *x, double R[9], double t[3]);

/* A surface to show a scene by (crom-export, crom-diff): each body's shape
 * as outward-oriented triangles (a box's 12; a sphere or capsule as
 * latitude-longitude rings, `res` rings from pole to pole, res >= 2) in a
 * shell-kind mesh disp (thickness 1e-3 times the scene's size: a display
 * surface, not a physical shell), with regions named as the scene's. Every
 * display vertex moves with its body's frame: its displacement is Σ_k
 * beta[4i+k] u(frame vertex 4 body[i] + k) (exact for the affine motion the
 * frame carries). beta [nd][4] and body [nd] are malloc'ed. */
int crom_rigidsys_display(const crom_mesh *scene, int res, crom_mesh *disp, double **beta, int **body);

/* The display displacement ud [nd][3] of frame displacements u [nv][3]. */
void crom_rigidsys_display_map(int nd, const double *beta, const int *body, const double *u, double *ud);

/* The gap |x_a(P) − x_b(P)| (a pin: |x_a(P) − P|; a slider: the distance
 * of b's point from a's axis) of every joint of the scene at positions x,
 * in scene order, into gap [nj] (m). */
void crom_rigidsys_joint_gaps(const crom_rigidsys *s, const double *x, double *gap);

#endif
