"""Figures of docs/flight.md: where the dynamic steady-state rule accepts and rejects samples, and what
the balance rule (the shipped flight profile) judges.

Run from the repository root: ``PYTHONPATH=src python docs/make_flight_figures.py`` (needs matplotlib).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

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
    params, profile = load_motor_params(), load_profile("flight_dynamic")
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
    balance_figure(flights, params)


def balance_figure(flights, params) -> None:
    """The balance rule's deviations (what the tree judges) against the activity-widened bands."""
    profile = load_profile("flight")
    fig, axes = plt.subplots(4, 1, figsize=(10, 11), sharex=True)
    for row, flight in enumerate(flights):
        r = diagnose(flight.table, params, profile)
        sel = (r["motor"] == 2) & (r["time_s"] > 18) & (r["time_s"] < 32)
        t = r["time_s"][sel]
        judged = r["steady"][sel]
        dw = (r["omega_judged_rad_s"] - r["omega_model_rad_s"])[sel]
        di = (r["current_judged_a"] - r["current_model_a"])[sel]
        speed_band = r["speed_band_rad_s"][sel]
        for ax, dev, below, above, unit in (
            (axes[2 * row], dw, speed_band, speed_band, "Δω [rad/s]"),
            (axes[2 * row + 1], di, r["current_band_below_a"][sel], r["current_band_a"][sel], "Δi [A]"),
        ):
            ax.fill_between(
                t, -below, above, color="tab:green", alpha=0.15, label="band (widened by activity)"
            )
            ax.plot(t, dev, ".", ms=3, color="0.6", label="not judged (warm-up, step)")
            ax.plot(t[judged], dev[judged], ".", ms=4, color="tab:blue", label="judged")
            ax.axvline(25.0, color="k", ls=":", lw=1)
            ax.set_ylabel(unit)
        axes[2 * row].set_title(
            f"{flight.truth['turbulence']} air, motor 2, F4.1 at 25 s: balance rule, "
            f"input activity {float(np.nanmedian(r['input_activity_v'][sel])):.2f} V"
        )
        axes[2 * row].legend(loc="lower left", fontsize=8)
    axes[-1].set_xlabel("time [s]")
    fig.tight_layout()
    fig.savefig(OUT / "flight_balance_rule.png", dpi=90)
    print(f"wrote {OUT / 'flight_balance_rule.png'}")


if __name__ == "__main__":
    main()
