"""Tune a threshold profile on labelled flights (the ``tune`` command's core; pure numpy).

The paper set its bands at twice the sensor noise seen on the testbed and split F2.1 from F4.2 at a
current seen there. In flight the residuals of a healthy motor are wider (the input moves, the
telemetry is late and quantised) and the stall currents depend on the battery. ``tune_profile`` reads
those numbers off labelled flights instead:

1. **Bands.** On healthy samples (motors without a fault, and the faulty motor before onset) that the
   steady rule accepts and whose current is trusted, the residuals against the model are collected, as
   the tree judges them (after the flight rule's residual low-pass).
   The speed band is ``margin ×`` the ``quantile`` of |ω − ω_model|; the current band is the same per bin
   of input voltage, made non-decreasing in voltage, with the bins' centres as anchors. With the
   ``balance`` rule the bands widen with the input's activity: the widths come from the calmest bin of
   activity, and each bin adds a row (activity, speed widening, current widening above the model, current
   widening below it) to ``activity_band``. The current's two sides are read off their own tails: in
   gusty air a healthy motor's current deviation is skewed (more and longer dips below the model than
   rises above it), and one width for both would let the dips through as "current low".
2. **Stall split.** The F2.1 and F4.2 currents after onset, below the stop speed, give one split per
   flight, the midpoint between the two kinds' currents; where the flights cover several bus voltages
   the split is fitted as ``a + b·(V_bus − V_ref)`` (a stalled motor's current scales with the voltage
   the ESC applies), else held constant.
   **Slow look** (``steady.slow_factor`` > 0, balance rule): with the new bands, ``slow_band_fraction``
   is ``margin ×`` the ``quantile`` of the healthy samples' slow deviations in shares of the bands, in
   the activity bin where that is largest.
3. **Persistence.** With the new bands, the runs of each false raw state on healthy samples (first to
   last eligible sample of a run, which is what persistence times; with ``max_depth`` > 1, Σ depth·Δt
   over the run, as persistence counts it) set that state's hold time: at least
   ``margin`` × the longest, and at least the run length that the runs' exponential tail says comes
   ``false_rate_per_hour`` times per flight hour (0.01: one per hundred hours) on the healthy flights,
   so that a few minutes of training flight stand for the hours a fleet flies. With the ``balance`` rule
   the holds grow with the input activity (``h0 + slope·a`` over the flights' median activities, see
   ``_hold_line``). What flickered on healthy motors is not announced. The result is checked by diagnosing the flights again; if any false event
   remains the bands are widened by 10 % and the procedure repeats.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..model.params import MotorParams
from ..telemetry.table import TelemetryTable
from .persistence import run_hold
from .pipeline import diagnose
from .plausibility import CURRENT_UNTRUSTED
from .profile import PersistenceRule, ThresholdProfile
from .rules import BalanceRule
from .states import MotorState

__all__ = ["LabelledFlight", "TuneResult", "fault_masks", "tune_profile"]


@dataclass(frozen=True)
class LabelledFlight:
    """A flight's telemetry and its ground truth (the simulator's sidecar: ``faults`` with kind, motor,
    onset_s)."""

    table: TelemetryTable
    truth: Mapping[str, Any]
    name: str = ""


@dataclass(frozen=True)
class TuneResult:
    profile: ThresholdProfile
    report: dict[str, Any] = field(default_factory=dict)


def fault_masks(
    result: TelemetryTable, truth: Mapping[str, Any]
) -> tuple[NDArray[np.bool_], NDArray[np.object_]]:
    """Per row: healthy (no fault active on that motor) and the true fault label ('' where healthy)."""
    n = len(result)
    label = np.full(n, "", dtype=object)
    for fault in truth.get("faults", []):
        sel = (result["motor"] == int(fault["motor"])) & (result["time_s"] >= float(fault["onset_s"]))
        end = fault.get("end_s")
        if end is not None:
            sel &= result["time_s"] < float(end)
        label[sel] = fault.get("fault", fault.get("kind"))
    return label == "", label


def _quantile(x: NDArray[np.float64], q: float) -> float:
    x = x[np.isfinite(x)]
    return float(np.quantile(x, q)) if x.size else float("nan")


def _activity_band(
    res_w: NDArray[np.float64],
    res_i: NDArray[np.float64],
    activity: NDArray[np.float64],
    quantile: float,
    margin: float,
    bins: int,
) -> tuple[float, float, tuple[tuple[float, float, float, float], ...]]:
    """Base speed and current widths from the calmest activity bin, and rows (activity, speed widening,
    current widening above the model, current widening below it) from every bin: anchored at the bin's
    90th percentile of activity (most of the bin judged with no more than its own widening),
    non-decreasing in activity.

    ``res_w`` may be unsigned; ``res_i`` is signed (measured minus model). Each side of the current band
    is read off its own tail: ``margin`` × the ``(1 + quantile)/2`` quantile of the residuals above the
    model, and of those below it, which for a symmetric residual is the ``quantile`` of |residual|. The
    widenings are each side's growth over the calmest bin, whose base width is that of |residual|."""
    side_q = 0.5 * (1.0 + quantile)
    edges = np.quantile(activity, np.linspace(0, 1, bins + 1))
    rows: list[tuple[float, float, float, float, float]] = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        sel = (activity >= lo) & (activity <= hi)
        if sel.sum() >= 20:
            anchor = float(np.quantile(activity[sel], 0.9))
            rows.append(
                (
                    anchor,
                    margin * _quantile(np.abs(res_w[sel]), quantile),
                    margin * _quantile(np.abs(res_i[sel]), quantile),
                    margin * _quantile(res_i[sel], side_q),
                    margin * _quantile(-res_i[sel], side_q),
                )
            )
    if not rows:
        return margin * _quantile(np.abs(res_w), quantile), margin * _quantile(np.abs(res_i), quantile), ()
    speed = np.maximum.accumulate([r[1] for r in rows])
    above = np.maximum.accumulate([r[3] for r in rows])
    below = np.maximum.accumulate([r[4] for r in rows])
    base_w, base_i = float(speed[0]), float(rows[0][2])
    table: dict[float, tuple[float, float, float, float]] = {}
    for row, w, up, down in zip(rows, speed, above, below):
        key = round(row[0], 3)
        table[key] = (
            key,
            round(float(w) - base_w, 3),
            round(max(0.0, float(up - above[0])), 4),
            round(max(0.0, float(down - below[0])), 4),
        )
    return base_w, base_i, tuple(table.values())


def _slow_band_fraction(
    results: Sequence[TelemetryTable],
    masks: Sequence[tuple[NDArray[np.bool_], NDArray]],
    quantile: float,
    margin: float,
    bins: int,
) -> tuple[float, dict[str, Any]]:
    """The share of the bands that the slow look needs: ``margin`` × the ``quantile`` of the healthy
    samples' slow deviations in shares of their bands (the larger of speed and current), in the bin of
    input activity where it is largest (the look's noise falls with averaging, its model error does not,
    and neither by the same amount at every activity). At most 1."""
    shares, acts = [], []
    for r, (healthy, _) in zip(results, masks):
        use = healthy & r["slow_ready"] & ((r["sensor_flags"] & CURRENT_UNTRUSTED) == 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            w = np.abs(r["omega_slow_judged_rad_s"] - r["omega_model_rad_s"]) / r["speed_band_rad_s"]
            di = r["current_slow_judged_a"] - r["current_model_a"]
            i = np.abs(di) / np.where(di < 0, r["current_band_below_a"], r["current_band_a"])
        share = np.fmax(w, i)
        use &= np.isfinite(share)
        shares.append(share[use])
        acts.append(np.nan_to_num(r["input_activity_v"][use]))
    share, act = np.concatenate(shares), np.concatenate(acts)
    if share.size < 50:
        raise ValueError(f"only {share.size} healthy samples for the slow look: too few to tune it")
    edges = np.quantile(act, np.linspace(0, 1, bins + 1))
    per_bin = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        sel = (act >= lo) & (act <= hi)
        if sel.sum() >= 50:
            per_bin.append(
                (round(float(np.median(act[sel])), 3), round(margin * _quantile(share[sel], quantile), 3))
            )
    if not per_bin:  # too few samples to split by activity
        per_bin.append((round(float(np.median(act)), 3), round(margin * _quantile(share, quantile), 3)))
    fraction = min(1.0, max(f for _, f in per_bin))
    return round(fraction, 3), {"samples": int(share.size), "fraction_by_activity": per_bin}


def _false_runs(
    result: TelemetryTable, healthy: NDArray[np.bool_], max_gap_s: float, max_depth: float = 1.0
) -> dict[int, list[float]]:
    """The holds [s] that the runs of each raw state other than NORMAL over eligible healthy samples reach:
    their durations, or with ``max_depth`` > 1 their Σ depth·Δt (as persistence counts them)."""
    runs: dict[int, list[float]] = {}
    eligible = (result["steady"] | np.isin(result["state"], [MotorState.F2_1, MotorState.F4_2])) & healthy
    for motor in result.motors():
        sel = np.flatnonzero((result["motor"] == motor) & eligible)
        if sel.size == 0:
            continue
        t, s = result["time_s"][sel], result["state"][sel].astype(np.int64)
        edges = np.flatnonzero((np.diff(s) != 0) | (np.diff(t) > max_gap_s)) + 1
        starts = np.concatenate([[0], edges])
        ends = np.concatenate([edges, [s.size]])
        for a, b in zip(starts, ends):
            code = int(s[a])
            if code in (MotorState.NORMAL, MotorState.NO_DATA):
                continue
            # persistence announces a state at an eligible sample of its run that comes at least the hold
            # after the run's first: a hold longer than the run's last sample never announces it
            rate = np.minimum(result["depth"][sel][a:b], max_depth) if max_depth > 1 else None
            runs.setdefault(code, []).append(run_hold(t[a:b], rate))
    return runs


def _tail_hold(durations: list[float], hours: float, rate_per_hour: float) -> float:
    """The hold that runs as long as these would exceed at most ``rate_per_hour`` times per hour.

    The runs' tail (the longest quarter, at least five) is taken as exponential beyond its threshold u:
    runs longer than u come ``n_u/hours`` times per hour and their excess has mean μ, so runs longer
    than ``u + μ·ln(n_u/(hours·rate))`` come ``rate`` times per hour. A short training set sees only
    its own longest run; this extrapolates to the flight hours a fleet will fly."""
    x = np.sort(np.asarray(durations, dtype=float))
    n_tail = max(5, x.size // 4)
    if x.size < 10 or hours <= 0:
        return 0.0
    u = float(x[-n_tail - 1])
    excess = x[-n_tail:] - u
    mu = float(np.mean(excess))
    return float(max(0.0, u + mu * np.log(n_tail / (hours * rate_per_hour))))


def _hold_line(points: list[tuple[float, float]], min_hold_s: float) -> tuple[float, float]:
    """Hold ``h0 + slope·a`` over flights' (activity, needed hold): h0 what the calmest flights need
    (activity within 1.5 × the lowest), the slope the smallest that covers every other flight."""
    levels = np.array([a for a, _ in points])
    need = np.array([h for _, h in points])
    calm = levels <= 1.5 * levels.min()
    h0 = max(min_hold_s, float(need[calm].max()))
    rest = (levels > 0) & ~calm
    slope = float(max(0.0, np.max((need[rest] - h0) / levels[rest]))) if rest.any() else 0.0
    if not (levels > 0).any():
        h0 = max(min_hold_s, float(need.max()))
    return h0, slope


def _false_events(result: TelemetryTable, healthy: NDArray[np.bool_]) -> int:
    events = 0
    for motor in result.motors():
        sel = result["motor"] == motor
        announced = result["announced"][sel].astype(np.int64)
        ok = healthy[sel]
        changed = np.flatnonzero(np.diff(announced) != 0) + 1
        events += int(np.sum(ok[changed] & (announced[changed] != MotorState.NORMAL)))
    return events


def tune_profile(
    flights: Sequence[LabelledFlight],
    params: MotorParams | dict[int, MotorParams],
    base: ThresholdProfile,
    *,
    quantile: float = 0.99,
    margin: float = 1.5,
    voltage_bins: int = 6,
    min_hold_s: float = 0.05,
    name: str = "flight",
    max_rounds: int = 8,
    false_rate_per_hour: float = 0.01,
) -> TuneResult:
    """Fit bands, stall split and persistence of ``base`` on labelled flights (see module doc)."""
    if not flights:
        raise ValueError("tune_profile needs at least one labelled flight")
    results = [diagnose(f.table, params, base) for f in flights]
    masks = [fault_masks(r, f.truth) for r, f in zip(results, flights)]

    # 1. bands from healthy, steady, trusted samples
    rw, ri, rv, ra = [], [], [], []
    for r, (healthy, _) in zip(results, masks):
        use = healthy & r["steady"] & ((r["sensor_flags"] & CURRENT_UNTRUSTED) == 0)
        use &= r["omega_model_rad_s"] >= base.stop_speed_rad_s
        # the measurement as the tree judged it (after the flight rule's residual low-pass)
        rw.append(np.abs(r["omega_judged_rad_s"] - r["omega_model_rad_s"])[use])
        ri.append((r["current_judged_a"] - r["current_model_a"])[use])  # signed: the sides may differ
        rv.append(r["voltage_v"][use])
        activity = r.get("input_activity_v")
        ra.append(np.zeros(int(use.sum())) if activity is None else np.nan_to_num(activity[use]))
    res_w, res_i, volts, acts = (np.concatenate(x) for x in (rw, ri, rv, ra))
    if res_w.size < 50:
        raise ValueError(f"only {res_w.size} healthy steady samples: too few to tune bands")
    fit_activity = isinstance(base.steady, BalanceRule) and bool(np.any(acts > 0))
    activity_band: tuple[tuple[float, ...], ...] = ()
    if fit_activity:
        # Bands that widen with the input's activity: widenings per activity bin and side (see
        # _activity_band); the current band's voltage anchors are then read off the residuals less
        # their bin's widening on their side.
        speed_band, _, activity_band = _activity_band(res_w, res_i, acts, quantile, margin, 2 * voltage_bins)
        xs = [row[0] for row in activity_band]
        if xs:
            up = np.interp(acts, xs, [row[2] for row in activity_band])
            down = np.interp(acts, xs, [row[3] for row in activity_band])
            res_i = np.maximum(np.abs(res_i) - np.where(res_i < 0, down, up), 0.0)
        else:
            res_i = np.abs(res_i)
    else:
        speed_band = margin * _quantile(res_w, quantile)
        res_i = np.abs(res_i)
    edges = np.quantile(volts, np.linspace(0, 1, voltage_bins + 1))
    anchors: list[tuple[float, float]] = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        sel = (volts >= lo) & (volts <= hi)
        if sel.sum() >= 20:
            anchors.append((float(np.median(volts[sel])), margin * _quantile(res_i[sel], quantile)))
    widths = np.maximum.accumulate([w for _, w in anchors])
    band = tuple((round(v, 3), round(float(w), 4)) for (v, _), w in zip(anchors, widths))
    band = tuple(dict(band).items())  # drop duplicate voltages (keeps the last, i.e. the widest)

    # 2. stall split from F2.1 / F4.2 flights
    stall: dict[str, list[tuple[float, float]]] = {"F2.1": [], "F4.2": []}
    for r, (_, label) in zip(results, masks):
        stopped = np.abs(r["omega_rad_s"]) < base.stop_speed_rad_s
        bus = r.get("bus_voltage_v")
        for kind in stall:
            sel = (label == kind) & stopped & np.isfinite(r["current_a"])
            if sel.sum() >= 5:
                v_bus = float(np.nanmedian(bus[sel])) if bus is not None else float("nan")
                stall[kind].append((v_bus, float(np.median(r["current_a"][sel]))))
    split_a, per_v, ref_v = base.stall_split_a, base.stall_split_per_v, base.stall_split_ref_v
    if stall["F2.1"] and stall["F4.2"]:
        f21 = np.array(stall["F2.1"])
        f42 = np.array(stall["F4.2"])
        buses = np.concatenate([f21[:, 0], f42[:, 0]])
        if np.all(np.isfinite(buses)) and np.ptp(buses) > 1.0:
            # currents proportional to bus voltage: split = mean ratio × V_bus
            ratio = 0.5 * (np.mean(f21[:, 1] / f21[:, 0]) + np.mean(f42[:, 1] / f42[:, 0]))
            ref_v = float(np.median(buses))
            split_a, per_v = ratio * ref_v, float(ratio)
        else:
            split_a = 0.5 * (float(np.max(f21[:, 1])) + float(np.min(f42[:, 1])))
            per_v = 0.0

    profile = replace(
        base,
        name=name,
        description=f"{base.name} tuned on {len(flights)} labelled flights",
        speed_band_rad_s=round(speed_band, 3),
        current_band_a=band,
        stall_split_a=round(split_a, 3),
        stall_split_per_v=round(per_v, 4),
        stall_split_ref_v=round(ref_v, 3),
        activity_band=activity_band,
    )
    # 2b. the slow look's share of the bands, from the healthy samples' longer averages
    slow_report: dict[str, Any] = {}
    if isinstance(base.steady, BalanceRule) and base.steady.slow_factor > 0:
        fraction, slow_report = _slow_band_fraction(
            [diagnose(f.table, params, profile) for f in flights], masks, quantile, margin, voltage_bins
        )
        profile = replace(profile, slow_band_fraction=fraction)
    # 3. persistence from the longest false runs, then verify (widen the bands if needed)
    rounds = []
    for _ in range(max_rounds):
        tuned = [diagnose(f.table, params, profile) for f in flights]
        # per flight: its false runs and, from their tail, the hold that keeps them below the target rate
        # in that flight's conditions (pooling a gusty flight with calm ones would dilute its rate)
        needs: dict[int, list[tuple[float, float]]] = {}
        for r, (healthy, _), flight in zip(tuned, masks, flights):
            # the tail's rate stands for stationary healthy flight: a flight with a fault has its upset
            # after the fault once, not once an hour, so there only the longest run counts
            stationary = not flight.truth.get("faults")
            flight_hours = float(np.ptp(r["time_s"])) / 3600.0 if len(r) and stationary else 0.0
            activity = r.get("input_activity_v")
            judged = healthy & r["steady"]
            level = (
                float(np.nanmedian(activity[judged]))
                if fit_activity and activity is not None and judged.any()
                else 0.0
            )
            false_runs = _false_runs(r, healthy, profile.persistence.max_gap_s, profile.persistence.max_depth)
            for code, durations in false_runs.items():
                need = max(margin * max(durations), _tail_hold(durations, flight_hours, false_rate_per_hour))
                needs.setdefault(code, []).append((level, need))
        # the base profile's holds are minimums (speed-only states, say, which labelled flights with a
        # trusted current never show)
        hold_by_label = dict(base.persistence.announce_s)
        per_activity: dict[str, float] = {}
        for code, points in needs.items():
            state_label = MotorState(code).label
            hold, slope = _hold_line(points, min_hold_s)
            hold_by_label[state_label] = max(hold_by_label.get(state_label, 0.0), round(hold, 3))
            if slope > 0:
                per_activity[state_label] = round(slope, 3)
        holds = tuple(sorted(hold_by_label.items()))
        profile = replace(
            profile,
            persistence=PersistenceRule(
                default_announce_s=max(min_hold_s, base.persistence.default_announce_s),
                clear_s=base.persistence.clear_s,
                announce_s=holds,
                max_gap_s=base.persistence.max_gap_s,
                announce_per_activity_s=tuple(sorted(per_activity.items())),
                max_depth=base.persistence.max_depth,
            ),
        )
        checked = [diagnose(f.table, params, profile) for f in flights]
        false = sum(_false_events(r, healthy) for r, (healthy, _) in zip(checked, masks))
        rounds.append({"speed_band_rad_s": profile.speed_band_rad_s, "false_events": false})
        if false == 0:
            break
        profile = replace(
            profile,
            speed_band_rad_s=round(profile.speed_band_rad_s * 1.1, 3),
            current_band_a=tuple((v, round(w * 1.1, 4)) for v, w in profile.current_band_a),
            activity_band=tuple(
                (row[0], round(row[1] * 1.1, 3), *(round(i * 1.1, 4) for i in row[2:]))
                for row in profile.activity_band
            ),
        )
    report = {
        "flights": [f.name or f.table.source for f in flights],
        "healthy_steady_samples": int(res_w.size),
        "speed_residual_q": _quantile(res_w, quantile),
        "quantile": quantile,
        "margin": margin,
        "stall_currents": {k: v for k, v in stall.items()},
        "rounds": rounds,
        "slow_look": slow_report,
    }
    return TuneResult(profile=profile, report=report)
