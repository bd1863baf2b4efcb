"""The report's SVG paths and bands, formatted a stretch at a time: the same text as point by point;
each motor's rows as a slice of the diagnosis' result."""

from __future__ import annotations

import math

import numpy as np

from mav_motor_health.replay import has_rows, motor_numbers, rows_by_motor
from mav_motor_health.replay_report import _band, _path


def plain_path(xs: np.ndarray, ys: np.ndarray) -> str:
    parts, pen_down = [], False
    for x, y in zip(xs.tolist(), ys.tolist()):
        if not (math.isfinite(x) and math.isfinite(y)):
            pen_down = False
            continue
        parts.append(f"{'L' if pen_down else 'M'}{x:.1f},{y:.1f}")
        pen_down = True
    return "".join(parts)


def plain_band(xs: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> str:
    ok = np.isfinite(xs) & np.isfinite(lo) & np.isfinite(hi)
    if ok.sum() < 2:
        return ""
    x, a, b = xs[ok], lo[ok], hi[ok]
    points = [f"{u:.1f},{v:.1f}" for u, v in zip(x.tolist(), b.tolist())]
    points += [f"{u:.1f},{v:.1f}" for u, v in zip(x[::-1].tolist(), a[::-1].tolist())]
    return " ".join(points)


def test_paths_and_bands_match_point_by_point_formatting() -> None:
    rng = np.random.default_rng(5)
    xs = np.linspace(64.0, 884.0, 400)
    ys = rng.normal(80.0, 60.0, 400)
    ys[[0, 5, 6, 7, 200, 399]] = np.nan
    ys[[10, 11]] = [-0.04, 0.25]  # "-0.0" and a tie
    xs[50] = np.inf
    lo, hi = ys - 5.0, ys + 5.0
    hi[300] = np.nan
    assert _path(xs, ys) == plain_path(xs, ys)
    assert _band(xs, lo, hi) == plain_band(xs, lo, hi)
    for n in (0, 1, 2):
        assert _path(xs[:n], ys[:n]) == plain_path(xs[:n], ys[:n])
        assert _band(xs[:n], lo[:n], hi[:n]) == plain_band(xs[:n], lo[:n], hi[:n])
    nothing = np.full(3, np.nan)
    assert _path(nothing, nothing) == ""


def test_rows_by_motor_are_slices_when_grouped_and_masks_otherwise() -> None:
    grouped = np.array([1, 1, 2, 2, 2, 4])
    rows = rows_by_motor(grouped, [1, 2, 3, 4])
    assert rows == {1: slice(0, 2), 2: slice(2, 5), 3: slice(5, 5), 4: slice(5, 6)}
    assert [has_rows(rows[m]) for m in (1, 2, 3, 4)] == [True, True, False, True]
    mixed = np.array([2, 1, 2])
    masks = rows_by_motor(mixed, [1, 2, 5])
    assert [masks[m].tolist() for m in (1, 2, 5)] == [[False, True, False], [True, False, True], [False] * 3]


def test_motor_numbers_with_and_without_grouped_rows() -> None:
    assert motor_numbers(np.array([1, 1, 2, 4, 4])) == [1, 2, 4]
    assert motor_numbers(np.array([3, 1, 3])) == [1, 3]
    assert motor_numbers(np.zeros(0, dtype=np.int64)) == []
