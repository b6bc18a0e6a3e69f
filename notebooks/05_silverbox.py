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
# from the measured input alone (`result.simulate`), with its initial state fitted on the
# first 50 samples, and the simulation error is taken over the rest.
#
# At 9 samples per period the simulation itself must be accurate: `result.simulate`
# integrates with DOP853 and interpolates the input as a band-limited signal (RK4 at the
# sampling step would add an error of about 1 mV, as large as the model errors we want
# to compare; the last section measures what the interpolation of the input changes).

# %%
import os
import time

# ALGID_NOTEBOOK_QUICK=1 selects a small workload (a shorter validation record).
QUICK = os.environ.get("ALGID_NOTEBOOK_QUICK", "") not in ("", "0")

import matplotlib.pyplot as plt
import numpy as np
from IPython.display import Markdown, display

import algid
from algid.datasets import silverbox

record = silverbox()
print(record)
print(record.citation)
estimation = record.segment("estimation")
arrow = record.segment("arrow")
if QUICK:
    # the first 3000 samples of the arrow part (small amplitude) keep the run short
    arrow = {name: values[:3000] for name, values in arrow.items()}
fs = record.fs
print(f"validation on {len(arrow['V2'])} samples of the arrow part "
      f"({len(arrow['V2']) / fs:.1f} s)")

# %% tags=["remove-cell"]
# The numbers that tests/test_notebooks.py checks: collected in cells tagged
# "remove-cell", which the documentation does not render.
RESULTS = {}

# %% [markdown]
# ## Identification: linear and cubic models
#
# The window is chosen from the data (no `window=` given); the standard errors account
# for the overlap of the windows (see `algid.identification._identify`). A result warns when the
# model does not explain the data within the noise.

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
    print(f"{label:7s} ({elapsed:.1f} s): {fits[label]}\n")


def natural_frequency_and_damping(fit):
    """Natural frequency (Hz) and damping ratio with their standard errors (delta method)."""
    index = [fit.model.parameters.index(p) for p in ("B", "K")]
    covariance = fit.covariance[np.ix_(index, index)]
    B, K = fit.B, fit.K
    frequency = np.sqrt(K) / (2 * np.pi)
    damping = B / (2 * np.sqrt(K))
    d_frequency = np.array([0.0, 1 / (4 * np.pi * np.sqrt(K))])
    d_damping = np.array([1 / (2 * np.sqrt(K)), -B / (4 * K ** 1.5)])
    return (frequency, float(np.sqrt(d_frequency @ covariance @ d_frequency)),
            damping, float(np.sqrt(d_damping @ covariance @ d_damping)))


def pm(value, spread):
    """``value ± spread``, with the spread to two significant digits."""
    digits = max(0, 1 - int(np.floor(np.log10(spread)))) if spread > 0 else 3
    return f"{value:.{digits}f} ± {spread:.{digits}f}"


cubic = fits["cubic"]
natural_frequency, frequency_se, damping_ratio, damping_se = natural_frequency_and_damping(cubic)
print(f"cubic model: natural frequency {pm(natural_frequency, frequency_se)} Hz, "
      f"damping ratio {pm(damping_ratio, damping_se)} (± one standard error)")

# %% tags=["remove-cell"]
RESULTS["natural_frequency_hz"] = natural_frequency
RESULTS["damping_ratio"] = damping_ratio
RESULTS["K3"] = cubic.K3
RESULTS["window_s"] = cubic.window
RESULTS["warnings"] = {label: len(fit.warnings) for label, fit in fits.items()}

# %% [markdown]
# ## The estimates across window lengths
#
# The algebraic equations hold on every window, whatever its length, so a model that
# describes the data gives the same parameters on short and on long windows, within
# their error bars. We identify both models again with the window fixed
# (`window=` in seconds) at the lengths of the grid the window rule searches, from the
# shortest up, and draw the natural frequency and the damping ratio of each, and the
# cubic coefficient, with ±2σ bars; the bottom-right panel is the window rule's
# criterion (`result.window_scores`, smallest is best). Where `identify` refuses a
# window (its equations do not separate the parameters there), a line says why and that
# length is left out of the figure.

# %%
lengths = sorted(cubic.window_scores)[:9]  # window lengths in samples, from the rule's grid


def identified_or_refused(equation, parameters, length):
    """The algebraic fit on a window of ``length`` samples (not refined: the window is
    what is studied), or None where identify refuses it (it does when the window's
    equations cannot separate the parameters)."""
    try:
        return algid.identify(estimation, equation, parameters, rate=fs,
                              window=(length - 1) / fs, refine=False)
    except algid.AlgidError as refusal:
        print(f"{equation}: window of {length} samples refused: {refusal}")
        return None


window_fits = {label: [identified_or_refused(*MODELS[label], n) for n in lengths]
               for label in MODELS}
kept = [i for i in range(len(lengths))
        if all(window_fits[label][i] is not None for label in MODELS)]
lengths = [lengths[i] for i in kept]
sweep = {label: [(window_fits[label][i], *natural_frequency_and_damping(window_fits[label][i]))
                 for i in kept] for label in MODELS}
window_ms = 1e3 * (np.array(lengths) - 1) / fs
chosen_ms = 1e3 * cubic.window

fig, axes = plt.subplots(2, 2, figsize=(11, 7), layout="constrained")
for i, label in enumerate(MODELS):
    rows = sweep[label]
    offset = 1 + 0.02 * (2 * i - 1)  # the two models side by side
    axes[0, 0].errorbar(window_ms * offset, [r[1] for r in rows], yerr=[2 * r[2] for r in rows],
                        fmt="o-", capsize=3, ms=4, color=f"C{i}", label=f"{label} model")
    axes[0, 1].errorbar(window_ms * offset, [r[3] for r in rows], yerr=[2 * r[4] for r in rows],
                        fmt="o-", capsize=3, ms=4, color=f"C{i}", label=f"{label} model")
rows = sweep["cubic"]
axes[1, 0].errorbar(window_ms, [r[0].K3 for r in rows], yerr=[2 * r[0].stderr["K3"] for r in rows],
                    fmt="o-", capsize=3, ms=4, color="C1", label="cubic model")
scores = cubic.window_scores
axes[1, 1].loglog(1e3 * (np.array(sorted(scores)) - 1) / fs, [scores[n] for n in sorted(scores)],
                  "o-", ms=3, color="C1")
for ax, title in zip(axes.flat, ("natural frequency (Hz)", "damping ratio",
                                 "cubic coefficient K3 (1/(V² s²))",
                                 "window criterion (cubic model), the whole grid")):
    ax.axvline(chosen_ms, color="0.4", ls=":", lw=1.0, label="window chosen (cubic model)")
    ax.set_xscale("log")
    ax.set_title(title, fontsize="medium")
    ax.set_xlabel("window length (ms)")
    ax.grid(alpha=0.3, which="both")
for ax in (axes[0, 0], axes[0, 1], axes[1, 0]):
    ax.set_xlim(window_ms[0] / 1.15, window_ms[-1] * 1.15)
    ax.set_xticks([25, 50, 100, 150], ["25", "50", "100", "150"])
    ax.minorticks_off()
axes[0, 0].legend(fontsize="small")
fig.suptitle("Silverbox: estimates on windows of fixed length (±2σ)")

# %%
rows = ["| window (ms) | " + " | ".join(f"{label}: f₀ (Hz) | {label}: ζ" for label in MODELS)
        + " | cubic: K3 |", "| ---: | " + " | ".join("---: | ---:" for _ in MODELS) + " | ---: |"]
for k, length in enumerate(lengths):
    cells = [f"{window_ms[k]:.1f}"]
    for label in MODELS:
        _, f0, f0_se, zeta, zeta_se = sweep[label][k]
        cells += [pm(f0, 2 * f0_se), pm(zeta, 2 * zeta_se)]
    fit = sweep["cubic"][k][0]
    cells.append(f"{fit.K3:.4g} ± {2 * fit.stderr['K3']:.2g}")
    rows.append("| " + " | ".join(cells) + " |")
display(Markdown("\n".join(rows)))

# %% tags=["remove-cell"]
RESULTS["window_sweep"] = {
    label: {"window_ms": window_ms.tolist(), "frequency_hz": [r[1] for r in sweep[label]],
            "frequency_se": [r[2] for r in sweep[label]]} for label in MODELS}

# %% [markdown]
# The cubic model gives nearly the same natural frequency and damping on every window
# up to a few periods of the resonance (its bars at the short windows are smaller than
# the markers); its cubic coefficient drifts down by a few per cent as the windows grow.
# The linear model does not hold still: its natural frequency and damping fall as the
# windows grow, far beyond their error bars. On a short window the output hardly changes
# amplitude and a linear spring fits it locally; a longer window sees the stiffness
# change with the amplitude, which the linear model can only average. That drift is
# what the warning of the linear fit reports. Beyond a few periods the windows average
# the high-frequency content out of the equations and every estimate loses precision
# (the bars grow): the rule keeps the window where every parameter is near its best
# precision.
#
# ## Validation on the arrow part, by accurate simulation

# %%
validation = {label: fit.simulate(arrow) for label, fit in fits.items()}
rows = ["| model | simulation RMSE (mV) | fit (%) |", "| --- | ---: | ---: |"]
for label, result in validation.items():
    rows.append(f"| {label} | {1e3 * result.rmse:.3f} | {result.fit_percent:.2f} |")
display(Markdown(f"On {len(arrow['V2'])} samples of the arrow part (output rms "
                 f"{1e3 * np.std(arrow['V2']):.1f} mV):\n\n" + "\n".join(rows)))

# %% tags=["remove-cell"]
for label, result in validation.items():
    RESULTS[f"rmse_mV_{label}"] = 1e3 * result.rmse

# %% [markdown]
# (`fit` is `100 (1 - |y - y_sim| / |y - mean(y)|)`.) For scale, on the full arrow part
# an output-error fit of the cubic model, simulated accurately, gives about 0.45 mV, a
# linear model about 16 mV; the natural frequency from an output-error fit on the
# low-amplitude part is about 68.4 Hz with a damping ratio of 0.048 (no physical values
# are published for the Silverbox). Without `ALGID_NOTEBOOK_QUICK` this notebook
# validates on the full arrow part; with it, on its first 3000 samples, where the
# amplitude is small and the two models differ less.
#
# The measured output and the cubic model's simulation, over the whole validation
# record and over a tenth of a second around its largest excursion, where each period is
# only nine samples:

# %%
cubic_run = validation["cubic"]
fig, (ax_all, ax_zoom) = plt.subplots(2, 1, figsize=(10, 6), layout="constrained")
ax_all.plot(cubic_run.t, 1e3 * cubic_run.measured, lw=0.5, label="measured V2")
ax_all.plot(cubic_run.t, 1e3 * cubic_run.simulated, lw=0.5, label="cubic model, simulated")
ax_all.set_xlabel("t (s) from row 100")
ax_all.set_title("Silverbox, arrow part: measured output against the output simulated "
                 "from V1 alone")
peak = cubic_run.t[np.argmax(np.abs(cubic_run.measured))]
zoom = np.abs(cubic_run.t - peak) <= 0.05
ax_zoom.plot(cubic_run.t[zoom], 1e3 * cubic_run.measured[zoom], "o", ms=4,
             label="measured V2 (samples)")
ax_zoom.plot(cubic_run.t[zoom], 1e3 * cubic_run.simulated[zoom], ".-", lw=1.0,
             label="cubic model, simulated")
ax_zoom.set_xlabel("t (s) from row 100")
ax_zoom.set_title("0.1 s around the largest excursion", fontsize="medium")
for ax in (ax_all, ax_zoom):
    ax.set_ylabel("mV")
    ax.legend(loc="upper left", fontsize="small")
    ax.grid(alpha=0.3)

# %% [markdown]
# At this scale the two curves cover each other. The residuals, measured minus simulated
# output, tell the models apart. On the left, over time (the first 50 samples, used to
# fit the initial state, are left out); on the right, their rms over blocks of 500
# samples against the rms of the output in the same block.

# %%
skip = cubic_run.skip
block = 500
fig, (ax_t, ax_a) = plt.subplots(1, 2, figsize=(12, 4.2), layout="constrained",
                                 gridspec_kw={"width_ratios": [1.6, 1]})
for i, (label, result) in enumerate(validation.items()):
    ax_t.plot(result.t[skip:], 1e3 * result.residuals[skip:], lw=0.4, color=f"C{i}",
              label=f"{label} model")
    n_blocks = (len(result.t) - skip) // block
    pieces = slice(skip, skip + n_blocks * block)
    residual_rms = np.sqrt(np.mean(result.residuals[pieces].reshape(n_blocks, block) ** 2, axis=1))
    output_rms = np.sqrt(np.mean(result.measured[pieces].reshape(n_blocks, block) ** 2, axis=1))
    ax_a.loglog(1e3 * output_rms, 1e3 * residual_rms, "o", ms=4, color=f"C{i}",
                label=f"{label} model")
ax_t.set_xlabel("t (s) from row 100")
ax_t.set_ylabel("measured − simulated (mV)")
ax_t.set_title("simulation residuals", fontsize="medium")
ax_a.set_xlabel("output rms in the block (mV)")
ax_a.set_ylabel("residual rms in the block (mV)")
ax_a.set_title(f"residual against amplitude, blocks of {block} samples", fontsize="medium")
for ax in (ax_t, ax_a):
    ax.legend(loc="upper left", fontsize="small")
    ax.grid(alpha=0.3, which="both")

# %% [markdown]
# The residual of the linear model grows quickly with the amplitude of the output: the
# stiffness it lacks is the cubic term, whose share of the restoring force grows with
# the square of the amplitude. The cubic model's residual is much smaller and grows far
# more slowly, if at all. (On the short record of the quick run the amplitudes span a
# narrow range, and the right panel has only a few blocks.)
#
# ## Why the accurate simulation matters here
#
# The same cubic model, simulated with the input interpolated by a cubic spline through
# the samples instead of a band-limited interpolation, differs from the accurate
# simulation by a fraction of the model error itself, a fraction that grows with the
# amplitude and the high-frequency content of the input (it is larger on the full arrow
# part than on the short record of the quick run):

# %%
spline_run = cubic.simulate(arrow, interpolation="cubic")
difference = cubic_run.simulated[skip:] - spline_run.simulated[skip:]
interpolation_difference = float(np.sqrt(np.mean(difference ** 2)))
print(f"band-limited against cubic-spline input: {1e3 * interpolation_difference:.3f} mV rms, "
      f"next to a model error of {1e3 * cubic_run.rmse:.3f} mV rms")

# %% tags=["remove-cell"]
RESULTS["interpolation_difference_mV"] = 1e3 * interpolation_difference
