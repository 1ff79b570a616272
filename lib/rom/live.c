/* live.c — commands that steer a reduced run between its steps (see live.h). */
#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "base/parse.h"
#include "rom/live.h"

static const struct {
    const char *name;
    crom_live_kind kind;
    const char *usage;
} cmds[] = {{"drag", CROM_LIVE_DRAG, "drag REF X,Y,Z [K]"},
            {"release", CROM_LIVE_RELEASE, "release [REF]"},
            {"force", CROM_LIVE_FORCE, "force REF FX,FY,FZ"},
            {"pin", CROM_LIVE_PIN, "pin REF"},
            {"unpin", CROM_LIVE_UNPIN, "unpin REF"},
            {"schedule", CROM_LIVE_SCHEDULE, "schedule CUBATURE"},
            {"condition", CROM_LIVE_CONDITION, "condition NAME=VALUE"},
            {"step", CROM_LIVE_STEP, "step N"},
            {"quit", CROM_LIVE_QUIT, "quit"}};
#define NCMDS (sizeof cmds / sizeof *cmds)

/* The next blank-separated word of *p into w (at most cap − 1 bytes);
 * returns its length, 0 at the end, −1 when too long. */
static int word(const char **p, char *w, size_t cap)
{
    const char *s = *p;
    while (*s == ' ' || *s == '\t')
        s++;
    size_t n = 0;
    while (s[n] && s[n] != ' ' && s[n] != '\t' && s[n] != '\n' && s[n] != '\r')
        n++;
    *p = s + n;
    if (n >= cap)
        return -1;
    memcpy(w, s, n);
    w[n] = 0;
    return (int)n;
}

int crom_live_parse(const char *line, crom_live_cmd *c)
{
    memset(c, 0, sizeof *c);
    const char *p = line;
    char name[32], a[sizeof c->ref], b[sizeof c->ref], extra[sizeof c->ref], more[sizeof c->ref];
    int n = word(&p, name, sizeof name);
    if (n == 0 || name[0] == '#')
        return 0; /* nothing */
    size_t i = 0;
    while (i < NCMDS && (n < 0 || strcmp(cmds[i].name, name)))
        i++;
    if (i == NCMDS) {
        char shown[40];
        snprintf(shown, sizeof shown, "%.32s%s", line + strspn(line, " \t"), n < 0 ? "..." : "");
        shown[strcspn(shown, " \t\r\n")] = 0;
        return crom_err(CROM_EUSAGE, "unknown command '%s' (drag, release, force, pin, unpin, schedule, condition, "
                        "step, quit)", shown);
    }
    c->kind = cmds[i].kind;
    const char *usage = cmds[i].usage;
    int na = word(&p, a, sizeof a), nb = na > 0 ? word(&p, b, sizeof b) : 0;
    int nx = nb > 0 ? word(&p, extra, sizeof extra) : 0, nmore = nx > 0 ? word(&p, more, sizeof more) : 0;
    if (na < 0 || nb < 0 || nx < 0 || nmore < 0)
        return crom_err(CROM_EUSAGE, "%s: a word too long (at most %zu bytes)", name, sizeof c->ref - 1);
    int args = (na > 0) + (nb > 0) + (nx > 0) + (nmore > 0);
    int lo = 1, hi = 1;
    switch (c->kind) {
    case CROM_LIVE_DRAG: lo = 2, hi = 3; break;
    case CROM_LIVE_RELEASE: lo = 0; break;
    case CROM_LIVE_FORCE: lo = hi = 2; break;
    case CROM_LIVE_QUIT: lo = hi = 0; break;
    default: break;
    }
    if (args < lo || args > hi)
        return crom_err(CROM_EUSAGE, "%s: expected '%s'", name, usage);
    if (na > 0)
        snprintf(c->ref, sizeof c->ref, "%s", a);
    int rc = 0;
    switch (c->kind) {
    case CROM_LIVE_DRAG:
    case CROM_LIVE_FORCE:
        rc = crom_parse_doubles(b, name, 3, c->v);
        if (!rc && !(isfinite(c->v[0]) && isfinite(c->v[1]) && isfinite(c->v[2])))
            rc = crom_err(CROM_EUSAGE, "%s %s: '%s' is not a finite vector", name, c->ref, b);
        if (!rc && nx > 0) {
            rc = crom_parse_double(extra, "drag stiffness", &c->k);
            if (!rc && !(c->k > 0 && isfinite(c->k)))
                rc = crom_err(CROM_EUSAGE, "drag %s: the stiffness '%s' must be positive (N/m)", c->ref, extra);
        }
        break;
    case CROM_LIVE_STEP:
        rc = crom_parse_int(a, "step", 1, 100000000L, &c->n);
        break;
    case CROM_LIVE_CONDITION:
        if (!strchr(a, '=') || a[0] == '=')
            rc = crom_err(CROM_EUSAGE, "condition: expected NAME=VALUE, not '%s'", a);
        break;
    default: break;
    }
    return rc;
}

/* The default drag: its spring, stretched by a tenth of the body's size,
 * carries the body's weight (100 m g / L; g = 9.81 if the run has none). */
static double default_drag_k(const crom_live *L)
{
    const crom_cubature *c = L->cubs[L->cur];
    double g = sqrt(L->sc.gravity[0] * L->sc.gravity[0] + L->sc.gravity[1] * L->sc.gravity[1] +
                    L->sc.gravity[2] * L->sc.gravity[2]);
    return 10 * L->sc.density * c->mesh_volume * (g > 0 ? g : 9.81) / L->sim.L;
}

int crom_live_init(crom_live *L, const crom_cubature *cub, const crom_scenario *sc, int solver, double kappa,
                   double drag_k)
{
    memset(L, 0, sizeof *L);
    if (cub->map_rank > 0) /* its W is a nonlinear map's feature basis, which rsim does not step */
        return crom_err(CROM_EUSAGE, "the cubature of a nonlinear map (model %s): crom-live steps linear subspaces "
                        "(crom-reducedstep --model runs it)", cub->model_id);
    L->sc = *sc;
    L->cubs = crom_malloc(sizeof *L->cubs);
    if (!L->cubs)
        return CROM_EINTERNAL;
    L->cubs[0] = (crom_cubature *)cub; /* borrowed: never freed here */
    L->ncubs = 1;
    L->first_live = L->sc.nforce;
    int rc = crom_rsim_init(&L->sim, cub, &L->sc, solver, kappa, NULL, NULL);
    if (rc) {
        free(L->cubs);
        L->cubs = NULL;
        return rc;
    }
    L->drag_k = drag_k > 0 ? drag_k : default_drag_k(L);
    return 0;
}

double crom_live_force_window(const crom_live *L) { return L->sim.t + 0.5 * L->sc.dt; }

/* The region exists on mesh m and is not empty. */
static int check_ref(const crom_mesh *m, const char *ref)
{
    int *idx = NULL, n = 0;
    int rc = crom_mesh_select(m, ref, &idx, &n);
    free(idx);
    return rc;
}

static int apply_force(crom_live *L, const crom_live_cmd *c)
{
    int rc = check_ref(&L->cubs[L->cur]->mesh, c->ref);
    if (rc)
        return rc;
    crom_scenario *sc = &L->sc;
    for (int i = L->first_live; i < sc->nforce; i++)
        if (!strcmp(sc->force[i].ref, c->ref)) { /* changed in place: loads are taken step by step */
            memcpy(sc->force[i].v, c->v, sizeof c->v);
            return 0;
        }
    if (!c->v[0] && !c->v[1] && !c->v[2])
        return 0;
    if (sc->nforce == CROM_SCENARIO_MAX)
        return crom_err(CROM_EUSAGE, "force %s: at most %d forces in a run", c->ref, CROM_SCENARIO_MAX);
    crom_bc *b = &sc->force[sc->nforce];
    memset(b, 0, sizeof *b);
    snprintf(b->ref, sizeof b->ref, "%s", c->ref);
    memcpy(b->v, c->v, sizeof c->v);
    b->t0 = crom_live_force_window(L);
    b->t1 = INFINITY;
    sc->nforce++;
    if ((rc = crom_rsim_sync_forces(&L->sim))) {
        sc->nforce--;
        return rc;
    }
    L->nlive++;
    return 0;
}

/* Pins change the BC penalty's directions: the simulation is rebuilt on its
 * cubature, its state kept. */
static int apply_pin(crom_live *L, const crom_live_cmd *c)
{
    crom_scenario *sc = &L->sc;
    int at = -1;
    for (int i = 0; i < sc->npins; i++)
        if (!strcmp(sc->pins[i], c->ref))
            at = i;
    if (c->kind == CROM_LIVE_PIN) {
        if (at >= 0)
            return crom_err(CROM_EUSAGE, "pin %s: pinned already", c->ref);
        if (sc->npins == CROM_SCENARIO_MAX)
            return crom_err(CROM_EUSAGE, "pin %s: at most %d pins", c->ref, CROM_SCENARIO_MAX);
        int rc = check_ref(&L->cubs[L->cur]->mesh, c->ref);
        if (rc)
            return rc;
        snprintf(sc->pins[sc->npins++], sizeof sc->pins[0], "%s", c->ref);
    } else {
        if (at < 0)
            return crom_err(CROM_EUSAGE, "unpin %s: not pinned (pinned: %d regions)", c->ref, sc->npins);
        memmove(sc->pins[at], sc->pins[at + 1], sizeof sc->pins[0] * (size_t)(sc->npins - at - 1));
        sc->npins--;
    }
    return crom_rsim_set_cubature(&L->sim, L->cubs[L->cur]);
}

static int apply_schedule(crom_live *L, const crom_live_cmd *c)
{
    crom_cubature *cub = crom_malloc(sizeof *cub);
    crom_cubature **a = cub ? realloc(L->cubs, sizeof *a * (size_t)(L->ncubs + 1)) : NULL;
    if (!a) {
        free(cub);
        return CROM_EINTERNAL;
    }
    L->cubs = a;
    int rc = crom_cubature_load(c->ref, cub, NULL);
    if (!rc && cub->map_rank > 0)
        rc = crom_err(CROM_EDATA, "%s is the cubature of a nonlinear map: crom-live steps linear subspaces", c->ref);
    if (!rc && (cub->r != L->sim.r || strcmp(cub->model_id, L->cubs[L->cur]->model_id)))
        rc = crom_err(CROM_EDATA, "%s belongs to model %s (rank %d), the run uses model %s (rank %d)", c->ref,
                      cub->model_id, cub->r, L->cubs[L->cur]->model_id, L->sim.r);
    if (!rc) /* every region the run uses must be on the new mesh */
        rc = crom_scenario_check_regions(&L->sc, &cub->mesh);
    for (int d = 0; !rc && d < L->sim.ndrag; d++)
        rc = check_ref(&cub->mesh, L->sim.drag[d].ref);
    if (!rc)
        rc = crom_rsim_set_cubature(&L->sim, cub);
    if (rc) {
        crom_cubature_free(cub);
        free(cub);
        return rc;
    }
    L->cubs[L->ncubs] = cub;
    L->cur = L->ncubs++;
    return 0;
}

int crom_live_apply(crom_live *L, const crom_live_cmd *c)
{
    switch (c->kind) {
    case CROM_LIVE_DRAG:
        return crom_rsim_drag_set(&L->sim, c->ref, c->v, c->k > 0 ? c->k : L->drag_k);
    case CROM_LIVE_RELEASE:
        if (c->ref[0] && crom_rsim_drag_release(&L->sim, c->ref) == 0)
            return crom_err(CROM_EUSAGE, "release %s: no drag on it", c->ref);
        if (!c->ref[0])
            crom_rsim_drag_release(&L->sim, NULL);
        return 0;
    case CROM_LIVE_FORCE: return apply_force(L, c);
    case CROM_LIVE_PIN:
    case CROM_LIVE_UNPIN: return apply_pin(L, c);
    case CROM_LIVE_SCHEDULE: return apply_schedule(L, c);
    case CROM_LIVE_CONDITION:
        return crom_err(CROM_EUSAGE, "condition %s: model %s has no conditions", c->ref, L->cubs[L->cur]->model_id);
    default: return 0;
    }
}

void crom_live_free(crom_live *L)
{
    crom_rsim_free(&L->sim);
    for (int i = 1; i < L->ncubs; i++) {
        crom_cubature_free(L->cubs[i]);
        free(L->cubs[i]);
    }
    free(L->cubs);
    memset(L, 0, sizeof *L);
}
