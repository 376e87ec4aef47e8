/* mmstab embedded example: the tracking controller's closed loop in plain C.
 *
 * The template for putting the controller on a robot. The generated controller_step.c/.h
 * (`mmstab codegen PROBLEM.yaml -o DIR`) is the whole controller: task Jacobian, QP, solver
 * and answer check, as one C function with CasADi's calling convention
 *
 *   controller_step(arg, res, iw, w, mem)
 *     arg[0] state (9)       [x, y, heading] of the base in the slope frame, then the joints
 *                            [theta_l, theta_r, theta_0..theta_3]   [m, m, rad, rad...]
 *     arg[1] reference (23)  [xi_des (6), xi_dot_ref (6), q_ref (4), q_dot_ref (4),
 *                            ground (3)]: base point, heading, arm CoM, the arm posture for
 *                            the posture task, and the local ground (z, roll, pitch) of the
 *                            reference pose (zero on the ramp)
 *     arg[2] params (42)     gains, weights, posture gains and weights, dt, joint limits
 *     res[0] qdot (6)        joint speeds to command [rad/s] (zero = hold still on failure)
 *     res[1] status          0 ok, 1 non-finite input, 2 infeasible bounds, 3 solver failed
 *     res[2] objective       the QP's cost at qdot
 *
 * The sizes and layouts (MMSTAB_N_*, MMSTAB_REF_*) and the certificate's tolerance
 * (MMSTAB_KKT_TOL) come from the generated controller_layout.h; controller_qp_data (exported
 * with the step) gives the QP of a step (H, g, bounds) for the KKT check.
 *
 * Real-time rules followed here: the work arrays are allocated once, statically, sized from
 * the generated header and checked at start against controller_step_work(); nothing is
 * allocated inside the loop (with the qrqp plugin the generated code references no allocator
 * at all). On a robot, replace the run file by the planner's reference stream and
 * advance() (the generated plant) by reading the encoders; keep the rest.
 *
 * Usage: mmstab_loop RUN_FILE   (written by `mmstab codegen PROBLEM.yaml -o DIR --example`)
 * Prints the initial and final tracking errors, the failures, the KKT check of every answer
 * (line "kkt:", see kkt_check), the loop's wall time, and the final state and error at full
 * precision (lines "final_state:" and "final_error:").
 */
#define _POSIX_C_SOURCE 199309L
#include <math.h>
#include <stdio.h>
#include <time.h>

#include "controller_layout.h"
#include "controller_step.h"
#include "run_file.h"

enum {
  NX = MMSTAB_N_STATE,
  NQ = MMSTAB_N_JOINTS,
  NXI = MMSTAB_N_TASK,
  NARM = MMSTAB_N_ARM,
  NREF = MMSTAB_N_REFERENCE,
  NP = MMSTAB_N_PARAMS
};

/* Work arrays: the largest of the three generated functions used here, plus one (no 0-size). */
#define MAX2(a, b) ((a) > (b) ? (a) : (b))
#define MAX4(a, b, c, d) MAX2(MAX2(a, b), MAX2(c, d))
#define SZ(K)                                                                              \
  (MAX4(controller_step_SZ_##K, controller_task_SZ_##K, controller_plant_SZ_##K,           \
        controller_qp_data_SZ_##K) +                                                       \
   1)
#define SZ_ARG SZ(ARG)
#define SZ_RES SZ(RES)
#define SZ_IW SZ(IW)
#define SZ_W SZ(W)
static const casadi_real* arg[SZ_ARG];
static casadi_real* res[SZ_RES];
static casadi_int iw[SZ_IW];
static casadi_real w[SZ_W];

#include "plant_step.h" /* advance(): the generated plant, after the work arrays */

typedef int (*WorkFn)(casadi_int*, casadi_int*, casadi_int*, casadi_int*);

/* The generated function's own work sizes must fit the static arrays. */
static int check_work(WorkFn work, const char* name) {
  casadi_int n_arg, n_res, n_iw, n_w;
  if (work(&n_arg, &n_res, &n_iw, &n_w) != 0 || n_arg > SZ_ARG || n_res > SZ_RES ||
      n_iw > SZ_IW || n_w > SZ_W) {
    fprintf(stderr, "%s: work arrays too small for the generated code\n", name);
    return 1;
  }
  return 0;
}

/* Input i of a generated function must be a dense column of n numbers. */
static int check_input(const casadi_int* sparsity, casadi_int n, const char* what) {
  if (sparsity[0] != n || sparsity[1] != 1) {
    fprintf(stderr, "generated controller: %s has %lld rows, expected %lld\n", what,
            (long long)sparsity[0], (long long)n);
    return 1;
  }
  return 0;
}

/* Tracking error xi_des - xi(state), heading wrapped to (-pi, pi]; 0 on success. */
static int tracking_error(const double state[NX], const double ref[NREF], double e[NXI]) {
  double xi[NXI];
  int i;
  arg[0] = state;
  arg[1] = ref + MMSTAB_REF_GROUND; /* the local ground the reference was placed with */
  res[0] = xi;
  if (controller_task(arg, res, iw, w, 0) != 0) return 1;
  for (i = 0; i < NXI; ++i) e[i] = ref[MMSTAB_REF_XI_DES + i] - xi[i];
  e[2] = atan2(sin(e[2]), cos(e[2]));
  return 0;
}

/* Largest |q_ref - q_arm| over the arm joints [rad]. */
static double posture_error(const double state[NX], const double ref[NREF]) {
  double worst = 0;
  int i;
  for (i = 0; i < NARM; ++i) {
    const double d = fabs(ref[MMSTAB_REF_Q_REF + i] - state[NX - NARM + i]);
    worst = d > worst ? d : worst;
  }
  return worst;
}

/* The KKT conditions of one step's QP at its answer, checked here, apart from the step's own
 * certificate: min 1/2 q'Hq + g'q s.t. lbx <= q <= ubx, with the gradient r = Hq + g scaled by
 * 1/H_ii (so that every residual is in rad/s, like MMSTAB_KKT_TOL):
 *   primal feasibility  lbx - tol <= q <= ubx + tol
 *   stationarity        |r_i| <= tol where q_i is off both bounds by more than tol
 *   dual feasibility    the bound multiplier has the right sign: r_i >= -tol at a lower bound,
 *                       r_i <= tol at an upper bound
 *   complementarity     min(max(r_i, 0), q_i - lbx_i) <= tol and min(max(-r_i, 0), ubx_i - q_i)
 *                       <= tol (a positive multiplier only on an active bound) */
typedef struct {
  double primal, stationarity, dual, complementarity; /* largest residuals [rad/s] */
  int64_t checked, failed;                             /* steps checked, steps over tol */
} Kkt;

static double max2(double a, double b) { return a > b ? a : b; }
static double min2(double a, double b) { return a < b ? a : b; }

/* Check step's answer qdot at (state, reference, params); 0 on success (nonzero: no QP data). */
static int kkt_check(Kkt* kkt, const double* state, const double* ref, const double* params,
                     const double qdot[NQ]) {
  double H[NQ * NQ], g[NQ], lb[NQ], ub[NQ], cost0, status, r, p = 0, s = 0, d = 0, c = 0;
  const double tol = MMSTAB_KKT_TOL;
  int i, j;
  arg[0] = state;
  arg[1] = ref;
  arg[2] = params;
  res[0] = H;
  res[1] = g;
  res[2] = lb;
  res[3] = ub;
  res[4] = 0;
  res[5] = 0;
  res[6] = &cost0;
  res[7] = &status;
  if (controller_qp_data(arg, res, iw, w, 0) != 0) return 1;
  for (i = 0; i < NQ; ++i) {
    r = g[i];
    for (j = 0; j < NQ; ++j) r += H[i + j * NQ] * qdot[j];
    r /= H[i + i * NQ];
    p = max2(p, max2(lb[i] - qdot[i], qdot[i] - ub[i]));
    if (qdot[i] - lb[i] > tol && ub[i] - qdot[i] > tol) s = max2(s, fabs(r));
    if (qdot[i] - lb[i] <= tol) d = max2(d, -r);
    if (ub[i] - qdot[i] <= tol) d = max2(d, r);
    c = max2(c, min2(max2(r, 0), qdot[i] - lb[i]));
    c = max2(c, min2(max2(-r, 0), ub[i] - qdot[i]));
  }
  kkt->primal = max2(kkt->primal, p);
  kkt->stationarity = max2(kkt->stationarity, s);
  kkt->dual = max2(kkt->dual, d);
  kkt->complementarity = max2(kkt->complementarity, c);
  kkt->checked += 1;
  /* written with ! so that a NaN residual counts as a failure */
  kkt->failed += !(p <= tol && s <= tol && d <= tol && c <= tol);
  return 0;
}

static void print_errors(const char* when, const double e[NXI], double posture) {
  printf("%s tracking error: base point %.3e m, heading %.3e rad, arm CoM %.3e m, "
         "arm posture %.3e rad\n",
         when, hypot(e[0], e[1]), fabs(e[2]), sqrt(e[3] * e[3] + e[4] * e[4] + e[5] * e[5]),
         posture);
}

static double seconds(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

int main(int argc, char* argv[]) {
  RunFile run;
  double state[NX], qdot[NQ], status, objective, e0[NXI], e[NXI], t0, t1;
  int64_t k, failures = 0;
  Kkt kkt = {0, 0, 0, 0, 0, 0};
  int i, mem;
  if (argc != 2) {
    fprintf(stderr, "usage: %s RUN_FILE\n", argv[0]);
    return 2;
  }
  if (check_work(controller_step_work, "controller_step") ||
      check_work(controller_task_work, "controller_task") ||
      check_work(controller_plant_work, "controller_plant") ||
      check_input(controller_step_sparsity_in(0), NX, "state") ||
      check_input(controller_step_sparsity_in(1), NREF, "reference") ||
      check_input(controller_step_sparsity_in(2), NP, "params") ||
      check_work(controller_qp_data_work, "controller_qp_data") ||
      run_file_read(argv[1], &run, NX, NREF, NP))
    return 1;
  for (i = 0; i < NX; ++i) state[i] = run.state0[i];
  if (tracking_error(state, run.reference, e0)) return 1;

  mem = controller_step_checkout(); /* a memory slot of the solver (one per thread) */
  if (mem < 0) return 1;
  t0 = seconds();
  for (k = 0; k < run.steps; ++k) {
    arg[0] = state;                       /* the arguments are set before every call: */
    arg[1] = run.reference + k * NREF;    /* tracking_error() and the solver's own calls */
    arg[2] = run.params;                  /* use the same arrays as scratch */
    res[0] = qdot;
    res[1] = &status;
    res[2] = &objective;
    if (controller_step(arg, res, iw, w, mem) != 0 || status != 0) {
      for (i = 0; i < NQ; ++i) qdot[i] = 0; /* the safe action: hold still */
      ++failures;
    } else if (kkt_check(&kkt, state, run.reference + k * NREF, run.params, qdot)) {
      return 1; /* every answer checked against its QP's KKT conditions */
    }
    if (advance(state, qdot, run.dt)) return 1; /* on a robot: command qdot, read encoders */
  }
  t1 = seconds();
  controller_step_release(mem);

  if (tracking_error(state, run.reference + run.steps * NREF, e)) return 1;
  printf("closed loop: %lld steps of %g s (%g s simulated)\n", (long long)run.steps, run.dt,
         (double)run.steps * run.dt);
  print_errors("initial", e0, posture_error(run.state0, run.reference));
  print_errors("final  ", e, posture_error(state, run.reference + run.steps * NREF));
  printf("failures: %lld of %lld steps held still\n", (long long)failures, (long long)run.steps);
  printf("kkt: %lld of %lld answers checked, %lld over tolerance %g rad/s; largest residuals "
         "[rad/s]: primal %.3e, stationarity %.3e, dual %.3e, complementarity %.3e\n",
         (long long)kkt.checked, (long long)(run.steps - failures), (long long)kkt.failed,
         MMSTAB_KKT_TOL, kkt.primal, kkt.stationarity, kkt.dual, kkt.complementarity);
  printf("loop wall time: %.4f s (%.3f us per step: controller, KKT check and integration)\n",
         t1 - t0, 1e6 * (t1 - t0) / (double)run.steps);
  printf("final_state:");
  for (i = 0; i < NX; ++i) printf(" %.17g", state[i]);
  printf("\nfinal_error:");
  for (i = 0; i < NXI; ++i) printf(" %.17g", e[i]);
  printf("\n");
  run_file_free(&run);
  return 0;
}
