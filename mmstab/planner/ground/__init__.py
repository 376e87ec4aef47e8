"""The ground under the arm: one check for the offline planner and the online loop.

The arm's pieces (``arm_pieces``) and their lowest points in B through the attitude
margin's tilts, measured against the ground's rise above the pose's support plane on a
1 cm lattice in M (``under_arm``: :class:`GroundUnderArm` on a terrain's surface, by
tiles); on a live map (``map_lattice``: unknown cells filled, tiles kept between maps;
``map_ground``: a pose's state per map, one node's verification). One C kernel for both
(``kernel``, ``kernel.c``): the pieces, the heights on a peak map, a live map's peaks.
"""
