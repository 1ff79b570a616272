/* scene.h — rigid-body scenes (Sharp et al. 2023 §5.1; issue 17): bodies
 * with an analytic shape, penalty joints and collision pairs (crom/mesh).
 *
 * A scene is a kind of crom mesh: its vertices are the bodies' FRAME
 * VERTICES (4 per body, body b owning vertices 4b … 4b+3; lib/phys/rigid.h
 * says how four lumped masses carry a body's [R|t] and its inertia
 * exactly), it has no tets or triangles, and each body's four vertices
 * form a named region, so the scenario flags (--fix BODY, --force BODY …)
 * act on bodies. This module holds the scene's data and its HDF5 layout;
 * the physics (frames, masses, element energies) is lib/phys/rigid.h.
 *
 * At rest body b's shape stands at its centre c turned by its rotation Q
 * (body to world): the body point of shape coordinates p is at the rest
 * position X = c + Q p (Q = I unless given).
 */
#ifndef CROM_SCENE_H
#define CROM_SCENE_H

#include <hdf5.h>

/* Shapes, in the body's shape coordinates p (m):
 *   box:     size = full extents (a, b, c);
 *   sphere:  size[0] = radius;
 *   capsule: size[0] = radius, size[1] = length of its axis segment, which
 *            runs along x from −size[1]/2 to size[1]/2;
 *   ring:    a chain link: a tube of radius size[0] around a stadium curve
 *            in the xy-plane, two half circles of radius size[1] centred
 *            at x = ±size[2]/2 joined by straight runs of length size[2]
 *            (size[2] = 0: a torus). */
enum { CROM_SCENE_BOX = 0, CROM_SCENE_SPHERE = 1, CROM_SCENE_CAPSULE = 2, CROM_SCENE_RING = 3, CROM_SCENE_COUNT };

typedef struct {
    int shape;        /* CROM_SCENE_* */
    double size[3];   /* see above (m); unused entries 0 */
    double centre[3]; /* rest centre of the shape (m) */
    double density;   /* kg/m³ */
    double rot[9];    /* rest rotation Q, shape to world, row-major (orthonormal, det +1) */
} crom_scene_body;

/* A body of the given shape, size, centre and density, its rotation the
 * identity. */
crom_scene_body crom_scene_body_make(int shape, const double size[3], const double centre[3], double density);

/* A penalty joint (Sharp eq. 9, w_eq |C_eq(q)|² with C the gap): the body
 * point of body a at rest position `point` is held to the same point of
 * body b, or (b = −1) pinned to its rest position in the world; a slider
 * (point on axis) holds b's point on the line through a's point along a's
 * rest direction `axis` (a unit vector), free to slide along it. */
enum { CROM_SCENE_POINT = 0, CROM_SCENE_SLIDER = 1 };
typedef struct {
    int a, b;         /* bodies; b = −1: the world (point joints) */
    double point[3];  /* rest position (m) */
    double weight;    /* w (N/m): energy ½ w |gap|² */
    int kind;         /* CROM_SCENE_POINT or CROM_SCENE_SLIDER */
    double axis[3];   /* a slider's rest direction in body a (unit) */
} crom_scene_joint;

/* A collision pair: sample points of body a's surface against the signed
 * distance of body b's shape, energy ½ w Σ min(φ_b, 0)² (Sharp eq. 9,
 * w_ineq). */
typedef struct {
    int a, b;
    double weight;    /* N/m */
} crom_scene_pair;

typedef struct {
    int nb, nj, np;
    crom_scene_body *bodies;
    crom_scene_joint *joints;
    crom_scene_pair *pairs;
    double ortho_weight; /* w of w ‖RᵀR − I‖²_F per body (J) */
} crom_scene;

/* The name of a shape, and the shape of a name (−1 if none). */
const char *crom_scene_shape_name(int shape);
int crom_scene_shape_parse(const char *name);

/* The volume of a body's shape (m³). */
double crom_scene_body_volume(const crom_scene_body *b);

/* Check a scene: at least one body; joints of a known kind (a slider
 * between two bodies, along a unit axis); known shapes with positive finite
 * sizes (a ring's straight length may be 0, and its tube must be thinner
 * than its radius) and density; rotations orthonormal with det +1 (to
 * 1e-9); joints and pairs naming existing bodies (a pair of two
 * different ones); non-negative finite weights and finite points. Returns
 * 0 or CROM_EDATA naming the first problem. */
int crom_scene_validate(const crom_scene *s);

/* Append a body, joint or pair (CROM_EINTERNAL when out of memory). */
int crom_scene_add_body(crom_scene *s, const crom_scene_body *b);
int crom_scene_add_joint(crom_scene *s, const crom_scene_joint *j);
int crom_scene_add_pair(crom_scene *s, const crom_scene_pair *p);

/* Deep copy, and release (NULL-safe). */
int crom_scene_copy(const crom_scene *src, crom_scene *dst);
void crom_scene_free(crom_scene *s);

/* Write the scene as the group `scene` under loc (a crom/mesh root or a
 * trajectory's /mesh), and read it back (validated). */
int crom_scene_write(hid_t loc, const crom_scene *s);
int crom_scene_read(hid_t loc, crom_scene *s);

#endif
