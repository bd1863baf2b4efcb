"""Score a diagnosis against ground truth, beside the paper's own results (section IV).

Inputs: a diagnosis table (columns ``time_s, motor, state, announced, steady`` with state labels such
as ``F3.1`` or integer codes — what ``diagnose``/``replay`` write) and a truth sidecar JSON written by
the simulator (``fault``, ``motor``, ``onset_s``...).

Metrics:

* **fault accuracy** — share of the faulty motor's *steady* samples after onset whose raw state is the
  true fault (the paper's flight F4.1 figures were taken over all samples after injection: we give that
  too, ``fault_accuracy_all``);
* **normal accuracy** — share of healthy steady samples (other motors, and the faulty motor before
  onset) diagnosed ``NORMAL`` (and over all healthy samples);
* **model accuracy** — the paper's "normal operation estimated to an accuracy of 99.11 %" is the model's
  accuracy on healthy data (:func:`~mav_motor_health.model.estimation.accuracy_pct`, mean of speed and
  current), given when the diagnosis has the measured and modelled columns;
* **time to detection** — from onset to the first announced state equal to the true fault;
* **false fault events per hour** — announcements of any fault state (the five faults, UNKNOWN, and the
  speed-only SLOW/STALLED/FAST) on a healthy motor (or before onset), per hour of flight.
"""

from __future__ import annotations

import csv
import json
import math
from collections import Counter
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..diagnosis.states import MotorState
from ..errors import DataError
from ..model.estimation import accuracy_pct

__all__ = ["PAPER", "Score", "format_score", "read_diagnosis", "read_truth", "score"]

#: The paper's results (Lee et al. 2021, section IV): testbed diagnosis times [s]; flight accuracies [%].
PAPER: dict[str, Any] = {
    "testbed_detection_s": {"F1.1": 1.1, "F2.1": 0.8, "F3.1": 0.35, "F4.1": 0.43, "F4.2": 0.9},
    "flight_F4.1_accuracy_pct": {"test 1 (calm)": 98.49, "test 2 (moderate)": 93.70, "test 3 (gusty)": 71.85},
    "flight_F4.1_detection_s": {"test 1 (calm)": 0.1, "test 2 (moderate)": 0.2, "test 3 (gusty)": 1.4},
    "flight_F4.2_error_pct": 2.44,
    "flight_normal_accuracy_pct": 99.11,
}
#: Every state that says a motor is faulty (the five faults, UNKNOWN and the speed-only SLOW/STALLED/FAST).
_FAULT_CODES = [int(state) for state in MotorState if state.is_fault]
_TURBULENCE_TEST = {"calm": "test 1 (calm)", "moderate": "test 2 (moderate)", "gusty": "test 3 (gusty)"}


@dataclass(frozen=True)
class Score:
    fault: str | None
    motor: int | None
    onset_s: float | None
    fault_accuracy_pct: float | None
    fault_accuracy_all_pct: float | None
    detection_s: float | None
    normal_accuracy_pct: float | None
    normal_accuracy_all_pct: float | None
    #: the model's accuracy on healthy samples (speed and current, paper's definition; NaN without them)
    model_accuracy_pct: float | None
    false_events: int
    false_events_per_hour: float
    hours: float
    samples: int
    #: the false events by the state announced (label: count), e.g. ``{"F2.1": 2}``
    false_events_by_state: dict[str, int] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def _codes(values: list[str], path: Path, column: str) -> NDArray[np.int64]:
    out = np.empty(len(values), dtype=np.int64)
    for k, v in enumerate(values):
        v = v.strip()
        try:
            out[k] = int(v) if v.lstrip("-").isdigit() else int(MotorState.from_label(v))
        except ValueError:
            raise DataError(
                f"'{v}' is not a motor state", path=path, where=f"row {k + 2}, column {column}"
            ) from None
    return out


def read_diagnosis(path: str | Path) -> dict[str, NDArray[Any]]:
    """A diagnosis CSV: ``time_s, motor, state, announced, steady`` (+ anything else, ignored)."""
    path = Path(path)
    try:
        with path.open(newline="", encoding="utf-8-sig") as handle:
            rows = list(csv.reader(handle))
    except OSError as exc:
        raise DataError(f"cannot read: {exc.strerror or exc}", path=path) from exc
    if not rows:
        raise DataError("empty file; expected a header with time_s,motor,state,announced,steady", path=path)
    header = [h.strip() for h in rows[0]]
    needed = ("time_s", "motor", "state", "announced", "steady")
    missing = [c for c in needed if c not in header]
    if missing:
        raise DataError(f"missing column(s) {', '.join(missing)}", path=path, where="line 1")
    body = [r for r in rows[1:] if len(r) == len(header)]
    col = {name: [r[header.index(name)] for r in body] for name in needed}
    extra: dict[str, NDArray[Any]] = {}
    for name in ("omega_rad_s", "omega_model_rad_s", "current_a", "current_model_a"):
        if name in header:
            j = header.index(name)
            extra[name] = np.array([_float(r[j]) for r in body])
    try:
        time_s = np.array([float(x) for x in col["time_s"]])
        motor = np.array([int(float(x)) for x in col["motor"]])
    except ValueError as exc:
        raise DataError(f"not a number: {exc}", path=path, where="column time_s or motor") from None
    steady = np.array([x.strip().lower() in ("1", "true", "yes") for x in col["steady"]])
    return {
        "time_s": time_s,
        "motor": motor,
        "state": _codes(col["state"], path, "state"),
        "announced": _codes(col["announced"], path, "announced"),
        "steady": steady,
        **extra,
    }


def _float(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        return float("nan")


def read_truth(path: str | Path) -> dict[str, Any]:
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise DataError(f"cannot read: {exc.strerror or exc}", path=path) from exc
    except json.JSONDecodeError as exc:
        raise DataError(f"not JSON: {exc.msg}", path=path, where=f"line {exc.lineno}") from None
    if not isinstance(data, dict) or "faults" not in data:
        raise DataError("not a simulator truth file", path=path, where="expected a 'faults' list")
    return data


def score(diagnosis: Mapping[str, NDArray[Any]], truth: Mapping[str, Any]) -> Score:
    t, motor = diagnosis["time_s"], diagnosis["motor"]
    state, announced, steady = diagnosis["state"], diagnosis["announced"], diagnosis["steady"]
    faults = truth.get("faults") or []
    f = faults[0] if faults else None
    hours = float(truth.get("duration_s") or (t.max() - t.min() if t.size else 0.0)) / 3600.0
    healthy = np.ones(t.size, dtype=bool)
    fault_acc = fault_all = detection = None
    if f is not None:
        code = int(MotorState.from_label(f["fault"]))
        on = float(f["onset_s"])
        end = f.get("end_s")
        end = math.inf if end is None else float(end)
        after = (motor == int(f["motor"])) & (t >= on) & (t < end)
        healthy &= ~((motor == int(f["motor"])) & (t >= on))
        sel = after & steady
        fault_acc = 100.0 * float(np.mean(state[sel] == code)) if sel.any() else None
        fault_all = 100.0 * float(np.mean(state[after] == code)) if after.any() else None
        hit = np.flatnonzero(after & (announced == code))
        detection = float(t[hit[0]] - on) if hit.size else None
    normal_sel = healthy & steady
    normal_acc = 100.0 * float(np.mean(state[normal_sel] == MotorState.NORMAL)) if normal_sel.any() else None
    normal_all = 100.0 * float(np.mean(state[healthy] == MotorState.NORMAL)) if healthy.any() else None
    model_acc = None
    if all(k in diagnosis for k in ("omega_rad_s", "omega_model_rad_s", "current_a", "current_model_a")):
        model_acc = 0.5 * (
            accuracy_pct(diagnosis["omega_rad_s"][healthy], diagnosis["omega_model_rad_s"][healthy])
            + accuracy_pct(diagnosis["current_a"][healthy], diagnosis["current_model_a"][healthy])
        )
    by_state: Counter[str] = Counter()
    for m in np.unique(motor):
        sel = np.flatnonzero((motor == m) & healthy)
        a = announced[sel]
        is_fault = np.isin(a, _FAULT_CODES)
        starts = np.flatnonzero(np.concatenate([is_fault[:1], is_fault[1:] & (a[1:] != a[:-1])]))
        by_state.update(MotorState(int(code)).label for code in a[starts].tolist())
    false_events = sum(by_state.values())
    return Score(
        fault=None if f is None else str(f["fault"]),
        motor=None if f is None else int(f["motor"]),
        onset_s=None if f is None else float(f["onset_s"]),
        fault_accuracy_pct=fault_acc,
        fault_accuracy_all_pct=fault_all,
        detection_s=detection,
        normal_accuracy_pct=normal_acc,
        normal_accuracy_all_pct=normal_all,
        model_accuracy_pct=model_acc,
        false_events=false_events,
        false_events_per_hour=false_events / hours if hours > 0 else float("nan"),
        hours=hours,
        samples=int(t.size),
        false_events_by_state=dict(sorted(by_state.items())),
    )


def _pct(x: float | None) -> str:
    return "   -   " if x is None else f"{x:6.2f} %"


def format_score(s: Score, truth: Mapping[str, Any]) -> str:
    """The score as text, with the paper's figure for the same situation beside it."""
    mode = truth.get("mode")
    lines = [f"scenario {truth.get('scenario', '?')} ({mode}, {s.samples} samples, {s.hours * 60:.1f} min)"]
    paper_time = paper_acc = None
    if s.fault is not None and mode == "testbed":
        paper_time = PAPER["testbed_detection_s"].get(s.fault)
    if s.fault == "F4.1" and mode == "flight":
        test = _TURBULENCE_TEST.get(str(truth.get("turbulence")))
        if test:
            paper_acc = (
                f"{PAPER['flight_F4.1_accuracy_pct'][test]:.2f} % ({test}, all samples after injection)"
            )
            paper_time = PAPER["flight_F4.1_detection_s"][test]
    if s.fault == "F4.2" and mode == "flight":
        paper_acc = f"{100 - PAPER['flight_F4.2_error_pct']:.2f} % (error {PAPER['flight_F4.2_error_pct']} %)"
    if s.fault is not None:
        lines.append(f"  fault {s.fault} on motor {s.motor} at {s.onset_s:.2f} s")
        lines.append(
            f"  accuracy (steady samples after onset)  {_pct(s.fault_accuracy_pct)}"
            f"   all samples after onset {_pct(s.fault_accuracy_all_pct)}"
            + (f"   paper: {paper_acc}" if paper_acc else "")
        )
        det = "not detected" if s.detection_s is None else f"{s.detection_s:6.2f} s"
        lines.append(
            f"  time to detection  {det}" + (f"   paper: {paper_time} s" if paper_time is not None else "")
        )
    normal_paper = f"   paper: {PAPER['flight_normal_accuracy_pct']} % (flight)" if mode == "flight" else ""
    lines.append(
        f"  normal accuracy (healthy steady samples NORMAL)  {_pct(s.normal_accuracy_pct)}"
        f"   all healthy samples {_pct(s.normal_accuracy_all_pct)}"
    )
    lines.append(
        f"  model accuracy on healthy samples (speed, current)  {_pct(s.model_accuracy_pct)}{normal_paper}"
    )
    lines.append(f"  false fault events  {s.false_events}  ({s.false_events_per_hour:.1f} per flight hour)")
    return "\n".join(lines)
