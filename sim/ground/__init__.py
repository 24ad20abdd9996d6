"""Ground worlds: wheeled robots on a floor (``flat_ground`` and what is built on it).

Imports :mod:`taskflow_sim.core` and the framework's public API; a paper's world may subclass
:class:`~taskflow_sim.ground.flat_ground.FlatGround`.
"""
