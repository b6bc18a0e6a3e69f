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
# # 7. Tracking: identification while the machine runs
#
# `algid.Tracker` is the streaming form of `algid.identify`: the same window equations,
# each formed as soon as the last sample of its window arrives, accumulated with
# exponential forgetting of half-life `half_life` seconds (`None` keeps every window).
# `tracker.update(chunk)` takes the next samples, from one to a whole record, and returns
# the estimates at every window end in the chunk with their standard errors, and the
# times of the change alarms it raised (a CUSUM test; the user guide, "Tracking on a
# stream", has the details). Four streams:
#
# 1. the EMPS positioning system (notebook 6) streamed as a data logger would send it,
#    the estimates and their ±2σ bands against the published values;
# 2. its validation run, with force pulses on the drive;
# 3. a simulated friction loop whose mass grows by 25 % in mid-record: forgetting lets
#    the estimate follow, and the alarm marks the change;
# 4. the Silverbox (notebook 5) tracked by a *linear* model: the stiffness it reports
#    rises with the amplitude, the hardening spring made visible.

# %%
import os
import time

# ALGID_NOTEBOOK_QUICK=1 selects a small workload (the first 8 s of the EMPS runs, the
# first 40 s of the Silverbox's arrow part).
QUICK = os.environ.get("ALGID_NOTEBOOK_QUICK", "") not in ("", "0")

import matplotlib.pyplot as plt
import numpy as np
from IPython.display import Markdown, display

import algid
from algid.datasets import (
    EMPS_EQUATION,
    EMPS_PUBLISHED,
    EMPS_PUBLISHED_RELATIVE_STD,
    emps,
    silverbox,
)
from algid.identification import TrackUpdate
from algid.models import parse_equation
from algid.simulation import simulate_model

PARAMETERS = list(EMPS_PUBLISHED)  # M Fv Fc off
UNITS = {"M": "kg", "Fv": "N s/m", "Fc": "N", "off": "N"}
runs = {"estimation": emps("estimation"), "validation": emps("validation")}
# the EMPS runs last 24.8 s; the quick workload streams their first 8 s
SPAN = 8.0 if QUICK else None
print(EMPS_EQUATION)
print("streamed: " + ("the first 8 s of each EMPS run" if QUICK else "the whole EMPS runs"))

# %% tags=["remove-cell"]
# The numbers that tests/test_notebooks.py checks: collected in cells tagged
# "remove-cell", which the documentation does not render.
RESULTS = {"quick": QUICK}

# %% [markdown]
# ## EMPS, streamed
#
# The EMPS record is sent to the tracker in chunks of 1000 samples (one second at
# 1 kHz), as a data logger would. The window is 0.03 s, the one `identify` chooses on
# the whole record (without `window=` the tracker chooses it by the same rule on the
# first seconds of the stream, `warmup`), and nothing is forgotten (`half_life=None`): the
# estimate at time *t* is then `identify`'s on the samples up to *t*, but for where the
# crossings of `sign(qm')` are placed (the tracker places them causally, from the
# samples it has seen).

# %%
WINDOW = 0.03


def stream(tracker, record, span=None, chunk=1000):
    """Feed ``record`` (its first ``span`` seconds) to ``tracker`` in chunks of ``chunk``
    samples; returns the reports of every chunk joined, and the seconds it took."""
    n = len(next(iter(record.values())))
    if span is not None:
        n = int(np.searchsorted(record["t"], record["t"][0] + span, side="right"))
    start, reports = time.perf_counter(), []
    for i in range(0, n, chunk):
        stop = min(i + chunk, n)
        reports.append(tracker.update({name: values[i:stop] for name, values in record.items()}))
    if tracker.window is None:   # it ended in the warm-up: the window on what it holds
        reports.append(tracker.update({name: values[:0] for name, values in record.items()},
                                      last=True))
    joined = TrackUpdate(reports[0].parameters,
                         *(np.concatenate([getattr(r, field) for r in reports])
                           for field in ("t", "values", "stderr", "numerical_error", "alarms")))
    return joined, time.perf_counter() - start


def emps_columns(record):
    """The signals that EMPS_EQUATION names, and the time column."""
    return {"t": record.t, "qm": record.qm, "F": record.F}


tracked, seconds = {}, {}
for name, record in runs.items():
    tracker = algid.Tracker(EMPS_EQUATION, PARAMETERS, window=WINDOW)
    tracked[name], seconds[name] = stream(tracker, emps_columns(record), SPAN)
    streamed = tracked[name].t[-1] - record.t[0]
    print(f"{name} run: {streamed:.1f} s of record streamed in {seconds[name]:.1f} s "
          f"({streamed / seconds[name]:.1f} times faster than real time), "
          f"{len(tracked[name])} window ends, "
          f"alarms at {np.round(tracked[name].alarms, 2).tolist()} s")

# %% [markdown]
# The last streamed estimates next to `identify` on the same samples and the published
# values (±2σ):

# %%
out = tracked["estimation"]
estimation = runs["estimation"]
n_streamed = int(np.searchsorted(estimation.t, out.t[-1], side="right"))
batch = algid.identify({k: v[:n_streamed] for k, v in emps_columns(estimation).items()},
                       EMPS_EQUATION, PARAMETERS, window=WINDOW)
final_error = {p: float(out.values[-1, k] / EMPS_PUBLISHED[p] - 1)
               for k, p in enumerate(PARAMETERS)}
over_identify = {p: float(out.values[-1, k] / batch.values[p] - 1)
                 for k, p in enumerate(PARAMETERS)}
rows = ["| parameter | tracker, last ± 2σ | identify, same samples | published ± 2σ | "
        "tracker − published |", "| --- | ---: | ---: | ---: | ---: |"]
for k, p in enumerate(PARAMETERS):
    reference = EMPS_PUBLISHED[p]
    rows.append(f"| {p} ({UNITS[p]}) | {out.values[-1, k]:.3f} ± {2 * out.stderr[-1, k]:.3f} | "
                f"{batch.values[p]:.3f} ± {2 * batch.stderr[p]:.3f} | "
                f"{reference:.3f} ± {2 * EMPS_PUBLISHED_RELATIVE_STD[p] * abs(reference):.3f} | "
                f"{100 * final_error[p]:+.2f} % |")
display(Markdown(f"At t = {out.t[-1]:.2f} s:\n\n" + "\n".join(rows)))

# %% tags=["remove-cell"]
RESULTS["emps_final_relative_error"] = final_error
RESULTS["emps_tracker_over_identify"] = over_identify
RESULTS["emps_streamed_s"] = float(out.t[-1] - estimation.t[0])

# %% [markdown]
# Over time: each estimate with its ±2σ band, the published value (black) with its own
# ±2σ band (grey), the alarms (red, dashed).


# %%
def axis_limits(out, k, reference, band):
    """A y range that holds the published band and most of the estimate's band."""
    low = out.values[:, k] - 2 * out.stderr[:, k]
    high = out.values[:, k] + 2 * out.stderr[:, k]
    ok = np.isfinite(low)
    bottom = min(reference - band, np.percentile(low[ok], 2))
    top = max(reference + band, np.percentile(high[ok], 98))
    pad = 0.1 * (top - bottom)
    return bottom - pad, top + pad


def draw_estimates(axes, out, title):
    for k, (ax, p) in enumerate(zip(axes.flat, PARAMETERS)):
        reference = EMPS_PUBLISHED[p]
        band = 2 * EMPS_PUBLISHED_RELATIVE_STD[p] * abs(reference)
        ax.axhspan(reference - band, reference + band, color="0.85", label="published ± 2σ")
        ax.axhline(reference, color="k", lw=0.9, label="published")
        ax.fill_between(out.t, out.values[:, k] - 2 * out.stderr[:, k],
                        out.values[:, k] + 2 * out.stderr[:, k], color="C0", alpha=0.3,
                        lw=0, label="tracker ± 2σ")
        ax.plot(out.t, out.values[:, k], color="C0", lw=1.0, label="tracker")
        for j, when in enumerate(out.alarms):
            ax.axvline(when, color="C3", ls="--", lw=0.9, label="alarm" if j == 0 else None)
        ax.set_ylim(*axis_limits(out, k, reference, band))
        ax.set_title(f"{p} [{UNITS[p]}]", fontsize="medium")
        ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("t (s)")
    fig = axes.flat[0].figure
    fig.legend(*axes.flat[0].get_legend_handles_labels(), loc="outside lower center", ncol=5,
               fontsize="small")
    fig.suptitle(title)


fig, axes = plt.subplots(2, 2, figsize=(11, 6), sharex=True, layout="constrained")
draw_estimates(axes, out, "EMPS, estimation run, streamed: estimates against the published "
               "values")

# %%
first = out.t[np.flatnonzero(np.isfinite(out.values[:, 0]))[0]]
determined = out.t[np.flatnonzero(np.isfinite(out.values).all(axis=1))[0]]
relative_M = np.abs(out["M"] / EMPS_PUBLISHED["M"] - 1)
outside = np.flatnonzero(~(relative_M <= 0.05))
settled_M = out.t[outside[-1] + 1] if len(outside) else out.t[0]
alarms = out.alarms
k_Fv = PARAMETERS.index("Fv")
if len(alarms):
    at_alarm = np.searchsorted(out.t, alarms[0], side="right") - 1
    Fv_then, Fv_se_then = out.values[at_alarm, k_Fv], out.stderr[at_alarm, k_Fv]
    Fv_last = out.values[-1, k_Fv]
    windows_then = int(np.sum(np.isfinite(out.values[:at_alarm + 1, k_Fv])))
    alarm_text = (
        f"The tracker raised {len(alarms)} alarm(s), at "
        f"{', '.join(f'{a:.2f}' for a in alarms)} s, all within "
        f"{alarms[-1] - determined:.1f} s of the moment all four parameters were "
        f"determined. The machine did not change: "
        f"the tracker was still learning. At the first alarm Fv was {Fv_then:.1f} ± "
        f"{2 * Fv_se_then:.1f} N s/m, {abs(Fv_last - Fv_then) / Fv_se_then:.0f} of its "
        f"standard errors from the {Fv_last:.1f} N s/m it reached at the end: the first "
        f"motions of the record pin the parameters down less well than standard errors "
        f"computed from their {windows_then} windows say, and the CUSUM, "
        f"which compares each new window with the estimate made before it, reads the "
        f"estimate's correction as a change. Later the equations pile up and no alarm "
        f"follows.")
else:
    alarm_text = "The tracker raised no alarm on this run."
display(Markdown(
    f"The record starts at rest: the first estimates (M, Fv) come at {first:.2f} s, once "
    f"the window equations of the first motions determine them; Fc and off, whose terms "
    f"are proportional while the velocity keeps its sign, follow at the first reversal, "
    f"{determined:.2f} s. From "
    f"{settled_M:.2f} s on, M stays within 5 % of the published value. At the end of the "
    f"stream ({out.t[-1]:.1f} s) the estimates are "
    + ", ".join(f"{p} {100 * final_error[p]:+.2f} %"
                for p in PARAMETERS)
    + " from the published values, and within "
    f"{100 * max(abs(v) for v in over_identify.values()):.2f} % of "
    f"`identify` on the same samples (the causal placement of the `sign` crossings). "
    + alarm_text))

# %% tags=["remove-cell"]
RESULTS["emps_first_estimate_s"] = float(first)
RESULTS["emps_M_within_5pct_from_s"] = float(settled_M)
RESULTS["emps_alarms"] = alarms.tolist()
RESULTS["emps_all_determined_s"] = float(determined)
RESULTS["emps_alarms_within_s_of_determined"] = (float(alarms[-1] - determined) if len(alarms)
                                            else 0.0)
RESULTS["emps_Fv_sigmas_at_first_alarm"] = (
    float(abs(Fv_last - Fv_then) / Fv_se_then) if len(alarms) else None)

# %% [markdown]
# ## The validation run, with its force pulses
#
# On the validation run force pulses are injected into the drive command, on top of
# the controller's output (`pulses_N`; as notebook 6 shows, the drive command `vir`
# already carries them, so the force on the mass is `F = gtau * vir` on both runs).
# For the tracker the pulses are more excitation. Top: the force and the pulses; below,
# the tracked estimates relative to the published values, with their ±2σ bands.

# %%
validation = runs["validation"]
out_v = tracked["validation"]
shown = validation.t <= out_v.t[-1]
fig, (ax_f, ax_e) = plt.subplots(2, 1, figsize=(11, 6.5), sharex=True, layout="constrained",
                                 gridspec_kw={"height_ratios": [1, 1.6]})
ax_f.plot(validation.t[shown], validation.F[shown], lw=0.6, label="force F = gtau*vir")
ax_f.set_ylabel("force (N)")
ax_p = ax_f.twinx()
ax_p.plot(validation.t[shown], validation.pulses_N[shown], color="C1", lw=0.8,
          label="pulses_N (right axis)")
ax_p.set_ylabel("pulses_N")
ax_f.legend(loc="upper left", fontsize="small")
ax_p.legend(loc="upper right", fontsize="small")
ax_f.set_title("EMPS, validation run: force with pulses, and the tracked estimates")
for k, p in enumerate(PARAMETERS):
    reference = EMPS_PUBLISHED[p]
    relative = 100 * (out_v.values[:, k] / reference - 1)
    spread = 100 * 2 * out_v.stderr[:, k] / abs(reference)
    ax_e.fill_between(out_v.t, relative - spread, relative + spread, color=f"C{k}", alpha=0.2,
                      lw=0)
    ax_e.plot(out_v.t, relative, color=f"C{k}", lw=1.0, label=f"{p} ± 2σ")
for j, when in enumerate(out_v.alarms):
    ax_e.axvline(when, color="C3", ls="--", lw=0.9, label="alarm" if j == 0 else None)
ax_e.axhline(0, color="k", lw=0.9)
ax_e.set_ylim(-15, 15)
ax_e.set_ylabel("estimate − published (%)")
ax_e.set_xlabel("t (s)")
ax_e.legend(loc="lower right", fontsize="small", ncol=5)
for ax in (ax_f, ax_e):
    ax.grid(alpha=0.3)

# %%
final_v = {p: out_v.values[-1, k] / EMPS_PUBLISHED[p] - 1 for k, p in enumerate(PARAMETERS)}
display(Markdown(
    f"At the end of the stream ({out_v.t[-1]:.1f} s) the validation run's estimates are "
    + ", ".join(f"{p} {100 * v:+.2f} %" for p, v in final_v.items())
    + " from the published values (which were identified on the estimation run); "
    + (f"the tracker raised {len(out_v.alarms)} alarm(s)." if len(out_v.alarms)
       else "the tracker raised no alarm: the pulses are not a change of the machine.")))

# %% tags=["remove-cell"]
RESULTS["validation_final_relative_error"] = {p: float(v) for p, v in final_v.items()}
RESULTS["validation_alarms"] = out_v.alarms.tolist()

# %% [markdown]
# ## A mass that changes
#
# A simulated mass with viscous and Coulomb friction and an offset, on a position loop
# `F = kp (r - q) - kv q'` that follows a multisine reference `r`: 14 s at 1 kHz, the
# position measured with a noise of 1 µm. At 7 s, mid-record, the mass grows by 25 % (a load
# is added), and the simulation continues from the same position and velocity.
# (`simulate_model` integrates from one reversal of the velocity to the next and holds
# the mass at rest while the force stays below the Coulomb friction.)

# %%
TRUE = {"M": 2.0, "Fv": 5.0, "Fc": 1.0, "off": -0.2}
KP, KV, RATE, DURATION, T_CHANGE, CHANGE = 4000.0, 120.0, 1000.0, 14.0, 7.0, 0.25
FRICTION_EQUATION = "M*q'' + Fv*q' + Fc*sign(q') + off = F"

rng = np.random.default_rng(777)
frequencies, phases = np.linspace(0.3, 3.0, 6), rng.uniform(0, 2 * np.pi, 6)
t = np.arange(int(round(DURATION * RATE)) + 1) / RATE
reference = 0.02 * np.sqrt(2 / 6) * np.sin(2 * np.pi * np.outer(t, frequencies) + phases).sum(1)
# the plant and the controller in one equation, driven by the reference r
loop = parse_equation(f"M*q'' + Fv*q' + Fc*sign(q') + off + {KV!r}*q' + {KP!r}*q = {KP!r}*r",
                      PARAMETERS)
cut = int(round(T_CHANGE * RATE))
before = simulate_model(loop, TRUE, t[:cut + 1], {"r": reference[:cut + 1]},
                        initial_state=[reference[0], 0.0], return_states=True)
after = simulate_model(loop, {**TRUE, "M": (1 + CHANGE) * TRUE["M"]}, t[cut:],
                       {"r": reference[cut:]}, initial_state=before[:, -1], return_states=True)
q, velocity = np.concatenate([before[:, :-1], after], axis=1)
loop_record = {"t": t, "q": q + 1e-6 * np.random.default_rng(0).standard_normal(len(t)),
               "F": KP * (reference - q) - KV * velocity}

HALF_LIFE = 1.0
loop_tracked = {}
for half_life in (HALF_LIFE, None):
    tracker = algid.Tracker(FRICTION_EQUATION, PARAMETERS, half_life=half_life, every=0.05)
    loop_tracked[half_life], elapsed = stream(tracker, loop_record)
    print(f"half_life={half_life}: {DURATION:.0f} s streamed in {elapsed:.1f} s, window "
          f"{tracker.window:.4f} s, alarms at {np.round(loop_tracked[half_life].alarms, 3)} s")

# %%
out_loop, kept = loop_tracked[HALF_LIFE], loop_tracked[None]
true_M = np.where(out_loop.t < T_CHANGE, TRUE["M"], (1 + CHANGE) * TRUE["M"])
fig, ax = plt.subplots(figsize=(10, 4), layout="constrained")
ax.plot([t[0], T_CHANGE, T_CHANGE, t[-1]], [TRUE["M"], TRUE["M"], (1 + CHANGE) * TRUE["M"],
        (1 + CHANGE) * TRUE["M"]], color="k", lw=1.0, label="true mass")
ax.fill_between(out_loop.t, out_loop["M"] - 2 * out_loop.stderr[:, 0],
                out_loop["M"] + 2 * out_loop.stderr[:, 0], color="C0", alpha=0.3, lw=0)
ax.plot(out_loop.t, out_loop["M"], color="C0", label=f"half-life {HALF_LIFE:g} s, ± 2σ")
ax.plot(kept.t, kept["M"], color="C2", ls=":", label="no forgetting")
for j, when in enumerate(out_loop.alarms):
    ax.axvline(when, color="C3", ls="--", lw=1.0, label="alarm" if j == 0 else None)
ax.set_xlabel("t (s)")
ax.set_ylabel("M (kg)")
ax.set_ylim(0.8 * TRUE["M"], 1.45 * TRUE["M"])
ax.set_title(f"Simulated friction loop: the mass grows by {100 * CHANGE:.0f} % at "
             f"{T_CHANGE:g} s")
ax.legend(loc="upper left", fontsize="small")
ax.grid(alpha=0.3)


# %%
def estimate_at(out, name, when):
    """The estimate of the last report at or before ``when``."""
    return out[name][np.searchsorted(out.t, when, side="right") - 1]


M_before = estimate_at(out_loop, "M", T_CHANGE) / TRUE["M"] - 1
M_after = estimate_at(out_loop, "M", T_CHANGE + 4) / ((1 + CHANGE) * TRUE["M"]) - 1
M_kept = kept["M"][-1] / ((1 + CHANGE) * TRUE["M"]) - 1
early = out_loop.alarms[out_loop.alarms < T_CHANGE]
late = out_loop.alarms[out_loop.alarms >= T_CHANGE]
display(Markdown(
    f"With a half-life of {HALF_LIFE:g} s, M is {100 * M_before:+.2f} % from the true mass "
    f"just before the change and {100 * M_after:+.2f} % from the new mass 4 s after it. "
    + (f"The first alarm comes {late[0] - T_CHANGE:.2f} s after the change"
       if len(late) else "No alarm follows the change")
    + (", and none before it. " if not len(early)
       else f"; {len(early)} alarm(s) came before it. ")
    + f"Without forgetting (dotted) the estimate is an average over the whole record: at "
    f"the end it is still {100 * M_kept:+.1f} % from the new mass, and its alarms keep "
    f"coming ({len(kept.alarms)} of them), since its estimate never catches up with the "
    f"machine."))

# %% tags=["remove-cell"]
RESULTS["loop_M_before_relative_error"] = float(M_before)
RESULTS["loop_M_4s_after_relative_error"] = float(M_after)
RESULTS["loop_M_no_forgetting_relative_error"] = float(M_kept)
RESULTS["loop_alarms"] = out_loop.alarms.tolist()
RESULTS["loop_t_change"] = T_CHANGE
RESULTS["loop_alarms_no_forgetting"] = kept.alarms.tolist()

# %% [markdown]
# ## The Silverbox tracked by a linear model
#
# The arrow part of the Silverbox (notebook 5) is filtered noise whose amplitude grows
# linearly over its 66 s (the quick workload streams its first 40 s). We track it with
# the *linear* model `V2'' + B V2' + K V2 = G V1 + d` and a half-life of 1 s. Its spring
# is hardening: notebook 5 fits `K V2 + K3 V2³`. A linear spring fitted to it over a stretch where
# the output has standard deviation σ sees the stiffness `K + 3 K3 σ²` (the
# least-squares slope of `K x + K3 x³` against `x`, for a Gaussian `x`), so the tracked
# `K` should rise with the amplitude along that curve. The cubic model's `K` and `K3`
# come from `identify` on the other part of the record, the multisine.

# %%
record_sb = silverbox()
fs = record_sb.fs
arrow = record_sb.segment("arrow")
if QUICK:
    arrow = {name: values[:int(40 * fs)] for name, values in arrow.items()}
cubic = algid.identify(record_sb.segment("estimation"),
                       "V2'' + B*V2' + K*V2 + K3*V2**3 = G*V1 + d", "B K K3 G d", rate=fs)
print(f"cubic model on the multisine part: K = {cubic.K:.0f} 1/s², K3 = {cubic.K3:.4g} 1/(V² s²)")
tracker = algid.Tracker("V2'' + B*V2' + K*V2 = G*V1 + d", "B K G d", rate=fs,
                        half_life=HALF_LIFE, every=0.05)
out_sb, elapsed = stream(tracker, arrow, chunk=610)
print(f"arrow part: {len(arrow['V2']) / fs:.1f} s streamed in {elapsed:.1f} s, window "
      f"{tracker.window * 1e3:.1f} ms, alarms at {np.round(out_sb.alarms, 2).tolist()} s")

# the output's variance over the same memory: its mean square with the same forgetting
# (the offset removed), at each report
centred = arrow["V2"] - np.mean(arrow["V2"])
decay = 2.0 ** (-1 / (HALF_LIFE * fs))
weights = decay ** np.arange(len(centred))[::-1]
ends = np.round(out_sb.t * fs).astype(int)
mean_square = np.array([np.sum(weights[-i - 1:] * centred[:i + 1] ** 2)
                        / np.sum(weights[-i - 1:]) for i in ends])
amplitude = np.sqrt(mean_square)
predicted_K = cubic.K + 3 * cubic.K3 * mean_square

# %%
k_K = out_sb.parameters.index("K")
K, K_se = out_sb["K"], out_sb.stderr[:, k_K]
fig, (ax_t, ax_a) = plt.subplots(1, 2, figsize=(12, 4.4), layout="constrained",
                                 gridspec_kw={"width_ratios": [1.5, 1]})
ax_t.fill_between(out_sb.t, (K - 2 * K_se) / 1e3, (K + 2 * K_se) / 1e3, color="C0", alpha=0.3,
                  lw=0)
ax_t.plot(out_sb.t, K / 1e3, color="C0", lw=1.0, label="tracked K (linear model) ± 2σ")
ax_t.plot(out_sb.t, predicted_K / 1e3, color="C1", lw=1.2, label="K + 3 K3 σ² (cubic model)")
for j, when in enumerate(out_sb.alarms):
    ax_t.axvline(when, color="C3", ls="--", lw=0.9, label="alarm" if j == 0 else None)
ax_t.set_xlabel("t (s) from row 100")
ax_t.set_ylabel("stiffness (10³ / s²)")
ax_s = ax_t.twinx()
ax_s.plot(out_sb.t, 1e3 * amplitude, color="0.5", lw=0.8, label="output σ (right axis)")
ax_s.set_ylabel("output standard deviation σ (mV)")
ax_t.legend(loc="upper left", fontsize="small")
ax_s.legend(loc="lower right", fontsize="small")
ax_t.set_title("Silverbox, arrow part: stiffness of a linear model over time", fontsize="medium")
after_start = out_sb.t >= 5.0  # once the memory of the forgetting is filled
ax_a.plot(1e3 * amplitude[after_start], K[after_start] / 1e3, ".", ms=3, color="C0",
          label="tracked K (after the first 5 s)")
order = np.argsort(amplitude[after_start])
ax_a.plot(1e3 * amplitude[after_start][order], predicted_K[after_start][order] / 1e3,
          color="C1", lw=1.5, label="K + 3 K3 σ²")
ax_a.set_xlabel("output standard deviation σ (mV)")
ax_a.set_ylabel("stiffness (10³ / s²)")
ax_a.set_title("the same against the amplitude", fontsize="medium")
ax_a.legend(loc="upper left", fontsize="small")
for ax in (ax_t, ax_a):
    ax.grid(alpha=0.3)

# %%
settled = after_start
low, high = np.percentile(amplitude[settled], [10, 90])
quiet, loud = settled & (amplitude <= low), settled & (amplitude >= high)
rise = np.mean(K[loud]) / np.mean(K[quiet]) - 1
mismatch = np.abs(K[settled] / predicted_K[settled] - 1)
display(Markdown(
    f"As the output's standard deviation grows from {1e3 * amplitude[settled].min():.0f} to "
    f"{1e3 * amplitude.max():.0f} mV, the stiffness of the linear model rises: by "
    f"{100 * rise:.1f} % from the quietest tenth of the reports after the first 5 s to the "
    f"loudest tenth, that is "
    f"the natural frequency from {np.sqrt(np.mean(K[quiet])) / (2 * np.pi):.1f} "
    f"to {np.sqrt(np.mean(K[loud])) / (2 * np.pi):.1f} Hz. The curve "
    f"`K + 3 K3 σ²` of the cubic model, identified on another part of the record, "
    f"predicts it: after the first 5 s the tracked K stays within "
    f"{100 * np.median(mismatch):.2f} % of it in half of the reports and within "
    f"{100 * np.percentile(mismatch, 95):.1f} % in 95 %. "
    f"A linear model does not describe this spring, and tracked over time it says so, "
    f"and how"
    + (f". The tracker raised {len(out_sb.alarms)} alarm(s) on the way (dashed, at "
       f"{', '.join(f'{a:.1f}' for a in out_sb.alarms)} s)." if len(out_sb.alarms)
       else ".")))

# %% tags=["remove-cell"]
RESULTS["silverbox_K_rise"] = float(rise)
RESULTS["silverbox_K_mismatch_median"] = float(np.median(mismatch))
RESULTS["silverbox_K_mismatch_p95"] = float(np.percentile(mismatch, 95))
RESULTS["silverbox_K_amplitude_correlation"] = float(
    np.corrcoef(K[settled], mean_square[settled])[0, 1])
