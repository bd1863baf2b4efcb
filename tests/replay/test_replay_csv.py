"""The vectorised CSV writer: exactly the text of a plain one-value-at-a-time formatting.

diagnosis.csv must not change when the writer gets faster: time to the microsecond, other numbers to 4
decimals (rounded half to even after scaling, trailing zeros dropped), missing values empty, states as
labels. These tests pin that text on tables with NaN, ±inf, negatives, -0.0, values that round to zero,
rounding ties (0.00005), carries (999.99995), values past the int64 range of the scaled digits and
beyond the 1e15 cap, and on many chunks.
"""

from __future__ import annotations

import io

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mav_motor_health import replay_csv
from mav_motor_health.replay_csv import Column, format_number, write_csv_columns

LABELS = ["NORMAL", "F1.1", "F3.1", "SENSOR_FAULT", "UNCALIBRATED"]
EDGES = [
    0.0,
    -0.0,
    0.00005,
    -0.00005,
    0.00015,
    0.00004999,
    1.00005,
    2.5,
    -2.5,
    999.99995,
    9999.99995,
    12.5,
    -12.34567,
    0.1 + 0.2,
    1e-12,
    123456789.123456,
    -98765432.1,
    4.6e14,  # x 1e4 passes int64's 2**62: written one by one
    1e15,  # the cap
    1e20,  # beyond the cap: written as the cap
    -3e17,
    float("nan"),
    float("inf"),
    float("-inf"),
]


def plain_csv(columns: list[Column]) -> str:
    """The reference: every cell formatted on its own with Python (format_number or the label)."""
    lines = [",".join(name for name, _, _ in columns)]
    for i in range(len(columns[0][1])):
        cells = []
        for _, values, how in columns:
            if isinstance(how, int):
                cells.append(format_number(values[i], how))
            else:
                cells.append(how[int(values[i])])
        lines.append(",".join(cells))
    return "\n".join(lines) + "\n"


def fast_csv(columns: list[Column]) -> str:
    buffer = io.BytesIO()
    write_csv_columns(buffer, columns)
    return buffer.getvalue().decode("ascii")


def test_format_number_is_the_documented_rule() -> None:
    cases = {
        (0.00005, 4): "0",  # 0.5 after scaling: half to even
        (0.00015, 4): "0.0001",  # 1.4999… after scaling
        (-0.00005, 4): "0",  # no sign on a zero
        (-0.0, 4): "0",
        (2.5, 0): "2",
        (3.5, 0): "4",
        (999.99995, 4): "1000",
        (1234.56789, 4): "1234.5679",
        (-12.5, 4): "-12.5",
        (3599.999999, 6): "3599.999999",
        (0.04, 6): "0.04",
        (1e20, 4): "1000000000000000",
        (-1e20, 6): "-1000000000000000",
        (float("nan"), 4): "",
        (float("-inf"), 4): "",
        (-7, 0): "-7",
    }
    for (value, decimals), text in cases.items():
        assert format_number(value, decimals) == text, (value, decimals)


def test_a_diagnosis_like_table_is_written_exactly() -> None:
    time_s = np.array([0.04, 1.5, 3599.999999, 0.0000005, 12.0])
    columns: list[Column] = [
        ("time_s", time_s, 6),
        ("motor", np.array([1, 2, 3, 4, 6], dtype=np.int64), 0),
        ("state", np.array([0, 2, 3, 4, 0], dtype=np.int8), LABELS),
        ("steady", np.array([1, 0, 1, 0, 0], dtype=np.int64), 0),
        ("omega_rad_s", np.array([560.66964, np.nan, -0.00004, 0.00005, 1e20]), 4),
        ("sensor_flags", np.array([0, 128, 2, 0, 8], dtype=np.int16), 4),
    ]
    assert fast_csv(columns) == (
        "time_s,motor,state,steady,omega_rad_s,sensor_flags\n"
        "0.04,1,NORMAL,1,560.6696,0\n"
        "1.5,2,F3.1,0,,128\n"
        "3599.999999,3,SENSOR_FAULT,1,0,2\n"
        "0,4,UNCALIBRATED,0,0,0\n"
        "12,6,NORMAL,0,1000000000000000,8\n"
    )


@pytest.mark.parametrize("chunk_rows", [3, 1000])
def test_edge_values_in_every_column_kind_match_the_plain_formatting(
    chunk_rows: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(replay_csv, "CHUNK_ROWS", chunk_rows)
    rng = np.random.default_rng(18)
    edges = np.array(EDGES)
    n = 4 * len(edges)
    values = np.concatenate([edges, -edges, edges * 1e-3, rng.permutation(edges)])
    columns: list[Column] = [("time_s", np.sort(rng.uniform(0, 20_000, n)), 6)]
    columns += [(f"x{d}", np.roll(values, d), d) for d in range(9)]
    columns += [
        ("big_int", rng.integers(-(10**12), 10**12, n), 4),
        ("flag", rng.integers(0, 2, n).astype(bool), 0),
        ("state", rng.integers(0, len(LABELS), n), LABELS),
        ("unsigned", np.abs(values), 4),
    ]
    assert fast_csv(columns) == plain_csv(columns)


def test_columns_without_finite_values_and_labels_not_used() -> None:
    columns: list[Column] = [
        ("all_nan", np.full(4, np.nan), 4),
        ("infinite", np.array([np.inf, -np.inf, np.nan, np.inf]), 6),
        ("state", np.zeros(4, dtype=np.int8), LABELS),
    ]
    assert fast_csv(columns) == "all_nan,infinite,state\n" + ",,NORMAL\n" * 4


def test_header_only_when_empty() -> None:
    assert fast_csv([("time_s", np.zeros(0), 6), ("state", np.zeros(0, dtype=np.int8), LABELS)]) == (
        "time_s,state\n"
    )


def test_label_code_outside_the_labels_is_an_error() -> None:
    with pytest.raises(IndexError):
        fast_csv([("state", np.array([0, len(LABELS)]), LABELS)])


numbers = st.one_of(
    st.floats(min_value=-1e9, max_value=1e9),
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(-(10**6), 10**6).map(lambda k: k / 20_000),  # ties at 4 decimals
)


@settings(max_examples=150, deadline=None, derandomize=True)
@given(values=st.lists(numbers, min_size=1, max_size=60), decimals=st.integers(0, 8))
def test_random_numbers_match_the_plain_formatting(values: list[float], decimals: int) -> None:
    columns: list[Column] = [("x", np.array(values, dtype=float), decimals), ("n", np.arange(len(values)), 0)]
    assert fast_csv(columns) == plain_csv(columns)
