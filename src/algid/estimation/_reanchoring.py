"""Re-anchoring of the time origin of a stream: where estimators restart, which is
reported.

The weights ``tau**k`` and the iterated integrals grow without bound, and an estimate
that uses the whole past cannot follow a change of the parameters.  Because the method
does not depend on the initial conditions, the time origin may be moved to any
sample.  With a re-anchoring period of ``2 * half`` samples two estimators run
staggered by ``half`` samples: estimator 0 restarts at samples ``0, 2 half, 4 half,
...`` and estimator 1 at ``half, 3 half, ...``.  At every sample the estimate reported
is that of the estimator with the older origin, of age between ``half`` and ``2 half
- 1`` samples (before estimator 1 starts, that of estimator 0).

:func:`anchor_plan` says this for any run of samples; it is a pure function of sample
indices, so a stream cut anywhere gets the same plan.
"""

from __future__ import annotations

from typing import NamedTuple

__all__ = ["AnchorSegment", "anchor_plan"]


class AnchorSegment(NamedTuple):
    """Samples ``start`` to ``stop - 1`` of a run, reported by one estimator.

    Over a segment nothing restarts after ``start``, and the same estimator is reported.

    Attributes
    ----------
    start, stop : int
        Positions in the run (0 = its first sample).
    restart : int or None
        The estimator (0 or 1) whose origin is the sample at ``start``, if any.
    reported : int
        The estimator whose estimates are reported over the segment.
    running : tuple of int
        The estimators that run over the segment (``(0,)`` before estimator 1 starts).
    """

    start: int
    stop: int
    restart: int | None
    reported: int
    running: tuple


def anchor_plan(first, count, half):
    """The segments of a run of samples of a re-anchored stream.

    Parameters
    ----------
    first : int
        Stream index of the run's first sample (0 = the first sample of the stream).
    count : int
        Number of samples in the run.
    half : int
        Half the re-anchoring period, in samples (``>= 1``).

    Returns
    -------
    list of AnchorSegment
        Consecutive segments covering positions ``0 .. count - 1``, split at every
        multiple of ``half``.

    Examples
    --------
    >>> [tuple(s) for s in anchor_plan(8, 6, 5)]
    [(0, 2, None, 0, (0, 1)), (2, 6, 0, 1, (0, 1))]
    """
    if half < 1:
        raise ValueError(f"half must be at least 1, got {half!r}")
    segments = []
    pos = 0
    while pos < count:
        k, phase = divmod(first + pos, half)
        stop = min(count, pos + half - phase)
        segments.append(AnchorSegment(
            start=pos, stop=stop, restart=k % 2 if phase == 0 else None,
            reported=0 if k == 0 or k % 2 else 1, running=(0,) if k == 0 else (0, 1)))
        pos = stop
    return segments
