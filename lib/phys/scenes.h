/* scenes.h — rigid-body scenes of Sharp et al. 2023 (§5.1, Table 1) built
 * from parameters, as scene meshes (mesh/scene.h, phys/rigidsys.h). y is
 * up; gravity acts along −y.
 *
 * Default penalty weights (a parameter <= 0 asks for it) keep the
 * penalties stiff against the scene's own weight: a joint of weight
 * w_j = 1e4 m g / l stretches by 1e-4 l under the whole scene's weight m g
 * (l the link length), and w_o = 1e4 m_b g l makes the frame's shear
 * under a torque m_b g l about 1e-4 (m_b the heaviest body). */
#ifndef CROM_SCENES_H
#define CROM_SCENES_H

#include "mesh/mesh.h"

typedef struct {
    int links;            /* chain: number of links */
    int rings;            /* chain: 1: interlocked ring links held by contacts (Sharp's chain), 0: capsules
                           * joined end to end */
    double ring_radius;   /* ring links: the radius of their half circles (m) */
    double contact_weight; /* N/m per contact point; <= 0: 1e3 m g / r (r the tube radius) */
    double length;        /* pendulum: distance pivot–bob centre; chain: each link's axis length (m) */
    double radius;        /* bob radius, or link radius (m) */
    double density;       /* kg/m³ */
    double angle;         /* pendulum: initial angle below the horizontal (radians), π/2 hanging; a
                           * chain starts horizontal (angle 0; its capsules' axes are x at rest) */
    double joint_weight;  /* N/m; <= 0: the default above */
    double ortho_weight;  /* J; <= 0: the default above */
    double gravity;       /* |g| the defaults are scaled with (m/s²; 9.81) */
} crom_scenes_params;

/* A pendulum: a sphere of `radius` whose centre is `length` from a pivot
 * at the origin, pinned there (a joint to the world at the pivot). Its
 * region is "bob". */
int crom_scenes_pendulum(const crom_scenes_params *p, crom_mesh *m);

/* A chain along +x from the origin, pinned to the world at the origin (the
 * first link's end; a ball joint), its links regions "link0" … :
 *   - capsules (rings = 0) of axis `length` and `radius`, end to end,
 *     joined point to point at every shared end;
 *   - rings (rings = 1): links of tube `radius`, `ring_radius` and straight
 *     run `length`, alternately in the xy- and the xz-plane, each through
 *     the next's opening with a gap of r/2 at rest (pitch 2(h + R) − 2.5 r),
 *     held by contacts alone: every pair of neighbours collides both ways
 *     (Sharp et al.'s chain, Figs. 6 and 8; with 2 links, the mini chain of
 *     Fig. 11). */
int crom_scenes_chain(const crom_scenes_params *p, crom_mesh *m);

/* The Klann linkage (Sharp et al. Fig. 2; planar, one degree of freedom):
 * a crank turning about A, a connecting rod C-H-F (one rigid triangle) held
 * at H by a rocker from the fixed pivot B, and a leg E-F-G whose top E a
 * rocker from the fixed pivot D holds and whose end G is the foot. Bar
 * lengths are the optimized Klann geometry of boim.com/Walkin8r (AC 17.5,
 * B (-38.8, -12.5), D (-14.6, 41.9), BH 23.7, CF 73.4, CH 38.8, DE 34.1,
 * EF 57.7, EG 111.7, FG 59, FH 35.2), scaled so that AC = `length`, in the
 * xy-plane with A at the origin. The five moving links are thin boxes
 * (`radius`: half their width and thickness) along their longest side;
 * every revolute joint is two point joints ±radius along z (the ground
 * pivots A, B, D pinned to the world), so the linkage cannot leave its
 * plane. The rest state is the linkage assembled at crank angle `angle`.
 * Regions: crank, rod, rocker_b, rocker_d, leg. */
int crom_scenes_klann(const crom_scenes_params *p, crom_mesh *m);

/* The Stewart platform (Sharp et al. Fig. 2; 14 bodies, 168 DOF): a base
 * (a flat box pinned to the world at three points) and a platform of
 * radius 0.6 `length` at height `length` above it, joined by six
 * telescoping legs; leg i's lower capsule hangs from the base by a ball
 * joint at B_i (radius `length`, angles -20, 20, 100, 140, 220, 260
 * degrees) and its upper capsule holds the platform by a ball joint at P_i
 * (angles -50, 50, 70, 170, 190, 290), the upper sliding in the lower (two
 * sliders along the leg's axis); `radius` is the legs' radius. y is up.
 * Regions: base, platform, leg<i>_lower, leg<i>_upper. With no actuators
 * the legs slide freely: the platform has its six degrees of freedom. */
int crom_scenes_stewart(const crom_scenes_params *p, crom_mesh *m);

/* The Klann linkage's points at crank angle theta (xy, metres): A, B, C,
 * D, E, F, G, H into P [8][2] in that order, by a direct kinematic solve
 * (circle intersections). prev (may be NULL) is the previous solution: each
 * branch is then the one nearer to it; without it the assembly crom-scene
 * builds. CROM_EDATA where the linkage cannot be assembled. */
int crom_scenes_klann_points(double theta, double length, const double *prev, double P[8][2]);

#endif
