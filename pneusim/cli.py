"""The ``pneusim`` command line.

Each sub-command lives in its own module under :mod:`pneusim.commands` with a
``register(subparsers)`` function that adds its parser and sets ``func``.  User
mistakes (:class:`~pneusim.errors.PneusimError`) print one sentence and exit 2;
tracebacks are kept for bugs.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys

from .errors import PneusimError
from .shutdown import EXIT_TERMINATED, Terminated, sigterm_raises
from .version import __version__

__all__ = ["main", "run_command", "build_parser", "COMMANDS"]

#: sub-commands, in the order of ``pneusim --help``; a hyphen in a name is an underscore in its module
COMMANDS = ("simulate", "check", "fit", "diagnose", "run", "sweep", "mre", "serve-rig", "rigs", "effects", "plot", "friction")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="pneusim",
        description="Simulate servo-pneumatic rigs from their physics and benchmark system identification.")
    parser.add_argument("--version", action="version", version=f"pneusim {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        module_name = f"pneusim.commands.{name.replace('-', '_')}"   # serve-rig lives in serve_rig.py
        try:
            module = importlib.import_module(module_name)
        except ModuleNotFoundError as exc:
            if exc.name != module_name:
                raise
            continue
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:   # argparse: --help, --version (exit 0) or a refused option (2, one line printed)
        if exc.code in (0, None):
            raise
        return exc.code if isinstance(exc.code, int) else 2
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    args.argv = argv   # recordings write the command that made them
    return run_command(args)


def run_command(args: argparse.Namespace) -> int:
    """Run the parsed sub-command ``args.func(args)``; a user's mistake is one line on stderr and exit 2.

    SIGTERM stops any command as Ctrl-C does (:mod:`pneusim.shutdown`): its ``finally`` blocks run, so the
    valve goes to its null and no result is left half-written; the exit status is 143.
    """
    try:
        with sigterm_raises():
            return int(args.func(args) or 0)
    except BrokenPipeError:
        # the reader went away (``pneusim check ... | head``): stop quietly, as cat and grep do
        _silence_stdout()
        return 0
    except PneusimError as exc:
        print(f"pneusim {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        # the file system refused a read or write the checks could not foresee (an output folder that
        # cannot be created, a full disk): one sentence, as for any other user-side problem
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"pneusim {args.command}: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        if isinstance(exc, Terminated):
            print("terminated (SIGTERM)", file=sys.stderr)
            return EXIT_TERMINATED
        print("interrupted", file=sys.stderr)
        return 130


def _silence_stdout() -> None:
    """Point stdout at /dev/null so that Python's flush at exit does not report the broken pipe again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass


if __name__ == "__main__":
    sys.exit(main())
