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


def test_the_demo_counts_the_delay_from_the_injection_on_the_agents_clock() -> None:
    """Where the simulation fell behind real time before the fault (a machine busy at the start), the
    fault's simulated time after the agent's first state is not when it was injected on the agent's
    clock: the delay is counted from the injection itself. (Once, in a fresh-clone CI run, the count from
    the simulated time said 1.23 s where the announcement then typically came 0.4 s after the injection
    (0.14–0.17 s since 6 December); a slip of the simulation before the fault is a way it can, and the
    cause was not proven.)"""
    from types import SimpleNamespace

    from mav_motor_health.agent.demo import FaultPlan, demo_summary
    from mav_motor_health.agent.monitor import StateChange
    from mav_motor_health.diagnosis.states import MotorState

    first = StateChange(3, 100.0, MotorState.NORMAL, MotorState.NO_DATA, {})
    # the simulation fell 0.9 s behind before its 6 s: injected at 106.9 on the agent's clock
    announced = StateChange(3, 107.3, MotorState.F3_1, MotorState.NORMAL, {})
    agent = SimpleNamespace(changes=[first, announced])
    fault = FaultPlan("F3.1", 6.0, 3)
    assert "0.40 s after the injection" in demo_summary(agent, "s", fault, 12.0, injected_at_s=106.9)
    # without the injection's time: counted from the first state, the slip included
    assert "1.30 s after the injection" in demo_summary(agent, "s", fault, 12.0)
