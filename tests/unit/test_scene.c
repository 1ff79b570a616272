/* test_scene.c — rigid-body scenes as a physical system (lib/mesh/scene.h,
 * lib/phys/rigidsys.h, lib/phys/scenes.h; issue 17): the assembled energy's
 * gradient and sparse Hessian against finite differences on a perturbed
 * chain (which checks the pattern and the scatter of 4- and 8-vertex
 * elements), the element interface summing to the assembly, capsule and
 * sphere inertia against numerical integration, validation of bad scenes,
 * and crom_sim on scenes: free fall exactly as implicit Euler moves a
 * point, and a pendulum's small-angle period within 1% of 2π√(L/g). */
#include <lapacke.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fixtures.h"
#include "base/err.h"
#include "base/rng.h"
#include "phys/scenes.h"
#include "phys/sim.h"
#include "phys/system.h"
#include "rom/map.h"
#include "rom/model.h"
#include "rom/nlsim.h"
#include "datafree/datafree.h"

static crom_scenes_params params(void)
{
    crom_scenes_params p = {.links = 3, .length = 0.1, .radius = 0.01, .density = 1000, .gravity = 9.81};
    return p;
}

typedef struct {
    crom_system *s;
} sctx;

static double s_energy(const double *x, void *ctx)
{
    double E = 0;
    crom_system_assemble(((sctx *)ctx)->s, x, NULL, &E, NULL, NULL);
    return E;
}

static void s_grad(const double *x, void *ctx, double *g)
{
    crom_system_assemble(((sctx *)ctx)->s, x, NULL, NULL, g, NULL);
}

static void test_chain_derivatives(void)
{
    crom_scenes_params p = params();
    crom_mesh m;
    CHECK(crom_scenes_chain(&p, &m) == 0);
    CHECK(m.nv == 12 && m.scene->nb == 3 && m.scene->nj == 3);
    crom_system s;
    CHECK(crom_system_init(&s, &m, 1e6, 0.3, 1000) == 0);
    CHECK(s.rigid && s.nenergy == 6 && s.n == 36);
    CHECK_NEAR(s.total_mass, 3 * 1000 * M_PI * 1e-4 * (0.1 + 4.0 / 3 * 0.01), 1e-12);
    /* at rest every penalty is zero */
    double E0;
    CHECK(crom_system_energy(&s, m.X, &E0) == 0);
    CHECK_LT(fabs(E0), 1e-20);
    crom_rng rng;
    crom_rng_seed(&rng, 5);
    int n = s.n;
    double *x = malloc(sizeof(double) * n), *g = malloc(sizeof(double) * n), *gf = malloc(sizeof(double) * n);
    double *H = malloc(sizeof(double) * s.nnz), *Hd = calloc((size_t)n * n, sizeof(double)),
           *Hf = malloc(sizeof(double) * n * n);
    for (int i = 0; i < n; i++)
        x[i] = m.X[i] + 0.01 * crom_rng_normal(&rng);
    sctx c = {&s};
    double E;
    crom_fem_opts fo = {0, 0, NULL, 1};
    CHECK(crom_system_assemble(&s, x, &fo, &E, g, H) == 0);
    check_fd_gradient(s_energy, &c, x, n, 1e-6, gf);
    check_fd_jacobian(s_grad, &c, x, n, n, 1e-6, Hf);
    for (int col = 0; col < n; col++) /* the full matrix of the upper CSC */
        for (int k = s.colptr[col]; k < s.colptr[col + 1]; k++) {
            int r = s.rowind[k];
            CHECK(r <= col);
            Hd[r * n + col] = Hd[col * n + r] = H[k];
        }
    double eg = check_relerr(g, gf, n, 1e-8), eh = check_relerr(Hd, Hf, n * n, 1e-6);
    fprintf(stderr, "chain of 3: gradient %.1e, Hessian %.1e against finite differences\n", eg, eh);
    CHECK_LT(eg, 1e-7);
    CHECK_LT(eh, 1e-6);
    /* the element interface sums to the assembly */
    double Es = 0;
    for (int e = 0; e < s.nenergy; e++) {
        int v[CROM_SYSTEM_MAXV], k = crom_system_elem_vertices(&s, e, v);
        double xe[3 * CROM_SYSTEM_MAXV], Ee;
        CHECK(k == (e < 3 ? 4 : e == 3 ? 4 : 8)); /* bodies, the pin, then two joints */
        for (int a = 0; a < k; a++)
            memcpy(xe + 3 * a, x + 3 * (size_t)v[a], 3 * sizeof(double));
        CHECK(crom_system_elem_eval(&s, e, xe, 0, &Ee, NULL, NULL) == 0);
        Es += Ee;
    }
    CHECK_NEAR(Es, E, 1e-12 * fabs(E));
    free(x), free(g), free(gf), free(H), free(Hd), free(Hf);
    crom_system_free(&s);
    crom_mesh_free(&m);
}

/* ∫ρ x_i² over a shape by the midpoint rule on a fine grid */
static void grid_moments(const crom_scene_body *b, double *m, double S[3])
{
    int N = 200;
    double ext[3];
    double r = b->size[0], L = b->shape == CROM_SCENE_CAPSULE ? b->size[1] : 0;
    ext[0] = L / 2 + r, ext[1] = ext[2] = r;
    *m = S[0] = S[1] = S[2] = 0;
    double h[3] = {2 * ext[0] / N, 2 * ext[1] / N, 2 * ext[2] / N}, dV = h[0] * h[1] * h[2];
    for (int i = 0; i < N; i++)
        for (int j = 0; j < N; j++)
            for (int k = 0; k < N; k++) {
                double p[3] = {-ext[0] + (i + 0.5) * h[0], -ext[1] + (j + 0.5) * h[1], -ext[2] + (k + 0.5) * h[2]};
                double ax = fabs(p[0]) > L / 2 ? fabs(p[0]) - L / 2 : 0;
                if (ax * ax + p[1] * p[1] + p[2] * p[2] > r * r)
                    continue;
                *m += b->density * dV;
                for (int d = 0; d < 3; d++)
                    S[d] += b->density * dV * p[d] * p[d];
            }
}

/* ∫ρ over a ring (tube radius r around a stadium of radius R and straight
 * length 2h in the xy-plane) by the midpoint rule */
static void grid_ring(const crom_scene_body *b, double *m, double S[3])
{
    int N = 240;
    double r = b->size[0], R = b->size[1], h = b->size[2] / 2, ext[3] = {h + R + r, R + r, r};
    *m = S[0] = S[1] = S[2] = 0;
    double hh[3] = {2 * ext[0] / N, 2 * ext[1] / N, 2 * ext[2] / N}, dV = hh[0] * hh[1] * hh[2];
    for (int i = 0; i < N; i++)
        for (int j = 0; j < N; j++)
            for (int k = 0; k < N; k++) {
                double p[3] = {-ext[0] + (i + 0.5) * hh[0], -ext[1] + (j + 0.5) * hh[1], -ext[2] + (k + 0.5) * hh[2]};
                double phi;
                crom_rigid_sdf(CROM_SCENE_RING, b->size, p, &phi, NULL, NULL);
                if (phi > 0)
                    continue;
                *m += b->density * dV;
                for (int d = 0; d < 3; d++)
                    S[d] += b->density * dV * p[d] * p[d];
            }
    (void)h;
}

static void test_inertia(void)
{
    const double s1[3] = {0.1, 0.5, 0}, c1[3] = {1, 2, 3}, s2[3] = {0.2, 0, 0}, c2[3] = {0, 0, 0};
    crom_scene_body caps = crom_scene_body_make(CROM_SCENE_CAPSULE, s1, c1, 700),
                    sph = crom_scene_body_make(CROM_SCENE_SPHERE, s2, c2, 1200);
    const crom_scene_body *bs[2] = {&caps, &sph};
    for (int i = 0; i < 2; i++) {
        crom_rigid_inertia in;
        crom_rigidsys_body_inertia(bs[i], &in);
        double m, S[3];
        grid_moments(bs[i], &m, S);
        fprintf(stderr, "%s: mass %.6g (grid %.6g), S %.4g %.4g %.4g (grid %.4g %.4g %.4g)\n",
                crom_scene_shape_name(bs[i]->shape), in.m, m, in.S[0], in.S[4], in.S[8], S[0], S[1], S[2]);
        CHECK_NEAR(in.m, bs[i]->density * crom_scene_body_volume(bs[i]), 1e-12 * in.m);
        CHECK_NEAR(in.m, m, 2e-3 * in.m); /* the grid's error: O(h) at the curved surface */
        for (int d = 0; d < 3; d++)
            CHECK_NEAR(in.S[4 * d], S[d], 3e-3 * in.S[4 * d]);
        CHECK(in.S[1] == 0 && in.S[2] == 0 && in.S[5] == 0);
    }
    /* a ring, and the same ring turned: S = Q S0 Qᵀ */
    const double s3[3] = {0.01, 0.04, 0.06}, c3[3] = {0, 0, 0};
    crom_scene_body ring = crom_scene_body_make(CROM_SCENE_RING, s3, c3, 1000);
    crom_rigid_inertia in;
    crom_rigidsys_body_inertia(&ring, &in);
    double m, S[3];
    grid_ring(&ring, &m, S);
    fprintf(stderr, "ring: mass %.6g (grid %.6g), S %.4g %.4g %.4g (grid %.4g %.4g %.4g)\n", in.m, m, in.S[0], in.S[4],
            in.S[8], S[0], S[1], S[2]);
    CHECK_NEAR(in.m, 1000 * crom_scene_body_volume(&ring), 1e-12 * in.m);
    CHECK_NEAR(in.m, m, 5e-3 * in.m);
    for (int d = 0; d < 3; d++)
        CHECK_NEAR(in.S[4 * d], S[d], 5e-3 * in.S[4 * d]);
    crom_rng rng;
    crom_rng_seed(&rng, 9);
    fx_random_rotation(&rng, ring.rot);
    crom_rigid_inertia it;
    crom_rigidsys_body_inertia(&ring, &it);
    double worst = 0;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double v = 0;
            for (int k = 0; k < 3; k++)
                v += ring.rot[3 * i + k] * in.S[4 * k] * ring.rot[3 * j + k];
            worst = fmax(worst, fabs(v - it.S[3 * i + j]));
        }
    CHECK_LT(worst, 1e-15 * in.S[0] * 10);
}

/* the signed distances' gradients and Hessians against finite differences,
 * at points inside each shape; and contacts, in both frames */
typedef struct {
    int shape;
    const double *size;
    const double *beta, *Bq;
    double w;
} cctx;

static double sdf_f(const double *q, void *ctx)
{
    cctx *c = ctx;
    double phi;
    crom_rigid_sdf(c->shape, c->size, q, &phi, NULL, NULL);
    return phi;
}

static void sdf_g(const double *q, void *ctx, double *g)
{
    cctx *c = ctx;
    double phi;
    crom_rigid_sdf(c->shape, c->size, q, &phi, g, NULL);
}

static double con_f(const double *y, void *ctx)
{
    cctx *c = ctx;
    double E;
    crom_rigid_contact(c->beta, c->Bq, c->shape, c->size, c->w, y, y + 12, 0, &E, NULL, NULL);
    return E;
}

static void con_g(const double *y, void *ctx, double *g)
{
    cctx *c = ctx;
    crom_rigid_contact(c->beta, c->Bq, c->shape, c->size, c->w, y, y + 12, 0, NULL, g, NULL);
}

static void test_contacts(void)
{
    static const double sizes[4][3] = {{0.3, 0.2, 0.1}, {0.1, 0, 0}, {0.05, 0.3, 0}, {0.02, 0.06, 0.08}};
    static const double inside[4][3] = {{0.1, -0.05, 0.02}, {0.03, 0.05, -0.02}, {0.08, 0.02, -0.03},
                                        {0.02, 0.055, 0.012}};
    const char *names[4] = {"box", "sphere", "capsule", "ring"};
    crom_rng rng;
    crom_rng_seed(&rng, 21);
    for (int sh = 0; sh < 4; sh++) {
        cctx c = {sh, sizes[sh], NULL, NULL, 0};
        double q[3], g[3], gf[3], H[9], Hf[9], phi;
        memcpy(q, inside[sh], sizeof q);
        crom_rigid_sdf(sh, sizes[sh], q, &phi, g, H);
        CHECK(phi < 0);
        check_fd_gradient(sdf_f, &c, q, 3, 1e-7, gf);
        check_fd_jacobian(sdf_g, &c, q, 3, 3, 1e-7, Hf);
        double eg = check_relerr(g, gf, 3, 1e-8), eh = check_relerr(H, Hf, 9, 1);
        /* a body's frame: a box of the shape's rough extent, turned and
         * moved, the point a little inside the shape */
        const double ext[3] = {0.3, 0.25, 0.2}, c0[3] = {0.1, -0.2, 0.3};
        crom_rigid_inertia in;
        crom_rigid_inertia_box(ext, c0, 1000, &in);
        double Yb[12], B[9], Q[9], Bq[9], Ya[12], Ba[9];
        CHECK(crom_rigid_frame(&in, Yb) == 0 && crom_rigid_frame_inverse(Yb, B) == 0);
        fx_random_rotation(&rng, Q);
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++)
                Bq[3 * i + j] = B[3 * i] * Q[j] + B[3 * i + 1] * Q[3 + j] + B[3 * i + 2] * Q[6 + j];
        /* the rest point X = c0 + Q q, in frame a (another box near it) */
        double X[3], beta[4];
        for (int i = 0; i < 3; i++)
            X[i] = c0[i] + Q[3 * i] * q[0] + Q[3 * i + 1] * q[1] + Q[3 * i + 2] * q[2];
        const double ca[3] = {0.2, -0.1, 0.25};
        crom_rigid_inertia_box(ext, ca, 800, &in);
        CHECK(crom_rigid_frame(&in, Ya) == 0 && crom_rigid_frame_inverse(Ya, Ba) == 0);
        crom_rigid_coords(Ya, Ba, X, beta);
        /* at rest the contact's φ is the shape's: E = ½ w φ² */
        double y[24], E;
        memcpy(y, Ya, sizeof Ya);
        memcpy(y + 12, Yb, sizeof Yb);
        CHECK(crom_rigid_contact(beta, Bq, sh, sizes[sh], 3.0, y, y + 12, 0, &E, NULL, NULL) == 0);
        CHECK_NEAR(E, 1.5 * phi * phi, 1e-12 * E);
        for (int i = 0; i < 24; i++)
            y[i] += 1e-3 * crom_rng_normal(&rng);
        cctx cc = {sh, sizes[sh], beta, Bq, 3.0};
        double G[24], Gf[24], HH[576], HHf[576], HP[576];
        CHECK(crom_rigid_contact(beta, Bq, sh, sizes[sh], 3.0, y, y + 12, 0, &E, G, HH) == 0 && E > 0);
        check_fd_gradient(con_f, &cc, y, 24, 1e-7, Gf);
        check_fd_jacobian(con_g, &cc, y, 24, 24, 1e-7, HHf);
        double cg = check_relerr(G, Gf, 24, 1e-10), ch = check_relerr(HH, HHf, 576, 1e-6);
        CHECK(crom_rigid_contact(beta, Bq, sh, sizes[sh], 3.0, y, y + 12, 1, NULL, NULL, HP) == 0);
        fprintf(stderr, "%-8s phi %.4f: sdf gradient %.1e Hessian %.1e; contact gradient %.1e Hessian %.1e, "
                        "projected min eigenvalue %.1e\n",
                names[sh], phi, eg, eh, cg, ch, fx_min_eig(HP, 24));
        CHECK_LT(eg, 1e-7);
        CHECK_LT(eh, 1e-6);
        CHECK_LT(cg, 1e-6);
        CHECK_LT(ch, 1e-5);
        CHECK(fx_min_eig(HP, 24) > -1e-9 * fabs(HH[0]));
        /* outside the shape: nothing */
        double far[3] = {1, 1, 1};
        crom_rigid_sdf(sh, sizes[sh], far, &phi, NULL, NULL);
        CHECK(phi > 0);
    }
}

static void test_validation(void)
{
    crom_scenes_params p = params();
    crom_mesh m;
    CHECK(crom_scenes_chain(&p, &m) == 0);
    crom_scene *s = m.scene;
    s->joints[1].b = 7;
    CHECK(crom_mesh_validate(&m) == CROM_EDATA);
    CHECK(strstr(crom_errmsg(), "joint 1 names body 7") != NULL);
    s->joints[1].b = 0;
    s->joints[2].weight = -1;
    CHECK(crom_mesh_validate(&m) == CROM_EDATA);
    CHECK(strstr(crom_errmsg(), "non-negative") != NULL);
    s->joints[2].weight = 1;
    s->bodies[0].size[0] = 0;
    CHECK(crom_mesh_validate(&m) == CROM_EDATA);
    CHECK(strstr(crom_errmsg(), "size 0") != NULL);
    s->bodies[0].size[0] = 0.01;
    crom_scene_pair pr = {0, 0, 1};
    CHECK(crom_scene_add_pair(s, &pr) == 0);
    CHECK(crom_mesh_validate(&m) == CROM_EDATA);
    CHECK(strstr(crom_errmsg(), "with itself") != NULL);
    s->pairs[0].b = 1;
    CHECK(crom_mesh_validate(&m) == 0);
    crom_system sys; /* a pair becomes a contact element per sample point of body 0 */
    CHECK(crom_system_init(&sys, &m, 1, 0.3, 1) == 0);
    CHECK(sys.rb.ncontact > 100 && sys.nenergy == 3 + 3 + sys.rb.ncontact);
    crom_system_free(&sys);
    s->np = 0;
    m.X[5] += 1e-3; /* frame vertices that are not the body's */
    CHECK(crom_system_init(&sys, &m, 1, 0.3, 1) == CROM_EDATA);
    CHECK(strstr(crom_errmsg(), "body 0's frame vertices") != NULL);
    crom_mesh_free(&m);
    p.links = 0;
    CHECK(crom_scenes_chain(&p, &m) == CROM_EUSAGE);
    crom_err_clear();
}

/* a body point's position: rest point X0 carried by body b's frame at x */
static void carried(const crom_rigidsys *rs, int b, const double *x, const double X0[3], double out[3])
{
    double R[9], t[3];
    crom_rigidsys_pose(rs, b, x, R, t);
    for (int i = 0; i < 3; i++)
        out[i] = R[3 * i] * X0[0] + R[3 * i + 1] * X0[1] + R[3 * i + 2] * X0[2] + t[i];
}

/* the position of body b's centre at positions x */
static void centre(const crom_sim *s, int b, double c[3])
{
    carried(&s->sys.rb, b, s->x, s->mesh->scene->bodies[b].centre, c);
}

static void test_free_fall(void)
{
    crom_scenes_params p = params();
    crom_mesh m;
    CHECK(crom_scenes_chain(&p, &m) == 0);
    m.scene->nj = 0; /* three loose links */
    crom_scenario sc;
    crom_scenario_defaults(&sc);
    sc.dt = 0.01;
    sc.steps = 20;
    crom_sim s;
    crom_sim_stats st;
    CHECK(crom_sim_init(&s, &m, &sc) == 0);
    double c0[3], c[3], worst = 0;
    centre(&s, 1, c0);
    for (int k = 1; k <= sc.steps; k++) {
        CHECK(crom_sim_step(&s, &st) == 0);
        centre(&s, 1, c);
        double want = c0[1] - 9.81 * sc.dt * sc.dt * k * (k + 1) / 2; /* implicit Euler under constant g */
        worst = fmax(worst, fabs(c[1] - want) + fabs(c[0] - c0[0]) + fabs(c[2] - c0[2]));
    }
    fprintf(stderr, "free fall: centre within %.1e m of h^2 g N(N+1)/2\n", worst);
    CHECK_LT(worst, 1e-9);
    crom_sim_free(&s);
    crom_mesh_free(&m);
}

static void test_pendulum(void)
{
    crom_scenes_params p = {.links = 1, .length = 1.0, .radius = 0.02, .density = 1000,
                            .angle = M_PI / 2 - 5 * M_PI / 180, .gravity = 9.81};
    crom_mesh m;
    CHECK(crom_scenes_pendulum(&p, &m) == 0);
    crom_scenario sc;
    crom_scenario_defaults(&sc);
    sc.dt = 1e-3;
    crom_sim s;
    crom_sim_stats st;
    CHECK(crom_sim_init(&s, &m, &sc) == 0);
    double c[3], xp = 0, tp = 0, cross[8];
    int nc = 0;
    centre(&s, 0, c);
    xp = c[0];
    for (int k = 0; k < 7000 && nc < 8; k++) {
        CHECK(crom_sim_step(&s, &st) == 0);
        centre(&s, 0, c);
        if ((xp > 0) != (c[0] > 0))
            cross[nc++] = tp + xp / (xp - c[0]) * (s.t - tp);
        xp = c[0];
        tp = s.t;
    }
    CHECK(nc >= 5);
    double T = 2 * (cross[nc - 1] - cross[0]) / (nc - 1), T0 = 2 * M_PI * sqrt(1.0 / 9.81);
    fprintf(stderr, "pendulum of 1 m at 5 degrees: period %.5f s, 2 pi sqrt(L/g) = %.5f s (%.3f%%)\n", T, T0,
            100 * (T / T0 - 1));
    CHECK_LT(fabs(T / T0 - 1), 0.01);
    crom_sim_free(&s);
    crom_mesh_free(&m);
}

/* the volume a closed surface of outward triangles encloses (divergence theorem) */
static double enclosed(const crom_mesh *d, int body, const int *bodyv)
{
    double V = 0;
    for (int t = 0; t < d->ntri; t++) {
        const int *v = d->tris + 3 * t;
        if (bodyv[v[0]] != body)
            continue;
        const double *a = d->X + 3 * v[0], *b = d->X + 3 * v[1], *c = d->X + 3 * v[2];
        V += (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
              a[2] * (b[0] * c[1] - b[1] * c[0])) / 6;
    }
    return V;
}

/* The display surface: closed and outward (its enclosed volume is the
 * box's exactly and converges to the capsule's and sphere's), and carried
 * exactly by the frames: a rigid motion of the frames moves every display
 * vertex rigidly. */
static void test_display(void)
{
    crom_scene sc = {0};
    const double sb[3] = {0.3, 0.2, 0.1}, cb[3] = {0, 1, 0}, sc1[3] = {0.05, 0.4, 0}, cc[3] = {1, 0, 0},
                 ss[3] = {0.1, 0, 0}, cs[3] = {0, 0, 1};
    crom_scene_body bx = crom_scene_body_make(CROM_SCENE_BOX, sb, cb, 500),
                    cp = crom_scene_body_make(CROM_SCENE_CAPSULE, sc1, cc, 500),
                    sp = crom_scene_body_make(CROM_SCENE_SPHERE, ss, cs, 500);
    const double sr[3] = {0.02, 0.06, 0.05}, cr[3] = {-1, 0, 0};
    crom_scene_body rg = crom_scene_body_make(CROM_SCENE_RING, sr, cr, 500);
    crom_rng r0;
    crom_rng_seed(&r0, 17);
    fx_random_rotation(&r0, rg.rot); /* turned at rest */
    fx_random_rotation(&r0, bx.rot);
    CHECK(crom_scene_add_body(&sc, &bx) == 0 && crom_scene_add_body(&sc, &cp) == 0 &&
          crom_scene_add_body(&sc, &sp) == 0 && crom_scene_add_body(&sc, &rg) == 0);
    sc.ortho_weight = 1;
    crom_mesh m;
    CHECK(crom_rigidsys_scene_mesh(&sc, NULL, &m) == 0);
    double prev[4] = {0, 0, 0, 0};
    for (int res = 8; res <= 64; res *= 2) {
        crom_mesh d;
        double *beta;
        int *body;
        CHECK(crom_rigidsys_display(&m, res, &d, &beta, &body) == 0);
        CHECK(crom_mesh_validate(&d) == 0 && d.nregions == 4);
        double err[4];
        for (int b = 0; b < 4; b++)
            err[b] = fabs(enclosed(&d, b, body) / crom_scene_body_volume(&m.scene->bodies[b]) - 1);
        fprintf(stderr, "display at %2d rings: volume error box %.1e, capsule %.2e, sphere %.2e, ring %.2e\n", res,
                err[0], err[1], err[2], err[3]);
        CHECK_LT(err[0], 1e-12);
        if (res > 8) /* second order: a quarter each time the rings double */
            for (int b = 1; b < 4; b++)
                CHECK(err[b] < 0.3 * prev[b]);
        CHECK_LT(err[1], 0.05);
        memcpy(prev, err, sizeof prev);
        /* a rotation and a shift of every frame moves the display rigidly */
        double Q[9], t[3] = {0.1, -0.2, 0.3};
        crom_rng rng;
        crom_rng_seed(&rng, 3);
        fx_random_rotation(&rng, Q);
        double *u = malloc(sizeof(double) * 3 * m.nv), *ud = malloc(sizeof(double) * 3 * d.nv), worst = 0;
        for (int i = 0; i < m.nv; i++)
            for (int r = 0; r < 3; r++)
                u[3 * i + r] = Q[3 * r] * m.X[3 * i] + Q[3 * r + 1] * m.X[3 * i + 1] + Q[3 * r + 2] * m.X[3 * i + 2] +
                               t[r] - m.X[3 * i + r];
        crom_rigidsys_display_map(d.nv, beta, body, u, ud);
        for (int i = 0; i < d.nv; i++)
            for (int r = 0; r < 3; r++) {
                const double *X = d.X + 3 * i;
                double want = Q[3 * r] * X[0] + Q[3 * r + 1] * X[1] + Q[3 * r + 2] * X[2] + t[r] - X[r];
                worst = fmax(worst, fabs(ud[3 * i + r] - want));
            }
        CHECK_LT(worst, 1e-13);
        free(u), free(ud), free(beta), free(body);
        crom_mesh_free(&d);
    }
    crom_mesh_free(&m);
}

/* Reduced simulation over a scene's elements (8-vertex contacts and
 * joints through lib/rom/nlsim): in the full-rank linear basis (the
 * identity over every frame coordinate) the reduced run of the mini chain
 * is the full run, the loose ring falling onto the pinned one and caught
 * by the contacts: within 1e-7 m over 40 steps (measured 3e-9); after
 * that the contacts amplify the solvers' different round-off (2e-5 m
 * after 80 steps), as they would any perturbation. */
static void test_reduced_full_rank(void)
{
    crom_scenes_params p = {.links = 2, .rings = 1, .length = 0.03, .radius = 0.005, .ring_radius = 0.02,
                            .density = 1000, .gravity = 9.81};
    crom_mesh m;
    CHECK(crom_scenes_chain(&p, &m) == 0);
    int n = 3 * m.nv;
    double *W = calloc((size_t)n * n, sizeof(double));
    for (int i = 0; i < n; i++)
        W[(size_t)i * n + i] = 1;
    crom_model model;
    CHECK(crom_model_from_mesh(&model, "pod", &m, W, n) == 0);
    crom_map map;
    CHECK(crom_map_init(&map, &model, NULL) == 0);
    crom_scenario sc;
    crom_scenario_defaults(&sc);
    sc.dt = 0.002;
    sc.tol = 1e-9;
    sc.max_iter = 200;
    crom_sim s;
    crom_sim_stats st;
    crom_nlsim r;
    crom_rsim_stats rst;
    CHECK(crom_sim_init(&s, &m, &sc) == 0);
    int rc = crom_nlsim_init(&r, &map, &sc, 0, NULL, NULL, 1);
    CHECK_MSG(rc == 0, "nlsim on a scene: %s", crom_errmsg());
    if (rc)
        return;
    double *x = malloc(sizeof(double) * n), worst = 0, fall = 0;
    for (int k = 0; k < 80; k++) {
        CHECK(crom_sim_step(&s, &st) == 0);
        CHECK(crom_nlsim_step(&r, &rst) == 0);
        crom_nlsim_positions(&r, x, NULL);
        double wk = 0;
        for (int i = 0; i < n; i++)
            wk = fmax(wk, fabs(x[i] - s.x[i]));
        if (getenv("SCENE_DEBUG"))
            fprintf(stderr, "step %d: %.2e (newton %d, rsim iters %d)\n", k, wk, st.newton, rst.iterations);
        if (k < 40)
            worst = fmax(worst, wk);
        fall = fmax(fall, m.X[13] - s.x[13]); /* the loose ring's frame vertex 4, y */
    }
    double wk = 0;
    for (int i = 0; i < n; i++)
        wk = fmax(wk, fabs(x[i] - s.x[i]));
    fprintf(stderr, "mini chain: the full-rank reduced run within %.1e m of the full run over 40 steps (contacts "
                    "engaged), %.1e m after 80 (the two solvers' round-off, grown by the contacts), the loose ring "
                    "fell %.3f m\n", worst, wk, fall);
    CHECK(fall > 0.005);
    CHECK_LT(worst, 1e-7);
    free(x);
    free(W);
    crom_nlsim_free(&r);
    crom_sim_free(&s);
    crom_map_free(&map);
    crom_model_free(&model);
    crom_mesh_free(&m);
}

/* The Klann linkage: assembled exactly (zero energy at rest); a direct
 * kinematic solve closes at every crank angle of a full turn with every
 * bar at its length; and crom-fullsim's linkage swinging under gravity
 * keeps its foot on the kinematic solution for its own crank angle (the
 * joints' give: measured 5e-6 of the leg). */
static void test_klann(void)
{
    crom_scenes_params p = {.length = 0.05, .radius = 0.004, .density = 1000, .gravity = 9.81};
    double P[8][2], prev[16], worst = 0;
    CHECK(crom_scenes_klann_points(0, 0.05, NULL, P) == 0);
    const double s = 0.05 / 17.5;
    static const int bars[][2] = {{0, 2}, {1, 7}, {2, 7}, {2, 5}, {7, 5}, {3, 4}, {4, 5}, {4, 6}, {5, 6}};
    static const double len[] = {17.5, 23.7, 38.8, 73.4, 35.2, 34.1, 57.7, 111.7, 59};
    for (int k = 0; k <= 72; k++) { /* a full turn in 5-degree steps, each branch nearest the last */
        memcpy(prev, P, sizeof prev);
        CHECK(crom_scenes_klann_points(2 * M_PI * k / 72, 0.05, prev, P) == 0);
        for (int b = 0; b < 9; b++)
            worst = fmax(worst, fabs(hypot(P[bars[b][0]][0] - P[bars[b][1]][0], P[bars[b][0]][1] - P[bars[b][1]][1]) -
                                     s * len[b]));
    }
    CHECK_LT(worst, 1e-12);
    crom_mesh m;
    CHECK(crom_scenes_klann(&p, &m) == 0);
    CHECK(m.scene->nb == 5 && m.scene->nj == 14);
    crom_scenario sc;
    crom_scenario_defaults(&sc);
    sc.dt = 0.005;
    sc.max_iter = 100;
    crom_sim sim;
    crom_sim_stats st;
    CHECK(crom_sim_init(&sim, &m, &sc) == 0);
    double E0;
    CHECK(crom_system_energy(&sim.sys, m.X, &E0) == 0);
    CHECK_LT(E0, 1e-20);
    CHECK(crom_scenes_klann_points(0, 0.05, NULL, P) == 0);
    const double C0[3] = {P[2][0], P[2][1], 0}, G0[3] = {P[6][0], P[6][1], 0};
    double foot = 0, lo = 0, hi = 0;
    for (int k = 0; k < 300; k++) {
        CHECK(crom_sim_step(&sim, &st) == 0);
        double C[3], G[3], Q[8][2];
        carried(&sim.sys.rb, 0, sim.x, C0, C);
        carried(&sim.sys.rb, 4, sim.x, G0, G);
        double th = atan2(C[1], C[0]);
        lo = fmin(lo, th), hi = fmax(hi, th);
        memcpy(prev, P, sizeof prev);
        CHECK(crom_scenes_klann_points(th, 0.05, prev, Q) == 0);
        memcpy(P, Q, sizeof P);
        foot = fmax(foot, hypot(hypot(G[0] - Q[6][0], G[1] - Q[6][1]), G[2]));
    }
    fprintf(stderr, "Klann: bars at their lengths to %.1e m over a turn; swinging under gravity (crank %.1f..%.1f "
                    "degrees) the simulated foot stays %.1e m (%.1e of the leg) from the kinematic solution\n",
            worst, lo * 180 / M_PI, hi * 180 / M_PI, foot, foot / (s * 111.7));
    CHECK(hi - lo > 0.2);
    CHECK_LT(foot, 1e-3 * s * 111.7);
    crom_sim_free(&sim);
    crom_mesh_free(&m);
}

/* Sharp et al. Fig. 2: a data-free 1-D subspace of the Klann linkage
 * (energy objective, no gravity: the penalties alone; sigma 0.02 m, lambda
 * 1 as in their Table 1, 10000 steps, 1.5 s). Decoded over z in [-2.5,
 * 2.5], its states are measured against the linkage: the joints' largest
 * gap relative to the crank (measured 3.1%), the crank angles covered
 * (-33..28 degrees), and the foot against the direct kinematic solve at
 * the decoded crank angle (6.6% of the leg). The targets (1% and
 * 2%, the whole cycle) are not met: with 40000 steps 2.7%, -19..19
 * degrees, 2.4% (KL_STEPS=40000 build/tests/test_scene prints it). */
static void test_klann_datafree(void)
{
    crom_scenes_params p = {.length = 0.05, .radius = 0.004, .density = 1000, .gravity = 9.81};
    crom_mesh m;
    CHECK(crom_scenes_klann(&p, &m) == 0);
    crom_datafree_problem P = {.mesh = &m, .gravity = {0, 0, 0}};
    crom_material_init(&P.mat, 1e6, 0.3, 1000);
    crom_datafree_opts o;
    crom_datafree_defaults(&o, CROM_DATAFREE_ENERGY);
    o.rank = 1;
    o.steps = getenv("KL_STEPS") ? atoi(getenv("KL_STEPS")) : 10000;
    o.sigma = getenv("KL_SIGMA") ? atof(getenv("KL_SIGMA")) : 0.02;
    o.lambda = getenv("KL_LAMBDA") ? atof(getenv("KL_LAMBDA")) : 1;
    o.width = 64;
    o.depth = 6;
    o.seed = 5;
    crom_model model;
    crom_dftrain_log log;
    int rc = crom_datafree_train(&P, &o, &model, &log);
    CHECK_MSG(rc == 0, "train: %s", crom_errmsg());
    if (rc)
        return;
    crom_map map;
    CHECK(crom_map_init(&map, &model, NULL) == 0);
    crom_rigidsys rs;
    CHECK(crom_rigidsys_init(&rs, &m) == 0);
    double Pk[8][2], prev[16], gap[14], x[60], worst_gap = 0, foot = 0, lo = 10, hi = -10;
    CHECK(crom_scenes_klann_points(0, 0.05, NULL, Pk) == 0);
    const double C0[3] = {Pk[2][0], Pk[2][1], 0}, G0[3] = {Pk[6][0], Pk[6][1], 0};
    double Pz[8][2];
    memcpy(Pz, Pk, sizeof Pz);
    for (int dir = -1; dir <= 1; dir += 2) { /* from z = 0 outwards, each kinematic branch nearest the last */
        memcpy(Pk, Pz, sizeof Pk);
        for (int k = 0; k <= 50; k++) {
            double z = dir * 2.5 * k / 50, C[3], G[3], Q[8][2];
            CHECK(crom_map_eval(&map, &z, x, NULL) == 0);
            crom_rigidsys_joint_gaps(&rs, x, gap);
            for (int j = 0; j < 14; j++)
                worst_gap = fmax(worst_gap, gap[j]);
            carried(&rs, 0, x, C0, C);
            carried(&rs, 4, x, G0, G);
            double th = atan2(C[1], C[0]);
            lo = fmin(lo, th), hi = fmax(hi, th);
            memcpy(prev, Pk, sizeof prev);
            if (crom_scenes_klann_points(th, 0.05, prev, Q) == 0) {
                memcpy(Pk, Q, sizeof Pk);
                foot = fmax(foot, hypot(G[0] - Q[6][0], G[1] - Q[6][1]));
            }
        }
    }
    fprintf(stderr, "Klann, data-free d = 1 (%d steps, sigma %g, lambda %g): over z in [-2.5, 2.5] the joints' gaps "
                    "<= %.2g of the crank, crank %.0f..%.0f degrees, foot within %.2g of the leg of the kinematic "
                    "solve\n",
            o.steps, o.sigma, o.lambda, worst_gap / 0.05, lo * 180 / M_PI, hi * 180 / M_PI, foot / (0.05 / 17.5 * 111.7));
    if (!getenv("KL_STEPS")) { /* the default run: measured 3.1%, -33..28 degrees, 6.6% */
        CHECK_LT(worst_gap, 0.06 * 0.05);
        CHECK(hi - lo > 40 * M_PI / 180);
        CHECK_LT(foot, 0.1 * 0.05 / 17.5 * 111.7);
    }
    crom_rigidsys_free(&rs);
    crom_map_free(&map);
    crom_model_free(&model);
    crom_dftrain_log_free(&log);
    crom_mesh_free(&m);
}

/* The slider (point on axis): gradient and Hessian against finite
 * differences at a stretched, sheared pair of frames; zero when the point
 * slides along the axis of a rigidly moved body. */
typedef struct {
    const double *beta, *gamma, *c;
} sctx2;

static double sl_f(const double *y, void *ctx)
{
    sctx2 *c = ctx;
    double E;
    crom_rigid_slider(c->beta, c->gamma, c->c, 2.5, y, y + 12, 0, &E, NULL, NULL);
    return E;
}

static void sl_g(const double *y, void *ctx, double *g)
{
    sctx2 *c = ctx;
    crom_rigid_slider(c->beta, c->gamma, c->c, 2.5, y, y + 12, 0, NULL, g, NULL);
}

static void test_slider(void)
{
    const double ext[3] = {0.5, 0.1, 0.1}, ca[3] = {0, 0, 0}, cb[3] = {0.3, 0.02, -0.01};
    crom_rigid_inertia ia, ib;
    crom_rigid_inertia_box(ext, ca, 1000, &ia);
    crom_rigid_inertia_box(ext, cb, 700, &ib);
    double Ya[12], Yb[12], Ba[9], Bb[9], beta[4], gamma[4], c[4];
    CHECK(crom_rigid_frame(&ia, Ya) == 0 && crom_rigid_frame_inverse(Ya, Ba) == 0);
    CHECK(crom_rigid_frame(&ib, Yb) == 0 && crom_rigid_frame_inverse(Yb, Bb) == 0);
    const double P[3] = {0.2, 0.01, 0.005}, a0[3] = {1, 0, 0};
    crom_rigid_coords(Ya, Ba, P, beta);
    crom_rigid_coords(Yb, Bb, P, gamma);
    crom_rigid_axis_weights(Ba, a0, c);
    CHECK_NEAR(c[0] + c[1] + c[2] + c[3], 0, 1e-12);
    /* a rigid turn of a, and b's point slid 0.1 along a's turned axis: no energy */
    crom_rng rng;
    crom_rng_seed(&rng, 31);
    double Q[9], y[24], E, t[3] = {0.1, -0.3, 0.2};
    fx_random_rotation(&rng, Q);
    for (int k = 0; k < 4; k++)
        for (int i = 0; i < 3; i++) {
            y[3 * k + i] = Q[3 * i] * Ya[3 * k] + Q[3 * i + 1] * Ya[3 * k + 1] + Q[3 * i + 2] * Ya[3 * k + 2] + t[i];
            y[12 + 3 * k + i] = Q[3 * i] * (Yb[3 * k] + 0.1) + Q[3 * i + 1] * Yb[3 * k + 1] +
                                Q[3 * i + 2] * Yb[3 * k + 2] + t[i];
        }
    CHECK(crom_rigid_slider(beta, gamma, c, 2.5, y, y + 12, 0, &E, NULL, NULL) == 0);
    CHECK_LT(E, 1e-28);
    for (int i = 0; i < 24; i++)
        y[i] += 0.03 * crom_rng_normal(&rng);
    sctx2 cx = {beta, gamma, c};
    double g[24], gf[24], H[576], Hf[576], Hp[576];
    CHECK(crom_rigid_slider(beta, gamma, c, 2.5, y, y + 12, 0, &E, g, H) == 0 && E > 0);
    check_fd_gradient(sl_f, &cx, y, 24, 1e-6, gf);
    check_fd_jacobian(sl_g, &cx, y, 24, 24, 1e-6, Hf);
    double eg = check_relerr(g, gf, 24, 1e-10), eh = check_relerr(H, Hf, 576, 1e-8);
    CHECK(crom_rigid_slider(beta, gamma, c, 2.5, y, y + 12, 1, NULL, NULL, Hp) == 0);
    fprintf(stderr, "slider: gradient %.1e, Hessian %.1e against finite differences; projected min eigenvalue %.1e\n",
            eg, eh, fx_min_eig(Hp, 24));
    CHECK_LT(eg, 1e-7);
    CHECK_LT(eh, 1e-6);
    CHECK(fx_min_eig(Hp, 24) > -1e-9 * fabs(H[0]));
}

/* The Stewart platform: assembled exactly; pushed sideways by a force on
 * the platform (no gravity) the platform moves while every ball joint and
 * slider holds (the legs telescope). */
static void test_stewart(void)
{
    crom_scenes_params p = {.length = 0.5, .radius = 0.02, .density = 1000, .gravity = 9.81};
    crom_mesh m;
    CHECK(crom_scenes_stewart(&p, &m) == 0);
    CHECK(m.scene->nb == 14 && m.scene->nj == 27);
    crom_scenario sc;
    crom_scenario_defaults(&sc);
    sc.dt = 0.01;
    sc.gravity[1] = 0;
    sc.max_iter = 100;
    CHECK(crom_bc_parse("--force", "platform=20,0,0", &sc.force[0]) == 0);
    sc.nforce = 1;
    crom_sim sim;
    crom_sim_stats st;
    int rc = crom_sim_init(&sim, &m, &sc);
    CHECK_MSG(rc == 0, "stewart: %s", crom_errmsg());
    if (rc)
        return;
    double E0, gap[27], worst = 0;
    CHECK(crom_system_energy(&sim.sys, m.X, &E0) == 0);
    CHECK_LT(E0, 1e-20);
    for (int k = 0; k < 30; k++) {
        CHECK(crom_sim_step(&sim, &st) == 0);
        crom_rigidsys_joint_gaps(&sim.sys.rb, sim.x, gap);
        for (int j = 0; j < 27; j++)
            worst = fmax(worst, gap[j]);
    }
    const double c0[3] = {0, 0.5125, 0};
    double c[3];
    carried(&sim.sys.rb, 1, sim.x, c0, c);
    fprintf(stderr, "Stewart platform pushed for 0.3 s: platform moved %.3f m along x, joints within %.1e m\n",
            c[0], worst);
    CHECK(c[0] > 0.02);
    CHECK_LT(worst, 1e-3);
    crom_sim_free(&sim);
    crom_mesh_free(&m);
}

int main(void)
{
    check_begin("test_scene");
    test_chain_derivatives();
    test_inertia();
    test_validation();
    test_free_fall();
    test_pendulum();
    test_display();
    test_contacts();
    test_reduced_full_rank();
    test_klann();
    test_klann_datafree();
    test_slider();
    test_stewart();
    return check_done();
}
