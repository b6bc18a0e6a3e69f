"""The linear system ``P theta = Q`` of a derivation, as the generated estimators compute it.

The integrator chains that realise its kernels, the symbols of its entries, and
Cramer's rule on them, shared by one equation's derivation
(:class:`~algid.symbolic.Derivation`) and a system's
(:class:`~algid.symbolic.SystemDerivation`).  A square system of symbols ``p_i_j``,
``q_i``: for at most :data:`EXPANDED_CRAMER_MAX` unknowns its numerators and
denominator are expanded polynomials of the entries; beyond, a straight-line program
computes them from the minors of ``[P | Q]`` on its first rows, each minor once.  A
system of more rows than unknowns (the stacked equations of a system,
:mod:`algid.symbolic._system_derivation`) is solved through its normal equations
``P^T P theta = P^T Q``: their entries are steps of the program, and Cramer's rule
solves them.  Exact data satisfy every row at the true parameters, so the normal
equations give them too.
"""

from __future__ import annotations

import itertools

import sympy as sp

__all__ = ["EXPANDED_CRAMER_MAX", "kernel_chains", "kernel_symbols", "entry_symbols",
           "expanded_cramer", "cramer_program", "normal_equations"]

#: Largest number of unknowns whose Cramer numerators and denominator are expanded
#: (``n!`` products each); larger systems are solved through shared minors.
EXPANDED_CRAMER_MAX = 5


def kernel_chains(kernels) -> tuple:
    """The integrator chains that realise kernels, sorted.

    Parameters
    ----------
    kernels : iterable of Kernel
        The filtered signals (:class:`~algid.symbolic.Kernel`).

    Returns
    -------
    tuple of (str, int, int)
        ``(channel, power, depth)``: level ``l`` of a chain is the ``l``-fold integral
        of ``t**power`` times the channel; ``depth`` is the deepest level a kernel needs.
    """
    depth = {}
    for k in kernels:
        key = (k.signal, k.power)
        depth[key] = max(depth.get(key, 0), k.order)
    return tuple((sig, power, d) for (sig, power), d in sorted(depth.items()))


def kernel_symbols(kernels) -> dict:
    """Each kernel's expression mapped to a plain symbol named after the kernel.

    Parameters
    ----------
    kernels : iterable of Kernel

    Returns
    -------
    dict
        :class:`~algid.symbolic.IteratedIntegral` -> :class:`sympy.Symbol` (``x_t2_i1``,
        ...).
    """
    return {k.expression(): sp.Symbol(k.name) for k in kernels}


def entry_symbols(shape):
    """Symbols ``p_i_j`` and ``q_i`` standing for the entries of ``P`` and ``Q``.

    Parameters
    ----------
    shape : tuple of int
        The shape of ``P``.

    Returns
    -------
    P, Q : sympy.Matrix
        Matrices of symbols of the shapes of ``P`` and ``Q``.
    """
    n, m = shape
    Ps = sp.Matrix(n, m, lambda i, j: sp.Symbol(f"p_{i}_{j}"))
    Qs = sp.Matrix(n, 1, lambda i, j: sp.Symbol(f"q_{i}"))
    return Ps, Qs


def expanded_cramer(Ps, Qs):
    """Cramer's numerators and denominator of a square system, expanded.

    Parameters
    ----------
    Ps : sympy.Matrix
        ``n`` by ``n`` entries.
    Qs : sympy.Matrix
        ``n`` by 1 known side.

    Returns
    -------
    numerators : tuple of sympy.Expr
        One per unknown (``det P`` with its column replaced by ``Q``).
    denominator : sympy.Expr
        ``det P``.
    """
    den = sp.expand(Ps.det(method="berkowitz"))
    nums = []
    for j in range(Ps.shape[1]):
        Pj = Ps.copy()
        Pj[:, j] = Qs
        nums.append(sp.expand(Pj.det(method="berkowitz")))
    return tuple(nums), den


def cramer_program(Ps, Qs):
    """Cramer's rule on a square system as a straight-line program.

    Up to :data:`EXPANDED_CRAMER_MAX` unknowns there are no steps and the result is
    :func:`expanded_cramer`.  Beyond, the minors of ``[P | Q]`` on its first ``k`` rows
    are computed level by level, each by expansion along its last row from the minors
    of the level before (``m<k>_<columns as bits>``); the denominator and the
    numerators are the minors of all ``n`` rows.

    Parameters
    ----------
    Ps : sympy.Matrix
        ``n`` by ``n`` entries.
    Qs : sympy.Matrix
        ``n`` by 1 known side.

    Returns
    -------
    steps : tuple of (sympy.Symbol, sympy.Expr)
        Assignments, in order.
    numerators : tuple of sympy.Expr
        One per unknown, in the entries and the symbols of ``steps``.
    denominator : sympy.Expr
        ``det P``.

    Raises
    ------
    ValueError
        ``Ps`` is not square.
    """
    n = Ps.shape[1]
    if Ps.shape[0] != n:
        raise ValueError("Cramer's rule needs as many equations as unknowns")
    if n <= EXPANDED_CRAMER_MAX:
        return ((), *expanded_cramer(Ps, Qs))

    def entry(row, column):
        return Ps[row, column] if column < n else Qs[row]

    minors = {1 << c: entry(0, c) for c in range(n + 1)}
    steps = []
    for k in range(2, n + 1):
        level = {}
        for columns in itertools.combinations(range(n + 1), k):
            bits = sum(1 << c for c in columns)
            value = sp.Add(*(
                (-1) ** (k - 1 + i) * entry(k - 1, c) * minors[bits & ~(1 << c)]
                for i, c in enumerate(columns)))
            symbol = sp.Symbol(f"m{k}_{bits}")
            steps.append((symbol, value))
            level[bits] = symbol
        minors = level
    every = (1 << (n + 1)) - 1
    den = minors[every & ~(1 << n)]
    # column j of P replaced by Q: Q moved from the last place to place j
    nums = tuple((-1) ** (n - 1 - j) * minors[every & ~(1 << j)] for j in range(n))
    return tuple(steps), nums, den


def normal_equations(Ps, Qs):
    """The normal equations ``P^T P theta = P^T Q`` of a system of more rows than
    unknowns, their entries as steps of a program.

    Parameters
    ----------
    Ps : sympy.Matrix
        ``r`` by ``n`` entries (an entry known to be zero given as 0: its products are
        left out).
    Qs : sympy.Matrix
        ``r`` by 1 known side.

    Returns
    -------
    steps : tuple of (sympy.Symbol, sympy.Expr)
        ``n_i_j`` (``i <= j``) and ``b_i``, the entries of ``P^T P`` and ``P^T Q``, in
        order; an entry that is identically zero has no step.
    N : sympy.Matrix
        ``n`` by ``n``, symmetric: the symbols ``n_i_j`` (``n_j_i`` below the
        diagonal), or 0.
    b : sympy.Matrix
        ``n`` by 1: the symbols ``b_i``, or 0.

    Examples
    --------
    >>> import sympy as sp
    >>> from algid.symbolic._linear_system import normal_equations
    >>> steps, N, b = normal_equations(sp.Matrix([[sp.Symbol("p_0_0")], [2]]),
    ...                                sp.Matrix([sp.Symbol("q_0"), 0]))
    >>> steps, N, b
    (((n_0_0, p_0_0**2 + 4), (b_0, p_0_0*q_0)), Matrix([[n_0_0]]), Matrix([[b_0]]))
    """
    rows, n = Ps.shape
    steps = []
    N = sp.zeros(n, n)
    for i in range(n):
        for j in range(i, n):
            value = sp.Add(*(Ps[k, i] * Ps[k, j] for k in range(rows)))
            if value != 0:
                symbol = sp.Symbol(f"n_{i}_{j}")
                steps.append((symbol, value))
                N[i, j] = N[j, i] = symbol
    b = sp.zeros(n, 1)
    for i in range(n):
        value = sp.Add(*(Ps[k, i] * Qs[k] for k in range(rows)))
        if value != 0:
            symbol = sp.Symbol(f"b_{i}")
            steps.append((symbol, value))
            b[i] = symbol
    return tuple(steps), N, b
