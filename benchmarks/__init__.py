"""Accuracy and speed benchmark of ``algid`` against the baselines a user would pick.

Run from the repository root with ``python -m benchmarks`` (see :mod:`benchmarks.run`).
Modules: :mod:`benchmarks.baselines` (the baseline estimators, from scratch),
:mod:`benchmarks.measure` (timing, memory, convergence, streams),
:mod:`benchmarks.sections` (the five sections), :mod:`benchmarks.report` (tables and
targets), :mod:`benchmarks.run` (command line).  Not part of the test run, except for
its smallest mode (``tests/test_benchmarks.py``).
"""
