"""The hexacopter view as a self-contained HTML fragment, for reports (the replay's report.html).

The fragment inlines the same ``hexaview.js``/``hexaview.css`` the live display serves, plus a time slider:
the report shows at any moment of a flight what the display would have shown then. No network, no CDN.

>>> timelines = {4: [(0.0, "NORMAL"), (85.2, "F3.1")]}
>>> html = hexaview_fragment(timelines, t_start_s=0.0, t_end_s=120.0)
"""

from __future__ import annotations

import html
import itertools
import json
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ...diagnosis.states import MotorState
from ...errors import DataError
from ...telemetry.table import TelemetryTable
from .layout import FRAMES, HEXA_X, MotorPosition, layout_for_log
from .server import state_kinds, static_text

__all__ = ["StateTimeline", "hexaview_fragment", "hexaview_report_section", "state_timelines"]

#: Per motor, the moments its announced state changed: ``[(time_s, label), ...]`` in time order.
StateTimeline = Sequence[tuple[float, str]]

_ids = itertools.count(1)

_REPLAY_CSS = """
.mmh-replay { font-family: system-ui, -apple-system, "Segoe UI", Roboto, "DejaVu Sans", sans-serif;
  color: #263238; max-width: 980px; display: grid; grid-template-columns: minmax(280px, 1fr) 1fr;
  gap: 8px 16px; align-items: start; }
.mmh-replay .mmh-replay-controls { grid-column: 1 / -1; display: flex; gap: 8px; align-items: center; }
.mmh-replay .mmh-replay-slider { flex: 1; }
.mmh-replay .mmh-replay-time { font-variant-numeric: tabular-nums; min-width: 7em; font-weight: 700; }
.mmh-replay .mmh-replay-motors { list-style: none; margin: 0; padding: 0; font-size: 15px; }
.mmh-replay .mmh-replay-motors li { padding: 4px 8px; margin: 3px 0; border-left: 6px solid #9e9e9e; }
.mmh-replay .mmh-replay-motors li.kind-ok { border-left-color: #2e7d32; }
.mmh-replay .mmh-replay-motors li.kind-fault { border-left-color: #c62828; color: #b71c1c;
  font-weight: 700; background: #fff5f5; }
.mmh-replay .mmh-replay-motors li.kind-sensor { border-left-color: #e65100; }
"""


def state_timelines(table: TelemetryTable, column: str = "announced") -> dict[int, list[tuple[float, str]]]:
    """The change points of a diagnosed table's announced state, per motor (what the fragment needs).

    ``table`` is what :func:`~mav_motor_health.diagnosis.pipeline.diagnose` returns (``time_s``,
    ``motor`` and an integer state column). The first sample of each motor is always a change point.
    """
    if column not in table:
        raise DataError(
            f"table has no '{column}' column (state codes); has {', '.join(table.names)}",
            path=table.source or None,
        )
    ordered = _ordered_timelines(table["motor"], table["time_s"], np.asarray(table[column]).astype(np.int64))
    if ordered is not None:
        return ordered
    out: dict[int, list[tuple[float, str]]] = {}
    for motor in table.motors():
        rows = table.for_motor(motor)
        order = np.argsort(rows["time_s"], kind="stable")
        time_s = rows["time_s"][order]
        codes = np.asarray(rows[column])[order].astype(np.int64)
        if codes.size == 0:
            continue
        change = np.flatnonzero(np.concatenate(([True], codes[1:] != codes[:-1])))
        out[int(motor)] = [(float(time_s[i]), MotorState(int(codes[i])).label) for i in change]
    return out


def _ordered_timelines(
    motor: np.ndarray, time_s: np.ndarray, codes: np.ndarray
) -> dict[int, list[tuple[float, str]]] | None:
    """:func:`state_timelines` in one pass where the rows are grouped by motor in order, each motor's in
    time order (the diagnosis' result is); None where they are not."""
    same_motor = motor[1:] == motor[:-1]
    if len(motor) == 0 or not np.all((motor[1:] > motor[:-1]) | (same_motor & (time_s[1:] >= time_s[:-1]))):
        return None
    change = np.flatnonzero(np.concatenate(([True], ~same_motor | (codes[1:] != codes[:-1]))))
    out: dict[int, list[tuple[float, str]]] = {}
    for m, t, code in zip(motor[change].tolist(), time_s[change].tolist(), codes[change].tolist()):
        out.setdefault(int(m), []).append((float(t), MotorState(code).label))
    return out


def _script_json(value: Any) -> str:
    # Inside <script>, "</" would end the element: escape "<" (and the JS line separators) in the JSON.
    text = json.dumps(value, allow_nan=False, separators=(",", ":"))
    return text.replace("<", "\\u003c").replace("\u2028", "\\u2028").replace("\u2029", "\\u2029")


def hexaview_fragment(
    timelines: Mapping[int, StateTimeline],
    *,
    t_start_s: float | None = None,
    t_end_s: float | None = None,
    initial_t_s: float | None = None,
    layout: Sequence[MotorPosition] = HEXA_X,
    title: str = "Motor health during the flight",
    element_id: str | None = None,
    include_assets: bool = True,
    note: str = "",
) -> str:
    """A ``<section>`` with the hexacopter view and a time slider over ``[t_start_s, t_end_s]``.

    ``timelines``: motor number → ``[(time_s, state label), ...]`` change points (see
    :func:`state_timelines`). Before its first change point a motor shows "no data yet".
    ``initial_t_s``: where the slider starts (default ``t_start_s``); ``note``: a line under the title.
    ``include_assets=False`` leaves out the inlined JS/CSS when a page holds several fragments (they are
    guarded, so including them twice is harmless too).
    """
    changes: dict[str, list[list[Any]]] = {}
    for motor, timeline in timelines.items():
        rows = sorted(((float(t), str(label)) for t, label in timeline), key=lambda r: r[0])
        for t, label in rows:
            if not np.isfinite(t):
                raise DataError(f"motor {motor}: non-finite change time {t}")
            MotorState.from_label(label)  # unknown labels are a caller's bug: say so now
        changes[str(int(motor))] = [[t, MotorState.from_label(label).label] for t, label in rows]
    all_times = [row[0] for rows in changes.values() for row in rows]
    start = float(t_start_s) if t_start_s is not None else (min(all_times) if all_times else 0.0)
    end = float(t_end_s) if t_end_s is not None else (max(all_times) if all_times else start)
    if end < start:
        raise DataError(f"time span ends ({end}) before it starts ({start})")
    data = {
        "layout": [m.to_dict() for m in layout],
        "states": state_kinds(),
        "t_start_s": start,
        "t_end_s": end,
        "initial_t_s": None if initial_t_s is None else float(initial_t_s),
        "timelines": changes,
    }
    root = element_id or f"mmh-replay-{next(_ids)}"
    if not root.replace("-", "").replace("_", "").isalnum():
        raise ValueError(f"element_id {root!r}: use letters, digits, '-' and '_'")
    assets = ""
    if include_assets:
        assets = (
            f"<style>{static_text('hexaview.css')}{_REPLAY_CSS}</style>\n"
            f"<script>{static_text('hexaview.js')}</script>\n"
            f"<script>{static_text('hexaview-replay.js')}</script>\n"
        )
    return (
        f'<section class="mmh-replay-section">\n<h2>{html.escape(title)}</h2>\n'
        + (f'<p class="mmh-replay-note">{html.escape(note)}</p>\n' if note else "")
        + f"{assets}"
        f'<div class="mmh-replay" id="{root}">\n'
        '<div class="mmh-replay-controls">'
        '<button type="button" class="mmh-replay-prev" title="previous state change">&#9664; change</button>'
        '<input type="range" class="mmh-replay-slider" aria-label="time in the flight">'
        '<button type="button" class="mmh-replay-next" title="next state change">change &#9654;</button>'
        '<output class="mmh-replay-time"></output></div>\n'
        '<div class="mmh-replay-view"></div>\n<ul class="mmh-replay-motors"></ul>\n</div>\n'
        f'<script type="application/json" id="{root}-data">{_script_json(data)}</script>\n'
        f'<script>MmhHexaReplay.mount("{root}");</script>\n</section>\n'
    )


def hexaview_report_section(
    result: TelemetryTable,
    meta: Mapping[str, Any],
    *,
    t_start_s: float | None = None,
    t_end_s: float | None = None,
) -> str:
    """The view for a replayed log's report: frame from the log, slider starting at the first fault.

    ``result`` is the diagnosed table (with ``announced``), ``meta`` the log's table meta. When no top view
    fits the vehicle, a short paragraph says why instead.
    """
    timelines = state_timelines(result)
    frame, note = layout_for_log(meta, sorted(timelines))
    if frame is None:
        return f'<section class="mmh-replay-section"><p class="meta">No top view: {html.escape(note)}.</p></section>\n'
    kinds = state_kinds()
    onsets = [
        t for rows in timelines.values() for t, label in rows if kinds[label]["kind"] in ("fault", "sensor")
    ]
    return hexaview_fragment(
        timelines,
        t_start_s=t_start_s,
        t_end_s=t_end_s,
        initial_t_s=min(onsets) if onsets else None,
        layout=FRAMES[frame],
        title=f"The {frame} at any moment of the flight (announced state)",
        note=note,
    )
