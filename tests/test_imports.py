"""Module structure of ``src/algid``: no import cycles, no private names imported across
modules, no module over about 600 lines."""

import ast
import pathlib

SRC = pathlib.Path(__file__).resolve().parents[1] / "src"
#: Longest module, in lines (generated code excepted).
MAX_LINES = 650

#: Known findings, to fix in these modules; remove each entry once its module is clean.
PENDING_CYCLES = []
PENDING_PRIVATE = set()
PENDING_LONG = set()


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


def test_no_module_is_too_long():
    found = {}
    for name, path in modules().items():
        n = len(path.read_text(encoding="utf-8").splitlines())
        if n > MAX_LINES and ".generated." not in name and name not in PENDING_LONG:
            found[name] = n
    assert not found, f"modules over {MAX_LINES} lines: {found}"
