"""Seeded damaged copies of every log format replay reads: never a traceback, never a hang.

The benchmark (benchmarks/bench_fuzz.py) runs 1,250 such copies; this test runs a seeded sample of them
and the two fixed checks (truncation at 90 %, one flipped byte) on each format.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mav_motor_health.evaluation.damage import (
    DAMAGE_KINDS,
    count_samples,
    damaged_copies,
    dataflash_text,
    run_case,
)

SITL_LOGS = Path(__file__).resolve().parents[2] / "sitl_logs"


def _logs(real_logs: Path) -> list[Path]:
    return [
        SITL_LOGS / "flight_healthy_long.tlog",
        SITL_LOGS / "flight_F4.1_moderate.bin",
        SITL_LOGS / "flight_F4.1_moderate.csv",
        real_logs / "px4" / "esc_status_log.ulg",
        real_logs / "ardupilot" / "mechanical_fail.log",
    ]


@pytest.mark.slow
@pytest.mark.parametrize("index", range(5))
def test_damaged_logs_end_in_samples_or_a_clear_error(real_logs, tmp_path, index: int) -> None:
    log = _logs(real_logs)[index]
    outcomes = []
    for case in damaged_copies(log.read_bytes(), log.suffix, seed=7, count=3 * len(DAMAGE_KINDS)):
        path = tmp_path / f"case{log.suffix}"
        path.write_bytes(case.data)
        result = run_case(path, limit_s=60.0)
        assert result.outcome in ("ok", "error"), f"{case.kind} seed {case.seed}: {result.message}"
        outcomes.append(result.outcome)
    if log.name != "mechanical_fail.log":  # no ESC records at all: a clear error every time
        assert outcomes.count("ok") >= len(outcomes) // 2


@pytest.mark.parametrize("index", range(5))
def test_truncation_and_one_flipped_byte_keep_almost_every_sample(real_logs, tmp_path, index: int) -> None:
    if (
        index == 4
    ):  # DataFlash text with ESC records: a rendering of the simulated .bin (no public one has them)
        log = tmp_path / "rendered.log"
        log.write_text(dataflash_text(SITL_LOGS / "flight_F4.1_moderate.bin"), encoding="utf-8")
    else:
        log = _logs(real_logs)[index]
    data = log.read_bytes()
    intact = count_samples(log)
    path = tmp_path / f"cut{log.suffix}"
    path.write_bytes(data[: int(0.9 * len(data))])
    cut = run_case(path)
    assert cut.outcome == "ok" and cut.samples >= 0.89 * intact
    rng = np.random.default_rng(index)
    for _ in range(5):
        damaged = bytearray(data)
        damaged[int(rng.integers(0, len(data)))] ^= int(rng.integers(1, 256))
        path.write_bytes(bytes(damaged))
        flipped = run_case(path)
        assert flipped.outcome == "ok" and flipped.samples >= 0.999 * intact, flipped.message


def test_a_text_log_with_bits_flipped_in_its_esc_records_reads_or_fails_clearly(tmp_path) -> None:
    """The benchmark's first run over a text log with ESC records found 14 tracebacks, all with scattered
    bit flips: a damaged instance or PWM read as NaN and cast to an integer, an ESC index in the millions,
    a parameter name damaged into a number. These are the copies of that run (seed 1)."""
    rendered = dataflash_text(SITL_LOGS / "flight_F4.1_moderate.bin").encode()
    path = tmp_path / "case.log"
    cases = [c for c in damaged_copies(rendered, ".log", seed=1, count=100) if c.kind == "flip_bits"]
    assert len(cases) >= 12
    for case in cases:
        path.write_bytes(case.data)
        result = run_case(path, limit_s=60.0)
        assert result.outcome in ("ok", "error"), f"seed {case.seed}: {result.message}"
