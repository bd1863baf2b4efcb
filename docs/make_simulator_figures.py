"""Make the figures of docs/simulator.md (needs matplotlib, the ``plot`` extra)::

    PYTHONPATH=src python docs/make_simulator_figures.py

Writes docs/img/sim_*.png. Everything is simulated with fixed seeds, so the figures are reproducible.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from mav_motor_health.config import load_motor_params, load_profile
from mav_motor_health.diagnosis.pipeline import diagnose
from mav_motor_health.diagnosis.states import MotorState
from mav_motor_health.model.equations import steady_state
from mav_motor_health.sim.engine import Simulation, run_scenario
from mav_motor_health.sim.scenario import load_scenario, scenario_from_dict
from mav_motor_health.sim.writers.csv_writer import sim_table

OUT = Path(__file__).resolve().parent / "img"
FAULTS = ("F1.1", "F2.1", "F3.1", "F4.1", "F4.2")


def steady_state_figure(params) -> None:
    volts = np.linspace(4.0, 11.0, 11)
    table = []
    for v in volts:
        sc = scenario_from_dict(
            {
                "scenario": {"mode": "testbed", "duration_s": 3.0, "seed": int(v * 10)},
                "testbed": {"voltage_v": v},
            }
        )
        rec = run_scenario(sc)
        cols = rec.esc_columns()
        keep = cols["time_s"] > 1.0
        table.append((cols["voltage_v"][keep], cols["omega_rad_s"][keep], cols["current_a"][keep]))
    fine = np.linspace(3.5, 11.5, 200)
    model = steady_state(params, fine)
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4))
    for v, w, i in table:
        a.plot(v, w, ".", ms=2, color="tab:blue", alpha=0.3)
        b.plot(v, i, ".", ms=2, color="tab:orange", alpha=0.3)
    a.plot(fine, model.omega_rad_s, "k-", label="paper's model (eq. 2, 7)")
    b.plot(fine, model.current_a, "k-", label="paper's model (eq. 2, 7)")
    a.set(xlabel="input voltage [V]", ylabel="speed [rad/s]", title="simulated ESC reports vs model")
    b.set(xlabel="input voltage [V]", ylabel="motor current [A]", title="noise ±10 rad/s, ±0.15…1.0 A")
    a.legend()
    b.legend()
    fig.tight_layout()
    fig.savefig(OUT / "sim_steady_state.png", dpi=110)
    plt.close(fig)


def testbed_figure(params) -> None:
    profile = load_profile("testbed")
    fig, axes = plt.subplots(len(FAULTS), 3, figsize=(13, 12), sharex=True)
    for row, fault in enumerate(FAULTS):
        for volts, color in (("4.2", "tab:blue"), ("7.6", "tab:green"), ("11.0", "tab:red")):
            rec = run_scenario(load_scenario(f"testbed/{fault}_{volts}V"))
            res = diagnose(sim_table(rec), params, profile)
            t = res["time_s"]
            axes[row, 0].plot(t, res["omega_rad_s"], ".", ms=2, color=color, label=f"{volts} V")
            axes[row, 0].plot(t, res["omega_model_rad_s"], "-", color=color, lw=0.8)
            axes[row, 1].plot(t, res["current_a"], ".", ms=2, color=color)
            axes[row, 1].plot(t, res["current_model_a"], "-", color=color, lw=0.8)
            axes[row, 2].step(t, res["announced"], where="post", color=color)
        axes[row, 0].set_ylabel(f"{fault}\nspeed [rad/s]")
        axes[row, 1].set_ylabel("current [A]")
        axes[row, 2].set_yticks([int(s) for s in MotorState][:6], [s.label for s in MotorState][:6])
        axes[row, 2].set_ylabel("announced")
        for ax in axes[row]:
            ax.axvline(10.0, color="k", lw=0.6, ls="--")
            ax.set_xlim(8.5, 13.0)
    axes[0, 0].legend(loc="upper right", fontsize=7)
    for ax in axes[-1]:
        ax.set_xlabel("time [s] (fault at 10 s)")
    fig.suptitle("Testbed: faults at 4.2, 7.6 and 11 V (dots measured, lines model), testbed profile")
    fig.tight_layout()
    fig.savefig(OUT / "sim_testbed_faults.png", dpi=100)
    plt.close(fig)


def flight_f41_figure(params) -> None:
    profile = load_profile("flight")
    fig, axes = plt.subplots(3, 2, figsize=(12, 8), sharex=True)
    for row, level in enumerate(("calm", "moderate", "gusty")):
        sc = scenario_from_dict(
            {
                "scenario": {"mode": "flight", "duration_s": 16.0, "seed": 42, "dt_s": 0.01},
                "flight": {"turbulence": level},
                "fault": [{"kind": "F4.1", "motor": 2, "onset_s": 8.0}],
            }
        )
        rec = run_scenario(sc)
        res = diagnose(sim_table(rec), params, profile)
        m2 = res["motor"] == 2
        t = res["time_s"][m2]
        axes[row, 0].plot(t, res["omega_rad_s"][m2], ".", ms=2, label="motor 2 measured")
        axes[row, 0].plot(t, res["omega_model_rad_s"][m2], "-", lw=0.8, label="model at its input")
        ok = 100 * np.mean(res["state"][m2][t >= 8.0] == MotorState.F4_1)
        axes[row, 0].set_ylabel(f"{level}\nspeed [rad/s]")
        axes[row, 0].set_title(
            f"F4.1 on motor 2 at 8 s: {ok:.1f} % of samples after it diagnosed F4.1", fontsize=9
        )
        duty = np.array([v.duty for v in rec.vehicle])
        tv = np.array([v.time_s for v in rec.vehicle])
        for j in range(6):
            axes[row, 1].plot(tv, duty[:, j], lw=0.7, label=f"motor {j + 1}")
        axes[row, 1].set_ylabel("duty (input voltage / bus)")
    axes[0, 0].legend(fontsize=7)
    axes[0, 1].legend(fontsize=7, ncol=3)
    for ax in axes[-1]:
        ax.set_xlabel("time [s]")
    fig.tight_layout()
    fig.savefig(OUT / "sim_flight_F4.1_turbulence.png", dpi=100)
    plt.close(fig)


def motor_loss_figure() -> None:
    sc = scenario_from_dict(
        {
            "scenario": {"mode": "flight", "duration_s": 14.0, "seed": 3, "dt_s": 0.01},
            "flight": {"turbulence": "calm"},
            "fault": [{"kind": "F2.1", "motor": 1, "onset_s": 4.0, "stall_current_a": 2.26}],
        }
    )
    sim = Simulation(sc)
    rows = []
    while sim.time_s < sc.duration_s:
        sim.step()
        b = sim.body
        assert b is not None
        rows.append(
            (
                sim.time_s,
                *sim.duty,
                *sim.bank.omega_rad_s,
                *sim.bank.current_a,
                b.alt_m,
                *np.degrees(b.att[:2]),
            )
        )
    a = np.array(rows)
    t = a[:, 0]
    fig, axes = plt.subplots(4, 1, figsize=(10, 9), sharex=True)
    for j in range(6):
        axes[0].plot(t, a[:, 1 + j], lw=0.8, label=f"motor {j + 1}")
        axes[1].plot(t, a[:, 7 + j], lw=0.8)
        axes[2].plot(t, a[:, 13 + j], lw=0.8)
    axes[0].set_ylabel("duty")
    axes[0].legend(ncol=6, fontsize=7)
    axes[1].set_ylabel("speed [rad/s]")
    axes[2].set_ylabel("motor current [A]")
    axes[3].plot(t, a[:, 19], label="altitude [m]")
    axes[3].plot(t, a[:, 20], label="roll [deg]")
    axes[3].plot(t, a[:, 21], label="pitch [deg]")
    axes[3].legend(fontsize=7)
    axes[3].set_xlabel("time [s] (F2.1 on motor 1 at 4 s)")
    for ax in axes:
        ax.axvline(4.0, color="k", lw=0.6, ls="--")
    fig.suptitle("Motor 1 loses a phase in flight: its command saturates, motors 3-6 take the load")
    fig.tight_layout()
    fig.savefig(OUT / "sim_flight_motor_loss.png", dpi=100)
    plt.close(fig)


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    params = load_motor_params()
    steady_state_figure(params)
    testbed_figure(params)
    flight_f41_figure(params)
    motor_loss_figure()
    for p in sorted(OUT.glob("sim_*.png")):
        print(p)


if __name__ == "__main__":
    main()
