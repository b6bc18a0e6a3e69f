"""Built-in models: the mass-spring-damper of Becedas et al. and its unknown-mass form."""

from __future__ import annotations

import sympy as sp

from algid.errors import ModelError
from algid.symbolic._model import LinearODEModel

__all__ = ["BUILTIN_MODELS", "KNOWN_MASS", "builtin_model"]


def _msd() -> LinearODEModel:
    B, K = sp.symbols("B K")
    return LinearODEModel(
        name="msd",
        output_coefficients=(1, B, K),
        input_coefficients=(1,),
        parameters=(B, K),
        output="x",
        input="f",
        description="mass-spring-damper with known mass: B = c/m, K = k/m, f = F/m",
    )


def _msd_mass() -> LinearODEModel:
    m, c, k = sp.symbols("m c k")
    return LinearODEModel(
        name="msd_mass",
        output_coefficients=(m, c, k),
        input_coefficients=(1,),
        parameters=(m, c, k),
        output="x",
        input="F",
        description="mass-spring-damper with unknown mass, damping and stiffness; F is the force",
    )


#: Name -> factory of every built-in model.
BUILTIN_MODELS = {"msd": _msd, "msd_mass": _msd_mass}

#: Name -> (quantity -> the parameter it is the known mass times, channels divided by the
#: mass) for the built-in models that take a known mass.
KNOWN_MASS = {"msd": ({"c": "B", "k": "K"}, ("f",))}


def builtin_model(name: str) -> LinearODEModel:
    """Return the built-in model called ``name``.

    Parameters
    ----------
    name : str
        ``"msd"`` or ``"msd_mass"``.

    Returns
    -------
    LinearODEModel
        The model.

    Raises
    ------
    ModelError
        If there is no such model (the message lists the known ones).

    Examples
    --------
    >>> from algid.symbolic import builtin_model
    >>> model = builtin_model("msd_mass")
    >>> print(model.equation_text())
    m*x'' + c*x' + k*x = F
    >>> model.parameters
    (m, c, k)
    """
    try:
        return BUILTIN_MODELS[name]()
    except KeyError:
        raise ModelError(f"unknown model {name!r} (known: {', '.join(BUILTIN_MODELS)})") from None
