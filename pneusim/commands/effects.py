"""``pneusim effects``: list the optional effects and their parameters with units and ranges."""

from __future__ import annotations

from ..model.effects import EFFECTS, range_words


def register(sub) -> None:
    p = sub.add_parser("effects", help="list the optional effects, their parameters, defaults and ranges",
                       description="List the optional physics that --effect switches on, with each parameter's "
                                   "default and allowed range (SI unit in the name) and each option's choices.")
    p.set_defaults(func=run)


def run(args) -> int:
    for name, cls in EFFECTS.items():
        print(f"{name}: {cls.description}")
        for key, default in cls.parameters.items():
            print(f"    {key:<36} default {default:<12.6g} ({range_words(getattr(cls, 'ranges', {}).get(key))})")
        for key, choices in cls.options.items():
            print(f"    {key:<36} one of {', '.join(choices)} (default {choices[0]})")
    print("use: --effect NAME or --effect NAME:PARAM=VALUE,PARAM=VALUE (repeatable); "
          "a fit frees PARAM as --free NAME.PARAM")
    return 0
