"""The window equations of :func:`algid.identify` in a well-conditioned basis, and
whether they separate the parameters.

The stacked equations ``A theta = b`` come with their columns already divided by powers
of two (:mod:`algid.identification._identify`: every factor's samples brought into ``[1, 2)``, the
time measured in a power of two near the sampling step), so that no product of them
overflows or underflows whatever the units of the records.  Their columns can still be
nearly dependent for reasons that have nothing to do with the data's information: an
offset next to a drift ``d1*t`` on Unix-epoch times, or ``t**6`` next to ``t``.  Normal
equations square that conditioning, so every solver works in the basis of
:class:`WindowBasis`: the columns scaled by powers of two to norms in ``[0.5, 1)`` and
then orthonormalised (a QR factorisation), the known side scaled by a power of two.
The parameters in that basis, ``phi``, give back ``theta = M phi`` (``M`` upper
triangular over a power of two).

Separability (:func:`separability`): from the same factorisation, the singular values
of the regressors with unit columns.  A smallest one at round-off level
(:data:`ROUNDOFF_SEPARABILITY`) means proportional terms; otherwise it is compared with
the equations' own misfit, the smallest singular value of the regressors and the known
side together (with unit columns): the ratio (:attr:`Separability.ratio`) is at least 1,
and near 1 the weakest combination of the parameters is no better determined than the
misfit (output noise, quadrature error, model error): that combination is free.  Columns
that do not read the output (inputs, offsets, drifts in ``t``) carry no output noise and
are taken out of that comparison.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from algid.errors import InputDataError

__all__ = ["WindowBasis", "Separability", "separability", "check_excited", "check_finite",
           "exponent",
           "ROUNDOFF_SEPARABILITY", "FREE_RATIO", "WEAK_RATIO", "FREE_NOISE_RATIO",
           "WEAK_NOISE_RATIO", "COLLINEAR", "DETERMINED_LEAK"]

#: Smallest singular value of the unit-column regressors below which terms count as
#: proportional whatever the misfit (round-off of window sums is about 1e-15).
ROUNDOFF_SEPARABILITY = 1e-10

#: Largest share of a parameter's unit direction in the null space of the equations at
#: which it still counts as determined (round-off leaves about 1e-15; the tracker's).
DETERMINED_LEAK = 1e-6

#: Separability ratio below which the weakest parameter combination counts as free.
FREE_RATIO = 1.5

#: Separability ratio below which the weakest combination is reported as poorly
#: determined (a warning).
WEAK_RATIO = 4.0

#: Noise separability (second generalised eigenvalue over the first) below which a
#: combination counts as free: it is determined to about its own size or worse.
FREE_NOISE_RATIO = 2.0

#: Noise separability below which a combination is reported as poorly determined.
WEAK_NOISE_RATIO = 10.0

#: Smallest singular value of the unit-column regressors below which some parameters
#: are reported as strongly correlated (a condition index of 1000).
COLLINEAR = 1e-3

#: A parameter belongs to the weakest combination if its weight there is at least this
#: fraction of the largest weight.
NAMED_WEIGHT = 0.1


def exponent(values):
    """The power of two ``e`` bringing the largest ``|value|`` into ``[1, 2)``.

    Zero where no value is nonzero.

    Parameters
    ----------
    values : array_like or sequence of array_like
        Finite samples.

    Returns
    -------
    int
    """
    largest = max((float(np.max(np.abs(v))) for v in values if np.size(v)), default=0.0) \
        if isinstance(values, (list, tuple)) else float(np.max(np.abs(values), initial=0.0))
    if largest == 0.0 or not np.isfinite(largest):
        return 0
    return int(np.frexp(largest)[1]) - 1


class WindowBasis:
    """Orthonormal regressors ``Q = A D R^-1`` and known side ``beta b``.

    Parameters
    ----------
    A : numpy.ndarray, shape (windows, p)
        Regressors (no zero column).
    b : numpy.ndarray, shape (windows,)
        Known side.

    Attributes
    ----------
    A, b : numpy.ndarray
        The regressors and known side in the basis.
    R : numpy.ndarray
        The triangular factor of the scaled ``[A | b]`` (``p + 1`` square).
    """

    def __init__(self, A, b):
        p = A.shape[1]
        self.shifts = np.array([exponent(np.linalg.norm(A[:, i])) + 1 for i in range(p)])
        self.b_shift = exponent(np.linalg.norm(b)) + 1
        scaled = np.column_stack([np.ldexp(A, -self.shifts), np.ldexp(b, -self.b_shift)])
        Q, self.R = np.linalg.qr(scaled)
        self.A = Q[:, :p]
        self.b = scaled[:, p]
        self._inverse = None

    @property
    def map(self):
        """``M`` with ``theta = M phi`` when ``beta`` is folded in: ``D R^-1 / beta``."""
        if self._inverse is None:
            p = len(self.shifts)
            inverse = np.linalg.inv(self.R[:p, :p])
            self._inverse = np.ldexp(inverse, (self.b_shift - self.shifts)[:, None])
        return self._inverse

    @property
    def change(self):
        """``M`` with ``[A | b]`` in the basis ``= [A | b] M`` (``p + 1`` square)."""
        p = len(self.shifts)
        full = np.zeros((p + 1, p + 1))
        full[:p, :p] = np.ldexp(np.linalg.inv(self.R[:p, :p]), -self.shifts[:, None])
        full[p, p] = np.ldexp(1.0, -self.b_shift)
        return full

    def grams(self, grams):
        """Per-window noise covariances of ``[A | b]`` in the basis.

        Parameters
        ----------
        grams : numpy.ndarray, shape (windows, p + 1, p + 1)
            Those of the original ``[A | b]`` (overwritten; a read-only broadcast of
            one window's, as a streamed record's, is transformed once).

        Returns
        -------
        numpy.ndarray
            ``grams``, in the basis.
        """
        full = self.change
        if not grams.flags.writeable and grams.strides[0] == 0:   # one for every window
            return np.broadcast_to(full.T @ grams[0] @ full, grams.shape)
        for start in range(0, len(grams), 4096):   # in place, in blocks: no full copies
            block = grams[start:start + 4096]
            block[...] = full.T @ block @ full
        return grams

    def theta(self, phi):
        """Parameters from their values in the basis.

        Parameters
        ----------
        phi : numpy.ndarray
            Solution of ``self.A phi = self.b``.

        Returns
        -------
        numpy.ndarray
            Solution of the original ``A theta = b``.
        """
        return self.map @ phi

    def covariance(self, covariance):
        """Covariance of the parameters from that in the basis.

        Parameters
        ----------
        covariance : numpy.ndarray
            Covariance of ``phi``.

        Returns
        -------
        numpy.ndarray
        """
        return self.map @ covariance @ self.map.T

    def instruments(self, Z):
        """Instruments in the basis (the same change of variables as the regressors).

        Parameters
        ----------
        Z : numpy.ndarray, shape (windows, p)
            Instruments of the original regressors.

        Returns
        -------
        numpy.ndarray
        """
        p = len(self.shifts)
        return np.ldexp(Z, -self.shifts) @ np.linalg.inv(self.R[:p, :p])


@dataclass
class Separability:
    """How well the window equations separate the parameters.

    Attributes
    ----------
    smallest : float
        Smallest singular value of the regressors with unit columns (of the measured
        columns less their projection on the exact ones, see :func:`separability`).
    misfit : float
        Smallest singular value of those regressors and the known side.
    weights : numpy.ndarray
        The weakest combination of the parameters (unit columns).
    noise_ratio : float
        The second smallest generalised eigenvalue of the normal matrix of ``[A | b]``
        and the output noise's covariance, over the smallest (infinite without noise).
    noise_weights : numpy.ndarray or None
        The combination of the parameters of the second eigenvector, less the known side.
    collinear : float
        Smallest singular value of all the regressors with unit columns (exact ones
        included): below :data:`COLLINEAR` some parameters are strongly correlated.
    collinear_weights : numpy.ndarray or None
        Its combination of the parameters.
    """

    smallest: float
    misfit: float
    weights: np.ndarray
    noise_ratio: float = np.inf
    noise_weights: np.ndarray | None = None
    collinear: float = 1.0
    collinear_weights: np.ndarray | None = None

    @property
    def ratio(self):
        """``smallest / misfit`` (at least 1; infinite for exact equations)."""
        return self.smallest / self.misfit if self.misfit > 0 else np.inf

    @property
    def proportional(self):
        """Whether the weakest combination is zero to round-off."""
        return self.smallest < ROUNDOFF_SEPARABILITY

    @property
    def free(self):
        """Whether a combination of the parameters is not determined by the records.

        That is: proportional terms, or a combination no better determined than the
        output noise.
        """
        return self.proportional or self.noise_ratio < FREE_NOISE_RATIO

    @property
    def misfit_free(self):
        """Whether a combination is no better determined than the equations' misfit.

        Where the misfit is output noise or quadrature error (the model holds), such a
        combination is free; where it is the model's own error, the model is wrong
        rather than its parameters inseparable.
        """
        return self.ratio < FREE_RATIO

    @property
    def weak(self):
        """Whether some combination is poorly determined or strongly correlated."""
        return (self.ratio < WEAK_RATIO or self.noise_ratio < WEAK_NOISE_RATIO
                or self.collinear < COLLINEAR)

    def _by_noise(self):
        # which test names the combination: the noise's where it is the one that fails
        if self.proportional or self.noise_weights is None:
            return False
        if self.noise_ratio < FREE_NOISE_RATIO:
            return True
        return not self.ratio < WEAK_RATIO and self.noise_ratio < WEAK_NOISE_RATIO

    def involved(self, names):
        """Names of the parameters of the weakest combination.

        Parameters
        ----------
        names : sequence of str
            The parameters, in column order.

        Returns
        -------
        list of str
        """
        w = np.abs(self.noise_weights if self._by_noise() else self.weights)
        return [n for n, v in zip(names, w) if v >= NAMED_WEIGHT * w.max()]

    def _cause(self):
        if self._by_noise():
            return (f"to within the output noise (noise separability {self.noise_ratio:.3g}, "
                    f"need {FREE_NOISE_RATIO:g}; {WEAK_NOISE_RATIO:g} for a reliable error)")
        return (f"to within the equations' misfit (separability {self.ratio:.3g}, need "
                f"{FREE_RATIO:g}; {WEAK_RATIO:g} for a reliable error)")

    def message(self, names):
        """One line naming the parameters of the weakest combination.

        Parameters
        ----------
        names : sequence of str
            The parameters, in column order.

        Returns
        -------
        str
        """
        involved = self.involved(names)
        listed = (" and ".join(involved) if len(involved) <= 2
                  else ", ".join(involved[:-1]) + " and " + involved[-1])
        one = len(involved) == 1
        if self.proportional:
            cause = ("its term vanishes" if one else
                     "their terms are proportional") + " on these records"
        else:
            cause = (f"{'its term is' if one else 'their terms are'} dependent on these "
                     f"records {self._cause()}")
        verb = "cannot be determined" if one else "cannot be separated"
        return f"parameter{'' if one else 's'} {listed} {verb}: {cause}"

    def poorly_separated(self, misfit=True):
        """Whether :meth:`warnings` reports a poorly determined combination.

        Parameters
        ----------
        misfit : bool
            As in :meth:`warnings`.

        Returns
        -------
        bool
        """
        return bool(misfit and (self.noise_ratio < WEAK_NOISE_RATIO
                                or self.ratio < WEAK_RATIO))

    def warnings(self, names, misfit=True, advice=""):
        """One line per reservation about the estimate.

        A poorly determined combination; strongly correlated parameters.

        Parameters
        ----------
        names : sequence of str
            The parameters, in column order.
        misfit : bool
            Whether the equations' misfit is output noise or quadrature error (the
            model holds): if not, both tests measure the model's error, and a poorly
            determined combination is not reported (the model's error is).
        advice : str
            What would help (:func:`algid.identification._window_rule.window_advice`),
            appended to the line of a poorly determined combination.

        Returns
        -------
        list of str
        """
        lines = []
        if self.poorly_separated(misfit):
            involved = self.involved(names)
            lines.append(f"parameter{'s' if len(involved) > 1 else ''} {', '.join(involved)}: "
                         f"poorly separated on these records, {self._cause()}; the "
                         f"standard errors are large and less reliable"
                         + (f"; {advice}" if advice else ""))
        if self.collinear < COLLINEAR and self.collinear_weights is not None:
            w = np.abs(self.collinear_weights)
            involved = [n for n, v in zip(names, w) if v >= NAMED_WEIGHT * w.max()]
            lines.append(f"parameters {', '.join(involved)}: nearly proportional terms on "
                         f"these records (smallest singular value {self.collinear:.2g} of "
                         f"the regressors with unit columns, below {COLLINEAR:g}): their "
                         f"estimates are strongly correlated (see the covariance)")
        return lines


def separability(basis, exact=(), noise=None):
    """Separability of the parameters from a :class:`WindowBasis`.

    Two tests.  The misfit's: the smallest singular value of the regressors with unit
    columns against that of the regressors and the known side (the equations' misfit).
    Columns whose factors do not read the output (an input, an offset, a drift in ``t``)
    carry no output noise, and no quadrature error beyond the inputs' own: a
    combination of them alone is determined however small it is (its error is linear
    in the misfit, and the standard errors say how large), so this ratio is that of the
    other columns and the known side after what the exact columns explain is removed
    from them (an offset next to a drift on epoch times does not make the model
    unidentifiable, only the two parameters strongly correlated).  The noise's, when
    the output noise's covariance of ``[A | b]`` is given: the generalised eigenvalues
    of the normal matrix and that covariance are the misfit per unit of noise of every
    combination; the smallest is the model's equation, and a second one close to it a
    combination of the parameters that the data determine no better than the noise
    (columns unequally affected by noise, as a third derivative and the plain output,
    make the first test's singular values differ even for such a combination).

    Parameters
    ----------
    basis : WindowBasis
    exact : sequence of int
        Indices of the exact columns.
    noise : numpy.ndarray, optional
        Output noise covariance of ``[basis.A | basis.b]`` (summed over the windows).

    Returns
    -------
    Separability
    """
    R = basis.R
    p = R.shape[0] - 1
    tiny = np.finfo(float).tiny
    unit = R / np.maximum(np.linalg.norm(R, axis=0), tiny)
    _, values, vectors = np.linalg.svd(unit[:p, :p])
    if values[-1] < ROUNDOFF_SEPARABILITY:
        return Separability(float(values[-1]), float(values[-1]), vectors[-1])
    collinear, collinear_vectors = values, vectors
    exact = sorted(set(exact))
    measured = [i for i in range(p) if i not in exact]
    smallest, misfit, weights = float(values[-1]), 0.0, vectors[-1]
    if measured:
        # the measured columns and the known side, less their projection on the exact ones
        k = len(exact)
        full = np.linalg.qr(R[:, exact + measured + [p]], mode="r")
        norms = np.maximum(np.linalg.norm(full[k:, k:], axis=0), tiny)
        rest = full[k:, k:] / norms
        _, values, vectors = np.linalg.svd(rest[:, :-1])
        smallest = float(values[-1])
        misfit = float(np.linalg.svd(rest, compute_uv=False)[-1])
        # the weakest combination, with the exact columns that compensate it
        coefficients = np.zeros(p)
        coefficients[measured] = vectors[-1] / norms[:-1]
        if k:
            coefficients[exact] = -np.linalg.solve(full[:k, :k], full[:k, k:-1]
                                                   @ coefficients[measured])
        weights = coefficients * np.linalg.norm(R[:, :p], axis=0)
    result = Separability(smallest, misfit, weights, collinear=float(collinear[-1]),
                          collinear_weights=collinear_vectors[-1])
    if noise is not None and p > 1 and np.any(noise != 0):
        _noise_test(result, basis, noise)
    return result


def _noise_test(result, basis, noise):
    """The noise's separability test of :func:`separability` (fills ``result``)."""
    from scipy.linalg import eigh

    p = len(basis.shifts)
    phi = np.column_stack([basis.A, basis.b])
    normal = phi.T @ phi
    d = np.sqrt(np.diag(normal))
    try:
        mu, vectors = eigh(noise / d[:, None] / d[None, :], normal / d[:, None] / d[None, :])
    except np.linalg.LinAlgError:   # equations exact to round-off: no noise to compare
        return
    if not mu[-1] > 0:
        return
    result.noise_ratio = float(mu[-1] / mu[-2]) if mu[-2] > 0 else np.inf
    first, second = vectors[:, -1] / d, vectors[:, -2] / d
    combination = second * first[p] - first * second[p]   # no known side in it
    direction = np.linalg.solve(basis.R[:p, :p], combination[:p])
    result.noise_weights = direction * np.linalg.norm(basis.R[:p, :p], axis=0)


def check_finite(problem, A, b):
    """Refuse window equations whose products overflow floating point.

    Parameters
    ----------
    problem : object
        The windowed problem of :func:`algid.identify`: its ``parameters`` and ``model``.
    A, b : numpy.ndarray
        The window equations.

    Raises
    ------
    InputDataError
        Naming the terms of the columns that overflow (a constant coefficient too large
        for the units of the signals).
    """
    with np.errstate(over="ignore", invalid="ignore"):
        squares = np.sum(np.column_stack([A, b]) ** 2, axis=0)
    if np.all(np.isfinite(squares)):
        return
    columns = [*problem.parameters, None]
    bad = {columns[i] for i in np.flatnonzero(~np.isfinite(squares))}
    terms = [t for t in problem.model.terms if t.parameter in bad]
    largest = max(abs(t.coefficient) for t in terms)
    named = ", ".join(str(t).lstrip("-") for t in terms if abs(t.coefficient) == largest)
    raise InputDataError(f"the term {named} of the equation overflows floating point: its "
                         f"constant coefficient {largest:g} is too large for these units "
                         f"(rescale the equation or the signals)")


def check_excited(problem, length, multiplicity, A, b):
    """Refuse records on which a parameter's terms, or the known side, vanish.

    Parameters
    ----------
    problem : object
        The windowed problem of :func:`algid.identify`: its ``parameters``, ``model``
        and ``excitation(length, multiplicity, A, b)`` (per column and for the known
        side, their size relative to the largest they could have).
    length, multiplicity : int
        The windows of ``A`` and ``b``.
    A, b : numpy.ndarray
        The window equations.

    Raises
    ------
    InputDataError
        Naming the parameters whose terms vanish, or the known side.
    """
    excitation = problem.excitation(length, multiplicity, A, b)
    idle = [p for p, e in zip(problem.parameters, excitation) if e < ROUNDOFF_SEPARABILITY]
    if excitation[-1] < ROUNDOFF_SEPARABILITY and len(idle) == len(problem.parameters):
        raise InputDataError("the signals are constant or zero on these records: they "
                             "determine no parameter")
    if idle:
        terms = ", ".join(f"{t.factor}" + "'" * t.derivative
                          for t in problem.model.terms if t.parameter in idle)
        one = len(idle) == 1
        raise InputDataError(f"parameter{'' if one else 's'} {', '.join(idle)} cannot be "
                             f"determined: {'its term' if one else 'their terms'} {terms} "
                             f"vanish{'es' if one else ''} on these records (a constant "
                             f"signal, or one too small in these units)")
    if excitation[-1] < ROUNDOFF_SEPARABILITY:
        known = " + ".join(str(t) for t in problem.model.known_terms) or "0"
        raise InputDataError(f"the known side {known} vanishes on these records: nothing "
                             f"fixes the scale of the parameters")
