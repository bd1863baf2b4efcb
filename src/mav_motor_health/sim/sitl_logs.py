"""Regenerate the committed ``sitl_logs/`` set from the bundled scenarios (deterministic: every scenario
has its own seed)::

    PYTHONPATH=src python -m mav_motor_health.sim.sitl_logs sitl_logs --force

Writes every testbed scenario as CSV, each flight as CSV (one also as .tlog and .bin), the long healthy
flight as .tlog, each with its ``.truth.json``, and ``MANIFEST.md``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from ..config import PARAMS_DIR
from .engine import run_scenario
from .scenario import load_scenario
from .writers import truth_path, write_record

__all__ = ["generate"]

#: (scenario name, output file names)
FLIGHT_OUTPUTS = {
    "flight/F4.1_calm": ("flight_F4.1_calm.csv",),
    "flight/F4.1_moderate": (
        "flight_F4.1_moderate.csv",
        "flight_F4.1_moderate.tlog",
        "flight_F4.1_moderate.bin",
    ),
    "flight/F4.1_gusty": ("flight_F4.1_gusty.csv",),
    "flight/F2.1_moderate": ("flight_F2.1_moderate.csv",),
    "flight/F4.2_moderate": ("flight_F4.2_moderate.csv",),
    "flight/healthy_calm": ("flight_healthy_calm.csv",),
    "flight/healthy_long": ("flight_healthy_long.tlog",),
}


def _jobs() -> list[tuple[str, tuple[str, ...]]]:
    jobs: list[tuple[str, tuple[str, ...]]] = []
    for path in sorted((PARAMS_DIR / "scenarios" / "testbed").glob("*.toml")):
        jobs.append((f"testbed/{path.stem}", (f"testbed_{path.stem}.csv",)))
    jobs.extend(FLIGHT_OUTPUTS.items())
    return jobs


def generate(outdir: str | Path, *, force: bool = False, log: bool = True) -> list[Path]:
    outdir = Path(outdir)
    written: list[Path] = []
    rows = []
    for name, files in _jobs():
        scenario = load_scenario(name)
        record = run_scenario(scenario)
        for file in files:
            out, _ = write_record(record, outdir / file, force=force)
            written.append(out)
            truth = json.loads(truth_path(out).read_text())
            f = truth["faults"][0] if truth["faults"] else None
            rows.append(
                f"| `{file}` | `{name}` | {truth['mode']} | "
                + (f"{truth['voltage_v']} V" if truth["mode"] == "testbed" else str(truth["turbulence"]))
                + f" | {truth['duration_s']:.0f} s | "
                + (
                    "healthy"
                    if f is None
                    else f"{f['fault']} on motor {f['motor']} at {f['onset_s']:.1f} s, severity {f['severity']:g}"
                )
                + f" | {truth['seed']} |"
            )
            if log:
                print(f"wrote {out}", file=sys.stderr)
    manifest = outdir / "MANIFEST.md"
    manifest.write_text(
        "# Simulated logs with ground truth\n\n"
        "Made by the project's simulator (docs/simulator.md) from the scenarios in `params/scenarios/`; "
        "regenerate them, identically, with\n\n"
        "    PYTHONPATH=src python -m mav_motor_health.sim.sitl_logs sitl_logs --force\n\n"
        "Each file has a sidecar `<file>.truth.json` (fault, motor, onset, severity, turbulence, seed). "
        "CSV files are in the project's telemetry CSV format (`current_a` is the motor current, "
        "`esc_current_a` what the ESC reports: duty × motor current). Testbed files hold one motor (motor 1) "
        "at constant voltage, the paper's cases 4.2/5.8/7.6/9.2/11 V, fault at 10 s of 20 s.\n\n"
        "| file | scenario | mode | voltage / air | length | truth | seed |\n|---|---|---|---|---|---|---|\n"
        + "\n".join(rows)
        + "\n",
        encoding="utf-8",
    )
    written.append(manifest)
    return written


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description="regenerate the simulated sitl_logs set")
    p.add_argument("outdir")
    p.add_argument("--force", action="store_true")
    args = p.parse_args(argv)
    generate(args.outdir, force=args.force)
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
