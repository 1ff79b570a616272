/* skin.c — the skinning-handle subspace as a linear basis (see skin.h). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <lapacke.h>

#include "base/err.h"
#include "io/io.h"
#include "mesh/locate.h"
#include "rom/skin.h"

/* ------------------------------------------------------------ the frame */

int crom_skin_frame(size_t n, const double *X, const double *m, double F[12])
{
    double mt = 0, c[3] = {0, 0, 0}, S[9] = {0};
    for (size_t i = 0; i < n; i++) {
        if (!isfinite(m[i]) || m[i] < 0 || !isfinite(X[3 * i]) || !isfinite(X[3 * i + 1]) || !isfinite(X[3 * i + 2]))
            return crom_err(CROM_EDATA, "point %zu has a non-finite position or a bad mass", i);
        mt += m[i];
        for (int k = 0; k < 3; k++)
            c[k] += m[i] * X[3 * i + k];
    }
    if (!(mt > 0))
        return crom_err(CROM_EDATA, "the body has no mass");
    for (int k = 0; k < 3; k++)
        c[k] /= mt;
    for (size_t i = 0; i < n; i++)
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++)
                S[3 * a + b] += m[i] * (X[3 * i + a] - c[a]) * (X[3 * i + b] - c[b]) / mt;
    /* P = Σ^−½ = R Λ^−½ Rᵀ (symmetric: no choice of axes in a degenerate
     * eigenspace changes it) */
    double lam[3];
    if (LAPACKE_dsyev(LAPACK_ROW_MAJOR, 'V', 'U', 3, S, 3, lam) != 0 || !(lam[2] > 0))
        return crom_err(CROM_EDATA, "the body has no extent");
    double P[9] = {0};
    for (int k = 0; k < 3; k++) {
        double l = lam[k] > 1e-6 * lam[2] ? lam[k] : 1e-6 * lam[2];
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++)
                P[3 * a + b] += S[3 * a + k] * S[3 * b + k] / sqrt(l);
    }
    for (int a = 0; a < 3; a++) {
        F[4 * a + 3] = 0;
        for (int b = 0; b < 3; b++) {
            F[4 * a + b] = P[3 * a + b];
            F[4 * a + 3] -= P[3 * a + b] * c[b];
        }
    }
    return 0;
}

/* The 4H scalar functions φ_(4h+j) = w_h [X̂; 1]_j at X. */
static void phis(int H, const double F[12], const double *x, const double *w, double *phi)
{
    double xh[4] = {0, 0, 0, 1};
    for (int a = 0; a < 3; a++)
        xh[a] = F[4 * a] * x[0] + F[4 * a + 1] * x[1] + F[4 * a + 2] * x[2] + F[4 * a + 3];
    for (int h = 0; h < H; h++)
        for (int j = 0; j < 4; j++)
            phi[4 * h + j] = w[h] * xh[j];
}

int crom_skin_basis(int H, const double F[12], const double *C, int S, size_t n, const double *X, const double *w,
                    double *W)
{
    size_t r = C ? 3 * (size_t)S : 12 * (size_t)H;
    int A = 4 * H;
    double *phi = crom_malloc(sizeof(double) * (size_t)(A + S + 1)), *psi = phi + A;
    if (!phi)
        return CROM_EINTERNAL;
    for (size_t i = 0; i < n; i++) {
        double *Wi = W + i * 3 * r;
        memset(Wi, 0, sizeof(double) * 3 * r);
        phis(H, F, X + 3 * i, w + i * H, phi);
        if (!C) {
            for (int c = 0; c < 3; c++)
                for (int h = 0; h < H; h++)
                    for (int j = 0; j < 4; j++)
                        Wi[c * r + 12 * (size_t)h + 4 * c + j] = phi[4 * h + j];
            continue;
        }
        for (int t = 0; t < S; t++)
            psi[t] = 0;
        for (int a = 0; a < A; a++)
            if (phi[a] != 0)
                for (int t = 0; t < S; t++)
                    psi[t] += phi[a] * C[(size_t)a * S + t];
        for (int c = 0; c < 3; c++)
            for (int t = 0; t < S; t++)
                Wi[c * r + (size_t)c * S + t] = psi[t];
    }
    free(phi);
    return 0;
}

int crom_skin_coordinates(int H, int constant, const double F[12], size_t n, const double *X, const double *m,
                          const double *w, double tol, double **Cout, int *Sout)
{
    int A = 4 * H, k0 = constant ? 4 : 0, B = A - k0, rc = 0;
    *Cout = NULL;
    *Sout = 0;
    double *G = crom_calloc((size_t)A * A, sizeof(double)), *phi = crom_malloc(sizeof(double) * (size_t)A);
    double *lam = crom_malloc(sizeof(double) * (size_t)A), *C = crom_calloc((size_t)A * A, sizeof(double));
    if (!G || !phi || !lam || !C) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    /* the mass-mean Gram matrix of the φ's */
    double mt = 0;
    for (size_t i = 0; i < n; i++) {
        phis(H, F, X + 3 * i, w + i * H, phi);
        mt += m[i];
        for (int a = 0; a < A; a++)
            for (int b = a; b < A; b++)
                G[a * A + b] += m[i] * phi[a] * phi[b];
    }
    if (!(mt > 0)) {
        rc = crom_err(CROM_EDATA, "the body has no mass");
        goto out;
    }
    for (int a = 0; a < A; a++)
        for (int b = a; b < A; b++)
            G[b * A + a] = G[a * A + b] /= mt;
    for (int a = 0; a < A * A; a++)
        if (!isfinite(G[a])) {
            rc = crom_err(CROM_EDATA, "the skinning weights are not finite");
            goto out;
        }
    /* a free body: ψ_0..3 = φ_0..3 (X̂ and 1: orthonormal by the frame);
     * the rest made orthogonal to them: G' = G_BB − G_BA G_AB */
    double *Gp = G; /* the B block, overwritten in place as a B x B matrix at G */
    if (k0) {
        double *T = crom_malloc(sizeof(double) * (size_t)B * B);
        if (!T) {
            rc = CROM_EINTERNAL;
            goto out;
        }
        for (int a = 0; a < B; a++)
            for (int b = 0; b < B; b++) {
                double v = G[(k0 + a) * A + k0 + b];
                for (int k = 0; k < k0; k++)
                    v -= G[(k0 + a) * A + k] * G[k * A + k0 + b];
                T[a * B + b] = v;
            }
        /* keep G_AB (rows 0..3) for the coefficients: move it to phi-sized scratch later */
        for (int k = 0; k < k0; k++)
            for (int b = 0; b < B; b++)
                C[k * A + b] = G[k * A + k0 + b]; /* temporarily: G_AB in C's first rows */
        memcpy(G, T, sizeof(double) * (size_t)B * B);
        free(T);
    }
    int S0 = 0;
    if (B > 0) {
        if (LAPACKE_dsyev(LAPACK_ROW_MAJOR, 'V', 'U', B, Gp, B, lam) != 0) {
            rc = crom_err(CROM_EINTERNAL, "LAPACK dsyev failed on the skinning Gram matrix");
            goto out;
        }
        double lmax = lam[B - 1];
        if (!(lmax > 0) && !k0) {
            rc = crom_err(CROM_EDATA, "the skinning weights vanish over the body");
            goto out;
        }
        for (int e = B - 1; e >= 0 && lam[e] > tol * lmax && lmax > 0; e--)
            S0++;
    }
    int S = k0 + S0;
    double *Cn = crom_calloc((size_t)A * (S ? S : 1), sizeof(double));
    if (!Cn) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    for (int k = 0; k < k0; k++)
        Cn[(size_t)k * S + k] = 1;
    for (int t = 0; t < S0; t++) {
        int e = B - 1 - t; /* largest first; eigenvector e is column e of Gp */
        double f = 1 / sqrt(lam[e]);
        for (int b = 0; b < B; b++)
            Cn[(size_t)(k0 + b) * S + k0 + t] = f * Gp[b * B + e];
        for (int k = 0; k < k0; k++) { /* − G_AB v / sqrt(λ) */
            double v = 0;
            for (int b = 0; b < B; b++)
                v += C[k * A + b] * Gp[b * B + e];
            Cn[(size_t)k * S + k0 + t] = -f * v;
        }
    }
    *Cout = Cn;
    *Sout = S;
out:
    free(G);
    free(phi);
    free(lam);
    free(C);
    return rc;
}

/* ------------------------------------------------------------ the mask */

double crom_skin_mask_at(const double X[3], int npin, const double *pinX, int ntri, const double *triX,
                         double len)
{
    if (npin < 1 && ntri < 1)
        return 1;
    double d2 = INFINITY;
    for (int k = 0; k < ntri && d2 > 0; k++) {
        const double *T = triX + 9 * (size_t)k;
        double d = crom_locate_tri_dist2(T, T + 3, T + 6, X);
        d2 = d < d2 ? d : d2;
    }
    for (int k = 0; k < npin && d2 > 0; k++) {
        const double *P = pinX + 3 * (size_t)k;
        double d = (X[0] - P[0]) * (X[0] - P[0]) + (X[1] - P[1]) * (X[1] - P[1]) + (X[2] - P[2]) * (X[2] - P[2]);
        d2 = d < d2 ? d : d2;
    }
    double t = sqrt(d2) / len;
    return t >= 1 ? 1 : t * (2 - t);
}

/* ------------------------------------------------------------ evaluation */

int crom_skin_weights(const crom_model *m, size_t n, const double *X, double *w, size_t *noutside)
{
    if (noutside)
        *noutside = 0;
    if (m->field != CROM_MODEL_FIELD_SKIN)
        return crom_err(CROM_EUSAGE, "model %s is not a skinning model (basis '%s')", m->model_id, m->basis);
    int H = m->handles, k = m->skin_constant;
    if (n == 0)
        return 0;
    if (m->skin_w && crom_mesh_is_surface(&m->mesh)) {
        /* weights on a shell live at its own vertices only (as a shell's
         * mesh field, lib/rom/model.c) */
        int same = n == (size_t)m->mesh.nv;
        for (size_t i = 0; same && i < 3 * n; i++)
            same = fabs(X[i] - m->mesh.X[i]) <= 1e-9 * (1 + fabs(X[i]));
        if (!same)
            return crom_err(CROM_EDATA, "model %s (skinning weights on a shell surface of %d vertices) is evaluated "
                            "only at them, got %zu other points", m->model_id, m->mesh.nv, n);
        memcpy(w, m->skin_w, sizeof(double) * n * (size_t)H);
        return 0;
    }
    if (m->skin_w) {
        crom_locate_interp(&m->loc, n, X, H, m->skin_w, w, noutside);
        return 0;
    }
    int Ht = H - k;
    double *wt = Ht > 0 ? crom_malloc(sizeof(double) * n * (size_t)Ht) : NULL;
    if (Ht > 0 && !wt)
        return CROM_EINTERNAL;
    int rc = 0;
    if (Ht > 0) {
        crom_nn_ws ws;
        if ((rc = crom_nn_ws_init(&ws, &m->mlp, n < 4096 ? (int)n : 4096, 1))) {
            free(wt);
            return rc;
        }
        rc = crom_nn_mlp_eval(&m->mlp, &ws, n, X, wt, NULL);
        crom_nn_ws_free(&ws);
    }
    for (size_t i = 0; !rc && i < n; i++) {
        double s = crom_skin_mask_at(X + 3 * i, m->npin_points, m->pin_points, m->npin_triangles, m->pin_triangles,
                                     m->pin_length);
        if (k)
            w[i * H] = 1;
        for (int h = 0; h < Ht; h++)
            w[i * H + k + h] = s * wt[i * Ht + h];
    }
    free(wt);
    return rc;
}

int crom_skin_width(const crom_model *m) { return m->skin_C ? 3 * m->skin_S : 12 * m->handles; }

int crom_skin_eval(const crom_model *m, size_t n, const double *X, double *W, size_t *noutside)
{
    if (n == 0) {
        if (noutside)
            *noutside = 0;
        return 0;
    }
    double *w = crom_malloc(sizeof(double) * n * (size_t)m->handles);
    if (!w)
        return CROM_EINTERNAL;
    int rc = crom_skin_weights(m, n, X, w, noutside);
    if (!rc)
        rc = crom_skin_basis(m->handles, m->skin_frame, m->skin_C, m->skin_S, n, X, w, W);
    free(w);
    return rc;
}

void crom_skin_handles(const crom_model *m, const double *q, double *T)
{
    const double *F = m->skin_frame;
    int H = m->handles, S = m->skin_S;
    double Qh[12];
    for (int h = 0; h < H; h++) {
        const double *Q = q + 12 * (size_t)h;
        if (m->skin_C) { /* Q_h[c][j] = Σ_s C[4h + j][s] q[cS + s] */
            for (int c = 0; c < 3; c++)
                for (int j = 0; j < 4; j++) {
                    double v = 0;
                    for (int t = 0; t < S; t++)
                        v += m->skin_C[(size_t)(4 * h + j) * S + t] * q[(size_t)c * S + t];
                    Qh[4 * c + j] = v;
                }
            Q = Qh;
        }
        double *Th = T + 12 * (size_t)h;
        for (int c = 0; c < 3; c++)
            for (int j = 0; j < 4; j++) {
                /* (Q F̄)[c][j] = Σ_k<3 Q[c][k] F[k][j] + Q[c][3] [j == 3] */
                double v = (j == 3) ? Q[4 * c + 3] : 0;
                for (int k = 0; k < 3; k++)
                    v += Q[4 * c + k] * F[4 * k + j];
                Th[4 * c + j] = v + (c == j);
            }
    }
}

/* ---------------------------------------------------------- construction */

static int copy_pins(crom_model *m, int npin, const double *pinX, int ntri, const double *triX, double len)
{
    m->pin_length = len;
    if (npin > 0) {
        if (!(m->pin_points = crom_malloc(sizeof(double) * 3 * (size_t)npin)))
            return CROM_EINTERNAL;
        memcpy(m->pin_points, pinX, sizeof(double) * 3 * (size_t)npin);
        m->npin_points = npin;
    }
    if (ntri > 0) {
        if (!(m->pin_triangles = crom_malloc(sizeof(double) * 9 * (size_t)ntri)))
            return CROM_EINTERNAL;
        memcpy(m->pin_triangles, triX, sizeof(double) * 9 * (size_t)ntri);
        m->npin_triangles = ntri;
    }
    return 0;
}

static void set_kind(crom_model *m, int H, int constant, const double F[12])
{
    snprintf(m->basis, sizeof m->basis, "skinning");
    m->field = CROM_MODEL_FIELD_SKIN;
    m->handles = H;
    m->rank = 12 * H;
    m->skin_constant = constant ? 1 : 0;
    m->encoder = CROM_MODEL_ENC_LSQ;
    memcpy(m->skin_frame, F, sizeof m->skin_frame);
}

int crom_skin_model_mlp(crom_model *m, const crom_nn_mlp *net, int H, int constant, const double F[12], int npin,
                        const double *pinX, int ntri, const double *triX, double len)
{
    crom_model_clear(m);
    const crom_nn_spec *sp = &net->spec;
    if (H < 1 || sp->width[0] != 3 || sp->width[sp->nlayers] != H - (constant ? 1 : 0))
        return crom_err(CROM_EUSAGE, "the weight network goes %d -> %d, expected 3 -> %d for %d handles%s",
                        sp->width[0], sp->width[sp->nlayers], H - (constant ? 1 : 0), H,
                        constant ? " (one constant)" : "");
    if (!(len > 0))
        return crom_err(CROM_EUSAGE, "the pin mask width must be positive");
    set_kind(m, H, constant, F);
    int rc = crom_nn_mlp_from_params(&m->mlp, sp, net->params, net->nparams, net->shift, net->scale);
    if (!rc)
        rc = copy_pins(m, npin, pinX, ntri, triX, len);
    if (rc) {
        crom_model_free(m);
        return rc;
    }
    crom_model_id(m, m->model_id);
    return 0;
}

int crom_skin_model_mesh(crom_model *m, const crom_mesh *mesh, const double *w, int H, int constant,
                         const double F[12], const double *eig)
{
    crom_model_clear(m);
    if (H < 1)
        return crom_err(CROM_EUSAGE, "a skinning model needs a handle");
    set_kind(m, H, constant, F);
    size_t nw = (size_t)mesh->nv * H;
    int rc = 0;
    m->mesh.nv = mesh->nv;
    m->mesh.nt = mesh->nt;
    m->mesh.ntri = mesh->ntri;
    m->mesh.thickness = mesh->thickness;
    m->mesh.X = crom_malloc(sizeof(double) * 3 * (size_t)mesh->nv);
    m->mesh.tets = crom_malloc(sizeof(int) * 4 * (size_t)(mesh->nt ? mesh->nt : 1));
    m->mesh.tris = mesh->ntri ? crom_malloc(sizeof(int) * 3 * (size_t)mesh->ntri) : NULL;
    m->skin_w = crom_malloc(sizeof(double) * nw);
    m->skin_eig = eig ? crom_malloc(sizeof(double) * (size_t)H) : NULL;
    if (!m->mesh.X || !m->mesh.tets || (mesh->ntri && !m->mesh.tris) || !m->skin_w || (eig && !m->skin_eig))
        rc = CROM_EINTERNAL;
    if (!rc) {
        memcpy(m->mesh.X, mesh->X, sizeof(double) * 3 * (size_t)mesh->nv);
        if (mesh->nt)
            memcpy(m->mesh.tets, mesh->tets, sizeof(int) * 4 * (size_t)mesh->nt);
        if (mesh->ntri)
            memcpy(m->mesh.tris, mesh->tris, sizeof(int) * 3 * (size_t)mesh->ntri);
        memcpy(m->skin_w, w, sizeof(double) * nw);
        if (eig)
            memcpy(m->skin_eig, eig, sizeof(double) * (size_t)H);
        rc = crom_mesh_is_surface(&m->mesh) ? 0 : crom_locate_init(&m->loc, &m->mesh);
    }
    if (rc) {
        crom_model_free(m);
        return rc;
    }
    crom_model_id(m, m->model_id);
    return 0;
}

int crom_skin_set_coordinates(crom_model *m, const double *C, int S)
{
    double *Cn = NULL;
    if (C) {
        if (S < 1 || S > 4 * m->handles)
            return crom_err(CROM_EUSAGE, "%d orthonormal functions for %d handles", S, m->handles);
        if (!(Cn = crom_malloc(sizeof(double) * 4 * (size_t)m->handles * S)))
            return CROM_EINTERNAL;
        memcpy(Cn, C, sizeof(double) * 4 * (size_t)m->handles * S);
    }
    free(m->skin_C);
    m->skin_C = Cn;
    m->skin_S = C ? S : 0;
    m->rank = C ? 3 * S : 12 * m->handles;
    crom_model_id(m, m->model_id);
    return 0;
}

int crom_skin_orthonormalize(crom_model *m, size_t n, const double *X, const double *mass, double tol)
{
    double *w = crom_malloc(sizeof(double) * (n ? n : 1) * (size_t)m->handles), *C = NULL;
    int S = 0, rc = w ? crom_skin_weights(m, n, X, w, NULL) : CROM_EINTERNAL;
    if (!rc)
        rc = crom_skin_coordinates(m->handles, m->skin_constant, m->skin_frame, n, X, mass, w, tol, &C, &S);
    if (!rc)
        rc = crom_skin_set_coordinates(m, C, S);
    free(w);
    free(C);
    return rc;
}

/* ------------------------------------------------------------- digest */

static uint64_t fnv(uint64_t h, const void *p, size_t n)
{
    const unsigned char *b = p;
    for (size_t i = 0; i < n; i++) {
        h ^= b[i];
        h *= 0x100000001b3ULL;
    }
    return h;
}

static uint64_t fnv_i64(uint64_t h, long long v)
{
    int64_t x = v;
    return fnv(h, &x, 8);
}

uint64_t crom_skin_digest(const crom_model *m, uint64_t h)
{
    h = fnv_i64(h, m->handles);
    h = fnv_i64(h, m->skin_constant);
    h = fnv(h, m->skin_frame, sizeof m->skin_frame);
    h = fnv_i64(h, m->skin_C ? m->skin_S : 0);
    if (m->skin_C)
        h = fnv(h, m->skin_C, sizeof(double) * 4 * (size_t)m->handles * m->skin_S);
    if (m->skin_w) {
        h = fnv_i64(h, m->mesh.nv);
        h = fnv_i64(h, m->mesh.nt);
        h = fnv(h, m->mesh.X, sizeof(double) * 3 * (size_t)m->mesh.nv);
        h = fnv(h, m->mesh.tets, sizeof(int) * 4 * (size_t)m->mesh.nt);
        if (crom_mesh_is_surface(&m->mesh)) { /* a shell's weights: its triangles too */
            h = fnv_i64(h, m->mesh.ntri);
            h = fnv(h, m->mesh.tris, sizeof(int) * 3 * (size_t)m->mesh.ntri);
        }
        return fnv(h, m->skin_w, sizeof(double) * (size_t)m->mesh.nv * m->handles);
    }
    const crom_nn_spec *sp = &m->mlp.spec;
    for (int l = 0; l <= sp->nlayers; l++) {
        int32_t w = sp->width[l];
        h = fnv(h, &w, 4);
    }
    const char *act = crom_nn_act_name(sp->act);
    h = fnv(h, act, strlen(act) + 1);
    for (int i = 0; i < 3; i++) {
        double v = m->mlp.shift ? m->mlp.shift[i] : 0;
        h = fnv(h, &v, 8);
    }
    for (int i = 0; i < 3; i++) {
        double v = m->mlp.scale ? m->mlp.scale[i] : 1;
        h = fnv(h, &v, 8);
    }
    if (m->mlp.nparams)
        h = fnv(h, m->mlp.params, sizeof(float) * m->mlp.nparams);
    h = fnv_i64(h, m->npin_points);
    if (m->npin_points)
        h = fnv(h, m->pin_points, sizeof(double) * 3 * (size_t)m->npin_points);
    h = fnv_i64(h, m->npin_triangles);
    if (m->npin_triangles)
        h = fnv(h, m->pin_triangles, sizeof(double) * 9 * (size_t)m->npin_triangles);
    return fnv(h, &m->pin_length, 8);
}

/* ------------------------------------------------------------- files */

int crom_skin_write(hid_t loc, const crom_model *m)
{
    hsize_t d34[2] = {3, 4}, dh = (hsize_t)m->handles;
    int rc = crom_h5_set_i64(loc, ".", "handles", m->handles);
    if (!rc)
        rc = crom_h5_set_i64(loc, ".", "constant_handle", m->skin_constant);
    if (!rc)
        rc = crom_h5_set_str(loc, ".", "skin_weights", m->skin_w ? "eigen" : "trained");
    if (!rc)
        rc = crom_h5_put_f64(loc, "skin/frame", 2, d34, m->skin_frame);
    if (!rc && m->skin_C) {
        hsize_t dc[2] = {4 * (hsize_t)m->handles, (hsize_t)m->skin_S};
        rc = crom_h5_put_f64(loc, "skin/coordinates", 2, dc, m->skin_C);
    }
    if (rc)
        return rc;
    if (m->skin_w) {
        hsize_t dw[2] = {(hsize_t)m->mesh.nv, (hsize_t)m->handles};
        rc = crom_model_write_field_mesh(loc, &m->mesh);
        if (!rc)
            rc = crom_h5_put_f64(loc, "skin/weights", 2, dw, m->skin_w);
        if (!rc && m->skin_eig)
            rc = crom_h5_put_f64(loc, "skin/eigenvalues", 1, &dh, m->skin_eig);
        return rc;
    }
    const crom_nn_mlp *W = &m->mlp;
    int w[CROM_NN_MAX_LAYERS + 1];
    for (int l = 0; l <= W->spec.nlayers; l++)
        w[l] = W->spec.width[l];
    hsize_t dl = (hsize_t)W->spec.nlayers + 1, np = W->nparams, d3 = 3, d1 = 1;
    double sh[3], sc[3];
    for (int i = 0; i < 3; i++) {
        sh[i] = W->shift[i];
        sc[i] = W->scale[i];
    }
    rc = crom_h5_set_str(loc, ".", "activation", crom_nn_act_name(W->spec.act));
    if (!rc)
        rc = crom_h5_put_i32(loc, "field/widths", 1, &dl, w);
    if (!rc)
        rc = crom_h5_put_f32(loc, "field/params", 1, &np, W->params);
    if (!rc)
        rc = crom_h5_put_f64(loc, "field/input_shift", 1, &d3, sh);
    if (!rc)
        rc = crom_h5_put_f64(loc, "field/input_scale", 1, &d3, sc);
    hsize_t dp[2] = {(hsize_t)m->npin_points, 3}, dtr[3] = {(hsize_t)m->npin_triangles, 3, 3};
    if (!rc && m->npin_points)
        rc = crom_h5_put_f64(loc, "skin/pin_points", 2, dp, m->pin_points);
    if (!rc && m->npin_triangles)
        rc = crom_h5_put_f64(loc, "skin/pin_triangles", 3, dtr, m->pin_triangles);
    if (!rc)
        rc = crom_h5_put_f64(loc, "skin/pin_length", 1, &d1, &m->pin_length);
    return rc;
}

static int all_finite(const double *p, size_t n)
{
    for (size_t i = 0; i < n; i++)
        if (!isfinite(p[i]))
            return 0;
    return 1;
}

static int read_fixed(hid_t h, const char *name, int rank, const hsize_t *want, double *out)
{
    hsize_t d[3];
    double *v = NULL;
    int rc = crom_h5_read_f64(h, name, rank, d, &v);
    if (rc)
        return rc;
    for (int k = 0; k < rank; k++)
        if (d[k] != want[k]) {
            free(v);
            return crom_err(CROM_EDATA, "%s has the wrong shape", name);
        }
    size_t n = 1;
    for (int k = 0; k < rank; k++)
        n *= want[k];
    memcpy(out, v, sizeof(double) * n);
    free(v);
    return all_finite(out, n) ? 0 : crom_err(CROM_EDATA, "%s has non-finite values", name);
}

static int read_weight_mlp(hid_t h, crom_model *m, const char *actname)
{
    hsize_t d;
    int *wv = NULL, rc = crom_h5_read_i32(h, "field/widths", 1, &d, &wv);
    if (rc)
        return rc;
    int w[CROM_NN_MAX_LAYERS + 1], nw = (int)d;
    if (d < 2 || d > CROM_NN_MAX_LAYERS + 1) {
        free(wv);
        return crom_err(CROM_EDATA, "field/widths has %llu entries (2..%d expected)", (unsigned long long)d,
                        CROM_NN_MAX_LAYERS + 1);
    }
    memcpy(w, wv, sizeof(int) * d);
    free(wv);
    crom_nn_act a;
    if (crom_nn_act_parse(actname ? actname : "elu", &a) || (a != CROM_NN_ELU && a != CROM_NN_SINE && a != CROM_NN_GELU))
        return crom_err(CROM_EDATA, "unknown activation '%s' (elu, gelu or sine)", actname);
    crom_nn_spec spec;
    if (crom_nn_spec_set(&spec, nw, w, a))
        return crom_err(CROM_EDATA, "field/widths: %s", crom_errmsg());
    int Ht = m->handles - m->skin_constant;
    if (w[0] != 3 || w[nw - 1] != Ht)
        return crom_err(CROM_EDATA, "field/widths go %d -> %d, expected 3 -> %d for %d handles", w[0], w[nw - 1], Ht,
                        m->handles);
    if ((rc = crom_model_read_net(h, "field/params", "field/input_shift", "field/input_scale", &spec,
                                  "the weight network", &m->mlp)))
        return rc;
    hsize_t d1 = 1;
    if ((rc = read_fixed(h, "skin/pin_length", 1, &d1, &m->pin_length)))
        return rc;
    if (!(m->pin_length > 0))
        return crom_err(CROM_EDATA, "skin/pin_length must be positive");
    hsize_t dd[3];
    if (crom_h5_has(h, "skin/pin_points")) {
        if ((rc = crom_h5_read_f64(h, "skin/pin_points", 2, dd, &m->pin_points)))
            return rc;
        if (dd[1] != 3 || !all_finite(m->pin_points, 3 * (size_t)dd[0]))
            return crom_err(CROM_EDATA, "skin/pin_points must be finite [n][3]");
        m->npin_points = (int)dd[0];
    }
    if (crom_h5_has(h, "skin/pin_triangles")) {
        if ((rc = crom_h5_read_f64(h, "skin/pin_triangles", 3, dd, &m->pin_triangles)))
            return rc;
        if (dd[1] != 3 || dd[2] != 3 || !all_finite(m->pin_triangles, 9 * (size_t)dd[0]))
            return crom_err(CROM_EDATA, "skin/pin_triangles must be finite [n][3][3]");
        m->npin_triangles = (int)dd[0];
    }
    if (m->skin_constant && (m->npin_points || m->npin_triangles))
        return crom_err(CROM_EDATA, "a constant handle with pins: the pinned part would move");
    return 0;
}

static int read_weight_mesh(hid_t h, crom_model *m)
{
    int rc = crom_model_read_field_mesh(h, m);
    if (rc)
        return rc;
    hsize_t d[2];
    if ((rc = crom_h5_read_f64(h, "skin/weights", 2, d, &m->skin_w)))
        return rc;
    if (d[0] != (hsize_t)m->mesh.nv || d[1] != (hsize_t)m->handles)
        return crom_err(CROM_EDATA, "skin/weights is [%llu, %llu], expected [%d, %d]", (unsigned long long)d[0],
                        (unsigned long long)d[1], m->mesh.nv, m->handles);
    if (!all_finite(m->skin_w, (size_t)m->mesh.nv * m->handles))
        return crom_err(CROM_EDATA, "skin/weights has non-finite values");
    if (crom_h5_has(h, "skin/eigenvalues")) {
        hsize_t dh = (hsize_t)m->handles;
        if (!(m->skin_eig = crom_malloc(sizeof(double) * (size_t)m->handles)))
            return CROM_EINTERNAL;
        if ((rc = read_fixed(h, "skin/eigenvalues", 1, &dh, m->skin_eig)))
            return rc;
    }
    return crom_mesh_is_surface(&m->mesh) ? 0 : crom_locate_init(&m->loc, &m->mesh);
}

int crom_skin_read(hid_t h, crom_model *m, const char *act)
{
    long long H = 0, k = 0;
    char *kind = NULL;
    int rc = crom_h5_get_i64(h, ".", "handles", &H);
    if (!rc)
        rc = crom_h5_get_i64(h, ".", "constant_handle", &k);
    if (!rc)
        rc = crom_h5_get_str(h, ".", "skin_weights", &kind);
    if (rc) {
        free(kind);
        return rc;
    }
    if (H < 1 || H > 100000 || (k != 0 && k != 1)) {
        free(kind);
        return crom_err(CROM_EDATA, "%lld handles (constant %lld) are not a skinning model", H, k);
    }
    m->handles = (int)H;
    m->skin_constant = (int)k;
    hsize_t d34[2] = {3, 4};
    if ((rc = read_fixed(h, "skin/frame", 2, d34, m->skin_frame))) {
        free(kind);
        return rc;
    }
    if (crom_h5_has(h, "skin/coordinates")) {
        hsize_t dc[2];
        if ((rc = crom_h5_read_f64(h, "skin/coordinates", 2, dc, &m->skin_C))) {
            free(kind);
            return rc;
        }
        m->skin_S = (int)dc[1];
        if (dc[0] != 4 * (hsize_t)H || dc[1] < 1 || dc[1] > dc[0] || !all_finite(m->skin_C, dc[0] * dc[1]))
            rc = crom_err(CROM_EDATA, "skin/coordinates must be finite [4H][S] with 1 <= S <= 4H = %lld", 4 * H);
        else if (!m->latent.nparams && 3 * m->skin_S != m->rank) /* (skin-field: φ's width, checked after) */
            rc = crom_err(CROM_EDATA, "%d orthonormal functions do not make rank %d (3 per function)", m->skin_S,
                          m->rank);
    } else if (!m->latent.nparams && 12 * H != m->rank) {
        rc = crom_err(CROM_EDATA, "%lld handles do not make rank %d (12 per handle)", H, m->rank);
    }
    if (rc) {
        free(kind);
        return rc;
    }
    if (!strcmp(kind, "eigen"))
        rc = read_weight_mesh(h, m);
    else if (!strcmp(kind, "trained"))
        rc = read_weight_mlp(h, m, act);
    else
        rc = crom_err(CROM_EDATA, "skin_weights '%s' is not trained or eigen", kind);
    free(kind);
    return rc;
}
