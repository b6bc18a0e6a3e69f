"""The likely cause of a large numerical error of the paper's estimator, in one line.

An error of the quadrature falls by ``2**q`` when the sampling rate doubles (``q`` of the
order of the rule), one of noise or of data that do not follow the model hardly
changes: the estimate from every other sample tells them apart.  Where the sampling is
not the cause, white noise on the output is named with its level when the output's
differences reach a noise floor (:func:`algid.identification._records.white_noise_floor`).
"""

from __future__ import annotations

import math

import numpy as np

from algid.identification._records import white_noise_floor

__all__ = ["numerical_error_warning", "NUMERICAL_ERROR_WARNING", "SAMPLING_ERROR_RATIO"]


#: Above this estimated relative numerical error ``algid estimate`` warns on stderr.
NUMERICAL_ERROR_WARNING = 1e-3


#: Halving the sampling rate multiplies an error of the quadrature by ``2**q`` (``q`` of
#: the order of the rule's points, 6 to 8: 250 to 2000 measured on under-resolved
#: records) but one of noise or of data that do not follow the model by about 0.5 to 3:
#: above this ratio the error is put down to the sampling.
SAMPLING_ERROR_RATIO = 8.0


def numerical_error_warning(source, error, half_rate_error, output, x):
    """The one-line warning for a large final numerical error, with its likely cause.

    Parameters
    ----------
    source : str
        What the estimate was made from (the file name), at the head of the line.
    error : float
        The final estimate's relative numerical error.
    half_rate_error : callable
        Returns the same error for the estimate from every other sample (NaN if there
        is none); called only when ``error`` is large.
    output : str
        Name of the output signal.
    x : numpy.ndarray
        The output samples: where the sampling is not the cause, white noise on them is
        named with its level when their differences reach a noise floor.

    Returns
    -------
    str or None
        ``"warning: ..."``, or None when ``error`` is at most
        :data:`NUMERICAL_ERROR_WARNING`.
    """
    if not error > NUMERICAL_ERROR_WARNING:
        return None
    if math.isinf(error):
        return (f"warning: {source}: the data do not determine the estimate at the end of "
                "the record (a term of the model is not excited)")
    half = half_rate_error()
    if half >= SAMPLING_ERROR_RATIO * error:
        cause = (f"it comes from the sampling (at half the rate it is {half:.1e}): "
                 "resample faster")
    else:
        rate = "" if math.isnan(half) else f" (at half the rate it is {half:.1e})"
        # in units of the largest sample: the squares of 1e300 overflow, of 1e-300
        # underflow, and the noise level relative to the rms is the same
        largest = float(np.max(np.abs(x))) if len(x) else 0.0
        unit = x / largest if largest > 0 else x
        noisy, variance = white_noise_floor(unit)
        spread = float(unit.std()) if len(unit) else 0.0
        if noisy and spread > 0:
            cause = (f"it does not come from the sampling{rate}: {output!r} carries white "
                     f"noise of about {math.sqrt(variance) / spread:.1e} of its rms (a "
                     f"higher --filter-order or a longer record reduces its effect)")
        elif error >= 1.0:
            cause = (f"the estimate means nothing and {output!r} shows no noise floor: "
                     "too few samples per period of the signals, or data that do not "
                     "follow the model")
        else:
            cause = (f"it does not come from the sampling{rate}: data that do not follow "
                     "the model (check the columns and the model)")
    return f"warning: {source}: estimated relative numerical error {error:.1e}; {cause}"
