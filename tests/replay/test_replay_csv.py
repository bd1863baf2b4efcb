"""The vectorised CSV writer: what it writes reads back as the rounded numbers and the labels."""

from __future__ import annotations

import csv
import io

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from mav_motor_health.replay_csv import fixed_point_bytes, write_csv_columns

numbers = st.one_of(st.floats(min_value=-1e9, max_value=1e9), st.just(float("nan")))


@settings(max_examples=100, deadline=None, derandomize=True)
@given(values=st.lists(numbers, min_size=1, max_size=50), decimals=st.integers(0, 6))
def test_fixed_point_reads_back_as_the_rounded_value(values: list[float], decimals: int) -> None:
    matrix = fixed_point_bytes(np.array(values), decimals)
    for value, row in zip(values, matrix):
        text = bytes(row[row != 0]).decode("ascii")
        if np.isnan(value):
            assert text == ""
            continue
        assert float(text) == float(np.round(abs(value) * 10**decimals) / 10**decimals) * (
            -1 if value < 0 and np.round(abs(value) * 10**decimals) > 0 else 1
        )
        assert not (decimals and "." in text and text.endswith("0")), text  # no trailing zeros


def test_columns_labels_and_missing_cells_round_trip() -> None:
    rng = np.random.default_rng(7)
    n = 1000
    time_s = np.sort(rng.uniform(0, 3600, n))
    codes = rng.integers(0, 3, n)
    values = rng.normal(0, 100, n)
    values[::17] = np.nan
    buffer = io.BytesIO()
    write_csv_columns(
        buffer, [("time_s", time_s, 6), ("state", codes, ["NORMAL", "F1.1", "F3.1"]), ("x", values, 4)]
    )
    rows = list(csv.DictReader(io.StringIO(buffer.getvalue().decode("ascii"))))
    assert len(rows) == n
    np.testing.assert_allclose([float(r["time_s"]) for r in rows], time_s, atol=5e-7, rtol=0)
    assert [r["state"] for r in rows] == [["NORMAL", "F1.1", "F3.1"][c] for c in codes]
    got = np.array([float(r["x"]) if r["x"] else np.nan for r in rows])
    np.testing.assert_allclose(got, values, atol=5e-5, rtol=0)
    assert np.array_equal(np.isnan(got), np.isnan(values))
