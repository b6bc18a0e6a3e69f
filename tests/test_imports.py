"""Module structure of ``src/algid``: the layout by concept, no import cycles, no private
names imported across modules, module docstrings that stay short."""

import ast
import pathlib
import re

ROOT = pathlib.Path(__file__).resolve().parents[1]
SRC = ROOT / "src"
#: The public modules and subpackages directly in ``algid/``; everything else is private.
PUBLIC = {"errors", "io", "datasets", "plotting", "cli", "models", "estimation",
          "identification", "simulation", "signals", "symbolic", "paper"}
#: Longest module docstring, in lines (what and why; figures belong to the docs).
MAX_DOCSTRING_LINES = 40

#: Known findings, to fix in these modules; remove each entry once its module is clean.
PENDING_CYCLES = []
PENDING_PRIVATE = set()


def modules():
    """Module name -> path of every module of the package."""
    out = {}
    for path in sorted(SRC.rglob("*.py")):
        parts = path.relative_to(SRC).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = path
    return out


def imports(name, path, known):
    """``(module imported, names imported from it)`` for every import in a module."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, ()
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join(parts + ([base] if base else []))
            submodules = [f"{base}.{a.name}" for a in node.names if f"{base}.{a.name}" in known]
            if len(submodules) == len(node.names):
                for sub in submodules:  # 'from package import module'
                    yield sub, ()
            else:
                yield base, tuple(a.name for a in node.names)


def graph():
    known = modules()
    return {name: {target for target, _ in imports(name, path, known) if target in known
                   and target != name}
            for name, path in known.items()}


def cycles(edges):
    """The strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(edges[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = set()
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.add(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(component)

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return found


def test_the_cycle_finder_finds_a_cycle():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [{"a", "b", "c"}]


def test_no_import_cycles():
    found = [c for c in cycles(graph()) if c not in PENDING_CYCLES]
    assert not found, f"import cycles: {found}"


def test_no_private_names_imported_across_modules():
    known = modules()
    found = []
    for name, path in known.items():
        if name in PENDING_PRIVATE:
            continue
        for target, names in imports(name, path, known):
            private = [n for n in names if n.startswith("_") and n != "__version__"]
            if target.startswith("algid") and private:
                found.append(f"{name} imports {', '.join(private)} from {target}")
    assert not found, "\n".join(found)


def test_public_modules_are_the_concepts():
    top = {p.stem if p.suffix == ".py" else p.name for p in (SRC / "algid").iterdir()
           if (p.suffix == ".py" or (p / "__init__.py").exists()) and p.stem != "__init__"}
    public = {name for name in top if not name.startswith("_")}
    assert public == PUBLIC, f"public modules changed: {sorted(public ^ PUBLIC)}"
    # inside a subpackage, everything but its __init__ is private
    exposed = [name for name in modules() if name.count(".") > 1
               and name.split(".")[1] in PUBLIC and not name.split(".")[2].startswith("_")]
    assert not exposed, f"public modules inside subpackages: {exposed}"


def test_every_module_is_in_the_developer_layout():
    """docs/developer.rst lists every module with what it holds: a module's concept is
    decided when it is created, not found out later."""
    text = (ROOT / "docs" / "developer.rst").read_text(encoding="utf-8")
    layout = text[text.index("\nLayout\n"):]
    listed = set()
    for row in re.findall(r"\* - (.+?)\n     - ", layout, flags=re.S):
        folder = re.match(r"``(\w+)/``: ", row)
        for name in re.findall(r"``([\w.]+/?)``", row):
            if folder and name != folder.group(0)[2:-4]:
                listed.add(f"{folder.group(1)}/{name}")
            else:
                listed.add(name)
    missing = []
    for path in sorted((SRC / "algid").rglob("*.py")):
        rel = path.relative_to(SRC / "algid").as_posix()
        parts = rel.split("/")
        if parts[0] in ("_generated",) or (len(parts) > 2 and parts[1] == "_errata"):
            candidates = {parts[0] + "/", "/".join(parts[:2]) + "/"}
        elif len(parts) == 2 and parts[1] == "__init__.py":
            candidates = {parts[0] + "/", rel}
        else:
            candidates = {rel}
        if not candidates & listed:
            missing.append(rel)
    assert not missing, f"modules missing from the layout of docs/developer.rst: {missing}"


def test_module_docstrings_are_short():
    found = {}
    for name, path in modules().items():
        if "._generated" in name:
            continue
        doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or ""
        if len(doc.splitlines()) > MAX_DOCSTRING_LINES:
            found[name] = len(doc.splitlines())
    assert not found, f"module docstrings over {MAX_DOCSTRING_LINES} lines: {found}"


def test_import_algid_leaves_numba_and_scipy_s_heavy_subpackages_unimported():
    """They cost a second of CPU at start-up; the calls that need them import them
    (pandas and Dask: identify_many and the command line of fleets)."""
    import subprocess
    import sys

    heavy = ["numba", "scipy.signal", "scipy.stats", "scipy.interpolate", "scipy.integrate",
             "scipy.optimize", "scipy.sparse", "control", "sympy", "matplotlib", "pandas",
             "pyarrow", "dask", "distributed"]
    code = f"import sys, algid; print(' '.join(m for m in {heavy!r} if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env={"PYTHONPATH": str(SRC), "PATH": ""}, check=True)
    assert out.stdout.split() == []
