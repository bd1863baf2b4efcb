"""The forward solution satisfies eqs. 2 and 7, is monotone in voltage, and is robust at the edges."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mav_motor_health.errors import ConfigError
from mav_motor_health.model import MotorParams, current_from_speed, steady_state, voltage_from_current_speed
from mav_motor_health.model.params import MotorRows, same_type

motors = st.builds(
    MotorParams,
    R_ohm=st.floats(0.01, 2.0),
    k_e=st.floats(1e-3, 0.1),
    C_p=st.floats(1e-13, 1e-6),
    B=st.floats(0.0, 1e-4),
    T_f=st.floats(0.0, 0.05),
    k=st.sampled_from([1, 2, 3, 4, 5]),
)
voltages = st.lists(st.floats(0.0, 60.0), min_size=1, max_size=30)


@settings(max_examples=300, deadline=None)
@given(motors, voltages)
def test_forward_solution_satisfies_both_equations(params: MotorParams, volts: list[float]) -> None:
    v = np.array(volts)
    sol = steady_state(params, v)
    turning = sol.omega_rad_s > 0
    # eq. 2 holds wherever the motor turns
    np.testing.assert_allclose(
        voltage_from_current_speed(params, sol.current_a, sol.omega_rad_s)[turning],
        v[turning],
        rtol=1e-7,
        atol=1e-9,
    )
    # eq. 7: the torque balance, relative to the drive torque
    torque = params.k_t * sol.current_a
    load = current_from_speed(params, sol.omega_rad_s) * params.k_t
    scale = params.k_e * v / params.R_ohm  # the stall torque: i = (V − k_e·ω)/R cancels near no-load speed
    assert np.all(np.abs(torque - load)[turning] <= 1e-7 * scale[turning])
    # below the start voltage friction holds the motor
    assert np.all(sol.omega_rad_s[v <= params.start_voltage_v] == 0)
    assert np.all(sol.omega_rad_s >= 0)


@settings(max_examples=200, deadline=None)
@given(motors, st.floats(0.0, 50.0), st.floats(1e-3, 10.0))
def test_speed_rises_with_voltage(params: MotorParams, v: float, dv: float) -> None:
    low, high = steady_state(params, [v, v + dv]).omega_rad_s
    assert high >= low
    if v > params.start_voltage_v:
        assert high > low


@pytest.mark.parametrize("k", [1, 2, 3, 4, 5, 2.7])
def test_every_exponent_is_solved(k: float) -> None:
    params = MotorParams(R_ohm=0.165, k_e=9.75e-3, C_p=1.692e-10 * 900 ** (3 - k), B=1.275e-7, T_f=1e-3, k=k)
    v = np.linspace(0, 25, 501)
    sol = steady_state(params, v)
    assert np.all(np.isfinite(sol.omega_rad_s))
    assert np.all(np.diff(sol.omega_rad_s) >= 0)


def test_paper_motor_at_eleven_volts(paper_motor: MotorParams) -> None:
    # Hand solution of C_p·ω³ + (B + k_e²/R)·ω = k_e·V/R − T_f at 11 V: ω ≈ 908 rad/s, i ≈ 13.0 A.
    sol = steady_state(paper_motor, 11.0)
    assert sol.omega_rad_s == pytest.approx(908.09, abs=0.05)
    assert sol.current_a == pytest.approx(13.007, abs=0.005)


def test_edges_zero_negative_nan_and_shape(paper_motor: MotorParams) -> None:
    v = np.array([[0.0, -3.0], [np.nan, 1e-12]])
    sol = steady_state(paper_motor, v)
    assert sol.omega_rad_s.shape == (2, 2)
    assert sol.omega_rad_s[0, 0] == 0 and sol.current_a[0, 0] == 0
    assert sol.omega_rad_s[0, 1] == 0 and sol.current_a[0, 1] == 0  # clipped: no reversing
    assert np.isnan(sol.omega_rad_s[1, 0]) and np.isnan(sol.current_a[1, 0])
    assert sol.omega_rad_s[1, 1] == 0  # below the start voltage


def test_invalid_parameters_are_refused() -> None:
    with pytest.raises(ConfigError, match="R_ohm"):
        MotorParams(R_ohm=0.0, k_e=0.01, C_p=1e-10, B=0, T_f=0)
    with pytest.raises(ConfigError, match="k_e"):
        MotorParams(R_ohm=0.1, k_e=float("nan"), C_p=1e-10, B=0, T_f=0)
    with pytest.raises(ConfigError, match="'k'"):
        MotorParams(R_ohm=0.1, k_e=0.01, C_p=1e-10, B=0, T_f=0, k=9)


def test_at_the_start_voltage_itself_the_motor_stands_still() -> None:
    # found by Hypothesis: k_e·V/R − T_f rounded to a tiny positive drive at V = T_f·R/k_e
    params = MotorParams(
        R_ohm=0.0428899947017729, k_e=0.08151375368082697, C_p=1e-9, B=0.0, T_f=0.04563777886388609, k=3
    )
    sol = steady_state(params, np.array([params.start_voltage_v, np.nextafter(params.start_voltage_v, 0)]))
    assert np.all(sol.omega_rad_s == 0)


@settings(max_examples=100, deadline=None)
@given(
    motors,
    st.lists(st.tuples(st.floats(0.8, 1.25), st.floats(0.9, 1.1)), min_size=2, max_size=6),
    st.lists(st.floats(0.0, 60.0) | st.just(float("nan")), min_size=1, max_size=12),
)
def test_motor_rows_solve_each_motor_as_its_own_model(
    params: MotorParams, scales: list[tuple[float, float]], volts: list[float]
) -> None:
    """Several motors of one type in one call (MotorRows: R and k_e per row, as the live agent diagnoses
    identification's per-motor models together) give each row what its motor's own model gives: the
    standing-still test, the closed forms and the Newton steps are elementwise."""
    models = [params.replace(R_ohm=params.R_ohm * r, k_e=params.k_e * e) for r, e in scales]
    rows = MotorRows.of(models)
    v = np.tile(np.array(volts), (len(models), 1))
    v[:, ::2] *= 0.97  # not the same voltages on every row
    v = v * np.linspace(1.0, 1.05, len(models))[:, None]
    together = steady_state(rows, v)
    for r, model in enumerate(models):
        alone = steady_state(model, v[r])
        np.testing.assert_allclose(together.omega_rad_s[r], alone.omega_rad_s, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(together.current_a[r], alone.current_a, rtol=1e-12, atol=1e-12)
        # the closed forms (k = 1, 2, 3) take no data-dependent number of steps: the same bits
        if params.k in (1, 2, 3):
            np.testing.assert_array_equal(together.omega_rad_s[r], alone.omega_rad_s)


def test_motor_rows_are_only_of_one_type(paper_motor: MotorParams) -> None:
    """One model for every row is that model; models that differ beyond R and k_e are refused."""
    assert MotorRows.of([paper_motor, paper_motor]) is paper_motor
    assert same_type(paper_motor, paper_motor.replace(R_ohm=0.2, k_e=0.01, name="motor 2"))
    other = paper_motor.replace(C_p=2 * paper_motor.C_p)
    assert not same_type(paper_motor, other)
    with pytest.raises(ValueError, match="beyond R and k_e"):
        MotorRows.of([paper_motor, other])
