/* cutfeat.h — features that let a smooth field jump across a cut.
 *
 * A LiCROM basis W(X) is an MLP of the rest position: smooth in X, so it can
 * not put different displacements on the two faces of a crack that the
 * training data opened (crom-remesh cut duplicates the vertices there). Its
 * best fit to an open crack stretches the elements beside it, and the
 * reduced step, which minimizes that energy, keeps the crack shut. Given
 * the cut's geometry the field can take, besides X, one feature per cut
 * ribbon that jumps across that ribbon and nowhere else:
 *
 *     f_k(X) = ω_k(p) / π,   ω_k(p) = atan2((a − p) × (b − p), (a − p) · (b − p)),
 *
 * the signed angle the segment from a to b subtends at p, where p, a and b
 * are the in-plane coordinates (u, v) of X and of the segment's ends in the
 * plane perpendicular to the ribbons' axis (the convention of crom-remesh
 * cut, lib/mesh/remesh.h: (y, z) for axis x, (x, z) for axis y, (x, y) for
 * axis z). It is the 2-D winding number of the open segment: continuous
 * everywhere but across the segment, where it jumps from +1 (the left of
 * a → b) to −1 (the right), and it decays like |b − a| / |p| far away. A
 * point exactly on the segment gets +1 (the left side, as crom-remesh's
 * cut rule puts a centroid on a segment's line); at an end point it is 0.
 * An intact body needs no jump: the network learns to leave the features
 * out of the fields an intact body uses.
 */
#ifndef CROM_CUTFEAT_H
#define CROM_CUTFEAT_H

#include <stddef.h>

#define CROM_CUTFEAT_MAX 16 /* ribbons of one cut */

typedef struct {
    int axis;       /* the ribbons' axis: 0 x, 1 y, 2 z */
    int nseg;       /* K ribbons, 0 <= K <= CROM_CUTFEAT_MAX (0: no features) */
    double seg[CROM_CUTFEAT_MAX][4]; /* A_u, A_v, B_u, B_v (m) */
} crom_cutfeat;

/* Check a cut: axis in 0..2, 0..CROM_CUTFEAT_MAX ribbons, finite ends,
 * no zero-length segment. Returns 0 or CROM_EUSAGE naming the problem. */
int crom_cutfeat_check(const crom_cutfeat *c);

/* The K features at one point X [3] into f [K]. */
void crom_cutfeat_point(const crom_cutfeat *c, const double X[3], double *f);

/* A network's inputs at n points X [n][3]: in [n][3 + K], X then the K
 * features at S [n][3] (NULL: at X; float, as the networks take them). */
void crom_cutfeat_inputs_f(const crom_cutfeat *c, size_t n, const float *X, const float *S, float *in);
/* The same from double points into double inputs. */
void crom_cutfeat_inputs_d(const crom_cutfeat *c, size_t n, const double *X, const double *S, double *in);

#endif
