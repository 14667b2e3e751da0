"""The committed scenes in ``sample_frames/``: the demo's default input.

The paper's samples #1–#3 inflated from 0 to their maximum pressure (bending
to the paper's experimental angles, Table 2), each in another look, size,
orientation and file format, plus a harder scene that over-curls past 360°
and crosses its own base. ``microtube render --sample-frames --out DIR``
regenerates them bit for bit.
"""

from __future__ import annotations

from pathlib import Path

from models import get_sample

from .atomic import write_text
from .render import default_scene, render_scene, strain_for_angle


def sample_scenes() -> dict:
    """name → (Scene, format, bit depth) of every committed scene."""
    s3 = get_sample(3)
    return {
        "sample1": (default_scene(1, n_frames=40, seed=11, width=1024, height=768,
                                  notes="paper sample #1, transmitted light, MJPG AVI"),
                    "avi", 8),
        "sample2": (default_scene(2, n_frames=24, seed=12, width=640, height=480,
                                  base_angle_deg=90.0, mirror=True,
                                  notes="paper sample #2, base below, curling clockwise, "
                                        "PNG folder"),
                    "png", 8),
        "sample3": (default_scene(3, n_frames=24, seed=13, width=640, height=480,
                                  base_angle_deg=-90.0, look="opaque",
                                  notes="paper sample #3, opaque tube, base above, "
                                        "multi-page TIFF"),
                    "tiff", 8),
        "overcurl": (default_scene(3, n_frames=60, seed=14, width=800, height=600,
                                   base_angle_deg=180.0,
                                   eps_max=strain_for_angle(s3, 440.0, p_max=0.17),
                                   notes="sample #3 made softer: curls to 440 deg and "
                                         "crosses its own base, MJPG AVI"),
                     "avi", 8),
    }


def write_sample_frames(out_dir, *, progress=None) -> list[Path]:
    """Render every committed scene into ``out_dir``/NAME and write a README."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    lines = ["# sample_frames/", "",
             "Synthetic microscope scenes with known truth: the demo's default input.",
             "Rendered by `pipeline/render.py` from the line-segment model",
             "(`models.ls_shape`) with the parameters in each `scene.json`; regenerate",
             "all of them, bit for bit, with", "",
             "    .venv/bin/microtube render --sample-frames --out sample_frames", "",
             "Each folder holds the frames, `truth_tracks.csv` and",
             "`truth_centrelines.csv` (the tracker's columns and coordinates),",
             "`pressure.csv` (the pressure log) and `scene.json` (every setting).", "",
             "| scene | sample | frames | size | format | look | eps_max | k (1/um) | "
             "max bend |",
             "|---|---|---|---|---|---|---|---|---|"]
    from models import ls_bend_angle

    for name, (scene, fmt, depth) in sample_scenes().items():
        render_scene(scene, out_dir / name, fmt=fmt, bit_depth=depth, progress=progress)
        written.append(out_dir / name)
        bend = float(ls_bend_angle(get_sample(scene.sample), scene.pressures()[-1],
                                   scene.params())) * 180 / 3.141592653589793
        look = scene.look if isinstance(scene.look, str) else scene.look.get("name", "custom")
        lines.append(f"| {name} | #{scene.sample} | {scene.n_frames} | {scene.width}x"
                     f"{scene.height} | {fmt} | {look} | {scene.eps_max:.4f} | "
                     f"{scene.k_de_per_um:g} | {bend:.1f} deg |")
    lines += ["", "eps_min = 0.5 and N = 1000 segments throughout; pressure ramps linearly "
              "from 0 to the sample's p_max (0.14, 0.14, 0.17 MPa).", ""]
    write_text("\n".join(lines), out_dir / "README.md")
    return written
