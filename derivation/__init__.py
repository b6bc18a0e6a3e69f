"""Regenerates algid's generated estimator modules: ``python -m derivation``."""
