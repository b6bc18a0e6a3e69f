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

import random
from dataclasses import dataclass

import sympy as sp

from algid.models._system import SystemModel
from algid.symbolic._linear_system import (
    cramer_program,
    entry_symbols,
    kernel_chains,
    kernel_symbols,
    normal_equations,
)

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

    def inseparable(self) -> tuple:
        """The parameters that no data can separate, or ``()``.

        Those of a combination that the stacked ``P`` maps to zero whatever the signals
        (terms proportional in every equation, ``a*y + b*y``).  ``P`` is evaluated with
        every kernel an independent random integer (a fixed seed), exactly: a
        combination it cannot separate there is one it cannot separate for any signals.

        Returns
        -------
        tuple of str
            The parameters with a weight in the combination, in the system's order.
        """
        rng = random.Random(0)
        values = {symbol: sp.Integer(rng.randint(1, 10**6))
                  for symbol in self.kernel_symbols().values()}
        null = self.P.xreplace(self.kernel_symbols()).xreplace(values).nullspace()
        if not null:
            return ()
        return tuple(str(p) for p, weight in zip(self.parameters, null[0]) if weight != 0)

    def chains(self) -> tuple:
        """The integrator chains that realise the kernels of every equation, sorted.

        Returns
        -------
        tuple of (str, int, int)
            As :meth:`algid.symbolic.Derivation.chains`.
        """
        return kernel_chains(self.kernels)

    def kernel_symbols(self) -> dict:
        """Each kernel's expression mapped to a plain symbol named after the kernel.

        Returns
        -------
        dict
        """
        return kernel_symbols(self.kernels)

    def entry_symbols(self):
        """Symbols ``p_i_j`` and ``q_i`` for the entries of the stacked ``P`` and ``Q``.

        0 for an entry that is zero whatever the data (a parameter absent from a row's
        equation, the known side of an equation without a known term).

        Returns
        -------
        P, Q : sympy.Matrix
        """
        Ps, Qs = entry_symbols(self.P.shape)
        for i in range(Ps.shape[0]):
            for j in range(Ps.shape[1]):
                if self.P[i, j] == 0:
                    Ps[i, j] = 0
            if self.Q[i] == 0:
                Qs[i] = 0
        return Ps, Qs

    def cramer_program(self):
        """The solution of the stacked system as a straight-line program.

        A square stacked system is solved by Cramer's rule
        (:func:`algid.symbolic._linear_system.cramer_program`); one of more rows than
        unknowns by Cramer's rule on its normal equations ``P^T P theta = P^T Q``, whose
        entries are the first steps (:func:`algid.symbolic._linear_system.normal_equations`).
        Either way every row holds at the true parameters on exact data, and so does
        the solution.

        Returns
        -------
        steps : tuple of (sympy.Symbol, sympy.Expr)
        numerators : tuple of sympy.Expr
        denominator : sympy.Expr
            ``det P``, or ``det(P^T P)``.
        """
        Ps, Qs = self.entry_symbols()
        if self.square:
            return cramer_program(Ps, Qs)
        normal, N, b = normal_equations(Ps, Qs)
        steps, numerators, denominator = cramer_program(N, b)
        return normal + steps, numerators, denominator


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
