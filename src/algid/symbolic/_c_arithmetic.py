"""The arithmetic of the C estimator, as C text: the code run for every sample.

Functions of the writer of :mod:`algid.symbolic._codegen_c` (its attributes: ``pre``
and ``PRE`` the prefixes ``algid_<name>`` / ``ALGID_<NAME>``, ``algebra_pre`` that of
the ``_algebra`` function the loops call (a companion calls its estimator's), ``p`` the
filter order,
``q`` the points of the rule, ``chains``, ``chain_ints``, ``kernels``, ``P``, ``Q``,
``numerators``, ``denominator``, ...), each returning a list of lines:

- :func:`algebra_function`, :func:`algebra_statements`: ``P``, ``Q`` and Cramer's rule,
  printed by SymPy's C printer;
- :func:`startup_functions`: the first samples after an origin, with the start-up
  rules of :mod:`algid.signals._quadrature`;
- :func:`integrator_step_function`, :func:`sample_loop_function`: one sample at a time
  (short chunks);
- :func:`block_loop_function`: blocks of samples, each level's increments in a loop
  without dependencies (vectorised by the compiler), then the running sums of the
  independent integrators side by side.

Both loops do the same operations in the same order for every sample, so the numbers
do not depend on how a stream is cut.
"""

from __future__ import annotations

from sympy.printing.c import C99CodePrinter

from algid.symbolic._printing import double_constants

__all__ = ["algebra_function", "algebra_statements", "level0", "startup_functions",
           "integrator_step_function", "sample_loop_function", "block_loop_function"]


class _Printer(C99CodePrinter):
    """C99 arithmetic on doubles; small integer powers as products (as NumPy's
    ``x**2`` is ``x * x``), not ``pow``; integers and rationals beyond 2**53 as double
    literals (an integer constant that large is not C)."""

    def _print_Integer(self, expr):
        if abs(expr.p) < 2 ** 53:
            return super()._print_Integer(expr)
        return _double_literal(expr)

    def _print_Rational(self, expr):
        if abs(expr.p) < 2 ** 53 and expr.q < 2 ** 53:
            return super()._print_Rational(expr)
        return _double_literal(expr)

    def _print_Float(self, expr):
        return _double_literal(expr)

    def _print_Pow(self, expr):
        base, exp = expr.args
        if exp.is_Integer and 2 <= int(exp) <= 4:
            factor = self.parenthesize(base, 100)  # always parenthesise a compound base
            return "(" + "*".join([factor] * int(exp)) + ")"
        return super()._print_Pow(expr)


def _double_literal(number) -> str:
    """The nearest double of ``number`` as a C literal that reads back exactly."""
    text = repr(float(number))
    return f"({text})" if text.startswith("-") else text if ("." in text or "e" in text) \
        else text + ".0"


def _code(expr) -> str:
    return _Printer().doprint(double_constants(expr))


def algebra_statements(w, kernel, lane, indent):
    """Statements computing ``P``, ``Q`` and the Cramer numerators and denominator.

    Every expression is printed by SymPy's C printer from the derivation.

    Parameters
    ----------
    w : object
        The writer of :mod:`algid.symbolic._codegen_c` (its attributes, see above).
    kernel : callable
        ``kernel(i)``: C expression of the value of kernel ``i`` (in ``w.kernels`` order).
    lane : callable
        ``lane(r)``: C lvalue for numerator ``r`` (parameter order), ``r = n_parameters``
        for the denominator ``det P``.
    indent : int
        Spaces before each statement.

    Returns
    -------
    list of str
        Lines of C.
    """
    pad = " " * indent
    n_eq, n_par = w.P.shape
    lines = []
    for idx, k in enumerate(w.kernels):
        lines.append(f"{pad}const double {k.name} = {kernel(idx)};  "
                     f"/* {k.order}-fold integral of t**{k.power} {k.signal} */")
    for i in range(n_eq):
        for j in range(n_par):
            lines.append(f"{pad}const double p_{i}_{j} = {_code(w.P[i, j])};")
    for i in range(n_eq):
        lines.append(f"{pad}const double q_{i} = {_code(w.Q[i])};")
    for symbol, value in w.steps:
        lines.append(f"{pad}const double {symbol} = {_code(value)};")
    for r, num in enumerate(w.numerators):
        lines.append(f"{pad}{lane(r)} = {_code(num)};  /* numerator of {w.params[r]} */")
    lines.append(f"{pad}{lane(n_par)} = {_code(w.denominator)};  /* det P */")
    return lines

def algebra_function(w):
    """The static function ``<pre>_algebra(kv, lanes)`` (see :func:`algebra_statements`).

    Parameters
    ----------
    w : object
        The writer of :mod:`algid.symbolic._codegen_c` (its attributes, see above).

    Returns
    -------
    list of str
        Lines of C.
    """
    pre = w.pre
    lines = ["/* P, Q and Cramer's rule from the kernels kv (in the order below); writes",
             "   the numerators (parameter order) and the denominator det P to lanes. */",
             f"static void {pre}_algebra(const double *kv, double *lanes)", "{"]
    lines += algebra_statements(w, lambda i: f"kv[{i}]", lambda r: f"lanes[{r}]", 4)
    lines += ["}", ""]
    return lines


def level0(w, c, tau, u, y):
    """C expression of level 0 of chain ``c``: ``tau**power * signal``.

    Parameters
    ----------
    w : object
        The writer of :mod:`algid.symbolic._codegen_c` (its attributes, see above).
    c : int
        Index of the chain in ``w.chains``.
    tau, u, y : str
        C expressions of the time since the origin, the input and the output.

    Returns
    -------
    str
        ``tau * tau`` for power 2, as NumPy computes ``tau**2``.
    """
    signal, power, _ = w.chains[c]
    value = u if signal == w.model.input else y
    if power == 0:
        return value
    factor = "*".join([tau] * power)
    return f"({factor}) * {value}" if power > 1 else f"{tau} * {value}"

def startup_functions(w):
    """The first samples after an origin, by a start-up rule given as data.

    ``<pre>_start_level``, ``<pre>_start`` and ``<pre>_early``, for a ``<pre>_rule``.
    ``<pre>_start`` integrates samples ``0 .. n - 1`` with the rule of ``n <= q``
    points and reports sample ``n - 1``: the estimator's own rule once sample
    ``q - 1`` has arrived, and the rules of fewer points for the samples before it
    (:func:`algid.estimation._core.first_estimate`), through ``<pre>_early``, which works on a copy
    of the window.  One function for every rule, with the operations of the Python
    backends in the same order.

    Parameters
    ----------
    w : object
        The writer of :mod:`algid.symbolic._codegen_c` (its attributes, see above).

    Returns
    -------
    list of str
        Lines of C.
    """
    pre, q = w.pre, w.q
    lines = [
        "/* Integrate the n samples a[0 .. n-1] of an integrand with the start-up rule",
        "   of n points; set integrator k to its state after sample n-1; out[j]: the",
        "   integral. */",
        f"static void {pre}_start_level({pre}_window *w, int k, const double *a, double dt,",
        f"{' ' * (len(pre) + 18)}double *out, const {pre}_rule *rule)",
        "{",
        f"    double inc[{q - 1}];",
        "    double s = 0.0;",
        "    const int n = rule->n;",
        "    int i, j;",
        "    for (j = 0; j < n - 2; ++j) {",
        "        double acc = (rule->ws[j * n] * dt) * a[0];",
        "        for (i = 1; i < n; ++i) acc += (rule->ws[j * n + i] * dt) * a[i];",
        "        inc[j] = acc;",
        "    }",
        "    inc[n - 2] = (rule->w[0] * dt) * a[0];",
        "    for (i = 1; i < n; ++i) inc[n - 2] += (rule->w[i] * dt) * a[i];",
        "    out[0] = 0.0;",
        "    for (j = 1; j < n; ++j) {",
        "        s += inc[j - 1];", "        out[j] = s;", "    }",
        "    w->sum[k] = s;",
        "    for (i = 0; i < n - 1; ++i) w->hist[k][i] = a[i + 1];",
        "}", "",
        "/* Samples 0 .. n-1 after the origin by the rule of n points: the estimate of",
        "   sample n-1 into theta. */",
        f"static void {pre}_start({pre}_window *w, double dt, double *theta, "
        f"const {pre}_rule *rule)",
        "{",
        f"    double lv[{w.levels}][{q}] = {{{{0.0}}}};  /* every level of every chain */",
        f"    double lanes[{w.p + 1}][{w.lanes}][{q}] = {{{{{{0.0}}}}}};",
        f"    double kv[{len(w.kernels)}], row[{w.lanes}];",
        "    const int n = rule->n;",
        "    int j, r;"]
    if w.p:
        lines.append("    int lev;")
    base = {}
    offset = 0
    for c, (_, _, d) in enumerate(w.chains):
        base[c] = offset
        offset += d + 1
    lines.append("    for (j = 0; j < n; ++j) {")
    lines.append("        const double tau = (double)j * dt;")
    for c in range(len(w.chains)):
        lines.append(f"        lv[{base[c]}][j] = "
                     f"{level0(w, c, 'tau', 'w->start_u[j]', 'w->start_y[j]')};")
    lines.append("    }")
    for k, (c, lev) in enumerate(w.chain_ints):
        lines.append(f"    {pre}_start_level(w, {k}, lv[{base[c] + lev - 1}], dt, "
                     f"lv[{base[c] + lev}], rule);")
    lines.append("    for (j = 0; j < n; ++j) {")
    chain_of = {(s, pw): c for c, (s, pw, _) in enumerate(w.chains)}
    for idx, k in enumerate(w.kernels):
        c = chain_of[(k.signal, k.power)]
        lines.append(f"        kv[{idx}] = lv[{base[c] + k.order}][j];")
    lines += [f"        {w.algebra_pre}_algebra(kv, row);",
              f"        for (r = 0; r < {w.lanes}; ++r) lanes[0][r][j] = row[r];",
              "    }"]
    if w.p:
        n_chain = len(w.chain_ints)
        lines += [f"    for (lev = 0; lev < {w.p}; ++lev) {{",
                  f"        for (r = 0; r < {w.lanes}; ++r) {{",
                  f"            {pre}_start_level(w, {n_chain} + lev * {w.lanes} + r, "
                  "lanes[lev][r], dt, lanes[lev + 1][r], rule);",
                  "        }", "    }"]
    lines += [f"    for (r = 0; r < {w.lanes}; ++r) row[r] = lanes[{w.p}][r][n - 1];",
              f"    {pre}_divide(row, theta);", "}", ""]
    if w.early_points:
        lines += ["/* The estimate of sample n-1 by the rule of n < q points, before the",
                  "   start-up of the estimator's own rule (the window is left as it is). */",
                  f"static void {pre}_early(const {pre}_window *w, double dt, double *theta,",
                  f"{' ' * (len(pre) + 13)}const {pre}_rule *rule)",
                  "{", f"    {pre}_window scratch = *w;",
                  f"    {pre}_start(&scratch, dt, theta, rule);", "}", ""]
    return lines


def integrator_step_function(w):
    """``<pre>_integrate``: one sample through one integrator (the per-sample loop).

    Parameters
    ----------
    w : object
        The writer of :mod:`algid.symbolic._codegen_c` (its attributes, see above).

    Returns
    -------
    list of str
        Lines of C.
    """
    pre, q = w.pre, w.q
    m = q - 1
    terms = " + ".join([f"({pre}_w[{i}] * dt) * hist[{i}]" for i in range(m)]
                      + [f"({pre}_w[{m}] * dt) * v"])
    lines = [
        "/* One step of an integrator: v is its integrand at this sample; returns the",
        "   integral.  The increment is summed left to right, as NumPy does. */",
        f"static double {pre}_integrate(double *sum, double *hist, double v, double dt)",
        "{",
        f"    const double inc = {terms};",
    ]
    lines += [f"    hist[{i}] = hist[{i + 1}];" for i in range(m - 1)]
    lines += [f"    hist[{m - 1}] = v;", "    *sum += inc;", "    return *sum;", "}", ""]
    return lines

def sample_loop_function(w):
    """``<pre>_samples``: samples after the start-up, one at a time (short chunks).

    Parameters
    ----------
    w : object
        The writer of :mod:`algid.symbolic._codegen_c` (its attributes, see above).

    Returns
    -------
    list of str
        Lines of C.
    """
    pre = w.pre
    lines = [
        "/* Samples after the start-up (w->n >= q), one by one: for short chunks, where",
        "   the set-up of a block costs more than it saves.  Same arithmetic as the blocks. */",
        f"static void {pre}_samples({pre}_window *w, const double *u, const double *y, size_t n,",
        f"{' ' * (len(pre) + 16)}double dt, double *theta{_grid_parameters(w)})",
        "{",
        "    double *const s = w->sum;",
        f"    double (*const h)[{w.PRE}_M] = w->hist;",
        "    double count = w->n;",
        f"    double kv[{len(w.kernels)}], lanes[{w.lanes}];",
        "    size_t i;",
    ]
    if w.grid:
        lines += [f"    double below[{len(w.kernels)}], fir[{_grid_levels(w) * w.lanes}], "
                  f"lanes0[{w.lanes}], top[{w.lanes}];",
                  "    int on_grid, r;"]
    lines += [
        "    for (i = 0; i < n; ++i, count += 1.0) {",
        "        const double tau = count * dt;",
    ]
    if w.grid:
        lines.append(f"        on_grid = g != NULL && fmod(count + 1.0, {w.grid_step}.0) == 0.0;")
    value = {}
    for c in range(len(w.chains)):
        lines.append(f"        const double c{c}_0 = {level0(w, c, 'tau', 'u[i]', 'y[i]')};")
        value[(c, 0)] = f"c{c}_0"
    chain_of = {(s, pw): c for c, (s, pw, _) in enumerate(w.chains)}
    # the kernels whose level below is this integrator's integrand (the grid's sums of
    # that integrand, before the step moves its history on)
    fed_by = {}
    for idx, k in enumerate(w.kernels):
        if k.order:
            fed_by.setdefault((chain_of[(k.signal, k.power)], k.order), []).append(idx)
    # level by level: independent chains side by side
    for c, lev in sorted(w.chain_ints, key=lambda cl: (cl[1], cl[0])):
        idx = w.chain_ints.index((c, lev))
        for kernel in fed_by.get((c, lev), []) if w.grid else []:
            lines.append(f"        below[{kernel}] = on_grid ? {pre}_sum_history(h[{idx}], "
                         f"c{c}_{lev - 1}, g->taps) : 0.0;")
        lines.append(f"        const double c{c}_{lev} = {pre}_integrate(&s[{idx}], h[{idx}], "
                     f"c{c}_{lev - 1}, dt);")
    for idx, k in enumerate(w.kernels):
        lines.append(f"        kv[{idx}] = c{chain_of[(k.signal, k.power)]}_{k.order};")
        if w.grid and not k.order:
            lines.append(f"        below[{idx}] = 0.0;")
    lines.append(f"        {w.algebra_pre}_algebra(kv, lanes);")
    if w.grid:
        lines.append(f"        for (r = 0; r < {w.lanes}; ++r) lanes0[r] = lanes[r];")
    n_chain = len(w.chain_ints)
    for lev in range(w.p):
        if w.grid and lev == w.p - 1:
            lines.append(f"        for (r = 0; r < {w.lanes}; ++r) top[r] = lanes[r];")
        for r in range(w.lanes):
            k = n_chain + lev * w.lanes + r
            if w.grid and lev < w.p - 1:
                lines.append(f"        if (on_grid) fir[{lev * w.lanes + r}] = "
                             f"{pre}_sum_history(h[{k}], lanes[{r}], g->taps);")
            lines.append(f"        lanes[{r}] = {pre}_integrate(&s[{k}], h[{k}], lanes[{r}], dt);")
    lines.append(f"        {pre}_divide(lanes, theta + i * {w.n_par});")
    if w.grid:
        lines += _grid_row(w, "i", "count", "        ")
    lines += ["    }", "    w->n = count;", "}", ""]
    return lines


def _grid_levels(w):
    """Rows of the grid's filter arrays (at least one: C has no empty arrays)."""
    return max(1, w.p - 1)


def _grid_parameters(w):
    """The extra parameters of an estimator's loops that form the propagated companion
    (:mod:`algid.estimation._error_propagation`): its state and the companion's rows."""
    return f",\n{' ' * (len(w.pre) + 16)}{w.pre}_grid *g, double *other" if w.grid else ""


def _grid_row(w, row, count, pad):
    """Lines that write row ``row`` of ``other`` at a grid sample: the companion's
    estimates (the kernels, the sums below, the filter's sums, lanes0 and top gathered;
    the other rows are not read)."""
    return [f"{pad}if (g != NULL && on_grid) {{",
            *_grid_call(w, count, row, pad + "    "),
            f"{pad}}}"]

def _grid_call(w, count, row, pad):
    """The call that writes the companion's estimates at the grid sample whose count
    since the origin is ``count`` (before it) into row ``row`` of ``other``."""
    return [f"{pad}{w.pre}_grid_other(g, kv, below, fir, lanes0, top,",
            f"{pad}{' ' * (len(w.pre) + 12)}({count} + 1.0 - {w.grid_switch}.0) * dt, dt,",
            f"{pad}{' ' * (len(w.pre) + 12)}other + {row} * {w.n_par});"]


def block_loop_function(w):
    """``<pre>_blocks``: samples after the start-up, in blocks (long chunks).

    Parameters
    ----------
    w : object
        The writer of :mod:`algid.symbolic._codegen_c` (its attributes, see above).

    Returns
    -------
    list of str
        Lines of C.
    """
    pre, P, q = w.pre, w.PRE, w.q
    m = q - 1
    n_chain = len(w.chain_ints)
    base, offset = {}, 0
    for c, (_, _, d) in enumerate(w.chains):
        base[c] = offset
        offset += d + 1
    chain_of = {(s, pw): c for c, (s, pw, _) in enumerate(w.chains)}
    fir = " + ".join(f"({pre}_w[{j}] * dt) * a[b + {j}]" for j in range(q))
    lines = [
        "/* Samples after the start-up (w->n >= q), a block of at most BLOCK samples at",
        "   a time: for each level the increments of the block (a loop without",
        "   dependencies), then the running sums.  Row lv[l] (fl[f][r] for the filter)",
        "   holds the last M values of a level before the block, then its values over",
        "   the block.  Each sample gets the same arithmetic whatever the block. */",
        "#if defined(__GNUC__) && !defined(__clang__) && __GNUC__ >= 6 \\",
        "    && defined(__x86_64__) && defined(__linux__)",
        "/* GCC on x86-64 Linux: a second copy of this loop for processors with AVX2",
        "   (four doubles per instruction instead of two), chosen when the library is",
        "   loaded.  The avx2 target has no fused multiply-add: same numbers. */",
        '__attribute__((target_clones("avx2", "default")))',
        "#endif",
        f"static void {pre}_blocks({pre}_window *w, const double *u, const double *y, size_t n,",
        f"{' ' * (len(pre) + 15)}double dt, double *theta{_grid_parameters(w)})",
        "{",
        f"    double lv[{w.levels}][{P}_M + {P}_BLOCK];",
        f"    double fl[{w.p + 1}][{w.lanes}][{P}_M + {P}_BLOCK];",
        f"    double inc[{w.width}][{P}_BLOCK];",
        f"    double row[{w.lanes}];",
        f"    double s[{P}_NI];",
        "    double count = w->n;",
        "    size_t start, b, nb;",
        "    int k, i, r;",
        "    const double *a;",
        f"    double acc[{w.width}];",
    ]
    if w.p:
        lines.append("    int lev;")
    if w.grid:
        lines += [f"    double kv[{len(w.kernels)}], below[{len(w.kernels)}], "
                  f"fir[{_grid_levels(w) * w.lanes}], lanes0[{w.lanes}], top[{w.lanes}];"]
    lines += [f"    for (k = 0; k < {P}_NI; ++k) s[k] = w->sum[k];",
              f"    for (i = 0; i < {P}_M; ++i) {{"]
    for k, (c, lev) in enumerate(w.chain_ints):
        lines.append(f"        lv[{base[c] + lev - 1}][i] = w->hist[{k}][i];")
    if w.p:
        lines += [f"        for (lev = 0; lev < {w.p}; ++lev) {{",
                  f"            for (r = 0; r < {w.lanes}; ++r) "
                  f"fl[lev][r][i] = w->hist[{n_chain} + lev * {w.lanes} + r][i];",
                  "        }"]
    lines += ["    }",
              "    for (start = 0; start < n; start += nb) {",
              f"        nb = n - start < {P}_BLOCK ? n - start : {P}_BLOCK;",
              "        if (nb < " + P + "_BLOCK) {  /* the increments run over whole blocks",
              "                                   (a loop the compiler vectorises): give the",
              "                                   unused tail defined values */",
              f"            for (b = {P}_M + nb; b < {P}_M + {P}_BLOCK; ++b) {{",
              f"                for (k = 0; k < {w.levels}; ++k) lv[k][b] = 0.0;",
              f"                for (i = 0; i < {w.p + 1}; ++i) {{",
              f"                    for (r = 0; r < {w.lanes}; ++r) fl[i][r][b] = 0.0;",
              "                }",
              "            }",
              "        }",
              "        for (b = 0; b < nb; ++b) {",
              "            const double tau = (count + (double)b) * dt;"]
    for c in range(len(w.chains)):
        lines.append(f"            lv[{base[c]}][{P}_M + b] = "
                     f"{level0(w, c, 'tau', 'u[start + b]', 'y[start + b]')};")
    lines.append("        }")

    def integrate(pairs, indent):
        # pairs: (integrand row, integral row, integrator index); the increments
        # of each, then one loop of running sums: independent dependency chains
        # side by side
        pad = " " * indent
        out = []
        for j, (src, _, _) in enumerate(pairs):
            out += [f"{pad}a = {src};",
                    f"{pad}for (b = 0; b < {P}_BLOCK; ++b) inc[{j}][b] = {fir};"]
        for j, (_, _, k) in enumerate(pairs):
            out.append(f"{pad}acc[{j}] = s[{k}];")
        out.append(f"{pad}for (b = 0; b < nb; ++b) {{")
        for j, (_, dst, _) in enumerate(pairs):
            out += [f"{pad}    acc[{j}] += inc[{j}][b];",
                    f"{pad}    {dst}[{P}_M + b] = acc[{j}];"]
        out.append(f"{pad}}}")
        for j, (_, _, k) in enumerate(pairs):
            out.append(f"{pad}s[{k}] = acc[{j}];")
        return out

    depth = max(d for _, _, d in w.chains)
    for level in range(1, depth + 1):
        pairs = [(f"lv[{base[c] + level - 1}]", f"lv[{base[c] + level}]",
                  w.chain_ints.index((c, level)))
                 for c, (_, _, d) in enumerate(w.chains) if d >= level]
        lines += integrate(pairs, 8)
    # straight-line code over the whole block, as the increments: vectorised
    lines.append(f"        for (b = 0; b < {P}_BLOCK; ++b) {{")

    def kernel_row(idx):
        kern = w.kernels[idx]
        return f"lv[{base[chain_of[(kern.signal, kern.power)]] + kern.order}][{P}_M + b]"

    lines += algebra_statements(w, kernel_row, lambda r: f"fl[0][{r}][{P}_M + b]", 12)
    lines.append("        }")
    if w.p:
        lines += [f"        for (lev = 0; lev < {w.p}; ++lev) {{"]
        lines += integrate([(f"fl[lev][{r}]", f"fl[lev + 1][{r}]",
                             f"{n_chain} + lev * {w.lanes} + {r}")
                            for r in range(w.lanes)], 12)
        lines += ["        }"]
    lines += ["        for (b = 0; b < nb; ++b) {",
              f"            for (r = 0; r < {w.lanes}; ++r) row[r] = fl[{w.p}][r][{P}_M + b];",
              f"            {pre}_divide(row, theta + (start + b) * {w.n_par});",
              "        }"]
    if w.grid:
        step = w.grid_step
        lines += ["        /* the propagated companion (algid.estimation._error_propagation) at",
                  "           the grid samples (the estimates stand in for it elsewhere) */",
                  "        if (g != NULL) {",
                  f"            for (b = (size_t)fmod({step}.0 - fmod(count + 1.0, {step}.0), "
                  f"{step}.0); b < nb; b += {step}) {{",
                  "                const size_t j = " + P + "_M + b;"]
        for idx in range(len(w.kernels)):
            kern = w.kernels[idx]
            row = base[chain_of[(kern.signal, kern.power)]] + kern.order
            lines.append(f"                kv[{idx}] = lv[{row}][j];")
            below = f"{pre}_sum_block(lv[{row - 1}], j, g->taps)" if kern.order else "0.0"
            lines.append(f"                below[{idx}] = {below};")
        lines += [f"                for (r = 0; r < {w.lanes}; ++r) {{",
                  "                    lanes0[r] = fl[0][r][j];",
                  f"                    top[r] = fl[{w.p - 1}][r][j];",
                  "                }"]
        if w.p > 1:
            lines += [f"                for (lev = 0; lev < {w.p - 1}; ++lev) {{",
                      f"                    for (r = 0; r < {w.lanes}; ++r) "
                      f"fir[lev * {w.lanes} + r] = {pre}_sum_block(fl[lev][r], j, g->taps);",
                      "                }"]
        lines += [*_grid_call(w, "(count + (double)b)", "(start + b)", " " * 16),
                  "            }",
                  "        }"]
    lines += ["        /* the last M values of every level start the next block */",
              f"        for (i = 0; i < {P}_M; ++i) {{",
              f"            for (k = 0; k < {w.levels}; ++k) lv[k][i] = lv[k][nb + (size_t)i];"]
    if w.p:
        lines += [f"            for (lev = 0; lev < {w.p}; ++lev) {{",
                  f"                for (r = 0; r < {w.lanes}; ++r) "
                  "fl[lev][r][i] = fl[lev][r][nb + (size_t)i];",
                  "            }"]
    lines += ["        }", "        count += (double)nb;", "    }",
              f"    for (k = 0; k < {P}_NI; ++k) w->sum[k] = s[k];",
              f"    for (i = 0; i < {P}_M; ++i) {{"]
    for k, (c, lev) in enumerate(w.chain_ints):
        lines.append(f"        w->hist[{k}][i] = lv[{base[c] + lev - 1}][i];")
    if w.p:
        lines += [f"        for (lev = 0; lev < {w.p}; ++lev) {{",
                  f"            for (r = 0; r < {w.lanes}; ++r) "
                  f"w->hist[{n_chain} + lev * {w.lanes} + r][i] = fl[lev][r][i];",
                  "        }"]
    lines += ["    }", "    w->n = count;", "}", ""]
    del m
    return lines

