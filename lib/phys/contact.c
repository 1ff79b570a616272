/* contact.c — penalty half-spaces and lagged smoothed friction (contact.h). */
#include <math.h>

#include "phys/contact.h"

static double dist(const double a[3], const double b[3])
{
    return hypot(hypot(a[0] - b[0], a[1] - b[1]), a[2] - b[2]);
}

void crom_contact_normal(const crom_contact_plane *p, const double x[3], double n[3])
{
    double rho = p->sphere ? dist(x, p->c) : 0;
    for (int i = 0; i < 3; i++)
        n[i] = !p->sphere ? p->n[i] : rho > 0 ? (x[i] - p->c[i]) / rho : i == 1;
}

double crom_contact_depth(const crom_contact_plane *p, const double x[3])
{
    double phi = p->sphere ? p->r - dist(x, p->c) : p->d - (p->n[0] * x[0] + p->n[1] * x[1] + p->n[2] * x[2]);
    return phi > 0 ? phi : 0;
}

double crom_contact_eval(const crom_contact_plane *p, double k, double m, const double x[3],
                         const double xprev[3], double lam, double eps, double g[3], double H[9])
{
    double n[3];
    double E = 0;
    double phi = crom_contact_depth(p, x);
    crom_contact_normal(p, x, n);
    if (phi > 0) {
        /* E_n = ½ k m φ², ∇ = −k m φ n, H = k m n nᵀ */
        E += 0.5 * k * m * phi * phi;
        for (int i = 0; i < 3; i++) {
            if (g)
                g[i] -= k * m * phi * n[i];
            if (H)
                for (int j = 0; j < 3; j++)
                    H[3 * i + j] += k * m * n[i] * n[j];
        }
    }
    if (p->mu > 0 && lam > 0 && eps > 0) {
        if (p->sphere) /* the tangent plane at the step's start */
            crom_contact_normal(p, xprev, n);
        /* tangential displacement of the step */
        double dx[3] = {x[0] - xprev[0], x[1] - xprev[1], x[2] - xprev[2]};
        double dn = n[0] * dx[0] + n[1] * dx[1] + n[2] * dx[2];
        double u[3] = {dx[0] - dn * n[0], dx[1] - dn * n[1], dx[2] - dn * n[2]};
        double y = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
        double c = p->mu * lam, f0, f1_over_y, f1p;
        if (y < eps) {
            f0 = -y * y * y / (3 * eps * eps) + y * y / eps + eps / 3;
            f1_over_y = 2 / eps - y / (eps * eps); /* f1(y)/y, finite at y = 0 */
            f1p = 2 / eps - 2 * y / (eps * eps);   /* f1'(y) >= 0 */
        } else {
            f0 = y;
            f1_over_y = 1 / y;
            f1p = 0;
        }
        E += c * f0;
        /* ∇ = c f1(y) u/y (u = T dx and T is symmetric, idempotent) */
        if (g)
            for (int i = 0; i < 3; i++)
                g[i] += c * f1_over_y * u[i];
        /* H = c [ f1'(y) û ûᵀ + f1(y)/y (T − û ûᵀ) ]: both coefficients >= 0 */
        if (H) {
            double uh[3] = {0, 0, 0};
            if (y > 0)
                for (int i = 0; i < 3; i++)
                    uh[i] = u[i] / y;
            for (int i = 0; i < 3; i++)
                for (int j = 0; j < 3; j++) {
                    double T = (i == j) - n[i] * n[j], uu = uh[i] * uh[j];
                    H[3 * i + j] += c * (f1p * uu + f1_over_y * (T - uu));
                }
        }
    }
    return E;
}
