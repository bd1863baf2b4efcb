"""Replay flight logs through the diagnosis: log → telemetry table → the same core as the live agent → files.

For one log, :func:`replay_log` writes into its output folder:

* ``diagnosis.csv`` — one row per motor sample: ``time_s, motor, state, announced, steady, omega_rad_s,
  omega_model_rad_s, current_a, current_model_a, voltage_v`` (states as labels, ``F3.1``...), then the
  command and bus voltage the motor voltage came from;
* ``events.jsonl`` — one JSON object per change of a motor's announced state, with the evidence;
* ``report.html`` — one self-contained page: verdict per motor, fault timeline, measured vs model.

:func:`replay_many` replays many logs in worker processes (one folder per log) and writes a fleet summary
(``fleet_summary.csv`` and ``.json``). An existing output folder is never overwritten without ``force``.
"""

from __future__ import annotations

import csv
import json
import math
import os
import sys
import time
import traceback
import warnings
from collections.abc import Callable, Iterable, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, TextIO

import numpy as np
from numpy.typing import NDArray

from .diagnosis.noise import band_noise_of
from .diagnosis.pipeline import DIAGNOSIS_COLUMNS, RESIDUAL_COLUMNS, diagnose
from .diagnosis.profile import ThresholdProfile
from .diagnosis.states import MotorState
from .diagnosis.vehicle_check import VehicleFit, describe_vehicle_fit
from .errors import DataError, MotorHealthError
from .model.params import MotorParams
from .model.vehicle import VehicleParams
from .telemetry.table import TelemetryTable

__all__ = [
    "CONTEXT_COLUMNS",
    "FleetResult",
    "MotorVerdict",
    "ReplayResult",
    "collect_logs",
    "events_from_diagnosis",
    "motor_verdicts",
    "replay_log",
    "replay_many",
]

#: Columns copied into diagnosis.csv besides the diagnosis itself when the log has them: the two the
#: motor voltage comes from (voltage_v = throttle × bus_voltage_v).
CONTEXT_COLUMNS = ("throttle", "bus_voltage_v")
#: A motor whose samples lack speed or current this often is reported as NO_DATA.
NO_DATA_SHARE = 0.5
#: A motor whose telemetry ends this long before the others' is reported as NO_DATA (telemetry lost).
STALE_S = 5.0
#: What a folder is searched for (a CSV is replayed only when named: folders hold many other CSVs).
LOG_SUFFIXES = (".tlog", ".bin", ".ulg")
OUTPUT_FILES = ("diagnosis.csv", "events.jsonl", "report.html")


@dataclass(frozen=True)
class MotorVerdict:
    """What the replay concludes about one motor."""

    motor: int
    state: str  # label: NORMAL, F3.1, ..., NO_DATA
    reason: str
    first_fault_s: float | None
    fault_time_s: float
    final_state: str
    samples: int
    steady_samples: int
    no_data_share: float

    @property
    def is_fault(self) -> bool:
        return MotorState.from_label(self.state).is_fault


@dataclass(frozen=True)
class ReplayResult:
    """One replayed log: where its files are, the verdicts and the events."""

    log: str
    out_dir: str
    format: str
    duration_s: float
    rows: int
    verdicts: tuple[MotorVerdict, ...]
    events: tuple[dict[str, Any], ...]
    warnings: tuple[str, ...] = ()
    elapsed_s: float = 0.0
    error: str | None = None

    def summary_row(self) -> dict[str, Any]:
        faults = [v for v in self.verdicts if v.is_fault]
        nodata = [v for v in self.verdicts if v.state == "NO_DATA"]
        uncalibrated = any(v.state == "UNCALIBRATED" for v in self.verdicts)
        return {
            "log": self.log,
            "out_dir": self.out_dir,
            "format": self.format,
            "duration_s": round(self.duration_s, 3),
            "rows": self.rows,
            "motors": len(self.verdicts),
            "verdict": "ERROR"
            if self.error
            else (
                "FAULT"
                if faults
                else ("UNCALIBRATED" if uncalibrated else ("NO_DATA" if nodata else "NORMAL"))
            ),
            "faults": "; ".join(f"motor {v.motor} {v.state} from {v.first_fault_s:.1f} s" for v in faults),
            "no_data_motors": " ".join(str(v.motor) for v in nodata),
            "events": len(self.events),
            "warnings": len(self.warnings),
            "elapsed_s": round(self.elapsed_s, 3),
            "error": self.error or "",
        }


@dataclass(frozen=True)
class FleetResult:
    out_dir: str
    results: tuple[ReplayResult, ...] = field(default_factory=tuple)

    @property
    def failed(self) -> list[ReplayResult]:
        return [r for r in self.results if r.error]


class Progress:
    """A one-line progress indicator on stderr that shows up only when the work takes a moment."""

    def __init__(self, label: str, stream: TextIO | None = None, delay_s: float = 0.5) -> None:
        self.label = label
        self.stream = stream
        self.start = time.monotonic()
        self.delay_s = delay_s
        self.shown = False

    def update(self, done: int, total: int, what: str = "") -> None:
        if self.stream is None or time.monotonic() - self.start < self.delay_s:
            return
        width = 24
        filled = int(width * done / max(total, 1))
        bar = "#" * filled + "-" * (width - filled)
        self.stream.write(f"\r{self.label} [{bar}] {done}/{total} {what[:40]:40s}")
        self.stream.flush()
        self.shown = True

    def close(self) -> None:
        if self.shown and self.stream is not None:
            self.stream.write("\n")
            self.stream.flush()


def collect_logs(paths: Iterable[str | Path]) -> list[Path]:
    """The log files named, with folders searched recursively for ``.tlog .bin .ulg`` files."""
    found: list[Path] = []
    for p in map(Path, paths):
        if p.is_dir():
            found += sorted(f for f in p.rglob("*") if f.is_file() and f.suffix.lower() in LOG_SUFFIXES)
        else:
            found.append(p)
    if not found:
        raise DataError("no log files found", where=", ".join(map(str, paths)))
    return found


def events_from_diagnosis(result: TelemetryTable) -> list[dict[str, Any]]:
    """One event per change of a motor's announced state (the first sample starts from NORMAL)."""
    events: list[dict[str, Any]] = []
    motors = result["motor"]
    announced = result["announced"].astype(np.int64)
    change = np.zeros(len(result), dtype=bool)
    previous = np.full(len(result), int(MotorState.NORMAL), dtype=np.int64)
    if len(result):
        first = np.ones(len(result), dtype=bool)
        first[1:] = motors[1:] != motors[:-1]
        previous[1:] = announced[:-1]
        previous[first] = int(MotorState.NORMAL)
        change = announced != previous
    for i in np.flatnonzero(change).tolist():
        events.append(
            {
                "time_s": _num(result["time_s"][i]),
                "motor": int(motors[i]),
                "state": MotorState(int(announced[i])).label,
                "previous": MotorState(int(previous[i])).label,
                "description": MotorState(int(announced[i])).description,
                "evidence": {
                    "omega_rad_s": _num(result["omega_rad_s"][i]),
                    "omega_model_rad_s": _num(result["omega_model_rad_s"][i]),
                    "current_a": _num(result["current_a"][i]),
                    "current_model_a": _num(result["current_model_a"][i]),
                    "voltage_v": _num(result["voltage_v"][i]),
                    "raw_state": MotorState(int(result["state"][i])).label,
                    "steady": bool(result["steady"][i]),
                    # which equation the motor departs in (model/balance.py); None where not computed
                    **{name: _num(result[name][i]) for name in RESIDUAL_COLUMNS if name in result},
                },
            }
        )
    events.sort(key=lambda e: (e["time_s"], e["motor"]))
    return events


def _num(x: Any) -> float | None:
    value = float(x)
    return round(value, 6) if math.isfinite(value) else None


def rows_by_motor(motor: NDArray[np.int64], wanted: Sequence[int]) -> dict[int, slice | NDArray[np.bool_]]:
    """Each wanted motor's rows: a slice where the table is grouped by motor in order (the diagnosis'
    result is), else a mask."""
    if np.all(motor[1:] >= motor[:-1]):
        bounds = np.searchsorted(motor, [list(wanted), [m + 1 for m in wanted]])
        return {m: slice(int(a), int(b)) for m, a, b in zip(wanted, *bounds.tolist())}
    return {m: motor == m for m in wanted}


def motor_numbers(motor: NDArray[np.int64]) -> list[int]:
    """The motors a table has rows of, in order (without sorting where its rows are grouped by motor)."""
    if np.all(motor[1:] >= motor[:-1]):
        return motor[np.concatenate(([True], motor[1:] != motor[:-1]))].tolist() if len(motor) else []
    return [int(m) for m in np.unique(motor)]


def has_rows(rows: slice | NDArray[np.bool_]) -> bool:
    """Whether :func:`rows_by_motor`'s selection holds any row."""
    return rows.stop > rows.start if isinstance(rows, slice) else bool(rows.any())


def motor_verdicts(result: TelemetryTable, expected: Sequence[int] = ()) -> list[MotorVerdict]:
    """The verdict per motor: NO_DATA if its telemetry is missing or stale, else its main announced fault."""
    verdicts = []
    log_end = float(np.max(result["time_s"])) if len(result) else 0.0
    motors = sorted(set(motor_numbers(result["motor"])) | set(expected))
    selections = rows_by_motor(result["motor"], motors)
    for motor in motors:
        sel = selections[motor]
        n = len(result["time_s"][sel])
        if n == 0:
            verdicts.append(
                MotorVerdict(
                    motor,
                    "NO_DATA",
                    "no ESC telemetry for this motor in the log",
                    None,
                    0.0,
                    "NO_DATA",
                    0,
                    0,
                    1.0,
                )
            )
            continue
        t = result["time_s"][sel]
        raw = result["state"][sel].astype(np.int64)
        announced = result["announced"][sel].astype(np.int64)
        steady = int(result["steady"][sel].sum())
        no_data = float(np.mean(raw == MotorState.NO_DATA))
        dt = np.diff(t, append=t[-1])
        durations = np.bincount(announced, weights=dt, minlength=len(MotorState))
        faults = [s for s in MotorState if s.is_fault and durations[s] > 0]
        final = MotorState(int(announced[-1])).label
        if no_data > NO_DATA_SHARE:
            state, reason = (
                "NO_DATA",
                f"speed or current missing or stale in {100 * no_data:.0f} % of samples",
            )
            first, fault_time = None, 0.0
        elif log_end - t[-1] > STALE_S:
            state, reason = (
                "NO_DATA",
                f"telemetry stops at {t[-1]:.1f} s, {log_end - t[-1]:.1f} s before the others",
            )
            first, fault_time = None, 0.0
        elif faults:
            main = max(faults, key=lambda s: durations[s])
            first = float(t[np.argmax(announced == main)])
            fault_time = float(durations[main])
            state = main.label
            reason = f"{main.description} announced from {first:.1f} s, {fault_time:.1f} s in total"
        elif durations[MotorState.UNCALIBRATED] > 0:
            since = float(t[np.argmax(announced == MotorState.UNCALIBRATED)])
            state, reason, first, fault_time = (
                "UNCALIBRATED",
                f"the motor model does not describe this vehicle (from {since:.1f} s): no fault can be named",
                None,
                0.0,
            )
        else:
            state, reason, first, fault_time = "NORMAL", "no fault announced", None, 0.0
        verdicts.append(MotorVerdict(motor, state, reason, first, fault_time, final, n, steady, no_data))
    return verdicts


def _check_out_dir(out_dir: Path, force: bool) -> None:
    """Refuse an output folder that exists with files in it (unless ``force``) or that is a file."""
    if out_dir.exists() and not out_dir.is_dir():
        raise DataError("exists and is not a folder", path=out_dir)
    if out_dir.is_dir() and any(out_dir.iterdir()) and not force:
        raise DataError(
            "output folder exists already; not overwritten (use --force to replace its files)", path=out_dir
        )


def write_diagnosis_csv(result: TelemetryTable, path: Path) -> None:
    """diagnosis.csv: time to the µs, other numbers to 4 decimals, states as labels (``F3.1``)."""
    from .replay_csv import Column, write_csv_columns

    labels = [s.label for s in MotorState]
    extra = [c for c in CONTEXT_COLUMNS if c in result]
    pairing = result.get("pairing_error_rad_s")
    if pairing is not None and np.isfinite(pairing).any():  # the log said how closely it pairs (pairing.py)
        extra.append("pairing_error_rad_s")
    columns: list[Column] = []
    for name in [*DIAGNOSIS_COLUMNS, *extra]:
        values = result[name]
        if name in ("state", "announced"):
            columns.append((name, values, labels))
        elif name in ("motor", "steady"):
            columns.append((name, values.astype(np.int64), 0))
        else:
            columns.append((name, values, 6 if name == "time_s" else 4))
    write_csv_columns(path, columns)


#: the flight profile's benchmark figures hold for samples paired with a command within this (the agent's
#: 200 Hz streams; docs/flight.md, section 6, "Through the logs")
PAIRING_OK_S = 0.0075


def pairing_note(meta: Mapping[str, Any], profile: ThresholdProfile) -> str | None:
    """A warning when the log pairs ESC samples with motor commands too loosely for the balance rule."""
    pairing = meta.get("pairing_s")
    if profile.steady.kind != "balance" or pairing is None or not pairing > PAIRING_OK_S:
        return None
    return (
        f"ESC samples are paired with motor commands only to within about {1000 * pairing:.0f} ms in this "
        f"log; the {profile.name!r} profile holds its benchmark figures with commands within about 5 ms. "
        "Where the commands move fast (gusts, manoeuvres) the diagnosis does not use the current there, or "
        "does not judge at all (pairing_error_rad_s and sensor flag 128, current_unpaired, in "
        'diagnosis.csv), and small faults go unseen (docs/flight.md, section 6, "Through the logs"). Log '
        "or stream the ESC telemetry and the motor outputs at 200 Hz to avoid this."
    )


def vehicle_note(meta: Mapping[str, Any], params: MotorParams | dict[int, MotorParams]) -> str | None:
    """The vehicle check's line where the motor model does not describe the logged vehicle."""
    check = meta.get("vehicle_check")
    if not check or check["verdict"] != VehicleFit.SPEED_OFF:
        return None
    model = params if isinstance(params, MotorParams) else params[min(params)]
    return describe_vehicle_fit(check["verdict"], check["departures"], f"the motor model {model.name!r}")


def replay_log(
    log: str | Path,
    out_dir: str | Path,
    params: MotorParams | dict[int, MotorParams] | VehicleParams,
    profile: ThresholdProfile,
    *,
    force: bool = False,
    progress: TextIO | None = None,
    reissue_warnings: bool = True,
    calibrate_s: tuple[float, float] | None = None,
) -> ReplayResult:
    """Replay one log into ``out_dir`` (diagnosis.csv, events.jsonl, report.html).

    ``calibrate_s`` (start, end): first fit the motor model on that healthy stretch of the same log
    (:func:`~mav_motor_health.diagnosis.calibration.calibrate`, ``params`` as the base), then diagnose
    the whole flight with it.
    """
    from .replay_report import render_report
    from .telemetry import sources

    started = time.monotonic()
    log, out_dir = Path(log), Path(out_dir)
    _check_out_dir(out_dir, force)
    bar = Progress(log.name, progress)
    bar.update(0, 4, "reading")
    with warnings.catch_warnings(record=True) as recorded:
        warnings.simplefilter("always")
        table = sources.read(log)
    # what the reader said of this log; a ResourceWarning is the garbage collector's word on some other
    # object that happened to be collected meanwhile (catch_warnings records the whole process)
    caught = [w for w in recorded if not issubclass(w.category, ResourceWarning)]
    warned = tuple(str(w.message) for w in caught)
    notes = warned
    if reissue_warnings:
        for w in caught:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    if len(table) == 0:
        raise DataError("the log's ESC telemetry has no samples for any motor", path=log)
    noise = None
    if isinstance(params, VehicleParams):  # the vehicle's ESC map and current sensing, then its motors
        noise = band_noise_of(params.noise)  # the noise its bands are measured in (noise_bands profiles)
        table = params.calibrate(table)
        params = params.models(range(1, max(motor_numbers(table["motor"])) + 1))
    if calibrate_s is not None:
        from .diagnosis.calibration import calibrate

        base = params if isinstance(params, MotorParams) else params[min(params)]
        calibration = calibrate(table, base, *calibrate_s)
        params = calibration.params
        how = "speed only: the current is not trusted" if calibration.speed_only else "speed and current"
        notes += (
            f"Motor model calibrated on {calibrate_s[0]:g}–{calibrate_s[1]:g} s of this log ({how}; "
            f"{calibration.samples} samples, {100 * calibration.current_trusted_share:.0f} % with a "
            "trusted current).",
        )
    pairing = pairing_note(table.meta, profile)
    if pairing is not None:
        warned += (pairing,)
        notes += (pairing,)
        if reissue_warnings:
            warnings.warn(f"{log}: {pairing}", UserWarning, stacklevel=2)
    bar.update(1, 4, f"diagnosing {len(motor_numbers(table['motor']))} motors" if progress else "")
    result = diagnose(table, params, profile, noise)  # the same core the live agent runs
    unfit = vehicle_note(result.meta, params)
    if unfit is not None:
        warned += (unfit,)
        notes += (unfit,)
        if reissue_warnings:
            warnings.warn(f"{log}: {unfit}", UserWarning, stacklevel=2)
    expected = [int(m) for m in table.meta.get("motors", [])]
    verdicts = motor_verdicts(result, expected)
    events = events_from_diagnosis(result)
    bar.update(2, 4, "writing diagnosis.csv")
    out_dir.mkdir(parents=True, exist_ok=True)
    write_diagnosis_csv(result, out_dir / "diagnosis.csv")
    with (out_dir / "events.jsonl").open("w", encoding="utf-8") as handle:
        for event in events:
            handle.write(json.dumps(event) + "\n")
    bar.update(3, 4, "writing report.html")
    meta = dict(table.meta)
    duration = float(meta.get("duration_s") or (np.ptp(table["time_s"]) if len(table) else 0.0))
    html = render_report(log, result, verdicts, events, profile, params, meta, notes)
    (out_dir / "report.html").write_text(html, encoding="utf-8")
    bar.update(4, 4, "done")
    bar.close()
    return ReplayResult(
        log=str(log),
        out_dir=str(out_dir),
        format=str(meta.get("format", log.suffix.lstrip("."))),
        duration_s=duration,
        rows=len(result),
        verdicts=tuple(verdicts),
        events=tuple(events),
        warnings=warned,
        elapsed_s=time.monotonic() - started,
    )


def _replay_worker(
    log: str,
    out_dir: str,
    params: MotorParams | dict[int, MotorParams] | VehicleParams,
    profile: ThresholdProfile,
    force: bool,
    calibrate_s: tuple[float, float] | None = None,
) -> ReplayResult:
    started = time.monotonic()
    try:
        return replay_log(
            log, out_dir, params, profile, force=force, reissue_warnings=False, calibrate_s=calibrate_s
        )
    except MotorHealthError as exc:
        return _error_result(log, out_dir, str(exc), started)
    except Exception as exc:  # a bug met in this log must not stop the others: an ERROR row that says so
        detail = traceback.format_exc()
        return _error_result(
            log,
            out_dir,
            f"internal error ({type(exc).__name__}: {exc}); please report it with this log",
            started,
            (detail,),
        )


def _error_result(
    log: str, out_dir: str, message: str, started: float, detail: tuple[str, ...] = ()
) -> ReplayResult:
    return ReplayResult(
        log,
        out_dir,
        Path(log).suffix.lstrip("."),
        0.0,
        0,
        (),
        (),
        detail,
        time.monotonic() - started,
        message,
    )


def _folder_names(logs: Sequence[Path]) -> list[str]:
    names: list[str] = []
    for log in logs:
        base = log.name.replace(".", "_")
        name, k = base, 2
        while name in names:
            name, k = f"{base}-{k}", k + 1
        names.append(name)
    return names


def replay_many(
    logs: Sequence[str | Path],
    out_dir: str | Path,
    params: MotorParams | dict[int, MotorParams] | VehicleParams,
    profile: ThresholdProfile,
    *,
    force: bool = False,
    jobs: int | None = None,
    progress: TextIO | None = None,
    on_result: Callable[[ReplayResult], None] | None = None,
    calibrate_s: tuple[float, float] | None = None,
    dask_scheduler: str | None = None,
) -> FleetResult:
    """Replay many logs in worker processes: ``out_dir/<log name>/`` each, plus the fleet summary.

    ``dask_scheduler`` (a dask.distributed scheduler address, ``tcp://HOST:8786``) maps the logs over that
    cluster instead of local processes; its workers read the logs and write each log's folder, so both
    paths must be the same on every worker (a shared filesystem). The fleet summary is written here.
    """
    paths = [Path(p) for p in logs]
    out_dir = Path(out_dir)
    _check_out_dir(out_dir, force)
    out_dir.mkdir(parents=True, exist_ok=True)
    folders = [out_dir / name for name in _folder_names(paths)]
    jobs = max(1, min(jobs or (os.cpu_count() or 1), len(paths)))
    results: list[ReplayResult] = []
    bar = Progress(f"replay {len(paths)} logs", progress, delay_s=0.0)
    bar.update(0, len(paths))
    if dask_scheduler is not None:
        for result in _replay_on_dask(dask_scheduler, paths, folders, params, profile, force, calibrate_s):
            results.append(result)
            if on_result:
                on_result(result)
            bar.update(len(results), len(paths), Path(result.log).name)
    elif jobs == 1:
        for path, folder in zip(paths, folders):
            results.append(_replay_worker(str(path), str(folder), params, profile, force, calibrate_s))
            if on_result:
                on_result(results[-1])
            bar.update(len(results), len(paths), path.name)
    else:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            futures = {
                pool.submit(_replay_worker, str(p), str(f), params, profile, force, calibrate_s): (p, f)
                for p, f in zip(paths, folders)
            }
            for future in as_completed(futures):
                try:
                    results.append(future.result())
                except Exception as exc:  # the worker process itself died (killed, out of memory)
                    log, folder = futures[future]
                    message = f"worker process failed ({type(exc).__name__}: {exc})"
                    results.append(_error_result(str(log), str(folder), message, time.monotonic()))
                if on_result:
                    on_result(results[-1])
                bar.update(len(results), len(paths), Path(results[-1].log).name)
    bar.close()
    order = {str(p): i for i, p in enumerate(paths)}
    results.sort(key=lambda r: order[r.log])
    write_fleet_summary(out_dir, results)
    return FleetResult(str(out_dir), tuple(results))


def _replay_on_dask(
    scheduler: str,
    paths: Sequence[Path],
    folders: Sequence[Path],
    params: MotorParams | dict[int, MotorParams] | VehicleParams,
    profile: ThresholdProfile,
    force: bool,
    calibrate_s: tuple[float, float] | None,
) -> Iterable[ReplayResult]:
    """Each log's replay as one task on a dask.distributed cluster, results as they finish."""
    try:
        from distributed import Client
        from distributed import as_completed as finished
    except ImportError:
        raise DataError(
            "replay --dask needs dask.distributed: pip install 'mav-motor-health[fleet]'"
        ) from None
    with Client(scheduler, timeout=30) as client:
        futures = {
            client.submit(
                _replay_worker,
                str(p),
                str(f),
                params,
                profile,
                force,
                calibrate_s,
                pure=False,
                key=f"replay-{f.name}",
            ): (p, f)
            for p, f in zip(paths, folders)
        }
        for future in finished(list(futures)):
            try:
                yield future.result()
            except Exception as exc:  # the worker died or could not run the task
                log, folder = futures[future]
                yield _error_result(
                    str(log),
                    str(folder),
                    f"dask worker failed ({type(exc).__name__}: {exc})",
                    time.monotonic(),
                )


def write_fleet_summary(out_dir: Path, results: Sequence[ReplayResult]) -> None:
    rows = [r.summary_row() for r in results]
    with (out_dir / "fleet_summary.csv").open("w", encoding="utf-8", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]) if rows else ["log"])
        writer.writeheader()
        writer.writerows(rows)
    detail = [
        {**r.summary_row(), "verdicts": [asdict(v) for v in r.verdicts], "warning_messages": list(r.warnings)}
        for r in results
    ]
    (out_dir / "fleet_summary.json").write_text(json.dumps(detail, indent=2), encoding="utf-8")


def print_verdicts(result: ReplayResult, stream: TextIO | None = None) -> None:
    # sys.stdout looked up at the call, not at import: it may have been replaced since (tests, embedding)
    stream = sys.stdout if stream is None else stream
    stream.write(f"{result.log}: {result.rows} samples, {result.duration_s:.1f} s -> {result.out_dir}\n")
    for v in result.verdicts:
        stream.write(f"  motor {v.motor}: {v.state:8s} {v.reason}\n")
