/* scenario.h — the scenario both simulators run (crom-fullsim and
 * crom-reducedstep parse it with this one module): material, time stepping,
 * gravity, pinned and prescribed-velocity regions, time-scheduled forces,
 * collision half-spaces with friction, damping, solver tolerance.
 *
 * A scenario is a set of flags (DESIGN.md); a file of flags can stand in for
 * them (@FILE, expanded by crom_cli_parse). crom_scenario_text() gives the
 * canonical flag text stored in every output, which parses back to the same
 * scenario. Regions are named mesh regions or inline predicates (mesh.h). */
#ifndef CROM_SCENARIO_H
#define CROM_SCENARIO_H

#include "base/opt.h"
#include "mesh/mesh.h"
#include "phys/bc.h"
#include "phys/contact.h"
#include "phys/material.h"
#include "phys/rod.h"

#define CROM_SCENARIO_MAX 32 /* pins, velocities, forces, planes: at most this many of each */

/* A region of another material (--youngs REGION=E, --poisson REGION=NU,
 * --density REGION=RHO): the tets whose four corners are all in the
 * region; NaN: the run's. */
typedef struct {
    char ref[128];
    double youngs, poisson, density;
} crom_scenario_material;

typedef struct {
    double youngs, poisson, density; /* Pa, 1, kg/m³ */
    int nmat;
    crom_scenario_material mat[CROM_SCENARIO_MAX]; /* in the order first given; a later one wins a tet */
    double dt;                       /* s */
    int steps, every;
    double gravity[3];               /* m/s² */
    int npins;
    char pins[CROM_SCENARIO_MAX][128];     /* regions held at rest */
    int nvel;
    crom_bc vel[CROM_SCENARIO_MAX];        /* prescribed velocities (held still outside [t0, t1]) */
    int nforce;
    crom_bc force[CROM_SCENARIO_MAX];      /* total forces, spread over the region by mass */
    int nrod;
    crom_rod rod[CROM_SCENARIO_MAX];       /* rods between two regions (--rod) */
    int nplanes;                     /* collision planes and spheres (--plane, --sphere), in order */
    crom_contact_plane plane[CROM_SCENARIO_MAX];
    double damping;                  /* mass-proportional damping rate (1/s) */
    double contact_stiffness;        /* penalty rate k (1/s²): force k·m_v·depth */
    double friction_eps;             /* velocity below which friction is smoothed (m/s) */
    double tol;                      /* Newton tolerance on the step's displacement error / size */
    int max_iter;                    /* Newton iteration limit per step */
    double v0[3];                    /* initial velocity (m/s) */
    double spin[3];                  /* initial angular velocity about the centroid (rad/s) */
} crom_scenario;

/* Defaults: E = 2.5 MPa, nu = 0.25 (LiCROM Table 1), rho = 1000 kg/m³,
 * dt = 0.01 s, 100 steps, every step stored, gravity (0, -9.81, 0), no
 * boundary conditions, no damping, tol 1e-7, 50 Newton iterations. */
void crom_scenario_defaults(crom_scenario *s);

/* The scenario options, for a program's crom_cli_doc. */
extern const crom_opt crom_scenario_opts[];

/* The name of scenario option key ("youngs", "pin", ...), or NULL when key
 * is not a scenario option. */
const char *crom_scenario_opt_name(int key);

/* Handle a scenario option: returns 0, CROM_EUSAGE with a message, or -1 if
 * key is not a scenario option (so a program handler can chain). */
int crom_scenario_option(crom_scenario *s, int key, const char *value);

/* Check values that only make sense together (after parsing): material,
 * dt, steps, every. Returns 0 or CROM_EUSAGE. */
int crom_scenario_check(const crom_scenario *s);

/* The pinned and the moved regions of s on mesh m share no vertex, so each
 * vertex follows one condition (pins may overlap each other: both hold it
 * at rest). Else CROM_EUSAGE naming both flags and a shared vertex; also
 * the errors of crom_mesh_select for a region m lacks. What crom_sim_init,
 * crom_rsim_init and crom_nlsim_init check on their meshes. */
int crom_scenario_check_regions(const crom_scenario *s, const crom_mesh *m);

/* The material of each tet of solid mesh m (material.h): mats [nmat]
 * (room for CROM_SCENARIO_MAX + 1) gets the run's material (--youngs,
 * --poisson, --density) as mats[0] and one per region of another material,
 * *tmat [nt] (malloc'ed) each tet's index into mats: the last region given
 * that holds its four corners, else 0. Without such regions *nmat = 1 and
 * *tmat = NULL. Returns 0, or CROM_EUSAGE for a region that is not on the
 * mesh or holds no whole tet, a bad material, or a shell or scene mesh
 * (their materials are uniform). */
/* The regions of other materials as flags, one per line ("--youngs
 * REGION=E\n--poisson REGION=NU\n"), into buf (cap bytes, snprintf's
 * way); returns the length they need. */
size_t crom_scenario_material_flags(const crom_scenario *s, char *buf, size_t cap);

/* 0 when the body is of one material; CROM_EUSAGE naming the first
 * region of another material otherwise (for a program, prog, that does not
 * take them yet). */
int crom_scenario_uniform(const crom_scenario *s, const char *prog);

int crom_scenario_materials(const crom_scenario *s, const crom_mesh *m, crom_material *mats, int *nmat, int **tmat);

/* ---- Conditions: scenario parameters a subspace is trained over --------
 * (Sharp et al. §3.5, conditional subspaces: the map takes [z, c]). A
 * condition names one number of the scenario:
 *   ratio:REGION   the Young's modulus of REGION's tets over the body's
 *                  (a region of another material, --youngs REGION=E)
 *   gravity:AXIS   the gravitational acceleration along x, y or z (m/s²)
 *   pin:REGION:AXIS where a pinned REGION is held: displaced by the value
 *                  (m) along x, y or z from rest (Sharp's pinned endpoints;
 *                  the map moves it, lib/rom/map.h: no scenario flag does)
 * and, when trained over, the range [lo, hi] it was drawn from. */
enum { CROM_SCENARIO_COND_RATIO = 1, CROM_SCENARIO_COND_GRAVITY = 2, CROM_SCENARIO_COND_PIN = 3 };
typedef struct {
    int kind;
    char ref[128];      /* ratio, pin: the region */
    int axis;           /* gravity, pin: 0, 1, 2 */
    double lo, hi;      /* the range (lo <= hi) */
} crom_scenario_cond;

/* Parse "NAME=LO:HI" (range 1) or "NAME=VALUE" (range 0: lo = hi =
 * VALUE) of flag into c. Returns 0 or CROM_EUSAGE naming the problem (an
 * unknown kind, an empty region, a bad axis, lo > hi, a ratio not
 * positive, a value not finite). */
int crom_scenario_cond_parse(const char *flag, const char *v, int range, crom_scenario_cond *c);

/* "NAME=LO:HI" of c into buf (cap bytes, snprintf's way); returns the
 * length it needs. */
int crom_scenario_cond_format(const crom_scenario_cond *c, char *buf, int cap);

/* 1 when a and b name the same parameter. */
int crom_scenario_cond_same(const crom_scenario_cond *a, const crom_scenario_cond *b);

/* Set the parameter c names to value in s: a ratio makes REGION's tets of
 * modulus value × s->youngs (adding the region of another material if s
 * lacks it), gravity sets its component; a pin's place is the map's, and
 * leaves s as it is. Returns 0 or CROM_EUSAGE (too many regions; a ratio
 * not positive). */
int crom_scenario_cond_apply(crom_scenario *s, const crom_scenario_cond *c, double value);

/* Canonical flag text, one flag per line (malloc'ed). */
char *crom_scenario_text(const crom_scenario *s);

/* Parse flag text ("--youngs 1e6\n--pin clamp\n", as crom_scenario_text
 * writes it and `scenario` attributes store it) into s. Flags that are not
 * scenario options are skipped; NULL text is no flags. Returns 0 or
 * CROM_EDATA naming the bad flag. */
int crom_scenario_parse_text(const char *text, crom_scenario *s);

/* Initial velocity of the material point at X: the uniform velocity plus
 * the spin about the centroid c, v = v0 + ω × (X − c). */
void crom_scenario_initial_velocity(const crom_scenario *s, const double c[3], const double X[3], double v[3]);

/* Write the scenario as root attributes (scenario text, dt, every, steps,
 * youngs, poisson, density, gravity, tolerance) of an output. */
int crom_scenario_write_attrs(hid_t loc, const crom_scenario *s);

#endif
