"""Own-renderer regression set: the report's scenes (committed, stress, drawn), rendered once
into evals/own/scenes, tracked by whatever `pipeline` is first on PYTHONPATH (a worktree of
another commit, to compare).

  .venv/bin/python evals/own_eval.py render
  PYTHONPATH=/tree .venv/bin/python evals/own_eval.py track OUT [-j 2] [--only a b]
  .venv/bin/python evals/own_compare.py OUT_A OUT_B
"""
import json, sys, time, argparse
from pathlib import Path
from concurrent.futures import ProcessPoolExecutor
import numpy as np, pandas as pd

HERE = Path(__file__).parent / "own"
SCENES = HERE / "scenes"


def render():
    from pipeline.report import _stress_scenes
    from pipeline.render import render_scene
    from pipeline.tracking_report import _draw_scene, DRAWN_SEED
    import shutil
    SCENES.mkdir(parents=True, exist_ok=True)
    for name in ("sample1", "sample2", "sample3", "overcurl"):
        src = Path(__file__).resolve().parents[1] / "sample_frames" / name
        if not (SCENES / name).exists():
            shutil.copytree(src, SCENES / name)
    for name, scene in _stress_scenes().items():
        render_scene(scene, SCENES / name, fmt="avi")
    rng = np.random.default_rng(DRAWN_SEED)
    for i in range(24):
        scene, fmt, depth = _draw_scene(rng, i)
        render_scene(scene, SCENES / f"drawn_{i:02d}", fmt=fmt, bit_depth=depth)


def _one(args):
    name, out = args
    from pipeline.tracks import track_video
    from pipeline.accuracy import score_folder
    d = SCENES / name
    rec = json.loads((d / "scene.json").read_text())
    t0 = time.perf_counter()
    try:
        track_video(d / rec["frames_file"], Path(out) / name, um_per_px=rec["layout"]["um_per_px"])
    except Exception as e:  # noqa
        return {"scene": name, "error": repr(e)[:200]}
    dt = time.perf_counter() - t0
    err, acc = score_folder(d, Path(out) / name)
    err.insert(0, "scene", name)
    err.to_csv(Path(out) / name / "errors.csv", index=False)
    return {"scene": name, "lost": acc.frames_lost, "median": acc.angle_median, "p95": acc.angle_p95,
            "max": acc.angle_max, "rms": acc.centreline_rms_px, "len": acc.length_error_max_pct,
            "base": float(err.base_error_px.median()),
            "ok": acc.meets_targets(), "s": dt}


def track(out, jobs, only):
    names = sorted(p.name for p in SCENES.iterdir() if p.is_dir())
    if only:
        names = [n for n in names if n in only]
    Path(out).mkdir(parents=True, exist_ok=True)
    with ProcessPoolExecutor(jobs) as ex:
        rows = list(ex.map(_one, [(n, out) for n in names]))
    df = pd.DataFrame(rows)
    df.to_csv(Path(out) / "summary.csv", index=False)
    with pd.option_context("display.width", 200, "display.max_rows", 200):
        print(df.round(3).to_string(index=False))
    print(f"{int(df.ok.sum())}/{len(df)} pass, lost {int(df.lost.sum())}")


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("cmd")
    ap.add_argument("out", nargs="?")
    ap.add_argument("-j", type=int, default=2)
    ap.add_argument("--only", nargs="*")
    a = ap.parse_args()
    render() if a.cmd == "render" else track(a.out, a.j, a.only)
