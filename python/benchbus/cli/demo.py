"""``benchbus demo``: the demo session, and its plot."""

from __future__ import annotations

import argparse

from benchbus.cli._args import Parser, parse_int

__all__ = ["HELP", "add_arguments", "run"]


def run(args: argparse.Namespace) -> int:
    """Run ``benchbus demo`` as ``args`` say; the exit status."""
    from benchbus._demo import run

    run(args.port, args.out, unit=args.unit)  # prints its table and where the plot went
    return 0


#: What ``benchbus demo`` does, as ``--help`` says.
HELP = "run the benchbus demo and save its plot"
#: The rest of its ``--help``.
EPILOG = "Without --port the demo runs on simulated devices."


def add_arguments(parser: Parser, parents: list[Parser]) -> None:
    """The arguments of ``benchbus demo`` (``parents``: its option groups, for its actions)."""
    parser.add_argument("--port", metavar="PATH", help="a real port to run the demo on")
    parser.add_argument(
        "--out",
        metavar="FILE.png",
        help="where to save the plot (default: benchbus-demo.png in the current directory)",
    )
    parser.add_argument(
        "--unit", type=parse_int, default=1, help="the BLD drive's unit with --port (default 1)"
    )
