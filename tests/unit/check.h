/* check.h — the tiny assertion kit of crom's unit tests.
 *
 * Each CHECK prints "not ok" with the values on failure and counts it; a test
 * program ends with `return check_done();`, which prints a one-line summary and
 * returns non-zero when anything failed. Also: finite-difference helpers used by
 * every derivative test.
 */
#ifndef CROM_CHECK_H
#define CROM_CHECK_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int check_fail_count, check_pass_count;
static const char *check_name = "test";

#define CHECK_MSG(cond, ...)                                                    \
    do {                                                                        \
        if (cond) {                                                             \
            check_pass_count++;                                                 \
        } else {                                                                \
            check_fail_count++;                                                 \
            fprintf(stderr, "not ok %s:%d: ", __FILE__, __LINE__);              \
            fprintf(stderr, __VA_ARGS__);                                       \
            fputc('\n', stderr);                                                \
        }                                                                       \
    } while (0)

#define CHECK(cond) CHECK_MSG((cond), "%s", #cond)

/* |a - b| <= tol */
#define CHECK_NEAR(a, b, tol)                                                   \
    do {                                                                        \
        double check_a_ = (a), check_b_ = (b), check_t_ = (tol);                \
        CHECK_MSG(fabs(check_a_ - check_b_) <= check_t_,                        \
                  "%s = %.12g, %s = %.12g, |diff| = %.3g > %.3g", #a, check_a_, \
                  #b, check_b_, fabs(check_a_ - check_b_), check_t_);           \
    } while (0)

/* |a - b| <= rtol * max(|b|, tiny) */
#define CHECK_REL(a, b, rtol)                                                   \
    do {                                                                        \
        double check_a_ = (a), check_b_ = (b), check_t_ = (rtol);               \
        double check_s_ = fabs(check_b_) > 1e-300 ? fabs(check_b_) : 1e-300;    \
        CHECK_MSG(fabs(check_a_ - check_b_) <= check_t_ * check_s_,             \
                  "%s = %.12g, %s = %.12g, rel diff %.3g > %.3g", #a, check_a_, \
                  #b, check_b_, fabs(check_a_ - check_b_) / check_s_, check_t_);\
    } while (0)

/* a < b */
#define CHECK_LT(a, b)                                                          \
    do {                                                                        \
        double check_a_ = (a), check_b_ = (b);                                  \
        CHECK_MSG(check_a_ < check_b_, "%s = %.6g is not < %s = %.6g", #a,      \
                  check_a_, #b, check_b_);                                      \
    } while (0)

static inline void check_begin(const char *name) { check_name = name; }

static inline int check_done(void)
{
    if (check_fail_count)
        fprintf(stderr, "%s: %d of %d checks FAILED\n", check_name,
                check_fail_count, check_fail_count + check_pass_count);
    else
        fprintf(stderr, "%s: all %d checks passed\n", check_name,
                check_pass_count);
    return check_fail_count ? 1 : 0;
}

/* Relative error ‖a - b‖ / max(‖b‖, floor) of two vectors. */
static inline double check_relerr(const double *a, const double *b, int n,
                                  double floor)
{
    double d = 0, nb = 0;
    for (int i = 0; i < n; i++) {
        d += (a[i] - b[i]) * (a[i] - b[i]);
        nb += b[i] * b[i];
    }
    nb = sqrt(nb);
    return sqrt(d) / (nb > floor ? nb : floor);
}

/* Central-difference gradient of f at x (n entries), step h, into g. */
typedef double (*check_scalar_fn)(const double *x, void *ctx);
static inline void check_fd_gradient(check_scalar_fn f, void *ctx, double *x,
                                     int n, double h, double *g)
{
    for (int i = 0; i < n; i++) {
        double xi = x[i];
        x[i] = xi + h;
        double fp = f(x, ctx);
        x[i] = xi - h;
        double fm = f(x, ctx);
        x[i] = xi;
        g[i] = (fp - fm) / (2 * h);
    }
}

/* Central-difference Jacobian of a vector function v: R^n -> R^m at x, into
 * J (row-major m x n). */
typedef void (*check_vector_fn)(const double *x, void *ctx, double *out);
static inline void check_fd_jacobian(check_vector_fn v, void *ctx, double *x,
                                     int n, int m, double h, double *J)
{
    double *fp = malloc(sizeof(double) * m), *fm = malloc(sizeof(double) * m);
    for (int j = 0; j < n; j++) {
        double xj = x[j];
        x[j] = xj + h;
        v(x, ctx, fp);
        x[j] = xj - h;
        v(x, ctx, fm);
        x[j] = xj;
        for (int i = 0; i < m; i++)
            J[i * n + j] = (fp[i] - fm[i]) / (2 * h);
    }
    free(fp);
    free(fm);
}

#endif
