"""``pneusim simulate``: run an experiment on a simulated rig and write a recording."""

from __future__ import annotations

import shlex
import sys

from ..errors import PneusimError
from ..experiment import INPUT_KINDS, standard_experiment
from ..plausibility import check_noise_scale, end_stop_text
from ..plots import plot_recording
from ..recording import MIN_SAMPLES, read_recording, write_recording
from ..simulate import rerun_recording, rig_effects, simulate
from .common import (DURATION, NOISE_SCALE, SEED, add_rig_arguments, output_file, parse_effects,
                     recording_provenance, refuse_inputs_as_outputs, rig_for_recording, rig_with_overrides)

BACKENDS = ("cvode", "scipy-radau", "scipy-bdf", "scipy-lsoda")


def register(sub) -> None:
    p = sub.add_parser("simulate", help="simulate a rig and write a recording (CSV or .mat)",
                       description="Simulate a rig's physics (CVODE) and write what its sensors would record. "
                                   "The recording's metadata holds everything needed to run it again "
                                   "(rig, --param overrides, effects, seed, noise scale, pneusim version, command).")
    add_rig_arguments(p)
    p.add_argument("--input", choices=INPUT_KINDS, help="experiment signal (reference in closed loop, "
                   "valve command in open loop)")
    p.add_argument("--like", metavar="RECORDING", help="re-run the experiment of a recording "
                   "(its commands for open loop, its reference and controller for closed loop) on its rig, "
                   "with its rig overrides, effects, seed and noise scale unless given here; --duration keeps "
                   "only the first S seconds")
    p.add_argument("--duration", type=DURATION, default=None, metavar="S", help="duration in s (default 80 s "
                   "for paper2-enfield, 20 s otherwise; with --like: the whole recording)")
    p.add_argument("--loop", choices=("open", "closed"), default=None, help="closed (default) or open")
    p.add_argument("--seed", type=SEED, default=None, help="seed of the signal and of the sensor noise "
                   "(default 0, or the recording's with --like)")
    p.add_argument("--noise-scale", type=NOISE_SCALE, default=None, metavar="F",
                   help="multiplies the rig's sensor noise (default 1, or the recording's with --like)")
    p.add_argument("--no-pressures", action="store_true", help="leave the pressure columns out")
    p.add_argument("--backend", default="cvode", choices=BACKENDS, help="ODE solver: cvode (default), "
                   "scipy-radau, scipy-bdf, scipy-lsoda")
    p.add_argument("--out", required=True, metavar="FILE", help="output recording, .csv or .mat")
    p.add_argument("--plot", metavar="FILE", help="also draw position, command and pressures (.png or .svg)")
    p.set_defaults(func=run)


def run(args) -> int:
    out = output_file(args.out, "--out", (".csv", ".mat"))
    if args.plot:
        output_file(args.plot, "--plot", (".png", ".svg"))
    rig_file = args.rig if args.rig and args.rig.lower().endswith(".toml") else None
    refuse_inputs_as_outputs({"--out": args.out, "--plot": args.plot},
                             {"the recording given with --like": args.like, "the rig file given with --rig": rig_file})
    effects = parse_effects(args.effect)
    if args.like:
        if args.input:
            raise PneusimError("give either --input or --like, not both")
        recording = read_recording(args.like)
        made = recording_provenance(recording, args.like)
        if args.loop and recording.loop and args.loop != recording.loop:
            raise PneusimError(f"--loop {args.loop}: {args.like} is a recording in {recording.loop} loop, "
                               "and --like re-runs its experiment as it was")
        rig = rig_for_recording(recording, args.like, args.rig, args.param, use_metadata_overrides=not args.rig)
        if abs(recording.sample_time_s - rig.sample_time_s) > 1e-12:
            rig = rig.with_params({"sample_time_s": recording.sample_time_s})
        if not args.effect:
            effects = made["effects"]
        seed = args.seed if args.seed is not None else (made["seed"] if made["seed"] is not None else 0)
        noise = args.noise_scale if args.noise_scale is not None else (
            made["noise_scale"] if made["noise_scale"] is not None else 1.0)
        check_noise_scale(rig, noise, "--noise-scale" if args.noise_scale is not None
                          else f"{args.like}: metadata noise_scale")
        if args.duration is not None:
            span = recording.n_samples * recording.sample_time_s
            n = int(round(args.duration / recording.sample_time_s))
            if n > recording.n_samples:
                raise PneusimError(f"--duration {args.duration:g} s: {args.like} holds only {span:g} s")
            if n < MIN_SAMPLES:
                raise PneusimError(f"--duration {args.duration:g} s gives {n} samples at {recording.sample_time_s:g} s; "
                                   f"at least {MIN_SAMPLES} are needed")
            recording = recording.slice(None, float(recording.time_s[0]) + (n - 0.5) * recording.sample_time_s)
        sim = rerun_recording(rig, recording, effects, seed=seed, noise_scale=noise, backend=args.backend,
                              record_pressures=recording.has_pressures and not args.no_pressures)
    else:
        if not args.input:
            raise PneusimError("give --input multisine|steps|pulses or --like RECORDING")
        if not args.rig:
            raise PneusimError("give --rig (paper1-mre, paper2-enfield or a rig file)")
        rig = rig_with_overrides(args.rig, args.param)
        if not args.effect and getattr(rig, "effects", ()):
            effects = rig_effects(rig)   # a rig file's [effects.NAME] tables (e.g. a fitted rig)
        duration = args.duration if args.duration is not None else (80.0 if rig.name == "paper2-enfield" else 20.0)
        seed = args.seed if args.seed is not None else 0
        noise = args.noise_scale if args.noise_scale is not None else 1.0
        check_noise_scale(rig, noise, "--noise-scale")
        exp = standard_experiment(rig, args.input, duration, args.loop or "closed", seed=seed)
        sim = simulate(rig, exp, effects, seed=seed, noise_scale=noise,
                       record_pressures=not args.no_pressures, backend=args.backend, progress=True)
    sim.recording.metadata["command"] = "pneusim " + shlex.join(getattr(args, "argv", None) or sys.argv[1:])
    write_recording(sim.recording, out)
    duration = sim.recording.n_samples * sim.recording.sample_time_s
    print(f"wrote {out}: {sim.recording.n_samples} samples, {duration:.3f} s simulated in "
          f"{sim.wall_time_s:.2f} s ({duration / max(sim.wall_time_s, 1e-9):.0f}x real time)")
    if sim.recording.loop == "open":
        print(end_stop_text(sim.recording, rig.stroke_m))
    if args.plot:
        plot_recording(sim.recording, args.plot)
        print(f"wrote {args.plot}")
    return 0

