"""The project's one least-squares fit and its one result type (lmfit's lesson: numerics wrapped once).

Every fit of the model goes through here: the bench's two-step Levenberg–Marquardt estimate
(:mod:`.estimation`, eqs. 9 and 10 and the ESC map), the workbench's output-error fit with effects
(:mod:`.effects.fit`), and identification from a flight log (:mod:`.identify` and :mod:`.esc`, whose
balances are linear in their coefficients). Two entries, one result:

* :func:`fit_least_squares` — a nonlinear residual on parameters divided by a typical scale: scipy's
  Levenberg–Marquardt where nothing is bounded, its trust-region reflective counterpart where something is
  (LM takes no bounds);
* :func:`fit_linear` — ``y ≈ A·x`` with bounds on x (bounded-variable least squares on columns scaled to
  a unit maximum);
* :class:`LeastSquaresFit` — values, bounds, standard errors, covariance, the residual, RMSE, AIC/BIC,
  R² and accuracy against the target, success and message, and :meth:`LeastSquaresFit.report`.

The covariance is one rule for both: ``(JᵀJ)⁻¹`` at the solution (J the Jacobian, for a linear fit A),
times the residual variance ``SSR/(n − p)`` (``scale_covar``, as in lmfit; off where the residuals are
already in units of their noise), in the parameters' own units. No degrees of freedom, no covariance
(NaN). A singular ``JᵀJ`` (a parameter the residual does not depend on at all) leaves that parameter's
row and column NaN and the others from the pseudo-inverse.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["LeastSquaresFit", "accuracy_pct", "fit_least_squares", "fit_linear"]

FloatArray = NDArray[np.float64]


def accuracy_pct(measured: ArrayLike, modelled: ArrayLike) -> float:
    """``100·(1 − Σ|m − y| / Σ|m|)``: the project's one definition of model accuracy.

    Over the operating points (bin means): one minus the weighted mean absolute percentage error of the
    steady-state means, as the paper compares averaged measurements with the model in Figs. 1 and 2."""
    m = np.asarray(measured, dtype=float)
    y = np.asarray(modelled, dtype=float)
    ok = np.isfinite(m) & np.isfinite(y)
    denominator = np.abs(m[ok]).sum()
    if denominator == 0:
        return float("nan")
    return float(100.0 * (1.0 - np.abs(m[ok] - y[ok]).sum() / denominator))


@dataclass(frozen=True)
class LeastSquaresFit:
    """One least-squares fit: what it found, how sure, and how well it fits.

    ``residual`` is each row's residual as the fit minimised it, in its units; ``target`` the measured
    values where the residual is model − target in their units (eq. 8's ``y_t − y_m`` in the paper's
    sign: then :attr:`r_squared` and :attr:`accuracy_pct` say how well the model reproduces them), else
    None."""

    title: str
    values: dict[str, float]
    stderr: dict[str, float]
    covariance: FloatArray = field(repr=False)
    lower: dict[str, float] = field(repr=False)
    upper: dict[str, float] = field(repr=False)
    #: each parameter's typical size, as the solver saw it (what "on a bound" is measured in)
    scale: dict[str, float] = field(repr=False)
    residual: FloatArray = field(repr=False)
    success: bool = True
    message: str = ""
    method: str = ""
    target: FloatArray | None = field(default=None, repr=False)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self.values)

    @property
    def x(self) -> FloatArray:
        """The values as an array, in the order of :attr:`names`."""
        return np.array(list(self.values.values()))

    @property
    def x_stderr(self) -> FloatArray:
        """The standard errors as an array, in the order of :attr:`names`."""
        return np.array(list(self.stderr.values()))

    @property
    def n_points(self) -> int:
        return int(self.residual.size)

    @property
    def n_parameters(self) -> int:
        return len(self.values)

    @property
    def ssr(self) -> float:
        """The sum of squared residuals (eq. 8)."""
        return float(self.residual @ self.residual)

    @property
    def rmse(self) -> float:
        return math.sqrt(self.ssr / self.n_points) if self.n_points else math.nan

    @property
    def aic(self) -> float:
        n, p = self.n_points, self.n_parameters
        return n * math.log(max(self.ssr, 1e-300) / n) + 2 * p

    @property
    def bic(self) -> float:
        n, p = self.n_points, self.n_parameters
        return n * math.log(max(self.ssr, 1e-300) / n) + p * math.log(n)

    @property
    def r_squared(self) -> float:
        """``1 − SSR/SST`` against the target (NaN without one, or with a constant target)."""
        if self.target is None:
            return math.nan
        sst = float(((self.target - self.target.mean()) ** 2).sum())
        return 1.0 - self.ssr / sst if sst > 0 else math.nan

    @property
    def accuracy_pct(self) -> float:
        """:func:`accuracy_pct` of the model (target + residual) against the target (NaN without one)."""
        if self.target is None:
            return math.nan
        return accuracy_pct(self.target, self.target + self.residual)

    def at_bound(self, name: str, tolerance: float = 1e-6) -> bool:
        """Whether the parameter ``name`` ended on one of its bounds (within ``tolerance`` of its scale)."""
        value, near = self.values[name], tolerance * abs(self.scale[name])
        return any(math.isfinite(b) and abs(value - b) <= near for b in (self.lower[name], self.upper[name]))

    def report(self, units: Mapping[str, str] | None = None) -> str:
        """The fit as text: its statistics, then each parameter with its standard error (and unit)."""
        units = units or {}
        head = f"  {self.title}: rmse {self.rmse:.4g}"
        if self.target is not None:
            head += f", R² {self.r_squared:.5f}, accuracy {self.accuracy_pct:.2f} %"
        head += f", AIC {self.aic:.1f}, BIC {self.bic:.1f}"
        lines = [head + ("" if self.success else f"  (NOT CONVERGED: {self.message})")]
        for name, value in self.values.items():
            err = self.stderr.get(name, math.nan)
            rel = abs(err / value) * 100 if value else math.inf
            unit = f"  [{units[name]}]" if name in units else ""
            bound = "  (at its bound)" if self.at_bound(name) else ""
            lines.append(f"    {name:6s} = {value: .5g} +/- {err:.3g} ({rel:.2g} %){unit}{bound}")
        return "\n".join(lines)


def _covariance(jac: FloatArray, ssr: float, scale: FloatArray, scale_covar: bool) -> FloatArray:
    """``(JᵀJ)⁻¹`` (× SSR/(n − p) with ``scale_covar``) in the parameters' units (module doc)."""
    n, p = jac.shape
    dof = n - p
    if scale_covar and dof <= 0:
        return np.full((p, p), np.nan)
    info = jac.T @ jac
    try:
        inverse = np.linalg.inv(info)
    except np.linalg.LinAlgError:
        inverse = np.linalg.pinv(info)
        undetermined = ~np.any(jac != 0, axis=0)
        inverse[undetermined, :] = np.nan
        inverse[:, undetermined] = np.nan
    if scale_covar:
        inverse = inverse * (ssr / dof)
    return inverse * np.outer(scale, scale)


def _result(
    title: str,
    names: Sequence[str],
    x: FloatArray,
    covariance: FloatArray,
    lower: FloatArray,
    upper: FloatArray,
    scale: FloatArray,
    residual: FloatArray,
    target: ArrayLike | None,
    success: bool,
    message: str,
    method: str,
) -> LeastSquaresFit:
    stderr = np.sqrt(np.clip(np.diag(covariance), 0, None))
    return LeastSquaresFit(
        title=title,
        values=dict(zip(names, map(float, x))),
        stderr=dict(zip(names, map(float, stderr))),
        covariance=covariance,
        lower=dict(zip(names, map(float, lower))),
        upper=dict(zip(names, map(float, upper))),
        scale=dict(zip(names, map(float, scale))),
        residual=residual,
        success=success,
        message=message,
        method=method,
        target=None if target is None else np.asarray(target, dtype=float),
    )


def fit_least_squares(
    residual: Callable[[FloatArray], FloatArray],
    x0: ArrayLike,
    names: Sequence[str],
    *,
    scale: ArrayLike | None = None,
    lower: ArrayLike | None = None,
    upper: ArrayLike | None = None,
    target: ArrayLike | None = None,
    title: str = "",
    max_nfev: int | None = None,
    scale_covar: bool = True,
) -> LeastSquaresFit:
    """Minimise ``Σ residual(x)²`` (eq. 8) over the parameters ``names`` from ``x0``.

    The solver works on ``x / scale`` (a typical size of each parameter; default 1) with its Jacobian's
    column norms as further scaling (``x_scale="jac"``): Levenberg–Marquardt without bounds, trust-region
    reflective with ``lower``/``upper`` (either may be None: unbounded on that side; the start is clipped
    into them). ``target``: the measured values, where ``residual`` returns model − target in their units.
    """
    x0 = np.asarray(x0, dtype=float)
    p = x0.size
    # scipy.optimize where a fit needs it: its import takes about 0.12 s here, which replay and the
    # agent would pay at every start (issue 18; tests/test_cli_arguments.py)
    from scipy.optimize import least_squares

    sc = np.ones(p) if scale is None else np.asarray(scale, dtype=float)

    def scaled(z: FloatArray) -> FloatArray:
        return residual(z * sc)

    if lower is None and upper is None:
        lo, hi = np.full(p, -np.inf), np.full(p, np.inf)
        method = "lm"
        result = least_squares(scaled, x0 / sc, method=method, x_scale="jac", max_nfev=max_nfev)
    else:
        lo = np.full(p, -np.inf) if lower is None else np.asarray(lower, dtype=float) / sc
        hi = np.full(p, np.inf) if upper is None else np.asarray(upper, dtype=float) / sc
        method = "trf"
        start = np.clip(x0 / sc, lo, hi)
        result = least_squares(
            scaled, start, method=method, bounds=(lo, hi), x_scale="jac", max_nfev=max_nfev
        )
    r = np.asarray(result.fun, dtype=float)
    covariance = _covariance(np.asarray(result.jac, dtype=float), float(r @ r), sc, scale_covar)
    return _result(
        title,
        names,
        result.x * sc,
        covariance,
        lo * sc,
        hi * sc,
        sc,
        r,
        target,
        bool(result.success),
        str(result.message),
        method,
    )


def fit_linear(
    a: ArrayLike,
    y: ArrayLike,
    names: Sequence[str],
    *,
    lower: ArrayLike = 0.0,
    upper: ArrayLike = np.inf,
    target: ArrayLike | None = None,
    title: str = "",
    scale_covar: bool = True,
) -> LeastSquaresFit:
    """``y ≈ A·x`` with ``lower ≤ x ≤ upper`` (default x ≥ 0: a motor's resistances, constants and
    torques are not negative), by bounded-variable least squares on A's columns scaled to a unit maximum;
    the residual is ``A·x − y``. ``scale_covar=False`` where the rows are already divided by their noise
    (the covariance is then ``(AᵀA)⁻¹`` as it stands)."""
    a = np.asarray(a, dtype=float)
    y = np.asarray(y, dtype=float)
    p = a.shape[1]
    col = np.maximum(np.abs(a).max(axis=0), 1e-30) if a.shape[0] else np.ones(p)
    lo = np.broadcast_to(np.asarray(lower, dtype=float), (p,))
    hi = np.broadcast_to(np.asarray(upper, dtype=float), (p,))
    from scipy.optimize import lsq_linear  # (imported here: see fit_least_squares)

    solution = lsq_linear(a / col, y, bounds=(lo * col, hi * col), method="bvls")
    # within the bounds as asked: BVLS may return a bound missed by a rounding (a variance of −1e−20,
    # whose square root failed the noise measurement of held-out world 1034's identification)
    x = np.clip(solution.x / col, lo, hi)
    r = a @ x - y
    covariance = _covariance(a, float(r @ r), np.ones(p), scale_covar)
    return _result(
        title,
        names,
        x,
        covariance,
        lo,
        hi,
        1.0 / col,
        r,
        target,
        bool(solution.success),
        str(solution.message),
        "bvls",
    )
