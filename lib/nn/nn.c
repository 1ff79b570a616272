/* nn.c — dense MLPs, PointNet, Adam (see nn.h for conventions).
 *
 * A dense layer computes z = W a + b and a' = f(z) for a batch of rows at once:
 * Z [B][out] = A [B][in] W^T (one sgemm, the batch as the long dimension), then
 * one fused loop adds the bias and applies f. The backward pass of a layer, with
 * G = dL/da' [B][out]:
 *     dZ = G (.) f'(z)
 *     dL/dW += dZ^T A     (sgemm, summing over the batch)
 *     dL/db += sum over rows of dZ   (accumulated in double)
 *     dL/da  = dZ W       (sgemm)
 * and the forward-mode tangent of a layer, T = da [rows][in]: T' = (T W^T) (.) f'(z).
 * f' is recomputed from the stored output (ELU: a > 0 ? 1 : a + 1) or from the
 * stored pre-activation (sine, GELU), so linear and ELU layers store only a.
 */
#include <cblas.h>
#ifdef _OPENMP
#include <omp.h>
#endif
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "nn/nn.h"

/* ---- activations ---------------------------------------------------------- */

static int act_valid(int a)
{
    return a == CROM_NN_LINEAR || a == CROM_NN_ELU || a == CROM_NN_SINE ||
           a == CROM_NN_GELU;
}

/* Does the backward/JVP of this activation need the pre-activation z? */
static int act_needs_z(crom_nn_act a) { return a == CROM_NN_SINE || a == CROM_NN_GELU; }

static const char *const act_names[] = {"linear", "elu", "sine", "gelu"};

const char *crom_nn_act_name(crom_nn_act act)
{
    return act_valid((int)act) ? act_names[act] : "unknown";
}

int crom_nn_act_parse(const char *name, crom_nn_act *act)
{
    for (int i = 0; i < 4; i++)
        if (name && strcmp(name, act_names[i]) == 0) {
            *act = (crom_nn_act)i;
            return CROM_OK;
        }
    return crom_err(CROM_EUSAGE,
                    "unknown activation '%s' (expected linear, elu, sine or gelu)",
                    name ? name : "(null)");
}

/* Float <-> bits, so that selections can be done with integer masks: under
 * the default -ftrapping-math GCC does not if-convert float compares, and the
 * ELU loops would not vectorize. */
static inline uint32_t f2u(float f)
{
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    return u;
}

static inline float u2f(uint32_t u)
{
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

/* exp(z) - 1 for -87 <= z <= 0: z = n ln2 + r with |r| <= ln2/2, expm1(r) by its
 * Taylor polynomial to degree 7 (truncation < 6e-9), then 2^n expm1(r) +
 * (2^n - 1). Max relative error about 1e-7 (checked against expm1). */
static inline float expm1_neg(float z)
{
    const float magic = 12582912.0f; /* 1.5 * 2^23: adding it rounds to integer */
    float t = z * 1.44269504088896341f + magic;
    float n = t - magic;
    float s = u2f((f2u(t) - 0x4B400000u + 127u) << 23); /* 2^n */
    float r = z - n * 0.693145751953125f; /* ln 2, high part (exact product) */
    r = r - n * 1.428606765330187e-06f;   /* ln 2, low part */
    float p = 1.0f / 5040.0f;
    p = p * r + 1.0f / 720.0f;
    p = p * r + 1.0f / 120.0f;
    p = p * r + 1.0f / 24.0f;
    p = p * r + 1.0f / 6.0f;
    p = p * r + 0.5f;
    float q = r + r * r * p; /* expm1(r) */
    return s * q + (s - 1.0f);
}

/* ELU (alpha = 1), branch-free: v for v >= 0, expm1(max(v, -87)) for v < 0
 * (the same to float precision: expm1(-87) rounds to -1). NaN stays NaN. */
static inline float elu(float v)
{
    uint32_t vb = f2u(v);
    uint32_t neg = (uint32_t)-(int32_t)(vb >> 31); /* all ones if the sign is set */
    uint32_t m = vb & 0x7fffffffu & neg;           /* |v| if negative, else 0 */
    uint32_t mc = m < 0x42AE0000u ? m : 0x42AE0000u; /* min(|v|, 87) */
    mc = m > 0x7f800000u ? m : mc;                   /* ... but keep a NaN */
    float e = expm1_neg(u2f(mc | 0x80000000u));
    return u2f((f2u(e) & neg) | (vb & ~neg));
}

/* ELU'(z) from a = ELU(z): 1 for a >= 0, a + 1 = exp(z) for a < 0. */
static inline float elu_deriv(float a)
{
    uint32_t neg = (uint32_t)-(int32_t)(f2u(a) >> 31);
    return u2f((f2u(a + 1.0f) & neg) | (0x3f800000u & ~neg));
}

#define INV_SQRT2 0.70710678118654752440f
#define INV_SQRT2PI 0.39894228040143267794f

/* The element-wise kernels are compiled twice, for AVX2 and for the baseline,
 * and the CPU picks at load time (GCC's target_clones): the fused bias + ELU
 * loop is a fifth of a forward pass with 4-wide SSE. */
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__)
#define NN_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define NN_CLONES
#endif

/* Rows r0..r1-1 of Z [rows][w] += b (broadcast over rows); A = f(Z). A may equal
 * Z (then Z is not kept). */
NN_CLONES static void bias_act_rows(crom_nn_act act, float omega0, int r0, int r1,
                                    int w, const float *b, float *Z, float *A)
{
    for (int r = r0; r < r1; r++) {
        float *z = Z + (size_t)r * w, *a = A + (size_t)r * w;
        switch (act) {
        case CROM_NN_ELU:
#pragma omp simd
            for (int j = 0; j < w; j++)
                a[j] = elu(z[j] + b[j]);
            break;
        case CROM_NN_SINE:
            for (int j = 0; j < w; j++) {
                float v = z[j] + b[j];
                z[j] = v;
                a[j] = sinf(omega0 * v);
            }
            break;
        case CROM_NN_GELU:
            for (int j = 0; j < w; j++) {
                float v = z[j] + b[j];
                z[j] = v;
                a[j] = 0.5f * v * (1.0f + erff(v * INV_SQRT2));
            }
            break;
        default:
#pragma omp simd
            for (int j = 0; j < w; j++)
                a[j] = z[j] + b[j];
            break;
        }
    }
}

/* Rows r0..r1-1 of D [rows][w] = G (.) f'(z), where the pre-activation of row r
 * is that of input row r / K (A: outputs, Z: pre-activations of the layer). D
 * may equal G. */
NN_CLONES static void mul_deriv_rows(crom_nn_act act, float omega0, int r0, int r1,
                                     int K, int w, const float *G, float *D,
                                     const float *A, const float *Z)
{
    for (int r = r0; r < r1; r++) {
        const float *g = G + (size_t)r * w;
        float *d = D + (size_t)r * w;
        const float *a = A + (size_t)(r / K) * w;
        const float *z = Z ? Z + (size_t)(r / K) * w : NULL;
        switch (act) {
        case CROM_NN_ELU:
#pragma omp simd
            for (int j = 0; j < w; j++)
                d[j] = g[j] * elu_deriv(a[j]);
            break;
        case CROM_NN_SINE:
            for (int j = 0; j < w; j++)
                d[j] = g[j] * omega0 * cosf(omega0 * z[j]);
            break;
        case CROM_NN_GELU:
            for (int j = 0; j < w; j++) {
                float v = z[j];
                float dphi = 0.5f * (1.0f + erff(v * INV_SQRT2)) +
                             v * INV_SQRT2PI * expf(-0.5f * v * v);
                d[j] = g[j] * dphi;
            }
            break;
        default:
            if (d != g)
                memcpy(d, g, sizeof(float) * (size_t)w);
            break;
        }
    }
}

/* ---- specs ---------------------------------------------------------------- */

int crom_nn_spec_check(const crom_nn_spec *spec)
{
    if (!spec)
        return crom_err(CROM_EUSAGE, "network spec is NULL");
    if (spec->nlayers < 1)
        return crom_err(CROM_EUSAGE,
                        "a network needs at least one layer (two widths), got %d layers",
                        spec->nlayers);
    if (spec->nlayers > CROM_NN_MAX_LAYERS)
        return crom_err(CROM_EUSAGE, "too many layers: %d (at most %d)",
                        spec->nlayers, CROM_NN_MAX_LAYERS);
    for (int i = 0; i <= spec->nlayers; i++)
        if (spec->width[i] < 1 || spec->width[i] > CROM_NN_MAX_WIDTH)
            return crom_err(CROM_EUSAGE,
                            "network width[%d] = %d must be in 1..%d", i,
                            spec->width[i], CROM_NN_MAX_WIDTH);
    if (!act_valid((int)spec->act) || !act_valid((int)spec->out_act))
        return crom_err(CROM_EUSAGE, "invalid activation code (%d, %d)",
                        (int)spec->act, (int)spec->out_act);
    if ((spec->act == CROM_NN_SINE || spec->out_act == CROM_NN_SINE) &&
        !(isfinite(spec->omega0) && spec->omega0 > 0))
        return crom_err(CROM_EUSAGE, "sine frequency omega0 = %g must be positive",
                        (double)spec->omega0);
    return CROM_OK;
}

int crom_nn_spec_set(crom_nn_spec *spec, int nwidths, const int *widths,
                     crom_nn_act act)
{
    if (!spec || !widths)
        return crom_err(CROM_EUSAGE, "network spec or widths is NULL");
    if (nwidths < 2)
        return crom_err(CROM_EUSAGE,
                        "a network needs at least two widths (input and output), got %d",
                        nwidths);
    if (nwidths - 1 > CROM_NN_MAX_LAYERS)
        return crom_err(CROM_EUSAGE, "too many layers: %d (at most %d)",
                        nwidths - 1, CROM_NN_MAX_LAYERS);
    memset(spec, 0, sizeof *spec);
    spec->nlayers = nwidths - 1;
    memcpy(spec->width, widths, sizeof(int) * (size_t)nwidths);
    spec->act = act;
    spec->out_act = CROM_NN_LINEAR;
    spec->omega0 = 30.0f;
    return crom_nn_spec_check(spec);
}

size_t crom_nn_spec_nparams(const crom_nn_spec *spec)
{
    if (crom_nn_spec_check(spec))
        return 0;
    size_t n = 0;
    for (int l = 0; l < spec->nlayers; l++)
        n += (size_t)spec->width[l] * (size_t)spec->width[l + 1] +
             (size_t)spec->width[l + 1];
    return n;
}

int crom_nn_mlp_has_spec(const crom_nn_mlp *net, const crom_nn_spec *spec)
{
    const crom_nn_spec *s = &net->spec;
    return s->nlayers == spec->nlayers && s->act == spec->act &&
           !memcmp(s->width, spec->width, sizeof(int) * (size_t)(spec->nlayers + 1)) &&
           net->nparams == crom_nn_spec_nparams(spec);
}

/* ---- MLP construction ----------------------------------------------------- */

/* Re-record the current message, prefixed with what, as CROM_EDATA (a stored
 * model that is inconsistent is bad data, not bad usage). */
static int as_data_error(const char *what)
{
    char msg[512];
    snprintf(msg, sizeof msg, "%s", crom_errmsg());
    return crom_err(CROM_EDATA, "%s: %s", what, msg);
}

static float uniform_pm(crom_rng *rng, double a)
{
    return (float)((2.0 * crom_rng_uniform(rng) - 1.0) * a);
}

/* Xavier-uniform weights and zero biases, or SIREN's init for sine networks;
 * layer by layer, weights in row-major order, then biases. */
static void init_params(crom_nn_mlp *net, crom_rng *rng)
{
    int siren = net->spec.act == CROM_NN_SINE;
    for (int l = 0; l < net->spec.nlayers; l++) {
        crom_nn_layer *ly = &net->layer[l];
        double wa, ba;
        if (siren || ly->act == CROM_NN_SINE) {
            wa = l == 0 ? 1.0 / ly->in : sqrt(6.0 / ly->in) / net->spec.omega0;
            ba = 1.0 / sqrt((double)ly->in);
        } else {
            wa = sqrt(6.0 / (ly->in + ly->out));
            ba = 0;
        }
        for (size_t i = 0; i < (size_t)ly->in * ly->out; i++)
            ly->W[i] = uniform_pm(rng, wa);
        for (int j = 0; j < ly->out; j++)
            ly->b[j] = ba > 0 ? uniform_pm(rng, ba) : 0.0f;
    }
}

void crom_nn_mlp_free(crom_nn_mlp *net)
{
    if (!net)
        return;
    if (net->owns_params)
        free(net->params);
    free(net->shift); /* scale lives in the same block */
    memset(net, 0, sizeof *net);
}

int crom_nn_mlp_init(crom_nn_mlp *net, const crom_nn_spec *spec, float *storage,
                     crom_rng *rng)
{
    if (!net)
        return crom_err(CROM_EUSAGE, "network is NULL");
    memset(net, 0, sizeof *net);
    int rc = crom_nn_spec_check(spec);
    if (rc)
        return rc;
    net->spec = *spec;
    net->nparams = crom_nn_spec_nparams(spec);
    if (!storage) {
        storage = crom_calloc(net->nparams, sizeof(float));
        if (!storage)
            return CROM_EINTERNAL;
        net->owns_params = 1;
    }
    net->params = storage;
    int d = spec->width[0];
    net->shift = crom_malloc(sizeof(float) * 2 * (size_t)d);
    if (!net->shift) {
        crom_nn_mlp_free(net);
        return CROM_EINTERNAL;
    }
    net->scale = net->shift + d;
    for (int i = 0; i < d; i++) {
        net->shift[i] = 0.0f;
        net->scale[i] = 1.0f;
    }
    size_t off = 0;
    for (int l = 0; l < spec->nlayers; l++) {
        crom_nn_layer *ly = &net->layer[l];
        ly->in = spec->width[l];
        ly->out = spec->width[l + 1];
        ly->act = l + 1 < spec->nlayers ? spec->act : spec->out_act;
        ly->woff = off;
        off += (size_t)ly->in * ly->out;
        ly->boff = off;
        off += (size_t)ly->out;
        ly->W = storage + ly->woff;
        ly->b = storage + ly->boff;
    }
    if (rng)
        init_params(net, rng);
    return CROM_OK;
}

int crom_nn_mlp_set_norm(crom_nn_mlp *net, const float *shift, const float *scale)
{
    if (!net || !net->shift)
        return crom_err(CROM_EUSAGE, "network is not initialized");
    int d = net->spec.width[0];
    for (int i = 0; i < d; i++) {
        float s = shift ? shift[i] : 0.0f, c = scale ? scale[i] : 1.0f;
        if (!isfinite(s) || !isfinite(c) || !(c > 0))
            return crom_err(CROM_EDATA,
                            "input normalization %d: shift %g, scale %g (scale must be finite and positive)",
                            i, (double)s, (double)c);
    }
    for (int i = 0; i < d; i++) {
        net->shift[i] = shift ? shift[i] : 0.0f;
        net->scale[i] = scale ? scale[i] : 1.0f;
    }
    return CROM_OK;
}

int crom_nn_mlp_from_params(crom_nn_mlp *net, const crom_nn_spec *spec,
                            const float *params, size_t nparams,
                            const float *shift, const float *scale)
{
    if (!net)
        return crom_err(CROM_EUSAGE, "network is NULL");
    memset(net, 0, sizeof *net);
    if (crom_nn_spec_check(spec))
        return as_data_error("stored network");
    size_t n = crom_nn_spec_nparams(spec);
    if (!params || n != nparams)
        return crom_err(CROM_EDATA,
                        "stored network has %zu parameters, its shape needs %zu",
                        params ? nparams : 0, n);
    int rc = crom_nn_mlp_init(net, spec, NULL, NULL);
    if (rc)
        return rc;
    memcpy(net->params, params, sizeof(float) * n);
    rc = crom_nn_mlp_set_norm(net, shift, scale);
    if (rc)
        crom_nn_mlp_free(net);
    return rc;
}

int crom_nn_norm_fit(const double *x, size_t n, int dim, float *shift, float *scale)
{
    if (!x || !shift || !scale || n < 1 || dim < 1)
        return crom_err(CROM_EUSAGE, "normalization needs at least one point (n = %zu, dim = %d)",
                        n, dim);
    double hmax = 0;
    for (int k = 0; k < dim; k++) {
        double lo = x[k], hi = x[k];
        for (size_t i = 0; i < n; i++) {
            double v = x[i * (size_t)dim + k];
            if (!isfinite(v))
                return crom_err(CROM_EDATA, "point %zu coordinate %d is not finite", i, k);
            lo = v < lo ? v : lo;
            hi = v > hi ? v : hi;
        }
        shift[k] = (float)(0.5 * (lo + hi));
        double h = 0.5 * (hi - lo);
        scale[k] = (float)h;
        hmax = h > hmax ? h : hmax;
    }
    for (int k = 0; k < dim; k++)
        if (!(scale[k] > 0) || !isfinite(scale[k]))
            scale[k] = hmax > 0 && isfinite((float)hmax) ? (float)hmax : 1.0f;
    return CROM_OK;
}

/* ---- workspaces ------------------------------------------------------------ */

/* Rows per block: the batch is processed in blocks of rows small enough that a
 * block's activations stay in the L2 cache between the sgemm that writes them
 * and the loop that applies the activation (and between layers). Wider layers
 * get fewer rows; never fewer than the input width (a Jacobian block holds
 * width[0] tangents of one input). */
#define NN_BLOCK_ROWS 512
#define NN_BLOCK_FLOATS (1 << 16)

struct crom_nn_thread {
    float *buf[2];                         /* [block][maxw] ping-pong scratch */
    float *gA[CROM_NN_MAX_LAYERS + 1];     /* gathered rows of A (subset backward) */
    float *gZ[CROM_NN_MAX_LAYERS + 1];     /* gathered rows of Z */
    float *grad;                           /* [nparams] private weight gradient */
    double *acc;                           /* bias-gradient sums, layer by layer */
    float *mem;
};

static size_t round16(size_t n) { return (n + 15) & ~(size_t)15; }

void crom_nn_ws_free(crom_nn_ws *ws)
{
    if (!ws)
        return;
    if (ws->thr)
        for (int t = 0; t < ws->nthreads; t++) {
            free(ws->thr[t].mem);
            free(ws->thr[t].acc);
        }
    free(ws->thr);
    free(ws->mem);
    memset(ws, 0, sizeof *ws);
}

int crom_nn_ws_init(crom_nn_ws *ws, const crom_nn_mlp *net, int maxbatch, int nthreads)
{
    if (!ws)
        return crom_err(CROM_EUSAGE, "workspace is NULL");
    memset(ws, 0, sizeof *ws);
    if (!net || !net->params)
        return crom_err(CROM_EUSAGE, "network is not initialized");
    if (maxbatch < 1)
        return crom_err(CROM_EUSAGE, "workspace batch size %d must be positive", maxbatch);
    if (nthreads < 1 || nthreads > 1024)
        return crom_err(CROM_EUSAGE, "workspace thread count %d must be in 1..1024", nthreads);
    const crom_nn_spec *s = &net->spec;
    int L = s->nlayers, maxw = 0;
    size_t sumw = 0, sumz = 0;
    for (int l = 0; l <= L; l++) {
        maxw = s->width[l] > maxw ? s->width[l] : maxw;
        sumw += (size_t)s->width[l];
        if (l > 0 && act_needs_z(net->layer[l - 1].act))
            sumz += (size_t)s->width[l];
    }
    int blk = NN_BLOCK_FLOATS / maxw;
    blk = blk > NN_BLOCK_ROWS ? NN_BLOCK_ROWS : blk < 16 ? 16 : blk;
    blk = blk < s->width[0] ? s->width[0] : blk;

    /* activations of a whole batch */
    size_t rows = (size_t)maxbatch, total = 0;
    size_t offA[CROM_NN_MAX_LAYERS + 1], offZ[CROM_NN_MAX_LAYERS + 1];
    for (int l = 0; l <= L; l++) {
        offA[l] = total;
        total += round16(rows * (size_t)s->width[l]);
        offZ[l] = (size_t)-1;
        if (l > 0 && act_needs_z(net->layer[l - 1].act)) {
            offZ[l] = total;
            total += round16(rows * (size_t)s->width[l]);
        }
    }
    if (total > ((size_t)1 << 40))
        return crom_err(CROM_EUSAGE, "workspace of %d rows would need %zu floats",
                        maxbatch, total);
    ws->mem = aligned_alloc(64, sizeof(float) * total);
    ws->thr = crom_calloc((size_t)nthreads, sizeof *ws->thr);
    ws->nthreads = nthreads;
    if (!ws->mem || !ws->thr) {
        crom_nn_ws_free(ws);
        return crom_err(CROM_EINTERNAL, "out of memory for a workspace of %d rows (%zu MB)",
                        maxbatch, sizeof(float) * total >> 20);
    }
    for (int l = 0; l <= L; l++) {
        ws->A[l] = ws->mem + offA[l];
        ws->Z[l] = offZ[l] == (size_t)-1 ? NULL : ws->mem + offZ[l];
        ws->width[l] = s->width[l];
    }

    /* per-thread scratch */
    size_t b = (size_t)blk;
    size_t per = 2 * round16(b * (size_t)maxw) + round16(b * sumw) + round16(b * sumz) +
                 round16(net->nparams);
    for (int t = 0; t < nthreads; t++) {
        struct crom_nn_thread *th = &ws->thr[t];
        th->mem = aligned_alloc(64, sizeof(float) * per);
        th->acc = crom_malloc(sizeof(double) * sumw);
        if (!th->mem || !th->acc) {
            crom_nn_ws_free(ws);
            return crom_err(CROM_EINTERNAL, "out of memory for workspace scratch");
        }
        float *p = th->mem;
        th->buf[0] = p;
        p += round16(b * (size_t)maxw);
        th->buf[1] = p;
        p += round16(b * (size_t)maxw);
        float *g = p;
        for (int l = 0; l <= L; l++) {
            th->gA[l] = g;
            g += b * (size_t)s->width[l];
        }
        p += round16(b * sumw);
        g = p;
        for (int l = 0; l <= L; l++) {
            th->gZ[l] = NULL;
            if (ws->Z[l]) {
                th->gZ[l] = g;
                g += b * (size_t)s->width[l];
            }
        }
        p += round16(b * sumz);
        th->grad = p;
    }
    ws->maxbatch = maxbatch;
    ws->nlayers = L;
    ws->maxw = maxw;
    ws->block = blk;
    ws->last_rows = -1;
    ws->last_net = NULL;
    return CROM_OK;
}

const float *crom_nn_ws_output(const crom_nn_ws *ws) { return ws->A[ws->nlayers]; }

/* CROM_OK if ws was made for net's shape (widths and where z is stored). */
static int ws_check(const crom_nn_mlp *net, const crom_nn_ws *ws)
{
    if (!net || !net->params)
        return crom_err(CROM_EUSAGE, "network is not initialized");
    if (!ws || !ws->mem)
        return crom_err(CROM_EUSAGE, "workspace is not initialized");
    int ok = ws->nlayers == net->spec.nlayers;
    for (int l = 0; ok && l <= ws->nlayers; l++) {
        ok = ws->width[l] == net->spec.width[l];
        if (ok && l > 0)
            ok = (ws->Z[l] != NULL) == act_needs_z(net->layer[l - 1].act);
    }
    if (!ok)
        return crom_err(CROM_EUSAGE, "workspace was made for a network of another shape");
    return CROM_OK;
}

static int rows_check(const crom_nn_ws *ws, int B, const char *what)
{
    if (B < 0)
        return crom_err(CROM_EUSAGE, "%s: negative batch size %d", what, B);
    if (B > ws->maxbatch)
        return crom_err(CROM_EUSAGE, "%s: batch of %d rows exceeds the workspace (%d rows)",
                        what, B, ws->maxbatch);
    return CROM_OK;
}

static int thread_id(void)
{
#ifdef _OPENMP
    return omp_get_thread_num();
#else
    return 0;
#endif
}

/* Threads to use for nb blocks. */
static int team(const crom_nn_ws *ws, int nb) { return nb < ws->nthreads ? (nb > 0 ? nb : 1) : ws->nthreads; }

/* ---- forward, backward, tangents ------------------------------------------ */

/* A0 [B][d] = (x - shift) / scale. */
static void normalize_f(const crom_nn_mlp *net, int B, const float *x, float *A0)
{
    int d = net->spec.width[0];
    for (int r = 0; r < B; r++)
        for (int i = 0; i < d; i++)
            A0[(size_t)r * d + i] = (x[(size_t)r * d + i] - net->shift[i]) / net->scale[i];
}

static void normalize_d(const crom_nn_mlp *net, int B, const double *x, float *A0)
{
    int d = net->spec.width[0];
    for (int r = 0; r < B; r++)
        for (int i = 0; i < d; i++)
            A0[(size_t)r * d + i] =
                (float)((x[(size_t)r * d + i] - net->shift[i]) / net->scale[i]);
}

/* Forward pass of rows r0..r0+m-1 whose normalized inputs are in ws->A[0]. */
static void forward_block(const crom_nn_mlp *net, crom_nn_ws *ws, int r0, int m)
{
    for (int l = 0; l < net->spec.nlayers; l++) {
        const crom_nn_layer *ly = &net->layer[l];
        float *A = ws->A[l + 1] + (size_t)r0 * ly->out;
        float *Z = ws->Z[l + 1] ? ws->Z[l + 1] + (size_t)r0 * ly->out : A;
        cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasTrans, m, ly->out, ly->in, 1.0f,
                    ws->A[l] + (size_t)r0 * ly->in, ly->in, ly->W, ly->in, 0.0f, Z,
                    ly->out);
        bias_act_rows(ly->act, net->spec.omega0, 0, m, ly->out, ly->b, Z, A);
    }
}

/* Forward pass of B rows whose normalized inputs are in ws->A[0]. */
static void forward_rows(const crom_nn_mlp *net, crom_nn_ws *ws, int B)
{
    int S = ws->block, nb = (B + S - 1) / S, nt = team(ws, nb);
    (void)nt;
#pragma omp parallel for num_threads(nt) schedule(static, 1) if (nt > 1)
    for (int k = 0; k < nb; k++)
        forward_block(net, ws, k * S, B - k * S < S ? B - k * S : S);
    ws->last_rows = B;
    ws->last_net = net;
}

int crom_nn_mlp_forward(const crom_nn_mlp *net, crom_nn_ws *ws, int B,
                        const float *x, float *y)
{
    int rc = ws_check(net, ws);
    if (rc || (rc = rows_check(ws, B, "MLP forward")))
        return rc;
    if (B > 0 && !x)
        return crom_err(CROM_EUSAGE, "MLP forward: input is NULL");
    normalize_f(net, B, x, ws->A[0]);
    forward_rows(net, ws, B);
    if (y && B > 0)
        memcpy(y, ws->A[net->spec.nlayers],
               sizeof(float) * (size_t)B * net->spec.width[net->spec.nlayers]);
    return CROM_OK;
}

/* Backward through m rows of the last forward pass: rows r0.. of it, or rows
 * idx[0..m-1] if idx != NULL (then gathered into the thread's scratch). G: dL/dy
 * of these m rows. Adds dL/dW into g (if g), bias sums into acc, and writes dL/dx
 * of the m rows into dx (if dx). */
static void backward_block(const crom_nn_mlp *net, const crom_nn_ws *ws,
                           struct crom_nn_thread *th, int r0, int m, const int *idx,
                           const float *G, float *g, double *acc, float *dx)
{
    int L = net->spec.nlayers;
    const float *Ar[CROM_NN_MAX_LAYERS + 1], *Zr[CROM_NN_MAX_LAYERS + 1];
    for (int l = 0; l <= L; l++) {
        int w = net->spec.width[l];
        if (idx) {
            for (int i = 0; i < m; i++)
                memcpy(th->gA[l] + (size_t)i * w, ws->A[l] + (size_t)idx[i] * w,
                       sizeof(float) * (size_t)w);
            if (ws->Z[l])
                for (int i = 0; i < m; i++)
                    memcpy(th->gZ[l] + (size_t)i * w, ws->Z[l] + (size_t)idx[i] * w,
                           sizeof(float) * (size_t)w);
            Ar[l] = th->gA[l];
            Zr[l] = ws->Z[l] ? th->gZ[l] : NULL;
        } else {
            Ar[l] = ws->A[l] + (size_t)r0 * w;
            Zr[l] = ws->Z[l] ? ws->Z[l] + (size_t)r0 * w : NULL;
        }
    }
    size_t accoff = 0;
    for (int l = L - 1; l >= 0; l--) {
        const crom_nn_layer *ly = &net->layer[l];
        int in = ly->in, out = ly->out;
        /* dZ = G (.) f'(z): in place when G is scratch, else into buf[0] */
        const float *dZ = G;
        if (ly->act != CROM_NN_LINEAR) {
            float *D = G == th->buf[1] ? th->buf[1] : th->buf[0];
            mul_deriv_rows(ly->act, net->spec.omega0, 0, m, 1, out, G, D, Ar[l + 1],
                           Zr[l + 1]);
            dZ = D;
        }
        if (g) {
            cblas_sgemm(CblasRowMajor, CblasTrans, CblasNoTrans, out, in, m, 1.0f, dZ,
                        out, Ar[l], in, 1.0f, g + ly->woff, in);
            double *a = acc + accoff;
            for (int r = 0; r < m; r++) {
                const float *d = dZ + (size_t)r * out;
#pragma omp simd
                for (int j = 0; j < out; j++)
                    a[j] += d[j];
            }
            accoff += (size_t)out;
        }
        if (l == 0 && !dx)
            break;
        float *Gp = dZ == th->buf[0] ? th->buf[1] : th->buf[0];
        cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, m, in, out, 1.0f, dZ, out,
                    ly->W, in, 0.0f, Gp, in);
        G = Gp;
    }
    if (dx) {
        int d = net->spec.width[0];
        for (int r = 0; r < m; r++)
            for (int i = 0; i < d; i++)
                dx[(size_t)r * d + i] = G[(size_t)r * d + i] / net->scale[i];
    }
}

/* Backward through n rows (0..n-1 of the last forward pass, or idx[0..n-1]); dy
 * and dx have n rows. Blocks are dealt to threads round-robin; each thread sums
 * its weight gradients privately (when there are several) and the sums are
 * added in thread order, so results depend only on the thread count. */
static void backward_rows(const crom_nn_mlp *net, crom_nn_ws *ws, int n, const int *idx,
                          const float *dy, float *grad, float *dx)
{
    int S = ws->block, nb = (n + S - 1) / S, nt = team(ws, nb);
    int L = net->spec.nlayers, out = net->spec.width[L], d = net->spec.width[0];
    size_t nacc = 0;
    for (int l = 1; l <= L; l++)
        nacc += (size_t)net->spec.width[l];
#pragma omp parallel num_threads(nt) if (nt > 1)
    {
        int t = thread_id();
        struct crom_nn_thread *th = &ws->thr[t];
        float *g = grad && nt > 1 ? th->grad : grad;
        if (g && nt > 1)
            memset(g, 0, sizeof(float) * net->nparams);
        memset(th->acc, 0, sizeof(double) * nacc);
        for (int k = t; k < nb; k += nt) {
            int r0 = k * S, m = n - r0 < S ? n - r0 : S;
            backward_block(net, ws, th, r0, m, idx ? idx + r0 : NULL,
                           dy + (size_t)r0 * out, g, th->acc,
                           dx ? dx + (size_t)r0 * d : NULL);
        }
    }
    if (!grad)
        return;
    for (int t = 0; t < nt; t++) {
        const struct crom_nn_thread *th = &ws->thr[t];
        if (nt > 1)
            for (int l = 0; l < L; l++) {
                const crom_nn_layer *ly = &net->layer[l];
                float *gw = grad + ly->woff;
                const float *tw = th->grad + ly->woff;
                for (size_t i = 0; i < (size_t)ly->in * ly->out; i++)
                    gw[i] += tw[i];
            }
    }
    /* bias sums: acc holds layers from the top down */
    size_t accoff = 0;
    for (int l = L - 1; l >= 0; l--) {
        const crom_nn_layer *ly = &net->layer[l];
        for (int j = 0; j < ly->out; j++) {
            double s = 0;
            for (int t = 0; t < nt; t++)
                s += ws->thr[t].acc[accoff + j];
            grad[ly->boff + j] += (float)s;
        }
        accoff += (size_t)ly->out;
    }
}

int crom_nn_mlp_backward(const crom_nn_mlp *net, crom_nn_ws *ws, int B,
                         const float *dy, float *grad, float *dx)
{
    int rc = ws_check(net, ws);
    if (rc)
        return rc;
    if (ws->last_net != net || ws->last_rows < 0)
        return crom_err(CROM_EUSAGE,
                        "MLP backward without a forward pass of this network on this workspace");
    if (B != ws->last_rows)
        return crom_err(CROM_EUSAGE, "MLP backward of %d rows after a forward pass of %d rows",
                        B, ws->last_rows);
    if (B > 0 && !dy)
        return crom_err(CROM_EUSAGE, "MLP backward: dL/dy is NULL");
    if (B > 0)
        backward_rows(net, ws, B, NULL, dy, grad, dx);
    return CROM_OK;
}

/* Propagate the tangents in th->buf[0] ([bi*K][in], normalized input) of input
 * rows r0..r0+bi-1 of the last forward pass; returns the buffer holding the
 * output tangents [bi*K][out]. */
static const float *tangent_block(const crom_nn_mlp *net, const crom_nn_ws *ws,
                                  struct crom_nn_thread *th, int r0, int bi, int K)
{
    int cur = 0, rows = bi * K;
    for (int l = 0; l < net->spec.nlayers; l++) {
        const crom_nn_layer *ly = &net->layer[l];
        float *T = th->buf[cur], *To = th->buf[1 - cur];
        cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasTrans, rows, ly->out, ly->in, 1.0f,
                    T, ly->in, ly->W, ly->in, 0.0f, To, ly->out);
        if (ly->act != CROM_NN_LINEAR)
            mul_deriv_rows(ly->act, net->spec.omega0, 0, rows, K, ly->out, To, To,
                           ws->A[l + 1] + (size_t)r0 * ly->out,
                           ws->Z[l + 1] ? ws->Z[l + 1] + (size_t)r0 * ly->out : NULL);
        cur = 1 - cur;
    }
    return th->buf[cur];
}

int crom_nn_mlp_jvp(const crom_nn_mlp *net, crom_nn_ws *ws, int B, const float *x,
                    int K, const float *dx, float *y, float *dy)
{
    int rc = ws_check(net, ws);
    if (rc || (rc = rows_check(ws, B, "MLP JVP")))
        return rc;
    if (K < 1 || K > ws->block)
        return crom_err(CROM_EUSAGE, "MLP JVP: %d tangents per input (at most %d)", K,
                        ws->block);
    if (B > 0 && (!x || !dx || !dy))
        return crom_err(CROM_EUSAGE, "MLP JVP: input, tangents or output is NULL");
    int d = net->spec.width[0], out = net->spec.width[net->spec.nlayers];
    normalize_f(net, B, x, ws->A[0]);
    forward_rows(net, ws, B);
    int bi = ws->block / K, nb = (B + bi - 1) / bi, nt = team(ws, nb);
#pragma omp parallel num_threads(nt) if (nt > 1)
    {
        int t = thread_id();
        struct crom_nn_thread *th = &ws->thr[t];
        for (int k = t; k < nb; k += nt) {
            int r0 = k * bi, m = B - r0 < bi ? B - r0 : bi;
            const float *src = dx + (size_t)r0 * K * d;
            for (size_t r = 0; r < (size_t)m * K; r++)
                for (int i = 0; i < d; i++)
                    th->buf[0][r * d + i] = src[r * d + i] / net->scale[i];
            const float *To = tangent_block(net, ws, th, r0, m, K);
            memcpy(dy + (size_t)r0 * K * out, To, sizeof(float) * (size_t)m * K * out);
        }
    }
    if (y && B > 0)
        memcpy(y, ws->A[net->spec.nlayers], sizeof(float) * (size_t)B * out);
    return CROM_OK;
}

/* After a forward pass of m rows: the Jacobians of those rows, written into
 * J + (row offset) as float (Jf) or double (Jd), [m][out][in]. */
static void jacobian_rows(const crom_nn_mlp *net, crom_nn_ws *ws, int m, float *Jf,
                          double *Jd)
{
    int d = net->spec.width[0], out = net->spec.width[net->spec.nlayers];
    int bi = ws->block / d, nb = (m + bi - 1) / bi, nt = team(ws, nb);
#pragma omp parallel num_threads(nt) if (nt > 1)
    {
        int t = thread_id();
        struct crom_nn_thread *th = &ws->thr[t];
        for (int k = t; k < nb; k += nt) {
            int r0 = k * bi, mi = m - r0 < bi ? m - r0 : bi;
            float *T = th->buf[0];
            memset(T, 0, sizeof(float) * (size_t)mi * d * d);
            for (int b = 0; b < mi; b++)
                for (int i = 0; i < d; i++)
                    T[((size_t)b * d + i) * d + i] = 1.0f / net->scale[i];
            const float *To = tangent_block(net, ws, th, r0, mi, d);
            for (int b = 0; b < mi; b++) {
                size_t base = (size_t)(r0 + b) * out * d;
                for (int o = 0; o < out; o++)
                    for (int i = 0; i < d; i++) {
                        float v = To[((size_t)b * d + i) * out + o];
                        if (Jf)
                            Jf[base + (size_t)o * d + i] = v;
                        else
                            Jd[base + (size_t)o * d + i] = v;
                    }
            }
        }
    }
}

int crom_nn_mlp_jacobian(const crom_nn_mlp *net, crom_nn_ws *ws, size_t n,
                         const float *x, float *J, float *y)
{
    int rc = ws_check(net, ws);
    if (rc)
        return rc;
    int d = net->spec.width[0], out = net->spec.width[net->spec.nlayers];
    if (n > 0 && (!x || !J))
        return crom_err(CROM_EUSAGE, "MLP Jacobian: input or output is NULL");
    size_t chunk = (size_t)ws->maxbatch;
    for (size_t s = 0; s < n; s += chunk) {
        int m = (int)(n - s < chunk ? n - s : chunk);
        normalize_f(net, m, x + s * d, ws->A[0]);
        forward_rows(net, ws, m);
        jacobian_rows(net, ws, m, J + s * out * d, NULL);
        if (y)
            memcpy(y + s * out, ws->A[net->spec.nlayers], sizeof(float) * (size_t)m * out);
    }
    ws->last_rows = -1; /* the activations are of the last chunk only */
    return CROM_OK;
}

int crom_nn_mlp_eval(const crom_nn_mlp *net, crom_nn_ws *ws, size_t n,
                     const double *x, double *y, double *J)
{
    int rc = ws_check(net, ws);
    if (rc)
        return rc;
    int d = net->spec.width[0], L = net->spec.nlayers, out = net->spec.width[L];
    if (n > 0 && (!x || (!y && !J)))
        return crom_err(CROM_EUSAGE, "MLP eval: input or output is NULL");
    size_t chunk = (size_t)ws->maxbatch;
    for (size_t s = 0; s < n; s += chunk) {
        int m = (int)(n - s < chunk ? n - s : chunk);
        normalize_d(net, m, x + s * d, ws->A[0]);
        forward_rows(net, ws, m);
        if (y)
            for (size_t i = 0; i < (size_t)m * out; i++)
                y[s * out + i] = ws->A[L][i];
        if (J)
            jacobian_rows(net, ws, m, NULL, J + s * out * d);
    }
    ws->last_rows = -1;
    return CROM_OK;
}

/* ---- PointNet ------------------------------------------------------------- */

int crom_nn_pointnet_spec(crom_nn_spec *point, crom_nn_spec *head, int npw,
                          const int *pw, int nhw, const int *hw)
{
    int rc = crom_nn_spec_set(point, npw, pw, CROM_NN_ELU);
    if (rc)
        return crom_err_ctx("PointNet per-point MLP");
    point->out_act = CROM_NN_ELU;
    rc = crom_nn_spec_set(head, nhw, hw, CROM_NN_ELU);
    if (rc)
        return crom_err_ctx("PointNet head");
    if (hw[0] != pw[npw - 1])
        return crom_err(CROM_EUSAGE, "PointNet head input %d != per-point output %d",
                        hw[0], pw[npw - 1]);
    return CROM_OK;
}

size_t crom_nn_pointnet_nparams(const crom_nn_spec *point, const crom_nn_spec *head)
{
    size_t a = crom_nn_spec_nparams(point), b = a ? crom_nn_spec_nparams(head) : 0;
    if (!a || !b)
        return 0;
    if (head->width[0] != point->width[point->nlayers]) {
        crom_err(CROM_EUSAGE, "PointNet head input %d != per-point output %d",
                 head->width[0], point->width[point->nlayers]);
        return 0;
    }
    return a + b;
}

void crom_nn_pointnet_free(crom_nn_pointnet *pn)
{
    if (!pn)
        return;
    crom_nn_mlp_free(&pn->point);
    crom_nn_mlp_free(&pn->head);
    if (pn->owns_params)
        free(pn->params);
    memset(pn, 0, sizeof *pn);
}

int crom_nn_pointnet_init(crom_nn_pointnet *pn, const crom_nn_spec *point,
                          const crom_nn_spec *head, float *storage, crom_rng *rng)
{
    if (!pn)
        return crom_err(CROM_EUSAGE, "PointNet is NULL");
    memset(pn, 0, sizeof *pn);
    size_t n = crom_nn_pointnet_nparams(point, head);
    if (!n)
        return crom_errcode() ? crom_errcode() : CROM_EUSAGE;
    if (!storage) {
        storage = crom_calloc(n, sizeof(float));
        if (!storage)
            return CROM_EINTERNAL;
        pn->owns_params = 1;
    }
    pn->params = storage;
    pn->nparams = n;
    int rc = crom_nn_mlp_init(&pn->point, point, storage, rng);
    if (!rc)
        rc = crom_nn_mlp_init(&pn->head, head, storage + pn->point.nparams, rng);
    if (rc)
        crom_nn_pointnet_free(pn);
    return rc;
}

int crom_nn_pointnet_from_params(crom_nn_pointnet *pn, const crom_nn_spec *point,
                                 const crom_nn_spec *head, const float *params,
                                 size_t nparams, const float *shift,
                                 const float *scale)
{
    if (!pn)
        return crom_err(CROM_EUSAGE, "PointNet is NULL");
    memset(pn, 0, sizeof *pn);
    size_t n = crom_nn_pointnet_nparams(point, head);
    if (!n)
        return as_data_error("stored PointNet");
    if (!params || n != nparams)
        return crom_err(CROM_EDATA, "stored PointNet has %zu parameters, its shape needs %zu",
                        params ? nparams : 0, n);
    int rc = crom_nn_pointnet_init(pn, point, head, NULL, NULL);
    if (rc)
        return rc;
    memcpy(pn->params, params, sizeof(float) * n);
    rc = crom_nn_mlp_set_norm(&pn->point, shift, scale);
    if (rc)
        crom_nn_pointnet_free(pn);
    return rc;
}

void crom_nn_pointnet_ws_free(crom_nn_pointnet_ws *ws)
{
    if (!ws)
        return;
    crom_nn_ws_free(&ws->point);
    crom_nn_ws_free(&ws->head);
    free(ws->argmax);
    free(ws->pooled);
    free(ws->dfeat);
    free(ws->rows);
    memset(ws, 0, sizeof *ws);
}

int crom_nn_pointnet_ws_init(crom_nn_pointnet_ws *ws, const crom_nn_pointnet *pn,
                             int maxframes, int maxpoints, int nthreads)
{
    if (!ws)
        return crom_err(CROM_EUSAGE, "workspace is NULL");
    memset(ws, 0, sizeof *ws);
    if (!pn || !pn->params)
        return crom_err(CROM_EUSAGE, "PointNet is not initialized");
    if (maxframes < 1 || maxpoints < 1 || (long long)maxframes * maxpoints > 0x7fffffff)
        return crom_err(CROM_EUSAGE, "PointNet workspace of %d frames x %d points is invalid",
                        maxframes, maxpoints);
    int rows = maxframes * maxpoints, C = pn->head.spec.width[0];
    /* rows that can receive a gradient: at most C argmax points per frame */
    size_t grows = (size_t)maxframes * (size_t)(maxpoints < C ? maxpoints : C);
    int rc = crom_nn_ws_init(&ws->point, &pn->point, rows, nthreads);
    if (!rc)
        rc = crom_nn_ws_init(&ws->head, &pn->head, maxframes, 1);
    if (rc) {
        crom_nn_pointnet_ws_free(ws);
        return rc;
    }
    ws->argmax = crom_malloc(sizeof(int) * (size_t)maxframes * C);
    ws->pooled = crom_malloc(sizeof(float) * 2 * (size_t)maxframes * C);
    ws->dfeat = crom_malloc(sizeof(float) * grows * (size_t)C);
    ws->rows = crom_malloc(sizeof(int) * ((size_t)rows + grows));
    if (!ws->argmax || !ws->pooled || !ws->dfeat || !ws->rows) {
        crom_nn_pointnet_ws_free(ws);
        return CROM_EINTERNAL;
    }
    ws->maxframes = maxframes;
    ws->maxrows = rows;
    ws->last_frames = ws->last_points = -1;
    return CROM_OK;
}

static int pn_check(const crom_nn_pointnet *pn, const crom_nn_pointnet_ws *ws)
{
    if (!pn || !pn->params)
        return crom_err(CROM_EUSAGE, "PointNet is not initialized");
    if (!ws || !ws->pooled)
        return crom_err(CROM_EUSAGE, "PointNet workspace is not initialized");
    int rc = ws_check(&pn->point, &ws->point);
    if (!rc)
        rc = ws_check(&pn->head, &ws->head);
    return rc ? crom_err_ctx("PointNet") : CROM_OK;
}

int crom_nn_pointnet_forward(const crom_nn_pointnet *pn, crom_nn_pointnet_ws *ws,
                             int F, int P, const float *pts, float *q)
{
    int rc = pn_check(pn, ws);
    if (rc)
        return rc;
    if (F < 1 || P < 1 || F > ws->maxframes || (long long)F * P > ws->maxrows)
        return crom_err(CROM_EUSAGE,
                        "PointNet forward: %d frames x %d points do not fit the workspace (%d frames, %d rows)",
                        F, P, ws->maxframes, ws->maxrows);
    if (!pts || !q)
        return crom_err(CROM_EUSAGE, "PointNet forward: points or output is NULL");
    ws->last_frames = ws->last_points = -1;
    rc = crom_nn_mlp_forward(&pn->point, &ws->point, F * P, pts, NULL);
    if (rc)
        return rc;
    const float *feat = crom_nn_ws_output(&ws->point);
    int C = pn->head.spec.width[0];
    for (int f = 0; f < F; f++) {
        float *mx = ws->pooled + (size_t)f * C;
        int *am = ws->argmax + (size_t)f * C;
        const float *ft = feat + (size_t)f * P * C;
        for (int c = 0; c < C; c++) {
            mx[c] = ft[c];
            am[c] = 0;
        }
        for (int p = 1; p < P; p++) {
            const float *row = ft + (size_t)p * C;
            for (int c = 0; c < C; c++)
                if (row[c] > mx[c]) {
                    mx[c] = row[c];
                    am[c] = p;
                }
        }
    }
    rc = crom_nn_mlp_forward(&pn->head, &ws->head, F, ws->pooled, q);
    if (rc)
        return rc;
    ws->last_frames = F;
    ws->last_points = P;
    return CROM_OK;
}

int crom_nn_pointnet_backward(const crom_nn_pointnet *pn, crom_nn_pointnet_ws *ws,
                              int F, int P, const float *dq, float *grad, float *dpts)
{
    int rc = pn_check(pn, ws);
    if (rc)
        return rc;
    if (ws->last_frames < 0 || F != ws->last_frames || P != ws->last_points ||
        ws->point.last_net != &pn->point || ws->point.last_rows != F * P)
        return crom_err(CROM_EUSAGE,
                        "PointNet backward of %d frames x %d points does not follow a forward pass of that size",
                        F, P);
    if (!dq)
        return crom_err(CROM_EUSAGE, "PointNet backward: dL/dq is NULL");
    int C = pn->head.spec.width[0], din = pn->point.spec.width[0];
    float *dpool = ws->pooled + (size_t)ws->maxframes * C;
    rc = crom_nn_mlp_backward(&pn->head, &ws->head, F, dq,
                              grad ? grad + pn->point.nparams : NULL, dpool);
    if (rc)
        return rc;
    /* The max-pool sends each channel's gradient to its argmax point; only those
     * points (at most C per frame) get a gradient, so the per-point backward runs
     * on them alone: slot[row] = their compact index, idx = their rows. */
    int *slot = ws->rows, *idx = ws->rows + ws->maxrows, n = 0;
    for (int f = 0; f < F; f++) {
        int *sl = slot + (size_t)f * P;
        for (int p = 0; p < P; p++)
            sl[p] = -1;
        for (int c = 0; c < C; c++)
            sl[ws->argmax[(size_t)f * C + c]] = -2; /* marked */
        for (int p = 0; p < P; p++)
            if (sl[p] == -2) {
                sl[p] = n;
                idx[n++] = f * P + p;
            }
    }
    float *dfc = ws->dfeat; /* [n][C] */
    memset(dfc, 0, sizeof(float) * (size_t)n * C);
    for (int f = 0; f < F; f++)
        for (int c = 0; c < C; c++) {
            int p = ws->argmax[(size_t)f * C + c];
            dfc[(size_t)slot[(size_t)f * P + p] * C + c] = dpool[(size_t)f * C + c];
        }
    /* dL/dx of the n rows goes compactly into the first n rows of dpts, and is
     * then spread out to the rows idx */
    if (dpts)
        memset(dpts, 0, sizeof(float) * (size_t)F * P * din);
    backward_rows(&pn->point, &ws->point, n, idx, dfc, grad, dpts);
    if (dpts)
        for (int i = n - 1; i >= 0; i--) {
            /* idx is increasing and idx[i] >= i: move row i to row idx[i] from
             * the top down, clearing its old place */
            if (idx[i] == i)
                continue;
            memcpy(dpts + (size_t)idx[i] * din, dpts + (size_t)i * din,
                   sizeof(float) * (size_t)din);
            memset(dpts + (size_t)i * din, 0, sizeof(float) * (size_t)din);
        }
    return CROM_OK;
}

int crom_nn_pointnet_encode(const crom_nn_pointnet *pn, crom_nn_pointnet_ws *ws,
                            size_t n, const double *pts, double *q)
{
    int rc = pn_check(pn, ws);
    if (rc)
        return rc;
    if (n < 1 || !pts || !q)
        return crom_err(CROM_EUSAGE, "PointNet encode needs at least one point");
    int d = pn->point.spec.width[0], C = pn->head.spec.width[0];
    int L = pn->point.spec.nlayers;
    float *mx = ws->pooled;
    size_t chunk = (size_t)ws->point.maxbatch;
    for (size_t s = 0; s < n; s += chunk) {
        int m = (int)(n - s < chunk ? n - s : chunk);
        normalize_d(&pn->point, m, pts + s * d, ws->point.A[0]);
        forward_rows(&pn->point, &ws->point, m);
        const float *feat = ws->point.A[L];
        for (int p = 0; p < m; p++)
            for (int c = 0; c < C; c++)
                if ((s == 0 && p == 0) || feat[(size_t)p * C + c] > mx[c])
                    mx[c] = feat[(size_t)p * C + c];
    }
    normalize_f(&pn->head, 1, mx, ws->head.A[0]);
    forward_rows(&pn->head, &ws->head, 1);
    int r = pn->head.spec.width[pn->head.spec.nlayers];
    for (int j = 0; j < r; j++)
        q[j] = ws->head.A[pn->head.spec.nlayers][j];
    ws->point.last_rows = ws->head.last_rows = -1;
    ws->last_frames = ws->last_points = -1;
    return CROM_OK;
}

/* ---- Adam ----------------------------------------------------------------- */

void crom_nn_adam_free(crom_nn_adam *opt)
{
    if (!opt)
        return;
    free(opt->m);
    memset(opt, 0, sizeof *opt);
}

int crom_nn_adam_init(crom_nn_adam *opt, size_t n)
{
    if (!opt)
        return crom_err(CROM_EUSAGE, "Adam state is NULL");
    memset(opt, 0, sizeof *opt);
    if (n == 0)
        return crom_err(CROM_EUSAGE, "Adam over zero parameters");
    opt->m = crom_calloc(2 * n, sizeof(float)); /* v lives in the same block */
    if (!opt->m)
        return CROM_EINTERNAL;
    opt->v = opt->m + n;
    opt->n = n;
    opt->beta1 = 0.9;
    opt->beta2 = 0.999;
    opt->eps = 1e-8;
    return CROM_OK;
}

void crom_nn_adam_step(crom_nn_adam *opt, float *params, const float *grad, double lr)
{
    opt->t++;
    double bc1 = 1.0 - pow(opt->beta1, (double)opt->t);
    double bc2 = 1.0 - pow(opt->beta2, (double)opt->t);
    const float b1 = (float)opt->beta1, b2 = (float)opt->beta2;
    const float c1 = (float)(1.0 - opt->beta1), c2 = (float)(1.0 - opt->beta2);
    const float step = (float)(lr / bc1), rs2 = (float)(1.0 / sqrt(bc2));
    const float eps = (float)opt->eps;
    float *m = opt->m, *v = opt->v;
#pragma omp simd
    for (size_t i = 0; i < opt->n; i++) {
        float g = grad[i];
        m[i] = b1 * m[i] + c1 * g;
        v[i] = b2 * v[i] + c2 * g * g;
        params[i] -= step * m[i] / (sqrtf(v[i]) * rs2 + eps);
    }
}

double crom_nn_lr_schedule(double base, int epoch, int nepochs)
{
    if (nepochs < 1 || epoch < 0)
        return base;
    long long e3 = 3LL * epoch;
    if (e3 < nepochs)
        return base;
    if (e3 < 2LL * nepochs)
        return base / 5;
    return base / 50;
}
