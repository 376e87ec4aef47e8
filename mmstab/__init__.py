"""mmstab: stability-aware planning and control of tracked mobile manipulators on slopes.

Pipeline (one module per stage; ``docs/architecture.md``): ``config``/``schema`` (inputs) ->
``robot``/``kinematics`` and ``terrain`` (the ground, one interface) -> ``problem`` ->
``stability`` (force-angle) -> ``workspace`` -> ``planner`` (CMA-ES) -> ``tasks``/``limits``/
``controller`` (QP diff-IK with a posture task) -> ``codegen`` -> ``tracking``/``app``/
``experiments`` -> ``cli``.
"""

__version__ = "0.1.0"
