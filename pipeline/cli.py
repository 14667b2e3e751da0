"""The ``microtube`` command line (also ``python -m pipeline``).

Only this module talks to the terminal: it parses options, draws progress bars
(tqdm, on a terminal only), and turns every error about the input into one
clear line on stderr with exit status 2 (3 for an internal error, 130 when
interrupted). Library code never prints.

A failed run leaves no output behind and never replaces a good one: ``track``
writes into a hidden folder inside ``--out`` and moves the files into place
only once the run has succeeded.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import shutil
import sys
import tempfile
from pathlib import Path

from . import schema as S

EXAMPLES = {
    "track": "microtube track video.avi --out tracked/ --um-per-px 12.5\n"
             "  microtube track frames/ --out tracked/ --sample 1 --base 12,380",
    "calibrate": "microtube calibrate --sample 1 --tracks tracked/ --pressure pressure.csv "
                 "--out fit.json",
    "render": "microtube render --sample 1 --out scene/ --format avi --frames 50 --seed 3\n"
              "  microtube render --sample-frames --out sample_frames/",
    "demo": "microtube demo",
    "report": "microtube report --out reports/",
}


class CliError(Exception):
    """An error to report in one line."""


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (argparse prints the usage first)."""

    def error(self, message):
        if message.endswith("expected one argument"):
            # argparse takes a value such as "-5,10" for an option
            message += " (write a value that starts with '-' as --option=VALUE)"
        self.exit(2, f"{self.prog}: error: {message} (see '{self.prog} --help')\n")


def _output_folder(path, option: str = "--out") -> Path:
    """``path`` as a Path, refusing an existing non-folder before any work is done."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise CliError(f"{option} {path}: exists and is not a folder")
    return path


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"must be a positive number, got {text!r}")
    return value


def _non_negative_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not value >= 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"must be a number >= 0, got {text!r}")
    return value


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be a positive whole number, got {text!r}")
    return value


def _progress(quiet: bool, desc: str):
    """A ``progress(done, total)`` callback drawing a tqdm bar on a terminal, or None."""
    if quiet or not sys.stderr.isatty():
        return None, lambda: None
    from tqdm import tqdm

    bar = tqdm(desc=desc, unit="frame", leave=False, dynamic_ncols=True)

    def update(done, total):
        if total and bar.total != total:
            bar.total = total
        bar.n = done
        bar.refresh()

    return update, bar.close


def cmd_track(args) -> int:
    from .tracks import track_video

    out = _output_folder(args.out)
    with _staged_outputs(out) as stage:
        update, close = _progress(args.quiet, "tracking")
        try:
            run = track_video(args.input, stage, um_per_px=args.um_per_px, sample=args.sample,
                              base=args.base, fps=args.fps, overlay=args.overlay,
                              progress=update)
        finally:
            close()
        if run.n_ok == 0:
            # a table of NaN rows is no result: fail, keep any earlier output
            import pandas as pd

            why = pd.read_csv(stage / S.TRACKS_FILE)[S.STATUS].value_counts()
            raise CliError(f"no frame of the {run.n_frames} could be measured ("
                           + "; ".join(f"{k}: {v} frames" for k, v in why.items())
                           + f"); nothing written to {out}")
    stale = out / "overlay.png"
    if not args.overlay and stale.exists():
        # an earlier run's picture would show other centrelines than these tracks
        stale.unlink()
    if not args.quiet:
        print(f"tracked {run.n_ok}/{run.n_frames} frames in {run.runtime_s:.2f} s "
              f"({run.frames_per_s:.0f} frames/s) -> {out}")
        for note in run.notes:
            print(f"  - {note}")
    return 0


@contextlib.contextmanager
def _staged_outputs(out: Path):
    """A hidden folder inside ``out`` whose files replace those of ``out`` only on success.

    On failure the staging folder is removed, and so are the folders made for
    ``out`` if they are still empty: a failed run leaves nothing behind and
    keeps an earlier run's files as they were.
    """
    made = []  # folders created here, deepest first
    missing = out
    while not missing.exists() and missing != missing.parent:
        made.append(missing)
        missing = missing.parent
    out.mkdir(parents=True, exist_ok=True)
    stage = Path(tempfile.mkdtemp(prefix=".microtube-", suffix=".part", dir=out))
    try:
        yield stage
        # each move is atomic (one file system); tracks.csv last, so whoever sees
        # the new tracks.csv also finds the new centrelines
        for f in sorted(stage.iterdir(), key=lambda f: (f.name == S.TRACKS_FILE, f.name)):
            os.replace(f, out / f.name)
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        for folder in made:
            try:
                folder.rmdir()
            except OSError:
                break
        raise
    shutil.rmtree(stage, ignore_errors=True)


def cmd_calibrate(args) -> int:
    if args.pressure is not None and args.p_max is not None:
        raise CliError("give either --pressure or --p-max, not both")
    out = Path(args.out)
    if out.is_dir():
        raise CliError(f"--out {out}: is a folder; give the result's file name, e.g. "
                       f"{out / 'fit.json'}")
    tracks = Path(args.tracks)
    inputs = [tracks / S.TRACKS_FILE, tracks / S.CENTRELINES_FILE] + (
        [Path(args.pressure)] if args.pressure else [])
    if any(out.resolve() == p.resolve() for p in inputs):
        raise CliError(f"--out {out} would overwrite an input file; give another name, e.g. "
                       f"{out.with_name('fit.json')}")
    from .calibrate import calibrate_folder

    result = calibrate_folder(args.sample, args.tracks, pressure_csv=args.pressure,
                              p_max=args.p_max, model=args.model, n_segments=args.segments,
                              out_json=args.out, **({} if args.tracking_sd_deg is None else
                                                    {"tracking_sd_deg": args.tracking_sd_deg}))
    if not args.quiet:
        print(result.summary() if hasattr(result, "summary") else f"wrote {args.out}")
    return 0


def cmd_render(args) -> int:
    chosen = [x for x in (args.sample, args.scene) if x is not None] + (
        ["--sample-frames"] if args.sample_frames else [])
    if len(chosen) != 1:
        raise CliError("give exactly one of --sample ID, --scene scene.json or "
                       "--sample-frames")
    update, close = _progress(args.quiet, "rendering")
    try:
        if args.sample_frames:
            from .sample_scenes import write_sample_frames

            written = write_sample_frames(args.out, progress=update)
            if not args.quiet:
                print(f"rendered {len(written)} scenes -> {args.out}")
            return 0
        from .render import render_to_folder

        size = _size(args.size)
        out = render_to_folder(args.sample, args.out, fmt=args.format, n_frames=args.frames,
                               seed=args.seed, look=args.look, bit_depth=args.bit_depth,
                               scene_file=args.scene, progress=update,
                               **({} if args.scene else {
                                   "base_angle_deg": args.angle, "mirror": args.mirror,
                                   "width": size[0], "height": size[1]}))
    finally:
        close()
    if not args.quiet:
        print(f"rendered {'scene ' + args.scene if args.scene else 'sample ' + args.sample} "
              f"-> {out}")
    return 0


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise CliError(f"--size must be WIDTHxHEIGHT in px, e.g. 1024x768, got {text!r}") \
            from None
    if w < 32 or h < 32:
        raise CliError(f"--size must be at least 32x32 px, got {text!r}")
    return w, h


def cmd_demo(args) -> int:
    from .demo import run_demo

    _output_folder(args.out)
    _output_folder(args.reports, "--reports")
    run_demo(frames_dir=args.frames, out_dir=args.out, reports_dir=args.reports,
             quiet=args.quiet)
    return 0


def cmd_report(args) -> int:
    from .report import write_reports

    _output_folder(args.out)
    paths = write_reports(args.out, benchmarks=args.benchmarks, quiet=args.quiet)
    if not args.quiet:
        print(f"wrote {len(paths)} files into {args.out}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="microtube",
        description="Track, measure and model the bending of pneumatic microtube actuators.",
        epilog="Run 'microtube COMMAND --help' for a command's options and an example.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    def add(name, help_text, func):
        p = sub.add_parser(name, help=help_text, description=help_text,
                           epilog="example:\n  " + EXAMPLES[name],
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        p.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors")
        p.set_defaults(func=func, subparser=p)
        return p

    p = add("track", "Track the tube in a video, a folder of images or a multi-page TIFF: "
            "centreline and bend angle for every frame.", cmd_track)
    p.add_argument("input", help="video file, folder of images, or multi-page TIFF")
    p.add_argument("--out", required=True, help="output folder (tracks.csv, centrelines.csv, "
                   "run.json)")
    scale = p.add_mutually_exclusive_group()
    scale.add_argument("--um-per-px", type=_positive_float, help="image scale, um per pixel")
    scale.add_argument("--sample", help="catalogue id (1-8) or sample .toml: the scale is then "
                       "taken from its length L_tot on the least-bent frame")
    p.add_argument("--base", help="where the tube leaves the pipette, X,Y in pixels "
                   "(found automatically otherwise)")
    p.add_argument("--fps", type=_positive_float, help="frame rate, when the file has none")
    p.add_argument("--overlay", action="store_true",
                   help="also write overlay.png with the tracked centrelines")

    p = add("calibrate", "Fit the line-segment (or Euler-Bernoulli) model to tracked shapes "
            "of one sample.", cmd_calibrate)
    p.add_argument("--sample", required=True, help="catalogue id (1-8) or sample .toml")
    p.add_argument("--tracks", required=True, help="folder written by 'microtube track'")
    p.add_argument("--pressure", help="pressure log CSV (frame or time_s, pressure_mpa)")
    p.add_argument("--p-max", type=_positive_float,
                   help="without a log: pressure ramps linearly from 0 to this, MPa")
    p.add_argument("--model", choices=("ls", "eb"), default="ls")
    p.add_argument("--segments", type=_positive_int, help="line segments N (default 1000)")
    p.add_argument("--tracking-sd-deg", type=_non_negative_float,
                   help="the tracker's systematic tip-angle error (1 sd, degrees) added to "
                        "the 95%% intervals (default 0.25; 0: bootstrap over frames and "
                        "length error only)")
    p.add_argument("--out", required=True, help="result JSON (residuals CSV and overlay PNG "
                   "are written beside it)")

    p = add("render", "Render synthetic microscope frames of a sample with known truth.",
            cmd_render)
    p.add_argument("--sample", help="catalogue id (1-8) or sample .toml")
    p.add_argument("--scene", help="regenerate the scene described by a scene.json")
    p.add_argument("--sample-frames", action="store_true",
                   help="regenerate all the committed scenes of sample_frames/")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--format", choices=("avi", "mp4", "png", "tiff"), default=None,
                   help="default: avi, or the scene file's own with --scene")
    p.add_argument("--frames", type=_positive_int, default=50)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--look", default="transmitted",
                   help="transmitted, opaque, fluorescent or low_contrast")
    p.add_argument("--bit-depth", type=int, choices=(8, 16), default=None,
                   help="default: 8, or the scene file's own with --scene")
    p.add_argument("--size", default="1024x768", help="image size WIDTHxHEIGHT, px")
    p.add_argument("--angle", type=float, default=0.0,
                   help="direction of the tube at its base, degrees CCW from +x")
    p.add_argument("--mirror", action="store_true", help="curl clockwise")

    p = add("demo", "Track every scene in sample_frames/, calibrate each sample, compare with "
            "the truth and write reports/.", cmd_demo)
    p.add_argument("--frames", default=None, help="scenes folder (default: sample_frames/)")
    p.add_argument("--out", default="demo_out", help="where tracks and fits go")
    p.add_argument("--reports", default="reports", help="where the reports go")

    p = add("report", "Write reports/: model accuracy and speed, stability, paper "
            "reproduction, tracking and calibration results.", cmd_report)
    p.add_argument("--out", default="reports")
    p.add_argument("--benchmarks", action="store_true",
                   help="also run the slower speed benchmarks")
    return parser


def main(argv=None) -> int:
    """Run the command line on ``argv`` (default ``sys.argv[1:]``); return the exit status.

    0 on success (also for ``--help``), 2 for bad options or input, 3 for an
    internal error, 130 when interrupted; errors are one line on stderr.
    """
    parser = build_parser()
    try:
        args, extra = parser.parse_known_args(argv)
        if extra:  # name the subcommand whose options these are not
            args.subparser.error(f"unrecognized arguments: {' '.join(extra)}")
    except SystemExit as exc:  # --help, or an option error already printed
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
    try:
        return args.func(args)
    except KeyboardInterrupt:
        print("microtube: interrupted", file=sys.stderr)
        return 130
    except (CliError, ValueError, OSError) as exc:
        print(f"microtube {args.command}: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    except Exception as exc:  # a bug, not bad input: still one line unless debugging
        if os.environ.get("MICROTUBE_DEBUG"):
            raise
        print(f"microtube {args.command}: internal error: {type(exc).__name__}: "
              f"{_one_line(exc)} (set MICROTUBE_DEBUG=1 for the traceback)", file=sys.stderr)
        return 3


def _one_line(exc: BaseException) -> str:
    if isinstance(exc, OSError) and exc.strerror:
        # "[Errno 17] File exists: 'x'" -> "x: file exists"
        text = exc.strerror[:1].lower() + exc.strerror[1:]
        if exc.filename is not None:
            text = f"{exc.filename}: {text}"
        return text
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
