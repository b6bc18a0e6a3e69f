"""Hidden signals of a linear system of equations: eliminated into input–output
equations, whose coefficients are mapped back to the physical parameters.

With the operator ``D`` the system is ``P(D) y + Q(D) u = 0`` (``P`` square, one
output per equation; constant coefficients, so ``D`` commutes with them and Cramer's
rule holds for the operators).  Multiplying by the adjugate of ``P`` gives, for every
measured output ``y_j``, ``det P(D) y_j + (adj P Q)_j(D) u = 0``: an equation in that
output and the inputs only, every hidden signal gone.  Divided by the leading
coefficient of ``det P`` (the measured output's highest derivative then has the known
coefficient 1), its coefficients are rational functions ``c(theta)`` of the physical
parameters; those of ``det P`` are shared by the equations of all the measured outputs.

- **Identifiability** (:func:`check_identifiable`): the rank of the Jacobian of ``c``
  at generic parameter values; below the number of parameters, the set is refused,
  naming what is determined (the coefficients as functions of the parameters) and the
  parameters of which one must be fixed.
- **Back to the parameters** (:func:`physical_parameters`): weighted least squares on
  ``c(theta) = c_hat`` with the coefficients' covariance, from many starts; parameter
  sets that fit equally well are reported as several solutions; the covariance by the
  delta method.  The output-error refinement on the full system (the hidden signals
  simulated) then makes the estimate efficient
  (:mod:`algid.identification._system_refinement`).

SymPy does the elimination (the ``derive`` extra).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from algid.errors import InputDataError, ModelError
from algid.models._expression import Constant, Signal
from algid.models._grammar import LIMITS

__all__ = ["Elimination", "eliminate", "check_identifiable", "physical_parameters",
           "STARTS", "NEAR_COST", "MAX_CANDIDATES"]

#: Starting points of the least-squares map from the coefficients to the parameters.
STARTS = 64

#: Distinct solutions of that map whose weighted cost is within this much of the best
#: (a chi-square difference of 3 standard errors in one direction) are candidates too:
#: the coefficients' noise can favour a wrong set, and the output-error fit on the full
#: system chooses between them.
NEAR_COST = 9.0

#: At most this many such candidates besides the best.
MAX_CANDIDATES = 2

#: Relative rank tolerance of the coefficient map's Jacobian at generic values.
RANK_TOLERANCE = 1e-8


@dataclass
class Elimination:
    """The input–output equations of a system with hidden signals.

    Attributes
    ----------
    equations : list of str
        One per measured output, in algid's grammar, with coefficient parameters.
    coefficients : list of str
        The names of the coefficient parameters.
    expressions : dict
        Coefficient name -> its SymPy expression in the physical parameters.
    latex : list of str
        Each input–output equation in LaTeX, with its coefficients as functions of the
        physical parameters.
    """

    equations: list
    coefficients: list
    expressions: dict
    latex: list

    def coefficient_map(self, parameters):
        """``c(theta)`` and its Jacobian as NumPy functions of the parameters (in the
        order of ``parameters``)."""
        import sympy as sp

        symbols = [sp.Symbol(p) for p in parameters]
        exprs = [self.expressions[c] for c in self.coefficients]
        values = sp.lambdify(symbols, exprs, "numpy")
        jacobian = sp.lambdify(symbols, sp.Matrix(exprs).jacobian(symbols), "numpy")
        return (lambda theta: np.array(values(*theta), dtype=float),
                lambda theta: np.array(jacobian(*theta), dtype=float))


def _sympy():
    try:
        import sympy
    except ImportError:
        raise ModelError("hidden signals are eliminated by SymPy: install the 'derive' "
                         "extra (pip install 'algid[derive]')") from None
    return sympy


def eliminate(system, hidden):
    """Eliminate the ``hidden`` outputs of a linear system (see the module notes).

    Parameters
    ----------
    system : algid.models.SystemModel
    hidden : sequence of str
        Outputs of the system that are not measured.

    Returns
    -------
    Elimination

    Raises
    ------
    ModelError
        A nonlinear equation, a term in time, a hidden name that is no output, every
        output hidden.
    """
    sp = _sympy()
    outputs = list(system.outputs)
    for name in hidden:
        if name not in outputs:
            raise ModelError(f"hidden signal {name!r} is no equation's output "
                             f"({', '.join(outputs)}); only outputs can be hidden")
    measured = [y for y in outputs if y not in hidden]
    if not measured:
        raise ModelError("every output is hidden: nothing measured to identify on")
    if not system.is_linear:
        raise ModelError("hidden signals are eliminated from linear systems only (a hidden "
                         "signal inside a nonlinear factor cannot be)")
    s = sp.Symbol("s")
    channels = []
    for model in system.equations:
        for term in model.terms:
            if isinstance(term.factor, Signal) and term.factor.name not in outputs:
                channels.append(term.factor.name)
            elif isinstance(term.factor, Constant):
                channels.append("1")
            elif not isinstance(term.factor, Signal):
                raise ModelError(f"the term {term} cannot be carried through the "
                                 f"elimination of hidden signals (time terms are not)")
    channels = list(dict.fromkeys(channels))
    m = len(outputs)
    P, Q = sp.zeros(m, m), sp.zeros(m, len(channels))
    for i, model in enumerate(system.equations):
        for term in model.terms:
            c = sp.nsimplify(term.coefficient) * (1 if term.parameter is None
                                                  else sp.Symbol(term.parameter))
            factor = term.factor
            if isinstance(factor, Signal) and factor.name in outputs:
                P[i, outputs.index(factor.name)] += c * s ** term.derivative
            elif isinstance(factor, Signal):
                Q[i, channels.index(factor.name)] += c * s ** term.derivative
            else:   # the constant 1: its derivatives vanish
                Q[i, channels.index("1")] += sp.nsimplify(factor.value) * c * \
                    (1 if term.derivative == 0 else 0)
    det = sp.expand(P.det())
    adjugate = P.adjugate()
    det_poly = sp.Poly(det, s)
    if det_poly.is_zero:
        raise ModelError("the equations do not determine their outputs (their operator "
                         "matrix is singular)")
    order = det_poly.degree()
    lead = det_poly.LC()
    expressions, coefficients, equations, latex = {}, [], [], []

    def coefficient(name, expr):
        expr = sp.cancel(expr / lead)
        if expr.free_symbols:
            if name not in expressions:
                expressions[name] = expr
                coefficients.append(name)
            return name, expr
        return None, expr

    most = 0   # (the coefficients of one eliminated equation, at most)
    for y in measured:
        j = outputs.index(y)
        pieces, tex, used = [], [], set()
        for k in range(order, -1, -1):
            a = det_poly.coeff_monomial(s ** k)
            if a == 0:
                continue
            name, expr = coefficient(f"a{k}", a)
            used.add(name)
            pieces.append(_term(name, expr, y, k))
            tex.append(_tex(expr, y, k))
        coupled = sp.expand(adjugate[j, :] * Q) if Q.shape[1] else sp.zeros(1, 0)
        for c, channel in enumerate(channels):
            poly = sp.Poly(sp.expand(coupled[0, c]), s)
            if poly.is_zero:
                continue
            for k in range(poly.degree(), -1, -1):
                b = poly.coeff_monomial(s ** k)
                if b == 0:
                    continue
                label = "one" if channel == "1" else channel
                suffix = f"_{y}" if len(measured) > 1 else ""
                name, expr = coefficient(f"b{k}_{label}{suffix}", b)
                used.add(name)
                if channel == "1":
                    pieces.append(name if name else _number(expr))
                    tex.append(sp.latex(expr))
                else:
                    pieces.append(_term(name, expr, channel, k))
                    tex.append(_tex(expr, channel, k))
        equations.append(" + ".join(pieces).replace("+ -", "- ") + " = 0")
        latex.append(" + ".join(tex) + " = 0")
        most = max(most, len(used - {None}))
    if most > LIMITS["parameters"]:
        raise ModelError(f"hiding {', '.join(hidden)} leaves an input-output equation with "
                         f"{most} coefficients to identify, more than the "
                         f"{LIMITS['parameters']} an equation may have: measure "
                         f"{'it' if len(hidden) == 1 else 'one of them'}, or hide another "
                         f"output instead")
    if len(coefficients) > LIMITS["system_parameters"]:
        raise ModelError(f"hiding {', '.join(hidden)} leaves input-output equations with "
                         f"{len(coefficients)} coefficients to identify, more than the "
                         f"{LIMITS['system_parameters']} a system may have: measure "
                         f"{'it' if len(hidden) == 1 else 'one of them'}")
    for name in coefficients:
        if name in system.signals:
            raise ModelError(f"a signal is named {name}, as a coefficient of the eliminated "
                             f"equations: rename it")
    return Elimination(equations, coefficients, expressions, latex)


def _number(expr):
    return repr(float(expr))


def _term(name, expr, signal, k):
    primes = "'" * k
    if name is None:
        return f"{signal}{primes}" if expr == 1 else f"{_number(expr)}*{signal}{primes}"
    return f"{name}*{signal}{primes}"


def _tex(expr, signal, k):
    import sympy as sp

    derivative = signal if k == 0 else (f"{signal}^{{({k})}}" if k > 3
                                        else signal + "'" * k)
    if expr == 1:
        return derivative
    return rf"\left({sp.latex(expr)}\right) {derivative}"


def check_identifiable(elimination, parameters, seed=0):
    """Refuse parameters that the input–output coefficients cannot determine.

    The Jacobian of the coefficient map at generic values (uniform in ``[0.5, 2]``) has
    full column rank where the parameters are locally identifiable.

    Parameters
    ----------
    elimination : Elimination
    parameters : sequence of str

    Raises
    ------
    ModelError
        Naming what is determined and which parameters to fix.
    """
    _, jacobian = elimination.coefficient_map(parameters)
    rng = np.random.default_rng(seed)
    J = jacobian(rng.uniform(0.5, 2.0, len(parameters)))
    if J.shape[0] < len(parameters):
        rank, null = J.shape[0], np.linalg.svd(J)[2][-1]
    else:
        sv, vt = np.linalg.svd(J)[1:]
        rank = int(np.sum(sv > RANK_TOLERANCE * sv[0]))
        null = vt[-1]
    if rank >= len(parameters):
        return
    weight = np.abs(null)
    named = [p for p, w in zip(parameters, weight) if w >= 0.1 * weight.max()]
    shown = ", ".join(str(elimination.expressions[c]) for c in elimination.coefficients)
    raise ModelError(f"the measured signals determine only {rank} combinations of the "
                     f"{len(parameters)} parameters ({shown}): fix one of "
                     f"{', '.join(named)}")


def physical_parameters(elimination, parameters, values, covariance, seed=0):
    """The parameters from the coefficients' estimate, by weighted least squares.

    Parameters
    ----------
    elimination : Elimination
    parameters : sequence of str
    values : mapping
        Coefficient name -> estimate.
    covariance : numpy.ndarray
        Their covariance (in ``elimination.coefficients`` order).

    Returns
    -------
    theta : numpy.ndarray
        The best fit.
    theta_covariance : numpy.ndarray
        By the delta method.
    others : list of numpy.ndarray
        Further parameter sets that fit the coefficients as well (several solutions).
    candidates : list of (numpy.ndarray, numpy.ndarray)
        Further distinct sets that fit them nearly as well (within :data:`NEAR_COST`),
        with their covariances, best first: for the output-error fit to choose from.
    """
    from scipy.optimize import least_squares

    values_of, jacobian = elimination.coefficient_map(parameters)
    c_hat = np.array([values[c] for c in elimination.coefficients])
    se = np.sqrt(np.maximum(np.diag(covariance), 0.0))
    se[se == 0] = 1.0
    corr = covariance / se[:, None] / se[None, :]
    whiten = np.linalg.cholesky(np.linalg.inv(corr + 1e-12 * np.eye(len(se)))).T

    def residuals(theta):
        with np.errstate(all="ignore"):
            r = whiten @ ((values_of(theta) - c_hat) / se)
        return np.where(np.isfinite(r), r, 1e150)

    rng = np.random.default_rng(seed)
    fits = []
    for _ in range(STARTS):
        start = 10 ** rng.uniform(-2, 2, len(parameters))
        solution = least_squares(residuals, start, method="lm", xtol=1e-14, ftol=1e-14,
                                 gtol=1e-14, max_nfev=100 * (len(parameters) + 1))
        if np.all(np.isfinite(solution.x)):
            fits.append((2 * solution.cost, solution.x))
    if not fits:
        raise InputDataError("no parameter values reproduce the estimated coefficients of "
                             "the eliminated equations")
    fits.sort(key=lambda f: f[0])
    best_cost, theta = fits[0]
    def distinct(x, sets):   # (by more than 1e-4 relative in some parameter)
        return all(np.max(np.abs(x - o) / np.maximum(np.abs(o), 1e-300)) > 1e-4
                   for o in sets)

    others, candidates = [], []
    for cost, x in fits[1:]:   # (all finite)
        if cost <= best_cost + 1e-6 * (1 + best_cost) + 1e-9 and \
                distinct(x, [theta, *others]):
            others.append(x)
        elif len(candidates) < MAX_CANDIDATES and cost <= best_cost + NEAR_COST and \
                distinct(x, [theta, *others, *candidates]):
            candidates.append(x)

    def delta_method(x):
        J = jacobian(x)
        return np.linalg.pinv(J.T @ np.linalg.solve(covariance, J))

    return (theta, delta_method(theta), others,
            [(x, delta_method(x)) for x in candidates])
