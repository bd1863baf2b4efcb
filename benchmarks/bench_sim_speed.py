"""How fast the simulator runs, as ratios against a baseline measured in the same run.

Goal: an hour of flight in well under a minute, i.e. a real-time factor (simulated seconds per CPU
second) of at least 60, with the long-flight step (dt = 0.02 s), on an idle machine. The absolute
number depends on the machine; the ratio to the baseline (a pure-Python loop of 10^6 float additions,
a stand-in for "how fast is this Python here") is what to compare between runs.

    PYTHONPATH=src python benchmarks/bench_sim_speed.py
"""

from __future__ import annotations

import time

from mav_motor_health.sim.engine import run_scenario
from mav_motor_health.sim.scenario import scenario_from_dict


def baseline_s() -> float:
    start = time.process_time()
    x = 0.0
    for k in range(1_000_000):
        x += k * 0.5
    return time.process_time() - start


def flight_cpu_s(duration_s: float, dt_s: float, turbulence: str = "moderate") -> float:
    sc = scenario_from_dict(
        {
            "scenario": {"mode": "flight", "duration_s": duration_s, "dt_s": dt_s, "seed": 1},
            "flight": {"turbulence": turbulence},
            "fault": [{"kind": "F4.1", "motor": 2, "onset_s": duration_s / 2}],
        }
    )
    start = time.process_time()
    run_scenario(sc)
    return time.process_time() - start


def main() -> None:
    base = baseline_s()
    print(f"baseline (10^6 float additions): {base:.3f} s CPU")
    for dt in (0.01, 0.02):
        cpu = flight_cpu_s(120.0, dt)
        factor = 120.0 / cpu
        print(
            f"flight dt={dt}: real-time factor {factor:6.1f} (one hour in {3600 / factor:5.1f} s CPU); "
            f"hour / baseline = {3600 / factor / base:6.1f}"
        )
    start = time.process_time()
    run_scenario(scenario_from_dict({"scenario": {"mode": "testbed", "duration_s": 20.0}}))
    print(f"testbed 20 s at dt=0.001: {time.process_time() - start:.2f} s CPU")


if __name__ == "__main__":
    main()
