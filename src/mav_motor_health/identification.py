"""Identify a vehicle from its own flight logs: the shell around :func:`.model.identify.identify`.

``fit LOG... --out vehicle.toml`` calls :func:`identify_logs`: every log is read by the one telemetry
reader, the logs are laid one after another on one time axis (a gap between them, so no balance or
low-pass reaches across two flights), and the vehicle is identified from all their samples. With no
prior given, the bundled motor serves as the first prior only to set scales; identification then runs
again with its own first result as the prior, so that what the data cannot say (a hover-only flight says
little about B vs T_f) is pulled toward this vehicle's motor, not toward the paper's.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from .config import DEFAULT_MOTOR, MAX_MOTOR_NUMBER, load_motor_params, load_profile
from .diagnosis import diagnose
from .diagnosis.noise import (
    BandNoise,
    EquationNoise,
    band_noise_of,
    measure_band_noise,
    measure_speed_vs_siblings,
)
from .diagnosis.prediction import MIN_COVARIANCE_SAMPLES, MIN_MOTORS, measure_speed_covariance
from .diagnosis.profile import ThresholdProfile
from .errors import DataError, FitError
from .model.identify import Identification, identify
from .model.params import MotorParams
from .model.vehicle import VehicleParams
from .telemetry import sources
from .telemetry.table import TelemetryTable

__all__ = [
    "FLIGHT_LOG_SUFFIXES",
    "IdentifiedVehicle",
    "identify_logs",
    "is_flight_table",
    "join_flights",
    "provenance",
    "with_band_noise",
]

#: formats that always hold flights (a CSV may hold a flight or a test stand's steps)
FLIGHT_LOG_SUFFIXES = (".tlog", ".bin", ".log", ".ulg")
#: the gap laid between two logs on the joined time axis [s]
GAP_BETWEEN_LOGS_S = 60.0
#: the profile whose flight rule measures the band noise: its [steady] rule (low-passes, settling) is the
#: one every profile with ``noise_bands`` must share, since the noise depends on it
NOISE_PROFILE = "flight_vehicle"


@dataclass(frozen=True)
class IdentifiedVehicle:
    """The vehicle found, the identification behind it, and what it was found from."""

    vehicle: VehicleParams
    found: Identification
    logs: tuple[str, ...]
    prior: str

    def report(self) -> str:
        head = [
            f"[[Identification from flight]]  {len(self.logs)} log(s): {', '.join(self.logs)}",
            f"prior: {self.prior}",
        ]
        return "\n".join([*head, self.found.report()])


def provenance(found: Identification, logs: Sequence[str], prior: str) -> dict[str, str]:
    """What the params file's ``[source]`` says of an identification."""
    return {
        "identified_from": ", ".join(logs),
        "span_s": f"{found.span_s[0]:.2f}-{found.span_s[1]:.2f}",
        "samples": str(found.samples),
        "prior": prior,
        "determined_by": ", ".join(f"{k}: {v}" for k, v in found.determined_by.items()),
        "k_bic": ", ".join(f"k={k:g}: {b:.1f}" for k, b in sorted(found.k_bic.items())),
        **{f"finding_{i + 1}": text for i, text in enumerate(found.findings)},
    }


def is_flight_table(table: TelemetryTable, suffix: str) -> bool:
    """A flight (identify it) rather than a test stand's steady steps (the bench fit): a flight-log
    format, or a table with the command and the bus voltage of more than one motor over 20 s or more."""
    if suffix.lower() in FLIGHT_LOG_SUFFIXES:
        return True
    if "throttle" not in table or "bus_voltage_v" not in table or len(table.motors()) < 2:
        return False
    t = table["time_s"]
    return bool(np.isfinite(t).any() and np.nanmax(t) - np.nanmin(t) >= 20.0)


def join_flights(tables: Sequence[TelemetryTable]) -> TelemetryTable:
    """Several flights on one time axis, each after the one before with a gap between."""
    if len(tables) == 1:
        return tables[0]
    shifted: list[TelemetryTable] = []
    end = 0.0
    for table in tables:
        t = np.asarray(table["time_s"], dtype=float)
        start = float(np.nanmin(t)) if np.isfinite(t).any() else 0.0
        offset = end - start + (GAP_BETWEEN_LOGS_S if shifted else 0.0)
        shifted.append(table.with_columns(time_s=t + offset))
        end = float(np.nanmax(t)) + offset if np.isfinite(t).any() else end
    common = set.intersection(*(set(tb.names) for tb in shifted))
    return TelemetryTable.concat(
        TelemetryTable({k: v for k, v in tb.columns.items() if k in common}, source=tb.source)
        for tb in shifted
    )


def identify_logs(
    logs: Sequence[str | Path],
    *,
    prior: str | Path | None = None,
    k: float | None = None,
    name: str | None = None,
) -> IdentifiedVehicle:
    """Identify the vehicle flown in ``logs`` (healthy flights of one vehicle)."""
    if not logs:
        raise DataError("no log given; expected one or more flight logs")
    tables = [sources.read(log) for log in logs]
    for log, table in zip(logs, tables):
        if not len(table):
            raise DataError("no ESC samples to identify from", path=log)
    joined = join_flights(tables)
    label = name or f"identified from {Path(logs[0]).name}" + (
        f" and {len(logs) - 1} more" if len(logs) > 1 else ""
    )
    if prior is not None:
        prior_params = load_motor_params(prior)
        # a prior the user gives (a bench fit of the motor) keeps its own R where the flight cannot part
        # R from k_e, instead of the winding's typical share
        found = identify(joined, prior_params, k=k, name=label, copper_share=None)
        prior_text = f"{prior} (given)"
    else:
        # first pass: the bundled motor sets only the scales; second: this vehicle's own first estimate
        first = identify(joined, load_motor_params(DEFAULT_MOTOR), k=k, name=label)
        found = identify(joined, _as_prior(first.params), k=k, name=label)
        prior_text = "weak: the vehicle's own first estimate (no --prior given)"
    paths = tuple(str(p) for p in logs)
    vehicle = with_band_noise(VehicleParams.identified(found), tables)
    said = without_prediction(vehicle, joined, NOISE_PROFILE)
    if said:
        found = replace(found, findings=(*found.findings, said))
    vehicle = replace(vehicle, source=provenance(found, paths, prior_text))
    return IdentifiedVehicle(
        vehicle=vehicle,
        found=found,
        logs=paths,
        prior=prior_text,
    )


def with_band_noise(
    vehicle: VehicleParams, tables: Sequence[TelemetryTable], profile: str = NOISE_PROFILE
) -> VehicleParams:
    """The vehicle with each motor's band noise (:mod:`.diagnosis.noise`) added to its ``noise``: the
    flight rule of ``profile`` run over its healthy flights with the model identification found."""
    # each motor on its own first: the siblings' prediction needs the covariances this pass measures
    profile_rules = replace(load_profile(profile), speed_against_siblings=0.0)
    # an ESC that reports its input current: the torque balance carries the duty's ripple (noise.py), and
    # the rule reads the torque through the duty (model/balance.py)
    input_current = vehicle.current is not None and vehicle.current.side == "input"
    # while the noise is measured, no band: every sample the rule judges counts (a band would set aside
    # those the log's pairing makes doubtful, and those are part of the noise the bands must cover)
    unbounded = {m: BandNoise.unbounded(input_current) for m in range(1, MAX_MOTOR_NUMBER + 1)}
    diagnosed = _diagnosed(vehicle, tables, profile_rules, unbounded)
    # the rule's wait after a step: how much wider the deviations are while it waits (noise.py)
    settle_s = float(getattr(profile_rules.steady, "settle_s", 0.0))
    measured = measure_band_noise(diagnosed, profile_rules.min_command, settle_s, input_current)
    measured = _with_siblings_prediction(vehicle, tables, profile_rules, diagnosed, measured, unbounded)
    noise = {m: dict(v) for m, v in vehicle.noise.items()}
    for motor, band in measured.items():
        noise.setdefault(motor, {}).update(band.as_mapping())
    return replace(vehicle, noise=noise)


def without_prediction(vehicle: VehicleParams, table: TelemetryTable, profile: str = NOISE_PROFILE) -> str:
    """What the report says where the flight did not give the covariances the siblings' prediction needs
    (:func:`~.diagnosis.prediction.measure_speed_covariance`) for three or more motors: that the speed
    is then judged motor by motor, why, and what would let it be measured; "" where it did."""
    noise = band_noise_of(vehicle.noise)
    if sum(1 for n in noise.values() if n.speed_covariance) >= MIN_MOTORS:
        return ""
    tau_s = float(getattr(load_profile(profile).steady, "residual_tau_s", 0.0))
    time_s, motor = np.asarray(table["time_s"], dtype=float), np.asarray(table["motor"])
    gaps = [np.diff(np.sort(time_s[motor == m])) for m in np.unique(motor)]
    gaps = [g[np.isfinite(g) & (g > 0)] for g in gaps]
    every = float(np.median(np.concatenate(gaps))) if any(g.size for g in gaps) else math.nan
    return (
        "the speed is judged motor by motor, not against its siblings' prediction: the flight did not give "
        f"{MIN_COVARIANCE_SAMPLES} judged samples of three or more motors with every sibling's report of "
        f"the {tau_s:g} s before (the ESCs report every {every:.2f} s); a longer flight, or ESC telemetry "
        f"faster than every {tau_s:g} s, lets fit measure it"
    )


def _diagnosed(
    vehicle: VehicleParams,
    tables: Sequence[TelemetryTable],
    profile: ThresholdProfile,
    noise: Mapping[int, BandNoise],
) -> list[TelemetryTable]:
    """Each flight calibrated as the vehicle's ESC and current reading say and diagnosed with its models."""
    out = []
    for table in tables:
        calibrated = vehicle.calibrate(table)
        models = vehicle.models(range(1, max(int(m) for m in calibrated.motors()) + 1))
        out.append(diagnose(calibrated, models, profile, noise))
    return out


def _with_siblings_prediction(
    vehicle: VehicleParams,
    tables: Sequence[TelemetryTable],
    profile_rules: ThresholdProfile,
    diagnosed: Sequence[TelemetryTable],
    measured: dict[int, BandNoise],
    unbounded: Mapping[int, BandNoise],
) -> dict[int, BandNoise]:
    """``measured`` with each motor's speed covariance with its siblings and the noise of its speed
    deviation less their linear prediction (:mod:`.diagnosis.prediction`): Σ from the flights as
    diagnosed, then the flights diagnosed again with it (the noise still unbounded, each motor's offset
    applied as the bands will apply it) and the deviation less the siblings' part measured. Unchanged where
    Σ cannot be measured (too few motors or instants where all have a value)."""
    tau_s = float(getattr(profile_rules.steady, "residual_tau_s", 0.0))
    covariance, lagged = measure_speed_covariance(diagnosed, tau_s, profile_rules.min_command)
    if not covariance or not set(covariance) <= set(measured):
        return measured
    with_covariance = {
        m: replace(n, speed_covariance=covariance.get(m, ()), speed_lagged_covariance=lagged.get(m, ()))
        for m, n in measured.items()
    }
    predicting = dict(unbounded)
    for m, n in with_covariance.items():
        predicting[m] = replace(
            unbounded[m],
            speed_offset_rad_s=n.speed_offset_rad_s,
            speed_covariance=n.speed_covariance,
            speed_lagged_covariance=n.speed_lagged_covariance,
            speed_vs_siblings=EquationNoise(math.inf),
        )
    profile_predicting = replace(profile_rules, speed_against_siblings=1.0)
    again = _diagnosed(vehicle, tables, profile_predicting, predicting)
    settle_s = float(getattr(profile_rules.steady, "settle_s", 0.0))
    against, after_step = measure_speed_vs_siblings(again, profile_rules.min_command, settle_s)
    return {
        m: replace(n, speed_vs_siblings=against.get(m), speed_vs_siblings_after_step=after_step)
        for m, n in with_covariance.items()
    }


def _as_prior(params: MotorParams) -> MotorParams:
    """A first estimate as a prior: it must be a valid motor (positive C_p to set the load's scale)."""
    if params.C_p > 0 and math.isfinite(params.C_p):
        return params
    raise FitError(
        "identification found no propeller load (C_p = 0): is the log a flight with motors turning?"
    )
