"""``pneusim rigs``: list the shipped rigs and their parameters with units and ranges."""

from __future__ import annotations

from ..rig import RANGES, known_rig_names, range_text
from .common import load_rig_file


def register(sub) -> None:
    p = sub.add_parser("rigs", help="list the shipped rigs and their parameters (SI units, allowed ranges)",
                       description="List the rigs that ship with pneusim (names for --rig) and, with --params or "
                                   "a NAME, their parameters by section with value, unit and allowed range.  "
                                   "Copy a rig file (the path is printed) to describe your own rig.")
    p.add_argument("name", nargs="?", metavar="NAME", help="one rig (a shipped name or a rig file) to show in full")
    p.add_argument("--params", action="store_true", help="show every rig's parameters")
    p.set_defaults(func=run)


def run(args) -> int:
    names = [args.name] if args.name else known_rig_names()
    for name in names:
        rig = load_rig_file(name)
        print(f"{rig.name}: {rig.description}")
        print(f"  file: {rig.source}")
        if args.params or args.name:
            for section, keys in rig.sections.items():
                print(f"  [{section}]")
                for key in keys:
                    allowed = f"  ({range_text(key)})" if key in RANGES else ""
                    print(f"    {key:<40} {rig.params[key]:<12.6g}{allowed}")
    if not args.name:
        print("units are in the names (_m, _Pa, _kg, _N_s_per_m ...); use a name with --rig, or the path of a "
              "copied and edited file")
    return 0
