"""Draw the figure of the user guide's page "How good is my estimate".

Left: RMSE over the Cramér–Rao bound per parameter, the algebraic and the refined
estimate, white and AR(1) output noise (``benchmarks/refinement_results.json``, written
by ``python -m benchmarks.refinement_study --runs 100 --json
benchmarks/refinement_results.json``).  Right: the scores of the residual test on one
record each of the right model, a model without its offset and the output 3 samples
late (the records of ``benchmarks.residual_adequacy``), against the limit.

Run from the repository root (needs the ``plot`` extra; about half a minute)::

    python docs/make_refinement_figure.py      # writes docs/_static/algid_refinement.png
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import algid  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from benchmarks import residual_adequacy  # noqa: E402

OUT = ROOT / "docs" / "_static" / "algid_refinement.png"
PARAMETERS = ("B", "K", "G", "d")


def main():
    study = json.loads((ROOT / "benchmarks" / "refinement_results.json").read_text())
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 3.8))
    x = np.arange(len(PARAMETERS))
    bars = [("white", "algebraic", "#9ab"), ("white", "refined", "#246"),
            ("ar1", "algebraic", "#dba"), ("ar1", "refined", "#a52")]
    for i, (noise, kind, colour) in enumerate(bars):
        values = [study[noise][kind][p]["rmse/crlb"] for p in PARAMETERS]
        left.bar(x + (i - 1.5) * 0.2, values, 0.2, color=colour,
                 label=f"{kind}, {'white' if noise == 'white' else 'AR(1) 0.9'}")
    left.axhline(1.0, color="k", lw=0.8)
    left.set_yscale("log")
    left.set_xticks(x, PARAMETERS)
    left.set_ylabel("RMSE / Cramér–Rao bound")
    left.set_title(f"{study['runs']} records of 30 s at 1 kHz, 30 dB")
    left.legend(fontsize=8)
    cases = ["right", "missing offset", "output 3 samples late"]
    for i, name in enumerate(cases):
        truth_eq, values, model, options, _ = residual_adequacy.CASES[name]
        record = residual_adequacy.record(
            residual_adequacy.clean_output(truth_eq, values, options), 0)
        test = algid.identify(record, *model).refinement.residual_test
        names = [k for k in test.scores if k not in test.aliases]
        right.scatter([i] * len(names), [max(test.scores[k], 1e-2) for k in names],
                      color="#246", s=18)
        top = max(names, key=test.scores.get)
        right.annotate(top.split(":")[0], (i, test.scores[top]), xytext=(6, 0),
                       textcoords="offset points", fontsize=8, va="center")
    right.axhline(residual_adequacy_limit(), color="#a52", lw=1, label="limit")
    right.set_yscale("log")
    right.set_xticks(range(len(cases)), ["right model", "no offset", "output 3 late"])
    right.set_ylabel("score of each candidate cause")
    right.set_title("test of the simulation residuals")
    right.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(OUT, dpi=110)
    print(f"wrote {OUT}")


def residual_adequacy_limit():
    from algid.identification._residual_tests import CHI2_LIMIT

    return CHI2_LIMIT


if __name__ == "__main__":
    main()
