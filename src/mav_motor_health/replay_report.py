"""The replay report: one self-contained HTML page (inline CSS, SVG and script, nothing fetched).

A pilot reads, top to bottom: the verdict per motor, the fault timeline (announced state of every motor
over the flight), then per motor the measured versus modelled speed and current with the tree's bands and
a ribbon of the raw per-sample state.
"""

from __future__ import annotations

import html
import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from .diagnosis.profile import ThresholdProfile
from .diagnosis.states import MotorState
from .model.params import MotorParams
from .publish.web.hexaview import hexaview_report_section
from .replay import has_rows, rows_by_motor
from .telemetry.table import TelemetryTable

if TYPE_CHECKING:
    from .replay import MotorVerdict

__all__ = ["STATE_COLOURS", "render_report"]

STATE_COLOURS = {
    MotorState.NORMAL: "#2e7d32",
    MotorState.F1_1: "#8e24aa",
    MotorState.F2_1: "#c62828",
    MotorState.F3_1: "#ef6c00",
    MotorState.F4_1: "#6d4c41",
    MotorState.F4_2: "#1565c0",
    MotorState.UNKNOWN: "#455a64",
    MotorState.NO_DATA: "#bdbdbd",
    MotorState.SENSOR_FAULT: "#f9a825",
    MotorState.SLOW: "#ad1457",
    MotorState.STALLED: "#b71c1c",
    MotorState.FAST: "#ff8f00",
    MotorState.UNCALIBRATED: "#00838f",
}
WIDTH = 900
LEFT = 64
RIGHT = 16
MAX_POINTS = 1500

_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:24px auto;max-width:960px;color:#212121}
h1{font-size:22px;margin:0 0 4px} h2{font-size:18px;margin:28px 0 8px;border-bottom:1px solid #ddd}
h3{font-size:15px;margin:18px 0 4px} .meta{color:#555;font-size:13px}
table{border-collapse:collapse;font-size:13px;margin:6px 0} td,th{border:1px solid #ddd;padding:3px 8px;text-align:left}
th{background:#f5f5f5} .badge{display:inline-block;padding:1px 8px;border-radius:9px;color:#fff;font-weight:600}
.warn{background:#fff8e1;border-left:4px solid #f9a825;padding:6px 10px;font-size:13px;margin:6px 0}
svg text{font-size:11px;fill:#424242} .legend span{display:inline-block;margin-right:12px;font-size:12px}
.legend i{display:inline-block;width:12px;height:12px;margin-right:4px;vertical-align:-2px}
"""


def _esc(x: Any) -> str:
    return html.escape(str(x))


def _badge(label: str) -> str:
    colour = STATE_COLOURS[MotorState.from_label(label)]
    return f'<span class="badge" style="background:{colour}">{_esc(label)}</span>'


def _ticks(lo: float, hi: float, n: int = 6) -> list[float]:
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi <= lo:
        return [lo] if math.isfinite(lo) else []
    raw = (hi - lo) / n
    mag = 10 ** math.floor(math.log10(raw))
    step = min((m * mag for m in (1, 2, 2.5, 5, 10) if m * mag >= raw), default=10 * mag)
    first = math.ceil(lo / step) * step
    return [first + k * step for k in range(int((hi - first) / step) + 1)]


class _Axes:
    def __init__(self, t0: float, t1: float, y0: float, y1: float, height: int, top: int = 8) -> None:
        self.t0, self.t1 = t0, t1 if t1 > t0 else t0 + 1.0
        pad = 0.05 * (y1 - y0) if y1 > y0 else 1.0
        self.y0, self.y1 = y0 - pad, y1 + pad
        self.height, self.top = height, top

    def x(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        return LEFT + (np.asarray(t) - self.t0) / (self.t1 - self.t0) * (WIDTH - LEFT - RIGHT)

    def y(self, v: NDArray[np.float64]) -> NDArray[np.float64]:
        return self.top + (self.y1 - np.asarray(v)) / (self.y1 - self.y0) * self.height


#: :func:`_decimal_cells` formats magnitudes below this (beyond: Python's own formatting)
_CELL_MAX = 1e7
#: scaled values this close to a tie (….5) are left to Python's own formatting (see the function)
_TIE_MARGIN = 1e-6
_ZERO = ord("0")


def _decimal_cells(values: NDArray[np.float64], decimals: int = 1) -> NDArray[np.uint8] | None:
    """Each value as ``f"{value:.{decimals}f}"`` writes it (1 or 2 decimals), one row of ASCII bytes per
    value, padded with 0 bytes (the sign first, the digits at the end of the row: the text once the 0 bytes
    are removed). None where a value is not finite, not below :data:`_CELL_MAX` or within
    :data:`_TIE_MARGIN` of a tie once scaled: Python rounds the exact binary value half to even, and the
    scaled value (below 1e9) is within 1e-7 of the exact product, so away from ties rounding it gives
    Python's digits."""
    size = np.abs(values)
    if not (np.isfinite(size).all() and (size < _CELL_MAX).all()):
        return None
    scaled = size * float(10**decimals)
    floor = np.floor(scaled)
    if (np.abs(scaled - floor - 0.5) < _TIE_MARGIN).any():
        return None
    whole, fraction = np.divmod((floor + (scaled - floor > 0.5)).astype(np.int64), 10**decimals)
    digits = len(str(int(whole.max(initial=0))))
    powers = 10 ** np.arange(digits - 1, -1, -1, dtype=np.int64)
    cells = np.zeros((len(values), 2 + digits + decimals), dtype=np.uint8)
    cells[:, 0] = np.where(np.signbit(values), ord("-"), 0)  # -0.0 and -0.04 too: "-0.0"
    shown = (whole[:, None] >= powers) | (powers == 1)  # no leading zeros; a lone 0 stays
    cells[:, 1 : 1 + digits] = np.where(shown, _ZERO + whole[:, None] // powers % 10, 0)
    cells[:, 1 + digits] = ord(".")
    tenths = 10 ** np.arange(decimals - 1, -1, -1, dtype=np.int64)
    cells[:, 2 + digits :] = _ZERO + fraction[:, None] // tenths % 10
    return cells


def _text_of(rows: list[NDArray[np.uint8]]) -> str:
    """Equally long byte tables side by side, row after row, as text (0 bytes dropped)."""
    return np.hstack(rows).tobytes().translate(None, b"\0").decode("utf-8")


def _constant(text: str, rows: int) -> NDArray[np.uint8]:
    """``text`` (UTF-8) in every row."""
    return np.tile(np.frombuffer(text.encode("utf-8"), dtype=np.uint8), (rows, 1))


def _text_table(texts: Sequence[str]) -> NDArray[np.uint8]:
    """Texts as UTF-8 bytes, one row each, padded with 0 bytes to the longest."""
    encoded = [text.encode("utf-8") for text in texts]
    table = np.zeros((len(encoded), max(map(len, encoded), default=0)), dtype=np.uint8)
    for row, text in zip(table, encoded):
        row[: len(text)] = np.frombuffer(text, dtype=np.uint8)
    return table


def _path(xs: NDArray[np.float64], ys: NDArray[np.float64]) -> str:
    """An SVG path through the points, broken where a value is missing: ``M`` then ``L`` points with one
    decimal each, formatted for all points at once (:func:`_decimal_cells`; else one ``%`` format per
    stretch)."""
    ok = np.isfinite(xs) & np.isfinite(ys)
    edges = np.flatnonzero(np.diff(np.concatenate(([False], ok, [False])).astype(np.int8)))
    if not len(edges):
        return ""
    x_cells, y_cells = _decimal_cells(xs[ok]), _decimal_cells(ys[ok])
    if x_cells is not None and y_cells is not None:
        lengths = edges[1::2] - edges[::2]
        move = np.full((len(x_cells), 1), ord("L"), dtype=np.uint8)
        move[np.concatenate(([0], np.cumsum(lengths)[:-1]))] = ord("M")  # each stretch's first point
        return _text_of([move, x_cells, _constant(",", len(x_cells)), y_cells])
    parts: list[str] = []
    for start, stop in zip(edges[::2].tolist(), edges[1::2].tolist()):
        points = np.column_stack([xs[start:stop], ys[start:stop]]).ravel().tolist()
        parts.append(("M%.1f,%.1f" + "L%.1f,%.1f" * (stop - start - 1)) % tuple(points))
    return "".join(parts)


def _band(xs: NDArray[np.float64], lo: NDArray[np.float64], hi: NDArray[np.float64]) -> str:
    """The band's outline, ``x,y`` points with one decimal each separated by spaces: along the top, back
    along the bottom."""
    ok = np.isfinite(xs) & np.isfinite(lo) & np.isfinite(hi)
    if ok.sum() < 2:
        return ""
    x, a, b = xs[ok], lo[ok], hi[ok]
    outline = np.column_stack([np.concatenate([x, x[::-1]]), np.concatenate([b, a[::-1]])])
    x_cells, y_cells = _decimal_cells(outline[:, 0]), _decimal_cells(outline[:, 1])
    if x_cells is not None and y_cells is not None:
        return _text_of([x_cells, _constant(",", len(outline)), y_cells, _constant(" ", len(outline))])[:-1]
    return " ".join(["%.1f,%.1f"] * len(outline)) % tuple(outline.ravel().tolist())


def _thin(n: int) -> NDArray[np.int64]:
    if n <= MAX_POINTS:
        return np.arange(n)
    picked = np.linspace(0, n - 1, MAX_POINTS).astype(np.int64)
    if (picked[1:] < picked[:-1]).any():  # (linspace does not go back: never, but then numpy's own)
        return np.unique(picked)
    return picked[np.concatenate(([True], picked[1:] != picked[:-1]))]  # in order: repeats dropped


def _runs(t: NDArray[np.float64], codes: NDArray[np.int64], t_end: float) -> list[tuple[float, float, int]]:
    """(start, end, state) runs of equal state."""
    if len(t) == 0:
        return []
    change = np.flatnonzero(np.diff(codes) != 0) + 1
    starts = np.concatenate([[0], change])
    ends = np.concatenate([change, [len(t)]])
    out = []
    for s, e in zip(starts.tolist(), ends.tolist()):
        t_stop = float(t[e]) if e < len(t) else t_end
        out.append((float(t[s]), t_stop, int(codes[s])))
    return out


def _per_pixel(
    axes: _Axes, t: NDArray[np.float64], codes: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """One state per horizontal pixel (the highest code in it: faults and missing data stay visible)."""
    pixels = WIDTH - LEFT - RIGHT
    if len(t) <= pixels:
        return t, codes
    bins = np.clip(((t - axes.t0) / (axes.t1 - axes.t0) * pixels).astype(np.int64), 0, pixels - 1)
    first = np.flatnonzero(np.diff(bins, prepend=-1) != 0)
    return t[first], np.maximum.reduceat(codes, first)


def _ribbon(
    axes: _Axes, t: NDArray[np.float64], codes: NDArray[np.int64], y: float, h: float, t_end: float
) -> str:
    rects = []
    t, codes = _per_pixel(axes, t, codes)
    runs = _runs(t, codes, t_end)
    if not runs:
        return ""
    starts = np.array([r[0] for r in runs])
    stops = np.array([r[1] for r in runs])
    fast = _ribbon_text(axes.x(starts), axes.x(stops), starts, stops, [r[2] for r in runs], y, h)
    if fast is not None:
        return fast
    x0s, x1s = axes.x(starts).tolist(), axes.x(stops).tolist()
    looks: dict[int, tuple[str, str]] = {}  # each state's colour and label, looked up once
    for (start, stop, code), x0, x1 in zip(runs, x0s, x1s):
        if code not in looks:
            looks[code] = (STATE_COLOURS[MotorState(code)], MotorState(code).label)
        colour, label = looks[code]
        rects.append(
            f'<rect x="{x0:.1f}" y="{y:.1f}" width="{max(x1 - x0, 0.6):.1f}" height="{h}" '
            f'fill="{colour}"><title>{label} '
            f"{start:.2f}–{stop:.2f} s</title></rect>"
        )
    return "".join(rects)


def _ribbon_text(
    x0s: NDArray[np.float64],
    x1s: NDArray[np.float64],
    starts: NDArray[np.float64],
    stops: NDArray[np.float64],
    codes: list[int],
    y: float,
    h: float,
) -> str | None:
    """:func:`_ribbon`'s rectangles, formatted for all runs at once (:func:`_decimal_cells`); None where a
    number needs Python's own formatting."""
    widths = np.maximum(x1s - x0s, 0.6)
    cells = [_decimal_cells(x0s), _decimal_cells(widths), _decimal_cells(starts, 2), _decimal_cells(stops, 2)]
    if any(c is None for c in cells):
        return None
    x0c, wc, sc, ec = cells
    states = sorted(set(codes))  # each state's colour and label, looked up once
    looks = _text_table(
        [f'fill="{STATE_COLOURS[MotorState(code)]}"><title>{MotorState(code).label} ' for code in states]
    )
    look = looks[np.searchsorted(states, codes)]
    n = len(codes)
    return _text_of(
        [
            _constant('<rect x="', n),
            x0c,  # type: ignore[list-item]
            _constant(f'" y="{y:.1f}" width="', n),
            wc,  # type: ignore[list-item]
            _constant(f'" height="{h}" ', n),
            look,
            sc,  # type: ignore[list-item]
            _constant("–", n),
            ec,  # type: ignore[list-item]
            _constant(" s</title></rect>", n),
        ]
    )


def _steady_rects(axes: _Axes, t: NDArray[np.float64], steady: NDArray[np.int64], t_end: float) -> str:
    """The grey rectangles of the steady runs (per pixel), formatted for all runs at once where
    :func:`_decimal_cells` can, else one by one."""
    runs = [(start, stop) for start, stop, code in _runs(*_per_pixel(axes, t, steady), t_end) if code]
    if not runs:
        return ""
    ends = axes.x(np.array(runs))  # (runs, 2): the same numbers as one run at a time
    x0c, wc = _decimal_cells(ends[:, 0]), _decimal_cells(np.maximum(ends[:, 1] - ends[:, 0], 0.6))
    if x0c is not None and wc is not None:
        n = len(runs)
        return _text_of(
            [
                _constant('<rect x="', n),
                x0c,
                _constant('" y="24" width="', n),
                wc,
                _constant('" height="10" fill="#78909c"/>', n),
            ]
        )
    rects = []
    for start, stop in runs:
        x0, x1 = axes.x(np.array([start, stop]))
        rects.append(
            f'<rect x="{x0:.1f}" y="24" width="{max(x1 - x0, 0.6):.1f}" height="10" fill="#78909c"/>'
        )
    return "".join(rects)


def _time_axis(axes: _Axes, y: float) -> str:
    out = [f'<line x1="{LEFT}" y1="{y}" x2="{WIDTH - RIGHT}" y2="{y}" stroke="#9e9e9e"/>']
    for tick in _ticks(axes.t0, axes.t1, 10):
        x = float(axes.x(np.array([tick]))[0])
        out.append(f'<line x1="{x:.1f}" y1="{y}" x2="{x:.1f}" y2="{y + 4}" stroke="#9e9e9e"/>')
        out.append(f'<text x="{x:.1f}" y="{y + 15}" text-anchor="middle">{tick:g}</text>')
    return "".join(out)


def _chart(
    title: str,
    unit: str,
    t: NDArray[np.float64],
    measured: NDArray[np.float64],
    model: NDArray[np.float64],
    half: NDArray[np.float64] | float | Callable[[NDArray[np.int64]], NDArray[np.float64]],
    t0: float,
    t1: float,
) -> str:
    """A chart of at most :data:`MAX_POINTS` samples; ``half`` the band's half-width: a number, one per
    sample, or a function giving it at the samples drawn (worked out for those only)."""
    idx = _thin(len(t))
    tt, mm, md = t[idx], measured[idx], model[idx]
    if callable(half):
        hw = np.asarray(half(idx), dtype=float)
    else:
        hw = np.broadcast_to(np.asarray(half, dtype=float), t.shape)[idx]
    values = np.concatenate(
        [mm[np.isfinite(mm)], (md + hw)[np.isfinite(md + hw)], (md - hw)[np.isfinite(md - hw)]]
    )
    lo, hi = (float(values.min()), float(values.max())) if len(values) else (0.0, 1.0)
    axes = _Axes(t0, t1, lo, hi, height=150)
    xs = axes.x(tt)
    parts = [
        f'<svg width="{WIDTH}" height="190" viewBox="0 0 {WIDTH} 190" role="img" aria-label="{_esc(title)}">'
    ]
    for tick in _ticks(axes.y0, axes.y1, 5):
        y = float(axes.y(np.array([tick]))[0])
        parts.append(f'<line x1="{LEFT}" y1="{y:.1f}" x2="{WIDTH - RIGHT}" y2="{y:.1f}" stroke="#eeeeee"/>')
        parts.append(f'<text x="{LEFT - 6}" y="{y + 4:.1f}" text-anchor="end">{tick:g}</text>')
    band = _band(xs, axes.y(md - hw), axes.y(md + hw))
    if band:
        parts.append(f'<polygon points="{band}" fill="#90caf9" fill-opacity="0.35" stroke="none"/>')
    parts.append(f'<path d="{_path(xs, axes.y(md))}" fill="none" stroke="#1565c0" stroke-width="1.2"/>')
    parts.append(f'<path d="{_path(xs, axes.y(mm))}" fill="none" stroke="#d84315" stroke-width="1"/>')
    parts.append(_time_axis(axes, 8 + 150 + 4))
    parts.append(
        f'<text x="{LEFT}" y="{190 - 2}" >{_esc(title)} [{_esc(unit)}] — measured (orange), model (blue), '
        "tree band (shaded); time [s]</text>"
    )
    parts.append("</svg>")
    return "".join(parts)


def _halfwidth_at(
    profile: ThresholdProfile, voltage_v: NDArray[np.float64]
) -> Callable[[NDArray[np.int64]], NDArray[np.float64]]:
    """The profile's current half-width at the samples a chart draws (it is one per sample, at that
    sample's voltage: worked out for the drawn ones only)."""

    def at(drawn: NDArray[np.int64]) -> NDArray[np.float64]:
        return profile.current_halfwidth_a(voltage_v[drawn])

    return at


def _legend() -> str:
    items = "".join(
        f'<span><i style="background:{c}"></i>{s.label} ({_esc(s.description)})</span>'
        for s, c in STATE_COLOURS.items()
    )
    return f'<div class="legend">{items}</div>'


def render_report(
    log: Path,
    result: TelemetryTable,
    verdicts: Sequence[MotorVerdict],
    events: Sequence[Mapping[str, Any]],
    profile: ThresholdProfile,
    params: MotorParams | dict[int, MotorParams],
    meta: Mapping[str, Any],
    notes: Sequence[str] = (),
) -> str:
    """The report page as one HTML string."""
    t_all = result["time_s"]
    t0 = float(np.nanmin(t_all)) if len(t_all) else 0.0
    t1 = float(np.nanmax(t_all)) if len(t_all) else 1.0
    vehicle = meta.get("vehicle", {})
    vehicle_text = ", ".join(f"{k} {v}" for k, v in vehicle.items() if k != "messages")
    motor_names = (
        {m: p.name for m, p in params.items()}
        if isinstance(params, dict)
        else {0: getattr(params, "name", "")}
    )
    out = [
        "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>",
        f"<title>Motor health replay — {_esc(log.name)}</title><style>{_CSS}</style></head><body>",
        f"<h1>Motor health replay: {_esc(log.name)}</h1>",
        f"<div class='meta'>{_esc(meta.get('format', ''))} log, {t1 - t0:.1f} s of ESC telemetry, "
        f"{len(result)} motor samples; vehicle: {_esc(vehicle_text) or 'unknown'}; profile "
        f"<b>{_esc(profile.name)}</b>; motor model {_esc(', '.join(sorted(set(map(str, motor_names.values())))))}</div>",
    ]
    for note in notes:
        out.append(f"<div class='warn'>{_esc(note)}</div>")
    out.append(
        "<h2>Verdict per motor</h2><table><tr><th>motor</th><th>verdict</th><th>why</th>"
        "<th>final announced</th><th>samples</th><th>steady</th></tr>"
    )
    for v in verdicts:
        out.append(
            f"<tr><td>{v.motor}</td><td>{_badge(v.state)}</td><td>{_esc(v.reason)}</td>"
            f"<td>{_badge(v.final_state)}</td><td>{v.samples}</td>"
            f"<td>{100 * v.steady_samples / max(v.samples, 1):.0f} %</td></tr>"
        )
    out.append("</table>")

    # Fault timeline: the announced state of every motor over the flight.
    motors = [v.motor for v in verdicts]
    rows = rows_by_motor(result["motor"], motors)
    row_h = 22
    height = 16 + row_h * len(motors) + 24
    axes = _Axes(t0, t1, 0.0, 1.0, height=1)
    svg = [
        f'<svg width="{WIDTH}" height="{height}" viewBox="0 0 {WIDTH} {height}" role="img" aria-label="fault timeline">'
    ]
    for k, motor in enumerate(motors):
        y = 8 + k * row_h
        svg.append(f'<text x="{LEFT - 6}" y="{y + 14}" text-anchor="end">motor {motor}</text>')
        sel = rows[motor]
        if not has_rows(sel):
            svg.append(
                f'<rect x="{LEFT}" y="{y}" width="{WIDTH - LEFT - RIGHT}" height="{row_h - 6}" '
                f'fill="{STATE_COLOURS[MotorState.NO_DATA]}"><title>no telemetry</title></rect>'
            )
            continue
        svg.append(
            _ribbon(axes, result["time_s"][sel], result["announced"][sel].astype(np.int64), y, row_h - 6, t1)
        )
    svg.append(_time_axis(axes, 8 + row_h * len(motors) + 2))
    svg.append("</svg>")
    out.append("<h2>Fault timeline (announced state)</h2>")
    out.append("".join(svg))
    out.append(_legend())
    # The display's top view with a time slider (inline script and styles, nothing fetched).
    out.append(hexaview_report_section(result, meta, t_start_s=t0, t_end_s=t1))

    out.append("<h2>Measured versus model, per motor</h2>")
    for v in verdicts:
        out.append(f"<h3>Motor {v.motor} — {_badge(v.state)} <span class='meta'>{_esc(v.reason)}</span></h3>")
        sel = rows[v.motor]
        if not has_rows(sel):
            out.append("<p class='meta'>No ESC telemetry for this motor.</p>")
            continue
        t = result["time_s"][sel]
        voltage = result["voltage_v"][sel]
        out.append(
            _chart(
                "speed",
                "rad/s",
                t,
                result["omega_rad_s"][sel],
                result["omega_model_rad_s"][sel],
                profile.speed_band_rad_s,
                t0,
                t1,
            )
        )
        out.append(
            _chart(
                "current",
                "A",
                t,
                result["current_a"][sel],
                result["current_model_a"][sel],
                _halfwidth_at(profile, voltage),
                t0,
                t1,
            )
        )
        rib = [
            f'<svg width="{WIDTH}" height="40" viewBox="0 0 {WIDTH} 40" role="img" aria-label="state ribbon">'
        ]
        rib.append(f'<text x="{LEFT - 6}" y="14" text-anchor="end">state</text>')
        rib.append(_ribbon(axes, t, result["state"][sel].astype(np.int64), 3, 14, t1))
        rib.append(f'<text x="{LEFT - 6}" y="33" text-anchor="end">steady</text>')
        rib.append(_steady_rects(axes, t, result["steady"][sel].astype(np.int64), t1))
        rib.append("</svg>")
        out.append("".join(rib))
    if events:
        out.append(
            f"<h2>Events</h2><details><summary>{len(events)} changes of announced state (also in "
            "events.jsonl)</summary><table><tr><th>time [s]</th><th>motor</th><th>from</th>"
            "<th>to</th><th>ω / model [rad/s]</th><th>i / model [A]</th></tr>"
        )
        for e in list(events)[:200]:
            ev = e["evidence"]
            out.append(
                f"<tr><td>{e['time_s']:.2f}</td><td>{e['motor']}</td><td>{_badge(e['previous'])}</td>"
                f"<td>{_badge(e['state'])}</td><td>{_fmt(ev['omega_rad_s'])} / {_fmt(ev['omega_model_rad_s'])}</td>"
                f"<td>{_fmt(ev['current_a'])} / {_fmt(ev['current_model_a'])}</td></tr>"
            )
        out.append("</table></details>")
        if len(events) > 200:
            out.append(f"<p class='meta'>… {len(events) - 200} more in events.jsonl</p>")

    out.append(_legend())
    out.append(
        f"<p class='meta'>Bands: speed ±{profile.speed_band_rad_s:.0f} rad/s around the model; current ± the profile's half-width at the "
        "input voltage. The ribbon shows the tree's state per sample; the timeline shows what the live agent "
        "would announce after its persistence rules. Made by <code>mav-motor-health replay</code>.</p>"
    )
    out.append("</body></html>")
    return "\n".join(out)


def _fmt(x: float | None) -> str:
    return "–" if x is None else f"{x:.2f}"
