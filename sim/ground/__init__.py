"""Ground worlds: wheeled robots on a floor — the racecar and Husky bodies, the ground plane shared by the
worlds built on a floor (``ground_plane``: the PyBullet client and the box floor) and ``flat_ground``
(what is built on it; a paper's world may subclass :class:`~taskflow_sim.ground.flat_ground.FlatGround`).

Imports :mod:`taskflow_sim.core`, pybullet, ``taskflow_robots`` and the framework's public API only
(never the control laws).
"""
