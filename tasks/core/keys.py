"""Observation keys several control laws read, one definition each (a paper's own keys live with its tasks).

A task lists the keys it reads in ``requires`` (checked at load against what the robot and the world
provide) and reads with the same objects, ``POSE(obs)``: an entry it did not declare cannot be read by
a misspelt string, and a required entry that is absent raises :class:`taskflow.api.MissingObservation`
instead of reading as a silent default (:class:`taskflow.api.ObsKey`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from taskflow.api import ObsKey, array, scalar
from taskflow.messages import MarkerPose, Wrench

#: the odometry pose ``T_odom_base = (x, y, yaw)`` (m, m, rad) of a ground robot or a mobile base
POSE: ObsKey[NDArray[np.float64]] = ObsKey("state.pose", array(3))
#: the measured signed forward speed (m/s)
SPEED: ObsKey[float] = ObsKey("state.v", scalar())
#: the latest fiducial-marker detection (``None`` before the first one)
MARKER: ObsKey[MarkerPose | None] = ObsKey("sensors.marker", MarkerPose, optional=True)
#: the latest wrist force/torque reading (``None`` before the first one)
WRENCH: ObsKey[Wrench | None] = ObsKey("sensors.wrench", Wrench, optional=True)
