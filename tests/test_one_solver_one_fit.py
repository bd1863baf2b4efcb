"""One solver and one fit (issue 16, item 5): the base model is the model with no effects, solved by the same
function, and every fit of the model returns the same result type from one wrapper."""

from __future__ import annotations

import ast
import math
from pathlib import Path

import numpy as np
import pytest

from mav_motor_health.config import load_motor_params
from mav_motor_health.model.effects import BUILTIN_EFFECTS, base_terms, compose, solve
from mav_motor_health.model.effects.fit import fit_effects
from mav_motor_health.model.equations import steady_state
from mav_motor_health.model.estimation import estimate
from mav_motor_health.model.lsq import LeastSquaresFit, fit_least_squares, fit_linear
from mav_motor_health.model.solve import turning_speed

PACKAGE = Path(__file__).resolve().parents[1] / "src" / "mav_motor_health"


@pytest.mark.parametrize("k", [1.0, 2.0, 3.0, 4.0, 3.3])
def test_the_model_without_effects_is_the_base_model_bit_for_bit(k: float) -> None:
    params = load_motor_params("paper_x2212").replace(k=k)
    voltage = np.concatenate([np.linspace(-1.0, 13.0, 1401), [np.nan, 0.0, params.start_voltage_v * 1.5]])
    base = steady_state(params, voltage)
    composed = solve(base_terms(params, voltage))
    np.testing.assert_array_equal(composed.omega_rad_s, base.omega_rad_s)
    np.testing.assert_array_equal(composed.current_a, base.current_a)


def test_an_effect_that_changes_nothing_gives_the_base_model() -> None:
    params = load_motor_params("paper_x2212")
    voltage = np.linspace(2.0, 12.0, 301)
    friction = BUILTIN_EFFECTS["bearing_friction"]  # B2 = 0: neutral
    composed = solve(compose(params, voltage, {}, [(friction, friction.defaults("neutral"))]))
    np.testing.assert_array_equal(composed.omega_rad_s, steady_state(params, voltage).omega_rad_s)


def test_the_solver_balances_per_sample_laws() -> None:
    rng = np.random.default_rng(16)
    n = 500
    drive = rng.uniform(1.0, 500.0, n)
    linear = rng.uniform(0.01, 1.0, n)
    power = rng.uniform(0.0, 1e-6, n)
    exponent = rng.uniform(1.0, 4.5, n)
    quadratic = rng.uniform(0.0, 1e-4, n)
    w = turning_speed(drive, linear, power, exponent, quadratic)
    f = power * w**exponent + quadratic * w * w + linear * w - drive
    assert np.all(w > 0)
    assert np.max(np.abs(f) / drive) < 1e-9


def test_a_linear_fit_is_ordinary_least_squares_with_its_textbook_errors() -> None:
    rng = np.random.default_rng(5)
    x = np.linspace(0.0, 10.0, 60)
    a = np.column_stack([x, np.ones_like(x)])
    y = 2.0 * x + 3.0 + rng.normal(0.0, 0.5, x.size)
    fit = fit_linear(a, y, ("slope", "offset"), lower=-np.inf)
    coef, ssr, *_ = np.linalg.lstsq(a, y, rcond=None)
    sigma2 = float(ssr[0]) / (x.size - 2)
    cov = sigma2 * np.linalg.inv(a.T @ a)
    assert fit.values["slope"] == pytest.approx(coef[0], rel=1e-12)
    assert fit.values["offset"] == pytest.approx(coef[1], rel=1e-12)
    assert fit.stderr["slope"] == pytest.approx(math.sqrt(cov[0, 0]), rel=1e-9)
    assert fit.stderr["offset"] == pytest.approx(math.sqrt(cov[1, 1]), rel=1e-9)
    n = x.size
    assert fit.aic == pytest.approx(n * math.log(fit.ssr / n) + 4)
    assert fit.bic == pytest.approx(n * math.log(fit.ssr / n) + 2 * math.log(n))
    # the same problem as a nonlinear residual: the same numbers from the other entry
    nonlinear = fit_least_squares(lambda p: a @ p - y, np.zeros(2), ("slope", "offset"), target=y)
    assert nonlinear.method == "lm"
    for name in ("slope", "offset"):
        assert nonlinear.values[name] == pytest.approx(fit.values[name], rel=1e-9)
        assert nonlinear.stderr[name] == pytest.approx(fit.stderr[name], rel=1e-6)
    assert nonlinear.r_squared > 0.99 and nonlinear.accuracy_pct > 95


def test_bounds_are_kept_and_reported() -> None:
    x = np.linspace(1.0, 5.0, 30)
    a = np.column_stack([x, np.ones_like(x)])
    y = 2.0 * x - 1.0  # a negative offset, held at its bound 0
    fit = fit_linear(a, y, ("slope", "offset"))
    assert fit.values["offset"] == 0.0 and fit.at_bound("offset") and not fit.at_bound("slope")
    assert "offset =  0 " in fit.report() and "(at its bound)" in fit.report()
    bounded = fit_least_squares(lambda p: a @ p - y, np.ones(2), ("slope", "offset"), lower=[0.0, 0.0])
    assert bounded.method == "trf" and bounded.at_bound("offset") and bounded.values["offset"] >= 0.0


def test_a_parameter_the_data_do_not_touch_has_no_error_the_others_keep_theirs() -> None:
    rng = np.random.default_rng(9)
    x = np.linspace(0.0, 1.0, 40)
    a = np.column_stack([x, np.ones_like(x), np.zeros_like(x)])  # the third coefficient moves nothing
    y = 1.5 * x + 0.2 + rng.normal(0.0, 0.01, x.size)
    fit = fit_linear(a, y, ("slope", "offset", "idle"))
    assert math.isnan(fit.stderr["idle"])
    assert math.isfinite(fit.stderr["slope"]) and fit.stderr["slope"] > 0


def test_no_degrees_of_freedom_no_errors() -> None:
    a = np.array([[1.0, 0.0], [0.0, 1.0]])
    fit = fit_linear(a, np.array([1.0, 2.0]), ("p", "q"))
    assert fit.values == {"p": 1.0, "q": 2.0}
    assert all(math.isnan(e) for e in fit.stderr.values())


def test_every_fit_of_the_model_returns_the_one_result_type() -> None:
    params = load_motor_params("paper_x2212")
    rng = np.random.default_rng(3)
    voltage = np.repeat(np.linspace(4.0, 11.0, 11), 30)
    model = steady_state(params, voltage)
    current = model.current_a + rng.normal(0.0, 0.1, voltage.size)
    omega = model.omega_rad_s + rng.normal(0.0, 3.0, voltage.size)
    bench = estimate(voltage, current, omega)
    assert isinstance(bench.electrical, LeastSquaresFit) and isinstance(bench.mechanical, LeastSquaresFit)
    friction = BUILTIN_EFFECTS["bearing_friction"]
    with_effect = fit_effects(bench.params, [friction], voltage, omega, current, {})
    assert isinstance(with_effect.fit, LeastSquaresFit)
    assert with_effect.aic == with_effect.fit.aic and with_effect.stderr == with_effect.fit.stderr


def _scipy_fit_imports(path: Path) -> set[str]:
    names = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("scipy.optimize"):
            names.update(alias.name for alias in node.names)
    return names & {"least_squares", "lsq_linear", "curve_fit", "leastsq", "nnls"}


def test_only_the_one_wrapper_calls_scipy_s_least_squares() -> None:
    users = {
        str(path.relative_to(PACKAGE)): _scipy_fit_imports(path)
        for path in PACKAGE.rglob("*.py")
        if _scipy_fit_imports(path)
    }
    assert users == {"model/lsq.py": {"least_squares", "lsq_linear"}}
