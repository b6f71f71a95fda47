"""The wire log: every frame sent and received, as hex, on the logger ``benchbus.wire``."""

from __future__ import annotations

import logging
import sys
from typing import TextIO

from benchbus._core import refresh_logging

__all__ = ["enable_wire_log"]

WIRE_LOGGER = "benchbus.wire"


def enable_wire_log(stream: TextIO | None = None, level: int = logging.DEBUG) -> logging.Logger:
    """Show every frame on the wire: ``-> 01 03 00 06 00 01 64 0B`` / ``<- 01 03 02 ...``.

    Sets the ``benchbus.wire`` logger to ``level`` (DEBUG: every frame), gives it a handler
    writing to ``stream`` (default stderr) unless it already has one, and makes the open
    Buses pick up the new level. Returns the logger, so ``enable_wire_log().setLevel(...)``
    or adding your own handler works as usual. Calling it again adds no second handler.
    """
    logger = logging.getLogger(WIRE_LOGGER)
    logger.setLevel(level)
    if not any(getattr(h, "_benchbus_wire", False) for h in logger.handlers):
        handler = logging.StreamHandler(sys.stderr if stream is None else stream)
        handler.setFormatter(logging.Formatter("%(asctime)s %(name)s %(message)s"))
        handler._benchbus_wire = True  # type: ignore[attr-defined]
        logger.addHandler(handler)
    refresh_logging()
    return logger
