/* body.c — the body a data-free subspace is trained on (see body.h). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/clock.h"
#include "base/err.h"
#include "datafree/body.h"
#include "datafree/dffield.h"
#include "io/io.h"
#include "mesh/pred.h"
#include "phys/modes.h"
#include "rom/equil.h"
#include "rom/map.h"
#include "rom/result.h"
#include "phys/mderiv.h"
#include "phys/system.h"
#include "rom/skin.h"

/* ============================================================ geometry */

int crom_body_load(crom_body *b, const crom_body_source *src, const crom_scenario *sc)
{
    memset(b, 0, sizeof *b);
    crom_model_clear(&b->modes);
    if (src->mesh) {
        if (crom_mesh_load(src->mesh, CROM_MESH_SURFACES | CROM_MESH_SCENES, &b->mesh, &b->history))
            return crom_err_ctx("--mesh");
        if (b->mesh.scene && !src->scenes)
            return crom_err(CROM_EUSAGE, "--mesh %s is a rigid-body scene (%d bodies): this objective trains on "
                            "solids and shells; on a scene use --objective energy",
                            strcmp(src->mesh, "-") ? src->mesh : "stdin", b->mesh.scene->nb);
        if (crom_mesh_is_surface(&b->mesh) && !src->shells)
            return crom_err(CROM_EUSAGE, "--mesh %s is a shell surface (%d triangles): this objective trains on "
                            "solids; on a shell use --objective energy or neuralmodes, or skinning with --weights eigen",
                            strcmp(src->mesh, "-") ? src->mesh : "stdin", b->mesh.ntri);
        return 0;
    }
    for (int i = 0; i < sc->npins; i++) /* before the sampling reports anything */
        if (!crom_pred_is(sc->pins[i]))
            return crom_err(CROM_EUSAGE, "--pin %s: a surface or point cloud has no named regions; give a predicate "
                            "such as 'x<-0.49'", sc->pins[i]);
    int rc = src->surface ? crom_cloud_from_surface(src->surface, src->sample_points ? src->sample_points : 8192,
                                                    src->seed ^ 0xc10d, &b->cloud)
                          : crom_cloud_read(src->cloud, &b->cloud);
    if (rc)
        return crom_err_ctx(src->surface ? "--surface" : "--cloud");
    return crom_cloud_stencils(&b->cloud, src->seed ^ 0x57e1, &b->mesh);
}

void crom_body_free(crom_body *b)
{
    crom_mesh_free(&b->mesh);
    crom_cloud_free(&b->cloud);
    crom_model_free(&b->modes);
    free(b->deriv);
    free(b->history);
    free(b->fixed);
    free(b->pinX);
    free(b->triX);
    free(b->W);
    free(b->freq);
    crom_result_equilibria_free(&b->eq);
    free(b->visit);
    free(b->seed);
    crom_model_free(&b->init);
    memset(b, 0, sizeof *b);
}

int crom_body_supervise(crom_body *b, const char *path, int rank, crom_datafree_problem *P)
{
    int rc = crom_result_equilibria_load(path, &b->eq);
    if (rc)
        return crom_err_ctx("--supervised");
    if (crom_map_same_mesh(&b->eq.mesh, &b->mesh))
        return crom_err(CROM_EUSAGE, "--supervised %s: the equilibria live on another mesh", path);
    if (b->eq.r != rank)
        return crom_err(CROM_EUSAGE, "--supervised %s: equilibria in %d modal coordinates for a map of rank %d", path,
                        b->eq.r, rank);
    P->nsup = b->eq.K;
    P->sup_z = b->eq.Z;
    P->sup_u = b->eq.U;
    return 0;
}

int crom_body_visit(crom_body *b, const char *path, int rank, crom_datafree_problem *P)
{
    if (crom_equil_latents(path, rank, &b->visit, &b->nvisit))
        return crom_err_ctx("--latents");
    const char *base = strrchr(path, '/');
    snprintf(b->visit_what, sizeof b->visit_what, "%ld modal coordinates of %s", b->nvisit, base ? base + 1 : path);
    P->nvisit = b->nvisit;
    P->visit_z = b->visit;
    return 0;
}

/* frames a seed state may be from the end of a stream (a ring of them is kept) */
#define SEED_RING 64

int crom_body_seed(crom_body *b, const char *path, long frame, crom_datafree_problem *P)
{
    crom_result res;
    int rc = crom_result_open(&res, path, NULL, NULL), got = 0;
    if (rc)
        return crom_err_ctx("--seed-state");
    size_t n = 3 * (size_t)b->mesh.nv;
    long k = 0, want = frame;
    double t, *u = NULL, *ring = NULL;
    if (crom_map_same_mesh(&res.mesh, &b->mesh))
        rc = crom_err(CROM_EUSAGE, "--seed-state %s: a trajectory of another mesh", path);
    else if (res.latent)
        rc = crom_err(CROM_EUSAGE, "--seed-state %s: a latent, not a full state (decode it with crom-export --vtu "
                                   "or give crom-fullsim's run)", path);
    else if (frame < 0 && res.in.form == CROM_IO_H5) { /* a file knows its length: count from the start */
        if (frame + res.in.nframes < 0)
            rc = crom_err(CROM_EUSAGE, "--seed-frame %ld: %s has %ld frames", frame, path, res.in.nframes);
        want = frame = frame + res.in.nframes;
    } else if (frame < -SEED_RING)
        rc = crom_err(CROM_EUSAGE, "--seed-frame %ld: a stream is read once, so at most %d frames from its end",
                      frame, SEED_RING);
    /* a stream's last -frame frames in a ring (frame < 0), or up to frame */
    long keep = frame < 0 ? -frame : 1;
    if (!rc && !(ring = crom_malloc(sizeof(double) * n * (size_t)keep)))
        rc = CROM_EINTERNAL;
    while (!rc && (frame < 0 || k <= want) && (got = crom_result_next(&res, &t, ring + n * (size_t)(k % keep), NULL)) == 1)
        k++;
    if (!rc && got > 1)
        rc = crom_err_ctx("--seed-state");
    else if (!rc && (frame < 0 ? k < keep : k <= want))
        rc = crom_err(CROM_EUSAGE, "--seed-frame %ld: %s has %ld frames", frame, path, k);
    if (!rc) {
        long at = frame < 0 ? k + frame : want;
        if (!(u = crom_malloc(sizeof(double) * n)))
            rc = CROM_EINTERNAL;
        else
            memcpy(u, ring + n * (size_t)(at % keep), sizeof(double) * n);
        const char *base = strrchr(path, '/');
        snprintf(b->seed_what, sizeof b->seed_what, "frame %ld of %s", at, base ? base + 1 : path);
    }
    free(ring);
    crom_result_close(&res);
    if (rc)
        return rc;
    free(b->seed);
    b->seed = u;
    P->seed = u;
    return 0;
}

int crom_body_refine(crom_body *b, const char *path, const char *latents, int rank, const char *basis,
                     crom_datafree_problem *P)
{
    crom_model *m = &b->init;
    crom_model_free(m);
    int rc = crom_model_load(path, m);
    if (rc)
        return crom_err_ctx("--init-model");
    b->init_path = path;
    int skin = !strcmp(basis, "skin-field"), cfield = !strcmp(basis, "energy-field");
    if (strcmp(m->basis, basis))
        return crom_err(CROM_EUSAGE, "--init-model %s is a %s model, not %s", path, m->basis,
                        skin ? "a field over skinning eigenmodes (skin-field)" :
                        cfield ? "a continuous field with a trained W(X) (energy-field)" : "an energy map");
    if (!cfield && crom_map_same_mesh(&m->mesh, &b->mesh)) /* (a trained W(X) lays on any mesh of the body) */
        return crom_err(CROM_EUSAGE, "--init-model %s maps another mesh", path);
    if (m->rank != rank)
        return crom_err(CROM_EUSAGE, "--init-model %s has rank %d, not %d", path, m->rank, rank);
    int same = m->ncond == P->ncond;
    for (int k = 0; same && k < m->ncond; k++)
        same = crom_scenario_cond_same(&m->cond[k], &P->cond[k]) && m->cond[k].lo == P->cond[k].lo &&
               m->cond[k].hi == P->cond[k].hi;
    if (!same)
        return crom_err(CROM_EUSAGE, "--init-model %s was trained over other conditions (give its --condition flags)",
                        path);
    if (P->seed)
        return crom_err(CROM_EUSAGE, "--init-model brings its own seed state: drop --seed-state");
    P->init = skin || cfield ? &m->latent : &m->mlp;
    P->init_field = cfield ? &m->mlp : NULL;
    P->seed = m->seed_v;
    if (m->seed_v)
        snprintf(b->seed_what, sizeof b->seed_what, "the seed state of model %s", m->model_id);
    if (!latents)
        return 0;
    crom_in in;
    char *id = NULL;
    if ((rc = crom_in_open(&in, latents)))
        return crom_err_ctx("--latents");
    if ((rc = crom_in_expect(&in, "crom/latent", 1)) || (rc = crom_h5_get_str(in.h5, ".", "model_id", &id)))
        crom_err_ctx("--latents");
    else if (strcmp(id, m->model_id))
        rc = crom_err(CROM_EUSAGE, "--latents %s is a run of model %s, not of --init-model %s (%s)", latents, id, path,
                      m->model_id);
    free(id);
    crom_in_close(&in);
    return rc ? rc : crom_body_visit(b, latents, rank, P);
}

double crom_body_volume(const crom_body *b)
{
    return b->cloud.n ? b->cloud.volume : crom_mesh_volume(&b->mesh);
}

double crom_body_mass(const crom_body *b) { return b->mat.rho * crom_body_volume(b); }

/* ============================================================ the modes */

/* The pins recorded in a scenario text, appended to sc (without repeats). */
static int add_pins(crom_scenario *sc, const char *text)
{
    crom_scenario tmp;
    crom_scenario_defaults(&tmp);
    int rc = crom_scenario_parse_text(text, &tmp);
    for (int i = 0; !rc && i < tmp.npins; i++) {
        int dup = 0;
        for (int j = 0; j < sc->npins; j++)
            dup |= !strcmp(sc->pins[j], tmp.pins[i]);
        if (dup)
            continue;
        if (sc->npins == CROM_SCENARIO_MAX)
            return crom_err(CROM_EUSAGE, "too many pins (at most %d)", CROM_SCENARIO_MAX);
        snprintf(sc->pins[sc->npins++], sizeof sc->pins[0], "%s", tmp.pins[i]);
    }
    return rc;
}

int crom_body_load_modes(crom_body *b, const char *path, const char *mesh_name, int *rank, crom_scenario *sc,
                         int material_given, int *differs)
{
    crom_model *m = &b->modes;
    if (differs)
        *differs = 0;
    b->modes_path = path;
    if (crom_model_load(path, m))
        return crom_err_ctx("--modes");
    if (strcmp(m->basis, "modes"))
        return crom_err(CROM_EDATA, "--modes %s is a '%s' model; neuralmodes builds on linear vibration modes "
                        "(basis 'modes', from crom-modes)", path, m->basis);
    if (crom_map_same_mesh(&m->mesh, &b->mesh))
        return crom_err(CROM_EDATA, "--modes %s was computed on another mesh (%d vertices, %d tets) than --mesh %s "
                        "(%d vertices, %d tets)", path, m->mesh.nv, m->mesh.nt, mesh_name, b->mesh.nv, b->mesh.nt);
    if (*rank <= 0)
        *rank = m->rank;
    else if (*rank > m->rank)
        return crom_err(CROM_EUSAGE, "--rank %d: --modes %s has only %d modes", *rank, path, m->rank);
    if (!material_given && isfinite(m->youngs) && isfinite(m->poisson) && isfinite(m->density)) {
        sc->youngs = m->youngs;
        sc->poisson = m->poisson;
        sc->density = m->density;
    } else if (differs && isfinite(m->youngs) &&
               (m->youngs != sc->youngs || m->poisson != sc->poisson || m->density != sc->density)) {
        *differs = 1;
    }
    return add_pins(sc, m->scenario);
}

/* The lowest r modes [nv][3][r] and their frequencies; they must not move
 * a pinned vertex. */
static int take_modes(crom_body *b, int r)
{
    const crom_model *m = &b->modes;
    int n = 3 * b->mesh.nv;
    b->W = crom_malloc(sizeof(double) * (size_t)n * r);
    b->freq = crom_malloc(sizeof(double) * (size_t)r);
    if (!b->W || !b->freq)
        return CROM_EINTERNAL;
    for (int i = 0; i < n; i++)
        for (int k = 0; k < r; k++) {
            double w = m->basis_v[(size_t)i * m->rank + k];
            b->W[(size_t)i * r + k] = w;
            if (b->fixed[i] && w != 0)
                return crom_err(CROM_EDATA, "--modes %s moves vertex %d, which is pinned here: compute the modes "
                                "with the same --pin", b->modes_path, i / 3);
        }
    for (int k = 0; k < r; k++)
        b->freq[k] = m->frequencies ? m->frequencies[k] : 0;
    return 0;
}

/* ============================================================ problems */

int crom_body_pins(crom_body *b, const crom_scenario *sc, int cloud_pins)
{
    int rc = crom_scenario_check(sc);
    if (!rc)
        rc = crom_material_init(&b->mat, sc->youngs, sc->poisson, sc->density);
    if (rc)
        return rc;
    const char *refs[CROM_SCENARIO_MAX];
    for (int i = 0; i < sc->npins; i++)
        refs[i] = sc->pins[i];
    if (cloud_pins && b->cloud.n &&
        (rc = crom_cloud_pins(&b->cloud, sc->npins, refs, &b->npin, &b->pinX, &b->ntri, &b->triX)))
        return rc;
    return crom_modes_pins(&b->mesh, sc->npins, refs, &b->fixed, &b->npinned);
}

int crom_body_map_problem(crom_body *b, const crom_scenario *sc, int objective, int rank,
                          crom_datafree_problem *P)
{
    int nm = objective == CROM_DATAFREE_NEURALMODES, rc;
    if (nm && (rc = take_modes(b, rank)))
        return rc;
    *P = (crom_datafree_problem){.mesh = &b->mesh, .mat = b->mat, .gravity = {sc->gravity[0], sc->gravity[1],
                                 sc->gravity[2]}, .fixed = b->fixed, .modes = b->W, .freq = b->freq,
                                 .materials = sc->nmat ? sc : NULL};
    if (nm) /* nonlinear modes are equilibria of the elastic energy alone */
        P->gravity[0] = P->gravity[1] = P->gravity[2] = 0;
    return 0;
}

int crom_body_derivatives(crom_body *b, crom_datafree_problem *P, int rank)
{
    crom_system sys;
    int rc = crom_system_init(&sys, &b->mesh, b->mat.E, b->mat.nu, b->mat.rho);
    if (!rc && P->materials)
        rc = crom_system_set_materials(&sys, P->materials, &b->mesh);
    if (rc) {
        crom_system_free(&sys);
        return rc;
    }
    free(b->deriv);
    b->deriv = crom_malloc(sizeof(double) * 3 * (size_t)b->mesh.nv * ((size_t)rank * (rank + 1) / 2));
    rc = b->deriv ? crom_mderiv_compute(&sys, b->mesh.X, b->fixed, b->W, rank, b->deriv) : CROM_EINTERNAL;
    crom_system_free(&sys);
    P->deriv = rc ? NULL : b->deriv;
    return rc;
}

int crom_body_train_skin(const crom_body *b, const crom_scenario *materials, const crom_dfskin_opts *o,
                         crom_model *out, crom_dftrain_log *log)
{
    int rc;
    if (b->cloud.n && (rc = crom_dfskin_check_handles(&b->mesh, b->fixed, o->handles)))
        return rc;
    crom_dfskin_problem P = {&b->mesh, b->mat, b->fixed, b->cloud.n > 0, b->npin, b->pinX, b->ntri, b->triX,
                             materials};
    return crom_dfskin_train(&P, o, out, log);
}

int crom_body_skin_coordinates(const crom_body *b, crom_model *m, double tol)
{
    if (b->cloud.n)
        return crom_skin_orthonormalize(m, (size_t)b->cloud.n, b->cloud.X, b->cloud.vol, tol);
    double *vv = crom_malloc(sizeof(double) * (size_t)b->mesh.nv);
    if (!vv)
        return CROM_EINTERNAL;
    crom_mesh_vertex_volumes(&b->mesh, vv);
    int rc = crom_skin_orthonormalize(m, (size_t)b->mesh.nv, b->mesh.X, vv, tol);
    free(vv);
    return rc;
}

/* Whether the skinning basis [nv][3][p] at b's vertices is that of the
 * skin-field b refines (b->init): the eigensolve is deterministic, so the
 * same mesh, material, pins and handles give it again. */
static int same_basis(const crom_body *b, const double *basis, int p)
{
    const crom_model *m = &b->init;
    size_t n = 3 * (size_t)b->mesh.nv * p;
    int pm = m->latent.spec.width[m->latent.spec.nlayers];
    if (pm != p)
        return crom_err(CROM_EUSAGE, "--init-model %s is a field over another skinning basis (%d functions, not %d: "
                        "other --handles?)", b->init_path, pm, p);
    double *w = crom_malloc(sizeof(double) * n), d = 0, s = 0;
    int rc = w ? crom_skin_eval(m, (size_t)b->mesh.nv, b->mesh.X, w, NULL) : CROM_EINTERNAL;
    for (size_t i = 0; !rc && i < n; i++) {
        d = fmax(d, fabs(w[i] - basis[i]));
        s = fmax(s, fabs(basis[i]));
    }
    free(w);
    if (!rc && !(d <= 1e-8 * s))
        rc = crom_err(CROM_EUSAGE, "--init-model %s is a field over another skinning basis (%.3g apart: other "
                      "material or pins?)", b->init_path, d / s);
    return rc;
}

int crom_body_train_skin_field(const crom_body *b, const crom_datafree_problem *P, const crom_datafree_opts *o,
                               int H, crom_model *out, crom_dftrain_log *log, long *solves)
{
    crom_nn_mlp phi;
    memset(&phi, 0, sizeof phi);
    double t0 = crom_clock_now();
    int rc = crom_dfskin_eigen(&b->mesh, &b->mat, P->materials, b->fixed, H, out, solves);
    if (!rc)
        rc = crom_body_skin_coordinates(b, out, 1e-6);
    int p = out->rank, nv = b->mesh.nv;
    double *basis = rc ? NULL : crom_malloc(sizeof(double) * 3 * (size_t)nv * p);
    if (!rc && !basis)
        rc = CROM_EINTERNAL;
    if (!rc)
        rc = crom_skin_eval(out, (size_t)nv, b->mesh.X, basis, NULL);
    if (!rc && P->init) /* refining: the basis of the field it starts from, to round-off */
        rc = same_basis(b, basis, p);
    if (!rc)
        rc = crom_dffield_train_latent(P, o, basis, p, &phi, log);
    if (!rc)
        rc = crom_model_skin_field(out, &phi);
    if (!rc) /* the eigensolve and the training */
        out->training_seconds = crom_clock_wall(crom_clock_now() - t0);
    free(basis);
    crom_nn_mlp_free(&phi);
    return rc;
}

/* ============================================================ the record */

/* The material (its regions of other materials too), the gravity (if
 * asked) and the pins of sc as flags, one per line, and the material, into
 * m. */
static int provenance(crom_model *m, const crom_scenario *s, int gravity)
{
    size_t cap = 512 + (size_t)s->npins * 140 + (size_t)s->nmat * 340;
    char *t = crom_malloc(cap);
    if (!t)
        return CROM_EINTERNAL;
    size_t l = (size_t)snprintf(t, cap, "--youngs %.17g\n--poisson %.17g\n--density %.17g\n", s->youngs, s->poisson,
                                s->density);
    l += crom_scenario_material_flags(s, t + l, cap - l);
    if (gravity)
        l += (size_t)snprintf(t + l, cap - l, "--gravity %.17g,%.17g,%.17g\n", s->gravity[0], s->gravity[1],
                              s->gravity[2]);
    for (int i = 0; i < s->npins; i++)
        l += (size_t)snprintf(t + l, cap - l, "--pin %s\n", s->pins[i]);
    free(m->scenario);
    m->scenario = t;
    m->youngs = s->youngs;
    m->poisson = s->poisson;
    m->density = s->density;
    return 0;
}

/* Record sc in m (gravity if asked), create the output at path and write
 * m into it; on failure nothing is left behind. */
static int create(const crom_body *b, const crom_scenario *sc, int gravity, crom_model *m, const char *path,
                  const char *cmdline, crom_out *out)
{
    int rc = provenance(m, sc, gravity);
    if (!rc)
        rc = crom_out_create(out, path, CROM_MODEL_SCHEMA, CROM_MODEL_VERSION, cmdline, b->history, CROM_OUT_PLAIN);
    if (!rc && (rc = crom_model_write(out->h5, m)))
        crom_out_fail(out);
    return rc;
}

/* Commit out if rc is 0, else drop it. */
static int finish(crom_out *out, int rc)
{
    if (!rc)
        return crom_out_commit(out);
    crom_out_fail(out);
    return rc;
}

int crom_body_write_map(const crom_body *b, const crom_scenario *sc, crom_model *m, const crom_datafree_opts *o,
                        const crom_datafree_problem *P, const crom_dftrain_log *log, const char *path,
                        const char *cmdline)
{
    int nm = o->objective == CROM_DATAFREE_NEURALMODES;
    crom_out out;
    int rc = create(b, sc, !nm, m, path, cmdline, &out);
    if (rc)
        return rc;
    rc = crom_datafree_write_record(out.h5, o, P, log, crom_body_mass(b), nm ? b->modes.model_id : NULL);
    if (!rc && nm && P->nsup > 0) {
        char what[96];
        snprintf(what, sizeof what, "%d constrained equilibria in the modes %s", b->eq.K, b->eq.model_id);
        rc = crom_h5_set_str(out.h5, ".", "supervised", what);
    }
    if (!rc && P->nvisit > 0)
        rc = crom_h5_set_str(out.h5, ".", "sampled_along", b->visit_what);
    if (!rc && P->init)
        rc = crom_h5_set_str(out.h5, ".", "refined_from", b->init.model_id);
    if (!rc && P->seed)
        rc = crom_h5_set_str(out.h5, ".", "seed_state", b->seed_what);
    return finish(&out, rc);
}

int crom_body_write_skin(const crom_body *b, const crom_scenario *sc, crom_model *m, const crom_dfskin_opts *o,
                         const crom_dftrain_log *log, const char *path, const char *cmdline)
{
    crom_out out;
    int rc = create(b, sc, 0, m, path, cmdline, &out);
    if (rc)
        return rc;
    return finish(&out, crom_dfskin_write_record(out.h5, o, log, crom_body_mass(b)));
}
