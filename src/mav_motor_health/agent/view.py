"""The terminal view: the motors' states live (ANSI redraw on a terminal, one line per change otherwise)."""

from __future__ import annotations

import math
from typing import TextIO

from ..diagnosis.states import MotorState
from .monitor import MotorStatus, StateChange

__all__ = ["StateView"]

_COLOURS = {
    MotorState.NORMAL: "\x1b[32m",
    MotorState.NO_DATA: "\x1b[90m",
    MotorState.F2_1: "\x1b[1;31m",
    MotorState.F4_2: "\x1b[1;31m",
}
_RESET = "\x1b[0m"


def _fmt(x: object, spec: str) -> str:
    try:
        value = float(x)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return "-"
    return format(value, spec) if math.isfinite(value) else "-"


class StateView:
    """Shows motor states on ``stream``; ``live`` redraws a table in place (for a terminal)."""

    def __init__(self, stream: TextIO, live: bool, title: str = "") -> None:
        self.stream = stream
        self.live = live
        self.title = title
        self._lines = 0
        self.origin_s: float | None = None  # link time shown as 0 (the first change seen)

    def change(self, change: StateChange, vehicle_time_s: float | None = None) -> None:
        """One line per change of state (when not redrawing)."""
        if self.live:
            return
        ev = change.evidence
        if self.origin_s is None:
            self.origin_s = change.time_s
        self.stream.write(
            f"t={change.time_s - self.origin_s:9.3f} s motor {change.motor}: {change.previous.label} -> {change.state.label}"
            f" ({change.state.description}) omega {_fmt(ev.get('omega_rad_s'), '.0f')}"
            f"/{_fmt(ev.get('omega_model_rad_s'), '.0f')} rad/s current {_fmt(ev.get('current_a'), '.2f')}"
            f"/{_fmt(ev.get('current_model_a'), '.2f')} A\n"
        )
        self.stream.flush()

    def redraw(self, status: dict[int, MotorStatus], now_s: float, header: str = "") -> None:
        """Redraw the table in place (terminal only)."""
        if not self.live:
            return
        lines = [
            f"{self.title}  {header}".rstrip(),
            "motor  state     since   omega/model rad/s   current/model A   V",
        ]
        for motor, s in status.items():
            row = s.row
            colour = _COLOURS.get(s.state, "\x1b[1;33m")
            since = now_s - s.since_s if math.isfinite(s.since_s) else math.nan
            lines.append(
                f"  {motor}    {colour}{s.state.label:8s}{_RESET} {_fmt(since, '6.1f'):>6}s"
                f"  {_fmt(row.get('omega_rad_s'), '7.0f'):>7}/{_fmt(row.get('omega_model_rad_s'), '<7.0f'):7}"
                f"     {_fmt(row.get('current_a'), '6.2f'):>6}/{_fmt(row.get('current_model_a'), '<6.2f'):6}"
                f"   {_fmt(row.get('voltage_v'), '5.2f')}  {s.state.description if s.state.is_fault else ''}"
            )
        out = []
        if self._lines:
            out.append(f"\x1b[{self._lines}F")  # back to the first line of the last drawing
        out.extend(f"\x1b[2K{line}\n" for line in lines)
        self.stream.write("".join(out))
        self.stream.flush()
        self._lines = len(lines)
