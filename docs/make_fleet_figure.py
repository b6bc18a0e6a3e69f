"""Draw the fleet figure of the user guide ("Fleets and long records").

A fleet of 120 mass-spring-dampers of one type, 5 s at 1 kHz each: damping and
stiffness spread by 2 % from unit to unit, three units worn (damping 40 % higher, one of
them also 10 % softer), two records bad (too short, NaN throughout).  Identified with
:func:`algid.identify_many` and drawn with :func:`algid.plotting.plot_fleet`.

Run from the repository root (needs the ``plot`` and ``fleet`` extras; about half a
minute)::

    python docs/make_fleet_figure.py            # writes docs/_static/algid_fleet.png
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import algid
from algid.plotting import plot_fleet, save_figure

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "_static" / "algid_fleet.png"
NOMINAL = {"B": 2.0, "K": 30.0}
WORN = {"m017": {"B": 1.4}, "m058": {"B": 1.4, "K": 0.9}, "m093": {"B": 1.4}}
BAD = ("m031", "m104")


def _force(t):
    """Three lines between 0.5 and 3 Hz (N)."""
    return (np.sin(2 * np.pi * 0.5 * t) + np.sin(2 * np.pi * 1.3 * t + 1.0)
            + np.sin(2 * np.pi * 2.9 * t + 2.0))


def fleet(units=120, seed=1):
    """Mapping unit id -> record."""
    rng = np.random.default_rng(seed)
    records = {}
    for i in range(units):
        name = f"m{i:03d}"
        values = {p: v * (1 + 0.02 * rng.normal()) * WORN.get(name, {}).get(p, 1.0)
                  for p, v in NOMINAL.items()}
        sim = algid.simulate(_force, c=values["B"], k=values["K"], duration=5.0,
                             rate=1000.0, noise_std=2e-4, seed=int(rng.integers(2**31)))
        record = {"t": sim.t, "f": sim.f, "x": sim.x}
        if name == BAD[0]:
            record = {k: v[:40] for k, v in record.items()}
        elif name == BAD[1]:
            record["x"] = np.full_like(sim.x, np.nan)
        records[name] = record
    return records


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(OUT))
    args = parser.parse_args(argv)
    table = algid.identify_many(fleet(), "x'' + B*x' + K*x = f", "B K")
    fig = plot_fleet(table, true_values=NOMINAL)
    print(save_figure(fig, args.out, dpi=110))
    flags = algid.identification.fleet_outliers(table)
    print("outliers:", {p: list(table.index[flags[p]]) for p in flags})
    print("refused:", list(table.index[table["error"].notna()]))


if __name__ == "__main__":
    main()
