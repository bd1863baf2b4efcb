"""A CSV writer for long numeric tables, vectorised with numpy: no Python work per value.

Each column becomes a byte matrix (one row per table row, fixed width, unused bytes 0): numbers in fixed
point (``decimals`` places, trailing zeros and a bare decimal point dropped), labels from a look-up table.
The matrices are laid side by side with commas and newlines, and the zero bytes are removed from the
flattened buffer, which leaves ordinary variable-width CSV text. Missing values (NaN) are empty cells.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import BinaryIO

import numpy as np
from numpy.typing import NDArray

__all__ = ["Column", "fixed_point_bytes", "label_bytes", "write_csv_columns"]

#: (name, values, decimals or labels): decimals for numbers, a label list for integer codes.
Column = tuple[str, NDArray, "int | Sequence[str]"]
CHUNK_ROWS = 200_000


def fixed_point_bytes(values: NDArray, decimals: int) -> NDArray[np.uint8]:
    """Numbers as ASCII in fixed point, one row per value, padded with zero bytes (removed later)."""
    v = np.asarray(values, dtype=float)
    finite = np.isfinite(v)
    scale = 10**decimals
    magnitude = np.abs(np.where(finite, v, 0.0))
    scaled = np.round(np.minimum(magnitude, 1e15) * scale).astype(np.int64)
    whole, frac = np.divmod(scaled, scale)
    digits = max(int(whole.max()) if len(whole) else 0, 1)
    width_int = len(str(digits))
    width = 1 + width_int + (1 + decimals if decimals else 0)
    out = np.zeros((len(v), width), dtype=np.uint8)
    out[:, 0] = np.where((v < 0) & (scaled > 0), ord("-"), 0)
    rest = whole.copy()
    for k in range(width_int):
        col = width_int - k
        rest, digit = np.divmod(rest, 10)
        out[:, col] = 48 + digit
        if k > 0:
            out[(rest == 0) & (digit == 0), col] = 0  # a leading zero
    if decimals:
        point = width_int + 1
        rest = frac.copy()
        for k in range(decimals):
            rest, digit = np.divmod(rest, 10)
            out[:, point + decimals - k] = 48 + digit
        trailing = np.ones(len(v), dtype=bool)
        for col in range(point + decimals, point, -1):
            trailing &= out[:, col] == 48
            out[trailing, col] = 0
        out[:, point] = np.where(trailing, 0, ord("."))
    out[~finite] = 0
    return out


def label_bytes(codes: NDArray, labels: Sequence[str]) -> NDArray[np.uint8]:
    """Integer codes as their labels (ASCII), padded with zero bytes."""
    width = max(len(label) for label in labels)
    table = np.zeros((len(labels), width), dtype=np.uint8)
    for i, label in enumerate(labels):
        table[i, : len(label)] = np.frombuffer(label.encode("ascii"), dtype=np.uint8)
    return table[np.asarray(codes, dtype=np.int64)]


def _chunk_bytes(columns: Sequence[Column], start: int, stop: int) -> bytes:
    parts: list[NDArray[np.uint8]] = []
    n = stop - start
    comma = np.full((n, 1), ord(","), dtype=np.uint8)
    for k, (_, values, how) in enumerate(columns):
        chunk = values[start:stop]
        parts.append(fixed_point_bytes(chunk, how) if isinstance(how, int) else label_bytes(chunk, how))
        parts.append(comma if k < len(columns) - 1 else np.full((n, 1), ord("\n"), dtype=np.uint8))
    flat = np.concatenate(parts, axis=1).ravel()
    return flat[flat != 0].tobytes()


def write_csv_columns(target: Path | BinaryIO, columns: Sequence[Column]) -> None:
    """Write a header line and the rows of equally long columns."""
    rows = len(columns[0][1]) if columns else 0

    def write(handle: BinaryIO) -> None:
        handle.write((",".join(name for name, _, _ in columns) + "\n").encode("ascii"))
        for start in range(0, rows, CHUNK_ROWS):
            handle.write(_chunk_bytes(columns, start, min(start + CHUNK_ROWS, rows)))

    if isinstance(target, Path):
        with target.open("wb") as handle:
            write(handle)
    else:
        write(target)
