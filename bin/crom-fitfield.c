/* crom-fitfield — learn a displacement basis W(X) (crom/model) from point
 * samples (crom/samples): a neural field, or a classic POD basis; or, with
 * no data at all, a subspace from the energy of a body (--objective
 * energy|neuralmodes|field|skinning: the library's datafree layer; this
 * program parses the options, reports and shows progress).
 *
 * Built with -DCROM_MPI (the Makefile does when it finds Open MPI's mpicc)
 * and launched by mpirun, it trains the neural field data-parallel: each
 * rank evaluates its shards of every step and MPI_Allreduce sums the
 * gradient (lib/rom/fit.h, --shards). The library knows nothing of MPI:
 * this program gives it the allreduce, and only here is MPI called. */
#ifdef _OPENMP
#include <omp.h>
#endif
#ifdef CROM_MPI
#include <mpi.h>
#endif
#include <fcntl.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "base/err.h"
#include "base/parse.h"
#include "cli/cli.h"
#include "datafree/body.h"
#include "datafree/datafree.h"
#include "datafree/dffield.h"
#include "datafree/dfskin.h"
#include "io/io.h"
#include "phys/scenario.h"
#include "rom/fit.h"
#include "rom/model.h"
#include "rom/samples.h"
#include "rom/skin.h"

enum { O_RANK = 300, O_ENCODER, O_BASIS, O_EPOCHS, O_MINUTES, O_LR, O_BATCH, O_PPS, O_ENCPTS,
       O_ACT, O_WIDTH, O_DEPTH, O_TIK, O_OBJECTIVE, O_MESH, O_MODES, O_SIGMA, O_LAMBDA, O_RAMP, O_BOX, O_BOXSC,
       O_ORTHO, O_STEPS, O_FEATURES, O_TETS, O_PINW, O_OPTIM, O_RESAMPLE, O_TANW, O_TANF, O_HANDLES, O_WEIGHTS,
       O_SURFACE, O_CLOUD, O_SPOINTS, O_COORDS, O_COORDTOL, O_DERIV, O_SUPERV, O_TANANCHOR, O_VISIT, O_SHARDS, O_COND, O_SEEDST, O_SEEDFR, O_INITM, O_CUTSEG, O_CUTAXIS, O_LAST };

/* --objective skinning (lib/datafree/dfskin.h), next to the CROM_DATAFREE_* codes */
#define OBJ_SKINNING 100

/* the end of --shards' text: what this build does (tests/prog/mpi.sh reads it) */
#ifdef CROM_MPI
#define CROM_FITFIELD_MPI_NOTE "This crom-fitfield was built with MPI; under it --threads 0 (all cores) means the " \
                               "cores of a node divided by the ranks on it."
#else
#define CROM_FITFIELD_MPI_NOTE "This crom-fitfield was built without MPI (no mpicc when it was made, or MPI=0): " \
                               "the shards of a step are evaluated one after another."
#endif

static const crom_opt fit_opts[] = {
    {"output", 'o', "OUT", "Write the model to OUT (default: stdout, which must not be a terminal)."},
    {"objective", O_OBJECTIVE, "KIND", "samples (default): fit a basis to the samples read from SAMPLES. energy: learn a nonlinear subspace of the mesh given with --mesh from its energy alone, no data (Sharp et al. 2023). neuralmodes: nonlinear modes x(z) = X + Phi z + y(z) on the linear modes of --modes (Wang et al. 2024). field: a continuous nonlinear subspace x(X, z) = X + W(X) phi(z), trained like energy from the energy integrated by a random cubature of --mesh, that lays on any mesh of the body (beyond both papers). skinning: a linear subspace of --handles affine skinning handles whose weights w(X) lay on any mesh (Simplicits, Modi et al. 2024; skinning eigenmodes, Benchekroun et al. 2023)."},
    {"rank", O_RANK, "R", "Number of basis fields r, the latent dimension (default 20; energy: 8; neuralmodes: every mode of --modes). At most the number of frames with a non-zero displacement (for pod: the numerical rank of the snapshots; data-free: the free degrees of freedom; neuralmodes: the modes in --modes)."},
    {"basis", O_BASIS, "KIND", "mlp (default): a neural field W(X), usable on any mesh. pod: classic POD of samples of ONE mesh taken with crom-sample --points all, stored as a piecewise-linear field on that mesh."},
    {"encoder", O_ENCODER, "KIND", "How q is found for a frame during and after training (mlp only). lsq (default): the least-squares fit of W to the frame's samples, re-solved at every step (variable projection; fast). pointnet: the paper's PointNet encoder, trained jointly with W (LiCROM eq. 4) and stored in the model."},
    {"cut-segment", O_CUTSEG, "AU,AV,BU,BV", "A field that can jump across a cut (mlp; LiCROM's tearing): the segment from A to B of a ribbon of the cut the training data was made with, in crom-remesh cut's coordinates (the other two axes of --cut-axis, in x,y,z order); repeatable, at most 16. The field then takes, after X, one feature per segment: the angle the segment subtends at X over pi, which jumps from +1 to -1 across the segment and nowhere else. A smooth field of X alone cannot open a crack: its best fit stretches the elements beside it and the reduced step keeps the crack shut (README, tearing)."},
    {"cut-axis", O_CUTAXIS, "x|y|z", "The axis the ribbons of --cut-segment are extruded along (default y, as crom-remesh cut)."},
    {NULL, 0, NULL, NULL}};

static const crom_opt df_opts[] = {
    {"mesh", O_MESH, "MESH", "The crom/mesh the data-free subspace maps (required with --objective energy|neuralmodes; field and skinning take it, --surface or --cloud; '-' for stdin). Its regions resolve --pin. energy and neuralmodes store it: the subspace lives on this mesh; field and skinning are trained on it and lay on any mesh."},
    {"surface", O_SURFACE, "FILE", "field, skinning (trained): train on a closed triangle surface (.stl or .obj) instead of a tet mesh: --sample-points points inside it (inside/outside by the winding number, on a jittered grid), each standing for an equal share of the enclosed volume, integrated through small virtual tets. --pin takes predicates ('x<-0.49'); the surface's triangles inside a pin hold the weights at exactly 0 there on any mesh."},
    {"cloud", O_CLOUD, "FILE", "field, skinning (trained): train on a point cloud with volumes: a text file of lines 'x y z volume' (metres, cubic metres; blanks or commas; # comments), each point standing for its volume. --pin takes predicates."},
    {"sample-points", O_SPOINTS, "N", "--surface: about N points inside it (default 8192)."},
    {"handles", O_HANDLES, "H", "skinning: the number of affine handles, 12 latent coordinates each (default 8). A free body (no pin) has a constant handle among them, so rigid motions are in the subspace exactly. At most the free degrees of freedom / 12. field: lay the continuous field over the skinning eigenmodes of H handles of --mesh instead of training a feature field W(X): x(X, z) = X + W(X) (phi(z) - phi(0)) with W the skinning basis and phi alone trained (model basis 'skin-field')."},
    {"coordinates", O_COORDS, "KIND", "skinning: orthonormal (default): the latent is 3S coordinates of S functions psi_s mass-orthonormal over the training geometry that span the same space as the 4H functions w_h [X_hat; 1]_j (the affine ones first on a free body), so W^T M W = m I and no latent direction is redundant; numerically dependent directions (Gram eigenvalue below --coordinate-tol of the largest) are dropped. handles: the 12H handle coordinates themselves, W[c][12h + 4c + j] = w_h [X_hat; 1]_j (near-dependent for smooth weights: an ill-conditioned reduced Hessian)."},
    {"coordinate-tol", O_COORDTOL, "T", "skinning: the relative eigenvalue below which a direction of the handle span is dropped (default 1e-6)."},
    {"weights", O_WEIGHTS, "KIND", "skinning: trained (default): an MLP 3 -> H trained data-free on the energy of random handle poses plus the orthogonality of the weights (Simplicits). eigen: no training, the lowest eigenvectors of the scalar stiffness (the elasticity Hessian at rest summed over the three components) against the lumped mass, pinned vertices eliminated (skinning eigenmodes; needs --mesh, a solid's or a shell's: on a shell the weights live at its vertices, and the sheet's normal direction, where it has no extent, drops out of the span)."},
    {"modes", O_MODES, "MODEL", "neuralmodes (required): a crom/model of linear modes of the same mesh, from crom-modes. Its lowest --rank modes are the linear part Phi; its pins are kept, its material is the default."},
    {"steps", O_STEPS, "N", "Training steps of a data-free objective (energy, neuralmodes: default 4000 of --batch 8 samples at --lr 3e-3; field, skinning: 2000 of 32 (skinning: 16) at 1e-3). The learning rate is halved after each quarter of the steps (or of --minutes). neuralmodes takes 0: no training, y = 0 (with --derivatives: the quadratic manifold X + Phi z + 1/2 sum Psi_ij z_i z_j of Barbic and James)."},
    {"sigma", O_SIGMA, "S", "energy: isometry scale in metres: the subspace should move the body by S (RMS displacement) per unit of latent distance, |f(z) - f(z')|_M / sqrt(m) ~ S |z - z'|, z ~ N(0, I) (default 0.05 times the bounding-box diagonal; field --handles: 0.15). Sharp et al.'s sigma divided by sqrt(body mass). skinning: the RMS displacement in metres of the random handle poses the weights are trained on (default 0.01 times the diagonal)."},
    {"lambda", O_LAMBDA, "L", "energy: weight of the isometry term, the squared log-ratio of mass-norm distances to S |z - z'| over all pairs of a batch, against the energy in units of E V (Young's modulus times volume) (default 0.03; field: 1, with --handles 0.03). A weaker isometry lets the energy shape the subspace: 1 keeps the map near-isometric but leaves the static sag of a soft body 40-80% off."},
    {"ramp", O_RAMP, "F", "energy: the seed-state blend rho grows linearly from 0 to 1 over the first fraction F of the steps, then stays 1 (default 0.5; Sharp et al. §4.1). The seed state is the rest shape, or --seed-state."},
    {"tangent-weight", O_TANW, "W", "energy, field: weight of the collapse floor at rest (Neural Modes §4.4's mode-collapse measure made a loss): the secants z = 0.1 e_k from rest along the r latent axes give the Gram matrix G = J^T M J / m of the map at rest, and every eigenvalue mu of r G / tr G below --tangent-floor adds log^2(mu / floor), so that no latent direction collapses at rest, where every run starts (default 0.03; field with --handles: 0.1; 0: none)."},
    {"tangent-floor", O_TANF, "F", "energy, field: the floor of --tangent-weight, in (0, 1]: normalized eigenvalues above it cost nothing (default 0.03; crom-metrics counts a dimension below 0.01 as collapsed). On the soft bar of the benchmarks a floor of 0.1 made the first step from rest 13-15% off for the skin-field and the energy map; 0.03 keeps every direction above 0.01 and the skin-field's first step at 4-7%."},
    {"box", O_BOX, "A", "neuralmodes: half-width of the box the modal coordinates z are drawn from, in metres of RMS displacement: [-A, A] for the lowest mode (default 0.2 times the bounding-box diagonal; see --box-scaling)."},
    {"derivatives", O_DERIV, NULL, "neuralmodes: seed the map with the modal derivatives Psi_ij of its --rank modes (Barbic and James 2005, computed here on --mesh with the material and pins): x(z) = X + Phi z + 1/2 sum_{i<=j} Psi_ij z_i z_j + y(z). The second-order term is the in-plane shortening that keeps bent modes of a shell or a slender body from stretching (locking), which y alone learns slowly; the model stores Psi."},
    {"tangent-anchor", O_TANANCHOR, NULL, "neuralmodes: anchor the correction's tangent too: y(z) = N(z) - N(0) - J_N(0) z, zero to first order, so that the map leaves rest along the modes exactly as the constrained equilibria do (a learned first-order part stiffens small deflections). Trained with J_N(0) z as a central difference of step 0.01 z; the model (tangent_anchored) evaluates it exactly."},
    {"supervised", O_SUPERV, "EQ", "neuralmodes: the supervised baseline of Wang et al. (their 'L2 supervised'): the same map fitted to the constrained equilibria of EQ (crom-fullsim --equilibria in the same modes, on --mesh) by the mean squared mass-weighted distance, instead of trained on the energy; batches are drawn from the equilibria."},
    {"condition", O_COND, "NAME=LO:HI", "energy: a conditional map (Sharp et al. 3.5): the network takes [z, c] and each batch is trained at a c drawn uniformly from LO:HI. NAME: ratio:REGION, the Young's modulus of REGION's tets over the body's (a region of another material); gravity:x|y|z, that component of gravity (m/s^2); pin:REGION:x|y|z, where a pinned REGION (give --pin REGION) is held, displaced along that axis (m): the map then starts from the body's static lift at rest with the pin moved so (field/lifts). Repeatable (at most 4). crom-reducedstep --model takes --condition NAME=VALUE[@T] to run the map at a condition, or change it at time T."},
    {"seed-state", O_SEEDST, "RUN", "energy: grow the map from a seed state instead of the rest shape (Sharp et al. 4.1): the displacement of a frame of RUN, a crom-fullsim trajectory of --mesh (e.g. the equilibrium of a bar compressed by --velocity on its ends, their regions then pinned here where the seed holds them). The map is anchored there, x(0) = X + u_seed (field/seed in the model): a reduced run starts from it, and its pins and prescribed motions are taken from it."},
    {"seed-frame", O_SEEDFR, "K", "--seed-state: which frame (default -1, the last; negative counts from the end)."},
    {"init-model", O_INITM, "MODEL", "energy: refine the energy map MODEL (of --mesh, with the same --rank, --condition, --width and --depth) instead of training from scratch: training starts from its network at rho = 1 (no seed blend) and keeps its seed state; with --latents RUN (a crom-reducedstep --model MODEL run), every other sample is drawn near a latent the run visited (plus 0.15 N(0, I)), so the map's energy is lowered where the run went (e.g. a bistable bar's second equilibrium). Still data-free: the run is in the subspace. The model records refined_from. field: refine the continuous field MODEL the same way (its phi and W(X), on any mesh of the body); with --handles, the skin-field MODEL (its latent network phi over the same skinning eigenmodes, which the same mesh, material, pins and --handles give again; checked), e.g. along its static run under the load it must hold (a smaller --lr refines better: 1e-4 took a soft bar's static sag error from 18-19% to 5.6-8.6% in 5000 steps, where the default 1e-3 made it worse, and an energy map's from 6-28% to 1.5-7.6% in 3000; README)."},
    {"latents", O_VISIT, "RUN", "neuralmodes: sample along a run: every other sample of a batch is drawn near the modal coordinates of a frame of RUN (a crom/latent of a reduced run in the same modes, e.g. crom-reducedstep --model of the untrained map, --steps 0), moved by up to 15% of max(box half-width, |z_k|) per coordinate; the others from the box. For deformations whose coordinates lie outside the box (a soft body sagging far under its load). Still data-free: no full simulation. energy and field: with --init-model only (see there)."},
    {"box-scaling", O_BOXSC, "KIND", "neuralmodes: frequency (default): mode k is drawn from [-A f_1/f_k, A f_1/f_k], the same linear energy at every edge, so that the stiff modes do not swamp the energy of the soft ones; uniform: every mode from [-A, A] (Wang et al.)."},
    {"optimizer", O_OPTIM, "KIND", "energy, neuralmodes: adam (default): Adam on a fresh batch every step. lbfgs: L-BFGS with a backtracking line search (Wang et al.), --resample iterations on each batch."},
    {"resample", O_RESAMPLE, "N", "--optimizer lbfgs: iterations on each batch of samples before a fresh one is drawn (default 10)."},
    {"features", O_FEATURES, "P", "field: the feature fields of W(X), the output width of phi (default 32)."},
    {"tets", O_TETS, "K", "Tets of the random cubature drawn afresh at every step, each standing for nt/K of them (field, skinning: default 512; energy, neuralmodes: default every tet, exactly; at most every tet)."},
    {"pin-length", O_PINW, "L", "field: the field is masked by smoothstep(d / L), d the distance to the nearest pinned vertex of --mesh, so it vanishes there on any mesh (default: twice the mean edge length). skinning (trained): the weights are masked by s(d / L), s(t) = t (2 - t) below 1 (default 0.05 times the diagonal)."},
    {"ortho-weight", O_ORTHO, "W", "neuralmodes: weight of the penalty |Phi^T M y(z)|^2 / (m A^2) keeping the correction M-orthogonal to the linear modes, against the energy in units of the linear energy of a mode at the edge of the box (default 1e4). skinning: weight of the orthogonality loss |G - I|^2 of the weights' mass-mean Gram matrix G (default 1)."},
    {NULL, 0, NULL, NULL}};

static const crom_opt train_opts[] = {
    {"epochs", O_EPOCHS, "N", "Training epochs (default 400 for lsq, 3750 for pointnet as in the paper). An epoch is one pass over the frames in batches of --batch frames. The learning rate is --lr, divided by 5 after a third of the epochs and by 50 after two thirds (LiCROM §3.1)."},
    {"minutes", O_MINUTES, "M", "Stop training after M minutes of wall time. The learning-rate schedule then follows whichever is further along: the fraction of epochs done or the fraction of the time budget used, so a run cut short by the clock still goes through all three rates. Runs limited by the clock are not byte-reproducible."},
    {"lr", O_LR, "LR", "Base learning rate of Adam (default 5e-3 for lsq, 1e-3 for pointnet as in the paper; data-free: see --steps). With --optimizer lbfgs: the largest change of a parameter in its first step."},
    {"batch", O_BATCH, "B", "Frames per step (default 16); data-free: latent samples per step (see --steps)."},
    {"points-per-step", O_PPS, "P", "Samples of each frame used per step (default: 128 for lsq, every sample for pointnet). For vertex samples, a step evaluates W once at a random subset of one mesh's vertices, shared by all frames of the batch; P sets its size (about P x vertices / samples-per-frame). Interior samples are evaluated frame by frame, which costs about --batch times more per step."},
    {"encoder-points", O_ENCPTS, "N", "Points per frame the PointNet encoder sees, a random subsample (default 2500, or all if fewer)."},
    {"activation", O_ACT, "ACT", "Hidden activation of W: elu (default) or sine (SIREN, omega0 = 30). With omega0 = 30 a sine field can interpolate the training points and oscillate between them: check it with crom-encode on another mesh. Data-free maps: elu (energy default), gelu (neuralmodes default) or sine."},
    {"width", O_WIDTH, "W", "Hidden width of the field MLP (default 60; data-free maps: 64)."},
    {"depth", O_DEPTH, "D", "Dense layers of the field MLP (default 5: 3 -> 60 -> 60 -> 60 -> 60 -> 3r; data-free maps: 6, i.e. r -> 64 x 5 -> 3nv)."},
    {"tikhonov", O_TIK, "T", "Relative Tikhonov weight of the lsq fits: lambda = T tr(W^T W) / r (default 1e-6)."},
    {"shards", O_SHARDS, "S", "Cut each step's batch into S shards of consecutive frames, about --batch/S each, every shard with points of its own (vertex samples: its own subset of the mesh's vertices, so a step evaluates W at S times as many points), and take the gradient of the mean loss over all their samples (default 1; under MPI the number of ranks; at most the frames of a batch). Under MPI (mpirun -n P crom-fitfield --shards S ... SAMPLES) rank p evaluates shards p, p + P, ..., one MPI_Allreduce per step sums the gradient with the loss terms (8 bytes per network parameter, plus 72), and every rank takes the same Adam step: P ranks train the model one process trains with the same --shards and --seed, up to round-off. Every rank reads SAMPLES (a file, not stdin); rank 0 alone prints and writes the model; an error on any rank stops them all. " CROM_FITFIELD_MPI_NOTE},
    {NULL, 0, NULL, NULL}};

static const crom_cli_optgroup groups[] = {{"Options", fit_opts},
                                       {"Training", train_opts},
                                       {"Data-free subspaces (--objective energy|neuralmodes|field|skinning)", df_opts},
                                       {"Scenario options of data-free training (the flags of crom-fullsim: material, gravity and "
                                        "--pin are used, the others accepted and ignored)", crom_scenario_opts},
                                       {NULL, NULL}};

/* The end of the description, from the skinning paragraph on (joined to
 * doc.description at start-up: a string literal may not exceed 4095
 * characters in ISO C). */
static const char doc_tail[] =
    "--objective skinning (Simplicits, Modi et al. 2024; skinning eigenmodes, Benchekroun et al. 2023): "
    "a LINEAR subspace of --handles H affine handles, u(X) = sum_h w_h(X) Q_h [X_hat; 1], X_hat the body's "
    "rest position normalized by its centre of mass and mass covariance (so the 12H handle coordinates, Q_h "
    "row by row, are in metres and of comparable scale); the handle transforms are T_h = [I|0] + Q_h [F; 0 0 0 "
    "1] with the stored frame F. By default the latent is instead 3S mass-orthonormal coordinates of the same "
    "span (--coordinates). q = 0 is the rest shape exactly. A free body has a constant handle, so rigid "
    "motions are in the subspace exactly; on a pinned body every weight vanishes on the pins. The model "
    "('skinning') is a linear basis: crom-cubature, crom-reducedstep (hard pins, contact planes, --schedule), "
    "crom-encode and crom-export use it as they use a LiCROM field, on any mesh of the body. --weights "
    "trained (default): an ELU MLP 3 -> H (4 layers of width 64) trained on batches of --batch random handle "
    "poses (RMS displacement --sigma) to minimize the mean Rayleigh quotient of their elastic energy (a random "
    "cubature of --tets tets) with the weights whitened over the cubature, in units of E V / D^2, plus "
    "--ortho-weight times |G - I|^2, G the mass-mean Gram matrix of the weights (Simplicits' orthogonality "
    "loss); no gravity. --weights eigen: the lowest eigenvectors of the scalar stiffness of --mesh against "
    "its lumped mass (ARPACK, as crom-modes), no training; the weights are stored on that mesh. "
    "--surface and --cloud train field and skinning without a tet mesh.\n\n"
    "A data-free step costs --batch energy evaluations (of the whole mesh, or of --tets tets); "
    "--threads runs them in parallel (the result does not depend on the thread count).";

static crom_cli_doc doc = {
    "crom-fitfield",
    "learn a displacement basis W(X) from point samples",
    "crom-fitfield [--rank R] [--encoder lsq|pointnet] [--basis mlp|pod] [--epochs N] [--minutes M] [--seed S] [-o OUT] [SAMPLES]\n"
    "mpirun -n P crom-fitfield [--shards S] [options of a neural field] -o OUT SAMPLES\n"
    "crom-fitfield --objective energy --mesh MESH [--rank R] [--sigma S] [--lambda L] [--steps N] [scenario] [-o OUT]\n"
    "crom-fitfield --objective neuralmodes --mesh MESH --modes MODEL [--rank R] [--box A] [--derivatives]\n"
    "              [--tangent-anchor] [--supervised EQ | --latents RUN] [--steps N] [-o OUT]\n"
    "crom-fitfield --objective field --mesh MESH [--rank R] [--features P] [--tets K] [--steps N] [scenario] [-o OUT]\n"
    "crom-fitfield --objective skinning --handles H [--weights trained|eigen] --mesh MESH|--surface STL|--cloud XYZV\n"
    "              [--steps N] [scenario] [-o OUT]",
    "Reads a crom/samples file (a path, or stdin) and writes a crom/model: a basis W(X) of r "
    "displacement fields, so that u(X) = W(X) q for a latent q in metres (LiCROM §3).\n\n"
    "--basis mlp trains a neural field: an MLP with ELU activations (5 layers of width 60 by "
    "default) mapping a rest position to the 3 x r matrix W(X), with Adam, Xavier "
    "initialization and 16 frames per batch. With --encoder lsq every frame's q is the "
    "least-squares fit of the current W to the frame's samples (variable projection, with a "
    "tiny Tikhonov term), re-solved at every step; the gradient is that of the fit with q held "
    "fixed. Frames of one mesh share the points of a step, so W is evaluated once per point "
    "for the whole batch. With --encoder pointnet a PointNet encoder seeing a 2500-point "
    "subsample is trained jointly (LiCROM eq. 4) and kept in the model. Displacements are "
    "scaled by their RMS value during training; the model keeps q in metres. Afterwards the "
    "fields are re-expressed, exactly, in a canonical basis of their span: orthonormal over the "
    "training points and ordered by decreasing variance over the training frames, like POD.\n\n"
    "--basis pod computes the classic proper orthogonal decomposition of samples of one mesh "
    "with every vertex in every frame (crom-sample --points all): the r leading modes of the "
    "snapshots weighted by the lumped vertex volumes (orthonormal in the volume-mean inner "
    "product; the density cancels), stored as a piecewise-linear field on that mesh so the "
    "whole pipeline can run the classic linear ROM as a baseline.\n\n"
    "The relative error ||Wq - u|| / ||u|| over all samples of all frames is printed and stored "
    "with the training log (per epoch: wall time and the loss on each step's points, which reads "
    "lower). The same samples, options and --seed give the same bytes (set "
    "SOURCE_DATE_EPOCH for the stored times; --threads changes the last bits).\n\n"
    "Data-free subspaces need no samples, only a mesh (--mesh), a material, and the pins and "
    "gravity of the scenario flags. They are nonlinear maps from a latent z to the positions of "
    "every vertex of that mesh, stored as models of basis 'energy' or 'neuralmodes' with the "
    "mesh (and its regions): crom-reducedstep --model simulates in them, crom-export and crom-diff "
    "decode them on that mesh, crom-metrics measures them. Pinned vertices are built into the "
    "map (held exactly at rest). Every data-free map is anchored at rest: its network's value at "
    "z = 0 is subtracted, in training too, so x(0) = X exactly and runs from rest start at z = 0.\n\n"
    "--objective energy (Sharp et al. 2023, eq. 4 and §4.1): x(z) = X + N(z) - N(0) with N an ELU "
    "MLP r -> 64 x 5 -> 3nv, trained on batches of z ~ N(0, I) to minimize the mean potential energy "
    "(stable neo-Hookean plus gravity, in units of E V) of the samples plus --lambda times the "
    "mean over all pairs of the batch of (log(|N(z) - N(z')|_M / sqrt(m) / (S |z - z'|)))^2, "
    "the isometry term that keeps the subspace from collapsing to the lowest-energy state (and "
    "--tangent-weight, its collapse floor at rest). The seed-state blend X + rho (N(z) - N(0)) grows rho from 0 to 1 "
    "over the first --ramp of the steps. A free body under gravity is refused.\n\n"
    "--objective neuralmodes (Wang et al. 2024, eq. 12-13): x(z) = X + W z + y(z) on the lowest "
    "--rank linear modes W of --modes (computed by crom-modes on the same mesh; W^T M W = m I, so z "
    "is in metres), with a GELU MLP correction y = N(z) - N(0) trained from zero on z uniform in a "
    "box (--box, --box-scaling) to minimize the elastic energy plus a penalty on the projection "
    "W^T M y(z). The training log is stored in the model.\n\n"
    "--objective field (beyond both papers): a continuous subspace x(X, z) = X + W(X) (phi(z) - phi(0)), "
    "W a neural field 3 -> 3p (--features p), phi an MLP r -> p, trained like energy with the "
    "integrals over the body taken by a random cubature of --tets tets per step; pins are a mask "
    "vanishing on the pinned faces. The model ('energy-field') stores no mesh and lays on "
    "any mesh of the body (with --mesh). With --handles H, W is the skinning eigenmodes of --mesh "
    "and phi alone is trained ('skin-field').\n\n",
    groups,
    "crom-sample run*.h5 | crom-fitfield --rank 20 -o model.h5\n"
    "crom-fitfield --encoder pointnet --epochs 3750 -o model.h5 samples.h5\n"
    "mpirun -n 2 crom-fitfield --shards 2 --epochs 400 -o model.h5 samples.h5\n"
    "crom-sample --points all run.h5 | crom-fitfield --basis pod --rank 10 -o pod.h5\n"
    "crom-fitfield --objective energy --mesh bar.h5 --pin clamp --youngs 1e6 --rank 3 -o df.h5\n"
    "crom-modes --pin clamp --youngs 1e6 --count 6 -o modes.h5 bar.h5\n"
    "crom-fitfield --objective neuralmodes --mesh bar.h5 --modes modes.h5 -o nm.h5\n"
    "crom-fitfield --objective field --mesh bar.h5 --pin clamp --youngs 1e6 -o fld.h5\n"
    "crom-fitfield --objective skinning --handles 8 --mesh bar.h5 --pin clamp --youngs 1e6 -o skin.h5\n"
    "crom-fitfield --objective skinning --weights eigen --handles 8 --mesh bar.h5 --pin clamp -o eig.h5\n"
    "crom-fitfield --objective skinning --surface bar.stl --pin 'x<-0.49' --youngs 1e6 -o skin.h5",
    "crom-sample(1), crom-encode(1), crom-cubature(1), crom-modes(1), crom-reducedstep(1), crom-metrics(1), crom-info(1)"};

typedef struct {
    const char *input, *out;
    int pod;
    crom_fit_opts fit;
    /* data-free */
    int objective;               /* 0: samples, else CROM_DATAFREE_* or OBJ_SKINNING */
    const char *mesh, *modes, *surface, *cloud, *supervised, *visit, *seed_state, *init_model;
    long seed_frame;
    int sample_points, handles, eigen, raw_coords, derivatives;
    double coord_tol;
    crom_datafree_opts df;
    crom_scenario sc;
    unsigned char given[O_LAST - O_RANK]; /* which options were given (GIVEN) */
    int material_given;          /* --youngs, --poisson or --density */
    int samples_only;            /* a samples-only option given (its key), for the message */
    int df_only;                 /* a data-free-only option given (its key) */
    int mpi;                     /* started by an MPI launcher: MPI_Init was called */
    int remote;                  /* the run stopped because another MPI rank failed */
    int ncond;                   /* energy: --condition NAME=LO:HI */
    crom_scenario_cond cond[CROM_MODEL_MAXCOND];
    crom_cutfeat cut;            /* --cut-segment, --cut-axis */
} args;

#define GIVEN(a, key) ((a)->given[(key) - O_RANK])

/* Whether key is an option of the table opts. */
static int in_opts(const crom_opt *opts, int key)
{
    for (; opts->name; opts++)
        if (opts->key == key)
            return 1;
    return 0;
}

/* The long name of option key, for messages. */
static const char *opt_name(int key)
{
    for (int g = 0; groups[g].opts; g++)
        for (const crom_opt *o = groups[g].opts; o->name; o++)
            if (o->key == key)
                return o->name;
    return "?";
}

/* Option key's value v: an integer in [lo, hi]. */
static int int_opt(int key, const char *v, long lo, long hi, int *out)
{
    char flag[64];
    long n;
    snprintf(flag, sizeof flag, "--%s", opt_name(key));
    if (crom_parse_int(v, flag, lo, hi, &n))
        return CROM_EUSAGE;
    *out = (int)n;
    return 0;
}

/* Option key's value v: a number >= 0. */
static int nonneg_opt(int key, const char *v, double *out)
{
    char flag[64];
    snprintf(flag, sizeof flag, "--%s", opt_name(key));
    if (crom_parse_double(v, flag, out))
        return CROM_EUSAGE;
    return *out >= 0 ? 0 : crom_err(CROM_EUSAGE, "%s must be >= 0, got %s", flag, v);
}

/* Option key's value v: one of the words names (NULL-terminated), its
 * index in *out. */
static int choice_opt(int key, const char *v, const char *const *names, int *out)
{
    char list[160] = "";
    int n = 0;
    while (names[n])
        n++;
    for (int i = 0; i < n; i++) {
        if (!strcmp(v, names[i])) {
            *out = i;
            return 0;
        }
        size_t l = strlen(list);
        snprintf(list + l, sizeof list - l, "%s%s", i == 0 ? "" : i == n - 1 ? " or " : ", ", names[i]);
    }
    return crom_err(CROM_EUSAGE, "--%s: '%s' is not %s", opt_name(key), v, list);
}

static int on_opt(void *ctx, int key, const char *v)
{
    static const char *const objectives[] = {"samples", "energy", "neuralmodes", "field", "skinning", NULL};
    static const int objective_codes[] = {0, CROM_DATAFREE_ENERGY, CROM_DATAFREE_NEURALMODES, CROM_DATAFREE_FIELD,
                                          OBJ_SKINNING};
    static const char *const coords[] = {"orthonormal", "handles", NULL}, *const weights[] = {"trained", "eigen", NULL},
                             *const boxsc[] = {"uniform", "frequency", NULL}, *const optim[] = {"adam", "lbfgs", NULL},
                             *const basis[] = {"mlp", "pod", NULL}, *const encoders[] = {"lsq", "pointnet", NULL};
    args *a = ctx;
    int i, rc;
    double d;
    const char *scn = crom_scenario_opt_name(key);
    if (scn) {
        if (!strcmp(scn, "youngs") || !strcmp(scn, "poisson") || !strcmp(scn, "density"))
            a->material_given = 1;
        if (!a->df_only)
            a->df_only = key;
        return crom_scenario_option(&a->sc, key, v);
    }
    if (key >= O_RANK && key < O_LAST)
        GIVEN(a, key) = 1;
    if (in_opts(df_opts, key))
        a->df_only = key;
    else if (key == O_EPOCHS || key == O_BASIS || key == O_ENCODER || key == O_PPS || key == O_ENCPTS || key == O_TIK ||
             key == O_SHARDS || key == O_CUTSEG || key == O_CUTAXIS)
        a->samples_only = key;
    switch (key) {
    case 0:
        if (a->input)
            return crom_err(CROM_EUSAGE, "unexpected operand '%s' (one samples file)", v);
        a->input = v;
        return 0;
    case 'o': a->out = v; return 0;
    case O_OBJECTIVE:
        if ((rc = choice_opt(key, v, objectives, &i)))
            return rc;
        a->objective = objective_codes[i];
        return 0;
    case O_MESH: a->mesh = v; return 0;
    case O_SURFACE: a->surface = v; return 0;
    case O_CLOUD: a->cloud = v; return 0;
    case O_MODES: a->modes = v; return 0;
    case O_DERIV: a->derivatives = 1; return 0;
    case O_SUPERV: a->supervised = v; return 0;
    case O_VISIT: a->visit = v; return 0;
    case O_SEEDST: a->seed_state = v; return 0;
    case O_INITM: a->init_model = v; return 0;
    case O_SEEDFR: return crom_parse_int(v, "--seed-frame", -100000000L, 100000000L, &a->seed_frame);
    case O_COND:
        if (a->ncond == CROM_MODEL_MAXCOND)
            return crom_err(CROM_EUSAGE, "--condition: at most %d", CROM_MODEL_MAXCOND);
        if (crom_scenario_cond_parse("--condition", v, 1, &a->cond[a->ncond]))
            return CROM_EUSAGE;
        for (int k = 0; k < a->ncond; k++)
            if (crom_scenario_cond_same(&a->cond[k], &a->cond[a->ncond]))
                return crom_err(CROM_EUSAGE, "--condition %s: given twice", v);
        a->ncond++;
        return 0;
    case O_TANANCHOR: a->df.tangent_anchor = 1; return 0;
    case O_SPOINTS: return int_opt(key, v, 1, 100000000L, &a->sample_points);
    /* 0 parses, so that the training reports it as a count it cannot use */
    case O_HANDLES: return int_opt(key, v, 0, 100000L, &a->handles);
    case O_COORDS: return choice_opt(key, v, coords, &a->raw_coords);
    case O_COORDTOL:
        if (crom_parse_double(v, "--coordinate-tol", &a->coord_tol) || !(a->coord_tol >= 0 && a->coord_tol < 1))
            return crom_err(CROM_EUSAGE, "--coordinate-tol must be in [0, 1), got %s", v);
        return 0;
    case O_WEIGHTS: return choice_opt(key, v, weights, &a->eigen);
    case O_STEPS: return int_opt(key, v, 0, 1000000000L, &a->df.steps);
    case O_SIGMA: return crom_parse_positive(v, "--sigma", &a->df.sigma);
    case O_LAMBDA: return nonneg_opt(key, v, &a->df.lambda);
    case O_RAMP:
        if (crom_parse_double(v, "--ramp", &a->df.ramp))
            return CROM_EUSAGE;
        return a->df.ramp >= 0 && a->df.ramp <= 1 ? 0 : crom_err(CROM_EUSAGE, "--ramp must be in [0, 1], got %s", v);
    case O_BOX: return crom_parse_positive(v, "--box", &a->df.box);
    case O_BOXSC: return choice_opt(key, v, boxsc, &a->df.box_scaled);
    case O_FEATURES: return int_opt(key, v, 1, 4096, &a->df.features);
    case O_TETS: return int_opt(key, v, 1, 100000000L, &a->df.tets);
    case O_PINW: return crom_parse_positive(v, "--pin-length", &a->df.pin_length);
    case O_OPTIM: return choice_opt(key, v, optim, &a->df.optimizer); /* CROM_DATAFREE_ADAM, _LBFGS */
    case O_TANW: return nonneg_opt(key, v, &a->df.tangent_weight);
    case O_TANF: return crom_parse_positive(v, "--tangent-floor", &a->df.tangent_floor);
    case O_RESAMPLE: return int_opt(key, v, 1, 1000000L, &a->df.resample);
    case O_ORTHO: return nonneg_opt(key, v, &a->df.ortho_weight);
    case O_RANK: return int_opt(key, v, 1, 10000, &a->fit.rank);
    case O_CUTSEG:
        if (a->cut.nseg == CROM_CUTFEAT_MAX)
            return crom_err(CROM_EUSAGE, "too many --cut-segment (at most %d)", CROM_CUTFEAT_MAX);
        if (crom_parse_doubles(v, "--cut-segment", 4, a->cut.seg[a->cut.nseg]))
            return CROM_EUSAGE;
        if (a->cut.seg[a->cut.nseg][0] == a->cut.seg[a->cut.nseg][2] &&
            a->cut.seg[a->cut.nseg][1] == a->cut.seg[a->cut.nseg][3])
            return crom_err(CROM_EUSAGE, "--cut-segment %s has zero length", v);
        a->cut.nseg++;
        return 0;
    case O_CUTAXIS:
        if (strlen(v) != 1 || v[0] < 'x' || v[0] > 'z')
            return crom_err(CROM_EUSAGE, "--cut-axis: '%s' is not x, y or z", v);
        a->cut.axis = v[0] - 'x';
        return 0;
    case O_BASIS: return choice_opt(key, v, basis, &a->pod);
    case O_ENCODER:
        if ((rc = choice_opt(key, v, encoders, &i)))
            return rc;
        a->fit.encoder = i ? CROM_MODEL_ENC_POINTNET : CROM_MODEL_ENC_LSQ;
        return 0;
    case O_EPOCHS: return int_opt(key, v, 1, 100000000L, &a->fit.epochs);
    case O_SHARDS: return int_opt(key, v, 1, 1000000L, &a->fit.shards);
    case O_MINUTES: return crom_parse_positive(v, "--minutes", &a->fit.minutes);
    case O_LR: return crom_parse_positive(v, "--lr", &a->fit.lr);
    case O_BATCH: return int_opt(key, v, 1, 1000000L, &a->fit.batch);
    case O_PPS: return int_opt(key, v, 1, 100000000L, &a->fit.points_per_step);
    case O_ENCPTS: return int_opt(key, v, 1, 100000000L, &a->fit.enc_points);
    case O_ACT:
        if (!strcmp(v, "elu"))
            a->fit.act = CROM_NN_ELU;
        else if (!strcmp(v, "sine"))
            a->fit.act = CROM_NN_SINE;
        else if (!strcmp(v, "gelu"))
            a->fit.act = CROM_NN_GELU;
        else
            return crom_err(CROM_EUSAGE, "--activation: '%s' is not elu or sine (or gelu, for data-free maps)", v);
        return 0;
    case O_WIDTH: return int_opt(key, v, 1, 4096, &a->fit.width);
    case O_DEPTH: return int_opt(key, v, 2, CROM_NN_MAX_LAYERS, &a->fit.depth);
    case O_TIK:
        if (crom_parse_double(v, "--tikhonov", &d))
            return CROM_EUSAGE;
        if (d < 0 || d > 1)
            return crom_err(CROM_EUSAGE, "--tikhonov must be in [0, 1], got %s", v);
        a->fit.tikhonov = d;
        return 0;
    }
    return crom_err(CROM_EINTERNAL, "unhandled option");
}

/* Exit with the usage error just recorded (rc, CROM_EUSAGE). */
static void usage_exit(crom_cli *cli, int rc) { exit(crom_cli_exit(cli, rc)); }

/* The data-free objective's options fit together (else a usage error). */
static void check_datafree(crom_cli *cli, const args *a)
{
    int skin = a->objective == OBJ_SKINNING, cont = skin || a->objective == CROM_DATAFREE_FIELD;
    const char *name = a->objective == CROM_DATAFREE_ENERGY ? "energy" : a->objective == CROM_DATAFREE_FIELD ? "field"
                       : skin ? "skinning" : "neuralmodes";
    int ngeom = !!a->mesh + !!a->surface + !!a->cloud;
    int over = a->objective == CROM_DATAFREE_FIELD && GIVEN(a, O_HANDLES);
    const char *bad = !skin && !over && GIVEN(a, O_HANDLES) ? "--handles" : !skin && GIVEN(a, O_WEIGHTS) ? "--weights"
                      : !skin && (a->raw_coords || a->coord_tol > 0) ? "--coordinates"
                      : skin && GIVEN(a, O_RANK) ? "--rank" : !cont && a->surface ? "--surface"
                      : !cont && a->cloud ? "--cloud" : !a->surface && a->sample_points ? "--sample-points" : NULL;
    if (bad)
        usage_exit(cli, crom_err(CROM_EUSAGE, "%s does not apply to --objective %s%s", bad, name,
                                 !strcmp(bad, "--rank") ? " (its latent has 12 coordinates per handle: --handles H)"
                                 : !strcmp(bad, "--sample-points") ? " without --surface"
                                 : !cont ? " (a map of one mesh needs that mesh: --mesh)" : ""));
    if (cont && ngeom != 1)
        usage_exit(cli, crom_err(CROM_EUSAGE, "--objective %s trains on %s: --mesh MESH, --surface STL or --cloud FILE",
                                 name, ngeom ? "one body, give only one of" : "a body"));
    if (over && !a->mesh)
        usage_exit(cli, crom_err(CROM_EUSAGE, "--objective field --handles lays the field over the skinning "
                                 "eigenmodes of a tet mesh: give --mesh MESH (or drop --handles to train W(X) "
                                 "from %s)", a->surface ? "the surface" : "the cloud"));
    if (over && GIVEN(a, O_FEATURES))
        usage_exit(cli, crom_err(CROM_EUSAGE, "--features does not apply to --objective field --handles (the "
                                 "features are the skinning basis's coordinates)"));
    if (skin && a->eigen && !a->mesh)
        usage_exit(cli, crom_err(CROM_EUSAGE, "--weights eigen solves an eigenproblem on a tet mesh: give --mesh MESH "
                                 "(or train the weights from %s: --weights trained)",
                                 a->surface ? "the surface" : "the cloud"));
    if (a->samples_only)
        usage_exit(cli, crom_err(CROM_EUSAGE, "--%s applies to --objective samples, not %s%s",
                                 opt_name(a->samples_only), name, a->samples_only == O_EPOCHS ? " (use --steps)" : ""));
    if (a->input)
        usage_exit(cli, crom_err(CROM_EUSAGE, "--objective %s learns from no samples: drop the operand '%s' (the mesh "
                                 "comes with --mesh)", name, a->input));
    if (!cont && !a->mesh)
        usage_exit(cli, crom_err(CROM_EUSAGE, "--objective %s needs the mesh it maps: --mesh MESH", name));
    if (a->objective == CROM_DATAFREE_NEURALMODES && !a->modes)
        usage_exit(cli, crom_err(CROM_EUSAGE, "--objective neuralmodes needs the linear modes it builds on: --modes "
                                 "MODEL (from crom-modes on the same mesh)"));
    if (a->objective != CROM_DATAFREE_NEURALMODES && a->modes)
        usage_exit(cli, crom_err(CROM_EUSAGE, "--modes applies to --objective neuralmodes"));
    int refine_field = a->init_model && a->objective == CROM_DATAFREE_FIELD;
    if (a->objective != CROM_DATAFREE_NEURALMODES &&
        (a->derivatives || a->supervised || a->df.tangent_anchor || (a->visit && !a->init_model)))
        usage_exit(cli, crom_err(CROM_EUSAGE, "%s applies to --objective neuralmodes%s",
                                 a->derivatives ? "--derivatives" : a->supervised ? "--supervised" :
                                 a->visit ? "--latents" : "--tangent-anchor",
                                 a->visit && !a->derivatives && !a->supervised && a->objective == CROM_DATAFREE_ENERGY
                                     ? " (or to energy or field with --init-model, the map whose run it is)" : ""));
    if (a->ncond && a->objective != CROM_DATAFREE_ENERGY)
        usage_exit(cli, crom_err(CROM_EUSAGE, "--condition applies to --objective energy"));
    if (a->init_model && a->objective != CROM_DATAFREE_ENERGY && !refine_field)
        usage_exit(cli, crom_err(CROM_EUSAGE, "--init-model applies to --objective energy or field"));
    if ((a->seed_state || GIVEN(a, O_SEEDFR)) && a->objective != CROM_DATAFREE_ENERGY)
        usage_exit(cli, crom_err(CROM_EUSAGE, "--seed-state applies to --objective energy"));
    if (GIVEN(a, O_SEEDFR) && !a->seed_state)
        usage_exit(cli, crom_err(CROM_EUSAGE, "--seed-frame picks a frame of --seed-state RUN: give it"));
    if (a->supervised && a->visit)
        usage_exit(cli, crom_err(CROM_EUSAGE, "--latents samples the energy along a run; --supervised fits equilibria: "
                                 "give one"));
    if (a->objective != CROM_DATAFREE_NEURALMODES && GIVEN(a, O_STEPS) && a->df.steps == 0)
        usage_exit(cli, crom_err(CROM_EUSAGE, "--steps 0 (no training) applies to --objective neuralmodes"));
}

/* The data-free options: those given, the objective's defaults for the
 * others (skinning: the field's, see skin_opts). */
static crom_datafree_opts datafree_opts(const crom_cli *cli, const args *a)
{
    crom_datafree_opts d;
    crom_datafree_defaults(&d, a->objective == OBJ_SKINNING ? CROM_DATAFREE_FIELD : a->objective);
    if (a->objective == CROM_DATAFREE_FIELD && GIVEN(a, O_HANDLES))
        crom_dffield_latent_defaults(&d);
    d.rank = GIVEN(a, O_RANK) ? a->fit.rank : d.rank;
    d.act = GIVEN(a, O_ACT) ? a->fit.act : d.act;
    d.width = GIVEN(a, O_WIDTH) ? a->fit.width : d.width;
    d.depth = GIVEN(a, O_DEPTH) ? a->fit.depth : d.depth;
    d.lr = GIVEN(a, O_LR) ? a->fit.lr : d.lr;
    d.batch = GIVEN(a, O_BATCH) ? a->fit.batch : d.batch;
    d.minutes = GIVEN(a, O_MINUTES) ? a->fit.minutes : 0;
    /* the data-free options given; the objective's defaults for the others */
#define DF_GIVEN(key, field) if (GIVEN(a, key)) d.field = a->df.field
    DF_GIVEN(O_STEPS, steps);
    DF_GIVEN(O_TANANCHOR, tangent_anchor);
    DF_GIVEN(O_SIGMA, sigma);
    DF_GIVEN(O_LAMBDA, lambda);
    DF_GIVEN(O_RAMP, ramp);
    DF_GIVEN(O_BOX, box);
    DF_GIVEN(O_BOXSC, box_scaled);
    DF_GIVEN(O_ORTHO, ortho_weight);
    DF_GIVEN(O_FEATURES, features);
    DF_GIVEN(O_TETS, tets);
    DF_GIVEN(O_PINW, pin_length);
    DF_GIVEN(O_OPTIM, optimizer);
    DF_GIVEN(O_RESAMPLE, resample);
    DF_GIVEN(O_TANW, tangent_weight);
    DF_GIVEN(O_TANF, tangent_floor);
#undef DF_GIVEN
    d.seed = cli->seed;
    return d;
}

static void parse_args(crom_cli *cli, args *a, int argc, char **argv)
{
    static char description[8192];
    if (!strstr(doc.description, doc_tail)) {
        snprintf(description, sizeof description, "%s%s", doc.description, doc_tail);
        doc.description = description;
    }
    memset(a, 0, sizeof *a);
    crom_fit_defaults(&a->fit);
    crom_datafree_defaults(&a->df, CROM_DATAFREE_ENERGY);
    crom_scenario_defaults(&a->sc);
    a->seed_frame = -1;
    a->cut.axis = 1;
    crom_cli_parse(cli, &doc, argc, argv, on_opt, a);
    if (GIVEN(a, O_CUTAXIS) && !a->cut.nseg)
        usage_exit(cli, crom_err(CROM_EUSAGE, "--cut-axis needs --cut-segment"));
    if (a->pod && a->cut.nseg)
        usage_exit(cli, crom_err(CROM_EUSAGE, "--cut-segment is for a neural field (--basis mlp): a POD basis lives "
                                 "on one mesh, with its cut"));
    a->fit.cut = a->cut.nseg ? &a->cut : NULL;
    if (!a->objective && crom_scenario_uniform(&a->sc, "crom-fitfield on samples")) /* (data-free: every objective) */
        usage_exit(cli, CROM_EUSAGE);
    if (a->pod && GIVEN(a, O_ENCODER) && a->fit.encoder == CROM_MODEL_ENC_POINTNET)
        usage_exit(cli, crom_err(CROM_EUSAGE, "--basis pod has no neural encoder: its q is the lsq projection (drop "
                                 "--encoder pointnet)"));
    if (a->pod && GIVEN(a, O_SHARDS))
        usage_exit(cli, crom_err(CROM_EUSAGE, "--shards applies to a neural field (--basis mlp): --basis pod is one "
                                 "eigen-decomposition"));
    if (!a->objective && a->df_only)
        usage_exit(cli, crom_err(CROM_EUSAGE, "--%s applies to a data-free subspace (--objective "
                                 "energy|neuralmodes|field|skinning)", opt_name(a->df_only)));
    if (a->objective) {
        check_datafree(cli, a);
        a->df = datafree_opts(cli, a);
    } else if (a->fit.act == CROM_NN_GELU) {
        usage_exit(cli, crom_err(CROM_EUSAGE, "--activation: gelu is for data-free maps; a neural field is elu or "
                                 "sine"));
    }
    a->fit.seed = cli->seed;
#ifdef _OPENMP
    a->fit.threads = cli->threads > 0 ? cli->threads : omp_get_num_procs();
#else
    a->fit.threads = 1;
#endif
    a->df.threads = a->fit.threads;
}

/* ------------------------------------------------------------------ MPI */

/* How many processes an MPI launcher started with this one, and this one's
 * rank, from the environment it sets (Open MPI's mpirun:
 * OMPI_COMM_WORLD_SIZE and _RANK; MPICH and Slurm's PMI: PMI_SIZE and
 * PMI_RANK; PMIx launchers: PMIX_RANK, with srun's SLURM_STEP_NUM_TASKS),
 * or 0 when none did. MPI is initialized only for more than one process:
 * otherwise (no launcher, mpirun -n 1, a one-task Slurm step) this is the
 * serial program, which never calls MPI. Always 0 without MPI. */
static int launched(int *rank)
{
    *rank = 0;
#ifdef CROM_MPI
    const char *v;
    if ((v = getenv("OMPI_COMM_WORLD_SIZE"))) {
        *rank = (v = getenv("OMPI_COMM_WORLD_RANK")) ? atoi(v) : 0;
        return atoi(getenv("OMPI_COMM_WORLD_SIZE"));
    }
    if ((v = getenv("PMI_SIZE"))) {
        *rank = (v = getenv("PMI_RANK")) ? atoi(v) : 0;
        return atoi(getenv("PMI_SIZE"));
    }
    if ((v = getenv("PMIX_RANK"))) {
        *rank = atoi(v);
        v = getenv("SLURM_STEP_NUM_TASKS");
        return v ? atoi(v) : 2; /* a size unknown: several, to be safe */
    }
#endif
    return 0;
}

/* Ranks after the first say nothing while the options are parsed: every
 * rank parses the same options and finds the same errors, which rank 0
 * reports. Their stdout and stderr go to /dev/null; returns the saved
 * stderr (restored by mpi_start, for errors of the rank's own), or -1. */
static int hush(int nlaunched, int rank)
{
    if (nlaunched < 2 || rank < 1)
        return -1;
    int saved = dup(2), null = open("/dev/null", O_WRONLY);
    if (null >= 0) {
        dup2(null, 1);
        dup2(null, 2);
        close(null);
    }
    return saved;
}

#ifdef CROM_MPI
/* The library's allreduce (lib/rom/fit.h): buf summed in place over the
 * ranks, every rank getting the same sums (MPI_Allreduce with MPI_IN_PLACE,
 * MPI 2.2 §5.9.6). */
static int sum_over_ranks(void *ctx, double *buf, size_t n)
{
    (void)ctx;
    if (n > INT_MAX)
        return crom_err(CROM_EINTERNAL, "an allreduce of %zu doubles exceeds MPI's int count", n);
    int rc = MPI_Allreduce(MPI_IN_PLACE, buf, (int)n, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
    return rc == MPI_SUCCESS ? 0 : crom_err(CROM_EINTERNAL, "MPI_Allreduce failed (MPI error %d)", rc);
}
#endif

/* Started by an MPI launcher with others (nlaunched > 1): MPI_Init; this
 * rank and the number of ranks into a->fit (proc, nprocs) with the
 * allreduce; --shards defaults to the ranks, and --threads 0 (all cores)
 * is the cores of a node over its ranks; ranks after 0 are quiet. What ranks cannot do is
 * refused alike on every rank: output to stdout (Open MPI hands it to rank
 * 0 through a terminal), POD and the data-free objectives (one process),
 * samples on stdin (which only rank 0 gets). Returns 0 or CROM_EUSAGE. */
static int mpi_start(crom_cli *cli, args *a, int nlaunched, int saved_err)
{
#ifdef CROM_MPI
    if (nlaunched < 2)
        return 0;
    int rank, size;
    MPI_Init(NULL, NULL);
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    if (saved_err >= 0) {
        dup2(saved_err, 2);
        close(saved_err);
    }
    a->mpi = 1;
    a->fit.proc = rank;
    a->fit.nprocs = size;
    if (rank > 0)
        cli->quiet = 1;
    if (!a->out || !strcmp(a->out, "-"))
        return crom_err(CROM_EUSAGE, "under MPI give the model a file, -o OUT: mpirun passes stdout through a "
                        "terminal");
    if (size == 1)
        return 0; /* the launcher's environment said more */
    if (a->objective || a->pod)
        return crom_err(CROM_EUSAGE, "%d MPI ranks train a neural field (--basis mlp) together; %s runs in one "
                        "process: start it without mpirun", size, a->pod ? "--basis pod" : "a data-free objective");
    if (!a->input || !strcmp(a->input, "-"))
        return crom_err(CROM_EUSAGE, "under MPI every rank reads the samples: give SAMPLES as a file, not stdin");
    if (!GIVEN(a, O_SHARDS))
        a->fit.shards = size;
    if (cli->threads <= 0) {
        /* the ranks on this node share its cores (MPI-3 shared-memory split) */
        MPI_Comm node;
        int local = 1, procs = 1;
        if (MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, rank, MPI_INFO_NULL, &node) == MPI_SUCCESS) {
            MPI_Comm_size(node, &local);
            MPI_Comm_free(&node);
        }
#ifdef _OPENMP
        procs = omp_get_num_procs();
#endif
        a->fit.threads = procs / local > 1 ? procs / local : 1;
    }
    a->fit.allreduce = sum_over_ranks;
#endif
    return 0;
}

/* With several ranks: whether every rank got this far without an error
 * (one MPI_Allreduce), so that no rank goes on to a collective call the
 * others never make. A rank that did not fail itself gets CROM_EINTERNAL
 * and a->remote. Returns rc otherwise. */
static int mpi_agree(args *a, int rc)
{
#ifdef CROM_MPI
    if (a->fit.nprocs > 1) {
        int failed = rc != 0;
        MPI_Allreduce(MPI_IN_PLACE, &failed, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
        if (failed && !rc) {
            a->remote = 1;
            rc = crom_err(CROM_EINTERNAL, "stopped: another MPI rank failed");
        }
    }
#endif
    return rc;
}

/* The end (crom_cli_exit). Under MPI every rank learns every rank's result
 * (MPI_Allgather): the lowest rank with an error of its own reports it,
 * alone, and every rank exits with its code after MPI_Finalize, so that
 * mpirun reports that code once. */
static int mpi_exit(crom_cli *cli, args *a, int rc)
{
#ifdef CROM_MPI
    if (a->mpi) {
        int n = a->fit.nprocs, mine[2] = {rc, rc && !a->remote}, who = -1;
        int *all = malloc(sizeof(int) * 2 * (size_t)n);
        if (!all)
            MPI_Abort(MPI_COMM_WORLD, CROM_EINTERNAL);
        MPI_Allgather(mine, 2, MPI_INT, all, 2, MPI_INT, MPI_COMM_WORLD);
        for (int own = 1; own >= 0 && who < 0; own--)
            for (int r = 0; r < n && who < 0; r++)
                if (all[2 * r + own])
                    who = r;
        int code = who < 0 ? 0 : all[2 * who];
        free(all);
        /* the reporting rank writes its line before any rank may exit:
         * mpirun aborts the job when a rank exits non-zero, which could
         * kill the reporter before it had written it */
        int out = who == a->fit.proc ? crom_cli_exit(cli, rc) : 0;
        MPI_Barrier(MPI_COMM_WORLD);
        MPI_Finalize();
        if (who != a->fit.proc) {
            out = crom_cli_exit(cli, 0);
            return code ? code : out;
        }
        return out;
    }
#endif
    return crom_cli_exit(cli, rc);
}

static void on_progress(void *ctx, int epoch, double frac, double loss)
{
    char buf[64];
    snprintf(buf, sizeof buf, "epoch %d, loss %.3g m^2 (the steps' points)", epoch, loss);
    crom_cli_progress_update(ctx, (long)(frac * 1000), buf);
}

static void on_df_progress(void *ctx, long step, double frac, double obj)
{
    char buf[64];
    snprintf(buf, sizeof buf, "step %ld, objective %.4g", step, obj);
    crom_cli_progress_update(ctx, (long)(frac * 1000), buf);
}

/* The body of a data-free objective (lib/datafree/body.h); a sampled one
 * is announced. */
static int load_body(crom_cli *cli, const args *a, crom_body *b)
{
    int shells = a->objective == CROM_DATAFREE_ENERGY || a->objective == CROM_DATAFREE_NEURALMODES ||
                 (a->objective == OBJ_SKINNING && a->eigen);
    crom_body_source src = {a->mesh, a->surface, a->cloud, a->sample_points, cli->seed, shells,
                            a->objective == CROM_DATAFREE_ENERGY};
    int rc = crom_body_load(b, &src, &a->sc);
    if (!rc && b->cloud.n)
        crom_cli_info(cli, "%s: %d points standing for %.6g m^3, integrated through virtual tets",
                      a->surface ? a->surface : a->cloud, b->cloud.n, b->cloud.volume);
    return rc;
}

/* The linear modes of a neuralmodes map, warning where their material is
 * not the one trained with. */
static int load_modes(crom_cli *cli, args *a, crom_body *b)
{
    int differs;
    if (!GIVEN(a, O_RANK))
        a->df.rank = 0; /* every mode */
    int rc = crom_body_load_modes(b, a->modes, a->mesh, &a->df.rank, &a->sc, a->material_given, &differs);
    if (differs)
        crom_cli_warn(cli, "the modes were computed with E = %g, nu = %g, rho = %g; training uses E = %g, nu = %g, "
                      "rho = %g", b->modes.youngs, b->modes.poisson, b->modes.density, a->sc.youngs, a->sc.poisson,
                      a->sc.density);
    return rc;
}

/* The options of the skinning weights: the data-free options given, the
 * skinning defaults for the others. */
static crom_dfskin_opts skin_opts(const crom_cli *cli, const args *a)
{
    crom_dfskin_opts o;
    crom_dfskin_defaults(&o);
    o.handles = GIVEN(a, O_HANDLES) ? a->handles : o.handles;
    o.depth = GIVEN(a, O_DEPTH) ? a->df.depth : o.depth;
    o.width = GIVEN(a, O_WIDTH) ? a->df.width : o.width;
    o.act = GIVEN(a, O_ACT) ? a->df.act : o.act;
    o.steps = a->df.steps;
    o.minutes = a->df.minutes;
    o.lr = a->df.lr;
    o.batch = GIVEN(a, O_BATCH) ? a->df.batch : o.batch;
    o.sigma = a->df.sigma;
    o.ortho_weight = GIVEN(a, O_ORTHO) ? a->df.ortho_weight : o.ortho_weight;
    o.tets = a->df.tets;
    o.pin_length = a->df.pin_length;
    o.threads = a->df.threads;
    o.seed = cli->seed;
    return o;
}

/* The summary of a trained map or field. */
static void report_map(crom_cli *cli, const args *a, const crom_body *b, const crom_model *m,
                       const crom_dftrain_log *log, double secs)
{
    int j = log->nblocks - 1, r = a->df.rank, nv = b->mesh.nv, np = b->npinned;
    if (j < 0) { /* neuralmodes --steps 0 */
        crom_cli_info(cli, "neuralmodes map, rank %d on %d vertices (%d pinned): no training, y = 0: the linear modes%s",
                      r, nv, np, m->deriv_v ? " and their modal derivatives, X + Phi z + 1/2 sum Psi_ij z_i z_j" : "");
        return;
    }
    if (a->objective == CROM_DATAFREE_FIELD && m->field == CROM_MODEL_FIELD_SKIN)
        crom_cli_info(cli, "continuous field over %d skinning eigenmodes (%d features), rank %d, trained on %d "
                      "vertices (%d pinned): %ld steps in %.1f s; last objective %.4g, mean potential energy %.4g J, "
                      "mean squared log isometry ratio %.3g (sigma %.4g m)", m->handles, crom_skin_width(m), r, nv, np,
                      log->steps, secs, log->objective[j], log->energy[j], log->penalty[j], log->sigma);
    else if (a->objective == CROM_DATAFREE_FIELD)
        crom_cli_info(cli, "continuous field, rank %d with %d features, trained on %d vertices (%d pinned): %ld steps "
                      "in %.1f s; last objective %.4g, mean potential energy %.4g J, mean squared log isometry ratio "
                      "%.3g (sigma %.4g m)", r, a->df.features, nv, np, log->steps, secs, log->objective[j],
                      log->energy[j], log->penalty[j], log->sigma);
    else if (a->objective == CROM_DATAFREE_NEURALMODES)
        crom_cli_info(cli, "neuralmodes map, rank %d on %d vertices (%d pinned): %ld steps in %.1f s; last objective "
                      "%.4g, mean elastic energy %.4g J, orthogonality penalty %.3g (box %.4g m)", r, nv, np,
                      log->steps, secs, log->objective[j], log->energy[j], log->penalty[j], log->box);
    else
        crom_cli_info(cli, "energy map, rank %d on %d vertices (%d pinned): %ld steps in %.1f s; last objective %.4g, "
                      "mean potential energy %.4g J, mean squared log isometry ratio %.3g (sigma %.4g m)", r, nv, np,
                      log->steps, secs, log->objective[j], log->energy[j], log->penalty[j], log->sigma);
    if (cli->verbose)
        crom_cli_info(cli, "%s: reference energy %.4g J; model_id %s", a->objective == CROM_DATAFREE_FIELD ? "field"
                      : a->objective == CROM_DATAFREE_NEURALMODES ? "neuralmodes" : "energy", log->Eref, m->model_id);
}

/* The summary of a trained skinning model or of skinning eigenmodes. */
static void report_skin(crom_cli *cli, const args *a, const crom_body *b, const crom_model *m,
                        const crom_dftrain_log *log, long solves, double secs)
{
    const char *one = m->skin_constant ? ", one constant" : "";
    if (a->eigen) {
        crom_cli_info(cli, "skinning eigenmodes, %d handles (rank %d%s) on %d vertices (%d pinned): %ld solves in "
                      "%.2f s; eigenvalues %.4g .. %.4g 1/s^2", m->handles, m->rank, one, b->mesh.nv, b->npinned,
                      solves, secs, m->skin_eig[m->skin_constant < m->handles ? m->skin_constant : 0],
                      m->skin_eig[m->handles - 1]);
    } else {
        char where[96];
        int j = log->nblocks - 1;
        if (b->cloud.n)
            snprintf(where, sizeof where, "%d points (pinned: %d points, %d surface triangles)", b->cloud.n, b->npin,
                     b->ntri);
        else
            snprintf(where, sizeof where, "%d vertices (%d pinned)", b->mesh.nv, b->npinned);
        crom_cli_info(cli, "trained skinning weights, %d handles (rank %d%s) on %s: %ld steps in %.1f s; last "
                      "objective %.4g, mean energy %.4g J, |G - I|^2 %.3g (sigma %.4g m)", m->handles, m->rank, one,
                      where, log->steps, secs, log->objective[j], log->energy[j], log->penalty[j], log->sigma);
    }
    if (cli->verbose)
        crom_cli_info(cli, "skinning: model_id %s", m->model_id);
}

/* A data-free subspace: the body (and the modes), its pins, the training
 * (skinning eigenmodes: an eigensolve) with the progress display, the
 * coordinates of skinning weights, the model, the summary. */
static int run_datafree(crom_cli *cli, args *a)
{
    int skin = a->objective == OBJ_SKINNING;
    crom_body b;
    crom_model out;
    crom_dftrain_log log;
    crom_datafree_problem P;
    crom_dfskin_opts so = skin_opts(cli, a);
    long solves = 0;
    crom_model_clear(&out);
    memset(&log, 0, sizeof log);
    int rc = 0;
    for (int k = 0; k < a->ncond && !rc; k++) /* the body at the middle of each range (a ratio's region) */
        rc = crom_scenario_cond_apply(&a->sc, &a->cond[k], 0.5 * (a->cond[k].lo + a->cond[k].hi));
    if (!rc)
        rc = load_body(cli, a, &b);
    if (!rc && a->objective == CROM_DATAFREE_NEURALMODES)
        rc = load_modes(cli, a, &b);
    if (!rc)
        rc = crom_body_pins(&b, &a->sc, skin);
    if (!rc && !skin)
        rc = crom_body_map_problem(&b, &a->sc, a->objective, a->df.rank, &P);
    if (!rc && !skin) {
        P.ncond = a->ncond;
        P.cond = a->cond;
    }
    if (!rc && a->derivatives)
        rc = crom_body_derivatives(&b, &P, a->df.rank);
    if (!rc && a->supervised)
        rc = crom_body_supervise(&b, a->supervised, a->df.rank, &P);
    if (!rc && a->seed_state)
        rc = crom_body_seed(&b, a->seed_state, a->seed_frame, &P);
    if (!rc && a->init_model)
        rc = crom_body_refine(&b, a->init_model, a->visit, a->df.rank,
                              a->objective != CROM_DATAFREE_FIELD ? "energy" :
                              GIVEN(a, O_HANDLES) ? "skin-field" : "energy-field", &P);
    else if (!rc && a->visit)
        rc = crom_body_visit(&b, a->visit, a->df.rank, &P);
    double t0 = crom_clock_now();
    if (!rc && skin && a->eigen) {
        rc = crom_dfskin_eigen(&b.mesh, &b.mat, a->sc.nmat ? &a->sc : NULL, b.fixed, so.handles, &out, &solves);
    } else if (!rc) {
        crom_cli_progress prog;
        crom_cli_progress_start(&prog, cli, "fitfield", 1000);
        so.progress = a->df.progress = on_df_progress;
        so.progress_ctx = a->df.progress_ctx = &prog;
        if (skin)
            rc = crom_body_train_skin(&b, a->sc.nmat ? &a->sc : NULL, &so, &out, &log);
        else if (a->objective == CROM_DATAFREE_FIELD && GIVEN(a, O_HANDLES))
            rc = crom_body_train_skin_field(&b, &P, &a->df, so.handles, &out, &log, &solves);
        else
            rc = crom_datafree_train(&P, &a->df, &out, &log);
        crom_cli_progress_end(&prog);
    }
    if (!rc && skin && !a->raw_coords)
        rc = crom_body_skin_coordinates(&b, &out, a->coord_tol > 0 ? a->coord_tol : 1e-6);
    double secs = crom_clock_now() - t0;
    if (!rc && skin && a->eigen)
        out.training_seconds = crom_clock_wall(secs);
    if (!rc)
        rc = skin ? crom_body_write_skin(&b, &a->sc, &out, &so, a->eigen ? NULL : &log, a->out, cli->cmdline)
                  : crom_body_write_map(&b, &a->sc, &out, &a->df, &P, &log, a->out, cli->cmdline);
    if (!rc && skin)
        report_skin(cli, a, &b, &out, &log, solves, secs);
    else if (!rc)
        report_map(cli, a, &b, &out, &log, crom_clock_now() - t0);
    crom_dftrain_log_free(&log);
    crom_model_free(&out);
    crom_body_free(&b);
    return rc;
}

/* The model to a->out. Its history records the command line; after a run
 * on several MPI ranks, as a shell comment, the ranks and the shards (one
 * process with those --shards trains the same model up to round-off). */
static int write_model(const crom_cli *cli, const args *a, crom_model *m, const char *parent_history)
{
    char *cmd = NULL;
    if (a->fit.nprocs > 1) {
        size_t n = strlen(cli->cmdline) + 64;
        if (!(cmd = crom_malloc(n)))
            return CROM_EINTERNAL;
        snprintf(cmd, n, "%s # on %d MPI ranks, --shards %d", cli->cmdline, a->fit.nprocs, a->fit.shards);
    }
    crom_out o;
    int rc = crom_out_create(&o, a->out, CROM_MODEL_SCHEMA, CROM_MODEL_VERSION, cmd ? cmd : cli->cmdline,
                             parent_history, CROM_OUT_PLAIN);
    free(cmd);
    if (rc)
        return rc;
    if ((rc = crom_model_write(o.h5, m)))
        crom_out_fail(&o);
    else
        rc = crom_out_commit(&o);
    return rc;
}

/* A basis fitted to the samples: POD, or the neural field with the
 * progress display; the model; the summary. */
static int run_samples(crom_cli *cli, args *a)
{
    crom_in in;
    crom_samples S;
    memset(&S, 0, sizeof S);
    int rc = crom_in_open(&in, a->input);
    if (!rc) {
        if (!(rc = crom_in_expect(&in, CROM_SAMPLES_SCHEMA, CROM_SAMPLES_VERSION)))
            rc = crom_samples_read(&in, &S);
        crom_in_close(&in);
    }
    if ((rc = mpi_agree(a, rc))) {
        crom_samples_free(&S);
        return rc;
    }
    crom_model m;
    crom_model_clear(&m);
    double captured = NAN, t0 = crom_clock_now();
    crom_fit_stats stats = {0};
    if (a->pod) {
        rc = crom_fit_pod(&S, a->fit.rank, &m, &captured);
    } else {
        crom_cli_progress prog;
        crom_cli_progress_start(&prog, cli, "fitfield", 1000);
        a->fit.progress = on_progress;
        a->fit.progress_ctx = &prog;
        a->fit.stats = &stats;
        rc = crom_fit_mlp(&S, &a->fit, &m);
        crom_cli_progress_end(&prog);
        a->remote = stats.remote_failure;
        rc = mpi_agree(a, rc); /* every rank trained: rank 0 writes */
    }
    if (!rc && a->fit.proc == 0)
        rc = write_model(cli, a, &m, S.history);
    if (!rc && a->fit.proc == 0) {
        if (a->pod)
            crom_cli_info(cli, "relative reconstruction error %.4g over %d frames (pod, rank %d, %.1f%% of the snapshot energy, %.1f s)",
                          m.reconstruction_error, S.F, m.rank, 100 * captured, crom_clock_now() - t0);
        else
            crom_cli_info(cli, "relative reconstruction error %.4g over %d frames (mlp/%s, rank %d, %d epochs, %.1f s)",
                          m.reconstruction_error, S.F, crom_model_encoder_name(m.encoder), m.rank,
                          m.nepochs, crom_clock_now() - t0);
        if (cli->verbose && !a->pod && stats.seconds > 0)
            crom_cli_info(cli, "%ld steps in %.1f s: %.3g points/s through W forward+backward, %.3g samples/s in the loss",
                          stats.steps, stats.seconds, stats.rows / stats.seconds, stats.samples / stats.seconds);
        if (a->fit.nprocs > 1)
            crom_cli_info(cli, "data parallel: %d MPI ranks, %d shards a step; each of the %ld steps allreduced %zu "
                          "doubles (%.1f kB)", a->fit.nprocs, a->fit.shards, stats.steps, stats.allreduce_doubles,
                          8e-3 * (double)stats.allreduce_doubles);
        if (cli->verbose)
            crom_cli_info(cli, "model_id %s", m.model_id);
    }
    crom_model_free(&m);
    crom_samples_free(&S);
    return rc;
}

static int run(crom_cli *cli, args *a) { return a->objective ? run_datafree(cli, a) : run_samples(cli, a); }

int main(int argc, char **argv)
{
    crom_cli cli;
    args a;
    int rank, nlaunched = launched(&rank), saved_err = hush(nlaunched, rank);
    parse_args(&cli, &a, argc, argv);
    int rc = mpi_start(&cli, &a, nlaunched, saved_err);
    if (!rc)
        rc = run(&cli, &a);
    return mpi_exit(&cli, &a, rc);
}
