"""Simulation: responses of the paper's plant and of any model written as an equation.

Public:

- :func:`simulate`, :func:`plant`, :class:`SimulationResult`: the mass-spring-damper
  ``m x'' + c x' + k x = F`` of the paper, exact for its step and sine inputs; they need
  python-control (``pip install 'algid[simulate]'``) and are imported on first use.
- :func:`simulate_model`, :func:`fit_initial_state`: the output of a user model
  (:class:`algid.models.Model`) for any parameter values, driven by sampled inputs; they
  need only SciPy.  ``sign()`` of the simulated state is stepped over (Filippov).
- :func:`simulate_system`: the outputs of a linear system of equations (one output per
  equation, shared parameters), exact for inputs linear between samples.
"""

from algid.simulation._model import fit_initial_state, simulate_model
from algid.simulation._system import simulate_system

__all__ = ["simulate", "plant", "SimulationResult", "simulate_model", "fit_initial_state",
           "simulate_system"]

_NEEDS_CONTROL = {"simulate", "plant", "SimulationResult"}


def __getattr__(name):
    # python-control is an optional extra: import the plant's simulator on first use
    if name in _NEEDS_CONTROL:
        import algid.simulation._plant as _plant
        return getattr(_plant, name)
    raise AttributeError(f"module 'algid.simulation' has no attribute {name!r}")
