"""Figures for compare, explain and fit --with (matplotlib, the optional ``plot`` extra).

A thin shell: it draws what the pure functions computed and writes PNG files.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ..errors import DataError
from .compare import Comparison
from .steps import EffectSteps

__all__ = ["plot_comparison", "plot_steps"]


def _pyplot() -> Any:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as exc:  # pragma: no cover - matplotlib is in the dev environment
        raise DataError("plots need matplotlib: pip install 'mav-motor-health[plot]'") from exc
    return plt


def _new_file(path: Path, force: bool) -> Path:
    if path.exists() and not force:
        raise DataError("exists already; not overwritten (use --force to replace it)", path=path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return path


def plot_comparison(
    comparison: Comparison, folder: str | Path, *, force: bool = False, max_points: int = 2000
) -> list[Path]:
    """Measured vs model against voltage and time, and residuals against every variable."""
    plt = _pyplot()
    folder = Path(folder)
    if folder.exists() and any(folder.iterdir()) and not force:
        raise DataError("output folder exists and is not empty (use --force)", path=folder)
    folder.mkdir(parents=True, exist_ok=True)
    s = comparison.samples
    n = len(s["time_s"])
    idx = np.arange(n) if n <= max_points else np.linspace(0, n - 1, max_points).round().astype(int)
    written = []
    for axis, label in (("voltage_v", "voltage [V]"), ("time_s", "time [s]")):
        fig, axes = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
        x = s[axis][idx]
        for ax, (meas, model, unit) in zip(
            axes,
            (
                ("omega_rad_s", "omega_model_rad_s", "speed [rad/s]"),
                ("current_a", "current_model_a", "current [A]"),
            ),
        ):
            size = 2 if len(idx) > 300 else 6  # bench files: a few points, drawn larger
            ax.plot(x, s[meas][idx], ".", ms=size, alpha=0.5, label="measured")
            ax.plot(x, s[model][idx], "x" if size > 2 else ".", ms=size, color="C3", label="model")
            ax.set_ylabel(unit)
            ax.legend(loc="upper left", markerscale=4)
        axes[-1].set_xlabel(label)
        fig.suptitle(f"measured vs model: {comparison.params.name}")
        fig.tight_layout()
        path = _new_file(folder / f"measured_vs_model_{axis}.png", True)
        fig.savefig(path, dpi=90)
        plt.close(fig)
        written.append(path)
    variables = ["voltage_v", "time_s"] + [k for k in s if k.startswith("context:") and k != "context:time_s"]
    cols = 3
    rows = (len(variables) + cols - 1) // cols
    fig, axes = plt.subplots(rows * 2, cols, figsize=(4 * cols, 2.6 * rows * 2), squeeze=False)
    nw, ni = comparison.noise.omega_rad_s, comparison.noise.current_a
    for j, var in enumerate(variables):
        r, c = divmod(j, cols)
        x = s[var][idx]
        name = var.removeprefix("context:")
        for k, (res, floor, unit) in enumerate(
            (
                ("omega_residual_rad_s", nw, "speed error [rad/s]"),
                ("current_residual_a", ni, "current error [A]"),
            )
        ):
            ax = axes[2 * r + k][c]
            ax.plot(x, s[res][idx], ".", ms=1.5, alpha=0.4)
            for sign in (-1, 1):
                ax.axhline(sign * floor, color="k", lw=0.8, ls="--")
            ax.set_xlabel(name)
            ax.set_ylabel(unit, fontsize=8)
    for j in range(len(variables), rows * cols):
        r, c = divmod(j, cols)
        axes[2 * r][c].set_visible(False)
        axes[2 * r + 1][c].set_visible(False)
    fig.suptitle("forward errors against every variable (dashed: ±1 σ noise floor)")
    fig.tight_layout()
    path = _new_file(folder / "residuals_vs_variables.png", True)
    fig.savefig(path, dpi=60)
    plt.close(fig)
    written.append(path)
    return written


def plot_steps(steps: EffectSteps, path: str | Path, *, force: bool = False) -> Path:
    """The speed and current error after each added effect, against the noise floor."""
    plt = _pyplot()
    path = _new_file(Path(path), force)
    labels = [s.label for s in steps.steps]
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for ax, (attr, floor, unit) in zip(
        axes,
        (
            ("rmse_omega_rad_s", steps.noise.omega_rad_s, "speed rmse [rad/s]"),
            ("rmse_current_a", steps.noise.current_a, "current rmse [A]"),
        ),
    ):
        ax.plot(range(len(labels)), [getattr(s, attr) for s in steps.steps], "o-")
        ax.axhline(floor, color="k", ls="--", lw=1, label="noise floor")
        ax.set_xticks(range(len(labels)))
        ax.set_xticklabels(labels, rotation=25, ha="right", fontsize=8)
        ax.set_ylabel(unit)
        ax.set_ylim(bottom=0)
        ax.legend()
    fig.suptitle("forward error as effects are added")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path
