/* test_viewer.c — crom-view's messages and command check (view/viewer.h):
 *   - the surface is the closed boundary of the mesh (Euler characteristic
 *     2 for a box, every edge in two triangles, outward: the enclosed volume
 *     by the divergence theorem equals the mesh's), and each surface vertex
 *     carries its mesh vertex's basis rows;
 *   - decoding X + W q from the surface message, read back byte by byte as a
 *     page reads it, gives the cubature's W q at those vertices to float
 *     rounding (1e-6 relative), and the frame message holds q exactly;
 *   - a page's command is passed on normalized so that crom_live_parse
 *     reads back the very same numbers; step, quit, an unoffered schedule,
 *     a region or vertex not on the mesh, NaN are refused with a message;
 *   - the greeting escapes its strings and refuses what does not fit; a
 *     switch passed on is taken by the frame that shows the next cubature
 *     number and dropped after CROM_VIEWER_SWITCH_FRAMES frames without it;
 *     a page's drags are forgotten by their releases. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "base/rng.h"
#include "check.h"
#include "fixtures.h"
#include "view/viewer.h"

static uint32_t u32(const unsigned char *p) { return p[0] | p[1] << 8 | p[2] << 16 | (uint32_t)p[3] << 24; }

static float f32(const unsigned char *p)
{
    uint32_t v = u32(p);
    float f;
    memcpy(&f, &v, 4);
    return f;
}

static double f64(const unsigned char *p)
{
    uint64_t v = u32(p) | (uint64_t)u32(p + 4) << 32;
    double f;
    memcpy(&f, &v, 8);
    return f;
}

enum { R = 5 };

static void test_surface(void)
{
    crom_mesh m;
    crom_rng rng;
    crom_rng_seed(&rng, 3);
    const double lo[3] = {-0.2, 0, 0.1};
    fx_box_mesh(&m, 4, 3, 2, lo, 0.1, 0.2, &rng, NULL);
    CHECK(crom_mesh_region_spec(&m, "top=y>0.29") == 0);
    /* a cubature holding the mesh and a basis; only W and the mesh are used */
    crom_cubature c;
    memset(&c, 0, sizeof c);
    c.r = R;
    c.mesh = m;
    c.W = malloc(sizeof(double) * 3 * R * (size_t)m.nv);
    for (int i = 0; i < 3 * R * m.nv; i++)
        c.W[i] = crom_rng_normal(&rng);
    crom_viewer_surface s;
    CHECK(crom_viewer_surface_init(&s, &c) == 0);
    /* a closed, outward surface: V - E + F = 2, volume by the divergence theorem */
    int E = 3 * s.nt / 2;
    CHECK_MSG(s.ns - E + s.nt == 2, "V - E + F = %d - %d + %d", s.ns, E, s.nt);
    double vol = 0;
    for (int t = 0; t < s.nt; t++) {
        const float *a = s.X + 3 * s.tri[3 * t], *b = s.X + 3 * s.tri[3 * t + 1], *d = s.X + 3 * s.tri[3 * t + 2];
        vol += (a[0] * (b[1] * d[2] - b[2] * d[1]) - a[1] * (b[0] * d[2] - b[2] * d[0]) +
                a[2] * (b[0] * d[1] - b[1] * d[0])) / 6.0;
    }
    CHECK_REL(vol, crom_mesh_volume(&m), 1e-6);
    CHECK_NEAR(s.lo[0], -0.2, 0.03);
    CHECK_NEAR(s.hi[1], 0.3, 0.03);

    /* the message, read back as the page does, decodes to W q */
    unsigned char *buf;
    size_t len, pre = 16;
    CHECK(crom_viewer_surface_msg(&s, 3, pre, &buf, &len) == 0);
    const unsigned char *p = buf + pre;
    CHECK(!memcmp(p, "SURF", 4) && u32(p + 4) == 3 && (int)u32(p + 8) == s.ns && (int)u32(p + 12) == s.nt &&
          u32(p + 16) == R);
    size_t ns = (size_t)s.ns, oX = 44, oW = oX + 12 * ns, oT = oW + 12 * R * ns, oV = oT + 12 * (size_t)s.nt;
    CHECK(len == oV + 4 * ns);
    double q[R], worst = 0, scale = 0;
    for (int k = 0; k < R; k++)
        q[k] = 0.01 * crom_rng_normal(&rng);
    double *x = malloc(sizeof(double) * 3 * ns);
    crom_viewer_decode(&s, q, x);
    int tris_ok = 1;
    for (int t = 0; t < 3 * s.nt; t++)
        tris_ok &= u32(p + oT + 4 * (size_t)t) == s.tri[t];
    CHECK(tris_ok);
    for (size_t i = 0; i < ns; i++) {
        int v = (int)u32(p + oV + 4 * i);
        CHECK_MSG(v == s.vid[i] && v >= 0 && v < m.nv, "vid %zu", i);
        for (int d = 0; d < 3; d++) {
            double page = f32(p + oX + 4 * (3 * i + d)), exact = m.X[3 * v + d];
            for (int k = 0; k < R; k++) {
                page += (double)f32(p + oW + 4 * ((3 * i + d) * R + k)) * q[k];
                exact += c.W[(3 * (size_t)v + d) * R + k] * q[k];
            }
            worst = fmax(worst, fmax(fabs(page - exact), fabs(x[3 * i + d] - exact)));
            scale = fmax(scale, fabs(exact));
        }
    }
    CHECK_MSG(worst <= 1e-6 * scale, "decoded surface off by %.3g (scale %.3g)", worst, scale);
    free(buf);
    free(x);

    /* the frame message */
    unsigned char fb[48 + 8 * R];
    crom_viewer_frame f = {7, 0.07, 1.5, 12, 2, 1, q};
    CHECK(crom_viewer_frame_msg(fb, R, &f) == sizeof fb && crom_viewer_frame_size(R) == sizeof fb);
    CHECK(!memcmp(fb, "FRAM", 4) && u32(fb + 4) == R && u32(fb + 8) == 2 && u32(fb + 12) == 1);
    CHECK(f64(fb + 16) == 7 && f64(fb + 24) == 0.07 && f64(fb + 32) == 1.5 && f64(fb + 40 + 8 * R) == 12);
    int same = 1;
    for (int k = 0; k < R; k++)
        same &= f64(fb + 40 + 8 * k) == q[k];
    CHECK(same);

    /* a nonlinear map's cubature is refused */
    c.map_rank = 2;
    crom_viewer_surface s2;
    CHECK(crom_viewer_surface_init(&s2, &c) == CROM_EUSAGE);
    crom_err_clear();
    crom_viewer_surface_free(&s);
    free(c.W);
    crom_mesh_free(&m);
}

static void test_check(void)
{
    crom_mesh m;
    fx_unit_grid(&m, 2, 1);
    CHECK(crom_mesh_region_spec(&m, "top=y>0.9") == 0);
    const char *offers[] = {"cut.h5"};
    crom_live_cmd c, back;
    char out[320];
    /* passed on normalized; read back, the same numbers */
    const char *good[] = {"drag #3 0.1,0.2,0.30000000000000004 1e7", "drag top 1e-3,-2,3", "force y<0.5 0,-9.81,0",
                          "release #3", "release", "pin top", "unpin top", "schedule cut.h5", "  drag   #0 1,2,3  "};
    for (size_t i = 0; i < sizeof good / sizeof *good; i++) {
        int rc = crom_viewer_check(&m, good[i], offers, 1, &c, out, sizeof out);
        CHECK_MSG(rc == 0, "'%s': %s", good[i], crom_errmsg());
        CHECK(crom_live_parse(out, &back) == 0);
        CHECK_MSG(back.kind == c.kind && !strcmp(back.ref, c.ref) && back.v[0] == c.v[0] && back.v[1] == c.v[1] &&
                      back.v[2] == c.v[2] && back.k == c.k,
                  "'%s' -> '%s' reads back otherwise", good[i], out);
    }
    CHECK(crom_viewer_check(&m, "drag #3 0.1,0.2,0.30000000000000004", NULL, 0, &c, out, sizeof out) == 0 &&
          !strcmp(out, "drag #3 0.1,0.2,0.30000000000000004"));
    CHECK(crom_viewer_check(&m, "# a comment", NULL, 0, &c, out, sizeof out) == 0 && !out[0]);
    /* refused, each with a message */
    const char *bad[] = {"step 3", "quit", "schedule other.h5", "schedule /etc/passwd", "drag nowhere 0,0,0",
                         "drag #27 0,0,0", "drag #-1 0,0,0", "drag top nan,0,0", "force top 1,2", "bogus",
                         "pin x>7", "release nowhere"};
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
        crom_err_clear();
        int rc = crom_viewer_check(&m, bad[i], offers, 1, &c, out, sizeof out);
        CHECK_MSG(rc == CROM_EUSAGE && crom_errmsg()[0], "'%s' not refused (%d)", bad[i], rc);
    }
    crom_err_clear();
    crom_mesh_free(&m);
}

static void test_bookkeeping(void)
{
    char b[256];
    const char *offers[] = {"a\"b.h5", "c\\d\n.h5"};
    CHECK(crom_viewer_hello(b, sizeof b, "x.h5", "0123abcd", 20, 99, offers, 2) == 0);
    CHECK_MSG(!strcmp(b, "{\"cubature\":\"x.h5\",\"model\":\"0123abcd\",\"rank\":20,\"vertices\":99,"
                         "\"offers\":[\"a\\\"b.h5\",\"c\\\\d\\u000a.h5\"]}"), "greeting: %s", b);
    for (size_t cap = 1; cap < strlen(b) + 1; cap += 7) {
        char t[256];
        CHECK_MSG(crom_viewer_hello(t, cap, "x.h5", "0123abcd", 20, 99, offers, 2) == CROM_EUSAGE, "cap %zu", cap);
    }
    crom_err_clear();

    crom_viewer_switches w;
    int ref[CROM_VIEWER_SWITCHES], nref;
    crom_viewer_switches_init(&w);
    CHECK(crom_viewer_switch_frame(&w, 0, 1, ref, &nref) == 0 && nref == 0);
    CHECK(crom_viewer_switch_frame(&w, 1, 2, ref, &nref) == -1); /* a number nobody asked for */
    CHECK(crom_viewer_switch_passed(&w, 2, 10) == 0);
    CHECK(crom_viewer_switch_frame(&w, 0, 11, ref, &nref) == 0 && nref == 0); /* not yet */
    CHECK(crom_viewer_switch_frame(&w, 1, 12, ref, &nref) == 2 && nref == 0); /* taken */
    CHECK(crom_viewer_switch_passed(&w, 3, 20) == 0);                       /* refused by the run */
    CHECK(crom_viewer_switch_frame(&w, 1, 20 + CROM_VIEWER_SWITCH_FRAMES, ref, &nref) == 2 && nref == 0);
    CHECK(crom_viewer_switch_frame(&w, 1, 21 + CROM_VIEWER_SWITCH_FRAMES, ref, &nref) == 2 && nref == 1 &&
          ref[0] == 3);
    CHECK(crom_viewer_switch_passed(&w, 1, 60) == 0 && crom_viewer_switch_passed(&w, 0, 60) == 0);
    CHECK(crom_viewer_switch_frame(&w, 3, 61, ref, &nref) == 0 && nref == 0); /* both taken at once */
    CHECK(crom_viewer_switch_frame(&w, 2, 62, ref, &nref) == 1 && w.npend == 0);
    for (int i = 0; i < CROM_VIEWER_SWITCHES; i++)
        CHECK(crom_viewer_switch_passed(&w, 1, 70) == 0);
    CHECK(crom_viewer_switch_passed(&w, 1, 70) == CROM_EUSAGE);
    crom_err_clear();

    crom_viewer_drags d = {0};
    crom_live_cmd c;
    const char *lines[] = {"drag #3 0,0,0", "drag top 0,0,0", "drag #3 1,1,1", "release #3", "force top 1,0,0"};
    for (size_t i = 0; i < sizeof lines / sizeof *lines; i++) {
        CHECK(crom_live_parse(lines[i], &c) == 0);
        crom_viewer_drags_note(&d, &c);
    }
    CHECK(d.n == 1 && !strcmp(d.ref[0], "top"));
    CHECK(crom_live_parse("release", &c) == 0);
    crom_viewer_drags_note(&d, &c);
    CHECK(d.n == 0);
}

int main(void)
{
    check_name = "viewer";
    test_surface();
    test_check();
    test_bookkeeping();
    return check_done();
}
