"""The derivation of a system of equations that share parameters.

Each equation of a :class:`~algid.models.SystemModel` is derived on its own, as one
equation is (:func:`~algid.symbolic.derive` on its
:class:`~algid.symbolic._channels.ChannelModel`: the other signals of the system are
measured signals there).  The system's linear system stacks every equation's ``P``
and ``Q``, each equation's columns placed in the columns of its parameters among the
system's: ``sum_e n_e`` rows (``n_e`` the parameters of equation ``e``) in the ``p``
unknowns of the system.  An equation without a known term (``Q = 0``) fixes only the
ratios of its parameters; a parameter it shares with another equation fixes its scale,
which is why the rows are solved together.
"""

from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from algid.models._system import SystemModel

__all__ = ["SystemDerivation", "stack_system"]


@dataclass(frozen=True)
class SystemDerivation:
    """The derivation of every equation of a system and their stacked linear system.

    Attributes
    ----------
    system : algid.models.SystemModel
    equations : tuple of algid.symbolic.Derivation
        One per equation that has parameters, in the system's order.
    skipped : tuple of str
        Equations without parameters (nothing to estimate from them), as written.
    parameters : tuple of sympy.Symbol
        The system's unknowns, in its order.
    P, Q : sympy.Matrix
        The stacked linear system ``P theta = Q``: the rows of ``equations[0]``, then
        those of ``equations[1]``, ..., in the columns of :attr:`parameters`.
    rows : tuple of (int, int)
        For each row of ``P``: the equation (index in :attr:`equations`) and its row
        there.
    numbers : tuple of int
        For each of :attr:`equations`, its number in the system (from 1).

    Examples
    --------
    >>> from algid.models import parse_system
    >>> from algid.symbolic import derive
    >>> d = derive(parse_system(["L*i' + R*i + K*w = u", "J*w' + b*w = K*i"],
    ...                         "L R K J b"))
    >>> d.P.shape, [e.P.shape for e in d.equations], list(d.Q[3:, 0])
    ((6, 5), [(3, 3), (3, 3)], [0, 0, 0])
    """

    system: SystemModel
    equations: tuple
    skipped: tuple
    parameters: tuple
    P: sp.Matrix
    Q: sp.Matrix
    rows: tuple
    numbers: tuple

    @property
    def kernels(self) -> tuple:
        """Every filtered signal in ``P`` and ``Q``, sorted (those of all equations)."""
        return tuple(sorted({k for d in self.equations for k in d.kernels}))

    @property
    def square(self) -> bool:
        """Whether the stacked system has as many rows as unknowns."""
        return self.P.shape[0] == self.P.shape[1]


def stack_system(system, derivations) -> SystemDerivation:
    """Stack the derivations of a system's equations (:func:`~algid.symbolic.derive`
    on a :class:`~algid.models.SystemModel` calls this).

    Parameters
    ----------
    system : algid.models.SystemModel
    derivations : list of algid.symbolic.Derivation or None
        Per equation of the system, its derivation; None for an equation without
        parameters.

    Returns
    -------
    SystemDerivation
    """
    parameters = tuple(sp.Symbol(p) for p in system.parameters)
    kept, skipped, blocks, rows, numbers = [], [], [], [], []
    for number, (model, d) in enumerate(zip(system.equations, derivations), 1):
        if d is None:
            skipped.append(model.equation)
            continue
        columns = [system.parameters.index(p) for p in model.parameters]
        block = sp.zeros(d.P.shape[0], len(parameters))
        for j, column in enumerate(columns):
            block[:, column] = d.P[:, j]
        rows += [(len(kept), i) for i in range(d.P.shape[0])]
        blocks.append((block, d.Q))
        kept.append(d)
        numbers.append(number)
    return SystemDerivation(system=system, equations=tuple(kept), skipped=tuple(skipped),
                            parameters=parameters,
                            P=sp.Matrix.vstack(*(b for b, _ in blocks)),
                            Q=sp.Matrix.vstack(*(q for _, q in blocks)), rows=tuple(rows),
                            numbers=tuple(numbers))
