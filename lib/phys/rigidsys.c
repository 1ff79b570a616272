/* rigidsys.c — the system of a rigid-body scene (rigidsys.h). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "phys/rigidsys.h"
#include "phys/sym.h"

/* The second moment of a ring (scene.h) about its centre in its shape
 * coordinates: two half tori of tube radius r and radius R shifted to
 * x = ±h, and two straight tubes of length 2h along x at y = ±R. A torus
 * of mass m_t has S_xx = S_yy = m_t (R²/2 + 3r²/8), S_zz = m_t r²/4, and
 * ∫x dV over its x > 0 half is 2π r² (R² + r²/4). */
static void ring_moments(double r, double R, double L, double rho, double *m, double S[3])
{
    double h = L / 2, mt = rho * 2 * M_PI * M_PI * R * r * r, mc = rho * M_PI * r * r * L;
    *m = mt + 2 * mc;
    S[0] = mt * (R * R / 2 + 3 * r * r / 8) + 2 * h * rho * 2 * 2 * M_PI * r * r * (R * R + r * r / 4) + h * h * mt +
           2 * mc * L * L / 12;
    S[1] = mt * (R * R / 2 + 3 * r * r / 8) + 2 * mc * (R * R + r * r / 4);
    S[2] = mt * r * r / 4 + 2 * mc * r * r / 4;
}

void crom_rigidsys_body_inertia(const crom_scene_body *b, crom_rigid_inertia *in)
{
    const double *a = b->size, rho = b->density;
    double m, D[3]; /* mass and the diagonal second moment in shape coordinates */
    if (b->shape == CROM_SCENE_BOX) {
        m = rho * a[0] * a[1] * a[2];
        for (int k = 0; k < 3; k++)
            D[k] = m * a[k] * a[k] / 12;
    } else if (b->shape == CROM_SCENE_RING) {
        ring_moments(a[0], a[1], a[2], rho, &m, D);
    } else {
        double r = a[0], L = b->shape == CROM_SCENE_CAPSULE ? a[1] : 0;
        /* a cylinder of length L along x (m_c) and a sphere of radius r split
         * into two caps at ±L/2 (m_s): ∫x² dm over a cap about its base plane
         * is m_cap r²/5 and its centroid is 3r/8 from the base */
        double mc = rho * M_PI * r * r * L, ms = rho * 4.0 / 3.0 * M_PI * r * r * r;
        m = mc + ms;
        D[0] = mc * L * L / 12 + ms * (L * L / 4 + 3 * L * r / 8 + r * r / 5);
        D[1] = D[2] = mc * r * r / 4 + ms * r * r / 5;
    }
    memset(in, 0, sizeof *in);
    in->m = m;
    memcpy(in->c, b->centre, sizeof in->c);
    const double *Q = b->rot; /* S = Q diag(D) Qᵀ */
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            in->S[3 * i + j] = Q[3 * i] * D[0] * Q[3 * j] + Q[3 * i + 1] * D[1] * Q[3 * j + 1] +
                               Q[3 * i + 2] * D[2] * Q[3 * j + 2];
}

int crom_rigidsys_frames(const crom_scene *sc, double *X)
{
    for (int b = 0; b < sc->nb; b++) {
        crom_rigid_inertia in;
        crom_rigidsys_body_inertia(&sc->bodies[b], &in);
        if (crom_rigid_frame(&in, X + 12 * (size_t)b))
            return crom_err_ctx("body %d", b);
    }
    return 0;
}

int crom_rigidsys_scene_mesh(crom_scene *sc, const char *const *names, crom_mesh *m)
{
    memset(m, 0, sizeof *m);
    int rc = crom_scene_validate(sc);
    m->scene = crom_malloc(sizeof *m->scene);
    m->X = crom_malloc(sizeof(double) * 12 * (size_t)(sc->nb > 0 ? sc->nb : 1));
    m->tets = crom_malloc(sizeof(int) * 4);
    if (!rc && (!m->scene || !m->X || !m->tets))
        rc = CROM_EINTERNAL;
    if (rc) {
        crom_scene_free(sc);
        free(m->scene);
        m->scene = NULL;
        crom_mesh_free(m);
        return rc;
    }
    *m->scene = *sc;
    memset(sc, 0, sizeof *sc);
    m->nv = 4 * m->scene->nb;
    rc = crom_rigidsys_frames(m->scene, m->X);
    for (int b = 0; !rc && b < m->scene->nb; b++) {
        char name[80], src[80];
        int v[4] = {4 * b, 4 * b + 1, 4 * b + 2, 4 * b + 3};
        if (!names || !names[b])
            snprintf(name, sizeof name, "body%d", b);
        snprintf(src, sizeof src, "scene:body%d", b);
        rc = crom_mesh_add_region(m, names && names[b] ? names[b] : name, src, v, 4);
    }
    if (!rc)
        rc = crom_mesh_validate(m);
    if (rc)
        crom_mesh_free(m);
    return rc;
}

void crom_rigidsys_free(crom_rigidsys *s)
{
    if (!s)
        return;
    free(s->colptr);
    free(s->rowind);
    free(s->mass);
    free(s->Y);
    free(s->B);
    free(s->Bq);
    free(s->reach);
    free(s->el);
    memset(s, 0, sizeof *s);
}

int crom_rigidsys_elem_vertices(const crom_rigidsys *s, int e, int *v)
{
    const crom_rigidsys_elem *el = &s->el[e];
    for (int k = 0; k < 4; k++)
        v[k] = 4 * el->a + k;
    if (el->kind == CROM_RIGIDSYS_ORTHO || el->kind == CROM_RIGIDSYS_PIN)
        return 4;
    for (int k = 0; k < 4; k++)
        v[4 + k] = 4 * el->b + k;
    return 8;
}

int crom_rigidsys_elem_eval(const crom_rigidsys *s, int e, const double *xe, int project, double *E, double *g,
                            double *H)
{
    const crom_rigidsys_elem *el = &s->el[e];
    switch (el->kind) {
    case CROM_RIGIDSYS_ORTHO:
        if (crom_rigid_ortho(s->B + 9 * (size_t)el->a, el->w, xe, project, E, g, H))
            return CROM_EDATA;
        break;
    case CROM_RIGIDSYS_PIN:
        crom_rigid_pin(el->beta, el->w, xe, el->target, E, g, H);
        break;
    case CROM_RIGIDSYS_JOINT:
        crom_rigid_joint(el->beta, el->gamma, el->w, xe, xe + 12, E, g, H);
        break;
    case CROM_RIGIDSYS_SLIDER:
        if (crom_rigid_slider(el->beta, el->gamma, el->c, el->w, xe, xe + 12, project, E, g, H))
            return CROM_EDATA;
        break;
    default: {
        const crom_scene_body *sb = &s->body[el->b];
        /* far from b (by twice its reach, which its frame's give never
         * closes): no contact, without computing b's signed distance */
        double d2 = 0;
        for (int i = 0; i < 3; i++) {
            double d = -0.25 * (xe[12 + i] + xe[15 + i] + xe[18 + i] + xe[21 + i]);
            for (int k = 0; k < 4; k++)
                d += el->beta[k] * xe[3 * k + i];
            d2 += d * d;
        }
        if (d2 > 4 * s->reach[el->b] * s->reach[el->b]) {
            if (E)
                *E = 0;
            if (g)
                memset(g, 0, 24 * sizeof(double));
            if (H)
                memset(H, 0, 576 * sizeof(double));
            return CROM_OK;
        }
        if (crom_rigid_contact(el->beta, s->Bq + 9 * (size_t)el->b, sb->shape, sb->size, el->w, xe, xe + 12, project,
                               E, g, H))
            return CROM_EDATA;
    }
    }
    int m = el->kind == CROM_RIGIDSYS_ORTHO || el->kind == CROM_RIGIDSYS_PIN ? 12 : 24;
    if (E && !isfinite(*E))
        return CROM_EDATA;
    for (int i = 0; g && i < m; i++)
        if (!isfinite(g[i]))
            return CROM_EDATA;
    return CROM_OK;
}

static int elem_verts(const void *ctx, int e, int *v)
{
    return crom_rigidsys_elem_vertices(ctx, e, v);
}

/* The upper-CSC pattern: full 3×3 blocks for every pair of vertices that
 * share an element (every body's four vertices share its orthogonality
 * element). */
static int build_pattern(crom_rigidsys *s)
{
    return crom_sym_block_pattern(s->nv, s->nel, elem_verts, s, &s->colptr, &s->rowind, &s->nnz);
}

static int add_contacts(crom_rigidsys *s, const crom_mesh *m);

int crom_rigidsys_init(crom_rigidsys *s, const crom_mesh *m)
{
    memset(s, 0, sizeof *s);
    const crom_scene *sc = m->scene;
    if (!sc)
        return crom_err(CROM_EINTERNAL, "not a rigid-body scene");
    s->nb = sc->nb;
    s->nj = sc->nj;
    s->body = sc->bodies;
    s->nv = m->nv;
    s->n = 3 * m->nv;
    s->nel = sc->nb + sc->nj;
    s->mass = crom_malloc(sizeof(double) * (size_t)s->nv);
    s->Y = crom_malloc(sizeof(double) * 12 * (size_t)s->nb);
    s->B = crom_malloc(sizeof(double) * 9 * (size_t)s->nb);
    s->Bq = crom_malloc(sizeof(double) * 9 * (size_t)s->nb);
    s->reach = crom_malloc(sizeof(double) * (size_t)s->nb);
    s->el = crom_calloc((size_t)s->nel, sizeof *s->el);
    if (!s->mass || !s->Y || !s->B || !s->Bq || !s->reach || !s->el) {
        crom_rigidsys_free(s);
        return CROM_EINTERNAL;
    }
    int rc = 0;
    double L = crom_mesh_points_diagonal(m->X, m->nv);
    for (int b = 0; !rc && b < s->nb; b++) {
        crom_rigid_inertia in;
        crom_rigidsys_body_inertia(&sc->bodies[b], &in);
        if (crom_rigid_frame(&in, s->Y + 12 * (size_t)b)) { /* crom_rigidsys_frames' frame */
            rc = crom_err_ctx("body %d", b);
            break;
        }
        for (int i = 0; i < 12; i++)
            if (!(fabs(m->X[12 * (size_t)b + i] - s->Y[12 * (size_t)b + i]) <= 1e-9 * L))
                rc = crom_err(CROM_EDATA, "body %d's frame vertices are not those of its shape and density", b);
        if (!rc && crom_rigid_frame_inverse(s->Y + 12 * (size_t)b, s->B + 9 * (size_t)b))
            rc = crom_err(CROM_EDATA, "body %d has a degenerate frame", b);
        const double *a = sc->bodies[b].size;
        switch (sc->bodies[b].shape) {
        case CROM_SCENE_BOX: s->reach[b] = 0.5 * sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]); break;
        case CROM_SCENE_SPHERE: s->reach[b] = a[0]; break;
        case CROM_SCENE_CAPSULE: s->reach[b] = a[0] + a[1] / 2; break;
        default: s->reach[b] = a[0] + a[1] + a[2] / 2;
        }
        const double *B = s->B + 9 * (size_t)b, *Q = sc->bodies[b].rot;
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++)
                s->Bq[9 * (size_t)b + 3 * i + j] = B[3 * i] * Q[j] + B[3 * i + 1] * Q[3 + j] + B[3 * i + 2] * Q[6 + j];
        for (int k = 0; k < 4; k++)
            s->mass[4 * b + k] = in.m / 4;
        s->total_mass += in.m;
        s->volume += crom_scene_body_volume(&sc->bodies[b]);
        crom_rigidsys_elem *el = &s->el[b];
        el->kind = CROM_RIGIDSYS_ORTHO;
        el->a = el->b = b;
        el->w = sc->ortho_weight;
    }
    for (int j = 0; !rc && j < sc->nj; j++) {
        const crom_scene_joint *J = &sc->joints[j];
        crom_rigidsys_elem *el = &s->el[sc->nb + j];
        el->kind = J->b < 0                        ? CROM_RIGIDSYS_PIN
                   : J->kind == CROM_SCENE_SLIDER ? CROM_RIGIDSYS_SLIDER
                                                  : CROM_RIGIDSYS_JOINT;
        el->a = J->a;
        el->b = J->b;
        el->w = J->weight;
        crom_rigid_coords(s->Y + 12 * (size_t)J->a, s->B + 9 * (size_t)J->a, J->point, el->beta);
        if (J->b >= 0)
            crom_rigid_coords(s->Y + 12 * (size_t)J->b, s->B + 9 * (size_t)J->b, J->point, el->gamma);
        if (el->kind == CROM_RIGIDSYS_SLIDER)
            crom_rigid_axis_weights(s->B + 9 * (size_t)J->a, J->axis, el->c);
        memcpy(el->target, J->point, sizeof el->target);
    }
    if (!rc)
        rc = add_contacts(s, m);
    if (!rc)
        rc = build_pattern(s);
    if (rc)
        crom_rigidsys_free(s);
    return rc;
}

int crom_rigidsys_assemble(const crom_rigidsys *s, const double *x, const crom_fem_opts *o, double *E, double *g,
                           double *H)
{
    double Et = 0, xe[24], ge[24], He[576];
    int project = o ? o->project : 0;
    if (g)
        memset(g, 0, sizeof(double) * (size_t)s->n);
    if (H)
        memset(H, 0, sizeof(double) * (size_t)s->nnz);
    for (int e = 0; e < s->nel; e++) {
        int vs[CROM_RIGIDSYS_MAXV], k = crom_rigidsys_elem_vertices(s, e, vs), m = 3 * k;
        for (int a = 0; a < k; a++)
            memcpy(xe + 3 * a, x + 3 * (size_t)vs[a], 3 * sizeof(double));
        double Ee;
        if (crom_rigidsys_elem_eval(s, e, xe, project, &Ee, g ? ge : NULL, H ? He : NULL))
            return crom_err(CROM_EDATA, "rigid element %d (body %d): non-finite energy", e, s->el[e].a);
        Et += Ee;
        if (Ee == 0 && s->el[e].kind == CROM_RIGIDSYS_CONTACT)
            continue; /* a contact not touching: no force, no stiffness */
        for (int i = 0; g && i < m; i++)
            g[3 * vs[i / 3] + i % 3] += ge[i];
        for (int p = 0; H && p < m; p++)
            for (int q = p; q < m; q++) {
                int gp = 3 * vs[p / 3] + p % 3, gq = 3 * vs[q / 3] + q % 3;
                int lo = gp <= gq ? gp : gq, hi = gp <= gq ? gq : gp;
                H[crom_sym_entry(s->colptr, s->rowind, lo, hi)] += He[m * p + q];
            }
    }
    crom_sym_dirichlet_mass(s->n, s->colptr, s->rowind, o ? o->fixed : NULL, s->mass, o ? o->mass_scale : 0, g, H);
    if (E)
        *E = Et;
    return CROM_OK;
}

void crom_rigidsys_pose(const crom_rigidsys *s, int b, const double *x, double R[9], double t[3])
{
    crom_rigid_affine(s->Y + 12 * (size_t)b, s->B + 9 * (size_t)b, x + 12 * (size_t)b, R, t);
}

void crom_rigidsys_joint_gaps(const crom_rigidsys *s, const double *x, double *gap)
{
    for (int e = s->nb; e < s->nb + s->nj; e++) {
        const crom_rigidsys_elem *el = &s->el[e];
        const double *ya = x + 12 * (size_t)el->a, *yb = el->kind == CROM_RIGIDSYS_PIN ? NULL : x + 12 * (size_t)el->b;
        double d[3], u[3], du = 0, d2 = 0;
        for (int i = 0; i < 3; i++) {
            d[i] = yb ? 0 : -el->target[i];
            u[i] = 0;
            for (int k = 0; k < 4; k++) {
                d[i] += el->beta[k] * ya[3 * k + i] - (yb ? el->gamma[k] * yb[3 * k + i] : 0);
                u[i] += el->c[k] * ya[3 * k + i];
            }
            du += d[i] * u[i];
        }
        for (int i = 0; i < 3; i++) { /* a slider: the part across its axis (c = 0 otherwise) */
            double v = el->kind == CROM_RIGIDSYS_SLIDER ? d[i] - du * u[i] : d[i];
            d2 += v * v;
        }
        gap[e - s->nb] = sqrt(d2);
    }
}

/* ------------------------------------------------------------- display */

typedef struct {
    double *X;
    int *T, *bodyv, nv, nt, capv, capt;
} dbuf;

/* a display vertex of body b (scene body sb) at shape coordinates p */
static int dvert(dbuf *d, const double p[3], const crom_scene_body *sb, int b)
{
    if (d->nv == d->capv) {
        int c = d->capv ? 2 * d->capv : 256;
        double *X = crom_realloc(d->X, sizeof(double) * 3 * (size_t)c);
        if (!X)
            return -1;
        d->X = X;
        int *bv = crom_realloc(d->bodyv, sizeof(int) * (size_t)c);
        if (!bv)
            return -1;
        d->bodyv = bv;
        d->capv = c;
    }
    const double *Q = sb->rot;
    for (int i = 0; i < 3; i++)
        d->X[3 * (size_t)d->nv + i] = sb->centre[i] + Q[3 * i] * p[0] + Q[3 * i + 1] * p[1] + Q[3 * i + 2] * p[2];
    d->bodyv[d->nv] = b;
    return d->nv++;
}

static int dtri(dbuf *d, int a, int b, int c)
{
    if (d->nt == d->capt) {
        int cap = d->capt ? 2 * d->capt : 256;
        int *T = crom_realloc(d->T, sizeof(int) * 3 * (size_t)cap);
        if (!T)
            return -1;
        d->T = T;
        d->capt = cap;
    }
    d->T[3 * d->nt] = a, d->T[3 * d->nt + 1] = b, d->T[3 * d->nt + 2] = c;
    d->nt++;
    return 0;
}

/* a box's 8 corners and 12 outward triangles */
static int display_box(dbuf *d, const crom_scene_body *sb, int b)
{
    int v0 = d->nv;
    for (int k = 0; k < 8; k++) {
        double p[3];
        for (int i = 0; i < 3; i++)
            p[i] = ((k >> i) & 1 ? 0.5 : -0.5) * sb->size[i];
        if (dvert(d, p, sb, b) < 0)
            return CROM_EINTERNAL;
    }
    /* faces as corner quads (bit i of a corner index: +x, +y, +z), each
     * listed counter-clockwise seen from outside */
    static const int q[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
    for (int f = 0; f < 6; f++)
        if (dtri(d, v0 + q[f][0], v0 + q[f][1], v0 + q[f][2]) || dtri(d, v0 + q[f][0], v0 + q[f][2], v0 + q[f][3]))
            return CROM_EINTERNAL;
    return 0;
}

/* a sphere or capsule (axis x): poles on ±x and latitude rings between
 * them, 2 res points each: a sphere's res − 1 rings at polar angles
 * π k/res from −x; a capsule's (res rounded up to even) the −x cap's rings
 * down to its equator, shifted by −h, then the +x cap's from its equator,
 * shifted by +h, the cylinder joining the two equators */
static int display_round(dbuf *d, const crom_scene_body *sb, int b, int res)
{
    double r = sb->size[0], h = sb->shape == CROM_SCENE_CAPSULE ? sb->size[1] / 2 : 0;
    if (h > 0 && res % 2)
        res++;
    int nlon = 2 * res, nring = h > 0 ? res : res - 1, prev = -1;
    double p[3] = {-h - r, 0, 0};
    int south = dvert(d, p, sb, b);
    if (south < 0)
        return CROM_EINTERNAL;
    for (int k = 0; k < nring; k++) {
        double phi, shift = 0;
        if (h > 0 && k < res / 2)
            phi = M_PI * (k + 1) / res, shift = -h;
        else if (h > 0)
            phi = M_PI * (k - res / 2) / res + M_PI / 2, shift = h;
        else
            phi = M_PI * (k + 1) / res;
        int ring = d->nv;
        for (int l = 0; l < nlon; l++) {
            double th = 2 * M_PI * l / nlon;
            double q3[3] = {-r * cos(phi) + shift, r * sin(phi) * cos(th), r * sin(phi) * sin(th)};
            if (dvert(d, q3, sb, b) < 0)
                return CROM_EINTERNAL;
        }
        for (int l = 0; l < nlon; l++) {
            int a = ring + l, c = ring + (l + 1) % nlon;
            int rc = k == 0 ? dtri(d, south, c, a)
                            : (dtri(d, prev + l, prev + (l + 1) % nlon, c) || dtri(d, prev + l, c, a));
            if (rc)
                return CROM_EINTERNAL;
        }
        prev = ring;
    }
    p[0] = h + r;
    int north = dvert(d, p, sb, b);
    if (north < 0)
        return CROM_EINTERNAL;
    for (int l = 0; l < nlon; l++)
        if (dtri(d, prev + l, prev + (l + 1) % nlon, north))
            return CROM_EINTERNAL;
    return 0;
}

/* a ring: 2 res + 2 stations along its stadium centreline (res + 1 round
 * each half circle, the straight runs joining them; a torus has no
 * straight runs and 2 res stations), each a circle of 2 res points around
 * the tube; quads between neighbouring circles */
static int display_ring(dbuf *d, const crom_scene_body *sb, int b, int res)
{
    double r = sb->size[0], R = sb->size[1], h = sb->size[2] / 2;
    int torus = h == 0, ns = torus ? 2 * res : 2 * res + 2, nt = 2 * res, v0 = d->nv;
    for (int k = 0; k < ns; k++) {
        double al, cx;
        if (torus) {
            al = 2 * M_PI * k / ns, cx = 0;
        } else { /* stations 0..res round the +x end, res+1..2res+1 round the −x end */
            int half = k <= res ? 0 : 1, j = half ? k - res - 1 : k;
            al = -M_PI / 2 + M_PI * j / res + half * M_PI, cx = half ? -h : h;
        }
        double n[3] = {cos(al), sin(al), 0}; /* outward in the plane, e_z the other tube axis */
        for (int l = 0; l < nt; l++) {
            double ps = 2 * M_PI * l / nt;
            double p[3] = {cx + R * n[0] + r * cos(ps) * n[0], R * n[1] + r * cos(ps) * n[1], r * sin(ps)};
            if (dvert(d, p, sb, b) < 0)
                return CROM_EINTERNAL;
        }
    }
    for (int k = 0; k < ns; k++) {
        int a0 = v0 + k * nt, a1 = v0 + ((k + 1) % ns) * nt;
        for (int l = 0; l < nt; l++) {
            int l1 = (l + 1) % nt;
            if (dtri(d, a0 + l, a1 + l, a1 + l1) || dtri(d, a0 + l, a1 + l1, a0 + l1))
                return CROM_EINTERNAL;
        }
    }
    return 0;
}

int crom_rigidsys_display(const crom_mesh *scene, int res, crom_mesh *disp, double **beta, int **body)
{
    memset(disp, 0, sizeof *disp);
    *beta = NULL;
    *body = NULL;
    const crom_scene *sc = scene->scene;
    if (!sc || res < 2)
        return crom_err(CROM_EINTERNAL, "crom_rigidsys_display: not a scene, or res < 2");
    dbuf d = {0};
    int rc = 0;
    for (int b = 0; b < sc->nb && !rc; b++)
        rc = sc->bodies[b].shape == CROM_SCENE_BOX    ? display_box(&d, &sc->bodies[b], b)
             : sc->bodies[b].shape == CROM_SCENE_RING ? display_ring(&d, &sc->bodies[b], b, res)
                                                      : display_round(&d, &sc->bodies[b], b, res);
    double *bt = rc ? NULL : crom_malloc(sizeof(double) * 4 * (size_t)d.nv);
    if (!rc && !bt)
        rc = CROM_EINTERNAL;
    for (int i = 0; !rc && i < d.nv; i++) {
        const double *Y = scene->X + 12 * (size_t)d.bodyv[i];
        double B[9];
        if (crom_rigid_frame_inverse(Y, B))
            rc = crom_err(CROM_EDATA, "body %d has a degenerate frame", d.bodyv[i]);
        else
            crom_rigid_coords(Y, B, d.X + 3 * (size_t)i, bt + 4 * (size_t)i);
    }
    if (!rc) {
        disp->nv = d.nv;
        disp->X = d.X;
        disp->ntri = d.nt;
        disp->tris = d.T;
        disp->tets = crom_malloc(sizeof(int) * 4);
        disp->thickness = 1e-3 * crom_mesh_points_diagonal(d.X, d.nv);
        d.X = NULL, d.T = NULL;
        if (!disp->tets)
            rc = CROM_EINTERNAL;
    }
    /* the scene's regions, as the display vertices of their bodies */
    int *idx = rc ? NULL : crom_malloc(sizeof(int) * (size_t)(disp->nv ? disp->nv : 1));
    if (!rc && !idx)
        rc = CROM_EINTERNAL;
    for (int r = 0; !rc && r < scene->nregions; r++) {
        const crom_mesh_region *g = &scene->regions[r];
        int n = 0;
        for (int i = 0; i < disp->nv; i++) {
            int in = 0;
            for (int j = 0; j < g->n && !in; j++)
                in = g->idx[j] / 4 == d.bodyv[i];
            if (in)
                idx[n++] = i;
        }
        rc = crom_mesh_add_region(disp, g->name, g->source, idx, n);
    }
    free(idx);
    free(d.X);
    free(d.T);
    if (rc) {
        free(bt);
        free(d.bodyv);
        crom_mesh_free(disp);
        return rc;
    }
    *beta = bt;
    *body = d.bodyv;
    return 0;
}

void crom_rigidsys_display_map(int nd, const double *beta, const int *body, const double *u, double *ud)
{
    for (int i = 0; i < nd; i++) {
        const double *bt = beta + 4 * (size_t)i, *uf = u + 12 * (size_t)body[i];
        for (int c = 0; c < 3; c++)
            ud[3 * i + c] = bt[0] * uf[c] + bt[1] * uf[3 + c] + bt[2] * uf[6 + c] + bt[3] * uf[9 + c];
    }
}

/* The contact elements of every collision pair: body a's display vertices
 * (at CROM_RIGIDSYS_CONTACT_RINGS) against body b's shape. */
static int add_contacts(crom_rigidsys *s, const crom_mesh *m)
{
    const crom_scene *sc = m->scene;
    if (!sc->np)
        return 0;
    crom_mesh d;
    double *beta;
    int *body, rc = crom_rigidsys_display(m, CROM_RIGIDSYS_CONTACT_RINGS, &d, &beta, &body);
    if (rc)
        return rc;
    int *count = crom_calloc((size_t)sc->nb, sizeof(int));
    if (!count) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    for (int i = 0; i < d.nv; i++)
        count[body[i]]++;
    size_t add = 0;
    for (int p = 0; p < sc->np; p++)
        add += (size_t)count[sc->pairs[p].a];
    if (add + (size_t)s->nel > 100000000) {
        rc = crom_err(CROM_EUSAGE, "the scene's collision pairs make %zu contact elements: too many", add);
        goto out;
    }
    crom_rigidsys_elem *el = crom_realloc(s->el, sizeof *el * ((size_t)s->nel + add));
    if (!el) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    s->el = el;
    for (int p = 0; p < sc->np; p++) {
        const crom_scene_pair *P = &sc->pairs[p];
        for (int i = 0; i < d.nv; i++) {
            if (body[i] != P->a)
                continue;
            crom_rigidsys_elem *e = &s->el[s->nel++];
            memset(e, 0, sizeof *e);
            e->kind = CROM_RIGIDSYS_CONTACT;
            e->a = P->a;
            e->b = P->b;
            e->w = P->weight;
            memcpy(e->beta, beta + 4 * (size_t)i, sizeof e->beta);
            memcpy(e->target, d.X + 3 * (size_t)i, sizeof e->target); /* its rest position, for reports */
            s->ncontact++;
        }
    }
out:
    free(count);
    free(beta);
    free(body);
    crom_mesh_free(&d);
    return rc;
}
