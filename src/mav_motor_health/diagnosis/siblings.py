"""Each motor's torque balance against its siblings' (issue 17): the vehicle stage of the pipeline, between
the rules that compare each motor with its model and the rule that judges the torque balance
(:mod:`.rules.equations`).

Why. What moves the torque balance ``r_T`` of a healthy motor moves it on all six alike: an ESC that
reports its input current adds the duty ripple's copper loss, ``V·σ_d²/R``, and the ripple grows with
the air (``benchmarks/bench_input_ripple.py``); the one motor model shared by six motors leaves the same
error at an operating point the identification flight did not cover; the battery and the air are the
same for all. Friction (F1.1) or a lighter propeller (F3.1) moves one motor. So where the vehicle's
noise has it, the torque is judged as ``r_T`` minus the median of the other motors' ``r_T``, against
that difference's own healthy noise (``[noise.N] torque_vs_siblings_nm ...``, measured by
identification like the torque's own, :mod:`.noise`). What it gained and cost on the held-out worlds:
docs/flight.md, "The torque balance against its siblings".

The reference of a sample of motor m at time t is the median of the other motors' latest residuals that
reached the core before it, in the order the live agent receives samples (time, then motor number: a
sibling's sample of the same instant counts where its number is lower) and are at most the sample's own
low-pass time old (``frame.low_pass_s``: an older value is not of the same air). Where fewer than three
of the vehicle's other motors have one (all but one where it has fewer than five others), there is none
(NaN) and the torque is not judged there: a median of three holds against one sibling that departs (a
faulty motor, or one the model is carried far beyond its identified speeds for). Replay calls
:meth:`VehicleStage.references` once with every motor's whole log; the live agent with each batch, the
latest value of every motor carried between calls: both give the same references.

**Beyond the identified speeds.** What the siblings share is the same only where they turn alike: the
model's error depends on the speed, and beyond the speeds the identification flight covered it is an
extrapolation that grows with the distance. On held-out world 1018 in gusty air the vehicle flew for
15 s with three motors saturated at full command (422 rad/s, a third beyond their identified top) and three
at 0.77 (343 rad/s); the saturated three's torque residuals (0.065 N·m) were the median of a motor at
343 rad/s whose own read 0.02, and it was named F3.1 (docs/flight.md). So a sibling's value whose model
speed lay beyond its identified range (widened by the profile's ``range_margin``, as the rules judge,
:mod:`.rules.judged`) is a reference only for a motor within :attr:`VehicleStage.alike` (the same
``range_margin``, as a share of the motor's speed) of its speed; in its range it is one at any speed.
The motors compensating a failed one run beyond their range together, at one speed, and stay each
other's references.

**A sibling in its own step's transient** (the torque). A sibling's torque residual is no reference
where it waits after its own input step (within the balance rule's ``settle_s``) and departs from its
offset by more than the band it is judged in there (``equation_bands`` times its torque σ at the sample's
activity and pairing, widened after a step as identification measured, not grown by the air): the
low-passed balance then carries that step's transient (the inertia term of a spin-up or run-down the
low-pass smears, an input current read through a duty that just jumped), not the air all six share. On
development world 3, with a damaged propeller on motor 3, motors 1 and 6 ran down from a command of 0.74
to 0.23 in the compensation and read +1.1 to +1.6 N·m for half a second (their hover torque is about
0.19 N·m), while the two motors at a steady command read −0.03; beyond the identified speeds, the faulty
motor and the one at idle were no reference for them, so the two running down were two of their three
siblings, the median +1.1 N·m: motor 2 read F3.1 on 43 of its judged samples after onset, and with the
``step_over_changes`` option on, which counts more of them settled, it was announced (docs/flight.md,
"... a sibling in its own step's transient"). Every sibling in its wait left out instead would leave a
motor without three references whenever the air keeps all of them stepping, and there its torque is not
read (development world 4's friction in gusty air, announced 8 s after onset, was then not announced in a
30-s flight); a sibling within its band is a reference as before.
The motor's own residual is judged as before; identification measures the torque against its siblings
the same way, so its noise is that of what is judged.

The same stage takes a second look across motors where the profile grows its bands beyond the noise's
conditions as the siblings run (``conditions_siblings``, :mod:`.rules.bands`): each motor's low-passed
square of its deviations in its identified σ, speed and current, whose siblings' median says how wide
healthy deviations run in the air all six share right now. :class:`VehicleStage` carries every motor's
latest value of each quantity it takes (:data:`STAGE_QUANTITIES`) and works out the references of all of
them in one pass (the speed deviation's, :data:`PREDICTED`, is the siblings' linear prediction instead of
their median, where the profile asks for it: :mod:`.prediction`): the samples put in arrival order once,
each motor's latest value found for every quantity and every sample together (on the live agent's hot
path, a call of every motor's few samples).

**One stream for the quantities.** Each motor's latest value of a quantity at each place of the stream is
found by a running maximum over the places where that motor gave it (a finite value): one pass over
columns × stream per quantity, about a tenth of a whole log's stage. Quantities lost at the same places
have the same latest places, and the stage takes two that are (the squared deviations of speed and
current, low-passed together in :mod:`.rules.bands`): the running maximum is worked out once for each
distinct pattern of lost places, and the quantities of one pattern share which siblings' values are
recent enough. (The torque and the speed deviation are lost at the same samples too, but the speed
deviation also carries each motor's latest value before the instant of its latest, :data:`PREDICTED`:
their patterns differ at those places.) For the patterns to be the same in the stream too, the values
carried from the call before that are of one sample (the same motor, time, model speed and range, bit for
bit) are one place of the stream, a value of each of those quantities, instead of one place per quantity:
every quantity's latest values, their times and their order are those of one place per quantity (issue
18; the same references, byte for byte).

**The siblings' spread** (:attr:`VehicleStage.spreads`). Where the profile asks for it
(``torque_siblings_spread``, :mod:`.rules.bands`), the stage also gives how far the other motors' torque
residuals lie from their median at each sample: their median absolute deviation from it, times
:data:`MAD_TO_SIGMA` (a standard deviation where they are normal), from the same values and with the same
need of three as the median. It says how wide a healthy motor's torque against its siblings runs in the
air of this instant, measured on the siblings alone (the motor's own departure never counts in it), and
a faulty sibling among five moves a median absolute deviation as little as it moves the median. Where the
profile bounds the torque's slow look by its siblings (``torque_slow_siblings``, :mod:`.rules.equations`),
the same for each motor's slow average of its torque residual (``torque_slow_raw_nm``), taken like the
torque: a sibling beyond its identified speeds only at the motor's own speed. The voltage residual alike
(:mod:`.rules.voltage`).
"""

from __future__ import annotations

import struct
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._arrays import part_bounds
from .prediction import SiblingPrediction

__all__ = ["SPREAD", "STAGE_QUANTITIES", "STAGE_SPREADS", "VehicleStage", "median_of_finite"]

#: what the vehicle stage takes across motors: the frame's value each motor gives, and the frame's field
#: its siblings' reference goes to (rules/base.py, :class:`~.rules.base.Frame`)
STAGE_QUANTITIES = (
    ("torque_residual_nm", "torque_siblings_nm"),
    ("live_z2_speed", "siblings_z2_speed"),
    ("live_z2_current", "siblings_z2_current"),
    ("speed_deviation_rad_s", "speed_siblings_rad_s"),
    ("slow_ms_speed", "siblings_slow_ms_speed"),
    ("slow_ms_current", "siblings_slow_ms_current"),
    ("torque_slow_raw_nm", "siblings_torque_slow_nm"),
    ("voltage_residual_v", "voltage_siblings_v"),
    ("slow_ms_voltage", "siblings_slow_ms_voltage"),
)
#: the quantities whose siblings' spread the stage also gives, where asked (:attr:`VehicleStage.spreads`):
#: the quantity, and the frame field the spread goes to (module doc, "The siblings' spread")
STAGE_SPREADS = (
    ("torque_residual_nm", "torque_siblings_spread_nm"),
    ("torque_slow_raw_nm", "siblings_torque_slow_spread_nm"),
)
#: the key of a quantity's spread in what :meth:`VehicleStage.references` returns
SPREAD = " spread"
#: the median absolute deviation of normal values times this is their standard deviation
MAD_TO_SIGMA = 1.4826

#: the quantity whose reference is the siblings' linear prediction (:mod:`.prediction`), not their median
PREDICTED = "speed_deviation_rad_s"
#: the key of each motor's latest value of :data:`PREDICTED` before the instant of its latest one
_BEFORE = " before"

#: the other motors' values a reference needs: a median of three holds against one that departs (the
#: faulty motor, or one the model is carried far beyond its identified speeds for); a quadcopter's all but one
MEDIAN_OF = 3
#: a call of the stage works out its stream in parts of about this many samples (a whole log's; the live
#: agent's calls are far shorter): arrays of about a megabyte, in the processor's cache (of 1024, 2048,
#: 4096 and 8192, 4096 took the least time over a six-motor hour, ``benchmarks/bench_replay_speed.py``)
STREAM_CHUNK = 4096
#: from this many values on, :func:`median_of_finite` orders them with its sorting network (a whole
#: log's stream; the live agent's calls are sorted)
_NETWORK_MIN = 4096


@dataclass
class VehicleStage:
    """The vehicle stage's state: the vehicle's motors, and for each quantity of :data:`STAGE_QUANTITIES`
    it takes, each motor's latest finite value and its time."""

    #: the vehicle's motor numbers (its frame); motors seen in a call and not listed are added
    motors: list[int] = field(default_factory=list)
    #: the frame fields of :data:`STAGE_QUANTITIES` the stage takes (what a rule after it reads)
    quantities: tuple[str, ...] = ()
    #: quantity → motor → (time [s], value, model speed [rad/s], whether that speed lay in the motor's
    #: identified range) of its latest finite value
    latest: dict[str, dict[int, tuple[float, float, float, bool]]] = field(default_factory=dict)
    #: quantity → how far, as a share of a motor's model speed, a sibling's may lie from it and still be
    #: a reference where the sibling's own lies beyond its identified range (the torque: the profile's
    #: ``range_margin``; module doc, "Beyond the identified speeds"); other quantities take every sibling
    alike: dict[str, float] = field(default_factory=dict)
    #: the siblings' linear prediction of :data:`PREDICTED` (:mod:`.prediction`; None: not predicted)
    prediction: SiblingPrediction | None = None
    #: the quantities whose siblings' spread is given too (:data:`STAGE_SPREADS`), under their name and
    #: :data:`SPREAD`
    spreads: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        for m in () if self.prediction is None else self.prediction.motors:
            if m not in self.motors:
                self.motors.append(m)

    def references(
        self,
        motors: Sequence[int],
        time_s: NDArray[np.float64],
        values: Mapping[str, NDArray[np.float64]],
        counts: Sequence[int],
        max_age_s: NDArray[np.float64],
        speed_rad_s: NDArray[np.float64] | None = None,
        in_range: NDArray[np.bool_] | None = None,
    ) -> dict[str, NDArray[np.float64]]:
        """The siblings' reference of each quantity in ``values`` at each sample of rows of motors
        (module doc): ``time_s``, ``max_age_s``, each of ``values``, and for the quantities of
        :attr:`alike` ``speed_rad_s`` (each sample's model speed) and ``in_range`` (whether it lies in the
        motor's identified range; both None: every sibling counts), 2-D, one row per motor of ``motors``,
        each row's first ``counts`` samples its own (the rest padding: NaN in the result). Advances the
        carried latest values.

        A call of more than :data:`STREAM_CHUNK` samples (a whole log) is worked out as consecutive calls
        of about that many, cut between instants in arrival order, as the live agent's batches cut it
        (the same references: every reference is of the latest values before it, which each call
        carries to the next); the stream's arrays (quantities × samples × motors) then stay in the
        processor's cache instead of running to hundreds of megabytes (issue 18)."""
        chunks = _chunks(time_s, counts)
        if chunks is not None:
            return self._references_in_chunks(
                chunks, motors, time_s, values, counts, max_age_s, speed_rad_s, in_range
            )
        rows, width = np.shape(time_s)
        names = list(values)
        out = {name: np.full((rows, width), np.nan) for name in self._given(names)}
        for m in motors:
            if m not in self.motors:
                self.motors.append(int(m))
        if len(self.motors) < 2 or rows == 0 or not names:
            return out
        column = {m: j for j, m in enumerate(self.motors)}
        valid = np.arange(width)[None, :] < np.asarray(counts)[:, None]
        r_at, c_at = np.nonzero(valid)
        # the stream: the carried latest values first (each one a value of its own quantities only, NaN
        # for the others: it never counts as another's latest), then the call's samples
        carried = self._carried(names)
        held = len(carried)
        t = np.concatenate([[c[1] for c in carried], time_s[r_at, c_at]])
        v = np.full((len(names), t.size), np.nan)
        for i, (_, _, _, _, of) in enumerate(carried):
            for q, value in of:
                v[q, i] = value
        judging_alike = speed_rad_s is not None and in_range is not None
        own_speed, own_range = np.full(r_at.size, np.nan), np.ones(r_at.size, dtype=bool)
        if speed_rad_s is not None and in_range is not None:
            own_speed, own_range = speed_rad_s[r_at, c_at], in_range[r_at, c_at]
        speeds = np.concatenate([[c[2] for c in carried], own_speed])
        trusted = np.concatenate([[c[3] for c in carried], own_range]).astype(bool)
        for q, name in enumerate(names):
            v[q, held:] = values[name][r_at, c_at]
        who = np.concatenate(
            [[column[c[0]] for c in carried], np.asarray([column[int(m)] for m in motors])[r_at]]
        ).astype(np.intp)
        age_limit = np.concatenate([np.full(held, -np.inf), max_age_s[r_at, c_at]])
        order = np.lexsort((np.asarray(self.motors)[who], t))  # arrival: time, then motor number
        t, v, who, age_limit = t[order], v[:, order], who[order], age_limit[order]
        speeds, trusted = speeds[order], trusted[order]
        # each motor's (column's) latest finite value at or before each place in the stream, for every
        # quantity at once: (columns, stream) per quantity, each column's stream contiguous (issue 18);
        # quantities lost at the same places share it ("One stream for the quantities")
        k = np.arange(t.size)
        columns = len(self.motors)
        mine = who[None, :] == np.arange(columns)[:, None]
        not_mine = ~mine
        kind, masks = _alike_rows(np.isfinite(v))
        last_of = np.where(mine[None] & masks[:, None, :], k, -1)
        np.maximum.accumulate(last_of, axis=2, out=last_of)
        have_of = last_of >= 0
        # (−1 where none: an index all the same, every value it picks masked by ``have``)
        last = [last_of[kind[q]] for q in range(len(names))]
        have = [have_of[kind[q]] for q in range(len(names))]
        # the quantities whose reference is the siblings' median (the predicted one's is the prediction,
        # worked out below from each sibling's latest before the sample's instant)
        predicted = self.prediction is not None and PREDICTED in names
        medians = [q for q, name in enumerate(names) if not (predicted and name == PREDICTED)]
        reference = np.full((len(names), t.size), np.nan)
        spread: dict[int, NDArray[np.float64]] = {}
        if medians:
            others = np.empty((len(medians), columns, t.size))
            recent: dict[int, NDArray[np.bool_]] = {}  # each kind's siblings recent enough
            for i, q in enumerate(medians):
                q_at = last[q]
                fresh = recent.get(kind[q])
                if fresh is None:
                    fresh = recent[kind[q]] = have[q] & (t - t[q_at] <= age_limit) & not_mine
                share = self.alike.get(names[q])
                if share is not None and judging_alike:
                    # a sibling beyond its identified speeds carries the model's error there: a reference
                    # only at this motor's own speed (module doc, "Beyond the identified speeds")
                    with np.errstate(invalid="ignore"):
                        near = np.abs(speeds[q_at] - speeds) <= share * np.abs(speeds)
                    fresh = fresh & (trusted[q_at] | near)
                np.copyto(others[i], np.where(fresh, v[q][q_at], np.nan))
            need = min(MEDIAN_OF, max(1, columns - 2))  # three others, or all but one where fewer
            reference[medians] = median_of_finite(others, need, axis=1)
            for i, q in enumerate(medians):
                if names[q] in self.spreads:  # how far the others lie from their median ("The spread")
                    spread[q] = MAD_TO_SIGMA * median_of_finite(
                        np.abs(others[i] - reference[q]), need, axis=0
                    )
        if predicted:
            q = names.index(PREDICTED)
            # each sibling's latest before the sample's own time, never of the same instant (prediction.py,
            # "Before, never of the same instant"): its latest at the place before the instant's first
            first = np.searchsorted(t, t, side="left")
            before = np.where(first > 0, last[q][:, first - 1], -1)
            at_before = before  # (−1 where none, masked as ``at`` is)
            fresh_before = (before >= 0) & (t - t[at_before] <= age_limit) & not_mine
            if judging_alike:
                # a sibling beyond its identified speeds: not in the pattern Σ was measured in
                fresh_before &= trusted[at_before]
            reference[q] = self._predicted(v[q][at_before], fresh_before, v[q], who)
        back = np.empty(t.size, dtype=np.intp)
        back[order] = k
        for q, name in enumerate(names):
            out[name][r_at, c_at] = reference[q, back[held:]]
            if q in spread:
                out[name + SPREAD][r_at, c_at] = spread[q][back[held:]]
            kept = self.latest.setdefault(name, {})

            def entry(i: int, q: int = q) -> tuple[float, float, float, bool]:
                return float(t[i]), float(v[q, i]), float(speeds[i]), bool(trusted[i])

            for j in np.flatnonzero(have[q][:, -1]).tolist():
                j_at = int(last[q][j, -1])
                kept[self.motors[j]] = entry(j_at)
                if name == PREDICTED:
                    # and its latest before that instant: what a sibling of that instant still to come
                    # in the next call is predicted from ("Before, never of the same instant")
                    start = int(np.searchsorted(t, t[j_at], side="left"))
                    earlier = int(last[q][j, start - 1]) if start > 0 else -1
                    into = self.latest.setdefault(name + _BEFORE, {})
                    if earlier >= 0:
                        into[self.motors[j]] = entry(earlier)
                    else:
                        into.pop(self.motors[j], None)
        return out

    def _carried(self, names: Sequence[str]) -> list[tuple[int, float, float, bool, list[tuple[int, float]]]]:
        """The latest values carried for the quantities ``names`` as places of the stream: (motor, time,
        model speed, in range, [(quantity's place in ``names``, value), ...]). Values of one sample (the
        same motor, time, speed and range, bit for bit) share a place ("One stream for the
        quantities"); the places in the order the quantities and motors come."""
        places: dict[tuple[int, bytes, bool], tuple[int, float, float, bool, list[tuple[int, float]]]] = {}
        for q, name in enumerate(names):
            for key in (name, name + _BEFORE) if name == PREDICTED else (name,):
                latest = self.latest.get(key, {})
                for m in self.motors:
                    if m not in latest:
                        continue
                    time_s, value, speed, in_range = latest[m]
                    place = (m, struct.pack("<dd", time_s, speed), in_range)
                    if place not in places:
                        places[place] = (m, time_s, speed, in_range, [])
                    places[place][4].append((q, value))
        return list(places.values())

    def _references_in_chunks(
        self,
        chunks: NDArray[np.intp],
        motors: Sequence[int],
        time_s: NDArray[np.float64],
        values: Mapping[str, NDArray[np.float64]],
        counts: Sequence[int],
        max_age_s: NDArray[np.float64],
        speed_rad_s: NDArray[np.float64] | None,
        in_range: NDArray[np.bool_] | None,
    ) -> dict[str, NDArray[np.float64]]:
        """:meth:`references` as consecutive calls: ``chunks[r, c]`` the first sample of row r in the
        c-th (its last column: the row's count)."""
        rows, width = np.shape(time_s)
        out = {name: np.full((rows, width), np.nan) for name in self._given(values)}
        for c in range(chunks.shape[1] - 1):
            lo, hi = chunks[:, c].tolist(), chunks[:, c + 1].tolist()
            found = self.references(
                motors,
                _part(time_s, lo, hi, np.nan),
                {name: _part(v, lo, hi, np.nan) for name, v in values.items()},
                [h - l for l, h in zip(lo, hi)],
                _part(max_age_s, lo, hi, np.nan),
                None if speed_rad_s is None else _part(speed_rad_s, lo, hi, np.nan),
                None if in_range is None else _part(in_range, lo, hi, False),
            )
            for name, got in found.items():
                for r, (l, h) in enumerate(zip(lo, hi)):
                    out[name][r, l:h] = got[r, : h - l]
        return out

    def _given(self, names: Iterable[str]) -> list[str]:
        """The keys :meth:`references` returns for the quantities ``names``: each, and its spread where
        the stage gives one."""
        return [key for name in names for key in (name, name + SPREAD)[: 2 if name in self.spreads else 1]]

    def _predicted(
        self,
        latest: NDArray[np.float64],
        fresh: NDArray[np.bool_],
        own: NDArray[np.float64],
        who: NDArray[np.intp],
    ) -> NDArray[np.float64]:
        """The siblings' part of each stream place's own value (:meth:`.SiblingPrediction.explained`): each
        predicted motor's latest fresh value (``latest`` and ``fresh``: columns × stream), the place's own
        motor its own; NaN at a place of a motor the prediction does not know, or where one of its motors
        has no fresh value."""
        assert self.prediction is not None
        column = {m: j for j, m in enumerate(self.motors)}
        where = np.asarray([column[m] for m in self.prediction.motors], dtype=np.intp)
        position = np.full(len(self.motors), -1, dtype=np.intp)
        position[where] = np.arange(where.size)
        x = np.where(fresh[where], latest[where], np.nan).T
        p = position[who]
        known = np.flatnonzero(p >= 0)
        out = np.full(who.size, np.nan)
        if known.size:
            x[known, p[known]] = own[known]
            out[known] = self.prediction.explained(x[known], p[known])
        return out


def _part(x: NDArray[Any], lo: list[int], hi: list[int], fill: Any) -> NDArray[Any]:
    """Samples ``lo[r]`` to ``hi[r]`` of each row r of ``x``, as rows padded with ``fill``."""
    piece = np.full((len(lo), max(h - l for l, h in zip(lo, hi))), fill, dtype=x.dtype)
    for r, (l, h) in enumerate(zip(lo, hi)):
        piece[r, : h - l] = x[r, l:h]
    return piece


def _chunks(time_s: NDArray[np.float64], counts: Sequence[int]) -> NDArray[np.intp] | None:
    """Where a call holds more than 2 × :data:`STREAM_CHUNK` samples with finite times: each row's first
    sample of each consecutive part of about :data:`STREAM_CHUNK` samples in arrival order, cut between
    instants (one column per part, and a last one: the rows' counts); None otherwise (one call)."""
    total = int(sum(counts))
    if total <= 2 * STREAM_CHUNK:
        return None
    times = np.asarray(time_s, dtype=float)
    return part_bounds([times[r, :k] for r, k in enumerate(counts)], STREAM_CHUNK)


def _alike_rows(rows: NDArray[np.bool_]) -> tuple[list[int], NDArray[np.bool_]]:
    """Each row's kind (the first row equal to it, counted among the distinct ones) and the distinct
    rows, in order."""
    kinds: list[int] = []
    seen: dict[bytes, int] = {}
    for row in rows:
        kinds.append(seen.setdefault(row.tobytes(), len(seen)))
    firsts = [kinds.index(u) for u in range(len(seen))]
    return kinds, rows[firsts]


def median_of_finite(values: NDArray[np.float64], need: int, axis: int = 1) -> NDArray[np.float64]:
    """The median of the finite values along ``axis`` (each row's, by default); NaN where fewer than
    ``need`` are finite.

    Along a short axis (a vehicle's motors) of a long array (a whole log's stream), the values are put in
    order by a sorting network of minima and maxima over whole slices (NaN as +inf, last), ``axis`` moved
    first so that each slice is contiguous: ``np.sort`` along a short axis sorts one row at a time, about
    twice as slow there (issue 18). A small array (the live agent's call) is sorted, in fewer numpy
    calls. The same values either way."""
    x = np.moveaxis(np.asarray(values, dtype=float), axis, 0)
    finite = np.isfinite(x)
    count = np.sum(finite, axis=0)
    n = x.shape[0]
    if x.size <= _NETWORK_MIN:
        ranked = np.sort(x, axis=0)  # NaN last
        lo = np.take_along_axis(ranked, np.maximum((count - 1) // 2, 0)[None], axis=0)[0]
        hi = np.take_along_axis(ranked, np.maximum(count // 2, 0)[None], axis=0)[0]
        return np.where(count >= max(need, 1), 0.5 * (lo + hi), np.nan)
    in_order = list(np.where(finite, x, np.inf))
    for r in range(n):  # odd-even transposition: n rounds put n values in order
        for i in range(r % 2, n - 1, 2):
            a, b = in_order[i], in_order[i + 1]
            in_order[i], in_order[i + 1] = np.minimum(a, b), np.maximum(a, b)
    out = np.full(count.shape, np.nan)
    for c in range(max(need, 1), n + 1):
        # c finite values: the middle one, or the mean of the middle two
        np.copyto(out, 0.5 * (in_order[(c - 1) // 2] + in_order[c // 2]), where=count == c)
    return out
