"""A damaged or implausible CSV loses the rows concerned, says so with the line, and keeps the rest."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from mav_motor_health.errors import DataError
from mav_motor_health.telemetry.csv import read_csv

SITL_LOGS = Path(__file__).resolve().parents[2] / "sitl_logs"
HEADER = "time_s,motor,rpm,current_a,voltage_v\n"


def _read(path: Path) -> tuple[object, list[str]]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        table = read_csv(path)
    return table, [str(w.message) for w in caught]


def _rows(n: int) -> list[str]:
    return [f"{0.02 * k:.2f},{1 + k % 6},{6000 + k},{3.5 + 0.001 * k},{7.0}\n" for k in range(n)]


def test_a_byte_that_is_not_utf8_loses_its_line_not_the_file(tmp_path) -> None:
    source = (SITL_LOGS / "flight_F4.1_moderate.csv").read_bytes()
    intact, _ = _read(SITL_LOGS / "flight_F4.1_moderate.csv")
    at = 141242
    damaged = bytearray(source)
    damaged[at] = 0xFF
    path = tmp_path / "damaged.csv"
    path.write_bytes(bytes(damaged))
    table, said = _read(path)
    line = source[:at].count(b"\n") + 1
    assert len(table) == len(intact) - 1
    (message,) = [m for m in said if "not UTF-8" in m]
    assert f"line {line}" in message and f"byte {at}" in message and str(path) in message


def test_a_file_of_binary_bytes_is_refused_clearly(tmp_path) -> None:
    path = tmp_path / "binary.csv"
    path.write_bytes(bytes(range(128, 256)) * 8)
    with pytest.raises(DataError, match="not a text CSV file"):
        read_csv(path)


@pytest.mark.parametrize(
    ("bad_row", "what"),
    [
        ("1.00,2,-6000,3.5,7.0\n", "negative rpm"),
        ("inf,2,6000,3.5,7.0\n", "no finite time_s"),
        ("1.00,2,6000\n", "another number of cells"),
        ("1.00,99,6000,3.5,7.0\n", "no valid motor number"),
        ("1.00,2.5,6000,3.5,7.0\n", "no valid motor number"),
    ],
)
def test_impossible_or_short_rows_are_left_out_and_counted(tmp_path, bad_row: str, what: str) -> None:
    rows = _rows(40)
    rows[17] = bad_row
    path = tmp_path / "t.csv"
    path.write_text(HEADER + "".join(rows), encoding="utf-8")
    table, said = _read(path)
    assert len(table) == 39
    (message,) = [m for m in said if what in m]
    assert "1 row(s)" in message and "line 19" in message and "skipped" in message
    assert np.all(np.isfinite(table["time_s"])) and np.all(table["omega_rad_s"] >= 0)
    assert set(table["motor"].tolist()) <= set(range(1, 7))


def test_windows_line_ends_and_a_byte_order_mark_read_as_usual(tmp_path) -> None:
    path = tmp_path / "crlf.csv"
    path.write_bytes(b"\xef\xbb\xbf" + (HEADER + "".join(_rows(12))).replace("\n", "\r\n").encode())
    table, said = _read(path)
    assert len(table) == 12 and not said
