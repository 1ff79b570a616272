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
    crom_scene_joint j = {0, -1, {0, 0, 0}, 0, CROM_SCENE_POINT, {0, 0, 0}};
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
    crom_scene_joint j = {0, -1, {0, 0, 0}, 0, CROM_SCENE_POINT, {0, 0, 0}};
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
            crom_scene_joint j = {i, i - 1, {i * l, 0, 0}, 0, CROM_SCENE_POINT, {0, 0, 0}};
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

/* ------------------------------------------------------------- Klann */

/* the optimized Klann geometry (boim.com/Walkin8r), crank AC = 17.5 */
#define K_AC 17.5
static const double k_B[2] = {-38.8, -12.5}, k_D[2] = {-14.6, 41.9};
#define K_BH 23.7
#define K_CF 73.4
#define K_CH 38.8
#define K_DE 34.1
#define K_EF 57.7
#define K_EG 111.7
#define K_FG 59.0
#define K_FH 35.2
enum { KA, KB, KC, KD, KE, KF, KG, KH };

/* the two intersections of circles (p, r) and (q, s): out[0] left of p->q
 * (counter-clockwise), out[1] right; 1 when they do not meet */
static int circles(const double p[2], double r, const double q[2], double s, double out[2][2])
{
    double dx = q[0] - p[0], dy = q[1] - p[1], d = hypot(dx, dy);
    if (!(d > 0) || d > r + s || d < fabs(r - s))
        return 1;
    double a = (r * r - s * s + d * d) / (2 * d), h = sqrt(fmax(r * r - a * a, 0));
    double mx = p[0] + a * dx / d, my = p[1] + a * dy / d;
    out[0][0] = mx - h * dy / d, out[0][1] = my + h * dx / d;
    out[1][0] = mx + h * dy / d, out[1][1] = my - h * dx / d;
    return 0;
}

/* the branch of two intersections: the one nearer to hint (when given),
 * else out[side] */
static void pick(double out[2][2], const double *hint, int side, double res[2])
{
    int k = side;
    if (hint)
        k = hypot(out[0][0] - hint[0], out[0][1] - hint[1]) <= hypot(out[1][0] - hint[0], out[1][1] - hint[1]) ? 0 : 1;
    res[0] = out[k][0], res[1] = out[k][1];
}

int crom_scenes_klann_points(double theta, double length, const double *prev, double P[8][2])
{
    double s = length / K_AC, X[2][2];
    P[KA][0] = P[KA][1] = 0;
    P[KB][0] = s * k_B[0], P[KB][1] = s * k_B[1];
    P[KD][0] = s * k_D[0], P[KD][1] = s * k_D[1];
    P[KC][0] = length * cos(theta), P[KC][1] = length * sin(theta);
    /* H: on the rocker from B and CH from C; F and G: the rigid triangles
     * C-H-F and E-F-G, on the side they were built with (the knee's bend);
     * E: on the rocker from D and EF from F. The branches: the assembly
     * whose crank turns fully with the foot below, tracing Klann's flat
     * stride (74 by 33 units at the geometry's scale) */
    if (circles(P[KB], s * K_BH, P[KC], s * K_CH, X))
        return crom_err(CROM_EDATA, "the Klann linkage does not assemble at crank angle %g (H)", theta);
    pick(X, prev ? prev + 2 * KH : NULL, 0, P[KH]);
    if (circles(P[KC], s * K_CF, P[KH], s * K_FH, X))
        return crom_err(CROM_EDATA, "the Klann linkage does not assemble at crank angle %g (F)", theta);
    pick(X, NULL, 0, P[KF]);
    if (circles(P[KD], s * K_DE, P[KF], s * K_EF, X))
        return crom_err(CROM_EDATA, "the Klann linkage does not assemble at crank angle %g (E)", theta);
    pick(X, prev ? prev + 2 * KE : NULL, 1, P[KE]);
    if (circles(P[KE], s * K_EG, P[KF], s * K_FG, X))
        return crom_err(CROM_EDATA, "the Klann linkage does not assemble at crank angle %g (G)", theta);
    pick(X, NULL, 0, P[KG]);
    return 0;
}

/* a thin box along the segment p0-p1 in the xy-plane, half width and
 * thickness hw */
static crom_scene_body bar(const double p0[2], const double p1[2], double hw, double density)
{
    double dx = p1[0] - p0[0], dy = p1[1] - p0[1], L = hypot(dx, dy);
    const double size[3] = {L + 2 * hw, 2 * hw, 2 * hw}, c[3] = {(p0[0] + p1[0]) / 2, (p0[1] + p1[1]) / 2, 0};
    crom_scene_body b = crom_scene_body_make(CROM_SCENE_BOX, size, c, density);
    double cs = dx / L, sn = dy / L; /* shape x along the bar: a turn about z */
    const double Q[9] = {cs, -sn, 0, sn, cs, 0, 0, 0, 1};
    memcpy(b.rot, Q, sizeof Q);
    return b;
}

int crom_scenes_klann(const crom_scenes_params *p, crom_mesh *m)
{
    memset(m, 0, sizeof *m);
    int rc = check_params(p, 0);
    if (rc)
        return rc;
    double P[8][2];
    if ((rc = crom_scenes_klann_points(p->angle, p->length, NULL, P)))
        return rc;
    double hw = p->radius;
    crom_scene s = {0};
    /* bodies: crank A-C, rod C-F (with H), rocker B-H, rocker D-E, leg E-G (with F) */
    crom_scene_body b[5] = {bar(P[KA], P[KC], hw, p->density), bar(P[KC], P[KF], hw, p->density),
                            bar(P[KB], P[KH], hw, p->density), bar(P[KD], P[KE], hw, p->density),
                            bar(P[KE], P[KG], hw, p->density)};
    for (int i = 0; i < 5 && !rc; i++)
        rc = crom_scene_add_body(&s, &b[i]);
    /* revolute joints: (body, body or world, point) */
    static const int J[7][3] = {{0, -1, KA}, {2, -1, KB}, {3, -1, KD}, {0, 1, KC}, {1, 2, KH}, {1, 4, KF}, {4, 3, KE}};
    for (int j = 0; j < 7 && !rc; j++)
        for (int k = -1; k <= 1 && !rc; k += 2) {
            crom_scene_joint jt = {J[j][0], J[j][1], {P[J[j][2]][0], P[J[j][2]][1], k * hw}, 0, CROM_SCENE_POINT,
                                   {0, 0, 0}};
            rc = crom_scene_add_joint(&s, &jt);
        }
    if (rc) {
        crom_scene_free(&s);
        return rc;
    }
    double mass = 0, mb = 0;
    for (int i = 0; i < 5; i++) {
        double mi = p->density * crom_scene_body_volume(&s.bodies[i]);
        mass += mi;
        mb = fmax(mb, mi);
    }
    default_weights(p, mass, mb, p->length, &s);
    static const char *const names[] = {"crank", "rod", "rocker_b", "rocker_d", "leg"};
    return crom_rigidsys_scene_mesh(&s, names, m);
}

/* ------------------------------------------------------------ Stewart */

/* a capsule of radius r from p0 to p1 (its axis x turned onto p1 - p0) */
static crom_scene_body capsule_between(const double p0[3], const double p1[3], double r, double density)
{
    double v[3] = {p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]}, L = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    const double size[3] = {r, L, 0}, c[3] = {(p0[0] + p1[0]) / 2, (p0[1] + p1[1]) / 2, (p0[2] + p1[2]) / 2};
    crom_scene_body b = crom_scene_body_make(CROM_SCENE_CAPSULE, size, c, density);
    for (int i = 0; i < 3; i++)
        v[i] /= L;
    /* columns: v, a unit vector across it, and their cross product */
    double t[3] = {fabs(v[1]) < 0.9 ? 0 : 1, fabs(v[1]) < 0.9 ? 1 : 0, 0}, w[3];
    double tv = t[0] * v[0] + t[1] * v[1] + t[2] * v[2], tn;
    for (int i = 0; i < 3; i++)
        t[i] -= tv * v[i];
    tn = sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
    for (int i = 0; i < 3; i++)
        t[i] /= tn;
    w[0] = v[1] * t[2] - v[2] * t[1], w[1] = v[2] * t[0] - v[0] * t[2], w[2] = v[0] * t[1] - v[1] * t[0];
    for (int i = 0; i < 3; i++)
        b.rot[3 * i] = v[i], b.rot[3 * i + 1] = t[i], b.rot[3 * i + 2] = w[i];
    return b;
}

int crom_scenes_stewart(const crom_scenes_params *p, crom_mesh *m)
{
    memset(m, 0, sizeof *m);
    int rc = check_params(p, 0);
    if (rc)
        return rc;
    static const double ab[6] = {-20, 20, 100, 140, 220, 260}, ap[6] = {-50, 50, 70, 170, 190, 290};
    double L = p->length, rp = 0.6 * L, r = p->radius;
    crom_scene s = {0};
    const double bsize[3] = {2.4 * L, 0.1 * L, 2.4 * L}, bc[3] = {0, -0.05 * L, 0};
    const double psize[3] = {1.4 * rp, 0.05 * L, 1.4 * rp}, pc[3] = {0, L + 0.025 * L, 0};
    crom_scene_body base = crom_scene_body_make(CROM_SCENE_BOX, bsize, bc, p->density),
                    plat = crom_scene_body_make(CROM_SCENE_BOX, psize, pc, p->density);
    rc = crom_scene_add_body(&s, &base);
    if (!rc)
        rc = crom_scene_add_body(&s, &plat);
    for (int k = 0; k < 3 && !rc; k++) { /* the base pinned at three points */
        double a = 2 * M_PI * k / 3;
        crom_scene_joint j = {0, -1, {L * cos(a), -0.05 * L, L * sin(a)}, 0, CROM_SCENE_POINT, {0, 0, 0}};
        rc = crom_scene_add_joint(&s, &j);
    }
    for (int i = 0; i < 6 && !rc; i++) {
        double B[3] = {L * cos(ab[i] * M_PI / 180), 0, L * sin(ab[i] * M_PI / 180)};
        double P[3] = {rp * cos(ap[i] * M_PI / 180), L, rp * sin(ap[i] * M_PI / 180)}, d[3], len = 0;
        for (int k = 0; k < 3; k++)
            d[k] = P[k] - B[k], len += d[k] * d[k];
        len = sqrt(len);
        double M1[3], M2[3], Q[3]; /* the lower capsule ends at 0.65, the upper starts at 0.35 of the leg */
        for (int k = 0; k < 3; k++) {
            d[k] /= len;
            M1[k] = B[k] + 0.65 * len * d[k];
            M2[k] = B[k] + 0.35 * len * d[k];
            Q[k] = B[k] + 0.5 * len * d[k];
        }
        crom_scene_body lo = capsule_between(B, M1, r, p->density), up = capsule_between(M2, P, r, p->density);
        int bl = s.nb, bu = s.nb + 1;
        rc = crom_scene_add_body(&s, &lo);
        if (!rc)
            rc = crom_scene_add_body(&s, &up);
        crom_scene_joint jb = {bl, 0, {B[0], B[1], B[2]}, 0, CROM_SCENE_POINT, {0, 0, 0}},
                         jp = {bu, 1, {P[0], P[1], P[2]}, 0, CROM_SCENE_POINT, {0, 0, 0}},
                         s1 = {bl, bu, {M2[0], M2[1], M2[2]}, 0, CROM_SCENE_SLIDER, {d[0], d[1], d[2]}},
                         s2 = {bl, bu, {Q[0], Q[1], Q[2]}, 0, CROM_SCENE_SLIDER, {d[0], d[1], d[2]}};
        if (!rc)
            rc = crom_scene_add_joint(&s, &jb);
        if (!rc)
            rc = crom_scene_add_joint(&s, &jp);
        if (!rc)
            rc = crom_scene_add_joint(&s, &s1);
        if (!rc)
            rc = crom_scene_add_joint(&s, &s2);
    }
    if (rc) {
        crom_scene_free(&s);
        return rc;
    }
    double mass = 0, mb = 0;
    for (int i = 1; i < s.nb; i++) { /* the pinned base aside */
        double mi = p->density * crom_scene_body_volume(&s.bodies[i]);
        mass += mi;
        mb = fmax(mb, mi);
    }
    default_weights(p, mass, mb, L, &s);
    char names[14][24];
    const char *np[14];
    snprintf(names[0], sizeof names[0], "base");
    snprintf(names[1], sizeof names[1], "platform");
    for (int i = 0; i < 6; i++) {
        snprintf(names[2 + 2 * i], sizeof names[0], "leg%d_lower", i);
        snprintf(names[3 + 2 * i], sizeof names[0], "leg%d_upper", i);
    }
    for (int i = 0; i < 14; i++)
        np[i] = names[i];
    return crom_rigidsys_scene_mesh(&s, np, m);
}
