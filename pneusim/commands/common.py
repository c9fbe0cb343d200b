"""Argument helpers shared by the sub-commands."""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import PneusimError
from ..model import Effect, parse_effect_text
from ..rig import Rig, load_rig


def output_file(path: str, option: str, suffixes: tuple[str, ...]) -> Path:
    """Check an output file name before any work is done: its suffix, and a folder that exists and
    can be written (a long fit or simulation should not end in a failed write)."""
    out = Path(path)
    if out.suffix.lower() not in suffixes:
        raise PneusimError(f"{option} {path}: expected a {' or '.join(suffixes)} file name")
    folder = out.parent
    if not folder.is_dir():
        raise PneusimError(f"{option} {path}: the folder {folder} does not exist")
    if not os.access(folder, os.W_OK):
        raise PneusimError(f"{option} {path}: the folder {folder} cannot be written")
    return out


def output_folder(path, option: str) -> Path:
    """Create an output folder before any work is done, or say in one sentence why it cannot be."""
    out = Path(path)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise PneusimError(f"{option} {path}: the folder cannot be created ({exc.strerror or exc})") from None
    if not os.access(out, os.W_OK):
        raise PneusimError(f"{option} {path}: the folder cannot be written")
    return out


def parse_param_overrides(items: list[str] | None) -> dict[str, float]:
    """``["NAME=VALUE", ...]`` from repeated ``--param`` options."""
    out = {}
    for item in items or []:
        name, eq, value = item.partition("=")
        if not eq:
            raise PneusimError(f"--param {item!r}: expected NAME=VALUE")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            raise PneusimError(f"--param {item!r}: VALUE must be a number, got {value!r}") from None
    return out


def rig_with_overrides(rig_name: str, params: list[str] | None) -> Rig:
    return load_rig(rig_name).with_params(parse_param_overrides(params))


def parse_effects(items: list[str] | None) -> list[Effect]:
    return [parse_effect_text(text) for text in items or []]


def add_rig_arguments(parser, rig_required: bool = False) -> None:
    parser.add_argument("--rig", required=rig_required,
                        help="rig name (paper1-mre, paper2-enfield) or path of a rig file (.toml)")
    parser.add_argument("--param", action="append", metavar="NAME=VALUE",
                        help="override a rig parameter (SI units, repeatable), e.g. moving_mass_kg=1.5")
    parser.add_argument("--effect", action="append", metavar="NAME[:PARAM=VALUE,...]",
                        help="switch an optional effect on (repeatable), e.g. valve_deadband:deadband_V=0.3")
