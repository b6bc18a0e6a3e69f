"""Docstrings of the public API follow numpydoc, and their examples run.

Every name in ``algid.__all__`` and in the ``__all__`` of each public module (functions,
classes, and the public methods and properties a class defines) is validated with
``numpydoc.validate.validate``; the test fails listing each offender with the numpydoc
codes it breaks.  Every public function and class has an Examples section that runs
(not skipped) and imports from public modules; the examples themselves run as doctests
(``--doctest-modules`` in ``pyproject.toml``).
"""

from __future__ import annotations

import importlib
import inspect
import pkgutil
import re

import pytest

validate = pytest.importorskip("numpydoc.validate").validate
NumpyDocString = pytest.importorskip("numpydoc.docscrape").NumpyDocString

import algid  # noqa: E402

#: The numpydoc checks applied: docstring present (GL08), parameters documented and
#: existing (PR01, PR02), a Returns section where something is returned (RT01), and a
#: one-line summary that starts with a capital letter, ends with a period and is not
#: indented (SS01-SS04, SS06).
CHECKS = {"GL08", "PR01", "PR02", "RT01", "SS01", "SS02", "SS03", "SS04", "SS06"}

#: Modules that are not API: the command line, generated code (checked by its
#: generator's tests) and ``python -m algid``.
SKIPPED_MODULES = ("algid.cli", "algid.__main__", "algid._generated")


#: Known findings, to fix in these modules; remove each entry once its module is clean.
PENDING = ()


def public_modules():
    """``algid`` and every module below it whose name has no leading underscore."""
    names = ["algid"]
    for info in pkgutil.walk_packages(algid.__path__, "algid."):
        parts = info.name.split(".")
        if any(p.startswith("_") for p in parts) or info.name.startswith(SKIPPED_MODULES):
            continue
        names.append(info.name)
    return names


def public_objects():
    """``(import path, object)`` of every public function, class, method and property."""
    seen, out = set(), []

    def add(path, obj):
        key = id(obj.fget) if isinstance(obj, property) else id(obj)
        if key not in seen:
            seen.add(key)
            out.append((path, obj))

    # the deepest public module that exports an object is its home (as on the API pages)
    for modname in sorted(public_modules(), key=lambda m: -m.count(".")):
        module = importlib.import_module(modname)
        for name in getattr(module, "__all__", ()):
            obj = getattr(module, name)
            if not (inspect.isfunction(obj) or inspect.isclass(obj)):
                continue  # constants are documented with #: comments
            if not (getattr(obj, "__module__", None) or "").startswith("algid"):
                continue  # e.g. a SymPy function symbol
            defined = obj.__module__
            home = (f"{modname}.{obj.__qualname__}" if "._" in defined
                    else f"{defined}.{obj.__qualname__}")
            add(home, obj)
            if inspect.isclass(obj):
                for attr, value in vars(obj).items():
                    if attr.startswith("_") or not (inspect.isfunction(value)
                                                    or isinstance(value, property)):
                        continue
                    add(f"{home}.{attr}", value)
    return out


def attribute_names(obj):
    """Names documented in the Attributes section of a class (``m, c, k : float``)."""
    names = set()
    for item in NumpyDocString(inspect.getdoc(obj) or "")["Attributes"]:
        names.update(n.strip() for n in item.name.split(","))
    return names


def offences(path, obj):
    """The numpydoc findings of :data:`CHECKS` for one import path.

    A class may document its constructor's parameters as Attributes (dataclasses);
    private fields (leading underscore) need no documentation.
    """
    found = []
    for code, message in validate(path)["errors"]:
        if code not in CHECKS:
            continue
        if code == "PR01" and inspect.isclass(obj):
            missing = set(re.findall(r"'\*{0,2}(\w+)'", message)) - attribute_names(obj)
            if not {name for name in missing if not name.startswith("_")}:
                continue
        found.append(f"{code} {message}")
    return found


def test_the_walk_finds_the_api():
    paths = {path for path, _ in public_objects()}
    assert "algid.simulation.simulate" in paths
    assert "algid.simulation.SimulationResult.to_csv" in paths
    assert "algid.symbolic.derive" in paths
    assert not any("._" in path for path in paths)  # internals are not API


def half(value):
    """halve a value"""
    return value / 2


def test_the_checks_catch_a_bad_docstring():
    found = {e[:4] for e in offences(f"{__name__}.half", half)}
    assert found == {"PR01", "RT01", "SS02", "SS03"}


def test_public_docstrings_follow_numpydoc():
    found = {}
    for path, obj in public_objects():
        if path.startswith(PENDING):
            continue
        errors = offences(path, obj)
        if errors:
            found[path] = errors
    report = "\n".join(f"{path}:\n    " + "\n    ".join(errs)
                       for path, errs in sorted(found.items()))
    assert not found, f"{len(found)} public objects with docstring problems:\n{report}"


def example_problem(obj):
    """What is wrong with the Examples section of a docstring, or None.

    An example must run (a ``>>>`` line not skipped) and import from public modules
    only, as a user would.
    """
    lines = NumpyDocString(inspect.getdoc(obj) or "")["Examples"]
    code = [line.strip()[4:] for line in lines if line.strip().startswith((">>>", "..."))]
    if not any("+SKIP" not in line for line in code if line):
        return "no Examples section that runs"
    private = [line for line in code if re.search(r"\balgid(\.\w+)*\._", line)]
    if private:
        return f"imports a private module: {private[0]}"
    return None


def test_the_example_check_catches_a_bad_example():
    assert example_problem(half) == "no Examples section that runs"

    def skipped():
        """Do nothing.

        Examples
        --------
        >>> skipped()  # doctest: +SKIP
        """

    def private():
        """Do nothing.

        Examples
        --------
        >>> from algid.models._grammar import parse_equation
        """

    def public():
        """Do nothing.

        Examples
        --------
        >>> from algid.estimation import convergence_time
        >>> public()  # doctest: +SKIP
        """

    assert example_problem(skipped) == "no Examples section that runs"
    assert example_problem(private).startswith("imports a private module")
    assert example_problem(public) is None


def test_every_public_function_and_class_has_examples():
    found = {}
    for path, obj in public_objects():
        if path.count(".") != 2 or not (inspect.isfunction(obj) or inspect.isclass(obj)):
            continue  # methods and properties are shown in their class's examples
        problem = example_problem(obj)
        if problem:
            found[path] = problem
    report = "\n".join(f"{path}: {problem}" for path, problem in sorted(found.items()))
    assert not found, f"{len(found)} public functions and classes without examples:\n{report}"
