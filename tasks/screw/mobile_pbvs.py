"""The screw-fastening tasks: the paper's control loop (section 7) bound to its states (section 6).

One control tick (``MobilePbvs.step``), with the equation numbers of ``papers/002``:

1. camera error ``E_co`` (eq. 10 as meant) → ``L_Eo`` in the base frame (25–32) → platform PID (33)
   [+ the part's velocity fed forward] → omnidirectional platform command (7.3);
2. end-effector set-point ``H*_be = H_bc H_co H*_ot [H_tp]`` (21–23; here ``T_body_camera ·
   T_camera_object · T_object_target [· T_target_approach]``), error ``E_be`` (13 as meant) of
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

Every integration step uses the control period ``TaskContext.dt`` = 1 / ``rate_hz``
(:func:`taskflow_tasks.screw.data.control_period`).  The PID and admittance states, the nominal joint
trajectory ``q*`` and the part-motion predictor are mission data (:mod:`taskflow_tasks.screw.data`).
Frames are written ``T_a_b`` (the pose of ``b`` in ``a``); the equations keep the paper's ``H_ab``.

Profile slots: ``platform`` and ``arm`` take ``pid`` profiles (:class:`taskflow_tasks.core.pid.PidProfile`),
``impedance`` takes ``impedance`` profiles (:class:`taskflow_tasks.core.impedance.ImpedanceProfile`),
``prediction`` takes a ``prediction`` profile (:class:`Prediction`, default: off — the paper's plain
PID; :mod:`taskflow_tasks.screw.prediction`).
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, Field, field_validator
from taskflow_robots.iiwa_urdf import IiwaKinematics
from taskflow_robots.mobile_iiwa import MobileIiwaParams, Pose
from taskflow_tasks.core import pbvs
from taskflow_tasks.core.impedance import AdmittanceState, ImpedanceProfile, admittance_step
from taskflow_tasks.core.keys import MARKER, WRENCH
from taskflow_tasks.core.pid import PidProfile, PidState, pid_step
from taskflow_tasks.screw.data import (
    ADMITTANCE,
    ODOM,
    PID_A,
    PID_B,
    PREDICTOR,
    Q_NOM,
    Q_REF,
    Q,
    control_period,
)
from taskflow_tasks.screw.prediction import MotionPredictor, Prediction, no_motion, propagate

from taskflow.api import (
    DISTANCE,
    FLAG,
    FORCE,
    ROTATION_ANGLE,
    MemoryKey,
    Observation,
    StepResult,
    StrictModel,
    Task,
    TaskContext,
)
from taskflow.registry import register_task
from taskflow.spatial import inverse
from taskflow.specs import Requires

RELAX_TAU = 0.1  # s: a state without an impedance set lets the compliance offset decay with this time constant
_ZERO3 = np.zeros(3)
Target = tuple[NDArray[np.float64] | None, NDArray[np.float64] | None]


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


class MobilePbvs(Task[Any, MobileIiwaParams]):
    """Platform PBVS + arm PBVS + admittance; subclasses choose the set-points and the slots."""

    Params: ClassVar[type[BaseModel]] = PlatformParams
    slots: ClassVar[dict[str, type[BaseModel]]] = {
        "platform": PidProfile, "arm": PidProfile, "impedance": ImpedanceProfile, "prediction": Prediction}
    metrics: ClassVar[dict[str, str]] = {"camera_error.t": DISTANCE, "camera_error.r": ROTATION_ANGLE,
                                         "contact_force": FORCE}
    command_interface: ClassVar[str] = "base_arm"
    robot_params: ClassVar[type[BaseModel]] = MobileIiwaParams
    kinematics: ClassVar[type | None] = IiwaKinematics
    requires: ClassVar[Requires] = (ODOM, Q, Q_REF, MARKER, WRENCH)
    writes: ClassVar[tuple[MemoryKey[Any], ...]] = (PID_B, PID_A, Q_NOM, ADMITTANCE, PREDICTOR)

    def __init__(self, ctx: TaskContext[Any, MobileIiwaParams]) -> None:
        super().__init__(ctx)
        rp = ctx.robot_params
        self.dt = control_period(ctx, self.name or type(self).__name__)
        self.kin = ctx.kinematics(IiwaKinematics)
        self.T_body_camera = rp.T_body_camera()
        self.R_body_camera = self.T_body_camera[:3, :3].copy()
        self.v_max, self.w_max, self.qd_max = rp.v_max, rp.w_max, rp.qd_max
        self.lam = rp.dls_damping
        self.g_b = ctx.profile("platform", PidProfile).arrays()
        self.g_a = ctx.profile("arm", PidProfile).arrays()
        imp = ctx.optional_profile("impedance", ImpedanceProfile)
        self.g_i = imp.arrays() if imp is not None else None
        self.pred = ctx.profile("prediction", Prediction)  # the loader binds its defaults (off) when a mission binds none
        params: PlatformParams | ArmParams = ctx.params
        self.T_camera_object_star = params.camera_target.matrix()
        self.T_object_camera_star = inverse(self.T_camera_object_star)
        self.T_camera_body = inverse(self.T_body_camera)
        self.T_object_target, self.T_target_approach = self._arm_target(ctx.params)
        m = ctx.memory
        self.mem = m
        for key in (PID_B, PID_A):
            st = key.get(m)
            if st is not None:
                st.reset_derivative()  # a new set-point or gain set: no derivative kick
        self.arm_gains_zero = not (np.any(self.g_a.kp) or np.any(self.g_a.ki) or np.any(self.g_a.kd))
        self.max_age: float | None = None  # how far a marker pose is propagated: the profile's max_age

    def _arm_target(self, params: Any) -> Target:
        return None, None

    def _object_pose(self, obs: Observation, t: float) -> tuple[NDArray[np.float64] | None, NDArray[np.float64], NDArray[np.float64]]:
        """``(T_camera_object now, v_o, w_o)``: the object seen from the camera and its world velocity
        expressed in the base frame (zeros without prediction; :mod:`taskflow_tasks.screw.prediction`)."""
        marker = MARKER(obs)
        if not self.pred.enabled:
            return no_motion(marker)
        predictor = PREDICTOR.get(self.mem)
        if predictor is None:
            predictor = MotionPredictor()
            PREDICTOR.set(self.mem, predictor)
        odom = ODOM(obs)
        predictor.record_odometry(t, odom)
        if marker is None:
            return None, _ZERO3, _ZERO3
        fit = predictor.add_marker(marker, self.T_body_camera, self.pred.window, self.pred.order)
        if not fit.slope.any():
            return no_motion(marker)
        return propagate(fit, t, odom, self.T_camera_body, self.pred, self.max_age)

    # -- one tick -------------------------------------------------------------------------------------
    def step(self, obs: Observation) -> StepResult:
        m = self.mem
        t = obs.t
        dt = self.dt
        q = np.asarray(Q(obs), dtype=np.float64)
        q_ref = np.asarray(Q_REF(obs), dtype=np.float64)
        q_nom = Q_NOM.get(m)
        if q_nom is None:
            q_nom = q_ref.copy()
        T_co, v_o, w_o = self._object_pose(obs, t)
        predicting = self.pred.enabled and bool(v_o.any() or w_o.any())
        metrics: dict[str, float] = {}
        wrench = WRENCH(obs)
        force = np.asarray(wrench.force, dtype=np.float64) if wrench is not None else _ZERO3
        metrics["contact_force"] = float(math.sqrt(force @ force))
        if T_co is None:  # the target was never seen: hold still
            Q_NOM.set(m, q_nom)
            return StepResult({"base_twist": np.zeros(3), "arm_dq": q_nom - q_ref}, metrics)
        T_bo = self.T_body_camera @ T_co
        # 1. platform (eqs. 10, 25-33)
        E_co = T_co @ self.T_object_camera_star  # eq. 10 as meant (pbvs.camera_error)
        et, er = pbvs.pose_error_norms(E_co)
        metrics["camera_error.t"], metrics["camera_error.r"] = et, er
        L_Eo = pbvs.camera_error_vector(E_co, self.R_body_camera)
        st_b = PID_B.get(m) or PidState()
        V_b, st_b = pid_step(L_Eo, st_b, self.g_b, dt)
        PID_B.set(m, st_b)
        # the PID acts on the nominal pose q* (the twist controller's own trajectory); the measured
        # pose (with the compliance displacement and servo lag) gives the transition metrics of eq. 12
        T_be, J = self.kin.fk_jacobian(q_nom)
        p_be = T_be[:3, 3]
        T_be_star = None
        if self.T_object_target is not None:
            T_be_star = pbvs.ee_setpoint(self.T_body_camera, T_co, self.T_object_target, self.T_target_approach)
        if predicting:
            V_b = V_b + pbvs.platform_feedforward(v_o, w_o, T_bo[:3, 3])
        cmd_b = pbvs.platform_twist_controller(V_b, self.v_max, self.w_max)
        V_b_eff = pbvs.planar_twist(cmd_b)
        # 2. arm (eqs. 21-23, 13, 34-36)
        V_a = np.zeros(6)
        if T_be_star is not None:
            L_Ee = pbvs.ee_error_vector(T_be, T_be_star)
            T_be_measured = self.kin.fk(q)
            metrics["ee_error.t"], metrics["ee_error.r"] = pbvs.error_norms(pbvs.ee_error_vector(T_be_measured, T_be_star))
            if not self.arm_gains_zero:
                V_be = pbvs.platform_induced_twist(V_b_eff, p_be)
                # with the part's motion estimated, eq. 35 compensates the platform's motion relative to the target
                V_t = pbvs.target_twist(v_o, w_o, T_bo[:3, 3], T_be_star[:3, 3]) if predicting and self.pred.relative else None
                L_c = pbvs.compensate_error(L_Ee, V_be, dt, V_t)
                st_a = PID_A.get(m) or PidState()
                V_a, st_a = pid_step(L_c, st_a, self.g_a, dt)
                PID_A.set(m, st_a)
                if predicting:
                    V_a = V_a + pbvs.arm_feedforward(v_o, w_o, T_bo[:3, 3], T_be_star[:3, 3], V_b_eff)
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
            dX[3:] = T_be[:3, :3] @ adm.x  # tool-frame displacement in the base frame (at q*)
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


class FollowParams(StrictModel):
    """``camera_target``: ``H*_co`` (eq. 5), the camera–object pose the platform keeps; ``coast`` (s): how
    long after the last marker's capture the part's predicted motion is followed without a new one."""

    camera_target: Pose
    coast: float = Field(default=1.5, ge=0.0, le=10.0)


@register_task("pbvs_follow")
class PbvsFollow(MobilePbvs):
    """The searching state (beyond the paper's, which holds still): the screwdriver has stopped; while the
    marker is lost, and for at most ``coast`` after its last capture, the platform servoes ``H*_co`` on the
    part's *predicted* pose (the prediction profile's fitted motion, propagated over the marker's age) and
    the arm holds the tool where it was on the part when the loss began (eqs. 21–23 with that pose as
    ``H*_ot``), so a short loss leaves the bit on its bolt.  Without prediction (profile off, or nothing
    fitted), or once the last marker is older than ``coast``, it stops all motion — the paper's searching
    state.  When a new marker arrives the platform re-aligns on it (the arm as before: on the held tool
    pose, or still); ``target_seen`` (1 from then on, else 0) and ``camera_error.*`` say when the
    interrupted operation may resume.  Metrics: those of :class:`MobilePbvs`, ``ee_error.*`` while the
    tool pose is held, ``target_seen`` and ``following`` (1 while the prediction is followed)."""

    Params = FollowParams
    metrics: ClassVar[dict[str, str]] = {**MobilePbvs.metrics, "ee_error.t": DISTANCE, "ee_error.r": ROTATION_ANGLE,
                                         "tool_force_z": "N", "target_seen": FLAG, "following": FLAG}

    def __init__(self, ctx: TaskContext[Any, MobileIiwaParams]) -> None:
        super().__init__(ctx)
        self.coast = float(ctx.params.coast)
        self.max_age = max(self.pred.max_age, self.coast)
        self.entry_seq: int | None = None  # the last marker before the loss (its seq), set at the first tick
        self.started = False
        self.capture = False  # take the tool's pose on the part at this tick's pose estimate

    def _object_pose(self, obs: Observation, t: float) -> tuple[NDArray[np.float64] | None, NDArray[np.float64], NDArray[np.float64]]:
        """:meth:`MobilePbvs._object_pose`; on the first tick that follows the prediction, the tool's nominal
        pose in the part's predicted frame becomes the arm's target ``H*_ot`` (held through the loss)."""
        T_co, v_o, w_o = super()._object_pose(obs, t)
        if self.capture and T_co is not None:
            self.capture = False
            q_nom = Q_NOM.get(self.mem)
            if q_nom is not None:
                self.T_object_target = inverse(self.T_body_camera @ T_co) @ self.kin.fk(q_nom)
        return T_co, v_o, w_o

    def step(self, obs: Observation) -> StepResult:
        marker = MARKER(obs)
        if not self.started:
            self.started = True
            self.entry_seq = None if marker is None else marker.seq
        seen = marker is not None and marker.seq != self.entry_seq
        age = math.inf if marker is None else obs.t - marker.stamp
        follow = (not seen and self.pred.enabled and age <= self.coast
                  and (fit := self._fit()) is not None and bool(fit.slope.any()))
        extra = {"target_seen": float(seen), "following": float(follow)}
        self.capture = follow and self.T_object_target is None
        if seen or follow:
            res = super().step(obs)
            return StepResult(res.command, {**res.metrics, **extra})
        if self.pred.enabled:  # keep the odometry history the predictor places markers with
            self._object_pose(obs, obs.t)
        wrench = WRENCH(obs)
        force = np.asarray(wrench.force, dtype=np.float64) if wrench is not None else _ZERO3
        return StepResult({"base_twist": np.zeros(3), "arm_dq": np.zeros(7)},
                          {"contact_force": float(math.sqrt(force @ force)), **extra})

    def _fit(self) -> Any:
        predictor = PREDICTOR.get(self.mem)
        return None if predictor is None else predictor.fit
