"""The generated estimator modules of the built-in models."""

from __future__ import annotations

import ast
import builtins
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


def _generated_import(name, globals=None, locals=None, fromlist=(), level=0):
    """``__import__`` of a generated module: only :data:`_GENERATED_IMPORTS`."""
    if level != 0 or not (name.split(".")[0] in _GENERATED_IMPORTS
                          or name.startswith("algid_user_")):
        raise ImportError(f"a generated module may not import {name!r}")
    return importlib.__import__(name, globals, locals, fromlist, level)


#: The builtins a generated module's code sees (its loops use a few of them).
_GENERATED_BUILTINS = {
    **{n: getattr(builtins, n) for n in (
        "range", "max", "min", "abs", "len", "tuple", "list", "float", "int", "bool",
        "round", "enumerate", "zip", "sum", "pow", "divmod", "ValueError",
        "ZeroDivisionError", "ArithmeticError", "OverflowError", "IndexError")},
    "__import__": _generated_import}


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
            # (a cached loop imports its model's algebra, cached beside it as algid_user_*)
            if not all(m.split(".")[0] in _GENERATED_IMPORTS or m.startswith("algid_user_")
                       for m in modules):
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
                # numba.njit(...)(function): the outer call is of the inner one's result,
                # which the walk checks on its own
                if isinstance(call, ast.Call) and not isinstance(call.func, ast.Call) \
                        and ast.unparse(call.func) not in _GENERATED_CALLS:
                    raise ModelError(f"generated module {name!r}: unexpected call at line "
                                     f"{call.lineno}")


def _split_text(tree):
    """The parts of a checked module that are data, taken out of its code.

    Returns ``(doc, values, functions_doc, code)``: the module docstring, the top-level
    assignments of literal values (read by :func:`ast.literal_eval`, which runs
    nothing), the docstrings of the functions, and the rest as a module tree without
    them.  What a generator writes from a user's equation (the equation, its
    description, the factors' text) is in the first three.
    """
    doc, values, functions_doc, body = None, {}, {}, []
    for i, node in enumerate(tree.body):
        if i == 0 and isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant):
            doc = node.value.value
            continue
        if isinstance(node, ast.Assign) and all(isinstance(t, ast.Name) for t in node.targets):
            try:
                value = ast.literal_eval(node.value)
            except (ValueError, TypeError, SyntaxError, MemoryError, RecursionError):
                pass
            else:
                values.update((t.id, value) for t in node.targets)
                continue
        if isinstance(node, ast.FunctionDef):
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) \
                    and isinstance(first.value.value, str):
                functions_doc[node.name] = first.value.value
                node.body = node.body[1:] or [ast.Pass(lineno=first.lineno,
                                                        col_offset=first.col_offset)]
        body.append(node)
    return doc, values, functions_doc, ast.Module(body=body, type_ignores=[])


def module_from_source(source: str, name: str, *, filename: str | None = None) -> ModuleType:
    """Make a module of text written by this package's own generators.

    Only for generated text (user models compiled in memory,
    :func:`algid.symbolic._codegen.compile_model`, and their cached copies on disk).  The
    text is first checked to have the shape the generators write (a docstring, imports of
    NumPy, numba, math and algid, assignments and functions; no call outside the
    functions but ``numba.njit``).  Then its data are taken out of its code: the
    docstrings and the assignments of literal values are read with
    :func:`ast.literal_eval` and set on the module, and only the rest is compiled, after
    a check that it holds no text but identifiers.  So a user's equation or any other
    free text never reaches the compiler: at most names the grammar checked.

    Parameters
    ----------
    source : str
        Text of a generated module.
    name : str
        Module name to register it under.
    filename : str, optional
        The file the text was read from (numba caches the machine code of functions
        defined in a file); by default a ``<generated name>`` label.

    Returns
    -------
    module

    Raises
    ------
    ModelError
        If the text is not shaped as the generators write it, or its code holds text.
    """
    _check_generated_shape(source, name)
    doc, values, functions_doc, code = _split_text(ast.parse(source))
    for node in ast.walk(code):
        if isinstance(node, ast.Constant) and isinstance(node.value, (str, bytes)) \
                and not (isinstance(node.value, str) and node.value.isidentifier()):
            raise ModelError(f"generated module {name!r}: text in its code at line "
                             f"{node.lineno}")
        # no way to reach Python's internals: no private attribute, no dunder name
        if (isinstance(node, ast.Attribute) and node.attr.startswith("_")) or \
                (isinstance(node, ast.Name) and node.id.startswith("__")):
            raise ModelError(f"generated module {name!r}: a private name in its code at "
                             f"line {node.lineno}")
    module = ModuleType(name, doc)
    module.__file__ = filename or f"<generated {name}>"
    module.GENERATED_SOURCE = source  # the text it was made from (to cache its compiled loop)
    module.__dict__.update(values)
    # the code runs with the builtins it needs alone: an import only of the modules the
    # shape check allows, no open, eval, exec or getattr
    module.__dict__["__builtins__"] = _GENERATED_BUILTINS
    sys.modules[name] = module
    exec(compile(code, module.__file__, "exec"), module.__dict__)  # checked above
    for function, text in functions_doc.items():
        target = module.__dict__[function]
        # a numba dispatcher documents the Python function it wraps
        getattr(target, "py_func", target).__doc__ = text
    return module
