"""A CSV writer for long numeric tables, vectorised with numpy: no Python work per value.

Every row has the same fixed-width layout: each cell gets as many bytes as its column's widest value
needs (sign, integer digits, decimal point, decimals, separator), unused bytes 0. A row is held as a few
64-bit words, and a cell's text is put together from small look-up tables of pre-formatted digit groups
(up to four digits an entry) that already sit at the cell's place in the row: formatting a column is a
few integer operations, table look-ups and ORs over whole arrays. The rows' bytes are then laid end to
end and the zero bytes removed, which leaves ordinary variable-width CSV text.

What a number becomes (:func:`format_number` is the same rule, one value at a time):

* ``q = round_half_even(min(|v|, 1e15) × 10**decimals)``, written as its integer part, a point and the
  decimals, trailing zeros and a bare point dropped (``2.5``, ``3``, ``0.0001``);
* ``-`` in front when ``v < 0`` and ``q > 0`` (at 4 decimals ``-0.0`` and ``-0.00004`` are ``0``);
* NaN and ±inf are empty cells.

Label columns hold integer codes and a label list (``state`` → ``F3.1``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import BinaryIO

import numpy as np
from numpy.typing import NDArray

__all__ = ["MAGNITUDE_CAP", "Column", "format_number", "write_csv_columns"]

#: (name, values, decimals or labels): decimals for numbers, a label list for integer codes.
Column = tuple[str, NDArray, "int | Sequence[str]"]
#: rows formatted at once: one chunk's arrays stay in the processor's cache
CHUNK_ROWS = 32_768
#: larger magnitudes are written as this (a bound on a column's width)
MAGNITUDE_CAP = 1e15
#: digits per look-up table entry, and the entries of a group's table per flag value
GROUP_DIGITS = 4
GROUP = 10**GROUP_DIGITS
#: scaled values from here on are formatted one by one in Python (int64 would overflow)
FAST_LIMIT = 2**62
MAX_DECIMALS = 2 * GROUP_DIGITS
WORD_BYTES = 8
ZERO = ord("0")

Index = NDArray[np.int64]


def format_number(value: float, decimals: int) -> str:
    """One number as the writer writes it (module doc): the plain reference for the vectorised path."""
    v = float(value)
    if not np.isfinite(v):
        return ""
    q = round(min(abs(v), MAGNITUDE_CAP) * 10**decimals)
    sign = "-" if v < 0 and q > 0 else ""
    if decimals == 0:
        return f"{sign}{q}"
    whole, frac = divmod(q, 10**decimals)
    return sign + f"{whole}.{frac:0{decimals}d}".rstrip("0").rstrip(".")


# -- look-up tables: one row of ASCII bytes per entry, 0 where nothing is written ----------------------
def _digit_text(digits: int) -> NDArray[np.uint8]:
    """0 … 10**digits − 1 as zero-padded ASCII digits."""
    values = np.arange(10**digits, dtype=np.int64)
    powers = 10 ** np.arange(digits - 1, -1, -1, dtype=np.int64)
    return (ZERO + values[:, None] // powers % 10).astype(np.uint8)


def _drop_leading_zeros(text: NDArray[np.uint8], keep_last: bool) -> NDArray[np.uint8]:
    """Leading ``0`` digits made 0 bytes (the last digit kept when ``keep_last``: ``0`` stays ``0``)."""
    leading = np.cumprod(text == ZERO, axis=1).astype(bool)
    if keep_last:
        leading[:, -1] = False
    return np.where(leading, 0, text).astype(np.uint8)


def _drop_trailing_zeros(text: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """Trailing ``0`` digits made 0 bytes."""
    trailing = np.cumprod((text == ZERO)[:, ::-1], axis=1)[:, ::-1].astype(bool)
    return np.where(trailing, 0, text).astype(np.uint8)


def _padded(table: NDArray[np.uint8], rows: int) -> NDArray[np.uint8]:
    """``table`` with all-zero rows appended up to ``rows``."""
    return np.vstack([table, np.zeros((rows - len(table), table.shape[1]), dtype=np.uint8)])


def _integer_group_table(digits: int, top: bool, units: bool, signed: bool) -> NDArray[np.uint8]:
    """One group of ``digits`` integer digits, indexed by ``value + GROUP × flag``; entry 2·GROUP blank.

    The top (most significant) group: flag = negative, a sign byte in front when the column is
    ``signed``, leading zeros dropped. Any lower group: flag = a higher group is not zero, then every
    digit is written. The ``units`` group keeps a lone ``0``.
    """
    text = _digit_text(digits)
    short = _drop_leading_zeros(text, keep_last=units)
    if top:
        sign = np.zeros((len(text), int(signed)), dtype=np.uint8)
        halves = [np.hstack([sign, short]), np.hstack([sign + ord("-"), short])]
    else:
        halves = [short, text]
    return _padded(np.vstack([_padded(h, GROUP) for h in halves]), 2 * GROUP + 1)


def _fraction_table(digits: int, point: bool, more: bool) -> NDArray[np.uint8]:
    """``digits`` decimals, trailing zeros dropped; the point in front when ``point`` (none for 0).

    With ``more``, entries from 10**digits on are for decimals that continue in a further table: every
    digit and the point written.
    """
    text = _digit_text(digits)
    dot = np.full((len(text), int(point)), ord("."), dtype=np.uint8)
    short = np.hstack([dot, _drop_trailing_zeros(text)])
    short[0] = 0
    return np.vstack([short, np.hstack([dot, text])]) if more else short


def _label_table(labels: Sequence[str]) -> NDArray[np.uint8]:
    """Labels as ASCII, padded with 0 bytes to the longest."""
    encoded = [label.encode("ascii") for label in labels]
    table = np.zeros((len(encoded), max(map(len, encoded), default=0)), dtype=np.uint8)
    for i, text in enumerate(encoded):
        table[i, : len(text)] = np.frombuffer(text, dtype=np.uint8)
    return table


# -- tables placed in a row -------------------------------------------------------------------------------
def _place(table: NDArray[np.uint8], at_byte: int) -> tuple[int, NDArray[np.uint64]]:
    """A text table put at byte ``at_byte`` of the row: the first row word it touches, and each entry's
    bits in the words it touches (entries × words)."""
    first, last = at_byte // WORD_BYTES, (at_byte + table.shape[1] - 1) // WORD_BYTES
    placed = np.zeros((table.shape[0], (last - first + 1) * WORD_BYTES), dtype=np.uint8)
    start = at_byte - first * WORD_BYTES
    placed[:, start : start + table.shape[1]] = table
    return first, placed.view("<u8").astype(np.uint64)


# -- columns ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Numbers:
    """A numeric column's layout, from the whole column: the widest value, any sign, anything special.

    ``clean``: no value missing, infinite or at the cap, so no row needs checking.
    """

    decimals: int
    int_digits: int
    signed: bool
    clean: bool

    @classmethod
    def of(cls, values: NDArray, decimals: int) -> _Numbers:
        """The layout that holds every value of ``values`` at ``decimals``."""
        if not 0 <= decimals <= MAX_DECIMALS:
            raise ValueError(f"decimals must be 0…{MAX_DECIMALS}, not {decimals}")
        if values.dtype.kind in "iub":
            decimals = 0  # no fraction to write: 128 at 4 decimals is 128
        lo, hi, clean = _finite_range(values)
        largest = round(min(max(abs(lo), abs(hi)), MAGNITUDE_CAP) * 10**decimals)
        clean = clean and largest < _limit(decimals)
        negative = lo < 0 and round(min(-lo, MAGNITUDE_CAP) * 10**decimals) > 0
        return cls(decimals, len(str(largest // 10**decimals)), negative, clean)

    @property
    def groups(self) -> int:
        return -(-self.int_digits // GROUP_DIGITS)

    @property
    def width(self) -> int:
        return int(self.signed) + self.int_digits + (1 + self.decimals if self.decimals else 0)

    def tables(self) -> list[NDArray[np.uint8]]:
        """Integer groups (most significant first), then the decimals: laid end to end, the cell."""
        tables = []
        for g in range(self.groups - 1, -1, -1):
            top = g == self.groups - 1
            digits = self.int_digits - GROUP_DIGITS * g if top else GROUP_DIGITS
            tables.append(_integer_group_table(digits, top, units=g == 0, signed=self.signed and top))
        if self.decimals:
            head = min(self.decimals, GROUP_DIGITS)
            more = self.decimals > head
            tables.append(_fraction_table(head, point=True, more=more))
            if more:
                tables.append(_fraction_table(self.decimals - head, point=False, more=False))
        return tables

    def indices(self, values: NDArray) -> tuple[list[Index], Index | None]:
        """Each table's index per value, and the rows written one by one (None if none): those the
        tables cannot hold, left blank by them."""
        scaled, negative, special = self._scaled(values)
        slow = None
        if special is not None:
            rows = np.flatnonzero(special)
            scaled[rows] = 0
            if negative is not None:
                negative[rows] = False
            slow = rows[np.isfinite(values[rows])] if values.dtype.kind == "f" else rows
        whole, frac = _divmod(scaled, 10**self.decimals) if self.decimals else (scaled, None)
        out: list[Index] = []
        for g in range(self.groups - 1, -1, -1):
            value = whole // GROUP**g if g else whole
            if g < self.groups - 1:  # the top group has no higher digits
                value = value % GROUP
            if g == self.groups - 1:
                out.append(value + GROUP * negative if negative is not None else value)
            else:
                out.append(value + GROUP * (whole >= GROUP ** (g + 1)))
        if frac is not None:
            if self.decimals > GROUP_DIGITS:
                high, low = _divmod(frac, 10 ** (self.decimals - GROUP_DIGITS))
                out += [high + GROUP * (low > 0), low]
            else:
                out.append(frac)
        if special is not None:  # blank: the top group has the sign, the units group a lone 0
            out[0][rows] = 2 * GROUP
            out[self.groups - 1][rows] = 2 * GROUP
        return out, slow

    def _scaled(self, values: NDArray) -> tuple[Index, NDArray[np.bool_] | None, NDArray[np.bool_] | None]:
        """``round(|v| × 10**decimals)`` as int64, where negative (None unless ``signed``), and the rows
        the tables cannot hold (None if none): missing, infinite, at the cap or beyond int64."""
        if values.dtype.kind in "iub":
            v = values.astype(np.int64)
            negative = v < 0 if self.signed else None
            magnitude = np.abs(v) if self.signed else v
            if self.clean:
                return magnitude, negative, None
            special = magnitude >= _limit(0)
            return magnitude, negative, special if special.any() else None
        with np.errstate(over="ignore"):  # beyond 1.8e308: inf, written one by one (as the cap)
            x = np.multiply(values, float(10**self.decimals), dtype=np.float64)
        np.rint(x, out=x)
        negative = x < 0 if self.signed else None
        if self.signed:
            np.abs(x, out=x)
        if self.clean:
            return x.astype(np.int64), negative, None
        if not self.signed:
            np.abs(x, out=x)  # -inf
        limit = float(_limit(self.decimals))
        np.fmin(x, limit, out=x)  # NaN and inf become the limit too
        special = x >= limit
        return x.astype(np.int64), negative, special if special.any() else None

    def text(self, value: float) -> str:
        return format_number(value, self.decimals)


def _divmod(values: Index, divisor: int) -> tuple[Index, Index]:
    """``np.divmod`` of non-negative integers by a positive one: the quotient by numpy's division by a
    scalar (a multiplication inside), the remainder from it: half the time of ``np.divmod``'s own loop."""
    quotient = np.floor_divide(values, divisor)
    remainder = np.multiply(quotient, divisor)
    np.subtract(values, remainder, out=remainder)
    return quotient, remainder


def _finite_range(values: NDArray) -> tuple[float, float, bool]:
    """The smallest and largest finite value (0, 0 if none), and whether every value is finite."""
    if len(values) == 0:
        return 0.0, 0.0, True
    lo, hi = float(values.min()), float(values.max())
    if np.isfinite(lo) and np.isfinite(hi):
        return lo, hi, True
    if not (np.isnan(lo) or np.isnan(hi)) or values.dtype.kind != "f":  # NaN-free: an infinite end
        finite = values[np.isfinite(values)]
        return (float(finite.min()), float(finite.max()), False) if len(finite) else (0.0, 0.0, False)
    lo, hi = float(np.fmin.reduce(values)), float(np.fmax.reduce(values))  # NaN left out
    if np.isfinite(lo) and np.isfinite(hi):
        return lo, hi, False
    finite = values[np.isfinite(values)]
    return (float(finite.min()), float(finite.max()), False) if len(finite) else (0.0, 0.0, False)


def _limit(decimals: int) -> int:
    """Scaled magnitudes from here on are written one by one: at the cap, or too large for int64."""
    return min(round(MAGNITUDE_CAP * 10**decimals), FAST_LIMIT)


@dataclass(frozen=True)
class _Labels:
    """A label column: integer codes written as the labels (padded to the longest label used)."""

    labels: tuple[str, ...]

    @classmethod
    def of(cls, codes: NDArray, labels: Sequence[str]) -> _Labels:
        """The labels used by ``codes`` (the others left empty: no width for them)."""
        counts = np.bincount(np.asarray(codes, dtype=np.int64), minlength=len(labels))
        if len(counts) > len(labels):
            raise IndexError(f"label code {len(counts) - 1} but only {len(labels)} labels")
        return cls(tuple(label if n else "" for label, n in zip(labels, counts.tolist())))

    @property
    def width(self) -> int:
        return max(map(len, self.labels), default=0)

    def tables(self) -> list[NDArray[np.uint8]]:
        return [_label_table(self.labels)] if self.width else []

    def indices(self, codes: NDArray) -> tuple[list[Index], Index | None]:
        return ([codes] if self.width else []), None

    def text(self, code: float) -> str:
        return self.labels[int(code)]


_Cell = _Numbers | _Labels


@lru_cache(maxsize=256)
def _cell_words(cell: _Cell, shift: int) -> tuple[tuple[int, NDArray[np.uint64]], ...]:
    """A cell's tables placed from byte ``shift`` (0–7) of a row word: per table, the first word it
    touches (counted from the cell's first) and its entries' bits in the words it touches."""
    placed, pos = [], shift
    for table in cell.tables():
        first_word, words = _place(table, pos)
        words.setflags(write=False)
        placed.append((first_word, words))
        pos += table.shape[1]
    return tuple(placed)


# -- rows -------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Step:
    """One look-up into one row word: ``table[index]`` written (``first``) or ORed into word ``word``."""

    index: int  # which of the column's index arrays
    table: NDArray[np.uint64]
    word: int
    first: bool


@dataclass(frozen=True)
class _RowLayout:
    """Where each column's cell sits in a row, the look-ups that fill it, and the separators."""

    cells: tuple[_Cell, ...]
    offsets: tuple[int, ...]
    steps: tuple[tuple[_Step, ...], ...]  # per column
    base: NDArray[np.uint64]  # the separators per row word; in the first step's table of each word

    @classmethod
    def of(cls, columns: Sequence[Column]) -> _RowLayout:
        cells: list[_Cell] = [
            _Numbers.of(np.asarray(values), how) if isinstance(how, int) else _Labels.of(values, how)
            for _, values, how in columns
        ]
        offsets, at = [], 0
        for cell in cells:
            offsets.append(at)
            at += cell.width + 1  # the separator
        row = np.zeros(-(-at // WORD_BYTES) * WORD_BYTES, dtype=np.uint8)
        for cell, offset in zip(cells, offsets):
            row[offset + cell.width] = ord(",")
        row[at - 1] = ord("\n")
        base = row.view("<u8").astype(np.uint64)
        seen: set[int] = set()
        steps = []
        for cell, offset in zip(cells, offsets):
            column_steps = []
            for i, (first_word, words) in enumerate(_cell_words(cell, offset % WORD_BYTES)):
                first_word += offset // WORD_BYTES
                for k in range(words.shape[1]):
                    word, first = first_word + k, first_word + k not in seen
                    bits = words[:, k] | base[word] if first else words[:, k]
                    column_steps.append(_Step(i, np.ascontiguousarray(bits), word, first))
                    seen.add(word)
            steps.append(tuple(column_steps))
        return cls(tuple(cells), tuple(offsets), tuple(steps), base)

    def chunk_bytes(
        self, columns: Sequence[Column], start: int, stop: int, words: NDArray[np.uint64]
    ) -> bytes:
        """Rows ``start:stop`` as CSV text; ``words`` (row words × rows) is scratch space."""
        n = stop - start
        scratch = np.empty(n, dtype=np.uint64)
        for (_, values, _), cell, offset, steps in zip(columns, self.cells, self.offsets, self.steps):
            chunk = values[start:stop]
            indices, slow = cell.indices(chunk)
            for step in steps:
                if step.first:
                    np.take(step.table, indices[step.index], out=words[step.word, :n], mode="clip")
                else:
                    np.take(step.table, indices[step.index], out=scratch, mode="clip")
                    np.bitwise_or(words[step.word, :n], scratch, out=words[step.word, :n])
            if slow is not None and len(slow):
                _write_one_by_one(words[:, :n], cell, offset, chunk, slow)
        return words[:, :n].T.tobytes().translate(None, b"\0")

    def scratch(self, rows: int) -> NDArray[np.uint64]:
        """Row words × rows, the words no look-up touches holding their separators."""
        words = np.empty((len(self.base), rows), dtype=np.uint64)
        touched = {step.word for steps in self.steps for step in steps}
        for k in set(range(len(self.base))) - touched:
            words[k] = self.base[k]
        return words


def _write_one_by_one(
    words: NDArray[np.uint64], cell: _Cell, offset: int, values: NDArray, rows: Index
) -> None:
    """Cells the look-ups left blank, formatted one by one (Python) into their place."""
    texts = np.zeros((len(rows), cell.width), dtype=np.uint8)
    for i, value in enumerate(values[rows].tolist()):
        text = cell.text(value).encode("ascii")
        texts[i, : len(text)] = np.frombuffer(text, dtype=np.uint8)
    first_word, bits = _place(texts, offset)
    for k in range(bits.shape[1]):
        words[first_word + k, rows] |= bits[:, k]


def write_csv_columns(target: Path | BinaryIO, columns: Sequence[Column]) -> None:
    """Write a header line and the rows of equally long columns."""
    rows = len(columns[0][1]) if columns else 0

    def write(handle: BinaryIO) -> None:
        handle.write((",".join(name for name, _, _ in columns) + "\n").encode("ascii"))
        if rows:
            layout = _RowLayout.of(columns)
            words = layout.scratch(min(rows, CHUNK_ROWS))
            for start in range(0, rows, CHUNK_ROWS):
                handle.write(layout.chunk_bytes(columns, start, min(start + CHUNK_ROWS, rows), words))

    if isinstance(target, Path):
        with target.open("wb") as handle:
            write(handle)
    else:
        write(target)
