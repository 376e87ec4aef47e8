"""The whole robot in MuJoCo: model from the YAML, controller in the loop, verdict checks.

:mod:`~mmstab.physics.robot_model` generates the robot's MJCF, :mod:`~mmstab.physics.robot_sim`
simulates it, :mod:`~mmstab.physics.closed_loop` runs the controller on it,
:mod:`~mmstab.physics.edge_cases` / :mod:`~mmstab.physics.verdict_sim` hold mmstab's tip and
slide verdicts against it. The heightfield drops of the base alone:

:mod:`~mmstab.physics.mujoco_drop` builds the MuJoCo model and drops the robot;
:mod:`~mmstab.physics.compare` compares a predictor with the drops;
:mod:`~mmstab.physics.plane` is the analytic predictor for planes.
:mod:`~mmstab.physics.robot_model` generates the whole robot (tracks, arm servos, payload)
as MJCF and :mod:`~mmstab.physics.robot_sim` simulates it (``docs/physics.md``). MuJoCo is
an optional dependency (the ``validate`` extra): import those modules only where needed.
"""

from mmstab.physics.plane import Prediction, Predictor, plane_predictor, roll_pitch

__all__ = ["Prediction", "Predictor", "plane_predictor", "roll_pitch"]
