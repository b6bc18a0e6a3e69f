"""The estimator methods of :func:`algid.identify` and :class:`algid.Tracker`, by name.

A method is a solver of the window equations (in the orthonormal basis of
:mod:`algid.identification._window_basis`) and two flags: whether instrumental-variable
iterations follow its first estimate, and whether the Tracker offers it (its stacked
solve of accumulated sums is its own, in :mod:`algid.identification._tracker`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

from algid.identification._bias_compensation import bias_compensated, least_squares

__all__ = ["Method", "METHODS", "TRACKER_METHODS"]


class Method(NamedTuple):
    """One estimator method.

    Attributes
    ----------
    solve : callable
        ``solve(A, b, grams, bound)`` -> ``theta, scores, jacobian, variance``, as
        :func:`algid.identification._bias_compensation.bias_compensated`: the estimate,
        its estimating equations per window and their derivative, and the noise
        variance of its correction (None: none).
    instrumental : bool
        Whether instrumental variables from the output simulated by ``solve``'s estimate
        refine it (``identify``'s ``iterations``).
    tracked : bool
        Whether :class:`algid.Tracker` offers it (instruments need the whole record).
    weighted : bool
        Whether the windows are weighed by the inverse covariance of their equations'
        noise: ``solve``'s estimate makes that covariance, and the equations are solved
        again so weighted (:mod:`algid.identification._window_weighting`; the whole
        record in memory).
    """

    solve: Callable
    instrumental: bool
    tracked: bool
    weighted: bool = False


#: Solvers: least squares, bias-compensated least squares (identify's default; Koopmans'
#: estimator), instrumental variables (first estimated as "bc"), and bias-compensated
#: generalised least squares (the windows weighed by their noise; first estimated as
#: "bc").
METHODS = {
    "ls": Method(least_squares, instrumental=False, tracked=True),
    "bc": Method(bias_compensated, instrumental=False, tracked=True),
    "iv": Method(bias_compensated, instrumental=True, tracked=False),
    "gls": Method(bias_compensated, instrumental=False, tracked=False, weighted=True),
}

#: The methods of :class:`algid.Tracker`.
TRACKER_METHODS = tuple(sorted(name for name, m in METHODS.items() if m.tracked))
