/* mmstab step timing: the generated controller step in a pure C loop.
 *
 * Runs the closed loop of a run file once (as main.c does), recording the state at every
 * step, then times controller_step on those recorded inputs: batches of BATCH consecutive
 * steps timed with clock_gettime (median over all batches of all passes), and every call
 * timed alone (its p50, p99 and maximum, which include the clock's own cost).
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
  BATCH = 100
};

#define MAX2(a, b) ((a) > (b) ? (a) : (b))
#define SZ_ARG (MAX2(controller_step_SZ_ARG, controller_plant_SZ_ARG) + 1)
#define SZ_RES (MAX2(controller_step_SZ_RES, controller_plant_SZ_RES) + 1)
#define SZ_IW (MAX2(controller_step_SZ_IW, controller_plant_SZ_IW) + 1)
#define SZ_W (MAX2(controller_step_SZ_W, controller_plant_SZ_W) + 1)
static const casadi_real* arg[SZ_ARG];
static casadi_real* res[SZ_RES];
static casadi_int iw[SZ_IW];
static casadi_real w[SZ_W];

#include "plant_step.h" /* advance(): the generated plant, after the work arrays */

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
  double *states, *batches, *singles, state[NX], qdot[NQ], status, t0, t1, loop_s;
  long n, n_batches, b, p, passes = argc > 2 ? atol(argv[2]) : 5, nb = 0, failures = 0;
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
  if (!states || !batches || !singles || n_batches < 1) return 1;
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
         "\"loop_s\": %.6f, \"failures\": %ld}\n",
         n, passes, BATCH, nb, 1e6 * quantile(batches, nb, 0.5), 1e6 * quantile(batches, nb, 0.1),
         1e6 * quantile(batches, nb, 0.9), 1e6 * quantile(singles, n, 0.5),
         1e6 * quantile(singles, n, 0.99), 1e6 * singles[n - 1], loop_s, failures);
  free(states);
  free(batches);
  free(singles);
  run_file_free(&run);
  return 0;
}
