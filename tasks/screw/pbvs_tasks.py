"""The screw-fastening tasks: the paper's control loop (section 7) bound to its states (section 6).

One control tick (``MobilePbvs.step``), with the equation numbers of ``papers/002``:

1. camera error ``E_co`` (eq. 10 as meant) → ``L_Eo`` in the base frame (25–32) → platform PID (33)
   [+ the part's velocity fed forward] → omnidirectional platform command (7.3);
2. end-effector set-point ``H*_be = H_bc H_co H*_ot [H_tp]`` (21–23), error ``E_be`` (13 as meant) of
   the nominal pose ``FK(q*)``, compensated for the platform's motion (34–35) → arm PID (36)
   [+ feed-forward].  The PID works on the nominal pose so that it does not fight the compliance:
   with the measured pose it would integrate the admittance's displacement away and press the tool
   into the part with far more than the commanded force; the transition metrics ``ee_error.*``
   use the measured pose (joint sensors), as eq. (12) does;
3. arm twist controller ``q* = q + J⁺ V_a dt`` (37) with Pinocchio's Jacobian and a damped
   least-squares ``J⁺``;
4. admittance from the measured contact force, integrated every tick (38–39 as meant), mapped to
   joints with ``J⁺(q*)`` (40);
5. the transition metrics of eqs. (9)–(14): ``camera_error.t`` / ``camera_error.r`` and
   ``ee_error.t`` / ``ee_error.r`` (m, rad).

Every integration step (the PIDs' integral and derivative, the compensation ``E' = E − V_be dt`` of
eq. 35, the arm step of eq. 37, the admittance of eqs. 38–40, :class:`ArmHome`'s joint ramp) uses the
control period ``TaskContext.dt`` = 1 / ``rate_hz``, the time that passes between two ticks of the
mission; it is not estimated from observation times.

The PID and admittance states, the nominal joint trajectory ``q*`` and the part-motion history are
mission data (declared keys ``screw.*``, written by every PBVS task): a state change switches gains and set-points, not the
controllers' memory (the platform keeps the integral that carries it along with the part).

Profile slots: ``platform`` and ``arm`` take ``pid`` profiles (:class:`taskflow_tasks.core.pid.PidProfile`),
``impedance`` takes ``impedance`` profiles (:class:`taskflow_tasks.core.impedance.ImpedanceProfile`),
``prediction`` takes a ``prediction`` profile (:class:`Prediction`, default: off — the paper's plain
PID).  With prediction on, the part's velocity is estimated by a least-squares fit of its pose in the
odometry frame over a short window, the stale marker pose is propagated to the current time (the
latency), the estimated motion is fed forward into both twists, and eq. 35 compensates the platform's
motion relative to the target's (``Prediction.relative``; the paper's ``E − V_be dt`` leaves the tool
``v·dt`` behind a moving bolt) — the fix the paper names for its irregular-motion failures.
"""

from __future__ import annotations

import bisect
import math
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, Field, field_validator
from taskflow_robots.mobile_iiwa import MobileIiwaParams, Pose
from taskflow_tasks.core import pbvs
from taskflow_tasks.core.impedance import AdmittanceState, ImpedanceProfile, admittance_step
from taskflow_tasks.core.pid import PidProfile, PidState, pid_step

from taskflow.api import (
    DISTANCE,
    FORCE,
    ROTATION_ANGLE,
    MemoryKey,
    Metric,
    Observation,
    ObsSpec,
    StepResult,
    StrictModel,
    Task,
    TaskContext,
    array,
    instance,
    message,
    scalar,
    sequence,
)
from taskflow.messages import MarkerPose, Wrench
from taskflow.registry import register_task
from taskflow.spatial import inverse, transform_xyz_yaw

# the mission data the screw tasks keep across states (one definition each; every MobilePbvs task writes
# them all — each one starts from what is there, or from zero — and ArmHome the arm's)
PID_B: MemoryKey[PidState] = MemoryKey("screw.pid_b", instance(PidState), output=False,
                                       doc="platform PID state (eqs. 25-33)")
PID_A: MemoryKey[PidState] = MemoryKey("screw.pid_a", instance(PidState), output=False,
                                       doc="arm PID state (eqs. 34-36)")
Q_NOM: MemoryKey[NDArray[np.float64]] = MemoryKey("screw.q_nom", array(7), unit="rad",
                                                  doc="the arm's nominal joint trajectory q*")
ADMITTANCE: MemoryKey[AdmittanceState] = MemoryKey("screw.adm", instance(AdmittanceState), output=False,
                                                   doc="compliance offset (eqs. 38-40)")
ODOM_T: MemoryKey[list[float]] = MemoryKey("screw.odom_t", sequence(), unit="s", output=False,
                                           doc="odometry history (prediction): times ...")
ODOM_P: MemoryKey[list[tuple[float, float, float]]] = MemoryKey("screw.odom_p", sequence(), output=False,
                                                                doc="... and poses (x m, y m, yaw rad)")
OBJ_SEQ: MemoryKey[int] = MemoryKey("screw.obj_seq", scalar(), unit=Metric("", low=1.0, reason="a marker sequence number"),
                                   doc="the last marker used (prediction)")
OBJ_HIST: MemoryKey[list[tuple[float, float, float, float]]] = MemoryKey(
    "screw.obj_hist", sequence(), output=False, doc="(t, x, y, yaw) of the part (prediction)")
OBJ_FIT: MemoryKey[tuple[float, NDArray[np.float64], NDArray[np.float64]]] = MemoryKey(
    "screw.obj_fit", sequence(), output=False, doc="(t, H_wo, slope): the part's last fitted motion (prediction)")
_PBVS_DATA = (PID_B, PID_A, Q_NOM, ADMITTANCE, ODOM_T, ODOM_P, OBJ_SEQ, OBJ_HIST, OBJ_FIT)
ODOM_HISTORY_S = 0.5  # odometry kept to place a marker pose at its capture time (latency ≪ this)
RELAX_TAU = 0.1  # s: a state without an impedance set lets the compliance offset decay with this time constant
_ZERO3 = np.zeros(3)


class Prediction(StrictModel):
    """Velocity feed-forward (beyond the paper): ``enabled``, fit ``window`` (s), ``gain`` on the
    fed-forward twists, ``max_age`` (s) beyond which a marker pose is not propagated, and ``relative``:
    the compensation of eq. 35 subtracts the platform's motion relative to the target's estimated motion."""

    kind: ClassVar[str] = "prediction"

    enabled: bool = False
    window: float = Field(default=0.4, gt=0.0, le=5.0)
    gain: float = Field(default=1.0, ge=0.0, le=2.0)
    max_age: float = Field(default=0.3, gt=0.0)
    relative: bool = Field(default=True, description="eq. 35 compensates the platform's motion relative to the "
                           "target's estimated motion (false: the paper's E − V_be dt, which leaves the tool v·dt behind)")


class PlatformParams(StrictModel):
    """``camera_target``: the camera–object pose ``H*_co`` to servo to (eq. 5 / eq. 24).

    ``screws`` (optional): the mission's whole list of operation poses ``H*_T`` (eq. 6).  Given here it
    is validated at load time in full — a ``foreach`` item is checked only with its first element."""

    camera_target: Pose
    screws: list[Pose] | None = None

    @field_validator("screws")
    @classmethod
    def _non_empty(cls, v: list[Pose] | None) -> list[Pose] | None:
        if v is not None and not v:
            raise ValueError("screws must list at least one operation pose")
        return v


class ArmParams(StrictModel):
    """``camera_target`` (``H*_co``, the platform keeps servoing it), ``target``: the operation pose
    ``H*_ot`` in the object frame, ``approach``: ``H_tp`` (eq. 21; omit for eqs. 22/23)."""

    camera_target: Pose
    target: Pose
    approach: Pose | None = None


def _control_period(ctx: TaskContext, name: str) -> float:
    """The control period ``ctx.dt`` (1 / rate_hz, set by the framework): the PIDs integrate it, the
    compensation (eqs. 34–36), the arm step (eq. 37) and the admittance (eqs. 38–40) use it.  A task
    built without one would integrate nothing and never move the arm, so that is refused."""
    dt = float(ctx.dt)
    if not (math.isfinite(dt) and dt > 0.0):
        raise ValueError(f"{name} needs the control period TaskContext.dt > 0 s (1 / rate_hz), got {ctx.dt!r}")
    return dt


def _T_world_base(odom: tuple[float, float, float]) -> NDArray[np.float64]:
    """``T_world_base`` of the platform at the odometry pose ``(x, y, yaw)``."""
    x, y, th = (float(v) for v in odom)
    return transform_xyz_yaw(x, y, 0.0, th)


def _interp_odom(times: list[float], poses: list[tuple[float, float, float]], t: float) -> tuple[float, float, float]:
    """Platform pose at time ``t`` from the odometry history (linear; clamped to its ends)."""
    i = bisect.bisect_left(times, t)
    if i <= 0:
        return poses[0]
    if i >= len(times):
        return poses[-1]
    t0, t1 = times[i - 1], times[i]
    a, b = poses[i - 1], poses[i]
    w = (t - t0) / (t1 - t0) if t1 > t0 else 1.0
    return (a[0] + w * (b[0] - a[0]), a[1] + w * (b[1] - a[1]), a[2] + w * math.remainder(b[2] - a[2], 2 * math.pi))


class MobilePbvs(Task[Any, MobileIiwaParams]):
    """Platform PBVS + arm PBVS + admittance; subclasses choose the set-points and the slots."""

    Params: ClassVar[type[BaseModel]] = PlatformParams
    slots: ClassVar[dict[str, type[BaseModel]]] = {
        "platform": PidProfile, "arm": PidProfile, "impedance": ImpedanceProfile, "prediction": Prediction}
    metrics: ClassVar[dict[str, str]] = {"camera_error.t": DISTANCE, "camera_error.r": ROTATION_ANGLE,
                                         "contact_force": FORCE}
    command_interface: ClassVar[str] = "base_arm"
    robot_params: ClassVar[type[BaseModel]] = MobileIiwaParams
    requires: ClassVar[dict[str, ObsSpec]] = {"state.odom": array(3), "state.q": array(7), "state.q_ref": array(7),
                                              "sensors.marker": message(MarkerPose), "sensors.wrench": message(Wrench)}
    writes: ClassVar[tuple[MemoryKey[Any], ...]] = _PBVS_DATA

    def __init__(self, ctx: TaskContext[Any, MobileIiwaParams]) -> None:
        super().__init__(ctx)
        rp = ctx.robot_params
        self.dt = _control_period(ctx, self.name or type(self).__name__)
        self.kin = ctx.robot.kinematics  # type: ignore[attr-defined]
        self.H_bc = rp.H_bc()
        self.R_bc = self.H_bc[:3, :3].copy()
        self.v_max, self.w_max, self.qd_max = rp.v_max, rp.w_max, rp.qd_max
        self.lam = rp.dls_damping
        self.g_b = ctx.profile("platform", PidProfile).arrays()
        self.g_a = ctx.profile("arm", PidProfile).arrays()
        imp = ctx.optional_profile("impedance", ImpedanceProfile)
        self.g_i = imp.arrays() if imp is not None else None
        self.pred = ctx.optional_profile("prediction", Prediction) or Prediction()
        self.H_co_star = ctx.params.camera_target.matrix()  # type: ignore[attr-defined]
        self.H_co_star_inv = inverse(self.H_co_star)
        self.H_cb = inverse(self.H_bc)
        self.H_ot, self.H_tp = self._arm_target(ctx.params)
        m = ctx.memory
        self.mem = m
        for key in (PID_B, PID_A):
            st = key.get(m)
            if st is not None:
                st.reset_derivative()  # a new set-point or gain set: no derivative kick
        self.arm_gains_zero = not (np.any(self.g_a.kp) or np.any(self.g_a.ki) or np.any(self.g_a.kd))

    def _arm_target(self, params: Any) -> tuple[NDArray[np.float64] | None, NDArray[np.float64] | None]:
        return None, None

    # -- the part's pose: latest marker, optionally propagated with the estimated motion ---------
    def _object_pose(self, obs: Observation, t: float) -> tuple[NDArray[np.float64] | None, NDArray[np.float64], NDArray[np.float64]]:
        """``(H_co now, v_o, w_o)``: the object seen from the camera and its world velocity expressed
        in the base frame (zeros without prediction).

        With prediction, every new marker pose is placed in the odometry frame with the platform pose
        interpolated at its capture time; a least-squares line over the last ``window`` seconds gives
        the part's planar velocity and yaw rate (once per marker), and each tick the latest pose is
        propagated over its age and brought back into the current base frame.
        """
        marker: MarkerPose | None = obs.sensors.get("marker")
        if not self.pred.enabled:
            return (None if marker is None else marker.T_camera_object), _ZERO3, _ZERO3
        m = self.mem
        odom = obs.state["odom"]
        times: list[float] = ODOM_T.setdefault(m, [])
        poses: list[tuple[float, float, float]] = ODOM_P.setdefault(m, [])
        times.append(t)
        poses.append((float(odom[0]), float(odom[1]), float(odom[2])))
        if times[0] < t - 1.5 * ODOM_HISTORY_S:  # trimmed in blocks: keep ODOM_HISTORY_S, at any rate
            cut = bisect.bisect_left(times, t - ODOM_HISTORY_S)
            del times[:cut], poses[:cut]
        if marker is None:
            return None, _ZERO3, _ZERO3
        if marker.seq != OBJ_SEQ.get(m):
            OBJ_SEQ.set(m, marker.seq)
            H_wo = _T_world_base(_interp_odom(times, poses, marker.stamp)) @ self.H_bc @ marker.T_camera_object
            objs: list[tuple[float, float, float, float]] = OBJ_HIST.setdefault(m, [])
            yaw = math.atan2(H_wo[1, 0], H_wo[0, 0])
            if objs:
                yaw = objs[-1][3] + math.remainder(yaw - objs[-1][3], 2 * math.pi)  # unwrapped
            objs.append((marker.stamp, H_wo[0, 3], H_wo[1, 3], yaw))
            while len(objs) > 2 and objs[0][0] < marker.stamp - self.pred.window:
                objs.pop(0)
            slope = np.zeros(3)
            if len(objs) >= 3:
                arr = np.array(objs)
                _, slope = pbvs.fit_velocity(arr[:, 0], arr[:, 1:])
            OBJ_FIT.set(m, (marker.stamp, H_wo, slope))
        t_cap, H_wo, slope = OBJ_FIT(m)
        if not slope.any():
            return marker.T_camera_object, _ZERO3, _ZERO3
        # propagate the latest measurement over its age with the fitted motion (latency compensation)
        age = min(self.pred.max_age, max(0.0, t - t_cap))
        vx, vy, wz = float(slope[0]), float(slope[1]), float(slope[2])
        dyaw = wz * age
        c, s = math.cos(dyaw), math.sin(dyaw)
        H_now = H_wo.copy()
        H_now[0, :3] = c * H_wo[0, :3] - s * H_wo[1, :3]
        H_now[1, :3] = s * H_wo[0, :3] + c * H_wo[1, :3]
        H_now[0, 3] += vx * age
        H_now[1, 3] += vy * age
        # back into the current base frame: H_bw = (odom)⁻¹, planar
        bx, by, bth = float(odom[0]), float(odom[1]), float(odom[2])
        cb, sb = math.cos(bth), math.sin(bth)
        H_bw = np.array([[cb, sb, 0.0, -cb * bx - sb * by], [-sb, cb, 0.0, sb * bx - cb * by],
                         [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
        g = self.pred.gain
        v_o = np.array([g * (cb * vx + sb * vy), g * (-sb * vx + cb * vy), 0.0])
        return self.H_cb @ (H_bw @ H_now), v_o, np.array([0.0, 0.0, g * wz])

    # -- one tick -------------------------------------------------------------------------------------
    def step(self, obs: Observation) -> StepResult:
        m = self.mem
        t = obs.t
        dt = self.dt
        q = np.asarray(obs.state["q"], dtype=np.float64)
        q_ref = np.asarray(obs.state["q_ref"], dtype=np.float64)
        q_nom = Q_NOM.get(m)
        if q_nom is None:
            q_nom = q_ref.copy()
        H_co, v_o, w_o = self._object_pose(obs, t)
        predicting = self.pred.enabled and bool(v_o.any() or w_o.any())
        metrics: dict[str, float] = {}
        wrench: Wrench | None = obs.sensors.get("wrench")
        force = np.asarray(wrench.force, dtype=np.float64) if wrench is not None else _ZERO3
        metrics["contact_force"] = float(math.sqrt(force @ force))
        if H_co is None:  # the target was never seen: hold still
            Q_NOM.set(m, q_nom)
            return StepResult({"base_twist": np.zeros(3), "arm_dq": q_nom - q_ref}, metrics)
        H_bo = self.H_bc @ H_co
        # 1. platform (eqs. 10, 25-33)
        E_co = H_co @ self.H_co_star_inv  # eq. 10 as meant (pbvs.camera_error)
        et, er = pbvs.pose_error_norms(E_co)
        metrics["camera_error.t"], metrics["camera_error.r"] = et, er
        L_Eo = pbvs.camera_error_vector(E_co, self.R_bc)
        st_b = PID_B.get(m) or PidState()
        V_b, st_b = pid_step(L_Eo, st_b, self.g_b, dt)
        PID_B.set(m, st_b)
        # the PID acts on the nominal pose q* (the twist controller's own trajectory); the measured
        # pose (with the compliance displacement and servo lag) gives the transition metrics of eq. 12
        H_be, J = self.kin.fk_jacobian(q_nom)
        p_be = H_be[:3, 3]
        H_be_star = None
        if self.H_ot is not None:
            H_be_star = pbvs.ee_setpoint(self.H_bc, H_co, self.H_ot, self.H_tp)
        if predicting:
            V_b = V_b + pbvs.platform_feedforward(v_o, w_o, H_bo[:3, 3])
        cmd_b = pbvs.platform_twist_controller(V_b, self.v_max, self.w_max)
        V_b_eff = pbvs.planar_twist(cmd_b)
        # 2. arm (eqs. 21-23, 13, 34-36)
        V_a = np.zeros(6)
        if H_be_star is not None:
            L_Ee = pbvs.ee_error_vector(H_be, H_be_star)
            H_meas = self.kin.fk(q)
            metrics["ee_error.t"], metrics["ee_error.r"] = pbvs.error_norms(pbvs.ee_error_vector(H_meas, H_be_star))
            if not self.arm_gains_zero:
                V_be = pbvs.platform_induced_twist(V_b_eff, p_be)
                # with the part's motion estimated, eq. 35 compensates the platform's motion relative to the target
                V_t = pbvs.target_twist(v_o, w_o, H_bo[:3, 3], H_be_star[:3, 3]) if predicting and self.pred.relative else None
                L_c = pbvs.compensate_error(L_Ee, V_be, dt, V_t)
                st_a = PID_A.get(m) or PidState()
                V_a, st_a = pid_step(L_c, st_a, self.g_a, dt)
                PID_A.set(m, st_a)
                if predicting:
                    V_a = V_a + pbvs.arm_feedforward(v_o, w_o, H_bo[:3, 3], H_be_star[:3, 3], V_b_eff)
        # 3. arm twist controller (eq. 37), joint speed limited
        if not self.arm_gains_zero:
            dq = pbvs.dls_solve(J, V_a * dt, self.lam)
            lim = self.qd_max * dt
            peak = float(np.max(np.abs(dq)))
            if peak > lim:
                dq *= lim / peak
            q_nom = np.clip(q_nom + dq, self.kin.lower, self.kin.upper)
        Q_NOM.set(m, q_nom)
        # 4. admittance (eqs. 38-40)
        q_cmd = q_nom
        adm = ADMITTANCE.get(m) or AdmittanceState()
        if self.g_i is not None:
            adm = admittance_step(force, adm, self.g_i, dt)
        else:  # no compliance in this state: let the offset decay
            adm = AdmittanceState(adm.x * math.exp(-dt / RELAX_TAU), adm.v * 0.0)
        ADMITTANCE.set(m, adm)
        if float(adm.x @ adm.x) > 1e-12:  # displacements under a micrometre (stiff set) are not worth a Jacobian
            dX = np.zeros(6)
            dX[3:] = H_be[:3, :3] @ adm.x  # tool-frame displacement in the base frame (at q*)
            J_star = self.kin.jacobian(q_nom)
            q_cmd = q_nom + pbvs.impedance_joint_offset(J_star, dX, self.lam)
        metrics["tool_force_z"] = float(force[2])
        return StepResult({"base_twist": cmd_b, "arm_dq": q_cmd - q_ref}, metrics)


@register_task("pbvs_platform")
class PbvsPlatform(MobilePbvs):
    """s1 initial platform approach: the platform servoes the camera to ``H*_co`` (eq. 9 ends it);
    the arm's PID is bound to ``zero`` and it holds."""

    Params = PlatformParams


@register_task("pbvs_arm")
class PbvsArm(MobilePbvs):
    """s2–s7: the platform keeps ``H*_co`` while the arm servoes the tool to
    ``H_bc H_co H*_ot [H_tp]`` (eqs. 21–23; eq. 12 ends it)."""

    Params = ArmParams
    metrics: ClassVar[dict[str, str]] = {**MobilePbvs.metrics, "ee_error.t": DISTANCE, "ee_error.r": ROTATION_ANGLE,
                                         "tool_force_z": "N"}

    def _arm_target(self, params: Any) -> tuple[NDArray[np.float64] | None, NDArray[np.float64] | None]:
        return params.target.matrix(), (params.approach.matrix() if params.approach is not None else None)


@register_task("pbvs_platform_retract")
class PbvsPlatformRetract(MobilePbvs):
    """s8 final platform retract to ``H⊗_co`` (eq. 24): no impedance set is bound (the tool is clear
    of the part), so this task has no ``impedance`` slot."""

    Params = PlatformParams
    slots: ClassVar[dict[str, type[BaseModel]]] = {"platform": PidProfile, "arm": PidProfile, "prediction": Prediction}


class HomeParams(StrictModel):
    """Joint-space move to the robot's ``q_home`` at ``speed`` (rad/s)."""

    speed: float = Field(default=0.5, gt=0.0, le=2.0)


class HomePose(StrictModel):
    """The robot parameter the homing law reads: the arm's home configuration (rad)."""

    q_home: tuple[float, ...]


@register_task("arm_home")
class ArmHome(Task[HomeParams, HomePose]):
    """Error handling: the platform stops and the arm retracts to ``q_home`` in joint space (no
    camera needed, so it works when the target is lost).  ``joint_error`` (rad) is the largest joint
    distance to home."""

    Params: ClassVar[type[BaseModel]] = HomeParams
    metrics: ClassVar[dict[str, str]] = {"joint_error": Metric("rad", low=0.0, reason="the largest |joint angle error|")}
    command_interface: ClassVar[str] = "base_arm"
    robot_params: ClassVar[type[BaseModel]] = HomePose
    requires: ClassVar[dict[str, ObsSpec]] = {"state.q": array(7), "state.q_ref": array(7)}
    writes: ClassVar[tuple[MemoryKey[Any], ...]] = (Q_NOM, ADMITTANCE)

    def __init__(self, ctx: TaskContext[HomeParams, HomePose]) -> None:
        super().__init__(ctx)
        self.dt = _control_period(ctx, self.name or type(self).__name__)
        self.home = np.array(ctx.robot_params.q_home)
        self.speed = float(ctx.params.speed)
        self.mem = ctx.memory

    def step(self, obs: Observation) -> StepResult:
        m = self.mem
        dt = self.dt
        q_ref = np.asarray(obs.state["q_ref"], dtype=np.float64)
        q_nom = Q_NOM.get(m)
        q_nom = q_ref.copy() if q_nom is None else q_nom
        d = self.home - q_nom
        peak = float(np.max(np.abs(d)))
        step = self.speed * dt
        q_nom = self.home.copy() if peak <= step else q_nom + d * (step / peak)
        Q_NOM.set(m, q_nom)
        ADMITTANCE.set(m, AdmittanceState())
        q = np.asarray(obs.state["q"], dtype=np.float64)
        return StepResult({"base_twist": np.zeros(3), "arm_dq": q_nom - q_ref},
                          {"joint_error": float(np.max(np.abs(self.home - q)))})
