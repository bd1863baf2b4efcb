"""The ``mav_motor_health`` MAVLink dialect (``mav_motor_health.xml``): the MOTOR_HEALTH message.

It also carries common.xml's ESC_STATUS (291, PX4's ESC telemetry) verbatim, because the dialects shipped
with pymavlink 2.4.50 lack it; :func:`register` adds it to a dialect module only where it is missing.

:func:`load` runs pymavlink's own generator (``mavgen``, Python 3, MAVLink 2) on the shipped XML into a
private temporary folder once per process and imports the result, so the package ships the definition,
never generated code that could drift from it. :func:`register` teaches a pymavlink dialect module
(``ardupilotmega``, ``common``...) to decode MOTOR_HEALTH too: a receiver keeps its usual dialect.
"""

from __future__ import annotations

import atexit
import contextlib
import functools
import importlib.util
import io
import shutil
import sys
import tempfile
from pathlib import Path
from types import ModuleType
from typing import Any

__all__ = ["ESC_STATUS_ID", "MOTOR_HEALTH_ID", "XML_PATH", "load", "register"]

XML_PATH = Path(__file__).resolve().parent / "mav_motor_health.xml"
MOTOR_HEALTH_ID = 54100
ESC_STATUS_ID = 291


@functools.lru_cache(maxsize=1)
def load() -> ModuleType:
    """The generated pymavlink module for the dialect (``MAVLink_motor_health_message``...)."""
    from pymavlink.generator import mavgen, mavparse

    folder = Path(tempfile.mkdtemp(prefix="mav_motor_health_dialect_"))
    atexit.register(shutil.rmtree, folder, True)  # the module stays imported; the files are not needed
    out = folder / "mav_motor_health_dialect.py"
    opts = mavgen.Opts(str(out), wire_protocol=mavparse.PROTOCOL_2_0, language="Python3", validate=False)
    with contextlib.redirect_stdout(io.StringIO()):  # mavgen prints its progress
        ok = mavgen.mavgen(opts, [str(XML_PATH)])
    if not ok or not out.exists():
        raise RuntimeError(f"pymavlink mavgen could not generate {XML_PATH}")
    spec = importlib.util.spec_from_file_location("mav_motor_health_dialect", out)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def register(dialect_module: Any) -> None:
    """Let a pymavlink dialect module decode MOTOR_HEALTH, and ESC_STATUS if it lacks it (its ``mavlink_map``)."""
    generated = load()
    dialect_module.mavlink_map[MOTOR_HEALTH_ID] = generated.MAVLink_motor_health_message
    dialect_module.mavlink_map.setdefault(ESC_STATUS_ID, generated.MAVLink_esc_status_message)
