"""Byte-level helpers shared by the binary log readers: record chains, CRCs, damage reports, time alignment.

A binary log is a chain of records: each record says how long it is, so the start of the next one is
known. :func:`follow_chain` takes every *candidate* record start (found with numpy, e.g. every sync byte)
and the start its header claims for the next record, and keeps the candidates on the chain that begins at
the first one. Where the chain breaks (damage, truncation), it resynchronises on the next candidate that
``accept`` approves. Python only runs at the breaks and at false candidates (sync bytes inside payloads):
every stretch where candidate ``i`` is followed exactly by candidate ``i + 1`` is taken in one slice.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "Damage",
    "crc_x25_rows",
    "follow_chain",
    "gather_rows",
    "hold_previous",
]


@dataclass
class Damage:
    """Where a log was found damaged: byte offsets of the breaks and how many bytes were skipped."""

    offsets: list[int] = field(default_factory=list)
    skipped_bytes: int = 0
    bad_records: int = 0
    truncated_at: int | None = None

    def __bool__(self) -> bool:
        return bool(self.offsets) or self.bad_records > 0 or self.truncated_at is not None

    def add(self, offset: int, skipped: int = 0) -> None:
        self.offsets.append(int(offset))
        self.skipped_bytes += int(skipped)

    def warn(self, path: Path | str, what: str = "records") -> None:
        """One warning for the whole file, naming it and the first damaged byte offset."""
        if not self:
            return
        places = sorted(set(self.offsets + ([self.truncated_at] if self.truncated_at is not None else [])))
        first = places[0]
        more = f" and {len(places) - 1} other place(s)" if len(places) > 1 else ""
        parts = []
        if self.skipped_bytes:
            parts.append(f"{self.skipped_bytes} byte(s) skipped")
        if self.bad_records:
            parts.append(f"{self.bad_records} corrupt {what} dropped")
        if self.truncated_at is not None:
            parts.append(f"truncated at byte {self.truncated_at}")
        detail = "; ".join(parts)
        warnings.warn(
            f"{path}: damaged log at byte offset {first}{more} ({detail}); "
            f"read past the damage by resynchronising on the next valid {what[:-1]}",
            stacklevel=3,
        )

    def to_dict(self) -> dict[str, object]:
        return {
            "offsets": self.offsets[:20],
            "breaks": len(self.offsets),
            "skipped_bytes": self.skipped_bytes,
            "bad_records": self.bad_records,
            "truncated_at": self.truncated_at,
        }


def follow_chain(
    starts: NDArray[np.int64],
    next_starts: NDArray[np.int64],
    size: int,
    accept: Callable[[int], bool],
    damage: Damage,
    first: int = 0,
    tail_slack: int = 0,
) -> NDArray[np.int64]:
    """Indices (into ``starts``) of the candidates on the record chain.

    ``starts`` are sorted candidate record offsets, ``next_starts[i]`` the offset record ``i`` claims for
    its successor. A record whose successor lies past ``size`` is incomplete and dropped (truncation). At a
    break, the next candidate after the broken record for which ``accept(i)`` is true restarts the chain;
    the break's offset and the skipped bytes go into ``damage``. Up to ``tail_slack`` trailing bytes
    that start no record (a logger stopped mid-header) are not counted as damage.
    """
    n = len(starts)
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    follows = np.zeros(n, dtype=bool)
    follows[:-1] = next_starts[:-1] == starts[1:]
    # run_end[i]: the last index of the run of consecutive "follows" starting at i.
    breaks = np.flatnonzero(~follows)
    run_end_of = breaks[np.searchsorted(breaks, np.arange(n))]
    pieces: list[NDArray[np.int64]] = []
    i = first
    if i > 0 and n:
        damage.add(0, int(starts[i]))
    jumped_from = -1  # the record whose successor was reached by jumping over false candidates
    while i < n:
        j = int(run_end_of[i])
        nxt = int(next_starts[j])
        pieces.append(np.arange(i, j + 1, dtype=np.int64))
        if nxt == size:
            break
        if nxt < size:
            k = int(np.searchsorted(starts, nxt))
            if k < n and starts[k] == nxt:
                # False candidates (sync bytes inside payloads) sat between j and its successor.
                jumped_from, i = j, k
                continue
        # The chain is broken after record j. If j was reached by a jump and is followed by nothing,
        # the jump itself was wrong (a damaged length landed on a false candidate): undo it.
        resync_from = j
        if jumped_from >= 0 and pieces[-1][0] == i and len(pieces[-1]) <= 2 and jumped_from < i:
            damage.bad_records += len(pieces.pop())
            resync_from = jumped_from
        jumped_from = -1
        k = int(np.searchsorted(starts, starts[resync_from], side="right"))
        while k < n and not accept(k):
            k += 1
        last = int(pieces[-1][-1]) if pieces and len(pieces[-1]) else -1
        claimed = int(next_starts[last]) if last >= 0 else 0
        if k >= n:
            if claimed > size and last >= 0:  # the last record is cut short
                pieces[-1] = pieces[-1][:-1]
                damage.truncated_at = int(starts[last])
            elif size - claimed > tail_slack:
                damage.add(claimed, size - claimed)
            break
        damage.add(min(claimed, int(starts[k])), max(int(starts[k]) - claimed, 0))
        if last >= 0 and starts[k] < claimed:
            # the last record overlaps the next good one: its own length field was damaged; drop it.
            pieces[-1] = pieces[-1][:-1]
            damage.bad_records += 1
        i = k
    if not pieces:
        return np.zeros(0, dtype=np.int64)
    return np.concatenate(pieces)


def gather_rows(
    data: NDArray[np.uint8], offsets: NDArray[np.int64], width: int, lengths: NDArray[np.int64] | None = None
) -> NDArray[np.uint8]:
    """An ``(n, width)`` byte array of the records at ``offsets``; bytes past ``lengths`` are zero.

    Rows are copied from a sliding-window view of the bytes (one memcpy per row, no index array). Rows
    reaching past the end of ``data`` are zero-filled there. MAVLink 2 drops trailing zero bytes from
    payloads; ``lengths`` pads them back to the full layout.
    """
    n = len(offsets)
    if n == 0 or width == 0:
        return np.zeros((n, width), dtype=np.uint8)
    size = len(data)
    offsets = np.asarray(offsets, dtype=np.int64)
    if size >= width:
        windows = np.lib.stride_tricks.sliding_window_view(np.asarray(data), width)
        inside = offsets + width <= size
        if inside.all():
            rows = windows[offsets]
        else:
            rows = np.zeros((n, width), dtype=np.uint8)
            rows[inside] = windows[offsets[inside]]
            for r in np.flatnonzero(~inside).tolist():
                part = np.asarray(data[offsets[r] : size])
                rows[r, : len(part)] = part
    else:
        rows = np.zeros((n, width), dtype=np.uint8)
        for i in range(n):
            part = np.asarray(data[offsets[i] : offsets[i] + width])
            rows[i, : len(part)] = part
    if lengths is not None:
        rows[np.arange(width)[None, :] >= np.asarray(lengths)[:, None]] = 0
    return rows


def _crc_table() -> NDArray[np.uint16]:
    table = np.zeros(256, dtype=np.uint16)
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0x8408 if crc & 1 else crc >> 1
        table[byte] = crc
    return table


_CRC_TABLE = _crc_table()


def crc_x25_rows(rows: NDArray[np.uint8], lengths: NDArray[np.int64], extra: int) -> NDArray[np.uint16]:
    """X.25 (CRC-16/MCRF4XX) of each row's first ``lengths`` bytes followed by ``extra``: MAVLink's CRC.

    Vectorised over rows: one table look-up per column, for all frames at once.
    """
    n, width = rows.shape
    crc = np.full(n, 0xFFFF, dtype=np.uint16)
    table = _CRC_TABLE
    for col in range(width):
        active = lengths > col
        if not active.any():
            break
        step = (crc >> 8) ^ table[(crc ^ rows[:, col]) & 0xFF]
        crc = np.where(active, step, crc).astype(np.uint16)
    return ((crc >> 8) ^ table[(crc ^ np.uint16(extra)) & 0xFF]).astype(np.uint16)


def hold_previous(
    t_source: NDArray[np.float64],
    values: NDArray[np.float64],
    t_target: NDArray[np.float64],
    max_age_s: float | None = None,
) -> NDArray[np.float64]:
    """The last value at or before each target time (previous-value hold); NaN before the first value.

    ``t_source`` must be sorted. Values older than ``max_age_s`` count as missing.
    """
    out = np.full(len(t_target), np.nan)
    if len(t_source) == 0:
        return out
    idx = np.searchsorted(t_source, t_target, side="right") - 1
    valid = idx >= 0
    out[valid] = np.asarray(values, dtype=float)[idx[valid]]
    if max_age_s is not None:
        age = np.full(len(t_target), np.inf)
        age[valid] = t_target[valid] - t_source[idx[valid]]
        out[age > max_age_s] = np.nan
    return out
