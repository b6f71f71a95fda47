"""``python -m benchbus``: the ``benchbus`` command line."""

from __future__ import annotations

from benchbus.cli import main

if __name__ == "__main__":
    raise SystemExit(main())
