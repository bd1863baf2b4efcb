"""Fixtures of the workbench tests: hidden-effect sessions (cached per session) and the real bench logs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mav_motor_health.model.effects import BUILTIN_EFFECTS
from mav_motor_health.model.params import MotorParams
from mav_motor_health.sim.steady import SensorNoise
from mav_motor_health.telemetry.table import TelemetryTable
from mav_motor_health.workbench.synthetic import hidden_effect_session

#: A bench-grade sensor set: optical speed ±3 rad/s, current ±0.05 A at low load to ±0.3 A at full load.
BENCH_NOISE = SensorNoise(speed_rad_s=3.0, current_low_a=0.05, current_high_a=0.3)

#: Hidden truth per library effect: realistic magnitudes (copper, NdFeB, a bus-current ESC...).
HIDDEN = {
    "resistance_temperature": {"alpha_per_k": 0.0039},
    "flux_temperature": {"beta_per_k": 0.0012},
    "esc_pwm": {"throttle_offset": 0.08, "bus_current_fraction": 1.0},
    "air_density": {"density_exponent": 1.0},
    "propeller_exponent": {"delta_k": -0.5},
    "bearing_friction": {"B2": 2e-7},
    "esc_voltage_drop": {"drop_v": 0.4, "wiring_ohm": 0.0},
}


def session(params: MotorParams, effects: list, seed: int = 1) -> TelemetryTable:
    return hidden_effect_session(
        params,
        np.random.default_rng(seed),
        effects,
        duration_s=600.0,
        throttle_range=(0.06, 1.0),
        noise=BENCH_NOISE,
    )


@pytest.fixture(scope="session")
def hidden_sessions(paper_motor: MotorParams) -> dict[str, TelemetryTable]:
    return {name: session(paper_motor, [(BUILTIN_EFFECTS[name], values)]) for name, values in HIDDEN.items()}


@pytest.fixture(scope="session")
def bench_logs() -> Path:
    here = Path(__file__).resolve()
    for parent in here.parents:
        candidate = parent / "shared" / "real_logs" / "bench"
        if candidate.is_dir():
            return candidate
    pytest.fail("the shared real logs are missing: expected shared/real_logs/bench above the repository")
