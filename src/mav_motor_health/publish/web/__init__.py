"""The ground-station display (a static page fed by MQTT over WebSocket) and the reusable hexacopter view.

- :class:`DisplayServer` / :class:`DisplayConfig`: serve the page (``mav-motor-health display``).
- :func:`hexaview_fragment`: the same top view as a self-contained HTML fragment with a time slider,
  for reports; :func:`state_timelines` turns a diagnosed table into what it needs.
- :data:`HEXA_X`: ArduPilot's hexa-X motor positions and spin directions.
"""

from .hexaview import StateTimeline, hexaview_fragment, state_timelines
from .layout import FRAMES, HEXA_X, MotorPosition
from .server import DisplayConfig, DisplayServer, state_kinds

__all__ = [
    "FRAMES",
    "HEXA_X",
    "DisplayConfig",
    "DisplayServer",
    "MotorPosition",
    "StateTimeline",
    "hexaview_fragment",
    "state_kinds",
    "state_timelines",
]
