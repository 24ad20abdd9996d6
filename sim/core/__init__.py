"""The shared core of every world: what a paper's world is built from, never a world itself.

* :mod:`~taskflow_sim.core.stepped` — :class:`SteppedWorld` (the simulation clock, whole physics steps,
  the command check) and :class:`SensorSchedule` (when a sensor of a declared rate fires);
* :mod:`~taskflow_sim.core.sensors` — :class:`SensorStream`: one sensor's rate, latency, noise, dropout,
  fault intervals and lost/found events, polled by the stepping base;
* :mod:`~taskflow_sim.core.faults` — fault intervals (dropouts, occlusions, blackouts in time);
* :mod:`~taskflow_sim.core.bodies` — :class:`GroundBody`, the interface of a wheeled robot's body;
* :mod:`~taskflow_sim.core.command_delay` and :mod:`~taskflow_sim.core.odometry_slip` — actuator and
  odometry models shared by several worlds.

These modules import only the framework's public API (``taskflow.api`` and friends), numpy, pydantic and
pybullet — never a paper's package (``taskflow_sim.screw`` …), which import from here.
"""
