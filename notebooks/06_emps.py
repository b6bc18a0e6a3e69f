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
# # 6. EMPS: mass, viscous and Coulomb friction of a positioning system
#
# The EMPS (Janot, Gautier and Brunot, 2019; shipped with algid as
# `algid.datasets.emps()`) is a mass on a ball screw driven by a DC motor, recorded at
# 1 kHz in closed loop under a position controller. The force on the mass is
# `F = gtau * vir` (drive gain times drive command), the output the position `qm`. The
# published reference model, identified by inverse-model least squares (IDIM-LS), is
#
# $$M\,q'' + F_v\,q' + F_c\,\mathrm{sign}(q') + \mathrm{off} = F,$$
#
# with $M$ = 95.1089 kg, $F_v$ = 203.5034 N s/m, $F_c$ = 20.3935 N and off = −3.1648 N
# (`algid.datasets.EMPS_PUBLISHED`, keyed by the parameters of that equation).
# Coulomb friction is as large as the peak viscous force: a model without it gets the
# damping wrong. We identify the model with `algid.identify` on the estimation run and,
# anew, on the validation run (with force pulses injected into the drive command), and
# validate by the relative error of the predicted force (published: 4.08 % and 5.98 %)
# and by a closed-loop simulation with the controller gains stored in the file.

# %%
import os
import time

# ALGID_NOTEBOOK_QUICK=1 selects a small workload (a shorter closed-loop simulation).
QUICK = os.environ.get("ALGID_NOTEBOOK_QUICK", "") not in ("", "0")

import matplotlib.pyplot as plt
import numpy as np

import algid
from algid.datasets import EMPS_PUBLISHED, EMPS_PUBLISHED_FORCE_ERROR, emps
from algid.differentiation import algebraic_derivative
from algid.grammar import parse_equation
from algid.model_simulation import simulate_model

RESULTS = {}
runs = {"estimation": emps("estimation"), "validation": emps("validation")}
print(runs["estimation"])
print(runs["estimation"].citation)
EQUATION = "M*qm'' + Fv*qm' + Fc*sign(qm') + off = F"

# %% [markdown]
# ## Identification on both runs
#
# The record's own time column `t` is the time axis; the window is chosen from the data.

# %%
fits = {}
for name, record in runs.items():
    start = time.perf_counter()
    fits[name] = algid.identify(record, EQUATION, "M Fv Fc off", time="t")
    print(f"{name} ({time.perf_counter() - start:.1f} s): {fits[name]}")

print(f"\n{'':12s}" + "".join(f"{p:>22s}" for p in EMPS_PUBLISHED))
print(f"{'published':12s}" + "".join(f"{v:22.4f}" for v in EMPS_PUBLISHED.values()))
for name, fit in fits.items():
    cells = []
    for p, reference in EMPS_PUBLISHED.items():
        error = fit.values[p] / reference - 1
        cells.append(f"{fit.values[p]:10.4f} ({100 * error:+5.2f} %)")
        RESULTS[f"{name}_relative_error_{p}"] = error
    print(f"{name:12s}" + "".join(f"{c:>22s}" for c in cells))

# targets of the project: estimation run within 1, 2, 3, 5 %; validation within 3, 5, 5 %
for p, limit in {"M": 0.01, "Fv": 0.02, "Fc": 0.03, "off": 0.05}.items():
    assert abs(RESULTS[f"estimation_relative_error_{p}"]) <= limit, p
for p, limit in {"M": 0.03, "Fv": 0.05, "Fc": 0.05}.items():
    assert abs(RESULTS[f"validation_relative_error_{p}"]) <= limit, p

# %% [markdown]
# ## Relative error of the predicted force
#
# The inverse model predicts the force from the measured position. Every term is
# low-passed by the same filter so that the comparison is fair: the algebraic
# differentiator's minimal estimate of the n-th derivative is the n-th derivative
# averaged with the weight Beta(κ+n+1, μ+n+1) over its window, so the force
# (n = 0, κ = μ = 4), the velocity (n = 1, κ = μ = 3) and the acceleration
# (n = 2, κ = μ = 2) all see the same Beta(5, 5) average over 50 ms (a low-pass with
# its −3 dB point at 17 Hz).

# %%
WINDOW = 0.05


def force_error(record, values):
    """||F - predicted F|| / ||F||, every term through the same Beta(5, 5) average."""
    dt = float(np.median(np.diff(record.t)))
    force = algebraic_derivative(record.F, dt, derivative=0, window=WINDOW, kappa=4, mu=4)
    velocity = algebraic_derivative(record.qm, dt, derivative=1, window=WINDOW, kappa=3, mu=3)
    acceleration = algebraic_derivative(record.qm, dt, derivative=2, window=WINDOW,
                                        kappa=2, mu=2)
    predicted = (values["M"] * acceleration + values["Fv"] * velocity
                 + values["Fc"] * np.sign(velocity) + values["off"])
    return float(np.linalg.norm(force - predicted) / np.linalg.norm(force))


for name, record in runs.items():
    ours, published = force_error(record, fits[name].values), force_error(record, EMPS_PUBLISHED)
    RESULTS[f"force_error_{name}"] = ours
    RESULTS[f"force_error_{name}_published_values"] = published
    print(f"{name:10s}: identified {100 * ours:.2f} %, published values {100 * published:.2f} %"
          f" (published figure {100 * EMPS_PUBLISHED_FORCE_ERROR[name]:.2f} %)")

# %% [markdown]
# ## The pulses of the validation run are already in the drive command
#
# `DATA_EMPS_PULSES.mat` also stores `pulses_N`. If those pulses acted on the mass in
# addition to the drive, the force balance would need `gtau*vir + pulses_N`. The record
# says otherwise: in a least-squares fit of the force balance, `pulses_N` gets a
# coefficient near zero, and the drive command itself carries the pulses. Identified with
# `gtau*vir + pulses_N` as the force, the offset absorbs the pulses' mean (they are 0 or
# 5) and lands far from the published value: the force is `F = gtau*vir` on both runs.

# %%
validation = runs["validation"]
dt = 1e-3
velocity = algebraic_derivative(validation.qm, dt, derivative=1, window=WINDOW, kappa=3, mu=3)
acceleration = algebraic_derivative(validation.qm, dt, derivative=2, window=WINDOW,
                                    kappa=2, mu=2)
smooth = {name: algebraic_derivative(validation[name], dt, derivative=0, window=WINDOW,
                                     kappa=4, mu=4) for name in ("F", "pulses_N")}
columns = np.c_[acceleration, velocity, np.sign(velocity), np.ones_like(velocity),
                smooth["pulses_N"]]
coefficients = np.linalg.lstsq(columns, smooth["F"], rcond=None)[0]
RESULTS["pulses_coefficient_in_force_balance"] = float(coefficients[-1])
print("force balance M, Fv, Fc, off, pulses:", np.round(coefficients, 4))
with_pulses = {"t": validation.t, "qm": validation.qm, "F": validation.F + validation.pulses_N}
fit_with_pulses = algid.identify(with_pulses, EQUATION, "M Fv Fc off", time="t")
print(f"identified with F = gtau*vir + pulses_N: {fit_with_pulses}")
RESULTS["off_relative_error_with_pulses"] = fit_with_pulses.off / EMPS_PUBLISHED["off"] - 1
print(f"off: {100 * RESULTS['off_relative_error_with_pulses']:+.1f} % with the pulses added, "
      f"{100 * RESULTS['validation_relative_error_off']:+.1f} % without")
assert abs(coefficients[-1]) < 0.1

# %% [markdown]
# ## Without Coulomb friction
#
# A linear mass-damper-spring with an offset, `M q'' + c q' + k q + off = F`, absorbs the
# Coulomb friction into a damping about twice too large and a spurious spring.

# %%
linear = algid.identify(runs["estimation"], "M*qm'' + c*qm' + k*qm + off = F", "M c k off",
                        time="t")
print(linear)
RESULTS["no_friction_c_over_Fv"] = linear.c / EMPS_PUBLISHED["Fv"]
RESULTS["no_friction_force_error"] = force_error(
    runs["estimation"], {"M": linear.M, "Fv": linear.c, "Fc": 0.0, "off": linear.off})

# %% [markdown]
# ## Closed-loop simulation with the stored controller gains
#
# The file stores the gains `kp` and `kv` of the position and velocity loops. Reading the
# controller as `vir = kv * (kp * (qg - q) - q')` (a least-squares fit of the record's
# `vir` on `qg - qm` and `qm'` agrees within about 10 %), the closed loop is one more
# model equation, driven by the reference position `qg`. The Coulomb term keeps its
# `sign`: the simulator integrates from one velocity reversal to the next and holds the
# mass at standstill while the force stays below the friction (`algid.switching`). The
# position follows the reference closely whatever the model, so the comparison is on the
# force the controller asks for. Over the whole run (without `ALGID_NOTEBOOK_QUICK`, about
# 2.5 s per simulation): 5.86 % with the identified values, 5.89 % with the published
# ones (6.30 % with the friction smoothed to `tanh(q'/1 mm/s)`).

# %%
record = runs["estimation"]
gain_velocity = record.gtau * record.kv
gain_position = record.gtau * record.kv * record.kp
closed_loop = parse_equation(
    f"M*q'' + Fv*q' + Fc*sign(q') + off + {gain_velocity!r}*q' + {gain_position!r}*q"
    f" = {gain_position!r}*qg", ["M", "Fv", "Fc", "off"])
n = 5000 if QUICK else len(record.t)
closed = {}
for label, values in (("identified", fits["estimation"].values), ("published", EMPS_PUBLISHED)):
    states = simulate_model(closed_loop, values, record.t[:n], {"qg": record.qg[:n]},
                            initial_state=[record.qm[0], 0.0], method="LSODA", rtol=1e-7,
                            return_states=True)
    force = gain_velocity * (record.kp * (record.qg[:n] - states[0]) - states[1])
    closed[label] = force
    error = float(np.linalg.norm(force - record.F[:n]) / np.linalg.norm(record.F[:n]))
    RESULTS[f"closed_loop_force_error_{label}"] = error
    print(f"closed loop, {label} values: relative force error {100 * error:.2f} %")

fig, ax = plt.subplots(figsize=(9, 3.5))
ax.plot(record.t[:n], record.F[:n], lw=0.6, label="measured gtau*vir")
ax.plot(record.t[:n], closed["identified"], lw=0.6, label="closed-loop simulation")
ax.set_xlabel("t (s)")
ax.set_ylabel("force (N)")
ax.legend(loc="upper right")
ax.set_title("EMPS, estimation run: force asked by the controller")
plt.tight_layout()

# %%
print(RESULTS)
