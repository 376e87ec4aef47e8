/* Motion of the robot over one control period (the simulation side of the example loop).
 *
 * Exact motion over dt at constant joint speeds, the same formula as TaskModel.f_integrate
 * (mmstab/controller.py): tracks v = r (w_l + w_r) / 2, w = r (w_r - w_l) / b; the base
 * drives an arc, i.e. a chord of length v dt sin(a)/a (a = w dt / 2) along the mid-heading;
 * the joints move by qdot dt. On a robot this is replaced by commanding qdot and reading the
 * encoders and the base pose estimate.
 */
#ifndef MMSTAB_MOTION_H
#define MMSTAB_MOTION_H

#include <math.h>

#include "controller_layout.h" /* MMSTAB_N_*: generated with the controller */

/* state s = [x, y, heading, theta_l, theta_r, theta_0..theta_3] (MMSTAB_N_STATE), qdot
 * (MMSTAB_N_JOINTS) [rad/s], dt [s], track = [sprocket radius r [m], track separation b [m],
 * |a| under which sin(a)/a uses its series 1 - a^2/6]. */
static void integrate(double s[MMSTAB_N_STATE], const double qdot[MMSTAB_N_JOINTS], double dt,
                      const double track[MMSTAB_N_TRACK]) {
  const double r = track[0], b = track[1], series_below = track[2];
  const double v = r * (qdot[0] + qdot[1]) / 2, omega = r * (qdot[1] - qdot[0]) / b;
  const double half = omega * dt / 2;
  const double sinc = fabs(half) < series_below ? 1 - half * half / 6 : sin(half) / half;
  const double chord = v * dt * sinc, mid = s[2] + half;
  int i;
  s[0] += chord * cos(mid);
  s[1] += chord * sin(mid);
  s[2] += omega * dt;
  for (i = 0; i < MMSTAB_N_JOINTS; ++i) /* the joints are the state's last entries */
    s[MMSTAB_N_STATE - MMSTAB_N_JOINTS + i] += qdot[i] * dt;
}

#endif /* MMSTAB_MOTION_H */
