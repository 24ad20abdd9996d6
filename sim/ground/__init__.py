"""Ground robots and the flat-ground world: the racecar and Husky bodies, the ground plane shared by the
worlds built on a floor (``ground_plane``: the PyBullet client and the box floor) and ``flat_ground``.
Imports pybullet, ``taskflow_robots`` and the public framework API only (never the control laws)."""
