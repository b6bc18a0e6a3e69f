"""Draw the tracking figure of the README.

Left: the EMPS estimation run streamed through ``algid.Tracker`` in chunks of one second
(window 0.03 s, no forgetting), the mass estimate with its ±2σ band against the
published value and its ±2σ band.  Right: the simulated friction loop of
``benchmarks.change_records.friction_change`` (the mass grows by 25 % at 10 s), tracked
with a half-life of 1 s, with the alarm.

Run from the repository root (needs the ``plot`` extra; about a minute)::

    python docs/make_tracking_figure.py          # writes docs/_static/algid_tracking.png
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import algid  # noqa: E402
from algid import datasets  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "_static" / "algid_tracking.png"


def stream(tracker, record, chunk=1000):
    """Times, estimates, standard errors and alarms of ``record`` streamed in chunks."""
    n = len(record["t"])
    reports = [tracker.update({k: v[i:i + chunk] for k, v in record.items()})
               for i in range(0, n, chunk)]
    return (np.concatenate([r.t for r in reports]),
            np.concatenate([r.values for r in reports]),
            np.concatenate([r.stderr for r in reports]),
            np.concatenate([r.alarms for r in reports]))


def draw(out: Path):
    """Draw both panels into ``out`` and return the numbers they show."""
    sys.path.insert(0, str(ROOT))  # the benchmarks' synthetic records
    from benchmarks.change_records import friction_change

    rec = datasets.emps()
    parameters = list(datasets.EMPS_PUBLISHED)
    t, values, stderr, _ = stream(
        algid.Tracker(datasets.EMPS_EQUATION, parameters, window=0.03),
        {"t": rec.t, "qm": rec.qm, "F": rec.F})
    M, M_se = values[:, 0], stderr[:, 0]
    published = datasets.EMPS_PUBLISHED["M"]
    band = 2 * datasets.EMPS_PUBLISHED_RELATIVE_STD["M"] * published

    t_change = 10.0
    record, before, after = friction_change(t_change=t_change)
    t_loop, values_loop, stderr_loop, alarms = stream(
        algid.Tracker("M*q'' + Fv*q' + Fc*sign(q') + off = F", "M Fv Fc off", half_life=1.0,
                      every=0.05), record)

    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 3.4), layout="constrained")
    left.axhspan(published - band, published + band, color="0.85", label="published ± 2σ")
    left.axhline(published, color="k", lw=0.9)
    left.fill_between(t, M - 2 * M_se, M + 2 * M_se, color="C0", alpha=0.3, lw=0)
    left.plot(t, M, color="C0", lw=1, label="tracked ± 2σ")
    left.set_ylim(published - 2.5, published + 2.5)
    left.set_title("EMPS streamed: mass M (kg), no forgetting", fontsize=10)
    left.legend(fontsize=8, loc="lower right")

    right.plot([0, t_change, t_change, record["t"][-1]],
               [before["M"], before["M"], after["M"], after["M"]], color="k", lw=1,
               label="true mass")
    right.fill_between(t_loop, values_loop[:, 0] - 2 * stderr_loop[:, 0],
                       values_loop[:, 0] + 2 * stderr_loop[:, 0], color="C0", alpha=0.3, lw=0)
    right.plot(t_loop, values_loop[:, 0], color="C0", lw=1, label="tracked ± 2σ")
    for k, when in enumerate(alarms):
        right.axvline(when, color="C3", ls="--", lw=1, label="alarm" if k == 0 else None)
    right.set_ylim(0.9 * before["M"], 1.2 * after["M"])
    right.set_title(f"Mass +25 % at {t_change:g} s, half-life 1 s: M (kg)", fontsize=10)
    right.legend(fontsize=8, loc="upper left", ncol=3)
    for ax in (left, right):
        ax.set_xlabel("t [s]")
        ax.grid(alpha=0.3)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return {"M_end": float(M[-1]), "alarms": alarms.tolist()}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=OUT, help=f"PNG to write (default {OUT})")
    args = parser.parse_args(argv)
    numbers = draw(args.out)
    print(f"wrote {args.out}: EMPS final M {numbers['M_end']:.5g}; alarms on the changing "
          f"mass at {', '.join(f'{a:.3f}' for a in numbers['alarms'])} s")


if __name__ == "__main__":
    main()
