"""The wheel smoke suite: benchbus as a user gets it from ``pip install``, outside the source.

.ci/wheel-smoke.sh installs a built wheel into a fresh virtual environment, copies this
directory to a temporary one and runs pytest there, so nothing of the checkout is importable.
The main test run does not collect it (tests/conftest.py ignores this directory).

Markers say what a test needs beyond the wheel itself; the script deselects what the machine
cannot give: ``sim`` the simulators (``benchbus[sim]``: pymodbus needs Python 3.10 or later),
``pty`` pseudo-terminals (none on Windows), ``plot`` matplotlib (``benchbus[plot]``).
"""

from __future__ import annotations

import pytest

MARKERS = {
    "sim": "needs benchbus[sim] (pymodbus, Python 3.10 or later)",
    "pty": "needs pseudo-terminals (Linux, macOS)",
    "plot": "needs benchbus[plot] (matplotlib)",
}


def pytest_configure(config: pytest.Config) -> None:
    for name, needs in MARKERS.items():
        config.addinivalue_line("markers", f"{name}: {needs}")
