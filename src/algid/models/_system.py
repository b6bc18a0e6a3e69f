"""A system of model equations sharing parameters: several measured outputs, one per
equation.

Each equation is read as a :class:`~algid.models.Model` of its own (its output, by
default, the signal of highest derivative order in it), keeping the parameters of the
system that appear in it; an equation may have no known term when another one fixes
the scale of the parameters it shares (``m2*x2'' + c2*x2' + k2*(x2 - x1) = 0`` beside
an equation in which ``k2`` and a known force appear).  The measured signals that are
no equation's output are the system's inputs.
"""

from __future__ import annotations

from dataclasses import dataclass

from algid.errors import ModelError
from algid.models._grammar import LIMITS, parse_equation
from algid.models._model import Model

__all__ = ["SystemModel", "parse_system", "is_system", "MAX_EQUATIONS"]

#: Equations a system may hold.
MAX_EQUATIONS = 8


@dataclass(frozen=True)
class SystemModel:
    """Model equations that share parameters, each with its own measured output.

    Attributes
    ----------
    name : str
        Label of the system.
    equations : tuple of Model
        One model per equation, each with the parameters of the system that appear in
        it.
    parameters : tuple of str
        The unknown parameters of the system, in the order given.

    Examples
    --------
    >>> from algid.models import parse_system
    >>> system = parse_system(["L*i' + R*i + K*w = u", "J*w' + b*w = K*i"],
    ...                       "L R K J b")
    >>> system.outputs, system.inputs, system.equations[1].parameters
    (('i', 'w'), ('u',), ('K', 'J', 'b'))
    """

    name: str
    equations: tuple
    parameters: tuple

    @property
    def outputs(self) -> tuple:
        """The output of each equation, in the order of the equations."""
        return tuple(model.output for model in self.equations)

    @property
    def signals(self) -> tuple:
        """Every measured signal, in order of first appearance."""
        return tuple(dict.fromkeys(s for model in self.equations for s in model.signals))

    @property
    def channels(self) -> tuple:
        """Every factor of the equations, in order of first appearance."""
        return tuple(dict.fromkeys(f for model in self.equations for f in model.channels))

    @property
    def needs_derivatives(self) -> tuple:
        """Every ``(signal, order)`` estimated numerically inside a factor, once."""
        return tuple(dict.fromkeys(pair for model in self.equations
                                   for pair in model.needs_derivatives))

    @property
    def inputs(self) -> tuple:
        """Measured signals that are no equation's output."""
        return tuple(s for s in self.signals if s not in self.outputs)

    @property
    def is_linear(self) -> bool:
        """True when every equation is linear in its signals."""
        return all(model.is_linear for model in self.equations)

    @property
    def equation(self) -> str:
        """The equations, separated by ``"; "``."""
        return "; ".join(model.equation for model in self.equations)

    def columns(self, index) -> list:
        """Positions, in :attr:`parameters`, of an equation's parameters.

        Parameters
        ----------
        index : int
            The equation's position in :attr:`equations`.

        Returns
        -------
        list of int
        """
        return [self.parameters.index(p) for p in self.equations[index].parameters]

    def __str__(self):
        return f"{self.name}: {self.equation}"


def is_system(equation) -> bool:
    """Whether an ``equation`` argument holds several equations (a list or tuple, or a
    :class:`SystemModel`)."""
    return isinstance(equation, (list, tuple, SystemModel))


def parse_system(equations, parameters, *, outputs=None, name="custom") -> SystemModel:
    """Read a system of model equations.

    Parameters
    ----------
    equations : sequence of str or Model
        The equations, e.g. ``["m1*x1'' + c1*x1' + k1*x1 + k2*(x1 - x2) = u",
        "m2*x2'' + c2*x2' + k2*(x2 - x1) = 0"]``.
    parameters : sequence of str or str
        The unknown parameters of the whole system.
    outputs : sequence of str, optional
        The output of each equation; by default each equation's signal of highest
        derivative order.  Every equation needs an output of its own.
    name : str
        Label of the system.

    Returns
    -------
    SystemModel

    Raises
    ------
    ModelError
        One line naming the problem: an equation that cannot be read, two equations
        with one output, a parameter in no equation, no known term in the system.

    Examples
    --------
    >>> from algid.models import parse_system
    >>> system = parse_system(["m1*x1'' + c1*x1' + k1*x1 + k2*(x1 - x2) = u",
    ...                        "m2*x2'' + c2*x2' + k2*(x2 - x1) = 0"],
    ...                       "m1 c1 k1 k2 m2 c2")
    >>> system.outputs, system.inputs, system.equations[1].parameters
    (('x1', 'x2'), ('u',), ('k2', 'm2', 'c2'))
    """
    if isinstance(equations, SystemModel):
        return equations
    if isinstance(equations, (str, bytes)) or not isinstance(equations, (list, tuple)):
        raise ModelError(f"a system is a list of equations, got "
                         f"{'one text' if isinstance(equations, str) else type(equations).__name__}"
                         f"{' (parse_equation reads one)' if isinstance(equations, str) else ''}")
    equations = list(equations)
    if not equations:
        raise ModelError("a system needs at least one equation, got an empty list")
    if len(equations) > MAX_EQUATIONS:
        raise ModelError(f"{len(equations)} equations (at most {MAX_EQUATIONS})")
    if outputs is not None:
        outputs = [outputs] if isinstance(outputs, str) else list(outputs)
        if len(outputs) != len(equations) or not all(isinstance(o, str) for o in outputs):
            raise ModelError(f"outputs must name one signal per equation ({len(equations)}), "
                             f"got {outputs!r:.80}")
    if parameters is None and all(isinstance(e, Model) for e in equations):
        parameters = tuple(dict.fromkeys(p for e in equations for p in e.parameters))
    if parameters is None:
        raise ModelError("parameters: name the unknown parameters of the system")
    names = parameters.replace(",", " ").split() if isinstance(parameters, str) else \
        parameters
    if isinstance(names, (list, tuple)) and len(names) > LIMITS["system_parameters"]:
        raise ModelError(f"a system of {len(names)} parameters (at most "
                         f"{LIMITS['system_parameters']}, and 12 in each equation)")
    models = []
    for i, equation in enumerate(equations):
        if isinstance(equation, Model):
            equation = equation.equation
        if not isinstance(equation, str):
            raise ModelError(f"equation {i + 1} of the system must be a text equation, got "
                             f"{type(equation).__name__}")
        try:
            models.append(parse_equation(equation, parameters, within_system=True,
                                         output=None if outputs is None else outputs[i],
                                         name=f"{name}_{i + 1}"))
        except ModelError as error:   # a system names its outputs in one list
            raise ModelError(str(error).replace("give output=", "give outputs=[...], one "
                                                "per equation")) from None
    parameters = _all_parameters(parameters, models)
    seen = {}
    for i, model in enumerate(models):
        if model.output in seen:
            raise ModelError(f"equations {seen[model.output] + 1} and {i + 1} both have the "
                             f"output {model.output}: name each equation's output (outputs= "
                             f"in Python, --output once per --equation on the command line)")
        seen[model.output] = i
    if not any(model.known_terms for model in models):
        raise ModelError("no known term in the system: every term has a parameter, so the "
                         "scale is not fixed (give one term a known coefficient)")
    _check_scales(models)
    return SystemModel(name=name, equations=tuple(models), parameters=parameters)


def _check_scales(models):
    """Refuse an equation without a known term whose scale no other equation fixes.

    Such an equation holds for its parameters times any factor; the factor is fixed
    only by a parameter it shares with an equation whose scale is fixed (by a known
    term, or so in turn).
    """
    fixed = {i for i, model in enumerate(models) if model.known_terms}
    grew = True
    while grew:
        anchored = {p for i in fixed for p in models[i].parameters}
        grew = False
        for i, model in enumerate(models):
            if i not in fixed and anchored & set(model.parameters):
                fixed.add(i)
                grew = True
    for i, model in enumerate(models):
        if i not in fixed:
            raise ModelError(f"equation {i + 1} ({model.equation}) has no known term and "
                             f"shares no parameter with an equation whose scale is fixed: "
                             f"only the ratios of {', '.join(model.parameters)} are "
                             f"determined (give one of them a known value)")


def _all_parameters(parameters, models):
    if isinstance(parameters, str):
        parameters = parameters.replace(",", " ").split()
    parameters = tuple(parameters)
    used = {p for model in models for p in model.parameters}
    for p in parameters:
        if p not in used:
            raise ModelError(f"parameter {p} appears in no equation of the system (or its "
                             f"terms cancel)")
    return parameters
