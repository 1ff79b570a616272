/* keyframe.h — in-betweens of keyframes given in a model's latent
 * coordinates (Neural Modes, Wang et al. 2024, §5 "Keyframing"): the
 * animator poses the body at a few latent vectors z_0 … z_{K−1} and the
 * frames between them are the map's images of an interpolated latent,
 * x(z(s)), s ∈ [0, K−1]. In a nonlinear subspace that bends by rotating,
 * the in-betweens keep their shape, where the linear interpolation of the
 * keyframes' positions, (1−α) x(z_k) + α x(z_{k+1}), shortens a bending
 * limb and stores strain energy that no pose of the animation asked for.
 * Both energies are evaluated here so that the two can be compared.
 *
 * Latent interpolation: piecewise linear, or the uniform Catmull–Rom
 * spline through the keys (C¹, the end keys repeated as their outer
 * neighbours): the cubic Hermite segment
 *   z(k + α) = (2α³ − 3α² + 1) z_k + (α³ − 2α² + α) m_k
 *            + (−2α³ + 3α²) z_{k+1} + (α³ − α²) m_{k+1},
 * with tangents m_k = (z_{k+1} − z_{k−1}) / 2.
 */
#ifndef CROM_KEYFRAME_H
#define CROM_KEYFRAME_H

#include "phys/scenario.h"
#include "phys/system.h"
#include "rom/map.h"
#include "rom/model.h"

enum { CROM_KEYFRAME_LINEAR = 0, CROM_KEYFRAME_CUBIC = 1 };

/* The interpolated latent q [r] at parameter s (clamped to [0, nkeys−1])
 * of keys [nkeys][r], piecewise linear or Catmull–Rom (interp). */
void crom_keyframe_latent(int nkeys, int r, const double *keys, int interp, double s, double *q);

typedef struct {
    crom_map map;        /* the model on its mesh */
    crom_system sys;     /* the body's energy (the scenario's material) */
    int nkeys, r, n, interp;
    double *keys;        /* [nkeys][r] */
    double *xkeys;       /* [nkeys][n] the decoded keyframes */
    double *x;           /* [n] scratch */
} crom_keyframe;

/* Set up on model (borrowed during the call) laid on mesh (NULL: the
 * model's own, as crom_map_init), with the material of scenario sc
 * (--youngs, --poisson, --density and regions of other materials), keys
 * [nkeys][r] copied. Returns 0, CROM_EUSAGE (fewer than two keys; a
 * non-finite key), CROM_EDATA (a key the map cannot decode) or the errors
 * of crom_map_init and crom_system_init. On failure *k holds nothing to
 * free. */
int crom_keyframe_init(crom_keyframe *k, const crom_model *model, const crom_mesh *mesh, const crom_scenario *sc,
                       int nkeys, const double *keys, int interp);

/* The in-between at parameter s: its latent q [r], the elastic energy of
 * x(q) (J), and the elastic energy of the linear interpolation of the
 * decoded keyframe positions at the same s (J; *E_pos may be NULL).
 * Returns 0 or CROM_EDATA when a result is not finite. */
int crom_keyframe_eval(crom_keyframe *k, double s, double *q, double *E_latent, double *E_pos);

void crom_keyframe_free(crom_keyframe *k);

#endif
