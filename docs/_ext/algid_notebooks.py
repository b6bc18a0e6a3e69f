"""Execute the teaching notebooks once, for the tests and for the documentation.

Each ``notebooks/<name>.py`` (jupytext percent format) is run top to bottom by nbclient
in a fresh kernel, with matplotlib's inline backend (figures become PNG outputs) and,
in quick mode, ``ALGID_NOTEBOOK_QUICK=1`` (small Monte Carlo sizes and records).  Every
notebook collects the numbers behind its claims in a dict ``RESULTS``, in cells tagged
``remove-cell`` (myst-nb leaves them out of the page): one extra cell prints it as
JSON, the numbers are read back and stored in the notebook's metadata
(``metadata["algid"]["results"]``), and the extra cell is removed.  The executed notebook
is written as ``<out_dir>/<name>.ipynb``, which the documentation renders as it is.

A notebook already executed for the same source, the same ``src/algid`` tree and the
same mode is reused unless ``reuse=False``; ``tests/test_notebooks.py`` executes anew
once per test session and the documentation build of that session reuses the result.
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
NOTEBOOKS = ROOT / "notebooks"
MARKER = "ALGID_NOTEBOOK_RESULTS="
CELL_TIMEOUT = 900  # seconds; the quick workload takes a few seconds per notebook
INLINE_BACKEND = "module://matplotlib_inline.backend_inline"


def notebook_names():
    """Every notebook of ``notebooks/`` (``NN_name``), in order."""
    return sorted(p.stem for p in NOTEBOOKS.glob("[0-9][0-9]_*.py"))


def runs_this_python(argv0: str) -> bool:
    """Whether a kernel command starting with ``argv0`` runs this interpreter.

    jupyter_client replaces a bare ``python``, ``python3`` or ``python3.X`` by
    ``sys.executable``; any other path must be this interpreter itself.
    """
    major, minor = sys.version_info[:2]
    if argv0 in ("python", f"python{major}", f"python{major}.{minor}"):
        return True
    try:
        return os.path.samefile(argv0, sys.executable)
    except OSError:
        return False


def find_kernel(spare_dir):
    """``(kernel_name, KernelSpecManager or None)`` for a kernel running this Python.

    The ``python3`` kernel spec that ipykernel installs into the environment is used
    when it runs this interpreter (``None``: the default spec manager finds it).
    Otherwise (no such spec, or one for another Python) a private spec for
    ``sys.executable`` is written under ``spare_dir`` and a spec manager that looks
    only there is returned.
    """
    from jupyter_client.kernelspec import KernelSpecManager, NoSuchKernel

    try:
        spec = KernelSpecManager().get_kernel_spec("python3")
        if spec.argv and runs_this_python(spec.argv[0]):
            return "python3", None
    except NoSuchKernel:
        pass
    from ipykernel.kernelspec import write_kernel_spec

    write_kernel_spec(path=str(Path(spare_dir) / "python3"))  # argv[0] = sys.executable
    return "python3", KernelSpecManager(kernel_dirs=[str(spare_dir)])


def fingerprint(name: str, quick: bool) -> str:
    """Hash of the notebook's source, of every file of ``src/algid`` and of the mode."""
    digest = hashlib.sha256(f"quick={bool(quick)}".encode())
    for path in [NOTEBOOKS / f"{name}.py", *sorted((ROOT / "src" / "algid").rglob("*.py"))]:
        digest.update(str(path.relative_to(ROOT)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def execute_notebook(name: str, out_dir, *, quick: bool, kernel=None):
    """Execute ``notebooks/<name>.py`` into ``<out_dir>/<name>.ipynb``.

    Parameters
    ----------
    name : str
        The notebook's stem, e.g. ``"01_derivation"``.
    out_dir : path-like
        Where the executed notebook is written.
    quick : bool
        Run with ``ALGID_NOTEBOOK_QUICK=1``.
    kernel : tuple, optional
        ``(kernel_name, KernelSpecManager or None)`` from :func:`find_kernel`.

    Returns
    -------
    results : dict
        The notebook's ``RESULTS``.
    seconds : float
        Execution time.
    """
    import jupytext
    import nbclient
    import nbformat
    from jupyter_client import KernelManager

    if kernel is None:
        kernel = find_kernel(Path(tempfile.mkdtemp(prefix="algid-kernel-")))
    kernel_name, spec_manager = kernel
    nb = jupytext.read(NOTEBOOKS / f"{name}.py")
    nb.cells.append(nbformat.v4.new_code_cell(
        f"import json\nprint({MARKER!r} + json.dumps(RESULTS, default=str))"))
    env = dict(os.environ, MPLBACKEND=INLINE_BACKEND)
    env.pop("ALGID_NOTEBOOK_QUICK", None)
    if quick:
        env["ALGID_NOTEBOOK_QUICK"] = "1"
    km = None
    if spec_manager is not None:
        km = KernelManager(kernel_name=kernel_name, kernel_spec_manager=spec_manager)
    client = nbclient.NotebookClient(
        nb, km=km, kernel_name=kernel_name, timeout=CELL_TIMEOUT, allow_errors=False,
        resources={"metadata": {"path": str(NOTEBOOKS)}})
    start = time.perf_counter()
    client.execute(env=env)  # raises CellExecutionError on the first failing cell
    elapsed = time.perf_counter() - start
    marker_cell = nb.cells.pop()
    text = "".join(out.get("text", "") for out in marker_cell.outputs
                   if out.get("output_type") == "stream")
    line = next(ln for ln in text.splitlines() if ln.startswith(MARKER))
    results = json.loads(line[len(MARKER):])
    nb.metadata["algid"] = {"results": results, "quick": bool(quick),
                            "seconds": round(elapsed, 1),
                            "fingerprint": fingerprint(name, quick)}
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    tmp = out / f".{name}.ipynb.tmp"
    nbformat.write(nb, tmp)
    tmp.replace(out / f"{name}.ipynb")  # never a half-written notebook
    return results, elapsed


def is_fresh(name: str, out_dir, quick: bool) -> bool:
    """Whether ``<out_dir>/<name>.ipynb`` was executed from the current sources and mode."""
    path = Path(out_dir) / f"{name}.ipynb"
    if not path.exists():
        return False
    try:
        meta = json.loads(path.read_text(encoding="utf-8"))["metadata"]["algid"]
    except (ValueError, KeyError):
        return False
    return meta.get("fingerprint") == fingerprint(name, quick)


def execute_all(out_dir, *, quick: bool, reuse: bool = True, log=print):
    """Execute every notebook into ``out_dir`` (or keep a fresh one when ``reuse``).

    Parameters
    ----------
    out_dir : path-like
        Where the executed notebooks are written.
    quick : bool
        Run with ``ALGID_NOTEBOOK_QUICK=1``.
    reuse : bool, optional
        Keep a notebook executed from the same sources in the same mode.
    log : callable, optional
        Receives one line per notebook.

    Returns
    -------
    dict
        ``name -> (results, seconds)`` or ``name -> exception`` for a notebook that
        failed (the others still run).
    """
    outcome, kernel = {}, None
    for name in notebook_names():
        if reuse and is_fresh(name, out_dir, quick):
            meta = json.loads((Path(out_dir) / f"{name}.ipynb").read_text(
                encoding="utf-8"))["metadata"]["algid"]
            outcome[name] = (meta["results"], meta["seconds"])
            log(f"{name}: up to date")
            continue
        if kernel is None:
            kernel = find_kernel(Path(tempfile.mkdtemp(prefix="algid-kernel-")))
        try:
            outcome[name] = execute_notebook(name, out_dir, quick=quick, kernel=kernel)
            log(f"{name}: executed in {outcome[name][1]:.1f} s")
        except Exception as exc:  # noqa: BLE001 - reported per notebook by the caller
            (Path(out_dir) / f"{name}.ipynb").unlink(missing_ok=True)
            outcome[name] = exc
            log(f"{name}: FAILED ({type(exc).__name__})")
    return outcome
