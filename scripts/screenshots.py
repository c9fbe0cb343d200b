"""Render a picture (PNG) of each report type into docs/screenshots/, so that a reader sees what a command
writes before running anything.

    .venv/bin/python scripts/screenshots.py                 # into docs/screenshots/ (about two minutes)
    .venv/bin/python scripts/screenshots.py --keep /tmp/r   # and keep the reports themselves in /tmp/r

Each report is made from a small, fast input:

* ``scenario-report.png`` -- ``pneusim run`` on the tiny generalisation scenario of the tests (12 s of paper 2's
  multisine, ARX and the physical fit, a 2 bar supply never seen in training);
* ``sweep-summary.png`` -- ``pneusim sweep`` of paper 2's scenario over the supply pressure (3 values) and a
  random moving mass and noise (3 draws), 10 s records, the physical fit left out: its summary figure;
* ``mre-report.png`` -- ``pneusim mre scenarios/mre-paper1.toml --fast`` for 2 s: the report's figures;
* ``fit-report.png`` -- ``pneusim fit --report`` on a 12 s simulated recording of paper 2's rig (pulses, open
  loop);
* ``diagnosis-report.png`` -- ``pneusim diagnose --report`` on the first 30 s of ``shared/practice2/
  practice2_20.csv`` (a 0.37 V valve dead band; about half a minute).

A report with an HTML page (scenario, fit, diagnosis) is rendered by headless Chromium when it is installed
(``apt-get install chromium``), the top of the page down to its first figures; otherwise, and for the reports
without a page (sweep, MRE), the report's figures are stacked into one PNG under its title with matplotlib.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared"
PNEUSIM = [sys.executable, "-m", "pneusim.cli"]
#: the width of a screenshot, pixels, and the most of a page's height it shows
WIDTH_PX, MAX_HEIGHT_PX = 1100, 2600


def _run(args, cwd=ROOT) -> None:
    print("$ pneusim " + " ".join(str(a) for a in args), flush=True)
    subprocess.run(PNEUSIM + [str(a) for a in args], check=True, cwd=cwd, stdout=subprocess.DEVNULL)


def _chromium() -> str | None:
    return next((shutil.which(name) for name in ("chromium", "chromium-browser", "google-chrome")
                 if shutil.which(name)), None)


def _shrink(image_path: Path, out: Path) -> Path:
    """Crop the white below the page's content, scale to :data:`WIDTH_PX` and keep 256 colours."""
    from PIL import Image, ImageChops

    image = Image.open(image_path).convert("RGB")
    box = ImageChops.difference(image, Image.new("RGB", image.size, "white")).getbbox()
    if box:
        image = image.crop((0, 0, image.width, min(image.height, box[3] + 20)))
    if image.width != WIDTH_PX:
        image = image.resize((WIDTH_PX, round(image.height * WIDTH_PX / image.width)), Image.LANCZOS)
    image.quantize(colors=256, method=Image.Quantize.MEDIANCUT).save(out, optimize=True)
    return out


def _page(html: Path, out: Path, browser: str) -> Path:
    """A headless browser's picture of the top of ``html``."""
    with tempfile.TemporaryDirectory() as tmp:
        shot = Path(tmp) / "page.png"
        subprocess.run([browser, "--headless=new", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                        f"--window-size={WIDTH_PX},{MAX_HEIGHT_PX}", f"--screenshot={shot}", html.resolve().as_uri()],
                       check=True, capture_output=True, timeout=120)
        return _shrink(shot, out)


def _stack(title: str, figures: list[Path], out: Path) -> Path:
    """The report's figures one below the other under its title, as one PNG (matplotlib)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.image as mpimg
    import matplotlib.pyplot as plt

    images = [mpimg.imread(f) for f in figures]
    heights = [im.shape[0] / im.shape[1] for im in images]
    height_in = 11 * sum(heights) + 0.8
    fig, axes = plt.subplots(len(images), 1, figsize=(11, height_in), squeeze=False,
                             gridspec_kw={"height_ratios": heights})
    for ax, im in zip(axes[:, 0], images):
        ax.imshow(im)
        ax.axis("off")
    fig.suptitle(title, fontsize=14, fontweight="bold", x=0.02, ha="left", y=1.0 - 0.15 / height_in, va="top")
    fig.subplots_adjust(left=0.0, right=1.0, bottom=0.0, top=1.0 - 0.7 / height_in, hspace=0.02)
    with tempfile.TemporaryDirectory() as tmp:
        fig.savefig(Path(tmp) / "stack.png", dpi=100)
        plt.close(fig)
        return _shrink(Path(tmp) / "stack.png", out)


def _picture(title: str, folder: Path, page: str | None, figures: list[str], out: Path, browser: str | None) -> Path:
    if page and browser:
        return _page(folder / page, out, browser)
    return _stack(title, [folder / f for f in figures], out)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default=str(ROOT / "docs" / "screenshots"), help="folder of the pictures")
    parser.add_argument("--keep", metavar="DIR", help="make the reports in DIR and keep them (default: a temporary "
                                                      "folder)")
    args = parser.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    browser = _chromium()
    print(f"rendering pages with {browser}" if browser else "no Chromium: stacking each report's figures instead")
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(args.keep) if args.keep else Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        made = []

        folder = work / "scenario"
        _run(["run", "tests/pneusim/scenario/data/tiny-generalisation.toml", "--out", folder, "--no-progress",
              "--overwrite"])
        made.append(_picture("pneusim run: scenario report", folder, "report.html",
                             ["validation.png", "generalisation-supply-2-bar.png", "generalisation.png"],
                             out / "scenario-report.png", browser))

        folder = work / "sweep"
        sweep = work / "sweep-small.toml"
        sweep.write_text(f"""[sweep]
name = "screenshot"
scenario = "{(ROOT / 'scenarios' / 'paper2-multisine.toml').as_posix()}"
seeds = [0]
[base]
"experiment.duration_s" = 10.0
"identifiers.5.enabled" = false
[grid]
"rig.overrides.supply_Pa" = [501325.0, 601325.0, 701325.0]
[random]
n = 3
seed = 0
"rig.overrides.moving_mass_kg" = {{ low = 0.6, high = 3.0, log = true }}
"experiment.noise_scale" = {{ low = 0.5, high = 4.0 }}
""")
        _run(["sweep", sweep, "--out", folder, "--workers", "1", "--no-progress"])
        made.append(_shrink(folder / "summary-rig.overrides.supply_Pa.png", out / "sweep-summary.png"))

        folder = work / "mre"
        _run(["mre", "scenarios/mre-paper1.toml", "--fast", "--duration", "2", "--out", folder, "--no-status",
              "--overwrite"])
        made.append(_stack("pneusim mre: MRE report (the figures of report.md)", [
            folder / f for f in ("response.png", "predictions.png", "timing.png")], out / "mre-report.png"))

        folder = work / "fit"
        recording = work / "run.csv"
        subprocess.run([sys.executable, "-c", f"""
from pneusim.experiment import standard_experiment
from pneusim.recording import write_recording
from pneusim.rig import load_rig
from pneusim.simulate import simulate
rig = load_rig("paper2-enfield")
write_recording(simulate(rig, standard_experiment(rig, "pulses", 12.0, "open", seed=5), seed=6).recording,
                {str(recording)!r})
"""], check=True, cwd=ROOT)
        _run(["fit", recording.name, "--report", folder, "--quiet", "--overwrite"], cwd=work)
        made.append(_picture("pneusim fit --report: fit report", folder, "index.html", ["fit.png"],
                             out / "fit-report.png", browser))

        case = SHARED / "practice2" / "practice2_20.csv"
        if case.exists():
            folder = work / "diagnosis"
            sliced = work / "practice2_20-first-30s.csv"
            subprocess.run([sys.executable, "-c", f"""
from pneusim.recording import read_recording, write_recording
write_recording(read_recording({str(case)!r}).slice(0.0, 30.0), {str(sliced)!r})
"""], check=True, cwd=ROOT)
            _run(["diagnose", sliced.name, "--report", folder, "--quiet", "--overwrite"], cwd=work)
            made.append(_picture("pneusim diagnose --report: diagnosis report", folder, "index.html",
                                 ["fit.png", "residuals.png"], out / "diagnosis-report.png", browser))
        else:
            print(f"{case} not found: no diagnosis screenshot")
    for path in made:
        print(f"wrote {path.relative_to(ROOT) if path.is_relative_to(ROOT) else path} ({path.stat().st_size // 1024} kB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
