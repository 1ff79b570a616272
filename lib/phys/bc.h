/* bc.h — boundary conditions on a region of a mesh (the scenario's
 * --velocity and --force, scenario.h): a prescribed velocity or a total
 * force, switched on over a window of time.
 */
#ifndef CROM_BC_H
#define CROM_BC_H

/* A boundary condition on a region: a prescribed velocity or a total force,
 * active during [t0, t1] (t1 = +inf when open). */
typedef struct {
    char ref[128];   /* region name or predicate */
    double v[3];     /* velocity (m/s) or force (N) */
    double t0, t1;
} crom_bc;

/* Parse the flag value "REGION=X,Y,Z[@T0:T1]" of option flag (named in
 * messages) into b. Returns 0 or CROM_EUSAGE naming what is wrong. */
int crom_bc_parse(const char *flag, const char *v, crom_bc *b);

/* Velocity of prescribed-velocity BC b at time t (zero outside its window),
 * and the displacement it has accumulated by time t. */
void crom_bc_velocity(const crom_bc *b, double t, double v[3]);
void crom_bc_displacement(const crom_bc *b, double t, double u[3]);

/* Force of force BC b at time t (zero outside its window). */
void crom_bc_force(const crom_bc *b, double t, double f[3]);

#endif
