/* One control period of the generated plant (mmstab/control/plant.py, exported with the step as
 * controller_plant): the robot's motion in the example loops, written once, in Python.
 *
 * Include after controller_step.h, with NX / NQ (state and joint sizes) and the work arrays
 * arg, res, iw, w declared and large enough for controller_plant. On a robot this is replaced
 * by commanding qdot and reading the encoders and the base pose estimate. */
#ifndef MMSTAB_PLANT_STEP_H
#define MMSTAB_PLANT_STEP_H

/* state <- plant(state, qdot, dt); 0 on success. */
static int advance(double state[NX], const double qdot[NQ], double dt) {
  double next[NX];
  int i;
  arg[0] = state;
  arg[1] = qdot;
  arg[2] = &dt;
  res[0] = next;
  if (controller_plant(arg, res, iw, w, 0) != 0) return 1;
  for (i = 0; i < NX; ++i) state[i] = next[i];
  return 0;
}

#endif /* MMSTAB_PLANT_STEP_H */
