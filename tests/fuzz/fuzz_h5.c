/* fuzz_h5.c — the readers of crom's HDF5 files, one harness per kind (built
 * with -DFUZZ_KIND=...): the input is a file, opened by crom_in_open
 * (lib/io/io.c) and read by the module reader the programs use, then used a
 * little the way the programs use it, then freed.
 *
 *   fuzz_mesh      crom_mesh_load (a crom/mesh, or the /mesh of a trajectory
 *                  or cubature: carriers on), then volume and boundary
 *   fuzz_traj      crom_result_open + crom_result_next to the end (a
 *                  crom/trajectory: crom-export, crom-diff)
 *   fuzz_samples   crom_samples_read (crom-fitfield's training data)
 *   fuzz_model     crom_model_load (every basis: mlp, pod, modes, skinning,
 *                  data-free maps), then W at a few points
 *   fuzz_cubature  crom_cubature_load, then every cubature tet gathered (a shell's: its elements checked)
 *   fuzz_check     crom_validate_file (crom-info --check) on any crom file
 */
#include <math.h>

#include "base/err.h"
#include "io/io.h"
#include "mesh/mesh.h"
#include "rom/cubature.h"
#include "rom/model.h"
#include "rom/result.h"
#include "rom/samples.h"
#include "view/validate.h"

#include "fuzz.h"

/* macros, not an enum: #if compares them */
#define KIND_MESH 1
#define KIND_TRAJ 2
#define KIND_SAMPLES 3
#define KIND_MODEL 4
#define KIND_CUBATURE 5
#define KIND_CHECK 6
#ifndef FUZZ_KIND
#error "build with -DFUZZ_KIND=KIND_MESH (or another KIND_*)"
#endif

static FILE *devnull;

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc;
    (void)argv;
    fuzz_quiet_stdout();
    devnull = fopen("/dev/null", "w");
    if (!devnull)
        abort();
    return 0;
}

__attribute__((unused)) static void mesh_use(const crom_mesh *m)
{
    for (size_t j = 0; j < 4 * (size_t)m->nt; j++)
        if (m->tets[j] < 0 || m->tets[j] >= m->nv) {
            fprintf(stderr, "a mesh that was read has tet vertex %d of %d\n", m->tets[j], m->nv);
            abort();
        }
    for (size_t j = 0; j < 3 * (size_t)m->ntri; j++)
        if (m->tris[j] < 0 || m->tris[j] >= m->nv) {
            fprintf(stderr, "a mesh that was read has triangle vertex %d of %d\n", m->tris[j], m->nv);
            abort();
        }
    (void)crom_mesh_volume(m);
    int ntri = 0, *tris = NULL, *tri_tet = NULL;
    if (crom_mesh_boundary(m, &ntri, &tris, &tri_tet) == 0) {
        free(tris);
        free(tri_tet);
    }
}

#if FUZZ_KIND == KIND_MESH
static void run(const char *path)
{
    crom_mesh m;
    memset(&m, 0, sizeof m);
    char *history = NULL;
    if (crom_mesh_load(path, CROM_MESH_CARRIERS | CROM_MESH_SURFACES, &m, &history) == 0)
        mesh_use(&m);
    crom_mesh_free(&m);
    free(history);
}
#elif FUZZ_KIND == KIND_TRAJ
static void run(const char *path)
{
    crom_result res;
    if (crom_result_open(&res, path, NULL, NULL) != 0)
        return;
    size_t n = 3 * (size_t)res.mesh.nv;
    double *u = malloc((n ? n : 1) * sizeof *u), *v = malloc((n ? n : 1) * sizeof *v), t;
    if (u && v)
        while (crom_result_next(&res, &t, u, v) == 1)
            ;
    free(u);
    free(v);
    crom_result_close(&res);
}
#elif FUZZ_KIND == KIND_SAMPLES
static void run(const char *path)
{
    crom_in in;
    if (crom_in_open(&in, path) != 0)
        return;
    crom_samples s;
    memset(&s, 0, sizeof s);
    if (crom_in_expect(&in, "crom/samples", 1) == 0 && crom_samples_read(&in, &s) == 0)
        (void)crom_samples_nonzero_frames(&s);
    crom_samples_free(&s);
    crom_in_close(&in);
}
#elif FUZZ_KIND == KIND_MODEL
static void run(const char *path)
{
    crom_model m;
    if (crom_model_load(path, &m) == 0 && m.rank > 0) {
        double X[2][3] = {{0, 0, 0}, {0.1, -0.2, 0.3}};
        double *W = malloc(2 * 3 * (size_t)m.rank * sizeof *W);
        if (W)
            (void)crom_model_eval(&m, 2, &X[0][0], W, NULL);
        free(W);
    }
    crom_model_free(&m);
}
#elif FUZZ_KIND == KIND_CUBATURE
static void run(const char *path)
{
    crom_cubature c;
    memset(&c, 0, sizeof c);
    if (crom_cubature_load(path, &c, NULL) == 0) {
        mesh_use(&c.mesh);
        double Xe[12], Dminv[9], *W4 = malloc(12 * (size_t)(c.r > 0 ? c.r : 1) * sizeof *W4);
        int shell = crom_mesh_is_surface(&c.mesh), ne = shell ? c.ne : c.mesh.nt; /* a shell: its energy elements */
        for (int k = 0; W4 && k < c.k; k++) {
            if (c.elem[k] < 0 || c.elem[k] >= ne) {
                fprintf(stderr, "cubature element %d is %d of %d\n", k, c.elem[k], ne);
                abort();
            }
            if (!shell) /* a shell's cubature has no rest shapes of tets */
                crom_cubature_gather(&c, k, Xe, W4, Dminv);
        }
        free(W4);
    }
    crom_cubature_free(&c);
}
#elif FUZZ_KIND == KIND_CHECK
static void run(const char *path)
{
    crom_in in;
    if (crom_in_open(&in, path) != 0)
        return;
    (void)crom_validate_file(&in, devnull);
    crom_in_close(&in);
}
#endif

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    run(fuzz_write(data, size, ".h5"));
    if (getenv("CROM_FUZZ_VERBOSE")) /* why an input was refused */
        fprintf(stderr, "%s\n", *crom_errmsg() ? crom_errmsg() : "read");
    crom_err_clear();
    return 0;
}
