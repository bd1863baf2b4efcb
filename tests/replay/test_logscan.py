"""The readers' shared byte helpers: MAVLink's CRC two bytes a step, payload zero-padding."""

from __future__ import annotations

import numpy as np
from pymavlink.generator.mavcrc import x25crc

from mav_motor_health.telemetry._logscan import crc_x25_rows, gather_rows, zero_past


def test_crc_matches_pymavlink_for_odd_and_even_lengths() -> None:
    rng = np.random.default_rng(11)
    rows = rng.integers(0, 256, (300, 70), dtype=np.uint8)
    lengths = rng.integers(0, 71, 300)
    lengths[:4] = [0, 1, 2, 70]
    for extra in (0, 115, 255):
        got = crc_x25_rows(rows, lengths, extra)
        for row, length, crc in zip(rows, lengths.tolist(), got.tolist()):
            reference = x25crc(bytes(row[:length]))
            reference.accumulate(bytes([extra]))
            assert crc == reference.crc, (length, extra)


def test_gathered_rows_are_zero_past_their_lengths() -> None:
    data = np.arange(1, 101, dtype=np.uint8)
    offsets = np.array([0, 10, 95])
    rows = gather_rows(data, offsets, 8, np.array([8, 3, 8]))
    assert rows.tolist() == [
        [1, 2, 3, 4, 5, 6, 7, 8],
        [11, 12, 13, 0, 0, 0, 0, 0],
        [96, 97, 98, 99, 100, 0, 0, 0],  # past the end of the data
    ]
    every_row_short = zero_past(np.ones((3, 4), dtype=np.uint8), np.array([0, 2, 3]))
    assert every_row_short.tolist() == [[0, 0, 0, 0], [1, 1, 0, 0], [1, 1, 1, 0]]
