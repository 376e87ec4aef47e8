/* mmstab box QP: the controller's dedicated solver (mmstab/control/controller/boxqp.py).
 *
 *   min 1/2 x'Hx + g'x   s.t.  lbx <= x <= ubx,   H (6 x 6) symmetric positive definite
 *
 * A primal active-set method (Nocedal & Wright, Numerical Optimization, Alg. 16.3, for bounds):
 * the working set fixes some coordinates at a bound; each iteration solves the equality-
 * constrained problem on the free coordinates by a factorisation of the free block of
 * H, steps toward it until a free coordinate hits a bound (which joins the working set), and at
 * the subspace optimum drops the fixed coordinate whose multiplier has the wrong sign (LDL'
 * factorisation: one division per free coordinate, no square root). For a
 * strictly convex QP the objective decreases strictly between working sets, so no set repeats
 * and the method ends in finitely many iterations at the unique optimum.
 *
 * Start: the unconstrained optimum (one 6 x 6 LDL' solve; on most control steps no joint limit is
 * active and this is the answer), else that point clipped to the box with the clipped
 * coordinates fixed. The answer is always the subspace solution of the final working set, so it
 * is exact to round-off whatever path led there.
 *
 * No heap, no static state: all scratch is on the stack (about 0.5 kB). CasADi calling
 * convention, so the same function is the interpreted controller's solver (casadi.external of
 * a shared library built from this file) and, appended to the generated controller_step.c, the
 * generated one:
 *
 *   arg[0] H (6 x 6, dense, column-major)   arg[1] g (6)   arg[2] lbx (6)   arg[3] ubx (6)
 *   res[0] x (6)   res[1] flag: 0 optimal, 1 H not positive definite on a free block
 *                              (x = NaN), 2 iteration limit (x = the last iterate)
 *
 * A NULL argument is all zeros and a NULL result is not written (CasADi's convention). The
 * flag is informative: the controller's in-graph certificate judges x either way. */
#include <math.h>

#ifndef casadi_real
#define casadi_real double
#endif
#ifndef casadi_int
#define casadi_int long long int
#endif

#define MMSTAB_BOXQP_N 6
#define MMSTAB_BOXQP_MAXIT 60 /* far above the 2n-ish changes a box QP needs in practice */

/* Solve A z = b for the leading m x m block of A (symmetric positive definite; lower triangle
 * read) by an LDL' factorisation: one division per row and no square root. Returns 0, or 1 when
 * a pivot is not positive (or not finite). */
#if defined(__GNUC__)
__attribute__((always_inline)) /* inlined with m = 6 known: loops unrolled */
#endif
static inline int mmstab_boxqp_ldl(casadi_real A[MMSTAB_BOXQP_N][MMSTAB_BOXQP_N], casadi_real* b,
                            int m) {
  enum { N = MMSTAB_BOXQP_N };
  casadi_real LD[N][N], rd[N], s; /* A's lower triangle becomes L; LD = L diag(d) */
  int a, k, j;
  for (a = 0; a < m; ++a) {
    for (k = 0; k < a; ++k) {
      s = A[a][k];
      for (j = 0; j < k; ++j) s -= LD[a][j] * A[k][j];
      LD[a][k] = s;
      A[a][k] = s * rd[k];
    }
    s = A[a][a];
    for (j = 0; j < a; ++j) s -= LD[a][j] * A[a][j];
    if (!(s > 0)) return 1; /* also catches NaN */
    rd[a] = 1 / s;
  }
  for (a = 0; a < m; ++a) /* L y = b */
    for (j = 0; j < a; ++j) b[a] -= A[a][j] * b[j];
  for (a = 0; a < m; ++a) b[a] *= rd[a]; /* D w = y */
  for (a = m - 1; a >= 0; --a) /* L' z = w */
    for (j = a + 1; j < m; ++j) b[a] -= A[j][a] * b[j];
  return 0;
}

/* The unconstrained optimum c: H c = -g. Returns 0, or 1 (H not positive definite). */
static int mmstab_boxqp_free(const casadi_real* H, const casadi_real* g, casadi_real* c) {
  enum { N = MMSTAB_BOXQP_N };
  casadi_real A[N][N];
  int i, j;
  for (i = 0; i < N; ++i) {
    c[i] = -g[i];
    for (j = 0; j <= i; ++j) A[i][j] = H[i + j * N];
  }
  return mmstab_boxqp_ldl(A, c, N); /* N constant here: the compiler unrolls the loops */
}

/* Free coordinates' subspace optimum c (fixed coordinates keep x): H_FF c_F = -(g_F + H_FW x_W).
 * Returns 0, or 1 when H_FF is not positive definite (or not finite). */
static int mmstab_boxqp_subspace(const casadi_real* H, const casadi_real* g, const int* fixed,
                                 const casadi_real* x, casadi_real* c) {
  enum { N = MMSTAB_BOXQP_N };
  casadi_real A[N][N], b[N], s;
  int idx[N], m = 0, a, k, i, j;
  for (i = 0; i < N; ++i)
    if (!fixed[i]) idx[m++] = i;
  for (a = 0; a < m; ++a) {
    i = idx[a];
    s = -g[i];
    for (j = 0; j < N; ++j)
      if (fixed[j]) s -= H[i + j * N] * x[j];
    b[a] = s;
    for (k = 0; k <= a; ++k) A[a][k] = H[i + idx[k] * N];
  }
  if (mmstab_boxqp_ldl(A, b, m)) return 1;
  for (i = 0; i < N; ++i) c[i] = x[i];
  for (a = 0; a < m; ++a) c[idx[a]] = b[a];
  return 0;
}

int mmstab_boxqp(const casadi_real** arg, casadi_real** res, casadi_int* iw, casadi_real* w,
                 int mem) {
  enum { N = MMSTAB_BOXQP_N };
  static const casadi_real zeros[N * N] = {0};
  const casadi_real* H = arg[0] ? arg[0] : zeros;
  const casadi_real* g = arg[1] ? arg[1] : zeros;
  const casadi_real* lb = arg[2] ? arg[2] : zeros;
  const casadi_real* ub = arg[3] ? arg[3] : zeros;
  casadi_real x[N], c[N], alpha, r, worst, tol;
  int fixed[N] = {0}, i, j, it, block, side = 0, drop, flag = 0, any;
  (void)iw;
  (void)w;
  (void)mem;
  if (mmstab_boxqp_free(H, g, c)) {
    flag = 1;
  } else {
    /* the unconstrained optimum, clipped; the clipped coordinates start fixed */
    for (i = 0; i < N; ++i) {
      if (c[i] < lb[i]) {
        x[i] = lb[i];
        fixed[i] = -1;
      } else if (c[i] > ub[i]) {
        x[i] = ub[i];
        fixed[i] = 1;
      } else {
        x[i] = c[i];
      }
    }
    any = 0;
    for (i = 0; i < N; ++i) any |= fixed[i];
    for (it = 0; any; ++it) { /* any: the unconstrained optimum was not feasible */
      if (it == MMSTAB_BOXQP_MAXIT) {
        flag = 2;
        break;
      }
      if (mmstab_boxqp_subspace(H, g, fixed, x, c)) {
        flag = 1;
        break;
      }
      alpha = 1;
      block = -1;
      for (i = 0; i < N; ++i) { /* the first bound met on the way from x to c */
        if (fixed[i]) continue;
        if (c[i] < lb[i]) {
          r = (lb[i] - x[i]) / (c[i] - x[i]);
          if (r < alpha || block < 0) {
            alpha = r < alpha ? r : alpha;
            block = i;
            side = -1;
          }
        } else if (c[i] > ub[i]) {
          r = (ub[i] - x[i]) / (c[i] - x[i]);
          if (r < alpha || block < 0) {
            alpha = r < alpha ? r : alpha;
            block = i;
            side = 1;
          }
        }
      }
      if (block >= 0) { /* blocked: move to the bound, fix that coordinate */
        if (alpha < 0) alpha = 0;
        for (i = 0; i < N; ++i)
          if (!fixed[i]) x[i] += alpha * (c[i] - x[i]);
        x[block] = side < 0 ? lb[block] : ub[block];
        fixed[block] = side;
        continue;
      }
      for (i = 0; i < N; ++i) x[i] = c[i]; /* the subspace optimum */
      worst = 0;
      drop = -1;
      for (i = 0; i < N; ++i) { /* a fixed coordinate whose multiplier has the wrong sign */
        if (!fixed[i]) continue;
        r = g[i];
        tol = fabs(g[i]);
        for (j = 0; j < N; ++j) {
          r += H[i + j * N] * x[j];
          tol += fabs(H[i + j * N] * x[j]);
        }
        /* at a lower bound the gradient must be >= 0, at an upper bound <= 0; round-off in
           the gradient (relative 1e-13 of its terms) is not a reason to move */
        r = fixed[i] < 0 ? -r : r;
        if (r > 1e-13 * tol && r / H[i + i * N] > worst) {
          worst = r / H[i + i * N];
          drop = i;
        }
      }
      if (drop < 0) break; /* optimal */
      fixed[drop] = 0;
    }
  }
  if (flag == 1)
    for (i = 0; i < N; ++i) x[i] = NAN;
  if (res[0])
    for (i = 0; i < N; ++i) res[0][i] = x[i];
  if (res[1]) res[1][0] = (casadi_real)flag;
  return 0;
}

/* The External interface CasADi reads (casadi.external): sizes, sparsities, names. */
static const casadi_int mmstab_boxqp_sp_h[] = {6,  6,  0,  6,  12, 18, 24, 30, 36, 0, 1, 2,
                                                3,  4,  5,  0,  1,  2,  3,  4,  5,  0, 1, 2,
                                                3,  4,  5,  0,  1,  2,  3,  4,  5,  0, 1, 2,
                                                3,  4,  5,  0,  1,  2,  3,  4,  5};
static const casadi_int mmstab_boxqp_sp_v[] = {6, 1, 0, 6, 0, 1, 2, 3, 4, 5};
static const casadi_int mmstab_boxqp_sp_s[] = {1, 1, 0, 1, 0};

casadi_int mmstab_boxqp_n_in(void) { return 4; }
casadi_int mmstab_boxqp_n_out(void) { return 2; }

const casadi_int* mmstab_boxqp_sparsity_in(casadi_int i) {
  return i == 0 ? mmstab_boxqp_sp_h : (i < 4 ? mmstab_boxqp_sp_v : 0);
}

const casadi_int* mmstab_boxqp_sparsity_out(casadi_int i) {
  return i == 0 ? mmstab_boxqp_sp_v : (i == 1 ? mmstab_boxqp_sp_s : 0);
}

const char* mmstab_boxqp_name_in(casadi_int i) {
  static const char* names[] = {"h", "g", "lbx", "ubx"};
  return i >= 0 && i < 4 ? names[i] : 0;
}

const char* mmstab_boxqp_name_out(casadi_int i) {
  static const char* names[] = {"x", "flag"};
  return i >= 0 && i < 2 ? names[i] : 0;
}
