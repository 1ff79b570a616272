/* scenario.c — scenario flags shared by the full and reduced simulators. */
#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/array.h"
#include "base/err.h"
#include "base/parse.h"
#include "io/io.h"
#include "phys/bc.h"
#include "phys/scenario.h"

enum {
    SC_YOUNGS = 0x1000, SC_POISSON, SC_DENSITY, SC_DT, SC_STEPS, SC_EVERY, SC_GRAVITY,
    SC_PIN, SC_VELOCITY, SC_FORCE, SC_PLANE, SC_DAMPING, SC_CONTACT_K, SC_FRICTION_EPS,
    SC_TOL, SC_MAXIT, SC_V0, SC_SPIN, SC_SPHERE, SC_ROD
};

const crom_opt crom_scenario_opts[] = {
    {"youngs", SC_YOUNGS, "[REGION=]E", "Young's modulus in Pa (default 2.5e6, LiCROM Table 1). With REGION=, the modulus of the tets whose four corners are in REGION (repeatable: regions of other materials; where they overlap the last given wins; crom-fullsim, crom-reducedstep, crom-live, crom-modes and crom-fitfield's data-free objectives)."},
    {"poisson", SC_POISSON, "[REGION=]NU", "Poisson ratio in (-1, 0.5) (default 0.25). With REGION=, that of the tets of REGION, as --youngs REGION=E."},
    {"density", SC_DENSITY, "[REGION=]RHO", "Density in kg/m^3 (default 1000). With REGION=, that of the tets of REGION, as --youngs REGION=E (the lumped masses follow)."},
    {"dt", SC_DT, "H", "Time step in s (default 0.01)."},
    {"steps", SC_STEPS, "N", "Number of time steps (default 100)."},
    {"every", SC_EVERY, "K", "Store every K-th step (default 1); frame 0 is the initial state."},
    {"gravity", SC_GRAVITY, "GX,GY,GZ", "Gravitational acceleration in m/s^2 (default 0,-9.81,0)."},
    {"pin", SC_PIN, "REGION", "Hold the vertices of REGION (a mesh region name, a predicate such as 'y<-0.45', or one vertex '#N') at rest (repeatable; a region pinned or moved by --velocity already is an error)."},
    {"velocity", SC_VELOCITY, "REGION=VX,VY,VZ[@T0:T1]", "Move REGION at the given velocity (m/s) during [T0, T1] (default: always) and hold it still outside (repeatable, once per region). LiCROM's compression: --velocity 'y>0.45=0,-2,0' --pin 'y<-0.45'."},
    {"force", SC_FORCE, "REGION=FX,FY,FZ[@T0:T1]", "Apply a total force (N) to REGION, spread over its vertices by mass, during [T0, T1] (repeatable: forces on one region add up)."},
    {"rod", SC_ROD, "A/B=K,L0[,AMP,PERIOD[,PHASE]]", "A rod between the centroids of regions A and B (names, predicates or vertices '#N'): a spring of stiffness K (N/m) whose rest length is L0 (m, or 'rest': the ends' distance at rest) plus AMP sin(2 pi t / PERIOD + PHASE) (Neural Modes' puppet); its force spreads over each end by mass (repeatable; crom-fullsim, crom-reducedstep, crom-live)."},
    {"plane", SC_PLANE, "NX,NY,NZ,D[,MU]", "Collision half-space: keep n.x >= D (n is normalized), with Coulomb friction coefficient MU (default 0) (repeatable)."},
    {"sphere", SC_SPHERE, "CX,CY,CZ,R[,MU]", "Collision sphere (a fixed ball): keep vertices outside |x - c| >= R, with the planes' penalty and Coulomb friction coefficient MU (default 0) (repeatable; planes and spheres together at most 32)."},
    {"damping", SC_DAMPING, "A", "Mass-proportional damping rate in 1/s (default 0): a drag force A m v."},
    {"contact-stiffness", SC_CONTACT_K, "K", "Penalty rate of the collision planes and spheres in 1/s^2: a vertex of mass m at depth d feels K m d (default 1e5)."},
    {"friction-eps", SC_FRICTION_EPS, "V", "Tangential speed in m/s below which friction is smoothed (default 1e-3)."},
    {"tol", SC_TOL, "TOL", "Newton stops when its correction to any vertex position is below TOL times the bounding-box diagonal (default 1e-7); near convergence crom-fullsim first tries a cheaper simplified Newton correction with its reused factor, accepted below TOL/2."},
    {"max-iter", SC_MAXIT, "N", "Newton iterations allowed per step before the run fails (default 50)."},
    {"initial-velocity", SC_V0, "VX,VY,VZ", "Uniform initial velocity in m/s (default 0)."},
    {"spin", SC_SPIN, "WX,WY,WZ", "Initial angular velocity about the centroid in rad/s (default 0)."},
    {NULL, 0, NULL, NULL}};

void crom_scenario_defaults(crom_scenario *s)
{
    memset(s, 0, sizeof *s);
    s->youngs = 2.5e6;
    s->poisson = 0.25;
    s->density = 1000;
    s->dt = 0.01;
    s->steps = 100;
    s->every = 1;
    s->gravity[1] = -9.81;
    s->contact_stiffness = 1e5;
    s->friction_eps = 1e-3;
    s->tol = 1e-7;
    s->max_iter = 50;
}

const char *crom_scenario_opt_name(int key)
{
    for (const crom_opt *o = crom_scenario_opts; o->name; o++)
        if (o->key == key)
            return o->name;
    return NULL;
}

/* How region ref is already held ("pinned", "moved by --velocity"), or NULL:
 * a region held twice would keep only the last silently. */
static const char *held(const crom_scenario *s, const char *ref)
{
    for (int i = 0; i < s->npins; i++)
        if (!strcmp(s->pins[i], ref))
            return "pinned (--pin)";
    for (int i = 0; i < s->nvel; i++)
        if (!strcmp(s->vel[i].ref, ref))
            return "moved by --velocity";
    return NULL;
}

/* A region reference (a name or a predicate) goes into the scenario text one
 * line per flag, after "--pin " (crom_scenario_text), and must read back the
 * same: no control character (a newline would start a line, and a flag, of
 * its own) and no blank at either end (the reader skips them). */
static int check_ref(const char *flag, const char *ref, size_t len)
{
    if (len == 0)
        return crom_err(CROM_EUSAGE, "%s: empty region", flag);
    for (size_t i = 0; i < len; i++)
        if ((unsigned char)ref[i] < 0x20 || ref[i] == 0x7f)
            return crom_err(CROM_EUSAGE, "%s: region '%.*s' has a control character", flag, (int)len, ref);
    if (ref[0] == ' ' || ref[len - 1] == ' ')
        return crom_err(CROM_EUSAGE, "%s: region '%.*s' starts or ends with a blank", flag, (int)len, ref);
    return 0;
}

/* --youngs REGION=E, --poisson REGION=NU: a region of another material
 * (the value after the last '=', so a predicate may hold one) */
static int parse_material(crom_scenario *s, int key, const char *v)
{
    const char *flag = key == SC_YOUNGS ? "--youngs" : key == SC_DENSITY ? "--density" : "--poisson",
               *eq = strrchr(v, '=');
    size_t len = (size_t)(eq - v);
    if (!len || len >= sizeof s->mat[0].ref)
        return crom_err(CROM_EUSAGE, "%s: empty or too long region in '%s'", flag, v);
    if (check_ref(flag, v, len))
        return CROM_EUSAGE;
    double x;
    if (crom_parse_double(eq + 1, flag, &x))
        return CROM_EUSAGE;
    if (key == SC_YOUNGS && !(x > 0 && x <= 1e13))
        return crom_err(CROM_EUSAGE, "%s %.*s=: a positive modulus in Pa, got %g (allowed (0, 1e13])", flag,
                        (int)len, v, x);
    if (key == SC_POISSON && !(x > -1 && x < 0.5))
        return crom_err(CROM_EUSAGE, "%s %.*s=: must be in (-1, 0.5), got %g", flag, (int)len, v, x);
    if (key == SC_DENSITY && !(x > 0 && x <= 1e6))
        return crom_err(CROM_EUSAGE, "%s %.*s=: a positive density in kg/m^3, got %g (allowed (0, 1e6])", flag,
                        (int)len, v, x);
    int i = 0;
    while (i < s->nmat && (strlen(s->mat[i].ref) != len || strncmp(s->mat[i].ref, v, len)))
        i++;
    if (i == s->nmat) {
        if (s->nmat == CROM_SCENARIO_MAX)
            return crom_err(CROM_EUSAGE, "%s: at most %d regions of other materials", flag, CROM_SCENARIO_MAX);
        memcpy(s->mat[i].ref, v, len);
        s->mat[i].ref[len] = 0;
        s->mat[i].youngs = s->mat[i].poisson = s->mat[i].density = NAN;
        s->nmat++;
    }
    if (key == SC_YOUNGS)
        s->mat[i].youngs = x;
    else if (key == SC_DENSITY)
        s->mat[i].density = x;
    else
        s->mat[i].poisson = x;
    return 0;
}

static int parse_option(crom_scenario *s, int key, const char *v)
{
    long n;
    double d[5];
    int k;
    switch (key) {
    case SC_YOUNGS:
    case SC_POISSON:
        if (strchr(v, '='))
            return parse_material(s, key, v);
        return crom_parse_double(v, key == SC_YOUNGS ? "--youngs" : "--poisson",
                                 key == SC_YOUNGS ? &s->youngs : &s->poisson);
    case SC_DENSITY:
        if (strchr(v, '='))
            return parse_material(s, key, v);
        return crom_parse_double(v, "--density", &s->density);
    case SC_DT: return crom_parse_positive(v, "--dt", &s->dt);
    case SC_STEPS:
        if (crom_parse_int(v, "--steps", 0, 100000000L, &n))
            return CROM_EUSAGE;
        s->steps = (int)n;
        return 0;
    case SC_EVERY:
        if (crom_parse_int(v, "--every", 1, 100000000L, &n))
            return CROM_EUSAGE;
        s->every = (int)n;
        return 0;
    case SC_GRAVITY: return crom_parse_doubles(v, "--gravity", 3, s->gravity);
    case SC_PIN:
        if (s->npins == CROM_SCENARIO_MAX)
            return crom_err(CROM_EUSAGE, "--pin: at most %d", CROM_SCENARIO_MAX);
        if (!*v || strlen(v) >= sizeof s->pins[0])
            return crom_err(CROM_EUSAGE, "--pin: empty or too long region '%s'", v);
        if (check_ref("--pin", v, strlen(v)))
            return CROM_EUSAGE;
        if (held(s, v))
            return crom_err(CROM_EUSAGE, "--pin: region '%s' is already %s", v, held(s, v));
        snprintf(s->pins[s->npins++], sizeof s->pins[0], "%s", v);
        return 0;
    case SC_VELOCITY:
        if (s->nvel == CROM_SCENARIO_MAX)
            return crom_err(CROM_EUSAGE, "--velocity: at most %d", CROM_SCENARIO_MAX);
        if (crom_bc_parse("--velocity", v, &s->vel[s->nvel]) ||
            check_ref("--velocity", s->vel[s->nvel].ref, strlen(s->vel[s->nvel].ref)))
            return CROM_EUSAGE;
        if (held(s, s->vel[s->nvel].ref))
            return crom_err(CROM_EUSAGE, "--velocity: region '%s' is already %s (each vertex follows one)",
                            s->vel[s->nvel].ref, held(s, s->vel[s->nvel].ref));
        s->nvel++;
        return 0;
    case SC_FORCE:
        if (s->nforce == CROM_SCENARIO_MAX)
            return crom_err(CROM_EUSAGE, "--force: at most %d", CROM_SCENARIO_MAX);
        if (crom_bc_parse("--force", v, &s->force[s->nforce]) ||
            check_ref("--force", s->force[s->nforce].ref, strlen(s->force[s->nforce].ref)))
            return CROM_EUSAGE;
        s->nforce++;
        return 0;
    case SC_ROD:
        if (s->nrod == CROM_SCENARIO_MAX)
            return crom_err(CROM_EUSAGE, "--rod: at most %d", CROM_SCENARIO_MAX);
        if (crom_rod_parse("--rod", v, &s->rod[s->nrod]) ||
            check_ref("--rod", s->rod[s->nrod].a, strlen(s->rod[s->nrod].a)) ||
            check_ref("--rod", s->rod[s->nrod].b, strlen(s->rod[s->nrod].b)))
            return CROM_EUSAGE;
        s->nrod++;
        return 0;
    case SC_PLANE: {
        if (s->nplanes == CROM_SCENARIO_MAX)
            return crom_err(CROM_EUSAGE, "--plane: at most %d", CROM_SCENARIO_MAX);
        if (crom_parse_doubles_var(v, "--plane", 4, 5, d, &k))
            return CROM_EUSAGE;
        /* hypot: a component near DBL_MAX would make the sum of squares inf and
         * the normal (0, 0, 0) */
        double nn = hypot(hypot(d[0], d[1]), d[2]);
        if (!(nn > 0))
            return crom_err(CROM_EUSAGE, "--plane '%s': the normal is zero", v);
        crom_contact_plane *p = &s->plane[s->nplanes++];
        memset(p, 0, sizeof *p);
        if (fabs(nn - 1) < 8 * DBL_EPSILON)
            nn = 1; /* already unit: keep the bits, so the text round-trips */
        for (int i = 0; i < 3; i++)
            p->n[i] = d[i] / nn;
        p->d = d[3] / nn;
        /* a subnormal left by the division is 0 (the number parser refuses
         * subnormals, and the scenario text must read back) */
        for (int i = 0; i < 4; i++) {
            double *x = i < 3 ? &p->n[i] : &p->d;
            if (fabs(*x) < DBL_MIN)
                *x = 0 * *x;
        }
        p->mu = k == 5 ? d[4] : 0;
        if (p->mu < 0)
            return crom_err(CROM_EUSAGE, "--plane '%s': friction coefficient must be >= 0", v);
        return 0;
    }
    case SC_SPHERE: {
        if (s->nplanes == CROM_SCENARIO_MAX)
            return crom_err(CROM_EUSAGE, "--sphere: at most %d planes and spheres", CROM_SCENARIO_MAX);
        if (crom_parse_doubles_var(v, "--sphere", 4, 5, d, &k))
            return CROM_EUSAGE;
        if (!(d[3] > 0))
            return crom_err(CROM_EUSAGE, "--sphere '%s': the radius must be positive", v);
        if (k == 5 && d[4] < 0)
            return crom_err(CROM_EUSAGE, "--sphere '%s': friction coefficient must be >= 0", v);
        crom_contact_plane *p = &s->plane[s->nplanes++];
        memset(p, 0, sizeof *p);
        p->sphere = 1;
        memcpy(p->c, d, sizeof p->c);
        p->r = d[3];
        p->mu = k == 5 ? d[4] : 0;
        return 0;
    }
    case SC_DAMPING:
        if (crom_parse_double(v, "--damping", &s->damping))
            return CROM_EUSAGE;
        return 0;
    case SC_CONTACT_K: return crom_parse_positive(v, "--contact-stiffness", &s->contact_stiffness);
    case SC_FRICTION_EPS: return crom_parse_positive(v, "--friction-eps", &s->friction_eps);
    case SC_TOL: return crom_parse_positive(v, "--tol", &s->tol);
    case SC_MAXIT:
        if (crom_parse_int(v, "--max-iter", 1, 100000, &n))
            return CROM_EUSAGE;
        s->max_iter = (int)n;
        return 0;
    case SC_V0: return crom_parse_doubles(v, "--initial-velocity", 3, s->v0);
    case SC_SPIN: return crom_parse_doubles(v, "--spin", 3, s->spin);
    }
    return -1;
}

/* The range of each scenario value, checked as soon as it is given (so the
 * message names the flag, not a later overflow) and again by
 * crom_scenario_check. Returns 0 or CROM_EUSAGE. */
#define SC_MAX_G 1e5      /* m/s^2: ten thousand g */
#define SC_MAX_SPEED 1e5  /* m/s, rad/s */
static int norm_ok(const double v[3], double max) { return sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) <= max; }

static int check_value(const crom_scenario *s, int key)
{
    switch (key) {
    case SC_YOUNGS:
        if (!(s->youngs > 0 && s->youngs <= 1e13))
            return crom_err(CROM_EUSAGE, "--youngs must be a positive modulus in Pa, got %g (allowed (0, 1e13])",
                            s->youngs);
        return 0;
    case SC_POISSON:
        if (!(s->poisson > -1 && s->poisson < 0.5))
            return crom_err(CROM_EUSAGE, "--poisson must be in (-1, 0.5), got %g", s->poisson);
        return 0;
    case SC_DENSITY:
        if (!(s->density > 0 && s->density <= 1e6))
            return crom_err(CROM_EUSAGE, "--density must be positive, got %g (allowed (0, 1e6] kg/m^3)", s->density);
        return 0;
    case SC_DT:
        if (!(s->dt >= 1e-9 && s->dt <= 1e3))
            return crom_err(CROM_EUSAGE, "--dt must be in [1e-9, 1e3] s, got %g", s->dt);
        return 0;
    case SC_GRAVITY:
        if (!norm_ok(s->gravity, SC_MAX_G))
            return crom_err(CROM_EUSAGE, "--gravity: |g| must be at most %g m/s^2", SC_MAX_G);
        return 0;
    case SC_DAMPING:
        if (!(s->damping >= 0 && s->damping <= 1e6))
            return crom_err(CROM_EUSAGE, "--damping must be in [0, 1e6] 1/s, got %g", s->damping);
        return 0;
    case SC_CONTACT_K:
        if (!(s->contact_stiffness > 0 && s->contact_stiffness <= 1e12))
            return crom_err(CROM_EUSAGE, "--contact-stiffness must be in (0, 1e12] 1/s^2, got %g", s->contact_stiffness);
        return 0;
    case SC_FRICTION_EPS:
        if (!(s->friction_eps >= 1e-12 && s->friction_eps <= 1e3))
            return crom_err(CROM_EUSAGE, "--friction-eps must be in [1e-12, 1e3] m/s, got %g", s->friction_eps);
        return 0;
    case SC_TOL:
        /* relative to the bounding-box diagonal: 0.1 already accepts the first Newton step */
        if (!(s->tol >= 1e-16 && s->tol <= 0.1))
            return crom_err(CROM_EUSAGE, "--tol must be in [1e-16, 0.1] (relative to the body's size), got %g", s->tol);
        return 0;
    case SC_V0:
        if (!norm_ok(s->v0, SC_MAX_SPEED))
            return crom_err(CROM_EUSAGE, "--initial-velocity: the speed must be at most %g m/s", SC_MAX_SPEED);
        return 0;
    case SC_SPIN:
        if (!norm_ok(s->spin, SC_MAX_SPEED))
            return crom_err(CROM_EUSAGE, "--spin: the angular speed must be at most %g rad/s", SC_MAX_SPEED);
        return 0;
    }
    return 0;
}

int crom_scenario_check(const crom_scenario *s)
{
    static const int keys[] = {SC_YOUNGS, SC_POISSON, SC_DENSITY, SC_DT, SC_GRAVITY, SC_DAMPING,
                               SC_CONTACT_K, SC_FRICTION_EPS, SC_TOL, SC_V0, SC_SPIN};
    for (size_t i = 0; i < sizeof keys / sizeof *keys; i++) {
        int rc = check_value(s, keys[i]);
        if (rc)
            return rc;
    }
    if (s->every > s->steps && s->steps > 0)
        return crom_err(CROM_EUSAGE, "--every %d is more than --steps %d: no frame but the first would be stored",
                        s->every, s->steps);
    return 0;
}

int crom_scenario_option(crom_scenario *s, int key, const char *v)
{
    int rc = parse_option(s, key, v);
    return rc ? rc : check_value(s, key);
}

static void appendf(char **buf, size_t *len, size_t *cap, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
static void appendf(char **buf, size_t *len, size_t *cap, const char *fmt, ...)
{
    va_list ap;
    for (;;) {
        va_start(ap, fmt);
        int n = vsnprintf(*buf ? *buf + *len : NULL, *buf ? *cap - *len : 0, fmt, ap);
        va_end(ap);
        if (n < 0)
            return;
        if (*buf && *len + (size_t)n < *cap) {
            *len += (size_t)n;
            return;
        }
        if (crom_array_reserve((void **)buf, cap, *len + (size_t)n + 1, 1))
            return;
    }
}

static void bc_text(char **b, size_t *l, size_t *c, const char *flag, const crom_bc *bc)
{
    appendf(b, l, c, "%s %s=%.17g,%.17g,%.17g", flag, bc->ref, bc->v[0], bc->v[1], bc->v[2]);
    if (bc->t0 != 0 || isfinite(bc->t1)) {
        appendf(b, l, c, "@%.17g:", bc->t0);
        if (isfinite(bc->t1))
            appendf(b, l, c, "%.17g", bc->t1);
    }
    appendf(b, l, c, "\n");
}

char *crom_scenario_text(const crom_scenario *s)
{
    char *b = NULL;
    size_t l = 0, c = 0;
    appendf(&b, &l, &c, "--youngs %.17g\n--poisson %.17g\n--density %.17g\n", s->youngs,
            s->poisson, s->density);
    if (s->nmat) {
        char mb[CROM_SCENARIO_MAX * 3 * 180];
        crom_scenario_material_flags(s, mb, sizeof mb);
        appendf(&b, &l, &c, "%s", mb);
    }
    appendf(&b, &l, &c, "--dt %.17g\n--steps %d\n--every %d\n", s->dt, s->steps, s->every);
    appendf(&b, &l, &c, "--gravity %.17g,%.17g,%.17g\n", s->gravity[0], s->gravity[1], s->gravity[2]);
    for (int i = 0; i < s->npins; i++)
        appendf(&b, &l, &c, "--pin %s\n", s->pins[i]);
    for (int i = 0; i < s->nvel; i++)
        bc_text(&b, &l, &c, "--velocity", &s->vel[i]);
    for (int i = 0; i < s->nforce; i++)
        bc_text(&b, &l, &c, "--force", &s->force[i]);
    for (int i = 0; i < s->nrod; i++) {
        char rb[400];
        crom_rod_format(&s->rod[i], rb, sizeof rb);
        appendf(&b, &l, &c, "--rod %s\n", rb);
    }
    for (int i = 0; i < s->nplanes; i++)
        if (s->plane[i].sphere)
            appendf(&b, &l, &c, "--sphere %.17g,%.17g,%.17g,%.17g,%.17g\n", s->plane[i].c[0], s->plane[i].c[1],
                    s->plane[i].c[2], s->plane[i].r, s->plane[i].mu);
        else
            appendf(&b, &l, &c, "--plane %.17g,%.17g,%.17g,%.17g,%.17g\n", s->plane[i].n[0],
                    s->plane[i].n[1], s->plane[i].n[2], s->plane[i].d, s->plane[i].mu);
    if (s->damping)
        appendf(&b, &l, &c, "--damping %.17g\n", s->damping);
    appendf(&b, &l, &c, "--contact-stiffness %.17g\n--friction-eps %.17g\n--tol %.17g\n--max-iter %d\n",
            s->contact_stiffness, s->friction_eps, s->tol, s->max_iter);
    if (s->v0[0] || s->v0[1] || s->v0[2])
        appendf(&b, &l, &c, "--initial-velocity %.17g,%.17g,%.17g\n", s->v0[0], s->v0[1], s->v0[2]);
    if (s->spin[0] || s->spin[1] || s->spin[2])
        appendf(&b, &l, &c, "--spin %.17g,%.17g,%.17g\n", s->spin[0], s->spin[1], s->spin[2]);
    return b;
}

/* The flag and region of condition k: pins 0..npins-1, then velocities. */
static const char *cond_flag(const crom_scenario *s, int k) { return k < s->npins ? "--pin" : "--velocity"; }
static const char *cond_ref(const crom_scenario *s, int k)
{
    return k < s->npins ? s->pins[k] : s->vel[k - s->npins].ref;
}

int crom_scenario_check_regions(const crom_scenario *s, const crom_mesh *m)
{
    if (s->nvel == 0)
        return 0;
    int *owner = crom_malloc(sizeof(int) * (size_t)(m->nv ? m->nv : 1)), rc = 0;
    if (!owner)
        return CROM_EINTERNAL;
    for (int v = 0; v < m->nv; v++)
        owner[v] = -1;
    for (int k = 0; !rc && k < s->npins + s->nvel; k++) {
        int *idx = NULL, n = 0;
        if ((rc = crom_mesh_select(m, cond_ref(s, k), &idx, &n)))
            break;
        for (int i = 0; i < n; i++) {
            int v = idx[i], o = owner[v];
            if (o >= 0 && (k >= s->npins || o >= s->npins)) {
                const double *X = m->X + 3 * (size_t)v;
                rc = crom_err(CROM_EUSAGE, "%s '%s' and %s '%s' share vertex %d (at %.4g, %.4g, %.4g): each "
                              "vertex follows one condition; make the regions disjoint", cond_flag(s, o),
                              cond_ref(s, o), cond_flag(s, k), cond_ref(s, k), v, X[0], X[1], X[2]);
                break;
            }
            owner[v] = o >= 0 ? o : k;
        }
        free(idx);
    }
    free(owner);
    return rc;
}

void crom_scenario_initial_velocity(const crom_scenario *s, const double c[3], const double X[3], double v[3])
{
    const double *w = s->spin;
    double r[3] = {X[0] - c[0], X[1] - c[1], X[2] - c[2]};
    v[0] = s->v0[0] + w[1] * r[2] - w[2] * r[1];
    v[1] = s->v0[1] + w[2] * r[0] - w[0] * r[2];
    v[2] = s->v0[2] + w[0] * r[1] - w[1] * r[0];
}

int crom_scenario_parse_text(const char *text, crom_scenario *s)
{
    if (!text)
        return 0;
    const char *p = text;
    while (*p) {
        const char *e = strchr(p, '\n');
        size_t len = e ? (size_t)(e - p) : strlen(p);
        char line[512];
        if (len >= sizeof line)
            return crom_err(CROM_EDATA, "scenario line too long");
        memcpy(line, p, len);
        line[len] = 0;
        p += len + (e != NULL);
        char *c = line;
        while (*c == ' ' || *c == '\t')
            c++;
        if (strncmp(c, "--", 2))
            continue;
        c += 2;
        char *v = c + strcspn(c, " \t=");
        if (*v)
            *v++ = 0;
        while (*v == ' ' || *v == '\t')
            v++;
        for (const crom_opt *op = crom_scenario_opts; op->name; op++)
            if (!strcmp(op->name, c)) {
                int rc = crom_scenario_option(s, op->key, v);
                if (rc > 0)
                    return crom_err(CROM_EDATA, "scenario flag --%s %s: %s", c, v, crom_errmsg());
                break;
            }
    }
    return 0;
}

int crom_scenario_write_attrs(hid_t h, const crom_scenario *s)
{
    char *text = crom_scenario_text(s);
    if (!text)
        return crom_err(CROM_EINTERNAL, "out of memory");
    int rc = crom_h5_set_str(h, ".", "scenario", text);
    free(text);
    if (!rc)
        rc = crom_h5_set_f64(h, ".", "dt", &s->dt, 1);
    if (!rc)
        rc = crom_h5_set_i64(h, ".", "every", s->every);
    if (!rc)
        rc = crom_h5_set_i64(h, ".", "steps", s->steps);
    if (!rc)
        rc = crom_h5_set_f64(h, ".", "youngs", &s->youngs, 1);
    if (!rc)
        rc = crom_h5_set_f64(h, ".", "poisson", &s->poisson, 1);
    if (!rc)
        rc = crom_h5_set_f64(h, ".", "density", &s->density, 1);
    if (!rc)
        rc = crom_h5_set_f64(h, ".", "gravity", s->gravity, 3);
    if (!rc)
        rc = crom_h5_set_f64(h, ".", "tolerance", &s->tol, 1);
    return rc;
}

int crom_scenario_materials(const crom_scenario *s, const crom_mesh *m, crom_material *mats, int *nmat, int **tmat)
{
    *nmat = 1;
    *tmat = NULL;
    int rc = crom_material_init(&mats[0], s->youngs, s->poisson, s->density);
    if (rc || !s->nmat)
        return rc;
    if (crom_mesh_is_surface(m) || crom_mesh_is_scene(m))
        return crom_err(CROM_EUSAGE, "--youngs/--poisson %s=: regions of other materials are for tet meshes; this one "
                        "is a %s", s->mat[0].ref, crom_mesh_is_surface(m) ? "shell" : "rigid-body scene");
    int *t = crom_calloc((size_t)m->nt, sizeof *t);
    unsigned char *in = crom_malloc((size_t)(m->nv ? m->nv : 1));
    if (!t || !in) {
        free(t);
        free(in);
        return CROM_EINTERNAL;
    }
    for (int k = 0; !rc && k < s->nmat; k++) {
        const crom_scenario_material *o = &s->mat[k];
        double E = isnan(o->youngs) ? s->youngs : o->youngs, nu = isnan(o->poisson) ? s->poisson : o->poisson,
               rho = isnan(o->density) ? s->density : o->density;
        if ((rc = crom_material_init(&mats[k + 1], E, nu, rho))) {
            crom_err(rc, "region '%s': %s", o->ref, crom_errmsg());
            break;
        }
        int *idx = NULL, n = 0;
        if ((rc = crom_mesh_select(m, o->ref, &idx, &n)))
            break;
        memset(in, 0, (size_t)m->nv);
        for (int i = 0; i < n; i++)
            in[idx[i]] = 1;
        free(idx);
        int whole = 0;
        for (int e = 0; e < m->nt; e++) {
            const int *v = m->tets + 4 * (size_t)e;
            if (in[v[0]] && in[v[1]] && in[v[2]] && in[v[3]]) {
                t[e] = k + 1;
                whole++;
            }
        }
        if (!whole)
            rc = crom_err(CROM_EUSAGE, "region '%s' (%d vertices) holds no whole tet: it can have no material of its "
                          "own", o->ref, n);
    }
    free(in);
    if (rc) {
        free(t);
        return rc;
    }
    *nmat = s->nmat + 1;
    *tmat = t;
    return 0;
}

int crom_scenario_uniform(const crom_scenario *s, const char *prog)
{
    if (!s->nmat)
        return 0;
    return crom_err(CROM_EUSAGE, "--%s %s=: %s takes one material for the whole body (regions of other materials: "
                    "crom-fullsim, crom-reducedstep, crom-live, crom-modes, crom-fitfield's data-free objectives)", !isnan(s->mat[0].youngs) ? "youngs" : !isnan(s->mat[0].poisson) ? "poisson" : "density",
                    s->mat[0].ref, prog);
}

size_t crom_scenario_material_flags(const crom_scenario *s, char *buf, size_t cap)
{
    size_t l = 0;
    if (cap)
        buf[0] = 0;
    for (int i = 0; i < s->nmat; i++) {
        const crom_scenario_material *o = &s->mat[i];
        if (!isnan(o->youngs))
            l += (size_t)snprintf(buf + (l < cap ? l : cap), l < cap ? cap - l : 0, "--youngs %s=%.17g\n", o->ref,
                                  o->youngs);
        if (!isnan(o->poisson))
            l += (size_t)snprintf(buf + (l < cap ? l : cap), l < cap ? cap - l : 0, "--poisson %s=%.17g\n", o->ref,
                                  o->poisson);
        if (!isnan(o->density))
            l += (size_t)snprintf(buf + (l < cap ? l : cap), l < cap ? cap - l : 0, "--density %s=%.17g\n", o->ref,
                                  o->density);
    }
    return l;
}

/* ---- conditions (scenario.h) ----------------------------------------- */

int crom_scenario_cond_parse(const char *flag, const char *v, int range, crom_scenario_cond *c)
{
    memset(c, 0, sizeof *c);
    const char *eq = strrchr(v, '=');
    if (!eq)
        return crom_err(CROM_EUSAGE, "%s '%s': expected NAME=%s (NAME ratio:REGION, gravity:x|y|z or "
                        "pin:REGION:x|y|z)", flag, v, range ? "LO:HI" : "VALUE");
    size_t len = (size_t)(eq - v);
    if (len > 6 && !strncmp(v, "ratio:", 6)) {
        c->kind = CROM_SCENARIO_COND_RATIO;
        if (len - 6 >= sizeof c->ref || check_ref(flag, v + 6, len - 6))
            return crom_err(CROM_EUSAGE, "%s '%s': a bad region", flag, v);
        memcpy(c->ref, v + 6, len - 6);
    } else if (len == 9 && !strncmp(v, "gravity:", 8) && strchr("xyz", v[8]) && v[8]) {
        c->kind = CROM_SCENARIO_COND_GRAVITY;
        c->axis = v[8] - 'x';
    } else if (len > 6 && !strncmp(v, "pin:", 4)) { /* pin:REGION:AXIS */
        c->kind = CROM_SCENARIO_COND_PIN;
        if (!(len >= 7 && v[len - 2] == ':' && strchr("xyz", v[len - 1]) && v[len - 1]))
            return crom_err(CROM_EUSAGE, "%s '%s': expected pin:REGION:x|y|z", flag, v);
        c->axis = v[len - 1] - 'x';
        if (len - 6 >= sizeof c->ref || check_ref(flag, v + 4, len - 6))
            return crom_err(CROM_EUSAGE, "%s '%s': a bad region", flag, v);
        memcpy(c->ref, v + 4, len - 6);
    } else {
        return crom_err(CROM_EUSAGE, "%s '%.*s': not a condition (ratio:REGION, gravity:x|y|z or pin:REGION:x|y|z)",
                        flag, (int)len, v);
    }
    double d[2];
    if (range) {
        const char *colon = strchr(eq + 1, ':');
        char a[64];
        if (!colon || (size_t)(colon - eq - 1) >= sizeof a)
            return crom_err(CROM_EUSAGE, "%s '%s': expected a range LO:HI after '='", flag, v);
        memcpy(a, eq + 1, (size_t)(colon - eq - 1));
        a[colon - eq - 1] = 0;
        if (crom_parse_double(a, flag, &d[0]) || crom_parse_double(colon + 1, flag, &d[1]))
            return CROM_EUSAGE;
    } else if (crom_parse_double(eq + 1, flag, &d[0])) {
        return CROM_EUSAGE;
    } else {
        d[1] = d[0];
    }
    if (!(d[0] <= d[1]))
        return crom_err(CROM_EUSAGE, "%s '%s': the range is empty (%g > %g)", flag, v, d[0], d[1]);
    if (c->kind == CROM_SCENARIO_COND_RATIO && !(d[0] > 0 && d[1] <= 1e6))
        return crom_err(CROM_EUSAGE, "%s '%s': a modulus ratio must be in (0, 1e6]", flag, v);
    if (c->kind == CROM_SCENARIO_COND_GRAVITY && !(fabs(d[0]) <= 1e4 && fabs(d[1]) <= 1e4))
        return crom_err(CROM_EUSAGE, "%s '%s': gravity must be within 1e4 m/s^2", flag, v);
    if (c->kind == CROM_SCENARIO_COND_PIN && !(fabs(d[0]) <= 1e3 && fabs(d[1]) <= 1e3))
        return crom_err(CROM_EUSAGE, "%s '%s': a pin's displacement must be within 1e3 m", flag, v);
    c->lo = d[0];
    c->hi = d[1];
    return 0;
}

/* v with the fewest digits (15 to 17) that read back as v */
static void shortest(double v, char out[32])
{
    for (int d = 15; d <= 17; d++) {
        snprintf(out, 32, "%.*g", d, v);
        if (strtod(out, NULL) == v)
            return;
    }
}

int crom_scenario_cond_format(const crom_scenario_cond *c, char *buf, int cap)
{
    char lo[32], hi[32];
    shortest(c->lo, lo);
    shortest(c->hi, hi);
    if (c->kind == CROM_SCENARIO_COND_RATIO)
        return snprintf(buf, (size_t)cap, "ratio:%s=%s:%s", c->ref, lo, hi);
    if (c->kind == CROM_SCENARIO_COND_PIN)
        return snprintf(buf, (size_t)cap, "pin:%s:%c=%s:%s", c->ref, 'x' + c->axis, lo, hi);
    return snprintf(buf, (size_t)cap, "gravity:%c=%s:%s", 'x' + c->axis, lo, hi);
}

int crom_scenario_cond_same(const crom_scenario_cond *a, const crom_scenario_cond *b)
{
    return a->kind == b->kind && (a->kind == CROM_SCENARIO_COND_GRAVITY || !strcmp(a->ref, b->ref)) &&
           (a->kind == CROM_SCENARIO_COND_RATIO || a->axis == b->axis);
}

int crom_scenario_cond_apply(crom_scenario *s, const crom_scenario_cond *c, double value)
{
    if (c->kind == CROM_SCENARIO_COND_GRAVITY) {
        s->gravity[c->axis] = value;
        return 0;
    }
    if (c->kind == CROM_SCENARIO_COND_PIN)
        return 0;
    if (!(value > 0))
        return crom_err(CROM_EUSAGE, "ratio:%s: a modulus ratio must be positive, got %g", c->ref, value);
    char v[160];
    snprintf(v, sizeof v, "%s=%.17g", c->ref, value * s->youngs);
    return parse_material(s, SC_YOUNGS, v);
}
