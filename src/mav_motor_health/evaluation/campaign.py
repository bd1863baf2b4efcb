"""Flight campaigns on the simulated hexacopter: many labelled flights, run in worker processes.

Used by ``tune`` (profiles fitted on labelled flights), the flight benchmark and its tests. A flight is
described by a :class:`FlightCase` (turbulence, seed, duration, at most one fault) and becomes a sim
scenario with a fixed manoeuvre plan: hover, climb, translate, descend, hover, repeated to the end.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..diagnosis.tuning import LabelledFlight
from ..sim.engine import SimRecord, run_scenario
from ..sim.scenario import Scenario, scenario_from_dict
from ..telemetry.table import TelemetryTable

__all__ = [
    "FAULTS",
    "TURBULENCE_LEVELS",
    "FlightCase",
    "benchmark_fault_cases",
    "run_flights",
    "scenario_for",
    "table_columns",
]

TURBULENCE_LEVELS = ("calm", "moderate", "gusty")
FAULTS = ("F1.1", "F2.1", "F3.1", "F4.1", "F4.2")
_PLAN: tuple[dict[str, Any], ...] = (
    {"kind": "hover", "duration_s": 8.0},
    {"kind": "climb", "duration_s": 4.0, "speed_m_s": 1.0},
    {"kind": "translate", "duration_s": 8.0, "speed_m_s": 2.0, "heading_deg": 45.0},
    {"kind": "descend", "duration_s": 4.0, "speed_m_s": 1.0},
    {"kind": "translate", "duration_s": 8.0, "speed_m_s": 2.0, "heading_deg": 225.0},
)


@dataclass(frozen=True)
class FlightCase:
    turbulence: str
    seed: int
    duration_s: float = 60.0
    fault: str | None = None
    motor: int = 1
    onset_s: float = 30.0
    severity: float | None = None
    dt_s: float = 0.01

    @property
    def name(self) -> str:
        what = (
            "healthy"
            if self.fault is None
            else f"{self.fault}_m{self.motor}" + ("" if self.severity is None else f"_s{self.severity:g}")
        )
        return f"{what}_{self.turbulence}_seed{self.seed}"


def scenario_for(case: FlightCase) -> Scenario:
    segments = []
    total = 0.0
    while total < case.duration_s:
        for seg in _PLAN:
            segments.append(dict(seg))
            total += float(seg["duration_s"])
    data: dict[str, Any] = {
        "scenario": {
            "name": case.name,
            "mode": "flight",
            "duration_s": case.duration_s,
            "seed": case.seed,
            "dt_s": case.dt_s,
        },
        "flight": {"turbulence": case.turbulence, "segment": segments},
    }
    if case.fault is not None:
        fault: dict[str, Any] = {"kind": case.fault, "motor": case.motor, "onset_s": case.onset_s}
        if case.severity is not None:
            fault["severity"] = case.severity
        data["fault"] = [fault]
    return scenario_from_dict(data, path=f"<{case.name}>")


def table_columns(record: SimRecord) -> dict[str, np.ndarray]:
    """A simulated flight's ESC reports as the telemetry columns the benchmarks and the tuning diagnose:
    each sample with the command of its instant and the battery monitor's latest reading (the vehicle's
    records, ``log_hz``), so that the ESC currents' sum is checked against it as in a log or live."""
    columns = record.esc_columns()
    columns.pop("rpm", None)
    if record.vehicle:
        t = np.array([v.time_s for v in record.vehicle])
        amps = np.array([v.battery_current_a for v in record.vehicle])
        j = np.searchsorted(t, columns["time_s"], side="right") - 1
        columns["battery_current_a"] = np.where(j >= 0, amps[np.maximum(j, 0)], np.nan)
    return columns


def _run(case: FlightCase) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    scenario = scenario_for(case)
    return table_columns(run_scenario(scenario)), scenario.truth()


def benchmark_fault_cases(seed_offset: int = 0) -> list[FlightCase]:
    """The benchmark's fault flights (``benchmarks/bench_flight.py``, ``bench_telemetry_path.py``): per
    turbulence level and fault two 50-s flights with the fault at 25 s, seeds from 2000 (the training
    campaign's are from 1000), the motor rotating through the six. ``seed_offset`` flies the same plan
    with other seeds (another draw of turbulence and sensor noise)."""
    cases = []
    for k, turbulence in enumerate(TURBULENCE_LEVELS):
        for j, fault in enumerate(FAULTS):
            for rep in range(2):
                cases.append(
                    FlightCase(
                        turbulence,
                        2000 + seed_offset + 100 * k + 10 * j + rep,
                        50.0,
                        fault=fault,
                        motor=1 + (j + 2 * k + rep) % 6,
                        onset_s=25.0,
                    )
                )
    return cases


def run_flights(cases: Sequence[FlightCase], jobs: int | None = None) -> list[LabelledFlight]:
    """Simulate the cases (in ``jobs`` worker processes; default: all cores) as labelled flights."""
    jobs = jobs or os.cpu_count() or 1
    if jobs == 1 or len(cases) == 1:
        results = [_run(c) for c in cases]
    else:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            results = list(pool.map(_run, cases))
    return [
        LabelledFlight(TelemetryTable(cols, source=case.name), truth, case.name)
        for case, (cols, truth) in zip(cases, results)
    ]
