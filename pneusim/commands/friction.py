"""``pneusim friction``: which friction law measured seal-friction tests need."""

from __future__ import annotations

import math

from ..errors import PneusimError
from ..friction import FrictionStudy, read_friction_test
from ..friction.data import seal_of
from ..friction.plot import plot_friction_study
from ..outputs import write_json_atomic
from .common import output_file


def register(sub) -> None:
    p = sub.add_parser(
        "friction", help="fit friction laws to seal-friction tests and say which physics they need",
        description="Read seal-friction test files (the TU Delft 2021 CSV format: time_ms, laser_position_mm, "
                    "pressure_bar_gauge, force_N; one file per chamber pressure, named SEAL_<p>bar.csv), fit the "
                    "nominal Stribeck law (one level per direction, the same at every pressure) and the "
                    "pressure-dependent law of the effect pressure_dependent_friction, score both on each "
                    "pressure left out of the fit, and report whether the pressure dependence is missing.",
        epilog="example:\n  pneusim friction ../shared/data/real/cylinder_seal_friction_tudelft2021/*.csv "
               "--json friction.json --plot friction.png",
        formatter_class=__import__("argparse").RawDescriptionHelpFormatter)
    p.add_argument("files", metavar="FILE", nargs="+", help="friction test files (.csv), at least 3 pressures per seal")
    p.add_argument("--bore", action="append", metavar="SEAL=METRES",
                   help="bore diameter of a seal's cylinder, m (repeatable); known for the TU Delft files")
    p.add_argument("--supply-gauge", type=float, default=6.0e5, metavar="PA",
                   help="pressure S that normalises the pressure coefficient k, Pa (default 6e5, the rigs' "
                        "supply gauge pressure)")
    p.add_argument("--json", metavar="OUT.json", help="write the result as JSON")
    p.add_argument("--plot", metavar="FILE", help="friction against velocity per pressure, both laws (.png or .svg)")
    p.set_defaults(func=run)


def _bores(items) -> dict[str, float]:
    out = {}
    for item in items or []:
        seal, eq, value = item.partition("=")
        try:
            bore = float(value)
        except ValueError:
            bore = float("nan")
        if not eq or not seal.strip() or not (math.isfinite(bore) and 0.0 < bore < 1.0):
            raise PneusimError(f"--bore {item!r}: expected SEAL=METRES with a bore in (0, 1) m, e.g. O-ring=0.025")
        out[seal.strip()] = bore
    return out


def run(args) -> int:
    if args.json:
        output_file(args.json, "--json", (".json",))
    if args.plot:
        output_file(args.plot, "--plot", (".png", ".svg"))
    if not (math.isfinite(args.supply_gauge) and args.supply_gauge > 0):
        raise PneusimError(f"--supply-gauge {args.supply_gauge}: expected a positive pressure in Pa")
    bores = _bores(args.bore)
    tests = [read_friction_test(f, bores.get(seal_of(f))) for f in args.files]
    study = FrictionStudy(supply_gauge_Pa=args.supply_gauge).fit(tests, progress=True)
    print(study.table())
    if args.json:
        print(f"wrote {write_json_atomic(args.json, study.to_dict(), indent=2)}")
    if args.plot:
        print(f"wrote {plot_friction_study(study, args.plot)}")
    return 0
