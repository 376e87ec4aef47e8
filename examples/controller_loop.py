"""The QP controller in a robot's own loop: targets on its tasks, one step per period.

Here the "robot" is the controller's own plant model (the tracks' kinematics and the arm's
joints integrated over dt); on a robot, read the state from its sensors instead.
Run from the repository's root: ``python examples/controller_loop.py``.
"""

import numpy as np

import mmstab

robot = mmstab.load_robot("problems/robots/cameleon.yaml")
controller = mmstab.Controller(robot)  # the default settings: dt 1 ms, arm CoM in the body frame
d = controller.settings.base_offset  # the base's control point is d ahead of the body origin
q_goal = np.array([0.5, 0.6, 1.6, 0.0])  # the arm joints [rad]
com_goal = robot.arm_com(q_goal)  # its CoM in the body frame [m]
controller.tasks["base_point"].set_target([d + 0.3, 0.0, 0.0])  # (x, y, heading) [m, m, rad]
controller.tasks["arm_com_body"].set_target(com_goal)
controller.tasks["posture"].set_target(q_goal)
state = np.concatenate([[0.0, 0.0, 0.0, 0.0, 0.0], robot.stowed])  # pose, sprockets, arm
for _ in range(3000):  # 3 s
    command = controller.step(base_pose=state[:3], arm=state[5:], tracks=state[3:5])
    qdot = np.concatenate([command.tracks, command.arm])  # sprockets, arm [rad/s]
    state = controller.qp.model.integrate(state, qdot, controller.settings.dt)
com_error = np.linalg.norm(robot.arm_com(state[5:]) - com_goal)
print(f"base at ({state[0]:.3f}, {state[1]:.3f}) m, heading {state[2]:.3f} rad")
print(f"arm CoM error {com_error * 1e3:.2f} mm after 3 s; last status {command.status.name}")
assert command.success and com_error < 1e-3 and abs(state[0] - 0.3) < 1e-3
