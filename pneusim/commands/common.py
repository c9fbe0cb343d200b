"""Argument helpers shared by the sub-commands."""

from __future__ import annotations

import argparse
import math
import os
from pathlib import Path

from ..errors import PneusimError
from ..model import Effect, parse_effect_text
from ..mre.daq import daq_config
from ..outputs import ResultsFolder, command_text, refuse_inputs_as_outputs
from ..plausibility import recording_rig
from ..rig import Rig, load_rig
from ..simulate import rig_effects


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


def results_folder(args, path, option: str, identity=None, *, policy: str = "refuse", known=(), markers=None,
                   keep=(), inputs=None) -> ResultsFolder:
    """The command's results folder (:class:`pneusim.outputs.ResultsFolder`), prepared: created, refused
    or cleared when it holds another run's results (``--overwrite`` where the command has it), its notes
    printed.  Call ``finish()`` on it once the results are written."""
    folder = ResultsFolder(path, option, command_text(getattr(args, "argv", None), args.command), identity,
                           policy=policy, overwrite=getattr(args, "overwrite", False), known=known, markers=markers,
                           keep=keep, inputs=inputs)
    for note in folder.prepare():
        print(f"pneusim {args.command}: note: {note}")
    return folder


def add_overwrite_argument(parser, what: str = "results") -> None:
    parser.add_argument("--overwrite", action="store_true",
                        help=f"replace the {what} of another run in the output folder (default: refuse such a "
                             "folder; a rerun of the same inputs replaces its own results)")


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


def load_rig_file(name_or_path) -> Rig:
    """:func:`pneusim.rig.load_rig` and the sections other parts read: the ``[effects.NAME]`` tables built
    (:func:`pneusim.simulate.rig_effects`) and the ``[daq]`` table checked (:func:`pneusim.mre.daq.daq_config`),
    so that any command refuses a broken rig file in one line naming the file and the field."""
    rig = load_rig(name_or_path)
    rig_effects(rig)
    daq_config(rig)
    return rig


def rig_with_overrides(rig_name: str, params: list[str] | None) -> Rig:
    return load_rig_file(rig_name).with_params(parse_param_overrides(params), origin="--param")


def parse_effects(items: list[str] | None) -> list[Effect]:
    return [parse_effect_text(text) for text in items or []]


def add_rig_arguments(parser, rig_required: bool = False) -> None:
    parser.add_argument("--rig", required=rig_required,
                        help="rig name (paper1-mre, paper2-enfield) or path of a rig file (.toml)")
    parser.add_argument("--param", action="append", metavar="NAME=VALUE",
                        help="override a rig parameter (SI units, repeatable), e.g. moving_mass_kg=1.5")
    parser.add_argument("--effect", action="append", metavar="NAME[:PARAM=VALUE,...]",
                        help="switch an optional effect on (repeatable), e.g. valve_deadband:deadband_V=0.3")


# ---------------------------------------------------------------- numeric options
def number_type(what: str, low: float | None = None, high: float | None = None, *, low_included: bool = True,
                high_included: bool = True, integer: bool = False):
    """An argparse ``type=`` that accepts a finite number in a range and refuses anything else in one line.

    ``what`` is the expectation in words (e.g. ``"a duration in s > 0"``); argparse prints
    ``argument --duration: expected a duration in s > 0, got 'nan'`` and exits 2.
    """
    def parse(text: str):
        try:
            value = int(text) if integer else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
        ok = math.isfinite(value)
        if ok and low is not None:
            ok = value >= low if low_included else value > low
        if ok and high is not None:
            ok = value <= high if high_included else value < high
        if not ok:
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
        return value

    parse.__name__ = what   # argparse names the type in some messages
    return parse


DURATION = number_type("a duration in s > 0", 0.0, low_included=False)
SEED = number_type("a whole number >= 0 (seed)", 0, 2**32 - 1, integer=True)
NOISE_SCALE = number_type("a finite number >= 0 (0: no noise)", 0.0)
#: the real-time options of the loop (``pneusim mre``) and of the rig server (``pneusim serve-rig``)
CPU = number_type("a CPU number >= 0", 0, integer=True)
PRIORITY = number_type("a SCHED_FIFO priority in 0..99 (0: normal scheduling)", 0, 99, integer=True)


# ---------------------------------------------------------------- rig of a recording
def effects_from_metadata(meta) -> list[Effect]:
    """The effects a recording's ``effects`` metadata names (``NAME:PARAM=VALUE,...`` joined by ``;``)."""
    text = (meta.get("effects") or "none").strip()
    if text in ("", "none"):
        return []
    return [parse_effect_text(item) for item in text.split(";") if item.strip()]


def overrides_from_metadata(meta, where: str) -> dict[str, float]:
    """The ``rig_overrides`` metadata of a recording (``NAME=VALUE;...``), or ``{}``."""
    text = (meta.get("rig_overrides") or "none").strip()
    out: dict[str, float] = {}
    if text in ("", "none"):
        return out
    for item in text.split(";"):
        name, eq, value = item.partition("=")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            eq = ""
        if not eq:
            raise PneusimError(f"{where}: metadata 'rig_overrides' item {item!r}: expected NAME=VALUE")
    return out


def rig_for_recording(recording, path: str, rig_option: str | None, params: list[str] | None = None,
                      use_metadata_overrides: bool = False) -> Rig:
    """The rig a recording is checked, fitted or re-run against.

    ``--rig`` (a shipped name or a rig file) wins; else the recording's ``rig_file`` metadata, which must
    still exist unchanged (:func:`pneusim.plausibility.recording_rig`), else its ``rig`` name, which must
    be known.  ``use_metadata_overrides`` applies the recording's ``rig_overrides`` (a re-run, a check);
    ``--param`` overrides come last.
    """
    rig = recording_rig(recording, rig_option, where=path, load=load_rig_file)
    if use_metadata_overrides and not rig_option:
        rig = rig.with_params(overrides_from_metadata(recording.metadata, path), origin=f"{path} rig_overrides")
    return rig.with_params(parse_param_overrides(params), origin="--param")


def recording_provenance(recording, path: str) -> dict:
    """What a recording says made it, checked: ``{"effects", "rig_overrides", "seed", "noise_scale"}``
    (``None`` where the metadata does not say).  ``pneusim simulate --like`` re-runs with these, and
    ``pneusim check`` refuses what it would refuse, in one line naming the metadata key."""
    meta = recording.metadata
    try:
        effects = effects_from_metadata(meta)
    except PneusimError as exc:
        raise PneusimError(f"{path}: metadata 'effects: {meta.get('effects')}': {exc}") from None
    return {"effects": effects, "rig_overrides": overrides_from_metadata(meta, path),
            "seed": _metadata_number(meta, "seed", path, whole=True),
            "noise_scale": _metadata_number(meta, "noise_scale", path, whole=False)}


def _metadata_number(meta, key: str, path: str, whole: bool):
    """A seed (whole number >= 0) or a noise scale (finite number >= 0) from the metadata, or None."""
    text = meta.get(key)
    if text is None:
        return None
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value >= 0 and (not whole or (value.is_integer() and value <= 2**32 - 1))):
        expected = "a whole number >= 0 (a seed)" if whole else "a finite number >= 0"
        raise PneusimError(f"{path}: metadata '{key}: {text}': expected {expected}")
    return int(value) if whole else value
