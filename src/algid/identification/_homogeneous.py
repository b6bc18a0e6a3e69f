"""Equations without a known term, divided by a parameter another equation determines.

An equation of a system without a known term (``J*w' + b*w = K*i`` beside
``L*i' + R*i + K*w = u``) fixes the ratios of its parameters, not their scale: its
residual falls to zero with all of them.  Solved jointly with the others, such an
equation pulls the shared parameter that carries its scale (here ``K``) towards zero
wherever its own residual is large for any other reason: samples from before a
change still in a tracker's forgotten sums, a short window.  Scaled down together,
``J``, ``b`` and ``K`` shrink that residual at the small cost of ``K``'s term in the
other equation: the tracker of a motor whose ``K`` rose by a quarter reported
``K = 0.022 +- 0.004`` for a true 1.0, for ten half-lives.

Divided by that parameter (the *pivot*), the equation reads ``(J/K)*w' + (b/K)*w = i``:
a known term, and the ratios as its unknowns.  Its residual no longer depends on the
scale, which the other equations alone fix.  This module finds the equations that
can be so divided, maps their window rows to the ratios (a fixed linear map of each
row, so that sums of rows map as the rows do), and maps the solution back:
``J = (J/K) * K``, the covariance by the delta method.

An equation is divided when exactly one of its parameters appears in another
equation that has a known term, and that parameter is the pivot; its other
parameters, which appear in no other equation, become ratios.  Other equations
without a known term are left as they are (a joint estimate that the parameters
shared elsewhere keep from their trivial solution).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["Division", "divisions", "row_map", "to_physical"]


class Division(NamedTuple):
    """One equation divided by its pivot.

    Attributes
    ----------
    equation : int
        Position of the equation among the system's equations with parameters.
    pivot : int
        Position of the pivot among the system's parameters.
    ratios : tuple of int
        Positions of the parameters estimated as ratios to the pivot.
    """

    equation: int
    pivot: int
    ratios: tuple


def divisions(models, parameters):
    """The equations of a system that are divided by a pivot.

    Parameters
    ----------
    models : sequence of algid.models._model.Model
        The equations that have parameters, in the order of their rows.
    parameters : sequence of str
        The system's parameters (the order of the columns).

    Returns
    -------
    list of Division
    """
    scaled = [set(m.parameters) for m in models if m.known_terms]
    out = []
    for e, model in enumerate(models):
        if model.known_terms:
            continue
        others = [set(m.parameters) for f, m in enumerate(models) if f != e]
        shared = [p for p in model.parameters if any(p in s for s in others)]
        fixed = [p for p in shared if any(p in s for s in scaled)]
        if len(shared) != 1 or len(fixed) != 1:
            continue
        pivot = fixed[0]
        ratios = tuple(parameters.index(p) for p in model.parameters if p != pivot)
        out.append(Division(e, parameters.index(pivot), ratios))
    return out


def row_map(size, division):
    """The matrix ``M`` that turns an equation's augmented row ``r`` (columns of the
    parameters, then the known term, multiplying ``(theta, -1)``) into its row ``M r``
    in the ratios: the pivot's column becomes the known term.

    Parameters
    ----------
    size : int
        Length of an augmented row (parameters + 1).
    division : Division

    Returns
    -------
    numpy.ndarray
        ``(size, size)``.
    """
    M = np.eye(size)
    p, known = division.pivot, size - 1
    M[p, p] = 0.0
    M[known, known] = 0.0          # (the equation has no known term)
    M[known, p] = -1.0             # r . (phi, -1) = residual / pivot
    return M


def to_physical(phi, divisions_, covariance=None):
    """The physical parameters from a solution in the ratios, and their covariance.

    Parameters
    ----------
    phi : numpy.ndarray
        The solution: the ratios in their parameters' places, the others as they are.
    divisions_ : sequence of Division
    covariance : numpy.ndarray, optional
        The covariance of ``phi``.

    Returns
    -------
    theta : numpy.ndarray
    covariance : numpy.ndarray or None
        By the delta method (``None`` if none was given).
    """
    theta = np.array(phi, dtype=float)
    jacobian = np.eye(len(theta))
    for d in divisions_:
        for q in d.ratios:
            theta[q] = phi[q] * phi[d.pivot]
            jacobian[q, q] = phi[d.pivot]
            jacobian[q, d.pivot] = phi[q]
    if covariance is None:
        return theta, None
    return theta, jacobian @ covariance @ jacobian.T
