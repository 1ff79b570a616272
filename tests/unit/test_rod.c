/* test_rod.c — rods with animated rest lengths (phys/rod.h) and their
 * place in the full simulation:
 *   - --rod values parse, print and parse back the same; bad ones are
 *     refused naming the problem;
 *   - the rod's gradient and Hessian in its gap agree with central
 *     differences, stretched and compressed; the projected Hessian is
 *     positive semi-definite and equals the exact one when stretched;
 *   - on a mesh, the rods' gradient in the positions agrees with
 *     differences of their energy, and their Hessian product with
 *     differences of the gradient, ends of several vertices included;
 *   - a driven oscillator: a 1 kg block tied by a rod of k = 100 N/m to a
 *     pinned block, the rod's rest length L0 + a sin(ω t), with damping:
 *     crom_sim's steady state has the amplitude and phase of implicit
 *     Euler's discrete transfer function of m ẍ + A m ẋ + k x = k L(t)
 *     (within 1%, 0.01 rad), in phase below resonance (ω = 5 < ω0 = 10
 *     rad/s: lag < π/2) and against it above (ω = 20: lag > π/2), and
 *     converging to the continuous phase atan2(Aω, ω0² − ω²) at first
 *     order in h. */
#include <complex.h>
#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "base/rng.h"
#include "check.h"
#include "fixtures.h"
#include "phys/rod.h"
#include "phys/scenario.h"
#include "phys/sim.h"

static void test_parse(void)
{
    crom_rod r, back;
    CHECK(crom_rod_parse("--rod", "hand/x>0.4&y<0=250,rest,0.05,2,1.5", &r) == 0);
    CHECK(!strcmp(r.a, "hand") && !strcmp(r.b, "x>0.4&y<0") && r.k == 250 && isnan(r.L0) && r.amp == 0.05 &&
          r.period == 2 && r.phase == 1.5);
    char buf[400];
    crom_rod_format(&r, buf, sizeof buf);
    CHECK(crom_rod_parse("--rod", buf, &back) == 0 && !memcmp(&r.k, &back.k, 0) && back.k == r.k &&
          isnan(back.L0) && back.amp == r.amp && back.period == r.period && back.phase == r.phase &&
          !strcmp(back.b, r.b));
    CHECK(crom_rod_parse("--rod", "#3/x<=0.1=10,0.5", &r) == 0 && !strcmp(r.b, "x<=0.1") && r.L0 == 0.5 &&
          r.amp == 0);
    crom_rod_format(&r, buf, sizeof buf);
    CHECK(!strcmp(buf, "#3/x<=0.1=10,0.5"));
    const char *bad[] = {"a=1,1", "a/b", "/b=1,1", "a/=1,1", "a/b=0,1", "a/b=1,-1", "a/b=1,x", "a/b=1,1,0.1",
                         "a/b=1,1,0.1,0", "a/b=nan,1", "a/b=1,1,0.1,1,inf", "a/b=1"};
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
        CHECK_MSG(crom_rod_parse("--rod", bad[i], &r) == CROM_EUSAGE, "'%s' accepted", bad[i]);
        CHECK(strstr(crom_errmsg(), "--rod") != NULL);
        crom_err_clear();
    }
    /* the scenario keeps rods in its text */
    crom_scenario sc, sb;
    crom_scenario_defaults(&sc);
    crom_scenario_defaults(&sb);
    CHECK(crom_scenario_parse_text("--rod a/b=5,rest,0.1,3\n--rod #0/#1=7,0.2\n", &sc) == 0 && sc.nrod == 2);
    char *text = crom_scenario_text(&sc);
    CHECK(text && strstr(text, "--rod a/b=5,rest,0.10000000000000001,3,0\n") &&
          crom_scenario_parse_text(text, &sb) == 0 && sb.nrod == 2 && sb.rod[1].k == 7 && sb.rod[0].period == 3);
    free(text);
}

static void test_eval(void)
{
    crom_rng rng;
    crom_rng_seed(&rng, 11);
    for (int trial = 0; trial < 6; trial++) {
        double d[3], g[3], H[9], Hp[9], k = 3 + trial, L = trial % 2 ? 0.3 : 2.0; /* stretched, compressed */
        for (int i = 0; i < 3; i++)
            d[i] = crom_rng_uniform(&rng) - 0.5;
        crom_rod_eval(k, L, d, g, H, 0);
        crom_rod_eval(k, L, d, NULL, Hp, 1);
        double e = 1e-6, worst_g = 0, worst_h = 0;
        for (int i = 0; i < 3; i++) {
            double dp[3], dm[3], gp[3], gm[3];
            memcpy(dp, d, sizeof dp);
            memcpy(dm, d, sizeof dm);
            dp[i] += e;
            dm[i] -= e;
            double fd = (crom_rod_eval(k, L, dp, gp, NULL, 0) - crom_rod_eval(k, L, dm, gm, NULL, 0)) / (2 * e);
            worst_g = fmax(worst_g, fabs(fd - g[i]) / k);
            for (int j = 0; j < 3; j++)
                worst_h = fmax(worst_h, fabs((gp[j] - gm[j]) / (2 * e) - H[3 * j + i]) / k);
        }
        CHECK_LT(worst_g, 1e-8);
        CHECK_LT(worst_h, 1e-7);
        CHECK_LT(-1e-12, fx_min_eig(Hp, 3));
        double l = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]), same = 0;
        for (int i = 0; i < 9; i++)
            same = fmax(same, fabs(H[i] - Hp[i]));
        if (l > L)
            CHECK(same == 0);
        else
            CHECK_LT(fx_min_eig(H, 3), -1e-3); /* compressed: transverse buckling */
    }
}

static void test_mesh_rods(void)
{
    crom_mesh m;
    crom_rng rng;
    crom_rng_seed(&rng, 5);
    const double lo[3] = {0, 0, 0};
    fx_box_mesh(&m, 4, 2, 2, lo, 0.1, 0.2, &rng, NULL);
    CHECK(crom_mesh_region_spec(&m, "left=x<0.05") == 0);
    crom_rod rods[2];
    CHECK(crom_rod_parse("--rod", "left/x>0.35=40,0.2,0.05,0.5", &rods[0]) == 0);
    CHECK(crom_rod_parse("--rod", "#0/y>0.15&x>0.15=25,rest", &rods[1]) == 0);
    double *mass = malloc(sizeof(double) * m.nv);
    for (int v = 0; v < m.nv; v++)
        mass[v] = 0.5 + crom_rng_uniform(&rng);
    crom_rod_set R;
    CHECK(crom_rod_set_init(&R, 2, rods, &m, mass) == 0);
    size_t n = 3 * (size_t)m.nv;
    double *x = malloc(sizeof(double) * n), *g = calloc(n, sizeof(double)), *gp = calloc(n, sizeof(double)),
           *gm = calloc(n, sizeof(double)), *p = malloc(sizeof(double) * n), *Hp = calloc(n, sizeof(double)), Hd[18];
    for (size_t i = 0; i < n; i++) {
        x[i] = m.X[i] + 0.03 * (crom_rng_uniform(&rng) - 0.5);
        p[i] = crom_rng_uniform(&rng) - 0.5;
    }
    double t = 0.37;
    crom_rod_set_eval(&R, rods, t, x, g, Hd, 0);
    double worst = 0, e = 1e-6;
    for (size_t i = 0; i < n; i++) {
        double xi = x[i];
        x[i] = xi + e;
        double Ep = crom_rod_set_eval(&R, rods, t, x, NULL, NULL, 0);
        x[i] = xi - e;
        double Em = crom_rod_set_eval(&R, rods, t, x, NULL, NULL, 0);
        x[i] = xi;
        worst = fmax(worst, fabs((Ep - Em) / (2 * e) - g[i]));
    }
    CHECK_LT(worst, 1e-7);
    crom_rod_set_matvec(&R, Hd, NULL, p, Hp);
    for (size_t i = 0; i < n; i++)
        x[i] += e * p[i];
    crom_rod_set_eval(&R, rods, t, x, gp, NULL, 0);
    for (size_t i = 0; i < n; i++)
        x[i] -= 2 * e * p[i];
    crom_rod_set_eval(&R, rods, t, x, gm, NULL, 0);
    worst = 0;
    for (size_t i = 0; i < n; i++)
        worst = fmax(worst, fabs((gp[i] - gm[i]) / (2 * e) - Hp[i]));
    CHECK_LT(worst, 1e-6);
    /* the rest length at rest, and an end not on the mesh */
    CHECK(R.rest[1] > 0 && crom_rod_length(&rods[1], R.rest[1], 5) == R.rest[1]);
    CHECK_NEAR(crom_rod_length(&rods[0], 0, 0.125), 0.25, 1e-15);
    crom_rod_set_free(&R);
    CHECK(crom_rod_parse("--rod", "left/nowhere=1,1", &rods[0]) == 0);
    CHECK(crom_rod_set_init(&R, 1, rods, &m, mass) == CROM_EUSAGE && strstr(crom_errmsg(), "nowhere"));
    crom_err_clear();
    free(x), free(g), free(gp), free(gm), free(p), free(Hp), free(mass);
    crom_mesh_free(&m);
}

static int two_blocks(int i, int j, int k) { return i == 0 || i == 4; }

/* amplitude and phase lag of the steady state of the driven block */
static void driven(double w, double h, double *amp, double *lag, double *amp_d, double *lag_d, double *lag_c)
{
    const double k = 100, A = 2, a = 0.01, m = 1;
    crom_mesh mesh;
    const double lo[3] = {0, 0, 0};
    fx_box_mesh(&mesh, 5, 1, 1, lo, 0.1, 0, NULL, two_blocks);
    crom_scenario sc;
    crom_scenario_defaults(&sc);
    char text[512];
    int steps = (int)(12.0 / h);
    snprintf(text, sizeof text,
             "--youngs 1e8\n--poisson 0.3\n--density 1000\n--gravity 0,0,0\n--dt %.17g\n--steps %d\n--damping %g\n"
             "--pin x<0.15\n--rod x<0.15/x>0.35=%g,rest,%g,%.17g\n--tol 1e-10\n",
             h, steps, A, k, a, 2 * M_PI / w);
    CHECK(crom_scenario_parse_text(text, &sc) == 0);
    crom_sim s;
    crom_sim_stats st;
    CHECK(crom_sim_init(&s, &mesh, &sc) == 0);
    CHECK_NEAR(s.sys.total_mass, 2 * m, 1e-9);
    /* fit the last 2 s: ℓ(t) − ℓ0 = α sin ωt + β cos ωt */
    double Sss = 0, Scc = 0, Ssc = 0, Sxs = 0, Sxc = 0;
    for (int n = 1; n <= steps; n++) {
        if (crom_sim_step(&s, &st)) {
            CHECK_MSG(0, "step %d: %s", n, crom_errmsg());
            break;
        }
        double t = n * h, d[3];
        if (t < 10)
            continue;
        crom_rod_set_gap(&s.rods, 0, s.x, d);
        double xx = d[0] - s.rods.rest[0], sn = sin(w * t), cs = cos(w * t);
        Sss += sn * sn, Scc += cs * cs, Ssc += sn * cs, Sxs += xx * sn, Sxc += xx * cs;
    }
    double det = Sss * Scc - Ssc * Ssc, al = (Sxs * Scc - Sxc * Ssc) / det, be = (Sxc * Sss - Sxs * Ssc) / det;
    *amp = hypot(al, be) / a;
    *lag = atan2(-be, al); /* α sin + β cos = |X| sin(ωt − lag) */
    /* implicit Euler's transfer function, x_{n+1} = H a e^{iω t_{n+1}} */
    double w0 = sqrt(k / m);
    double complex zi = cexp(-I * w * h), den = (1 - zi) * (1 - zi) / (h * h) + A * (1 - zi) / h + w0 * w0;
    double complex H = w0 * w0 / den;
    *amp_d = cabs(H);
    *lag_d = -carg(H);
    *lag_c = atan2(A * w, w0 * w0 - w * w);
    crom_sim_free(&s);
    crom_mesh_free(&mesh);
}

static void test_driven(void)
{
    double amp, lag, amp_d, lag_d, lag_c, lag_c5;
    driven(5, 0.005, &amp, &lag, &amp_d, &lag_d, &lag_c);
    fprintf(stderr, "driven below resonance: amplitude %.4f (discrete %.4f), lag %.4f rad (discrete %.4f, "
            "continuous %.4f)\n", amp, amp_d, lag, lag_d, lag_c);
    CHECK_REL(amp, amp_d, 0.01);
    CHECK_NEAR(lag, lag_d, 0.01);
    CHECK_NEAR(lag, lag_c, 0.05);
    CHECK_LT(lag, M_PI / 2);
    driven(20, 0.005, &amp, &lag, &amp_d, &lag_d, &lag_c);
    fprintf(stderr, "driven above resonance: amplitude %.4f (discrete %.4f), lag %.4f rad (discrete %.4f, "
            "continuous %.4f)\n", amp, amp_d, lag, lag_d, lag_c);
    CHECK_REL(amp, amp_d, 0.01);
    CHECK_NEAR(lag, lag_d, 0.01);
    CHECK_LT(M_PI / 2, lag);
    /* implicit Euler's phase error is first order in h: a fifth of the step,
     * about a fifth of the gap to the continuous phase */
    lag_c5 = lag;
    driven(20, 0.001, &amp, &lag, &amp_d, &lag_d, &lag_c);
    fprintf(stderr, "driven above resonance, h = 1 ms: lag %.4f rad (continuous %.4f)\n", lag, lag_c);
    CHECK_NEAR(lag, lag_d, 0.01);
    CHECK_NEAR(lag, lag_c, 0.04);
    CHECK_LT(fabs(lag - lag_c), 0.3 * fabs(lag_c5 - lag_c));
}

int main(void)
{
    check_begin("rod");
    test_parse();
    test_eval();
    test_mesh_rods();
    test_driven();
    return check_done();
}
