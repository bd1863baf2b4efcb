"""Several motors in one core call give what one call per motor gives (issue 18's streaming core).

The live agent hands the core every motor's few new samples at once (:meth:`StreamingDiagnoser.update_motors`,
rows of different lengths); replay runs one motor's whole log per call. A simulated flight with a stall,
missing samples and six ESCs reporting at their own rates is fed in random chunks both ways, and whole.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from mav_motor_health.config import load_profile
from mav_motor_health.diagnosis import pipeline
from mav_motor_health.diagnosis.noise import BandNoise, EquationNoise
from mav_motor_health.diagnosis.pipeline import MotorBatch, StreamingDiagnoser, diagnose_motor
from mav_motor_health.diagnosis.plausibility import CurrentSumCheck, PlausibilityRule
from mav_motor_health.diagnosis.rules import tree as tree_rules
from mav_motor_health.diagnosis.states import MotorState
from mav_motor_health.diagnosis.vehicle_check import VehicleCheck, VehicleCheckRule
from mav_motor_health.model.params import MotorParams
from mav_motor_health.telemetry import sources

#: motor 1 stalls at 30 s
FLIGHT = Path(__file__).resolve().parents[1] / "sitl_logs" / "flight_F4.2_moderate.csv"
#: columns that are codes or flags: equal exactly; the others to rounding
DISCRETE = ("state", "announced", "steady", "sensor_flags", "slow_ready")


@pytest.fixture(scope="module", params=[False, True], ids=["all samples", "lost samples"])
def motors(request: pytest.FixtureRequest) -> dict[int, dict[str, np.ndarray]]:
    return _window(lost=request.param)


def _window(lost: bool) -> dict[int, dict[str, np.ndarray]]:
    table = sources.read(FLIGHT).sorted_by_motor_time()
    window = (table["time_s"] > 22.0) & (table["time_s"] < 38.0)
    rng = np.random.default_rng(18)
    out = {}
    for motor in table.motors():
        sel = window & (table["motor"] == motor)
        cols = {name: np.array(table[name][sel], dtype=float) for name in table.names}
        if lost:
            cols["omega_rad_s"][rng.random(cols["time_s"].size) < 0.03] = np.nan  # lost samples
            cols["esc_current_a"][rng.random(cols["time_s"].size) < 0.03] = np.nan
        out[int(motor)] = cols
    return out


def batch(cols: dict[str, np.ndarray], part: slice) -> MotorBatch:
    return MotorBatch(
        cols["time_s"][part],
        cols["voltage_v"][part],
        cols["omega_rad_s"][part],
        cols["current_a"][part],
        cols["bus_voltage_v"][part],
        command=cols["throttle"][part],
        sensor_current_a=cols["esc_current_a"][part],
        extra_flags=np.zeros(cols["time_s"][part].size, dtype=np.int16),
    )


def assert_same(got: dict[str, np.ndarray], want: dict[str, np.ndarray], motor: int) -> None:
    assert got.keys() == want.keys()
    for name in want:
        if name in DISCRETE:
            np.testing.assert_array_equal(got[name], want[name], err_msg=f"motor {motor}: {name}")
        else:
            np.testing.assert_allclose(
                got[name], want[name], rtol=1e-12, atol=1e-9, equal_nan=True, err_msg=f"motor {motor}: {name}"
            )


def per_motor_models(paper_motor: MotorParams, motors: Iterable[int]) -> dict[int, MotorParams]:
    """Each motor its own R and k_e, as identification's per-motor models give (a few per cent apart)."""
    return {
        m: paper_motor.replace(
            R_ohm=paper_motor.R_ohm * (1.0 + 0.04 * (m - 3.5)),
            k_e=paper_motor.k_e * (1.0 + 0.015 * (m - 3.5)),
            name=f"motor {m}",
        )
        for m in motors
    }


def stage_noise(motors: Iterable[int]) -> dict[int, BandNoise]:
    """Made-up noise for every motor, each its own, with the torque's against its siblings (the
    vehicle stage runs)."""
    return {
        m: BandNoise(
            6.0 + m,
            0.2 + 0.05 * m,
            15.0 + m,
            0.4,
            torque=EquationNoise(0.001, 0.002, 0.0, 0.0, through_duty=True),
            torque_vs_siblings=EquationNoise(0.0003 + 0.0001 * m, 0.001, 0.0, 0.0001),
        )
        for m in motors
    }


@pytest.mark.parametrize("models", ["one model", "per-motor models"])
@pytest.mark.parametrize("profile_name", ["flight", "flight_dynamic", "testbed", "flight_vehicle"])
def test_motors_in_one_call_give_what_one_call_per_motor_gives(
    paper_motor, motors, profile_name, models, monkeypatch
) -> None:
    profile = load_profile(profile_name)
    params = paper_motor if models == "one model" else per_motor_models(paper_motor, motors)
    calls = []  # the core calls update_motors makes: one for all motors, whether or not each has its model
    start_motors = pipeline.start_motors

    def counted(*args: Any, **kwargs: Any) -> Any:
        calls.append(args[2].shape[0])  # the rows: the motors in the call
        return start_motors(*args, **kwargs)

    monkeypatch.setattr(pipeline, "start_motors", counted)
    rng = np.random.default_rng(7)
    # bands from each motor's own noise (flight_vehicle): every motor a different one, so that a row
    # given another motor's noise would show; the torque balance's too, half of them read through the
    # duty (an input current: not judged in it, rules/equations.py). The stall split's typical current
    # three times the motor's hover current, as an input current identified in gusty air gives: this
    # flight's own (carried from call to call, counted from its 50th sample here so that it counts
    # before the stall in this window) names the stall F4.2 (rules/tree.py)
    monkeypatch.setattr(tree_rules, "MIN_FLIGHT_SAMPLES", 50)
    noise = {
        m: BandNoise(
            6.0 + m,
            0.2 + 0.05 * m,
            15.0 + m,
            0.4,
            current_typical_a=3.0 * 3.8,
            omega_low_rad_s=300.0,
            torque=EquationNoise(0.001 + 0.0002 * m, 0.002, 0.0, 0.0003 * m, through_duty=m % 2 == 1),
        )
        for m in motors
    }
    one_by_one = StreamingDiagnoser(params, profile, list(motors), noise)
    together = StreamingDiagnoser(params, profile, list(motors), noise)
    position = dict.fromkeys(motors, 0)
    parts_one: dict[int, list] = {m: [] for m in motors}
    parts_all: dict[int, list] = {m: [] for m in motors}
    while any(position[m] < motors[m]["time_s"].size for m in motors):
        batches = {}
        for m, cols in motors.items():
            size = int(rng.integers(0, 12))  # uneven: some motors send nothing in a batch, some a dozen
            start = position[m]
            if size == 0 or start >= cols["time_s"].size:
                continue
            part = slice(start, start + size)
            position[m] = min(start + size, cols["time_s"].size)
            batches[m] = batch(cols, part)
            b = batches[m]
            parts_one[m].append(
                one_by_one.update_many(
                    m,
                    b.time_s,
                    b.voltage_v,
                    b.omega_rad_s,
                    b.current_a,
                    b.bus_voltage_v,
                    command=b.command,
                    sensor_current_a=b.sensor_current_a,
                    extra_flags=b.extra_flags,
                )
            )
        calls.clear()
        for m, cols in together.update_motors(batches).items():
            parts_all[m].append(cols)
        assert calls == ([len(batches)] if batches else []), "one core call for every motor"
    for m, cols in motors.items():
        alone = {name: np.concatenate([p[name] for p in parts_one[m]]) for name in parts_one[m][0]}
        rows = {name: np.concatenate([p[name] for p in parts_all[m]]) for name in parts_all[m][0]}
        assert_same(rows, alone, m)
        assert together.carries[m].rules["persistence"] == one_by_one.carries[m].rules["persistence"]
        # (a batch that ends on a lost sample carries it as lost: the next batch averages its first
        # interval from its own sample alone, as the whole array does, model/dynamics.py; lost samples
        # included, the agent's states are replay's)
        whole, _ = diagnose_motor(
            params if isinstance(params, MotorParams) else params[m],
            profile,
            cols["time_s"],
            cols["voltage_v"],
            cols["omega_rad_s"],
            cols["current_a"],
            cols["bus_voltage_v"],
            command=cols["throttle"],
            sensor_current_a=cols["esc_current_a"],
            extra_flags=np.zeros(cols["time_s"].size, dtype=np.int16),
            noise=noise[m] if profile.noise_bands else None,
        )
        for name in ("state", "announced", "steady"):
            np.testing.assert_array_equal(rows[name], whole[name], err_msg=f"motor {m}: {name}")
    if profile_name in ("flight", "flight_vehicle"):  # the stall was seen, and named the same way in both
        assert (np.concatenate([p["announced"] for p in parts_all[1]]) != 0).any()
    if profile_name == "flight_vehicle":  # by the split of the flight's own typical current
        announced = np.concatenate([p["announced"] for p in parts_all[1]])
        assert set(np.unique(announced)) - {0} == {MotorState.F4_2}
        assert together.carries[1].rules["tree"].count >= 50


@pytest.mark.parametrize(
    "limited, step_sigmas, against, torque_spread, slow_siblings, over_changes",
    [
        (False, 0.0, False, 0.0, 0.0, 0.0),
        (True, 0.0, False, 0.0, 0.0, 0.0),
        (True, 1.0, False, 0.0, 0.0, 0.0),
        (True, 0.0, True, 0.0, 0.0, 0.0),
        (True, 0.0, False, 1.0, 0.0, 0.0),
        (True, 0.0, False, 0.0, 0.03, 0.0),
        (True, 0.0, False, 0.0, 0.0, 1.0),
    ],
    ids=[
        "within the conditions",
        "grown as siblings run",
        "a step in the motor's own noise",
        "the speed against the siblings' prediction",
        "the torque's band grown by its siblings' spread",
        "the slow look's bands as its siblings run",
        "a step's allowance over the command's changes",
    ],
)
def test_the_vehicle_stage_gives_the_same_in_batches_as_whole_logs(
    paper_motor, limited, step_sigmas, against, torque_spread, slow_siblings, over_changes
) -> None:
    """With the torque judged against the siblings (diagnosis/siblings.py), a motor's results depend on
    the others': batches cut in the order samples arrive (time, then motor) through
    :meth:`StreamingDiagnoser.update_motors` give what :func:`diagnose` gives the whole table. (Every
    sample given here; lost samples: the test above and the one of a log in parts, below.)
    ``limited``: the noise measured on a calmer flight, so that most samples lie beyond its conditions,
    where the shipped profile grows the bands as the siblings' deviations run (rules/bands.py): the
    bands depend on the other motors' too, and are the same both ways. ``step_sigmas``: a step also where
    the model speed jumps by that many σ of the motor's noise (rules/balance.py), the model speed of a
    batch's first sample compared with the one carried from the batch before. ``against``: the speed
    judged less the siblings' linear prediction (diagnosis/prediction.py), from a covariance whose
    motors move together, so that the prediction takes part of every motor's deviation off.
    ``torque_spread``: the torque's band grown beyond the conditions by its siblings' spread (the stage's,
    low-passed by the bands with a carry of their own: rules/bands.py, "The torque's own growth").
    ``slow_siblings``: the slow look's bands at most that multiple of the siblings' slow averages' root
    mean square (each motor's low-passed by the live noise with a carry of its own, the median the
    stage's: rules/tree.py, "The slow look as its siblings run"), small enough here that it names
    samples the motor's own slow bands leave NORMAL, and none before a sibling's mean holds a time
    constant's worth of samples. ``over_changes``: a step's allowance the zigzag over the command's
    changes (model/balance.py, ``change_zigzag_rows``), its low-passes, last change and command carried
    between batches (this window's steps are the same either way: the allowance's own carry is checked
    in calls cut anywhere in tests/test_balance_rule.py)."""
    motors = _window(lost=False)
    from mav_motor_health.diagnosis.pipeline import diagnose
    from mav_motor_health.telemetry.table import TelemetryTable

    # each motor on its own unless the case says (the shipped profile judges against the prediction)
    base = dataclasses.replace(load_profile("flight_vehicle"), speed_against_siblings=0.0)
    profile = base
    if step_sigmas or over_changes:
        profile = dataclasses.replace(
            profile,
            steady=dataclasses.replace(
                profile.steady, step_sigmas=step_sigmas, step_over_changes=over_changes
            ),
        )
    noise = stage_noise(motors)
    if torque_spread:
        profile = dataclasses.replace(profile, torque_siblings_spread=torque_spread)
    if slow_siblings:
        # a sibling's mean square is a reference once it holds one time constant of counted samples: a
        # shorter one than the profile's ten seconds, for the window's sixteen
        profile = dataclasses.replace(profile, slow_siblings=slow_siblings, conditions_siblings_s=2.0)
        # the slow look's own noise, as wide as the fast deviations' (none measured: no slow look)
        noise = {
            m: dataclasses.replace(
                n,
                slow_speed=EquationNoise(n.speed_rad_s, n.speed_rad_s_per_v),
                slow_current=EquationNoise(n.current_a, n.current_a_per_v),
            )
            for m, n in noise.items()
        }
    if against:
        profile = dataclasses.replace(profile, speed_against_siblings=1.0)
        # every pair correlated 0.5, each motor its own variance
        spread = {m: 6.0 + m for m in motors}
        noise = {
            m: dataclasses.replace(
                n,
                speed_covariance=tuple(
                    (o, spread[m] * spread[o] * (1.0 if o == m else 0.5)) for o in sorted(motors)
                ),
                speed_lagged_covariance=tuple(
                    (o, spread[m] * spread[o] * (1.0 if o == m else 0.4)) for o in sorted(motors)
                ),
                speed_vs_siblings=EquationNoise(0.8 * n.speed_rad_s, 0.8 * n.speed_rad_s_per_v),
            )
            for m, n in noise.items()
        }
    names = ("time_s", "voltage_v", "omega_rad_s", "current_a", "bus_voltage_v", "throttle", "esc_current_a")
    table = TelemetryTable(
        {
            "motor": np.concatenate([np.full(motors[m]["time_s"].size, m) for m in motors]),
            **{name: np.concatenate([motors[m][name] for m in motors]) for name in names},
        }
    )
    whole = diagnose(table, paper_motor, profile, noise)
    if limited:
        calm = float(np.quantile(whole["input_activity_v"][whole["steady"]], 0.3))
        noise = {m: dataclasses.replace(n, activity_high_v=calm) for m, n in noise.items()}
        whole = diagnose(table, paper_motor, profile, noise)
        # the growth bounded by the siblings' somewhere, and nowhere below the noise as measured
        m1 = whole["motor"] == 1
        excess = whole["input_activity_v"][m1] / ((1.0 + profile.range_margin) * calm)
        sigma = noise[1].sigmas(whole["input_activity_v"][m1])[0] * profile.noise_bands
        band = whole["speed_band_rad_s"][m1]
        if against:  # judged against the siblings' prediction, narrower by its noise's share
            band = band / np.where(np.isfinite(whole["speed_siblings_rad_s"][m1]), 0.8, 1.0)
        assert (band >= sigma * (1 - 1e-9)).all()
        assert (band < 0.9 * sigma * np.maximum(excess, 1.0) ** profile.conditions_growth).mean() > 0.05
    assert np.isfinite(whole["torque_siblings_nm"]).mean() > 0.5  # the stage ran
    if torque_spread:  # narrower than the deviations' growth somewhere, never below the torque's σ
        grown = diagnose(table, paper_motor, base, noise)
        ratio = whole["torque_band_nm"] / grown["torque_band_nm"]
        judged = np.isfinite(ratio)
        assert judged.mean() > 0.5 and (ratio[judged] <= 1.0 + 1e-12).all()
        assert (ratio[judged] < 0.9).mean() > 0.05
        a, e = whole["input_activity_v"], whole["pairing_error_rad_s"]
        for m in motors:
            rows_m = (whole["motor"] == m) & np.isfinite(whole["torque_band_nm"])
            sigma = noise[m].torque_vs_siblings.sigmas(a[rows_m], e[rows_m])
            assert (whole["torque_band_nm"][rows_m] >= profile.equation_bands * sigma * (1 - 1e-9)).all()
    if against:  # the prediction made, and the speed judged against it
        assert np.isfinite(whole["speed_siblings_rad_s"]).mean() > 0.3
        alone = diagnose(table, paper_motor, base, noise)
        moved = whole["omega_judged_rad_s"] != alone["omega_judged_rad_s"]
        assert moved.mean() > 0.3 and np.isnan(alone["speed_siblings_rad_s"]).all()
    if slow_siblings:  # the siblings' slow bands are narrower somewhere, and name what the own ones do not
        own = diagnose(table, paper_motor, dataclasses.replace(profile, slow_siblings=0.0), noise)
        named = (whole["state"] != 0) & (own["state"] == 0)
        assert named.sum() > 10
        assert whole["time_s"][named].min() > 22.0 + profile.conditions_siblings_s
    if step_sigmas:  # the model's jumps hold samples back that the volts' steps do not
        plain = diagnose(table, paper_motor, base, noise)
        held = plain["steady"] & ~whole["steady"]
        assert held.mean() > 0.01 and not (whole["steady"] & ~plain["steady"]).any()
    arrival = np.lexsort((whole["motor"], whole["time_s"]))
    stream = StreamingDiagnoser(paper_motor, profile, list(motors), noise)
    rng = np.random.default_rng(19)
    compared = (
        "state",
        "announced",
        "steady",
        "torque_siblings_nm",
        "speed_band_rad_s",
        "current_band_a",
        "speed_siblings_rad_s",
        "omega_judged_rad_s",
        "torque_band_nm",
    )
    got = {name: np.full(len(whole), np.nan) for name in compared}
    k = 0
    while k < arrival.size:
        size = int(rng.integers(1, 30))
        part = arrival[k : k + size]
        k += size
        batches = {}
        for m in np.unique(whole["motor"][part]).tolist():
            rows = part[whole["motor"][part] == m]
            if not (np.isfinite(whole["omega_rad_s"][rows]) | np.isfinite(whole["current_a"][rows])).any():
                continue
            rows = rows[np.isfinite(whole["omega_rad_s"][rows]) | np.isfinite(whole["current_a"][rows])]
            batches[m] = MotorBatch(
                whole["time_s"][rows],
                whole["voltage_v"][rows],
                whole["omega_rad_s"][rows],
                whole["current_a"][rows],
                whole["bus_voltage_v"][rows],
                command=whole["throttle"][rows],
                sensor_current_a=whole["esc_current_a"][rows],
                extra_flags=np.zeros(rows.size, dtype=np.int16),
            )
            batches[m] = (batches[m], rows)  # type: ignore[assignment]
        results = stream.update_motors({m: b for m, (b, _) in batches.items()})  # type: ignore[misc]
        for m, (_, rows) in batches.items():  # type: ignore[misc]
            for name in got:
                got[name][rows] = results[m][name]
    measured = np.isfinite(whole["omega_rad_s"]) | np.isfinite(whole["current_a"])
    for name in ("state", "announced", "steady"):
        np.testing.assert_array_equal(got[name][measured], whole[name][measured], err_msg=name)
    for name in compared[3:]:
        np.testing.assert_allclose(got[name][measured], whole[name][measured], rtol=1e-9, equal_nan=True)


def test_vehicle_check_row_by_row_equals_whole_arrays() -> None:
    rng = np.random.default_rng(3)
    n = 3000
    t = np.sort(rng.uniform(0.0, 30.0, n))
    m = rng.integers(1, 7, n)
    wm = rng.uniform(50.0, 900.0, n)
    w = wm * np.where(m <= 4, 0.85, 1.0) * rng.normal(1.0, 0.03, n)  # most motors off the model
    w[rng.random(n) < 0.02] = np.nan
    rule = VehicleCheckRule(min_samples=20, min_span_s=1.0)
    whole = VehicleCheck(rule, [1, 2, 3, 4, 5, 6], 100.0)
    want = whole._update_arrays(t, m, w, wm, np.isfinite(w) & (wm > 100.0))
    chunked = VehicleCheck(rule, [1, 2, 3, 4, 5, 6], 100.0)
    got, k = [], 0
    while k < n:
        size = int(rng.integers(1, 40))
        got.append(chunked.update(t[k : k + size], m[k : k + size], w[k : k + size], wm[k : k + size]))
        k += size
    np.testing.assert_array_equal(np.concatenate(got), want)
    assert set(want.tolist()) >= {1, 2}  # checking, then "does not fit"
    assert chunked.departures() == whole.departures()


def test_current_sum_row_by_row_equals_whole_arrays() -> None:
    rng = np.random.default_rng(4)
    n = 4000
    t = np.sort(rng.uniform(0.0, 40.0, n))
    m = rng.integers(1, 7, n)
    esc = rng.uniform(1.0, 6.0, n)
    esc[rng.random(n) < 0.05] = np.nan
    battery = np.where(t < 20.0, 21.0, 40.0) + rng.normal(0.0, 0.5, n)  # mis-scaled from 20 s on
    whole = CurrentSumCheck(PlausibilityRule(), range(1, 7))
    want = whole.update(t, m, esc, battery)
    chunked = CurrentSumCheck(PlausibilityRule(), range(1, 7))
    got, k = [], 0
    while k < n:
        size = int(rng.integers(1, 100))  # both the row-by-row and the vectorised sums
        got.append(chunked.update(t[k : k + size], m[k : k + size], esc[k : k + size], battery[k : k + size]))
        k += size
    np.testing.assert_array_equal(np.concatenate(got), want)
    assert want.any() and not want.all()
    np.testing.assert_array_equal(chunked.latest, whole.latest)


@pytest.mark.parametrize("profile_name", ["flight", "flight_vehicle"])
def test_a_log_diagnosed_in_parts_gives_what_it_gives_whole(paper_motor, monkeypatch, profile_name) -> None:
    """:func:`diagnose` takes a long log in consecutive parts (pipeline.LOG_PART samples, cut between
    instants), each motor's carry and the vehicle stage's taking one part on from the one before: the
    same results as the whole log in one part (codes equal, values to rounding). The F4.2 flight, a
    stall named, with lost samples and rows without a measurement, in parts of about 700 samples."""
    from mav_motor_health.diagnosis.pipeline import diagnose

    table = sources.read(FLIGHT)
    rng = np.random.default_rng(29)
    lost = rng.random(len(table)) < 0.03
    table = table.with_columns(
        omega_rad_s=np.where(lost, np.nan, table["omega_rad_s"]),
        current_a=np.where(lost | (rng.random(len(table)) < 0.02), np.nan, table["current_a"]),
    )
    profile = load_profile(profile_name)
    noise = None
    if profile.noise_bands > 0:
        profile = dataclasses.replace(profile, speed_against_siblings=0.0)
        noise = stage_noise(table.motors())
    whole = diagnose(table, paper_motor, profile, noise)  # (under 2 × LOG_PART: one part)
    monkeypatch.setattr(pipeline, "LOG_PART", 700)
    ordered = table.sorted_by_motor_time()
    rows = {int(m): np.flatnonzero(ordered["motor"] == m) for m in ordered.motors()}
    parts = pipeline._log_parts(ordered["time_s"], rows)
    assert len(parts) > 10 and all(sum(hi - lo for lo, hi in part.values()) > 500 for part in parts)
    got = diagnose(table, paper_motor, profile, noise)
    assert got.names == whole.names
    for name in whole.names:
        if name in (*DISCRETE, "vehicle_fit", "motor"):
            np.testing.assert_array_equal(got[name], whole[name], err_msg=name)
        else:
            np.testing.assert_allclose(
                got[name], whole[name], rtol=1e-9, atol=1e-9, equal_nan=True, err_msg=name
            )
    assert (whole["announced"] != MotorState.NORMAL).any() and (whole["state"] == MotorState.NO_DATA).any()
    if noise is not None:
        assert np.isfinite(whole["torque_siblings_nm"]).mean() > 0.5  # the stage ran, across the parts
