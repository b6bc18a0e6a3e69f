"""Markdown tables and target checks from the results of a benchmark run."""

from __future__ import annotations

import math

__all__ = ["targets", "markdown"]

#: Targets of the benchmark: name -> (description, limit).
TARGETS = {
    "convergence": ("algid default, noise-free: both within 0.1 % from (s)", 0.005),
    "efficiency": ("refined estimate: RMSE/CRLB (worst of B, K, inputs, horizons)", 1.1),
    "long_stream": ("long stream with re-anchoring: max relative error after convergence",
                    1e-6),
    "tracking": ("parameter change: time until within 0.1 % (s)", 0.1),
    "c_speed": ("C estimator (-O2) on one chunk: its time / the numba loop's", 1.0),
    "numpy_speed": ("NumPy backend, default (with the numerical error): its time / the "
                    "naive NumPy estimator's", 1.0 / 1.5),
    "error_speed": ("default estimate (with the numerical error), NumPy and numba, 2e6 and "
                    "1e7 samples: its time / the naive estimator's (highest of 3 runs)", 0.25),
    "error_cost": ("the numerical error: default time / numerical_error=False time", 1.25),
    "error_stream": ("stream in chunks of 1000 / batch, with the numerical error", 1.5),
}


def _num(value, fmt=".3g"):
    if value is None:
        return "—"
    if isinstance(value, float) and math.isnan(value):
        return "nan"
    if isinstance(value, float) and math.isinf(value):
        return "inf"
    return format(value, fmt)


def _time(value):
    if value is None:
        return "—"
    if isinstance(value, float) and math.isnan(value):
        return "not reached"
    return f"{value:.3f}"


def targets(results):
    """Check the targets against the results.

    Parameters
    ----------
    results : dict
        The results of :func:`benchmarks.run.run`.

    Returns
    -------
    list of dict
        ``name, description, limit, measured, met`` (``met`` is None when the section
        did not run).
    """
    out = []

    def add(name, measured, detail=""):
        description, limit = TARGETS[name]
        met = None if measured is None else bool(measured <= limit)
        out.append({"name": name, "description": description, "limit": limit,
                    "measured": measured, "met": met, "detail": detail})

    acc = results.get("accuracy")
    if acc:
        conv = [r["convergence_time"] for r in acc["rows"]
                if r["method"] == "algid" and r["experiment"] in ("step", "sine")]
        worst = math.inf if any(math.isnan(c) for c in conv) else max(conv)
        add("convergence", worst, "step and sine from rest, 1 kHz")
    eff = results.get("efficiency")
    if eff:
        ratios = [max(r["ratio_B"], r["ratio_K"]) for r in eff["rows"]
                  if r["method"] == "refined"]
        add("efficiency", max(ratios) if ratios else None,
            f"{eff['n_runs']} runs per input, noise {eff['noise_std']:g}")
    ls = results.get("long_stream")
    if ls and "rows" in ls:
        row = next(r for r in ls["rows"] if r["method"] == "online_reset")
        exact = next((r for r in ls["rows"] if r["method"] == "online_reset_1024"), None)
        detail = f"{ls['n_samples']} samples at 1 kHz, {row['label']}"
        if exact is not None:
            detail += (f"; {max(exact['max_rel_error'].values()):.2g} at 1024 Hz, where the "
                       f"sample times are exact")
        add("long_stream", max(row["max_rel_error"].values()), detail)
    tr = results.get("tracking")
    if tr and "rows" in tr:
        times = [r["tracking_time"] for r in tr["rows"]
                 if r["method"] == "online_reset" and not r.get("low_excitation")]
        worst = _worst(times)
        add("tracking", math.inf if math.isnan(worst) else worst,
            "worst of step/sine, the three changes and the change instants, except a "
            "change of B alone on a settled step (not excited)")
    perf = results.get("performance")
    if perf and "batch" in perf:
        ratios = {r["method"]: r["throughput_ratio"] for r in perf["batch"]
                  if "throughput_ratio" in r}
        if "algid" in ratios:
            detail = f"{ratios['algid']:.2f}× the naive estimator's throughput"
            if "algid_alone" in ratios:
                detail += f"; without the numerical error {ratios['algid_alone']:.2f}×"
            add("numpy_speed", 1.0 / ratios["algid"], detail)
    cs = results.get("c_speed")
    if cs and cs.get("c_over_numba", {}).get("O2"):
        from benchmarks.c_speed import target
        measured, detail = target(cs)
        add("c_speed", 1.0 / measured, detail)
    ec = results.get("error_cost")
    if ec and ec.get("sizes"):
        from benchmarks.error_cost import targets as error_targets
        for name, (measured, detail) in error_targets(ec).items():
            add(name, measured, detail)
    return out


def _worst(values):
    """Largest value, NaN or None (never reached; JSON has no NaN) counting as the largest."""
    values = [math.nan if v is None else v for v in values]
    return float("nan") if any(math.isnan(v) for v in values) else max(values)


def _table(head, rows):
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def markdown(results):
    """All the tables of a run, as Markdown.

    Parameters
    ----------
    results : dict

    Returns
    -------
    str
    """
    parts = []
    acc = results.get("accuracy")
    if acc:
        exps = list(dict.fromkeys(r["experiment"] for r in acc["rows"]))
        methods = list(dict.fromkeys(r["method"] for r in acc["rows"]))
        by = {(r["method"], r["experiment"]): r for r in acc["rows"]}
        rows = []
        for m in methods:
            first = by[m, exps[0]]
            cells = [first["label"]]
            for e in exps:
                r = by[m, e]
                cells.append(f"{_time(r['convergence_time'])} / "
                             f"{_num(max(r['error_B'], r['error_K']), '.1e')}")
            rows.append(cells)
        parts.append(f"### 1. Noise-free accuracy ({acc['duration']:g} s at "
                     f"{acc['rate']:g} Hz): time [s] from which B and K stay within 0.1 % / "
                     f"final relative error (worst of B, K)\n\n"
                     f"`_ic`: initial state (x0, v0) = {tuple(acc['initial_state_ic'])}, "
                     f"unknown to the estimators; '—': batch method.\n\n"
                     + _table(["method"] + exps, rows))
        pred = acc["svf_predicted_bias"]
        meas = {r["experiment"]: r for r in acc["rows"] if r["method"] == "svf_ls"}
        rows = [[e, f"{meas[e]['final_B'] - 2.0:.3e}", f"{pred[e]['B']:.3e}",
                 f"{meas[e]['final_K'] - 3.0:.3e}", f"{pred[e]['K']:.3e}"] for e in exps]
        parts.append("SVF least-squares bias, measured vs. predicted from the filter's "
                     "initial-condition transient:\n\n"
                     + _table(["experiment", "B measured", "B predicted", "K measured",
                               "K predicted"], rows))
    eff = results.get("efficiency")
    if eff:
        cols = [(i, h) for i in ("step", "sine") for h in eff["horizons"]]
        methods = list(dict.fromkeys(r["method"] for r in eff["rows"]))
        by = {(r["method"], r["input"], r["horizon"]): r for r in eff["rows"]}
        rows = []
        for m in methods:
            any_row = next(r for r in eff["rows"] if r["method"] == m)
            cells = [any_row["label"]]
            for i, h in cols:
                r = by.get((m, i, h))
                cells.append("—" if r is None else
                             f"{_num(r['ratio_B'], '.2f')} / {_num(r['ratio_K'], '.2f')}")
            rows.append(cells)
        head = ["method"] + [f"{i} T={h:g}" for i, h in cols]
        check = ", ".join(f"{k} {v:.1e}" for k, v in eff.get("same_data_check", {}).items())
        parts.append(f"### 2. RMSE / CRLB (B / K), noise σ = {eff['noise_std']:g} on x, "
                     f"{eff['n_runs']} seeded runs per input (study: {eff['study']})\n\n"
                     f"Baselines run on the study's records (its algebraic RMSE recomputed "
                     f"from them differs by: {check or 'n/a'}).  A ratio below 1 is "
                     f"possible for a biased estimator.\n\n"
                     + _table(head, rows))
        crlb_rows = [[f"{i} T={h:g}", f"{by[methods[-1], i, h]['crlb_B']:.3g}",
                      f"{by[methods[-1], i, h]['crlb_K']:.3g}"] for i, h in cols]
        parts.append("CRLB (standard deviation) per experiment:\n\n"
                     + _table(["experiment", "CRLB B", "CRLB K"], crlb_rows))
    perf = results.get("performance")
    if perf:
        rows = []
        for r in perf["batch"]:
            if "not_available" in r:
                missing = f"not available: {r['not_available']}"
                rows.append([r["label"], "—", "—", "—", "—", missing])
                continue
            rows.append([r["label"], f"{r['n_samples']:.0e}", f"{r['throughput']:.3g}",
                         f"{r['throughput_ratio']:.3g}", f"{r['memory_ratio']:.3g}", ""])
        parts.append(f"### 3. Batch throughput and peak memory (sine record; best of "
                     f"{perf['repeats']}; ratio 1.0 = naive NumPy trapezoid)\n\n"
                     + _table(["method", "samples", "samples/s", "throughput ratio",
                               "peak memory / input bytes", "note"], rows))
        rows = []
        for r in perf["streaming"]:
            if "not_available" in r:
                rows.append([r["label"], "—", "—", "—", f"not available: {r['not_available']}"])
                continue
            rows.append([r["label"], r["chunk"], f"{r['n_samples']:.0e}",
                         f"{r['cost_per_sample'] * 1e6:.3g}", f"{r['cost_ratio']:.3g}"])
        parts.append("Streaming cost per sample (ratio: to the naive NumPy batch cost per "
                     "sample):\n\n"
                     + _table(["method", "chunk", "samples", "µs / sample", "cost ratio"],
                              rows))
    ls = results.get("long_stream")
    if ls:
        if "rows" not in ls:
            parts.append(f"### 4. Long stream: not available ({ls['not_available']})")
        else:
            def mb(value):
                return _num(None if value is None else value / 1e6, ".3g")

            rows = [[r["label"], f"{r['settle_time']:g}",
                     _num(max(r["max_rel_error"].values()), ".2e"), r["n_undefined"],
                     mb(r["peak_bytes_first_tenth"]), mb(r["peak_bytes_last_tenth"]),
                     mb(r["rss_growth_bytes"]),
                     _num(r["max_state_magnitude"], ".3g"), f"{r['elapsed']:.3g}"]
                    for r in ls["rows"]]
            parts.append(f"### 4. Long stream: {ls['n_samples']:.0e} samples of the sine "
                         f"experiment, noise-free, chunks of {ls['chunk']}\n\n"
                         + _table(["estimator", "errors from t [s]", "max rel. error",
                                   "NaN", "traced peak MB, first 10 %",
                                   "traced peak MB, last 10 %", "RSS growth MB",
                                   "max abs. state", "time [s]"], rows))
    tr = results.get("tracking")
    if tr:
        if "rows" not in tr:
            parts.append(f"### 5. Tracking: not available ({tr['not_available']})")
        else:
            cols = list(dict.fromkeys((r["input"], r["change"]) for r in tr["rows"]))
            methods = list(dict.fromkeys(r["method"] for r in tr["rows"]))
            rows = []
            for m in methods:
                label = next(r["label"] for r in tr["rows"] if r["method"] == m)
                cells = [label]
                for i, c in cols:
                    times = [r["tracking_time"] for r in tr["rows"]
                             if (r["method"], r["input"], r["change"]) == (m, i, c)]
                    cells.append(_time(_worst(times)))
                rows.append(cells)
            offsets = ", ".join(f"{o * 1e3:g}" for o in tr["offsets"])
            parts.append(f"### 5. Tracking a change of the parameters ({tr['duration']:g} s "
                         f"stream, noise-free, change {offsets} ms after t = "
                         f"{tr['duration'] / 2:g} s): time [s] after the change until both "
                         f"within 0.1 % (worst over the change instants)\n\n"
                         f"'step, B 2->1': a change of B alone while the step response has "
                         f"settled is barely excited (at rest x does not depend on B); it "
                         f"is left out of the target.\n\n"
                         + _table(["estimator"] + [f"{i}, {c}" for i, c in cols], rows))
    if results.get("c_speed"):
        from benchmarks.c_speed import markdown as c_speed_markdown
        parts.append(c_speed_markdown(results["c_speed"]))
    if results.get("error_cost"):
        from benchmarks.error_cost import markdown as error_cost_markdown
        parts.append(error_cost_markdown(results["error_cost"]))
    tg = results.get("targets")
    if tg:
        rows = [[t["description"], f"≤ {t['limit']:.3g}", _num(t["measured"], ".3g"),
                 {True: "met", False: "missed", None: "not run"}[t["met"]], t["detail"]]
                for t in tg]
        parts.append("### Targets\n\n" + _table(["target", "limit", "measured", "", "detail"],
                                                rows))
    return "\n\n".join(parts) + "\n"
