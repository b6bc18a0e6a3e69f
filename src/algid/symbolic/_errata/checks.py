"""The checks of the printed equations (1)-(25), (32), (33) and the footnote.

Each check is ``check(printed, filters) -> (correct, corrected, explanation)``: it
compares the printed form with a first-principles computation (Newton's law and the
model equations, SymPy's Laplace transform, differentiation in ``s``) or with the
derivation, and builds the corrected form and a one-line explanation where they differ.
The filters (26)-(31) are checked in :mod:`algid.symbolic._errata.filter_checks`.
"""

from __future__ import annotations

from functools import cache

import sympy as sp

from algid.symbolic._builtin_models import builtin_model
from algid.symbolic._derivation import IteratedIntegral, Kernel, evaluate_kernel
from algid.symbolic._errata.notation import PHI, LowPass
from algid.symbolic._errata.reference import (
    entry_labels,
    entry_values,
    is_constant,
    is_zero,
    reference_derivation,
    signal_atoms,
)
from algid.symbolic._model import LAPLACE, TIME
from algid.symbolic._printing import show
from algid.symbolic._realization import integrate_from_zero, same_integral_form

t, s = TIME, LAPLACE


# ------------------------------------------------------ checks: model relations


@cache
def _newton():
    """Reference forces from ``m x'' + c x' + k x = F`` (built-in model ``msd_mass``)."""
    model = builtin_model("msd_mass")
    m, c, k = model.parameters
    x = model.output_function
    R = model.ode().lhs - model.ode().rhs
    spring, damper = -k * sp.diff(R, k), -c * sp.diff(R, c)
    applied = -R.subs({m: 0, c: 0, k: 0})
    labels = {sp.Symbol("F_s"): spring, sp.Symbol("F_d"): damper,
              sp.Symbol("sum_F"): applied + spring + damper,
              sp.Symbol("v"): x.diff(t), sp.Symbol("a"): x.diff(t, 2)}
    accel = sp.solve(R, x.diff(t, 2))[0]
    return (model.ode().lhs, model.ode().rhs), labels, {x.diff(t, 2): accel}


def check_forces(printed, filters):
    model, labels, ode = _newton()
    notes, corrected = [], []
    for rel in printed:
        ref = sp.expand(rel[0].xreplace(labels).subs(ode))
        bad = [side for side in rel[1:]
               if not is_zero(side.xreplace(labels).subs(ode) - ref)]
        if bad:
            notes.append(f"{', '.join(map(show, bad))} must be {show(labels.get(rel[0], ref))}")
            corrected.append((rel[0], labels.get(rel[0], ref)))
        else:
            corrected.append(rel)
    if not notes:
        return True, None, ("consistent with Newton's law sum_F = F + F_s + F_d = m a for "
                            f"the model {show(model)}")
    return False, tuple(corrected), (f"contradicts Newton's law for {show(model)}: "
                                     + "; ".join(notes))


def equivalent_ratio(a, b, forbidden=()):
    """Nonzero constant ``r`` with ``a = r b`` (``None`` if there is none).

    The ratio is read off one term of ``b`` (a signal, or else an entry symbol) and
    must be free of ``s``, ``t``, the signals and ``forbidden``.
    """
    a, b = sp.expand(a), sp.expand(b)
    if b == 0:
        return None
    probes = sorted(signal_atoms(b), key=sp.default_sort_key) or \
        sorted(b.free_symbols - {s, t} - set(forbidden), key=sp.default_sort_key)
    for probe in probes:
        cb = b.coeff(probe)
        if cb == 0 or cb.has(probe):
            continue
        ratio = sp.simplify(a.coeff(probe) / cb)
        if ratio == 0 or not is_constant(ratio, tuple(forbidden) + tuple(probes)):
            return None
        return ratio if is_zero(a - ratio * b) else None
    return None


def check_against(reference, label, forbidden=()):
    """Check a one-relation equation against the model ``reference() = (lhs, rhs)``."""
    def check(printed, filters):
        ((lhs, rhs),) = printed
        ref_l, ref_r = reference()
        ratio = equivalent_ratio(lhs - rhs, ref_l - ref_r, forbidden)
        if ratio is not None:
            scale = "" if ratio == 1 else f" (times {show(ratio)})"
            return True, None, f"equivalent to {label}{scale}"
        # the model, scaled like the printed equation's highest derivative
        top = max((ref_l - ref_r).atoms(sp.Derivative), key=lambda d: d.derivative_count)
        scale = sp.simplify(sp.expand(lhs - rhs).coeff(top) / sp.expand(ref_l - ref_r).coeff(top))
        if scale == 0 or not is_constant(scale, forbidden):
            scale = 1
        corrected = ((sp.expand(scale * ref_l), sp.expand(scale * ref_r)),)
        return False, corrected, f"not equivalent to {label}; correct: {show(corrected[0])}"
    return check


def msd_mass_equation():
    ode = builtin_model("msd_mass").ode()
    return ode.lhs, ode.rhs


def msd_equation():
    ode = builtin_model("msd").ode()
    return ode.lhs, ode.rhs


@cache
def _transfer_function():
    d = reference_derivation()
    X, F = d.transforms
    zero_ics = d.laplace.subs({ic: 0 for ic in d.initial_conditions})
    return sp.simplify(sp.solve(zero_ics, X)[0] / F)


def check_transfer(printed, filters):
    ((*sides,),) = printed
    G = _transfer_function()
    X, F = reference_derivation().transforms
    subs = {sp.Symbol("G"): G, X: G * F}
    bad = [side for side in sides if not is_zero(sp.simplify(side.xreplace(subs) - G))]
    if not bad:
        return True, None, ("agrees with the Laplace transform of (6) with zero initial "
                            f"conditions: X(s)/F(s) = {show(G)}")
    return False, ((sides[0], X / F, G),), f"{', '.join(map(show, bad))}: X(s)/F(s) is {show(G)}"


@cache
def _normalised_parameters():
    """``B``, ``K`` in terms of ``m``, ``c``, ``k``: ``msd_mass`` divided by its leading
    coefficient, matched coefficient by coefficient with ``msd``."""
    full, norm = builtin_model("msd_mass"), builtin_model("msd")
    lead = full.output_coefficients[0]
    eqs = [sp.Eq(a, b / lead) for a, b in zip(norm.output_coefficients, full.output_coefficients)]
    return sp.solve(eqs, norm.parameters, dict=True)[0]


def check_mass_relation(printed, filters):
    ((lhs, rhs),) = printed
    sol = _normalised_parameters()
    if is_zero((lhs - rhs).xreplace(sol)):
        return True, None, ("follows from B = c/m, K = k/m (msd_mass divided by m is msd: "
                            f"{', '.join(f'{p} = {show(v)}' for p, v in sol.items())})")
    # the corrected relation: the reference relation that holds the printed left side
    corrected = (lhs, rhs.xreplace(sol))
    for p, v in sol.items():
        if lhs in v.free_symbols:
            corrected = (lhs, sp.solve(sp.Eq(p, v), lhs)[0])
    relations = ', '.join(f'{p} = {show(v)}' for p, v in sol.items())
    return False, (corrected,), f"contradicts {relations}"


# ---------------------------------------------------- checks: the Laplace domain


@cache
def _sympy_laplace():
    """The Laplace transform of (6) computed by SymPy, in the derivation's symbols."""
    d = reference_derivation()
    model = d.model
    X, F = d.transforms
    x, f = model.output_function, model.input_function
    x0, xd0 = d.initial_conditions
    ode = model.ode()
    L = sp.laplace_transform(ode.lhs - ode.rhs, t, s, noconds=True)
    return sp.expand(L.subs({sp.LaplaceTransform(x, t, s): X, sp.LaplaceTransform(f, t, s): F,
                             sp.Subs(x.diff(t), t, 0): xd0}).subs(x.subs(t, 0), x0))


def check_laplace(printed, filters):
    ((lhs, rhs),) = printed
    ref = _sympy_laplace()
    engine = is_zero(ref - reference_derivation().laplace)
    if equivalent_ratio(lhs - rhs, ref, reference_derivation().parameters) is not None:
        return True, None, ("agrees with SymPy's laplace_transform of (6) with symbolic x(0), "
                            f"x'(0){' and with the derivation' if engine else ''}")
    return False, _arrange(ref), f"the Laplace transform of (6) is {show(_arrange(ref)[0])}"


def _arrange(residual):
    """``residual = 0`` as ``parameter terms + output terms = input terms``."""
    d = reference_derivation()
    F = d.transforms[1]
    terms = sp.Add.make_args(sp.expand(residual))
    right = sum((-term for term in terms if term.has(F)), sp.Integer(0))
    return ((sp.expand(residual + right), right),)


def check_identity(printed, filters):
    """Every side equal after carrying out the differentiations."""
    ((*sides,),) = printed
    ref = sp.expand(sides[0].doit())
    bad = [side for side in sides[1:] if not is_zero(side.doit() - ref)]
    if not bad:
        return True, None, f"differentiating gives {show(ref)}"
    return False, ((sides[0], ref),), (f"differentiating gives {show(ref)}, not "
                                       f"{', '.join(map(show, bad))}")


# ------------------------------------------- the linear comparison, group by group


def _compare_linear(printed_rel, ref_groups, params, evaluate, label, forbidden=()):
    """Compare a printed linear equation with a reference, parameter by parameter.

    Parameters
    ----------
    printed_rel : tuple
        ``(lhs, rhs)`` as printed (may hold unevaluated derivatives).
    ref_groups : dict
        ``{parameter or 1: coefficient}`` of the reference residual, in the form to
        show in a corrected equation.
    params : tuple
    evaluate : callable
        Brings a coefficient to a canonical form (``doit`` and ``expand``).
    label : str
        What the reference is, for the explanation.

    Returns
    -------
    (correct, corrected, explanation)
    """
    lhs, rhs = printed_rel
    zero = {p: 0 for p in params}

    def groups_of(side):
        out = {p: sp.diff(side, p) for p in params}
        out[1] = side.subs(zero)
        return out

    gl, gr = groups_of(lhs), groups_of(rhs)
    printed = {g: evaluate(gl[g] - gr[g]) for g in gl}
    ref = {g: evaluate(ref_groups.get(g, 0)) for g in gl}
    total_p = sum((g * printed[g] for g in printed), sp.Integer(0))
    total_r = sum((g * ref[g] for g in ref), sp.Integer(0))
    ratio = equivalent_ratio(total_p, total_r, tuple(params) + tuple(forbidden))
    if ratio is not None:
        scale = "" if ratio == 1 else f" (times {show(ratio)})"
        return True, None, f"agrees with {label}{scale}"

    if any(printed[g].has(*params) for g in printed):
        corrected = ((sum((p * ref_groups[p] for p in params), sp.Integer(0)), -ref_groups[1]),)
        return False, corrected, (f"not linear in {', '.join(map(str, params))}; correct: "
                                  f"{show(corrected[0])} ({label})")

    def differing(sign):
        return [g for g in gl if not is_zero(printed[g] - sign * ref[g])]

    diff = differing(1)
    alt = differing(-1)
    new_l, new_r = lhs, rhs
    notes = []
    for g in diff:
        in_l, in_r = evaluate(gl[g]) != 0, evaluate(gr[g]) != 0
        # where the corrected group goes: where it was printed (parameters on the left
        # and the parameter-free terms on the right when it was printed nowhere or on both)
        on_left = in_l and not in_r if g == 1 else in_l or not in_r
        want = ref_groups.get(g, 0) if on_left else -ref_groups.get(g, 0)
        have = gl[g] if on_left else gr[g]
        if on_left:
            new_l, new_r = new_l - g * gl[g] + g * want, new_r - g * gr[g]
        else:
            new_l, new_r = new_l - g * gl[g], new_r - g * gr[g] + g * want
        name = f"the {g} term" if g != 1 else ("the right side" if not on_left
                                               else "the terms without a parameter")
        shown_have, shown_want = show(g * have), show(g * want)
        if is_zero(printed[g] + ref[g]):
            notes.append(f"sign of {name} flipped ({shown_have} must be {shown_want})")
        elif printed[g] == 0:
            notes.append(f"{name} {shown_want} is missing")
        else:
            detail = f"{name} is {shown_have}; it must be {shown_want}"
            sign = 1 if on_left else -1
            have_terms = sp.Add.make_args(sp.expand(sign * printed[g]))
            want_terms = sp.Add.make_args(sp.expand(sign * ref[g]))
            lost = [term for term in want_terms if term not in have_terms]
            extra = [term for term in have_terms if term not in want_terms]
            if g == 1 and lost:
                detail += f" (it lost {', '.join(map(show, lost))}"
                detail += f"; {', '.join(map(show, extra))} should not be there)" if extra else ")"
            notes.append(detail)
    corrected = ((new_l if new_l.has(sp.Derivative) else sp.expand(new_l),
                  new_r if new_r.has(sp.Derivative) else sp.expand(new_r)),)
    text = "; ".join(notes)
    if 0 < len(alt) < len(diff):
        names = ", ".join(f"the {g} term" if g != 1 else "the right side" for g in alt)
        text += f" (equivalently, negating both sides, only {names} has the wrong sign)"
    return False, corrected, f"{text}; correct: {show(corrected[0])} ({label})"


def check_differentiated(printed, filters):
    d = reference_derivation()
    params = d.parameters
    no_ics = d.laplace.subs({ic: 0 for ic in d.initial_conditions})
    n = d.n_derivatives
    ref_groups = {p: sp.Derivative(sp.diff(no_ics, p), (s, n)) for p in params}
    ref_groups[1] = sp.Derivative(no_ics.subs({p: 0 for p in params}), (s, n))
    # the reference is d^n/ds^n of (10): the same with the derivatives carried out
    assert is_zero(sum((g * v for g, v in ref_groups.items()), 0).doit()
                    - sp.diff(d.laplace, s, n))
    return _compare_linear(printed[0], ref_groups, params, lambda e: sp.expand(e.doit()),
                           f"d^{n}/ds^{n} of (10)")


def check_multiplied(printed, filters):
    d = reference_derivation()
    params = d.parameters
    res = sp.expand(d.multiplied)
    ref_groups = {p: sp.expand(sp.diff(res, p)) for p in params}
    ref_groups[1] = res.subs({p: 0 for p in params})
    return _compare_linear(printed[0], ref_groups, params, lambda e: sp.expand(e.doit()),
                           f"s^-{d.s_power} times d^{d.n_derivatives}/ds^{d.n_derivatives} of (10)")


# --------------------------------------------------- checks: the time domain


def _entry_symbols():
    d = reference_derivation()
    n, m = d.P.shape
    P = sp.Matrix(n, m, lambda i, j: sp.Symbol(f"p{i + 1}{j + 1}"))
    Q = sp.Matrix(n, 1, lambda i, j: sp.Symbol(f"q{i + 1}"))
    return P, Q


def _rows(printed):
    """The scalar relations of a printed equation (a matrix equation gives one per row)."""
    out = []
    for lhs, rhs in printed:
        lhs, rhs = lhs.doit(), rhs.doit()
        if isinstance(lhs, sp.MatrixBase):
            out += [(lhs[i], rhs[i]) for i in range(lhs.rows)]
        else:
            out.append((lhs, rhs))
    return out


def time_equation_check(rows):
    """(15) and (20): the equations ``P theta = Q`` in the entries ``p11, ..., q2``.

    The verdict evaluates the printed equation, with the entries of the derivation, on
    the exact trajectory (it must vanish identically in B and K); the explanation and
    the correction compare it with the derivation's row, parameter by parameter.
    """
    def check(printed, filters):
        d = reference_derivation()
        params = d.parameters
        P, Q = _entry_symbols()
        values = entry_values()
        results = []
        for (lhs, rhs), i in zip(_rows(printed), rows):
            holds = is_zero((lhs - rhs).xreplace(values))
            ref_groups = {p: P[i, j] for j, p in enumerate(params)}
            ref_groups[1] = -Q[i]
            ok, corr, text = _compare_linear((lhs, rhs), ref_groups, params, sp.expand,
                                             f"row {i + 1} of P theta = Q")
            if holds and not ok:
                text = f"holds on the trajectory but is not the derivation's row: {text}"
            elif ok and not holds:  # pragma: no cover - the two routes must agree
                text = f"agrees with the derivation's row {i + 1} but fails on the trajectory"
            results.append((ok and holds, corr, text))
        if all(ok for ok, _, _ in results):
            return True, None, ("holds identically on an exact trajectory with nonzero initial "
                                "conditions; " + "; ".join(text for _, _, text in results))
        corrected = tuple(c[0] if c else (lhs, rhs) for (_, c, _), (lhs, rhs)
                          in zip(results, _rows(printed)))
        text = "; ".join(text for ok, _, text in results if not ok)
        if not all(is_zero((lhs - rhs).xreplace(values)) for lhs, rhs in _rows(printed)):
            text = f"fails on an exact trajectory: {text}"
        return False, corrected, text
    return check


def check_matrix_form(printed, filters):
    d = reference_derivation()
    n = len(d.parameters)
    depends = all(e.has(t) for e in list(d.P) + list(d.Q))
    ((lhs, rhs),) = printed
    shapes = lhs.shape == (n, 1) and rhs.shape == (n, 1) and d.P.shape == (n, n)
    consistent = all(is_zero((d.P * sp.Matrix(d.parameters) - d.Q)[i] - d.time_equations[i])
                     for i in range(n))
    if depends and shapes and consistent:
        return True, None, (f"the derivation gives P ({n}x{n}) and Q ({n}x1) with entries that "
                            f"depend on t, and X = ({', '.join(map(str, d.parameters))})")
    return False, None, "does not match the shape of the derivation's P theta = Q"


def check_definitions(printed, filters):
    """(16)-(18), (21)-(23): entries of P and Q defined as kernel combinations."""
    labels = entry_labels()
    notes, corrected, ok = [], [], True
    for rel in printed:
        values = [side.xreplace(labels) for side in rel]
        bad = [i for i in range(1, len(rel)) if not same_integral_form(values[i], values[0])]
        if not bad:
            corrected.append(rel)
            continue
        ok = False
        head = rel[0]
        if head not in labels:
            notes.append(f"{show(head)} is not an entry of P or Q")
            corrected.append(rel)
            continue
        rest = [values[i] for i in bad]
        match = [sym for sym, expr in labels.items()
                 if sym != head and all(same_integral_form(r, expr) for r in rest)]
        if match:
            notes.append(f"labelled {head} but it defines {match[0]} "
                         f"(= {show(labels[match[0]])}); {head} = {show(labels[head])}")
            corrected.append((match[0],) + tuple(rel[i] for i in bad))
        else:
            printed_sides = ', '.join(show(rel[i]) for i in bad)
            notes.append(f"{head} is {show(labels[head])}, not {printed_sides}")
            corrected.append((head, labels[head]))
    if ok:
        return True, None, "the same kernels as the derivation's entries"
    return False, tuple(corrected), "; ".join(notes)


@cache
def _cramer_solution():
    """Parameter -> Cramer's solution in the entry names ``p11, ..., q2``."""
    d = reference_derivation()
    nums, den = d.cramer()
    Ps, Qs = d.entry_symbols()
    P, Q = _entry_symbols()
    names = {Ps[i, j]: P[i, j] for i in range(P.rows) for j in range(P.cols)}
    names.update({Qs[i]: Q[i] for i in range(Q.rows)})
    return {p: (num.xreplace(names) / den.xreplace(names)) for p, num in zip(d.parameters, nums)}


def _equals_on_trajectory(expr, parameter):
    """Whether ``expr`` (entries of P, Q, possibly filtered) equals ``parameter`` exactly."""
    num, den = sp.together(expr - parameter).as_numer_denom()
    return is_zero(num)


def check_cramer(printed, filters):
    ((param, rhs),) = printed
    sol = _cramer_solution()
    holds = _equals_on_trajectory(rhs.xreplace(entry_values()), param)
    agrees = is_zero(sp.together(rhs - sol[param]).as_numer_denom()[0])
    if holds and agrees:
        return True, None, ("Cramer's rule on P theta = Q; returns the parameter exactly on an "
                            "exact trajectory")
    other = [p for p, v in sol.items() if p != param
             and is_zero(sp.together(rhs - v).as_numer_denom()[0])]
    if other:
        return False, ((param, sol[param]),), (f"labelled {param} but it is the solution for "
                                               f"{other[0]}")
    return False, ((param, sol[param]),), f"Cramer's rule gives {param} = {show(sol[param])}"


def check_filtered(printed, filters, orders=(1, 2)):
    """(32), (33): filtering numerator and denominator alike leaves the quotient."""
    ((param, rhs),) = printed
    on_traj = rhs.xreplace(entry_values())
    failed = []
    for p in orders:
        def low_pass(arg, p=p):
            g = sp.expand(arg)
            for _ in range(p):
                g = integrate_from_zero(g)
            return g
        if not _equals_on_trajectory(on_traj.replace(LowPass, low_pass), param):
            failed.append(p)
    unfiltered = rhs.replace(LowPass, lambda a: a)
    agrees = is_zero(sp.together(unfiltered - _cramer_solution()[param]).as_numer_denom()[0])
    if not failed and agrees:
        return True, None, (f"with F(s) = 1/s^p (p = {', '.join(map(str, orders))}) applied to "
                            "numerator and denominator alike the quotient is still exactly "
                            f"{param} on an exact trajectory (read F(s)[.] as the time-domain "
                            "filter)")
    num, den = sp.fraction(_cramer_solution()[param])
    corrected = ((param, LowPass(num) / LowPass(den)),)
    why = []
    if failed:
        why.append(f"the quotient is not {param} on an exact trajectory for F(s) = 1/s^p, "
                   f"p = {', '.join(map(str, failed))}: the same filter must act on numerator "
                   "and denominator")
    if not agrees:
        why.append(f"the unfiltered quotient is not Cramer's {param}")
    return False, corrected, "; ".join(why)


# ------------------------------------------------------------ the footnote


def check_footnote(printed, filters):
    tests = [sp.Lambda(t, 1 + t**2 - t * sp.exp(-2 * t))]
    bad = []
    for rel in printed:
        for phi in tests:
            values = []
            for side in rel:
                if isinstance(side, IteratedIntegral):
                    values.append(evaluate_kernel(Kernel("phi", 0, int(side.args[1])),
                                                  {"phi": phi(t)}))
                else:
                    values.append(side.replace(PHI, phi).doit())
            if any(not is_zero(v - values[0]) for v in values[1:]):
                bad.append(rel)
                break
    if not bad:
        return True, None, ("the nested integrals equal the n-fold integral from 0 to t "
                            "(checked for n = 1, 2, 3 on a test function)")
    sigma = sp.Symbol("sigma")
    corrected = tuple((rel[0], sp.Integral((t - sigma)**(rel[0].args[1] - 1)
                                           / sp.factorial(rel[0].args[1] - 1) * PHI(sigma),
                                           (sigma, 0, t))) for rel in bad)
    return False, corrected, f"{'; '.join(map(show, bad))} is not the n-fold integral from 0 to t"
