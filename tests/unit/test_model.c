/* test_model.c — point location (lib/locate) and crom/model files and
 * evaluation (lib/model): containing tets, exact interpolation of linear
 * fields, nearest tets outside, model round trips and model_id. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "check.h"
#include "base/err.h"
#include "io/io.h"
#include "fixtures.h"
#include "mesh/locate.h"
#include "rom/model.h"
#include "nn/nn.h"

static char dir[] = "/tmp/crom-model-XXXXXX";

/* A random point in tet t: Dirichlet(1,1,1,1) weights. */
static void random_in_tet(const crom_mesh *m, int t, crom_rng *rng, double *p)
{
    double b[4], s = 0;
    for (int k = 0; k < 4; k++)
        s += b[k] = -log(1 - crom_rng_uniform(rng));
    p[0] = p[1] = p[2] = 0;
    for (int k = 0; k < 4; k++)
        for (int c = 0; c < 3; c++)
            p[c] += b[k] / s * m->X[3 * (size_t)m->tets[4 * t + k] + c];
}

static int notch(int i, int j, int k) { return !(i >= 2 && j >= 2 && k < 4); } /* L-shaped */

static void test_locate_inside(const char *label, int (*keep)(int, int, int))
{
    crom_rng rng;
    crom_rng_seed(&rng, 11);
    crom_mesh m;
    double lo[3] = {-0.5, -0.25, 0.1};
    fx_box_mesh(&m, 4, 4, 4, lo, 0.25, 0.2, &rng, keep);
    CHECK(crom_mesh_validate(&m) == 0);
    crom_locator L;
    CHECK(crom_locate_init(&L, &m) == 0);
    /* a linear field f(X) = A X + c, 2 components */
    double A[2][3] = {{1.5, -2, 0.25}, {0.3, 0.7, -1.1}}, c0[2] = {0.2, -3};
    double *f = malloc(sizeof(double) * 2 * (size_t)m.nv);
    for (int v = 0; v < m.nv; v++)
        for (int d = 0; d < 2; d++)
            f[2 * v + d] = c0[d] + A[d][0] * m.X[3 * v] + A[d][1] * m.X[3 * v + 1] +
                           A[d][2] * m.X[3 * v + 2];
    int n = 2000, inside = 0, contains = 0;
    double worst_b = 0, worst_x = 0, worst_f = 0;
    for (int i = 0; i < n; i++) {
        double p[3], b[4], dist;
        int t0 = (int)crom_rng_below(&rng, (uint64_t)m.nt), t;
        random_in_tet(&m, t0, &rng, p);
        inside += crom_locate_point(&L, p, &t, b, &dist);
        double mn = fmin(fmin(b[0], b[1]), fmin(b[2], b[3])), sb = b[0] + b[1] + b[2] + b[3];
        contains += mn >= -1e-12 && fmax(fmax(b[0], b[1]), fmax(b[2], b[3])) <= 1 + 1e-12;
        worst_b = fmax(worst_b, fabs(sb - 1));
        double x[3] = {0, 0, 0};
        for (int k = 0; k < 4; k++)
            for (int cc = 0; cc < 3; cc++)
                x[cc] += b[k] * m.X[3 * (size_t)m.tets[4 * t + k] + cc];
        for (int cc = 0; cc < 3; cc++)
            worst_x = fmax(worst_x, fabs(x[cc] - p[cc]));
        double fi[2];
        crom_locate_interp(&L, 1, p, 2, f, fi, NULL);
        for (int d = 0; d < 2; d++) {
            double exact = c0[d] + A[d][0] * p[0] + A[d][1] * p[1] + A[d][2] * p[2];
            worst_f = fmax(worst_f, fabs(fi[d] - exact));
        }
    }
    printf("  %-10s %d tets: %d/%d inside, %d in [0,1]; |sum b - 1| %.1e, |x(b) - p| %.1e, linear field error %.1e\n",
           label, m.nt, inside, n, contains, worst_b, worst_x, worst_f);
    CHECK(inside == n);
    CHECK(contains == n);
    CHECK_LT(worst_b, 1e-12);
    CHECK_LT(worst_x, 1e-12);
    CHECK_LT(worst_f, 1e-12);
    free(f);
    crom_locate_free(&L);
    crom_mesh_free(&m);
}

/* Outside a convex box mesh, the nearest point of the mesh is the clamped
 * point: the located tet's clamped coordinates must reproduce it. */
static void test_locate_outside(void)
{
    crom_rng rng;
    crom_rng_seed(&rng, 12);
    crom_mesh m;
    double lo[3] = {0, 0, 0}, h = 0.2;
    fx_box_mesh(&m, 5, 3, 4, lo, h, 0.2, &rng, NULL);
    crom_locator L;
    CHECK(crom_locate_init(&L, &m) == 0);
    double hi[3] = {5 * h, 3 * h, 4 * h};
    int n = 1000, outside = 0;
    double worst = 0, worst_d = 0, worst_b = 0;
    for (int i = 0; i < n; i++) {
        double p[3], q[3], b[4], dist;
        int t;
        for (int c = 0; c < 3; c++) {
            p[c] = lo[c] - 0.5 + (hi[c] - lo[c] + 1.0) * crom_rng_uniform(&rng);
            q[c] = fmin(fmax(p[c], lo[c]), hi[c]);
        }
        int in = q[0] == p[0] && q[1] == p[1] && q[2] == p[2];
        int r = crom_locate_point(&L, p, &t, b, &dist);
        if (in)
            continue;
        outside++;
        CHECK(r == 0);
        double x[3] = {0, 0, 0}, d = 0;
        for (int k = 0; k < 4; k++) {
            worst_b = fmax(worst_b, -b[k]);
            for (int c = 0; c < 3; c++)
                x[c] += b[k] * m.X[3 * (size_t)m.tets[4 * t + k] + c];
        }
        for (int c = 0; c < 3; c++) {
            worst = fmax(worst, fabs(x[c] - q[c]));
            d += (p[c] - q[c]) * (p[c] - q[c]);
        }
        worst_d = fmax(worst_d, fabs(sqrt(d) - dist));
    }
    printf("  outside   %d points: nearest point error %.1e, distance error %.1e, min bary %.1e\n",
           outside, worst, worst_d, -worst_b);
    CHECK(outside > 500);
    CHECK_LT(worst, 1e-12);
    CHECK_LT(worst_d, 1e-12);
    CHECK(worst_b <= 0);
    crom_locate_free(&L);
    crom_mesh_free(&m);
}

/* Lumped vertex volumes sum to the mesh volume. */
static void test_vertex_volumes(void)
{
    crom_rng rng;
    crom_rng_seed(&rng, 13);
    crom_mesh m;
    double lo[3] = {0, 0, 0};
    fx_box_mesh(&m, 3, 3, 3, lo, 1.0 / 3, 0.2, &rng, NULL);
    double *w = malloc(sizeof(double) * (size_t)m.nv), s = 0;
    double V = crom_mesh_vertex_volumes(&m, w);
    for (int v = 0; v < m.nv; v++)
        s += w[v];
    CHECK_NEAR(V, 1.0, 1e-13);
    CHECK_NEAR(s, 1.0, 1e-13);
    free(w);
    crom_mesh_free(&m);
}

static int write_model(const char *path, crom_model *m)
{
    crom_out o;
    int rc = crom_out_create(&o, path, CROM_MODEL_SCHEMA, CROM_MODEL_VERSION, NULL, NULL, CROM_OUT_PLAIN);
    if (rc)
        return rc;
    if ((rc = crom_model_write(o.h5, m))) {
        crom_out_fail(&o);
        return rc;
    }
    return crom_out_commit(&o);
}

/* A mesh-field model: W linear in X is interpolated exactly; round trip. */
static void test_mesh_model(void)
{
    crom_rng rng;
    crom_rng_seed(&rng, 14);
    crom_mesh m;
    double lo[3] = {-0.5, -0.5, -0.5};
    fx_box_mesh(&m, 4, 4, 4, lo, 0.25, 0.15, &rng, NULL);
    int r = 3;
    double *B = malloc(sizeof(double) * 3 * r * (size_t)m.nv);
    /* field j, component c: (j + 1) X_c + (c - j) X_{(c+1)%3} + 0.1 j */
    for (int v = 0; v < m.nv; v++)
        for (int c = 0; c < 3; c++)
            for (int j = 0; j < r; j++)
                B[((size_t)v * 3 + c) * r + j] =
                    (j + 1) * m.X[3 * v + c] + (c - j) * m.X[3 * v + (c + 1) % 3] + 0.1 * j;
    crom_model M;
    CHECK(crom_model_from_mesh(&M, "pod", &m, B, r) == 0);
    int n = 300;
    double *X = malloc(sizeof(double) * 3 * n), *W = malloc(sizeof(double) * 3 * r * n);
    for (int i = 0; i < n; i++)
        random_in_tet(&m, (int)crom_rng_below(&rng, (uint64_t)m.nt), &rng, X + 3 * i);
    size_t nout = 9;
    CHECK(crom_model_eval(&M, (size_t)n, X, W, &nout) == 0);
    CHECK(nout == 0);
    double worst = 0;
    for (int i = 0; i < n; i++)
        for (int c = 0; c < 3; c++)
            for (int j = 0; j < r; j++) {
                double e = (j + 1) * X[3 * i + c] + (c - j) * X[3 * i + (c + 1) % 3] + 0.1 * j;
                worst = fmax(worst, fabs(W[((size_t)i * 3 + c) * r + j] - e));
            }
    printf("mesh-field model: linear basis interpolated with error %.1e, model_id %s\n", worst, M.model_id);
    CHECK_LT(worst, 1e-12);
    char path[256];
    snprintf(path, sizeof path, "%s/pod.h5", dir);
    CHECK(write_model(path, &M) == 0);
    crom_model R;
    CHECK(crom_model_load(path, &R) == 0);
    CHECK(!strcmp(R.model_id, M.model_id) && R.rank == r && R.field == CROM_MODEL_FIELD_MESH);
    double *W2 = malloc(sizeof(double) * 3 * r * n);
    CHECK(crom_model_eval(&R, (size_t)n, X, W2, NULL) == 0);
    CHECK(memcmp(W, W2, sizeof(double) * 3 * r * n) == 0);
    /* the id follows the parameters */
    char id[17];
    R.basis_v[5] += 1e-9;
    CHECK(strcmp(crom_model_id(&R, id), M.model_id) != 0);
    crom_model_free(&R);
    /* a point outside gets the nearest boundary value */
    double p[3] = {0.9, 0.1, 0.2}, q[3] = {0.5, 0.1, 0.2}, Wp[9], Wq[9];
    CHECK(crom_model_eval(&M, 1, p, Wp, &nout) == 0 && nout == 1);
    CHECK(crom_model_eval(&M, 1, q, Wq, NULL) == 0);
    CHECK(check_relerr(Wp, Wq, 9, 1e-30) < 1e-12);
    free(B);
    free(X);
    free(W);
    free(W2);
    crom_model_free(&M);
    crom_mesh_free(&m);
}

/* An MLP model with a PointNet: round trip, bitwise evaluation, model_id
 * check on reading a changed file. */
static void test_mlp_model(void)
{
    crom_rng rng;
    crom_rng_seed(&rng, 15);
    int r = 4, widths[] = {3, 10, 10, 3 * 4};
    crom_nn_spec spec, ps, hs;
    CHECK(crom_nn_spec_set(&spec, 4, widths, CROM_NN_ELU) == 0);
    crom_nn_mlp W;
    CHECK(crom_nn_mlp_init(&W, &spec, NULL, &rng) == 0);
    float sh[3] = {0.1f, -0.2f, 0.3f}, sc[3] = {0.5f, 0.75f, 2.0f};
    CHECK(crom_nn_mlp_set_norm(&W, sh, sc) == 0);
    const int pw[] = {6, 8, 12}, hw[] = {12, 8, 4};
    CHECK(crom_nn_pointnet_spec(&ps, &hs, 3, pw, 3, hw) == 0);
    crom_nn_pointnet P;
    CHECK(crom_nn_pointnet_init(&P, &ps, &hs, NULL, &rng) == 0);
    float psh[6] = {0, 0, 0, 0.01f, 0, 0}, psc[6] = {1, 1, 1, 0.05f, 0.05f, 0.05f};
    CHECK(crom_nn_mlp_set_norm(&P.point, psh, psc) == 0);
    crom_model M;
    CHECK(crom_model_from_mlp(&M, &W, NULL, &P) == 0);
    CHECK(M.rank == r && M.encoder == CROM_MODEL_ENC_POINTNET);
    M.reconstruction_error = 0.125;
    M.nepochs = 2;
    M.loss = malloc(2 * sizeof(double));
    M.seconds = malloc(2 * sizeof(double));
    M.loss[0] = 1, M.loss[1] = 0.5, M.seconds[0] = 0, M.seconds[1] = 0;
    int n = 50;
    double X[150], Wa[50 * 12], Wb[50 * 12], pts[50 * 6], qa[4], qb[4];
    for (int i = 0; i < 3 * n; i++)
        X[i] = 2 * crom_rng_uniform(&rng) - 1;
    for (int i = 0; i < n; i++)
        for (int c = 0; c < 3; c++) {
            pts[6 * i + c] = X[3 * i + c];
            pts[6 * i + 3 + c] = 0.01 * X[3 * i + (c + 1) % 3];
        }
    CHECK(crom_model_eval(&M, (size_t)n, X, Wa, NULL) == 0);
    CHECK(crom_model_encode_pointnet(&M, (size_t)n, pts, qa) == 0);
    /* layout: W(X)[c][j] is output c*r + j of the network */
    double y[12];
    crom_nn_ws ws;
    CHECK(crom_nn_ws_init(&ws, &W, 1, 1) == 0);
    CHECK(crom_nn_mlp_eval(&W, &ws, 1, X, y, NULL) == 0);
    CHECK(memcmp(y, Wa, sizeof y) == 0);
    crom_nn_ws_free(&ws);
    char path[256];
    snprintf(path, sizeof path, "%s/mlp.h5", dir);
    CHECK(write_model(path, &M) == 0);
    crom_model R;
    CHECK(crom_model_load(path, &R) == 0);
    CHECK(!strcmp(R.model_id, M.model_id));
    CHECK(R.encoder == CROM_MODEL_ENC_POINTNET && R.rank == r && R.mlp.spec.act == CROM_NN_ELU);
    CHECK(R.reconstruction_error == 0.125);
    CHECK(crom_model_eval(&R, (size_t)n, X, Wb, NULL) == 0);
    CHECK(memcmp(Wa, Wb, sizeof Wa) == 0);
    CHECK(crom_model_encode_pointnet(&R, (size_t)n, pts, qb) == 0);
    CHECK(memcmp(qa, qb, sizeof qa) == 0);
    printf("mlp model: round trip bitwise, model_id %s\n", M.model_id);
    crom_model_free(&R);
    /* change one parameter in the file: reading must fail on the model_id */
    hid_t f = H5Fopen(path, H5F_ACC_RDWR, H5P_DEFAULT);
    hid_t d = H5Dopen2(f, "field/params", H5P_DEFAULT);
    hsize_t one = 1, at = 3;
    hid_t fs = H5Dget_space(d), ms = H5Screate_simple(1, &one, NULL);
    H5Sselect_elements(fs, H5S_SELECT_SET, 1, &at);
    float v = 0.5f;
    H5Dwrite(d, H5T_NATIVE_FLOAT, ms, fs, H5P_DEFAULT, &v);
    H5Sclose(ms);
    H5Sclose(fs);
    H5Dclose(d);
    H5Fclose(f);
    CHECK(crom_model_load(path, &R) == CROM_EDATA);
    CHECK_MSG(strstr(crom_errmsg(), "does not match the basis parameters") != NULL, "%s", crom_errmsg());
    crom_model_free(&M);
    crom_nn_mlp_free(&W);
    crom_nn_pointnet_free(&P);
}

/* A field with cut features: round trip, its features in the digest, and
 * a file whose cut does not fit its network refused. */
static void test_cut_model(void)
{
    crom_rng rng;
    crom_rng_seed(&rng, 16);
    int widths[] = {5, 8, 3 * 2};
    crom_nn_spec spec;
    CHECK(crom_nn_spec_set(&spec, 3, widths, CROM_NN_ELU) == 0);
    crom_nn_mlp W;
    CHECK(crom_nn_mlp_init(&W, &spec, NULL, &rng) == 0);
    crom_cutfeat cut = {1, 2, {{0, -0.3, 0, 0}, {0, 0, 0.2, 0.25}}};
    crom_model M, N, R;
    CHECK(crom_model_from_mlp(&M, &W, NULL, NULL) == CROM_EUSAGE); /* 5 inputs need 2 features */
    CHECK(crom_model_from_mlp(&M, &W, &cut, NULL) == 0);
    cut.seg[1][3] = 0.3;
    CHECK(crom_model_from_mlp(&N, &W, &cut, NULL) == 0);
    CHECK(strcmp(M.model_id, N.model_id) != 0); /* the cut is part of the basis */
    crom_model_free(&N);
    double X[3 * 20], Wa[20 * 6], Wb[20 * 6], S[3 * 20];
    for (int i = 0; i < 60; i++) {
        X[i] = crom_rng_uniform(&rng) - 0.5;
        S[i] = -X[i];
    }
    CHECK(crom_model_eval(&M, 20, X, Wa, NULL) == 0);
    char path[256];
    snprintf(path, sizeof path, "%s/cut.h5", dir);
    CHECK(write_model(path, &M) == 0);
    CHECK(crom_model_load(path, &R) == 0);
    CHECK(!strcmp(R.model_id, M.model_id) && R.cut.nseg == 2 && R.cut.axis == 1);
    CHECK(crom_model_eval(&R, 20, X, Wb, NULL) == 0);
    CHECK(memcmp(Wa, Wb, sizeof Wa) == 0);
    /* sided: X's own features again when S = X; others differ */
    CHECK(crom_model_eval_sided(&R, 20, X, X, Wb, NULL) == 0);
    CHECK(memcmp(Wa, Wb, sizeof Wa) == 0);
    CHECK(crom_model_eval_sided(&R, 20, X, S, Wb, NULL) == 0);
    CHECK(memcmp(Wa, Wb, sizeof Wa) != 0);
    crom_model_free(&R);
    /* a file without its cut_axis: refused, naming it */
    hid_t f = H5Fopen(path, H5F_ACC_RDWR, H5P_DEFAULT);
    H5Adelete(f, "cut_axis");
    H5Fclose(f);
    CHECK(crom_model_load(path, &R) == CROM_EDATA);
    CHECK_MSG(strstr(crom_errmsg(), "cut_axis") != NULL, "%s", crom_errmsg());
    crom_model_free(&R);
    crom_model_free(&M);
    crom_nn_mlp_free(&W);
}

int main(void)
{
    check_begin("test_model");
    if (!mkdtemp(dir)) {
        perror("mkdtemp");
        return 1;
    }
    printf("point location: random points inside\n");
    test_locate_inside("box", NULL);
    test_locate_inside("L-shape", notch);
    test_locate_outside();
    test_vertex_volumes();
    test_mesh_model();
    test_mlp_model();
    test_cut_model();
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    if (system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", dir);
    return check_done();
}
