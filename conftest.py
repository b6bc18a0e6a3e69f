"""Collection of the examples in ``src/algid`` as doctests (``--doctest-modules``).

A module whose optional dependency is not installed is not collected, so that the
suite runs with any subset of the extras.
"""

import importlib.util

OPTIONAL = {"sympy": ["src/algid/symbolic/*", "src/algid/symbolic/*/*"],
            "control": ["src/algid/simulation/*"]}

collect_ignore_glob = [pattern for package, patterns in OPTIONAL.items()
                       if importlib.util.find_spec(package) is None for pattern in patterns]
