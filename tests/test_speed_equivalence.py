"""The faster forms of issue 18's second round give what the forms they replace give, value for value."""

from __future__ import annotations

import numpy as np
import pytest

from mav_motor_health._arrays import distinct
from mav_motor_health.diagnosis.persistence import _first_held
from mav_motor_health.diagnosis.pipeline import _motor_rows_in_time
from mav_motor_health.replay_report import _decimal_cells
from mav_motor_health.telemetry._logscan import crc_x25_rows, zero_past
from mav_motor_health.telemetry.assemble import HeldValues, _copied_runs, _distinct_runs
from mav_motor_health.telemetry.mavlink_messages import _since_first


def test_distinct_is_unique_with_counts() -> None:
    rng = np.random.default_rng(0)
    for values in (
        rng.integers(0, 300, 1000),
        rng.integers(0, 3, 50).astype(np.uint8),
        rng.integers(-5, 5, 40),  # negative: numpy's own
        np.array([70_000, 3, 70_000]),  # beyond the counted range
        np.zeros(0, dtype=np.int64),
    ):
        got, want = distinct(values), np.unique(values, return_counts=True)
        for g, w in zip(got, want):
            assert g.dtype == np.int64
            np.testing.assert_array_equal(g, w)


@pytest.mark.parametrize("decimals", [1, 2])
def test_decimal_cells_write_what_python_writes(decimals: int) -> None:
    rng = np.random.default_rng(1)
    values = np.concatenate(
        [rng.normal(0, 400, 5000), [0.0, -0.0, -0.04, 0.04, 9.96, -999.9, 1234567.89, 1e-300]]
    )
    cells = _decimal_cells(values, decimals)
    assert cells is not None
    got = [row.tobytes().replace(b"\0", b"").decode() for row in cells]
    assert got == [f"{v:.{decimals}f}" for v in values.tolist()]
    # ties, values beyond the cap and non-finite values are left to Python's formatting
    for odd in ([0.25], [0.35], [1e8], [np.nan], [np.inf]):
        assert _decimal_cells(np.array(odd), 1) is None


def test_crc_and_zero_past_from_any_row_layout() -> None:
    rng = np.random.default_rng(2)
    rows = rng.integers(0, 256, (40, 13), dtype=np.uint8)
    lengths = rng.integers(0, 12, 40)

    def one(row: np.ndarray, n: int, extra: int) -> int:  # the X.25 CRC, byte by byte
        crc = 0xFFFF
        for byte in [*row[:n].tolist(), extra]:
            tmp = byte ^ (crc & 0xFF)
            tmp = (tmp ^ (tmp << 4)) & 0xFF
            crc = ((crc >> 8) ^ (tmp << 8) ^ (tmp << 3) ^ (tmp >> 4)) & 0xFFFF
        return crc

    for layout in (rows, rows[:, ::-1], rows[:, 1:], np.asfortranarray(rows)):
        want = [one(r, n, 77) for r, n in zip(layout, lengths.tolist())]
        assert crc_x25_rows(layout, lengths, 77).tolist() == want
    for lengths_ in (lengths, np.full(40, 5), np.full(40, 20), rng.integers(10, 14, 40)):
        want = np.where(np.arange(13)[None, :] < lengths_[:, None], rows, 0)
        np.testing.assert_array_equal(zero_past(rows.copy(), lengths_), want)


def test_held_once_per_distinct_run_of_times() -> None:
    rng = np.random.default_rng(3)
    a, b = np.sort(rng.random(30)), np.sort(rng.random(20))
    targets = np.concatenate([a, a, b, a, b])
    kept, runs = _distinct_runs(targets)
    assert runs is not None and kept.size == a.size + b.size
    source = np.sort(rng.random(15))
    values = rng.random((15, 2))
    once, _ = HeldValues(2, 0.1).hold(source, values, kept)
    whole, _ = HeldValues(2, 0.1).hold(source, values, targets)
    for k in range(2):
        np.testing.assert_array_equal(_copied_runs(once[:, k], runs), whole[:, k])
    assert _distinct_runs(np.concatenate([a, b]))[1] is None


def test_since_first_is_a_running_or() -> None:
    rng = np.random.default_rng(4)
    for flags in (rng.random((4, 30)) < 0.05, np.zeros((3, 5), bool), np.ones((2, 4), bool)):
        np.testing.assert_array_equal(_since_first(flags), np.logical_or.accumulate(flags, axis=1))


def test_first_held_is_run_by_run() -> None:
    rng = np.random.default_rng(5)
    weighted = rng.random(300) * 0.05
    need = rng.random(300) * 0.6
    bounds = np.sort(rng.choice(np.arange(1, 300), 40, replace=False))
    starts, ends = np.concatenate([[0], bounds]), np.concatenate([bounds, [300]])
    candidates = np.sort(rng.choice(np.arange(starts.size), 25, replace=False))
    want = np.full(starts.size, -1)
    for r in candidates.tolist():
        held = (0.3 if r == 0 else 0.0) + np.cumsum(weighted[starts[r] : ends[r]])
        found = np.flatnonzero(held >= need[starts[r] : ends[r]])
        if found.size:
            want[r] = starts[r] + found[0]
    np.testing.assert_array_equal(_first_held(weighted, need, starts, ends, 0.3, candidates), want)


def test_motor_rows_in_time_order() -> None:
    motor = np.array([1, 1, 1, 2, 2, 4])
    time_s = np.array([0.0, 1.0, 2.0, 0.0, 2.0, 1.0])
    by_time = np.argsort(time_s, kind="stable")
    rows = _motor_rows_in_time(motor, by_time)
    assert rows is not None
    for m, at in rows.items():
        np.testing.assert_array_equal(at, np.flatnonzero(motor[by_time] == m))
    assert _motor_rows_in_time(np.array([2, 1]), np.array([0, 1])) is None
