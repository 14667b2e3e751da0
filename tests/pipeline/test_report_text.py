"""The reports' README states what the per-frame figures show."""

import os

import numpy as np
import pandas as pd
import pytest

from pipeline.report import _growth_line
from pipeline.tracking_report import _on_one_cpu, _timed_process, drawn_section


def test_the_error_growth_is_measured_from_the_per_frame_table(tmp_path):
    bend = np.linspace(0, 300, 31)
    per_frame = pd.concat([
        # measured bend 1 % ahead of the true one, turning clockwise (negative angles)
        pd.DataFrame({"scene": "ahead", "true_bend_deg": -bend, "angle_error_deg": -0.01 * bend}),
        pd.DataFrame({"scene": "flat", "true_bend_deg": bend,
                      "angle_error_deg": 0.1 * np.cos(bend)}),
    ])
    path = tmp_path / "per_frame.csv"
    per_frame.to_csv(path, index=False)
    track = pd.DataFrame({"scene": ["ahead", "flat"], "centreline_rms_px": [0.3, 0.02]})
    line = _growth_line(path, track)
    assert "+1.00 %" in line and "(ahead;" in line
    assert "In ahead the centreline sits 0.30–0.30 px" in line
    assert _growth_line(tmp_path / "missing.csv", track) == ""


def test_the_drawn_scenes_section_counts_and_lists_the_misses():
    def row(name, lost, median, meets):
        return {"scene": name, "sample": "5", "look": "fluorescent", "photons": np.nan,
                "blur_px": 2.0, "size": "800x600", "format": "mp4/8", "frames": 12,
                "frames_lost": lost, "angle_median_deg": median, "angle_p95_deg": 2 * median,
                "angle_max_deg": 3 * median, "centreline_rms_px": 0.1,
                "length_error_max_pct": 0.2, "meets_targets": meets}

    drawn = pd.DataFrame([row("a", 0, 0.2, True), row("b", 2, 1.5, False),
                          row("c", 0, 9.0, False)])
    text = "\n".join(drawn_section(drawn))
    assert "**1 of 3 meet every target**; frames lost: 2 of 36" in text
    # the misses, worst first; the scene that meets every target is not listed
    assert text.index("| c |") < text.index("| b |")
    assert "| a |" not in text
    assert "| c | 5 | fluorescent | — | 2.0 | 800x600 | mp4/8 | 0 | 9.00 |" in text


def test_the_speed_benchmark_runs_in_a_python_that_sees_one_cpu():
    before = os.sched_getaffinity(0) if hasattr(os, "sched_getaffinity") else None
    seen = _on_one_cpu(
        "import os, cv2; print(json.dumps({'args': sys.argv[1:], 'opencv': "
        "cv2.getNumberOfCPUs(), 'cpus': len(os.sched_getaffinity(0)) "
        "if hasattr(os, 'sched_getaffinity') else None}))", "a b", 2)
    assert seen["args"] == ["a b", "2"]
    if hasattr(os, "sched_setaffinity"):
        # held to one CPU from its start, so that the libraries' thread pools
        # are sized for one: OpenCV's counts one
        assert seen["cpus"] == 1 and seen["opencv"] == 1
    if hasattr(os, "sched_getaffinity"):
        assert os.sched_getaffinity(0) == before  # (this process keeps its CPUs)


def test_a_failing_benchmark_says_why():
    with pytest.raises(RuntimeError, match="speed benchmark failed: ZeroDivisionError"):
        _on_one_cpu("1 / 0")


def test_a_timed_command_runs_as_typed_and_says_why_it_failed():
    assert 0.0 < _timed_process(["-c", "import sys; sys.exit(0)"]) < 60.0
    with pytest.raises(RuntimeError, match="speed benchmark failed: ValueError: no"):
        _timed_process(["-c", "raise ValueError('no')"])


def test_the_speed_timing_gives_the_later_frames_cost_within_the_whole_run(tmp_path):
    from pipeline.render import default_scene, render_scene
    from pipeline.tracking_report import _time_track

    scene = default_scene(3, n_frames=16, seed=5, width=320, height=240)
    video = render_scene(scene, tmp_path / "scene", fmt="avi") / "frames.avi"
    t = _time_track(video, tmp_path / "out")
    assert t["frames_ok"] == 16
    assert 0.0 < t["decode_s"] < t["track_s"]
    # the second half's 8 frames take part of the whole run, which also finds the tube
    assert 0.0 < 8 * t["later_frame_s"] < t["track_s"]
