"""``benchbus gateway``: a Modbus TCP server in front of one serial port."""

from __future__ import annotations

import argparse
from collections.abc import Callable

import benchbus as bb
from benchbus._gateway import FRAME_TIMEOUT, IDLE_TIMEOUT, SLOW_REQUEST, parse_allow, parse_listen
from benchbus.cli._args import Parser, integer, number, seconds
from benchbus.cli._errors import CliError
from benchbus.cli._line import bus_options_of, open_bus, stopbits_of
from benchbus.cli._serve import serve_until_stopped

__all__ = ["HELP", "add_arguments", "run"]


def _checked(parse: Callable[[str], object]) -> Callable[[str], str]:
    """An argparse type: the text as given, once ``parse`` accepts it (its ValueError is the
    usage error)."""

    def convert(text: str) -> str:
        try:
            parse(text)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None
        return text

    return convert


def _unit_interval(text: str) -> tuple[int, float]:
    unit, sep, seconds = text.partition("=")
    if not sep:
        raise argparse.ArgumentTypeError(f"expected UNIT=SECONDS, e.g. 5=0.15, not {text!r}")
    value = number(seconds)
    if not 0.0 <= value <= 60.0:
        raise argparse.ArgumentTypeError(f"seconds must be 0..60, not {seconds!r}")
    return integer(1, 255, "UNIT")(unit), value


def run(args: argparse.Namespace) -> int:
    """Run ``benchbus gateway`` as ``args`` say; the exit status."""
    options = bus_options_of(args, "gateway")
    with open_bus(args, "gateway", reconnect=True) as bus:
        gateway = bb.Gateway(
            bus,
            args.listen,
            write_intervals=dict(args.write_interval),
            max_clients=args.max_clients,
            idle_timeout=args.idle_timeout,
            allow=args.allow,
            frame_timeout=args.frame_timeout,
        )
        try:
            gateway.start()
        except OSError as exc:
            raise CliError(f"cannot listen on {args.listen}: {exc.strerror or exc}") from None
        try:
            serve_until_stopped(
                gateway.url,
                f"gateway for {bus.port} ({options.describe(stopbits_of(args, options))})",
                args.seconds,
            )
        finally:
            gateway.stop()
    return 0


#: What ``benchbus gateway`` does, as ``--help`` says.
HELP = "share one serial port between processes: a Modbus TCP server in front of it"
#: The rest of its ``--help``.
EPILOG = (
    "The first line of stdout is the URL clients open as their port "
    "(bb.Bus('tcp://127.0.0.1:5020')). Requests from every client go over the one line, "
    "one at a time, with this command's timeout and retries; a unit that does not answer "
    "comes back to the client as exception 0x0B, a lost port as 0x0A (the port is "
    "reopened at the next request). Forwards every function, each reply as the unit sent "
    "it. A client that comes when every --max-clients slot is taken (none idle, none slow "
    "to send its request) has its first request answered exception 0x06 (server device "
    "busy), then is closed. For one machine; for a line shared across a network, use a "
    "dedicated gateway "
    "(mbusd). "
    "Modbus TCP has no authentication: listening beyond loopback prints a warning; "
    "--allow limits who may connect."
)
#: Its line options (see :func:`benchbus.cli._args.line_options`).
LINE_OPTIONS = {"unit": False}


def add_arguments(parser: Parser, parents: list[Parser]) -> None:
    """The arguments of ``benchbus gateway`` (``parents``: its option groups, for its actions)."""
    parser.add_argument(
        "--listen",
        metavar="HOST:PORT",
        type=_checked(parse_listen),
        default="127.0.0.1:5020",
        help="address to serve on (default 127.0.0.1:5020; port 0: any free port)",
    )
    parser.add_argument(
        "--write-interval",
        metavar="UNIT=S",
        type=_unit_interval,
        action="append",
        default=[],
        help="least seconds between two writes to UNIT on the line, from any client "
        "(repeatable; a J2 controller needs 0.15)",
    )
    parser.add_argument(
        "--idle-timeout",
        type=seconds,
        default=IDLE_TIMEOUT,
        metavar="S",
        help=f"close a client silent for S seconds between requests (default {IDLE_TIMEOUT:g}); "
        "when --max-clients are connected, a new one replaces the longest idle",
    )
    parser.add_argument(
        "--frame-timeout",
        type=seconds,
        default=FRAME_TIMEOUT,
        metavar="S",
        help="close a client whose request has not arrived whole S seconds after its first "
        f"byte (default {FRAME_TIMEOUT:g}); when --max-clients are connected and none is "
        f"idle, a new one replaces the one whose request has been arriving over "
        f"{SLOW_REQUEST:g} s",
    )
    parser.add_argument(
        "--max-clients",
        type=integer(1, 10_000, "max-clients"),
        default=32,
        metavar="N",
        help="clients served at once (default 32); one more is answered 0x06 (server "
        "device busy) and closed",
    )
    parser.add_argument(
        "--allow",
        metavar="ADDR[/BITS]",
        type=_checked(parse_allow),
        action="append",
        help="only this address or network may connect, e.g. 192.168.1.0/24 or ::1 "
        "(repeatable; default: any)",
    )
    parser.add_argument("--seconds", type=seconds, metavar="S", help="stop after S seconds")
