"""Independent checks of the terrain model: MuJoCo heightfield drops vs a predictor.

:mod:`~mmstab.physics.mujoco_drop` builds the MuJoCo model and drops the robot;
:mod:`~mmstab.physics.compare` compares a predictor with the drops;
:mod:`~mmstab.physics.plane` is the analytic predictor for planes.
:mod:`~mmstab.physics.robot_model` generates the whole robot (tracks, arm servos, payload)
as MJCF and :mod:`~mmstab.physics.robot_sim` simulates it (``docs/physics.md``). MuJoCo is
an optional dependency (the ``validate`` extra): import those modules only where needed.
"""

from mmstab.physics.plane import Prediction, Predictor, plane_predictor, roll_pitch

__all__ = ["Prediction", "Predictor", "plane_predictor", "roll_pitch"]
