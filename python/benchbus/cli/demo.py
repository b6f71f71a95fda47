"""``benchbus demo``: the demo session, and its plot."""

from __future__ import annotations

import argparse
from typing import Any

from benchbus.cli._args import Parser, add_command, parse_int

__all__ = ["add_parser", "run"]


def run(args: argparse.Namespace) -> int:
    """Run ``benchbus demo`` as ``args`` say; the exit status."""
    from benchbus._demo import run

    run(args.port, args.out, unit=args.unit)  # prints its table and where the plot went
    return 0


def add_parser(commands: Any, general: Parser) -> None:
    """The ``demo`` command's parser, under ``commands``."""
    demo = add_command(
        commands,
        "demo",
        "run the benchbus demo and save its plot",
        [general],
        epilog="Without --port the demo runs on simulated devices.",
    )
    demo.add_argument("--port", metavar="PATH", help="a real port to run the demo on")
    demo.add_argument("--out", metavar="FILE.png", help="where to save the plot")
    demo.add_argument(
        "--unit", type=parse_int, default=1, help="the BLD drive's unit with --port (default 1)"
    )
    demo.set_defaults(handler=run)
