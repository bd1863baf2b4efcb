"""Seeded damage to log files, and what replay makes of it (the fuzz benchmark and its test).

:func:`damaged_copies` draws damaged versions of a log's bytes: byte flips, scattered bit flips,
truncation, inserted, zeroed and duplicated blocks, a destroyed header and damaged format definitions
(DataFlash FMT records, ULog 'F' messages, a CSV header). :func:`run_case` reads one through the reader
and the diagnosis as replay does, in this process, with a time limit, and says whether it ended in a
clear project error, a crash (any other exception: a bug) or a hang, and how many samples survived.
"""

from __future__ import annotations

import signal
import time
import traceback
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import MotorHealthError

__all__ = [
    "DAMAGE_KINDS",
    "CaseResult",
    "Damage",
    "damaged_copies",
    "dataflash_text",
    "format_offsets",
    "run_case",
]

DAMAGE_KINDS = (
    "flip_byte",
    "flip_bits",
    "truncate",
    "insert_block",
    "zero_block",
    "duplicate_chunk",
    "destroy_header",
    "damage_format",
)


@dataclass(frozen=True)
class Damage:
    kind: str
    seed: int
    where: int  # byte offset of the damage (the first one for scattered flips)
    data: bytes


def format_offsets(data: bytes, suffix: str) -> list[int]:
    """Byte offsets of the format definitions a reader needs first (for ``damage_format``)."""
    if suffix == ".bin":
        marks = np.frombuffer(data, dtype=np.uint8)
        hits = np.flatnonzero((marks[:-2] == 0xA3) & (marks[1:-1] == 0x95) & (marks[2:] == 0x80))
        return [int(h) + 3 for h in hits[:200]]
    if suffix == ".ulg":
        out: list[int] = []
        pos = 16
        while pos + 3 <= len(data) and len(out) < 200:
            size, kind = int.from_bytes(data[pos : pos + 2], "little"), data[pos + 2]
            if kind == ord("F"):
                out.append(pos + 3)
            if kind in (ord("A"), ord("D")) or size == 0:
                break
            pos += 3 + size
        return out
    if suffix in (".csv", ".log"):
        end = data.find(b"\n")
        if suffix == ".log":  # DataFlash text: the FMT lines
            return [i for i in range(0, min(len(data), 200_000)) if data.startswith(b"FMT", i)][:200]
        return list(range(max(end, 1)))
    return []


def damaged_copies(data: bytes, suffix: str, seed: int, count: int) -> Iterator[Damage]:
    """``count`` damaged copies of ``data``, the kinds in turn, each from its own seed."""
    fmt = format_offsets(data, suffix)
    n = len(data)
    for k in range(count):
        kind = DAMAGE_KINDS[k % len(DAMAGE_KINDS)]
        case_seed = seed * 100_003 + k
        rng = np.random.default_rng(case_seed)
        buf = bytearray(data)
        at = int(rng.integers(0, n))
        if kind == "flip_byte":
            buf[at] ^= int(rng.integers(1, 256))
        elif kind == "flip_bits":
            share = float(rng.uniform(0.002, 0.006))
            bits = rng.choice(n * 8, size=max(1, int(share * n * 8)), replace=False)
            arr = np.frombuffer(bytes(buf), dtype=np.uint8).copy()
            np.bitwise_xor.at(arr, bits // 8, (1 << (bits % 8)).astype(np.uint8))
            buf, at = bytearray(arr.tobytes()), int(bits.min() // 8)
        elif kind == "truncate":
            at = int(n * rng.uniform(0.05, 0.99))
            buf = buf[:at]
        elif kind == "insert_block":
            buf[at:at] = rng.integers(0, 256, size=int(rng.integers(1, 4096)), dtype=np.uint8).tobytes()
        elif kind == "zero_block":
            size = int(rng.integers(1, 4096))
            buf[at : at + size] = bytes(len(buf[at : at + size]))
        elif kind == "duplicate_chunk":
            size = int(rng.integers(16, 8192))
            buf[at:at] = bytes(buf[at : at + size])
        elif kind == "destroy_header":
            size = min(n, int(rng.integers(1, 256)))
            buf[:size] = rng.integers(0, 256, size=size, dtype=np.uint8).tobytes()
            at = 0
        elif kind == "damage_format":
            if fmt:
                at = int(fmt[int(rng.integers(0, len(fmt)))]) + int(rng.integers(0, 64))
                at = min(at, n - 1)
            buf[at] ^= int(rng.integers(1, 256))
        yield Damage(kind, case_seed, at, bytes(buf))


@dataclass(frozen=True)
class CaseResult:
    outcome: str  # "ok", "error" (a clear project error), "crash" (any other exception) or "hang"
    samples: int  # samples with a speed or a current read from the damaged copy
    message: str  # the error's text, or the crash's traceback
    seconds: float


class _Hang(Exception):
    pass


def _alarm(signum: int, frame: object) -> None:
    raise _Hang


def count_samples(path: Path) -> int:
    """Samples with a speed or a current that the reader returns (0 where it refuses the file)."""
    from ..telemetry import sources

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        table = sources.read(path)
    return int(np.count_nonzero(np.isfinite(table["omega_rad_s"]) | np.isfinite(table["current_a"])))


def run_case(path: Path, limit_s: float = 30.0) -> CaseResult:
    """Read ``path`` and diagnose it as replay does; classify the outcome (see :class:`CaseResult`)."""
    from ..config import load_motor_params, load_profile
    from ..diagnosis import diagnose
    from ..telemetry import sources

    started = time.monotonic()
    previous = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, limit_s)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            table = sources.read(path)
            samples = int(
                np.count_nonzero(np.isfinite(table["omega_rad_s"]) | np.isfinite(table["current_a"]))
            )
            if len(table):
                diagnose(table, load_motor_params(), load_profile("flight"))
        return CaseResult("ok", samples, "", time.monotonic() - started)
    except _Hang:
        return CaseResult("hang", 0, f"no answer within {limit_s:g} s", time.monotonic() - started)
    except MotorHealthError as exc:
        return CaseResult("error", 0, str(exc), time.monotonic() - started)
    except Exception:
        return CaseResult("crash", 0, traceback.format_exc(), time.monotonic() - started)
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def dataflash_text(binary: Path, names: tuple[str, ...] = ("PARM", "ESC", "RCOU", "BAT")) -> str:
    """A DataFlash *text* log (what Mission Planner exports as .log) of a binary log's ``names`` records:
    their FMT lines, then the records in the binary log's order. No public text log carries ESC records,
    so the text reader's ESC path is tested and fuzzed on such a rendering."""
    from ..telemetry.dataflash import read_records

    log = read_records(binary, list(names), warn=False)
    present = [n for n in names if n in log]
    lines = []
    for name in present:
        fmt = log.formats[name]
        lines.append(f"FMT, {fmt.type}, {fmt.length}, {name}, {fmt.format}, {','.join(fmt.columns)}")
    rows: list[tuple[int, str]] = []
    for name in present:
        cols = log[name]
        for offset, row in zip(log.offsets[name].tolist(), zip(*cols.values())):
            cells = [c.split(b"\0")[0].decode() if isinstance(c, bytes) else repr(float(c)) for c in row]
            rows.append((int(offset), ", ".join([name, *cells])))
    rows.sort(key=lambda r: r[0])
    return (
        "ArduCopter V4.7.0-dev (text rendering)\n" + "\n".join([*lines, *(text for _, text in rows)]) + "\n"
    )
