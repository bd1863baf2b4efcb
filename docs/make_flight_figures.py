"""Figures of docs/flight.md: where the flight steady-state rule accepts and rejects samples.

Run from the repository root: ``PYTHONPATH=src python docs/make_flight_figures.py`` (needs matplotlib).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from mav_motor_health.config import load_motor_params, load_profile
from mav_motor_health.diagnosis import diagnose
from mav_motor_health.evaluation.campaign import FlightCase, run_flights

OUT = Path(__file__).resolve().parent / "img"


def main() -> None:
    OUT.mkdir(exist_ok=True)
    cases = [
        FlightCase(t, 5000 + k, 40.0, fault="F4.1", motor=2, onset_s=25.0)
        for k, t in enumerate(("calm", "gusty"))
    ]
    flights = run_flights(cases, jobs=1)
    params, profile = load_motor_params(), load_profile("flight")
    fig, axes = plt.subplots(4, 1, figsize=(10, 11), sharex=True)
    for row, flight in enumerate(flights):
        r = diagnose(flight.table, params, profile)
        sel = (r["motor"] == 2) & (r["time_s"] > 18) & (r["time_s"] < 32)
        t = r["time_s"][sel]
        steady = r["steady"][sel]
        ax = axes[2 * row]
        ax.plot(t, r["omega_rad_s"][sel], ".", ms=3, color="0.6", label="measured (rejected)")
        ax.plot(
            t[steady], r["omega_rad_s"][sel][steady], ".", ms=4, color="tab:blue", label="measured (accepted)"
        )
        ax.plot(
            t,
            r["omega_model_rad_s"][sel],
            "-",
            color="tab:red",
            lw=1,
            label="model through the motor's response",
        )
        ax.axvline(25.0, color="k", ls=":", lw=1)
        ax.set_ylabel("speed [rad/s]")
        ax.set_title(
            f"{flight.truth['turbulence']} air, motor 2, F4.1 at 25 s: "
            f"{100 * steady.mean():.0f} % of samples accepted"
        )
        ax.legend(loc="lower left", fontsize=8)
        ax = axes[2 * row + 1]
        ax.plot(t, r["current_a"][sel], ".", ms=3, color="0.6")
        ax.plot(t[steady], r["current_a"][sel][steady], ".", ms=4, color="tab:blue")
        ax.plot(t, r["current_model_a"][sel], "-", color="tab:red", lw=1)
        ax.axvline(25.0, color="k", ls=":", lw=1)
        ax.set_ylabel("current [A]")
    axes[-1].set_xlabel("time [s]")
    fig.tight_layout()
    fig.savefig(OUT / "flight_steady_rule.png", dpi=90)
    print(f"wrote {OUT / 'flight_steady_rule.png'}")


if __name__ == "__main__":
    main()
