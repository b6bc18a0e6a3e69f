"""Draw the figure of the README and of the documentation's landing page.

Left: the paper's system (m = 1, c = 2, k = 3) driven by a sine, with white noise of
standard deviation 0.01 on the measured position; the estimates of B and K from
``algid.estimate`` over time.  Right: the EMPS positioning system, the friction model
identified by ``algid.identify`` on the estimation run and simulated on the validation
run (open loop, from the measured force alone), against the measured position.

Run from the repository root (needs the ``simulate`` and ``plot`` extras)::

    python docs/make_readme_figure.py            # writes docs/_static/algid_overview.png
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import algid  # noqa: E402

OUT = Path(__file__).resolve().parent / "_static" / "algid_overview.png"


def emps_record(run):
    """The EMPS signals that the friction model names: time, position q, force F."""
    rec = algid.datasets.emps(run)
    return {"t": rec.t, "q": rec.qm, "F": rec.F}


def draw(out: Path):
    """Draw both panels into ``out`` and return the numbers they show."""
    sim = algid.simulate("sine", m=1, c=2, k=3, noise_std=0.01, seed=0)
    estimates = algid.estimate(sim.t, sim.f, sim.x)

    fit = algid.identify(emps_record("estimation"), algid.datasets.EMPS_EQUATION,
                         "M Fv Fc off")
    validation = fit.simulate(emps_record("validation"), method="RK4")

    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 3.4), layout="constrained")
    estimates.plot(true_values={"B": 2, "K": 3}, ax=left)
    left.set_title("Paper's system, sine input, noise 0.01: estimates", fontsize=10)
    left.set_xlabel("t [s]")
    left.legend(fontsize=8, ncol=2, loc="lower right")

    right.plot(validation.t, 1e3 * validation.measured, lw=1.2, label="measured")
    right.plot(validation.t, 1e3 * validation.simulated, lw=1, ls="--",
               label=f"simulated (fit {validation.fit_percent:.1f} %)")
    right.set_title("EMPS validation run: position, friction model", fontsize=10)
    right.set_xlabel("t [s]")
    right.set_ylabel("q [mm]")
    right.set_ylim(-30, 320)  # room for the legend above the motion
    right.legend(fontsize=8, loc="upper center", ncol=2)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return {"B": estimates.final()["B"], "K": estimates.final()["K"],
            "fit_percent": validation.fit_percent}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=OUT, help=f"PNG to write (default {OUT})")
    args = parser.parse_args(argv)
    numbers = draw(args.out)
    print(f"wrote {args.out}: final B {numbers['B']:.5g}, K {numbers['K']:.5g}; "
          f"EMPS validation fit {numbers['fit_percent']:.2f} %")


if __name__ == "__main__":
    main()
