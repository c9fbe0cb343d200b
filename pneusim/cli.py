"""The ``pneusim`` command line.

Each sub-command lives in its own module under :mod:`pneusim.commands` with a
``register(subparsers)`` function that adds its parser and sets ``func``.  User
mistakes (:class:`~pneusim.errors.PneusimError`) print one sentence and exit 2;
tracebacks are kept for bugs.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from . import __version__
from .errors import PneusimError

__all__ = ["main", "COMMANDS"]

#: sub-command modules, in the order of ``pneusim --help``
COMMANDS = ("simulate", "check", "fit", "run", "sweep")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="pneusim",
        description="Simulate servo-pneumatic rigs from their physics and benchmark system identification.")
    parser.add_argument("--version", action="version", version=f"pneusim {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        try:
            module = importlib.import_module(f"pneusim.commands.{name}")
        except ModuleNotFoundError as exc:
            if exc.name != f"pneusim.commands.{name}":
                raise
            continue
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except PneusimError as exc:
        print(f"pneusim {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        # the file system refused a read or write the checks could not foresee (an output folder that
        # cannot be created, a full disk): one sentence, as for any other user-side problem
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"pneusim {args.command}: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
