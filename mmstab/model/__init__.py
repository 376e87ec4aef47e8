"""The robot model: description, arm kinematics and CoM, payload, self-collision, URDF.

- ``parts``: frames and the description's parts (boxes, capsules, arm links, tracks, flippers).
- ``robot``: :class:`Robot`, loaded from YAML and checked once.
- ``kinematics``: the arm's link frames and CoM, CasADi and batched NumPy, from its links.
- ``payload``, ``collision`` (FCL), ``urdf`` (export), ``urdf_arm`` (an arm read from URDF),
  ``enclosing`` (the least capsule holding points).
"""
