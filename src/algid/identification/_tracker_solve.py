"""The per-window solves of :class:`algid.Tracker`: loops compiled by numba when
installed, run as Python otherwise (:func:`algid.identification._tracker_jit.jit`).

On a stream a window end arrives every few samples; here identify's mathematics runs
window after window over systems of ``p + 1 <= 13`` columns, in scalars and fixed-size
arrays (so that it compiles, and can be written in C99):

- :func:`solve_windows`: identify's solve on the accumulated triangular factor
  (columns scaled by powers of two, the triangular inverse), the check that the
  equations separate the parameters (one-sided Jacobi SVD), the parameters determined
  when some columns are proportional (a Givens QR of the kept columns), and the
  bias compensation, :func:`koopmans` (Cholesky reduction of the generalised
  eigenproblem, cyclic Jacobi eigenvalues, or the correction of the noise bound), which
  identify calls too;
- :func:`window_rows`, :func:`step_integrals`: the window equations and their noise
  covariances (quadrature weights of uniform windows, exact integrals of steps);
- :func:`difference_squares`, :func:`noise_bounds`: identify's bound on the output
  noise variance;
- :func:`window_stderr`: the sandwich covariance (centred HAC middle, its negative
  eigenvalues clipped or reflected), the long-run variance factor and the residual of
  the CUSUM.

Each window's result depends on that window's sums alone, so the outputs do not depend
on how the stream is cut into chunks; they agree with :func:`algid.identify` on the same
windows to round-off (identify's least-squares parts call LAPACK).
"""

from __future__ import annotations

import math

import numpy as np

from algid.identification._tracker_jit import jit as _jit
from algid.identification._window_basis import DETERMINED_LEAK, ROUNDOFF_SEPARABILITY
from algid.identification._window_covariance import INDEFINITE_RTOL

__all__ = ["koopmans", "solve_windows", "window_stderr", "window_rows", "step_integrals",
           "difference_squares", "noise_bounds"]


_SWEEPS = 60   # Jacobi sweeps (a few suffice at p <= 12)


@_jit
def _power(x, n):
    """``x ** n`` for an integer ``n``, by repeated squaring as numba computes it, so that
    the loops give the same bits compiled and as Python (whose ``**`` calls ``pow``)."""
    result = 1.0
    base = x
    exponent = -n if n < 0 else n
    while exponent != 0:
        if exponent & 1:
            result *= base
        exponent >>= 1
        base *= base
    return 1.0 / result if n < 0 else result


@_jit
def _product(A, B, transpose_a, transpose_b):
    """``op(A) @ op(B)`` in plain loops (a fixed order of operations, no BLAS call)."""
    n = A.shape[1] if transpose_a else A.shape[0]
    inner = A.shape[0] if transpose_a else A.shape[1]
    m = B.shape[0] if transpose_b else B.shape[1]
    out = np.empty((n, m))
    for i in range(n):
        for j in range(m):
            total = 0.0
            for k in range(inner):
                total += (A[k, i] if transpose_a else A[i, k]) \
                    * (B[j, k] if transpose_b else B[k, j])
            out[i, j] = total
    return out


@_jit
def _svd_jacobi(A, singular, V):
    """One-sided Jacobi SVD of a square ``A`` (destroyed): singular values in decreasing
    order and the right singular vectors (columns of ``V``), high relative accuracy."""
    n = A.shape[1]
    rows = A.shape[0]
    for i in range(n):
        for j in range(n):
            V[i, j] = 1.0 if i == j else 0.0
    for _ in range(_SWEEPS):
        rotated = False
        for i in range(n - 1):
            for j in range(i + 1, n):
                alpha = 0.0
                beta = 0.0
                gamma = 0.0
                for r in range(rows):
                    alpha += A[r, i] * A[r, i]
                    beta += A[r, j] * A[r, j]
                    gamma += A[r, i] * A[r, j]
                if gamma == 0.0 or abs(gamma) <= 1e-17 * math.sqrt(alpha * beta):
                    continue
                rotated = True
                zeta = (beta - alpha) / (2.0 * gamma)
                if abs(zeta) > 1e150:
                    t = 0.5 / zeta
                else:
                    t = math.copysign(1.0, zeta) / (abs(zeta) + math.sqrt(1.0 + zeta * zeta))
                c = 1.0 / math.sqrt(1.0 + t * t)
                s = c * t
                for r in range(rows):
                    ai = A[r, i]
                    aj = A[r, j]
                    A[r, i] = c * ai - s * aj
                    A[r, j] = s * ai + c * aj
                for r in range(n):
                    vi = V[r, i]
                    vj = V[r, j]
                    V[r, i] = c * vi - s * vj
                    V[r, j] = s * vi + c * vj
        if not rotated:
            break
    for j in range(n):
        total = 0.0
        for r in range(rows):
            total += A[r, j] * A[r, j]
        singular[j] = math.sqrt(total)
    for i in range(n):   # decreasing order (selection sort, columns of V along)
        best = i
        for j in range(i + 1, n):
            if singular[j] > singular[best]:
                best = j
        if best != i:
            singular[i], singular[best] = singular[best], singular[i]
            for r in range(n):
                V[r, i], V[r, best] = V[r, best], V[r, i]


@_jit
def _eigh_jacobi(M, values, vectors):
    """Cyclic Jacobi eigen-decomposition of a symmetric ``M`` (its upper triangle; ``M``
    destroyed): eigenvalues in increasing order, eigenvectors in the columns."""
    n = M.shape[0]
    for i in range(n):
        for j in range(n):
            vectors[i, j] = 1.0 if i == j else 0.0
        for j in range(i):
            M[i, j] = M[j, i]
    for _ in range(_SWEEPS):
        rotated = False
        for p in range(n - 1):
            for q in range(p + 1, n):
                apq = M[p, q]
                if apq == 0.0 or abs(apq) <= 1e-18 * math.sqrt(abs(M[p, p] * M[q, q])):
                    continue
                rotated = True
                tau = (M[q, q] - M[p, p]) / (2.0 * apq)
                if abs(tau) > 1e150:
                    t = 0.5 / tau
                else:
                    t = math.copysign(1.0, tau) / (abs(tau) + math.sqrt(1.0 + tau * tau))
                c = 1.0 / math.sqrt(1.0 + t * t)
                s = t * c
                for k in range(n):   # M <- J^T M J, J the rotation in (p, q)
                    mkp = M[k, p]
                    mkq = M[k, q]
                    M[k, p] = c * mkp - s * mkq
                    M[k, q] = s * mkp + c * mkq
                for k in range(n):
                    mpk = M[p, k]
                    mqk = M[q, k]
                    M[p, k] = c * mpk - s * mqk
                    M[q, k] = s * mpk + c * mqk
                M[p, q] = 0.0
                M[q, p] = 0.0
                for k in range(n):
                    vkp = vectors[k, p]
                    vkq = vectors[k, q]
                    vectors[k, p] = c * vkp - s * vkq
                    vectors[k, q] = s * vkp + c * vkq
        if not rotated:
            break
    for i in range(n):
        values[i] = M[i, i]
    for i in range(n):   # increasing order
        best = i
        for j in range(i + 1, n):
            if values[j] < values[best]:
                best = j
        if best != i:
            values[i], values[best] = values[best], values[i]
            for r in range(n):
                vectors[r, i], vectors[r, best] = vectors[r, best], vectors[r, i]


@_jit
def _upper_inverse(U, out):
    """Inverse of an upper triangular matrix with a nonzero diagonal."""
    n = U.shape[0]
    for j in range(n):
        for i in range(n):
            out[i, j] = 0.0
        out[j, j] = 1.0 / U[j, j]
        for i in range(j - 1, -1, -1):
            total = 0.0
            for k in range(i + 1, j + 1):
                total += U[i, k] * out[k, j]
            out[i, j] = -total / U[i, i]


@_jit
def _lu_inverse(A, out):
    """Inverse of a general matrix by LU with partial pivoting; False when singular."""
    n = A.shape[0]
    LU = A.copy()
    perm = np.arange(n)
    for k in range(n):
        pivot = k
        for i in range(k + 1, n):
            if abs(LU[i, k]) > abs(LU[pivot, k]):
                pivot = i
        if LU[pivot, k] == 0.0 or not math.isfinite(LU[pivot, k]):
            return False
        if pivot != k:
            for j in range(n):
                LU[k, j], LU[pivot, j] = LU[pivot, j], LU[k, j]
            perm[k], perm[pivot] = perm[pivot], perm[k]
        for i in range(k + 1, n):
            LU[i, k] /= LU[k, k]
            for j in range(k + 1, n):
                LU[i, j] -= LU[i, k] * LU[k, j]
    column = np.empty(n)
    for j in range(n):
        for i in range(n):
            total = 1.0 if perm[i] == j else 0.0
            for k in range(i):
                total -= LU[i, k] * column[k]
            column[i] = total
        for i in range(n - 1, -1, -1):
            total = column[i]
            for k in range(i + 1, n):
                total -= LU[i, k] * column[k]
            column[i] = total / LU[i, i]
        for i in range(n):
            out[i, j] = column[i]
    return True


@_jit
def koopmans(normal, noise, bound, theta_bar):
    """Koopmans' estimator from the sums of the window equations: the one implementation,
    for :func:`algid.identify`, its systems and :class:`algid.Tracker`.

    The top eigenpair ``(mu, v)`` of the pencil ``(noise, normal)``, both equilibrated by
    the square roots of ``diag(normal)``, gives ``theta_bar = -v / v[p]`` and the noise
    variance ``1 / mu`` when that is at most ``bound``; above it, the correction of
    ``bound`` (least squares with a known variance).  No correction where the noise is
    zero, ``bound`` is not positive or ``normal`` is not positive definite.  The pencil is
    reduced by the Cholesky factor of the equilibrated ``normal`` and solved by cyclic
    Jacobi rotations.

    Parameters
    ----------
    normal : numpy.ndarray, shape (p + 1, p + 1)
        ``Phi^T Phi`` of the window equations ``Phi = [A | b]`` (C-contiguous float64).
    noise : numpy.ndarray, shape (p + 1, p + 1)
        The sum of their per-window noise covariances.
    bound : float
        Upper bound on the output noise variance.
    theta_bar : numpy.ndarray, shape (p + 1,)
        Receives ``(theta, -1)`` where a correction applies.

    Returns
    -------
    float
        The noise variance of the correction: the eigenvalue, or ``bound`` where the
        eigenvalue exceeds it; NaN where no correction applies (plain least squares).

    Examples
    --------
    >>> import numpy as np
    >>> theta_bar = np.empty(2)
    >>> variance = koopmans(np.array([[2.0, 1.0], [1.0, 2.0]]), np.eye(2), np.inf,
    ...                     theta_bar)
    >>> theta_bar.round(6).tolist(), round(float(variance), 6)
    ([1.0, -1.0], 1.0)
    """
    q = normal.shape[0]
    p = q - 1
    eligible = bound > 0
    if eligible:
        eligible = False
        for i in range(q):
            for j in range(q):
                if noise[i, j] != 0.0:
                    eligible = True
    if not eligible:
        return math.nan
    diagonal = np.empty(q)
    for i in range(q):
        d = math.sqrt(normal[i, i])
        diagonal[i] = 1.0 if d == 0.0 else d
    lower = np.zeros((q, q))   # Cholesky factor of the equilibrated normal matrix
    for j in range(q):
        total = normal[j, j] / (diagonal[j] * diagonal[j])
        for k in range(j):
            total -= lower[j, k] * lower[j, k]
        if not total > 0.0:
            return math.nan
        lower[j, j] = math.sqrt(total)
        for i in range(j + 1, q):
            total = normal[i, j] / (diagonal[i] * diagonal[j])
            for k in range(j):
                total -= lower[i, k] * lower[j, k]
            lower[i, j] = total / lower[j, j]
    inverse = np.zeros((q, q))   # of the lower factor
    for j in range(q):
        inverse[j, j] = 1.0 / lower[j, j]
        for i in range(j + 1, q):
            total = 0.0
            for k in range(j, i):
                total += lower[i, k] * inverse[k, j]
            inverse[i, j] = -total / lower[i, i]
    scaled = np.empty((q, q))
    for i in range(q):
        for j in range(q):
            scaled[i, j] = noise[i, j] / (diagonal[i] * diagonal[j])
    reduced = _product(_product(inverse, scaled, False, False), inverse, False, True)
    mu = np.empty(q)
    vectors = np.empty((q, q))
    _eigh_jacobi(reduced, mu, vectors)
    top = mu[q - 1]
    v = np.empty(q)
    for i in range(q):
        total = 0.0
        for k in range(q):
            total += inverse[k, i] * vectors[k, q - 1]
        v[i] = total / diagonal[i]
    if top > 0 and abs(v[p]) * diagonal[p] > 1e-8 and 1.0 / top <= bound:
        for i in range(q):
            theta_bar[i] = -v[i] / v[p]
        return 1.0 / top
    if not (top > 0 and math.isfinite(bound)):
        return math.nan
    H = np.empty((p, p))   # the eigenvalue exceeds the bound: the bound's correction
    g = np.empty(p)
    d = np.empty(p)
    for i in range(p):
        for j in range(p):
            H[i, j] = normal[i, j] - bound * noise[i, j]
        g[i] = normal[i, p] - bound * noise[i, p]
    for i in range(p):
        d[i] = math.sqrt(abs(H[i, i]))
        if d[i] == 0.0:
            d[i] = 1.0
    for i in range(p):
        if not math.isfinite(g[i]):
            return math.nan
        for j in range(p):
            H[i, j] = H[i, j] / d[i] / d[j]
            if not math.isfinite(H[i, j]):
                return math.nan
    Hinv = np.empty((p, p))
    if not _lu_inverse(H, Hinv):
        return math.nan
    for i in range(p):
        total = 0.0
        for k in range(p):
            total += Hinv[i, k] * (g[k] / d[k])
        theta_bar[i] = total / d[i]
    theta_bar[p] = -1.0
    return bound


@_jit
def _smallest_singular(Rs, norms, m):
    """Smallest singular value of the first ``m`` columns of the triangular ``Rs``
    scaled to unit norms."""
    unit = np.empty((m, m))
    for i in range(m):
        for j in range(m):
            unit[i, j] = Rs[i, j] / norms[j]
    singular = np.empty(m)
    V = np.empty((m, m))
    _svd_jacobi(unit, singular, V)
    return singular[m - 1]


@_jit
def _solve_full(R, G, bound, bc, separability, theta, full, jacobian, mapping):
    """identify's solve of one window on its triangular factor ``R`` of ``[A | b]`` and
    noise sums ``G`` (``WindowBasis`` and ``_bias_compensation``); False where the equations do
    not determine every parameter (with ``separability > 0``: where the smallest singular
    value of the unit columns is below it).  A number, not a flag: numba compiles a
    function once per literal flag it is called with."""
    q = R.shape[1]
    p = q - 1
    rows = R.shape[0]
    shifts = np.empty(q, np.int64)
    for j in range(q):
        total = 0.0
        for i in range(rows):
            total += R[i, j] * R[i, j]
        norm = math.sqrt(total)
        if j < p and not norm > 0:
            return False
        shifts[j] = math.frexp(norm)[1] if norm > 0 else 1   # WindowBasis's scaling
    Rs = np.empty((rows, q))
    for i in range(rows):
        for j in range(q):
            Rs[i, j] = math.ldexp(R[i, j], -int(shifts[j]))
    if separability > 0.0:
        unit_norms = np.empty(p)
        for j in range(p):
            total = 0.0
            for i in range(rows):
                total += Rs[i, j] * Rs[i, j]
            unit_norms[j] = math.sqrt(total)
        if not _smallest_singular(Rs, unit_norms, p) >= separability:
            return False
    inverse = np.empty((p, p))
    _upper_inverse(Rs[:p, :p], inverse)
    normal = np.zeros((q, q))
    for i in range(p):
        normal[i, i] = 1.0
        normal[i, p] = Rs[i, p]
        normal[p, i] = Rs[i, p]
    total = 0.0
    for i in range(rows):
        total += Rs[i, p] * Rs[i, p]
    normal[p, p] = total
    for i in range(q):
        for j in range(q):
            full[i, j] = 0.0
    for i in range(p):
        for j in range(p):
            full[i, j] = math.ldexp(inverse[i, j], -int(shifts[i]))
    full[p, p] = math.ldexp(1.0, -int(shifts[p]))
    noise = _product(_product(full, G, True, False), full, False, False)
    phi = np.empty(p)
    for i in range(p):
        phi[i] = Rs[i, p]
    variance = 0.0
    if bc:
        theta_bar = np.empty(q)
        corrected = koopmans(normal, noise, bound, theta_bar)
        if math.isfinite(corrected):
            variance = corrected
            for i in range(p):
                phi[i] = theta_bar[i]
    for i in range(p):
        for j in range(p):
            jacobian[i, j] = (1.0 if i == j else 0.0) - variance * noise[i, j]
            mapping[i, j] = math.ldexp(inverse[i, j], int(shifts[p] - shifts[i]))
    for i in range(p):
        total = 0.0
        for j in range(p):
            total += mapping[i, j] * phi[j]
        theta[i] = total
    return True


@_jit
def _qr_columns(R, columns):
    """The triangular factor of the chosen columns of ``R`` (Givens rotations)."""
    rows = R.shape[0]
    n = columns.shape[0]
    A = np.empty((rows, n))
    for i in range(rows):
        for j in range(n):
            A[i, j] = R[i, columns[j]]
    for j in range(n):
        for i in range(j + 1, rows):
            if A[i, j] == 0.0:
                continue
            r = np.hypot(A[j, j], A[i, j])
            c = A[j, j] / r
            s = A[i, j] / r
            for k in range(j, n):
                ajk = A[j, k]
                aik = A[i, k]
                A[j, k] = c * ajk + s * aik
                A[i, k] = c * aik - s * ajk
            A[i, j] = 0.0
    return A[:n].copy()


@_jit
def _solve_window(R, G, bound, bc, theta, values, full, jacobian, mapping):
    """One window's solve, and where it fails the parameters the equations do determine
    (a parameter without a share :data:`DETERMINED_LEAK` in the null space of the unit
    columns is solved for with, per null direction, the column of largest share
    dropped): the kept columns' count (-1 where not solved); ``values`` the estimates
    in the residuals, ``theta`` NaN where not determined."""
    q = R.shape[1]
    p = q - 1
    norms = np.empty(p)
    positive = True
    unit = np.empty((p, p))
    for j in range(p):
        total = 0.0
        for i in range(p):
            total += R[i, j] * R[i, j]
        norms[j] = math.sqrt(total)
        positive = positive and norms[j] > 0
        scale = norms[j] if norms[j] > 0 else 1.0
        for i in range(p):
            unit[i, j] = R[i, j] / scale
    singular = np.empty(p)
    V = np.empty((p, p))
    _svd_jacobi(unit, singular, V)
    if singular[p - 1] >= ROUNDOFF_SEPARABILITY and positive:
        if not _solve_full(R, G, bound, bc, 0.0, theta, full, jacobian, mapping):
            return -1
        for i in range(p):
            values[i] = theta[i]
        return p
    if not singular[p - 1] < ROUNDOFF_SEPARABILITY:
        return -1
    determined = np.empty(p, np.bool_)
    anything = False
    for j in range(p):
        leak = 0.0
        for r in range(p):
            if singular[r] < ROUNDOFF_SEPARABILITY:
                leak += V[j, r] * V[j, r]
        determined[j] = math.sqrt(leak) < DETERMINED_LEAK and norms[j] > 0
        anything = anything or determined[j]
    if not anything:
        return -1
    keep = np.ones(p, np.bool_)
    for r in range(p):   # per null direction, the column of largest share
        if not singular[r] < ROUNDOFF_SEPARABILITY:
            continue
        best = -1
        for j in range(p):
            if keep[j] and (best < 0 or abs(V[j, r]) > abs(V[best, r])):
                best = j
        if best >= 0:
            keep[best] = False
    m = 0
    for j in range(p):
        m += keep[j]
    if m == 0:
        return -1
    columns = np.empty(m + 1, np.int64)
    k = 0
    for j in range(p):
        if keep[j]:
            columns[k] = j
            k += 1
    columns[m] = p
    reduced = _qr_columns(R, columns)
    Gsub = np.empty((m + 1, m + 1))
    for i in range(m + 1):
        for j in range(m + 1):
            Gsub[i, j] = G[columns[i], columns[j]]
    sub_theta = np.empty(m)
    sub_full = np.empty((m + 1, m + 1))
    sub_jacobian = np.empty((m, m))
    sub_mapping = np.empty((m, m))
    if not _solve_full(reduced, Gsub, bound, bc, ROUNDOFF_SEPARABILITY, sub_theta, sub_full,
                       sub_jacobian, sub_mapping):
        return -1
    for i in range(q):
        for j in range(q):
            full[i, j] = 0.0
    for i in range(p):
        values[i] = 0.0
        for j in range(p):
            jacobian[i, j] = 1.0 if i == j else 0.0
            mapping[i, j] = 0.0
    for a in range(m):
        i = columns[a]
        values[i] = sub_theta[a]
        for b in range(m):
            j = columns[b]
            full[i, j] = sub_full[a, b]
            jacobian[i, j] = sub_jacobian[a, b]
            mapping[i, j] = sub_mapping[a, b]
    full[p, p] = sub_full[m, m]
    for i in range(p):
        theta[i] = values[i] if determined[i] else math.nan
    return m


@_jit
def solve_windows(R, G, top, low, bounds, n_eff, wanted, bc, spare, theta, values, kept, full,
                  jacobian, mapping, lower):
    """Solve the wanted window ends, at the top and the low multiplicity.

    Parameters
    ----------
    R, G : numpy.ndarray, shape (n, m, p + 1, p + 1)
        Triangular factors of ``[A | b]`` and noise sums after each window, per
        multiplicity.
    top, low : int
        The indices of the top and the low multiplicity.
    bounds, n_eff : numpy.ndarray, shape (n,)
        The noise-variance bound and the effective number of windows.
    wanted : numpy.ndarray of bool, shape (n,)
        The window ends to solve.
    bc : bool
        Bias compensation (else least squares).
    spare : int
        Windows needed beyond the parameters solved for.
    theta, values : numpy.ndarray, shape (n, p)
        Estimates (NaN where not determined) and estimates in the residuals (NaN where
        not solved), at the top multiplicity.
    kept : numpy.ndarray of int64, shape (n,)
        Columns solved for.
    full, jacobian, mapping : numpy.ndarray
        The basis quantities of the covariance (shapes (n, p + 1, p + 1), (n, p, p) and
        (n, p, p)), NaN where not solved.
    lower : numpy.ndarray, shape (n, p)
        Estimates at the low multiplicity (their difference: the numerical error).
    """
    n = R.shape[0]
    p = R.shape[2] - 1
    sub_values = np.empty(p)
    sub_full = np.empty((p + 1, p + 1))
    sub_theta = np.empty(p)
    sub_jacobian = np.empty((p, p))
    sub_mapping = np.empty((p, p))
    theta[:] = math.nan
    values[:] = math.nan
    kept[:] = p
    full[:] = math.nan
    jacobian[:] = math.nan
    mapping[:] = math.nan
    lower[:] = math.nan
    for w in range(n):
        if not wanted[w]:
            continue
        m = _solve_window(R[w, top], G[w, top], bounds[w], bc, theta[w], sub_values, full[w],
                          jacobian[w], mapping[w])
        if m < 0 or not n_eff[w] >= m + spare:
            theta[w] = math.nan
            full[w] = math.nan
            jacobian[w] = math.nan
            mapping[w] = math.nan
        else:   # loops, not row assignments (each compiles a shape-mismatch error path)
            for i in range(p):
                values[w, i] = sub_values[i]
            kept[w] = m
        m = _solve_window(R[w, low], G[w, low], bounds[w], bc, sub_theta, sub_values, sub_full,
                          sub_jacobian, sub_mapping)
        if m >= 0 and n_eff[w] >= m + spare:
            for i in range(p):
                lower[w, i] = sub_theta[i]


@_jit
def window_stderr(R, top, W, bars, hac, trace, full, jacobian, mapping, kept, theta, lag_sum,
                  overlap, stderr, kappa, residual):
    """Standard errors, long-run variance factors and CUSUM residuals of the solved
    windows (identify's sandwich with the overlap's and the forgetting's weights), NaN
    elsewhere.

    Parameters
    ----------
    R : numpy.ndarray, shape (n, m, p + 1, p + 1)
        Triangular factors, per multiplicity.
    top : int
        The index of the top multiplicity.
    W : numpy.ndarray, shape (n, 2)
        Sums of the weights and of their squares.
    bars : numpy.ndarray, shape (n, p + 1)
        ``(values, -1)``: the estimates in the residuals.
    hac, trace : numpy.ndarray, shapes (n, p, p), (n,)
        From ``window_scores``.
    full, jacobian, mapping, kept, theta : numpy.ndarray
        From :func:`solve_windows`.
    lag_sum : float
        Sum of the flat-top lag weights.
    overlap : int
        Windows sharing a sample.
    stderr : numpy.ndarray, shape (n, p)
    kappa, residual : numpy.ndarray, shape (n,)
        Outputs.
    """
    n = R.shape[0]
    q = R.shape[2]
    p = q - 1
    stderr[:] = math.nan
    kappa[:] = math.nan
    residual[:] = math.nan
    fitted = np.empty(q)
    mean = np.empty(p)
    middle = np.empty((p, p))
    values = np.empty(p)
    vectors = np.empty((p, p))
    bread = np.empty((p, p))
    for w in range(n):
        if math.isnan(bars[w, 0]):
            continue
        for i in range(q):
            total = 0.0
            for j in range(q):
                total += R[w, top, i, j] * bars[w, j]
            fitted[i] = total
        determined = True
        for i in range(p):
            determined = determined and not math.isnan(theta[w, i])
        if determined:
            total = 0.0
            for i in range(q):
                total += fitted[i] * fitted[i]
            residual[w] = total / W[w, 0]
        for i in range(p):   # centred: the scores' mean is no scatter
            total = 0.0
            for k in range(q):
                total += R[w, top, k, i] * fitted[k]
            mean[i] = -total / W[w, 0]
        weight = (2.0 * lag_sum - 1.0) * W[w, 1]
        trace_hac = 0.0
        for i in range(p):
            for j in range(p):
                hac[w, i, j] -= weight * (mean[i] * mean[j])
            trace_hac += hac[w, i, i]
        kappa[w] = trace_hac / max(trace[w], 1e-300)
        scale = full[w, p, p]
        for i in range(p):   # scale^T hac scale, scale = full[:p, :p] * full[p, p]
            for j in range(p):
                total = 0.0
                for a in range(p):
                    inner = 0.0
                    for b in range(p):
                        inner += hac[w, a, b] * (full[w, b, j] * scale)
                    total += (full[w, a, i] * scale) * inner
                middle[i, j] = total
        _eigh_jacobi(middle, values, vectors)
        definite = values[p - 1] > 0 and values[0] > INDEFINITE_RTOL * values[p - 1]
        for i in range(p):
            values[i] = max(values[i], 0.0) if definite else abs(values[i])
        if not _lu_inverse(jacobian[w], bread):
            continue
        for i in range(p):   # middle <- V diag(values) V^T
            for j in range(p):
                total = 0.0
                for k in range(p):
                    total += vectors[i, k] * values[k] * vectors[j, k]
                middle[i, j] = total
        clipped = _product(_product(bread, middle, False, False), bread, False, True)
        sandwich = (clipped + clipped.T) / 2
        covariance = _product(_product(mapping[w], sandwich, False, False), mapping[w],
                              False, True)
        independent = _power(W[w, 0], 2) / W[w, 1] / overlap
        factor = independent / max(independent - kept[w], 1.0)
        for i in range(p):
            if math.isnan(theta[w, i]):
                continue
            stderr[w, i] = math.sqrt(max(covariance[i, i] * factor, 0.0))


@_jit
def window_rows(fac, sen, starts, step, irregular, weights, derivatives, coefficients,
                columns, sign_terms, noisy, noisy_weights, integrals, rows, grams):
    """The window equations ``[A | b]`` and their noise covariances (identify's kernels and
    ``term_rows``), window after window.

    Parameters
    ----------
    fac, sen : numpy.ndarray, shapes (terms, k), (r, k)
        Factor samples and output sensitivities (of the noisy columns' terms) of the
        segment's buffered samples.
    starts : numpy.ndarray of int64, shape (n,)
        First sample of each window in the buffer.
    step : numpy.ndarray, shape (n,)
        Each window's sampling step.
    irregular : numpy.ndarray of bool, shape (n,)
        Windows whose integrals (and noise covariances) the caller forms.
    weights : numpy.ndarray, shape (m, terms, length)
        Quadrature weights of a uniform window of unit step, per multiplicity and term.
    derivatives, columns : numpy.ndarray of int64, shape (terms,)
        Each term's derivative order and column (``p``: the known side).
    coefficients : numpy.ndarray, shape (terms,)
        Each term's coefficient.
    sign_terms : numpy.ndarray of bool, shape (terms,)
        Terms whose integrals the caller forms (exact integrals of steps).
    noisy : numpy.ndarray of int64, shape (r, 4)
        Per noisy column: its column, derivative order, term and row of ``sen``.
    noisy_weights : numpy.ndarray, shape (r,)
        Per noisy column: its signed coefficient.
    integrals : numpy.ndarray, shape (m, terms, n)
        The window integrals (in place, those of uniform windows of other terms).
    rows : numpy.ndarray, shape (m, n, p + 1)
    grams : numpy.ndarray, shape (m, n, p + 1, p + 1)
        Outputs (``grams``: zero for irregular windows).
    """
    m, terms, length = weights.shape
    n = starts.shape[0]
    q1 = rows.shape[2]
    p = q1 - 1
    r = noisy.shape[0]
    rows[:] = 0.0
    grams[:] = 0.0
    for w in range(n):
        first = starts[w]
        for x in range(m):
            for i in range(terms):
                if not (irregular[w] or sign_terms[i]):
                    total = 0.0
                    for j in range(length):
                        total += fac[i, first + j] * weights[x, i, j]
                    integrals[x, i, w] = total / _power(step[w], derivatives[i])
                value = coefficients[i] * integrals[x, i, w]
                if columns[i] == p:
                    rows[x, w, p] -= value
                else:
                    rows[x, w, columns[i]] += value
            if irregular[w]:
                continue
            for y in range(r):
                c1, k1, i1, s1 = noisy[y, 0], noisy[y, 1], noisy[y, 2], noisy[y, 3]
                for z in range(y, r):
                    c2, k2, i2, s2 = noisy[z, 0], noisy[z, 1], noisy[z, 2], noisy[z, 3]
                    total = 0.0
                    for j in range(length):
                        total += sen[s1, first + j] * sen[s2, first + j] \
                            * (weights[x, i1, j] * weights[x, i2, j])
                    value = total * (_power(step[w], -(k1 + k2)) * (noisy_weights[y]
                                                             * noisy_weights[z]))
                    grams[x, w, c1, c2] += value
                    if y != z:
                        grams[x, w, c2, c1] += value


@_jit
def _chebval(x, c):
    """A Chebyshev series at ``x`` (Clenshaw, as ``numpy.polynomial.chebyshev.chebval``)."""
    if c.shape[0] == 1:
        return c[0]
    if c.shape[0] == 2:
        return c[0] + c[1] * x
    x2 = 2.0 * x
    c0 = c[c.shape[0] - 2]
    c1 = c[c.shape[0] - 1]
    for i in range(3, c.shape[0] + 1):
        tmp = c0
        c0 = c[c.shape[0] - i] - c1
        c1 = tmp + c1 * x2
    return c0 + c1 * x


@_jit
def step_integrals(t, starts, length, levels, times, steps, primitive, derivative, out):
    """Exact window integrals of a piecewise-constant signal (identify's
    ``step_window_integrals`` with ``levels``), window after window.

    Parameters
    ----------
    t : numpy.ndarray
        The buffered sample times.
    starts : numpy.ndarray of int64, shape (n,)
        First sample of each window.
    length : int
        Samples per window.
    levels : numpy.ndarray, shape (n,)
        The signal at each window's start.
    times, steps : numpy.ndarray
        Increasing times of the steps and their sizes.
    primitive : numpy.ndarray
        Chebyshev coefficients of the term kernel's primitive.
    derivative : int
        The term's derivative order.
    out : numpy.ndarray, shape (n,)
    """
    whole = _chebval(1.0, primitive)
    for w in range(starts.shape[0]):
        t0 = t[starts[w]]
        span = t[starts[w] + length - 1] - t0
        end = t0 + span
        total = levels[w] * whole
        for j in range(times.shape[0]):
            if t0 < times[j] < end:
                u = (times[j] - t0) / span
                total += steps[j] * (whole - _chebval(2.0 * u - 1.0, primitive))
        out[w] = total / _power(span, derivative)


@_jit
def difference_squares(y, out):
    """Squared differences of orders 1 to 8 ending at each sample after the first 8 of
    ``y`` (identify's repeated differences, the same operations)."""
    v = np.empty(9)
    for i in range(out.shape[0]):
        for j in range(9):
            v[j] = y[i + j]
        for k in range(8):
            for j in range(8 - k):
                v[j] = v[j + 1] - v[j]
            out[i, k] = _power(v[7 - k], 2)


@_jit
def noise_bounds(sums, central, out):
    """identify's bound on the output noise variance of each window, from its sums of
    squared differences and their counts (the smallest ratio over the orders)."""
    for w in range(sums.shape[0]):
        bound = math.inf
        for k in range(sums.shape[2]):
            ratio = sums[w, 0, k] / sums[w, 1, k] / central[k] if sums[w, 1, k] > 0 \
                else math.inf
            if math.isnan(ratio) or ratio < bound:
                bound = ratio
            if math.isnan(bound):
                break
        out[w] = bound
