"""The ``benchbus`` command line (also ``python -m benchbus``).

::

    benchbus scan    --port PATH [--units 1-247] [--auto] [--progress]
    benchbus read    --port PATH [--unit N] ADDRESS [COUNT] [--table T] [--type T --order O]
    benchbus write   --port PATH [--unit N] ADDRESS VALUE [VALUE ...]
    benchbus read    --profile FILE --port PATH [NAME ...]    (a device profile's registers)
    benchbus write   --profile FILE --port PATH NAME VALUE
    benchbus drive   --port PATH [--family BLD|C20] status|start|stop|reverse|set-speed RPM
                                                  |reset-fault
    benchbus pbl     --port PATH status|start|stop|reverse|set-speed RPM
    benchbus j2      --port PATH status|set-sv VALUE|auto|manual|set-output PERCENT
    benchbus monitor --port PATH drive|pbl|j2 [--interval S] [--count N | --duration S] [--csv FILE]
                                              [--no-reconnect]
    benchbus monitor --port PATH --profile FILE [...as above]
    benchbus sim     drive|pbl|j2|instrument|atv31 [--unit N] [--baudrate B] [--seconds S]
    benchbus sim     --profile FILE [--value NAME=VALUE ...] [--unit N] [--seconds S]
    benchbus demo    [--port PATH [--unit N]] [--out FILE.png]
    benchbus profile check FILE  (a device profile's register table, or its mistakes)
    benchbus profile list        (the profiles found by name: BENCHBUS_PROFILES', shipped)
    benchbus profile show NAME   (one's register table, maker and source)
    benchbus ports   (the serial ports, with their USB ids, chip, maker and serial number)
    benchbus doctor  --port PATH [--unit N]  (what stands between benchbus and the port)

The line options (``--port``, ``--baudrate``, ``--parity``, ``--stopbits``, ``--unit``,
``--timeout``, ``--retries``; ``--framing rtu|ascii`` and ``--bytesize 7|8`` for Modbus ASCII,
7E1 unless given; ``--rs485`` and ``--rts-delay BEFORE,AFTER`` for a board UART in the Linux
kernel's RS485 mode) go anywhere after the command; their defaults are those of the device
family the command talks to (with ``--profile``, the profile's ``[line]``). ``--port`` falls
back to ``$BENCHBUS_PORT``. ``--profile`` takes a file or a profile's name (``sdm630``:
``benchbus profile list``). Numbers (addresses, values, units) are decimal or ``0x`` hex.

Errors print one line, ``benchbus: <what went wrong>``, on stderr and exit with 1 (2 for a
usage error, 130 after Ctrl-C; in ``monitor`` and ``sim`` Ctrl-C is the normal end and exits
0). ``--traceback`` shows the Python traceback instead, for a bug report. ``status`` and
``monitor`` refuse a unit recognised as another family than the command's.

Each command is a module of this package named after it, its parser beside its handler:
``HELP`` (and optionally ``EPILOG``) for ``--help``, ``LINE_OPTIONS`` (the keywords of
:func:`~benchbus.cli._args.line_options`; none without) and ``FAMILY_OPTION`` (True: takes
``--family``), ``add_arguments(parser, parents)`` for its own arguments and actions, and
``run(args)``, its handler, which returns the exit status. :data:`COMMANDS` lists them in the
order ``--help`` shows them.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import sys
import types

import benchbus as bb
from benchbus._device import NOTED
from benchbus._families import command_families
from benchbus.cli import (
    demo,
    doctor,
    gateway,
    ioc,
    monitor,
    ports,
    profile,
    read,
    scan,
    sim,
    write,
)
from benchbus.cli._args import (
    PORT_ENV,
    PROG,
    Parser,
    add_command,
    family_options,
    general_options,
    line_options,
    parse_int,
    parse_units,
)
from benchbus.cli._errors import CliError, UsageError, end_ctrl_c_line, interrupted, notes, one_line
from benchbus.cli._line import BUS_OPTIONS, BusOptions, opt
from benchbus.cli.scan import AUTO_FORMATS, guess_model
from benchbus.cli.sim import SIM_DEVICES

__all__ = [
    "AUTO_FORMATS",
    "BUS_OPTIONS",
    "COMMANDS",
    "PORT_ENV",
    "PROG",
    "SIM_DEVICES",
    "BusOptions",
    "CliError",
    "UsageError",
    "build_parser",
    "guess_model",
    "main",
    "parse_int",
    "parse_units",
]

#: The commands, in the order ``--help`` lists them: after ``write``, those of the families
#: the registry gives a command (``benchbus drive``...), each the module named by its key.
COMMANDS: tuple[types.ModuleType, ...] = (
    scan,
    read,
    write,
    *(importlib.import_module(f"{__name__}.{f.key}") for f in command_families()),
    monitor,
    sim,
    gateway,
    ioc,
    profile,
    ports,
    doctor,
    demo,
)


def build_parser() -> argparse.ArgumentParser:
    """The whole command line, from the commands' modules."""
    general = general_options()
    parser = Parser(
        prog=PROG,
        description="Modbus RTU master for the lab bench: find, read, drive and watch RS485 "
        "devices, or simulate one on a pseudo-terminal.",
        epilog=f"Numbers are decimal or 0x hex. --port falls back to ${PORT_ENV}. "
        f"Run '{PROG} COMMAND --help' for a command's options.",
        parents=[general],
    )
    parser.add_argument("--version", action="version", version=f"{PROG} {bb.__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for module in COMMANDS:
        parents = [general]
        line = getattr(module, "LINE_OPTIONS", None)
        if line is not None:
            parents.append(line_options(**line))
        if getattr(module, "FAMILY_OPTION", False):
            parents.append(family_options())
        name = module.__name__.rpartition(".")[2]
        epilog = getattr(module, "EPILOG", None)
        command = add_command(commands, name, module.HELP, parents, epilog=epilog)
        module.add_arguments(command, parents)
        command.set_defaults(handler=module.run)
    return parser


def _configure_logging(verbose: bool, traceback: bool = False) -> None:
    """Warnings of the library on stderr; with ``verbose``, every frame too (the wire log).

    Without ``traceback``, a record that is also a note on the exception being raised is
    left to the error line, which shows the notes."""
    handler = logging.StreamHandler(sys.stderr)
    handler.setLevel(logging.WARNING)  # the wire log has its own handler
    handler.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
    if not traceback:
        handler.addFilter(lambda record: not getattr(record, NOTED, False))
    logging.getLogger("benchbus").addHandler(handler)
    if verbose:
        bb.enable_wire_log(sys.stderr)


def main(argv: list[str] | None = None) -> int:
    """Run the command line with ``argv`` (default ``sys.argv[1:]``); the exit status."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version (0) and usage errors (2)
        return exc.code if isinstance(exc.code, int) else 2
    if opt(args, "traceback", False):
        _configure_logging(bool(opt(args, "verbose", False)), traceback=True)
        return int(args.handler(args))
    try:
        _configure_logging(bool(opt(args, "verbose", False)))
        return int(args.handler(args))
    except UsageError as exc:
        print(f"{PROG}: {args.command}: {one_line(exc)}", file=sys.stderr)
        return exc.status
    except CliError as exc:
        print(f"{PROG}: {one_line(exc)}", file=sys.stderr)
        return exc.status
    except (KeyboardInterrupt, SystemError) as exc:
        if not interrupted(exc):
            print(f"{PROG}: unexpected {type(exc).__name__}: {one_line(exc)}", file=sys.stderr)
            return 1
        if args.command in ("monitor", "sim", "gateway"):
            return 0
        end_ctrl_c_line()
        print("; ".join([f"{PROG}: interrupted", *notes(exc)]), file=sys.stderr)
        return 130
    except BrokenPipeError:
        # The reader went away (`benchbus read ... | head`): nothing more to say to it.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 1
    except (bb.BenchbusError, ValueError, TypeError, OSError, RuntimeError, ImportError) as exc:
        print(f"{PROG}: {one_line(exc)}", file=sys.stderr)
        return 1
    except (Exception, BaseException) as exc:  # also a panic in the core (PanicException)
        if isinstance(exc, (SystemExit, GeneratorExit)):
            raise
        print(
            f"{PROG}: unexpected {type(exc).__name__}: {one_line(exc)} "
            "(run again with --traceback to see where)",
            file=sys.stderr,
        )
        return 1
