"""Motor and propeller test-stand files: steady points, one row per throttle step.

Three public formats (see ``real_logs/MANIFEST.md``), recognised by their first line:

``strawson``  RCbenchmark 1520 CSV (StrawsonDesign motor_propeller_testing): ``ESC signal (µs)``,
              ``Voltage (V)`` (battery), ``Current (A)`` (battery), ``Motor Electrical Speed (RPM)``.
              Despite its name, that column is read as *mechanical* RPM (``pole_pairs = 1``): the
              back-EMF constant fitted from it matches the motors' KV ratings (e.g. a1, 2600 KV:
              k_e 0.0032 fitted vs 0.0037 V·s/rad from KV; h3, 2400 KV: 0.0040 vs 0.0040), while
              dividing by the 7 pole pairs of these 12N14P motors gives k_e seven times too large.
              The RCbenchmark software converts with the pole count it is configured with; pass
              ``pole_pairs`` for files recorded without that setting. Throttle = ``(µs − 1000)/1000``.
``ctu``       the CTU-MRS table extract (``motor,propeller,throttle_pct_assumed,...``): one group of rows
              per motor/propeller pair, numbered as motors 1..N in file order (``meta["motors"]`` names
              them); RPM is mechanical (BLHeli_32 telemetry), voltage and current are the battery's.
``dtu``       the DTU hexacopter stand's text files (``% Measurement from esc,motor,propeller test``):
              ESC value 0..1024 (= 1..2 ms), speed in rotations per second from two sensors (averaged),
              battery voltage, total current, thrust [gf], motor and ESC temperature [°C].

In all three the voltage is the *battery's* and the current the *battery's*: the motor sees
``throttle × bus_voltage_v`` only for an ideal ESC, and the current it draws is larger than the
battery's by 1/duty. The table therefore gives ``throttle`` and ``bus_voltage_v`` (not ``voltage_v``),
``current_a`` as measured, and the ``esc_pwm`` effect of the workbench models the rest. ``time_s`` is
the stand's clock where it has one, else the row number (one step per second). Rows that cannot be read
are skipped with one warning naming the file and lines.
"""

from __future__ import annotations

import csv as _csv
import math
import warnings
from pathlib import Path

import numpy as np

from ..errors import DataError
from .table import TelemetryTable

__all__ = ["BENCH_FORMATS", "bench_format", "read_bench"]

BENCH_FORMATS = ("strawson", "ctu", "dtu")
RPM_TO_RAD_S = 2.0 * math.pi / 60.0
GRAM_FORCE_N = 9.80665e-3
STRAWSON_POLE_PAIRS = 1  # the column is already mechanical RPM, see the module doc


def _first_line(path: Path) -> str:
    try:
        with path.open("r", encoding="utf-8-sig", errors="replace") as handle:
            return handle.readline().strip()
    except OSError as exc:
        raise DataError(f"cannot read: {exc.strerror or exc}", path=path) from exc


def bench_format(path: str | Path) -> str | None:
    """``"strawson"``, ``"ctu"`` or ``"dtu"`` when the file is one of those bench formats, else None."""
    path = Path(path)
    if not path.is_file():
        return None
    line = _first_line(path)
    if line.startswith("Time (s),ESC signal"):
        return "strawson"
    if line.startswith("motor,propeller,throttle_pct_assumed"):
        return "ctu"
    if line.startswith("% Measurement from esc,motor,propeller test"):
        return "dtu"
    return None


def read_bench(path: str | Path, *, fmt: str | None = None, pole_pairs: int | None = None) -> TelemetryTable:
    """Read a test-stand file (format detected unless ``fmt`` is given) into a telemetry table."""
    path = Path(path)
    fmt = fmt or bench_format(path)
    if fmt == "strawson":
        return _read_strawson(path, pole_pairs or STRAWSON_POLE_PAIRS)
    if fmt == "ctu":
        return _read_ctu(path)
    if fmt == "dtu":
        return _read_dtu(path)
    raise DataError(
        f"not a known test-stand file (first line {_first_line(path)[:60]!r})",
        path=path,
        where="line 1",
    )


def _float(cell: str) -> float:
    cell = cell.strip()
    return float(cell) if cell else math.nan


def _warn_bad(path: Path, bad: list[int]) -> None:
    if bad:
        shown = ", ".join(map(str, bad[:5])) + (", ..." if len(bad) > 5 else "")
        warnings.warn(f"{path}: {len(bad)} row(s) could not be read (line {shown}); skipped", stacklevel=3)


def _read_strawson(path: Path, pole_pairs: int) -> TelemetryTable:
    with path.open(newline="", encoding="utf-8-sig") as handle:
        rows = list(_csv.reader(handle))
    header = [h.strip() for h in rows[0]]
    want = {
        "time_s": "Time (s)",
        "esc_us": "ESC signal (µs)",
        "thrust_gf": "Thrust (gf)",
        "bus_voltage_v": "Voltage (V)",
        "current_a": "Current (A)",
        "erpm": "Motor Electrical Speed (RPM)",
    }
    missing = [v for v in want.values() if v not in header]
    if missing:
        raise DataError(f"RCbenchmark file lacks column(s) {', '.join(missing)}", path=path, where="line 1")
    col = {k: header.index(v) for k, v in want.items()}
    values: dict[str, list[float]] = {k: [] for k in want}
    bad = []
    for line_no, row in enumerate(rows[1:], start=2):
        if not any(c.strip() for c in row):
            continue
        try:
            parsed = {k: _float(row[j]) for k, j in col.items()}
        except (ValueError, IndexError):
            bad.append(line_no)
            continue
        for k, x in parsed.items():
            values[k].append(x)
    _warn_bad(path, bad)
    arr = {k: np.asarray(v, float) for k, v in values.items()}
    n = len(arr["time_s"])
    return TelemetryTable.from_columns(
        source=str(path),
        meta={"format": "strawson", "pole_pairs": pole_pairs, "speed": "RPM column / pole_pairs"},
        time_s=arr["time_s"],
        motor=np.ones(n, dtype=int),
        omega_rad_s=arr["erpm"] / pole_pairs * RPM_TO_RAD_S,
        current_a=arr["current_a"],
        throttle=np.clip((arr["esc_us"] - 1000.0) / 1000.0, 0.0, 1.0),
        bus_voltage_v=arr["bus_voltage_v"],
        thrust_n=arr["thrust_gf"] * GRAM_FORCE_N,
    )


def _read_ctu(path: Path) -> TelemetryTable:
    with path.open(newline="", encoding="utf-8-sig") as handle:
        rows = list(_csv.DictReader(handle))
    groups: dict[str, int] = {}
    cols: dict[str, list[float]] = {
        k: [] for k in ("time_s", "motor", "throttle", "thrust_n", "rpm", "v", "i")
    }
    bad = []
    for line_no, row in enumerate(rows, start=2):
        key = f"{row.get('motor', '').strip()} | {row.get('propeller', '').strip()}"
        try:
            parsed = (
                _float(row["throttle_pct_assumed"]) / 100.0,
                _float(row["Thrust (g)"]) * GRAM_FORCE_N,
                _float(row["RPM"]),
                _float(row["Voltage (V)"]),
                _float(row["Current (A)"]),
            )
        except (ValueError, KeyError, TypeError):
            bad.append(line_no)
            continue
        motor = groups.setdefault(key, len(groups) + 1)
        cols["time_s"].append(float(sum(1 for m in cols["motor"] if m == motor)))
        cols["motor"].append(motor)
        for k, x in zip(("throttle", "thrust_n", "rpm", "v", "i"), parsed):
            cols[k].append(x)
    _warn_bad(path, bad)
    if not cols["motor"]:
        raise DataError("no readable row", path=path, where="line 2 on")
    a = {k: np.asarray(v, float) for k, v in cols.items()}
    return TelemetryTable.from_columns(
        source=str(path),
        meta={"format": "ctu", "motors": {m: k for k, m in groups.items()}},
        time_s=a["time_s"],
        motor=a["motor"].astype(int),
        omega_rad_s=a["rpm"] * RPM_TO_RAD_S,
        current_a=a["i"],
        throttle=a["throttle"],
        bus_voltage_v=a["v"],
        thrust_n=a["thrust_n"],
    )


def _read_dtu(path: Path) -> TelemetryTable:
    rows: list[list[float]] = []
    bad = []
    with path.open(encoding="utf-8", errors="replace") as handle:
        for line_no, line in enumerate(handle, start=1):
            text = line.strip()
            if not text or text.startswith("%"):
                continue
            try:
                fields = [float(x) for x in text.split()]
            except ValueError:
                bad.append(line_no)
                continue
            if len(fields) < 9:
                bad.append(line_no)
                continue
            rows.append(fields[:9])
    _warn_bad(path, bad)
    if not rows:
        raise DataError("no data row (expected 9 numbers per line after the % header)", path=path)
    a = np.asarray(rows, float)
    rps = np.nanmean(a[:, 1:3], axis=1)
    return TelemetryTable.from_columns(
        source=str(path),
        meta={"format": "dtu"},
        time_s=np.arange(len(a), dtype=float),
        motor=np.ones(len(a), dtype=int),
        omega_rad_s=rps * 2.0 * math.pi,
        current_a=a[:, 4],
        throttle=a[:, 0] / 1024.0,
        bus_voltage_v=a[:, 3],
        thrust_n=a[:, 5] * GRAM_FORCE_N,
        motor_temp_c=a[:, 7],
        esc_temp_c=a[:, 8],
    )
