/* material.c — the stable neo-Hookean material from E, nu, rho (see
 * material.h).
 *
 *   [SNH18] Smith, de Goes, Kim 2018, "Stable Neo-Hookean Flesh Simulation".
 */
#include <math.h>

#include "base/err.h"
#include "phys/material.h"

int crom_material_init(crom_material *m, double E, double nu, double rho)
{
    if (!isfinite(E) || E <= 0)
        return crom_err(CROM_EUSAGE,
                        "Young's modulus E = %g must be finite and > 0 (Pa)", E);
    if (!isfinite(nu) || nu <= -1 || nu >= 0.5)
        return crom_err(CROM_EUSAGE,
                        "Poisson ratio nu = %g must be in (-1, 0.5)", nu);
    if (!isfinite(rho) || rho <= 0)
        return crom_err(CROM_EUSAGE,
                        "density rho = %g must be finite and > 0 (kg/m^3)", rho);
    double mu_lame = E / (2 * (1 + nu));
    double lambda_lame = E * nu / ((1 + nu) * (1 - 2 * nu));
    /* Matching the SNH linearization (3μ/4)‖ε‖² + (λ/2 − 5μ/16)(tr ε)² to
     * μL‖ε‖² + λL/2 (tr ε)²: μ = 4/3 μL, λ = λL + 5/6 μL, written here
     * without the cancellation of λL + 5/6 μL for ν < 0. */
    double mu = 4.0 / 3.0 * mu_lame;
    double lambda = mu_lame * (2 * nu + 5) / (6 * (1 - 2 * nu));
    if (!isfinite(mu) || !isfinite(lambda) || !(lambda > 0))
        return crom_err(CROM_EUSAGE,
                        "Poisson ratio nu = %g too close to 0.5: the material "
                        "parameters overflow", nu);
    m->E = E;
    m->nu = nu;
    m->rho = rho;
    m->mu_lame = mu_lame;
    m->lambda_lame = lambda_lame;
    m->mu = mu;
    m->lambda = lambda;
    m->alpha = 1 + 3 * mu / (4 * lambda); /* [SNH18] so that P(I) = 0 */
    return CROM_OK;
}
