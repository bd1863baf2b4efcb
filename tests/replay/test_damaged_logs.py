"""Property tests: truncated and bit-flipped logs never crash or hang a reader, and the records before and
after the damage are still returned, unchanged.

Each format is exercised on a slice of a real log. Damage lands anywhere except in the definitions a
format cannot do without (DataFlash FMT records, the ULog definitions section): a damaged definition
legitimately loses its message type.
"""

from __future__ import annotations

import struct
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mav_motor_health.telemetry.dataflash import read_records
from mav_motor_health.telemetry.tlog import read_messages
from mav_motor_health.telemetry.ulog import read_ulog_topics

Records = dict[tuple[str, int], bytes]


def tlog_records(path: Path) -> Records:
    msgs = read_messages(path, warn=False)
    out: Records = {}
    for name, arr in msgs.messages.items():
        for offset, rec, stamp in zip(msgs.offsets[name].tolist(), arr, msgs.time_us[name]):
            out[(name, offset)] = rec.tobytes() + stamp.tobytes()
    return out


def tlog_span(data: bytes, offset: int) -> int:
    magic, length = data[offset + 8], data[offset + 9]
    if magic == 0xFE:
        return 8 + 6 + length + 2
    return 8 + 10 + length + 2 + (13 if data[offset + 10] & 1 else 0)


def bin_records(path: Path) -> Records:
    log = read_records(path, names=BIN_TYPES, warn=False)
    out: Records = {}
    for name, cols in log.records.items():
        table = np.rec.fromarrays(list(cols.values()), names=list(cols))
        for offset, row in zip(log.offsets[name].tolist(), table):
            out[(name, offset)] = row.tobytes()
    return out


def ulog_records(path: Path) -> Records:
    log = read_ulog_topics(path, ULOG_TOPICS, warn=False)
    out: Records = {}
    for (name, instance), arr in log.topics.items():
        for offset, rec in zip(log.offsets[(name, instance)].tolist(), arr):
            out[(f"{name}/{instance}", offset)] = rec.tobytes()
    return out


def ulog_span(data: bytes, offset: int) -> int:
    return 3 + struct.unpack_from("<H", data, offset)[0]


BIN_TYPES = ("FMT", "PARM", "MSG", "ESC", "RCOU", "BAT", "BARO", "CTUN", "ATT", "IMU", "GPS")
ULOG_TOPICS = (
    "esc_status",
    "actuator_outputs",
    "battery_status",
    "vehicle_local_position",
    "vehicle_air_data",
)


@dataclass(frozen=True)
class Sample:
    data: bytes
    records: Records
    span: Callable[[bytes, int], int]
    protected: tuple[tuple[int, int], ...]  # byte ranges kept intact
    decode: Callable[[Path], Records]


def _cut_at_record(records: Records, limit: int) -> int:
    return max(offset for _, offset in records if offset < limit)


@pytest.fixture(scope="module")
def samples(
    sitl_tlog: Path, sitl_bin: Path, px4_esc_ulg: Path, tmp_path_factory: pytest.TempPathFactory
) -> dict[str, Sample]:
    folder = tmp_path_factory.mktemp("slices")
    out: dict[str, Sample] = {}

    raw = sitl_tlog.read_bytes()[:400_000]
    part = folder / "part.tlog"
    part.write_bytes(raw)
    raw = raw[: _cut_at_record(tlog_records(part), 300_000)]
    part.write_bytes(raw)
    out["tlog"] = Sample(raw, tlog_records(part), tlog_span, (), tlog_records)

    raw = sitl_bin.read_bytes()[:1_200_000]
    part = folder / "part.bin"
    part.write_bytes(raw)
    raw = raw[: _cut_at_record(bin_records(part), 1_000_000)]
    part.write_bytes(raw)
    records = bin_records(part)
    log = read_records(part, ["FMT"], warn=False)
    fmt = tuple((int(o), int(o) + 89) for o in log.offsets["FMT"].tolist())
    lengths = {name: f.length for name, f in log.formats.items()}
    out["bin"] = Sample(raw, records, _bin_span(records, lengths), fmt, bin_records)

    raw = px4_esc_ulg.read_bytes()
    records = ulog_records(px4_esc_ulg)
    first_data = min(offset for _, offset in records)
    out["ulog"] = Sample(raw, records, ulog_span, ((0, first_data),), ulog_records)
    return out


def _bin_span(records: Records, lengths: dict[str, int]) -> Callable[[bytes, int], int]:
    by_offset = {offset: lengths[name] for name, offset in records}

    def span(data: bytes, offset: int) -> int:
        return by_offset.get(offset, 256)

    return span


damage_plans = st.fixed_dictionaries(
    {
        "cut": st.one_of(st.none(), st.floats(0.1, 1.0)),
        "flips": st.lists(st.tuples(st.floats(0.0, 1.0), st.integers(0, 7)), min_size=0, max_size=6),
    }
).filter(lambda plan: plan["cut"] is not None or plan["flips"])


def _apply(sample: Sample, plan: dict) -> tuple[bytes, list[int], int]:
    data = bytearray(sample.data)
    cut = len(data) if plan["cut"] is None else int(plan["cut"] * len(data))
    allowed_from = max((end for _, end in sample.protected if end < cut), default=0)
    positions = []
    for where, bit in plan["flips"]:
        pos = int(allowed_from + where * max(cut - allowed_from - 1, 0))
        if any(lo <= pos < hi for lo, hi in sample.protected):
            continue
        data[pos] ^= 1 << bit
        positions.append(pos)
    return bytes(data[:cut]), positions, cut


@pytest.mark.timeout(300)
@pytest.mark.parametrize("fmt", ["tlog", "bin", "ulog"])
@settings(max_examples=40, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
@given(plan=damage_plans)
def test_damage_never_crashes_and_intact_records_survive(
    samples: dict[str, Sample], fmt: str, plan: dict, tmp_path_factory: pytest.TempPathFactory
) -> None:
    sample = samples[fmt]
    damaged, flips, cut = _apply(sample, plan)
    path = tmp_path_factory.mktemp("damaged") / f"damaged.{fmt}"
    path.write_bytes(damaged)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        got = sample.decode(path)
    ours = [w for w in caught if "damaged log" in str(w.message)]
    assert len(ours) <= 1, [str(w.message) for w in ours]
    for w in ours:
        assert str(path) in str(w.message) and "byte offset" in str(w.message)
    first_damage = min([*flips, cut])
    last_damage = max(flips, default=cut)
    for key, value in sample.records.items():
        offset = key[1]
        end = offset + sample.span(sample.data, offset)
        if end > cut:
            continue
        before = end <= first_damage
        after = offset > last_damage
        untouched = not any(offset <= f < end for f in flips)
        if before or after:
            assert got.get(key) == value, f"{fmt}: record {key} lost or changed (damage {flips}, cut {cut})"
        elif untouched and not flips:
            assert got.get(key) == value


@pytest.mark.timeout(300)
@pytest.mark.parametrize("suffix", [".tlog", ".bin", ".ulg"])
@settings(max_examples=30, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
@given(
    data=st.binary(min_size=0, max_size=4000),
    prefix=st.sampled_from([b"", b"ULog\x01\x12\x35\x01", b"\xa3\x95\x80"]),
)
def test_arbitrary_bytes_give_a_table_or_a_clear_error(
    suffix: str, data: bytes, prefix: bytes, tmp_path_factory: pytest.TempPathFactory
) -> None:
    from mav_motor_health.errors import DataError
    from mav_motor_health.telemetry import sources

    path = tmp_path_factory.mktemp("junk") / f"junk{suffix}"
    path.write_bytes(prefix + data)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            sources.read(path)
        except DataError as exc:
            assert str(path) in str(exc)
