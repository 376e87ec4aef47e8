/* mmstab step timing: the generated controller step in a pure C loop.
 *
 * Runs the closed loop of a run file once (as main.c does), recording the state at every
 * step, then times controller_step on those recorded inputs: batches of BATCH consecutive
 * steps timed with clock_gettime (median over all batches of all passes), and every call
 * timed alone (its p50, p99 and maximum, which include the clock's own cost).
 *
 * The time split (same batches, same recorded inputs): controller_jacobian (the task Jacobian
 * J alone), controller_qp_data (J and the QP's H, g, bounds and pre-solve checks: what the step
 * computes before the solver) and, when the step uses mmstab's box QP solver, mmstab_boxqp on
 * the recorded QPs. The rest of the step is glue: the guard, the certificate, CasADi's copies.
 *
 * Usage: mmstab_bench RUN_FILE [PASSES]
 * Prints one JSON object on stdout (times in microseconds).
 */
#define _POSIX_C_SOURCE 199309L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "controller_layout.h"
#include "controller_step.h"
#include "run_file.h"

enum {
  NX = MMSTAB_N_STATE,
  NQ = MMSTAB_N_JOINTS,
  NREF = MMSTAB_N_REFERENCE,
  NP = MMSTAB_N_PARAMS,
  NXI = MMSTAB_N_TASK,
  NQP = NQ * NQ + 3 * NQ, /* H, g, lbx, ubx */
  BATCH = 100
};

#define MAX2(a, b) ((a) > (b) ? (a) : (b))
#define MAX4(a, b, c, d) MAX2(MAX2(a, b), MAX2(c, d))
#define SZ(K)                                                                              \
  (MAX4(controller_step_SZ_##K, controller_plant_SZ_##K, controller_qp_data_SZ_##K,        \
        controller_jacobian_SZ_##K) +                                                      \
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

/* mmstab's box QP solver: present (appended to controller_step.c) with the box plugin only */
extern int mmstab_boxqp(const casadi_real** arg, casadi_real** res, casadi_int* iw, casadi_real* w,
                        int mem) __attribute__((weak));

static double seconds(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static int compare(const void* a, const void* b) {
  const double x = *(const double*)a, y = *(const double*)b;
  return (x > y) - (x < y);
}

/* q-quantile (0..1) of n sorted numbers (nearest rank). */
static double quantile(const double* sorted, long n, double q) {
  long i = (long)ceil(q * (double)n) - 1;
  return sorted[i < 0 ? 0 : (i >= n ? n - 1 : i)];
}

static int step(const double* state, const double* ref, const double* params, double* qdot,
                double* status, int mem) {
  double objective;
  arg[0] = state;
  arg[1] = ref;
  arg[2] = params;
  res[0] = qdot;
  res[1] = status;
  res[2] = &objective;
  return controller_step(arg, res, iw, w, mem);
}

int main(int argc, char* argv[]) {
  RunFile run;
  casadi_int n_arg, n_res, n_iw, n_w;
  double *states, *batches, *singles, *qps, *parts, state[NX], qdot[NQ], status, t0, t1, loop_s;
  long n, n_batches, b, p, passes = argc > 2 ? atol(argv[2]) : 5, nb = 0, failures = 0;
  long nparts[3] = {0, 0, 0}, part;
  /* where controller_qp_data's outputs go in one buffer: H, g, lbx, ubx, xi_dot_des,
     q_dot_posture, cost0, status */
  static const int qp_offsets[8] = {0, NQ * NQ, NQ * NQ + NQ, NQ * NQ + 2 * NQ, NQP, NQP + NQ,
                                    NQP + 2 * NQ, NQP + 2 * NQ + 1};
  long k;
  int i, mem;
  if (argc < 2 || passes < 1) {
    fprintf(stderr, "usage: %s RUN_FILE [PASSES]\n", argv[0]);
    return 2;
  }
  if (controller_step_work(&n_arg, &n_res, &n_iw, &n_w) || n_arg > SZ_ARG || n_res > SZ_RES ||
      n_iw > SZ_IW || n_w > SZ_W || controller_plant_work(&n_arg, &n_res, &n_iw, &n_w) ||
      n_arg > SZ_ARG || n_res > SZ_RES || n_iw > SZ_IW || n_w > SZ_W ||
      run_file_read(argv[1], &run, NX, NREF, NP))
    return 1;
  n = (long)run.steps;
  n_batches = n / BATCH;
  states = (double*)malloc((size_t)n * NX * sizeof(double)); /* all allocation happens here */
  batches = (double*)malloc((size_t)(passes * n_batches + 1) * sizeof(double));
  singles = (double*)malloc((size_t)n * sizeof(double));
  qps = (double*)malloc((size_t)n * NQP * sizeof(double));
  parts = (double*)malloc((size_t)(3 * passes * n_batches + 1) * sizeof(double));
  if (!states || !batches || !singles || !qps || !parts || n_batches < 1) return 1;
  mem = controller_step_checkout();

  /* the closed loop once, recording each step's input state (also the whole-run time) */
  for (i = 0; i < NX; ++i) state[i] = run.state0[i];
  t0 = seconds();
  for (k = 0; k < n; ++k) {
    for (i = 0; i < NX; ++i) states[k * NX + i] = state[i];
    if (step(state, run.reference + k * NREF, run.params, qdot, &status, mem) || status != 0) {
      for (i = 0; i < NQ; ++i) qdot[i] = 0;
      ++failures;
    }
    if (advance(state, qdot, run.dt)) return 1;
  }
  loop_s = seconds() - t0;

  /* batches of BATCH consecutive recorded steps */
  for (p = 0; p < passes; ++p) {
    for (b = 0; b < n_batches; ++b) {
      t0 = seconds();
      for (k = b * BATCH; k < (b + 1) * BATCH; ++k)
        step(states + k * NX, run.reference + k * NREF, run.params, qdot, &status, mem);
      t1 = seconds();
      batches[nb++] = (t1 - t0) / BATCH;
    }
  }
  /* the split: the same batches, each part on its own */
  for (k = 0; k < n; ++k) { /* the recorded QPs, for the solver alone */
    const double* ref = run.reference + k * NREF;
    double c0, st, xd[NQ], qp_post[NQ];
    arg[0] = states + k * NX;
    arg[1] = ref;
    arg[2] = run.params;
    res[0] = qps + k * NQP;
    res[1] = qps + k * NQP + NQ * NQ;
    res[2] = qps + k * NQP + NQ * NQ + NQ;
    res[3] = qps + k * NQP + NQ * NQ + 2 * NQ;
    res[4] = xd;
    res[5] = qp_post;
    res[6] = &c0;
    res[7] = &st;
    if (controller_qp_data(arg, res, iw, w, 0)) return 1;
  }
  for (part = 0; part < 3; ++part) {
    if (part == 2 && !mmstab_boxqp) break;
    nparts[part] = 0;
    for (p = 0; p < passes; ++p) {
      for (b = 0; b < n_batches; ++b) {
        t0 = seconds();
        for (k = b * BATCH; k < (b + 1) * BATCH; ++k) {
          const double* qp = qps + k * NQP;
          double J[NQ * NXI], out[NQP + NQ + NQ + 2], flag;
          if (part == 0) { /* the task Jacobian */
            arg[0] = states + k * NX;
            arg[1] = run.reference + k * NREF + MMSTAB_REF_GROUND;
            res[0] = J;
            controller_jacobian(arg, res, iw, w, 0);
          } else if (part == 1) { /* everything the step computes before the solver */
            arg[0] = states + k * NX;
            arg[1] = run.reference + k * NREF;
            arg[2] = run.params;
            for (i = 0; i < 8; ++i) res[i] = out + qp_offsets[i];
            controller_qp_data(arg, res, iw, w, 0);
          } else { /* the solver alone on the recorded QP */
            arg[0] = qp;
            arg[1] = qp + NQ * NQ;
            arg[2] = qp + NQ * NQ + NQ;
            arg[3] = qp + NQ * NQ + 2 * NQ;
            res[0] = qdot;
            res[1] = &flag;
            mmstab_boxqp(arg, res, iw, w, 0);
          }
        }
        t1 = seconds();
        parts[part * passes * n_batches + nparts[part]++] = (t1 - t0) / BATCH;
      }
    }
    qsort(parts + part * passes * n_batches, (size_t)nparts[part], sizeof(double), compare);
  }
  /* every call alone */
  for (k = 0; k < n; ++k) {
    t0 = seconds();
    step(states + k * NX, run.reference + k * NREF, run.params, qdot, &status, mem);
    singles[k] = seconds() - t0;
  }
  controller_step_release(mem);
  qsort(batches, (size_t)nb, sizeof(double), compare);
  qsort(singles, (size_t)n, sizeof(double), compare);
  printf("{\"steps\": %ld, \"passes\": %ld, \"batch\": %d, \"batches\": %ld, "
         "\"median_us\": %.4f, \"p10_us\": %.4f, \"p90_us\": %.4f, "
         "\"single_p50_us\": %.4f, \"single_p99_us\": %.4f, \"single_max_us\": %.4f, "
         "\"loop_s\": %.6f, \"failures\": %ld, "
         "\"split_us\": {\"jacobian\": %.4f, \"qp_data\": %.4f, \"solver\": %.4f}}\n",
         n, passes, BATCH, nb, 1e6 * quantile(batches, nb, 0.5), 1e6 * quantile(batches, nb, 0.1),
         1e6 * quantile(batches, nb, 0.9), 1e6 * quantile(singles, n, 0.5),
         1e6 * quantile(singles, n, 0.99), 1e6 * singles[n - 1], loop_s, failures,
         1e6 * quantile(parts, nparts[0], 0.5),
         1e6 * quantile(parts + passes * n_batches, nparts[1], 0.5),
         nparts[2] ? 1e6 * quantile(parts + 2 * passes * n_batches, nparts[2], 0.5) : -1.0);
  free(states);
  free(batches);
  free(singles);
  free(qps);
  free(parts);
  run_file_free(&run);
  return 0;
}
