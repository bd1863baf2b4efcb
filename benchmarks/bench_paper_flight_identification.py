"""The paper hexacopter's calm flight, identified at several seeds: how much one flight's draw moves J and R.

    PYTHONPATH=src python benchmarks/bench_paper_flight_identification.py [--seeds 205 1 2 3 4 5]
                                                                         [--committed]

``tests/test_identify.py`` identifies one committed log, ``sitl_logs/flight_healthy_calm.csv`` (the
scenario ``flight/healthy_calm``, seed 205), and bounds J within 30 % and each motor's R at the true ESC
map within 10 %. This flies that scenario again with the simulator as it is now, at each seed asked,
writes each flight as the CSV ``sitl_logs`` holds, and identifies it the test's two ways: ``identify``
from a weak start (C_p 1e-9, no B, T_f or J: J's error printed) and ``electrical_balance_at`` at the true
map (idle offset 0, input side: the worst motor's R error printed), with k_e's error. ``--committed`` adds
the committed log itself, for comparison (it was written by an earlier simulator; docs/flight.md, "World
1006's stalls: the simulator's bus, not the diagnosis").
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
from pathlib import Path

from mav_motor_health.config import load_motor_params
from mav_motor_health.model.identify import electrical_balance_at, identify
from mav_motor_health.sim.engine import run_scenario
from mav_motor_health.sim.scenario import load_scenario
from mav_motor_health.sim.writers import write_record
from mav_motor_health.telemetry import sources
from mav_motor_health.telemetry.table import TelemetryTable

COMMITTED = Path(__file__).resolve().parents[1] / "sitl_logs" / "flight_healthy_calm.csv"


def errors(table: TelemetryTable) -> tuple[float, float, float]:
    """J's and k_e's relative errors from ``identify``, and the worst motor's R error at the true map."""
    truth = load_motor_params()
    p = identify(table, truth.replace(C_p=1e-9, B=0.0, T_f=0.0, J_kg_m2=None)).params
    assert p.J_kg_m2 is not None and truth.J_kg_m2 is not None
    fits = electrical_balance_at(table, 0.0, "input")
    worst_r = max(abs(r_ohm / truth.R_ohm - 1.0) for _, r_ohm in fits.values())
    return p.J_kg_m2 / truth.J_kg_m2 - 1.0, p.k_e / truth.k_e - 1.0, worst_r


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[205, 1, 2, 3, 4, 5])
    ap.add_argument("--committed", action="store_true", help="identify the committed log too")
    args = ap.parse_args(argv)
    print(
        "flight/healthy_calm (60 s, calm), identified as tests/test_identify.py does (bounds: J 30 %, R 10 %)"
    )
    print(f"{'flight':>28}  {'J':>8}  {'k_e':>8}  {'worst R':>8}")
    if args.committed:
        j, k_e, r = errors(sources.read(COMMITTED))
        print(f"{'committed sitl_logs':>28}  {j:+8.1%}  {k_e:+8.1%}  {r:8.1%}")
    scenario = load_scenario("flight/healthy_calm")
    with tempfile.TemporaryDirectory() as folder:
        for seed in args.seeds:
            path = Path(folder) / f"seed{seed}.csv"
            write_record(run_scenario(dataclasses.replace(scenario, seed=seed)), path)
            j, k_e, r = errors(sources.read(path))
            print(f"{'flown now, seed ' + str(seed):>28}  {j:+8.1%}  {k_e:+8.1%}  {r:8.1%}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
