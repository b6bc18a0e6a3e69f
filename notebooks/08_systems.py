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
# # 8. Systems of equations and hidden signals
#
# Machines are rarely one equation. Here, three that are not:
#
# 1. two masses coupled by a spring, the force on the first, **both positions
#    measured**: two equations that share the coupling stiffness `k2`, identified
#    together with one joint covariance;
# 2. the same machine with **only the second position measured** (and the first mass
#    known): the hidden position is eliminated symbolically, the fourth-order equation
#    that remains is identified, and its coefficients are mapped back to the physical
#    parameters; with the first mass unknown too, the parameters are refused, and the
#    refusal says what the measurement does determine;
# 3. a **DC motor** with current and speed measured: the electrical and the mechanical
#    equations share the torque constant `K`.
#
# The records are simulated (`algid.simulate_system`, exact for inputs linear between
# samples) with white noise at 40 dB on every measured output.

# %%
import os

# ALGID_NOTEBOOK_QUICK=1 selects a small workload (10 s records at 500 Hz)
QUICK = os.environ.get("ALGID_NOTEBOOK_QUICK", "") not in ("", "0")

import matplotlib.pyplot as plt
import numpy as np
from IPython.display import Markdown, display

import algid

DURATION, RATE = (10.0, 500.0) if QUICK else (20.0, 1000.0)
t = np.arange(0.0, DURATION, 1.0 / RATE)
rng = np.random.default_rng(1)


def multisine(freqs):
    """A sum of sines of unit amplitude, phases fixed by the frequencies."""
    return sum(np.sin(2 * np.pi * f * t + f) for f in freqs)


def noisy(signals, snr_db=40.0):
    """Each signal with white noise at ``snr_db`` below its rms."""
    return {name: v + 10 ** (-snr_db / 20) * v.std() * rng.standard_normal(v.size)
            for name, v in signals.items()}


def table(fit, truth):
    """Estimates, standard errors and errors against the truth, as Markdown."""
    rows = ["| parameter | true | estimate | std. error | error / std. error |",
            "| --- | --- | --- | --- | --- |"]
    for p, true in truth.items():
        v, se = fit.values[p], fit.stderr[p]
        rows.append(f"| `{p}` | {true:g} | {v:.5g} | {se:.2g} | {(v - true) / se:+.2f} |")
    return Markdown("\n".join(rows))


# %% [markdown]
# ## 1. Two masses, both positions measured
#
# $m_1 \ddot x_1 + c_1 \dot x_1 + k_1 x_1 + k_2 (x_1 - x_2) = u$ and
# $m_2 \ddot x_2 + c_2 \dot x_2 + k_2 (x_2 - x_1) = 0$. The second equation has no
# known term: alone, its parameters would be determined only up to a common factor; in
# the system, `k2` fixes it.

# %%
TWO_MASS = ["m1*x1'' + c1*x1' + k1*x1 + k2*(x1 - x2) = u",
            "m2*x2'' + c2*x2' + k2*(x2 - x1) = 0"]
TRUTH = {"m1": 1.0, "c1": 0.5, "k1": 20.0, "k2": 15.0, "m2": 0.8, "c2": 0.3}
u = multisine([0.2, 0.45, 0.7, 0.95, 1.3, 1.7, 2.2, 3.0])
clean = algid.simulate_system(TWO_MASS, TRUTH, t, {"u": u},
                              initial_state=[0.01, 0.0, -0.02, 0.0])
record = {"t": t, "u": u, **noisy(clean)}

both = algid.identify(record, TWO_MASS, list(TRUTH))
print(both)
display(table(both, TRUTH))

# %% [markdown]
# The joint covariance counts what the two equations share: the noise of `x2` enters
# both, and `k1`, `k2` and the masses are read from the same motion. Its correlations:

# %%
fig, axes = plt.subplots(1, 2, figsize=(11, 3.8), gridspec_kw={"width_ratios": [1, 1.6]})
image = axes[0].imshow(both.correlation, vmin=-1, vmax=1, cmap="RdBu_r")
axes[0].set_xticks(range(len(TRUTH)), list(TRUTH))
axes[0].set_yticks(range(len(TRUTH)), list(TRUTH))
axes[0].set_title("correlation of the estimates")
fig.colorbar(image, ax=axes[0], shrink=0.8)
validation = both.simulate(record)
for name, color in (("x1", "C0"), ("x2", "C1")):
    axes[1].plot(t, validation.measured[name], color=color, lw=0.6, alpha=0.5,
                 label=f"{name} measured")
    axes[1].plot(t, validation.simulated[name], color=color, lw=1.2, ls="--",
                 label=f"{name} simulated ({validation.fit_percent[name]:.1f} %)")
axes[1].set_xlabel("t (s)")
axes[1].set_title("the coupled system simulated from the estimate")
axes[1].legend(fontsize=8, ncol=2)
fig.tight_layout()

# %% tags=["remove-cell"]
RESULTS = {"quick": QUICK}
RESULTS["both_estimate"] = both.estimate
RESULTS["both_relative_error"] = {p: both.values[p] / v - 1 for p, v in TRUTH.items()}
RESULTS["both_error_over_se"] = {p: (both.values[p] - v) / both.stderr[p]
                                 for p, v in TRUTH.items()}
RESULTS["both_fit_percent"] = validation.fit_percent

# %% [markdown]
# ## 2. Only the second position measured
#
# With `x1` hidden and `m1 = 1` known (written in the equation), the adjugate of the
# system's operator matrix eliminates `x1`: the measured position obeys one
# fourth-order equation whose coefficients are functions of the five remaining
# parameters.

# %%
HIDDEN = ["x1'' + c1*x1' + k1*x1 + k2*(x1 - x2) = u", TWO_MASS[1]]
TRUTH_HIDDEN = {p: v for p, v in TRUTH.items() if p != "m1"}
only_x2 = {"t": t, "u": u, "x2": record["x2"]}
hidden = algid.identify(only_x2, HIDDEN, list(TRUTH_HIDDEN), hidden=["x1"])
display(Markdown("$$" + hidden.elimination.latex[0] + "$$"))
display(table(hidden, TRUTH_HIDDEN))

# %% [markdown]
# The coefficients were identified first, then mapped back to the parameters by weighted
# least squares (`hidden.algebraic`), then the full system was refined by output error
# with the hidden position simulated. Where the first mass is unknown too, the
# measurement cannot tell a heavier first mass from a larger hidden motion, and the call
# is refused before any fit:

# %%
try:
    algid.identify(only_x2, TWO_MASS, list(TRUTH), hidden=["x1"])
except algid.ModelError as error:
    print(error)

# %% tags=["remove-cell"]
RESULTS["hidden_estimate"] = hidden.estimate
RESULTS["hidden_relative_error"] = {p: hidden.values[p] / v - 1
                                    for p, v in TRUTH_HIDDEN.items()}
RESULTS["hidden_error_over_se"] = {p: (hidden.values[p] - v) / hidden.stderr[p]
                                   for p, v in TRUTH_HIDDEN.items()}
try:
    algid.identify(only_x2, TWO_MASS, list(TRUTH), hidden=["x1"])
    RESULTS["refused"] = ""
except algid.ModelError as error:
    RESULTS["refused"] = str(error)

# %% [markdown]
# ## 3. A DC motor: current and speed measured
#
# $L \dot\imath + R i + K \omega = u$ and $J \dot\omega + b \omega = K i$: the torque
# constant `K` appears in both.

# %%
MOTOR = ["L*i' + R*i + K*w = u", "J*w' + b*w = K*i"]
MOTOR_TRUTH = {"L": 0.5, "R": 2.0, "K": 0.8, "J": 0.2, "b": 0.1}
voltage = multisine([0.1, 0.3, 0.6, 1.1, 1.9, 3.1, 5.0])
motor_record = {"t": t, "u": voltage,
                **noisy(algid.simulate_system(MOTOR, MOTOR_TRUTH, t, {"u": voltage}))}
motor = algid.identify(motor_record, MOTOR, list(MOTOR_TRUTH))
display(table(motor, MOTOR_TRUTH))
print(motor.to_control())

# %% [markdown]
# Alone, the mechanical equation has no known term, so `identify` refuses it; the
# system is what fixes its scale.

# %%
try:
    algid.identify(motor_record, MOTOR[1], "J b K")
except algid.ModelError as error:
    print(error)

# %% tags=["remove-cell"]
RESULTS["motor_estimate"] = motor.estimate
RESULTS["motor_error_over_se"] = {p: (motor.values[p] - v) / motor.stderr[p]
                                  for p, v in MOTOR_TRUTH.items()}
RESULTS["motor_relative_error"] = {p: motor.values[p] / v - 1 for p, v in MOTOR_TRUTH.items()}
