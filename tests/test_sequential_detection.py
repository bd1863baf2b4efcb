"""The sequential test (issue 17, item 2; diagnosis/detection.py): a CUSUM per fault direction on the
deviations in noise units, its threshold designed from a false-alarm rate."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.signal import lfilter

from mav_motor_health.config import dump_profile, load_profile
from mav_motor_health.diagnosis.detection import (
    CAPPED_DIRECTIONS,
    DIRECTIONS,
    SequentialCarry,
    SequentialRule,
    _lindley,
    average_run_length,
    design_threshold,
    direction_evidence,
    held_states,
    named_evidence,
    report_credit,
    sequential_alarms,
    with_slow_evidence,
)
from mav_motor_health.diagnosis.states import MotorState
from mav_motor_health.errors import ConfigError

DT_S, TAU_S = 0.02, 0.15


def healthy_noise(rng: np.random.Generator, n: int) -> np.ndarray:
    """Speed and current deviations of a healthy motor in σ: white noise through the rule's low-pass."""
    a = np.exp(-DT_S / TAU_S)
    z = lfilter([1 - a], [1, -a], rng.standard_normal((2, n)), axis=1)
    return z / z.std(axis=1, keepdims=True)


def run(rule: SequentialRule, z: np.ndarray, carry: SequentialCarry | None = None, start: int = 0):
    n = z.shape[1]
    evidence = direction_evidence(z[0], z[1], np.ones(n, dtype=bool), 4.5)
    return sequential_alarms(
        rule,
        (start + np.arange(n)) * DT_S,
        evidence,
        np.full(n, 2 * TAU_S),
        np.ones(n, dtype=bool),
        carry or SequentialCarry(),
        0.5,
        TAU_S,
    )


def test_the_threshold_grows_as_the_asked_rate_falls_and_the_chain_has_converged() -> None:
    rates = [1.0, 0.1, 0.01, 0.001]
    h = [design_threshold(r, 2.5, 0.3) for r in rates]
    assert all(a < b for a, b in zip(h, h[1:]))
    # the designed h gives (at least) the observations per false alarm asked for, a little less h does not
    needed = 4 * 8 * (3600 / 0.3) / 0.01
    assert average_run_length(h[2], 2.5) >= needed > average_run_length(0.97 * h[2], 2.5)
    # the Markov chain's answer does not hang on its resolution
    assert average_run_length(h[2], 2.5, 480) == pytest.approx(average_run_length(h[2], 2.5), rel=0.02)


def test_healthy_noise_raises_no_more_false_alarms_than_designed() -> None:
    """Ten hours of two healthy motors' low-passed Gaussian deviations at a rate asked high enough to be
    measured: the test stays within its design (conservatively: the low-passed signal is smoother than
    the independent observations the design counts), and not absurdly far below it."""
    rng = np.random.default_rng(170)
    rule = SequentialRule(false_alarms_per_100h=1e5, reference_sigmas=2.5)
    hours, motors = 10.0, 2
    alarms = 0
    for _ in range(motors):
        announced, _, _ = run(rule, healthy_noise(rng, int(hours * 3600 / DT_S)))
        alarms += int(np.sum((announced[1:] != 0) & (announced[:-1] == 0)))
    designed_per_motor_hour = 1e5 / 100 / 8
    measured = alarms / (motors * hours)
    assert 0.01 * designed_per_motor_hour < measured <= designed_per_motor_hour


@pytest.mark.parametrize(
    ("shift", "direction"),
    [
        ((0.0, 6.0), MotorState.F1_1),  # more current: friction
        ((-6.0, -6.0), MotorState.F4_1),  # slower and less current: an open transistor
        ((6.0, -6.0), MotorState.F3_1),  # faster with less current: a lighter propeller
    ],
)
def test_a_lasting_departure_is_named_in_its_direction_about_when_the_design_says(shift, direction) -> None:
    rng = np.random.default_rng(3)
    rule = SequentialRule(false_alarms_per_100h=1.0, reference_sigmas=2.5)
    n, onset = 3000, 1500
    z = healthy_noise(rng, n)
    z[:, onset:] += np.array(shift)[:, None]
    announced, _, _ = run(rule, z)
    assert not announced[:onset].any()
    named = np.flatnonzero(announced != 0)
    assert named.size and named[0] >= onset and announced[named[0]] == direction
    # h/(δ − k) observations of 2τ each, δ the evidence in σ (the deviation itself: the step is instant)
    delay = (named[0] - onset) * DT_S
    expected = rule.threshold(TAU_S) / (6.0 - rule.reference_sigmas) * 2 * TAU_S
    assert 0.3 * expected <= delay <= 3.0 * expected
    assert (announced[named[0] :] == direction).mean() > 0.95
    # a departure that ends is cleared once its evidence has run out: S falls by k per observation, so
    # an announcement lasts about as long again as the departure, times (δ − k)/k
    z = healthy_noise(rng, n)
    z[:, onset : onset + 200] += np.array(shift)[:, None]
    brief, _, _ = run(rule, z)
    assert (brief[onset : onset + 200] == direction).any()
    after = brief[onset + 200 + 3 * 200 :]  # (6 − 2.5)/2.5 = 1.4 times the 200 samples, and some
    assert after.size >= 500 and not after.any()


def test_any_split_into_calls_gives_the_same_alarms() -> None:
    rng = np.random.default_rng(11)
    rule = SequentialRule(false_alarms_per_100h=1e5, reference_sigmas=2.0)
    z = healthy_noise(rng, 20000)
    z[:, 8000:9000] += 3.0
    whole, whole_level, _ = run(rule, z)
    cuts = np.sort(rng.choice(np.arange(1, z.shape[1]), 60, replace=False))
    carry, parts, levels = SequentialCarry(), [], []
    for lo, hi in zip([0, *cuts], [*cuts, z.shape[1]]):
        got, lvl, carry = run(rule, z[:, lo:hi], carry, start=lo)
        parts.append(got)
        levels.append(lvl)
    np.testing.assert_array_equal(np.concatenate(parts), whole)
    np.testing.assert_allclose(np.concatenate(levels), whole_level, rtol=1e-9, atol=1e-9)
    assert (whole != 0).any()


def run_stream(rule, z, time_s, judged, carry=None):
    """:func:`run` on a stream of its own times and judged samples."""
    n = z.shape[1]
    evidence = direction_evidence(z[0], z[1], np.ones(n, dtype=bool), 4.5)
    return sequential_alarms(
        rule, time_s, evidence, np.full(n, 2 * TAU_S), judged, carry or SequentialCarry(), 0.5, TAU_S
    )


def test_a_lost_report_is_not_evidence() -> None:
    """10-Hz reports, one lost just before two samples 12 σ slow with less current (a dip the stream
    half missed): with the cap each sample counts at most one observation's worth per observation, and the
    sample after the lost report stands for the stream's 0.1 s, not the 0.2 s since the last report, so
    the pair is about two thirds of an observation and no alarm, as it is with no report lost."""
    rule = SequentialRule(false_alarms_per_100h=1.0, reference_sigmas=2.5, min_observations=1.0)
    rng = np.random.default_rng(21)
    t = np.arange(300) * 0.1
    z = 0.5 * rng.standard_normal((2, 300))
    z[:, 151:153] = -12.0
    kept = np.ones(300, dtype=bool)
    kept[150] = False  # the report before the dip never came
    announced, _, _ = run_stream(rule, z[:, kept], t[kept], np.ones(kept.sum(), dtype=bool))
    assert not announced.any()
    # four samples that deep are more than an observation: named, a lost report before them or not
    z[:, 153:155] = -12.0
    announced, _, _ = run_stream(rule, z[:, kept], t[kept], np.ones(kept.sum(), dtype=bool))
    assert (announced == MotorState.F4_1).any()


def test_an_unjudged_samples_time_is_not_lent_to_the_judged_one_after_it() -> None:
    """30-Hz reports; a sharp transient leaves three samples unjudged (0.1 s) and the two judged after it
    still 12 σ slow in their low-pass: they stand for their own 1/30 s each, two ninths of an observation
    at most, and are no alarm. Had they stood for the unjudged stretch's time too (as before), the first
    alone would have counted a third of an observation and more. Deep samples that are all judged are
    still named after one observation's worth of them, and the stretch's reports still count as reports
    (a lost one's time is spread as before)."""
    rule = SequentialRule(false_alarms_per_100h=1.0, reference_sigmas=2.5, min_observations=1.0)
    rng = np.random.default_rng(25)
    n = 600
    t = np.arange(n) / 30.0
    z = 0.5 * rng.standard_normal((2, n))
    z[:, 300:305] = -12.0
    judged = np.ones(n, dtype=bool)
    judged[300:303] = False
    announced, level, _ = run_stream(rule, z, t, judged)
    assert not announced.any()
    assert level[303] < level[304] < 0.25  # two samples of 1/30 s against an observation of 0.3 s
    # the same five judged: half an observation's worth, no alarm; a departure that lasts is named once
    # nine judged samples (0.3 s) have seen it, the three unjudged ones in it or not
    announced, _, _ = run_stream(rule, z, t, np.ones(n, dtype=bool))
    assert not announced.any()
    z[:, 305:315] = -12.0
    for mask, first in ((np.ones(n, dtype=bool), 308), (judged, 311)):
        announced, _, _ = run_stream(rule, z, t, mask)
        assert np.flatnonzero(announced == MotorState.F4_1)[0] == first


def test_each_report_stands_for_its_streams_interval() -> None:
    """Jittered 50-Hz reports with some lost: together they stand for the time they cover, none for more
    than about its stream's interval; reports in pairs (two per radio packet) each stand for 0.1 s."""
    rng = np.random.default_rng(23)
    t = np.cumsum(rng.uniform(0.015, 0.025, 5000))
    t = t[rng.random(t.size) > 0.03]
    credit, _ = report_credit(t, SequentialCarry(), 0.5)
    assert credit.sum() == pytest.approx(t[-1] - t[0], rel=0.01)
    assert credit.max() < 0.03 and np.diff(t).max() > 0.04
    pairs = np.repeat(np.arange(200) * 0.2, 2) + np.tile([0.0, 0.001], 200)
    credit, _ = report_credit(pairs, SequentialCarry(), 0.5)
    np.testing.assert_allclose(credit[20:], 0.1, rtol=0.01)


def test_the_report_credit_carries_across_calls() -> None:
    """Jittered 50-Hz reports with some lost and some samples not judged: any split into calls gives the
    alarms and levels of one call."""
    rng = np.random.default_rng(22)
    rule = SequentialRule(false_alarms_per_100h=1e5, reference_sigmas=2.0, min_observations=1.0)
    n = 20000
    t = np.cumsum(rng.uniform(0.015, 0.025, n))
    keep = rng.random(n) > 0.03
    t, z = t[keep], healthy_noise(rng, n)[:, keep]
    z[:, 8000:9000] += 3.0
    judged = rng.random(t.size) > 0.2
    whole, whole_level, _ = run_stream(rule, z, t, judged)
    cuts = np.sort(rng.choice(np.arange(1, t.size), 80, replace=False))
    carry, parts, levels = SequentialCarry(), [], []
    for lo, hi in zip([0, *cuts], [*cuts, t.size]):
        got, lvl, carry = run_stream(rule, z[:, lo:hi], t[lo:hi], judged[lo:hi], carry)
        parts.append(got)
        levels.append(lvl)
    np.testing.assert_array_equal(np.concatenate(parts), whole)
    np.testing.assert_allclose(np.concatenate(levels), whole_level, rtol=1e-9, atol=1e-9)
    assert (whole != 0).any()


def test_capped_evidence_reaching_h_exactly_is_an_alarm_however_the_samples_are_split() -> None:
    """Three 10-Hz samples beyond the cap are one observation's worth, exactly h: an alarm in one call and
    in any split into calls (the agent's batches), whatever the sums' rounding."""
    rule = SequentialRule(false_alarms_per_100h=1.0, reference_sigmas=2.5, min_observations=1.0)
    rng = np.random.default_rng(24)
    n = 400
    t = np.arange(n) * 0.1
    z = 0.3 * rng.standard_normal((2, n))
    for start in range(50, 350, 60):
        z[:, start : start + 3] = -15.0
    judged = np.ones(n, dtype=bool)
    whole, _, _ = run_stream(rule, z, t, judged)
    assert (np.flatnonzero(np.diff((whole == MotorState.F4_1).astype(int)) == 1).size) == 5
    for seed in range(20):
        cuts = np.sort(np.random.default_rng(seed).choice(np.arange(1, n), 40, replace=False))
        carry, parts = SequentialCarry(), []
        for lo, hi in zip([0, *cuts], [*cuts, n]):
            got, _, carry = run_stream(rule, z[:, lo:hi], t[lo:hi], judged[lo:hi], carry)
            parts.append(got)
        np.testing.assert_array_equal(np.concatenate(parts), whole)


def test_without_a_trusted_current_only_the_speed_directions_have_evidence() -> None:
    z = np.array([[-5.0, 5.0], [3.0, 3.0]])
    trusted = direction_evidence(z[0], z[1], np.array([True, True]), 4.5)
    alone = direction_evidence(z[0], z[1], np.array([False, False]), 4.5)
    slow, fast = DIRECTIONS.index(MotorState.SLOW), DIRECTIONS.index(MotorState.FAST)
    assert trusted[[slow, fast]].sum() == 0 and trusted.sum() > 0
    assert alone[slow, 0] == 5.0 and alone[fast, 1] == 5.0
    assert alone.sum() == 10.0
    # measured against the wider speed-only band (here 2.5 times the band: the tree's for speed alone),
    # the same departures are a 2-sigma one: a model error it cannot tell from a fault without the current
    wider = direction_evidence(z[0], z[1], np.array([False, False]), 4.5, z_omega_alone=z[0] / 2.5)
    assert wider[slow, 0] == 2.0 and wider[fast, 1] == 2.0
    np.testing.assert_array_equal(
        direction_evidence(z[0], z[1], np.array([True, True]), 4.5, z_omega_alone=z[0] / 2.5), trusted
    )


def test_the_profile_carries_the_test_and_refuses_it_without_noise_bands(tmp_path) -> None:
    profile = load_profile("flight_vehicle")
    assert profile.detection.on and profile.detection.false_alarms_per_100h == 1.0
    path = tmp_path / "again.toml"
    path.write_text(dump_profile(profile), encoding="utf-8")
    assert load_profile(path) == profile
    with pytest.raises(ConfigError, match="noise_bands"):
        dataclasses.replace(profile, noise_bands=0.0)
    bad = tmp_path / "bad.toml"
    bad.write_text(
        dump_profile(profile).replace("false_alarms_per_100h = 1.0", "false_alarms_per_100h = -1.0")
    )
    with pytest.raises(ConfigError) as err:
        load_profile(bad)
    assert "detection.false_alarms_per_100h" in str(err.value) and str(bad) in str(err.value)


def run_at(rule: SequentialRule, z: np.ndarray, dt_s: float) -> np.ndarray:
    """:func:`run` at another telemetry interval (the low-pass still TAU_S: one observation per 2τ)."""
    n = z.shape[1]
    announced, _, _ = sequential_alarms(
        rule,
        np.arange(n) * dt_s,
        direction_evidence(z[0], z[1], np.ones(n, dtype=bool), 4.5),
        np.full(n, 2 * TAU_S),
        np.ones(n, dtype=bool),
        SequentialCarry(),
        0.5,
        TAU_S,
    )
    return announced


def test_a_lone_outlier_is_no_alarm_at_any_rate_once_an_alarm_needs_one_observation() -> None:
    """10-Hz telemetry: one sample 13 σ or two 12 σ slow with less current (a command that dipped between
    two logged ones) is an F4.1 alarm without the floor, none with it; a departure that deep and lasting is
    still named, no sooner than one observation (2τ) and within a few."""
    loose = SequentialRule(false_alarms_per_100h=1.0, reference_sigmas=2.5)
    floored = dataclasses.replace(loose, min_observations=1.0)
    h = loose.threshold(TAU_S)
    assert floored.evidence_cap(h) == pytest.approx(2.5 + h) and loose.evidence_cap(h) == np.inf
    dt_s = 0.1
    rng = np.random.default_rng(18)
    for spikes, depth in ((1, 13.0), (2, 12.0)):
        z = 0.5 * rng.standard_normal((2, 300))
        z[:, 150 : 150 + spikes] = -depth
        assert (run_at(loose, z, dt_s) == MotorState.F4_1).any()
        assert not run_at(floored, z, dt_s).any()
    for dt in (0.1, 0.02, 0.005):  # 10, 50 and 200 Hz
        n, onset = int(6.0 / dt), int(3.0 / dt)
        z = 0.5 * rng.standard_normal((2, n))
        z[:, onset:] -= 12.0
        named = np.flatnonzero(run_at(floored, z, dt) == MotorState.F4_1)
        assert named.size and named[0] >= onset
        delay = (named[0] - onset) * dt
        assert 2 * TAU_S - dt <= delay <= 2 * 2 * TAU_S
        # without the floor, 12 σ at 200 Hz is named in a few samples: the floor's cost, one observation
        quick = np.flatnonzero(run_at(loose, z, dt) == MotorState.F4_1)
        assert quick[0] <= named[0]


def test_the_floor_spares_a_runaway_motor() -> None:
    """A lost propeller's motor runs away (faster, less current) and leaves the judged range within one
    observation: its few samples are named with the floor as without it, while the same few samples the
    other way (slower, less current: F4.1, a lasting direction) are capped and named by nothing."""
    loose = SequentialRule(false_alarms_per_100h=1.0, reference_sigmas=2.5)
    floored = dataclasses.replace(loose, min_observations=1.0)
    assert MotorState.F3_1 not in CAPPED_DIRECTIONS and MotorState.F4_1 in CAPPED_DIRECTIONS
    rng = np.random.default_rng(19)
    z = 0.5 * rng.standard_normal((2, 300))
    z[0, 150:152], z[1, 150:152] = 12.0, -12.0  # two 10-Hz samples, then out of the judged range
    z[:, 152:] = np.nan
    runaway = run_at(floored, z, 0.1)
    assert (runaway == MotorState.F3_1).any()
    assert np.array_equal(runaway, run_at(loose, z, 0.1))
    z[0, 150:152] = -12.0  # slower with less current: the lasting direction, capped
    assert (run_at(loose, z, 0.1) == MotorState.F4_1).any()
    assert not run_at(floored, z, 0.1).any()


def test_the_floor_is_validated_and_written_back(tmp_path) -> None:
    shipped = load_profile("flight_vehicle")
    assert shipped.detection.min_observations == 1.0  # one observation (docs/flight.md: measured)
    profile = dataclasses.replace(
        shipped, detection=dataclasses.replace(shipped.detection, min_observations=2.5)
    )
    path = tmp_path / "floored.toml"
    path.write_text(dump_profile(profile), encoding="utf-8")
    assert "min_observations = 2.5" in path.read_text(encoding="utf-8")
    assert load_profile(path) == profile
    with pytest.raises(ConfigError, match="min_observations"):
        SequentialRule(false_alarms_per_100h=1.0, min_observations=-1.0)


def test_a_direction_gains_only_on_samples_the_tree_named_that_way() -> None:
    """A healthy motor's model off by 3 σ in speed (slower), 10 s at 30 Hz, every sample inside the
    bands (the tree reads NORMAL): the sum of sub-band departures just above the reference reaches h
    in about 1.4 s without the tree's names, and never with them. A fault 5 σ deep named on every
    other sample (straddling the band) is still announced within a second (0.7 s), later than one
    named on every sample (0.4 s)."""
    rule = SequentialRule(false_alarms_per_100h=1.0, reference_sigmas=2.5, min_observations=1.0)
    rng = np.random.default_rng(26)
    n = 3000
    t = np.arange(n) / 30.0
    z = 0.3 * rng.standard_normal((2, n))
    z[0] -= 3.2  # slower than the model, the current as modelled: the F4.1 direction
    evidence = direction_evidence(z[0], z[1], np.ones(n, dtype=bool), 4.5)
    judged = np.ones(n, dtype=bool)

    def alarms(ev: np.ndarray) -> np.ndarray:
        announced, _, _ = sequential_alarms(
            rule, t, ev, np.full(n, 2 * TAU_S), judged, SequentialCarry(), 0.5, TAU_S
        )
        return np.flatnonzero(announced == MotorState.F4_1)

    assert alarms(evidence).size  # every sub-band sample adds: announced
    normal = np.full(n, int(MotorState.NORMAL), dtype=np.int8)
    assert alarms(named_evidence(evidence, normal, 2.5)).size == 0
    # a fault 5 σ deep: named on every sample, or on every other one (the rest just inside the band)
    z[0, 1500:] = -5.0
    z[0, 1501::2] = -4.4
    evidence = direction_evidence(z[0], z[1], np.ones(n, dtype=bool), 4.5)
    every = normal.copy()
    every[1500:] = MotorState.F4_1
    other = normal.copy()
    other[1500::2] = MotorState.F4_1
    first_every = alarms(named_evidence(evidence, every, 2.5))[0]
    first_other = alarms(named_evidence(evidence, other, 2.5))[0]
    assert 1500 < first_every < first_other < 1500 + 30  # both within a second


def test_once_announced_a_sample_departing_that_way_by_the_hold_reads_as_the_fault() -> None:
    """``hold_sigmas`` (detection.py, "Once announced"): a judged sample the tree read NORMAL reads as
    the direction announced at it where its departure that way is at least the hold; not where nothing
    is announced, not where it departs another way, not a sample the tree named otherwise or did not
    judge."""
    f41, f11 = DIRECTIONS.index(MotorState.F4_1), DIRECTIONS.index(MotorState.F1_1)
    n = 8
    evidence = np.zeros((len(DIRECTIONS), n))
    evidence[f41] = [3.0, 3.0, 2.4, 2.5, 3.0, 0.0, 3.0, 3.0]
    evidence[f11, 5] = 4.0  # departs the other way
    alarms = np.full(n, int(MotorState.F4_1), dtype=np.int8)
    alarms[1] = MotorState.NORMAL  # nothing announced there
    state = np.full(n, int(MotorState.NORMAL), dtype=np.int8)
    state[6] = MotorState.F1_1  # the tree named something else
    judged = np.ones(n, dtype=bool)
    judged[7] = False
    held, toward = held_states(state, alarms, evidence, judged, 2.5)
    np.testing.assert_array_equal(held, [True, False, False, True, True, False, False, False])
    np.testing.assert_array_equal(toward, [3.0, 0.0, 2.4, 2.5, 3.0, 0.0, 3.0, 3.0])
    # rows of motors, as the rule gives them
    held2, _ = held_states(
        state[None].repeat(2, 0),
        alarms[None].repeat(2, 0),
        evidence[:, None].repeat(2, 1),
        judged[None].repeat(2, 0),
        2.5,
    )
    np.testing.assert_array_equal(held2, np.stack([held, held]))
    with pytest.raises(ConfigError, match="hold_sigmas"):
        SequentialRule(false_alarms_per_100h=1.0, hold_sigmas=-1.0)


def test_the_hold_is_the_reference_in_the_shipped_profile_and_written_back(tmp_path) -> None:
    shipped = load_profile("flight_vehicle")
    assert shipped.detection.hold_sigmas == shipped.detection.reference_sigmas  # no new number
    path = tmp_path / "held.toml"
    path.write_text(dump_profile(shipped), encoding="utf-8")
    assert load_profile(path) == shipped


def test_the_slow_looks_evidence_counts_for_the_fewer_observations_it_gives() -> None:
    """``with_slow_evidence`` (detection.py, "The slow look's evidence"): where the slow look named a
    sample, its direction's evidence is the larger of the fast one and k + (y_slow − k)/slow_factor; other
    directions, samples it did not name and a profile without a slow look keep theirs."""
    f41, f11 = DIRECTIONS.index(MotorState.F4_1), DIRECTIONS.index(MotorState.F1_1)
    n = 4
    evidence = np.zeros((len(DIRECTIONS), n))
    evidence[f41] = [1.0, 2.5, 4.0, 1.0]
    evidence[f11] = [0.5, 0.5, 0.5, 0.5]
    state = np.array([MotorState.F4_1, MotorState.F4_1, MotorState.F4_1, MotorState.NORMAL], dtype=np.int8)
    slow = np.array([10.5, np.nan, 6.5, 10.5])  # the last: not named by the slow look (state NORMAL)
    out = with_slow_evidence(evidence, state, slow, 2.5, 4.0)
    np.testing.assert_allclose(out[f41], [4.5, 2.5, 4.0, 1.0])  # 2.5 + 8/4; none; the fast 4 > 3.5; none
    np.testing.assert_array_equal(out[f11], evidence[f11])
    np.testing.assert_array_equal(with_slow_evidence(evidence, state, None, 2.5, 4.0), evidence)
    np.testing.assert_array_equal(with_slow_evidence(evidence, state, slow, 2.5, 0.0), evidence)


def test_the_closed_form_sums_and_alarms_are_the_step_by_step_cusums() -> None:
    """``S ← max(0, S + step)``, an alarm from S ≥ h until S is back at 0, from a carried S and alarm:
    the closed form over whole rows (issue 18: one running count and one running maximum) against the
    recurrence sample by sample, rows that start alarmed or not, at 0 or not, some crossing h often."""
    rng = np.random.default_rng(23)
    h = 3.0
    steps = rng.normal(-0.4, 1.2, (2, 5, 400))
    steps[:, :, 50:60] = 0.0  # exactly 0: stays where it is
    start_sum = np.array([[0.0, 2.0, 5.0, 0.0, 1.0], [4.0, 0.0, 0.5, 3.0, 0.0]])
    start_alarm = np.array([[False, True, True, False, True], [True, False, False, True, True]])
    sums, alarms = _lindley(steps, start_sum, start_alarm, h)
    for d in range(2):
        for r in range(5):
            s, alarm = start_sum[d, r], bool(start_alarm[d, r])
            for n in range(steps.shape[2]):
                s = max(0.0, s + steps[d, r, n])
                alarm = (alarm or s >= h) and s > 0.0
                assert sums[d, r, n] == pytest.approx(s, abs=1e-9)
                assert alarms[d, r, n] == alarm, (d, r, n)
    assert alarms.any() and not alarms.all() and (sums == 0).any()


def test_an_unknown_departure_as_brief_as_a_logged_commands_gap_is_no_alarm() -> None:
    """Faster with more current (UNKNOWN: none of the five faults; a command the log missed between two
    commands logged at 10 Hz, at a translation's braking) for 0.14 s at 141 Hz, 12-16 σ: an alarm without
    the floor, none with it; lasting, it is still named, after one observation (2τ)."""
    loose = SequentialRule(false_alarms_per_100h=1.0, reference_sigmas=2.5)
    floored = dataclasses.replace(loose, min_observations=1.0)
    assert MotorState.UNKNOWN in CAPPED_DIRECTIONS
    dt = 1 / 141.0
    rng = np.random.default_rng(20)
    n, onset = int(6.0 / dt), int(3.0 / dt)
    z = 0.5 * rng.standard_normal((2, n))
    brief = np.s_[onset : onset + int(0.14 / dt)]
    z[0, brief], z[1, brief] = 16.0, 12.0
    assert (run_at(loose, z, dt) == MotorState.UNKNOWN).any()
    assert not run_at(floored, z, dt).any()
    z[:, onset:] = 0.5 * rng.standard_normal((2, n - onset)) + np.array([[16.0], [12.0]])
    named = np.flatnonzero(run_at(floored, z, dt) == MotorState.UNKNOWN)
    assert named.size and 2 * TAU_S - dt <= (named[0] - onset) * dt <= 2 * 2 * TAU_S
