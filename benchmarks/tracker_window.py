"""The Tracker's automatic window against identify's on the same samples
(``PYTHONPATH=src:. python -m benchmarks.tracker_window --runs N``; writes
``benchmarks/tracker_window_results.json``).

The records of :mod:`benchmarks.window_rule_study`: 30 s at 1 kHz of a lightly damped
1 Hz mode driven by a multisine (0.1-5 Hz, 30 lines), white output noise at 30 dB SNR,
for the linear model ``y'' + B*y' + K*y = G*u + d`` and the Duffing model (``+ K3*y**3``).
Over ``N`` noise realisations:

- ``no_forgetting``: :class:`algid.Tracker` with ``half_life=None`` and its automatic
  window, fed the whole record (its last estimate uses every sample), against
  ``identify(refine=False)`` on the same record: per parameter the RMSE over the truth of
  the Tracker's last estimate divided by identify's (the target: at most
  :data:`TARGET_RATIO`), and the windows each chose.  The same ratio for the Tracker at
  identify's window (``window=`` given) separates the window from the estimator: without
  forgetting the two are the same, to round-off on the samples up to the last window end
  (identify's noise bound also reads the few after it).
- ``forgetting`` (``--half-life H``, default :data:`HALF_LIFE` s): the steady error of
  the Tracker with forgetting, measured as ``benchmarks.tracking`` measures its tracking
  error (per run and parameter the RMS relative error of the estimates reported every
  0.05 s, here on a record whose parameters do not change), from the time the stream is
  as long as the forgetting's memory (``2 H / ln 2``, the span of its effective windows)
  to the end, over the runs (RMS).  The automatic window is compared with each fixed
  window of :data:`FIXED_WINDOWS` that the half-life allows, on the reports both
  determine (a long window's are NaN until enough effective windows accumulate: the
  median time from which every report is determined is given per window); ``worst``
  is the largest ratio, against the best of them.

Options: ``--runs N`` (default 20), ``--models linear duffing``, ``--half-life H``,
``--out FILE`` (default ``benchmarks/tracker_window_results.json``).
"""

from __future__ import annotations

import argparse
import json
import math
import pathlib
import time
from collections import Counter

import numpy as np

import algid
from algid.identification._tracker import Tracker, TrackerSetupError
from benchmarks.window_rule_study import MODELS, SNR_DB, simulate

OUT = pathlib.Path(__file__).resolve().parent / "tracker_window_results.json"

#: Target: the Tracker's RMSE at most this many times identify's on the same samples.
TARGET_RATIO = 1.3

#: Half-life (s) of the forgetting case.
HALF_LIFE = 5.0

#: Fixed windows (s) the automatic one is compared with under forgetting (those the
#: half-life allows: at 5 s, up to 1.0 s for the linear model and 0.9 s for Duffing).
FIXED_WINDOWS = (0.15, 0.3, 0.6, 0.8, 0.9, 1.0, 1.2)

#: Reporting interval (s) of the forgetting case (as ``benchmarks.tracking``).
EVERY = 0.05


def _record(model, seed, t, u, y, sigma):
    rng = np.random.default_rng(seed)
    return {"t": t, "u": u, "y": y + sigma * rng.standard_normal(len(t))}


def _final(equation, names, record, **options):
    """The Tracker's last estimate on the whole record, and its window."""
    tracker = Tracker(equation, names, time="t", **options)
    out = tracker.update(record, last=True)
    return out.values[-1], tracker.window


def _reports(equation, names, record, half_life, window=None):
    """Report times (as multiples of :data:`EVERY`), estimates and the window of the
    Tracker with forgetting."""
    tracker = Tracker(equation, names, time="t", half_life=half_life, every=EVERY,
                      window=window)
    out = tracker.update(record)
    return np.floor(out.t / EVERY + 1e-9).astype(int), out.t, out.values, tracker.window


def _determined_from(t, values):
    """The time from which every report is determined (inf if the last is not)."""
    bad = ~np.isfinite(values).all(axis=1)
    if not bad.any():
        return float(t[0])
    last = int(np.flatnonzero(bad)[-1])
    return math.inf if last == len(t) - 1 else float(t[last + 1])


def _relative_rms(values, truth):
    """Per parameter the RMS relative error over the reports (``benchmarks.tracking``'s
    tracking error without a change)."""
    scale = np.where(truth == 0, 1.0, np.abs(truth))
    return np.sqrt(np.mean(((values - truth) / scale) ** 2, axis=0))


def _rmse(errors):
    return np.sqrt(np.mean(np.asarray(errors) ** 2, axis=0))


def study(name, runs, half_life=HALF_LIFE):
    """The figures of one model over ``runs`` noise realisations."""
    model = MODELS[name]
    equation, names = model["equation"], model["parameters"].split()
    truth = np.array([model["truth"][p] for p in names])
    t, u, y = simulate(model)
    sigma = float(np.std(y)) * 10 ** (-SNR_DB / 20)
    memory = 2.0 * half_life / math.log(2.0)
    skip = max(3.0, memory)
    err = {"identify": [], "tracker": [], "tracker_at_identify_window": []}
    windows = {"identify": Counter(), "tracker": Counter()}
    steady, pairs, determined = [], {}, {}
    steady_windows = Counter()
    seconds = Counter()
    for seed in range(runs):
        record = _record(model, seed, t, u, y, sigma)
        start = time.perf_counter()
        reference = algid.identify(record, equation, names, refine=False)
        seconds["identify"] += time.perf_counter() - start
        err["identify"].append(np.array([reference.values[p] for p in names]) - truth)
        windows["identify"][round(reference.window, 4)] += 1
        start = time.perf_counter()
        final, tracked = _final(equation, names, record)
        seconds["tracker"] += time.perf_counter() - start
        err["tracker"].append(final - truth)
        windows["tracker"][round(tracked, 4)] += 1
        final, _ = _final(equation, names, record, window=reference.window)
        err["tracker_at_identify_window"].append(final - truth)
        start = time.perf_counter()
        keys, times, auto, window = _reports(equation, names, record, half_life)
        seconds["tracker_forgetting"] += time.perf_counter() - start
        steady_windows[round(window, 4)] += 1
        determined.setdefault("auto", []).append(_determined_from(times, auto))
        use = (times >= skip) & np.isfinite(auto).all(axis=1)
        steady.append(_relative_rms(auto[use], truth) if use.any()
                      else np.full(len(names), np.nan))
        for fixed in FIXED_WINDOWS:
            try:
                other_keys, other_times, other, _ = _reports(equation, names, record,
                                                             half_life, window=fixed)
            except TrackerSetupError:   # a window the half-life does not allow
                continue
            determined.setdefault(str(fixed), []).append(_determined_from(other_times, other))
            # the reports both make, determined, from the memory's length on
            common, i, j = np.intersect1d(keys, other_keys, return_indices=True)
            ok = (times[i] >= skip) & np.isfinite(auto[i]).all(axis=1) \
                & np.isfinite(other[j]).all(axis=1)
            pair = (_relative_rms(auto[i[ok]], truth), _relative_rms(other[j[ok]], truth)) \
                if ok.any() else (np.full(len(names), np.nan),) * 2
            pairs.setdefault(str(fixed), []).append(pair)
        print(f"  {name} run {seed + 1}/{runs}: windows identify {reference.window:.4g} s, "
              f"tracker {tracked:.4g} s, forgetting {window:.4g} s", flush=True)
    rmse = {k: _rmse(v) for k, v in err.items()}
    compared = {}
    for fixed, rows in pairs.items():
        if len(rows) < runs:
            continue
        a = np.array(rows)   # runs x (auto, fixed) x parameters
        auto_rms, fixed_rms = _rmse(a[:, 0]), _rmse(a[:, 1])
        compared[fixed] = {"auto": dict(zip(names, auto_rms.tolist())),
                           "fixed": dict(zip(names, fixed_rms.tolist())),
                           "ratio_auto_to_fixed": dict(zip(names, (auto_rms
                                                                  / fixed_rms).tolist()))}
    worst = {p: max(c["ratio_auto_to_fixed"][p] for c in compared.values()) for p in names}
    return {
        "model": name, "equation": equation, "runs": runs, "sigma": sigma,
        "no_forgetting": {
            "rmse": {k: dict(zip(names, v.tolist())) for k, v in rmse.items()},
            "ratio_tracker_to_identify": dict(zip(
                names, (rmse["tracker"] / rmse["identify"]).tolist())),
            "ratio_tracker_at_identify_window_to_identify": dict(zip(
                names, (rmse["tracker_at_identify_window"] / rmse["identify"]).tolist())),
            "windows": {k: {str(w): c for w, c in sorted(v.items())}
                        for k, v in windows.items()},
        },
        "forgetting": {
            "half_life": half_life, "from_s": skip,
            "auto_windows": {str(w): c for w, c in sorted(steady_windows.items())},
            "auto_rms_relative_error": dict(zip(names, _rmse(steady).tolist())),
            "determined_from_s_median": {k: float(np.median(v))
                                         for k, v in determined.items()},
            "against_fixed": compared,
            "ratio_auto_to_best_fixed": worst,
        },
        "seconds": dict(seconds),
    }


def report(row):
    """Lines of the printed table of one model."""
    nf, fg = row["no_forgetting"], row["forgetting"]
    names = list(nf["ratio_tracker_to_identify"])
    lines = [f"{row['model']} ({row['runs']} runs): windows identify "
             f"{nf['windows']['identify']}, tracker {nf['windows']['tracker']}",
             f"{'param':<6} {'RMSE id':>10} {'RMSE tr':>10} {'tr/id':>6} {'tr@id/id':>8}"]
    for p in names:
        ratio = nf["ratio_tracker_to_identify"][p]
        lines.append(f"{p:<6} {nf['rmse']['identify'][p]:>10.3g} "
                     f"{nf['rmse']['tracker'][p]:>10.3g} {ratio:>6.2f} "
                     f"{nf['ratio_tracker_at_identify_window_to_identify'][p]:>8.3f}"
                     f"{'' if ratio <= TARGET_RATIO else '  *'}")
    columns = list(fg["against_fixed"])
    lines.append(f"half-life {fg['half_life']:g} s, reports from {fg['from_s']:.3g} s: "
                 f"automatic windows {fg['auto_windows']}; all reports determined from "
                 f"(median, s) " + ", ".join(f"{k}: {v:.3g}" for k, v in
                                             fg["determined_from_s_median"].items()))
    lines.append("RMS relative error of the automatic window over that of fixed windows "
                 "(s), on the reports both determine")
    lines.append(f"{'param':<6} {'auto':>9} " + " ".join(f"{c:>7}" for c in columns)
                 + f" {'worst':>6}")
    for p in names:
        lines.append(f"{p:<6} {fg['auto_rms_relative_error'][p]:>9.3g} "
                     + " ".join(f"{fg['against_fixed'][c]['ratio_auto_to_fixed'][p]:>7.2f}"
                                for c in columns)
                     + f" {fg['ratio_auto_to_best_fixed'][p]:>6.2f}")
    return lines


def main(argv=None):
    """Run the benchmark, print its table and write the JSON."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.tracker_window",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20)
    parser.add_argument("--models", nargs="*", default=list(MODELS), choices=list(MODELS))
    parser.add_argument("--half-life", type=float, default=HALF_LIFE)
    parser.add_argument("--out", default=str(OUT))
    args = parser.parse_args(argv)
    print(f"algid from {algid.__file__}; target: the Tracker's RMSE at most "
          f"{TARGET_RATIO:g} x identify's (* missed)", flush=True)
    results = []
    for name in args.models:
        row = study(name, args.runs, args.half_life)
        results.append(row)
        print("\n".join(report(row)), flush=True)
    payload = {"command": f"PYTHONPATH=src:. python -m benchmarks.tracker_window --runs "
                          f"{args.runs}" + (f" --half-life {args.half_life:g}"
                                            if args.half_life != HALF_LIFE else ""),
               "results": results}
    pathlib.Path(args.out).write_text(json.dumps(payload, indent=1, allow_nan=True) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
