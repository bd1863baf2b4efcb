"""Two-step estimation recovers the paper's motor from data with the paper's noise."""

from __future__ import annotations

import numpy as np
import pytest

from mav_motor_health.errors import FitError
from mav_motor_health.model import MotorParams, accuracy_pct, estimate, steady_state
from mav_motor_health.sim.steady import PAPER_VOLTAGES_V, SensorNoise, steady_measurements


@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4])
def test_recovers_paper_motor(paper_motor: MotorParams, seed: int) -> None:
    rng = np.random.default_rng(seed)
    v, i, w = steady_measurements(paper_motor, PAPER_VOLTAGES_V, 2000, rng)
    fit = estimate(v, i, w)
    assert fit.success
    assert fit.params.R_ohm == pytest.approx(paper_motor.R_ohm, rel=0.02)
    assert fit.params.k_e == pytest.approx(paper_motor.k_e, rel=0.005)
    assert fit.params.k == 3
    assert fit.mechanical.accuracy_pct >= 99.0  # the model reproduces the measured current (eq. 10)
    assert fit.forward_accuracy_pct["current"] >= 99.0  # and from voltage alone
    assert fit.forward_accuracy_pct["omega"] >= 99.0
    # standard errors are reported and cover the truth within 4 sigma
    assert abs(fit.params.R_ohm - paper_motor.R_ohm) <= 4 * fit.stderr["R_ohm"]
    assert abs(fit.params.k_e - paper_motor.k_e) <= 4 * fit.stderr["k_e"]
    assert fit.electrical.r_squared > 0.999 and np.isfinite(fit.rmse["current_a"])


def test_raw_samples_are_biased_which_is_why_points_are_averaged(paper_motor: MotorParams) -> None:
    rng = np.random.default_rng(7)
    v, i, w = steady_measurements(paper_motor, PAPER_VOLTAGES_V, 2000, rng)
    raw = estimate(v, i, w, bin_width_v=None)
    binned = estimate(v, i, w)
    raw_err = abs(raw.params.R_ohm / paper_motor.R_ohm - 1)
    binned_err = abs(binned.params.R_ohm / paper_motor.R_ohm - 1)
    assert binned_err < raw_err


@pytest.mark.parametrize("true_k", [2, 4])
def test_exponent_is_chosen_by_least_squares(true_k: int) -> None:
    params = MotorParams(R_ohm=0.1, k_e=0.01, C_p=1.5e-10 * 900 ** (3 - true_k), B=1e-6, T_f=0.002, k=true_k)
    rng = np.random.default_rng(true_k)
    v, i, w = steady_measurements(params, np.linspace(3, 12, 15), 500, rng, SensorNoise(2.0, 0.02, 0.1))
    fit = estimate(v, i, w)
    assert fit.params.k == true_k
    assert min(fit.exponent_rmse_a, key=fit.exponent_rmse_a.__getitem__) == true_k


def test_real_exponent_fit(paper_motor: MotorParams) -> None:
    params = paper_motor.replace(k=2.6, C_p=paper_motor.C_p * 900**0.4)
    rng = np.random.default_rng(11)
    v, i, w = steady_measurements(params, PAPER_VOLTAGES_V, 2000, rng, SensorNoise(1.0, 0.01, 0.05))
    fit = estimate(v, i, w, fit_k=True)
    assert fit.params.k == pytest.approx(2.6, abs=0.1)
    assert "k" in fit.stderr


def test_too_few_points_is_a_clear_error(paper_motor: MotorParams) -> None:
    v = np.array([5.0, 5.0, 5.0, 6.0, 6.0, 6.0])
    s = steady_state(paper_motor, v)
    with pytest.raises(FitError, match="2 operating points"):
        estimate(v, s.current_a, s.omega_rad_s)


def test_accuracy_definition() -> None:
    assert accuracy_pct([10, 10], [9, 11]) == pytest.approx(90.0)
    assert accuracy_pct([1, np.nan], [1, 5]) == pytest.approx(100.0)


def test_report_names_every_parameter(paper_motor: MotorParams) -> None:
    rng = np.random.default_rng(3)
    fit = estimate(*steady_measurements(paper_motor, PAPER_VOLTAGES_V, 200, rng))
    text = fit.report()
    for name in ("R_ohm", "k_e", "C_p", "B", "T_f", "accuracy", "k=3"):
        assert name in text
    d = fit.to_dict()
    assert set(d["params"]) == {"R_ohm", "k_e", "C_p", "B", "T_f", "k"}
    assert set(d["stderr"]) >= {"R_ohm", "k_e", "C_p", "B", "T_f"}


def test_paper_noise_gives_a_physical_model_in_a_hundred_draws(paper_motor: MotorParams) -> None:
    """The paper's 11 voltage levels and sensor noise, 100 seeded draws: k = 3 unless the data prefer
    another clearly (BIC margin), no negative friction or damping, R and k_e as the paper reports."""
    k_three = close = 0
    for seed in range(100):
        rng = np.random.default_rng(1000 + seed)
        v, i, w = steady_measurements(paper_motor, PAPER_VOLTAGES_V, 300, rng)
        fit = estimate(v, i, w)
        p = fit.params
        assert p.B >= 0 and p.T_f >= 0 and p.C_p >= 0, f"draw {seed}: {p}"
        k_three += p.k == 3
        close += abs(p.R_ohm / paper_motor.R_ohm - 1) < 0.02 and abs(p.k_e / paper_motor.k_e - 1) < 0.005
    assert k_three >= 95
    assert close >= 95
