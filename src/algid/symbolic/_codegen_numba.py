"""Code generation: the compiled (numba) estimation loop of a generated model.

The loop performs, sample by sample, exactly the operations of the NumPy backend
(:mod:`algid.estimation._core_numpy`): every integrator is ``y[n] = y[n-1] + inc[n]`` with the
increment ``inc[n] = ((x[n-q+1] w[0] + x[n-q+2] w[1]) + ...) + x[n] w[q-1]`` (see
:func:`algid.signals._quadrature.integrate_padded`); the model algebra is the generated
module's own ``regressors_packed`` and ``cramer``, compiled.  It works on blocks of
:data:`BLOCK` samples: for each level the increments of every sample of the block
first (loops the compiler vectorises), then the running integrals (one dependency
chain per integrator, interleaved across integrators).

A chunk of one sample (a stream fed a sample at a time) takes ``advance_sample``: the
same operations in the same order on the state's own arrays, with no working array.
``advance_sample_pair`` advances an estimator and its companion over one sample and
computes the numerical error (:func:`algid.estimation._numerical_error_numba.sample_error`), in one
compiled call.  With the error propagation active, ``advance`` also forms the companion's
estimates at its grid samples (:mod:`algid.estimation._error_propagation`).

The text depends only on the model: ``python -m derivation`` writes it for every
built-in model beside its NumPy module; a user model gets it in memory
(:func:`algid.symbolic._codegen.compile_model`).
"""

from __future__ import annotations

from algid.estimation._core import layout_of

__all__ = ["numba_module_source", "BLOCK"]

#: Samples per block of the compiled loop.
BLOCK = 256


def _increments_source():
    """Lines of ``_increments``: the increments of a block, written out for every number
    of points so that the compiler unrolls and vectorises each."""
    from algid.signals._quadrature import QUADRATURE_POINTS
    lines = ["@numba.njit(cache=CACHE, nogil=True)",
             "def _increments(src, dst, nb, weights):",
             '    """dst[b] = weights @ src[b : b + points], summed oldest sample first."""',
             "    points = weights.shape[0]"]
    for i, points in enumerate(QUADRATURE_POINTS):
        lines.append(f"    {'if' if i == 0 else 'elif'} points == {points}:")
        lines.append("        " + ", ".join(f"w{j}" for j in range(points)) + ", = weights")
        total = "src[b] * w0"
        for j in range(1, points):
            total = f"{total if j == 1 else '(' + total + ')'} + src[b + {j}] * w{j}"
        lines.append("        for b in range(nb):")
        lines.append(f"            dst[b] = {total}")
    return lines


def _startup_source():
    """Lines of ``_startup_increments``: the first increments after the time origin."""
    return ["@numba.njit(cache=CACHE, nogil=True)",
            "def _startup_increments(src, dst, startup):",
            '    """At the time origin (src[W + i] is sample i): dst[0] = 0 and dst[j], j < W,',
            '    the start-up rule over samples 0 .. W (advance_integrators)."""',
            "    W = startup.shape[1] - 1",
            "    dst[0] = 0.0",
            "    for j in range(1, W):",
            "        acc = src[W] * startup[j - 1, 0]",
            "        for i in range(1, W + 1):",
            "            acc = acc + src[W + i] * startup[j - 1, i]",
            "        dst[j] = acc"]


def _copy_source():
    """Lines of ``_copy``: the first ``count`` values of one row into another.  A loop,
    not a slice assignment: numba compiles each slice assignment's shape-mismatch
    error path anew (about a sixth of a second each, dozens per model)."""
    return ["@numba.njit(cache=CACHE, nogil=True)",
            "def _copy(src, dst, count):",
            '    """dst[:count] = src[:count]."""',
            "    for i in range(count):",
            "        dst[i] = src[i]"]


def _integrate_sample_source():
    """Lines of ``_integrate_sample``: one integrator past one more sample."""
    return ["@numba.njit(cache=CACHE, nogil=True)",
            "def _integrate_sample(integrals, history, k, value, weights):",
            '    """Integrator k past one more integrand sample: its increment summed oldest',
            "    sample first (as _increments), its running integral (returned); the sample",
            '    joins its history."""',
            "    W = weights.shape[0] - 1",
            "    acc = history[k, 0] * weights[0]",
            "    for i in range(1, W):",
            "        acc = acc + history[k, i] * weights[i]",
            "    total = integrals[k] + (acc + value * weights[W])",
            "    for i in range(W - 1):",
            "        history[k, i] = history[k, i + 1]",
            "    history[k, W - 1] = value",
            "    integrals[k] = total",
            "    return total"]


def _propagation_source(a, layout, n_par):
    """Lines that form the companion's estimates at the grid samples of a block, as
    :func:`algid.estimation._error_propagation.companion_estimates` does (the same
    operations in the same order, one grid sample at a time), their relative differences
    from the estimates into ``grid_raw``, then the numerical error of the block's samples
    (:func:`_window_source`)."""
    lanes = layout.n_lanes
    a("        # the companion's estimates at the grid samples (estimation._error_propagation),")
    a("        # and their relative differences from the estimates into grid_raw")
    a("        if error_out.shape[0]:")
    a("            first_grid = (GRID - (n0 + start + 1) % GRID) % GRID")
    a("            b = first_grid")
    a("            while b < nb:")
    a("                j = W + b")
    a("                since = (n0 + start + b + 1 - switch) * dt")
    # the powers since / j! as propagation.companion_estimates forms them, unrolled
    # (literal divisors: the same numbers, the division by 2.0 a product)
    a("                power0 = 1.0")
    for j in range(1, max(1, *(level for level, _ in layout.kernels))):
        a(f"                power{j} = power{j - 1} * since / {float(j)!r}")
    # the telescoped level below every kernel: one loop over the taps, a sum per kernel
    # (independent sums side by side: the loop is not bound by the additions' latency)
    integrated = [(i, level, c) for i, (level, c) in enumerate(layout.kernels) if level]
    a("                base = j - taps.shape[0] + 1")
    for i, level, c in integrated:
        a(f"                t{i} = y{c}_{level - 1}[base] * taps[0]")
    a("                for k in range(1, taps.shape[0]):")
    for i, level, c in integrated:
        a(f"                    t{i} = t{i} + y{c}_{level - 1}[base + k] * taps[k]")
    for i, (level, c) in enumerate(layout.kernels):
        if level:
            a(f"                c{i} = y{c}_{level}[j] + {float(level)!r} * t{i}")
            for j in range(level):
                a(f"                c{i} = c{i} + residuals[{i}, {j}] * power{j}")
        else:
            a(f"                c{i} = y{c}_{level}[j] + 0.0")
    kernels = ", ".join(f"c{i}" for i in range(len(layout.kernels)))
    a(f"                P, Q = _regressors_packed(({kernels},))")
    a("                nums, den = _cramer(P, Q)")
    for r in range(n_par):
        a(f"                g{r} = nums[{r}] - fb[0, {r}, j]")
    a(f"                g{n_par} = den - fb[0, {n_par}, j]")
    for r in range(lanes):
        a(f"                h{r} = lane_difference[{r}]")
        a(f"                lane_difference[{r}] = g{r}")
    a("                for lev in range(filter_order - 1):")
    for r in range(lanes):
        a(f"                    u{r} = fb[lev, {r}, base] * taps[0]")
    a("                    for k in range(1, taps.shape[0]):")
    for r in range(lanes):
        a(f"                        u{r} = u{r} + fb[lev, {r}, base + k] * taps[k]")
    for r in range(lanes):
        # the trapezoid over the grid, plus the telescoped difference of the rules
        a(f"                    step = GRID * dt / 2.0 * (h{r} + g{r})"
          f" + (u{r} - telescoped[lev, {r}])")
        a(f"                    telescoped[lev, {r}] = u{r}")
        a(f"                    h{r} = level_difference[lev, {r}]")
        a(f"                    g{r} = h{r} + step")
        a(f"                    level_difference[lev, {r}] = g{r}")
    a(f"                d = fb[filter_order - 1, {n_par}, j] + g{n_par}")
    _divide(a, "                ", n_par, "d", lambda r: f"o{r}",
            lambda r: f"(fb[filter_order - 1, {r}, j] + g{r})")
    a(f"                raw = {'0.0' if n_par else 'np.nan'}")
    for r in range(n_par):
        a(f"                raw = larger_relative(raw, out[{r}, start + b], o{r})")
    a("                grid_raw[(b - first_grid) // GRID] = raw")
    a("                b += GRID")
    _window_source(a, n_par)


def _window_source(a, n_par):
    """Lines that write the numerical error of a block's samples: the largest finite
    relative difference over the last WINDOW samples
    (:func:`algid.estimation._numerical_error.window_maximum`'s numbers), where the
    differences are 0 but at the grid samples (the estimates stand for the companion's
    there: NaN where an estimate is not finite).  Of a window's samples within the chunk
    only its two grid samples count; of those before it, the suffix maxima of recent."""
    finite = " and ".join(f"abs(out[{r}, c]) < np.inf" for r in range(n_par)) or "False"
    a("            grid = first_grid")
    a("            for b in range(nb):")
    a("                c = start + b")
    a("                if b == grid:")
    a("                    raw = grid_raw[(b - first_grid) // GRID]")
    a("                    grid += GRID")
    a("                    previous = latest")
    a("                    previous_at = latest_at")
    a("                    latest = raw if abs(raw) < np.inf else 0.0")
    a("                    latest_at = c")
    a("                else:")
    a(f"                    raw = 0.0 if {finite} else np.nan")
    a("                largest = max(latest, previous)")
    a("                if c < width:")
    a("                    largest = max(largest, suffix[c])")
    a("                error_out[c] = largest if abs(raw) < np.inf else raw")


def _divide(a, indent, n_par, denominator, target, numerator):
    """Lines that divide the numerators by the denominator into the targets, NaN where
    the denominator is zero or not finite (as the NumPy backend's ``_divide``)."""
    a(f"{indent}if {denominator} == 0.0 or not math.isfinite({denominator}):")
    for r in range(n_par):
        a(f"{indent}    {target(r)} = np.nan")
    a(f"{indent}else:")
    for r in range(n_par):
        a(f"{indent}    {target(r)} = {numerator(r)} / {denominator}")


def _level_zero(a, layout, indent, index):
    """Lines of level 0 of the chains: ``tau**power * channel / divisor`` into y<c>_0."""
    for c, (channel, power, _) in enumerate(layout.chains):
        factor = "tau"
        for _ in range(power - 1):
            factor = f"({factor} * tau)"
        rhs = f"v{channel}" if power == 0 else f"{factor} * v{channel}"
        a(f"{indent}y{c}_0{index} = {rhs}")


def _sample_source(layout, channels, n_par):
    """Lines of ``advance_sample`` and ``advance_sample_pair``."""
    lanes = layout.n_lanes
    names = ", ".join(channels)
    src = ["@numba.njit(cache=CACHE, nogil=True)",
           f"def advance_sample({names}, out, integrals, history, n0, dt, divisors,",
           "                   weights, filter_order):",
           '    """advance over one sample continuing the stream, the channels given as',
           "    numbers: the same operations in the same order, on the state's arrays",
           '    (no working array)."""',
           "    tau = n0 * dt"]
    a = src.append
    for i, name in enumerate(channels):
        a(f"    v{i} = {name}")
        a(f"    if divisors[{i}] != 1.0:")
        a(f"        v{i} = v{i} / divisors[{i}]")
    _level_zero(a, layout, "    ", "")
    a("    # (np.intp(k): one compiled _integrate_sample, not one per literal index)")
    k = 0
    for level, rows in enumerate(layout.levels, start=1):
        for c in rows:
            a(f"    y{c}_{level} = _integrate_sample(integrals, history, np.intp({k}),"
              f" y{c}_{level - 1}, weights)")
            k += 1
    kernels = ", ".join(f"y{row}_{level}" for level, row in layout.kernels)
    a(f"    P, Q = _regressors_packed(({kernels},))")
    a("    nums, den = _cramer(P, Q)")
    lane_values = [f"nums[{r}]" for r in range(n_par)] + ["den"]
    for r, value in enumerate(lane_values):
        a(f"    f{r} = {value}")
    a("    for lev in range(filter_order):")
    for r in range(lanes):
        a(f"        f{r} = _integrate_sample(integrals, history, {k} + lev * {lanes} + {r},"
          f" f{r}, weights)")
    _divide(a, "    ", n_par, f"f{n_par}", lambda r: f"out[{r}, 0]", lambda r: f"f{r}")
    src += ["", "",
            "@numba.njit(cache=CACHE, nogil=True)",
            f"def advance_sample_pair({names}, n0, dt, buffer, offsets, filter_order,",
            "                        other_filter_order, out, error_out):",
            '    """One sample continuing the stream: the estimator (into out), its companion,',
            "    the numerical error (error_out) and the channels' extent, in one call; the",
            "    arrays of both estimators sit in buffer, array i at offsets[i] ..",
            '    offsets[i + 1] (algid.estimation._core_numba.PAIR_ARRAYS)."""',
            "    o = offsets",
            "    integrals = buffer[o[0]:o[1]]",
            "    history = buffer[o[1]:o[2]].reshape((o[1] - o[0], o[5] - o[4] - 1))",
            "    other_integrals = buffer[o[2]:o[3]]",
            "    other_history = buffer[o[3]:o[4]].reshape((o[3] - o[2], o[6] - o[5] - 1))",
            "    weights = buffer[o[4]:o[5]]",
            "    other_weights = buffer[o[5]:o[6]]",
            "    divisors = buffer[o[6]:o[7]]",
            "    other = buffer[o[7]:o[8]].reshape((o[8] - o[7], 1))",
            "    recent = buffer[o[8]:o[9]]",
            "    channel_max = buffer[o[9]:o[10]]",
            "    channel_last = buffer[o[10]:o[11]]",
            f"    advance_sample({names}, out, integrals, history, n0, dt, divisors, weights,",
            "                   filter_order)",
            f"    advance_sample({names}, other, other_integrals, other_history, n0, dt,",
            "                   divisors, other_weights, other_filter_order)",
            "    sample_error(out, other, recent, error_out)"]
    for i, name in enumerate(channels):
        a(f"    sample_extent({name}, divisors[{i}], {i}, channel_max, channel_last)")
    return src


def numba_module_source(module, *, header, cache=True) -> str:
    """Source of the compiled loop of a generated NumPy module.

    Parameters
    ----------
    module : module
        The generated NumPy module (``MODEL``, ``CHAINS``, ``KERNELS``, ``CHANNELS``,
        ``PARAMETERS``, ``regressors_packed``, ``cramer``); its ``__name__`` is
        imported by the loop's module.
    header : str
        How the file was generated (the docstring's last paragraph).
    cache : bool, optional
        Let numba cache the machine code beside the file (needs a file).

    Returns
    -------
    str
    """
    layout = layout_of(module.CHAINS, module.KERNELS, module.CHANNELS, len(module.PARAMETERS))
    n_par = len(module.PARAMETERS)
    lanes = layout.n_lanes
    channels = [f"channel_{i}" for i in range(len(module.CHANNELS))]
    chain_depth = [d for _, _, d in layout.chains]
    src = [f'"""Compiled estimation loop of the model {module.MODEL!r} (numba).', "",
           f"Channels: {', '.join(f'{c} = {n!r}' for c, n in zip(channels, module.CHANNELS))}.",
           "", header, '"""', "", "import math", "", "import numba", "import numpy as np", "",
           f"from {module.__name__} import cramer, regressors_packed",
           "from algid.estimation._error_propagation import GRID",
           "from algid.estimation._numerical_error_numba import larger_relative, sample_error, "
           "sample_extent", "",
           f"CACHE = {bool(cache)!r}", f"BLOCK = {BLOCK}", "",
           "_regressors_packed = numba.njit(cache=CACHE, nogil=True)(regressors_packed)",
           "_cramer = numba.njit(cache=CACHE, nogil=True)(cramer)", "", "",
           *_increments_source(), "", "", *_startup_source(), "", "",
           *_copy_source(), "", "", *_integrate_sample_source(), "", "",
           *_sample_source(layout, channels, n_par), "", "",
           "@numba.njit(cache=CACHE, nogil=True)",
           f"def advance({', '.join(channels)}, out, integrals, history, n0, dt, divisors,",
           "            weights, startup, filter_order, from_origin, taps, residuals,",
           "            switch, lane_difference, level_difference, telescoped, recent,",
           "            error_out):",
           '    """Advance the state (integrals, history) over the chunk; estimates into out.',
           "",
           "    The state layout is that of estimation._core.integrator_layout.  With from_origin",
           "    the chunk starts at the time origin and holds at least len(weights) samples.",
           "    With samples in error_out (as many as the chunk), the error propagation is",
           "    active: the numerical error goes there, recent holds the window's last values",
           "    (estimation._numerical_error); the other arguments are the propagation's state",
           '    (algid.estimation._error_propagation)."""']
    a = src.append
    # max(.., 0): W + b is then known to be non-negative, and the compiler drops the
    # negative-index wraparound from every access (about a fifth of the loop's time)
    a("    W = max(weights.shape[0] - 1, 0)")
    a(f"    size = {channels[0]}.shape[0]")
    a("    if size == 1 and not from_origin and error_out.shape[0] == 0:")
    a(f"        advance_sample({', '.join(c + '[0]' for c in channels)}, out, integrals, history,"
      " n0, dt,")
    a("                       divisors, weights, filter_order)")
    a("        return")
    a("    # the window's state: the largest of recent from every sample on (the window of")
    a("    # the chunk's sample c holds recent[c:]), the last two grid samples' values")
    a("    width = recent.shape[0]")
    a("    suffix = np.empty(width)")
    a("    largest = 0.0")
    a("    for i in range(width - 1, -1, -1):")
    a("        largest = max(largest, recent[i])")
    a("        suffix[i] = largest")
    a("    latest = previous = 0.0")
    a("    latest_at = previous_at = -1")
    a("    # y<c>_<l>[:W]: the last W values of level l of chain c before the block;")
    a("    # y<c>_<l>[W + b]: its value at sample b of the block; views into one scratch")
    a("    # array")
    n_buffers = sum(d + 1 for d in chain_depth)
    a("    blk = max(1, min(BLOCK, size))  # a short chunk needs short buffers")
    a("    span = W + blk")
    a(f"    work = np.empty({n_buffers} * span + {len(chain_depth)} * blk)")
    offset = 0
    for c, d in enumerate(chain_depth):
        for level in range(d + 1):
            a(f"    y{c}_{level} = work[{offset} * span:{offset + 1} * span]")
            offset += 1
    a(f"    at = {n_buffers} * span")
    for c in range(len(chain_depth)):
        a(f"    e{c} = work[at + {c} * blk:at + {c + 1} * blk]")
    # (own arrays, not reshaped views of work: numba compiles reshape's error path)
    a(f"    fb = np.empty((filter_order + 1, {lanes}, span))")
    a(f"    fe = np.empty(({lanes}, blk))")
    a(f"    fs = np.empty((filter_order, {lanes}))")
    a("    grid_raw = np.empty(blk // GRID + 1)")
    k = 0
    for level, rows in enumerate(layout.levels, start=1):
        for c in rows:
            a(f"    s{c}_{level} = integrals[{k}]")
            a(f"    _copy(history[{k}], y{c}_{level - 1}, W)")
            k += 1
    a("    for lev in range(filter_order):")
    a(f"        for r in range({lanes}):")
    a(f"            fs[lev, r] = integrals[{k} + lev * {lanes} + r]")
    a(f"            _copy(history[{k} + lev * {lanes} + r], fb[lev, r], W)")
    for i in range(len(channels)):
        a(f"    d{i} = divisors[{i}]")
    a("    for start in range(0, size, blk):")
    a("        nb = min(blk, size - start)")
    a("        # level 0: tau**power * channel / divisor")
    a("        for b in range(nb):")
    a("            tau = (n0 + start + b) * dt")
    for i, name in enumerate(channels):
        # as NumPy, which divides only by a divisor other than 1 (the same numbers)
        a(f"            v{i} = {name}[start + b]")
        a(f"            if d{i} != 1.0:")
        a(f"                v{i} = v{i} / d{i}")
    _level_zero(a, layout, "            ", "[W + b]")

    def fir(buffer, target):
        a(f"        _increments({buffer}, {target}, nb, weights)")
        a("        if from_origin and start == 0:")
        a(f"            _startup_increments({buffer}, {target}, startup)")

    for level, rows in enumerate(layout.levels, start=1):
        a(f"        # level {level}: the increments (vectorised), then the running integrals")
        for c in rows:
            fir(f"y{c}_{level - 1}", f"e{c}")
        a("        for b in range(nb):")
        for c in rows:
            a(f"            s{c}_{level} = s{c}_{level} + e{c}[b]")
            a(f"            y{c}_{level}[W + b] = s{c}_{level}")
    kernels = ", ".join(f"y{row}_{level}[W + b]" for level, row in layout.kernels)
    a("        # P, Q and Cramer's rule: the generated algebra")
    a("        for b in range(nb):")
    a(f"            P, Q = _regressors_packed(({kernels},))")
    a("            nums, den = _cramer(P, Q)")
    for r in range(n_par):
        a(f"            fb[0, {r}, W + b] = nums[{r}]")
    a(f"            fb[0, {n_par}, W + b] = den")
    a("        # the invariant filter 1/s**p on the numerators and the denominator")
    a("        for lev in range(filter_order):")
    a(f"            for r in range({lanes}):")
    a("                _increments(fb[lev, r], fe[r], nb, weights)")
    a("                if from_origin and start == 0:")
    a("                    _startup_increments(fb[lev, r], fe[r], startup)")
    for r in range(lanes):
        a(f"            t{r} = fs[lev, {r}]")
    a("            for b in range(nb):")
    for r in range(lanes):
        a(f"                t{r} = t{r} + fe[{r}, b]")
        a(f"                fb[lev + 1, {r}, W + b] = t{r}")
    for r in range(lanes):
        a(f"            fs[lev, {r}] = t{r}")
    a("        for b in range(nb):")
    a(f"            d = fb[filter_order, {n_par}, W + b]")
    _divide(a, "            ", n_par, "d", lambda r: f"out[{r}, start + b]",
            lambda r: f"fb[filter_order, {r}, W + b]")
    _propagation_source(a, layout, n_par)
    a("        # the last W values of every integrand start the next block")
    a("        for i in range(W):")
    for c, d in enumerate(chain_depth):
        for level in range(d):
            a(f"            y{c}_{level}[i] = y{c}_{level}[nb + i]")
    a("            for lev in range(filter_order):")
    a(f"                for r in range({lanes}):")
    a("                    fb[lev, r, i] = fb[lev, r, nb + i]")
    k = 0
    for level, rows in enumerate(layout.levels, start=1):
        for c in rows:
            a(f"    integrals[{k}] = s{c}_{level}")
            a(f"    _copy(y{c}_{level - 1}, history[{k}], W)")
            k += 1
    a("    for lev in range(filter_order):")
    a(f"        for r in range({lanes}):")
    a(f"            integrals[{k} + lev * {lanes} + r] = fs[lev, r]")
    a(f"            _copy(fb[lev, r], history[{k} + lev * {lanes} + r], W)")
    a("    if error_out.shape[0]:  # the window's last values: recent's, then the chunk's")
    a("        for i in range(width):")
    a("            recent[i] = recent[i + size] if i + size < width else 0.0")
    a("        if latest_at >= 0 and latest_at >= size - width:")
    a("            recent[width - size + latest_at] = latest")
    a("        if previous_at >= 0 and previous_at >= size - width:")
    a("            recent[width - size + previous_at] = previous")
    return "\n".join(src) + "\n"
