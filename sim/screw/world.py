"""``screw_conveyor``: the screw-fastening world of the paper (section 9) on PyBullet.

A motor-cover part with bolts (the ``bolts`` layout in the part frame, four by default) and an ArUco
marker moves on a conveyor (constant 50 mm/s) or on an irregularly pushed trolley
(:mod:`taskflow_sim.screw.motion`); the mobile iiwa (:mod:`taskflow_sim.screw.body`) follows it.  What the robot gets (:meth:`observe`):

* ``state``: ``q``/``qd`` (measured joints), ``q_ref`` (the joint reference the arm servo is
  heading to), ``base_twist`` (platform odometry twist ``v_x, v_y, ω_z``), ``odom`` (platform pose);
* ``sensors``: ``marker`` — the latest marker detection, a :class:`taskflow.messages.MarkerPose`
  (``T_camera_object``, stamped with its capture time, ``seq`` = n) once its latency has passed (None
  before the first), ``wrench`` — the tool's contact :class:`taskflow.messages.Wrench` (force N, torque
  N·m about the tool joint) in the ``tool`` frame, from PyBullet's F/T sensor on the fixed
  ``tool_joint`` minus the screwdriver's weight (a gravity-compensated sensor); in the rendered mode
  ``image`` — the grey image the ArUco detector was given for the latest frame it processed, a
  :class:`taskflow.messages.Image` in frame ``camera`` stamped with its capture time (no extra
  rendering: the region of interest at full resolution, or the coarse full view of a search; None
  before the first such frame, and frames that dropout or an occlusion skipped render none);
* ``events``: ``target_found`` on the first detection after the marker was lost (or never seen),
  ``target_lost`` when no detection has been captured for ``lost_after`` seconds; the screwdriver's
  end events.

The screwdriver is an asynchronous action ``screwdriver`` with params :class:`ScrewdriverParams`
``{phase: activate | fasten, duration: s > 0}`` (``action_params``; validated again by
:meth:`ScrewConveyor.start_action`).  Each activation starts one **operation** at the bolt the bit is
on: a bolt whose head is within the tool's coupling tolerances of the tip (lateral ``tol_t``, axial
``tol_axial``, tilt ``tol_r``) when the activation starts.  Activation takes ``duration`` (default the
tool's ``activation_s``) and ends with ``tool_activated`` when the bit stayed within those tolerances
the whole time, or ``tool_failed`` — failure ``coupling`` when it left them, ``no_bolt`` when no bolt
was within them at the start (a mission pose off every bolt, or a large positioning error; the
operation records the nearest bolt and its distance).  ``fasten`` runs ``duration`` (default
``fasten_s``) on the coupled bolt and ends with ``screw_done`` — or ``tool_failed`` as soon as the bit
slips off (lateral error beyond ``slip_t``: failure ``slipped``) or at once when no bolt is coupled
(``not_coupled``).  A cancelled activation ends its operation (``cancelled``); a cancelled fastening
leaves it ``interrupted`` with the bit coupled, and the next ``fasten`` continues it (a state resumed
after the marker was lost).

Ground truth (never in observations): :meth:`ground_truth` gives the platform pose and its speed and
yaw rate measured from PyBullet's base pose over the last physics step (``base_speed`` m/s,
``base_yaw_rate`` rad/s), the largest arm joint speed PyBullet reports (``arm_speed`` rad/s), the part
pose, the tool tip's errors to the nearest bolt and the contact force.  :meth:`summary_metrics`
describes what happened at the part, per screwdriver operation (:mod:`taskflow_sim.screw.scoring`).

The world is assembled from its parts: parameters (:mod:`taskflow_sim.screw.params`), the PyBullet
scene (:mod:`taskflow_sim.screw.scene`), the robot's body (:mod:`taskflow_sim.screw.body`), the sensors
(:mod:`taskflow_sim.screw.sensors`), the screwdriver (:mod:`taskflow_sim.screw.screwdriver`) and the
scoring (:mod:`taskflow_sim.screw.scoring`).

Fidelity: ``fidelity: paper`` sets the marker ``latency`` and the platform's command delay
``base_delay`` from the paper's stated rates (``ScrewWorldParams.FIDELITY`` in :mod:`taskflow_sim.screw.params`, with sources); the
platform's velocity lag is ``base_tau``.

:meth:`safe_stop` brakes the platform to rest at the robot's ``brake_decel`` (0.5 s from the 1 m/s
speed limit with the default 2 m/s²), holds the arm's reference where it is, and stops the
screwdriver.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar, cast

import numpy as np
import pybullet as p
from numpy.typing import NDArray
from pydantic import BaseModel
from taskflow_robots.mobile_iiwa import MobileIiwa, Pose
from taskflow_sim.core.faults import IntervalFault
from taskflow_sim.core.stepped import Scene, SteppedWorld, check_command
from taskflow_sim.ground.ground_plane import connect
from taskflow_sim.screw import scene as sc
from taskflow_sim.screw import scoring
from taskflow_sim.screw.body import MobileIiwaBody
from taskflow_sim.screw.motion import PartMotion
from taskflow_sim.screw.params import ScrewdriverParams, ScrewWorldParams
from taskflow_sim.screw.perception import ImageNoise, PoseNoise, RenderedDetector
from taskflow_sim.screw.screwdriver import BitErrors, Screwdriver
from taskflow_sim.screw.sensors import MarkerCamera, WrenchSensor, marker_stream, wrench_stream

from taskflow.api import Command, Marker, Observation, ObsSpec, Robot, RobotNeeds, message
from taskflow.messages import Image, MarkerPose, Wrench
from taskflow.registry import register_world
from taskflow.spatial import T_from_planar, planar_apply, planar_between

_NO_WRENCH = np.zeros(6)
@register_world("screw_conveyor")
class ScrewConveyor(SteppedWorld[Scene]):  # the PyBullet client is self.client (self.sim stays None)
    """The mobile iiwa fastening the bolts of a part carried by a conveyor or a trolley."""

    Params: ClassVar[type[ScrewWorldParams]] = ScrewWorldParams

    @classmethod
    def rate_problem(cls, params: BaseModel, robot_params: BaseModel | None, rate_hz: float) -> tuple[str, str] | None:
        """The part moves ``speed / rate_hz`` between two commands; more than the tool's coupling tolerance
        ``tol_t`` and the tool cannot stay on its bolt through activation and fastening (the tasks' PIDs and
        the prediction correct once per tick).  The paper's 40 Hz and the missions' 100 Hz pass at every
        shipped speed (0.03-0.08 m/s: ≥ 27 Hz needed with the trolley's fluctuation)."""
        wp = cast(ScrewWorldParams, params)
        tool = getattr(robot_params, "tool", None)
        tol_t = float(getattr(tool, "tol_t", 0.0) or 0.0)
        if tol_t <= 0.0:
            return None
        need = ScrewWorldParams.min_rate_hz(wp.speed, tol_t, wp.motion, wp.trolley_speed_sigma)
        if rate_hz >= need:
            return None
        step = 1000.0 * need * tol_t / rate_hz
        return (f"control rate_hz {rate_hz:g} Hz is too slow for world {cls.name!r}: the part ({wp.motion}, up to "
                f"{need * tol_t:g} m/s) moves {step:.3g} mm between two commands, more than the tool's coupling "
                f"tolerance tol_t = {1000.0 * tol_t:g} mm",
                f"rate_hz of at least {need:.3g} Hz that divides physics_hz, or a slower part")

    SCREWS_PARAMETER: ClassVar[str] = "screws"
    """The mission parameter listing the operation poses ``H*_ot_i`` (paper eq. 6) in the marker frame, one per bolt
    (``foreach in: $screws`` in ``lib/screw_operation.yaml``): checked against the part's ``bolts`` at load."""

    @classmethod
    def parameter_problems(cls, params: BaseModel, parameters: Mapping[str, Any]) -> list[tuple[str, str, str]]:
        """The mission's ``screws`` against the part's ``bolts`` (kept in step by hand before): fewer poses than bolts
        is refused — the mission's rule (every screw) would hold with bolts left unfastened, a success the part
        does not have.  A pose on no bolt, or a second pose on a bolt, fails at run time where the tool lands
        (``no_bolt``, over-force: the faults the safety region is there for), so it is left to run.  A pose that
        does not parse is left to the task's own check."""
        screws = parameters.get(cls.SCREWS_PARAMETER)
        if not isinstance(screws, list) or not screws:
            return []
        for raw in screws:
            try:
                Pose.model_validate(raw)
            except (ValueError, TypeError):
                return []
        wp = cast(ScrewWorldParams, params)
        if len(screws) >= len(wp.bolts):
            return []
        heads = [T[:3, 3] for T in sc.T_marker_bolts(wp.bolts)]
        name = cls.SCREWS_PARAMETER
        return [(name, f"`{name}` lists {len(screws)} operation poses but the part of world {cls.name!r} has "
                 f"{len(heads)} bolts (world.params.bolts): the mission would succeed with "
                 f"{len(heads) - len(screws)} of them unfastened",
                 "one pose per bolt, in the marker frame (paper eq. 6): "
                 + ", ".join(f"{{xyz: [{x:.4f}, {y:.4f}, {z:.4f}], rpy_deg: [180, 0, -90]}}" for x, y, z in heads))]

    events: ClassVar[tuple[str, ...]] = ("target_lost", "target_found")
    metrics: ClassVar[dict[str, str]] = {}
    ground_truth_keys: ClassVar[tuple[str, ...]] = ("base_x", "base_y", "base_yaw", "base_speed", "base_yaw_rate",
                                                    "arm_speed", "part_x", "part_y", "part_yaw",
                                                    "tool_err_t", "tool_err_r", "contact_force")
    poses: ClassVar[dict[str, tuple[str, str, str | None]]] = {"robot": ("base_x", "base_y", "base_yaw"),
                                                               "part": ("part_x", "part_y", "part_yaw")}
    actions: ClassVar[dict[str, tuple[str, ...]]] = {"screwdriver": ("tool_activated", "tool_failed", "screw_done")}
    action_params: ClassVar[dict[str, type[BaseModel]]] = {"screwdriver": ScrewdriverParams}
    needs: ClassVar[RobotNeeds] = RobotNeeds(interfaces=("base_arm",), sensors={"camera": "rgb_camera"})
    observations: ClassVar[dict[str, ObsSpec]] = {"sensors.marker": message(MarkerPose),
                                                  "sensors.wrench": message(Wrench, optional=False),
                                                  "sensors.image": message(Image)}  # rendered mode only

    params: ScrewWorldParams

    @classmethod
    def scene(cls, params: BaseModel) -> list[Marker]:
        """Where the part starts (its path is the ``part`` pose of the trace) and its bolts there (the
        ``bolts`` layout placed with the part's start pose, each a circle of the bolt radius)."""
        wp = cast(ScrewWorldParams, params)
        x, y, yaw = wp.part_start
        at_start = planar_apply(wp.part_start, wp.bolts)  # the bolts in the world at the part's start
        return [Marker.point("object", "part at start", x, y, yaw=yaw),
                *(Marker.point("object", f"bolt {i}", float(bx), float(by), radius=sc.BOLT_RADIUS)
                  for i, (bx, by) in enumerate(at_start))]
    robot: MobileIiwa

    def __init__(self, robot: Robot, params: ScrewWorldParams, seed: int, gui: bool = False) -> None:
        if not isinstance(robot, MobileIiwa):
            raise TypeError(f"world screw_conveyor hosts a mobile_iiwa, got {type(robot).__name__}")
        cam_period = 1.0 / robot.params.camera.rate_hz
        if params.lost_after <= cam_period:
            raise ValueError(f"screw_conveyor: lost_after ({params.lost_after:g} s) must be longer than one camera period "
                             f"({cam_period:g} s at {robot.params.camera.rate_hz:g} Hz), or the marker is lost between every two frames")
        super().__init__(robot, params, seed, gui)
        self.client: int | None = None
        self.occlusions = IntervalFault(params.occlusions, "occlusions")
        rp = robot.params
        self.T_body_camera = rp.T_body_camera()
        # numpy's general (LU) inverse, not spatial.inverse: the closed form differs in the last bits and
        # those propagate into the screw missions' traces (they were recorded with this one)
        self._T_camera_body = np.linalg.inv(self.T_body_camera)
        self._T_part_marker = sc.T_part_marker()
        self._T_part_bolts = sc.T_part_bolts(params.bolts)
        self._cam_K = rp.camera.K()

    # -- lifecycle -----------------------------------------------------------------------------
    def reset(self) -> None:
        self.close()
        wp, rp = self.params, self.robot.params
        self.client = c = connect(self.gui, self.physics_hz)
        sc.add_floor_and_conveyor(c)
        self.part = sc.add_part(c, wp.contact_stiffness, wp.contact_damping, wp.bolts)
        root = np.random.SeedSequence(self.seed)
        # the fourth stream (the rendered camera's pixel noise) leaves the first three as they were
        r_motion, r_sense, r_ft, r_image = (np.random.default_rng(s) for s in root.spawn(4))
        x0, y0, yaw0 = wp.part_start
        self.motion = PartMotion(wp.motion, x0, y0, yaw0, wp.speed, wp.direction, r_motion,
                                 wp.trolley_speed_sigma, wp.trolley_heading_sigma, wp.trolley_tau, wp.trolley_yaw_gain)
        sc.set_part_planar(c, self.part, self.motion.x, self.motion.y, self.motion.yaw)
        bx, by, byaw = sc.nominal_platform(wp.part_start)
        ox, oy, oyaw = wp.robot_offset
        # offsets along the conveyor (part x) and away from it (platform −x)
        cp, spn = math.cos(yaw0), math.sin(yaw0)
        start = (bx + ox * cp - oy * math.cos(byaw), by + ox * spn - oy * math.sin(byaw), byaw + oyaw)
        self.body = MobileIiwaBody(c, self.robot, start, np.array(rp.q_home), platform_tau=wp.base_tau,
                                   base_delay=wp.base_delay)
        p.changeDynamics(self.body.id, self.body.tool_link, contactStiffness=wp.contact_stiffness,
                         contactDamping=wp.contact_damping, lateralFriction=0.3, physicsClientId=c)
        self.camera = MarkerCamera(rp.camera, self.true_T_camera_object, self.body.camera_pose,
                                   PoseNoise(r_sense, wp.noise_xy, wp.noise_z, wp.noise_r, wp.noise_tau),
                                   RenderedDetector(c, rp.camera, roi=wp.roi_px, noise=ImageNoise(r_image, wp.image_noise))
                                   if wp.perception == "rendered" else None, self._cam_K)
        self.marker = self.add_stream("marker", marker_stream(self.camera, wp, r_sense, self.occlusions))
        self.force = WrenchSensor.for_tool(rp.tool, wp.ft_noise)
        self.wrench = self.add_stream("wrench", wrench_stream(self.force, self._read_wrench, r_ft, self.physics_hz))
        self.screwdriver = Screwdriver(rp.tool)
        self.restart_clock()
        self._ft_raw: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None  # no step yet: nothing to read
        self.start_streams()
        self._events: list[str] = []  # the screwdriver's end events of this tick (the streams keep theirs)
        self._dq_pending = np.zeros(7)
        self._base_rate = (0.0, 0.0)  # ground truth: platform speed (m/s) and yaw rate (rad/s) over the last step
        if self.gui:
            p.resetDebugVisualizerCamera(1.8, 20.0, -30.0, [x0, y0, 0.8], physicsClientId=c)

    def close(self) -> None:
        if self.client is not None:
            try:
                p.disconnect(physicsClientId=self.client)
            except p.error:
                pass
            self.client = None

    @property
    def detector(self) -> RenderedDetector | None:
        """The rendered mode's ArUco detector (None in the pose mode)."""
        return self.camera.detector

    # -- geometry ------------------------------------------------------------------------------
    def part_pose(self) -> NDArray[np.float64]:
        """``T_world_part``."""
        m = self.motion
        return sc.planar_pose(m.x, m.y, m.yaw, sc.part_top_height())

    def marker_pose(self) -> NDArray[np.float64]:
        """``T_world_marker``."""
        return self.part_pose() @ self._T_part_marker

    def camera_pose(self) -> NDArray[np.float64]:
        """``T_world_camera`` from the platform's pose and the camera mount."""
        return self.body.base_pose() @ self.T_body_camera

    def true_T_camera_object(self) -> NDArray[np.float64]:
        """The marker in the camera frame: ``T_camera_body · T_body_part · T_part_marker`` (planar platform
        and part, ``T_body_part`` from their planar poses)."""
        m = self.motion
        T_body_part = T_from_planar(planar_between(self.body._pose, (m.x, m.y, m.yaw)), sc.part_top_height())
        return self._T_camera_body @ T_body_part @ self._T_part_marker

    def bolt_poses(self) -> list[NDArray[np.float64]]:
        """``T_world_bolt`` of every bolt (its operation frame)."""
        T_world_part = self.part_pose()
        return [T_world_part @ T for T in self._T_part_bolts]

    # -- the loop ------------------------------------------------------------------------------
    def observe(self) -> Observation:
        q, qd = self.body.joints()
        ps = self.body.platform
        state = {"q": q, "qd": qd, "q_ref": self.body.q_ref_target.copy(), "base_twist": ps.twist.copy(),
                 "odom": ps.pose.copy()}
        marker = self.marker.last_present
        w = self._wrench()
        sensors: dict[str, Any] = {
            "marker": None if marker is None else marker.value,
            "wrench": Wrench(stamp=self.t, frame="tool", force=w[:3].copy(), torque=w[3:].copy())}
        if self.camera.detector is not None:
            sensors["image"] = self.camera.image
        return Observation(t=self.t, state=state, sensors=sensors, events=(*self.marker.events, *self._events))

    def apply(self, command: Command) -> None:
        """``base_twist`` (3) to the platform now; ``arm_dq`` (7) spread over the next ``advance``'s steps."""
        cmd = check_command(self.robot, command)
        self.body.command_base(cmd["base_twist"], self.t)
        self._dq_pending = cmd["arm_dq"]

    def safe_stop(self) -> None:
        """Bring the robot to rest: the platform brakes to zero at the robot's ``brake_decel``, the arm's
        reference stops where it is (the servo settles the joints there), the screwdriver stops."""
        self.body.brake()
        self.body.hold()
        self._dq_pending = np.zeros(7)
        if self.screwdriver.running:
            self.cancel_action("screwdriver")

    # -- stepping (SteppedWorld hooks) --------------------------------------------------------------
    def _before_steps(self) -> None:
        self._require_client()
        self._events = []

    def begin_steps(self, n: int, h: float) -> None:
        """The arm's pending joint increment, spread over the ``n`` steps (none when n = 0)."""
        if n <= 0:
            return
        self.body.command_arm(self._dq_pending, n)
        self._dq_pending = np.zeros(7)
        self._last_substep = n - 1

    def physics_step(self, h: float) -> None:
        """The part moves, the platform's and arm's actuators act, the solver steps."""
        if self.substep == self._last_substep:  # the platform's pose before the last step (ground-truth rates)
            self._base_before = self.body.sim_base_planar()
        self.motion.step(h)
        m = self.motion
        sc.set_part_planar(self._require_client(), self.part, m.x, m.y, m.yaw)
        self.body.before_step(h, self.t)
        p.stepSimulation(physicsClientId=self.client)

    def end_steps(self, n: int, h: float) -> None:
        if n <= 0:
            return
        before, after = self._base_before, self.body.sim_base_planar()
        self._base_rate = (math.hypot(after[0] - before[0], after[1] - before[1]) / h,
                           math.remainder(after[2] - before[2], 2.0 * math.pi) / h)
        self.body.sync_state()
        # the F/T joint's reaction and the tool's orientation as the last step left them, latched before the
        # screwdriver's checks recompute the arm's forward kinematics (the wrench stream reads this)
        self._ft_raw = (self.body.tool_joint_wrench(), self.body.link_rotation(self.body.tool_link))
        self._update_action()

    def _require_client(self) -> int:
        if self.client is None:
            raise RuntimeError("screw_conveyor: call reset() first")
        return self.client

    # -- force sensing ---------------------------------------------------------------------------
    def _read_wrench(self, _stamp: float, _state: object) -> NDArray[np.float64] | None:
        """The ``wrench`` stream's ``read``: the latched F/T reading (force of the flange on the tool, tool
        frame), compensated for the tool's weight; nothing before the first physics step."""
        if self._ft_raw is None:
            return None
        return self.force.compensate(*self._ft_raw)

    def _wrench(self) -> NDArray[np.float64]:
        """The latest delivered contact wrench (zeros before the first)."""
        r = self.wrench.last_present
        return _NO_WRENCH if r is None or r.value is None else r.value

    # -- the screwdriver (the state machine is taskflow_sim.screw.screwdriver) ----------------------------
    def bit_errors(self, bolt: int | None = None) -> tuple[int, BitErrors]:
        """The bolt (the nearest when ``bolt`` is None) and the bit's errors to it (ground truth)."""
        return scoring.bit_errors(self.body.tip_pose(), self.bolt_poses(), bolt)

    def start_action(self, name: str, params: Mapping[str, Any]) -> None:
        model = self.action_params.get(name)
        if model is None:
            raise KeyError(f"screw_conveyor has no action {name!r} — valid: {', '.join(self.action_params)}")
        sp = model.model_validate(dict(params))  # a ValidationError (ValueError) names the bad field
        assert isinstance(sp, ScrewdriverParams)
        sd = self.screwdriver
        if sd.running:  # a new phase replaces one still running
            self.cancel_action(name)
        t = self.t
        if sp.phase == "activate":
            nearest, e = self.bit_errors()
            sd.activate(t, self.robot.params.tool.activation_s if sp.duration is None else sp.duration, nearest, e)
        else:
            duration = self.params.fasten_s if sp.duration is None else sp.duration
            if sd.can_continue():
                sd.fasten_coupled(t, duration)
            else:  # fastening with no bolt coupled: an operation of its own that fails at once
                nearest, e = self.bit_errors()
                sd.fasten_uncoupled(t, duration, nearest, e.translation)
        self._sample_action()

    def cancel_action(self, name: str) -> None:
        self.screwdriver.cancel(self.t)

    def _sample_action(self) -> None:
        bolt = self.screwdriver.bolt
        if bolt is not None:
            self.screwdriver.sample(self.bit_errors(bolt)[1])

    def _update_action(self) -> None:
        if not self.screwdriver.running:
            return
        self._sample_action()
        event = self.screwdriver.update(self.t)
        if event is not None:
            self._events.append(event)

    # -- records ----------------------------------------------------------------------------------
    def ground_truth(self) -> dict[str, float]:
        ps = self.body.platform.pose
        m = self.motion
        _, e = self.bit_errors()
        _, qd = self.body.joints()
        return {"base_x": float(ps[0]), "base_y": float(ps[1]), "base_yaw": float(ps[2]),
                "base_speed": self._base_rate[0], "base_yaw_rate": self._base_rate[1],
                "arm_speed": float(np.max(np.abs(qd))), "part_x": m.x, "part_y": m.y,
                "part_yaw": m.yaw, "tool_err_t": e.translation, "tool_err_r": e.rotation,
                "contact_force": float(np.linalg.norm(self._wrench()[:3]))}

    def operation_log(self) -> list[dict[str, Any]]:
        """The operations with their errors to their bolt (:func:`scoring.operation_log`)."""
        return scoring.operation_log(self.screwdriver.log)

    def summary_metrics(self) -> dict[str, Any]:
        """What happened at the part (:func:`scoring.summary_metrics`)."""
        det = self.detector
        rendered = None if det is None else {"rendered_frames": det.frames, "rendered_searches": det.searches,
                                             "rendered_dropped": self.marker.dropped}
        return scoring.summary_metrics(self.screwdriver.log, len(self._T_part_bolts),
                                       self.ground_truth() if self.client is not None else None,
                                       self.camera.errors, rendered)
