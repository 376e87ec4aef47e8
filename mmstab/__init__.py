"""mmstab: stability-aware planning and control of tracked mobile manipulators on slopes.

Pipeline (one module per stage): ``robot``/``problem`` (validated inputs) ->
``kinematics`` (CasADi + NumPy) -> ``stability`` (force-angle) -> ``workspace`` ->
``planner`` (CMA-ES) -> ``posture``/``approach`` (the arm references, collision-checked) ->
``tasks``/``controller`` (QP diff-IK with a posture task) -> ``codegen``.
"""

__version__ = "0.1.0"
