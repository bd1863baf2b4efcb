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
