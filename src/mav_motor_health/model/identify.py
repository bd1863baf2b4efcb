"""Identify a vehicle's motors, ESCs and current sensing from its own flight log (every sample).

A bench fit needs steady operating points; a flight log has few. The model's equations, though, hold at
every instant (see :mod:`.balance`), so identification fits them as balances over the whole flight:

1. **Electrical, with the ESC map** (all motors share one ESC map, each motor its own R and k_e). The ESC
   turns the command ``c`` (0..1 over the autopilot's PWM range) into the duty
   ``d = clip((c − c₀)/(1 − c₀), 0, 1)``: ``c₀`` is the ESC's idle offset, and full command is full duty
   (the end point the autopilot's range sets; a full-scale error would only scale k_e and cannot be told
   from it). With the ESC reporting its *input* current ``s = g·d·i`` the balance is
   ``⟨d·(d·V_bus − k_e·ω)⟩ = (R/g)·⟨s⟩``; reporting the *motor* (phase) current ``s = g·i`` it is
   ``⟨d·V_bus − k_e·ω⟩ = (R/g)·⟨s⟩``. ``⟨·⟩`` are means over short time bins (``bin_s``): they average
   the ESC's own averaging and the command's pairing out, and every product is formed per sample before
   averaging, so the balance holds whatever the input does within a bin. For a given ``c₀`` each motor's
   (k_e, R/g) is a non-negative linear least-squares fit; ``c₀`` minimises the pooled residual (a bounded
   scalar search), for each convention on its own. A reading that does not follow the load at all
   (constant, zero, uncorrelated) is "unusable": then R comes from the prior and the current is left to
   the speed-only path.
1b. **Which convention**: where the flight tells, not the smaller residual (both are reported). The two
   balances differ only in R·i's share of the duty, a few hundredths of a volt, and the commands' pairing
   biases them by more, so the residuals chose at random (11 of 29 development worlds right). The side
   comes from a physical consequence instead (:func:`current_side_test`): at a given speed the load sets the motor current
   and the duty that drives it goes as ``1/V_bus``, so an input-side reading ``g·d·i`` has elasticity −1
   with the bus voltage and a motor-side one 0; the pack's discharge over the flight measures which
   (no command, no idle offset enters). Where the estimate lies less than :data:`SIDE_MARGIN_SE`
   standard errors beyond the midpoint, or more than that from the likelier side's own value, the
   flight does not tell: with a battery monitor, the convention whose implied sensor gain (the ESCs'
   summed charge over the battery's, read as each side's input current) lies nearer 1; without one, the
   convention with the smaller residual; a finding says it is a guess (docs/model.md).
2. **Current scale** ``g``: a current sensor's gain cannot be told from the motor's R by the motor's own
   data (R/g, g·C_p, g·J explain the same log). Where the log has the battery monitor, ``g`` is the ratio
   of the charges the ESCs (summed input current) and the battery counted over the flight
   (:func:`gain_from_pairs`); else ``g = 1`` is assumed and R, C_p, B, T_f and J are stated as "scaled by
   the current sensor's unknown gain".
3. **Mechanical, with the inertia**: ``k_t·i = C_p·ω^k + B·ω + T_f + J·dω/dt``, with ``i`` both the motor
   current the ESC reports and the one the electrical balance implies, ``(d·V − k_e·ω)/R``, each route
   weighed by its own scatter, through a second-order state-variable filter (no numerical derivative:
   the filtered ``J·dω/dt`` is ``J`` times the difference of the filter's two stages over τ). Linear in
   (C_p, B, T_f, J) for each k; bounded ≥ 0; B and
   T_f carry a weak prior toward the prior motor's share of the load (a hover says little about C_p vs B
   vs T_f; the report says which parameters the data determined). k = 3 unless another k lowers the BIC
   by :data:`K_BIC_MARGIN` or more.
4. **Per motor**: each motor's R, k_e and C_p relative to the motors' median (the motor type); a motor
   that departs from its siblings by more than :data:`SIBLING_DEPARTURE` is reported, not averaged in
   (the type is the median).

What a flight must contain (docs/model.md): the motors turning over a range of commands (take-off,
climbs, descents, yaw: the commands must move at a constant battery voltage for c₀ to be told from
k_e), some seconds of it; the battery monitor for the current scale.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ..errors import FitError
from ..telemetry.table import TelemetryTable
from .dynamics import first_order_response
from .esc import ElectricalTerms as _ElectricalTerms  # the ESC map and the electrical balance through it
from .esc import (
    EscMap,  # are shared with the bench fit (estimation.estimate_with_esc)
    motor_current_a,
)
from .esc import fit_electrical_balance as _electrical_fit
from .esc import search_idle_offset as _pooled_electrical
from .estimation import K_BIC_MARGIN, choose_exponent
from .lsq import fit_linear
from .params import MotorParams

__all__ = [
    "K_BIC_MARGIN",
    "CurrentReading",
    "EscMap",
    "Identification",
    "back_emf_share_at",
    "battery_current_pairs",
    "command_jitter",
    "electrical_balance_at",
    "gain_from_pairs",
    "identify",
]

FloatArray = NDArray[np.float64]

#: the mechanical balance's coefficients, in its design matrix's order (:func:`_mechanical_design`)
MECHANICAL_NAMES = ("C_p", "B", "T_f", "J_kg_m2")
#: candidate propeller exponents
K_CANDIDATES = (2.0, 2.5, 3.0, 3.5, 4.0)
#: a motor whose R, k_e or C_p departs from the motors' median by more than this is reported
SIBLING_DEPARTURE = 0.15
#: the lowest command used (below it the ESC's duty is near zero and says nothing)
MIN_COMMAND = 0.05
#: the prior's width for B·ω and T_f: this share of the load torque at the flight's median speed
PRIOR_SHARE = 0.02
#: where the flight does not part R from k_e, the share of the motor voltage the winding's resistance takes at
#: the flight's loads (R·i over d·V, dimensionless): about a tenth for a multirotor motor at its hover load
#: (the paper's motor, Table I, at its 3.8 A hover: 9.6 %; the DTU stand's MultiStar 3508-700KV, R 0.083 Ω,
#: with its 14x5.5 propeller at the DTU hexacopter's hover thrust: about 12 %); docs/model.md, "Where the
#: current does not part R from k_e"
COPPER_SHARE = 0.10
#: the current parts R from k_e where, the speed taken out, it follows the motor voltage with at least this
#: partial correlation over the flight's bins (its square: half the variance). Below it most of what is
#: left is noise, and the commands' pairing error (in the voltage, while the current follows the duty of
#: its own instant) pulls the other way: least squares puts R near its bound and k_e high by about the
#: winding's share (docs/model.md, "Where the current does not part R from k_e"; dimensionless)
R_PARTIAL_CORRELATION_MIN = 0.7
#: the idle offsets the speed-only search (no usable current) looks in, of the command range
SPEED_ONLY_OFFSET_RANGE = (-0.05, 0.3)
#: the balances' bins span at least this many pairing intervals of the log (dimensionless)
PAIRING_BINS = 4.0
#: an idle offset less certain than this (of the command range) is not taken from the data
IDLE_OFFSET_STDERR_MAX = 0.005
#: ESC-sum / battery-monitor ratios a current sensor's gain can explain (AM32 reads ~0.78; the real PX4
#: quad in shared/real_logs 0.47); outside them the comparison itself is not trusted
BATTERY_GAIN_RANGE = (0.3, 3.0)
#: the speed range (95th over 5th percentile) a flight must span before its data may choose k: over a
#: narrower range ω^k and a linear term are too alike for any k to be told from 3
K_SPEED_SPAN = 1.6
#: time constant of the mechanical balance's low-pass [s]
MECHANICAL_TAU_S = 0.3
#: an input current whose duty ripple's copper loss is estimated at this share of the reading or more
#: (:func:`duty_ripple_share`) is mostly ripple, not load: the flight does not choose the propeller exponent
#: (k = 3) and the report says to identify from a calmer flight (dimensionless; docs/model.md, "An input
#: current that is mostly ripple")
RIPPLE_SHARE_MAX = 0.5
#: the elasticity of the ESC's current reading with the bus voltage at a given speed on each side: at a
#: given speed the load, hence the motor current, is set; the duty that drives it is ∝ 1/V_bus, so an
#: input-side reading (duty × motor current) goes as V_bus⁻¹ and a motor-side one does not move
SIDE_ELASTICITY = {"input": -1.0, "motor": 0.0}
#: the side is taken from the data only where the measured elasticity lies this many standard errors
#: beyond the midpoint between the two sides' values (the convention the sibling findings use too)
SIDE_MARGIN_SE = 3.0
#: the bus voltage's slow part (its mean over this window [s], all motors) instruments it in the side
#: test, and the test's standard error treats blocks of this length as independent: the pack's discharge
#: and a manoeuvre's sag move the voltage over seconds and tens of seconds, while a burst of current
#: sags it at the instant the same reading is taken (that fast part would read as a dependence)
SIDE_VOLTAGE_WINDOW_S = 5.0
#: readings below this share of the flight's median reading are left out of the side test (an ESC
#: reports no negative current: near 0 a reading's mean says nothing of a proportion)
SIDE_MIN_READING_SHARE = 0.05


@dataclass(frozen=True)
class SideTest:
    """Which side the ESC reads its current on, from the reading's dependence on the bus voltage at a
    given speed (:func:`current_side_test`): ``elasticity`` ± ``stderr`` against
    :data:`SIDE_ELASTICITY`; ``margin_se`` how many standard errors the estimate lies beyond the midpoint
    between the two sides, positive toward the input side; ``side`` "input", "motor" or "undetermined"
    (less than :data:`SIDE_MARGIN_SE`, or the likelier side's own value more than that far off:
    ``likelier_fits`` False); ``likelier`` the side the estimate leans to."""

    elasticity: float
    stderr: float
    bins: int
    margin_se: float
    side: str
    likelier: str
    likelier_fits: bool = True

    def describe(self) -> str:
        return (
            f"elasticity of the reading with the bus voltage at a given speed {self.elasticity:+.2f} "
            f"+- {self.stderr:.2f} (input side -1, motor side 0; {self.bins} bins"
            + ("" if self.likelier_fits else "; neither side's")
            + ")"
        )


@dataclass(frozen=True)
class CurrentReading:
    """How the ESC reports current: ``side`` "input" (battery side, duty × motor current), "motor"
    (phase), or "unusable"; ``gain`` its scale (reading / true), ``gain_from`` "battery" or "assumed"."""

    side: str = "input"
    gain: float = 1.0
    gain_from: str = "assumed"
    offset_a: float = 0.0
    residual_v: Mapping[str, float] = field(default_factory=dict)
    #: the side test (:func:`current_side_test`) where it ran: None for a reading that never followed
    #: the load
    side_test: SideTest | None = None


@dataclass(frozen=True)
class Identification:
    """What identification found, with the evidence for it (see :meth:`report`)."""

    params: MotorParams  # the motor type (median of the motors), with J
    per_motor: Mapping[int, MotorParams]
    esc: EscMap
    current: CurrentReading
    stderr: Mapping[str, float]
    determined_by: Mapping[str, str]  # parameter -> "data", "prior" or "data and prior"
    k_bic: Mapping[float, float]  # candidate k -> BIC of the mechanical fit
    deviations: Mapping[int, Mapping[str, float]]  # motor -> parameter -> relative departure from the type
    noise: Mapping[int, Mapping[str, float]]  # motor -> residual std of the balances
    samples: int
    span_s: tuple[float, float]
    findings: tuple[str, ...] = ()
    #: the commands' jitter between reports relative to the duty, and the share of an input current's
    #: reading that the duty ripple's copper loss would make (:func:`duty_ripple_share`)
    duty_jitter: float = math.nan
    ripple_share: float = math.nan

    def report(self) -> str:
        p = self.params
        lines = [
            f"identified from {self.samples} samples, {self.span_s[0]:.1f}-{self.span_s[1]:.1f} s",
            f"ESC map: idle offset {self.esc.idle_offset:.4f} of the command range (full command = full duty)",
            f"current reading: {self.current.side} side, gain {self.current.gain:.3f} ({self.current.gain_from})"
            + (
                "; residual " + ", ".join(f"{k} {v:.3g} V" for k, v in self.current.residual_v.items())
                if self.current.residual_v
                else ""
            )
            + (f"; side test: {self.current.side_test.describe()}" if self.current.side_test else ""),
            "",
            f"{'parameter':<10}{'value':>14}{'stderr':>12}  determined by",
        ]
        for name in ("R_ohm", "k_e", "C_p", "B", "T_f", "J_kg_m2"):
            value = getattr(p, name)
            err = self.stderr.get(name, math.nan)
            lines.append(f"{name:<10}{value:>14.5g}{err:>12.3g}  {self.determined_by.get(name, 'data')}")
        chosen = p.k
        lines += ["", "propeller exponent k (BIC of the mechanical balance; lower is better):"]
        for k, bic in sorted(self.k_bic.items()):
            mark = "  <- chosen" if k == chosen else ""
            lines.append(f"  k = {k:g}: {bic:.1f}{mark}")
        lines.append(f"  (k = 3 unless another lowers the BIC by {K_BIC_MARGIN:g} or more)")
        lines += ["", "per motor (departure from the motors' median):"]
        for motor, dev in sorted(self.deviations.items()):
            noise = self.noise.get(motor, {})
            lines.append(
                f"  motor {motor}: "
                + ", ".join(f"{k} {100 * v:+.1f} %" for k, v in dev.items())
                + (
                    f"; balance noise {noise.get('voltage_v', math.nan):.3g} V, "
                    f"{noise.get('torque_nm', math.nan):.3g} N*m"
                    if noise
                    else ""
                )
            )
        if math.isfinite(self.ripple_share):
            lines += [
                "",
                f"duty ripple: the commands jitter by {100 * self.duty_jitter:.1f} % of the duty between "
                f"reports; an input current would read {100 * self.ripple_share:.0f} % above the load's "
                "current from the ripple's copper loss (jitter² over the winding's share of the voltage)",
            ]
        lines += [f"finding: {f}" for f in self.findings]
        return "\n".join(lines)


@dataclass(frozen=True)
class _MotorData:
    motor: int
    time_s: FloatArray
    omega: FloatArray
    command: FloatArray
    bus_v: FloatArray
    current: FloatArray  # the ESC's reading (NaN where none)
    bins: NDArray[np.int64]  # time bin of each sample


def _motor_data(table: TelemetryTable, bin_s: float) -> list[_MotorData]:
    for column in ("throttle", "bus_voltage_v"):
        if column not in table.names:
            raise FitError(
                f"identification needs the motor command and the ESC's bus voltage; the log has no {column!r}"
            )
    reading = table.get("esc_current_a")
    if reading is None:
        reading = table["current_a"]
    t0 = float(np.nanmin(table["time_s"]))
    out = []
    for motor in table.motors():
        sel = np.flatnonzero(table["motor"] == motor)
        sel = sel[np.argsort(table["time_s"][sel], kind="stable")]
        t, w = table["time_s"][sel], table["omega_rad_s"][sel]
        c, v, s = table["throttle"][sel], table["bus_voltage_v"][sel], reading[sel]
        ok = np.isfinite(t) & np.isfinite(w) & np.isfinite(c) & np.isfinite(v) & (c > MIN_COMMAND) & (w > 0)
        if ok.sum() < 20:
            continue
        out.append(
            _MotorData(
                motor=int(motor),
                time_s=t[ok],
                omega=w[ok],
                command=np.clip(c[ok], 0.0, 1.0),
                bus_v=v[ok],
                current=s[ok],
                bins=np.floor((t[ok] - t0) / bin_s).astype(np.int64),
            )
        )
    if len(out) == 0:
        raise FitError("no motor has 20 samples turning under a command with speed and bus voltage")
    return out


def _ke_given_r(terms: _ElectricalTerms, c0: float, side: str, r_ohm: float) -> float:
    """k_e with R fixed (the prior's), where the current cannot part the two: the same balance, one
    unknown."""
    y, x_ke, x_r, duty = terms.rows(c0, side)
    good = (duty > 0.02) & np.isfinite(y) & np.isfinite(x_ke) & np.isfinite(x_r)
    rest = y[good] - r_ohm * x_r[good]
    denominator = float(np.sum(x_ke[good] ** 2))
    return max(float(np.sum(rest * x_ke[good]) / denominator), 1e-7) if denominator > 0 else math.nan


def current_partial_correlation(terms: _ElectricalTerms, c0: float, side: str) -> float:
    """How well the reading follows the motor voltage once the speed is taken out: the partial correlation
    of the balance's current term with its voltage term given its speed term, over the weighted bins
    (NaN where there are too few). Near 1 the current parts R from k_e; near 0 it says nothing of R."""
    y, a, weight = terms.weighted_rows(c0, side)
    ok = (weight > 0) & np.isfinite(y) & np.isfinite(a).all(axis=1)
    if ok.sum() < 10:
        return math.nan
    y, x_ke, x_r = y[ok], a[ok, 0], a[ok, 1]
    denominator = float(x_ke @ x_ke)
    if denominator <= 0:
        return math.nan
    rest_y = y - x_ke * float(y @ x_ke) / denominator
    rest_r = x_r - x_ke * float(x_r @ x_ke) / denominator
    scale = math.sqrt(float(rest_y @ rest_y) * float(rest_r @ rest_r))
    return float(rest_y @ rest_r) / scale if scale > 0 else math.nan


def _ke_from_share(m: _MotorData, esc: EscMap, share: float) -> tuple[float, float]:
    """k_e where the current does not part R from it: the back-EMF takes ``1 − share`` of the motor voltage
    at the flight's loads, ``k_e = (1 − share)·Σ(d·V_bus·ω)/Σω²`` over the motor's samples. Sums over the
    whole flight, linear in the duty: the commands' pairing error (zero-mean) averages out, and no current
    reading enters (neither its side, gain nor the duty ripple an input-side reading carries). Also its
    standard error from the data alone (the ratio's scatter, samples taken as independent): what tells one
    motor from its siblings, which share the same ``share``; the share's own uncertainty is not in it."""
    dv = esc.duty(m.command) * m.bus_v
    w2 = float(np.sum(m.omega**2))
    ratio = float(np.sum(dv * m.omega)) / w2
    scatter = float(np.sum((dv - ratio * m.omega) ** 2)) / max(m.omega.size - 1, 1)
    return (1.0 - share) * ratio, (1.0 - share) * math.sqrt(scatter / w2)


def _r_from_share(terms: _ElectricalTerms, c0: float, side: str, share: float) -> float:
    """R (in the reading's units, R/g) that takes ``share`` of the motor voltage at the flight's loads:
    ``share·Σ⟨d·V⟩/Σ⟨i⟩`` over the weighted bins (the balance's own terms, either side)."""
    y, a, weight = terms.weighted_rows(c0, side)
    ok = (weight > 0) & np.isfinite(y) & np.isfinite(a[:, 1])
    current = float(np.sum(a[ok, 1]))
    return share * float(np.sum(y[ok])) / current if current > 0 else math.nan


def _usable_current(terms: _ElectricalTerms) -> bool:
    """A reading that follows the load: not constant, not zero, and rising with the speed."""
    s, w = terms.s, terms.w
    if s.size < 10 or not np.isfinite(s).all() or np.ptp(s) < 1e-6 or np.mean(np.abs(s)) < 1e-3:
        return False
    r = np.corrcoef(s, w * w)[0, 1]
    return bool(np.isfinite(r) and r > 0.3)


def current_side_test(
    data: Sequence[_MotorData], bin_s: float, motors: Sequence[int] | None = None
) -> SideTest | None:
    """The side the ESCs read their current on, from the reading's elasticity with the bus voltage at a
    given speed (:data:`SIDE_ELASTICITY`: input −1, motor 0). Needs no command, no idle offset and no
    electrical balance, so the commands' pairing and jitter (which bias that balance) do not enter.

    Per time bin and motor, ``log ⟨s⟩ = a_motor + cubic(log ⟨ω⟩) + β·log ⟨V_bus⟩``: the cubic in the
    speed stands for the load at that speed (any propeller exponent, friction); β is the elasticity.
    Two-stage least squares with the voltage's slow part (:data:`SIDE_VOLTAGE_WINDOW_S`) as the
    instrument, and a standard error robust to noise correlated within blocks of that length (the
    clusters). None where too few bins remain for the fit."""
    chosen = [m for m in data if motors is None or m.motor in motors]
    rows = []
    for m in chosen:
        have = np.isfinite(m.current) & np.isfinite(m.bus_v) & (m.bus_v > 0)
        if have.sum() < 10:
            continue
        keys, index, counts = np.unique(m.bins[have], return_inverse=True, return_counts=True)
        means = [np.bincount(index, weights=x[have]) / counts for x in (m.omega, m.current, m.bus_v)]
        rows.append(np.column_stack([np.full(keys.size, m.motor, float), keys.astype(float), *means]))
    if not rows:
        return None
    motor, key, w, s, v = np.vstack(rows).T
    ok = (s > SIDE_MIN_READING_SHARE * float(np.median(s))) & (s > 0) & (w > 0)
    motor, key, w, s, v = motor[ok], key[ok], w[ok], s[ok], v[ok]
    names = np.unique(motor)
    if s.size < 12 * (names.size + 4):  # a dozen bins per coefficient at the least
        return None
    lw = np.log(w / float(np.median(w)))
    lv = np.log(v / float(np.median(v)))
    # the instrument: the voltage's mean over all motors within the window around each bin
    times, at = np.unique(key, return_inverse=True)
    per_time = np.bincount(at, weights=lv) / np.bincount(at)
    half = 0.5 * SIDE_VOLTAGE_WINDOW_S / bin_s
    total = np.concatenate([[0.0], np.cumsum(per_time)])
    lo = np.searchsorted(times, times - half)
    hi = np.searchsorted(times, times + half, side="right")
    slow = ((total[hi] - total[lo]) / (hi - lo))[at]
    controls = [(motor == n).astype(float) for n in names] + [lw, lw**2, lw**3]
    x = np.column_stack([*controls, lv])
    z = np.column_stack([*controls, slow])
    y = np.log(s)
    blocks = np.floor(key * bin_s / SIDE_VOLTAGE_WINDOW_S)
    fitted = _two_stage(x, z, y, blocks)
    if fitted is None:
        return None
    beta, stderr = fitted
    midpoint = 0.5 * (SIDE_ELASTICITY["input"] + SIDE_ELASTICITY["motor"])
    margin = (midpoint - beta) / stderr if stderr > 0 else math.nan
    likelier = "input" if beta < midpoint else "motor"
    # the likelier side must itself fit: an estimate as far from both values says the reading depends on
    # the voltage in some other way on this flight, and the test tells nothing
    fits = abs(beta - SIDE_ELASTICITY[likelier]) <= SIDE_MARGIN_SE * stderr
    side = likelier if abs(margin) >= SIDE_MARGIN_SE and fits else "undetermined"
    return SideTest(float(beta), float(stderr), int(s.size), float(margin), side, likelier, fits)


def _two_stage(
    x: FloatArray, z: FloatArray, y: FloatArray, clusters: FloatArray
) -> tuple[float, float] | None:
    """The last coefficient of ``y = x·b`` by two-stage least squares with instruments ``z`` (same
    columns but the last), and its standard error robust to noise correlated within each cluster."""
    try:
        projection = np.linalg.lstsq(z, x, rcond=None)[0]
        x_hat = z @ projection
        a = x_hat.T @ x
        coef = np.linalg.solve(a, x_hat.T @ y)
        inverse = np.linalg.inv(a)
    except np.linalg.LinAlgError:
        return None
    resid = y - x @ coef
    labels, index = np.unique(clusters, return_inverse=True)
    if labels.size < 3:
        return None
    scores = np.zeros((labels.size, x.shape[1]))
    np.add.at(scores, index, x_hat * resid[:, None])
    cov = inverse @ (scores.T @ scores) @ inverse.T * labels.size / (labels.size - 1)
    variance = float(cov[-1, -1])
    if not (math.isfinite(variance) and variance > 0 and math.isfinite(coef[-1])):
        return None
    return float(coef[-1]), math.sqrt(variance)


def battery_current_pairs(
    table: TelemetryTable, side: str, esc: EscMap, *, bin_s: float = 1.0
) -> tuple[FloatArray, FloatArray] | None:
    """The ESCs' summed input current and the battery monitor's current, each averaged over the same
    ``bin_s`` bins of the log (a motor-side reading turned into input current with the duty ``esc`` gives),
    over the samples identification uses (turning, under a command); None without the monitor, a reading
    on every motor, or ten common bins."""
    return _battery_pairs(_motor_data(table, bin_s), table, side, esc, bin_s)


def _battery_pairs(
    data: Sequence[_MotorData], table: TelemetryTable, side: str, esc: EscMap, bin_s: float = 1.0
) -> tuple[FloatArray, FloatArray] | None:
    """:func:`battery_current_pairs` of the motors' samples already gathered."""
    battery = table.get("battery_current_a")
    if battery is None or not np.isfinite(battery).any():
        return None
    t0 = float(np.nanmin(table["time_s"]))
    per_motor = []
    for m in data:
        have = np.isfinite(m.current)
        if not have.any():
            return None
        duty = esc.duty(m.command[have])
        reading = m.current[have] if side == "input" else m.current[have] * duty
        bins = np.floor((m.time_s[have] - t0) / bin_s).astype(np.int64)
        keys, index, counts = np.unique(bins, return_inverse=True, return_counts=True)
        per_motor.append(dict(zip(keys.tolist(), (np.bincount(index, weights=reading) / counts).tolist())))
    common = sorted(set.intersection(*(set(d) for d in per_motor)))
    if len(common) < 10:
        return None
    esc_sum = np.array([sum(d[k] for d in per_motor) for k in common])
    bt = table["time_s"]
    good = np.isfinite(battery) & np.isfinite(bt)
    bbins = np.floor((bt[good] - t0) / bin_s).astype(np.int64)
    keys, index, counts = np.unique(bbins, return_inverse=True, return_counts=True)
    bmean = dict(zip(keys.tolist(), (np.bincount(index, weights=battery[good]) / counts).tolist()))
    pairs = [(e, bmean[k]) for e, k in zip(esc_sum, common) if k in bmean]
    if len(pairs) < 10:
        return None
    e, b = np.array(pairs).T
    return e, b


def _battery_gain(
    data: Sequence[_MotorData], table: TelemetryTable, side: str, esc: EscMap
) -> tuple[float, float] | None:
    """(gain, offset A) of the ESCs' summed input current against the battery monitor, or None."""
    pairs = _battery_pairs(data, table, side, esc)
    return None if pairs is None else gain_from_pairs(*pairs)


def gain_from_pairs(esc_sum_a: FloatArray, battery_a: FloatArray) -> tuple[float, float]:
    """(gain, offset A) from :func:`battery_current_pairs`: the ratio of the charges both counted over
    the flight, the rest of the vehicle's draw not told apart (offset 0: the gain comes out low by that
    draw's share of the battery current, avionics ~0.5-1 A of 5-50 A).

    Not the regression of the ESCs' sum on the battery's current: the monitor is a filtered current
    reported at 1-2 Hz in a .tlog, so each bin's pair is paired loosely, and the slope reads the lag as
    a weaker or stronger dependence (development worlds 0-19: slopes -0.12 to 0.50 for true gains of
    0.76-1.09, offsets -4.9 to -778 A; the real PX4 quad read on the input side: slope 0.81 with 23.6 A
    for the rest of a quad drawing 26-74 A; docs/model.md). A lag moves charge in time but not how much."""
    return float(np.sum(esc_sum_a) / np.sum(battery_a)), 0.0


def command_jitter(values: FloatArray) -> float:
    """How much a logged command moves from one logged value to the next: the spread of the successive
    differences of its distinct successive values, /√2 (the spread of each value about its neighbours'
    level for independent moves; a value held over several samples is one value). NaN with ten distinct
    values or fewer."""
    changed = values[np.concatenate([[True], values[1:] != values[:-1]])] if values.size else values
    return float(np.std(np.diff(changed))) / math.sqrt(2.0) if changed.size > 10 else math.nan


def duty_ripple_share(data: Sequence[_MotorData], esc: EscMap, k_e: float) -> tuple[float, float]:
    """(jitter, ripple share): how much the duty moves between reports, and what that does to a current
    read on the ESC's input side (module doc of :mod:`..diagnosis.rules.equations`, "An input current's
    ripple"). The input current the ESC averages is ``mean(d·i) = d̄·ī + V·σ_d²/R``: the motor current
    follows the duty's fast part (``δi = δd·V/R``, the rotor too slow to follow), and the two together
    lose power in the winding. Relative to the load's ``d̄·ī`` that is ``(σ_d/d̄)² / s``, with ``s`` the
    winding's share of the motor voltage, ``R·ī/(d̄·V)``. ``σ_d/d̄`` is read from the logged commands
    (each motor: :func:`command_jitter` of its duties over its median duty; the motors' median), ``s`` as ``1 − k_e·ω/(d·V)`` at the motors' median (at least 0.02). A flight-level figure:
    the duty between two reports is not in the log, only samples of it."""
    jitters, shares = [], []
    for m in data:
        duty = esc.duty(m.command)
        spread, level = command_jitter(duty), float(np.median(duty))
        if math.isfinite(spread) and level > 0:
            jitters.append(spread / level)
        motor_v = duty * m.bus_v
        ok = motor_v > 0
        if ok.any():
            shares.append(float(np.median(1.0 - k_e * m.omega[ok] / motor_v[ok])))
    if not jitters or not shares:
        return math.nan, math.nan
    jitter = float(np.median(jitters))
    return jitter, jitter**2 / max(float(np.median(shares)), 0.02)


def _lowpass(time_s: FloatArray, values: FloatArray, tau_s: float) -> FloatArray:
    return first_order_response(time_s, values, tau_s)[0]


def _motor_current(m: _MotorData, esc: EscMap, side: str, gain: float) -> FloatArray | None:
    """The motor current [A] the diagnosis will read from this motor's reading (the sensor's gain
    removed; an input-side reading divided by the duty, as :func:`.vehicle.calibrate_columns` does),
    gaps filled with the last reading; None without a usable reading."""
    if side not in SIDE_ELASTICITY or not np.isfinite(m.current).any():
        return None
    true = m.current / gain
    current = motor_current_a(true, esc.duty(m.command)) if side == "input" else true
    have = np.isfinite(current)
    if have.sum() < 20:
        return None
    last = np.maximum.accumulate(np.where(have, np.arange(current.size), 0))
    filled = current[last]
    return np.where(np.isfinite(filled), filled, current[have][0])


def _twice(time_s: FloatArray, values: FloatArray, tau_s: float) -> FloatArray:
    """The second-order state-variable filter F: two first-order low-passes of ``tau_s``."""
    return _lowpass(time_s, _lowpass(time_s, values, tau_s), tau_s)


def _settled(time_s: FloatArray, tau_s: float) -> NDArray[np.bool_]:
    """The samples after F has settled from its start."""
    return time_s - time_s[0] > 6 * tau_s


def _mechanical_design(m: _MotorData, k: float, tau_s: float) -> FloatArray:
    """The mechanical balance k_t·i = C_p·ω^k + B·ω + T_f + J·dω/dt through F (:func:`_twice`): the
    design matrix [F(ω^k), F(ω), 1, d F(ω)/dt] over the settled samples. The second stage keeps the
    speed's sample noise out of the derivative (with one stage, d F(ω)/dt = (ω − F(ω))/τ carries it
    whole, and the inertia, a coefficient on a regressor measured with noise, comes out low)."""
    t = m.time_s
    once = _lowpass(t, m.omega, tau_s)
    w_bar = _lowpass(t, once, tau_s)
    a = np.column_stack([_twice(t, m.omega**k, tau_s), w_bar, np.ones_like(t), (once - w_bar) / tau_s])
    return a[_settled(t, tau_s)]


def _mechanical_targets(
    m: _MotorData, esc: EscMap, k_e: float, r_ohm: float, tau_s: float, current_a: FloatArray | None
) -> list[FloatArray]:
    """F(k_t·i) over the settled samples, per route: i from the voltage balance, (d·V − k_e·ω)/R, and
    (where the ESC reports a usable one) the motor current ``current_a``."""
    t = m.time_s
    torques = [k_e * (esc.duty(m.command) * m.bus_v - k_e * m.omega) / r_ohm]
    if current_a is not None:
        torques.append(k_e * current_a)
    settled = _settled(t, tau_s)
    return [_twice(t, torque, tau_s)[settled] for torque in torques]


def _scatter(rows: Sequence[tuple[FloatArray, FloatArray]]) -> float:
    """The RMS residual of an unregularised fit (C_p, B, T_f, J ≥ 0) of the rows: their noise scale."""
    a = np.vstack([r[0] for r in rows])
    y = np.concatenate([r[1] for r in rows])
    return max(float(np.std(fit_linear(a, y, MECHANICAL_NAMES).residual)), 1e-12)


def _mechanical_fit(
    rows: Sequence[tuple[FloatArray, FloatArray]], prior: FloatArray, prior_sd: FloatArray
) -> tuple[FloatArray, FloatArray, float, int]:
    """(C_p, B, T_f, J) ≥ 0 with a Gaussian prior, their standard errors, the data's SSE and count."""
    a = np.vstack([r[0] for r in rows])
    y = np.concatenate([r[1] for r in rows])
    sigma = _scatter(rows)  # noise scale from an unregularised fit, to weigh the prior against the data
    weak = np.isfinite(prior_sd)
    a_aug = np.vstack([a / sigma, np.diag(1.0 / np.where(weak, prior_sd, 1.0))[weak]])
    y_aug = np.concatenate([y / sigma, (prior / np.where(weak, prior_sd, 1.0))[weak]])
    # every row already in units of its noise (the data's σ, the prior's sd): the covariance as it stands
    fit = fit_linear(a_aug, y_aug, MECHANICAL_NAMES, title="mechanical balance", scale_covar=False)
    sse = float(np.sum((y - a @ fit.x) ** 2))
    return fit.x, fit.x_stderr, sse, y.size


def identify(
    table: TelemetryTable,
    prior: MotorParams,
    *,
    bin_s: float = 0.25,
    k: float | None = None,
    name: str = "identified motor",
    copper_share: float | None = COPPER_SHARE,
) -> Identification:
    """Identify the vehicle in ``table`` (a healthy flight); ``prior`` fills what the data cannot say.

    Where the current does not part R from k_e (:func:`current_partial_correlation` below
    :data:`R_PARTIAL_CORRELATION_MIN`, or R on its bound), and where the ESCs report no usable current,
    k_e is the motor voltage over the speed with ``copper_share`` taken off for the winding, and R the
    resistance that takes that share at this flight's current; with ``copper_share`` None (a prior the user
    gave: a bench fit of the motor) R is the prior's and k_e is fitted with it.

    The balances' time bins are at least :data:`PAIRING_BINS` times the log's pairing of ESC samples
    with commands (``pairing_s`` in the table's meta, where the reader measured it), so that a command
    paired a report interval away averages out within a bin."""
    pairing_s = float(table.meta.get("pairing_s") or 0.0)
    bin_s = max(bin_s, PAIRING_BINS * pairing_s) if math.isfinite(pairing_s) else bin_s
    data = _motor_data(table, bin_s)
    terms = {
        m.motor: _ElectricalTerms.from_samples(m.command, m.bus_v, m.omega, m.current, m.bins) for m in data
    }
    usable = {motor: _usable_current(t) for motor, t in terms.items()}
    findings: list[str] = []
    c0_stderr = math.inf
    side_test: SideTest | None = None
    guessed = False  # the side the smaller residual chose, the side test not telling
    if sum(usable.values()) >= max(1, len(usable) // 2 + 1):
        with_current = {mo: t for mo, t in terms.items() if usable[mo]}
        fits = {side: _pooled_electrical(with_current, side) for side in ("input", "motor")}
        residual_v = {s: fits[s][1] for s in fits}
        # the side from the reading's dependence on the bus voltage, not from the residuals: the two
        # balances differ only in R·i's share of the duty, a few per cent of a volt, and the commands'
        # pairing biases them by more (docs/model.md, "Which side the ESC reads")
        side_test = current_side_test(data, bin_s, [mo for mo in usable if usable[mo]])
        if side_test is not None and side_test.side in SIDE_ELASTICITY:
            side = side_test.side
        else:
            guessed = True
            told = f" ({side_test.describe()})" if side_test is not None else ""
            found = {s: _battery_gain(data, table, s, EscMap(fits[s][0])) for s in fits}
            charges = {s: r[0] for s, r in found.items() if r is not None and r[0] > 0}
            if len(charges) == len(found):
                # the side whose sensor gain the battery's charge makes nearer 1: read on the wrong side
                # the sum comes out near duty x (input as motor) or 1/duty x (motor as input) the battery's
                side = min(charges, key=lambda s: abs(math.log(charges[s])))
                why = (
                    f"the ESCs' summed charge is {charges['input']:.2f} x the battery monitor's read "
                    f"as input current, {charges['motor']:.2f} x as motor current (x duty): the gain "
                    f"nearer 1 chose"
                )
            else:
                # no battery monitor to weigh the charges: the side the balance fits the better (on
                # development worlds it often picks the motor side for an input-side reading)
                side = min(fits, key=lambda s: fits[s][1])
                why = "no battery monitor to compare the charges with: the balances' smaller residual chose"
            findings.append(
                f"the flight does not tell which side the ESCs read their current on{told}: the "
                f"current is taken as the {side} side's, a guess ({why}); a flight with more of the "
                "battery's discharge would tell"
            )
        c0, _, c0_stderr = fits[side]
    else:
        side, residual_v = "unusable", {}
        c0 = _speed_only_offset(data, prior)
        findings.append(
            "the ESCs report no usable current: R is the prior's, the current is not judged"
            + (
                f"; k_e is the motor voltage over the speed with the winding's typical share "
                f"({100 * copper_share:.0f} %) taken off"
                if copper_share is not None
                else ""
            )
        )
    offset_from = "data"
    if side == "unusable" and min(abs(c0 - b) for b in SPEED_ONLY_OFFSET_RANGE) < 1e-3:
        c0, offset_from = 0.0, "prior"
        findings.append(
            "the speeds do not determine the ESC's idle offset (the search ended on its bound): taken as 0, "
            "the autopilot's PWM range"
        )
    # whether the current parts R from k_e on this flight: the motors' median partial correlation at the
    # balance's own idle offset
    partial = [
        current_partial_correlation(terms[m.motor], c0, side)
        for m in data
        if side != "unusable" and usable.get(m.motor)
    ]
    partial_r = float(np.nanmedian(partial)) if np.isfinite(partial).any() else math.nan
    parted = bool(partial_r >= R_PARTIAL_CORRELATION_MIN)
    if side != "unusable" and not c0_stderr <= IDLE_OFFSET_STDERR_MAX:
        c0, offset_from = 0.0, "prior"
        findings.append(
            "the flight does not determine the ESC's idle offset (the commands moved too little at a "
            "steady battery voltage): taken as 0, the autopilot's PWM range; fly climbs, descents and yaw"
        )
    elif side != "unusable" and not parted and copper_share is not None:
        # the offset came from the same balance, whose R went where the pairing, not the load, put it:
        # with k_e from the winding's share it would be half of a pair fitted together (it trades off
        # with k_e), and extrapolates wrongly where the flight did not go
        c0, offset_from = 0.0, "prior"
        findings.append(
            "the balance that gave the ESC's idle offset does not part R from k_e (below): the offset is "
            "taken as 0, the autopilot's PWM range"
        )
    esc = EscMap(idle_offset=c0)
    per_motor_e: dict[int, tuple[float, float]] = {}
    per_motor_err: dict[int, tuple[float, float]] = {}
    noise: dict[int, dict[str, float]] = {}
    r_share: dict[int, float] = {}  # R/g where the data do not give it: the copper share's
    for m in data:
        if side != "unusable" and usable.get(m.motor):
            coef, err_e, resid = _electrical_fit(terms[m.motor], c0, side)
            # R at its bound, or a current that does not follow the voltage, says the current did not
            # part R from k_e here: not a zero resistance
            r_fit = float(coef[1]) if coef[1] > 1e-9 and parted else math.nan
            if not math.isfinite(r_fit) and copper_share is not None:
                share_r = _r_from_share(terms[m.motor], c0, side, copper_share)
                if math.isfinite(share_r) and share_r > 0:
                    r_share[m.motor] = share_r
            k_e_err = float(err_e[0])
            if math.isfinite(r_fit):
                k_e_fit = float(coef[0])
            elif copper_share is not None:
                k_e_fit, k_e_err = _ke_from_share(m, esc, copper_share)
            else:
                k_e_fit = _ke_given_r(terms[m.motor], c0, side, prior.R_ohm)
            per_motor_e[m.motor] = (k_e_fit, r_fit)
            per_motor_err[m.motor] = (k_e_err, float(err_e[1]))
            noise[m.motor] = {"voltage_v": _rms(resid)}
        else:
            k_e_speed = (
                _ke_from_share(m, esc, copper_share)[0]
                if copper_share is not None
                else _speed_only_ke(m, esc, prior)
            )
            per_motor_e[m.motor] = (k_e_speed, math.nan)
            per_motor_err[m.motor] = (math.nan, math.nan)
            noise[m.motor] = {}
    gain_fit = _battery_gain(data, table, side, esc) if side != "unusable" else None
    if gain_fit is not None and not BATTERY_GAIN_RANGE[0] <= gain_fit[0] <= BATTERY_GAIN_RANGE[1]:
        findings.append(
            f"the ESCs' summed current is {gain_fit[0]:.2f} x the battery monitor's: too far off to be a "
            "sensor's gain (a monitor that does not see the ESCs, or loose pairing); gain taken as 1"
        )
        gain_fit = None
    gain, offset, gain_from = (1.0, 0.0, "assumed") if gain_fit is None else (*gain_fit, "battery")
    k_e_type = float(np.median([v[0] for v in per_motor_e.values()]))
    r_values = [v[1] * gain for v in per_motor_e.values() if math.isfinite(v[1])]
    # R where the data did not give it: the share's (or the prior's) in ohms, the reading's gain applied
    r_ohm_assumed = {mo: r * gain for mo, r in r_share.items()}
    if r_values:
        r_type = float(np.median(r_values))
    elif r_ohm_assumed:
        r_type = float(np.median(list(r_ohm_assumed.values())))
    else:
        r_type = prior.R_ohm
    if not r_values and side != "unusable":
        told = (
            f"the speed taken out, it follows the motor voltage with a partial correlation of only "
            f"{partial_r:.2f} < {R_PARTIAL_CORRELATION_MIN:g}: too little of what moves it is the load's, "
            "as in a flight of little load change or with commands paired loosely with the ESC reports"
            if not parted
            else "R at its bound on every motor"
        )
        if copper_share is not None and r_ohm_assumed:
            findings.append(
                f"the current did not part R from k_e ({told}): k_e is the motor voltage over the speed "
                f"with {100 * copper_share:.0f} % taken off for the winding (a multirotor motor's typical "
                "share at its flight loads), and R the resistance that takes that share at this flight's "
                "current; give a bench fit of the motor with --prior for its own R"
            )
        else:
            findings.append(f"the current did not part R from k_e ({told}): R is the prior's")
    # mechanical: each candidate k over all motors with their own electrical constants
    motors_r = {
        mo: (v[1] * gain if math.isfinite(v[1]) else r_ohm_assumed.get(mo, r_type))
        for mo, v in per_motor_e.items()
    }
    w_typ = float(np.median(np.concatenate([m.omega for m in data])))
    load = prior.C_p * w_typ**prior.k + prior.B * w_typ + prior.T_f
    jitter, ripple = duty_ripple_share(data, esc, k_e_type)
    rippled = side == "input" and ripple >= RIPPLE_SHARE_MAX
    candidates = (k,) if k is not None else K_CANDIDATES
    # the torque from the motor current the ESC reports, where it does: the quantity the diagnosis
    # compares with the model, read at the speed's own instant (the voltage balance's (d·V − k_e·ω)/R
    # divides the commands' pairing error by R, which the balance often puts near its bound)
    measured = {m.motor: _motor_current(m, esc, side, gain) if usable.get(m.motor) else None for m in data}

    targets = {
        m.motor: _mechanical_targets(
            m, esc, per_motor_e[m.motor][0], motors_r[m.motor], MECHANICAL_TAU_S, measured[m.motor]
        )
        for m in data
    }
    if not any(y.size for ys in targets.values() for y in ys):
        raise FitError(
            f"no motor turned for longer than the mechanical balance's filter needs to settle "
            f"({6 * MECHANICAL_TAU_S:g} s); expected a flight of tens of seconds"
        )
    results = {}
    for kk in candidates:
        design = {m.motor: _mechanical_design(m, kk, MECHANICAL_TAU_S) for m in data}
        # the routes (the voltage balance's torque for every motor, the reported current's where there is
        # one), fitted together, each in units of its own scatter: where R came out near its bound the
        # voltage route's torque is the commands' pairing error over R and counts for little; where the
        # reading is averaged or lags, the current route's inertia term does
        routes = [
            [(design[mo], ys[r]) for mo, ys in targets.items() if len(ys) > r and ys[r].size] for r in (0, 1)
        ]
        rows = [(a / sd, y / sd) for route in routes if route for sd in [_scatter(route)] for a, y in route]
        # B·ω and T_f are small shares of a propeller's load: a weak prior of 0 ± PRIOR_SHARE of it
        prior_x = np.zeros(4)
        prior_sd = np.array([np.inf, PRIOR_SHARE * load / w_typ, PRIOR_SHARE * load, np.inf])
        x, err, sse, n = _mechanical_fit(rows, prior_x, prior_sd)
        bic = n * math.log(max(sse / n, 1e-300)) + 4 * math.log(n)
        results[kk] = (x, err, bic)
    k_bic = {kk: r[2] for kk, r in results.items()}
    w_all = np.concatenate([m.omega for m in data])
    span = float(np.percentile(w_all, 95) / max(np.percentile(w_all, 5), 1e-9))
    if k is not None:
        chosen = k
    elif rippled:
        chosen = 3.0
        findings.append(
            f"the input current read on this flight is mostly the duty ripple's copper loss, not the load "
            f"(it reads about {100 * ripple:.0f} % above the load's current: the commands jitter by "
            f"{100 * jitter:.0f} % of the duty between reports): k = 3, the paper's; the propeller load and "
            "the current bands carry the ripple and read too high in calmer air; identify from a calmer "
            "flight (less wind, gentler manoeuvres)"
        )
    elif span < K_SPEED_SPAN:
        chosen = 3.0
        findings.append(
            f"the motors turned over too narrow a range (95th/5th percentile of speed {span:.2f} < "
            f"{K_SPEED_SPAN:g}) to tell the propeller exponent: k = 3, the paper's"
        )
    else:
        chosen = choose_exponent(k_bic)
    x, err, _ = results[chosen]
    for m in data:  # each motor's mechanical balance residual under the shared fit: its noise floor
        y = targets[m.motor][-1]  # on the reported current where there is one
        noise[m.motor]["torque_nm"] = _rms(y - _mechanical_design(m, chosen, MECHANICAL_TAU_S) @ x)
    c_p, b, t_f, inertia = (float(v) for v in x)
    determined = {
        "idle_offset": offset_from,
        # R from the copper share is still read through the current (its side and gain): the guess says so
        "R_ohm": (
            "prior" if not r_values else ("data" if gain_from == "battery" else "data (x current gain)")
        )
        + (f" as for the {side} side (a guess)" if guessed and (r_values or r_ohm_assumed) else ""),
        # without a current that parts R from it, k_e is the motor voltage over the speed less the
        # winding's typical share: the data's ratio, the prior's share
        "k_e": "data" if r_values else ("data and prior" if copper_share is not None else "data"),
        "C_p": "data",
        "B": "data" if err[1] < 0.5 * PRIOR_SHARE * load / w_typ else "prior",
        "T_f": "data" if err[2] < 0.5 * PRIOR_SHARE * load else "prior",
        "J_kg_m2": "data" if inertia > 0 and err[3] < 0.5 * inertia else "prior",
    }
    if inertia <= 0:
        inertia = prior.J_kg_m2 or 0.0
    params = MotorParams(
        R_ohm=r_type, k_e=k_e_type, C_p=c_p, B=b, T_f=t_f, k=chosen, name=name, J_kg_m2=inertia or None
    )
    per_motor = {}
    deviations = {}
    for mo, (ke, rr) in per_motor_e.items():
        r_m = rr * gain if math.isfinite(rr) else r_ohm_assumed.get(mo, r_type)
        per_motor[mo] = params.replace(R_ohm=r_m, k_e=ke, name=f"{name}, motor {mo}")
        deviations[mo] = {"k_e": ke / k_e_type - 1.0, "R_ohm": r_m / r_type - 1.0}
        # a departure counts where it is large and the motor's own fit is sure of it (3 standard errors)
        rel_err = {
            "k_e": per_motor_err[mo][0] / ke,
            "R_ohm": per_motor_err[mo][1] / rr if rr > 0 else math.inf,
        }
        off = [
            key
            for key, v in deviations[mo].items()
            if abs(v) > SIBLING_DEPARTURE and abs(v) > 3 * rel_err[key]
        ]
        if off:
            findings.append(f"motor {mo} departs from its siblings in {', '.join(off)}")
    t_all = np.concatenate([m.time_s for m in data])
    return Identification(
        params=params,
        per_motor=per_motor,
        esc=esc,
        current=CurrentReading(
            side=side,
            gain=gain,
            gain_from=gain_from,
            offset_a=offset,
            residual_v=residual_v,
            side_test=side_test,
        ),
        stderr={
            "R_ohm": _median_stderr([v[1] * gain for v in per_motor_e.values() if math.isfinite(v[1])]),
            "k_e": _median_stderr([v[0] for v in per_motor_e.values()]),
            "C_p": float(err[0]),
            "B": float(err[1]),
            "T_f": float(err[2]),
            "J_kg_m2": float(err[3]),
        },
        determined_by=determined,
        k_bic=k_bic,
        deviations=deviations,
        noise=noise,
        samples=int(sum(m.time_s.size for m in data)),
        span_s=(float(t_all.min()), float(t_all.max())),
        findings=tuple(findings),
        duty_jitter=jitter,
        ripple_share=ripple,
    )


def electrical_balance_at(
    table: TelemetryTable, idle_offset: float, side: str, *, bin_s: float = 0.25
) -> dict[int, tuple[float, float]]:
    """Each motor's (k_e, R/g) ≥ 0 from its electrical balance alone at a *given* idle offset and current
    side (``"input"`` or ``"motor"``): no search, no prior, no refit where R lands on its bound (then
    R/g is 0). The same bins and balance :func:`identify` fits: with the truth's ESC map and side it
    measures what the balance itself makes of a log (``benchmarks/bench_identify_worlds.py``)."""
    if side not in ("input", "motor"):
        raise ValueError(f"side {side!r}: expected 'input' or 'motor'")
    pairing_s = float(table.meta.get("pairing_s") or 0.0)
    bin_s = max(bin_s, PAIRING_BINS * pairing_s) if math.isfinite(pairing_s) else bin_s
    out = {}
    for m in _motor_data(table, bin_s):
        terms = _ElectricalTerms.from_samples(m.command, m.bus_v, m.omega, m.current, m.bins)
        if terms.s.size >= 10:
            coef, _, _ = _electrical_fit(terms, idle_offset, side)
            out[m.motor] = (float(coef[0]), float(coef[1]))
    return out


def back_emf_share_at(
    table: TelemetryTable, idle_offset: float, *, share: float = COPPER_SHARE
) -> dict[int, float]:
    """Each motor's k_e from the motor voltage over the speed with ``share`` taken off for the winding
    (what :func:`identify` takes where the current does not part R from k_e), at a *given* idle offset:
    with the truth's offset it measures what the rule itself makes of a log
    (``benchmarks/bench_identify_worlds.py``)."""
    esc = EscMap(idle_offset=idle_offset)
    return {m.motor: _ke_from_share(m, esc, share)[0] for m in _motor_data(table, 0.25)}


def _rms(values: FloatArray) -> float:
    good = np.isfinite(values)
    return float(np.sqrt(np.mean(values[good] ** 2))) if good.any() else math.nan


def _median_stderr(values: Sequence[float]) -> float:
    """Standard error of the motors' median (1.25·σ/√n; NaN for fewer than two motors)."""
    if len(values) < 2:
        return math.nan
    return float(1.2533 * np.std(values, ddof=1) / math.sqrt(len(values)))


def _speed_only_ke(m: _MotorData, esc: EscMap, prior: MotorParams) -> float:
    """k_e from speed alone: d·V = k_e·ω + R·i with the current the prior's load needs at ω."""
    from .equations import current_from_speed

    dv = esc.duty(m.command) * m.bus_v
    ri = prior.R_ohm * current_from_speed(prior, m.omega)
    return float(np.sum((dv - ri) * m.omega) / np.sum(m.omega**2))


def _speed_only_offset(data: Sequence[_MotorData], prior: MotorParams) -> float:
    def cost(c0: float) -> float:
        esc = EscMap(c0)
        total = 0.0
        for m in data:
            ke = _speed_only_ke(m, esc, prior)
            total += float(np.mean((esc.duty(m.command) * m.bus_v - ke * m.omega) ** 2))
        return total

    # scipy.optimize where a fit needs it: its import takes about 0.12 s here, which replay and the
    # agent would pay at every start (issue 18; tests/test_cli_arguments.py)
    from scipy.optimize import minimize_scalar

    found = minimize_scalar(cost, bounds=SPEED_ONLY_OFFSET_RANGE, method="bounded")
    return float(found.x)
