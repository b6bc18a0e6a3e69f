"""Long streams: feed a stream to an :class:`algid.OnlineEstimator` and summarise it
without keeping it (memory does not grow with the stream)."""

from __future__ import annotations

import numpy as np

__all__ = ["run_stream"]


def run_stream(estimator, chunks, *, true_values=None, settle_time=0.0):
    """Feed a stream to an estimator and summarise it without keeping it.

    For long-stream checks and benchmarks: memory does not grow with the stream.

    Parameters
    ----------
    estimator : OnlineEstimator
    chunks : iterable of (t, f, x) or (t, signals)
        The stream, chunk by chunk; ``signals`` a mapping of signal name -> samples
        (``update(t, signals=...)``, e.g. for a user model).
    true_values : dict or callable, optional
        Parameter name -> true value, or a function of the chunk's times returning
        such a dict (values may be arrays over the chunk).
    settle_time : float, optional
        Errors are accumulated over samples with ``t >= settle_time`` only.

    Returns
    -------
    dict
        ``n_samples``, ``n_chunks``, ``final`` (last estimates), ``max_state_magnitude``
        (over the chunk ends), and with ``true_values``: ``max_rel_error`` (name ->
        largest ``|estimate / true - 1|`` after ``settle_time``; NaN estimates count as
        inf) and ``n_undefined`` (NaN estimates after ``settle_time``).
    """
    n_samples = n_chunks = 0
    max_state = 0.0
    max_err = {}
    n_undefined = 0
    result = None
    for chunk in chunks:
        if len(chunk) == 2:
            result = estimator.update(chunk[0], signals=chunk[1])
        else:
            t, f, x = chunk
            result = estimator.update(t, f, x)
        n_samples += result.t.size
        n_chunks += 1
        max_state = max(max_state, estimator.state_magnitude)
        if true_values is None:
            continue
        truth = true_values(result.t) if callable(true_values) else true_values
        keep = result.t >= settle_time
        if not keep.any():
            continue
        for name, value in truth.items():
            est = result.estimates[name][keep]
            ref = np.broadcast_to(value, result.t.shape)[keep]
            err = np.abs(est / ref - 1.0)
            undefined = ~np.isfinite(err)
            n_undefined += int(np.count_nonzero(~np.isfinite(est)))
            worst = np.inf if undefined.any() else float(np.max(err))
            max_err[name] = max(max_err.get(name, 0.0), worst)
    summary = {"n_samples": n_samples, "n_chunks": n_chunks,
               "final": result.final() if result is not None and result.t.size else {},
               "max_state_magnitude": max_state}
    if true_values is not None:
        summary["max_rel_error"] = max_err
        summary["n_undefined"] = n_undefined
    return summary
