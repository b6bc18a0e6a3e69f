# ---
# jupyter:
#   jupytext:
#     formats: py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # 1. The algebraic derivation, step by step
#
# This notebook derives the algebraic estimator of Fliess and Sira-Ramírez for the
# mass-spring-damper of Becedas et al. (WCECS 2007),
#
# $$\ddot x + B\,\dot x + K\,x = f, \qquad B = c/m,\quad K = k/m,\quad f = F/m,$$
#
# with SymPy, one step at a time.  We measure the input $f$ and the position $x$; we
# do **not** know $B$, $K$, nor the initial position and velocity.  The goal is a pair
# of formulas $B(t)$, $K(t)$ made only of integrals of the measured signals, that are
# exact at every instant $t > 0$.
#
# The recipe has five moves:
#
# 1. Laplace-transform the model, keeping the unknown initial conditions as symbols.
# 2. Differentiate with respect to $s$ until the initial conditions disappear.
# 3. Multiply by a negative power of $s$, so that only integrations remain.
# 4. Go back to the time domain with a small operator table (no inverse Laplace
#    transform is ever computed).
# 5. Integrate once more to get as many equations as unknowns, and solve the linear
#    system $P(t)\,\theta = Q(t)$.
#
# Each move is done twice below: once by hand with SymPy, to see what happens, and
# once by the derivation engine `algid.symbolic.derive`, which we then check against
# our hand computation.  At the end we verify the result on an exact solution of the
# ODE with nonzero initial conditions, and derive the estimator of a model of our own.

# %%
import os

# ALGID_NOTEBOOK_QUICK=1 selects a small workload (fewer realisations, shorter records).
QUICK = os.environ.get("ALGID_NOTEBOOK_QUICK", "") not in ("", "0")

import matplotlib.pyplot as plt
import numpy as np
import sympy as sp
from IPython.display import Markdown, display

from algid.signals._quadrature import iterated_integrals, startup_samples
from algid.symbolic import LAPLACE as s
from algid.symbolic import TIME as t
from algid.symbolic import Kernel, LinearODEModel, builtin_model, derivation_report, derive
from algid.symbolic._realization import from_kernel_terms, kernel_terms

sp.init_printing()

# %% tags=["remove-cell"]
# The numbers that tests/test_notebooks.py checks: collected in cells tagged
# "remove-cell", which the documentation does not render.
RESULTS = {"identities": {}}

# %% [markdown]
# ## 1.1 The model
#
# The built-in model `"msd"` is the normalised mass-spring-damper.  Its unknowns are
# the parameters $B$ and $K$; the input is called `f` and the output `x`.

# %%
model = builtin_model("msd")
B, K = model.parameters
x, f = model.output_function, model.input_function
display(model.ode())
print("unknown parameters:", model.parameters, "  order:", model.order)

# %% [markdown]
# ## 1.2 Laplace transform, initial conditions kept
#
# The transform of a derivative brings in the initial values:
#
# $$\mathcal L[\dot x] = s X(s) - x(0), \qquad
#   \mathcal L[\ddot x] = s^2 X(s) - s\,x(0) - \dot x(0).$$
#
# We do **not** know $x(0)$ and $\dot x(0)$, so we keep them as symbols `x0`, `x_d0`.
# Written by hand, the model becomes (everything moved to the left, equal to zero):

# %%
X, F = sp.Function("X")(s), sp.Function("F")(s)
x0, xd0 = sp.symbols("x0 x_d0")

laplace_by_hand = (s**2 * X - s * x0 - xd0) + B * (s * X - x0) + K * X - F
display(sp.Eq(laplace_by_hand, 0))

# %% [markdown]
# SymPy's own `laplace_transform` agrees (it writes $\mathcal L[x]$ for $X$ and keeps
# $x(0)$, $\dot x(0)$ as unevaluated values at 0; we rename them):

# %%
ode = model.ode()
sympy_transform = sp.laplace_transform(ode.lhs - ode.rhs, t, s, noconds=True)
renamed = sympy_transform.subs({
    sp.LaplaceTransform(x, t, s): X,
    sp.LaplaceTransform(f, t, s): F,
    sp.Subs(sp.Derivative(x, t), t, 0): xd0,
    x.subs(t, 0): x0,
})
display(sp.Eq(renamed, 0))
print("SymPy's transform minus the hand computation:", sp.expand(renamed - laplace_by_hand))

# %% tags=["remove-cell"]
RESULTS["identities"]["sympy_laplace_equals_hand"] = sp.expand(renamed - laplace_by_hand) == 0

# %% [markdown]
# The engine does the same.  `derive(model)` returns every step of the derivation as a
# field of a `Derivation` object; the first one is this transformed equation.

# %%
d = derive(model)
print("initial conditions:", d.initial_conditions)
display(sp.Eq(d.laplace, 0))
print("the engine's transform minus the hand computation:",
      sp.expand(d.laplace - laplace_by_hand))

# %% tags=["remove-cell"]
RESULTS["identities"]["engine_laplace_equals_hand"] = sp.expand(d.laplace - laplace_by_hand) == 0

# %% [markdown]
# Look at where the initial conditions sit: collect the terms that contain them.

# %%
ic_part = sp.expand(d.laplace - d.laplace.subs({x0: 0, xd0: 0}))
display(sp.collect(ic_part, [x0, xd0]))
print("degree in s of the initial-condition part:", sp.degree(ic_part, s))

# %% [markdown]
# They form a **polynomial of degree 1 in $s$**: $-(s + B)\,x(0) - \dot x(0)$.  Any
# polynomial of degree $n-1$ is annihilated by $n$ derivatives, so differentiating
# twice with respect to $s$ removes the initial conditions, *whatever their values*.
# This is why the estimator will never need them.

# %% [markdown]
# ## 1.3 Differentiate with respect to $s$: the initial conditions disappear
#
# The engine keeps each derivative in `d.differentiated` (index 0 is the transformed
# equation itself).  After each step we list the initial conditions that are still
# there.

# %%
ics = set(d.initial_conditions)
ics_left = []
for i, expr in enumerate(d.differentiated):
    left = sorted(expr.free_symbols & ics, key=str)
    ics_left.append([str(c) for c in left])
    label = "transformed equation" if i == 0 else f"after d/ds applied {i} time(s)"
    print(f"{label}: initial conditions present = {left or 'none'}")
    display(sp.Eq(expr, 0))

# %% tags=["remove-cell"]
RESULTS["ics_left_after_each_derivative"] = ics_left

# %% [markdown]
# The first derivative removes $\dot x(0)$ (it was multiplied by $s^0$), the second
# removes $x(0)$.  Products such as $s^2 X(s)$ turn into sums by the product rule; for
# instance the paper's identities (12) and (13),
#
# $$\frac{d^2}{ds^2}\big[s^2 X\big] = 2X + 4s\,X' + s^2 X'', \qquad
#   \frac{d^2}{ds^2}\big[s X\big] = 2X' + s\,X'',$$
#
# are one line each in SymPy:

# %%
identity_12 = sp.expand(sp.diff(s**2 * X, s, 2) - (2 * X + 4 * s * X.diff(s) + s**2 * X.diff(s, 2)))
identity_13 = sp.expand(sp.diff(s * X, s, 2) - (2 * X.diff(s) + s * X.diff(s, 2)))
print("left side minus right side of (12):", identity_12, "  of (13):", identity_13)

# %% tags=["remove-cell"]
RESULTS["identities"]["paper_12"] = identity_12 == 0
RESULTS["identities"]["paper_13"] = identity_13 == 0

# %% [markdown]
# ## 1.4 Multiply by $s^{-2}$: only integrations remain
#
# A positive power of $s$ is a time derivative, which we must avoid on measured
# (noisy) signals.  The highest power of $s$ left is $s^2$ (in $s^2 X''$), so we
# multiply the whole equation by $s^{-2}$.  Afterwards every power of $s$ is $\le 0$:
# a multiplication by $s^{-k}$ is a $k$-fold integration.

# %%
print("multiply by s^-%d" % d.s_power)
display(sp.Eq(d.multiplied, 0))
def power_of_s(term):
    """The power of s multiplying a term c * s**k * (X, F or a derivative of them)."""
    plain = [a for a in sp.Mul.make_args(term) if not (a.has(X) or a.has(F))]
    return int(sp.Mul(*plain).as_coeff_exponent(s)[1])


powers = sorted({power_of_s(term) for term in sp.Add.make_args(d.multiplied)})
print("powers of s present:", powers)

# %% tags=["remove-cell"]
RESULTS["identities"]["no_positive_power_of_s"] = max(powers) <= 0

# %% [markdown]
# ## 1.5 Back to the time domain with the operator table
#
# Two rules suffice, and no inverse Laplace transform is needed:
#
# | Laplace domain | time domain |
# | --- | --- |
# | $\dfrac{d^b}{ds^b} X(s)$ | $(-t)^b\, x(t)$ |
# | $s^{-k}\,G(s)$ | $\displaystyle\int^{(k)} g = \int_0^t\!\int_0^{\sigma_1}\!\!\cdots\!\int_0^{\sigma_{k-1}} g(\sigma_k)\,d\sigma_k\cdots d\sigma_1$ |
#
# We apply them term by term to the equation of 1.4.  `IteratedIntegral(g, k)` is the
# engine's unevaluated symbol for $\int^{(k)} g$ (printed `int^k(g)`).

# %%
def to_time_domain(term):
    """One term c * s**-k * d^b/ds^b G(s) of the Laplace-domain equation, in time."""
    factors = sp.Mul.make_args(term)
    transform = next(a for a in factors if a.has(X) or a.has(F))
    coeff, power = sp.Mul(*[a for a in factors if a is not transform]).as_coeff_exponent(s)
    if isinstance(transform, sp.Derivative):
        base, b = transform.expr, transform.derivative_count
    else:
        base, b = transform, 0
    k = -int(power)
    return coeff * (Kernel(base.func.__name__.lower(), b, k).expression() * (-1) ** b), \
        transform, k, b


rows = ["| term | $k$ | $b$ | time domain |", "| --- | --- | --- | --- |"]
first_equation = 0
for term in sp.Add.make_args(d.multiplied):
    in_time, transform, k, b = to_time_domain(term)
    first_equation += in_time
    rows.append(f"| ${sp.latex(term)}$ | {k} | {b} | ${sp.latex(in_time)}$ |")
display(Markdown("\n".join(rows)))

print("the hand translation minus the engine's first time-domain equation:",
      sp.expand(first_equation - d.time_equations[0]))
display(sp.Eq(d.time_equations[0], 0))

# %% tags=["remove-cell"]
RESULTS["identities"]["hand_time_domain_equals_engine"] = (
    sp.expand(first_equation - d.time_equations[0]) == 0)

# %% [markdown]
# (`Kernel(signal, b, k)` names the filtered signal $\int^{(k)}(t^b\,\mathrm{signal})$;
# the sign $(-1)^b$ comes from $(-t)^b$.)  This is one linear equation in the two
# unknowns $B$ and $K$, with coefficients that are integrals of $t^b x$ and $t^b f$:
# causal, computable on-line from the measurements, and free of derivatives.
#
# ## 1.6 A second equation
#
# Two unknowns need two equations.  Integrating the first equation once more (that is,
# multiplying it by $s^{-1}$) gives a second, independent one: every kernel order goes
# up by one.

# %%
def integrate_once(expr):
    """Integrate a time-domain equation once: every kernel order goes up by one."""
    return from_kernel_terms({(sig, power, order + 1): coeff
                              for (sig, power, order), coeff in kernel_terms(expr).items()})


print("the first equation integrated once, minus the engine's second equation:",
      sp.expand(integrate_once(d.time_equations[0]) - d.time_equations[1]))
display(sp.Eq(d.time_equations[1], 0))

# %% tags=["remove-cell"]
RESULTS["identities"]["second_equation_is_first_integrated"] = (
    sp.expand(integrate_once(d.time_equations[0]) - d.time_equations[1]) == 0)

# %% [markdown]
# ## 1.7 The linear system $P(t)\,\theta = Q(t)$
#
# Both equations are linear in $\theta = (B, K)^T$.  Collecting the coefficients gives
# a $2\times 2$ matrix $P(t)$ and a vector $Q(t)$ whose entries are combinations of
# iterated integrals of the measured signals:

# %%
p_sym, q_sym = d.entry_symbols()
display(sp.Eq(sp.MatMul(p_sym, sp.Matrix(model.parameters)), q_sym))
for i in range(2):
    for j in range(2):
        display(sp.Eq(p_sym[i, j], d.P[i, j]))
for i in range(2):
    display(sp.Eq(q_sym[i], d.Q[i]))

# %% [markdown]
# The engine numbers rows and columns from 0: its $p_{00}, p_{01}, q_0$ are the paper's
# $p_{11}, p_{12}, q_1$ (equations 16-18), and its second row is the paper's
# $p_{21} = \int p_{11}$, $p_{22} = \int p_{12}$, $q_2 = \int q_1$ (21-23).  The toolkit
# also checks every printed equation of the paper against this derivation
# (`algid.symbolic._errata`); here are the verdicts for the equations of this section:

# %%
from algid.symbolic._errata import PRINTED, check_equation

rows = ["| eq. | as printed | verdict |", "| --- | --- | --- |"]
verdicts = {}
for entry in PRINTED:
    if entry.number in ("14", "15", "16", "17", "18", "24", "25"):
        v = check_equation(entry)
        verdicts[v.number] = v.correct
        verdict = "correct" if v.correct else f"differs; consistent form: `{v.corrected}`"
        rows.append(f"| ({v.number}) | `{v.printed}` | {verdict} |")
display(Markdown("\n".join(rows)))

# %% tags=["remove-cell"]
RESULTS["printed_equation_verdicts"] = verdicts

# %% [markdown]
# ## 1.8 Cramer's rule
#
# The system is solved at every instant with Cramer's rule.  On the symbolic entries
# $p_{ij}$, $q_i$ (the engine numbers them from 0):

# %%
numerators, denominator = d.cramer()
for name, num in zip(model.parameters, numerators):
    display(sp.Eq(name, num / denominator))

# %% [markdown]
# and, written out in the kernels, the complete estimator:

# %%
solution = d.solution()
for eq in solution:
    display(eq)

# %% [markdown]
# The estimate is defined wherever $\det P(t) \ne 0$ and is exact there: nothing is
# asymptotic.  For an excited system $\det P(t)$ is nonzero for small $t > 0$; it may
# cross zero at isolated instants later (section 1.9 shows an example), where the
# quotient has to be read as a limit.
# Against measurement noise, the numerators and the denominator may both be passed
# through the same low-pass filter (for instance $1/s^p$, $p$ more integrations) without
# changing the quotient; notebook 3 studies that filter.
#
# ## 1.9 Verification on an exact trajectory
#
# We now check the result on a closed-form solution of the paper's system ($B=2$,
# $K=3$) driven by a unit step, started from **nonzero** initial conditions that the
# estimator never sees: $x(0) = 1/2$, $\dot x(0) = -1$.

# %%
B_true, K_true = sp.Integer(2), sp.Integer(3)
x0_val, v0_val = sp.Rational(1, 2), sp.Integer(-1)
f_closed = sp.Integer(1)

xf = sp.Function("x")
trajectory = sp.dsolve(
    sp.Eq(xf(t).diff(t, 2) + B_true * xf(t).diff(t) + K_true * xf(t), f_closed), xf(t),
    ics={xf(0): x0_val, xf(t).diff(t).subs(t, 0): v0_val}).rhs
display(sp.Eq(sp.Symbol("x(t)"), trajectory))

# it solves the ODE and starts where it should
residual_ode = trajectory.diff(t, 2) + B_true * trajectory.diff(t) + K_true * trajectory - f_closed
print("x'' + 2 x' + 3 x - 1 =", sp.simplify(residual_ode), "  x(0) =", trajectory.subs(t, 0),
      "  x'(0) =", sp.simplify(trajectory.diff(t).subs(t, 0)))

# %% tags=["remove-cell"]
RESULTS["identities"]["trajectory_solves_ode"] = sp.simplify(residual_ode) == 0
RESULTS["identities"]["trajectory_initial_values"] = bool(
    trajectory.subs(t, 0) == x0_val and sp.simplify(trajectory.diff(t).subs(t, 0)) == v0_val)

# %% [markdown]
# To evaluate the kernels exactly we write the trajectory as a sum of terms
# $c\,t^n e^{a t}$ (the complex exponentials $e^{(-1\pm i\sqrt2)t}$ replace
# $e^{-t}\cos\sqrt2 t$ and $e^{-t}\sin\sqrt2 t$).  Such terms integrate in closed form,
#
# $$\int_0^t \tau^n e^{a\tau}\,d\tau = \Big[e^{a\tau}\sum_{j=0}^{n}
#   (-1)^j \frac{n!}{(n-j)!}\frac{\tau^{n-j}}{a^{j+1}}\Big]_0^t,$$
#
# and keeping every coefficient in the form $p + q\,i\sqrt2$ (rationals $p, q$) lets
# SymPy decide equality to zero by plain expansion.

# %%
def exponential_form(expr):
    """``expr`` as a sum of c * t**n * exp(a*t), each exponential in one piece."""
    expr = sp.expand_trig(expr)  # sin(t + pi/4) -> sin(t) cos(pi/4) + ...
    expr = sp.expand(sp.powsimp(sp.expand(expr.rewrite(sp.exp))), power_exp=False)
    return sp.powsimp(expr)


def closed_integral(expr):
    """``int_0^t expr`` for a sum of c * t**n * exp(a*t), in exponential form."""
    total = sp.Integer(0)
    for term in sp.Add.make_args(sp.expand(expr, power_exp=False)):
        coeff, rest = term.as_independent(t, as_Add=False)
        n, a = 0, sp.Integer(0)
        for factor in sp.Mul.make_args(rest):
            base, exp_ = factor.as_base_exp()
            if base == t:
                n += int(exp_)
            elif isinstance(factor, sp.exp):
                rate = sp.diff(factor.args[0], t)
                if rate.has(t):
                    raise ValueError(f"exponent of {factor} is not linear in t")
                a += rate
                coeff *= sp.expand_complex(sp.exp(factor.args[0].subs(t, 0)))
            elif factor != 1:
                raise ValueError(f"unexpected factor {factor}")
        if a == 0:
            total += coeff * t ** (n + 1) / (n + 1)
            continue
        inv_a = sp.radsimp(1 / a)  # rationalised once: p + q*I*sqrt(2)

        def antiderivative(v):
            return sp.exp(a * v) * sum((-1) ** j * sp.factorial(n) / sp.factorial(n - j)
                                       * v ** (n - j) * sp.expand(inv_a ** (j + 1))
                                       for j in range(n + 1))
        total += coeff * (antiderivative(t) - antiderivative(0))
    return sp.expand(total, power_exp=False)


def exact_kernels(derivation, signals):
    """Exact value of every kernel of ``derivation`` for closed-form ``signals``.

    Each chain t**p * signal is integrated once per level, so that the k-fold
    integral reuses the (k-1)-fold one (as the integrator chains of the estimator do).
    """
    depth = {}
    for kern in derivation.kernels:
        depth[(kern.signal, kern.power)] = max(depth.get((kern.signal, kern.power), 0),
                                               kern.order)
    values = {}
    for (sig, power), n_levels in depth.items():
        level = sp.expand(t**power * exponential_form(signals[sig]), power_exp=False)
        values[Kernel(sig, power, 0).expression()] = level
        for order in range(1, n_levels + 1):
            level = closed_integral(level)
            values[Kernel(sig, power, order).expression()] = level
    return values


kernel_values = exact_kernels(d, {"x": trajectory, "f": f_closed})
print(f"{len(kernel_values)} levels of the integrator chains evaluated exactly, e.g. int(t^2 x) =")
display(kernel_values[Kernel("x", 2, 1).expression()])

# %% [markdown]
# Now substitute into $P\,\theta - Q$ with the true parameters.  The result must be
# *identically* zero, for every $t$, although the initial conditions were nonzero:

# %%
theta_true = sp.Matrix([B_true, K_true])
residual = (d.P * theta_true - d.Q).xreplace(kernel_values)
residual = residual.applyfunc(lambda e: sp.expand(e, power_exp=False))
display(residual)

# %% tags=["remove-cell"]
RESULTS["msd_residual_is_zero"] = residual == sp.zeros(2, 1)

# %% [markdown]
# With wrong parameters, say $B = 2.1$, the same expression is a nonzero function of
# time: the identity pins the parameters down.

# %%
wrong = (d.P * sp.Matrix([sp.Rational(21, 10), K_true]) - d.Q).xreplace(kernel_values)
wrong = wrong.applyfunc(lambda e: sp.expand(e, power_exp=False))
wrong_at_1 = [complex(sp.N(e.subs(t, 1))).real for e in wrong]
print("P theta - Q at t = 1 with B = 2.1:", wrong_at_1)

# %% tags=["remove-cell"]
RESULTS["wrong_B_residual_at_1s"] = wrong_at_1

# %% [markdown]
# The estimator itself (Cramer's quotient) therefore returns the true values at every
# instant.  Its numerator for $B$ minus $2\times$ the denominator is identically zero,
# and likewise for $K$:

# %%
entry_values = {p_sym[i, j]: d.P[i, j].xreplace(kernel_values) for i in range(2) for j in range(2)}
entry_values.update({q_sym[i]: d.Q[i].xreplace(kernel_values) for i in range(2)})
den_t = sp.expand(denominator.xreplace(entry_values), power_exp=False)
quotient_is_exact = {}
for name, num, true in zip(model.parameters, numerators, (B_true, K_true)):
    num_t = sp.expand(num.xreplace(entry_values), power_exp=False)
    left_over = sp.expand(num_t - true * den_t, power_exp=False)
    quotient_is_exact[str(name)] = left_over == 0
    print(f"numerator of {name} - {true} x denominator = {left_over}")

estimates_at = {}
for when in (sp.Rational(1, 100), sp.Rational(1, 10), sp.Integer(1)):
    values = [sp.N((num.xreplace(entry_values) / den_t).subs(t, when), 30)
              for num in numerators]
    estimates_at[str(when)] = [complex(v).real for v in values]
    print(f"t = {str(when):>5}:  B = {sp.re(values[0])},  K = {sp.re(values[1])}")

# %% tags=["remove-cell"]
RESULTS["identities"].update({f"quotient_{k}_exact": v for k, v in quotient_is_exact.items()})
RESULTS["msd_estimates_at"] = estimates_at

# %% [markdown]
# The quotient is exact, but look at the size of the denominator $\det P(t)$.  Near
# $t=0$ it starts from zero like a high power of $t$; in exact arithmetic that does not
# matter, but with sampled data every numerical error of the integrals is divided by
# this tiny number, which is why the very first milliseconds of a numerical estimate
# are unreliable (notebook 2).  Later, $\det P(t)$ may also change sign (the dips of
# $|\det P|$ on the log scale below): at those isolated instants numerator and
# denominator vanish together.

# %%
import mpmath

# det P is a sum of many exponential terms that nearly cancel for small t: evaluate
# it with 60 significant digits rather than in double precision
mpmath.mp.dps = 60
det_function = sp.lambdify(t, den_t, "mpmath")
t_plot = np.logspace(-3, 1, 120)
det_values = np.array([float(mpmath.re(det_function(mpmath.mpf(float(v))))) for v in t_plot])
small = t_plot < 1e-2
slope = np.polyfit(np.log(t_plot[small]), np.log(np.abs(det_values[small])), 1)[0]
changes = np.flatnonzero(np.sign(det_values[1:]) != np.sign(det_values[:-1]))
sign_changes = [float(mpmath.findroot(lambda v: mpmath.re(det_function(v)),
                                      (t_plot[i], t_plot[i + 1]), solver="anderson"))
                for i in changes]
print(f"det P(t) ~ t^{slope:.2f} near t = 0; it changes sign at t =",
      ", ".join(f"{v:.4f} s" for v in sign_changes) or "(nowhere on the grid)")

x_function = sp.lambdify(t, trajectory, "numpy")
fig, (ax_x, ax_det) = plt.subplots(1, 2, figsize=(11, 4), layout="constrained")
t_lin = np.linspace(0, 10, 500)
ax_x.plot(t_lin, x_function(t_lin), label="closed-form $x(t)$")
ax_x.axhline(1 / 3, color="k", ls="--", lw=0.8, label="steady state $f/K = 1/3$")
ax_x.plot(0, float(x0_val), "o", color="C3", label="$x(0) = 1/2$ (unknown to the estimator)")
ax_x.set_xlabel("time $t$ [s]")
ax_x.set_ylabel("position $x$ [m]")
ax_x.set_title("exact trajectory used for the check")
ax_x.legend()
ax_x.grid(alpha=0.3)
ax_det.loglog(t_plot, np.abs(det_values), label=r"$|\det P(t)|$")
for v in sign_changes:
    ax_det.axvline(v, color="0.5", ls=":", lw=1)
ax_det.loglog(t_plot[small], np.abs(det_values[0]) * (t_plot[small] / t_plot[0]) ** slope, "k--",
              lw=0.8, label=f"slope {slope:.2f} near $t=0$")
ax_det.set_xlabel("time $t$ [s]")
ax_det.set_ylabel(r"$|\det P(t)|$")
ax_det.set_title("the denominator of the estimator")
ax_det.legend()
ax_det.grid(alpha=0.3, which="both")

# %% tags=["remove-cell"]
RESULTS["det_P_small_t_power"] = float(slope)

# %% [markdown]
# ## 1.10 Your own model
#
# The engine is not specific to the mass-spring-damper.  Any linear ODE with constant
# coefficients that are affine in the unknowns can be written as text, with primes for
# derivatives.  Here is a second-order system with a zero,
#
# $$y'' + a\,y' + b\,y = u' + u,$$
#
# with unknowns $a$, $b$, input $u$ and output $y$.  The input is differentiated too,
# so its initial value $u(0)$ becomes one more initial condition; it sits in the same
# degree-1 polynomial in $s$ and the same two derivatives remove it.

# %%
custom = LinearODEModel.from_equation("y'' + a*y' + b*y = u' + u", parameters="a b",
                                      input="u", output="y", name="zero_pole")
d_custom = derive(custom)
display(custom.ode())
print("initial conditions:", d_custom.initial_conditions)

# %% [markdown]
# The whole derivation, rendered by `derivation_report(model, "markdown")`:

# %%
display(Markdown(derivation_report(custom, "markdown")))

# %% [markdown]
# ### Check on an exact trajectory
#
# Take $a = 3$, $b = 2$, the input $u(t) = 1 + \sin t$ (so $u(0) = 1$) and the
# initial conditions $y(0) = 1$, $\dot y(0) = -1$.

# %%
a_true, b_true = sp.Integer(3), sp.Integer(2)
u_closed = 1 + sp.sin(t)
yf = sp.Function("y")
y_closed = sp.dsolve(
    sp.Eq(yf(t).diff(t, 2) + a_true * yf(t).diff(t) + b_true * yf(t),
          u_closed.diff(t) + u_closed), yf(t),
    ics={yf(0): 1, yf(t).diff(t).subs(t, 0): -1}).rhs
display(sp.Eq(sp.Symbol("y(t)"), y_closed))

custom_kernels = exact_kernels(d_custom, {"y": y_closed, "u": u_closed})
custom_residual = (d_custom.P * sp.Matrix([a_true, b_true]) - d_custom.Q).xreplace(custom_kernels)
custom_residual = custom_residual.applyfunc(lambda e: sp.expand(e, power_exp=False))
display(custom_residual)

# %% tags=["remove-cell"]
RESULTS["custom_residual_is_zero"] = custom_residual == sp.zeros(2, 1)

# %% [markdown]
# ### From the formulas to numbers
#
# The entries of $P$ and $Q$ are fixed combinations of kernels
# $\int^{(k)}(t^p\,\mathrm{signal})$.  Numerically, each kernel is a chain of
# cumulative integrals of the sampled signal (`algid.signals.iterated_integrals`,
# a causal 6-point rule), and the estimate is Cramer's quotient at every sample.  We
# sample the exact trajectory at 1 kHz, as a measurement would be, and run the
# estimator we just derived.

# %%
rate = 1000.0
duration = 2.0 if QUICK else 5.0
h = 1.0 / rate
tau = np.arange(int(round(duration * rate)) + 1) * h
samples = {"y": sp.lambdify(t, y_closed, "numpy")(tau),
           "u": sp.lambdify(t, u_closed, "numpy")(tau)}

kernel_symbols = d_custom.kernel_symbols()  # kernel expression -> plain symbol
depth = {}
for kern in d_custom.kernels:
    depth[(kern.signal, kern.power)] = max(depth.get((kern.signal, kern.power), 0), kern.order)
numeric = {}
for (sig, power), n_levels in depth.items():
    levels = iterated_integrals(tau**power * samples[sig], h, n_levels, points=6)
    for order, values in enumerate(levels):
        numeric[Kernel(sig, power, order).name] = values

args = [kernel_symbols[k.expression()] for k in d_custom.kernels]
entries = list(d_custom.P.xreplace(kernel_symbols)) + list(d_custom.Q.xreplace(kernel_symbols))
entries_fn = sp.lambdify(args, entries, "numpy")  # P row by row, then Q
p00, p01, p10, p11, q0, q1 = (np.broadcast_to(np.asarray(v, dtype=float), tau.shape)
                              for v in entries_fn(*[numeric[k.name] for k in d_custom.kernels]))

det = p00 * p11 - p01 * p10
with np.errstate(divide="ignore", invalid="ignore"):
    a_hat = (q0 * p11 - p01 * q1) / det
    b_hat = (p00 * q1 - q0 * p10) / det
a_hat[: startup_samples(6)] = np.nan  # start-up of the 6-point rule
b_hat[: startup_samples(6)] = np.nan

final = {"a": float(a_hat[-1]), "b": float(b_hat[-1])}
print(f"at t = {tau[-1]:g} s: a = {final['a']:.12f}, b = {final['b']:.12f}")

fig, (ax, ax_err) = plt.subplots(1, 2, figsize=(12, 4), layout="constrained")
ax.plot(tau, a_hat, color="C0", label=r"$\hat a(t)$")
ax.plot(tau, b_hat, color="C3", label=r"$\hat b(t)$")
ax.axhline(3, color="k", ls="--", lw=0.9, label="true $a = 3$, $b = 2$")
ax.axhline(2, color="k", ls="--", lw=0.9)
ax.set_ylim(0, 5)
ax.set_xlabel("time $t$ [s]")
ax.set_ylabel("estimate")
ax.set_title(r"estimates for $y'' + a y' + b y = u' + u$")
ax.legend()
ax.grid(alpha=0.3)
ax_err.semilogy(tau, np.abs(a_hat / 3 - 1), color="C0", label=r"$|\hat a/a - 1|$")
ax_err.semilogy(tau, np.abs(b_hat / 2 - 1), color="C3", label=r"$|\hat b/b - 1|$")
ax_err.set_xlabel("time $t$ [s]")
ax_err.set_ylabel("relative error")
ax_err.set_title("relative error (noise-free samples, 1 kHz, 6-point rule)")
ax_err.legend()
ax_err.grid(alpha=0.3, which="both")

# %% tags=["remove-cell"]
RESULTS["custom_final"] = final

# %% [markdown]
# Apart from the first few milliseconds, where $\det P$ is tiny (section 1.9), the
# estimates sit on the true values; what is left is the error of the numerical
# integrals, and they were obtained without knowing $y(0)$,
# $\dot y(0)$ or $u(0)$.  The built-in models `"msd"` and `"msd_mass"` are derived the
# same way; `algid.estimate` runs their generated estimators, and notebook 2 looks at
# them on the paper's experiments.
