"""Models: an equation linear in its unknown parameters, its grammar and compiled form.

Public:

- :func:`parse_equation` reads an equation such as ``"M*q'' + Fv*q' + Fc*sign(q') = F"``
  through a restricted grammar (never ``eval``) into a :class:`Model` of :class:`Term`\\ s;
- :func:`compile_equation` turns it into a generated estimator module for
  :func:`algid.estimate` and :class:`algid.OnlineEstimator` (needs SymPy);
- :func:`parse_system` reads several equations that share parameters into a
  :class:`SystemModel`;
- :func:`available_models` lists the built-in models (``"msd"``, ``"msd_mass"``);
- :data:`LIMITS` bounds what an equation may ask for (length, nesting, terms).
"""

from algid.models._compiled import compile_equation
from algid.models._grammar import LIMITS, parse_equation
from algid.models._model import Model, Term
from algid.models._registry import available_models
from algid.models._system import SystemModel, parse_system

__all__ = ["parse_equation", "parse_system", "compile_equation", "available_models", "Model",
           "SystemModel", "Term", "LIMITS"]
