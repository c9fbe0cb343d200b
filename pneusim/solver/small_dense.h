/* The Newton systems of a small model, for CVODE and CVODES: a SUNDIALS linear solver (SUNLinSolNewEmpty
 * with our operations) that factors and solves with the dense LU with partial pivoting of LINPACK's
 * dgefa/dgesl, which is what SUNDIALS' own dense solver (SUNLinSol_Dense) computes, and SUNDIALS' dense
 * matrix (SUNDenseMatrix) with our copy and M = I - gamma J.  Every operation acts on the same elements in
 * the same order as SUNDIALS' does, so CVODE computes the same doubles (a simulation and a fit give results
 * equal to the last bit); what changes is that the loops are unrolled for each state count up to
 * SMALL_DENSE_MAX_N and reached without dispatch or column-pointer indirection.
 *
 * Why: at 4 states the generic dense routines were mostly loop control around 16 numbers (factor, solve,
 * copy and I - gamma J together a seventh of a simulation's run under perf); this header takes the same
 * steps to the same results in less time (docs/decisions/0020 has the measurements).  CVODE still decides when to evaluate the Jacobian and set the matrix up; nothing here
 * integrates.  A model with more than SMALL_DENSE_MAX_N states uses the same code with its state count
 * as a run-time bound.
 *
 * Used by _cvode_compiled.pyx (the simulator) and _cvodes_sensitivity.pyx (the fit).
 */
#ifndef PNEUSIM_SMALL_DENSE_H
#define PNEUSIM_SMALL_DENSE_H

#include <math.h>
#include <stdlib.h>
#include <sundials/sundials_linearsolver.h>
#include <sundials/sundials_matrix.h>
#include <sundials/sundials_nvector.h>
#include <sunmatrix/sunmatrix_dense.h>

#define SMALL_DENSE_MAX_N 8

typedef struct {
  sunindextype n;
  sunindextype pivots[SMALL_DENSE_MAX_N];
  sunindextype *big_pivots; /* n > SMALL_DENSE_MAX_N */
  long last_flag;
} SmallDenseContent;

/* column-major a (a[j * n + i] is row i, column j), as SUNDIALS' dense matrix stores it */
#define SMALL_DENSE_GETRF_BODY(N)                                                        \
  for (sunindextype k = 0; k < (N); k++) {                                               \
    double *col_k = a + k * (N);                                                         \
    sunindextype l = k;                                                                  \
    for (sunindextype i = k + 1; i < (N); i++)                                           \
      if (fabs(col_k[i]) > fabs(col_k[l])) l = i;                                        \
    p[k] = l;                                                                            \
    if (col_k[l] == 0.0) return k + 1;                                                   \
    if (l != k) {                                                                        \
      for (sunindextype i = 0; i < (N); i++) {                                           \
        double temp = a[i * (N) + l];                                                    \
        a[i * (N) + l] = a[i * (N) + k];                                                 \
        a[i * (N) + k] = temp;                                                           \
      }                                                                                  \
    }                                                                                    \
    double mult = 1.0 / col_k[k];                                                        \
    for (sunindextype i = k + 1; i < (N); i++) col_k[i] *= mult;                         \
    for (sunindextype j = k + 1; j < (N); j++) {                                         \
      double *col_j = a + j * (N);                                                       \
      double a_kj = col_j[k];                                                            \
      if (a_kj != 0.0)                                                                   \
        for (sunindextype i = k + 1; i < (N); i++) col_j[i] -= a_kj * col_k[i];          \
    }                                                                                    \
  }                                                                                      \
  return 0;

#define SMALL_DENSE_GETRS_BODY(N)                                                        \
  for (sunindextype k = 0; k < (N); k++) {                                               \
    sunindextype pk = p[k];                                                              \
    if (pk != k) {                                                                       \
      double tmp = b[k];                                                                 \
      b[k] = b[pk];                                                                      \
      b[pk] = tmp;                                                                       \
    }                                                                                    \
  }                                                                                      \
  for (sunindextype k = 0; k < (N) - 1; k++) {                                           \
    const double *col_k = a + k * (N);                                                   \
    for (sunindextype i = k + 1; i < (N); i++) b[i] -= col_k[i] * b[k];                  \
  }                                                                                      \
  for (sunindextype k = (N) - 1; k > 0; k--) {                                           \
    const double *col_k = a + k * (N);                                                   \
    b[k] /= col_k[k];                                                                    \
    for (sunindextype i = 0; i < k; i++) b[i] -= col_k[i] * b[k];                        \
  }                                                                                      \
  b[0] /= a[0];

/* The same solve for nb right-hand sides stored one after another (b[c * N + i]), each operation of
 * SMALL_DENSE_GETRS_BODY applied to every right-hand side before the next: each element sees the same
 * operations in the same order (the same doubles), and the right-hand sides' chains of divisions and
 * products overlap instead of waiting on each other.  The fit's augmented corrector solves 12 blocks of 4
 * per Newton iteration: 93 ns a solve against 363 ns block by block (a C loop on this machine), one
 * evaluation of the paper-2 benchmark's pre-fit window 73 -> 55 ms. */
#define SMALL_DENSE_GETRS_BLOCKS_BODY(N)                                                 \
  for (sunindextype k = 0; k < (N); k++) {                                               \
    sunindextype pk = p[k];                                                              \
    if (pk != k)                                                                         \
      for (sunindextype c = 0; c < nb; c++) {                                            \
        double tmp = b[c * (N) + k];                                                     \
        b[c * (N) + k] = b[c * (N) + pk];                                                \
        b[c * (N) + pk] = tmp;                                                           \
      }                                                                                  \
  }                                                                                      \
  for (sunindextype k = 0; k < (N) - 1; k++) {                                           \
    const double *col_k = a + k * (N);                                                   \
    for (sunindextype i = k + 1; i < (N); i++)                                           \
      for (sunindextype c = 0; c < nb; c++) b[c * (N) + i] -= col_k[i] * b[c * (N) + k]; \
  }                                                                                      \
  for (sunindextype k = (N) - 1; k > 0; k--) {                                           \
    const double *col_k = a + k * (N);                                                   \
    for (sunindextype c = 0; c < nb; c++) b[c * (N) + k] /= col_k[k];                    \
    for (sunindextype i = 0; i < k; i++)                                                 \
      for (sunindextype c = 0; c < nb; c++) b[c * (N) + i] -= col_k[i] * b[c * (N) + k]; \
  }                                                                                      \
  for (sunindextype c = 0; c < nb; c++) b[c * (N)] /= a[0];

#define SMALL_DENSE_KERNELS(N)                                                           \
  static inline sunindextype small_dense_getrf_##N(double *a, sunindextype *p) {        \
    SMALL_DENSE_GETRF_BODY(N)                                                            \
  }                                                                                      \
  static inline void small_dense_getrs_##N(const double *a, const sunindextype *p,      \
                                           double *b) {                                  \
    SMALL_DENSE_GETRS_BODY(N)                                                            \
  }                                                                                      \
  static void small_dense_getrs_blocks_##N(const double *a, const sunindextype *p,      \
                                           double *b, sunindextype nb) {                 \
    SMALL_DENSE_GETRS_BLOCKS_BODY(N)                                                     \
  }

#pragma GCC push_options
#pragma GCC optimize("unroll-loops")
SMALL_DENSE_KERNELS(1)
SMALL_DENSE_KERNELS(2)
SMALL_DENSE_KERNELS(3)
SMALL_DENSE_KERNELS(4)
SMALL_DENSE_KERNELS(5)
SMALL_DENSE_KERNELS(6)
SMALL_DENSE_KERNELS(7)
SMALL_DENSE_KERNELS(8)
#pragma GCC pop_options

static sunindextype small_dense_getrf_any(double *a, sunindextype n, sunindextype *p) {
  SMALL_DENSE_GETRF_BODY(n)
}

static void small_dense_getrs_any(const double *a, sunindextype n, const sunindextype *p, double *b) {
  SMALL_DENSE_GETRS_BODY(n)
}

/* LU of the column-major n-by-n a in place, the unrolled kernel for n up to SMALL_DENSE_MAX_N: 0, or k + 1 at
 * a zero pivot in column k */
static inline sunindextype small_dense_getrf(double *a, sunindextype n, sunindextype *p) {
  switch (n) {
    case 1: return small_dense_getrf_1(a, p);
    case 2: return small_dense_getrf_2(a, p);
    case 3: return small_dense_getrf_3(a, p);
    case 4: return small_dense_getrf_4(a, p);
    case 5: return small_dense_getrf_5(a, p);
    case 6: return small_dense_getrf_6(a, p);
    case 7: return small_dense_getrf_7(a, p);
    case 8: return small_dense_getrf_8(a, p);
    default: return small_dense_getrf_any(a, n, p);
  }
}

/* b := A^-1 b with the LU small_dense_getrf left in a and p */
static inline void small_dense_getrs(const double *a, sunindextype n, const sunindextype *p, double *b) {
  switch (n) {
    case 1: small_dense_getrs_1(a, p, b); break;
    case 2: small_dense_getrs_2(a, p, b); break;
    case 3: small_dense_getrs_3(a, p, b); break;
    case 4: small_dense_getrs_4(a, p, b); break;
    case 5: small_dense_getrs_5(a, p, b); break;
    case 6: small_dense_getrs_6(a, p, b); break;
    case 7: small_dense_getrs_7(a, p, b); break;
    case 8: small_dense_getrs_8(a, p, b); break;
    default: small_dense_getrs_any(a, n, p, b);
  }
}

/* b := A^-1 b for nb right-hand sides b[c * n ...] (n <= SMALL_DENSE_MAX_N): the block solver's */
static inline void small_dense_getrs_blocks(const double *a, sunindextype n, const sunindextype *p, double *b,
                                            sunindextype nb) {
  switch (n) {
    case 1: small_dense_getrs_blocks_1(a, p, b, nb); break;
    case 2: small_dense_getrs_blocks_2(a, p, b, nb); break;
    case 3: small_dense_getrs_blocks_3(a, p, b, nb); break;
    case 4: small_dense_getrs_blocks_4(a, p, b, nb); break;
    case 5: small_dense_getrs_blocks_5(a, p, b, nb); break;
    case 6: small_dense_getrs_blocks_6(a, p, b, nb); break;
    case 7: small_dense_getrs_blocks_7(a, p, b, nb); break;
    case 8: small_dense_getrs_blocks_8(a, p, b, nb); break;
  }
}

#define SMALL_DENSE_CONTENT(S) ((SmallDenseContent *)(S)->content)
#define SMALL_DENSE_PIVOTS(c) ((c)->n > SMALL_DENSE_MAX_N ? (c)->big_pivots : (c)->pivots)

static SUNLinearSolver_Type small_dense_gettype(SUNLinearSolver S) { return SUNLINEARSOLVER_DIRECT; }

static SUNLinearSolver_ID small_dense_getid(SUNLinearSolver S) { return SUNLINEARSOLVER_CUSTOM; }

static int small_dense_initialize(SUNLinearSolver S) {
  SMALL_DENSE_CONTENT(S)->last_flag = SUNLS_SUCCESS;
  return SUNLS_SUCCESS;
}

static int small_dense_setup(SUNLinearSolver S, SUNMatrix A) {
  SmallDenseContent *c = SMALL_DENSE_CONTENT(S);
  double *a = SUNDenseMatrix_Data(A);
  sunindextype *p = SMALL_DENSE_PIVOTS(c);
  sunindextype flag;
  if (a == NULL || SUNDenseMatrix_Rows(A) != c->n || SUNDenseMatrix_Columns(A) != c->n) {
    c->last_flag = SUNLS_ILL_INPUT;
    return SUNLS_ILL_INPUT;
  }
  flag = small_dense_getrf(a, c->n, p);
  c->last_flag = flag;
  /* a zero pivot: recoverable, CVODE cuts the step and sets up again (as SUNLinSol_Dense) */
  return flag > 0 ? SUNLS_LUFACT_FAIL : SUNLS_SUCCESS;
}

static int small_dense_solve(SUNLinearSolver S, SUNMatrix A, N_Vector x, N_Vector b, sunrealtype tol) {
  SmallDenseContent *c = SMALL_DENSE_CONTENT(S);
  const double *a = SUNDenseMatrix_Data(A);
  const sunindextype *p = SMALL_DENSE_PIVOTS(c);
  double *xd = N_VGetArrayPointer(x);
  const double *bd = N_VGetArrayPointer(b);
  if (a == NULL || xd == NULL || bd == NULL) {
    c->last_flag = SUNLS_MEM_FAIL;
    return SUNLS_MEM_FAIL;
  }
  for (sunindextype i = 0; i < c->n; i++) xd[i] = bd[i];
  small_dense_getrs(a, c->n, p, xd);
  c->last_flag = SUNLS_SUCCESS;
  return SUNLS_SUCCESS;
}

static sunindextype small_dense_lastflag(SUNLinearSolver S) { return SMALL_DENSE_CONTENT(S)->last_flag; }

static int small_dense_free(SUNLinearSolver S) {
  if (S == NULL) return SUNLS_SUCCESS;
  if (S->content != NULL) {
    free(SMALL_DENSE_CONTENT(S)->big_pivots);
    free(S->content);
    S->content = NULL;
  }
  SUNLinSolFreeEmpty(S);
  return SUNLS_SUCCESS;
}

/* The two operations CVODE's linear-solver interface applies to the Newton matrix at every setup
 * (cvLsLinSys: copy to or from the saved Jacobian, then M = I - gamma J), as SUNMatCopy_Dense and
 * SUNMatScaleAddI_Dense compute them (the same doubles), on the contiguous column-major data without the
 * compatibility checks' dispatch: they were 7 % of the paper-1 simulator benchmark. */
static int small_dense_matrix_copy(SUNMatrix A, SUNMatrix B) {
  sunindextype n = SUNDenseMatrix_Rows(A);
  if (SUNDenseMatrix_Columns(A) != n || SUNDenseMatrix_Rows(B) != n || SUNDenseMatrix_Columns(B) != n)
    return SUNMAT_ILL_INPUT;
  const double *a = SUNDenseMatrix_Data(A);
  double *b = SUNDenseMatrix_Data(B);
  for (sunindextype k = 0; k < n * n; k++) b[k] = a[k];
  return SUNMAT_SUCCESS;
}

static int small_dense_matrix_scale_add_identity(sunrealtype c, SUNMatrix A) {
  sunindextype n = SUNDenseMatrix_Rows(A);
  double *a = SUNDenseMatrix_Data(A);
  for (sunindextype k = 0; k < n * n; k++) a[k] *= c;
  for (sunindextype j = 0; j < n; j++) a[j * n + j] += 1.0;
  return SUNMAT_SUCCESS;
}

static SUNMatrix small_dense_matrix_clone(SUNMatrix A);

static SUNMatrix small_dense_matrix_with_fast_ops(SUNMatrix A) {
  if (A == NULL) return NULL;
  A->ops->copy = small_dense_matrix_copy;
  A->ops->scaleaddi = small_dense_matrix_scale_add_identity;
  A->ops->clone = small_dense_matrix_clone;
  return A;
}

/* CVODE keeps its saved Jacobian in a clone of the Newton matrix: the clone gets the same operations */
static SUNMatrix small_dense_matrix_clone(SUNMatrix A) { return small_dense_matrix_with_fast_ops(SUNMatClone_Dense(A)); }

/* An n-by-n SUNDIALS dense matrix (SUNDenseMatrix) whose copy and I - gamma J operations, and its clones',
 * are the ones above; NULL when out of memory. */
static SUNMatrix SmallDenseMatrix(sunindextype n, SUNContext context) {
  return small_dense_matrix_with_fast_ops(SUNDenseMatrix(n, n, context));
}

/* A dense direct linear solver for n-by-n SUNDIALS dense matrices; NULL when out of memory. */
static SUNLinearSolver SmallDenseLinearSolver(sunindextype n, SUNContext context) {
  SUNLinearSolver S = SUNLinSolNewEmpty(context);
  SmallDenseContent *c;
  if (S == NULL) return NULL;
  c = (SmallDenseContent *)calloc(1, sizeof(SmallDenseContent));
  if (c == NULL) {
    SUNLinSolFreeEmpty(S);
    return NULL;
  }
  c->n = n;
  if (n > SMALL_DENSE_MAX_N) {
    c->big_pivots = (sunindextype *)malloc(n * sizeof(sunindextype));
    if (c->big_pivots == NULL) {
      free(c);
      SUNLinSolFreeEmpty(S);
      return NULL;
    }
  }
  S->content = c;
  S->ops->gettype = small_dense_gettype;
  S->ops->getid = small_dense_getid;
  S->ops->initialize = small_dense_initialize;
  S->ops->setup = small_dense_setup;
  S->ops->solve = small_dense_solve;
  S->ops->lastflag = small_dense_lastflag;
  S->ops->free = small_dense_free;
  return S;
}

/* The Newton systems of the fit's state-and-sensitivity system, integrated as one augmented state
 * [x; S e_1; ...; S e_ns] (n + n ns values): a linear solver that factors the leading n-by-n block of the
 * N-by-N Newton matrix, I - gamma f_x, and solves every n-value block of the right-hand side with it.
 * That is the block-diagonal part of the augmented Newton matrix; the blocks below it (the derivative of
 * f_x S + f_p with respect to x) are left out, as CVODES's staggered corrector leaves them out, and CVODE's
 * Newton iteration converges on the states as before.  The Jacobian callback fills only the leading block
 * (CVODE zeroes the rest).  Why: CVODES's own sensitivity machinery spends about ten times the model's cost
 * on bookkeeping for 11 vectors of 4 values; one vector of 48 takes one call per operation. */
typedef struct {
  sunindextype n_total;
  sunindextype n;
  double lu[SMALL_DENSE_MAX_N * SMALL_DENSE_MAX_N];
  sunindextype pivots[SMALL_DENSE_MAX_N];
  long last_flag;
} SmallBlockContent;

#define SMALL_BLOCK_CONTENT(S) ((SmallBlockContent *)(S)->content)

static int small_block_setup(SUNLinearSolver S, SUNMatrix A) {
  SmallBlockContent *c = SMALL_BLOCK_CONTENT(S);
  const double *a = SUNDenseMatrix_Data(A);
  sunindextype n = c->n, ld = c->n_total, flag;
  if (a == NULL || SUNDenseMatrix_Rows(A) != ld || SUNDenseMatrix_Columns(A) != ld) {
    c->last_flag = SUNLS_ILL_INPUT;
    return SUNLS_ILL_INPUT;
  }
  for (sunindextype j = 0; j < n; j++)
    for (sunindextype i = 0; i < n; i++) c->lu[j * n + i] = a[j * ld + i];
  flag = small_dense_getrf(c->lu, n, c->pivots);
  c->last_flag = flag;
  return flag > 0 ? SUNLS_LUFACT_FAIL : SUNLS_SUCCESS;
}

static int small_block_solve(SUNLinearSolver S, SUNMatrix A, N_Vector x, N_Vector b, sunrealtype tol) {
  SmallBlockContent *c = SMALL_BLOCK_CONTENT(S);
  double *xd = N_VGetArrayPointer(x);
  const double *bd = N_VGetArrayPointer(b);
  sunindextype n = c->n;
  if (xd == NULL || bd == NULL) {
    c->last_flag = SUNLS_MEM_FAIL;
    return SUNLS_MEM_FAIL;
  }
  if (xd != bd)
    for (sunindextype k = 0; k < c->n_total; k++) xd[k] = bd[k];
  small_dense_getrs_blocks(c->lu, n, c->pivots, xd, c->n_total / n);
  c->last_flag = SUNLS_SUCCESS;
  return SUNLS_SUCCESS;
}

static sunindextype small_block_lastflag(SUNLinearSolver S) { return SMALL_BLOCK_CONTENT(S)->last_flag; }

static int small_block_initialize(SUNLinearSolver S) {
  SMALL_BLOCK_CONTENT(S)->last_flag = SUNLS_SUCCESS;
  return SUNLS_SUCCESS;
}

static int small_block_free(SUNLinearSolver S) {
  if (S == NULL) return SUNLS_SUCCESS;
  free(S->content);
  S->content = NULL;
  SUNLinSolFreeEmpty(S);
  return SUNLS_SUCCESS;
}

/* The N-by-N Newton matrix of the block solver: only its leading n-by-n block is ever read, so CVODE's
 * zero, copy and I - gamma J act on that block alone (the same doubles there; 16 values instead of 2304
 * at 4 states and 11 directions), and CVODE can set the matrix up at every step for the price of the
 * state's. */
#define SMALL_BLOCK_MATRIX_OPS(NB)                                                        \
  static int small_block_zero_##NB(SUNMatrix A) {                                         \
    double *a = SUNDenseMatrix_Data(A);                                                   \
    sunindextype ld = SUNDenseMatrix_Rows(A);                                             \
    for (sunindextype j = 0; j < (NB); j++)                                               \
      for (sunindextype i = 0; i < (NB); i++) a[j * ld + i] = 0.0;                        \
    return SUNMAT_SUCCESS;                                                                \
  }                                                                                       \
  static int small_block_copy_##NB(SUNMatrix A, SUNMatrix B) {                            \
    const double *a = SUNDenseMatrix_Data(A);                                             \
    double *b = SUNDenseMatrix_Data(B);                                                   \
    sunindextype ld = SUNDenseMatrix_Rows(A);                                             \
    if (SUNDenseMatrix_Rows(B) != ld) return SUNMAT_ILL_INPUT;                            \
    for (sunindextype j = 0; j < (NB); j++)                                               \
      for (sunindextype i = 0; i < (NB); i++) b[j * ld + i] = a[j * ld + i];              \
    return SUNMAT_SUCCESS;                                                                \
  }                                                                                       \
  static int small_block_scale_add_identity_##NB(sunrealtype c, SUNMatrix A) {           \
    double *a = SUNDenseMatrix_Data(A);                                                   \
    sunindextype ld = SUNDenseMatrix_Rows(A);                                             \
    for (sunindextype j = 0; j < (NB); j++) {                                             \
      for (sunindextype i = 0; i < (NB); i++) a[j * ld + i] *= c;                         \
      a[j * ld + j] += 1.0;                                                               \
    }                                                                                     \
    return SUNMAT_SUCCESS;                                                                \
  }                                                                                       \
  static SUNMatrix small_block_clone_##NB(SUNMatrix A);                                   \
  static SUNMatrix small_block_with_ops_##NB(SUNMatrix A) {                               \
    if (A == NULL) return NULL;                                                           \
    A->ops->zero = small_block_zero_##NB;                                                 \
    A->ops->copy = small_block_copy_##NB;                                                 \
    A->ops->scaleaddi = small_block_scale_add_identity_##NB;                              \
    A->ops->clone = small_block_clone_##NB;                                               \
    return A;                                                                             \
  }                                                                                       \
  static SUNMatrix small_block_clone_##NB(SUNMatrix A) {                                  \
    return small_block_with_ops_##NB(SUNMatClone_Dense(A));                               \
  }

SMALL_BLOCK_MATRIX_OPS(1)
SMALL_BLOCK_MATRIX_OPS(2)
SMALL_BLOCK_MATRIX_OPS(3)
SMALL_BLOCK_MATRIX_OPS(4)
SMALL_BLOCK_MATRIX_OPS(5)
SMALL_BLOCK_MATRIX_OPS(6)
SMALL_BLOCK_MATRIX_OPS(7)
SMALL_BLOCK_MATRIX_OPS(8)

/* An n_total-by-n_total SUNDIALS dense matrix whose zero, copy and I - gamma J (and its clones') act on the
 * leading n-by-n block only: the block solver's Newton matrix.  NULL when out of memory or out of range. */
static SUNMatrix SmallBlockMatrix(sunindextype n_total, sunindextype n, SUNContext context) {
  if (n < 1 || n > SMALL_DENSE_MAX_N || n_total % n != 0) return NULL;
  SUNMatrix A = SUNDenseMatrix(n_total, n_total, context);
  switch (n) {
    case 1: return small_block_with_ops_1(A);
    case 2: return small_block_with_ops_2(A);
    case 3: return small_block_with_ops_3(A);
    case 4: return small_block_with_ops_4(A);
    case 5: return small_block_with_ops_5(A);
    case 6: return small_block_with_ops_6(A);
    case 7: return small_block_with_ops_7(A);
    default: return small_block_with_ops_8(A);
  }
}

/* The block solver above for an n_total-by-n_total Newton matrix of n-value blocks (n at most
 * SMALL_DENSE_MAX_N, n_total a multiple of n); NULL when out of memory or out of range. */
static SUNLinearSolver SmallBlockLinearSolver(sunindextype n_total, sunindextype n, SUNContext context) {
  SUNLinearSolver S;
  SmallBlockContent *c;
  if (n < 1 || n > SMALL_DENSE_MAX_N || n_total % n != 0) return NULL;
  S = SUNLinSolNewEmpty(context);
  if (S == NULL) return NULL;
  c = (SmallBlockContent *)calloc(1, sizeof(SmallBlockContent));
  if (c == NULL) {
    SUNLinSolFreeEmpty(S);
    return NULL;
  }
  c->n_total = n_total;
  c->n = n;
  S->content = c;
  S->ops->gettype = small_dense_gettype;
  S->ops->getid = small_dense_getid;
  S->ops->initialize = small_block_initialize;
  S->ops->setup = small_block_setup;
  S->ops->solve = small_block_solve;
  S->ops->lastflag = small_block_lastflag;
  S->ops->free = small_block_free;
  return S;
}

#endif
