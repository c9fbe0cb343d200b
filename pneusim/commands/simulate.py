"""``pneusim simulate``: run an experiment on a simulated rig and write a recording."""

from __future__ import annotations

from ..errors import PneusimError
from ..experiment import INPUT_KINDS, standard_experiment
from ..recording import read_recording, write_recording
from ..simulate import rerun_recording, simulate
from .common import add_rig_arguments, output_file, parse_effects, rig_with_overrides


def register(sub) -> None:
    p = sub.add_parser("simulate", help="simulate a rig and write a recording (CSV or .mat)",
                       description="Simulate a rig's physics (CVODE) and write what its sensors would record.")
    add_rig_arguments(p)
    p.add_argument("--input", choices=INPUT_KINDS, help="experiment signal (reference in closed loop, "
                   "valve command in open loop)")
    p.add_argument("--like", metavar="RECORDING", help="re-run the experiment of a recording "
                   "(its commands for open loop, its reference and controller for closed loop)")
    p.add_argument("--duration", type=float, default=None, metavar="S", help="duration in s (default 80 s "
                   "for paper2-enfield, 20 s otherwise)")
    p.add_argument("--loop", choices=("open", "closed"), default="closed")
    p.add_argument("--seed", type=int, default=0, help="seed of the signal and of the sensor noise")
    p.add_argument("--noise-scale", type=float, default=1.0, help="multiplies the rig's sensor noise")
    p.add_argument("--no-pressures", action="store_true", help="leave the pressure columns out")
    p.add_argument("--backend", default="cvode", help="cvode (default), scipy-radau, scipy-bdf, scipy-lsoda")
    p.add_argument("--out", required=True, metavar="FILE", help="output recording, .csv or .mat")
    p.add_argument("--plot", metavar="FILE", help="also draw position, command and pressures (.png or .svg)")
    p.set_defaults(func=run)


def run(args) -> int:
    out = output_file(args.out, "--out", (".csv", ".mat"))
    if args.plot:
        output_file(args.plot, "--plot", (".png", ".svg"))
    effects = parse_effects(args.effect)
    if args.like:
        if args.input:
            raise PneusimError("give either --input or --like, not both")
        recording = read_recording(args.like)
        rig_name = args.rig or recording.rig
        if not rig_name:
            raise PneusimError(f"{args.like} names no rig in its metadata; give --rig")
        rig = rig_with_overrides(rig_name, args.param)
        if abs(recording.sample_time_s - rig.sample_time_s) > 1e-12:
            rig = rig.with_params({"sample_time_s": recording.sample_time_s})
        sim = rerun_recording(rig, recording, effects, seed=args.seed, noise_scale=args.noise_scale,
                              backend=args.backend)
    else:
        if not args.input:
            raise PneusimError("give --input multisine|steps|pulses or --like RECORDING")
        if not args.rig:
            raise PneusimError("give --rig (paper1-mre, paper2-enfield or a rig file)")
        rig = rig_with_overrides(args.rig, args.param)
        duration = args.duration if args.duration is not None else (80.0 if rig.name == "paper2-enfield" else 20.0)
        exp = standard_experiment(rig, args.input, duration, args.loop, seed=args.seed)
        sim = simulate(rig, exp, effects, seed=args.seed, noise_scale=args.noise_scale,
                       record_pressures=not args.no_pressures, backend=args.backend, progress=True)
    write_recording(sim.recording, out)
    duration = sim.recording.n_samples * sim.recording.sample_time_s
    print(f"wrote {out}: {sim.recording.n_samples} samples, {duration:.3f} s simulated in "
          f"{sim.wall_time_s:.2f} s ({duration / max(sim.wall_time_s, 1e-9):.0f}x real time)")
    if args.plot:
        from ..plots import plot_recording
        plot_recording(sim.recording, args.plot)
        print(f"wrote {args.plot}")
    return 0
