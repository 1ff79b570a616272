/* nn.h — small float32 neural networks on the CPU: dense MLPs, a PointNet
 * encoder, Adam, and the LiCROM learning-rate schedule.
 *
 * What crom learns with it (DESIGN.md, seeds/):
 *   - the neural displacement field W: R^3 -> R^{3 x r} of LiCROM §3.1, an MLP
 *     3 -> 60 -> 60 -> 60 -> 60 -> 3r with ELU (or SIREN sine) activations;
 *   - the PointNet encoder P of LiCROM §3.1 / Fig. 4 (Qi et al. 2017 without the
 *     transform nets): a shared per-point MLP on (X, u) in R^6, a max-pool over the
 *     points of each frame, and an MLP head producing the latent q in R^r;
 *   - the subspace map f(z) of the Data-Free paper, whose Jacobian w.r.t. its
 *     latent input z comes from forward-mode tangents (crom_nn_mlp_jvp/_jacobian).
 *
 * Layout conventions
 *   - Batches are row-major: inputs [B][in], outputs [B][out].
 *   - Every network keeps ALL its parameters in ONE contiguous float vector
 *     (`params`, `nparams` entries); layer l has weights W_l [out][in] (row-major,
 *     PyTorch's nn.Linear layout) at params + layer[l].woff and biases b_l [out] at
 *     params + layer[l].boff, layers in order. A gradient array has the same
 *     layout, so Adam, serialization and an MPI allreduce see one vector.
 *   - The parameter vector is either owned by the network (storage == NULL at
 *     init) or borrowed from the caller (storage != NULL), so that several
 *     networks — e.g. the field W and the encoder P — can live in one vector
 *     trained by one Adam: place them at offsets of one array of size
 *     crom_nn_spec_nparams(spec_W) + crom_nn_pointnet_nparams(...).
 *   - Inputs are raw (un-normalized): every MLP stores a per-coordinate shift and
 *     scale and feeds (x - shift) / scale to its first layer; all derivatives
 *     w.r.t. the input are w.r.t. the raw x.
 *   - Activations: hidden layers use `act`; the output layer uses `out_act`
 *     (LINEAR for a regression head; the PointNet per-point MLP uses ELU there,
 *     as PointNet applies the nonlinearity before the max-pool). Sine layers
 *     compute sin(omega0 * (W x + b)) (SIREN, omega0 = 30 by default).
 *
 * Work space: forward/backward/JVP never allocate. A crom_nn_ws, sized for a
 * maximum batch, holds the activations of the last forward pass (needed by the
 * backward pass) and per-thread scratch. A network is read-only during these
 * calls, so several threads may share one network, each with its own workspace
 * and its own gradient array. Batches are processed in cache-sized blocks of
 * rows (a few hundred), one sgemm per layer and block.
 *
 * Threads: a workspace made for nthreads > 1 splits the blocks of a batch over
 * nthreads OpenMP threads (block k to thread k mod nthreads; each thread sums
 * its gradients privately, and the sums are added in thread order), so results
 * are deterministic for a given thread count, though they differ in the last
 * bits between thread counts. Each thread calls sgemm on its own blocks: with
 * nthreads > 1 keep OpenBLAS at one thread (openblas_set_num_threads(1)).
 * The default (nthreads = 1) runs serially and lets OpenBLAS thread if it will.
 *
 * Errors: functions returning int return CROM_OK or a crom error code with a
 * message (crom_errmsg()); nothing prints, nothing exits.
 */
#ifndef CROM_NN_H
#define CROM_NN_H

#include <stddef.h>

#include "base/rng.h"

#define CROM_NN_MAX_LAYERS 16        /* dense layers per MLP */
#define CROM_NN_MAX_WIDTH (1 << 20)  /* units per layer */

typedef enum {
    CROM_NN_LINEAR = 0, /* identity */
    CROM_NN_ELU = 1,    /* z > 0 ? z : exp(z) - 1   (alpha = 1, Clevert et al. 2016) */
    CROM_NN_SINE = 2,   /* sin(omega0 z)            (SIREN, Sitzmann et al. 2020) */
    CROM_NN_GELU = 3    /* z Phi(z), exact erf form (Neural Modes) */
} crom_nn_act;

/* The shape of an MLP: everything needed, with the parameter vector, to rebuild
 * it (what a model file stores). */
typedef struct {
    int nlayers;                       /* dense layers, 1..CROM_NN_MAX_LAYERS */
    int width[CROM_NN_MAX_LAYERS + 1]; /* width[0] inputs, ..., width[nlayers] outputs */
    crom_nn_act act;                   /* hidden-layer activation */
    crom_nn_act out_act;               /* output-layer activation (LINEAR normally) */
    float omega0;                      /* sine frequency factor (30) */
} crom_nn_spec;

/* A view of one dense layer inside the parameter vector. */
typedef struct {
    int in, out;      /* fan-in and fan-out */
    crom_nn_act act;  /* activation applied after W x + b */
    size_t woff;      /* offset of W [out][in] in params (and in gradients) */
    size_t boff;      /* offset of b [out] */
    float *W, *b;     /* params + woff, params + boff */
} crom_nn_layer;

typedef struct {
    crom_nn_spec spec;
    crom_nn_layer layer[CROM_NN_MAX_LAYERS];
    size_t nparams;   /* length of params */
    float *params;    /* all weights and biases, layer by layer (W_l then b_l) */
    float *shift;     /* [width[0]] input shift (default 0) */
    float *scale;     /* [width[0]] input scale (default 1): x_n = (x - shift)/scale */
    int owns_params;  /* params allocated by init (freed by crom_nn_mlp_free) */
} crom_nn_mlp;

/* Workspace of one MLP for batches up to maxbatch rows, used by nthreads
 * threads. Fields below nthreads are private. */
typedef struct crom_nn_thread crom_nn_thread; /* per-thread scratch (private) */
typedef struct {
    int maxbatch;     /* rows the activation buffers hold */
    int nthreads;     /* threads that split a batch (set at init) */
    int nlayers, width[CROM_NN_MAX_LAYERS + 1], maxw;
    int block;        /* rows per block (cache-sized) */
    int last_rows;    /* rows of the last forward pass (-1: none yet) */
    const void *last_net;
    float *A[CROM_NN_MAX_LAYERS + 1]; /* A[0] normalized input, A[l] layer outputs */
    float *Z[CROM_NN_MAX_LAYERS + 1]; /* pre-activations (only where needed) */
    crom_nn_thread *thr;              /* [nthreads] */
    float *mem;
} crom_nn_ws;

/* PointNet encoder: q = head(max over points of point(X_i, u_i)). */
typedef struct {
    crom_nn_mlp point; /* shared per-point MLP, e.g. 6 -> 64 -> 128 -> 256 */
    crom_nn_mlp head;  /* e.g. 256 -> 128 -> 64 -> r */
    size_t nparams;    /* point.nparams + head.nparams */
    float *params;     /* [point params | head params] */
    int owns_params;
} crom_nn_pointnet;

typedef struct {
    crom_nn_ws point, head;
    int maxframes, maxrows; /* frames, and frames x points, per call */
    int last_frames, last_points;
    int *argmax;       /* [maxframes][C] point index of each pooled channel */
    float *pooled;     /* [2][maxframes][C]: pooled features, their gradient */
    float *dfeat;      /* [maxframes * min(maxpoints, C)][C] gradient at argmax points */
    int *rows;         /* [maxrows] slots, then the argmax rows */
} crom_nn_pointnet_ws;

/* Adam (Kingma & Ba 2015) over a flat parameter vector, PyTorch's form:
 * m = b1 m + (1-b1) g, v = b2 v + (1-b2) g^2,
 * p -= lr / (1 - b1^t) * m / (sqrt(v / (1 - b2^t)) + eps). */
typedef struct {
    size_t n;
    float *m, *v;     /* first and second moments [n] */
    long t;           /* steps taken */
    double beta1, beta2, eps; /* 0.9, 0.999, 1e-8 */
} crom_nn_adam;

/* ---- activations and specs ------------------------------------------------ */

/* Name of an activation ("linear", "elu", "sine", "gelu"); "unknown" if invalid. */
const char *crom_nn_act_name(crom_nn_act act);

/* Parse an activation name into *act; CROM_EUSAGE if the name is unknown. */
int crom_nn_act_parse(const char *name, crom_nn_act *act);

/* Fill *spec from nwidths widths (input, hidden..., output), hidden activation
 * act, linear output, omega0 = 30; CROM_EUSAGE if the shape is invalid. */
int crom_nn_spec_set(crom_nn_spec *spec, int nwidths, const int *widths,
                     crom_nn_act act);

/* Validate a spec: CROM_OK if usable, CROM_EUSAGE (with a message) for a bad
 * layer count, width, activation or omega0. */
int crom_nn_spec_check(const crom_nn_spec *spec);

/* Number of parameters of an MLP of this shape; 0 (with a message) if invalid. */
size_t crom_nn_spec_nparams(const crom_nn_spec *spec);

/* 1 if net has the shape of spec (layers, widths, hidden activation, and
 * so the parameter count), else 0: whether its parameters can start a
 * network of that spec. */
int crom_nn_mlp_has_spec(const crom_nn_mlp *net, const crom_nn_spec *spec);

/* ---- MLP ------------------------------------------------------------------ */

/* Build an MLP of shape *spec on storage (NULL: allocate and own it). With an
 * rng, initialize the parameters: Xavier-uniform weights and zero biases, or
 * SIREN's init (first layer U(+-1/fan_in), later layers U(+-sqrt(6/fan_in)/omega0),
 * biases U(+-1/sqrt(fan_in))) when act is SINE; with rng == NULL the storage
 * keeps its contents (an already-trained vector). Normalization starts as the
 * identity. Returns CROM_EUSAGE for a bad spec, CROM_EINTERNAL if out of memory;
 * *net is then empty (safe to free). */
int crom_nn_mlp_init(crom_nn_mlp *net, const crom_nn_spec *spec, float *storage,
                     crom_rng *rng);

/* Rebuild a stored MLP: copy nparams parameters (must equal the shape's count)
 * and the optional input shift/scale (NULL: identity). CROM_EDATA if the count,
 * the spec or a scale is wrong. */
int crom_nn_mlp_from_params(crom_nn_mlp *net, const crom_nn_spec *spec,
                            const float *params, size_t nparams,
                            const float *shift, const float *scale);

/* Free what init allocated (borrowed storage is left alone); net becomes empty. */
void crom_nn_mlp_free(crom_nn_mlp *net);

/* Set the input normalization x_n = (x - shift) / scale (width[0] entries each;
 * NULL means 0 or 1). CROM_EDATA if a scale is not finite and positive. */
int crom_nn_mlp_set_norm(crom_nn_mlp *net, const float *shift, const float *scale);

/* Per-coordinate centre and half-extent of n points of dimension dim (row-major
 * [n][dim]), so that (x - shift) / scale lies in [-1, 1]. A coordinate with zero
 * extent gets the largest half-extent of the others (1 if all are zero).
 * CROM_EUSAGE if n < 1 or dim < 1, CROM_EDATA if a value is not finite. */
int crom_nn_norm_fit(const double *x, size_t n, int dim, float *shift,
                     float *scale);

/* Allocate a workspace for batches of up to maxbatch rows of this network's
 * shape, used by nthreads threads (1: serial). CROM_EUSAGE if maxbatch < 1 or
 * nthreads is not in 1..1024, CROM_EINTERNAL if out of memory. */
int crom_nn_ws_init(crom_nn_ws *ws, const crom_nn_mlp *net, int maxbatch,
                    int nthreads);

/* Free a workspace (safe on a zeroed or already freed one). */
void crom_nn_ws_free(crom_nn_ws *ws);

/* Output [B][out] of the last forward pass, inside the workspace (valid until
 * the next forward pass). */
const float *crom_nn_ws_output(const crom_nn_ws *ws);

/* Forward pass of B raw inputs x [B][in]; writes y [B][out] if y != NULL and
 * keeps the activations for crom_nn_mlp_backward. CROM_EUSAGE if B < 0,
 * B > ws->maxbatch, or ws was made for another shape. */
int crom_nn_mlp_forward(const crom_nn_mlp *net, crom_nn_ws *ws, int B,
                        const float *x, float *y);

/* Backward pass (vector-Jacobian product) through the last forward pass of this
 * network on this workspace: given dy = dL/dy [B][out], ADD dL/dparams into grad
 * (same layout as params; NULL to skip) and write dL/dx [B][in] w.r.t. the raw
 * input into dx (NULL to skip). May be called several times per forward pass.
 * CROM_EUSAGE if B differs from that forward pass or there was none. */
int crom_nn_mlp_backward(const crom_nn_mlp *net, crom_nn_ws *ws, int B,
                         const float *dy, float *grad, float *dx);

/* Forward pass plus forward-mode tangents (Jacobian-vector products): for each
 * of B inputs x [B][in], K tangents dx [B][K][in] give y [B][out] (NULL to skip)
 * and dy [B][K][out] = J(x_b) dx_bk. CROM_EUSAGE if B > ws->maxbatch or K >
 * ws->block (at least max(16, in) rows, 512 for narrow networks). Leaves the
 * activations for crom_nn_mlp_backward like a forward pass. */
int crom_nn_mlp_jvp(const crom_nn_mlp *net, crom_nn_ws *ws, int B,
                    const float *x, int K, const float *dx, float *y, float *dy);

/* Full Jacobian J [n][out][in] = dy/dx (raw input) at n inputs x [n][in] (any
 * n, in chunks of maxbatch; in forward-mode tangents per input), and y [n][out]
 * if y != NULL. CROM_EUSAGE on NULL arguments. */
int crom_nn_mlp_jacobian(const crom_nn_mlp *net, crom_nn_ws *ws, size_t n,
                         const float *x, float *J, float *y);

/* Inference in double: y [n][out] at n raw inputs x [n][in] (any n, in chunks of
 * maxbatch; normalization is applied in double before rounding to float), and
 * J [n][out][in] if J != NULL. Returns as crom_nn_mlp_forward. */
int crom_nn_mlp_eval(const crom_nn_mlp *net, crom_nn_ws *ws, size_t n,
                     const double *x, double *y, double *J);

/* ---- PointNet ------------------------------------------------------------- */

/* Fill the two specs of a PointNet encoder: per-point MLP with widths pw
 * (npw of them, e.g. 6,64,128,256; ELU on every layer including the last) and
 * head with widths hw (nhw, e.g. 256,128,64,r; ELU hidden, linear output).
 * CROM_EUSAGE if a shape is invalid or hw[0] != pw[npw-1]. */
int crom_nn_pointnet_spec(crom_nn_spec *point, crom_nn_spec *head, int npw,
                          const int *pw, int nhw, const int *hw);

/* Number of parameters of a PointNet of these shapes; 0 (with a message) if
 * invalid. */
size_t crom_nn_pointnet_nparams(const crom_nn_spec *point, const crom_nn_spec *head);

/* Build a PointNet on storage ([point | head], NULL: allocate and own), with
 * parameters initialized from rng (NULL: keep the storage's contents). Errors as
 * crom_nn_mlp_init, plus CROM_EUSAGE if head input != point output. */
int crom_nn_pointnet_init(crom_nn_pointnet *pn, const crom_nn_spec *point,
                          const crom_nn_spec *head, float *storage, crom_rng *rng);

/* Rebuild a stored PointNet from its flat parameters (count must match) and the
 * per-point input normalization (NULL: identity). CROM_EDATA on mismatch. */
int crom_nn_pointnet_from_params(crom_nn_pointnet *pn, const crom_nn_spec *point,
                                 const crom_nn_spec *head, const float *params,
                                 size_t nparams, const float *shift,
                                 const float *scale);

/* Free what init allocated; pn becomes empty. */
void crom_nn_pointnet_free(crom_nn_pointnet *pn);

/* Workspace for up to maxframes frames of up to maxpoints points each (i.e.
 * maxframes*maxpoints rows through the per-point MLP), nthreads threads for
 * the per-point MLP. CROM_EUSAGE on bad sizes, CROM_EINTERNAL out of memory. */
int crom_nn_pointnet_ws_init(crom_nn_pointnet_ws *ws, const crom_nn_pointnet *pn,
                             int maxframes, int maxpoints, int nthreads);

/* Free a PointNet workspace (safe on a zeroed one). */
void crom_nn_pointnet_ws_free(crom_nn_pointnet_ws *ws);

/* Encode F frames of P points each, pts [F][P][in] (in = 6 for (X, u)), into
 * q [F][r]. CROM_EUSAGE if F > maxframes, F*P exceeds the workspace, P < 1. */
int crom_nn_pointnet_forward(const crom_nn_pointnet *pn, crom_nn_pointnet_ws *ws,
                             int F, int P, const float *pts, float *q);

/* Backward through the last forward pass: given dq = dL/dq [F][r], ADD
 * dL/dparams into grad (layout of pn->params; NULL to skip) and write dL/dpts
 * [F][P][in] (NULL to skip). The max-pool passes each channel's gradient to the
 * point that attained the maximum (the first one on ties), so the per-point
 * backward runs only on those points (at most C per frame). CROM_EUSAGE if F, P
 * differ from that forward pass. */
int crom_nn_pointnet_backward(const crom_nn_pointnet *pn, crom_nn_pointnet_ws *ws,
                              int F, int P, const float *dq, float *grad,
                              float *dpts);

/* Inference in double: encode ONE frame of any number n >= 1 of points pts
 * [n][in] into q [r] (points in chunks of the workspace's rows). */
int crom_nn_pointnet_encode(const crom_nn_pointnet *pn, crom_nn_pointnet_ws *ws,
                            size_t n, const double *pts, double *q);

/* ---- Adam and the learning-rate schedule ---------------------------------- */

/* Zeroed Adam state for n parameters, beta1 0.9, beta2 0.999, eps 1e-8.
 * CROM_EUSAGE if n == 0, CROM_EINTERNAL if out of memory. */
int crom_nn_adam_init(crom_nn_adam *opt, size_t n);

/* Free the moments; opt becomes empty. */
void crom_nn_adam_free(crom_nn_adam *opt);

/* One Adam step with learning rate lr on params [n] given grad [n]. */
void crom_nn_adam_step(crom_nn_adam *opt, float *params, const float *grad,
                       double lr);

/* LiCROM §3.1 step schedule for 0-based epoch of nepochs: base for the first
 * third of the epochs, base/5 for the second, base/50 for the last third. */
double crom_nn_lr_schedule(double base, int epoch, int nepochs);

#endif
