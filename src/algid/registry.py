"""The generated estimator modules of the built-in models."""

from __future__ import annotations

import importlib
from types import ModuleType

from algid.errors import ModelError
from algid.generated import MODULES

__all__ = ["available_models", "load_model"]


def available_models():
    """Names of the models that have a generated estimator."""
    return tuple(MODULES)


def load_model(name):
    """The generated estimator module of model ``name``.

    Parameters
    ----------
    name : str or module
        A built-in model name, or a generated module itself (returned as is), such as
        one from :func:`algid.symbolic.codegen.compile_model`.

    Returns
    -------
    module

    Raises
    ------
    ModelError
        If no estimator was generated for ``name``.
    """
    if isinstance(name, ModuleType) and hasattr(name, "CHAINS"):
        return name
    if not isinstance(name, str) or name not in MODULES:
        raise ModelError(f"unknown model {name!r} (known: {', '.join(MODULES)})")
    return importlib.import_module(MODULES[name])
