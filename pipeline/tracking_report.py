"""Tracker benchmarks for reports/: speed against decoding and the settings sweep.

:func:`tracking_speed` times the whole ``track`` command on 1024×768 video
against merely decoding it; :func:`tracker_settings_sweep` tracks small scenes
under several :class:`pipeline.track.TrackSettings` (accuracy against
frames/s); :func:`drawn_scenes` tracks scenes drawn at random over looks,
noise, blur, sizes, orientations and file formats, none of which chose a
setting of the tracker. :func:`settings_section` and :func:`drawn_section`
are their parts of ``reports/README.md``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

SPEED_FILE = "tracking_speed.csv"
SETTINGS_FILE = "tracking_settings.csv"
SETTINGS_PLOT = "tracking_settings.png"
DRAWN_FILE = "tracking_drawn_scenes.csv"
#: The draw's seed: fixed, so that the report is the same scenes every run.
DRAWN_SEED = 20261123


def _fmt(v, spec=".2f"):
    return "—" if v is None or (isinstance(v, float) and not np.isfinite(v)) else format(v, spec)


def tracking_speed(work: Path, n_frames: int = 100) -> pd.DataFrame:
    """The track command on 1024x768 8-bit MJPG video against merely decoding it
    (each the best of 3 runs), on one CPU.

    Timed in a fresh Python started on one CPU (where the system can pin a
    process), as ``taskset -c 0 microtube track`` would run, its imports left
    out: OpenCV, OpenBLAS and pyarrow size their thread pools by the CPUs they
    see when loaded, and pools sized for more CPUs than a process is then held
    to spin against the work (pinning this process's threads afterwards made
    the run 4x slower).
    """
    from .render import default_scene, render_scene

    scene = default_scene(1, n_frames=n_frames, seed=31, width=1024, height=768)
    scene_dir = render_scene(scene, work / "speed_scene", fmt="avi")
    t = _on_one_cpu("from pipeline.tracking_report import _time_track; "
                    "print(json.dumps(_time_track(sys.argv[1], sys.argv[2])))",
                    scene_dir / "frames.avi", work / "speed_track")
    decode, total = t["decode_s"], t["track_s"]
    # the command as a user types it: a fresh process, its start-up included
    command = min(_timed_process(["-m", "pipeline", "track", scene_dir / "frames.avi",
                                  "--out", work / "speed_command", "--um-per-px", "12"])
                  for _ in range(3))
    startup = min(_timed_process(["-c", "import pipeline.cli, pipeline.tracks"])
                  for _ in range(3))
    return pd.DataFrame([{
        "video": "1024x768 8-bit MJPG AVI, sample #1 inflating", "frames": n_frames,
        "one_core": t["cpus"] == 1,
        "decode_s": decode, "decode_frames_per_s": n_frames / decode,
        "opencv_colour_decode_s": t["opencv_s"],
        "ratio_to_opencv_colour_decode": total / t["opencv_s"],
        "track_command_s": total, "track_frames_per_s": n_frames / total,
        "ratio_to_decode": total / decode, "frames_ok": t["frames_ok"],
        "later_frames_per_s": 1.0 / t["later_frame_s"],
        "command_s": command, "command_frames_per_s": n_frames / command,
        "startup_s": startup,
        "target_frames_per_s": 100, "meets_target": n_frames / total >= 100,
    }])


def _on_one_cpu(code: str, *args):
    """Run ``code`` (which has ``json`` and ``sys`` imported, and prints one
    JSON document) in a fresh Python held to one CPU from its start where the
    system can pin a process (else on all); its document."""
    done, _ = _python_on_one_cpu(["-c", "import json, sys; " + code, *args])
    return json.loads(done.stdout.strip().splitlines()[-1])


def _timed_process(args) -> float:
    """Wall time of ``python ARGS`` in a fresh process held to one CPU where the
    system can pin one, s."""
    return _python_on_one_cpu(args)[1]


def _python_on_one_cpu(args):
    """``python ARGS`` in a fresh process held to one CPU from its start where
    the system can pin one: the finished process and its wall time, s; a
    RuntimeError with its last line of stderr if it failed."""
    cpu = min(os.sched_getaffinity(0)) if hasattr(os, "sched_setaffinity") else None
    start = time.perf_counter()
    done = subprocess.run(
        [sys.executable, *map(str, args)], capture_output=True, text=True, check=False,
        preexec_fn=None if cpu is None else (lambda: os.sched_setaffinity(0, {cpu})))
    elapsed = time.perf_counter() - start
    if done.returncode:
        last = (done.stderr.strip().splitlines() or ["no message"])[-1]
        raise RuntimeError(f"the speed benchmark failed: {last}")
    return done, elapsed


def _time_track(video, out) -> dict:
    """Best of 3 decodings of ``video`` (by the frame reader, and by OpenCV's
    own colour decoding and grey conversion) and of 3 track runs into ``out``,
    s (as timeit: the other runs' extra time is the machine's, not ours)."""
    import cv2

    from .frames import open_frames
    from .tracks import track_video

    decode = total = opencv = later = np.inf
    for _ in range(3):
        start = time.perf_counter()
        with open_frames(video) as reader:
            for _ in reader:
                pass
        decode = min(decode, time.perf_counter() - start)
        start = time.perf_counter()
        cap = cv2.VideoCapture(str(video))
        while (got := cap.read())[0]:
            cv2.cvtColor(got[1], cv2.COLOR_BGR2GRAY)
        cap.release()
        opencv = min(opencv, time.perf_counter() - start)
        done = {}

        def tick(n, _total, done=done):
            done[n] = time.perf_counter()

        start = time.perf_counter()
        run = track_video(video, out, um_per_px=12.0, progress=tick)
        total = min(total, time.perf_counter() - start)
        # the second half's frames, each once the first frames' work is done
        # (detection, the look, the base votes): what each further frame of a
        # longer video costs
        n = max(done)
        later = min(later, (done[n] - done[n // 2]) / (n - n // 2))
    return {"decode_s": decode, "opencv_s": opencv, "track_s": total, "frames_ok": run.n_ok,
            "later_frame_s": later,
            "cpus": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None}


def _sweep_settings() -> dict:
    """The tracker settings the sweep compares, by name (the first is the default)."""
    from .track import TrackSettings

    return {
        "default": TrackSettings(),
        "1 round": TrackSettings(rounds=1),
        "2 rounds": TrackSettings(rounds=2),
        "5 rounds": TrackSettings(rounds=5),
        "fast tol 0.02 px": TrackSettings(fast_tol_px=0.02),
        "coarse spline": TrackSettings(widths_per_coef=1.5),
    }


def _sweep_scenes() -> dict:
    """Small scenes for the settings sweep: a plain look, a hard look, an over-curl."""
    from .render import default_scene

    return {
        "plain": default_scene(1, n_frames=30, seed=51, width=640, height=480,
                               base_angle_deg=0.0),
        "blur_noise": default_scene(3, n_frames=30, seed=52, width=640, height=480,
                                    base_angle_deg=30.0,
                                    look={"name": "transmitted", "blur_px": 1.5,
                                          "photons": 600.0, "read_noise": 0.01}),
        # sample #3 made softer, as the committed overcurl scene: crosses itself
        "overcurl": default_scene(3, n_frames=30, seed=53, width=640, height=480,
                                  base_angle_deg=180.0, eps_max=0.6397),
    }


def tracker_settings_sweep(work: Path, *, repeats: int = 3) -> pd.DataFrame:
    """Accuracy against speed of the tracker under several :class:`TrackSettings`.

    Each scene of :func:`_sweep_scenes` (rendered to MJPG AVI) is tracked with
    ``track_video`` under every setting of :func:`_sweep_settings` and scored
    against its truth (:func:`pipeline.accuracy.score_folder`). ``frames_per_s``
    is the rate after the first frame (which finds the tube from scratch),
    decoding included, from each frame's best time over ``repeats`` runs
    (tracking is deterministic; only the clock varies).

    Returns
    -------
    DataFrame
        One row per scene and setting: ``scene``, ``setting``, the settings'
        fields, ``is_default``, ``frames``, ``frames_per_s``,
        ``angle_median_deg``, ``angle_p95_deg``, ``angle_max_deg`` (absolute
        bend-angle error), ``centreline_rms_px``, ``frames_lost`` and
        ``frames_wide_or_redetect`` (frames whose fast fit failed its checks).
    """
    import json
    from dataclasses import asdict

    from .accuracy import score_folder
    from .render import render_scene
    from .tracks import track_video

    work = Path(work)
    settings = _sweep_settings()
    rows = []
    for scene_name, scene in _sweep_scenes().items():
        scene_dir = render_scene(scene, work / f"sweep_{scene_name}_scene", fmt="avi")
        scale = json.loads((scene_dir / "scene.json").read_text())["layout"]["um_per_px"]
        for i, (name, setting) in enumerate(settings.items()):
            out = work / f"sweep_{scene_name}_{i}"
            per_frame = None
            for _ in range(repeats):
                done = []
                run = track_video(scene_dir / "frames.avi", out, um_per_px=scale,
                                  settings=setting,
                                  progress=lambda k, n, done=done: done.append(
                                      time.perf_counter()))
                # each frame's best time over the repeats: a busy machine slows
                # different frames in different runs
                dt = np.diff(done)
                per_frame = dt if per_frame is None else np.minimum(per_frame, dt)
            _, acc = score_folder(scene_dir, out)
            rows.append({"scene": scene_name, "setting": name, **asdict(setting),
                         "is_default": i == 0, "frames": run.n_frames,
                         "frames_per_s": (per_frame.size / per_frame.sum() if per_frame.size
                                          else float("nan")),
                         "angle_median_deg": acc.angle_median,
                         "angle_p95_deg": acc.angle_p95, "angle_max_deg": acc.angle_max,
                         "centreline_rms_px": acc.centreline_rms_px,
                         "frames_lost": acc.frames_lost,
                         "frames_wide_or_redetect": (run.stages.get("wide", 0)
                                                     + run.stages.get("redetect", 0))})
    return pd.DataFrame(rows)


def plot_settings(sweep: pd.DataFrame, path: Path) -> Path:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.ticker import FixedLocator, FormatStrFormatter, NullFormatter

    fig = Figure(figsize=(8, 4.6))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    markers = {name: "o^vsDPX*hp"[i % 10] for i, name in enumerate(sweep["setting"].unique())}
    colours = {name: f"C{i % 10}" for i, name in enumerate(sweep["scene"].unique())}
    for r in sweep.itertuples(index=False):
        ax.plot(r.frames_per_s, r.angle_p95_deg, markers[r.setting], color=colours[r.scene],
                ms=9 if r.is_default else 6, mfc=colours[r.scene] if r.is_default else "none",
                mew=1.3)
    ax.axhline(2.0, color="0.6", lw=0.6, ls="--")
    handles = [ax.plot([], [], markers[m], color="0.3", mfc="none", label=m)[0]
               for m in markers]
    handles += [ax.plot([], [], "s", color=c, label=f"scene: {s}")[0]
                for s, c in colours.items()]
    ax.legend(handles=handles, fontsize=7, ncol=2)
    ax.set_yscale("log")  # a wrong setting is off by tens of degrees, the rest by tenths
    ax.yaxis.set_major_locator(FixedLocator([0.2, 0.5, 1, 2, 5, 10, 20, 50, 100]))
    ax.yaxis.set_major_formatter(FormatStrFormatter("%g"))
    ax.yaxis.set_minor_formatter(NullFormatter())
    ax.set_xlabel("frames/s (after the first frame, decoding included)")
    ax.set_ylabel("p95 |bend-angle error| (deg)")
    ax.set_title("Tracker settings: accuracy against speed (filled: default; dashed: 2° target)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path


def settings_section(sweep: pd.DataFrame, speed: pd.DataFrame) -> list[str]:
    """README lines for the tracker-settings sweep: a table per setting and scene."""
    scenes = list(sweep["scene"].unique())
    lines = [
        "### Tracker settings: accuracy against speed", "",
        f"![p95 bend-angle error against frames/s per tracker setting]({SETTINGS_PLOT})", "",
        "Small scenes (640×480, 30 frames each: `plain` = sample #1; `blur_noise` = sample "
        "#3 blurred, with few photons; `overcurl` = sample #3 made softer, curling past a "
        "turn over itself) tracked under several `pipeline.track.TrackSettings`: the "
        "fast path's Gauss–Newton rounds (and the rounds on the frame after a start), "
        "the convergence tolerance `tol_px` (and, in brackets, the fast path's "
        "`fast_tol_px`), and the spline's spacing in tube widths per "
        "coefficient while the section joints are not known (and, in brackets, once they "
        "are: given by a sample, or found in the frames). Each cell: p95 |bend-angle "
        "error| · frames/s after the first frame (decoding included; each frame's best "
        "of 3 runs).", "",
        "| setting | rounds (after a start) | tol (px) | widths/coef | "
        + " | ".join(scenes) + " |",
        "|---|---|---|---|" + "---|" * len(scenes),
    ]
    for name, g in sweep.groupby("setting", sort=False):
        g = g.set_index("scene")
        first = g.iloc[0]
        cells = []
        for sc in scenes:
            r = g.loc[sc]
            lost = f" ({int(r.frames_lost)} lost)" if r.frames_lost else ""
            cells.append(f"{_fmt(r.angle_p95_deg)}° · {r.frames_per_s:.0f}{lost}")
        label = f"**{name}**" if first.is_default else name
        lines.append(f"| {label} | {int(first.rounds)} ({int(first.first_rounds)}) "
                     f"| {first.tol_px:g} ({first.fast_tol_px:g}) | {first.widths_per_coef:g} "
                     f"({first.jointed_widths_per_coef:g}) | "
                     + " | ".join(cells) + " |")
    default = sweep[sweep["is_default"]].set_index("scene")

    def vs_default(name):
        g = sweep[sweep["setting"] == name].set_index("scene")
        return (float(np.median(g["frames_per_s"] / default["frames_per_s"])),
                float(g["angle_p95_deg"].max()))

    fewest = sweep.loc[sweep["rounds"].idxmin(), "setting"]
    fast_ratio, fast_p95 = vs_default(fewest)
    coarse = sweep.loc[sweep["widths_per_coef"].idxmax(), "setting"]
    coarse_ratio, coarse_p95 = vs_default(coarse)
    coarse_cells = ", ".join(
        f"{sc} {p:.2f}° against {default.loc[sc, 'angle_p95_deg']:.2f}°"
        for sc, p in sweep[sweep["setting"] == coarse].set_index("scene")["angle_p95_deg"].items())
    # how far the p95 moves with the rounds and the tolerance alone (same spline)
    fine = sweep[(sweep["widths_per_coef"] == default["widths_per_coef"].iloc[0])
                 & ~sweep["is_default"]]
    shift = (fine.set_index("scene")["angle_p95_deg"]
             - default["angle_p95_deg"].reindex(fine["scene"]).to_numpy())
    either = " either way" if shift.min() < 0 < shift.max() else ""
    d = sweep[sweep["is_default"]].iloc[0]
    rate = float(speed.iloc[0].track_frames_per_s)
    lines += ["", (
        f"[`{SETTINGS_FILE}`]({SETTINGS_FILE}) adds the median and max errors, the "
        "centreline RMS and the frames that needed the wide search. The rounds and the "
        f"tolerance move the p95 error by at most {np.abs(shift).max():.1f}°{either}: "
        "the error is set by the edges more than by how long Gauss–Newton runs from the "
        f"constant-velocity prediction. {fewest[0].upper() + fewest[1:]} runs at "
        f"{fast_ratio:.1f}× the default's frames/s (worst p95 over the scenes "
        f"{fast_p95:.2f}°, against {default['angle_p95_deg'].max():.2f}°). The default — "
        f"**{int(d.rounds)} rounds ({int(d.first_rounds)} after a start), tol "
        f"{d.tol_px:g} px ({d.fast_tol_px:g} px on the fast path), one coefficient per "
        f"{d.widths_per_coef:g} widths "
        f"({d.jointed_widths_per_coef:g} once the joints are known)** — stays, "
        "and every other figure here uses it: "
        + (f"{fewest} would be about as accurate here and faster, but "
           if fast_p95 <= default["angle_p95_deg"].max() + 0.5 else "")
        + "fewer rounds leave no margin on frames the constant-velocity prediction misses "
        "(a sudden pressure step), which these smoothly inflating scenes do not test"
        + (f"; the default still tracks at {rate:.0f} frames/s on 1024×768 video (above). "
           if rate >= 100 else ". ") +
        f"The {coarse} ({sweep['widths_per_coef'].max():g} widths per coefficient while "
        f"the joints are not known) runs at {coarse_ratio:.1f}× the default's frames/s, "
        f"worst p95 {coarse_p95:.2f}° (per scene: {coarse_cells}). It differs from the "
        "default only where no joint is found (a joint found switches to the jointed "
        "spacing either way). The finer spacing stays for that case: it is the spline "
        "the tube is found with at a start, where a coarse one cannot follow the "
        "skeleton's hooks (sample #1 came out 31 % short), and it must follow the "
        "curvature steps of a tube whose joints are not found.")]
    return lines


#: Look settings drawn besides the look itself: (field, share of the scenes,
#: range). Noise and blur; then uneven light, dust, flicker and fainter tubes
#: than the looks' own.
_DRAWN_LOOK = (("photons", 0.4, (500, 1500)), ("blur_px", 0.3, (0.5, 2.0)),
               ("gradient", 0.4, (0.2, 0.6)), ("vignetting", 0.4, (0.2, 0.6)),
               ("dust", 0.3, (10, 60)), ("flicker", 0.2, (0.01, 0.05)),
               ("contrast", 0.2, (0.25, 0.6)))


def _draw_scene(rng: np.random.Generator, index: int):
    """One scene drawn at random, and the file format to render it in."""
    from .render import default_scene

    sample = int(rng.integers(1, 9))
    look = {"name": str(rng.choice(["transmitted", "fluorescent", "low_contrast", "opaque"]))}
    for field, share, (low, high) in _DRAWN_LOOK:
        if field == "contrast" and look["name"] == "fluorescent":
            continue  # (an emitting tube has no transmission contrast)
        if rng.random() < share:
            look[field] = (int(rng.integers(low, high)) if field == "dust"
                           else float(rng.uniform(low, high)))
    width, height = ((320, 240), (480, 360), (640, 480), (800, 600), (1024, 768))[
        int(rng.integers(0, 5))]
    fmt, depth = (("avi", 8), ("mp4", 8), ("png", 8), ("tiff", 16))[int(rng.integers(0, 4))]
    angle, mirror = float(rng.uniform(0, 360)), bool(rng.random() < 0.5)
    scene = default_scene(sample, n_frames=12, seed=DRAWN_SEED + index, look=look,
                          width=width, height=height, base_angle_deg=angle, mirror=mirror)
    return scene, fmt, depth


def drawn_scenes(work: Path, n: int = 24) -> pd.DataFrame:
    """Track ``n`` scenes drawn at random (seed :data:`DRAWN_SEED`) at their
    scale, one row per scene: what was drawn and how well it was tracked.

    Samples 1–8; transmitted, fluorescent, low-contrast or opaque; 40 % with
    few photons (500–1500), 30 % blurred (0.5–2 px); 40 % each with a stronger
    illumination gradient or vignetting (0.2–0.6), 30 % with 10–60 dust specks,
    20 % with flicker (1–5 %), 20 % of the non-fluorescent ones fainter
    (contrast 0.25–0.6); 320×240 to 1024×768; any orientation, mirrored or
    not; MJPG AVI, MP4, PNG folder or 16-bit TIFF.
    """
    import json

    from .accuracy import score_folder
    from .render import render_scene
    from .tracks import track_video

    rng = np.random.default_rng(DRAWN_SEED)
    rows = []
    for i in range(n):
        scene, fmt, depth = _draw_scene(rng, i)
        scene_dir = render_scene(scene, work / f"drawn_{i:02d}", fmt=fmt, bit_depth=depth)
        record = json.loads((scene_dir / "scene.json").read_text())
        out = work / f"drawn_{i:02d}_tracked"
        track_video(scene_dir / record["frames_file"], out,
                    um_per_px=record["layout"]["um_per_px"])
        _, acc = score_folder(scene_dir, out)
        look = scene.look if isinstance(scene.look, dict) else {"name": str(scene.look)}
        rows.append({
            "scene": f"drawn_{i:02d}", "sample": scene.sample, "look": look.get("name"),
            "photons": look.get("photons", np.nan), "blur_px": look.get("blur_px", np.nan),
            "size": f"{scene.width}x{scene.height}", "format": f"{fmt}/{depth}",
            "base_angle_deg": scene.base_angle_deg, "mirror": scene.mirror,
            "frames": acc.frames, "frames_lost": acc.frames_lost,
            "angle_median_deg": acc.angle_median, "angle_p95_deg": acc.angle_p95,
            "angle_max_deg": acc.angle_max, "centreline_rms_px": acc.centreline_rms_px,
            "length_error_max_pct": acc.length_error_max_pct,
            "meets_targets": acc.meets_targets()})
    return pd.DataFrame(rows)


def drawn_section(drawn: pd.DataFrame) -> list[str]:
    """The drawn scenes' part of ``reports/README.md``."""
    ok = drawn[drawn["meets_targets"]]
    failed = drawn[~drawn["meets_targets"]].sort_values("angle_median_deg", ascending=False)
    lines = [
        "### Scenes drawn at random", "",
        f"{len(drawn)} scenes drawn at random (fixed seed) over what a lab's videos vary in: "
        "samples 1–8; transmitted, fluorescent, low-contrast or opaque; 40 % with few "
        "photons (500–1500), 30 % blurred (0.5–2 px); 40 % each with a stronger "
        "illumination gradient or vignetting, 30 % with 10–60 dust specks, 20 % with "
        "flicker, 20 % of the non-fluorescent ones fainter; 320×240 to 1024×768; any "
        "orientation, mirrored or not; MJPG AVI, MP4, PNG folder or 16-bit TIFF; 12 frames "
        "each. No setting of the tracker was chosen on them.", "",
        f"**{len(ok)} of {len(drawn)} meet every target**; frames lost: "
        f"{int(drawn['frames_lost'].sum())} of {int(drawn['frames'].sum())}; median over "
        f"scenes of the angle median / p95 / max: {drawn['angle_median_deg'].median():.2f} / "
        f"{drawn['angle_p95_deg'].median():.2f} / {drawn['angle_max_deg'].median():.2f}°.", "",
    ]
    if len(failed):
        lines += ["Those that miss a target:", "",
                  "| scene | sample | look | photons | blur (px) | size | format | lost "
                  "| median (°) | p95 (°) | max (°) | RMS (px) | length (%) |",
                  "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in failed.itertuples(index=False):
            lines.append(
                f"| {r.scene} | {r.sample} | {r.look} | {_fmt(r.photons, '.0f')} "
                f"| {_fmt(r.blur_px, '.1f')} | {r.size} | {r.format} | {r.frames_lost} "
                f"| {_fmt(r.angle_median_deg)} | {_fmt(r.angle_p95_deg)} "
                f"| {_fmt(r.angle_max_deg)} | {_fmt(r.centreline_rms_px, '.3f')} "
                f"| {_fmt(r.length_error_max_pct)} |")
        lines.append("")
    lines.append(f"Every scene: [`{DRAWN_FILE}`]({DRAWN_FILE}).")
    return lines
