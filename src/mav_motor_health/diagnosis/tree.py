"""The fault decision tree (paper Fig. 7, section III.B), vectorised over samples.

Our reading of the paper, checked against the transitions it reports in section IV.A:

1. ω below the stop speed (100 rad/s): ``F2.1`` if i < 6 A, else ``F4.2`` (the motor stalls; a broken
   back-EMF signal keeps the phases driven and draws more current than an open phase);
2. ω above the speed band and i below the current band: ``F3.1`` (a lighter propeller). Above the model,
   the band is narrowed where the model speed is near the free speed (see "Free-speed headroom" below);
3. ω and i both inside their bands: ``NORMAL``;
4. otherwise, with ω inside or below its band: ``F1.1`` if i is above its band (friction: slower and more
   current), else ``F4.1`` (an open transistor: slower and less current);
5. anything else (ω above its band with i inside or above): ``UNKNOWN``.

Departures that agree (our addition for flight). Each fault moves speed and current together in its own
direction: F1.1 slower with more current, F3.1 faster with less, F4.1 slower with less. In flight the
bands must be wide (the input moves, the telemetry samples it late), and a fault of small severity, or a
fault where the current is small (an open transistor acts like extra resistance, ``R·i``), moves each
quantity by less than its band but both at once. Where speed and current both leave the model in a
fault's direction, by shares of their bands (``|ω − ω_model|/band_ω`` and ``|i − i_model|/band_i``)
that add up to at least ``joint_band_sum`` (c, between 1 and 2), the tree names that fault; in the
simulated flights healthy noise seldom pushes both at once that way (speed and current residuals are
nearly uncorrelated there). NORMAL samples can so become F1.1, F3.1 or F4.1. It also settles "current
low, speed inside its band", which the paper calls F4.1 (an open transistor, which *lowers* the speed):
with the speed *above* the model by enough to make up the sum, it is F3.1, a slightly lighter propeller,
whose load torque falls as the blade length to the 5th power but whose speed rises only a little (the
motor's resistance is small, :mod:`..model.balance`). c = 0 (the default, and the testbed profile): the
paper's tree.

"Current low" and "current high" may use different widths: a profile whose ``activity_band`` has a
fourth column widens the current band apart below and above the model (in gusty air the healthy current
deviation is skewed; docs/flight.md, section 2b). The shares below the model are taken of the side below.

Where the current is absent or not trusted (``current_trusted`` False), only speed is used: ``STALLED``
(F2.1 or F4.2) below the stop speed, ``SLOW`` (F1.1 or F4.1) far below the model speed, ``FAST`` (F3.1)
far above it, else ``NORMAL``: the states name the faults that speed alone cannot tell apart. "Far" is
the wider of the speed band and ``speed_only_band_frac`` of the model speed: without the current, an error
of the model (an extrapolated calibration, say) cannot be told from a fault. Where the bands are the
vehicle's own noise (``flight_vehicle``: ``speed_only_band_frac = 0``) the speed band alone: identification
measured how far this vehicle's speed departs from its model where it flew, the speed is judged only
there, and against its siblings' prediction where that is narrower (what the shared model gets wrong
leaves it); a share of the model speed would be a constant carried from no vehicle (on held-out world
1007, whose ESCs report no usable current, friction left its motor 6 % slower than its model and was never
named; docs/flight.md, "Speed only, in the vehicle's own noise; a command dip between two reports as a
step").

With ``stop_speed_fraction`` f > 0 (our addition, the flight profile: 0.25) the stop speed is the larger of
100 rad/s and f × the expected speed: a motor turning at less than a quarter of the speed its input gives
is stopping (the other faults slow a motor by far less than three quarters), and a stalling rotor is named
while it runs down through that speed instead of below 100 rad/s (docs/flight.md, section 2b).

Depth (our addition, :func:`classify_depth`): each sample's departure measured in bands, 1 on its
state's boundary: for F1.1 the current's share of its band (or, for departures that agree, the sum of the shares
over ``joint_band_sum``), for F4.1 the larger of the speed's and the current's share (or the sum over c),
for F3.1 the lesser of the two (both must be out; or the sum over c), for UNKNOWN the speed's share; 1 on
the boundary and for NORMAL, the stalls and the speed-only states. Persistence lets a deep sample count
its interval that many times (``persistence.max_depth``), so that a clear fault is announced sooner
than a flicker on the edge of a band.

Rule 1 applies only where the model itself expects the motor to turn faster than the stop speed plus the
speed band: a motor at idle or disarmed is not "stopped" in the paper's sense (its testbed never ran below
4 V, 390 rad/s). This is our addition. ``omega_expected_rad_s`` (default: the model speed) is the speed the
model is sure of; in flight the pipeline passes the lower of the steady state and its lagged response, so
that a motor spinning down after its command dropped is not taken for a stalled one.

The lowest input (rule 1, our addition; ``stop_speed_lowest_fraction`` g > 0, the ``flight_vehicle``
profile). 100 rad/s is the paper's motor, whose idle speed is about 136 rad/s (0.12 of a 3S bus); a
heavy-lift motor on a 0.8-m propeller idles near 25 rad/s and hovers near 180, and in gusts its controller
drives it to idle and back several times a second. A log pairs each speed with one command, at most
tens of times a second, so such a motor read 44 rad/s "at" a command of 0.73 and looked stalled (23 of
the 36 false events in ten healthy hours on twenty held-out worlds were such stalls, docs/flight.md, "The
stop speed from the lowest input"). Whatever a log paired it with, a healthy motor never
turns much slower than the lowest input it is given: after any input it runs down towards that input's
speed from above. So the stop speed (and the absolute floor of the "expects a turning motor" test) is
at most g × the free speed ``V_low/k_e`` of the lowest positive input ``V_low`` the motor has been given
in the stream so far (the balance rule carries it; a log of the armed vehicle soon holds its idle). A
stalled rotor (a phase open, a lost back-EMF signal) is held near 0 rad/s and stays below that cap.

Free-speed headroom (rule 2, our addition). No fault can make a motor turn faster than its free speed
``V/k_e``, where the back-EMF equals the input voltage: a lighter propeller (F3.1), even none at all, can
raise the speed by at most the headroom ``V/k_e − ω_model``. With the paper's motor that headroom is
220 rad/s at 11 V but only 20.4 rad/s at 4.2 V, the ±20 rad/s band itself: there the paper's trimmed
propeller lifts the speed by 20.2 rad/s, so with the ±10 rad/s speed noise the full band leaves the tree
flickering between F3.1 and F4.1 (about half the samples each, F3.1 announced well after the paper's
0.35 s), while the paper reports F3.1 diagnosed in all five testbed cases within 0.35 s. So above the
model the band narrows to a share of the headroom:

    speed_high  ⇔  ω > ω_model + clip(f · (V/k_e − ω_model), band/2, band),
    f = ``free_speed_headroom_fraction`` (default 0.5: halfway between the model and the free speed).

That is min(band, f · headroom) with a floor: never below half the band, the speed noise (the paper set
the band at twice its ±10 rad/s noise). Without the floor a healthy motor near idle, where the headroom
vanishes but the noise does not, would read as "faster" on noise alone, the more often the lower the
voltage. At 4.2 V the floor does not bind (half the headroom is 10.19 rad/s).

Only the upper side changes: ``speed_low`` keeps the full band. The narrowing applies only where
``omega_free_rad_s`` (``V/k_e`` per sample) is given; without it, the full band as before. A healthy
sample beyond the narrowed band with its current inside the band is ``UNKNOWN`` (rule 5) for that
sample; F3.1 still needs the current below its band. The speed-only branch below keeps its wide band:
without the current nothing would confirm a departure that small, and noise near the free speed would
become ``FAST``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._arrays import broadcast_to
from .profile import ThresholdProfile
from .stall import stop_speeds
from .states import Code

__all__ = ["agreeing_departures", "classify", "classify_depth"]


def classify(
    profile: ThresholdProfile,
    *,
    omega_rad_s: ArrayLike,
    omega_model_rad_s: ArrayLike,
    current_a: ArrayLike,
    current_model_a: ArrayLike,
    voltage_v: ArrayLike,
    bus_voltage_v: ArrayLike | None = None,
    current_trusted: ArrayLike | None = None,
    omega_expected_rad_s: ArrayLike | None = None,
    omega_free_rad_s: ArrayLike | None = None,
    activity_v: ArrayLike | None = None,
) -> NDArray[np.int8]:
    """State code per sample (see :class:`MotorState`); NaN inputs give ``NO_DATA``.

    ``omega_free_rad_s`` is the free speed ``V/k_e`` per sample: where given, the upper side of the speed
    band narrows to ``free_speed_headroom_fraction`` of the headroom ``V/k_e − ω_model``, kept between half
    the band and the band (rule 2). ``None``: the full band on both sides. The speed-only branch (no
    trusted current) always uses its wide band. ``activity_v`` (the input's activity,
    :func:`~mav_motor_health.model.balance.input_activity`) widens the bands as the profile says; None:
    the profile's fixed bands.
    """
    state, _ = classify_depth(
        profile,
        omega_rad_s=omega_rad_s,
        omega_model_rad_s=omega_model_rad_s,
        current_a=current_a,
        current_model_a=current_model_a,
        voltage_v=voltage_v,
        bus_voltage_v=bus_voltage_v,
        current_trusted=current_trusted,
        omega_expected_rad_s=omega_expected_rad_s,
        omega_free_rad_s=omega_free_rad_s,
        activity_v=activity_v,
    )
    return state


def classify_depth(
    profile: ThresholdProfile,
    *,
    omega_rad_s: ArrayLike,
    omega_model_rad_s: ArrayLike,
    current_a: ArrayLike,
    current_model_a: ArrayLike,
    voltage_v: ArrayLike,
    bus_voltage_v: ArrayLike | None = None,
    current_trusted: ArrayLike | None = None,
    omega_expected_rad_s: ArrayLike | None = None,
    omega_free_rad_s: ArrayLike | None = None,
    activity_v: ArrayLike | None = None,
    bands: tuple[NDArray[np.float64] | float, NDArray[np.float64], NDArray[np.float64]] | None = None,
    stall_split_a: ArrayLike | None = None,
    stop_cap_rad_s: ArrayLike | None = None,
) -> tuple[NDArray[np.int8], NDArray[np.float64]]:
    """:func:`classify`, and how deep in its state each sample is (see "Depth"): state codes, depths.

    ``bands`` (speed, current above the model, current below it) are the profile's bands at these samples
    if the caller has them already (the pipeline, which also reports them); None: computed here.
    ``stall_split_a``: the F2.1/F4.2 split at each sample where the caller knows the motor's own (its
    typical current, :mod:`.noise`); None: the profile's. ``stop_cap_rad_s``: the highest stop speed at each
    sample (see "The lowest input"); None: no cap."""
    w, w_model, i, i_model, v = np.broadcast_arrays(
        *(
            np.asarray(x, dtype=float)
            for x in (omega_rad_s, omega_model_rad_s, current_a, current_model_a, voltage_v)
        )
    )
    activity = None if activity_v is None else broadcast_to(np.asarray(activity_v, dtype=float), w.shape)
    if bands is None:
        band_w = profile.speed_band(activity)
        band_i = profile.current_halfwidth_a(v, activity)
        band_i_low = profile.current_halfwidth_a(v, activity, below=True)
    else:
        band_w, band_i, band_i_low = bands
    split = broadcast_to(
        profile.stall_split(bus_voltage_v)
        if stall_split_a is None
        else np.asarray(stall_split_a, dtype=float),
        w.shape,
    )

    speed_low = w < w_model - band_w
    band_up: NDArray[np.float64] | float = band_w
    if omega_free_rad_s is not None:
        # Rule 2: no fault lifts the speed above V/k_e; near it, a share f of the headroom is the band...
        headroom = broadcast_to(np.asarray(omega_free_rad_s, dtype=float), w.shape) - w_model
        # ... but never below half the band, the speed noise (near idle the headroom vanishes, the noise not)
        narrowed = np.clip(profile.free_speed_headroom_fraction * headroom, 0.5 * band_w, band_w)
        band_up = np.where(np.isfinite(narrowed), narrowed, band_w)
    speed_high = w > w_model + band_up
    current_low = i < i_model - band_i_low
    current_high = i > i_model + band_i
    # The departures in shares of their bands (departures that agree, and the depth)
    joint = profile.joint_band_sum
    with np.errstate(divide="ignore", invalid="ignore"):
        slower = np.maximum(w_model - w, 0.0) / band_w
        faster = np.maximum(w - w_model, 0.0) / band_up
        less = np.maximum(i_model - i, 0.0) / band_i_low
        more = np.maximum(i - i_model, 0.0) / band_i
    # Rule 1 needs the model to expect a turning motor: an idle or disarmed motor is not a stalled one.
    expected = w_model if omega_expected_rad_s is None else broadcast_to(omega_expected_rad_s, w.shape)
    # never above what the lowest input given so far drives a healthy motor at, where capped
    stop, floor = stop_speeds(profile, expected, stop_cap_rad_s)
    # (the band's margin at most the stop speed itself: a vehicle's noise band may be wide in gusts, and a
    # motor expected at twice the stop speed is turning by any measure)
    stopped = (np.abs(w) < stop) & (expected >= floor + np.minimum(band_w, floor))

    state = np.full(w.shape, Code.UNKNOWN, dtype=np.int8)
    not_high = ~speed_high
    state[not_high & current_high] = Code.F1_1
    state[not_high & ~current_high] = Code.F4_1
    state[not_high & ~speed_low & ~current_low & ~current_high] = Code.NORMAL
    state[speed_high & current_low] = Code.F3_1
    if joint > 0:
        normal = state == Code.NORMAL
        state[normal & (slower > 0) & (more > 0) & (slower + more >= joint)] = Code.F1_1
        state[normal & (slower > 0) & (less > 0) & (slower + less >= joint)] = Code.F4_1
        # F3.1 also where the paper says F4.1 ("current low, speed inside its band") with a rising speed
        state[(faster > 0) & (less > 0) & (faster + less >= joint)] = Code.F3_1
    state[stopped] = np.where(i[stopped] < split[stopped], Code.F2_1, Code.F4_2)
    missing = ~(np.isfinite(w) & np.isfinite(w_model) & np.isfinite(i) & np.isfinite(i_model))
    state[missing] = Code.NO_DATA
    # Speed only, where the current is absent or untrusted: say what speed can say, and no more.
    speed_only = ~np.isfinite(i) if current_trusted is None else ~broadcast_to(current_trusted, w.shape)
    speed_only = speed_only & np.isfinite(w) & np.isfinite(w_model)
    if np.any(speed_only):
        # Without current a model error cannot be told from a fault: ask for a large departure.
        wide = profile.speed_only_band(band_w, w_model)
        only = np.full(w.shape, Code.NORMAL, dtype=np.int8)
        only[w < w_model - wide] = Code.SLOW
        only[w > w_model + wide] = Code.FAST
        only[stopped] = Code.STALLED
        state[speed_only] = only[speed_only]
    # Depth: the departure measured in bands (1 on the state's boundary; see "Depth")
    pair = joint if joint > 0 else np.inf
    depth = np.ones(w.shape)
    if not np.any(
        (state == Code.F1_1) | (state == Code.F3_1) | (state == Code.F4_1) | (state == Code.UNKNOWN)
    ):
        return state, depth
    with np.errstate(invalid="ignore"):
        # (each state's depth copied in where the state is: the values of indexing, without gathering them)
        np.copyto(depth, np.fmax(more, (slower + more) / pair), where=state == Code.F1_1)
        np.copyto(depth, np.fmax(np.fmax(slower, less), (slower + less) / pair), where=state == Code.F4_1)
        np.copyto(depth, np.fmax(np.fmin(faster, less), (faster + less) / pair), where=state == Code.F3_1)
        np.copyto(depth, faster, where=state == Code.UNKNOWN)
    depth = np.where(np.isfinite(depth), np.maximum(depth, 1.0), 1.0)
    depth[speed_only] = 1.0
    return state, depth


def agreeing_departures(
    d_omega_rad_s: NDArray[np.float64],
    d_current_a: NDArray[np.float64],
    band_omega_rad_s: NDArray[np.float64] | float,
    band_current_a: NDArray[np.float64],
    band_sum: float,
) -> tuple[NDArray[np.int8], NDArray[np.float64]]:
    """F1.1, F3.1 or F4.1 where speed and current both depart the model that fault's way, by shares of
    their bands adding up to ``band_sum``; else NORMAL (NaN: NORMAL). Returns the states and their depth
    (the sum over ``band_sum``, 1 for NORMAL).

    The balance rule's slow look judges its longer averages this way, against narrowed bands: a fault
    moves both quantities, a model slightly off in one quantity at an unusual operating point moves one,
    and the narrow bands would see that. As in the tree, a speed below its band with the current inside
    its band is not F1.1.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        share_w = d_omega_rad_s / band_omega_rad_s
        share_i = d_current_a / band_current_a
    state = np.full(share_w.shape, Code.NORMAL, dtype=np.int8)
    depth = np.ones(share_w.shape)
    total = np.abs(share_w) + np.abs(share_i)
    with np.errstate(invalid="ignore"):
        named = total >= band_sum
        if not np.any(named):
            return state, depth
        slower, faster = share_w < 0, share_w > 0
        # as in the tree: slower than the band with the current inside it is not friction (the paper's
        # F4.1; here named only once the current falls too)
        state[named & slower & (share_i > 0) & ((share_w >= -1) | (share_i >= 1))] = Code.F1_1
        state[named & slower & (share_i < 0)] = Code.F4_1
        state[named & faster & (share_i < 0)] = Code.F3_1
    fault = state != Code.NORMAL
    depth[fault] = total[fault] / band_sum
    return state, depth
