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
# # 5. Silverbox: a hardening spring identified from the equation you write down
#
# The Silverbox is an electronic circuit that behaves as a mass-spring-damper with a
# hardening cubic spring (Wigren and Schoukens, ECC 2013; the record ships with algid:
# `algid.datasets.silverbox()`). Its input `V1` and output `V2` are voltages sampled at
# 610.35 Hz, about 9 samples per period of the 68 Hz resonance, with small DC offsets on
# both channels. We write the physics as one equation, linear in its unknowns,
#
# $$V_2'' + B\,V_2' + K\,V_2 + K_3\,V_2^3 = G\,V_1 + d,$$
#
# where the gain `G` of the unknown input scale and the offset `d` are parameters like the
# others, and let `algid.identify` estimate them with the algebraic method on windows of
# the multisine part (rows 40650 to 105712). We then validate on held-out data, the
# "arrow" part (rows 100 to 40575, noise of growing amplitude): the model is simulated
# from the measured input alone, with its initial state fitted on the first 50 samples,
# and the simulation error is taken over the rest.
#
# At 9 samples per period the simulation itself must be accurate: `simulate_model`
# integrates with DOP853 and interpolates the input as a band-limited signal (a cubic
# spline through the samples, or RK4 at the sampling step, would add errors of the order
# of 0.1 to 1 mV, as large as the model errors we want to compare).

# %%
import os
import time

# ALGID_NOTEBOOK_QUICK=1 selects a small workload (a shorter validation record).
QUICK = os.environ.get("ALGID_NOTEBOOK_QUICK", "") not in ("", "0")

import matplotlib.pyplot as plt
import numpy as np

import algid
from algid.datasets import silverbox
from algid.grammar import parse_equation
from algid.model_simulation import fit_initial_state, simulate_model

RESULTS = {}
record = silverbox()
print(record)
print(record.citation)
estimation = record.segment("estimation")
arrow = record.segment("arrow")
if QUICK:
    # the first 3000 samples of the arrow part (small amplitude) keep the run short
    arrow = {name: values[:3000] for name, values in arrow.items()}
fs = record.fs

# %% [markdown]
# ## Identification: linear and cubic models
#
# The window is chosen from the data (no `window=` given); the standard errors account
# for the overlap of the windows (see `algid.identification`).

# %%
MODELS = {
    "linear": ("V2'' + B*V2' + K*V2 = G*V1 + d", "B K G d"),
    "cubic": ("V2'' + B*V2' + K*V2 + K3*V2**3 = G*V1 + d", "B K K3 G d"),
}
fits = {}
for label, (equation, parameters) in MODELS.items():
    start = time.perf_counter()
    fits[label] = algid.identify(estimation, equation, parameters, rate=fs)
    elapsed = time.perf_counter() - start
    print(f"{label:7s} ({elapsed:.1f} s): {fits[label]}")

cubic = fits["cubic"]
natural_frequency = np.sqrt(cubic.K) / (2 * np.pi)
damping_ratio = cubic.B / (2 * np.sqrt(cubic.K))
print(f"natural frequency {natural_frequency:.2f} Hz, damping ratio {damping_ratio:.4f}")
RESULTS["natural_frequency_hz"] = natural_frequency
RESULTS["damping_ratio"] = damping_ratio
RESULTS["K3"] = cubic.K3
RESULTS["window_s"] = cubic.window

# %% [markdown]
# ## Validation on the arrow part, by accurate simulation

# %%
t_arrow = np.arange(len(arrow["V2"])) / fs
validation = {}
for label, fit in fits.items():
    model = fit.model
    state = fit_initial_state(model, fit.values, t_arrow, arrow, arrow["V2"], 50)
    simulated = simulate_model(model, fit.values, t_arrow, arrow, initial_state=state)
    error = arrow["V2"][50:] - simulated[50:]
    validation[label] = simulated
    rmse = float(np.sqrt(np.mean(error ** 2)))
    RESULTS[f"rmse_mV_{label}"] = 1e3 * rmse
    print(f"{label:7s}: simulation RMSE on the arrow part {1e3 * rmse:.3f} mV "
          f"(output rms {1e3 * np.std(arrow['V2']):.1f} mV)")

# the cubic term must pay for itself on held-out data
assert RESULTS["rmse_mV_cubic"] < RESULTS["rmse_mV_linear"]

# %% [markdown]
# On the full arrow part (without `ALGID_NOTEBOOK_QUICK`) this gives 0.482 mV for the
# cubic model and 14.6 mV for the linear one. For scale: an output-error fit of the cubic
# model, simulated accurately, gives about 0.45 mV, a linear model about 16 mV. The natural frequency from an output-error fit on the low-amplitude part is
# about 68.4 Hz with a damping ratio of 0.048 (no physical values are published for the
# Silverbox).

# %%
fig, axes = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
axes[0].plot(t_arrow, 1e3 * arrow["V2"], lw=0.6, label="measured V2")
axes[0].plot(t_arrow, 1e3 * validation["cubic"], lw=0.6, label="cubic model")
axes[0].set_ylabel("mV")
axes[0].legend(loc="upper left")
for label, simulated in validation.items():
    axes[1].plot(t_arrow, 1e3 * (arrow["V2"] - simulated), lw=0.5, label=f"{label} error")
axes[1].set_ylabel("mV")
axes[1].set_xlabel("t (s) from row 100")
axes[1].legend(loc="upper left")
axes[0].set_title("Silverbox, arrow part: measured against simulated from V1 alone")
plt.tight_layout()

# %% [markdown]
# ## Why the accurate simulation matters here
#
# The same cubic model, simulated with the input interpolated by a cubic spline through
# the samples instead of a band-limited interpolation, differs by an amount comparable
# with the model error itself (0.063 mV rms over the full arrow part, where the model
# error is 0.482 mV; most of it where the amplitude, and the high-frequency content of
# the input, are largest).

# %%
state = fit_initial_state(cubic.model, cubic.values, t_arrow, arrow, arrow["V2"], 50,
                          interpolation="cubic")
spline_simulated = simulate_model(cubic.model, cubic.values, t_arrow, arrow,
                                  initial_state=state, interpolation="cubic")
difference = validation["cubic"][50:] - spline_simulated[50:]
RESULTS["interpolation_difference_mV"] = 1e3 * float(np.sqrt(np.mean(difference ** 2)))
print(f"band-limited vs cubic-spline input: {RESULTS['interpolation_difference_mV']:.3f} mV rms")

# %%
print(RESULTS)
