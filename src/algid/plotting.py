"""Figure helpers: experiments (input and response) and estimates over time.

The figures are built as :class:`matplotlib.figure.Figure` objects without pyplot, so
they need no display, touch no global pyplot state and can be drawn from any thread;
:func:`save_figure` writes them with the Agg renderer.  This module needs matplotlib
(``pip install algid[plot]``).
"""

from __future__ import annotations

import pathlib

import numpy as np
from matplotlib.figure import Figure

__all__ = ["plot_input_response", "plot_responses", "plot_estimates", "estimate_ylim",
           "plot_fleet", "save_figure"]

#: Colours of the parameters (matplotlib's default cycle, fixed so figures agree).
PARAMETER_COLORS = {"B": "C0", "K": "C3", "c": "C0", "k": "C3", "m": "C2"}


def plot_input_response(t, f, x, *, title=None, force_label="Force (N)",
                        position_label="Position (m)", figsize=(7.0, 5.0)):
    """Input force and response in two stacked panels, (a) and (b).

    Parameters
    ----------
    t, f, x : array_like
        Time [s], force, position.
    title : str, optional
        Figure title.
    force_label, position_label : str, optional
        Y-axis labels.
    figsize : (float, float), optional

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> from algid.plotting import plot_input_response
    >>> from algid.simulation import simulate
    >>> sim = simulate("step", duration=1.0, rate=100.0)
    >>> fig = plot_input_response(sim.t, sim.f, sim.x, title="Step response")
    >>> [ax.get_title(loc="left") for ax in fig.axes]
    ['(a) input', '(b) response']
    """
    fig = Figure(figsize=figsize, layout="constrained")
    ax_f, ax_x = fig.subplots(2, 1, sharex=True)
    ax_f.plot(t, f, color="C0")
    ax_f.set_ylabel(force_label)
    ax_f.set_title("(a) input", loc="left", fontsize="medium")
    ax_x.plot(t, x, color="C1")
    ax_x.set_ylabel(position_label)
    ax_x.set_xlabel("Time (s)")
    ax_x.set_title("(b) response", loc="left", fontsize="medium")
    for ax in (ax_f, ax_x):
        ax.grid(True, alpha=0.3)
        ax.set_xlim(t[0], t[-1])
    _pad_constant(ax_f, f)
    if title:
        fig.suptitle(title)
    return fig


def _pad_constant(ax, y):
    """Give a constant signal a visible y-range around its value."""
    y = np.asarray(y, dtype=float)
    lo, hi = float(np.min(y)), float(np.max(y))
    if hi - lo < 1e-12 * max(1.0, abs(hi)):
        pad = max(abs(hi), 1.0) * 0.5
        ax.set_ylim(min(0.0, lo - pad), hi + pad)


def plot_responses(panels, *, title=None, position_label="Position (m)",
                   figsize=(7.0, 5.0)):
    """Measured responses, one panel each, with the noise-free response overlaid.

    Parameters
    ----------
    panels : sequence of (t, x_measured, x_true or None, label)
        One panel per entry.
    title : str, optional
    position_label : str, optional
    figsize : (float, float), optional

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> from algid.plotting import plot_responses
    >>> from algid.simulation import simulate
    >>> runs = [simulate("step", duration=1.0, noise_std=std, seed=0) for std in (0.001, 0.01)]
    >>> fig = plot_responses([(r.t, r.x, r.x_true, f"noise {r.noise_std} m") for r in runs])
    >>> [ax.get_title(loc="left") for ax in fig.axes]
    ['noise 0.001 m', 'noise 0.01 m']
    """
    fig = Figure(figsize=figsize, layout="constrained")
    axes = np.atleast_1d(fig.subplots(len(panels), 1, sharex=True))
    for ax, (t, x, x_true, label) in zip(axes, panels):
        ax.plot(t, x, color="C1", lw=0.6, label="measured")
        if x_true is not None:
            ax.plot(t, x_true, color="k", lw=1.0, ls="--", label="noise-free")
        ax.set_ylabel(position_label)
        ax.set_title(label, loc="left", fontsize="medium")
        ax.grid(True, alpha=0.3)
        ax.set_xlim(t[0], t[-1])
        ax.legend(loc="best", fontsize="small")
    axes[-1].set_xlabel("Time (s)")
    if title:
        fig.suptitle(title)
    return fig


#: The default view of the estimates is set by the later part of the span where they are
#: defined: from this fraction of it to its end ("after they settle").
SETTLED_FROM = 0.5
#: Percentiles of the settled estimates that bound the default view: robust to the
#: isolated spikes where the estimator's determinant passes near zero.
SETTLED_PERCENTILES = (5.0, 95.0)


def estimate_ylim(t, estimates, *, true_values=None, t_max=None):
    """Y-limits that show estimates after they settle, the start-up clipped.

    An algebraic estimate starts ill-conditioned (values of 1e6 in the first
    milliseconds are common) and can spike where its determinant passes near zero; left
    to autoscaling, either sets the scale and the settled values are invisible.  The
    limits here are the 5th to 95th percentiles of each estimate over the later half of
    the span where it is defined (up to ``t_max``), widened to include the final
    estimates and the true values, with a margin of half the range on each side (the
    range being at least a tenth of the largest magnitude in it, so that a converged
    estimate is not a flat line at the edge).  What lies outside (the start-up, the
    spikes) is clipped.

    Parameters
    ----------
    t : array_like
        Sample times.
    estimates : mapping of str to array_like
        The estimates to show, sampled at ``t``.
    true_values : mapping of str to float, optional
        Reference values that must be inside the view.
    t_max : float, optional
        Right end of the view (default: the end of the record).

    Returns
    -------
    (float, float) or None
        The limits; None if no estimate has a finite sample in the view.

    Examples
    --------
    >>> t = np.linspace(0.0, 1.0, 101)
    >>> start_up = np.where(t < 0.02, 1e6, 2.0)
    >>> estimate_ylim(t, {"B": start_up}, true_values={"B": 2.0})
    (1.8, 2.2)
    """
    t = np.asarray(t, dtype=float)
    in_view = t <= (t[-1] if t_max is None else t_max)
    values = [float(v) for v in (true_values or {}).values() if np.isfinite(v)]
    for samples in estimates.values():
        samples = np.asarray(samples, dtype=float)
        defined = np.flatnonzero(np.isfinite(samples) & in_view)
        if defined.size == 0:
            continue
        first, last = t[defined[0]], t[defined[-1]]
        settled = samples[defined][t[defined] >= first + SETTLED_FROM * (last - first)]
        values.extend(np.percentile(settled, SETTLED_PERCENTILES).tolist())
        values.append(float(samples[defined[-1]]))
    if not values:
        return None
    lo, hi = min(values), max(values)
    span = max(hi - lo, 0.1 * max(abs(lo), abs(hi))) or 1.0
    middle = 0.5 * (lo + hi)
    return (middle - span, middle + span)


def plot_estimates(result, *, true_values=None, parameters=None, t_max=None, ylim=None,
                   reference=None, label="estimate", reference_label="reference",
                   marks=(), spans=(), title=None, ax=None, figsize=(7.5, 5.0)):
    """Estimates over time with the true values as dashed lines.

    Parameters
    ----------
    result : algid.estimation._result.EstimationResult
        The estimates to show.
    true_values : dict, optional
        Parameter -> true value, drawn as dashed horizontal lines.
    parameters : sequence of str, optional
        Which estimates to draw (default: those in ``true_values``, else all).
    t_max : float, optional
        Right end of the time axis (default: end of the record).
    ylim : (float, float), optional
        View limits of the estimates; default: :func:`estimate_ylim`, the range of the
        settled estimates and the true values (the ill-conditioned start-up, which
        would otherwise set the scale, is clipped).
    reference : algid.estimation._result.EstimationResult, optional
        A second estimation drawn thin and dotted for comparison.
    label, reference_label : str, optional
        Legend text of the two estimations.
    marks : sequence of (float, str), optional
        Vertical lines at the given times, with their legend text.
    spans : sequence of (float, float, str), optional
        Shaded time intervals, with their legend text.
    title : str, optional
    ax : matplotlib.axes.Axes, optional
        Draw into this axes instead of a new figure.
    figsize : (float, float), optional

    Returns
    -------
    matplotlib.figure.Figure
        The figure of the axes drawn into.

    Examples
    --------
    >>> from algid.estimation import estimate
    >>> from algid.plotting import plot_estimates
    >>> from algid.simulation import simulate
    >>> result = estimate(*simulate("step", duration=1.0), engine="numpy")
    >>> fig = plot_estimates(result, true_values={"B": 2.0, "K": 3.0})
    >>> [line.get_label() for line in fig.axes[0].lines]
    ['B estimate', 'true B = 2', 'K estimate', 'true K = 3']
    """
    own = ax is None
    if own:
        fig = Figure(figsize=figsize, layout="constrained")
        ax = fig.subplots()
    else:
        fig = ax.figure
    names = list(parameters or (true_values or result.estimates))
    t_end = result.t[-1] if t_max is None else t_max
    for name in names:
        color = PARAMETER_COLORS.get(name)
        if reference is not None and name in reference.estimates:
            ax.plot(reference.t, reference.estimates[name], color=color, lw=0.9, ls=":",
                    alpha=0.8, label=f"{name} {reference_label}")
        ax.plot(result.t, result.estimates[name], color=color, lw=1.4,
                label=f"{name} {label}")
        if true_values and name in true_values:
            ax.axhline(true_values[name], color="k", ls="--", lw=0.9, zorder=3,
                       label=f"true {name} = {true_values[name]:g}")
    styles = ("-.", (0, (1, 1)), "--")
    for i, (when, text) in enumerate(marks):
        ax.axvline(when, color="0.35", lw=0.9, ls=styles[i % len(styles)], label=text)
    for start, stop, text in spans:
        ax.axvspan(start, stop, color="0.5", alpha=0.12, lw=0, label=text)
    ax.set_xlim(result.t[0], t_end)
    if ylim is None:
        ylim = estimate_ylim(result.t, {name: result.estimates[name] for name in names},
                             true_values=true_values, t_max=t_end)
    if ylim is not None:
        ax.set_ylim(*ylim)
    ax.set_xlabel("Time (s)")
    ax.set_ylabel(", ".join(names))
    ax.grid(True, alpha=0.3)
    if own:  # below the axes: the early estimate fills the top of the view
        fig.legend(loc="outside lower center", fontsize="small", ncol=3, frameon=False)
    else:
        ax.legend(loc="upper right", fontsize="small", ncol=2)
    if title:
        ax.set_title(title)
    return fig


def plot_fleet(table, parameters=None, *, true_values=None, threshold=None,
               figsize=None):
    """The parameters of a fleet, record by record, its outliers flagged.

    One panel per parameter: every identified record's estimate with its ±2σ error
    bar, in the order of the table, the fleet's median and its spread (the band of
    :func:`algid.identification.fleet_outliers`' threshold), the outliers in red and
    named, and the count of refused records in the title.

    Parameters
    ----------
    table : pandas.DataFrame
        The table of :func:`algid.identify_many`.
    parameters : sequence of str, optional
        The parameters to draw (default: all of the table's).
    true_values : dict, optional
        Parameter -> a value drawn as a dashed line (a nominal value, say).
    threshold : float, optional
        The outlier threshold (default that of :func:`~algid.identification.fleet_outliers`).
    figsize : (float, float), optional
        Default: 7.5 wide, 2.4 per panel.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> import pandas as pd
    >>> from algid.plotting import plot_fleet
    >>> table = pd.DataFrame({"K": [3.0, 3.1, 2.9, 6.0], "stderr_K": [0.05] * 4,
    ...                       "error": [None] * 4}, index=["m1", "m2", "m3", "m4"])
    >>> fig = plot_fleet(table)
    >>> fig.axes[0].get_title()
    'K: 1 outlier (m4)'
    """
    from algid.identification import fleet_outliers

    options = {} if threshold is None else {"threshold": threshold}
    flags = fleet_outliers(table, parameters, **options)
    names = list(flags.columns)
    limit = options.get("threshold")
    if limit is None:
        from algid.identification._fleet import OUTLIER_THRESHOLD as limit
    refused = int(table["error"].notna().sum()) if "error" in table else 0
    fig = Figure(figsize=figsize or (7.5, 0.6 + 2.4 * len(names)), layout="constrained")
    axes = fig.subplots(len(names), 1, sharex=True, squeeze=False)[:, 0]
    order = np.arange(len(table))
    for ax, name in zip(axes, names):
        x = table[name].astype(float).to_numpy()
        e = table[f"stderr_{name}"].astype(float).to_numpy()
        out = flags[name].to_numpy()
        known = np.isfinite(x)
        median = float(np.median(x[known])) if known.any() else np.nan
        spread = 1.4826 * float(np.median(np.abs(x[known] - median))) if known.any() else 0
        ax.axhspan(median - limit * spread, median + limit * spread, color="0.9",
                   label=f"median ± {limit:g} spreads")
        ax.axhline(median, color="0.4", lw=1)
        keep = known & ~out
        ax.errorbar(order[keep], x[keep], 2 * e[keep], fmt="o", ms=2.5, lw=0.8,
                    color=PARAMETER_COLORS.get(name, "C0"), label="record ± 2σ")
        ax.errorbar(order[out], x[out], 2 * e[out], fmt="o", ms=4, lw=1, color="red",
                    label="outlier")
        for i in np.flatnonzero(out):
            ax.annotate(str(table.index[i]), (order[i], x[i]), textcoords="offset points",
                        xytext=(4, 4), fontsize="x-small", color="red")
        if true_values and name in true_values:
            ax.axhline(true_values[name], color="k", ls="--", lw=1, label="nominal")
        ax.set_ylabel(name)
        ax.grid(True, alpha=0.3)
        count = int(out.sum())
        named = ", ".join(str(table.index[i]) for i in np.flatnonzero(out)[:5])
        ax.set_title(f"{name}: {count} outlier{'' if count == 1 else 's'}"
                     + (f" ({named}{', ...' if count > 5 else ''})" if count else ""))
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", fontsize="small", ncol=4,
               frameon=False)   # below the panels: no point hidden
    axes[-1].set_xlabel(f"record (in the table's order; {refused} refused, not drawn)")
    return fig


def save_figure(fig, path, *, dpi=120):
    """Write a figure to a file (format from the suffix, e.g. PNG).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    path : str or path-like
    dpi : float, optional

    Returns
    -------
    pathlib.Path
        The path written.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> from matplotlib.figure import Figure
    >>> from algid.plotting import save_figure
    >>> fig = Figure()
    >>> _ = fig.subplots().plot([0, 1], [0, 1])
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = save_figure(fig, pathlib.Path(folder, "line.png"), dpi=50)
    ...     print(path.name, path.read_bytes()[1:4])
    line.png b'PNG'
    """
    path = pathlib.Path(path)
    fig.savefig(path, dpi=dpi)
    return path
