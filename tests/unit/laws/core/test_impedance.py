"""Admittance law of eq. 38 integrated with implicit Euler (eq. 39 as meant)."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError
from taskflow_tasks.core.impedance import AdmittanceState, ImpedanceProfile, admittance_step, static_displacement


def contact(k_env: float, F_cmd: float, K: float, D: float, M: float, dt: float, steps: int):
    """The tool (nominal at the surface of a spring along tool z) under the admittance law."""
    g = ImpedanceProfile(K=[K] * 3, D=[D] * 3, M=[M] * 3, force=[0, 0, F_cmd]).arrays()
    s = AdmittanceState()
    forces = []
    for _ in range(steps):
        pen = max(0.0, s.x[2])  # the tool moved along +z into the spring
        f = np.array([0.0, 0.0, -k_env * pen])  # the environment pushes back
        forces.append(-f[2])
        s = admittance_step(f, s, g, dt)
    return s, np.array(forces)


def test_settles_to_the_commanded_force_on_a_spring():
    # stiffness small against the spring: the contact force settles at the commanded 5 N
    s, forces = contact(k_env=1e4, F_cmd=5.0, K=10.0, D=60.0, M=1.0, dt=0.004, steps=2000)
    expected = 5.0 * 1e4 / (1e4 + 10.0)  # static balance K x = F_cmd - k_env x
    assert forces[-1] == pytest.approx(expected, rel=1e-4)
    assert forces[-1] == pytest.approx(5.0, rel=2e-3)
    assert np.all(np.isfinite(forces))


def test_steady_state_is_delta_f_over_k_and_free_motion_converges():
    g = ImpedanceProfile(K=[200, 300, 400], D=[40, 40, 40], M=[1, 1, 1], force=[0, 0, 2]).arrays()
    s = AdmittanceState()
    f = np.array([1.0, -2.0, 0.0])
    for _ in range(5000):
        s = admittance_step(f, s, g, 0.004)
    np.testing.assert_allclose(s.x, static_displacement(f, g), atol=1e-9)
    np.testing.assert_allclose(s.x, [1 / 200, -2 / 300, 2 / 400])


def test_implicit_integration_is_stable_for_a_stiff_profile_and_large_steps():
    g = ImpedanceProfile(K=[1e7] * 3, D=[0] * 3, M=[0.1] * 3).arrays()
    s = AdmittanceState(np.array([0.01, 0, 0]), np.zeros(3))
    for _ in range(100):
        s = admittance_step(np.zeros(3), s, g, 0.01)
        assert np.all(np.abs(s.x) <= 0.01 + 1e-12)
    assert abs(s.x[0]) < 1e-4


def test_dt_zero_is_a_no_op_and_shapes_are_checked():
    g = ImpedanceProfile(K=[1, 1, 1]).arrays()
    s = AdmittanceState()
    assert admittance_step(np.ones(3), s, g, 0.0) is s
    with pytest.raises(ValueError):
        admittance_step(np.ones(6), s, g, 0.01)


@pytest.mark.parametrize("bad", [{"K": [0, 1, 1]}, {"K": [-5, 1, 1]}, {"K": [1, 1]}, {"K": 1, "M": [0, 1, 1]},
                                 {"K": 1, "D": [-1, 0, 0]}])
def test_profile_rejects_non_positive_stiffness_and_mass(bad):
    with pytest.raises(ValidationError):
        ImpedanceProfile.model_validate(bad)
    assert ImpedanceProfile.kind == "impedance"
