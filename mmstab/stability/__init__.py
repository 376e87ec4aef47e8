"""Stability: the force-angle tip-over measure, static and dynamic, and how a base stands.

- ``static``: the force-angle measure (NumPy, batched, CasADi) and the μ trio along poses.
- ``dynamic``: the dynamic force-angle measure with external wrenches.
- ``slip``: the slip limit, the friction cone of a rigid robot on its support.
- ``stance``: how the robot stands at a pose on any terrain (``mmstab rest``), stability maps.
"""
