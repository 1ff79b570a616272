/* test_datafree.c — lib/datafree, rom/map, rom/nlsim, rom/metrics: the
 * data-free subspaces of Sharp et al. 2023 (energy + isometry) and Wang et
 * al. 2024 (Neural Modes) and the latent dynamics on them.
 *
 *  - gradient checks of the three training losses against central
 *    differences (float network, double loss, step 1e-3 on the float
 *    parameters, relative error of the whole gradient vector below 2e-3, as
 *    in test_fit.c), with pins, gravity, the anchor, the collapse floor at rest,
 *    every tet or a random cubature, and every term active;
 *  - the map's double-precision Jacobian against differences of the map;
 *  - every map is anchored: x(0) = X to the last bit, and a run with no
 *    load stays within 1e-12 m of rest (energy, neuralmodes, and the
 *    continuous field on its training mesh and on a finer one);
 *  - a small energy-trained subspace of a clamped bar under gravity has
 *    samples whose mean elastic energy is below that of the linear modes at
 *    the same displacement magnitude;
 *  - a Neural-Modes subspace has no collapsed dimension (Wang et al. §4.4);
 *  - latent dynamics: the reduced objective's gradient and Gauss–Newton
 *    matrix against differences, a finite and energy-dissipating run of a
 *    clamped bar under gravity, and with the linear part alone the same
 *    trajectory as the linear modal ROM of lib/rom.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <lapacke.h>

#include "check.h"
#include "fixtures.h"
#include "base/err.h"
#include "base/lbfgs.h"
#include "base/rng.h"
#include "datafree/datafree.h"
#include "io/io.h"
#include "datafree/dffield.h"
#include "datafree/dfskin.h"
#include "mesh/meshgen.h"
#include "nn/nn.h"
#include "phys/fem.h"
#include "phys/modes.h"
#include "phys/sym.h"
#include "rom/cubature.h"
#include "rom/map.h"
#include "rom/metrics.h"
#include "rom/model.h"
#include "rom/nlsim.h"
#include "rom/rsim.h"
#include "rom/skin.h"

#define FD_H 1e-3
#define FD_TOL 2e-3

static void make_bar(crom_mesh *m, double size)
{
    const double dims[3] = {1, 0.2, 0.2};
    fx_gen(CROM_MESHGEN_BOX, dims, size, m);
    CHECK(crom_mesh_region_spec(m, "clamp=x<-0.49") == 0);
}

static unsigned char *clamp_mask(const crom_mesh *m)
{
    unsigned char *f = calloc(3 * (size_t)m->nv, 1);
    for (int v = 0; v < m->nv; v++)
        if (m->X[3 * v] < -0.49)
            memset(f + 3 * v, 1, 3);
    return f;
}

/* the lowest k modes of the clamped bar as W = Φ sqrt(m) [nv][3][k] */
static double *bar_modes(const crom_mesh *m, const crom_material *mat, const unsigned char *fixed, int k,
                         double **freq)
{
    crom_modes_opts o;
    crom_modes_defaults(&o);
    o.count = k;
    crom_modes res;
    int rc = crom_modes_compute(m, mat, fixed, &o, &res);
    CHECK_MSG(rc == 0, "modes: %s", crom_errmsg());
    double mass = mat->rho * crom_mesh_volume(m), s = sqrt(mass);
    double *W = malloc(sizeof(double) * 3 * m->nv * k);
    for (int i = 0; i < 3 * m->nv * k; i++)
        W[i] = res.phi[i] * s;
    *freq = malloc(sizeof(double) * k);
    memcpy(*freq, res.freq, sizeof(double) * k);
    crom_modes_free(&res);
    return W;
}

/* ------------------------------------------------------- gradient checks */

typedef struct {
    crom_datafree_ctx *c;
    float *p;
    int n, B, K;
    const double *z;
    double rho;
    const int *tets;
} fd_case;

static double loss_at(const double *x, void *v)
{
    fd_case *t = v;
    for (int i = 0; i < t->n; i++)
        t->p[i] = (float)x[i];
    crom_dftrain_terms tm;
    if (crom_datafree_loss(t->c, t->B, t->z, t->rho, t->K, t->tets, &tm, NULL))
        return NAN;
    return tm.objective;
}

static int g_quadratic; /* gradient_check: neuralmodes with a quadratic part ½ Σ Ψ z z */
static int g_supervised; /* gradient_check: neuralmodes fitted to (made-up) equilibria */
static int g_tangent;    /* gradient_check: neuralmodes with its tangent anchored, y = N(z) − N(0) − J_N(0) z */
static int g_seeded;     /* gradient_check: an energy map grown from a seed state (Sharp §4.1) */

static void gradient_check(int objective)
{
    crom_mesh m;
    make_bar(&m, 0.2);
    crom_material mat;
    crom_material_init(&mat, 1e6, 0.3, 1000);
    unsigned char *fixed = clamp_mask(&m);
    int r = 3, B = 5;
    double *freq = NULL, *W = NULL;
    double *Psi = NULL;
    if (objective == CROM_DATAFREE_NEURALMODES)
        W = bar_modes(&m, &mat, fixed, r, &freq);
    if (g_quadratic) { /* a small random quadratic part, zero at the pins */
        crom_rng qr;
        crom_rng_seed(&qr, 23);
        Psi = malloc(sizeof(double) * 3 * m.nv * 6);
        for (int i = 0; i < 3 * m.nv * 6; i++)
            Psi[i] = fixed[i / 6] ? 0 : 0.2 * crom_rng_normal(&qr);
    }
    crom_datafree_problem P = {&m, mat, {0, -9.81, 0}, fixed, W, freq, Psi, 0, NULL, NULL, 0, NULL, NULL, 0, NULL, NULL, NULL, NULL};
    double *useed = NULL;
    if (g_seeded) { /* a seed state: a bend of 2 cm at the free end, zero at the clamp */
        useed = malloc(sizeof(double) * 3 * m.nv);
        for (int v = 0; v < m.nv; v++) {
            double s = m.X[3 * v] + 0.5;
            useed[3 * v] = -0.01 * s * m.X[3 * v + 1];
            useed[3 * v + 1] = 0.02 * s * s;
            useed[3 * v + 2] = 0;
        }
        P.seed = useed;
    }
    /* supervised: 4 made-up equilibria u = W z + v, v random and
     * M-orthogonal to the modes (so that W^T M u / m = z), zero at the pins */
    double zsup[4 * 3], *usup = NULL;
    int sup_idx[5] = {0, 1, 2, 3, 1};
    if (g_supervised) {
        crom_rng sr;
        crom_rng_seed(&sr, 29);
        int n = 3 * m.nv;
        double *mv = malloc(sizeof(double) * m.nv), mt = 0;
        crom_mesh_vertex_volumes(&m, mv);
        for (int v = 0; v < m.nv; v++)
            mt += mv[v];
        usup = malloc(sizeof(double) * 4 * n);
        for (int k = 0; k < 4; k++) {
            double *u = usup + (size_t)k * n;
            for (int i = 0; i < n; i++)
                u[i] = fixed[i] ? 0 : 0.01 * crom_rng_normal(&sr);
            for (int a = 0; a < r; a++) {
                double p = 0;
                for (int i = 0; i < n; i++)
                    p += mv[i / 3] * W[(size_t)i * r + a] * u[i];
                p /= mt;
                zsup[k * r + a] = 0.05 * crom_rng_normal(&sr);
                for (int i = 0; i < n; i++)
                    u[i] += W[(size_t)i * r + a] * (zsup[k * r + a] - p);
            }
        }
        free(mv);
        P.nsup = 4;
        P.sup_z = zsup;
        P.sup_u = usup;
    }
    crom_datafree_opts o;
    crom_datafree_defaults(&o, objective);
    o.rank = r;
    o.sigma = 0.04;
    o.lambda = 0.7;
    o.box = 0.1;
    o.ortho_weight = 3; /* a weight of the size of the energy term, so every term shows */
    o.tangent_anchor = g_tangent;
    o.tangent_weight = 0.5;
    o.tangent_floor = 1; /* every eigenvalue below the mean counts: the term shows */
    int widths[] = {r, 12, 12, 3 * m.nv};
    crom_nn_spec spec;
    CHECK(crom_nn_spec_set(&spec, 4, widths, o.act) == 0);
    crom_nn_mlp net;
    crom_rng rng;
    crom_rng_seed(&rng, 5);
    CHECK(crom_nn_mlp_init(&net, &spec, NULL, &rng) == 0);
    /* a small random last layer: displacements of a few cm, no inversions */
    crom_nn_layer *ly = &net.layer[2];
    for (int i = 0; i < ly->out * ly->in; i++)
        ly->W[i] *= 0.3f;
    for (int i = 0; i < ly->out; i++)
        ly->b[i] = (float)(0.01 * crom_rng_normal(&rng));
    /* ELU's hidden biases away from 0, where its second derivative jumps:
     * the secants from rest would sit on the kink, and central differences
     * err by O(h) there */
    for (int i = 0; objective == CROM_DATAFREE_ENERGY && i < net.layer[0].out; i++)
        net.layer[0].b[i] = (float)(0.5 * crom_rng_normal(&rng));
    crom_datafree_ctx c;
    CHECK(crom_datafree_ctx_init(&c, &P, &o, &net, B) == 0);
    double z[8 * 3]; /* the batch, then the tangent samples (energy) */
    for (int i = 0; i < B * r; i++)
        z[i] = objective == CROM_DATAFREE_ENERGY ? crom_rng_normal(&rng) : o.box * (2 * crom_rng_uniform(&rng) - 1);
    if (g_supervised) { /* the batch: equilibria 0 1 2 3 1 at their modal coordinates */
        for (int b = 0; b < B; b++)
            memcpy(z + b * r, zsup + sup_idx[b] * r, sizeof(double) * r);
        c.sup = sup_idx;
    }
    for (int i = B * r; i < (B + c.B0) * r; i++) /* the secants 0.1 e_k (as the trainer draws them) */
        z[i] = (i - B * r) % (r + 1) == 0 ? 0.1 : 0;
    CHECK(c.B0 == (objective == CROM_DATAFREE_ENERGY ? 3 : 0));
    /* a random cubature of a third of the tets, one repeated */
    int K = m.nt / 3, *tets = malloc(sizeof(int) * (size_t)K);
    for (int k = 0; k < K; k++)
        tets[k] = (int)crom_rng_below(&rng, (uint64_t)m.nt);
    tets[K - 1] = tets[0];
    int n = (int)net.nparams;
    float *g = malloc(sizeof(float) * n);
    double *ga = malloc(sizeof(double) * n), *gf = malloc(sizeof(double) * n), *x = malloc(sizeof(double) * n);
    /* every tet at rho 0.6 and 0, then the random cubature at rho 0.6; last
     * (energy) the collapse floor at rest alone: rho 0 (no energy), no pairs */
    double rhos[4] = {0.6, 0.0, 0.6, 0.0};
    int Ks[4] = {0, 0, K, 0};
    for (int k = 0; k < 4; k++) {
        if (objective != CROM_DATAFREE_ENERGY && (k == 1 || k == 3))
            continue; /* neuralmodes has no blend and no tangent term */
        if (k == 3) {
            c.o.lambda = 0;
            c.o.tangent_weight = 10;
        }
        crom_dftrain_terms tm;
        int rc = crom_datafree_loss(&c, B, z, rhos[k], Ks[k], Ks[k] ? tets : NULL, &tm, g);
        CHECK_MSG(rc == 0, "loss: %s", crom_errmsg());
        for (int i = 0; i < n; i++) {
            ga[i] = g[i];
            x[i] = net.params[i];
        }
        fd_case fc = {&c, net.params, n, B, Ks[k], z, rhos[k], Ks[k] ? tets : NULL};
        double e;
        if (!g_tangent) {
            check_fd_gradient(loss_at, &fc, x, n, FD_H, gf);
            e = check_relerr(ga, gf, n, 1e-12);
        } else {
            /* tangent-anchored: the central difference J_N(0) z ≈ (N(εz) − N(−εz)) / 2ε amplifies the
             * float32 rounding of the outputs 50-fold, too much for per-parameter differences of
             * step FD_H; check the gradient along its own direction d = g/|g| with steps that move
             * the loss far above that rounding: (L(θ + t d) − L(θ − t d)) / 2t against |g| */
            double gn = 0;
            for (int i = 0; i < n; i++)
                gn += ga[i] * ga[i];
            gn = sqrt(gn);
            e = 0;
            double *dir = malloc(sizeof(double) * n);
            crom_rng dr;
            crom_rng_seed(&dr, 31);
            for (int v = 0; v < 4; v++) { /* the gradient's direction, then three random ones (mixed with it) */
                double dn = 0, slope = 0, best = INFINITY;
                for (int i = 0; i < n; i++) {
                    dir[i] = ga[i] / gn + (v ? crom_rng_normal(&dr) / sqrt(n) : 0);
                    dn += dir[i] * dir[i];
                }
                for (int i = 0; i < n; i++) {
                    dir[i] /= sqrt(dn);
                    slope += ga[i] * dir[i];
                }
                for (double t = 1e-4; t <= 1e-2; t *= 10) {
                    for (int i = 0; i < n; i++)
                        gf[i] = x[i] + t * dir[i];
                    double Lp = loss_at(gf, &fc);
                    for (int i = 0; i < n; i++)
                        gf[i] = x[i] - t * dir[i];
                    double Lm = loss_at(gf, &fc);
                    best = fmin(best, fabs((Lp - Lm) / (2 * t) - slope) / gn);
                }
                e = fmax(e, best);
            }
            free(dir);
        }
        for (int i = 0; i < n; i++)
            net.params[i] = (float)x[i];
        fprintf(stderr, "%s loss (rho %.1f, %s): objective %.4g (energy %.4g J, penalty %.4g, tangent %.4g); "
                        "gradient vs FD %.2e over %d parameters%s\n",
                objective == CROM_DATAFREE_ENERGY ? "energy+isometry" : g_supervised ? "neuralmodes supervised (L2)"
                : g_tangent ? "neuralmodes tangent-anchored" : g_quadratic ? "neuralmodes + derivatives"
                : "neuralmodes", rhos[k],
                Ks[k] ? "random cubature" : "every tet", tm.objective, tm.energy, tm.penalty, tm.tangent, e, n,
                g_tangent ? " (along the gradient and 3 directions)" : "");
        CHECK_LT(e, FD_TOL);
        CHECK(tm.penalty > 0);
        CHECK(objective == CROM_DATAFREE_ENERGY ? tm.tangent > 0 : tm.tangent == 0);
        if (k == 3 && !g_seeded) /* the loss is the tangent term alone */
            CHECK_REL(tm.objective, 10 * tm.tangent, 1e-12);
        else if (k == 3) /* and the seed state's energy (checked below) */
            CHECK(tm.objective > 10 * tm.tangent);
        /* pinned outputs get no gradient: the last layer's pinned rows */
        double gp = 0;
        for (int i = 0; i < 3 * m.nv; i++)
            if (fixed[i])
                gp += fabs(ga[ly->boff + i]);
        CHECK(gp == 0);
    }
    if (g_tangent) { /* the stored map: tangent W at rest exactly; y as trained (the central difference) */
        crom_model model;
        crom_map map;
        CHECK(crom_model_from_map(&model, "neuralmodes", &net, &m, W) == 0);
        model.tangent_anchored = 1;
        CHECK(crom_map_init(&map, &model, NULL) == 0);
        int nd = 3 * m.nv;
        double *xm = malloc(sizeof(double) * nd), *J = malloc(sizeof(double) * nd * r), z0[3] = {0, 0, 0}, dj = 0;
        double dy = 0, ys = 0;
        CHECK(crom_map_eval(&map, z0, xm, J) == 0);
        for (int i = 0; i < nd * r; i++)
            dj = fmax(dj, fabs(J[i] - W[i]));
        crom_dftrain_terms tm;
        CHECK(crom_datafree_loss(&c, B, z, 0.6, 0, NULL, &tm, NULL) == 0);
        for (int b = 0; b < B; b++) {
            CHECK(crom_map_eval(&map, z + b * r, xm, NULL) == 0);
            for (int i = 0; i < nd; i++) {
                if (fixed[i]) /* (this test's random network does not zero its pinned rows; the trainer masks them) */
                    continue;
                double u = xm[i] - m.X[i];
                for (int a = 0; a < r; a++)
                    u -= W[(size_t)i * r + a] * z[b * r + a];
                dy = fmax(dy, fabs(u - c.Y[(size_t)b * nd + i]));
                ys = fmax(ys, fabs(c.Y[(size_t)b * nd + i]));
            }
        }
        fprintf(stderr, "tangent-anchored map: |J(0) - W| %.1e; y of the stored map against the trainer's (a central "
                        "difference of step 0.01 z) %.2e of %.2e m\n", dj, dy, ys);
        CHECK_LT(dj, 1e-12);
        CHECK_LT(dy, 1e-2 * ys);
        free(xm), free(J);
        crom_map_free(&map);
        crom_model_free(&model);
    }
    if (g_seeded) { /* at rho 0 every sample is the seed state: its potential, gravity from rest */
        crom_dftrain_terms tm;
        c.o.lambda = 0.7;
        CHECK(crom_datafree_loss(&c, B, z, 0.0, 0, NULL, &tm, NULL) == 0);
        int nd = 3 * m.nv;
        double *xs = malloc(sizeof(double) * nd), *gs = malloc(sizeof(double) * nd), Es = 0;
        for (int i = 0; i < nd; i++)
            xs[i] = m.X[i] + useed[i];
        crom_fem_opts fo = {0, 0, fixed, 1};
        CHECK(crom_system_assemble(&c.sys, xs, &fo, &Es, gs, NULL) == 0);
        for (int i = 0; i < nd; i++)
            if (!fixed[i])
                Es -= c.sys.mass[i / 3] * P.gravity[i % 3] * useed[i];
        fprintf(stderr, "seeded energy map: the samples at rho 0 have %.6g J, the seed state %.6g J\n", c.E[0], Es);
        CHECK(Es > 0);
        for (int b = 0; b < B; b++)
            CHECK_REL(c.E[b], Es, 1e-12);
        free(xs), free(gs);
    }
    crom_datafree_ctx_free(&c);
    crom_nn_mlp_free(&net);
    free(g);
    free(ga);
    free(gf);
    free(x);
    free(W);
    free(freq);
    free(Psi);
    free(usup);
    free(useed);
    free(tets);
    free(fixed);
    crom_mesh_free(&m);
}

/* The continuous field's loss (energy by a random cubature, isometry over
 * the sampled Gram matrix, through the pin mask) against central
 * differences over the parameters of both networks, on a tet list with
 * repeats; the mask is zero at the pins and 1 far from them. */
typedef struct {
    crom_dffield_ctx *c;
    float *pw, *pp;
    int nw, np, B, K;
    const double *z;
    const int *tets;
} fdf_case;

static double field_loss_at(const double *x, void *v)
{
    fdf_case *t = v;
    for (int i = 0; i < t->nw; i++)
        t->pw[i] = (float)x[i];
    for (int i = 0; i < t->np; i++)
        t->pp[i] = (float)x[t->nw + i];
    crom_dftrain_terms tm;
    if (crom_dffield_loss(t->c, t->B, t->z, 0.7, t->K, t->tets, &tm, NULL, NULL))
        return NAN;
    return tm.objective;
}

/* The field's options in the gradient checks: every term weighted. */
static void field_check_opts(crom_datafree_opts *o)
{
    crom_datafree_defaults(o, CROM_DATAFREE_FIELD);
    o->sigma = 0.04;
    o->lambda = 0.7;
    o->tangent_weight = 0.6;
    o->tangent_floor = 1; /* every eigenvalue below the mean counts: the term shows */
}

static void gradient_check_field(void)
{
    crom_mesh m;
    make_bar(&m, 0.2);
    crom_material mat;
    crom_material_init(&mat, 1e6, 0.3, 1000);
    unsigned char *fixed = clamp_mask(&m);
    crom_datafree_problem P = {&m, mat, {0, -9.81, 0}, fixed, NULL, NULL, NULL, 0, NULL, NULL, 0, NULL, NULL, 0, NULL, NULL, NULL, NULL};
    crom_datafree_opts o;
    field_check_opts(&o);
    o.pin_length = 0.3; /* a wide mask: many vertices inside it */
    int r = 2, pf = 4, B = 4;
    int ww[] = {3, 10, 10, 3 * pf}, pw[] = {r, 10, pf};
    crom_nn_spec ws, ps;
    CHECK(crom_nn_spec_set(&ws, 4, ww, CROM_NN_ELU) == 0);
    CHECK(crom_nn_spec_set(&ps, 3, pw, CROM_NN_ELU) == 0);
    crom_nn_mlp W, phi;
    crom_rng rng;
    crom_rng_seed(&rng, 9);
    CHECK(crom_nn_mlp_init(&W, &ws, NULL, &rng) == 0);
    CHECK(crom_nn_mlp_init(&phi, &ps, NULL, &rng) == 0);
    crom_nn_layer *ly = &W.layer[2]; /* displacements of a few cm */
    for (int i = 0; i < ly->out * ly->in; i++)
        ly->W[i] *= 0.05f;
    int K = m.nt / 2 + 3, *tets = malloc(sizeof(int) * (size_t)K);
    for (int k = 0; k < K; k++)
        tets[k] = (int)crom_rng_below(&rng, (uint64_t)m.nt);
    tets[K - 1] = tets[0]; /* a repeat */
    crom_dffield_ctx c;
    CHECK(crom_dffield_ctx_init(&c, &P, &o, &W, NULL, &phi, B, K) == 0);
    int inside = 0, onpin = 1, far = 1;
    for (int v = 0; v < m.nv; v++) {
        double x = m.X[3 * v];
        inside += c.mask[v] > 0 && c.mask[v] < 1;
        if (fixed[3 * v])
            onpin &= c.mask[v] == 0;
        if (x > 0)
            far &= c.mask[v] == 1;
    }
    CHECK(c.npins > 0 && onpin && far && inside > 0);
    double z[12]; /* the batch, then the tangent samples */
    for (int i = 0; i < B * r; i++)
        z[i] = crom_rng_normal(&rng);
    for (int i = B * r; i < (B + c.B0) * r; i++) /* the secants 0.1 e_k (as the trainer draws them) */
        z[i] = (i - B * r) % (r + 1) == 0 ? 0.1 : 0;
    CHECK(c.B0 == 2);
    int nw = (int)W.nparams, np = (int)phi.nparams, n = nw + np;
    float *gw = malloc(sizeof(float) * nw), *gp = malloc(sizeof(float) * np);
    double *ga = malloc(sizeof(double) * n), *gf = malloc(sizeof(double) * n), *x = malloc(sizeof(double) * n);
    crom_dftrain_terms tm;
    int rc = crom_dffield_loss(&c, B, z, 0.7, K, tets, &tm, gw, gp);
    CHECK_MSG(rc == 0, "field loss: %s", crom_errmsg());
    for (int i = 0; i < nw; i++) {
        ga[i] = gw[i];
        x[i] = W.params[i];
    }
    for (int i = 0; i < np; i++) {
        ga[nw + i] = gp[i];
        x[nw + i] = phi.params[i];
    }
    fdf_case fc = {&c, W.params, phi.params, nw, np, B, K, z, tets};
    /* the field's last layer is small (x 0.05): a step of 2e-4, not FD_H,
     * keeps the differences in their linear range (truncation error falls
     * as h², 7e-3 at h = 1e-3) */
    check_fd_gradient(field_loss_at, &fc, x, n, 2e-4, gf);
    double e = check_relerr(ga, gf, n, 1e-12), ew = check_relerr(ga, gf, nw, 1e-12),
           ep = check_relerr(ga + nw, gf + nw, np, 1e-12);
    fprintf(stderr, "continuous field loss: objective %.4g (energy %.4g J, isometry %.4g, tangent %.4g) over %d tets, "
                    "%d vertices inside the pin mask; gradient vs FD %.2e over %d parameters (field %.2e, latent "
                    "network %.2e)\n",
            tm.objective, tm.energy, tm.penalty, tm.tangent, K, inside, e, n, ew, ep);
    CHECK_LT(e, FD_TOL);
    CHECK_LT(ep, FD_TOL);
    CHECK(tm.penalty > 0 && tm.tangent > 0 && tm.energy != 0);
    CHECK(crom_dffield_loss(&c, B, z, 0.7, K + 1, tets, &tm, NULL, NULL) == CROM_EUSAGE);
    crom_dffield_ctx_free(&c);
    crom_nn_mlp_free(&W);
    crom_nn_mlp_free(&phi);
    free(tets);
    free(gw);
    free(gp);
    free(ga);
    free(gf);
    free(x);
    free(fixed);
    crom_mesh_free(&m);
}

/* The same loss over a FIXED basis (a skin-field's features: W(X_v) given,
 * zero on the pinned vertices, no mask): its gradient in φ's parameters
 * against central differences (field_loss_at with no field parameters). */
static void gradient_check_field_basis(void)
{
    crom_mesh m;
    make_bar(&m, 0.2);
    crom_material mat;
    crom_material_init(&mat, 1e6, 0.3, 1000);
    unsigned char *fixed = clamp_mask(&m);
    crom_datafree_problem P = {&m, mat, {0, -9.81, 0}, fixed, NULL, NULL, NULL, 0, NULL, NULL, 0, NULL, NULL, 0, NULL, NULL, NULL, NULL};
    crom_datafree_opts o;
    field_check_opts(&o);
    int r = 2, pf = 5, B = 4, pw[] = {r, 10, pf};
    crom_nn_spec ps;
    CHECK(crom_nn_spec_set(&ps, 3, pw, CROM_NN_ELU) == 0);
    crom_nn_mlp phi;
    crom_rng rng;
    crom_rng_seed(&rng, 19);
    CHECK(crom_nn_mlp_init(&phi, &ps, NULL, &rng) == 0);
    double *basis = malloc(sizeof(double) * 3 * (size_t)m.nv * pf); /* smooth in X, 0 at the clamp */
    for (int v = 0; v < m.nv; v++)
        for (int c = 0; c < 3; c++)
            for (int j = 0; j < pf; j++) {
                const double *X = m.X + 3 * v;
                double s = fixed[3 * v] ? 0 : (X[0] + 0.5) * 0.05;
                basis[((size_t)v * 3 + c) * pf + j] = s * cos((j + 1) * X[0] + c * X[1] + 0.3 * j * X[2]);
            }
    int K = m.nt / 2 + 3, *tets = malloc(sizeof(int) * (size_t)K);
    for (int k = 0; k < K; k++)
        tets[k] = (int)crom_rng_below(&rng, (uint64_t)m.nt);
    tets[K - 1] = tets[0];
    crom_dffield_ctx c;
    CHECK(crom_dffield_ctx_init(&c, &P, &o, NULL, NULL, &phi, B, K) == CROM_EUSAGE); /* neither W nor a basis */
    CHECK(crom_dffield_ctx_init(&c, &P, &o, NULL, basis, &phi, B, K) == 0);
    double z[12];
    for (int i = 0; i < B * r; i++)
        z[i] = crom_rng_normal(&rng);
    for (int i = B * r; i < (B + c.B0) * r; i++) /* the secants 0.1 e_k (as the trainer draws them) */
        z[i] = (i - B * r) % (r + 1) == 0 ? 0.1 : 0;
    int np = (int)phi.nparams;
    float *gp = malloc(sizeof(float) * np);
    double *ga = malloc(sizeof(double) * np), *gf = malloc(sizeof(double) * np), *x = malloc(sizeof(double) * np);
    crom_dftrain_terms tm;
    int rc = crom_dffield_loss(&c, B, z, 0.7, K, tets, &tm, NULL, gp);
    CHECK_MSG(rc == 0, "field loss over a basis: %s", crom_errmsg());
    for (int i = 0; i < np; i++) {
        ga[i] = gp[i];
        x[i] = phi.params[i];
    }
    fdf_case fc = {&c, NULL, phi.params, 0, np, B, K, z, tets};
    check_fd_gradient(field_loss_at, &fc, x, np, 1e-4, gf);
    double e = check_relerr(ga, gf, np, 1e-12);
    fprintf(stderr, "continuous field over a fixed basis of %d features: objective %.4g (energy %.4g J, isometry "
                    "%.4g, tangent %.4g); gradient vs FD %.2e over %d parameters of phi\n",
            pf, tm.objective, tm.energy, tm.penalty, tm.tangent, e, np);
    CHECK_LT(e, FD_TOL);
    CHECK(tm.penalty > 0 && tm.tangent > 0 && tm.energy != 0);
    crom_dffield_ctx_free(&c);
    crom_nn_mlp_free(&phi);
    free(basis);
    free(tets);
    free(gp);
    free(ga);
    free(gf);
    free(x);
    free(fixed);
    crom_mesh_free(&m);
}

/* ------------------------------------------------- the map in double */

typedef struct {
    crom_map *map;
    double *x;
} map_case;

static void map_at(const double *q, void *v, double *out)
{
    map_case *t = v;
    crom_map_eval(t->map, q, out, NULL);
}

/* T(q)ᵀ g, the gradient of gᵀa(q) (for the curvature's FD check) */
typedef struct {
    crom_map *map;
    const double *g;
} curv_case;

static void curv_grad(const double *q, void *v, double *out)
{
    curv_case *c = v;
    int p = c->map->p, r = c->map->r;
    double *T = malloc(sizeof(double) * (size_t)p * r);
    if (T && crom_map_features(c->map, q, NULL, T) == 0)
        for (int a = 0; a < r; a++) {
            out[a] = 0;
            for (int k = 0; k < p; k++)
                out[a] += T[(size_t)k * r + a] * c->g[k];
        }
    free(T);
}

/* crom_map_curvature (the exact Hessian of gᵀa(q), a random g) against
 * central differences of T(q)ᵀg; returns the relative error */
static double check_map_curvature(crom_map *map, double *q, unsigned seed)
{
    int p = map->p, r = map->r;
    crom_rng rng;
    crom_rng_seed(&rng, seed);
    double *g = malloc(sizeof(double) * (size_t)p), *C = malloc(sizeof(double) * (size_t)r * r);
    double *Cfd = malloc(sizeof(double) * (size_t)r * r), e = 1;
    for (int i = 0; g && i < p; i++)
        g[i] = crom_rng_normal(&rng);
    curv_case cc = {map, g};
    if (g && C && Cfd && crom_map_curvature(map, q, g, C) == 0) {
        check_fd_jacobian(curv_grad, &cc, q, r, r, 1e-5, Cfd);
        e = check_relerr(C, Cfd, r * r, 1e-12);
    }
    free(g);
    free(C);
    free(Cfd);
    return e;
}

/* A map model with a random network (and modes for neuralmodes): its
 * double Jacobian against differences, the curvature of its features, its positions against the float
 * network, pins exactly at rest after zeroing their rows. */
/* The loss options, a random network and the loss of problem P of the two
 * conditional tests: a map of rank r and 2 conditions to n outputs, its last
 * layer small (and zero on the rows of mask, the trainer's pins, unless
 * NULL), its first biases away from ELU's kink; and z [B + B0][r], a batch
 * of B normal draws then the secants 0.1 e_k as the trainer draws them. */
static void cond_case(crom_datafree_opts *o, crom_nn_mlp *net, crom_rng *rng, int r, int n, uint64_t seed,
                      const unsigned char *mask, const crom_datafree_problem *P, int B, crom_datafree_ctx *c, double *z)
{
    crom_datafree_defaults(o, CROM_DATAFREE_ENERGY);
    int widths[] = {r + 2, 12, 12, n};
    o->rank = r;
    o->sigma = 0.04;
    o->lambda = 0.7;
    o->tangent_weight = 0.5;
    o->tangent_floor = 1;
    crom_nn_spec spec;
    CHECK(crom_nn_spec_set(&spec, 4, widths, o->act) == 0);
    crom_rng_seed(rng, seed);
    CHECK(crom_nn_mlp_init(net, &spec, NULL, rng) == 0);
    crom_nn_layer *ly = &net->layer[2];
    for (int i = 0; i < ly->out; i++)
        for (int j = 0; j < ly->in; j++)
            ly->W[(size_t)i * ly->in + j] = mask && mask[i] ? 0 : 0.3f * ly->W[(size_t)i * ly->in + j];
    for (int i = 0; i < net->layer[0].out; i++)
        net->layer[0].b[i] = (float)(0.5 * crom_rng_normal(rng));
    CHECK_MSG(crom_datafree_ctx_init(c, P, o, net, B) == 0, "ctx: %s", crom_errmsg());
    for (int i = 0; i < B * r; i++)
        z[i] = crom_rng_normal(rng);
    for (int i = B * r; i < (B + c->B0) * r; i++)
        z[i] = (i - B * r) % (r + 1) == 0 ? 0.1 : 0;
}

/* A conditional energy map (Sharp et al. §3.5): the network takes [z, c]
 * with c the modulus ratio of the bar's far half and the gravity along y.
 * dL/dc (through the network's input and the energy's own dependence: the
 * far half's energy over the ratio, −Σ m u_y for gravity) against central
 * differences of the loss in c; the batch's materials follow c (the far
 * half's tets at c E); the stored map holds x(0, c) = X exactly at every
 * c, and x(z, c) − X is the trainer's Y at the same c. */
static void test_conditional(void)
{
    crom_mesh m;
    make_bar(&m, 0.2);
    unsigned char *fixed = clamp_mask(&m);
    crom_scenario sc;
    crom_scenario_defaults(&sc);
    sc.youngs = 1e6;
    sc.poisson = 0.3;
    crom_scenario_cond cond[2];
    CHECK(crom_scenario_cond_parse("--condition", "ratio:x>0=1:10", 1, &cond[0]) == 0);
    CHECK(crom_scenario_cond_parse("--condition", "gravity:y=-15:-5", 1, &cond[1]) == 0);
    CHECK(crom_scenario_cond_apply(&sc, &cond[0], 5.5) == 0 && sc.nmat == 1 && sc.mat[0].youngs == 5.5e6);
    /* the flag's forms: a value, a range, the names */
    crom_scenario_cond t;
    char buf[200];
    CHECK(crom_scenario_cond_parse("--condition", "gravity:z=-3", 0, &t) == 0 && t.axis == 2 && t.lo == -3 &&
          t.hi == -3);
    crom_scenario_cond_format(&cond[0], buf, sizeof buf);
    CHECK(!strcmp(buf, "ratio:x>0=1:10") && crom_scenario_cond_same(&cond[1], &t) == 0);
    const char *bad[] = {"ratio:x>0=0:2", "ratio:=1:2", "gravity:w=1:2", "stiff=1:2", "ratio:x>0=3:1", "gravity:y=1"};
    for (int i = 0; i < 6; i++) {
        CHECK_MSG(crom_scenario_cond_parse("--condition", bad[i], 1, &t) == CROM_EUSAGE, "'%s' accepted", bad[i]);
        crom_err_clear();
    }
    crom_material mat;
    crom_material_init(&mat, sc.youngs, sc.poisson, sc.density);
    crom_datafree_problem P = {&m, mat, {0, -9.81, 0}, fixed, NULL, NULL, NULL, 0, NULL, NULL, 0, NULL, &sc, 2, cond, NULL, NULL, NULL};
    crom_datafree_opts o;
    crom_nn_mlp net;
    crom_rng rng;
    int r = 3, B = 5;
    crom_datafree_ctx c;
    double z[8 * 3], cv[2] = {3.7, -8.2}, cp[2];
    cond_case(&o, &net, &rng, r, 3 * m.nv, 41, NULL, &P, B, &c, z);
    CHECK(crom_datafree_set_condition(&c, cv) == 0);
    CHECK_REL(c.sys.mats[1].E, 3.7e6, 1e-15);
    CHECK(c.grav[1] == -8.2 && c.grav[0] == 0);
    float *g = malloc(sizeof(float) * net.nparams);
    crom_dftrain_terms tm;
    CHECK(crom_datafree_loss(&c, B, z, 0.8, 0, NULL, &tm, g) == 0);
    double dc[2] = {c.dcond[0], c.dcond[1]}, worst = 0;
    for (int k = 0; k < 2; k++) {
        double h = 1e-2 * fabs(cv[k]), L[2]; /* the network runs in float: a step well above its rounding */
        for (int sgn = 0; sgn < 2; sgn++) {
            memcpy(cp, cv, sizeof cp);
            cp[k] += sgn ? -h : h;
            CHECK(crom_datafree_set_condition(&c, cp) == 0);
            CHECK(crom_datafree_loss(&c, B, z, 0.8, 0, NULL, &tm, NULL) == 0);
            L[sgn] = tm.objective;
        }
        double fd = (L[0] - L[1]) / (2 * h);
        fprintf(stderr, "conditional energy map: dL/dc_%d = %.6g, central difference %.6g\n", k, dc[k], fd);
        worst = fmax(worst, fabs(fd - dc[k]) / fmax(fabs(fd), 1e-12));
    }
    CHECK_LT(worst, 3e-3);
    /* the stored map at two conditions: rest exact, the trainer's Y */
    crom_model model;
    crom_map map;
    CHECK(crom_model_from_map(&model, "energy", &net, &m, NULL) == 0);
    CHECK(crom_model_set_conditions(&model, 2, cond) == 0 && model.rank == r);
    CHECK(crom_map_init(&map, &model, NULL) == 0 && map.nc == 2);
    CHECK(map.cond[0] == 5.5 && map.cond[1] == -10); /* the middles of the ranges */
    int n = 3 * m.nv;
    double *x = malloc(sizeof(double) * n), z0[3] = {0, 0, 0}, dmax = 0, ymax = 0, rest = 0;
    for (int pass = 0; pass < 2; pass++) {
        double cc[2] = {pass ? 9.0 : 1.5, pass ? -6.0 : -14.0};
        CHECK(crom_map_set_condition(&map, cc) == 0 && crom_datafree_set_condition(&c, cc) == 0);
        CHECK(crom_map_eval(&map, z0, x, NULL) == 0);
        for (int i = 0; i < n; i++)
            rest = fmax(rest, fabs(x[i] - m.X[i]));
        CHECK(crom_datafree_loss(&c, B, z, 1, 0, NULL, &tm, NULL) == 0);
        for (int b = 0; b < B; b++) {
            CHECK(crom_map_eval(&map, z + b * r, x, NULL) == 0);
            for (int i = 0; i < n; i++)
                if (!fixed[i]) {
                    dmax = fmax(dmax, fabs(x[i] - m.X[i] - c.Y[(size_t)b * n + i]));
                    ymax = fmax(ymax, fabs(c.Y[(size_t)b * n + i]));
                }
        }
    }
    fprintf(stderr, "conditional energy map: |x(0, c) - X| %.1e; x(z, c) - X against the trainer's %.1e of %.1e m\n",
            rest, dmax, ymax);
    CHECK(rest == 0);
    CHECK_LT(dmax, 1e-5 * ymax);
    double one[1] = {2};
    crom_map_free(&map);
    CHECK(crom_map_init(&map, &model, NULL) == 0);
    CHECK(crom_map_set_condition(&map, (double[]){NAN, 1}) == CROM_EDATA);
    crom_err_clear();
    crom_map_free(&map);
    crom_model_free(&model);
    /* an unconditional map refuses a condition */
    CHECK(crom_model_from_map(&model, "energy", &net, &m, NULL) == 0 && model.rank == r + 2);
    CHECK(crom_map_init(&map, &model, NULL) == 0 && crom_map_set_condition(&map, one) == CROM_EUSAGE);
    crom_err_clear();
    crom_map_free(&map);
    crom_model_free(&model);
    free(x);
    free(g);
    crom_datafree_ctx_free(&c);
    crom_nn_mlp_free(&net);
    free(fixed);
    crom_mesh_free(&m);
}

/* A pin condition (Sharp et al.'s conditional bar: where its pinned
 * endpoints are): the bar clamped at x = -0.5 and pinned at x = +0.5, the
 * far pin moved along y by c. dL/dc (through the network's input and the
 * energy's own dependence: the elastic force holding the far pin, along y)
 * against central differences; the stored map holds x(0, c) = X with the
 * far pin moved by c, every z keeps both pins where c puts them; a reduced
 * run over a cubature of half the tets starts there with its pins
 * satisfied, and after the condition changes its elastic energy at q = 0 is
 * that of the moved pin (the cubature's cached rows follow); a pin on a
 * region that is not pinned is refused. */
static void test_conditional_pin(void)
{
    crom_mesh m;
    make_bar(&m, 0.2);
    CHECK(crom_mesh_region_spec(&m, "far=x>0.49") == 0);
    int n = 3 * m.nv;
    unsigned char *fixed = clamp_mask(&m);
    for (int v = 0; v < m.nv; v++)
        if (m.X[3 * v] > 0.49)
            memset(fixed + 3 * v, 1, 3);
    crom_scenario_cond cond[2], t;
    CHECK(crom_scenario_cond_parse("--condition", "pin:far:y=-0.1:0.1", 1, &cond[0]) == 0);
    CHECK(cond[0].kind == CROM_SCENARIO_COND_PIN && cond[0].axis == 1 && !strcmp(cond[0].ref, "far"));
    CHECK(crom_scenario_cond_parse("--condition", "gravity:y=-15:-5", 1, &cond[1]) == 0);
    char buf[200];
    crom_scenario_cond_format(&cond[0], buf, sizeof buf);
    CHECK(!strcmp(buf, "pin:far:y=-0.1:0.1"));
    CHECK(crom_scenario_cond_parse("--condition", "pin:far:x=0.2", 0, &t) == 0 && !crom_scenario_cond_same(&t, &cond[0]));
    CHECK(crom_scenario_cond_parse("--condition", "pin:far:y=0.2", 0, &t) == 0 && crom_scenario_cond_same(&t, &cond[0]));
    const char *bad[] = {"pin:far=0:1", "pin::y=0:1", "pin:far:w=0:1", "pin:far:y=0:2e3"};
    for (int i = 0; i < 4; i++) {
        CHECK_MSG(crom_scenario_cond_parse("--condition", bad[i], 1, &t) == CROM_EUSAGE, "'%s' accepted", bad[i]);
        crom_err_clear();
    }
    crom_material mat;
    crom_material_init(&mat, 1e6, 0.3, 1000);
    crom_datafree_problem P = {&m, mat, {0, -9.81, 0}, fixed, NULL, NULL, NULL, 0, NULL, NULL, 0, NULL, NULL, 2, cond, NULL, NULL, NULL};
    crom_datafree_opts o;
    crom_nn_mlp net;
    crom_rng rng;
    int r = 3, B = 5;
    crom_datafree_ctx c;
    double z[8 * 3], cv[2] = {0.04, -8.2}, cp[2];
    cond_case(&o, &net, &rng, r, n, 43, fixed, &P, B, &c, z);
    CHECK(crom_datafree_set_condition(&c, cv) == 0);
    float *g = malloc(sizeof(float) * net.nparams);
    crom_dftrain_terms tm;
    CHECK(crom_datafree_loss(&c, B, z, 0.8, 0, NULL, &tm, g) == 0);
    double dc = c.dcond[0], L[2], h = 1e-2; /* the network runs in float: a step well above its rounding */
    for (int sgn = 0; sgn < 2; sgn++) {
        memcpy(cp, cv, sizeof cp);
        cp[0] += sgn ? -h : h;
        CHECK(crom_datafree_set_condition(&c, cp) == 0);
        CHECK(crom_datafree_loss(&c, B, z, 0.8, 0, NULL, &tm, NULL) == 0);
        L[sgn] = tm.objective;
    }
    double fd = (L[0] - L[1]) / (2 * h);
    fprintf(stderr, "pin condition: dL/dc = %.8g, central difference %.8g\n", dc, fd);
    CHECK(fabs(dc) > 0);
    CHECK_LT(fabs(fd - dc), 3e-3 * fabs(fd));
    /* the static lift: 1 m along y on the far pin, 0 on the clamp, and the
     * linear equilibrium at rest on the free DOFs (K lift = 0 there) */
    const double *lift = c.lift;
    double pinmiss = 0, kf = 0, kp = 0, *y = malloc(sizeof(double) * n), *Kv = malloc(sizeof(double) * c.sys.nnz);
    for (int i = 0; i < n; i++)
        if (fixed[i])
            pinmiss = fmax(pinmiss, fabs(lift[i] - (m.X[3 * (i / 3)] > 0.49 && i % 3 == 1)));
    crom_fem_opts whole = {0, 0, NULL, 1};
    CHECK(crom_system_assemble(&c.sys, m.X, &whole, NULL, NULL, Kv) == 0);
    crom_sym Ks = {n, c.sys.colptr, c.sys.rowind, Kv};
    crom_sym_matvec(&Ks, lift, y);
    for (int i = 0; i < n; i++) {
        if (fixed[i])
            kp = fmax(kp, fabs(y[i]));
        else
            kf = fmax(kf, fabs(y[i]));
    }
    fprintf(stderr, "pin condition: the lift's pins off by %.1e; |K lift| on the free DOFs %.2e, on the pins %.2e\n",
            pinmiss, kf, kp);
    CHECK(pinmiss == 0);
    CHECK_LT(kf, 1e-9 * kp);
    int zero = 1; /* the gravity condition's lift */
    for (int i = 0; i < n; i++)
        zero &= lift[n + i] == 0;
    CHECK(zero);
    free(y), free(Kv);
    /* the stored map: x(0, c) = X + c lift; the pins hold for every z */
    crom_model model;
    crom_map map;
    CHECK(crom_model_from_map(&model, "energy", &net, &m, NULL) == 0);
    CHECK(crom_model_set_conditions(&model, 2, cond) == 0);
    CHECK(crom_map_init(&map, &model, NULL) == CROM_EDATA); /* a pin condition without its lifts */
    crom_err_clear();
    model.lift_v = malloc(sizeof(double) * 2 * n);
    memcpy(model.lift_v, lift, sizeof(double) * 2 * n);
    CHECK(crom_map_init(&map, &model, NULL) == 0 && map.nc == 2 && map.cond[0] == 0);
    double *x = malloc(sizeof(double) * n), z0[3] = {0, 0, 0}, miss = 0, cc[2] = {0.07, -6};
    CHECK(crom_map_set_condition(&map, cc) == 0);
    for (int b = -1; b < B; b++) {
        CHECK(crom_map_eval(&map, b < 0 ? z0 : z + b * r, x, NULL) == 0);
        for (int i = 0; i < n; i++)
            if (b < 0 || fixed[i])
                miss = fmax(miss, fabs(x[i] - (m.X[i] + 0.07 * lift[i])));
    }
    CHECK_LT(miss, 1e-15);
    /* a reduced run over half the tets, then the condition changes */
    crom_scenario sc;
    crom_scenario_defaults(&sc);
    sc.youngs = 1e6;
    sc.poisson = 0.3;
    sc.gravity[1] = -6;
    strcpy(sc.pins[sc.npins++], "clamp");
    strcpy(sc.pins[sc.npins++], "far");
    crom_nlsim s;
    int rc = crom_nlsim_init(&s, &map, &sc, 0, NULL, NULL, 1);
    CHECK_MSG(rc == 0, "nlsim: %s", crom_errmsg());
    int K = m.nt / 2, *el = malloc(sizeof(int) * K);
    double *w = malloc(sizeof(double) * K);
    for (int k = 0; k < K; k++)
        el[k] = 2 * k, w[k] = 2;
    if (!rc) {
        CHECK(crom_nlsim_use_cubature(&s, K, el, w) == 0);
        CHECK(crom_nlsim_constraint_residual(&s) == 0);
        double c2[2] = {-0.05, -6}, Kk, Ee, W, Eref = 0;
        CHECK(crom_nlsim_set_condition(&s, &map, &sc, cond, c2) == 0);
        CHECK(crom_nlsim_constraint_residual(&s) == 0);
        CHECK(crom_nlsim_energies(&s, &Kk, &Ee, &W) == 0);
        crom_nlsim_positions(&s, x, NULL);
        crom_system sys;
        CHECK(crom_system_init(&sys, &m, 1e6, 0.3, 1000) == 0);
        for (int k = 0; k < K; k++) {
            double xe[12];
            crom_fem_tet_positions(&sys.fem, x, el[k], xe);
            Eref += 2 * crom_system_elem_energy(&sys, el[k], xe);
        }
        fprintf(stderr, "pin condition: the run's elastic energy at q = 0 after the pin moves to -0.05 m: %.8g J "
                        "(direct %.8g J)\n", Ee, Eref);
        CHECK(Eref > 0);
        CHECK_REL(Ee, Eref, 1e-12);
        crom_system_free(&sys);
        crom_nlsim_free(&s);
    }
    free(el), free(w);
    crom_map_free(&map);
    crom_model_free(&model);
    crom_datafree_ctx_free(&c);
    /* a pin condition on a region that is not pinned */
    unsigned char *clamp = clamp_mask(&m);
    P.fixed = clamp;
    CHECK(crom_datafree_ctx_init(&c, &P, &o, &net, B) == CROM_EUSAGE);
    CHECK(strstr(crom_errmsg(), "pin:far:y: the region is not pinned (give --pin far)") != NULL);
    crom_err_clear();
    crom_datafree_ctx_free(&c);
    free(clamp);
    free(x);
    free(g);
    crom_nn_mlp_free(&net);
    free(fixed);
    crom_mesh_free(&m);
}

static void test_map(void)
{
    crom_mesh m;
    make_bar(&m, 0.2);
    int r = 3, n = 3 * m.nv;
    int widths[] = {r, 10, 10, n};
    for (int kind = 0; kind < 3; kind++) { /* energy, neuralmodes, neuralmodes with modal derivatives */
        crom_nn_spec spec;
        CHECK(crom_nn_spec_set(&spec, 4, widths, kind ? CROM_NN_GELU : CROM_NN_ELU) == 0);
        spec.omega0 = 1;
        crom_nn_mlp net;
        crom_rng rng;
        crom_rng_seed(&rng, 11 + kind);
        CHECK(crom_nn_mlp_init(&net, &spec, NULL, &rng) == 0);
        for (int i = 0; i < (int)net.nparams; i++) /* biases too */
            if (net.params[i] == 0)
                net.params[i] = (float)(0.1 * crom_rng_normal(&rng));
        double *W = NULL;
        if (kind) {
            W = malloc(sizeof(double) * n * r);
            for (int i = 0; i < n * r; i++)
                W[i] = crom_rng_normal(&rng);
        }
        crom_model model;
        CHECK(crom_model_from_map(&model, kind ? "neuralmodes" : "energy", &net, &m, W) == 0);
        int nd = r * (r + 1) / 2;
        if (kind == 2) { /* the quadratic part ½ Σ Ψ_ij q_i q_j */
            model.deriv_v = malloc(sizeof(double) * n * nd);
            for (int i = 0; i < n * nd; i++)
                model.deriv_v[i] = crom_rng_normal(&rng);
            crom_model_id(&model, model.model_id);
        }
        crom_map map;
        int rc = crom_map_init(&map, &model, NULL);
        CHECK_MSG(rc == 0, "map: %s", crom_errmsg());
        double q[3] = {0.3, -0.7, 0.45}, *x = malloc(sizeof(double) * n), *J = malloc(sizeof(double) * n * r);
        double *Jfd = malloc(sizeof(double) * n * r);
        CHECK(crom_map_eval(&map, q, x, J) == 0);
        map_case mc = {&map, NULL};
        check_fd_jacobian(map_at, &mc, q, r, n, 1e-6, Jfd);
        double ej = check_relerr(J, Jfd, n * r, 1e-12);
        /* against the float network, anchored: x - X - W q = N(q) - N(0) */
        crom_nn_ws ws;
        CHECK(crom_nn_ws_init(&ws, &net, 2, 1) == 0);
        float qf[6] = {0.3f, -0.7f, 0.45f, 0, 0, 0}, *y = malloc(sizeof(float) * 2 * n);
        CHECK(crom_nn_mlp_forward(&net, &ws, 2, qf, y) == 0);
        double dn = 0, nn = 0;
        for (int i = 0; i < n; i++) {
            double lin = 0, yi = (double)y[i] - y[n + i];
            for (int k = 0; W && k < r; k++)
                lin += W[i * r + k] * q[k];
            for (int k = 0, c = 0; model.deriv_v && k < r; k++)
                for (int l = k; l < r; l++, c++)
                    lin += 0.5 * model.deriv_v[(size_t)i * nd + c] * q[k] * q[l];
            double d = x[i] - m.X[i] - lin - yi;
            dn += d * d;
            nn += yi * yi;
        }
        /* and exactly at rest at q = 0, to the last bit */
        double q0[3] = {0, 0, 0}, rest = 0;
        CHECK(crom_map_eval(&map, q0, x, NULL) == 0);
        for (int i = 0; i < n; i++)
            rest = fmax(rest, fabs(x[i] - m.X[i]));
        /* the curvature of the features, and of the sine activation's on
         * the same network */
        double ec = check_map_curvature(&map, q, 5), es;
        crom_nn_act act = map.act;
        map.act = CROM_NN_SINE;
        es = check_map_curvature(&map, q, 6);
        map.act = act;
        fprintf(stderr, "%s map: Jacobian vs FD %.2e, positions vs float network %.2e, largest |x(0) - X| %.3g m, "
                "feature curvature vs FD %.2e (sine %.2e)\n",
                kind == 2 ? "neuralmodes + derivatives" : kind ? "neuralmodes" : "energy", ej, sqrt(dn / nn), rest, ec,
                es);
        CHECK(map.rq == (kind == 2 ? nd : 0) && map.p == (kind ? r : 0) + map.rq + 10 + 1);
        CHECK_LT(ej, 1e-7);
        CHECK_LT(ec, 1e-6);
        CHECK_LT(es, 1e-6);
        CHECK_LT(sqrt(dn / nn), 1e-5);
        CHECK(rest == 0);
        /* a map decodes only on its own mesh */
        crom_mesh other;
        make_bar(&other, 0.15);
        crom_map bad;
        CHECK(crom_map_init(&bad, &model, &other) == CROM_EDATA);
        CHECK(strstr(crom_errmsg(), "decodes only onto its own mesh") != NULL);
        crom_mesh_free(&other);
        /* model_id covers the network, the mesh and W */
        char id0[17], id1[17];
        crom_model_id(&model, id0);
        model.mlp.params[7] += 1e-3f;
        crom_model_id(&model, id1);
        CHECK(strcmp(id0, id1) != 0);
        model.mlp.params[7] -= 1e-3f;
        if (W) {
            model.basis_v[5] += 1;
            crom_model_id(&model, id1);
            CHECK(strcmp(id0, id1) != 0);
            model.basis_v[5] -= 1;
        }
        if (model.deriv_v) {
            model.deriv_v[3] += 1;
            crom_model_id(&model, id1);
            CHECK(strcmp(id0, id1) != 0);
            model.deriv_v[3] -= 1;
        }
        crom_nn_ws_free(&ws);
        crom_map_free(&map);
        crom_model_free(&model);
        crom_nn_mlp_free(&net);
        free(W);
        free(x);
        free(J);
        free(Jfd);
        free(y);
    }
    crom_mesh_free(&m);
}

/* ------------------------------------------------------ trained maps */

/* The clamped bar of the subspace tests: 1 x 0.2 x 0.2 m, E = 1 MPa (soft:
 * its static sag under gravity is about 0.35 m at the tip), clamped at
 * x = -0.5. */
typedef struct {
    crom_mesh mesh;
    crom_material mat;
    unsigned char *fixed;
    crom_fem fem;
    crom_system sys; /* the same solid through the system interface (crom-metrics) */
    double *modes, *freq;
    int nmodes;
} bar_case;

static void bar_setup(bar_case *b, int nmodes)
{
    make_bar(&b->mesh, 0.1);
    crom_material_init(&b->mat, 1e6, 0.3, 1000);
    b->fixed = clamp_mask(&b->mesh);
    CHECK(crom_fem_init(&b->fem, &b->mesh, &b->mat) == 0);
    CHECK(crom_system_init(&b->sys, &b->mesh, b->mat.E, b->mat.nu, b->mat.rho) == 0);
    b->nmodes = nmodes;
    b->modes = bar_modes(&b->mesh, &b->mat, b->fixed, nmodes, &b->freq);
}

static void bar_free(bar_case *b)
{
    crom_fem_free(&b->fem);
    crom_system_free(&b->sys);
    free(b->fixed);
    free(b->modes);
    free(b->freq);
    crom_mesh_free(&b->mesh);
}

/* A linear map model of the modes (kind neuralmodes with a zero network:
 * x = X + W q exactly). */
static void linear_modes_model(const bar_case *b, crom_model *out)
{
    int r = b->nmodes, widths[] = {r, 4, 3 * b->mesh.nv};
    crom_nn_spec spec;
    crom_nn_spec_set(&spec, 3, widths, CROM_NN_GELU);
    crom_nn_mlp net;
    CHECK(crom_nn_mlp_init(&net, &spec, NULL, NULL) == 0); /* zero parameters */
    CHECK(crom_model_from_map(out, "neuralmodes", &net, &b->mesh, b->modes) == 0);
    crom_nn_mlp_free(&net);
}

/* The modes as a crom-modes-like mesh-field model (a linear basis). */
static void modes_model(const bar_case *b, crom_model *out)
{
    CHECK(crom_model_from_mesh(out, "modes", &b->mesh, b->modes, b->nmodes) == 0);
}

/* Rest is exact: the run of a map with no load (no gravity, no force,
 * no initial velocity) starts at q = 0, exactly the rest shape, and stays
 * there to round-off, every vertex within 1e-12 m of rest over 30 steps
 * (with the clamp as a pin penalty too). */
static void check_rest(const char *name, crom_map *map)
{
    crom_scenario sc;
    crom_scenario_defaults(&sc);
    sc.youngs = 1e6;
    sc.poisson = 0.3;
    sc.dt = 0.01;
    sc.tol = 1e-9;
    sc.gravity[0] = sc.gravity[1] = sc.gravity[2] = 0;
    strcpy(sc.pins[sc.npins++], "x<-0.49");
    crom_nlsim s;
    int rc = crom_nlsim_init(&s, map, &sc, 0, NULL, NULL, 1);
    CHECK_MSG(rc == 0, "%s: %s", name, crom_errmsg());
    if (rc)
        return;
    double *x = malloc(sizeof(double) * (size_t)map->n), worst = 0, qmax = 0;
    crom_nlsim_positions(&s, x, NULL);
    int same = 1;
    for (int i = 0; i < map->n; i++)
        same &= x[i] == map->mesh.X[i];
    CHECK(same); /* the start, bit for bit */
    for (int k = 0; k < 30; k++) {
        crom_rsim_stats st;
        if (crom_nlsim_step(&s, &st)) {
            CHECK_MSG(0, "%s, step %d: %s", name, k, crom_errmsg());
            break;
        }
        crom_nlsim_positions(&s, x, NULL);
        for (int i = 0; i < map->n; i++)
            worst = fmax(worst, fabs(x[i] - map->mesh.X[i]));
        for (int i = 0; i < map->r; i++)
            qmax = fmax(qmax, fabs(s.q[i]));
    }
    fprintf(stderr, "%s: no load, 30 steps from rest: largest vertex displacement %.3g m, largest |q| %.3g\n", name,
            worst, qmax);
    CHECK_LT(worst, 1e-12);
    free(x);
    crom_nlsim_free(&s);
}

static crom_model g_energy_model; /* trained once, used by the dynamics tests */

/* Sharp et al.: a rank-2 energy map of the clamped bar under gravity, 400
 * steps of 16 samples (the other options at their defaults). Its random
 * samples (z ~ N(0, I)) have less elastic energy than the two lowest
 * linear modes at the same RMS displacements: below half (measured 18 J
 * against 1922 J, ratio 0.01); it is nearly isometric at scale sigma
 * (ratio within [0.7, 1.3] for 90 % of the pairs; measured 0.89 .. 1.04),
 * pins stay exactly at rest, and so does a run with no load. */
static void test_energy_subspace(bar_case *b)
{
    crom_datafree_problem P = {&b->mesh, b->mat, {0, -9.81, 0}, b->fixed, NULL, NULL, NULL, 0, NULL, NULL, 0, NULL, NULL, 0, NULL, NULL, NULL, NULL};
    crom_datafree_opts o;
    crom_datafree_defaults(&o, CROM_DATAFREE_ENERGY);
    o.rank = 2;
    o.steps = 400;
    o.batch = 16;
    o.width = 32;
    o.seed = 3;
    crom_dftrain_log log;
    int rc = crom_datafree_train(&P, &o, &g_energy_model, &log);
    CHECK_MSG(rc == 0, "train: %s", crom_errmsg());
    if (rc)
        return;
    CHECK(!strcmp(g_energy_model.basis, "energy") && g_energy_model.rank == 2 && log.steps == 400);
    CHECK(log.nblocks == 100 && log.objective[99] < log.objective[0]);
    crom_map map, lin;
    crom_model lm;
    modes_model(b, &lm);
    CHECK(crom_map_init(&map, &g_energy_model, NULL) == 0);
    CHECK(crom_map_init(&lin, &lm, NULL) == 0);
    check_rest("energy map", &map);
    crom_metrics_opts mo;
    crom_metrics_defaults(&mo);
    mo.samples = 64;
    mo.sigma = log.sigma;
    crom_metrics res;
    double g[3] = {0, -9.81, 0};
    rc = crom_metrics_compute(&map, &b->sys, g, &mo, &lin, &res);
    CHECK_MSG(rc == 0, "metrics: %s", crom_errmsg());
    fprintf(stderr, "energy map (rank 2, 400 steps): mean elastic energy %.4g J at mean RMS displacement %.4g m; "
                    "linear modes at the same displacements %.4g J (ratio %.3g); isometry ratio q05 %.3f median "
                    "%.3f q95 %.3f; Gram eigenvalues %.3f %.3f\n",
            res.energy_mean, res.rms_mean, res.cmp_energy_mean, res.energy_mean / res.cmp_energy_mean, res.iso_q05,
            res.iso_median, res.iso_q95, res.gram_eig[0], res.gram_eig[1]);
    CHECK_LT(res.energy_mean, 0.5 * res.cmp_energy_mean);
    CHECK(res.iso_q05 > 0.7 && res.iso_q95 < 1.3);
    /* pinned vertices exactly at rest for any z */
    double q[2] = {1.7, -2.3}, *x = malloc(sizeof(double) * map.n), dmax = 0;
    CHECK(crom_map_eval(&map, q, x, NULL) == 0);
    for (int i = 0; i < map.n; i++)
        if (b->fixed[i])
            dmax = fmax(dmax, fabs(x[i] - b->mesh.X[i]));
    CHECK(dmax == 0);
    free(x);
    crom_metrics_free(&res);
    crom_map_free(&map);
    crom_map_free(&lin);
    crom_model_free(&lm);
    crom_dftrain_log_free(&log);
}

static void scenario_bar(crom_scenario *sc);

/* How far a network's parameters moved from those of net (largest
 * |after - before|), with the largest |before| in *largest: a refinement
 * that starts from net moves them by round-off in one step at a vanishing
 * rate. after is NULL when training failed (0 is returned). */
static double params_moved(const crom_nn_mlp *net, const float *after, double *largest)
{
    double d = 0, m = 0;
    for (size_t i = 0; after && i < net->nparams; i++) {
        d = fmax(d, fabs(after[i] - net->params[i]));
        m = fmax(m, fabs(net->params[i]));
    }
    *largest = m;
    return d;
}

/* An energy map grown from a seed state (Sharp et al. §4.1; map.h): a
 * random map whose pinned rows are zero, seeded with a bend and a shift
 * that moves the clamp too. x(0) is X + u_s bit for bit, pinned vertices
 * stay at the seed for any q, a reduced run starts there with its pins
 * satisfied and takes gravity's potential from rest (−Σ m g·u_s), and the
 * seed survives a write and read (and changes the model's id). */
static void test_seeded_map(bar_case *b)
{
    const crom_mesh *m = &b->mesh;
    int r = 2, n = 3 * m->nv;
    int widths[] = {r, 16, n};
    crom_nn_spec spec;
    CHECK(crom_nn_spec_set(&spec, 3, widths, CROM_NN_ELU) == 0);
    crom_nn_mlp net;
    crom_rng rng;
    crom_rng_seed(&rng, 41);
    CHECK(crom_nn_mlp_init(&net, &spec, NULL, &rng) == 0);
    crom_nn_layer *ly = &net.layer[1];
    for (int i = 0; i < n; i++) /* the trainer's mask: pinned rows zero */
        for (int j = 0; b->fixed[i] && j < ly->in; j++)
            ly->W[(size_t)i * ly->in + j] = 0;
    for (int i = 0; i < n; i++)
        if (b->fixed[i])
            ly->b[i] = 0;
    double *us = malloc(sizeof(double) * n);
    for (int v = 0; v < m->nv; v++) {
        double t = m->X[3 * v] + 0.5;
        us[3 * v] = 0.004 - 0.01 * t * m->X[3 * v + 1];
        us[3 * v + 1] = 0.03 * t * t;
        us[3 * v + 2] = 0.001;
    }
    crom_model plain, seeded;
    CHECK(crom_model_from_map(&plain, "energy", &net, m, NULL) == 0);
    CHECK(crom_model_from_map(&seeded, "energy", &net, m, NULL) == 0);
    seeded.seed_v = malloc(sizeof(double) * n);
    memcpy(seeded.seed_v, us, sizeof(double) * n);
    crom_model_id(&seeded, seeded.model_id);
    CHECK(strcmp(plain.model_id, seeded.model_id) != 0);
    const char *path = "build/tests/test_datafree_seeded.h5";
    crom_out out;
    int rc = crom_out_create(&out, path, CROM_MODEL_SCHEMA, CROM_MODEL_VERSION, NULL, NULL, CROM_OUT_PLAIN);
    if (!rc && (rc = crom_model_write(out.h5, &seeded)))
        crom_out_fail(&out);
    else if (!rc)
        rc = crom_out_commit(&out);
    CHECK_MSG(rc == 0, "write: %s", crom_errmsg());
    crom_model back;
    rc = crom_model_load(path, &back);
    CHECK_MSG(rc == 0, "read: %s", crom_errmsg());
    if (rc)
        return;
    int same = back.seed_v && !strcmp(back.model_id, seeded.model_id);
    for (int i = 0; same && i < n; i++)
        same = back.seed_v[i] == us[i];
    CHECK(same);
    crom_map map;
    CHECK(crom_map_init(&map, &back, NULL) == 0);
    double *x = malloc(sizeof(double) * n), q0[2] = {0, 0}, q[2] = {1.3, -0.7}, dpin = 0;
    CHECK(crom_map_eval(&map, q0, x, NULL) == 0);
    same = 1;
    for (int i = 0; i < n; i++)
        same &= x[i] == m->X[i] + us[i];
    CHECK(same);
    CHECK(crom_map_eval(&map, q, x, NULL) == 0);
    for (int i = 0; i < n; i++)
        if (b->fixed[i])
            dpin = fmax(dpin, fabs(x[i] - (m->X[i] + us[i])));
    CHECK(dpin == 0);
    crom_scenario sc;
    scenario_bar(&sc);
    crom_nlsim s;
    rc = crom_nlsim_init(&s, &map, &sc, 0, NULL, NULL, 1);
    CHECK_MSG(rc == 0, "nlsim: %s", crom_errmsg());
    if (!rc) {
        double K, Ee, W, Wref = 0;
        crom_nlsim_positions(&s, x, NULL);
        same = 1;
        for (int i = 0; i < n; i++)
            same &= x[i] == m->X[i] + us[i];
        CHECK(same);
        CHECK(crom_nlsim_constraint_residual(&s) == 0);
        CHECK(crom_nlsim_energies(&s, &K, &Ee, &W) == 0);
        for (int i = 0; i < n; i++)
            Wref -= s.sys.mass[i / 3] * sc.gravity[i % 3] * us[i];
        fprintf(stderr, "seeded map: starts at the seed (pins held there), potential of gravity %.6g J (direct %.6g J)\n",
                W, Wref);
        CHECK_REL(W, Wref, 1e-12);
        CHECK(K == 0);
        crom_nlsim_free(&s);
    }
    /* refining it (--init-model): training starts from its network (one
     * step at a vanishing rate leaves it), and another shape is refused */
    crom_datafree_problem P = {m, b->mat, {0, -9.81, 0}, b->fixed, NULL, NULL, NULL, 0, NULL, NULL, 0, NULL, NULL, 0, NULL, us, NULL, NULL};
    P.init = &net;
    crom_datafree_opts o;
    crom_datafree_defaults(&o, CROM_DATAFREE_ENERGY);
    o.rank = r;
    o.width = 16;
    o.depth = 2;
    o.steps = 1;
    o.lr = 1e-12;
    o.sigma = 0.05;
    crom_model ref;
    crom_dftrain_log log;
    rc = crom_datafree_train(&P, &o, &ref, &log);
    CHECK_MSG(rc == 0, "refine: %s", crom_errmsg());
    double pmax, dp = params_moved(&net, rc ? NULL : ref.mlp.params, &pmax);
    fprintf(stderr, "refined map: one step at rate 1e-12 moves its parameters by %.1e (largest %.2g)\n", dp, pmax);
    CHECK(!rc && dp <= 1e-9 * pmax && ref.seed_v && ref.seed_v[5] == us[5]);
    crom_model_free(&ref);
    crom_dftrain_log_free(&log);
    o.width = 17;
    CHECK(crom_datafree_train(&P, &o, &ref, &log) == CROM_EUSAGE && strstr(crom_errmsg(), "another shape"));
    crom_err_clear();
    crom_model_free(&ref);
    crom_dftrain_log_free(&log);
    free(x), free(us);
    crom_map_free(&map);
    crom_model_free(&back);
    crom_model_free(&plain);
    crom_model_free(&seeded);
    crom_nn_mlp_free(&net);
    remove(path);
}

/* Wang et al.: Neural Modes on the 3 lowest modes, 400 steps of 16 samples
 * in the box [-0.1, 0.1]^3 m. No latent dimension collapses (§4.4: the
 * smallest eigenvalue of r JᵀMJ / tr at 0 is above 0.8; measured 0.98, the
 * paper's collapsed ones are 0.0), y stays M-orthogonal to the modes
 * (within 1 % of the box; measured 1e-3) and is exactly 0 at the origin
 * (anchored), the samples of the box have less energy than the linear
 * modes at the same z (measured 284 J against 5508 J), and a run with no
 * load stays at rest. */
static void test_neuralmodes_subspace(bar_case *b)
{
    crom_datafree_problem P = {&b->mesh, b->mat, {0, 0, 0}, b->fixed, b->modes, b->freq, NULL, 0, NULL, NULL, 0, NULL, NULL, 0, NULL, NULL, NULL, NULL};
    crom_datafree_opts o;
    crom_datafree_defaults(&o, CROM_DATAFREE_NEURALMODES);
    o.rank = b->nmodes;
    o.steps = 400;
    o.batch = 16;
    o.width = 32;
    o.box = 0.1;
    o.box_scaled = 0; /* Wang et al.'s box: every mode in [-0.1, 0.1] */
    crom_dftrain_log log;
    crom_model nm;
    int rc = crom_datafree_train(&P, &o, &nm, &log);
    CHECK_MSG(rc == 0, "train: %s", crom_errmsg());
    if (rc)
        return;
    crom_map map, lin;
    crom_model lm;
    modes_model(b, &lm);
    CHECK(crom_map_init(&map, &nm, NULL) == 0);
    CHECK(crom_map_init(&lin, &lm, NULL) == 0);
    check_rest("neuralmodes map", &map);
    crom_metrics_opts mo;
    crom_metrics_defaults(&mo);
    mo.samples = 64;
    mo.dist = CROM_METRICS_BOX;
    mo.radius = 0.1;
    crom_metrics res, rl;
    double g[3] = {0, 0, 0};
    CHECK(crom_metrics_compute(&map, &b->sys, g, &mo, NULL, &res) == 0);
    CHECK(crom_metrics_compute(&lin, &b->sys, g, &mo, NULL, &rl) == 0);
    /* orthogonality and origin: |W^T M y / m| and |y(0)|_M / sqrt(m) relative to the box */
    int n = map.n, r = map.r;
    double *x = malloc(sizeof(double) * n), leak = 0, y0 = 0;
    crom_rng rng;
    crom_rng_seed(&rng, 9);
    for (int s = 0; s < 20; s++) {
        double q[8], c[8] = {0};
        for (int k = 0; k < r; k++)
            q[k] = 0.1 * (2 * crom_rng_uniform(&rng) - 1);
        crom_map_eval(&map, q, x, NULL);
        for (int i = 0; i < n; i++) {
            double lin2 = 0;
            for (int k = 0; k < r; k++)
                lin2 += b->modes[i * r + k] * q[k];
            double y = x[i] - b->mesh.X[i] - lin2;
            for (int k = 0; k < r; k++)
                c[k] += b->fem.mass[i / 3] * b->modes[i * r + k] * y / b->fem.total_mass;
        }
        for (int k = 0; k < r; k++)
            leak = fmax(leak, fabs(c[k]) / 0.1);
    }
    double q0[8] = {0};
    crom_map_eval(&map, q0, x, NULL);
    for (int i = 0; i < n; i++)
        y0 += b->fem.mass[i / 3] * (x[i] - b->mesh.X[i]) * (x[i] - b->mesh.X[i]);
    y0 = sqrt(y0 / b->fem.total_mass) / 0.1;
    fprintf(stderr, "neuralmodes (rank %d, 400 steps): Gram eigenvalues %.4f %.4f %.4f, correlation %.4f .. %.4f; "
                    "largest projection of y on a mode %.2e of the box, |y(0)| %.2e of the box; mean elastic "
                    "energy %.4g J (linear modes at the same z: %.4g J)\n",
            r, res.gram_eig[0], res.gram_eig[1], res.gram_eig[2], res.corr_eig[0], res.corr_eig[r - 1], leak, y0,
            res.energy_mean, rl.energy_mean);
    CHECK(res.gram_eig[0] > 0.8);
    CHECK_LT(leak, 0.01);
    CHECK_LT(y0, 0.01);
    CHECK_LT(res.energy_mean, rl.energy_mean);
    /* the linear modes themselves: exactly M-orthonormal, all eigenvalues 1 */
    CHECK(fabs(rl.gram_eig[0] - 1) < 1e-9 && fabs(rl.gram_eig[r - 1] - 1) < 1e-9);
    free(x);
    crom_metrics_free(&res);
    crom_metrics_free(&rl);
    crom_map_free(&map);
    crom_map_free(&lin);
    crom_model_free(&lm);
    crom_model_free(&nm);
    crom_dftrain_log_free(&log);
}

/* Run steps latent steps and measure the energy budget: the largest rise
 * of the total (kinetic + elastic + external) energy between steps, its
 * scale, the largest kinetic energy and constraint residual. Checks that
 * every step succeeds and the totals are finite. */
typedef struct {
    double worst, scale, tmax, cres;
} run_budget;

static run_budget run_steps(crom_nlsim *s, int steps)
{
    run_budget b = {-INFINITY, 0, 0, 0};
    double Eprev = NAN;
    int fin = 1;
    for (int k = 0; k <= steps; k++) {
        crom_rsim_stats st;
        if (k > 0 && crom_nlsim_step(s, &st)) {
            CHECK_MSG(0, "step %d: %s", k, crom_errmsg());
            break;
        }
        double K, Ee, W;
        CHECK(crom_nlsim_energies(s, &K, &Ee, &W) == 0);
        double T = K + Ee + W;
        fin &= isfinite(T);
        b.scale = fmax(b.scale, fabs(Ee) + fabs(W) + K);
        b.tmax = fmax(b.tmax, K);
        if (k > 0)
            b.worst = fmax(b.worst, T - Eprev);
        Eprev = T;
        b.cres = fmax(b.cres, crom_nlsim_constraint_residual(s));
    }
    CHECK(fin);
    return b;
}

static void scenario_bar(crom_scenario *sc);

/* The continuous field (--objective field): trained on the coarse bar by a
 * random cubature of half its tets per step, it is a subspace of lower
 * energy than the linear modes, with no collapsed dimension; laid on a
 * FINER mesh of the same bar, the same latent samples have nearly the same
 * energy (the field is continuous), the pins stay exactly at rest on the
 * training mesh, and latent dynamics on the finer mesh run, dissipate and
 * hold the clamp. */
/* Sampling along a run (problem.nvisit): with a visited point at three
 * times the box, every other sample is drawn near it, and the trained map
 * stores less elastic energy there than the same training on the box
 * alone, which extrapolates. */
static void test_neuralmodes_visit(bar_case *b)
{
    int r = b->nmodes;
    double visit[2 * 8] = {0};
    visit[0] = 0.3;       /* mode 1 at 3 times the box, */
    visit[r + 0] = 0.25;  /* and near it with mode 2 */
    visit[r + 1] = 0.05;
    crom_datafree_problem P = {&b->mesh, b->mat, {0, 0, 0}, b->fixed, b->modes, b->freq, NULL, 0, NULL, NULL, 0, NULL, NULL, 0, NULL, NULL, NULL, NULL};
    crom_datafree_opts o;
    crom_datafree_defaults(&o, CROM_DATAFREE_NEURALMODES);
    o.rank = r;
    o.steps = 400;
    o.batch = 16;
    o.width = 32;
    o.box = 0.1;
    o.box_scaled = 0;
    double E[2];
    for (int pass = 0; pass < 2; pass++) {
        P.nvisit = pass ? 2 : 0;
        P.visit_z = pass ? visit : NULL;
        crom_dftrain_log log;
        crom_model nm;
        int rc = crom_datafree_train(&P, &o, &nm, &log);
        CHECK_MSG(rc == 0, "train: %s", crom_errmsg());
        if (rc)
            return;
        crom_map map;
        CHECK(crom_map_init(&map, &nm, NULL) == 0);
        double *x = malloc(sizeof(double) * map.n);
        crom_map_eval(&map, visit, x, NULL);
        CHECK(crom_system_energy(&b->sys, x, &E[pass]) == 0);
        free(x);
        crom_map_free(&map);
        crom_model_free(&nm);
        crom_dftrain_log_free(&log);
    }
    fprintf(stderr, "neural modes at z1 = 0.3 (box 0.1): elastic energy %.4g J trained on the box, %.4g J sampled "
            "along the visited points\n", E[0], E[1]);
    CHECK(isfinite(E[0]) && isfinite(E[1]));
    CHECK_LT(E[1], E[0]);
}

static void test_field_subspace(bar_case *b)
{
    crom_datafree_problem P = {&b->mesh, b->mat, {0, -9.81, 0}, b->fixed, NULL, NULL, NULL, 0, NULL, NULL, 0, NULL, NULL, 0, NULL, NULL, NULL, NULL};
    crom_datafree_opts o;
    crom_datafree_defaults(&o, CROM_DATAFREE_FIELD);
    o.rank = 2;
    o.steps = 600;
    o.batch = 16;
    o.width = 32;
    o.field_width = 32;
    o.features = 8;
    o.tets = b->mesh.nt / 2;
    o.seed = 3;
    crom_model fm;
    crom_dftrain_log log;
    int rc = crom_datafree_train(&P, &o, &fm, &log);
    CHECK_MSG(rc == 0, "train: %s", crom_errmsg());
    if (rc)
        return;
    CHECK(!strcmp(fm.basis, "energy-field") && fm.field == CROM_MODEL_FIELD_CMAP && fm.rank == 2 &&
          log.steps == 600);
    CHECK(log.objective[log.nblocks - 1] < log.objective[0]);
    crom_mesh fine;
    make_bar(&fine, 0.07);
    crom_system ffem;
    CHECK(crom_system_init(&ffem, &fine, b->mat.E, b->mat.nu, b->mat.rho) == 0);
    crom_map map, lin, fmap;
    crom_model lm;
    modes_model(b, &lm);
    CHECK(crom_map_init(&map, &fm, NULL) == CROM_EUSAGE); /* a continuous field needs a mesh */
    CHECK(crom_map_init(&map, &fm, &b->mesh) == 0);
    CHECK(crom_map_init(&fmap, &fm, &fine) == 0);
    check_rest("continuous field on its training mesh", &map);
    check_rest("continuous field on a finer mesh", &fmap);
    CHECK(crom_map_init(&lin, &lm, NULL) == 0);
    crom_metrics_opts mo;
    crom_metrics_defaults(&mo);
    mo.samples = 64;
    mo.sigma = log.sigma;
    crom_metrics res, fres;
    double g[3] = {0, -9.81, 0};
    CHECK(crom_metrics_compute(&map, &b->sys, g, &mo, &lin, &res) == 0);
    CHECK(crom_metrics_compute(&fmap, &ffem, g, &mo, NULL, &fres) == 0);
    double rel = fabs(fres.energy_mean - res.energy_mean) / res.energy_mean;
    fprintf(stderr, "continuous field (rank 2, 8 features, 600 steps on %d of %d tets per step): mean elastic energy "
                    "%.4g J at RMS %.4g m on the training mesh (%d vertices), linear modes %.4g J (ratio %.3g); on "
                    "a finer mesh (%d vertices) %.4g J at RMS %.4g m (%.2f%% apart); isometry median %.3f; Gram "
                    "eigenvalues %.3f %.3f\n",
            o.tets, b->mesh.nt, res.energy_mean, res.rms_mean, b->mesh.nv, res.cmp_energy_mean,
            res.energy_mean / res.cmp_energy_mean, fine.nv, fres.energy_mean, fres.rms_mean, 100 * rel,
            res.iso_median, res.gram_eig[0], res.gram_eig[1]);
    CHECK_LT(res.energy_mean, 0.5 * res.cmp_energy_mean);
    CHECK_LT(rel, 0.1);
    CHECK(res.gram_eig[0] > 0.01 * res.gram_eig[1]);
    CHECK(res.iso_median > 0.7 && res.iso_median < 1.3);
    /* pinned vertices of the training mesh exactly at rest for any z */
    double q[2] = {1.7, -2.3}, *x = malloc(sizeof(double) * map.n), dmax = 0;
    double ecf = check_map_curvature(&map, q, 8); /* φ's outputs as features (not folded: p = 8) */
    fprintf(stderr, "continuous field: %d features, curvature vs FD %.2e\n", map.p, ecf);
    CHECK(map.p == 8);
    CHECK_LT(ecf, 1e-6);
    CHECK(crom_map_eval(&map, q, x, NULL) == 0);
    for (int i = 0; i < map.n; i++)
        if (b->fixed[i])
            dmax = fmax(dmax, fabs(x[i] - b->mesh.X[i]));
    CHECK(dmax == 0);
    free(x);
    /* latent dynamics on the finer mesh, clamped (its own clamp region) */
    crom_scenario sc;
    scenario_bar(&sc);
    strcpy(sc.pins[sc.npins++], "x<-0.49");
    crom_nlsim s;
    CHECK(crom_nlsim_init(&s, &fmap, &sc, 0, NULL, NULL, 1) == 0);
    run_budget rb = run_steps(&s, 40);
    fprintf(stderr, "continuous field on the finer mesh, 40 steps under gravity: largest rise of the total energy %.3g "
                    "J (scale %.4g J), largest kinetic energy %.4g J, largest clamp displacement %.3g m\n",
            rb.worst, rb.scale, rb.tmax, rb.cres);
    CHECK(rb.tmax > 1e-3 * rb.scale);
    CHECK_LT(rb.worst, 1e-6 * rb.scale);
    CHECK_LT(rb.cres, 0.01 * fres.rms_mean);
    crom_nlsim_free(&s);
    /* refining it (crom-fitfield --objective field --init-model): training
     * starts from both networks (one step at a vanishing rate leaves them),
     * W alone or another shape is refused */
    crom_datafree_problem P2 = P;
    P2.init = &fm.latent;
    P2.init_field = &fm.mlp;
    crom_datafree_opts o2 = o;
    o2.steps = 1;
    o2.lr = 1e-12;
    crom_model rm;
    crom_dftrain_log log2;
    rc = crom_datafree_train(&P2, &o2, &rm, &log2);
    CHECK_MSG(rc == 0, "refine: %s", crom_errmsg());
    double wmax, pmax, dw = params_moved(&fm.mlp, rc ? NULL : rm.mlp.params, &wmax);
    double dphi = params_moved(&fm.latent, rc ? NULL : rm.latent.params, &pmax);
    fprintf(stderr, "refined continuous field: one step at rate 1e-12 moves W by %.1e (largest %.2g), phi by %.1e "
            "(largest %.2g)\n", dw, wmax, dphi, pmax);
    CHECK(!rc && dw <= 1e-9 * wmax && dphi <= 1e-9 * pmax);
    CHECK(!rc && rm.mlp.shift[0] == fm.mlp.shift[0] && rm.mlp.scale[2] == fm.mlp.scale[2]);
    crom_model_free(&rm);
    crom_dftrain_log_free(&log2);
    o2.field_width = 33;
    CHECK(crom_datafree_train(&P2, &o2, &rm, &log2) == CROM_EUSAGE && strstr(crom_errmsg(), "another shape"));
    crom_err_clear();
    crom_dftrain_log_free(&log2);
    o2.field_width = o.field_width;
    P2.init_field = NULL;
    CHECK(crom_datafree_train(&P2, &o2, &rm, &log2) == CROM_EUSAGE && strstr(crom_errmsg(), "needs its feature field"));
    crom_err_clear();
    crom_dftrain_log_free(&log2);
    crom_metrics_free(&res);
    crom_metrics_free(&fres);
    crom_map_free(&map);
    crom_map_free(&fmap);
    crom_map_free(&lin);
    crom_model_free(&lm);
    crom_model_free(&fm);
    crom_system_free(&ffem);
    crom_mesh_free(&fine);
    crom_dftrain_log_free(&log);
}

/* A continuous field over skinning eigenmodes (skin-field): φ trained
 * alone over the orthonormal skinning basis of 4 handles. The model is
 * nonlinear, refuses crom_model_eval, its id covers φ; its map matches the
 * eigen basis times φ(q) − φ(0), has the Jacobian of differences, holds the
 * pinned vertices to round-off and rests exactly on its mesh and a finer one;
 * its samples have less energy than the two lowest linear modes'. */
static void test_skin_field(bar_case *b)
{
    crom_datafree_problem P = {&b->mesh, b->mat, {0, -9.81, 0}, b->fixed, NULL, NULL, NULL, 0, NULL, NULL, 0, NULL, NULL, 0, NULL, NULL, NULL, NULL};
    crom_model sm;
    int rc = crom_dfskin_eigen(&b->mesh, &b->mat, NULL, b->fixed, 4, &sm, NULL);
    CHECK_MSG(rc == 0, "eigen: %s", crom_errmsg());
    if (rc)
        return;
    double *mass = malloc(sizeof(double) * b->mesh.nv);
    for (int v = 0; v < b->mesh.nv; v++)
        mass[v] = b->fem.mass[v];
    CHECK(crom_skin_orthonormalize(&sm, (size_t)b->mesh.nv, b->mesh.X, mass, 1e-6) == 0);
    free(mass);
    int p = sm.rank, nv = b->mesh.nv;
    double *basis = malloc(sizeof(double) * 3 * (size_t)nv * p);
    CHECK(crom_skin_eval(&sm, (size_t)nv, b->mesh.X, basis, NULL) == 0);
    crom_datafree_opts o;
    crom_datafree_defaults(&o, CROM_DATAFREE_FIELD);
    o.rank = 2;
    o.steps = 400;
    o.batch = 16;
    o.width = 32;
    o.tets = b->mesh.nt / 2;
    o.seed = 5;
    crom_nn_mlp phi;
    crom_dftrain_log log;
    rc = crom_dffield_train_latent(&P, &o, basis, p, &phi, &log);
    CHECK_MSG(rc == 0, "train: %s", crom_errmsg());
    if (rc) {
        free(basis);
        crom_model_free(&sm);
        return;
    }
    CHECK(log.steps == 400 && log.objective[log.nblocks - 1] < log.objective[0]);
    CHECK(crom_model_skin_field(&sm, &phi) == 0);
    CHECK(crom_model_skin_field(&sm, &phi) == CROM_EUSAGE); /* not a linear skinning model any more */
    CHECK(!strcmp(sm.basis, "skin-field") && sm.rank == 2 && crom_model_is_nonlinear(&sm));
    double Wx[1000];
    CHECK(crom_model_eval(&sm, 1, b->mesh.X, Wx, NULL) == CROM_EDATA);
    char id0[17], id1[17];
    crom_model_id(&sm, id0);
    sm.latent.params[3] += 1e-3f;
    crom_model_id(&sm, id1);
    CHECK(strcmp(id0, id1) != 0);
    sm.latent.params[3] -= 1e-3f;
    crom_map map, fmap;
    CHECK(crom_map_init(&map, &sm, NULL) == 0); /* eigen weights: their own mesh */
    /* over φ's last hidden layer (width 32) when that is narrower than the basis */
    CHECK(map.p_model == p && map.p == (p > 33 ? 33 : p));
    /* x(q) = X + basis (φ(q) − φ(0)) with φ from the float network */
    double q[2] = {0.8, -1.1}, *x = malloc(sizeof(double) * map.n), *J = malloc(sizeof(double) * map.n * 2);
    double *Jfd = malloc(sizeof(double) * map.n * 2);
    CHECK(crom_map_eval(&map, q, x, J) == 0);
    crom_nn_ws ws;
    CHECK(crom_nn_ws_init(&ws, &phi, 2, 1) == 0);
    float qf[4] = {0.8f, -1.1f, 0, 0}, *a = malloc(sizeof(float) * 2 * p);
    CHECK(crom_nn_mlp_forward(&phi, &ws, 2, qf, a) == 0);
    double dn = 0, nn = 0, pin = 0;
    for (int i = 0; i < map.n; i++) {
        double u = 0;
        for (int j = 0; j < p; j++)
            u += basis[(size_t)i * p + j] * ((double)a[j] - a[p + j]);
        dn += (x[i] - b->mesh.X[i] - u) * (x[i] - b->mesh.X[i] - u);
        nn += u * u;
        if (b->fixed[i])
            pin = fmax(pin, fabs(x[i] - b->mesh.X[i]));
    }
    map_case mc = {&map, NULL};
    check_fd_jacobian(map_at, &mc, q, 2, map.n, 1e-6, Jfd);
    double ej = check_relerr(J, Jfd, map.n * 2, 1e-12);
    double ecs = check_map_curvature(&map, q, 9); /* over φ's last hidden layer */
    fprintf(stderr, "skin-field: %d features, curvature vs FD %.2e\n", map.p, ecs);
    CHECK_LT(ecs, 1e-6);
    crom_mesh fine;
    make_bar(&fine, 0.07);
    CHECK(crom_map_init(&fmap, &sm, &fine) == 0);
    check_rest("skin-field on its training mesh", &map);
    check_rest("skin-field on a finer mesh", &fmap);
    crom_map lin;
    crom_model lm;
    modes_model(b, &lm);
    CHECK(crom_map_init(&lin, &lm, NULL) == 0);
    crom_metrics_opts mo;
    crom_metrics_defaults(&mo);
    mo.samples = 64;
    mo.sigma = log.sigma;
    crom_metrics res;
    double g[3] = {0, -9.81, 0};
    CHECK(crom_metrics_compute(&map, &b->sys, g, &mo, &lin, &res) == 0);
    fprintf(stderr, "skin-field (4 eigen handles, %d features, rank 2, 400 steps): positions vs float phi %.2e, "
                    "Jacobian vs FD %.2e, largest pinned displacement %.3g m; mean elastic energy %.4g J at RMS "
                    "%.4g m, linear modes %.4g J; Gram eigenvalues %.3f %.3f\n",
            p, sqrt(dn / nn), ej, pin, res.energy_mean, res.rms_mean, res.cmp_energy_mean, res.gram_eig[0],
            res.gram_eig[1]);
    CHECK_LT(sqrt(dn / nn), 1e-5);
    CHECK_LT(ej, 1e-7);
    CHECK_LT(pin, 1e-14); /* (the eigen weights are 0 there, interpolated to round-off) */
    CHECK_LT(res.energy_mean, res.cmp_energy_mean);
    CHECK(res.gram_eig[0] > 0.01 * res.gram_eig[1]);
    crom_metrics_free(&res);
    crom_map_free(&lin);
    crom_model_free(&lm);
    /* refining φ over the same basis (crom-fitfield --objective field
     * --init-model): training starts from it (one step at a vanishing
     * rate leaves it), another shape is refused, and along a run its
     * potential energy at the visited latent goes down */
    crom_datafree_problem P2 = P;
    P2.init = &phi;
    crom_datafree_opts o2 = o;
    o2.steps = 1;
    o2.lr = 1e-12;
    crom_nn_mlp phi2;
    crom_dftrain_log log2;
    rc = crom_dffield_train_latent(&P2, &o2, basis, p, &phi2, &log2);
    CHECK_MSG(rc == 0, "refine: %s", crom_errmsg());
    double pmax, dp = params_moved(&phi, rc ? NULL : phi2.params, &pmax);
    CHECK(!rc && dp <= 1e-9 * pmax);
    crom_nn_mlp_free(&phi2);
    crom_dftrain_log_free(&log2);
    o2.width = 33;
    CHECK(crom_dffield_train_latent(&P2, &o2, basis, p, &phi2, &log2) == CROM_EUSAGE &&
          strstr(crom_errmsg(), "another shape"));
    crom_err_clear();
    crom_dftrain_log_free(&log2);
    double zv[2] = {2.5, -2.0}, Epot[2] = {0, 0};
    P2.nvisit = 1;
    P2.visit_z = zv;
    o2 = o;
    o2.steps = 300;
    rc = crom_dffield_train_latent(&P2, &o2, basis, p, &phi2, &log2);
    CHECK_MSG(rc == 0, "refine along a run: %s", crom_errmsg());
    for (int k = 0; k < 2 && !rc; k++) { /* E + the potential of gravity at x(zv), before and after */
        crom_model mk;
        crom_map mp;
        CHECK(crom_dfskin_eigen(&b->mesh, &b->mat, NULL, b->fixed, 4, &mk, NULL) == 0);
        double *mv = malloc(sizeof(double) * b->mesh.nv);
        for (int v = 0; v < b->mesh.nv; v++)
            mv[v] = b->fem.mass[v];
        CHECK(crom_skin_orthonormalize(&mk, (size_t)b->mesh.nv, b->mesh.X, mv, 1e-6) == 0);
        CHECK(crom_model_skin_field(&mk, k ? &phi2 : &phi) == 0 && crom_map_init(&mp, &mk, NULL) == 0);
        double *xv = malloc(sizeof(double) * mp.n), Ee = 0, Wg = 0;
        CHECK(crom_map_eval(&mp, zv, xv, NULL) == 0 && crom_fem_energy(&b->fem, xv, &Ee) == 0);
        for (int i = 0; i < mp.n; i++)
            Wg += mv[i / 3] * 9.81 * (i % 3 == 1) * (xv[i] - b->mesh.X[i]);
        Epot[k] = Ee + Wg;
        free(xv);
        free(mv);
        crom_map_free(&mp);
        crom_model_free(&mk);
    }
    fprintf(stderr, "skin-field refined 300 steps along a run through z = (2.5, -2): potential energy there %.4g J "
            "(before %.4g J)\n", Epot[1], Epot[0]);
    CHECK(!rc && Epot[1] < Epot[0]);
    crom_nn_mlp_free(&phi2);
    crom_dftrain_log_free(&log2);
    crom_map_free(&map);
    crom_map_free(&fmap);
    crom_mesh_free(&fine);
    crom_nn_ws_free(&ws);
    crom_nn_mlp_free(&phi);
    crom_dftrain_log_free(&log);
    crom_model_free(&sm);
    free(basis);
    free(x);
    free(J);
    free(Jfd);
    free(a);
}

/* ------------------------------------------------------ latent dynamics */

static void scenario_bar(crom_scenario *sc)
{
    crom_scenario_defaults(sc);
    sc->youngs = 1e6;
    sc->poisson = 0.3;
    sc->dt = 0.01;
    sc->tol = 1e-9;
}

static crom_nlsim *g_nl;
static int g_nlproject;
static double nl_obj(const double *q, void *ctx)
{
    (void)ctx;
    double E;
    crom_nlsim_objective(g_nl, q, &E, NULL, NULL, g_nlproject);
    return E;
}
static void nl_grad(const double *q, void *ctx, double *g)
{
    (void)ctx;
    double E;
    crom_nlsim_objective(g_nl, q, &E, g, NULL, g_nlproject);
}


/* The reduced objective of the energy map: gradient against differences,
 * with every term (inertia, damping, gravity, a force, a pin penalty on a
 * region the map moves, a frictional plane the bar touches, a rod with a
 * moving rest length), and the
 * Newton matrix (Gauss–Newton plus the map's curvature) against differences
 * of the gradient; then a free run: finite, and its total energy never
 * increases (implicit Euler dissipates). */
static void test_dynamics(bar_case *b)
{
    if (!g_energy_model.rank)
        return;
    crom_map map;
    CHECK(crom_map_init(&map, &g_energy_model, &b->mesh) == 0);
    int r = map.r;
    crom_scenario sc;
    scenario_bar(&sc);
    sc.damping = 2;
    strcpy(sc.pins[sc.npins++], "x>0.45");
    snprintf(sc.force[0].ref, sizeof sc.force[0].ref, "y>0.09");
    sc.force[0].v[2] = 30;
    sc.force[0].t0 = 0;
    sc.force[0].t1 = INFINITY;
    sc.nforce = 1;
    sc.plane[0].n[1] = 1;
    sc.plane[0].d = -0.2;
    sc.plane[0].mu = 0.3;
    sc.nplanes = 1;
    /* a rod pulling the free end's top toward the middle, its rest length moving */
    CHECK(crom_rod_parse("--rod", "x<-0.4/x>0.2&y>0.09=500,0.4,0.05,0.5", &sc.rod[0]) == 0);
    sc.nrod = 1;
    crom_nlsim s;
    double q0[2] = {0.4, -0.3}, qd0[2] = {2, 1};
    int rc = crom_nlsim_init(&s, &map, &sc, 1e5, q0, qd0, 1);
    CHECK_MSG(rc == 0, "nlsim: %s", crom_errmsg());
    crom_nlsim_begin_step(&s);
    g_nl = &s;
    for (g_nlproject = 0; g_nlproject <= 1; g_nlproject++) {
        double q[2] = {0.45, -0.2}, g[2], H[4], gfd[2], E;
        CHECK(crom_nlsim_objective(&s, q, &E, g, H, g_nlproject) == 0);
        check_fd_gradient(nl_obj, NULL, q, r, 1e-6, gfd);
        double eg = check_relerr(g, gfd, r, 1e-9);
        fprintf(stderr, "energy map: reduced gradient vs FD %.2e (project %d); Gauss-Newton matrix [%.4g %.4g; %.4g "
                        "%.4g]\n", eg, g_nlproject, H[0], H[1], H[2], H[3]);
        CHECK_LT(eg, 1e-6);
        CHECK(H[0] > 0 && H[0] * H[3] - H[1] * H[2] > 0 && fabs(H[1] - H[2]) <= 1e-12 * H[0]);
        if (!g_nlproject) { /* Newton: Gauss-Newton plus the map's curvature is the exact Hessian */
            double C[4], Hn[4], Hfd[4];
            CHECK(crom_nlsim_curvature(&s, q, C) == 0);
            for (int i = 0; i < 4; i++)
                Hn[i] = H[i] + C[i];
            check_fd_jacobian(nl_grad, NULL, q, r, r, 1e-6, Hfd);
            double eh = check_relerr(Hn, Hfd, 4, 1e-9), egn = check_relerr(H, Hfd, 4, 1e-9);
            fprintf(stderr, "energy map: Gauss-Newton + curvature vs FD Hessian %.2e (Gauss-Newton alone %.2e)\n", eh,
                    egn);
            CHECK_LT(eh, 1e-5);
        }
    }
    /* the objective in feature space (a quadratic in the features plus the
     * elastic tets) against the incremental potential summed over every
     * vertex and tet directly, at a point away from the predictor */
    {
        int n = map.n;
        double q[2] = {0.3, -0.45}, E, h = sc.dt, cin = 1 / (h * h), cd = sc.damping / h;
        double *x = malloc(sizeof(double) * (size_t)n), *xn = malloc(sizeof(double) * (size_t)n);
        double *vn = malloc(sizeof(double) * (size_t)n), *fext = malloc(sizeof(double) * (size_t)n);
        CHECK(x && crom_map_eval(&map, q, x, NULL) == 0);
        crom_nlsim_positions(&s, xn, vn);
        for (int i = 0; i < n; i++) /* gravity, and the force spread by mass over its region */
            fext[i] = s.sys.mass[i / 3] * sc.gravity[i % 3];
        for (int k = 0; k < s.nforce; k++) {
            double F[3];
            crom_bc_force(s.force[k].bc, s.t + h, F);
            for (int j = 0; j < s.force[k].n; j++) {
                int v = s.force[k].idx[j];
                for (int c = 0; c < 3; c++)
                    fext[3 * v + c] += F[c] * s.sys.mass[v] / s.force[k].mass;
            }
        }
        sc.nplanes = 0; /* contact is checked by differences above */
        CHECK(crom_nlsim_objective(&s, q, &E, NULL, NULL, 0) == 0);
        double Eref = 0, Eel;
        crom_fem_opts fo = {0, 0, NULL, 1};
        CHECK(crom_fem_assemble(&s.sys.fem, x, &fo, &Eel, NULL, NULL) == 0);
        Eref += Eel;
        for (int i = 0; i < n; i++) {
            double mi = s.sys.mass[i / 3], a = x[i] - xn[i] - h * vn[i], bb = x[i] - xn[i];
            Eref += 0.5 * mi * (cin * a * a + cd * bb * bb) - fext[i] * bb;
        }
        crom_rod_set R; /* the rod */
        CHECK(crom_rod_set_init(&R, 1, sc.rod, &map.mesh, s.sys.mass) == 0);
        Eref += crom_rod_set_eval(&R, sc.rod, s.t + h, x, NULL, NULL, 0);
        CHECK(R.rest[0] > 0.5 && fabs(R.rest[0] - s.rod_rest[0]) < 1e-14);
        crom_rod_set_free(&R);
        for (int j = 0; j < s.bc[0].n; j++) { /* the pin */
            int v = s.bc[0].idx[j];
            for (int c = 0; c < 3; c++) {
                double e = x[3 * v + c] - map.mesh.X[3 * v + c];
                Eref += 0.5 * s.kappa * s.sys.mass[v] * e * e;
            }
        }
        fprintf(stderr, "energy map: objective in feature space %.12g J, summed over vertices and tets %.12g J\n", E,
                Eref);
        CHECK_LT(fabs(E - Eref), 1e-10 * (fabs(Eref) + 1));
        sc.nplanes = 1;
        free(x);
        free(xn);
        free(vn);
        free(fext);
    }
    /* the same objective over a cubature (every other tet, weight 2):
     * gradient and Newton matrix against differences again, and the
     * elastic energy is that weighted sum */
    {
        int k = (s.sys.fem.nt + 1) / 2;
        int *elem = malloc(sizeof(int) * (size_t)k);
        double *w = malloc(sizeof(double) * (size_t)k);
        for (int j = 0; j < k; j++) {
            elem[j] = 2 * j;
            w[j] = 2;
        }
        CHECK(crom_nlsim_use_cubature(&s, k, elem, w) == 0);
        int bad[1] = {s.sys.fem.nt};
        double wbad[1] = {-1};
        CHECK(crom_nlsim_use_cubature(&s, 1, bad, w) == CROM_EDATA);
        CHECK(crom_nlsim_use_cubature(&s, 1, elem, wbad) == CROM_EDATA);
        double q[2] = {0.45, -0.2}, g[2], H[4], C[4], Hn[4], gfd[2], Hfd[4], E;
        g_nlproject = 0;
        CHECK(crom_nlsim_objective(&s, q, &E, g, H, 0) == 0);
        CHECK(crom_nlsim_curvature(&s, q, C) == 0);
        for (int i = 0; i < 4; i++)
            Hn[i] = H[i] + C[i];
        check_fd_gradient(nl_obj, NULL, q, r, 1e-6, gfd);
        check_fd_jacobian(nl_grad, NULL, q, r, r, 1e-6, Hfd);
        double eg = check_relerr(g, gfd, r, 1e-9), eh = check_relerr(Hn, Hfd, 4, 1e-9);
        fprintf(stderr, "energy map over a cubature of %d of %d tets: gradient vs FD %.2e, Newton matrix vs FD %.2e\n",
                k, s.sys.fem.nt, eg, eh);
        CHECK_LT(eg, 1e-6);
        CHECK_LT(eh, 1e-5);
        free(elem);
        free(w);
    }
    crom_nlsim_free(&s);
    /* a free run under gravity from rest: finite, total energy non-increasing */
    crom_scenario fr;
    scenario_bar(&fr);
    CHECK(crom_nlsim_init(&s, &map, &fr, 0, NULL, NULL, 1) == 0);
    /* it starts at q = 0, exactly at rest (the map is anchored there) */
    {
        double *x = malloc(sizeof(double) * (size_t)map.n), dmax = 0;
        CHECK(x && s.q[0] == 0 && s.q[1] == 0 && crom_map_eval(&map, s.q, x, NULL) == 0);
        for (int i = 0; x && i < map.n; i++)
            dmax = fmax(dmax, fabs(x[i] - map.mesh.X[i]));
        CHECK(dmax == 0);
        free(x);
    }
    int steps = 60;
    run_budget rb = run_steps(&s, steps);
    fprintf(stderr, "energy map, free run of %d steps under gravity: largest rise of the total energy %.3g J (energy "
                    "scale %.4g J, largest kinetic energy %.4g J)\n", steps, rb.worst, rb.scale, rb.tmax);
    CHECK(rb.tmax > 1e-3 * rb.scale); /* it moved */
    CHECK_LT(rb.worst, 1e-6 * rb.scale);
    crom_nlsim_free(&s);
    crom_map_free(&map);
}

/* A shell's energy map (the map integrates the sheet's membrane triangles
 * and hinges, lib/phys/system.h): trained briefly on a small sheet clamped
 * along one edge under gravity, its reduced objective (inertia, damping,
 * gravity, a pin penalty on a region the map moves, a frictional sphere the
 * sheet touches) has the gradient and Newton matrix of its differences and
 * equals the incremental potential summed over the vertices and elements
 * directly; a free run from rest moves and dissipates. */
static void test_shell_map(void)
{
    crom_meshgen_opts go;
    crom_meshgen_defaults(&go, CROM_MESHGEN_SHEET);
    go.dims[0] = go.dims[1] = 0.6;
    go.size = 0.1;
    go.thickness = 0.01;
    crom_mesh mesh;
    CHECK(crom_meshgen_sheet(&go, &mesh) == 0);
    const char *clamp[1] = {"y<-0.2"};
    unsigned char *fixed = NULL;
    int npinned = 0;
    CHECK(crom_modes_pins(&mesh, 1, clamp, &fixed, &npinned) == 0 && npinned > 0);
    crom_material mat;
    crom_material_init(&mat, 1e7, 0.3, 500);
    crom_datafree_problem P = {&mesh, mat, {0, 0, -9.81}, fixed, NULL, NULL, NULL, 0, NULL, NULL, 0, NULL, NULL, 0, NULL, NULL, NULL, NULL};
    crom_datafree_opts o;
    crom_datafree_defaults(&o, CROM_DATAFREE_ENERGY);
    o.rank = 2;
    o.steps = 200;
    o.width = 16;
    o.seed = 5;
    crom_model model;
    crom_dftrain_log log;
    int rc = crom_datafree_train(&P, &o, &model, &log);
    CHECK_MSG(rc == 0, "shell map: %s", crom_errmsg());
    o.tets = 16;
    crom_model bad;
    crom_dftrain_log blog;
    memset(&blog, 0, sizeof blog);
    CHECK(crom_datafree_train(&P, &o, &bad, &blog) == CROM_EUSAGE); /* no random tets on a shell */
    crom_dftrain_log_free(&blog);
    crom_map map;
    CHECK(rc == 0 && crom_map_init(&map, &model, NULL) == 0);
    CHECK(crom_mesh_is_surface(&map.mesh) && map.mesh.ntri == mesh.ntri);
    int r = map.r, n = map.n;
    crom_scenario sc;
    scenario_bar(&sc);
    sc.youngs = 1e7;
    sc.density = 500;
    sc.damping = 2;
    sc.gravity[0] = sc.gravity[1] = 0;
    sc.gravity[2] = -9.81;
    strcpy(sc.pins[sc.npins++], "x>0.25");
    double q[2] = {0.6, -0.4}, *x = malloc(sizeof(double) * (size_t)n);
    CHECK(x && crom_map_eval(&map, q, x, NULL) == 0);
    int vlow = 0; /* a sphere of radius 0.1 under the lowest vertex at q, 5 mm into it */
    for (int v = 0; v < map.nv; v++)
        if (x[3 * v + 2] < x[3 * vlow + 2])
            vlow = v;
    sc.plane[0].sphere = 1;
    sc.plane[0].r = 0.1;
    sc.plane[0].mu = 0.3;
    for (int c = 0; c < 3; c++)
        sc.plane[0].c[c] = x[3 * vlow + c] - (c == 2 ? 0.095 : 0);
    sc.nplanes = 1;
    crom_nlsim s;
    double q0[2] = {0.5, -0.3}, qd0[2] = {1, 0.5};
    rc = crom_nlsim_init(&s, &map, &sc, 1e5, q0, qd0, 1);
    CHECK_MSG(rc == 0, "shell nlsim: %s", crom_errmsg());
    CHECK(s.ne == s.sys.sh.nt + s.sys.sh.nh && s.nsurf == map.nv);
    crom_nlsim_begin_step(&s);
    g_nl = &s;
    for (g_nlproject = 0; g_nlproject <= 1; g_nlproject++) {
        double g[2], H[4], gfd[2], E;
        CHECK(crom_nlsim_objective(&s, q, &E, g, H, g_nlproject) == 0);
        check_fd_gradient(nl_obj, NULL, q, r, 1e-6, gfd);
        double eg = check_relerr(g, gfd, r, 1e-9);
        CHECK_LT(eg, 1e-6);
        CHECK(H[0] > 0 && H[0] * H[3] - H[1] * H[2] > 0 && fabs(H[1] - H[2]) <= 1e-12 * H[0]);
        double C[4], Hn[4], Hfd[4], eh = 0;
        if (!g_nlproject) { /* the sphere's Hessian is Gauss-Newton (contact.h): checked without it */
            sc.nplanes = 0;
            CHECK(crom_nlsim_objective(&s, q, &E, g, H, 0) == 0);
            CHECK(crom_nlsim_curvature(&s, q, C) == 0);
            for (int i = 0; i < 4; i++)
                Hn[i] = H[i] + C[i];
            check_fd_jacobian(nl_grad, NULL, q, r, r, 1e-6, Hfd);
            eh = check_relerr(Hn, Hfd, 4, 1e-9);
            CHECK_LT(eh, 1e-5);
            sc.nplanes = 1;
        }
        fprintf(stderr, "shell energy map (%d vertices, %d triangles, %d hinges): reduced gradient vs FD %.2e "
                        "(project %d)", map.nv, s.sys.sh.nt, s.sys.sh.nh, eg, g_nlproject);
        if (!g_nlproject)
            fprintf(stderr, ", Gauss-Newton + curvature vs FD Hessian %.2e (no contact)", eh);
        fputc('\n', stderr);
    }
    { /* the objective against the incremental potential summed directly (no contact) */
        double E, h = sc.dt, cin = 1 / (h * h), cd = sc.damping / h, Eel, Eref = 0;
        double *xn = malloc(sizeof(double) * (size_t)n), *vn = malloc(sizeof(double) * (size_t)n);
        crom_nlsim_positions(&s, xn, vn);
        sc.nplanes = 0;
        CHECK(crom_nlsim_objective(&s, q, &E, NULL, NULL, 0) == 0);
        CHECK(crom_system_energy(&s.sys, x, &Eel) == 0);
        Eref += Eel;
        for (int i = 0; i < n; i++) {
            double mi = s.sys.mass[i / 3], a = x[i] - xn[i] - h * vn[i], bb = x[i] - xn[i];
            Eref += 0.5 * mi * (cin * a * a + cd * bb * bb) - mi * sc.gravity[i % 3] * bb;
        }
        for (int j = 0; j < s.bc[0].n; j++)
            for (int c = 0; c < 3; c++) {
                int v = s.bc[0].idx[j];
                double e = x[3 * v + c] - map.mesh.X[3 * v + c];
                Eref += 0.5 * s.kappa * s.sys.mass[v] * e * e;
            }
        fprintf(stderr, "shell energy map: objective in feature space %.12g J, summed over vertices and elements "
                        "%.12g J\n", E, Eref);
        CHECK_LT(fabs(E - Eref), 1e-10 * (fabs(Eref) + 1));
        sc.nplanes = 1;
        free(xn);
        free(vn);
    }
    crom_nlsim_free(&s);
    crom_scenario fr;
    scenario_bar(&fr);
    fr.youngs = 1e7;
    fr.density = 500;
    fr.gravity[0] = fr.gravity[1] = 0;
    fr.gravity[2] = -9.81;
    CHECK(crom_nlsim_init(&s, &map, &fr, 0, NULL, NULL, 1) == 0);
    run_budget rb = run_steps(&s, 40);
    fprintf(stderr, "shell energy map, free run of 40 steps under gravity: largest rise of the total energy %.3g J "
                    "(scale %.4g J, largest kinetic energy %.4g J)\n", rb.worst, rb.scale, rb.tmax);
    CHECK(rb.tmax > 1e-3 * rb.scale);
    CHECK_LT(rb.worst, 1e-6 * rb.scale);
    crom_nlsim_free(&s);
    crom_map_free(&map);
    crom_model_free(&model);
    crom_dftrain_log_free(&log);
    free(x);
    free(fixed);
    crom_mesh_free(&mesh);
}

/* A rigid frame over a map (crom_map_add_frame: x = R(θ) y(q') + t), on
 * the modes of the clamped bar (a linear map) and on the trained energy
 * map: the Jacobian and the features' curvature against differences; x is
 * y moved rigidly (every distance kept); x(0) = x0 bit for bit. Then the
 * bar, no longer clamped, in its modes plus the frame: it falls under
 * gravity with its centre of mass exactly on implicit Euler's free fall
 * (the elastic forces are internal and t is in the subspace), and an
 * initial spin turns it about z by ω t. */
static void test_frame(bar_case *b)
{
    crom_model lm;
    modes_model(b, &lm);
    const crom_model *models[2] = {&lm, &g_energy_model};
    for (int mi = 0; mi < 2; mi++) {
        if (!models[mi]->rank)
            continue;
        crom_map map;
        int rc = crom_map_init(&map, models[mi], &b->mesh);
        CHECK_MSG(rc == 0, "map: %s", crom_errmsg());
        if (rc)
            continue;
        int ri = map.r;
        CHECK(crom_map_add_frame(&map) == 0 && map.r == ri + 6 && map.inner);
        CHECK(crom_map_add_frame(&map) == CROM_EUSAGE);
        int r = map.r, n = map.n;
        double q[16] = {0}, q0[16] = {0};
        for (int k = 0; k < ri; k++)
            q[k] = 0.2 * (k + 1) * (k % 2 ? -1 : 1);
        q[ri] = 0.3, q[ri + 1] = -0.4, q[ri + 2] = 0.7, q[ri + 3] = 0.1, q[ri + 4] = -0.2, q[ri + 5] = 0.05;
        double *x = malloc(sizeof(double) * n), *y = malloc(sizeof(double) * n);
        double *J = malloc(sizeof(double) * n * r), *Jfd = malloc(sizeof(double) * n * r);
        CHECK(crom_map_eval(&map, q, x, J) == 0 && crom_map_eval(map.inner, q, y, NULL) == 0);
        map_case mc = {&map, NULL};
        check_fd_jacobian(map_at, &mc, q, r, n, 1e-6, Jfd);
        double ej = check_relerr(J, Jfd, n * r, 1e-12), ec = check_map_curvature(&map, q, 17), dist = 0, moved = 0;
        for (int i = 0; i < map.nv; i += 7) /* distances between vertices kept, the body moved */
            for (int j = i + 3; j < map.nv; j += 11) {
                double dx = 0, dy = 0;
                for (int c = 0; c < 3; c++) {
                    dx += (x[3 * i + c] - x[3 * j + c]) * (x[3 * i + c] - x[3 * j + c]);
                    dy += (y[3 * i + c] - y[3 * j + c]) * (y[3 * i + c] - y[3 * j + c]);
                }
                dist = fmax(dist, fabs(sqrt(dx) - sqrt(dy)));
            }
        for (int i = 0; i < n; i++)
            moved = fmax(moved, fabs(x[i] - y[i]));
        CHECK(crom_map_eval(&map, q0, x, NULL) == 0);
        int rest = 1;
        for (int i = 0; i < n; i++)
            rest &= x[i] == map.x0[i];
        fprintf(stderr, "%s map in a rigid frame: Jacobian vs FD %.2e, curvature vs FD %.2e, distances kept to "
                "%.2e m (moved %.3g m), x(0) = x0 %s\n", mi ? "energy" : "modes", ej, ec, dist, moved,
                rest ? "exactly" : "NOT");
        CHECK_LT(ej, 1e-7);
        CHECK_LT(ec, 1e-6);
        CHECK_LT(dist, 1e-12);
        CHECK(moved > 0.1 && rest);
        if (mi == 0) { /* the free bar falling and spinning in its modes plus the frame */
            for (int spin = 0; spin < 2; spin++) {
                crom_scenario sc;
                scenario_bar(&sc);
                sc.tol = 1e-11;
                if (spin) {
                    sc.gravity[1] = 0;
                    sc.spin[2] = 2;
                }
                crom_nlsim s;
                rc = crom_nlsim_init(&s, &map, &sc, 0, NULL, NULL, 1);
                CHECK_MSG(rc == 0, "frame run: %s", crom_errmsg());
                if (rc)
                    break;
                int steps = 20;
                if (spin) { /* the Gauss-Newton matrix by frame blocks (nlsim.c) against the dense product */
                    double qt[16], Ha[256], Hb[256], E;
                    for (int k = 0; k < r; k++)
                        qt[k] = q[k];
                    crom_nlsim_begin_step(&s);
                    int pb = s.frame_pb;
                    CHECK(pb == map.inner->p + 1);
                    CHECK(crom_nlsim_objective(&s, qt, &E, NULL, Ha, 0) == 0);
                    s.frame_pb = 0;
                    CHECK(crom_nlsim_objective(&s, qt, &E, NULL, Hb, 0) == 0);
                    s.frame_pb = pb;
                    double eh = check_relerr(Ha, Hb, r * r, 1e-300);
                    fprintf(stderr, "  Gauss-Newton matrix by frame blocks vs dense: %.2e\n", eh);
                    CHECK_LT(eh, 1e-12);
                }
                for (int k = 0; k < steps && !rc; k++) {
                    crom_rsim_stats st;
                    rc = crom_nlsim_step(&s, &st);
                }
                CHECK_MSG(rc == 0, "frame run: %s", crom_errmsg());
                crom_nlsim_positions(&s, x, NULL);
                double c[3] = {0, 0, 0}, c0[3] = {0, 0, 0}, M = 0;
                for (int v = 0; v < map.nv; v++) {
                    M += b->fem.mass[v];
                    for (int k = 0; k < 3; k++) {
                        c[k] += b->fem.mass[v] * x[3 * v + k];
                        c0[k] += b->fem.mass[v] * b->mesh.X[3 * v + k];
                    }
                }
                double h = sc.dt, T = steps * h;
                if (!spin) { /* implicit Euler: y_n = y_0 + g h² n (n + 1) / 2 */
                    double want = sc.gravity[1] * h * h * steps * (steps + 1) / 2, got = (c[1] - c0[1]) / M;
                    fprintf(stderr, "  free fall in the frame, %d steps: centre of mass fell %.9f m, implicit Euler "
                            "%.9f m (apart %.1e); |q'| %.2e\n", steps, got, want, fabs(got - want), fabs(s.q[0]) + fabs(s.q[1]) + fabs(s.q[2]));
                    CHECK_LT(fabs(got - want), 1e-9 * fabs(want));
                } else {
                    double ang = s.q[ri + 2];
                    fprintf(stderr, "  spin 2 rad/s about z, %d steps: the frame turned %.5f rad (ω t = %.5f); centre "
                            "of mass moved %.2e m\n", steps, ang, 2 * T, fabs(c[0] - c0[0]) / M + fabs(c[1] - c0[1]) / M);
                    CHECK_LT(fabs(ang - 2 * T) / (2 * T), 0.01);
                    CHECK_LT(fabs(c[0] - c0[0]) / M + fabs(c[1] - c0[1]) / M, 1e-9);
                }
                crom_nlsim_free(&s);
            }
        }
        free(x);
        free(y);
        free(J);
        free(Jfd);
        crom_map_free(&map);
    }
    crom_model_free(&lm);
}

/* A cubature of the energy map through its features (crom-cubature
 * --model on a map): optimized NNLS weights fitted to the latent forces
 * T(q)ᵀ B_eᵀ f_e at samples of the training distribution reproduce the
 * exact latent forces at OTHER samples, and a run over the cubature's tets
 * follows the run over every tet. */
static void test_map_cubature(bar_case *b)
{
    if (!g_energy_model.rank)
        return;
    crom_map map;
    CHECK(crom_map_init(&map, &g_energy_model, &b->mesh) == 0);
    int r = map.r, p = map.p, P = 100;
    double *poses = malloc(sizeof(double) * 2 * P * p), *T = malloc(sizeof(double) * 2 * P * p * r);
    crom_rng rng;
    crom_rng_seed(&rng, 7);
    for (int j = 0; j < 2 * P; j++) {
        double q[2] = {crom_rng_normal(&rng), crom_rng_normal(&rng)};
        CHECK(crom_map_features(&map, q, poses + (size_t)j * p, T + (size_t)j * p * r) == 0);
    }
    crom_cubature_opts co = {CROM_CUBATURE_OPTIMIZED, 120, 0.002, 0, poses, P, 1e6, 0.3, T, r};
    crom_cubature cub;
    CHECK(crom_cubature_build(&cub, &map.mesh, map.B, p, "map", &co, &rng) == 0);
    double eE[2], eF[2];
    CHECK(crom_cubature_error(&cub, &b->mat, poses, P, T, r, &eE[0], &eF[0]) == 0);
    CHECK(crom_cubature_error(&cub, &b->mat, poses + (size_t)P * p, P, T + (size_t)P * p * r, r, &eE[1],
                              &eF[1]) == 0);
    fprintf(stderr, "energy map cubature: %d of %d tets; latent force error %.4f on the fitted samples, %.4f on "
                    "others (energy %.4f, %.4f)\n", cub.k, map.mesh.nt, eF[0], eF[1], eE[0], eE[1]);
    CHECK(cub.k < map.mesh.nt / 2);
    CHECK_LT(eF[0], 0.01);
    CHECK_LT(eF[1], 0.03);
    /* runs under gravity, every tet against the cubature */
    crom_scenario sc;
    scenario_bar(&sc);
    sc.tol = 1e-8;
    crom_nlsim all, cs;
    CHECK(crom_nlsim_init(&all, &map, &sc, 0, NULL, NULL, 1) == 0);
    CHECK(crom_nlsim_init(&cs, &map, &sc, 0, NULL, NULL, 1) == 0);
    CHECK(crom_nlsim_use_cubature(&cs, cub.k, cub.elem, cub.weight) == 0);
    double num = 0, den = 0, *xa = malloc(sizeof(double) * (size_t)map.n), *xc = malloc(sizeof(double) * (size_t)map.n);
    for (int k = 0; k < 40; k++) {
        crom_rsim_stats s1, s2;
        int rc1 = crom_nlsim_step(&all, &s1), rc2 = crom_nlsim_step(&cs, &s2);
        CHECK_MSG(rc1 == 0 && rc2 == 0, "step %d: %s", k, crom_errmsg());
        if (rc1 || rc2)
            break;
        crom_nlsim_positions(&all, xa, NULL);
        crom_nlsim_positions(&cs, xc, NULL);
        for (int i = 0; i < map.n; i++) {
            double u = xa[i] - map.mesh.X[i];
            num += (xc[i] - xa[i]) * (xc[i] - xa[i]);
            den += u * u;
        }
    }
    double rel = sqrt(num / den);
    fprintf(stderr, "energy map, 40 steps under gravity: cubature run vs every tet, relative displacement error "
                    "%.4f\n", rel);
    CHECK_LT(rel, 0.02);
    free(xa);
    free(xc);
    crom_nlsim_free(&all);
    crom_nlsim_free(&cs);
    crom_cubature_free(&cub);
    free(poses);
    free(T);
    crom_map_free(&map);
}

/* With its network zero, a Neural-Modes map is the linear modal basis:
 * Gauss–Newton is Newton and the run matches lib/rom's linear modal ROM
 * on a cubature of every tet, step by step; the Gauss-Newton matrix is then
 * the exact Hessian (against differences of the gradient). */
static void test_linear_equivalence(bar_case *b)
{
    crom_model lm;
    linear_modes_model(b, &lm);
    crom_map map;
    CHECK(crom_map_init(&map, &lm, &b->mesh) == 0);
    int r = map.r;
    crom_scenario sc;
    scenario_bar(&sc);
    sc.tol = 1e-12;
    sc.gravity[1] = -3;
    sc.damping = 0.5;
    crom_nlsim s;
    CHECK(crom_nlsim_init(&s, &map, &sc, 0, NULL, NULL, 1) == 0);
    /* exact Hessian of a linear map */
    crom_nlsim_begin_step(&s);
    g_nl = &s;
    g_nlproject = 0;
    double q[8] = {0.05, -0.03, 0.02}, H[64], Hfd[64], E;
    CHECK(crom_nlsim_objective(&s, q, &E, NULL, H, 0) == 0);
    check_fd_jacobian(nl_grad, NULL, q, r, r, 1e-7, Hfd);
    double eh = check_relerr(H, Hfd, r * r, 1e-9);
    CHECK_LT(eh, 1e-5);
    crom_cubature cub;
    crom_cubature_opts co = {CROM_CUBATURE_ALL, 0, 0, 0, NULL, 0, sc.youngs, sc.poisson, NULL, 0};
    crom_rng rng;
    crom_rng_seed(&rng, 1);
    CHECK(crom_cubature_build(&cub, &b->mesh, b->modes, r, "lin", &co, &rng) == 0);
    crom_rsim rs;
    CHECK(crom_rsim_init(&rs, &cub, &sc, CROM_RSIM_NEWTON, 0, NULL, NULL) == 0);
    crom_nlsim_free(&s);
    CHECK(crom_nlsim_init(&s, &map, &sc, 0, NULL, NULL, 1) == 0);
    double worst = 0, qmax = 0;
    for (int k = 0; k < 25; k++) {
        crom_rsim_stats a, c;
        int rc1 = crom_rsim_step(&rs, &a), rc2 = crom_nlsim_step(&s, &c);
        CHECK_MSG(rc1 == 0 && rc2 == 0, "step %d: %s", k, crom_errmsg());
        for (int i = 0; i < r; i++) {
            worst = fmax(worst, fabs(rs.q[i] - s.q[i]));
            qmax = fmax(qmax, fabs(rs.q[i]));
        }
    }
    fprintf(stderr, "linear part only: Gauss-Newton matrix vs FD Hessian %.2e; largest |q_map - q_rom| %.2e over 25 "
                    "steps (|q| up to %.3g m)\n", eh, worst, qmax);
    CHECK(qmax > 1e-3);
    CHECK_LT(worst, 1e-8 * qmax);
    /* the modes as a plain linear basis: crom_nlsim reuses its Gauss–Newton
     * matrix across iterations and steps (nlsim.c), and lands where a fresh
     * matrix at every iteration does, to the tolerance */
    crom_model bm;
    modes_model(b, &bm);
    crom_map bmap;
    CHECK(crom_map_init(&bmap, &bm, NULL) == 0);
    crom_nlsim lagged, fresh;
    sc.tol = 1e-10;
    CHECK(crom_nlsim_init(&lagged, &bmap, &sc, 0, NULL, NULL, 1) == 0);
    CHECK(crom_nlsim_init(&fresh, &bmap, &sc, 0, NULL, NULL, 1) == 0);
    CHECK(lagged.lagged == 1);
    fresh.lagged = 0;
    double lw = 0, lq = 0;
    long il = 0, ifr = 0;
    for (int k = 0; k < 25; k++) {
        crom_rsim_stats a, c;
        int rc1 = crom_nlsim_step(&lagged, &a), rc2 = crom_nlsim_step(&fresh, &c);
        CHECK_MSG(rc1 == 0 && rc2 == 0, "step %d: %s", k, crom_errmsg());
        il += a.iterations;
        ifr += c.iterations;
        for (int i = 0; i < bmap.r; i++) {
            lw = fmax(lw, fabs(lagged.q[i] - fresh.q[i]));
            lq = fmax(lq, fabs(fresh.q[i]));
        }
    }
    fprintf(stderr, "a linear basis in crom_nlsim: reused Gauss-Newton matrix vs fresh: largest |q| difference %.2e "
                    "(|q| up to %.3g m; %ld against %ld iterations)\n", lw, lq, il, ifr);
    CHECK(lq > 1e-3);
    CHECK_LT(lw, 1e-6 * lq);
    crom_nlsim_free(&lagged);
    crom_nlsim_free(&fresh);
    crom_map_free(&bmap);
    crom_model_free(&bm);
    crom_rsim_free(&rs);
    crom_cubature_free(&cub);
    crom_nlsim_free(&s);
    crom_map_free(&map);
    crom_model_free(&lm);
}

/* ------------------------------------------------------------ L-BFGS */

/* The two-loop recursion on a strictly convex quadratic ½ xᵀAx − bᵀx (n =
 * 30, condition number 1e3) with a backtracking line search from α = 1:
 * after 200 iterations it is within 1e-6 of the minimizer A⁻¹b (measured
 * 5e-7), where steepest descent with the same search is still far off
 * (memory 0: the direction is −g); a pair without positive curvature is
 * refused. Then the data-free trainer with --optimizer lbfgs on a random
 * cubature of half the tets lowers its objective. */
static double quad(const double *A, const double *b, const double *x, double *g, int n)
{
    double f = 0;
    for (int i = 0; i < n; i++) {
        double Ax = 0;
        for (int j = 0; j < n; j++)
            Ax += A[i * n + j] * x[j];
        g[i] = Ax - b[i];
        f += 0.5 * x[i] * Ax - b[i] * x[i];
    }
    return f;
}

/* 200 iterations from 0 on ½ xᵀAx − bᵀx [N = 30] with the backtracking
 * search from α = 1, as L-BFGS (pairs kept, memory 8) or as steepest
 * descent (no pair): the largest |x − x*|. With pairs, also checks that a
 * pair without positive curvature is refused. */
static double lbfgs_quad(const double *A, const double *b, const double *xs, int keep)
{
    enum { N = 30 };
    double x[N] = {0}, g[N], d[N], xt[N], gt[N], s[N], y[N];
    crom_lbfgs L;
    CHECK(crom_lbfgs_init(&L, N, 8) == 0);
    double f = quad(A, b, x, g, N), err = INFINITY;
    for (int it = 0; it < 200; it++) {
        crom_lbfgs_direction(&L, g, d);
        double slope = 0, alpha = 1, ft = 0;
        for (int i = 0; i < N; i++)
            slope += g[i] * d[i];
        if (L.k == 0) { /* no pair: a short steepest-descent step */
            for (int i = 0; i < N; i++)
                d[i] *= 1e-3;
            slope *= 1e-3;
        }
        for (int ls = 0; ls < 40; ls++, alpha *= 0.5) {
            for (int i = 0; i < N; i++)
                xt[i] = x[i] + alpha * d[i];
            ft = quad(A, b, xt, gt, N);
            if (ft <= f + 1e-4 * alpha * slope)
                break;
        }
        for (int i = 0; i < N; i++) {
            s[i] = xt[i] - x[i];
            y[i] = gt[i] - g[i];
        }
        if (keep)
            crom_lbfgs_push(&L, s, y);
        memcpy(x, xt, sizeof x);
        memcpy(g, gt, sizeof g);
        f = ft;
        err = 0;
        for (int i = 0; i < N; i++)
            err = fmax(err, fabs(x[i] - xs[i]));
    }
    if (keep) {
        for (int i = 0; i < N; i++) /* no positive curvature: refused */
            y[i] = -s[i];
        int k0 = L.k;
        CHECK(crom_lbfgs_push(&L, s, y) == 0 && L.k == k0);
    }
    crom_lbfgs_free(&L);
    return err;
}

static void test_lbfgs(bar_case *bc)
{
    enum { N = 30 };
    double A[N * N], b[N], xs[N];
    crom_rng rng;
    crom_rng_seed(&rng, 21);
    /* A = Q diag(1 .. 1000) Qᵀ with Q from the QR of a random matrix */
    double Q[N * N], tau[N];
    for (int i = 0; i < N * N; i++)
        Q[i] = crom_rng_normal(&rng);
    LAPACKE_dgeqrf(LAPACK_ROW_MAJOR, N, N, Q, N, tau);
    LAPACKE_dorgqr(LAPACK_ROW_MAJOR, N, N, N, Q, N, tau);
    for (int i = 0; i < N; i++)
        for (int j = 0; j < N; j++) {
            A[i * N + j] = 0;
            for (int k = 0; k < N; k++)
                A[i * N + j] += Q[i * N + k] * pow(1000.0, (double)k / (N - 1)) * Q[j * N + k];
        }
    for (int i = 0; i < N; i++) {
        b[i] = crom_rng_normal(&rng);
        xs[i] = b[i];
    }
    double Af[N * N];
    memcpy(Af, A, sizeof A);
    CHECK(LAPACKE_dposv(LAPACK_ROW_MAJOR, 'U', N, 1, Af, N, xs, 1) == 0);
    double errs[2] = {lbfgs_quad(A, b, xs, 1), lbfgs_quad(A, b, xs, 0)};
    fprintf(stderr, "L-BFGS on a quadratic (n %d, condition 1e3): |x - x*| %.2e after 200 iterations (steepest "
                    "descent %.2e)\n", N, errs[0], errs[1]);
    CHECK_LT(errs[0], 1e-6);
    CHECK_LT(errs[0], 1e-4 * errs[1]);

    crom_datafree_problem P = {&bc->mesh, bc->mat, {0, -9.81, 0}, bc->fixed, NULL, NULL, NULL, 0, NULL, NULL, 0, NULL, NULL, 0, NULL, NULL, NULL, NULL};
    crom_datafree_opts o;
    crom_datafree_defaults(&o, CROM_DATAFREE_ENERGY);
    o.rank = 2;
    o.steps = 60;
    o.width = 16;
    o.optimizer = CROM_DATAFREE_LBFGS;
    o.resample = 5;
    o.ramp = 0; /* the same objective from the start: comparable values */
    o.tets = bc->mesh.nt / 2;
    crom_model m;
    crom_dftrain_log log;
    int rc = crom_datafree_train(&P, &o, &m, &log);
    CHECK_MSG(rc == 0, "lbfgs training: %s", crom_errmsg());
    if (rc)
        return;
    double first = 0, last = 0; /* means over 10 steps: each batch is another objective */
    for (int j = 0; j < 10; j++) {
        first += log.objective[j] / 10;
        last += log.objective[log.nblocks - 1 - j] / 10;
    }
    fprintf(stderr, "energy map by L-BFGS (5 iterations per batch, %d of %d tets): mean objective of the first 10 "
                    "steps %.4g, of the last 10 %.4g (%ld steps)\n", o.tets, bc->mesh.nt, first, last, log.steps);
    CHECK(log.steps == 60 && log.nblocks == 60 && last < 0.5 * first);
    crom_model_free(&m);
    crom_dftrain_log_free(&log);
}

/* crom-metrics' and crom-cubature's samples of a neural-modes model come
 * from its training box: [-A f_1/f_k, A f_1/f_k] for mode k when it was
 * scaled by the frequencies (latent_box_scaling frequency), else [-A, A]. */
static void test_metrics_box(void)
{
    crom_model m;
    crom_model_clear(&m);
    strcpy(m.basis, "neuralmodes");
    m.latent_box = 0.2;
    double freq[3] = {2, 4, 8};
    m.frequencies = freq;
    for (int scaled = 0; scaled < 2; scaled++) {
        m.latent_box_scaled = scaled;
        crom_metrics_opts o;
        crom_metrics_defaults(&o);
        crom_metrics_training_dist(&m, 1.0, &o);
        CHECK(o.dist == CROM_METRICS_BOX && o.radius == 0.2 && (o.box_freq != NULL) == scaled);
        crom_rng rng;
        crom_rng_seed(&rng, 3);
        double big[3] = {0, 0, 0};
        for (int s = 0; s < 4000; s++) {
            double q[3];
            crom_metrics_sample(&rng, &o, 3, q);
            for (int k = 0; k < 3; k++)
                big[k] = fmax(big[k], fabs(q[k]));
        }
        for (int k = 0; k < 3; k++) {
            double a = scaled ? 0.2 * 2 / freq[k] : 0.2;
            CHECK_MSG(big[k] <= a && big[k] > 0.99 * a, "mode %d: largest |q| %g, half-width %g", k, big[k], a);
        }
    }
}

int main(void)
{
    check_begin("test_datafree");
    test_metrics_box();
    gradient_check(CROM_DATAFREE_ENERGY);
    gradient_check(CROM_DATAFREE_NEURALMODES);
    g_quadratic = 1;
    gradient_check(CROM_DATAFREE_NEURALMODES);
    g_supervised = 1; /* the supervised loss, with the quadratic part */
    gradient_check(CROM_DATAFREE_NEURALMODES);
    g_supervised = 0;
    g_tangent = 1; /* the tangent-anchored map, with the quadratic part */
    gradient_check(CROM_DATAFREE_NEURALMODES);
    g_tangent = 0;
    g_quadratic = 0;
    g_seeded = 1;
    gradient_check(CROM_DATAFREE_ENERGY);
    g_seeded = 0;
    gradient_check_field();
    gradient_check_field_basis();
    test_conditional();
    test_conditional_pin();
    test_map();
    bar_case b;
    bar_setup(&b, 3);
    test_energy_subspace(&b);
    test_seeded_map(&b);
    test_neuralmodes_subspace(&b);
    test_neuralmodes_visit(&b);
    test_field_subspace(&b);
    test_skin_field(&b);
    test_dynamics(&b);
    test_map_cubature(&b);
    test_frame(&b);
    test_linear_equivalence(&b);
    test_lbfgs(&b);
    test_shell_map();
    crom_model_free(&g_energy_model);
    bar_free(&b);
    return check_done();
}
