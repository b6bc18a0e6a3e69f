"""The automatic window of identify: its grid reaches the longest window the records
allow, its criterion does not drift with a near-zero parameter's reference, short
records that a fixed window determines are not refused, and a refusal or a warning says
which windows (in seconds) or how much less noise would separate the parameters."""

import re
import sys
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import ROOT

import algid
from algid.errors import AlgidError, ModelError
from algid.identification._window_basis import Separability
from algid.identification._window_rule import (
    HAC_WINDOWS,
    WindowFit,
    choose_window,
    longest_window,
    min_length,
    noise_factor,
    window_advice,
    window_criterion,
)

if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks.window_rule_study import _input, _linear_output, multisine  # noqa: E402

LINEAR = ("y'' + B*y' + K*y = G*u + d", "B K G d")


def _problem(*lengths, parameters=("B", "K", "G", "d")):
    problem = SimpleNamespace(segments=[np.zeros(n) for n in lengths], parameters=parameters)
    problem.share = 1.0
    problem.for_window_rule = lambda length, every_window=False: problem   # (the same)
    return problem


def _fit(stderr, theta, scale, separation=None, noise_model=True):
    stderr, theta = np.asarray(stderr, float), np.asarray(theta, float)
    return WindowFit(theta, np.diag(stderr ** 2), {8: theta, 12: theta},
                     np.asarray(scale, float), None, 100,
                     separation or Separability(1.0, 0.01, np.ones(len(theta))),
                     noise_model=noise_model)


def test_the_grid_reaches_the_longest_window_the_records_allow():
    problem = _problem(30001)
    asked = []

    def solve(problem, length, multiplicities, method):
        asked.append(length)
        return _fit([1.0 / length] * 4, [1.0] * 4, [1.0] * 4)

    choose_window(problem, (8, 12), solve)
    longest = longest_window(problem, min_length((8, 12))) + 1
    # the old grid stopped at a thirtieth of the data (1000 samples)
    assert max(asked) == longest > 30001 // 30
    assert 30001 // longest >= len(problem.parameters) + 8
    assert min(asked) == min_length((8, 12))


def test_the_rule_keeps_the_window_where_every_parameter_is_best():
    """Each parameter's error falls until 2000 samples and rises after: the rule keeps
    2000 (the old grid never looked past 1000)."""
    problem = _problem(30001)

    def solve(problem, length, multiplicities, method):
        error = (length / 2000.0 + 2000.0 / length)
        return _fit([0.01 * error] * 4, [1.0] * 4, [1.0] * 4)

    length, scores = choose_window(problem, (8, 12), solve)
    assert abs(length - 2000) / 2000 < 0.15
    assert scores[length] == min(scores.values())


def test_hac_errors_over_few_windows_do_not_choose_the_window():
    """Where the standard errors are the residuals' own (HAC), a window leaving fewer
    than HAC_WINDOWS independent ones is not compared (its errors are too noisy: the
    smallest wins by chance), unless no other window separates the parameters."""
    problem = _problem(30001)
    free = Separability(1.0, 1.0 / 1.2, np.ones(4))

    def solve(problem, length, multiplicities, method):
        error = 0.01 * 1000.0 / length   # smallest on the longest windows
        return _fit([error] * 4, [1.0] * 4, [1.0] * 4, noise_model=False)

    length, _ = choose_window(problem, (8, 12), solve)
    assert 30001 // length >= HAC_WINDOWS
    # and where only the long windows separate the parameters, they are kept

    def solve_long(problem, length, multiplicities, method):
        fit = solve(problem, length, multiplicities, method)
        fit.separation = fit.separation if length > 1500 else free
        return fit

    length, _ = choose_window(problem, (8, 12), solve_long)
    assert length > 1500


def test_a_near_zero_parameter_does_not_push_the_window_short():
    """The offset's standard error is the same on both windows, but its term's share of
    the known side grows with the window (the window average of y'' shrinks): its
    relative error must not, or the other parameter's better window is lost."""
    fits = {100: _fit([0.02, 0.01], [1.0, 1e-6], [1.0, 1.0]),
            400: _fit([0.01, 0.01], [1.0, 1e-6], [1.0, 4.0])}
    scores = window_criterion(fits)
    assert scores[400] < scores[100]
    assert scores[400] == pytest.approx(1.0)


def test_noise_factor_is_one_when_reliable_and_grows_as_separation_drops():
    reliable = Separability(1.0, 0.1, np.ones(2), noise_ratio=1e3)
    assert noise_factor(reliable) == 1.0
    weak = Separability(1.0, 1.0 / 1.35, np.ones(2), noise_ratio=1e3)
    weaker = Separability(1.0, 1.0 / 1.1, np.ones(2), noise_ratio=1e3)
    assert 1.0 < noise_factor(weak) < noise_factor(weaker)
    # ratio**2 - 1 grows as the signal-to-noise ratio squared: 4 needs 15 / 0.8225
    assert noise_factor(weak) == pytest.approx(np.sqrt(15 / (1.35 ** 2 - 1)))


def test_advice_names_the_windows_in_seconds():
    free = Separability(1.0, 1.0 / 1.2, np.ones(2))
    good = Separability(1.0, 0.1, np.ones(2))
    advice = window_advice({16: free, 101: good, 151: good}, 0.001, {101: 2.0, 151: 1.0})
    assert "windows of 0.1 s to 0.15 s separate them reliably" in advice
    assert "try window=0.15" in advice
    advice = window_advice({16: free, 101: free}, 0.001)
    assert "no window these records allow (0.015 s to 0.1 s) separates them" in advice
    assert re.search(r"output noise about [\d.]+ times smaller", advice)


# --------------------------------------------------------------------------------------
# short records: 2 s, 1.7 periods of the mode, 1 % output noise
# --------------------------------------------------------------------------------------

SHORT_TRUTH = {"B": 0.5, "K": (2 * np.pi * 0.85) ** 2, "G": (2 * np.pi * 0.85) ** 2,
               "d": 0.1}


def short_record(seed, noise=0.01):
    lines = multisine(f_low=0.2, f_high=5.0, count=20)
    t = np.arange(2001) / 1000.0
    y = _linear_output(SHORT_TRUTH, (0.0, 0.0), t, lines)
    y = y + noise * np.std(y) * np.random.default_rng(seed).standard_normal(len(t))
    return {"t": t, "u": _input(t, lines), "y": y}


def test_short_records_a_fixed_window_determines_are_not_refused():
    """On main every one of these was refused ("cannot be separated") by default while
    window=0.1 determined them; by default now each is identified, with errors within
    four reported standard errors."""
    for seed in range(6):
        record = short_record(seed)
        algid.identify(record, *LINEAR, window=0.1, refine=False)   # determined there
        r = algid.identify(record, *LINEAR, refine=False)
        assert not any("cannot" in w for w in r.warnings)
        for p, value in SHORT_TRUTH.items():
            assert abs(r.values[p] - value) <= 4 * r.stderr[p], (seed, p)


def test_a_refused_fixed_window_names_the_windows_to_try():
    with pytest.raises(ModelError) as info:
        algid.identify(short_record(0), *LINEAR, window=0.03, refine=False)
    message = str(info.value)
    assert "cannot be separated" in message and "\n" not in message
    match = re.search(r"windows of ([\d.]+) s to ([\d.]+) s separate them reliably on "
                      r"these records: try window=([\d.]+)", message)
    assert match, message
    low, high, chosen = (float(v) for v in match.groups())
    assert 0.03 < low <= chosen <= high <= 2.0 / 12
    algid.identify(short_record(0), *LINEAR, window=chosen, refine=False)   # and it does


def test_a_poorly_separated_warning_says_what_would_help():
    r = algid.identify(short_record(0), *LINEAR, window=0.1, refine=False)
    weak = [w for w in r.warnings if "poorly separated" in w]
    assert weak and re.search(r"try window=[\d.]+$", weak[0]), r.warnings


def test_a_refusal_of_the_rule_names_the_windows_it_tried():
    """Nothing separates a third-order model's parameters on second-order data at any
    window: the refusal names the range of windows tried and the noise that would."""
    record = short_record(0, noise=0.01)
    with pytest.raises(AlgidError) as info:
        algid.identify(record, "y''' + a2*y'' + a1*y' + a0*y = G*u + G1*u' + d",
                       "a2 a1 a0 G G1 d", refine=False)
    message = str(info.value)
    assert re.search(r"no window these records allow \([\d.]+ s to [\d.]+ s\) separates "
                     r"them", message), message
    assert "times smaller" in message
