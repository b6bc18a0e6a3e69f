"""A system's tracker across a change (``python -m benchmarks.systems_tracking``).

The DC motor ``L*i' + R*i + K*w = u``, ``J*w' + b*w = K*i`` (L 0.5, R 2, K 0.8, J 0.2,
b 0.1), current and speed measured at 500 Hz with 40 dB of white noise each, driven by
a multisine of 8 lines drawn from 0.2 to 8 Hz (one per record), 25 s.  ``K`` (shared by
both equations), or ``J`` (of the equation without a known term), rises by 25 % at
15 s, the state carried over; the same records without the change too.  The tracker:
window 0.2 s, half-life 2 s, the default false-alarm rate, fed half a second at a time.

Per record: the delay of the first alarm after the change (and any alarm before it),
and every parameter's smallest and largest estimate after the change over its new
value.  Solved jointly as it stood, the mechanical equation fell toward zero after a
change of ``K`` (0.022 for 1.0 one second after it, 0.25 ten seconds later); divided
by ``K`` (``algid.identification._homogeneous``) it follows.  Options: ``--seeds``
(default 100 to 104), ``--json FILE``.
"""

from __future__ import annotations

import argparse
import json

import numpy as np

import algid
from algid.simulation import simulate_system

MOTOR = ["L*i' + R*i + K*w = u", "J*w' + b*w = K*i"]
MOTOR_TRUE = {"L": 0.5, "R": 2.0, "K": 0.8, "J": 0.2, "b": 0.1}
CHANGE_AT, DURATION, FACTOR = 15.0, 25.0, 1.25


def motor_change_record(duration, change_at=None, factor=FACTOR, seed=100, rate=500.0,
                        parameter="K"):
    """The motor driven by a multisine, ``parameter`` times ``factor`` from
    ``change_at`` (the state carried over), 40 dB on both outputs."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(duration * rate)) / rate
    freqs = rng.uniform(0.2, 8.0, 8)
    phases = np.random.default_rng(seed).uniform(0, 2 * np.pi, len(freqs))
    u = np.sum(np.sin(2 * np.pi * freqs[:, None] * t + phases[:, None]), axis=0)
    k = len(t) if change_at is None else int(change_at * rate)
    y = simulate_system(MOTOR, MOTOR_TRUE, t[:k + 1], {"u": u[:k + 1]})
    if change_at is not None:
        changed = dict(MOTOR_TRUE, **{parameter: MOTOR_TRUE[parameter] * factor})
        rest = simulate_system(MOTOR, changed, t[k:], {"u": u[k:]},
                               initial_state=[y["i"][-1], y["w"][-1]])
        y = {n: np.concatenate([y[n][:-1], rest[n]]) for n in y}
    record = {"t": t, "u": u}
    for n, v in y.items():
        record[n] = v[:len(t)] + 0.01 * np.std(v) * rng.standard_normal(len(t))
    return record


def track(record):
    """Alarms, report times and estimates of the tracker fed half a second at a time."""
    tracker = algid.Tracker(MOTOR, list(MOTOR_TRUE), time="t", window=0.2, half_life=2.0)
    alarms, t, values = [], [], []
    for start in range(0, len(record["t"]), 250):
        out = tracker.update({k: v[start:start + 250] for k, v in record.items()})
        alarms += out.alarms.tolist()
        t += out.t.tolist()
        values += out.values.tolist()
    return alarms, np.array(t), np.array(values)


def run(seeds=range(100, 105)):
    """Every record's figures, as a list of dicts."""
    rows = []
    for parameter in ("K", "J", None):
        for seed in seeds:
            record = motor_change_record(DURATION, None if parameter is None else CHANGE_AT,
                                         seed=seed, parameter=parameter or "K")
            alarms, t, values = track(record)
            truth = dict(MOTOR_TRUE)
            if parameter is not None:
                truth[parameter] *= FACTOR
            after = values[t > CHANGE_AT] / np.array(list(truth.values()))
            rows.append({"changed": parameter, "seed": seed,
                         "alarms_before": [a for a in alarms if a <= CHANGE_AT],
                         "delay": next((a - CHANGE_AT for a in alarms if a > CHANGE_AT), None),
                         "lowest": dict(zip(truth, after.min(axis=0).tolist())),
                         "highest": dict(zip(truth, after.max(axis=0).tolist()))})
    return rows


def main(argv=None):
    """Print (and write with ``--json``) the figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=list(range(100, 105)))
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)
    rows = run(args.seeds)
    for row in rows:
        delay = "none" if row["delay"] is None else f"{row['delay']:.2f} s"
        low = " ".join(f"{v:.2f}" for v in row["lowest"].values())
        high = " ".join(f"{v:.2f}" for v in row["highest"].values())
        print(f"{row['changed'] or '-':>2} seed {row['seed']}: alarm {delay:>7} "
              f"(before: {len(row['alarms_before'])}); after the change, over the truth: "
              f"lowest {low}, highest {high}")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as out:
            json.dump(rows, out, indent=1)
    return rows


if __name__ == "__main__":
    main()
