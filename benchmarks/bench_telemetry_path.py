"""The flight profile on the same healthy flights as the simulator's table and as each log format carries
them: how much the telemetry path costs.

    PYTHONPATH=src python benchmarks/bench_telemetry_path.py [--seconds 60] [--seed 205]

The benchmark flights (``bench_flight.py``) give the diagnosis each ESC sample with the motor command
of the same instant. A log does not: a .tlog's ESC_TELEMETRY messages carry each ESC's *last* packet,
without its time, beside the command of the message's moment (SERVO_OUTPUT_RAW); a .bin's ESC records
have their own times, but the command (RCOU) is logged at its own rate and the reader takes the latest
one. The balance rule needs the voltage the motor saw when it was measured, so a command up to a
message interval off adds noise that the tuned bands do not cover.

For a calm and a gusty healthy flight (``flight/healthy_calm``'s manoeuvres), this prints, per path,
the share of the measured samples that are judged, the share of judged samples that are NORMAL (— where
none is judged) and the false fault events, and for the logs the same without the pairing rule
(``diagnosis/pairing.py``: the samples' ``pairing_s`` column and the log's summary left out): the simulator's table (as
``bench_flight.py`` sees it), CSV (the same), .bin with RCOU at 10 and 50 Hz, .tlog with
ESC_TELEMETRY and SERVO_OUTPUT_RAW at 10, 50, 100 and 200 Hz (the ESCs themselves report at 10–50 Hz;
the stream rate bounds how much older than its message's command a packet can be). Then the fault flights
of ``bench_flight.py`` (same seeds and motors) as the table and as a .tlog at 200 Hz, the rate the agent
asks for, with the vehicle's battery monitor: mean accuracy after onset, detection time, NORMAL and false
events per fault and turbulence level.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "src"))

from mav_motor_health.config import load_motor_params, load_profile  # noqa: E402
from mav_motor_health.diagnosis import diagnose  # noqa: E402
from mav_motor_health.evaluation.campaign import (  # noqa: E402
    FAULTS,
    TURBULENCE_LEVELS,
    FlightCase,
    benchmark_fault_cases,
    scenario_for,
    table_columns,
)
from mav_motor_health.evaluation.score import score  # noqa: E402
from mav_motor_health.sim.engine import run_scenario  # noqa: E402
from mav_motor_health.sim.scenario import load_scenario  # noqa: E402
from mav_motor_health.sim.writers import write_record  # noqa: E402
from mav_motor_health.telemetry import sources  # noqa: E402
from mav_motor_health.telemetry.table import TelemetryTable  # noqa: E402

PATHS = (
    ("table", None, None),
    ("csv", ".csv", 10.0),
    ("bin, RCOU 10 Hz", ".bin", 10.0),
    ("bin, RCOU 50 Hz", ".bin", 50.0),
    ("tlog, 10 Hz", ".tlog", 10.0),
    ("tlog, 50 Hz", ".tlog", 50.0),
    ("tlog, 100 Hz", ".tlog", 100.0),
    ("tlog, 200 Hz", ".tlog", 200.0),
)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--seed", type=int, default=205)
    args = parser.parse_args()
    params = load_motor_params("paper_x2212")
    profile = load_profile("flight")
    base = load_scenario("flight/healthy_calm")
    start = time.monotonic()
    print(
        f"healthy flights of {args.seconds:.0f} s (flight/healthy_calm manoeuvres, seed {args.seed}), profile flight"
    )
    print(
        f"{'turbulence':10s} {'path':16s} {'judged':>7s} {'NORMAL':>8s} {'false events':>13s}"
        f"   {'without the pairing rule: NORMAL':>32s} {'false':>6s}"
    )
    with tempfile.TemporaryDirectory() as tmp:
        for turbulence in ("calm", "gusty"):
            for name, ext, rate_hz in PATHS:
                scenario = dataclasses.replace(
                    base,
                    seed=args.seed,
                    duration_s=args.seconds,
                    flight=dataclasses.replace(base.flight, turbulence=turbulence),
                    esc_stream_hz=rate_hz or base.esc_stream_hz,
                    log_hz=rate_hz or base.log_hz,
                )
                record = run_scenario(scenario)
                if ext is None:  # as the benchmark flights see it
                    table = TelemetryTable(table_columns(record), source="simulator")
                else:
                    out, _ = write_record(
                        record, Path(tmp) / f"{turbulence}_{name.split(',')[0]}{ext}", force=True
                    )
                    table = sources.read(out)
                result = diagnose(table, params, profile)
                healthy = score({c: result[c] for c in result.names}, scenario.truth())
                measured = np.isfinite(result["omega_rad_s"]) | np.isfinite(result["current_a"])
                judged = 100.0 * np.mean(result["steady"][measured])
                normal = healthy.normal_accuracy_pct
                shown = "      —" if normal is None else f"{normal:7.2f}%"
                line = f"{turbulence:10s} {name:16s} {judged:6.1f}% {shown:>8s} {healthy.false_events:13d}"
                if table.meta.get("pairing_s") is not None:  # the same samples, their pairing not weighed
                    unpaired = {n: table[n] for n in table.names if n != "pairing_s"}
                    bare = diagnose(TelemetryTable(unpaired, source=table.source), params, profile)
                    unweighed = score({c: bare[c] for c in bare.names}, scenario.truth())
                    line += f"   {unweighed.normal_accuracy_pct:31.2f}% {unweighed.false_events:6d}"
                print(line)
        # 2. the benchmark's fault flights (bench_flight.py's seeds and motors) as the agent gets them: a
        # .tlog streamed at the 200 Hz it asks for (with the vehicle's battery monitor), against the table
        print("\nfault flights of bench_flight.py (2 per fault, fault at 25 s): table / .tlog at 200 Hz")
        print(
            f"{'turbulence':10s} {'fault':5s} {'accuracy':>17s} {'detect s':>17s} {'NORMAL':>17s} {'false':>7s}"
        )
        cases = benchmark_fault_cases()
        for turbulence in TURBULENCE_LEVELS:
            for fault in FAULTS:
                pair = [c for c in cases if c.turbulence == turbulence and c.fault == fault]
                print(fault_row(pair, params, profile, Path(tmp)))
    print(f"\n(benchmark took {time.monotonic() - start:.0f} s)")
    return 0


def fault_row(cases: list[FlightCase], params, profile, tmp: Path) -> str:
    """The flights of one fault and turbulence level: table against .tlog at 200 Hz."""
    rows: dict[str, list] = {"table": [], "tlog": []}
    for case in cases:
        scenario = dataclasses.replace(scenario_for(case), esc_stream_hz=200.0, log_hz=200.0)
        record = run_scenario(scenario)
        out, _ = write_record(record, tmp / f"{case.name}.tlog", force=True)
        for name, table in (
            ("table", TelemetryTable(table_columns(record), source="simulator")),
            ("tlog", sources.read(out)),
        ):
            result = diagnose(table, params, profile)
            rows[name].append(score({c: result[c] for c in result.names}, scenario.truth()))
    cells = []
    for attr in ("fault_accuracy_pct", "detection_s", "normal_accuracy_pct"):
        pair = [
            np.mean([np.nan if getattr(r, attr) is None else getattr(r, attr) for r in rows[n]]) for n in rows
        ]
        cells.append(f"{pair[0]:7.2f} / {pair[1]:7.2f}")
    false = [sum(r.false_events for r in rows[n]) for n in rows]
    return f"{cases[0].turbulence:10s} {cases[0].fault:5s} {cells[0]:>17s} {cells[1]:>17s} {cells[2]:>17s} {false[0]:3d} / {false[1]}"


if __name__ == "__main__":
    raise SystemExit(main())
