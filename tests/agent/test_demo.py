"""The first command a newcomer runs (``./dev demo``: agent --sim with a fault) ends by itself with a summary."""

from __future__ import annotations

import re
import time
from pathlib import Path

from mav_motor_health.cli import main
from mav_motor_health.config import PARAMS_DIR


def test_the_demo_ends_by_itself_and_says_what_happened(tmp_path: Path, capsys) -> None:
    # ./dev demo's own entry point and scenario, shortened from 60 s to 12 s of flight
    text = (PARAMS_DIR / "scenarios" / "flight" / "healthy_calm.toml").read_text(encoding="utf-8")
    short = tmp_path / "short.toml"
    short.write_text(re.sub(r"duration_s = 60\.0", "duration_s = 12.0", text, count=1), encoding="utf-8")
    started = time.monotonic()
    code = main(["agent", "--sim", str(short), "--fault", "F3.1@6:3", "--no-tui"])
    took = time.monotonic() - started
    out, err = capsys.readouterr()
    assert code == 0
    assert took < 30  # 12 s of flight, then it stops: no Ctrl-C needed
    assert "demo finished: 12 s of the simulated flight" in out
    assert "injected: F3.1 on motor 3 at 6 s" in out
    delay = float(re.search(r"announced: motor 3 F3\.1 \(propeller damage\) ([0-9.]+) s after", out).group(1))
    assert delay < 1.0
    assert "other fault announcements: none" in out
    assert "mav-motor-health replay" in out and "mav-motor-health fit" in out
    # not on a terminal: one line per change (the view's), not a log line as well
    assert out.count("motor 3: NORMAL -> F3.1") == 1
    assert "NORMAL -> F3.1" not in err
