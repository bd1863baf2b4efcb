"""Produce every figure and text excerpt of docs/workbench.md (run from the repository root).

    PYTHONPATH=src python docs/workbench/make_figures.py [--work DIR]

The worked example: a synthetic flight-like session of the paper's motor in which two effects are
hidden — the ESC reports its *bus* current and has a throttle offset (``esc_pwm``), and the winding
resistance rises with temperature (``resistance_temperature``) — run through the very commands a user
types: compare, explain, fit --with, explain again, compare again. Then the real DTU bench file.
Outputs: PNGs and the commands' text output under docs/workbench/; the session CSV and fitted TOMLs
under --work (default build/workbench-example, not committed).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import shutil
import sys
from pathlib import Path

import numpy as np

from mav_motor_health.cli import main
from mav_motor_health.config import load_motor_params
from mav_motor_health.model.effects import BUILTIN_EFFECTS
from mav_motor_health.sim.steady import SensorNoise
from mav_motor_health.telemetry.csv import write_csv
from mav_motor_health.workbench.synthetic import hidden_effect_session

DOCS = Path(os.path.relpath(Path(__file__).resolve().parent))


def run(argv: list[str], transcript: str | None = None) -> None:
    buffer = io.StringIO()
    with contextlib.redirect_stdout(buffer):
        code = main(argv)
    text = buffer.getvalue()
    sys.stdout.write(f"$ mav-motor-health {' '.join(argv)}\n{text}\n")
    if code != 0:
        raise SystemExit(f"command failed ({code}): {argv}")
    if transcript:
        (DOCS / transcript).write_text(f"$ mav-motor-health {' '.join(argv)}\n{text}", encoding="utf-8")


def real_bench_root() -> Path:
    for parent in Path(__file__).resolve().parents:
        candidate = parent / "shared" / "real_logs" / "bench"
        if candidate.is_dir():
            return candidate
    raise SystemExit("shared/real_logs/bench not found above the repository")


def main_script() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", default="build/workbench-example", help="folder for data and fitted models")
    work = Path(parser.parse_args().work)
    if work.exists():
        shutil.rmtree(work)
    work.mkdir(parents=True)
    for old in DOCS.glob("*.png"):
        old.unlink()

    motor = load_motor_params("paper_x2212")
    hidden = [
        (BUILTIN_EFFECTS["esc_pwm"], {"throttle_offset": 0.05, "bus_current_fraction": 1.0}),
        (BUILTIN_EFFECTS["resistance_temperature"], {"alpha_per_k": 0.0039}),
    ]
    table = hidden_effect_session(
        motor,
        np.random.default_rng(2026),
        hidden,
        duration_s=900.0,
        throttle_range=(0.08, 1.0),
        noise=SensorNoise(speed_rad_s=3.0, current_low_a=0.05, current_high_a=0.3),
    )
    session = work / "session.csv"
    write_csv(table, session)

    run(["compare", str(session), "--plot-dir", str(work / "before")], "compare_before.txt")
    for name in ("measured_vs_model_voltage_v.png", "residuals_vs_variables.png"):
        shutil.copy(work / "before" / name, DOCS / f"before_{name}")
    run(["explain", str(session)], "explain_1.txt")
    run(["fit", str(session), "--with", "esc_pwm", "--out", str(work / "step1.toml")])
    run(["explain", str(session), "--params", str(work / "step1.toml")], "explain_2.txt")
    run(
        [
            "fit",
            str(session),
            "--with",
            "esc_pwm,resistance_temperature",
            "--plot",
            str(DOCS / "fit_steps.png"),
            "--out",
            str(work / "repaired.toml"),
        ],
        "fit_with.txt",
    )
    run(
        ["compare", str(session), "--params", str(work / "repaired.toml"), "--plot-dir", str(work / "after")],
        "compare_after.txt",
    )
    for name in ("measured_vs_model_voltage_v.png", "residuals_vs_variables.png"):
        shutil.copy(work / "after" / name, DOCS / f"after_{name}")

    bench = real_bench_root()
    dtu = bench / "dtu" / "3508-700_14x5.5.txt"
    run(["explain", str(dtu)], "real_dtu_explain.txt")
    run(
        ["fit", str(dtu), "--with", "esc_pwm", "--plot", str(DOCS / "real_dtu_fit_steps.png")],
        "real_dtu_fit.txt",
    )
    run(["explain", str(bench.parent / "px4" / "esc_status_log.ulg")], "real_px4_explain.txt")
    straw = [str(bench / "strawson" / "rawdata" / f"g5_{s}.csv") for s in (7, 11)]
    run(["explain", *straw], "real_strawson_explain.txt")
    run(["compare", *straw, "--plot-dir", str(work / "strawson")], "real_strawson_compare.txt")
    shutil.copy(
        work / "strawson" / "measured_vs_model_voltage_v.png", DOCS / "real_strawson_measured_vs_model.png"
    )


if __name__ == "__main__":
    main_script()
