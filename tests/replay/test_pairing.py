"""One pairing of samples with commands and context (telemetry/assemble.py ``HeldValues``), for replay's
whole log and the live agent's batches.

Replay's rule (docs/replay.md, "What is read from each log"): previous-value hold by time, the last value
at or before the sample, none older than 1 s for commands, 5 s for context. ``HeldValues`` is that rule
with carried state: fed a whole log in one call it is the previous-value hold replay always used
(``_logscan.hold_previous``); fed the same stream in parts split anywhere, it gives the same values.
(The MAVLink messages both ways, .tlog and live batches: tests/replay/test_mavlink_messages.py.)
"""

from __future__ import annotations

import numpy as np
import pytest

from mav_motor_health.telemetry._logscan import hold_previous
from mav_motor_health.telemetry.assemble import COMMAND_MAX_AGE_S, HeldValues, held


def random_series(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Source times on a coarse grid (ties among them), gaps longer than the age limits, NaN values."""
    t = np.cumsum(rng.choice([0.0, 0.01, 0.02, 0.3, 1.2, 6.0], size=n, p=[0.1, 0.4, 0.3, 0.1, 0.07, 0.03]))
    v = rng.normal(size=n)
    v[rng.random(n) < 0.1] = np.nan
    return t, v


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("max_age_s", [COMMAND_MAX_AGE_S, 5.0])
def test_whole_it_is_the_previous_value_hold_replay_used(seed: int, max_age_s: float) -> None:
    """On one part (a log), values and ages are hold_previous's exactly, sources sorted or not."""
    rng = np.random.default_rng(seed)
    t, v = random_series(rng, 400)
    targets = np.sort(rng.uniform(-1.0, t[-1] + 8.0, 700))
    targets[:50] = rng.choice(t, 50)  # at a source's very time
    expected = hold_previous(t, v, targets, max_age_s)
    expected_age = targets - hold_previous(t, t, targets, max_age_s)
    value, age = held((t, v), targets, max_age_s)
    np.testing.assert_array_equal(value, expected)
    np.testing.assert_array_equal(age, expected_age)
    assert np.isnan(value).any() and np.isfinite(value).any()
    order = rng.permutation(len(t))  # sources out of time order: sorted stably, as replay sorted them
    shuffled = held((t[order], v[order]), targets, max_age_s)
    stable = np.argsort(t[order], kind="stable")
    t_sorted, v_sorted = t[order][stable], v[order][stable]
    np.testing.assert_array_equal(shuffled[0], hold_previous(t_sorted, v_sorted, targets, max_age_s))


def stream(rng: np.random.Generator, signals: int) -> tuple[np.ndarray, ...]:
    """A time-ordered stream of source rows (a value per signal, some absent) and targets; at the same time
    a source comes before a target (as a message before the ESC message it is paired with)."""
    t, _ = random_series(rng, 300)
    values = rng.normal(size=(len(t), signals))
    present = rng.random((len(t), signals)) < 0.6
    targets = np.sort(np.concatenate([rng.uniform(0, t[-1] + 7.0, 500), rng.choice(t, 60)]))
    signal = rng.integers(0, signals, len(targets))
    return t, values, present, targets, signal


def split_at(cuts: np.ndarray, t: np.ndarray, targets: np.ndarray) -> list[tuple[slice, slice]]:
    """The stream cut at the times ``cuts``: per part, its sources and its targets. A cut at a time shared
    by a source and a target falls after the source (the source comes first in the stream)."""
    src = np.searchsorted(t, cuts, side="right")
    tgt = np.searchsorted(targets, cuts, side="right")
    edges_src, edges_tgt = [0, *src.tolist(), len(t)], [0, *tgt.tolist(), len(targets)]
    return [
        (slice(a, b), slice(c, d)) for a, b, c, d in zip(edges_src, edges_src[1:], edges_tgt, edges_tgt[1:])
    ]


@pytest.mark.parametrize("seed", range(4))
def test_in_parts_split_anywhere_it_gives_what_the_whole_gives(seed: int) -> None:
    """Several signals (motors' commands: a row per message, absent where it carries none) fed whole or in
    parts cut anywhere — between a source and the target that uses it, in a gap longer than the age
    limit, at a shared time — give the same values and ages; each signal is its own previous-value hold."""
    rng = np.random.default_rng(100 + seed)
    t, values, present, targets, signal = stream(rng, signals=6)
    whole = HeldValues(6, COMMAND_MAX_AGE_S).hold(t, values, targets, signal, present)
    for k in range(6):  # each signal: hold_previous over its own values
        mine = signal == k
        expected = hold_previous(t[present[:, k]], values[present[:, k], k], targets[mine], COMMAND_MAX_AGE_S)
        np.testing.assert_array_equal(whole[0][mine], expected)
    assert np.isnan(whole[0]).any() and np.isfinite(whole[0]).any()
    cut_sets = [
        np.sort(rng.choice(np.concatenate([t, targets]), size=size, replace=False)) for size in (1, 5, 40)
    ]
    cut_sets.append(np.unique(np.concatenate([t, targets])))  # every source and target alone
    for cuts in cut_sets:
        pairing = HeldValues(6, COMMAND_MAX_AGE_S)
        parts = [
            pairing.hold(t[s], values[s], targets[g], signal[g], present[s])
            for s, g in split_at(cuts, t, targets)
        ]
        for got, want in zip((np.concatenate([p[i] for p in parts]) for i in range(2)), whole):
            np.testing.assert_array_equal(got, want)


def test_every_signal_at_every_target_and_the_carried_values() -> None:
    """``signal`` None: a column per signal (the battery's voltage and current); NaN is a value (a "no
    reading" is the latest word); what is carried is each signal's last value and its time."""
    pairing = HeldValues(2, 5.0)
    t = np.array([0.0, 1.0, 2.0])
    v = np.array([[15.0, 8.0], [14.9, np.nan], [np.nan, 7.0]])
    value, age = pairing.hold(t, v, np.array([-0.5, 1.0, 1.5]))
    np.testing.assert_array_equal(value, [[np.nan, np.nan], [14.9, np.nan], [14.9, np.nan]])
    np.testing.assert_array_equal(age, [[np.nan, np.nan], [0.0, 0.0], [0.5, 0.5]])
    np.testing.assert_array_equal(pairing.time_s, [2.0, 2.0])
    np.testing.assert_array_equal(pairing.value, [np.nan, 7.0])
    value, age = pairing.hold(np.zeros(0), np.zeros((0, 2)), np.array([6.5, 7.5]))  # nothing new
    np.testing.assert_array_equal(value, [[np.nan, 7.0], [np.nan, np.nan]])  # 7.5 s: older than 5 s
    np.testing.assert_array_equal(age, [[4.5, 4.5], [np.nan, np.nan]])


# -- each sample's pairing uncertainty (``pairing_s``), replay's table and the live agent alike ------------
def test_a_freshly_paired_sample_has_a_small_pairing_and_a_stale_one_a_large_one() -> None:
    """Samples with their own time (a .bin's ESC records) and commands at 10 Hz: each sample's ``pairing_s``
    is its held command's age: a few ms just after a command, ~90 ms just before the next, more once the
    commands stop; stamped by their message (a .tlog's), the interval of the motor's messages counts too
    (stale rows — a repeated packet, no speed — included), the larger of the two."""
    from pathlib import Path

    from mav_motor_health.telemetry.assemble import EscSamples, motor_table

    t = np.round(np.arange(0.0, 2.0, 0.01), 6) + 0.002  # 100 Hz ESC samples, two motors
    n = t.size
    esc = EscSamples(
        np.repeat(t, 2),
        np.tile([0, 1], n),
        np.full(2 * n, 600.0),
        np.full(2 * n, 3.0),
        np.full(2 * n, 12.0),
    )
    command_t = np.arange(0.0, 1.45, 0.1)  # 10 Hz, none after 1.4 s
    commands = {m: (command_t, np.full(command_t.size, 0.5)) for m in (1, 2)}
    own = motor_table(Path("x.bin"), esc, {0: 1, 1: 2}, commands, {}, {})
    m1 = own.for_motor(1)
    fresh = np.isclose(m1["time_s"] % 0.1, 0.002)  # 2 ms after a command
    stale = np.isclose(m1["time_s"] % 0.1, 0.092)  # 92 ms after one
    assert fresh.sum() > 5 and stale.sum() > 5
    np.testing.assert_allclose(m1["pairing_s"][fresh & (m1["time_s"] < 1.4)], 0.002, atol=1e-9)
    np.testing.assert_allclose(m1["pairing_s"][stale & (m1["time_s"] < 1.4)], 0.092, atol=1e-9)
    late = m1["time_s"] > 1.4
    np.testing.assert_allclose(m1["pairing_s"][late], m1["time_s"][late] - 1.4, atol=1e-9)
    assert own.meta["pairing_s"] == pytest.approx(np.percentile(own["pairing_s"], 95))
    # stamped by their message: at least the interval of the motor's messages (10 ms), a first 0
    tlog = motor_table(Path("x.tlog"), esc, {0: 1, 1: 2}, commands, {}, {"sample_time_uncertainty_s": 0.01})
    m1 = tlog.for_motor(1)
    np.testing.assert_allclose(m1["pairing_s"][1:], np.maximum(own.for_motor(1)["pairing_s"][1:], 0.01))
    assert m1["pairing_s"][0] == pytest.approx(0.002)  # its command's age: no message before it
    # the command's own age is a column of its own (a stall is weighed against it, diagnosis/stall.py)
    np.testing.assert_allclose(m1["command_age_s"], own.for_motor(1)["pairing_s"], atol=1e-9)
    # a stale row (repeated packet: no speed or current) is a message all the same
    gappy = EscSamples(
        esc.time_s[::2],
        esc.slot[::2],
        esc.omega_rad_s[::2].copy(),
        esc.current_a[::2].copy(),
        esc.bus_voltage_v[::2],
    )
    gappy.omega_rad_s[10:20] = np.nan
    gappy.current_a[10:20] = np.nan
    table = motor_table(Path("y.tlog"), gappy, {0: 1}, commands, {}, {"sample_time_uncertainty_s": 0.01})
    assert table["pairing_s"][20] == pytest.approx(0.01)


def test_message_intervals_in_parts_are_the_whole() -> None:
    """The interval of a signal's entries (a motor's ESC messages), causal: the mean over the last second
    (the time since the entry before the window's first, over the window's entries); with no window, the
    time since the entry before. Parts split anywhere give the whole's values; entries of several signals
    interleaved, ties (several messages with one stamp) kept in order."""
    from mav_motor_health.telemetry.assemble import MessageIntervals

    rng = np.random.default_rng(7)
    t = np.sort(np.round(rng.uniform(0, 10, 400), 2))  # ties among them
    signal = rng.integers(0, 6, t.size)
    untied = np.sort(rng.uniform(0, 10, 400))
    plain = MessageIntervals(6, window_s=0.0).since_previous(untied, signal)
    whole = MessageIntervals(6).since_previous(t, signal)
    for k in range(6):
        mine = signal == k
        np.testing.assert_allclose(plain[mine][1:], np.diff(untied[mine]))
        assert np.isnan(plain[mine][0]) and np.isnan(whole[mine][0])
        times = t[mine]
        for i in range(1, times.size):  # brute force: the mean of the intervals ending in the window
            first = max(int(np.searchsorted(times, times[i] - 1.0, side="left")), 0)
            first = min(first, i)
            expected = (times[i] - times[first - 1]) / (i - first + 1) if first else (times[i] - times[0]) / i
            assert whole[mine][i] == pytest.approx(expected, abs=1e-12)
    for cuts in ([1], [5, 17, 200], list(range(1, t.size))):
        for window_s, times, want in ((1.0, t, whole), (0.0, untied, plain)):
            parts = MessageIntervals(6, window_s)
            got = np.concatenate(
                [parts.since_previous(times[a:b], signal[a:b]) for a, b in zip([0, *cuts], [*cuts, t.size])]
            )
            np.testing.assert_array_equal(got, want)


def test_the_guards_window_is_the_oldest_command_a_source_pairs() -> None:
    from mav_motor_health.diagnosis.pairing import PAIRING_WINDOW_S
    from mav_motor_health.telemetry.assemble import COMMAND_MAX_AGE_S

    assert PAIRING_WINDOW_S == COMMAND_MAX_AGE_S


def excursions_brute_force(t: np.ndarray, v: np.ndarray, samples: np.ndarray) -> np.ndarray:
    """Per sample: how far the values since the sample before (times in (previous, this]) went beyond the
    values held at the two samples (the last value at or before each), 0 where they did not."""
    given = np.isfinite(v)
    t, v = t[given], v[given]
    out = np.zeros(samples.size)
    for k, s in enumerate(samples):
        if k == 0:
            continue
        prev = samples[k - 1]
        between = v[(t > prev) & (t <= s)]
        before, now = v[t <= prev], v[t <= s]
        if between.size == 0 or before.size == 0:
            continue
        lo, hi = sorted((before[-1], now[-1]))
        out[k] = max(between.max() - hi, lo - between.min(), 0.0)
    return out


@pytest.mark.parametrize("seed", range(4))
def test_command_excursions_whole_and_in_parts_are_the_brute_force(seed: int) -> None:
    """``CommandExcursions``: how far a motor's commands between two of its samples went beyond the two held
    commands (a dip and back between two ESC reports). Whole, it is the brute force's (a value at a sample's
    very time counts for that sample); parts cut anywhere but at a value's very time give the same."""
    from mav_motor_health.telemetry.assemble import CommandExcursions

    rng = np.random.default_rng(200 + seed)
    t = np.cumsum(rng.choice([0.0, 0.02, 0.05], size=300, p=[0.1, 0.6, 0.3]))
    v = rng.normal(size=t.size)
    v[rng.random(t.size) < 0.1] = np.nan
    samples = np.unique(np.concatenate([rng.uniform(-0.5, t[-1] + 0.5, 80), rng.choice(t, 10)]))
    expected = excursions_brute_force(t, v, samples)
    whole = CommandExcursions(1).beyond_held(t, v, np.zeros(samples.size, int), samples)
    np.testing.assert_allclose(whole, expected, rtol=0, atol=1e-15)
    assert (whole > 0).sum() > 20 and (whole == 0).sum() > 5  # dips and none both present
    times = np.unique(np.concatenate([t, samples]))
    free = times[~np.isin(times, t)]  # cut where no value is stamped (a sample's time, or none)
    for cuts in (rng.choice(free, 1), np.sort(rng.choice(free, 15, replace=False)), free):
        parts = CommandExcursions(1)
        got = []
        for lo, hi in zip([-np.inf, *cuts], [*cuts, np.inf]):
            vals = (t > lo) & (t <= hi)
            sam = (samples > lo) & (samples <= hi)
            got.append(parts.beyond_held(t[vals], v[vals], np.zeros(sam.sum(), int), samples[sam]))
        np.testing.assert_allclose(np.concatenate(got), expected, rtol=0, atol=1e-15)
    # a dip between two samples whose held commands are alike: the dip's depth
    dip = CommandExcursions(1).beyond_held(
        [0.0, 0.02, 0.04, 0.06], [0.5, 0.3, 0.4, 0.5], [0, 0], [0.01, 0.09]
    )
    np.testing.assert_allclose(dip, [0.0, 0.2])


@pytest.mark.parametrize("seed", range(6))
def test_command_excursions_of_every_motor_in_one_call_are_each_motors_brute_force(seed: int) -> None:
    """The live agent hands ``CommandExcursions`` every motor's commands (a column each, NaN where a
    message carries none) and samples (in message order, motors interleaved) of a batch in one call: each
    motor's excursions are its own brute force's, whole and in batches cut anywhere but at a command's very
    time, motors with commands but no sample in a batch included (they carry them to their next sample)."""
    from mav_motor_health.telemetry.assemble import CommandExcursions

    rng = np.random.default_rng(300 + seed)
    motors = int(rng.integers(2, 9))
    t = np.cumsum(rng.choice([0.0, 0.02, 0.05], size=200, p=[0.1, 0.6, 0.3]))
    v = rng.normal(size=(t.size, motors))
    v[rng.random(v.shape) < rng.uniform(0.05, 0.6)] = np.nan
    sample_t = np.sort(np.concatenate([rng.uniform(-0.3, t[-1] + 0.3, 150), rng.choice(t, 15)]))
    sample_m = rng.integers(0, motors, sample_t.size)
    keep = np.ones(sample_t.size, bool)  # one sample per motor and time, as an ESC message gives
    for m in range(motors):
        rows = np.flatnonzero(sample_m == m)
        keep[rows[1:][np.diff(sample_t[rows]) == 0]] = False
    sample_t, sample_m = sample_t[keep], sample_m[keep]
    expected = np.zeros(sample_t.size)
    for m in range(motors):
        rows = sample_m == m
        expected[rows] = excursions_brute_force(t, v[:, m], sample_t[rows])
    assert (expected > 0).sum() > 20
    times = np.unique(np.concatenate([t, sample_t]))
    free = times[~np.isin(times, t)]
    for cuts in ([], np.sort(rng.choice(free, 25, replace=False)), free):
        parts = CommandExcursions(motors)
        got = []
        for lo, hi in zip([-np.inf, *cuts], [*cuts, np.inf]):
            vals = (t > lo) & (t <= hi)
            sam = np.flatnonzero((sample_t > lo) & (sample_t <= hi))
            got.append(parts.beyond_held(t[vals], v[vals], sample_m[sam], sample_t[sam]))
        np.testing.assert_allclose(np.concatenate(got), expected, rtol=0, atol=1e-15)
