"""Signals: integrals, filters and derivatives of uniformly sampled signals.

Public:

- :func:`algebraic_derivative` and :class:`CausalDifferentiator`: the algebraic
  numerical differentiator of Mboup, Join and Fliess (Jacobi kernels), batch and causal;
- :func:`cumulative_integral` and :func:`iterated_integrals`: the cumulative quadrature
  (Adams–Moulton rules of 2 to 9 points) that the estimator's integrator chains use;
- :class:`LowpassFilter` and :func:`lti_response`: linear filters discretised exactly for
  a piecewise-polynomial input.
"""

from algid.signals._differentiation import CausalDifferentiator, algebraic_derivative
from algid.signals._filters import LowpassFilter, lti_response
from algid.signals._quadrature import cumulative_integral, iterated_integrals

__all__ = ["algebraic_derivative", "CausalDifferentiator", "cumulative_integral",
           "iterated_integrals", "LowpassFilter", "lti_response"]
