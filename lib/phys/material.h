/* material.h — the elastic material of crom's solids: stable neo-Hookean
 * (fem.h has its energy, stress and tangent) with parameters from Young's
 * modulus, Poisson ratio and density.
 */
#ifndef CROM_MATERIAL_H
#define CROM_MATERIAL_H

/* A stable neo-Hookean material. mu, lambda are the energy's parameters,
 * chosen so that its linearization at F = I is linear elasticity with the
 * Lamé parameters (mu_lame, lambda_lame) of (E, nu):
 *   mu = 4/3 mu_lame,  lambda = lambda_lame + 5/6 mu_lame.
 * lambda = mu_lame (2nu + 5) / (6 (1 - 2nu)) is positive for every nu in
 * (-1, 0.5), negative nu included (where lambda_lame < 0), so alpha is always
 * defined; lambda grows without bound as nu -> 0.5 (stiff but finite). */
typedef struct {
    double E;           /* Young's modulus (Pa) */
    double nu;          /* Poisson ratio, in (-1, 0.5) */
    double rho;         /* density (kg/m³) */
    double mu_lame;     /* μL = E / (2(1+ν)) */
    double lambda_lame; /* λL = Eν / ((1+ν)(1−2ν)), negative when ν < 0 */
    double mu;          /* SNH μ = 4/3 μL */
    double lambda;      /* SNH λ = λL + 5/6 μL (> 0) */
    double alpha;       /* SNH α = 1 + 3μ/(4λ) */
} crom_material;

/* Fill m from Young's modulus E (Pa), Poisson ratio nu and density rho
 * (kg/m³). Returns CROM_OK, or CROM_EUSAGE (message names the value) when a
 * value is not finite, E <= 0, rho <= 0 or nu is outside (-1, 0.5). */
int crom_material_init(crom_material *m, double E, double nu, double rho);

#endif
