/* SUNDIALS serial vectors of a small model with the element-wise operations CVODE calls at every step
 * implemented here: the same arithmetic on each element as SUNDIALS' serial vector (so CVODE computes the
 * same doubles), reached in one call instead of the serial module's call chains (N_VWrmsNorm_Serial calls
 * N_VWSqrSumLocal_Serial; N_VLinearSum_Serial branches through eight special cases to one of seven
 * helpers).  The vector's data, length and every other operation stay SUNDIALS' serial ones, and CVODE's
 * work vectors inherit these operations (N_VClone copies the operation table).
 *
 * Same arithmetic, case by case: z = a x + b y is computed as a x + b y except where SUNDIALS' serial
 * vector rounds differently, a == b (a (x + y)) and a == -b (a (x - y)), with a and b not +-1; its other
 * special cases (a or b equal to +-1, z aliasing x or y) give the same doubles as a x + b y in IEEE
 * arithmetic without fused multiply-adds (1 x = x, -1 x = -x exactly), which the extensions are
 * compiled without (-ffp-contract=off).  The weighted rms norm sums (x_i w_i)^2 in index order.
 *
 * Why: at 4 states the serial module's call chains and special-case branches cost more than the
 * arithmetic; with the same steps and the same results, both headers together run a simulation about
 * twice as fast as SUNDIALS' own vector, matrix and solver (benchmarks/test_bench_simulator.py prints the
 * ratio; docs/decisions/0020 has the measurements).
 *
 * Used by _cvode_compiled.pyx (the simulator, SmallSerialVector) and _cvodes_sensitivity.pyx (the fit,
 * SmallSerialVectorFused).
 */
#ifndef PNEUSIM_SMALL_VECTOR_H
#define PNEUSIM_SMALL_VECTOR_H

#include <math.h>
#include <nvector/nvector_serial.h>

#define SMALL_VECTOR_DATA(v) (((N_VectorContent_Serial)(v)->content)->data)
#define SMALL_VECTOR_LENGTH(v) (((N_VectorContent_Serial)(v)->content)->length)

static void small_vector_linear_sum(sunrealtype a, N_Vector x, sunrealtype b, N_Vector y, N_Vector z) {
  const sunindextype n = SMALL_VECTOR_LENGTH(x);
  const sunrealtype *xd = SMALL_VECTOR_DATA(x), *yd = SMALL_VECTOR_DATA(y);
  sunrealtype *zd = SMALL_VECTOR_DATA(z);
  const int unit = (a == 1.0 || a == -1.0 || b == 1.0 || b == -1.0);
  if (!unit && a == b) {
    for (sunindextype i = 0; i < n; i++) zd[i] = a * (xd[i] + yd[i]);
  } else if (!unit && a == -b) {
    for (sunindextype i = 0; i < n; i++) zd[i] = a * (xd[i] - yd[i]);
  } else {
    for (sunindextype i = 0; i < n; i++) zd[i] = a * xd[i] + b * yd[i];
  }
}

static void small_vector_scale(sunrealtype c, N_Vector x, N_Vector z) {
  const sunindextype n = SMALL_VECTOR_LENGTH(x);
  const sunrealtype *xd = SMALL_VECTOR_DATA(x);
  sunrealtype *zd = SMALL_VECTOR_DATA(z);
  for (sunindextype i = 0; i < n; i++) zd[i] = c * xd[i];
}

static void small_vector_const(sunrealtype c, N_Vector z) {
  const sunindextype n = SMALL_VECTOR_LENGTH(z);
  sunrealtype *zd = SMALL_VECTOR_DATA(z);
  for (sunindextype i = 0; i < n; i++) zd[i] = c;
}

static void small_vector_abs(N_Vector x, N_Vector z) {
  const sunindextype n = SMALL_VECTOR_LENGTH(x);
  const sunrealtype *xd = SMALL_VECTOR_DATA(x);
  sunrealtype *zd = SMALL_VECTOR_DATA(z);
  for (sunindextype i = 0; i < n; i++) zd[i] = fabs(xd[i]);
}

static void small_vector_inv(N_Vector x, N_Vector z) {
  const sunindextype n = SMALL_VECTOR_LENGTH(x);
  const sunrealtype *xd = SMALL_VECTOR_DATA(x);
  sunrealtype *zd = SMALL_VECTOR_DATA(z);
  for (sunindextype i = 0; i < n; i++) zd[i] = 1.0 / xd[i];
}

static sunrealtype small_vector_weighted_square_sum(N_Vector x, N_Vector w) {
  const sunindextype n = SMALL_VECTOR_LENGTH(x);
  const sunrealtype *xd = SMALL_VECTOR_DATA(x), *wd = SMALL_VECTOR_DATA(w);
  sunrealtype sum = 0.0;
  for (sunindextype i = 0; i < n; i++) {
    sunrealtype p = xd[i] * wd[i];
    sum += p * p;
  }
  return sum;
}

static sunrealtype small_vector_wrms_norm(N_Vector x, N_Vector w) {
  sunrealtype mean = small_vector_weighted_square_sum(x, w) / SMALL_VECTOR_LENGTH(x);
  return mean <= 0.0 ? 0.0 : sqrt(mean);
}

/* The fused and vector-array operations CVODES calls on the sensitivity vectors (enabled by
 * N_VEnableFusedOps_Serial), with the same arithmetic: a combination of one vector is a scaling, of two
 * a linear sum as above (with its two special cases), of three or more c_0 x_0 + c_1 x_1 + ... summed
 * left to right; z = a x + y and the norms element by element. */
static int small_vector_linear_combination(int nvec, sunrealtype *c, N_Vector *X, N_Vector z) {
  if (nvec == 1) {
    small_vector_scale(c[0], X[0], z);
    return 0;
  }
  if (nvec == 2) {
    small_vector_linear_sum(c[0], X[0], c[1], X[1], z);
    return 0;
  }
  const sunindextype n = SMALL_VECTOR_LENGTH(z);
  sunrealtype *zd = SMALL_VECTOR_DATA(z);
  const sunrealtype *xd = SMALL_VECTOR_DATA(X[0]);
  for (sunindextype k = 0; k < n; k++) zd[k] = c[0] * xd[k];
  for (int i = 1; i < nvec; i++) {
    xd = SMALL_VECTOR_DATA(X[i]);
    for (sunindextype k = 0; k < n; k++) zd[k] += c[i] * xd[k];
  }
  return 0;
}

static int small_vector_scale_add_multi(int nvec, sunrealtype *a, N_Vector x, N_Vector *Y, N_Vector *Z) {
  const sunindextype n = SMALL_VECTOR_LENGTH(x);
  const sunrealtype *xd = SMALL_VECTOR_DATA(x);
  for (int i = 0; i < nvec; i++) {
    const sunrealtype *yd = SMALL_VECTOR_DATA(Y[i]);
    sunrealtype *zd = SMALL_VECTOR_DATA(Z[i]);
    for (sunindextype k = 0; k < n; k++) zd[k] = a[i] * xd[k] + yd[k];
  }
  return 0;
}

static int small_vector_linear_sum_array(int nvec, sunrealtype a, N_Vector *X, sunrealtype b, N_Vector *Y,
                                         N_Vector *Z) {
  for (int i = 0; i < nvec; i++) small_vector_linear_sum(a, X[i], b, Y[i], Z[i]);
  return 0;
}

static int small_vector_scale_array(int nvec, sunrealtype *c, N_Vector *X, N_Vector *Z) {
  for (int i = 0; i < nvec; i++) small_vector_scale(c[i], X[i], Z[i]);
  return 0;
}

static int small_vector_const_array(int nvec, sunrealtype c, N_Vector *Z) {
  for (int i = 0; i < nvec; i++) small_vector_const(c, Z[i]);
  return 0;
}

static int small_vector_wrms_norm_array(int nvec, N_Vector *X, N_Vector *W, sunrealtype *norms) {
  for (int i = 0; i < nvec; i++) norms[i] = small_vector_wrms_norm(X[i], W[i]);
  return 0;
}

static int small_vector_scale_add_multi_array(int nvec, int nsum, sunrealtype *a, N_Vector *X, N_Vector **Y,
                                              N_Vector **Z) {
  const sunindextype n = SMALL_VECTOR_LENGTH(X[0]);
  for (int i = 0; i < nvec; i++) {
    const sunrealtype *xd = SMALL_VECTOR_DATA(X[i]);
    for (int j = 0; j < nsum; j++) {
      const sunrealtype *yd = SMALL_VECTOR_DATA(Y[j][i]);
      sunrealtype *zd = SMALL_VECTOR_DATA(Z[j][i]);
      for (sunindextype k = 0; k < n; k++) zd[k] = a[j] * xd[k] + yd[k];
    }
  }
  return 0;
}

static int small_vector_linear_combination_array(int nvec, int nsum, sunrealtype *c, N_Vector **X, N_Vector *Z) {
  N_Vector column[nsum];   /* X[0][j], X[1][j], ...: the terms of Z[j] (nsum is the BDF order + 1 or so) */
  for (int j = 0; j < nvec; j++) {
    for (int i = 0; i < nsum; i++) column[i] = X[i][j];
    small_vector_linear_combination(nsum, c, column, Z[j]);
  }
  return 0;
}

/* A serial N_Vector of length n with the operations above; NULL when out of memory. */
static N_Vector SmallSerialVector(sunindextype n, SUNContext context) {
  N_Vector v = N_VNew_Serial(n, context);
  if (v == NULL) return NULL;
  v->ops->nvlinearsum = small_vector_linear_sum;
  v->ops->nvscale = small_vector_scale;
  v->ops->nvconst = small_vector_const;
  v->ops->nvabs = small_vector_abs;
  v->ops->nvinv = small_vector_inv;
  v->ops->nvwrmsnorm = small_vector_wrms_norm;
  v->ops->nvwsqrsumlocal = small_vector_weighted_square_sum;
  return v;
}

/* The same with the fused and vector-array operations on (SUNDIALS' own for the few not defined here,
 * as N_VEnableFusedOps_Serial sets them); NULL when out of memory. */
static N_Vector SmallSerialVectorFused(sunindextype n, SUNContext context) {
  N_Vector v = SmallSerialVector(n, context);
  if (v == NULL) return NULL;
  N_VEnableFusedOps_Serial(v, SUNTRUE);
  v->ops->nvlinearcombination = small_vector_linear_combination;
  v->ops->nvscaleaddmulti = small_vector_scale_add_multi;
  v->ops->nvlinearsumvectorarray = small_vector_linear_sum_array;
  v->ops->nvscalevectorarray = small_vector_scale_array;
  v->ops->nvconstvectorarray = small_vector_const_array;
  v->ops->nvwrmsnormvectorarray = small_vector_wrms_norm_array;
  v->ops->nvscaleaddmultivectorarray = small_vector_scale_add_multi_array;
  v->ops->nvlinearcombinationvectorarray = small_vector_linear_combination_array;
  return v;
}

/* The augmented state [x; vec(S)] of the fit's sensitivity integration (_cvodes_sensitivity.pyx,
 * corrector="augmented"): the serial vector above whose weighted rms norm sums the leading n entries (the
 * state) and divides by the whole length.  Why: the sensitivities take no part in CVODE's error and Newton
 * convergence tests, which is what their weights of 1e-100 already give: their squares, (x w)^2 < 1e-180,
 * vanish in a sum of the state's terms to the last bit unless those are below about 1e-165, i.e. zero
 * (the benchmark fit and the 48 robustness fits give the same doubles).  The loop is the norm's chain of
 * dependent additions, and the state's 4 of 48 terms cut it to a twelfth (the paper-2 benchmark's pre-fit
 * window: the norms 5.3 -> 1.6 % of perf's samples, one evaluation 3 % faster).  Every other operation acts
 * on the whole vector. */
#define SMALL_VECTOR_LEADING_NORM(N)                                                          \
  static sunrealtype small_vector_leading_square_sum_##N(N_Vector x, N_Vector w) {          \
    const sunrealtype *xd = SMALL_VECTOR_DATA(x), *wd = SMALL_VECTOR_DATA(w);                \
    sunrealtype sum = 0.0;                                                                    \
    for (sunindextype i = 0; i < (N); i++) {                                                  \
      sunrealtype p = xd[i] * wd[i];                                                          \
      sum += p * p;                                                                           \
    }                                                                                         \
    return sum;                                                                               \
  }                                                                                           \
  static sunrealtype small_vector_leading_wrms_norm_##N(N_Vector x, N_Vector w) {           \
    sunrealtype mean = small_vector_leading_square_sum_##N(x, w) / SMALL_VECTOR_LENGTH(x);   \
    return mean <= 0.0 ? 0.0 : sqrt(mean);                                                    \
  }

SMALL_VECTOR_LEADING_NORM(1)
SMALL_VECTOR_LEADING_NORM(2)
SMALL_VECTOR_LEADING_NORM(3)
SMALL_VECTOR_LEADING_NORM(4)
SMALL_VECTOR_LEADING_NORM(5)
SMALL_VECTOR_LEADING_NORM(6)
SMALL_VECTOR_LEADING_NORM(7)
SMALL_VECTOR_LEADING_NORM(8)

/* SmallSerialVectorFused of length n_total whose norms sum its leading n entries (1 <= n <= 8, n < n_total);
 * NULL when out of memory or out of range.  Its clones (CVODE's work vectors) keep the operations. */
static N_Vector SmallLeadingNormVector(sunindextype n_total, sunindextype n, SUNContext context) {
  static sunrealtype (*const norms[8])(N_Vector, N_Vector) = {
      small_vector_leading_wrms_norm_1, small_vector_leading_wrms_norm_2, small_vector_leading_wrms_norm_3,
      small_vector_leading_wrms_norm_4, small_vector_leading_wrms_norm_5, small_vector_leading_wrms_norm_6,
      small_vector_leading_wrms_norm_7, small_vector_leading_wrms_norm_8};
  static sunrealtype (*const sums[8])(N_Vector, N_Vector) = {
      small_vector_leading_square_sum_1, small_vector_leading_square_sum_2, small_vector_leading_square_sum_3,
      small_vector_leading_square_sum_4, small_vector_leading_square_sum_5, small_vector_leading_square_sum_6,
      small_vector_leading_square_sum_7, small_vector_leading_square_sum_8};
  if (n < 1 || n > 8 || n >= n_total) return NULL;
  N_Vector v = SmallSerialVectorFused(n_total, context);
  if (v == NULL) return NULL;
  v->ops->nvwrmsnorm = norms[n - 1];
  v->ops->nvwsqrsumlocal = sums[n - 1];
  v->ops->nvwrmsnormvectorarray = NULL;   /* N_VWrmsNormVectorArray then calls the norm above per vector */
  return v;
}

#endif
