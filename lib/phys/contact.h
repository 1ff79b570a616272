/* contact.h — collision half-spaces and spheres with friction, per vertex,
 * for both simulators (the reduced one evaluates the same terms at its
 * contact points).
 *
 * Normal: a mass-scaled penalty  E_n = ½ k m φ²,  φ = max(0, d − n·x)
 * (force k m φ along n; k in 1/s², so the resting depth under gravity g is
 * g/k whatever the mass) — Sharp et al. 2023's inequality penalty
 * w |min(C(q), 0)|² (eq. 9) with C the signed distance and w = ½ k m.
 * A solid sphere of centre c and radius R (an analytic obstacle) has
 * φ = max(0, R − ρ), ρ = ‖x − c‖, and the outward normal n = (x − c)/ρ; its
 * Hessian is k m [n nᵀ − (φ/ρ)(I − n nᵀ)], of which the second term is
 * negative: the positive semidefinite part k m n nᵀ is returned. Friction
 * against a sphere uses the normal at the step's start (lagged, like λ).
 * Friction: Coulomb friction with a lagged normal force λ (from the start of
 * the step) and the smoothed magnitude f0 of IPC (Li et al. 2020):
 *   E_f = μ λ f0(‖T(x − x_prev)‖),  T = I − n nᵀ,
 *   f0(y) = −y³/(3ε²) + y²/ε + ε/3 for y < ε, y otherwise, ε = ε_v h,
 * so the friction force μλ points against the tangential motion of the step
 * and fades to zero smoothly below speed ε_v. Both terms are C¹ with
 * positive semi-definite Hessians. */
#ifndef CROM_CONTACT_H
#define CROM_CONTACT_H

/* A collision half-space n·x >= d (n unit), or (sphere = 1) the outside of
 * the sphere ‖x − c‖ >= r; friction coefficient mu. */
typedef struct {
    double n[3], d, mu;
    int sphere;
    double c[3], r;
} crom_contact_plane;

/* The outward normal of the obstacle at x (a sphere: (x − c)/‖x − c‖, +y
 * at the centre itself). */
void crom_contact_normal(const crom_contact_plane *p, const double x[3], double n[3]);

/* Penetration depth φ of point x: max(0, d − n·x), or max(0, r − ‖x − c‖). */
double crom_contact_depth(const crom_contact_plane *p, const double x[3]);

/* Energy of one vertex (mass m) at x against plane p, with penalty rate k,
 * lagged normal force lam (N) and smoothing length eps (m; ε_v h). Adds the
 * gradient to g[3] and the Hessian to H[9] when they are non-NULL. The
 * normal penalty's Hessian is k m n nᵀ: exact for a plane; for a sphere the
 * Gauss–Newton part, dropping the term −k m (φ/ρ)(I − n nᵀ) of its
 * curvature (ρ = |x − c|), which is negative in the tangent plane, so that
 * the Hessian stays positive semidefinite. */
double crom_contact_eval(const crom_contact_plane *p, double k, double m, const double x[3],
                         const double xprev[3], double lam, double eps, double g[3],
                         double H[9]);

#endif
