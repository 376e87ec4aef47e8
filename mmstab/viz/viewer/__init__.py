"""An interactive 3-D viewer in the browser (``mmstab view``), served by viser.

- :mod:`mmstab.viz.viewer.ground`: the terrain through the ``Terrain`` interface, as a mesh.
- :mod:`mmstab.viz.viewer.scene`: robot meshes and the stability picture of one instant (pure).
- stored runs are read and checked by :mod:`mmstab.runs.store`.
- :mod:`mmstab.viz.viewer.server`: the viser server, its scene tree and GUI (needs ``viser``);
  :mod:`~mmstab.viz.viewer.static` the scene that does not move,
  :mod:`~mmstab.viz.viewer.robot_view` the robot and its stability picture,
  :mod:`~mmstab.viz.viewer.controls` the GUI panel.
- :mod:`mmstab.viz.viewer.cli`: the ``mmstab view`` command.

Importing this package does not import viser (an optional dependency: ``mmstab[view]``).
"""
