"""Run the algid command line: ``python -m algid``."""

from algid.cli import main

if __name__ == "__main__":
    raise SystemExit(main())
