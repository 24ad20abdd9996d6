"""The screw-fastening paper's world (papers/002): ``screw_conveyor`` and the pieces it is built from.

``world`` holds the registered :class:`~taskflow_sim.screw.world.ScrewConveyor`; the rest are its
parts, each one concept: the part's motion (``motion``), the PyBullet scene (``scene``), the mobile
iiwa's body (``body``), the marker detector in both perception modes (``perception``) and the
screwdriver's state machine (``screwdriver``).  Modules here may import pybullet, ``taskflow_robots``,
the shared simulator core of ``taskflow_sim`` and the framework's public API (``taskflow.api``,
``messages``, ``spatial``, ...); nothing else of ``taskflow`` and no other paper's world.
"""
