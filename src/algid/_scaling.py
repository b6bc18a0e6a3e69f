"""Rescaling of the signal amplitudes by a power of two, against overflow and underflow.

The algebraic estimate does not depend on the unit of the signals: in a model linear in
its signals, with every term carrying one signal (``x'' + B x' + K x = f``, ``m x'' +
c x' + k x = F``, a user equation without nonlinear factors or offsets), multiplying
every signal by the same ``s`` multiplies every row of ``P theta = Q`` by ``s``, and
Cramer's numerators and denominator by ``s**n``: the parameters do not change.  But the
denominator is a product of ``n`` integrals of the signals: with amplitudes of 1e300 it
overflows, with 1e-300 it underflows, and the estimate is NaN.

So the signals are multiplied by a power of two ``s`` that brings the largest
amplitude into ``[1, 2)`` when it is outside :data:`SAFE_AMPLITUDES`.  Multiplying by
a power of two is exact in binary floating point, and so is every sum and product
after it (each result is the unscaled one times a power of two, barring overflow and
underflow): the estimates are *bit for bit* those of the unscaled computation whenever
that one neither overflows nor underflows, whatever power of two is chosen.  Hence a
stream, which must choose ``s`` from its first chunk with a nonzero sample, gives the
same numbers as the batch estimate, which chooses it from the whole record; and
ordinary signals (inside :data:`SAFE_AMPLITUDES`) are not touched at all.  Nothing is
to be undone on the parameters: they are invariant.
"""

from __future__ import annotations

import math

import numpy as np

from algid.errors import InputDataError

__all__ = ["SAFE_AMPLITUDES", "AMPLITUDE_BITS", "amplitude_scale", "scalable",
           "check_amplitude_range"]

#: Range of the largest absolute sample in which the signals are used as given.
SAFE_AMPLITUDES = (2.0**-64, 2.0**64)

#: Bits of the floating-point exponent range (up to ``2**1024``) given to the amplitude
#: of the channels.  Cramer's rule multiplies ``n`` integrals of the channels (``n``
#: parameters), each weighted by powers of the time since the origin: a channel may reach
#: ``2**(AMPLITUDE_BITS // n)`` (after the rescaling, divided by a known mass), and the
#: other half of the range is left to those powers (the paper's model, whose numerators
#: and denominator grow like ``t**10`` to ``t**11`` with the default filter, then runs for
#: about ``2**46`` time units before it overflows; at unit amplitude, ``2**93``).
AMPLITUDE_BITS = 512


def amplitude_scale(arrays):
    """The power of two that the signals are multiplied by.

    Parameters
    ----------
    arrays : sequence of ndarray
        The signals (finite float64).

    Returns
    -------
    float or None
        1.0 if the largest absolute sample is within :data:`SAFE_AMPLITUDES`; else
        ``2**k`` bringing it into ``[1, 2)`` (at most ``2**1023``: a subnormal one
        comes into ``[2**-51, 1)``); None if every sample is zero (no scale
        can be chosen yet, and none is needed).
    """
    largest = max((max(float(a.max()), -float(a.min())) for a in arrays if a.size),
                  default=0.0)
    if largest == 0.0:
        return None
    low, high = SAFE_AMPLITUDES
    if low <= largest <= high:
        return 1.0
    _, exponent = math.frexp(largest)  # largest = mantissa * 2**exponent, mantissa in [0.5, 1)
    # at most 2**1023, the largest power of two: a subnormal largest sample (below
    # 2**-1022) then lands in [2**-51, 1), inside SAFE_AMPLITUDES
    return math.ldexp(1.0, min(1 - exponent, 1023))


def scalable(module) -> bool:
    """Whether the parameters of a generated model are invariant under a common scale.

    True when every channel is a measured signal (no nonlinear factor, no offset's
    constant, no time channel: the module's ``FACTORS`` is empty).

    Parameters
    ----------
    module : module
        Generated estimator module.

    Returns
    -------
    bool
    """
    return not getattr(module, "FACTORS", {})


def check_amplitude_range(names, channels, divisors, scale, n_parameters):
    """Refuse channels whose amplitudes floating point cannot hold together.

    After the rescaling (``scale``) and the division by a known mass (``divisors``),
    a channel that is not identically zero must reach neither beyond ``2**(AMPLITUDE_BITS
    // n_parameters)`` (the products of its integrals would overflow) nor, divided by a
    known mass, only below ``2**-(AMPLITUDE_BITS // n_parameters)`` (it would vanish
    beside the others), nor only into the subnormal numbers (below ``2**-1022``: its
    samples would have lost their precision, as a record's other samples do beside an
    outlier of ``1e308``).

    Parameters
    ----------
    names : sequence of str
        The channels' names, for the message.
    channels : sequence of ndarray
        Their samples as given (finite).
    divisors : sequence of float
        Every channel's divisor (a known mass; 1 for none).
    scale : float or None
        The power of two the channels are multiplied by (:func:`amplitude_scale`).
    n_parameters : int
        The number of parameters (of integrals multiplied by Cramer's rule).

    Raises
    ------
    InputDataError
        Naming the channel, its largest sample and, for a lost precision, the largest
        sample of the record.
    """
    unit = 1.0 if scale is None else float(scale)
    largest = [max(float(c.max()), -float(c.min())) if c.size else 0.0 for c in channels]
    high = math.ldexp(1.0, AMPLITUDE_BITS // n_parameters)
    names = list(names)
    for name, c, size, divisor in zip(names, channels, largest, divisors):
        with np.errstate(over="ignore"):  # (a mass of 1e-320: the quotient is inf)
            held = size * unit / divisor
        # a known mass may shrink a channel as much as it may grow it (symmetric bounds)
        low = 2.0**-1022 if divisor == 1.0 else 1.0 / high
        if held == 0.0 or low <= held <= high:
            continue
        by = "" if divisor == 1.0 else f" divided by the mass {divisor:.6g}"
        remedy = ("express the force and the mass in other units" if by else
                  "remove the outlier or express the signals in other units")
        if by and held < low:
            raise InputDataError(
                f"signal {name!r}{by} is at most {size / divisor:.6g}, below "
                f"2**-{AMPLITUDE_BITS // n_parameters} times the other signals' unit: it "
                f"vanishes beside them in the products of the estimator's integrals; "
                f"{remedy}")
        if held > high:
            row = int(np.argmax(np.abs(c)))
            with np.errstate(over="ignore"):
                reached = float(c[row] / divisor)
            shown = f"{reached:.6g}" if math.isfinite(reached) else \
                f"{float(c[row]):.6g} / {float(divisor):.6g} (beyond 1.8e308)"
            raise InputDataError(
                f"signal {name!r}{by} reaches {shown} (row {row}), beyond "
                f"2**{AMPLITUDE_BITS // n_parameters} times the other signals' unit: the "
                f"products of the estimator's integrals overflow; {remedy}")
        top = int(np.argmax(largest))
        row = int(np.argmax(np.abs(channels[top])))
        beside = ("" if top == names.index(name) else
                  f" beside the largest sample, {channels[top][row]:.6g} of {names[top]!r} "
                  f"(row {row}),")
        raise InputDataError(
            f"signal {name!r}{by} is at most {size / divisor:.6g}:{beside} its samples fall "
            f"below the normal floating-point numbers in the estimator's unit and lose their "
            f"precision; {remedy}")
