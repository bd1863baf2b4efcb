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

from .._arrays import distinct

__all__ = [
    "Damage",
    "crc_x25_rows",
    "follow_chain",
    "gather_rows",
    "hold_previous",
    "zero_past",
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

    ``starts`` are strictly increasing candidate record offsets, ``next_starts[i]`` the offset record ``i`` claims for
    its successor. A record whose successor lies past ``size`` is incomplete and dropped (truncation). At a
    break, the next candidate after the broken record for which ``accept(i)`` is true restarts the chain;
    the break's offset and the skipped bytes go into ``damage``. Up to ``tail_slack`` trailing bytes
    that start no record (a logger stopped mid-header) are not counted as damage.
    """
    n = len(starts)
    if n == 0 or first >= n:
        return np.zeros(0, dtype=np.int64)
    # Successor of every candidate, found for all at once: its index, or END / BROKEN / CUT.
    end, broken, cut = -2, -1, -3
    k = np.searchsorted(starts, next_starts)
    k_safe = np.minimum(k, n - 1)
    succ = np.where(starts[k_safe] == next_starts, k_safe, broken)
    succ[next_starts == size] = end
    succ[next_starts > size] = cut
    paths = _RunPaths(succ)
    chain = _Chain()
    undone: set[int] = set()
    i = first
    if i > 0:
        damage.add(0, int(starts[i]))
    while 0 <= i < n:
        path = paths.path_from(i)  # the walk itself, vectorised
        chain.extend(path)
        i = int(succ[path[-1]])
        if i == end:
            break
        last = chain.last()
        resync_from = last
        if i == cut and not any(accept(q) for q in range(last + 1, min(last + 64, n))):
            chain.drop(1)  # the last record is cut short: the log was truncated
            damage.truncated_at = int(starts[last])
            break
        # The chain is broken after ``last``. If ``last`` came right after a jump over candidates and the
        # jump target is followed by at most one record, the jump may have been a damaged length landing
        # on a false candidate: undo it once and resynchronise from the record before it.
        tail = chain.tail(3)
        if last not in undone and len(tail) >= 2:
            if tail[-1] != tail[-2] + 1:
                undone.add(last)
                resync_from = tail[-2]
                chain.drop(1)
            elif len(tail) == 3 and tail[-2] != tail[-3] + 1:
                undone.add(last)
                resync_from = tail[-3]
                chain.drop(2)
        claimed = int(next_starts[chain.last()]) if len(chain) else 0
        k_next = resync_from + 1  # the next candidate (``starts`` increase strictly)
        while k_next < n and not accept(k_next):
            k_next += 1
        if k_next >= n:
            if len(chain) and claimed > size:
                damage.truncated_at = int(starts[chain.last()])
                chain.drop(1)
            elif size - claimed > tail_slack:
                damage.add(claimed, size - claimed)
            break
        damage.add(min(claimed, int(starts[k_next])), max(int(starts[k_next]) - claimed, 0))
        if len(chain) and starts[k_next] < claimed:
            # the last record overlaps the next good one: its own length field was damaged; drop it.
            chain.drop(1)
            damage.bad_records += 1
        i = k_next
    return chain.array()


class _Chain:
    """The records kept so far, as numpy pieces (appending 457 k Python ints would be slow)."""

    def __init__(self) -> None:
        self.pieces: list[NDArray[np.int64]] = []
        self.size = 0

    def __len__(self) -> int:
        return self.size

    def extend(self, piece: NDArray[np.int64]) -> None:
        self.pieces.append(piece)
        self.size += len(piece)

    def last(self) -> int:
        return int(self.pieces[-1][-1])

    def tail(self, k: int) -> list[int]:
        out: list[int] = []
        for piece in reversed(self.pieces):
            out = piece[-(k - len(out)) :].tolist() + out
            if len(out) >= k:
                break
        return out

    def drop(self, k: int) -> None:
        while k > 0 and self.pieces:
            take = min(k, len(self.pieces[-1]))
            self.pieces[-1] = self.pieces[-1][: len(self.pieces[-1]) - take]
            self.size -= take
            k -= take
            if len(self.pieces[-1]) == 0:
                self.pieces.pop()

    def array(self) -> NDArray[np.int64]:
        return np.concatenate(self.pieces) if self.pieces else np.zeros(0, dtype=np.int64)


class _RunPaths:
    """Paths through a successor table where most nodes are followed by the next one (``succ[i] = i+1``).

    Runs of such nodes are collapsed into one node each (every jump target starts a run), paths are found
    on the runs with :class:`_Paths`, and expanded back: the cost follows the number of irregularities
    (false candidates, breaks), not the number of records.
    """

    def __init__(self, succ: NDArray[np.int64]) -> None:
        n = len(succ)
        idx = np.arange(n)
        consecutive = succ[:-1] == idx[:-1] + 1
        is_start = np.ones(n, dtype=bool)
        is_start[1:] = ~consecutive
        # a node that is a jump target (reached from a node other than its predecessor) starts a run
        from_elsewhere = np.zeros(n, dtype=bool)
        sources = np.flatnonzero(succ >= 0)
        far = sources[succ[sources] != sources + 1]
        from_elsewhere[succ[far]] = True
        is_start |= from_elsewhere
        self.run_start = np.flatnonzero(is_start)
        self.run_end = np.append(self.run_start[1:] - 1, n - 1)
        self.run_of = np.cumsum(is_start) - 1
        last_succ = succ[self.run_end]
        self.run_succ = np.where(last_succ >= 0, self.run_of[np.maximum(last_succ, 0)], last_succ)
        self._succ_list: list[int] = self.run_succ.tolist()
        self._paths: _Paths | None = None  # pointer doubling, built only for long paths

    #: up to this many runs a path is walked one run at a time (a damaged log breaks it every few runs)
    WALK_RUNS = 256

    def path_from(self, first: int) -> NDArray[np.int64]:
        run = int(self.run_of[first])
        walked = [run]
        succ = self._succ_list
        while len(walked) <= self.WALK_RUNS:
            nxt = succ[walked[-1]]
            if nxt < 0:
                break
            walked.append(nxt)
        else:
            if self._paths is None:
                self._paths = _Paths(self.run_succ)
            walked = self._paths.path_from(run).tolist()
        if len(walked) == 1:
            return np.arange(first, int(self.run_end[run]) + 1, dtype=np.int64)
        runs = np.asarray(walked, dtype=np.int64)
        starts = self.run_start[runs].copy()
        starts[0] = first
        ends = self.run_end[runs]
        lengths = ends - starts + 1
        offsets = np.repeat(starts - np.concatenate([[0], np.cumsum(lengths)[:-1]]), lengths)
        return np.arange(int(lengths.sum()), dtype=np.int64) + offsets


class _Paths:
    """Paths through a successor table, vectorised with pointer doubling.

    Every node's distance to the end of its path is found for all nodes at once (list ranking); a node
    lies on the path from ``first`` iff jumping ``distance(first) − distance(node)`` steps from ``first``
    lands on it. Successors always lie after their node (records follow each other in the file), so a
    path is the sorted set of its nodes, and only the nodes between ``first`` and its path's end are tested.
    """

    def __init__(self, succ: NDArray[np.int64]) -> None:
        n = len(succ)
        self.sink = n
        nxt = np.append(np.where(succ >= 0, succ, n), n)
        depth = np.append((succ >= 0).astype(np.int64), 0)
        self.jumps = [nxt]  # jumps[r][x]: the node 2**r steps after x
        ptr = nxt
        while not (ptr == n).all():
            depth = depth + depth[ptr]
            ptr = ptr[ptr]
            self.jumps.append(ptr)
        self.depth = depth

    def _jump(self, start: NDArray[np.int64], steps: NDArray[np.int64]) -> NDArray[np.int64]:
        pos = start.copy()
        for r, table in enumerate(self.jumps):
            bit = ((steps >> r) & 1).astype(bool)
            if bit.any():
                pos[bit] = table[pos[bit]]
        return pos

    def path_from(self, first: int) -> NDArray[np.int64]:
        d0 = int(self.depth[first])
        last = int(self._jump(np.array([first]), np.array([d0]))[0])
        nodes = np.arange(first, last + 1, dtype=np.int64)
        steps = d0 - self.depth[nodes]
        nodes, steps = nodes[steps >= 0], steps[steps >= 0]
        return nodes[self._jump(np.full(len(nodes), first, dtype=np.int64), steps) == nodes]


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
        flat = np.asarray(data)
        windows = np.lib.stride_tricks.as_strided(
            flat, shape=(size - width + 1, width), strides=(flat.strides[0], flat.strides[0]), writeable=False
        )
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
    return rows if lengths is None else zero_past(rows, lengths)


def zero_past(rows: NDArray[np.uint8], lengths: NDArray[np.int64]) -> NDArray[np.uint8]:
    """``rows`` (changed in place) with the bytes past each row's length made zero: only the columns
    past the shortest length are touched (the frames of one message mostly share their length: then the
    tail is cleared as one block)."""
    width = rows.shape[1]
    lengths = np.asarray(lengths)
    if len(lengths) == 0:
        return rows
    low = max(int(lengths.min()), 0)
    if low >= width:
        return rows
    tail = rows[:, low:]
    if int(lengths.max()) == low:
        tail[...] = 0
    else:
        short = lengths < width
        some = np.flatnonzero(short) if not short.all() else None
        keep = np.arange(low, width)[None, :] < (lengths[:, None] if some is None else lengths[some, None])
        if some is None:
            tail *= keep
        else:
            tail[some] *= keep
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


def _crc_table16(table: NDArray[np.uint16]) -> NDArray[np.uint16]:
    """The X.25 step over two bytes at once: the CRC after bytes ``w & 0xFF`` then ``w >> 8`` of a
    16-bit CRC ``c`` depends only on ``c ^ w`` (both bytes are XORed into it before they are shifted out),
    so a 65,536-entry table does the two table steps in one look-up."""
    x = np.arange(65536, dtype=np.uint32)
    t = table.astype(np.uint32)
    first = t[x & 0xFF]
    return ((first >> 8) ^ t[((x >> 8) ^ first) & 0xFF]).astype(np.uint16)


_CRC_TABLE16 = _crc_table16(_CRC_TABLE)


def _byte_pairs_by_column(
    rows: NDArray[np.uint8], sel: NDArray[np.int64] | None, pairs: int
) -> NDArray[np.uint16]:
    """The first ``pairs`` little-endian byte pairs of the rows ``sel`` (None: all), pair by pair:
    (pairs, rows). The rows are read as 16-bit words and those transposed in one copy: moving whole words
    costs a fraction of moving the bytes of each pair apart and back."""
    if rows.strides[1] != 1:
        rows = np.ascontiguousarray(rows)
    part = rows[:, : 2 * pairs] if sel is None else rows[sel, : 2 * pairs]
    return np.ascontiguousarray(part.view("<u2").T)


def crc_x25_rows(rows: NDArray[np.uint8], lengths: NDArray[np.int64], extra: int) -> NDArray[np.uint16]:
    """X.25 (CRC-16/MCRF4XX) of each row's first ``lengths`` bytes followed by ``extra``: MAVLink's CRC.

    Vectorised over rows: rows of equal length are processed together, two bytes a step (one look-up in
    a 16-bit table for all of them at once), the rows' byte pairs laid out column by column.
    """
    out = np.zeros(len(rows), dtype=np.uint16)
    table = _CRC_TABLE
    kinds = distinct(lengths)[0].tolist()
    for length in kinds:
        sel = np.flatnonzero(lengths == length) if len(kinds) > 1 else np.arange(len(rows))
        pairs = _byte_pairs_by_column(rows, sel if len(kinds) > 1 else None, length // 2)
        crc = np.full(len(sel), 0xFFFF, dtype=np.uint16)
        mixed = np.empty_like(crc)
        for pair in pairs:
            np.bitwise_xor(crc, pair, out=mixed)
            np.take(_CRC_TABLE16, mixed, out=crc, mode="clip")
        if length % 2:
            crc = (crc >> 8) ^ table[(crc ^ rows[sel, length - 1]) & 0xFF]
        out[sel] = (crc >> 8) ^ table[(crc ^ np.uint16(extra)) & 0xFF]
    return out


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
