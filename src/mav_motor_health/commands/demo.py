"""``mav-motor-health demo``: the whole method end to end on the built-in simulated motor, no hardware.

1. Calibrate: noisy steady-state bench data at the paper's 11 voltages → two-step fit.
2. Diagnose: the paper's testbed experiments (five voltages × five faults, fault at t = 10 s of 20 s)
   with the fitted model and the testbed profile; prints what was announced and how fast.
"""

from __future__ import annotations

import argparse

import numpy as np

from ..config import load_motor_params, load_profile
from ..diagnosis.pipeline import diagnose
from ..diagnosis.states import MotorState
from ..model.estimation import estimate
from ..sim.steady import PAPER_VOLTAGES_V, steady_measurements, testbed_run
from ..telemetry.table import TelemetryTable

FAULTS = ("F1.1", "F2.1", "F3.1", "F4.1", "F4.2")
CASES_V = (4.2, 5.8, 7.6, 9.2, 11.0)


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("demo", help="run the method end to end on the built-in simulated motor")
    p.add_argument("--seed", type=int, default=2021, help="random seed (default 2021)")
    p.set_defaults(run=run)


def run_demo(seed: int = 2021) -> tuple[str, dict[tuple[str, float], tuple[str, float]]]:
    """Returns the printed text and, per (fault, voltage), the final announced state and detection time."""
    rng = np.random.default_rng(seed)
    truth = load_motor_params()
    profile = load_profile("testbed")
    v, i, w = steady_measurements(truth, PAPER_VOLTAGES_V, 2000, rng)
    fit = estimate(v, i, w, name="demo calibration")
    out = [
        "== 1. Calibration on the simulated bench (11 points, 4-11 V, paper noise)",
        fit.report(),
        "",
        "== 2. Testbed experiments: fault at t = 10 s, testbed profile, fitted model",
        f"{'fault':6s} " + " ".join(f"{c:>13.1f}V" for c in CASES_V),
    ]
    results: dict[tuple[str, float], tuple[str, float]] = {}
    for fault in FAULTS:
        cells = []
        for case in CASES_V:
            table = TelemetryTable(testbed_run(truth, fault, case, rng))
            res = diagnose(table, fit.params, profile)
            target = MotorState.from_label(fault)
            hit = np.flatnonzero((res["announced"] == target) & (res["time_s"] >= 10.0))
            delay = float(res["time_s"][hit[0]] - 10.0) if hit.size else float("nan")
            final = MotorState(int(res["announced"][-1])).label
            results[(fault, case)] = (final, delay)
            cells.append(f"{final:>6s} {delay:5.2f}s" if hit.size else f"{final:>6s}   --- ")
        out.append(f"{fault:6s} " + " ".join(f"{c:>14s}" for c in cells))
    out.append("(cells: announced state at the end, and time from fault onset to its announcement)")
    return "\n".join(out), results


def run(args: argparse.Namespace) -> int:
    text, _ = run_demo(args.seed)
    print(text)
    return 0
