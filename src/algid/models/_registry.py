"""The generated estimator modules of the built-in models."""

from __future__ import annotations

import ast
import importlib
import sys
from types import ModuleType

from algid._generated import MODULES
from algid.errors import ModelError

__all__ = ["available_models", "load_model", "module_from_source"]


def available_models():
    """Names of the models that have a generated estimator.

    Returns
    -------
    tuple of str
        The built-in model names.

    Examples
    --------
    >>> from algid.models import available_models
    >>> available_models()
    ('msd', 'msd_mass')
    """
    return tuple(MODULES)


def load_model(name):
    """The generated estimator module of model ``name``.

    Parameters
    ----------
    name : str or module
        A built-in model name, or a generated module itself (returned as is), such as
        one from :func:`algid.symbolic._codegen.compile_model`.

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


#: Modules a generated module may import (itself, or a package below it).
_GENERATED_IMPORTS = ("numpy", "numba", "math", "algid")
#: The only calls a generated module makes outside its functions (its decorators).
_GENERATED_CALLS = ("numba.njit",)


def _check_generated_shape(source, name):
    """Refuse text that is not shaped as our generators write: a docstring, imports of
    :data:`_GENERATED_IMPORTS`, assignments and function definitions, with no call outside
    the functions but :data:`_GENERATED_CALLS` (a user string that escaped its literal
    would add a statement or a call here)."""
    try:
        tree = ast.parse(source)
    except (SyntaxError, ValueError, RecursionError, MemoryError):
        raise ModelError(f"generated module {name!r} is not valid Python") from None
    for i, node in enumerate(tree.body):
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            modules = ([a.name for a in node.names] if isinstance(node, ast.Import)
                       else [node.module or ""])
            if not all(m.split(".")[0] in _GENERATED_IMPORTS for m in modules):
                raise ModelError(f"generated module {name!r} imports {modules}")
            continue
        docstring = (i == 0 and isinstance(node, ast.Expr) and isinstance(node.value,
                     ast.Constant) and isinstance(node.value.value, str))
        if not (docstring or isinstance(node, (ast.Assign, ast.FunctionDef))):
            raise ModelError(f"generated module {name!r}: unexpected statement at line "
                             f"{node.lineno}")
        if isinstance(node, ast.FunctionDef) and any(
                ast.unparse(d.func if isinstance(d, ast.Call) else d) not in _GENERATED_CALLS
                for d in node.decorator_list):
            raise ModelError(f"generated module {name!r}: unexpected decorator at line "
                             f"{node.lineno}")
        outside = ([node.value] if isinstance(node, ast.Assign) else
                   node.decorator_list + node.args.defaults + node.args.kw_defaults
                   if isinstance(node, ast.FunctionDef) else [])
        for part in outside:
            for call in ast.walk(part or ast.Constant(None)):
                if isinstance(call, ast.Call) and ast.unparse(call.func) not in \
                        _GENERATED_CALLS:
                    raise ModelError(f"generated module {name!r}: unexpected call at line "
                                     f"{call.lineno}")


def module_from_source(source: str, name: str) -> ModuleType:
    """Execute generated source text as a module registered in :data:`sys.modules`.

    Only for text written by this package's own generators (user models compiled in
    memory, :func:`algid.symbolic._codegen.compile_model`); never for user text, which
    they write only as escaped literals.  Before it runs, the text is checked to have
    the shape they write (a docstring, imports of NumPy, numba, math and algid,
    assignments and functions; no call outside the functions but ``numba.njit``), so
    that a user string escaping its literal is refused rather than run.

    Parameters
    ----------
    source : str
        Text of a generated module.
    name : str
        Module name to register it under.

    Returns
    -------
    module

    Raises
    ------
    ModelError
        If the text is not shaped as the generators write it.
    """
    _check_generated_shape(source, name)
    module = ModuleType(name)
    module.__file__ = f"<generated {name}>"
    module.GENERATED_SOURCE = source  # the text it was made from (to cache its compiled loop)
    sys.modules[name] = module
    exec(compile(source, module.__file__, "exec"), module.__dict__)
    return module
