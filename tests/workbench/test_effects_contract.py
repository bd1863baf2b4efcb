"""Contract tests over every effect: the built-ins and a user effect, held to the same rules."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mav_motor_health.errors import ConfigError
from mav_motor_health.model.effects import BUILTIN_EFFECTS, Effect, EffectParameter, compose, solve
from mav_motor_health.model.equations import steady_state
from mav_motor_health.model.params import MotorParams


def sensor_drift(terms, p, data):
    """The current sensor's zero drifts with ESC temperature (a user effect, for the contract)."""
    return terms.replace(
        current_offset_a=terms.current_offset_a + p["gain_a_per_k"] * (data["esc_temp_c"] - 25.0)
    )


USER = Effect(
    "sensor_drift",
    sensor_drift,
    (EffectParameter("gain_a_per_k", "A/K", -0.5, 0.5, 0.0, 0.0),),
    needs=("esc_temp_c",),
)
ALL = {**BUILTIN_EFFECTS, USER.name: USER}
VARIABLES = ("throttle", "bus_voltage_v", "motor_temp_c", "esc_temp_c", "alt_m", "air_temp_c")


def context(n: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
    return {
        "throttle": rng.uniform(0.2, 1.0, n),
        "bus_voltage_v": rng.uniform(10.5, 12.6, n),
        "motor_temp_c": rng.uniform(10, 90, n),
        "esc_temp_c": rng.uniform(10, 80, n),
        "alt_m": rng.uniform(0, 3000, n),
        "air_temp_c": rng.uniform(-10, 40, n),
    }


def declared_only(effect: Effect, ctx: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    names = {alt for need in effect.needs for alt in need.split("|")} | set(effect.optional)
    return {k: v for k, v in ctx.items() if k in names}


@pytest.fixture(params=sorted(ALL), ids=sorted(ALL))
def effect(request: pytest.FixtureRequest) -> Effect:
    return ALL[request.param]


def test_bounds_contain_initial_and_neutral(effect: Effect) -> None:
    assert effect.parameters, "an effect without parameters cannot be fitted"
    for p in effect.parameters:
        assert p.lower < p.upper
        assert p.lower <= p.initial <= p.upper
        assert p.lower <= p.neutral <= p.upper
        assert p.unit, f"{effect.name}.{p.name} has no unit"


def test_physics_is_written_down(effect: Effect) -> None:
    assert len(effect.physics) > 40
    assert effect.summary


def test_needs_are_declared_variables(effect: Effect, paper_motor: MotorParams) -> None:
    """The effect runs on exactly its declared variables, and names a missing one in the error."""
    rng = np.random.default_rng(0)
    ctx = context(50, rng)
    v = ctx["throttle"] * ctx["bus_voltage_v"]
    compose(paper_motor, v, declared_only(effect, ctx), [(effect, effect.defaults("initial"))])
    for need in effect.needs:
        reduced = {k: a for k, a in declared_only(effect, ctx).items() if k not in need.split("|")}
        with pytest.raises(ConfigError, match=need.split("|")[0]):
            compose(paper_motor, v, reduced, [(effect, effect.defaults("initial"))])
    assert all(alt in VARIABLES for need in effect.needs for alt in need.split("|"))


def test_neutral_parameters_reproduce_the_base_model(effect: Effect, paper_motor: MotorParams) -> None:
    rng = np.random.default_rng(1)
    ctx = context(200, rng)
    v = ctx["throttle"] * ctx["bus_voltage_v"]
    if "throttle" in effect.needs:  # the PWM effect computes the voltage itself, from duty and bus voltage
        v = np.clip(ctx["throttle"], 0, 1) * ctx["bus_voltage_v"]
    neutral = solve(compose(paper_motor, v, ctx, [(effect, effect.defaults("neutral"))]))
    base = steady_state(paper_motor, v)
    np.testing.assert_allclose(neutral.omega_rad_s, base.omega_rad_s, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(neutral.current_a, base.current_a, rtol=1e-9, atol=1e-9)


def test_moving_a_parameter_changes_the_prediction(effect: Effect, paper_motor: MotorParams) -> None:
    rng = np.random.default_rng(2)
    ctx = context(200, rng)
    v = ctx["throttle"] * ctx["bus_voltage_v"]
    base = solve(compose(paper_motor, v, ctx, [(effect, effect.defaults("neutral"))]))
    for p in effect.parameters:
        values = effect.defaults("neutral")
        values[p.name] = p.neutral + 0.3 * (p.upper - p.lower) * (1 if p.neutral < p.upper else -1)
        moved = solve(compose(paper_motor, v, ctx, [(effect, values)]))
        change = (
            np.abs(moved.omega_rad_s - base.omega_rad_s).max()
            + np.abs(moved.current_a - base.current_a).max()
        )
        assert change > 1e-3, f"{effect.name}.{p.name} does nothing"


def test_forward_solution_is_vectorised_and_consistent(effect: Effect, paper_motor: MotorParams) -> None:
    """Per-sample terms: solving all samples at once equals solving them one by one, and eq. 2 holds."""
    rng = np.random.default_rng(3)
    ctx = context(40, rng)
    v = ctx["throttle"] * ctx["bus_voltage_v"]
    values = {
        p.name: p.neutral + 0.2 * (p.upper - p.lower) * (1 if p.neutral < p.upper else -1)
        for p in effect.parameters
    }
    terms = compose(paper_motor, v, ctx, [(effect, values)])
    together = solve(terms)
    for j in (0, 17, 39):
        one_ctx = {k: a[j : j + 1] for k, a in ctx.items()}
        alone = solve(compose(paper_motor, v[j : j + 1], one_ctx, [(effect, values)]))
        assert alone.omega_rad_s[0] == pytest.approx(together.omega_rad_s[j], rel=1e-9)
        assert alone.current_a[0] == pytest.approx(together.current_a[j], rel=1e-9)
    t = terms.arrays(len(v))
    i_motor = (together.current_a - t["current_offset_a"]) / t["current_scale"]
    turning = together.omega_rad_s > 0
    np.testing.assert_allclose(
        (t["R_ohm"] * i_motor + t["k_e"] * together.omega_rad_s)[turning],
        np.clip(t["voltage_v"], 0, None)[turning],
        rtol=1e-7,
    )


def test_parameter_declarations_are_validated() -> None:
    with pytest.raises(ConfigError, match="outside"):
        EffectParameter("x", "1", 0.0, 1.0, 2.0)
    with pytest.raises(ConfigError, match="empty"):
        EffectParameter("x", "1", 1.0, 0.0, 0.5)
    with pytest.raises(ConfigError, match="no parameter"):
        compose(
            MotorParams(0.1, 0.01, 1e-10, 0, 0),
            [5.0],
            {},
            [(BUILTIN_EFFECTS["propeller_exponent"], {"not_a_parameter": 1.0})],
        )


@settings(max_examples=60, deadline=None)
@given(
    R=st.floats(0.02, 2.0),
    k_e=st.floats(0.002, 0.05),
    C_p=st.floats(1e-12, 1e-8),
    B=st.floats(0.0, 1e-5),
    T_f=st.floats(0.0, 0.02),
    k=st.sampled_from([1.0, 2.0, 2.6, 3.0, 4.0]),
    volts=st.lists(st.floats(-1.0, 30.0), min_size=1, max_size=20),
)
def test_composed_solution_without_effects_is_the_foundations(R, k_e, C_p, B, T_f, k, volts) -> None:
    params = MotorParams(R, k_e, C_p, B, T_f, k)
    ours = solve(compose(params, volts, {}, []))
    theirs = steady_state(params, volts)
    np.testing.assert_allclose(ours.omega_rad_s, theirs.omega_rad_s, rtol=1e-7, atol=1e-7)
    np.testing.assert_allclose(ours.current_a, theirs.current_a, rtol=1e-7, atol=1e-7)
