"""Ground worlds: wheeled robots on a floor (``flat_ground`` and what is built on it), the racecar and
Husky bodies (``racecar_body``/``racecar_ground``, ``husky_body``, their ``base_frame``) and the ground plane
every world stands on (``ground_plane``: the PyBullet client and the box floor).

Imports :mod:`taskflow_sim.core`, ``taskflow_robots`` and the framework's public API; a paper's world may
subclass :class:`~taskflow_sim.ground.flat_ground.FlatGround`.
"""
