"""Whether the refined model explains the records: tests of its simulation residuals.

A right model leaves in the residuals of its output-error fit only the output noise,
whatever its colour and whatever the inputs: nothing in them follows the inputs or the
simulated output.  A wrong one leaves its error, and that error has a direction: the
output's response to the term the model lacks.  Each :data:`CANDIDATES` names such a
term ``z`` (a constant, time, an input, an input's derivative, a power of the output, the
sign of its velocity) or a time shift of the output; its direction is the model's own
response to ``z`` (``z`` through ``1/A(D)``, from rest), or ``-y'`` for a delay, with the
directions the fit already spans (the parameters' and the initial states') projected
out.  The score of a direction ``d`` is the squared projection of the residuals on it
over its variance under the residuals' own correlation (the autoregressive model of the
covariance, :func:`algid.identification._refinement.sandwich_covariance`):

    chi2 = (d' r)**2 / (s2 * |H' d|**2)

(Lagrange multiplier test of adding the term), chi-square with one degree of freedom
for a right model.  A direction whose score exceeds :data:`CHI2_LIMIT`, and whose part
of the residuals is at least :data:`NEGLIGIBLE` of the output's rms, is reported,
naming the term as the likely cause; a term the model already has scores nothing (its
direction is projected out).  The whiteness of the residuals is not tested: coloured
output noise is no model error, and the covariance counts it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from algid.identification._linear_simulation import LinearSimulation, output_polynomials
from algid.identification._refinement import ar_fit, ar_order_limit
from algid.models._expression import Signal

__all__ = ["ResidualTest", "residual_test", "nonlinear_residual_test", "score_directions",
           "candidate_terms", "settles", "system_residual_test",
           "nonlinear_system_residual_test", "equation_candidates", "CHI2_LIMIT", "CANDIDATES",
           "DIRECTION_CHANGE"]

#: The score beyond which a direction is a model error: chi-square(1) exceeded with
#: probability 1e-4 (about 1e-3 over the candidates of a model with one input).
CHI2_LIMIT = 15.14

#: A shift of the output is read as a delay up to this fraction of the fastest mode's
#: period (beyond, a first-order shift means nothing).
DELAY_FRACTION = 0.05

#: Two directions whose normalised product exceeds this are the same cause.
SAME_DIRECTION = 0.99

#: A direction that keeps less than this part of its energy once the fitted ones are
#: projected out is one of them (the round-off of the projection remains).
SPANNED = 1e-8

#: A candidate whose part of the residuals is below this fraction of the output's rms
#: is not reported, however significant (the interpolation error of a noise-free record).
NEGLIGIBLE = 1e-3

#: A nonlinear model's direction for a candidate term is a central difference in the
#: term's coefficient that changes the simulated output by about this fraction of its
#: rms (:func:`nonlinear_residual_test`).
DIRECTION_CHANGE = 1e-6

#: The candidate causes, in the order they are reported at equal scores.
CANDIDATES = ("offset", "drift", "delay", "gain", "derivative", "cubic", "square",
              "coulomb")


@dataclass
class ResidualTest:
    """Scores of the refined fit's residuals against the candidate model errors.

    Attributes
    ----------
    scores : dict
        Candidate (``"offset"``, ``"delay"``, ``"gain:u"``, ...) -> chi-square score.
    coefficients : dict
        Candidate -> the residuals' regression coefficient on its direction (for
        ``"delay"``: the delay in seconds).
    limit : float
        :data:`CHI2_LIMIT`.
    messages : dict
        Candidate -> the warning it gives when its score exceeds the limit.
    aliases : dict
        Candidate -> the candidate of the same direction named in its place (an output
        shifted in time and an input's derivative, through a constant numerator).
    negligible : set
        Candidates whose part of the residuals is below :data:`NEGLIGIBLE` of the
        output's rms: not reported, whatever their score.
    """

    scores: dict = field(default_factory=dict)
    coefficients: dict = field(default_factory=dict)
    limit: float = CHI2_LIMIT
    messages: dict = field(default_factory=dict)
    aliases: dict = field(default_factory=dict)
    negligible: set = field(default_factory=set)

    @property
    def adequate(self):
        """True when no candidate scores above the limit."""
        return not any(v > self.limit and k not in self.negligible
                       for k, v in self.scores.items())

    def warnings(self):
        """One line per model error found, the likeliest first.

        Returns
        -------
        list of str
        """
        found = sorted((k for k, v in self.scores.items() if v > self.limit
                        and k not in self.aliases and k not in self.negligible),
                       key=lambda k: -self.scores[k])
        return [f"the simulation residuals {self.messages[k]} "
                f"(score {self.scores[k]:.3g}, limit {self.limit:.3g})" for k in found]


def _response(den, z, step, upsampling):
    """The forced response of ``A(D) y = z`` (z at the fine points)."""
    sim = LinearSimulation.of_polynomials(den, {"z": {0: 1.0}}, step, upsampling)
    return sim.run(z[None, :])[0]


def _fine(values, upsampling):
    """Coarse samples joined linearly at the fine points."""
    if upsampling == 1:
        return values
    coarse = np.arange(len(values)) * upsampling
    return np.interp(np.arange(coarse[-1] + 1), coarse, values)


def candidate_terms(output, inputs):
    """The candidate model errors: name -> (the term a model would add, in its
    signals, or None for the output's shift in time; the message that names it).

    Parameters
    ----------
    output : str
    inputs : sequence of str

    Returns
    -------
    dict
    """
    out = {"offset": ("1", "keep a constant part: an offset missing? (add a constant "
                           "term, e.g. '+ d')"),
           "drift": ("t", "grow with time: a drift? (add a term in t, e.g. '+ d1*t')")}
    for name in inputs:
        out[f"gain:{name}"] = (name, f"follow {name}: a wrong or missing gain of {name}? "
                                     f"(give its coefficient a parameter)")
        out[f"derivative:{name}"] = (f"{name}'", f"follow {name}': a term in {name}' "
                                                 f"missing?")
    out["cubic"] = (f"{output}**3", f"follow {output}**3: a cubic term missing? (e.g. "
                                    f"'+ K3*{output}**3')")
    out["square"] = (f"{output}**2", f"follow {output}**2: a quadratic term missing?")
    out["coulomb"] = (f"sign({output}')", f"follow sign({output}'): Coulomb friction "
                                          f"missing? (e.g. '+ Fc*sign({output}')')")
    out["delay"] = (None, "follow the model's output shifted in time: a delay between the "
                          "input and the output?")
    return out


def _directions(data, den, simulated):
    """Candidate name -> (its message, its direction per segment)."""
    model, step, L = data.model, data.step, data.upsampling
    inputs = [c for c in data.channels if not c.startswith("__")]
    fine_step = step / L
    lengths = [(len(y) - 1) * L + 1 for y in data.outputs]
    velocity = [np.gradient(y, step) for y in simulated]
    forcing = {"offset": [np.ones(n) for n in lengths],
               "drift": [np.linspace(0.0, (len(y) - 1) * step, (len(y) - 1) * L + 1)
                         for y in data.outputs],
               "cubic": [_fine(y ** 3, L) for y in simulated],
               "square": [_fine(y ** 2, L) for y in simulated],
               "coulomb": [_fine(np.sign(v), L) for v in velocity]}
    for name in inputs:
        row = data.channels.index(name)
        forcing[f"gain:{name}"] = [u[row] for u in data.inputs]
        forcing[f"derivative:{name}"] = [np.gradient(u[row], fine_step) for u in data.inputs]
    out = {}
    for name, (_, message) in candidate_terms(model.output, inputs).items():
        if name == "delay":
            out[name] = (message, [-v for v in velocity])
        else:
            out[name] = (message, [_response(den, z, step, L) for z in forcing[name]])
    return out


def residual_test(data, theta, residual, free, J, bounds, ar, dof):
    """The scores of :class:`ResidualTest` for a refined fit of a linear model.

    Parameters
    ----------
    data : algid.identification._output_error.OutputErrorData
    theta : numpy.ndarray
        The refined parameters.
    residual : numpy.ndarray
        The simulation residuals (every segment, stacked).
    free : list of numpy.ndarray
        Per segment, the free responses.
    J : numpy.ndarray
        The parameters' Jacobian, free responses projected out.
    bounds : list of (int, int)
        Each segment's rows.
    ar : numpy.ndarray
        The residuals' autoregressive polynomial.
    dof : int
        Residual degrees of freedom.

    Returns
    -------
    ResidualTest
    """
    den, _ = output_polynomials(data.model, dict(zip(data.model.parameters, theta)))
    simulated = [data.outputs[i] - residual[a:b] for i, (a, b) in enumerate(bounds)]
    with np.errstate(all="ignore"):
        directions = _directions(data, den, simulated)
    test, projected = score_directions(directions, data.outputs, residual, free, J, bounds,
                                       ar, dof, data.step)
    _one_of_delay_and_derivative(test, projected, den)
    return test


def _one_of_delay_and_derivative(test, projected, den):
    """Where the output's shift and an input's derivative are the same direction (a
    constant numerator), name one cause: a delay where the shift is small next to the
    fastest mode of ``A(D)`` (``den``: derivative order -> coefficient), what a shift
    can mean, else the derivative."""
    if "delay" not in test.coefficients:
        return
    tau = test.coefficients["delay"]
    poles = np.roots([den.get(k, 0.0) for k in range(max(den), -1, -1)]) if den \
        else np.zeros(0)
    fastest = np.max(np.abs(poles)) if poles.size else np.inf
    small = abs(tau) <= DELAY_FRACTION * 2 * np.pi / fastest
    for name in [k for k in projected if k.startswith("derivative:")]:
        if abs(projected[name] @ projected["delay"]) > SAME_DIRECTION:
            hidden, named = (name, "delay") if small else ("delay", name)
            test.aliases[hidden] = named


def nonlinear_residual_test(data, theta, states, residual, free, J, bounds, ar, dof):
    """The scores of :class:`ResidualTest` for a refined fit of a nonlinear model.

    A candidate term's direction is the model's own response to it along the fitted
    trajectory: the derivative of the simulated output in the coefficient of the term
    added to the equation's known side (central differences of the simulation, at the
    fitted parameters and initial states); the output's shift is ``-yhat'``.

    Parameters
    ----------
    data : algid.identification._output_error_nonlinear.NonlinearData
    theta : numpy.ndarray
        The refined parameters.
    states : list of numpy.ndarray
        Per segment, the fitted initial state.
    residual, free, J, bounds, ar, dof
        As in :func:`residual_test` (``free``: per segment, the initial states'
        columns of the Jacobian).

    Returns
    -------
    ResidualTest
    """
    model = data.model
    simulated = [y - residual[a:b] for y, (a, b) in zip(data.outputs, bounds)]
    step = data.simulations[0].step
    candidates = candidate_terms(model.output, model.inputs)
    terms = {name: term for name, (term, _) in candidates.items() if term is not None}
    simulations, added = _with_terms(data, terms)
    directions = {"delay": (candidates["delay"][1],
                            [-np.gradient(y, step) for y in simulated])}
    with np.errstate(all="ignore"):
        for k, name in enumerate(added):
            pieces = _term_direction(simulations, theta, states, simulated, k, len(added))
            if pieces is not None:
                directions[name] = (candidates[name][1], pieces)
    test, projected = score_directions(directions, data.outputs, residual, free, J, bounds,
                                       ar, dof, step)
    _one_of_delay_and_derivative(test, projected, _linear_part(model, theta))
    return test


def nonlinear_system_residual_test(data, theta, states, residual, free, J, bounds, runs, ar,
                                   dof):
    """The scores of :class:`ResidualTest` for a refined fit of a nonlinear system.

    As :func:`nonlinear_residual_test` for one equation: each candidate of
    :func:`candidate_terms` is a term added to one equation's known side (in the outputs
    of that equation, or the inputs), its direction the system's response to it along
    the fitted trajectory (central differences of the compiled simulation in the term's
    coefficient), every output weighted as the residuals are; the output's shift is one
    per output (``-yhat_j'`` on its own rows).  A candidate the simulator cannot take
    (a ``sign()`` of an output, a derivative of an input) is left out.  The warnings
    name the equation.

    Parameters
    ----------
    data : algid.identification._output_error_nonlinear.NonlinearData
        Of a system (``data.runs`` outputs per segment).
    theta : numpy.ndarray
        The refined parameters.
    states : list of numpy.ndarray
        Per segment, the fitted initial state.
    residual, free, J, bounds
        As in :func:`nonlinear_residual_test` (``bounds``: the segments' rows).
    runs : list of (int, int)
        The rows of each output of each segment.
    ar : numpy.ndarray
        The residuals' autoregressive polynomial.
    dof : int
        Residual degrees of freedom.

    Returns
    -------
    ResidualTest
    """
    system = data.model
    weights = data.simulations[0].weights
    simulated = [y - residual[a:b] for y, (a, b) in zip(data.outputs, bounds)]
    step = data.simulations[0].step
    added, simulations = _system_with_terms(data)
    directions = {}
    with np.errstate(all="ignore"):
        for k, (i, key, message) in enumerate(added):
            pieces = _term_direction(simulations, theta, states, simulated, k, len(added))
            if pieces is not None:
                directions[f"{key} in equation {i + 1}"] = (
                    f"{message}; in equation {i + 1}, {system.equations[i].equation}",
                    pieces)
    m = len(system.outputs)
    for j, y in enumerate(system.outputs):
        pieces = []
        for sim in simulated:
            rows = sim.reshape(m, -1)
            shift = np.zeros_like(rows)
            shift[j] = -np.gradient(rows[j] / weights[j], step) * weights[j]
            pieces.append(shift.ravel())
        directions[f"delay of {y}"] = ("", pieces)
    test, _ = score_directions(directions, data.outputs, residual, free, J, runs, ar, dof,
                               step, free_bounds=bounds)
    _name_delays(test, system.outputs, step)
    return test


def _system_with_terms(data):
    """The candidate terms that a system's simulation takes, each added with a fresh
    coefficient (last among the parameters, in order) to one equation's known side, as
    ``(equation, candidate, message)``; per segment, the weighted simulation of the
    system with all of them."""
    from algid.errors import AlgidError
    from algid.models._system import parse_system
    from algid.simulation._fast_simulation import FastSystemSimulation, WeightedRows
    from algid.simulation._system_equations import SystemStructure

    system = data.model
    candidates = [(i, key, term, message) for i, model in enumerate(system.equations)
                  for key, (term, message) in equation_candidates(system, model).items()]
    taken = set(system.parameters) | set(system.signals)
    names = [n for n in (f"c{k}" for k in range(len(candidates) + len(taken)))
             if n not in taken][:len(candidates)]
    equations = [model.equation for model in system.equations]

    def extended(chosen):
        texts = list(equations)
        for name, (i, _, term, _) in zip(names, chosen):
            left, _, right = texts[i].partition("=")
            texts[i] = f"{left}= {right} + {name}*({term})"
        other = parse_system(texts, (*system.parameters, *names[:len(chosen)]),
                             outputs=system.outputs)
        SystemStructure(other)   # (refuses what the simulator cannot take)
        return other

    chosen, other = [], None
    for candidate in candidates:
        try:
            other = extended([*chosen, candidate])
        except AlgidError:
            continue
        chosen.append(candidate)
    if other is None:
        return [], []
    simulations = []
    for seg, base in zip(data.segments, data.simulations):
        columns = {n: seg.values[n] for n in system.inputs}
        simulations.append(WeightedRows(
            FastSystemSimulation(other, seg.t, columns, interpolation=data.interpolation),
            base.weights))
    return [(i, key, message) for i, key, _, message in chosen], simulations


def settles(model, values):
    """Whether the model's linear part in its output (its terms in the output alone) has
    every root in the open left half-plane at ``values``: its simulation then forgets an
    error, so that a misfit that persists is the model's, not drift.  A model without a
    term in the output itself (a mass with friction) integrates: a small error of its
    velocity drifts its simulated position away, whatever its equation lacks.

    Parameters
    ----------
    model : algid.models._model.Model
    values : mapping
        Parameter name -> value.

    Returns
    -------
    bool
    """
    den = _linear_part(model, [values[p] for p in model.parameters])
    coefficients = [den.get(k, 0.0) for k in range(max(den, default=0), -1, -1)]
    if len(coefficients) < 2 or coefficients[0] == 0.0:
        return False
    roots = np.roots(coefficients)
    return bool(np.all(np.isfinite(roots)) and np.all(roots.real < 0))


def _linear_part(model, theta):
    """The terms of a model in its output alone, at ``theta``: derivative order ->
    coefficient (the modes of its linear part)."""
    values = dict(zip(model.parameters, theta))
    den = {}
    for term in model.terms:
        if isinstance(term.factor, Signal) and term.factor.name == model.output:
            value = 1.0 if term.parameter is None else float(values[term.parameter])
            den[term.derivative] = den.get(term.derivative, 0.0) + term.coefficient * value
    return den


def _with_terms(data, terms):
    """The records' simulations of the model with ``+ c_k*(term_k)`` added to its known
    side for every candidate term that can be (the coefficients last among the
    parameters, in order), and the names of the terms added.  One simulation for all:
    its set-up (the inputs on the fine grid) costs as much as a dozen runs."""
    from algid.errors import AlgidError
    from algid.models._grammar import parse_equation
    from algid.simulation._fast_simulation import FastSimulation

    model = data.model
    left, _, right = model.equation.partition("=")
    taken = set(model.parameters) | set(model.signals)
    names = [f"c{k}" for k in range(len(terms) + len(taken))]
    names = [n for n in names if n not in taken][:len(terms)]

    def extended(chosen):
        added = " ".join(f"+ {c}*({terms[name]})" for c, name in zip(names, chosen))
        return parse_equation(f"{left}= {right} {added}",
                              (*model.parameters, *names[:len(chosen)]),
                              output=model.output)

    chosen, equation = [], None
    for name in terms:   # (a term the grammar refuses, or one past its parameters: left out)
        try:
            equation = extended([*chosen, name])
        except AlgidError:
            continue
        chosen.append(name)
    if equation is None:
        return [], []
    try:
        return [FastSimulation(equation, seg.t, {n: seg.values[n] for n in model.inputs},
                               data.interpolation) for seg in data.segments], chosen
    except AlgidError:
        return [], []


def _term_direction(simulations, theta, states, simulated, k, count):
    """Per segment, the derivative of the simulated output in the ``k``-th added term's
    coefficient (central differences changing the output by about
    :data:`DIRECTION_CHANGE` of its rms), or None where the term does not move it."""
    base = np.concatenate(simulated)
    target = DIRECTION_CHANGE * float(np.sqrt(np.mean(base ** 2)))

    def run(c):
        extra = np.zeros(count)
        extra[k] = c
        return [sim.run(np.concatenate([theta, extra]), x0)
                for sim, x0 in zip(simulations, states)]

    h = 1.0
    for _ in range(6):
        up = run(h)
        size = float(np.sqrt(np.mean((np.concatenate(up) - base) ** 2)))
        if not np.isfinite(size):   # (diverged: a smaller coefficient)
            h *= 1e-3
            continue
        if size == 0.0:
            return None
        if 0.1 * target <= size <= 10.0 * target:
            return [(a - b) / (2 * h) for a, b in zip(up, run(-h))]
        h *= target / size
    return None


def _noise_model(residual, bounds, order, dof):
    """The AR polynomial of residual runs and its innovation variance per degree of
    freedom (as :func:`score_directions` uses them)."""
    from scipy.signal import lfilter

    a, _ = ar_fit([residual[lo:hi] for lo, hi in bounds], order)
    innovation = np.concatenate([lfilter(a, [1.0], residual[lo:hi]) for lo, hi in bounds])
    return a, float(innovation @ innovation) / max(dof, 1)


def score_directions(directions, outputs, residual, free, J, bounds, ar, dof, step,
                     free_bounds=None):
    """The :class:`ResidualTest` of the residuals against candidate directions.

    Parameters
    ----------
    directions : dict
        Candidate name -> (its message, its direction per segment).
    outputs : list of numpy.ndarray
        Per segment, the measured output.
    residual, free, J, bounds, ar, dof
        As in :func:`residual_test`.
    step : float
        Sampling step (s): the delay's message counts samples.
    free_bounds : list of (int, int), optional
        The rows of each of ``free`` (by default ``bounds``: a system's free responses
        span all the outputs of a segment, its residuals' runs are one output each).

    Returns
    -------
    test : ResidualTest
    projected : dict
        Candidate -> its direction with the fitted ones projected out, unit norm.
    """
    from scipy.signal import lfilter

    # the innovation variance of the residuals' AR model
    innovation = np.concatenate([lfilter(ar, [1.0], residual[a:b]) for a, b in bounds])
    s2 = float(innovation @ innovation) / max(dof, 1)
    order = ar_order_limit(bounds)
    test = ResidualTest()
    projected = {}
    output_rms = float(np.sqrt(np.mean(np.concatenate(outputs) ** 2)))
    with np.errstate(all="ignore"):
        for name, (message, pieces) in directions.items():
            d = np.concatenate(pieces)
            size = float(d @ d)
            for F, (a, b) in zip(free, free_bounds or bounds):   # (fitted: projected out)
                if F.shape[1]:
                    d[a:b] -= F @ np.linalg.lstsq(F, d[a:b], rcond=None)[0]
            d -= J @ np.linalg.lstsq(J, d, rcond=None)[0]
            energy = float(d @ d)
            if not (np.isfinite(energy) and energy > SPANNED * size):
                continue   # a term the model has (its direction is fitted)
            coefficient = float(d @ residual) / energy
            a_d, s2_d = ar, s2
            if len(ar) > 1:
                # the residuals' correlation under the alternative (the term's part
                # removed): a large misfit of the null model is coloured, and an AR model
                # of it absorbs its own direction, hiding the term it lacks
                a_d, s2_d = _noise_model(residual - coefficient * d, bounds, order, dof)
            whitened = np.concatenate([lfilter([1.0], a_d, d[a:b][::-1])[::-1]
                                       for a, b in bounds])
            variance = s2_d * float(whitened @ whitened)
            score = float(d @ residual) ** 2 / variance if variance > 0 else 0.0
            if not np.isfinite(score):
                continue
            if abs(coefficient) * np.sqrt(energy / len(d)) < NEGLIGIBLE * output_rms:
                test.negligible.add(name)   # too small to matter (a noise-free record's
                # interpolation error is significant and negligible)
            test.scores[name] = score
            test.coefficients[name] = coefficient
            test.messages[name] = message
            projected[name] = d / np.sqrt(energy)
    if "delay" in test.coefficients:   # the shift, in samples: y(t) = yhat(t - tau)
        tau = test.coefficients["delay"]
        shift = "delayed" if tau > 0 else "advanced"
        test.messages["delay"] = (f"follow the model's output {shift} by about "
                                  f"{abs(tau) / step:.2g} samples: a delay between "
                                  f"the input and the output?")
    return test, projected


def _forcing(kind, seg, signal):
    """A candidate term's samples on a segment (:func:`system_residual_test`):
    ``signal`` is the input's samples (``gain``, ``derivative``) or the output's
    simulated ones (``cubic``, ``square``, ``coulomb``)."""
    if kind == "offset":
        return np.ones(len(seg))
    if kind == "drift":
        return seg.t - seg.t[0]
    z = np.asarray(signal, dtype=float)
    if kind == "derivative":
        return np.gradient(z, seg.t)
    if kind == "coulomb":
        return np.sign(np.gradient(z, seg.t))
    return {"gain": z, "cubic": z ** 3, "square": z ** 2}[kind]


def system_residual_test(residuals, theta, residual, J, ar, dof):
    """The scores of :class:`ResidualTest` for a refined fit of a linear system.

    Each candidate of :func:`candidate_terms` is a term added to one equation's known
    side (a constant, time, an input or its derivative; a power or the velocity's sign
    of an output of that equation, at its simulated value): its direction is the
    system's response to it, every measured output weighted as the residuals are.  The
    output's shift is one per measured output (``-yhat_j'`` on its own rows).  The
    warnings name the equation.

    Parameters
    ----------
    residuals : algid.identification._system_refinement.SimulationResiduals
        Last called at the refined estimate (its segments, weights, fitted initial
        states and free responses).
    theta : numpy.ndarray
        The refined parameters.
    residual : numpy.ndarray
        The weighted simulation residuals (segment by segment, output by output).
    J : numpy.ndarray
        Their Jacobian in the parameters (initial states projected out).
    ar : numpy.ndarray
        The residuals' autoregressive polynomial.
    dof : int
        Residual degrees of freedom.

    Returns
    -------
    ResidualTest
    """
    from algid.errors import AlgidError
    from algid.models._system import parse_system
    from algid.simulation._system import StateSpace, simulate_space, state_space

    system = residuals.system
    values = dict(zip(system.parameters, theta))
    observed = residuals.observed
    weights = np.array([1.0 / residuals.sigma[y] for y in observed])
    taken = set(system.signals) | set(system.parameters)
    names = [n for n in (f"z{k}" for k in range(len(taken) + len(system.equations)))
             if n not in taken][:len(system.equations)]
    extended = []
    for model, name in zip(system.equations, names):
        left, _, right = model.equation.partition("=")
        extended.append(f"{left}= {right} + {name}")
    try:
        space = state_space(parse_system(extended, system.parameters,
                                         outputs=system.outputs), values)
        base = state_space(system, values)
    except AlgidError:   # (a system the grammar or the simulator takes only as it is)
        return ResidualTest()
    rows = [space.outputs.index(y) for y in observed]
    fitted, free_bounds, outputs, at = [], [], [], 0
    for seg, x0 in zip(residuals.segments, residuals.states):
        inputs = {u: seg.values[u] for u in system.inputs}
        fitted.append(simulate_space(base, seg.t, inputs, x0))   # every output
        free_bounds.append((at, at + len(rows) * len(seg)))
        at += len(rows) * len(seg)
        outputs.append(np.ravel([seg.values[y] * w for y, w in zip(observed, weights)]))

    def stacked(responses):   # per segment, (outputs, samples) -> the residuals' rows
        return [np.ravel(r[rows] * weights[:, None]) for r in responses]

    directions = {}
    for i, (model, name) in enumerate(zip(system.equations, names)):
        channel = StateSpace(space.A, space.B[:, [space.channels.index(name)]], space.C,
                             space.states, [name], space.outputs)
        where = f"; in equation {i + 1}, {model.equation}"
        candidates = {key: message for key, (_, message)
                      in equation_candidates(system, model).items()}
        for key, message in candidates.items():
            kind, _, signal = key.partition(":")
            if signal in system.inputs:
                forcing = [_forcing(kind, seg, seg.values[signal])
                           for seg in residuals.segments]
            else:   # (an output's simulated samples, or none)
                forcing = [_forcing(kind, seg, sim[system.outputs.index(signal)]
                                    if signal else None)
                           for seg, sim in zip(residuals.segments, fitted)]
            with np.errstate(all="ignore"):
                responses = [simulate_space(channel, seg.t, {name: z})
                             for seg, z in zip(residuals.segments, forcing)]
            directions[f"{key} in equation {i + 1}"] = (message + where, stacked(responses))
    for j, y in enumerate(observed):
        pieces = []
        for seg, sim in zip(residuals.segments, fitted):
            shift = np.zeros((len(rows), len(seg)))
            shift[j] = -np.gradient(sim[system.outputs.index(y)], seg.t) * weights[j]
            pieces.append(shift.ravel())
        directions[f"delay of {y}"] = ("", pieces)
    step = float(np.median(np.diff(residuals.segments[0].t)))
    test, _ = score_directions(directions, outputs, residual, residuals.bases, J,
                               residuals.bounds(), ar, dof, step, free_bounds)
    _name_delays(test, observed, step)
    return test


def equation_candidates(system, model):
    """The candidate terms of one equation of a system: those of :func:`candidate_terms`
    in each of its outputs (a power or a velocity's sign per output; the others once),
    without the shift in time (one per output, for the whole system).

    Parameters
    ----------
    system : algid.models.SystemModel
    model : algid.models._model.Model
        One of its equations.

    Returns
    -------
    dict
        Candidate -> (its term, its message).
    """
    found = {}
    for y in (y for y in system.outputs if y in model.signals):
        for key, (term, message) in candidate_terms(y, system.inputs).items():
            if term is None:
                continue
            if key in ("cubic", "square", "coulomb"):
                key = f"{key}:{y}"
            found.setdefault(key, (term, message))
    return found


def _name_delays(test, outputs, step):
    """The messages of each output's shift, in samples: ``y(t) = yhat(t - tau)``."""
    for y in outputs:
        tau = test.coefficients.get(f"delay of {y}")
        if tau is not None:
            test.messages[f"delay of {y}"] = (
                f"follow {y} simulated {'delayed' if tau > 0 else 'advanced'} by about "
                f"{abs(tau) / step:.2g} samples: a delay between the inputs and {y}?")
