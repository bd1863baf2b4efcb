"""Writers for simulated flights: ``.tlog`` (MAVLink), ``.bin`` (ArduPilot DataFlash), ``.csv``; each
with a ground-truth sidecar ``<file>.truth.json``. :func:`write_record` picks one by extension.

The logs show what a real vehicle's would: the autopilot's command (SERVO_OUTPUT_RAW, RCOU, the CSV's
``throttle``), the ESCs' readings. A randomised world's truth (motor, ESC idle offset, current sensing,
rates) is in the sidecar under ``world`` (:meth:`~mav_motor_health.sim.worlds.World.truth`)."""

from __future__ import annotations

import json
from pathlib import Path

from ...errors import DataError
from ..engine import SimRecord

__all__ = ["WRITERS", "truth_path", "write_record"]


def _csv(record: SimRecord, path: Path) -> None:
    from .csv_writer import write_sim_csv

    write_sim_csv(record, path)


def _tlog(record: SimRecord, path: Path) -> None:
    from .tlog import write_tlog

    write_tlog(record, path)


def _bin(record: SimRecord, path: Path) -> None:
    from .dataflash import write_dataflash

    write_dataflash(record, path)


WRITERS = {".csv": _csv, ".tlog": _tlog, ".bin": _bin}


def truth_path(path: str | Path) -> Path:
    path = Path(path)
    return path.with_name(path.name + ".truth.json")


def write_record(record: SimRecord, path: str | Path, *, force: bool = False) -> tuple[Path, Path]:
    """Write a simulated record and its truth sidecar; refuses to overwrite unless ``force``."""
    path = Path(path)
    writer = WRITERS.get(path.suffix.lower())
    if writer is None:
        raise DataError(
            f"cannot write '{path.suffix}'", path=path, where=f"expected one of {sorted(WRITERS)}"
        )
    truth = truth_path(path)
    for p in (path, truth):
        if p.exists() and not force:
            raise DataError("exists already; not overwritten (use --force to replace it)", path=p)
    path.parent.mkdir(parents=True, exist_ok=True)
    writer(record, path)
    data = record.scenario.truth()
    data["file"] = path.name
    data["esc_samples"] = len(record.esc)
    if record.world is not None:
        data["world"] = record.world.truth()
    truth.write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")
    return path, truth
