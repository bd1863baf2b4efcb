"""Each motor's speed deviation against its siblings' linear prediction (issue 17): the part of a healthy
motor's deviation that the other motors' deviations of the same moment explain, learned on the vehicle's
own healthy identification flight.

Why. In moderate and gusty air the speed deviations of healthy motors spread several times wider than in
calm air, and an open transistor (F4.1) or friction sits inside that spread. Much of it is not each
motor's own: the attitude controller drives the six motors in a pattern (collective, roll, pitch, yaw),
and what the model gets wrong in fast changes follows that pattern. A median of the siblings cancels only
what all share alike (opposite motors move opposite ways); a linear prediction cancels the pattern.
``benchmarks/bench_sibling_covariance.py`` measured the separation it gives before this was built
(docs/flight.md, "Each motor against its siblings' linear prediction, measured").

What. At a sample of motor m, the siblings' part of its deviation is the conditional mean
``E[x_m | x_o] = C_mo Σ_oo⁻¹ x_o`` from the siblings' latest deviations x_o (:class:`SiblingPrediction`).
Identification measures what it needs on its healthy flight (:func:`measure_speed_covariance`): Σ, the
covariance of the motors' speed deviations as the stage gives them (``[noise.N] speed_covariance_M``),
and each motor's covariance C with its siblings' latest values before its own sample
(``speed_lagged_covariance_M``). It then diagnoses the flight again with the prediction and measures the
noise of the deviation less the siblings' part (``speed_vs_siblings_rad_s ...``, :mod:`.noise`), which
the profile's ``speed_against_siblings`` judges against where its σ is the narrower
(:mod:`.rules.against`). The vehicle stage (:mod:`.siblings`) works the prediction out in the order
samples arrive, as it does the siblings' medians, so replay and the live agent give the same values.

What the prediction is made from, and where there is none:

* **Every sample's deviation, steady or not.** A sibling's latest deviation must be of the same moment;
  its latest *judged* one is, in a manoeuvre, from before it. On held-out world 1005, whose motors'
  deviations correlate by ±0.97, the prediction from judged values alone left 99th percentiles of 8 to
  14 of the difference's σ on its own identification flight; from every sample's, three of the six
  motors' came to 2 to 3 (the others' heavy tails are what the noise's deeper tail is for, :mod:`.noise`).
* **Before the sample, never of its instant.** A sibling's sample of the same instant reaches the live
  agent before or after the motor's own, by motor number; predicting from it would give the
  lower-numbered motors staler siblings than the higher-numbered ones. Each motor is predicted from its
  siblings' latest values before its own sample's time, which is what C is measured with.
* **One sibling that departs is left out.** A faulty sibling would lend its fault to the others: the
  sibling that departs most from the other siblings' prediction (the motor judged left out of it, so
  that its own fault never makes a sibling look departed), where it departs by more than
  ``exclude_sigmas`` of its conditional σ, is left out and the prediction is made from the other four
  (the one motor that departs is a finding, not a reference).
* **None where two depart, or a sibling runs beyond its identified speeds.** After a stall or a lost
  propeller the siblings compensate, each at another operating point: not the pattern Σ was measured in.
  On held-out world 1001 predicting there named the compensating motors UNKNOWN 44 times in its fault
  flights; there the motor is judged alone.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ..telemetry.assemble import held
from ..telemetry.table import TelemetryTable

__all__ = ["MIN_COVARIANCE_SAMPLES", "SiblingPrediction", "measure_speed_covariance"]

#: at least this many instants where every motor has a judged deviation, to measure Σ
MIN_COVARIANCE_SAMPLES = 200
#: at least this many motors (a motor and two siblings: one may be left out)
MIN_MOTORS = 3


@dataclass(frozen=True)
class SiblingPrediction:
    """The siblings' linear prediction of each motor's speed deviation (module doc), from Σ."""

    #: the motor numbers, in Σ's order
    motors: tuple[int, ...]
    #: the covariance of their speed deviations of the same moment [(rad/s)²]
    covariance: NDArray[np.float64]
    #: lagged[o, p]: the covariance of motor p's deviation with motor o's latest one before it, as the
    #: vehicle stage gives it (module doc, "Before, never of the same instant") [(rad/s)²]
    lagged: NDArray[np.float64]
    #: a sibling departing from its own prediction by more than this many of its conditional σ is left
    #: out of the others' (module doc)
    exclude_sigmas: float
    #: weights[p, e] the prediction of motor p's deviation from the others' with e left out (e == p: none),
    #: zero at p and e; precision the inverse of Σ
    weights: NDArray[np.float64] = field(init=False, repr=False, compare=False)
    #: without[p, e]: the precision of Σ without motors p and e (e == p: p alone; zero in their rows and
    #: columns), and the square roots of its diagonal (inf at p and e): each sibling's departure from the
    #: other siblings' prediction, those motors left out of it
    without: NDArray[np.float64] = field(init=False, repr=False, compare=False)
    without_scale: NDArray[np.float64] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        sigma = np.asarray(self.covariance, dtype=float)
        lagged = np.asarray(self.lagged, dtype=float)
        n = len(self.motors)
        weights = np.zeros((n, n, n))
        for p in range(n):
            for e in range(n):
                keep = [c for c in range(n) if c not in (p, e)]
                weights[p, e, keep] = np.linalg.solve(sigma[np.ix_(keep, keep)], lagged[keep, p])
        without = np.zeros((n, n, n, n))
        scale = np.full((n, n, n), np.inf)
        for p in range(n):
            for e in range(n):
                keep = [c for c in range(n) if c not in (p, e)]
                inverse = np.linalg.inv(sigma[np.ix_(keep, keep)])
                without[p, e][np.ix_(keep, keep)] = inverse
                scale[p, e, keep] = np.sqrt(np.diag(inverse))
        object.__setattr__(self, "weights", weights)
        object.__setattr__(self, "without", without)
        object.__setattr__(self, "without_scale", scale)

    @classmethod
    def of(
        cls,
        covariance: Mapping[int, Sequence[tuple[int, float]]],
        lagged: Mapping[int, Sequence[tuple[int, float]]],
        exclude_sigmas: float,
    ) -> SiblingPrediction | None:
        """The prediction from each motor's measured covariances by motor number
        (:attr:`~.noise.BandNoise.speed_covariance`, and :attr:`~.noise.BandNoise.speed_lagged_covariance`:
        motor p's with each sibling's latest before it); None where fewer than :data:`MIN_MOTORS` motors
        have them, or they do not make a positive definite Σ (a file written by hand)."""
        motors = tuple(sorted(m for m, row in covariance.items() if row and lagged.get(m)))
        if len(motors) < MIN_MOTORS:
            return None
        rows = {m: dict(covariance[m]) for m in motors}
        behind = {m: dict(lagged[m]) for m in motors}
        sigma = np.array([[rows[a].get(b, math.nan) for b in motors] for a in motors], dtype=float)
        # lagged[o, p] = cov(p now, o before): motor p's row of its own measurement, as a column
        late = np.array([[behind[p].get(o, math.nan) for p in motors] for o in motors], dtype=float)
        np.fill_diagonal(late, np.diag(sigma))  # a motor's own value is never predicted from itself
        if not (np.isfinite(sigma).all() and np.isfinite(late).all()):
            return None
        sigma = 0.5 * (sigma + sigma.T)
        if np.linalg.eigvalsh(sigma)[0] <= 0:
            return None
        return cls(motors, sigma, late, float(exclude_sigmas))

    def _departures(
        self, x: NDArray[np.float64], own: NDArray[np.intp], left_out: NDArray[np.intp]
    ) -> NDArray[np.float64]:
        """Each motor's |departure| from the prediction by the others, ``own`` and ``left_out`` left out of
        it (−inf for those two), in its conditional σ."""
        n = len(self.motors)
        pair = own * n + left_out  # (np.take of the pairs flattened: half the time of indexing by two)
        scale = np.take(self.without_scale.reshape(n * n, n), pair, axis=0)
        without = np.take(self.without.reshape(n * n, n, n), pair, axis=0)
        g = np.abs(np.einsum("ij,ijk->ik", x, without)) / scale
        return np.where(np.isfinite(scale), g, -np.inf)

    def explained(self, deviations: NDArray[np.float64], own: NDArray[np.intp]) -> NDArray[np.float64]:
        """The siblings' part of each row's own deviation: ``deviations`` rows × motors (in
        :attr:`motors` order, centred: the model shifted by each motor's offset), ``own`` each row's own
        column. NaN where any motor's value is missing, or where two siblings depart (module doc)."""
        x = np.asarray(deviations, dtype=float)
        rows = np.arange(x.shape[0])
        complete = np.isfinite(x).all(axis=1)
        x = np.where(complete[:, None], x, 0.0)
        # each sibling's departure from the other siblings' prediction in its conditional σ, the row's own
        # motor left out of both (its own fault must not make its siblings look departed):
        # (Σ₋ₚ⁻¹x)_j / √(Σ₋ₚ⁻¹)_jj; the one that departs most, where beyond exclude_sigmas, left out
        g = self._departures(x, own, own)
        worst = np.argmax(g, axis=1)
        departs = g[rows, worst] > self.exclude_sigmas
        left_out = np.where(departs, worst, own)
        n = len(self.motors)
        weights = np.take(self.weights.reshape(n * n, n), own * n + left_out, axis=0)
        part = np.einsum("ij,ij->i", weights, x)
        # and where, without it, another still departs: not the pattern Σ was measured in (a stalled
        # motor's siblings compensating it, each at another operating point): no prediction (only the
        # rows that left one out: elsewhere the departures without it are those above, none beyond)
        alike = ~departs
        left = np.flatnonzero(departs)
        if left.size:
            again = self._departures(x[left], own[left], left_out[left])
            alike[left] = np.max(again, axis=1) <= self.exclude_sigmas
        return np.where(complete & alike, part, np.nan)


def measure_speed_covariance(
    diagnosed: Sequence[TelemetryTable], max_age_s: float, min_command: float = 0.0
) -> tuple[dict[int, tuple[tuple[int, float], ...]], dict[int, tuple[tuple[int, float], ...]]]:
    """What the siblings' prediction needs (module doc, "Before, never of the same instant"), measured on
    diagnosed healthy flights (:func:`~.pipeline.diagnose` output of the flight rule, its noise
    unbounded): at each judged sample of each motor (steady, commanded above ``min_command``), every
    sibling's latest deviation before it, at most ``max_age_s`` old (of any sample, as the vehicle stage
    takes them), each motor's around its median. Σ: the covariance of those values over every motor's
    samples together; and each motor's
    covariance with its siblings' values. Each motor's rows as (motor, covariance) pairs, the two apart;
    both empty where a motor has fewer than :data:`MIN_COVARIANCE_SAMPLES` samples with every sibling's
    value, or the vehicle fewer than :data:`MIN_MOTORS` motors."""
    judged_of = [_judged(d, min_command) for d in diagnosed]
    # the motors judged at all: an output the log reports but nothing turns (a hexacopter's ESC slots 7
    # and 8, all zeros) is no sibling, and its empty rows would leave every motor without a covariance
    motors: list[int] = sorted(
        {int(m) for d, judged in zip(diagnosed, judged_of) for m in np.unique(np.asarray(d["motor"])[judged])}
    )
    n = len(motors)
    if n < MIN_MOTORS:
        return {}, {}
    before: dict[int, list[NDArray[np.float64]]] = {m: [] for m in motors}
    for d, judged in zip(diagnosed, judged_of):
        deviation = np.asarray(d["omega_judged_rad_s"]) - np.asarray(d["omega_model_rad_s"])
        time_s, motor = np.asarray(d["time_s"], dtype=float), np.asarray(d["motor"])
        series = {}
        for m in motors:
            sel = (motor == m) & np.isfinite(deviation)
            series[m] = (time_s[sel], deviation[sel])
        for m in motors:
            mine = (motor == m) & judged & np.isfinite(deviation)
            t, x = time_s[mine], deviation[mine]
            if t.size == 0:
                continue
            earlier = np.nextafter(t, -np.inf)  # strictly before: a sibling of the same instant is too late
            before[m].append(
                np.column_stack([x if o == m else held(series[o], earlier, max_age_s)[0] for o in motors])
            )
    rows = {m: _complete(np.vstack(parts)) if parts else np.zeros((0, n)) for m, parts in before.items()}
    if any(r.shape[0] < MIN_COVARIANCE_SAMPLES for r in rows.values()):
        return {}, {}
    own_center = np.array([np.median(rows[m][:, i]) for i, m in enumerate(motors)])
    # Σ over every motor's samples together (positive semi-definite by construction; each pair taken
    # apart over the samples of the motors that are neither was not: on world 1005, whose motors'
    # deviations correlate by ±0.97, it came out indefinite)
    sigma = np.cov(np.vstack(list(rows.values())) - own_center, rowvar=False)
    if not np.isfinite(sigma).all() or np.linalg.eigvalsh(sigma)[0] <= 0:
        return {}, {}
    covariance = {
        m: tuple((o, float(sigma[i, j])) for j, o in enumerate(motors)) for i, m in enumerate(motors)
    }
    lagged = {}
    for i, m in enumerate(motors):
        x = rows[m] - own_center
        lag = _covariance(x[:, [i]], x)[0]
        lagged[m] = tuple((o, float(lag[j])) for j, o in enumerate(motors))
    return covariance, lagged


def _judged(diagnosed: TelemetryTable, min_command: float) -> NDArray[np.bool_]:
    """The samples a diagnosed flight judged (steady) with a command of at least ``min_command``."""
    judged = np.asarray(diagnosed["steady"], dtype=bool)
    if min_command > 0 and "throttle" in diagnosed.names:
        judged &= np.asarray(diagnosed["throttle"], dtype=float) >= min_command
    return judged


def _complete(rows: NDArray[np.float64]) -> NDArray[np.float64]:
    """The rows where every column has a value."""
    return rows[np.isfinite(rows).all(axis=1)]


def _covariance(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """The covariance of the columns of ``a`` with those of ``b`` (centred already)."""
    return a.T @ b / max(a.shape[0] - 1, 1)
