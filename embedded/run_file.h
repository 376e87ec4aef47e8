/* Reading a run file: the inputs of one closed-loop run, written by Python
 * (mmstab.runs.rollout.write_run_file). On a robot these would come from the planner and the
 * robot's configuration instead; the controller itself needs none of this.
 *
 * Layout (little-endian):
 *   char    magic[8] = "MMSTRUN2"
 *   int64   steps, n_state, n_reference, n_params
 *   float64 dt                                control period = integration step [s]
 *   float64 params[n_params]                  the controller's packed run-time parameters
 *   float64 state0[n_state]                   initial state
 *   float64 reference[steps + 1][n_reference] [xi_des, xi_dot_ref, q_ref, q_dot_ref, ground]
 *                                             at t_k = k dt (layout: controller_layout.h)
 */
#ifndef MMSTAB_RUN_FILE_H
#define MMSTAB_RUN_FILE_H

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
  int64_t steps;
  double dt;
  const double* params;
  const double* state0;
  const double* reference; /* row k: [xi_des, xi_dot_ref, q_ref, q_dot_ref, ground] at t_k */
  double* data;            /* the one allocation holding all of the above */
} RunFile;

/* Read `path`, checking the sizes against the ones expected; returns 0 on success. */
static int run_file_read(const char* path, RunFile* run, int64_t n_state, int64_t n_reference,
                         int64_t n_params) {
  char magic[8];
  int64_t sizes[4];
  size_t n_data;
  FILE* f = fopen(path, "rb");
  if (!f) {
    fprintf(stderr, "cannot open run file %s\n", path);
    return 1;
  }
  if (fread(magic, 1, 8, f) != 8 || memcmp(magic, "MMSTRUN2", 8) != 0 ||
      fread(sizes, sizeof(int64_t), 4, f) != 4) {
    fprintf(stderr, "%s: not a run file\n", path);
    fclose(f);
    return 1;
  }
  if (sizes[0] < 1 || sizes[1] != n_state || sizes[2] != n_reference || sizes[3] != n_params) {
    fprintf(stderr, "%s: sizes %lld %lld %lld do not match the controller (%lld %lld %lld)\n",
            path, (long long)sizes[1], (long long)sizes[2], (long long)sizes[3],
            (long long)n_state, (long long)n_reference, (long long)n_params);
    fclose(f);
    return 1;
  }
  run->steps = sizes[0];
  n_data = (size_t)(1 + n_params + n_state + (sizes[0] + 1) * n_reference);
  run->data = (double*)malloc(n_data * sizeof(double));
  if (!run->data || fread(run->data, sizeof(double), n_data, f) != n_data) {
    fprintf(stderr, "%s: truncated run file\n", path);
    free(run->data);
    fclose(f);
    return 1;
  }
  fclose(f);
  run->dt = run->data[0];
  run->params = run->data + 1;
  run->state0 = run->params + n_params;
  run->reference = run->state0 + n_state;
  return 0;
}

static void run_file_free(RunFile* run) {
  free(run->data);
  run->data = 0;
}

#endif /* MMSTAB_RUN_FILE_H */
