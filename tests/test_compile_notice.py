"""The line on standard error while numba compiles algid's kernels (algid._compile_notice)."""

import time

import pytest

from algid import _compile_notice

numba = pytest.importorskip("numba")


def _fresh_kernel(name):
    """A function of an algid module, never compiled (so that numba compiles it)."""
    def kernel(x):
        return x + 1.0
    kernel.__module__ = "algid._compile_notice_test"
    kernel.__qualname__ = name
    return numba.njit(kernel)


@pytest.fixture
def fresh(monkeypatch):
    _compile_notice.watch()
    monkeypatch.setitem(_compile_notice._state, "said", False)


def test_a_compilation_longer_than_the_delay_is_said_once(fresh, monkeypatch, capsys):
    monkeypatch.setattr(_compile_notice, "DELAY", 0.0)
    _fresh_kernel("first")(1.0)
    time.sleep(0.2)   # (the timer's thread)
    _fresh_kernel("second")(1.0)
    time.sleep(0.2)
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "numba is compiling first" in err
    assert _compile_notice.said()


def test_a_short_compilation_and_other_packages_say_nothing(fresh, monkeypatch, capsys):
    monkeypatch.setattr(_compile_notice, "DELAY", 60.0)
    _fresh_kernel("short")(1.0)
    monkeypatch.setattr(_compile_notice, "DELAY", 0.0)
    numba.njit(lambda x: x * 2.0)(1.0)   # not algid's
    time.sleep(0.2)
    assert capsys.readouterr().err == "" and not _compile_notice.said()
