"""Output-error refinement of an algebraic estimate (Gauss–Newton): :func:`algid.refine`.

The algebraic estimate weights the data by powers of ``t`` and by the invariant
filter, so its variance stays above the Cramér–Rao bound (:func:`algid.crlb`).
With
white Gaussian noise on ``x``, the least-squares output-error estimate

    min over (B, K, x0, v0) of  sum_i (x_i - xhat(t_i; B, K, x0, v0))**2

is the maximum-likelihood estimate, asymptotically efficient.  It is a nonlinear
problem; the algebraic estimate, which needs no initial conditions, is a good start.
Each Gauss–Newton step simulates ``xhat`` and its sensitivities exactly
(:func:`algid.estimation._sensitivity.output_sensitivities`), solves the linearised least-squares
problem for the step and halves the step while the residual does not decrease.  The
unknown initial conditions start at their least-squares values given the starting
``B``, ``K`` (``xhat`` is linear in them).  NumPy and SciPy only.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from algid._signal_checks import check_experiment
from algid.errors import InputDataError
from algid.estimation._cramer_rao import covariance_from_sensitivities
from algid.estimation._sensitivity import SENSITIVITY_PARAMETERS, output_sensitivities

__all__ = ["refine", "RefinementResult"]

#: Largest number of step halvings in one Gauss–Newton iteration.
_MAX_HALVINGS = 30


@dataclass
class RefinementResult:
    """Output-error (Gauss–Newton) estimate of ``x'' + B x' + K x = f``.

    Attributes
    ----------
    B, K : float
        Refined parameters.
    x0, v0 : float
        Estimated displacement and velocity at the first sample.
    covariance : ndarray, shape (4, 4)
        Estimated covariance of ``(B, K, x0, v0)``: ``noise_std**2 inv(S^T S)`` at the
        estimate, with the noise estimated from the residual.
    std : dict
        Square roots of the diagonal of ``covariance`` by name (plus ``c``, ``k`` with
        a mass).
    noise_std : float
        Residual standard deviation ``sqrt(RSS / (N - 4))``.
    start : dict
        Starting ``B``, ``K``, ``x0``, ``v0``.
    iterations : int
        Gauss–Newton iterations done.
    converged : bool
        Whether the last step was below the tolerance.
    cost : list of float
        Residual sum of squares at the start and after each iteration.
    mass : float or None
    c, k : float or None
        ``B m`` and ``K m`` when the mass was given.

    Examples
    --------
    >>> from algid.estimation import refine
    >>> from algid.simulation import simulate
    >>> sim = simulate("step", initial_state=(0.1, -0.2), noise_std=0.01, seed=1)
    >>> result = refine(sim.t, sim.f, sim.x)
    >>> result.converged, sorted(result.std), round(result.noise_std, 3)
    (True, ['B', 'K', 'v0', 'x0'], 0.01)
    >>> abs(result.x0 - 0.1) < 4 * result.std["x0"]
    True
    """

    B: float
    K: float
    x0: float
    v0: float
    covariance: np.ndarray
    std: dict
    noise_std: float
    start: dict
    iterations: int
    converged: bool
    cost: list = field(default_factory=list)
    mass: float | None = None
    c: float | None = None
    k: float | None = None

    @property
    def parameters(self) -> dict:
        """Estimates by name: ``B``, ``K``, ``x0``, ``v0`` (and ``c``, ``k``)."""
        out = {"B": self.B, "K": self.K, "x0": self.x0, "v0": self.v0}
        if self.mass is not None:
            out.update(c=self.c, k=self.k)
        return out

    def to_dict(self) -> dict:
        """Estimates, their standard errors (``std_<name>``) and diagnostics, JSON-ready.

        Returns
        -------
        dict
            Plain Python numbers, lists and strings.
        """
        out = dict(self.parameters)
        out.update({f"std_{name}": value for name, value in self.std.items()})
        out.update(noise_std=self.noise_std, iterations=self.iterations,
                   converged=self.converged)
        return out

    def __repr__(self):
        est = ", ".join(f"{k}={v:.6g} ± {self.std[k]:.2g}" for k, v in self.parameters.items())
        return (f"<RefinementResult {est}; iterations={self.iterations} "
                f"converged={self.converged}>")


def _start_values(start, t, f, x, *, mass, filter_order, quadrature_order):
    if start is None:
        from algid.estimation._batch import estimate

        start = estimate(t, f, x, filter_order=filter_order, mass=mass,
                         quadrature_points=quadrature_order).final()
    elif hasattr(start, "final") and callable(start.final):  # an EstimationResult
        start = start.final()
    if isinstance(start, dict):
        if "B" not in start or "K" not in start:
            raise InputDataError(f"start must give 'B' and 'K', got keys {sorted(start)}")
        values = {name: start.get(name) for name in SENSITIVITY_PARAMETERS}
    else:
        try:
            seq = [float(v) for v in start]
        except (TypeError, ValueError):
            raise InputDataError(f"start must be a dict, an EstimationResult or a sequence "
                                 f"(B, K[, x0, v0]), got {start!r}") from None
        if len(seq) not in (2, 4):
            raise InputDataError(f"start must hold (B, K) or (B, K, x0, v0), got {len(seq)} "
                                 f"values")
        values = dict(zip(SENSITIVITY_PARAMETERS, seq + [None] * (4 - len(seq))))
    for name in ("B", "K"):
        value = values[name]
        if value is None or not np.isfinite(float(value)):
            raise InputDataError(f"starting value of {name} is {value!r}: the algebraic "
                                 f"estimate is not defined (too few samples?); give start")
    return values


def refine(t, f, x, *, start=None, iterations=10, mass=None, filter_order=2,
           quadrature_order=6, tol=1e-10):
    """Refine an estimate of ``B`` and ``K`` by output-error Gauss–Newton steps.

    Parameters
    ----------
    t : array_like
        Sample times [s], uniformly spaced; the initial state is at ``t[0]``.
    f : array_like
        Input: the force per unit mass ``f = F/m``, or the force ``F`` if ``mass`` is
        given.  Interpolated between samples as by the quadrature rule of
        ``quadrature_order`` points (2 = first-order hold).
    x : array_like
        Measured displacement [m].
    start : dict, EstimationResult or sequence, optional
        Starting point: ``{"B": .., "K": ..}`` (optionally ``"x0"``, ``"v0"``), the
        result of :func:`algid.estimate` (its final values), or ``(B, K[, x0, v0])``.
        Default: the algebraic estimate at the last sample (``algid.estimate`` with
        ``filter_order``).  Missing initial conditions start at their least-squares
        values given ``B`` and ``K``.
    iterations : int, optional
        Largest number of Gauss–Newton iterations (3 to 5 are usually enough).
        Default 10.
    mass : float, optional
        Known mass [kg]: ``f`` is then the force and the result holds ``c``, ``k``.
    filter_order : int, optional
        Filter order of the algebraic starting estimate.  Default 2.
    quadrature_order : int, optional
        Quadrature (and input interpolation) rule.  Default 6.
    tol : float, optional
        Stop when every step is below ``tol * (1 + |value|)``, or when the decrease of
        the residual sum of squares the step predicts is below ``tol**2`` times that sum
        (the step is then far below the statistical uncertainty).  Default 1e-10.

    Returns
    -------
    RefinementResult

    Raises
    ------
    InputDataError
        Bad signals or options, an undefined start, or parameters not identifiable
        from the data.

    Examples
    --------
    >>> from algid.estimation import refine
    >>> from algid.simulation import simulate
    >>> sim = simulate("step", initial_state=(0.1, -0.2), noise_std=0.01, seed=1)
    >>> r = refine(sim.t, sim.f, sim.x)
    >>> abs(r.B - 2.0) < 4 * r.std["B"], abs(r.K - 3.0) < 4 * r.std["K"]
    (True, True)
    """
    if isinstance(iterations, bool) or not isinstance(iterations, (int, np.integer)) \
            or iterations < 0:
        raise InputDataError(f"iterations must be an integer >= 0, got {iterations!r}")
    if mass is not None:
        if isinstance(mass, bool) or not np.isfinite(float(mass)) or float(mass) <= 0:
            raise InputDataError(f"mass must be a positive number, got {mass!r}")
        mass = float(mass)
    t, f, x, h = check_experiment(t, f, x, min_samples=max(2 * quadrature_order, 8))
    values = _start_values(start, t, f, x, mass=mass, filter_order=filter_order,
                           quadrature_order=quadrature_order)
    u = f / mass if mass is not None else f

    theta = np.array([float(values["B"]), float(values["K"]),
                      float(values["x0"] or 0.0), float(values["v0"] or 0.0)])
    with np.errstate(over="ignore", invalid="ignore"):
        xhat, S = output_sensitivities(t, u, B=theta[0], K=theta[1], x0=theta[2],
                                       v0=theta[3], order=quadrature_order)
    if not (np.all(np.isfinite(xhat)) and np.all(np.isfinite(S))):
        raise InputDataError(f"the model response from the start B={theta[0]:.6g}, "
                             f"K={theta[1]:.6g} overflows on this record; give a better start")
    missing = [i for i, name in ((2, "x0"), (3, "v0")) if values[name] is None]
    if missing:  # linear least squares for the unknown initial conditions
        coef, *_ = np.linalg.lstsq(S[:, missing], x - xhat, rcond=None)
        theta[missing] += coef
        xhat = xhat + S[:, missing] @ coef  # xhat is affine in (x0, v0); S is unchanged
    start_values = dict(zip(SENSITIVITY_PARAMETERS, theta.tolist()))

    residual = x - xhat
    cost = [float(residual @ residual)]
    converged = False
    for _ in range(iterations):
        step, *_ = np.linalg.lstsq(S, residual, rcond=None)
        accepted = False
        for _ in range(_MAX_HALVINGS):
            trial = theta + step
            with np.errstate(over="ignore", invalid="ignore"):  # a wild trial is rejected
                x_trial, S_trial = output_sensitivities(
                    t, u, B=trial[0], K=trial[1], x0=trial[2], v0=trial[3],
                    order=quadrature_order)
                r_trial = x - x_trial
                c_trial = float(r_trial @ r_trial)
            if np.isfinite(c_trial) and c_trial <= cost[-1]:
                accepted = True
                break
            step = step / 2
        predicted = float(np.sum((S @ step) ** 2))
        small = bool(np.all(np.abs(step) <= tol * (1.0 + np.abs(theta)))
                     or predicted <= tol**2 * cost[-1])
        if accepted:
            theta, S, residual = trial, S_trial, r_trial
            cost.append(c_trial)
        else:
            cost.append(cost[-1])
        if small or not accepted:
            converged = True  # no further decrease possible at this precision
            break

    n = t.size
    noise_std = float(np.sqrt(cost[-1] / (n - 4)))
    if noise_std > 0:
        covariance = covariance_from_sensitivities(S, noise_std)
    else:
        covariance = np.zeros((4, 4))
    std = {name: float(s) for name, s in
           zip(SENSITIVITY_PARAMETERS, np.sqrt(np.diag(covariance)))}
    c = k = None
    if mass is not None:
        c, k = theta[0] * mass, theta[1] * mass
        std["c"], std["k"] = std["B"] * mass, std["K"] * mass
    return RefinementResult(B=float(theta[0]), K=float(theta[1]), x0=float(theta[2]),
                            v0=float(theta[3]), covariance=covariance, std=std,
                            noise_std=noise_std, start=start_values, iterations=len(cost) - 1,
                            converged=converged, cost=cost, mass=mass,
                            c=None if c is None else float(c),
                            k=None if k is None else float(k))
