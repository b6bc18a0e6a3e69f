"""``python -m derivation [--out DIR]``: write every generated file, byte for byte.

Run from the repository root.  Without ``--out`` the files go to
``src/algid/_generated/``; a test writes them to a temporary folder and compares.  For
every built-in model: ``<model>.py``, the NumPy module (the model algebra), and
``<model>_numba.py``, the compiled loop of the numba backend.
"""

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "src"))

from algid.models._registry import module_from_source  # noqa: E402
from algid.symbolic._builtin_models import BUILTIN_MODELS, KNOWN_MASS, builtin_model  # noqa: E402
from algid.symbolic._codegen import HEADER, numpy_module_source, registry_source  # noqa: E402
from algid.symbolic._codegen_c import c_sources  # noqa: E402
from algid.symbolic._codegen_numba import numba_module_source  # noqa: E402
from algid.symbolic._derivation import derive  # noqa: E402
from algid.symbolic._differentiator import kernel_table_source  # noqa: E402
from algid.symbolic._modulating import table_module_source  # noqa: E402


def generated_files():
    """Map relative file name -> text of every generated file."""
    files = {}
    for name in BUILTIN_MODELS:
        mass_scaled, mass_divided = KNOWN_MASS.get(name, ({}, ()))
        text = numpy_module_source(derive(builtin_model(name)), mass_scaled=mass_scaled,
                                   mass_divided=mass_divided)
        files[f"{name}.py"] = text
        # the loop reads the model's tables from the module text just written
        module = module_from_source(text, f"algid._generated.{name}")
        try:
            files[f"{name}_numba.py"] = numba_module_source(module, header=HEADER)
        finally:
            del sys.modules[f"algid._generated.{name}"]
    files["__init__.py"] = registry_source(BUILTIN_MODELS)
    for name in BUILTIN_MODELS:  # the embedded C estimator, default options
        for rel, text in c_sources(derive(builtin_model(name))).items():
            files[f"c/{rel}"] = text
    files["differentiator_kernels.py"] = kernel_table_source()
    files["modulating.py"] = table_module_source(HEADER)
    return files


def write(out: Path) -> list:
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for rel, text in generated_files().items():
        path = out / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8", newline="\n")
        written.append(path)
    return written


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m derivation", description=__doc__)
    parser.add_argument("--out", type=Path, default=ROOT / "src" / "algid" / "_generated")
    args = parser.parse_args(argv)
    for path in write(args.out):
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
