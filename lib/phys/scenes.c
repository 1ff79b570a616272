/* scenes.c — the paper's rigid-body scenes from parameters (scenes.h). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "phys/rigidsys.h"
#include "phys/scenes.h"

static int check_params(const crom_scenes_params *p, int chain)
{
    if (chain && (p->links < 1 || p->links > 100000))
        return crom_err(CROM_EUSAGE, "a chain needs 1 to 100000 links, got %d", p->links);
    const double v[3] = {p->length, p->radius, p->density};
    const char *n[3] = {"length", "radius", "density"};
    for (int i = 0; i < 3; i++)
        if (!(v[i] > 0) || !isfinite(v[i]))
            return crom_err(CROM_EUSAGE, "scene %s %g: it must be positive and finite", n[i], v[i]);
    if (!isfinite(p->angle) || !isfinite(p->joint_weight) || !isfinite(p->ortho_weight) || !isfinite(p->gravity))
        return crom_err(CROM_EUSAGE, "scene parameters must be finite");
    return 0;
}

/* the defaults of scenes.h for a scene of total mass m, heaviest body mb,
 * link length l */
static void default_weights(const crom_scenes_params *p, double m, double mb, double l, crom_scene *s)
{
    double g = p->gravity > 0 ? p->gravity : 9.81;
    s->ortho_weight = p->ortho_weight > 0 ? p->ortho_weight : 1e4 * mb * g * l;
    for (int j = 0; j < s->nj; j++)
        s->joints[j].weight = p->joint_weight > 0 ? p->joint_weight : 1e4 * m * g / l;
    for (int k = 0; k < s->np; k++)
        s->pairs[k].weight = p->contact_weight > 0 ? p->contact_weight : 1e3 * m * g / p->radius;
}

int crom_scenes_pendulum(const crom_scenes_params *p, crom_mesh *m)
{
    memset(m, 0, sizeof *m);
    int rc = check_params(p, 0);
    if (rc)
        return rc;
    crom_scene s = {0};
    const double size[3] = {p->radius, 0, 0}, c[3] = {p->length * cos(p->angle), -p->length * sin(p->angle), 0};
    crom_scene_body b = crom_scene_body_make(CROM_SCENE_SPHERE, size, c, p->density);
    crom_scene_joint j = {0, -1, {0, 0, 0}, 0};
    if (crom_scene_add_body(&s, &b) || crom_scene_add_joint(&s, &j)) {
        crom_scene_free(&s);
        return CROM_EINTERNAL;
    }
    double mass = p->density * crom_scene_body_volume(&b);
    default_weights(p, mass, mass, p->length, &s);
    static const char *const names[] = {"bob"};
    return crom_rigidsys_scene_mesh(&s, names, m);
}

/* the rings of a ring chain and their contacts */
static int ring_links(const crom_scenes_params *p, crom_scene *s, double *mb, double *pitch)
{
    double r = p->radius, R = p->ring_radius, L = p->length, h = L / 2;
    if (!(R > r) || !isfinite(R))
        return crom_err(CROM_EUSAGE, "ring links: the ring radius %g m must exceed the tube radius %g m", R, r);
    *pitch = 2 * (h + R) - 2.5 * r;
    int rc = 0;
    for (int i = 0; i < p->links && !rc; i++) {
        const double size[3] = {r, R, L}, c[3] = {h + R + i * *pitch, 0, 0};
        crom_scene_body b = crom_scene_body_make(CROM_SCENE_RING, size, c, p->density);
        if (i % 2) { /* the xz-plane: shape y to world z, shape z to world −y */
            const double Q[9] = {1, 0, 0, 0, 0, -1, 0, 1, 0};
            memcpy(b.rot, Q, sizeof Q);
        }
        rc = crom_scene_add_body(s, &b);
        for (int k = 0; i > 0 && k < 2 && !rc; k++) {
            crom_scene_pair pr = {k ? i - 1 : i, k ? i : i - 1, 0};
            rc = crom_scene_add_pair(s, &pr);
        }
    }
    /* pinned at the first link's far end (a point of its tube's centreline) */
    crom_scene_joint j = {0, -1, {0, 0, 0}, 0};
    if (!rc)
        rc = crom_scene_add_joint(s, &j);
    if (!rc)
        *mb = p->density * crom_scene_body_volume(&s->bodies[0]);
    return rc;
}

int crom_scenes_chain(const crom_scenes_params *p, crom_mesh *m)
{
    memset(m, 0, sizeof *m);
    int rc = check_params(p, 1);
    if (rc)
        return rc;
    int n = p->links;
    crom_scene s = {0};
    double l = p->length, mb = 0, pitch = l;
    if (p->angle != 0)
        return crom_err(CROM_EUSAGE, "a chain starts horizontal (angle 0)");
    if (p->rings) {
        rc = ring_links(p, &s, &mb, &pitch);
    } else {
        /* a capsule's axis is its shape x: the chain starts straight along x
         * (Sharp Fig. 6 drops a horizontal chain) */
        for (int i = 0; i < n && !rc; i++) {
            const double size[3] = {p->radius, l, 0}, c[3] = {(i + 0.5) * l, 0, 0};
            crom_scene_body b = crom_scene_body_make(CROM_SCENE_CAPSULE, size, c, p->density);
            rc = crom_scene_add_body(&s, &b);
            crom_scene_joint j = {i, i - 1, {i * l, 0, 0}, 0};
            if (!rc)
                rc = crom_scene_add_joint(&s, &j);
        }
        if (!rc)
            mb = p->density * crom_scene_body_volume(&s.bodies[0]);
    }
    char **names = crom_calloc((size_t)n, sizeof(char *));
    if (!rc && !names)
        rc = CROM_EINTERNAL;
    for (int i = 0; !rc && i < n; i++) {
        char buf[32];
        snprintf(buf, sizeof buf, "link%d", i);
        if (!(names[i] = crom_strdup(buf)))
            rc = CROM_EINTERNAL;
    }
    if (rc) {
        crom_scene_free(&s);
    } else {
        default_weights(p, n * mb, mb, pitch, &s);
        rc = crom_rigidsys_scene_mesh(&s, (const char *const *)names, m);
    }
    for (int i = 0; names && i < n; i++)
        free(names[i]);
    free(names);
    return rc;
}
