"""The ``microtube`` command line: help, one-line errors, exit codes, no partial output.

Most checks call :func:`pipeline.cli.main` in-process (starting Python is slow);
two run the real ``microtube`` / ``python -m pipeline`` to prove that nothing but
one line reaches stderr. The end-to-end tests render a small scene of sample #1
(8 frames, 240x180 px, about 91 µm per px) with ``microtube render``, track it
and calibrate on it, and compare with the scene's truth.
"""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pipeline import schema as S
from pipeline.cli import main
from pipeline.frames import open_frames, write_frames

N_FRAMES = 8
# the columns of tracks.csv, in order (base_angle_deg may follow)
TRACK_COLUMNS = ["frame", "time_s", "bend_angle_deg", "tip_x_um", "tip_y_um", "base_x_um",
                 "base_y_um", "length_um", "status"]
FIT_KEYS = {"model", "parameters", "correlation", "rms_um", "max_residual_um",
            "angle_rms_deg", "frames_used", "frames_skipped", "pressure_source", "runtime_s"}
PARAMETER_KEYS = {"value", "stderr", "ci95", "fitted", "reason"}


def one_line_error(capsys, command: str) -> str:
    """The single stderr line of a failed run (checked to be one line, no traceback)."""
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"microtube {command}: error: ") or (
        command == "" and lines[0].startswith("microtube: error: ")), lines[0]
    return lines[0]


def snapshot(folder: Path) -> dict:
    """Every file under ``folder`` (hidden ones too) with its bytes."""
    return {p.relative_to(folder).as_posix(): p.read_bytes()
            for p in sorted(folder.rglob("*")) if p.is_file()}


# -- fixtures: a rendered scene, its tracks, bad inputs ---------------------------------

@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    folder = tmp_path_factory.mktemp("scene") / "s1"
    code = main(["render", "--sample", "1", "--out", str(folder), "--frames", str(N_FRAMES),
                 "--size", "240x180", "--seed", "1", "-q"])
    assert code == 0
    return folder


@pytest.fixture(scope="module")
def um_per_px(scene):
    return json.loads((scene / S.SCENE_FILE).read_text())["layout"]["um_per_px"]


@pytest.fixture(scope="module")
def tracked(scene, um_per_px, tmp_path_factory):
    out = tmp_path_factory.mktemp("tracked") / "out"
    code = main(["track", str(scene / "frames.avi"), "--out", str(out), "--um-per-px",
                 str(um_per_px), "--overlay", "-q"])
    assert code == 0
    return out


@pytest.fixture(scope="module")
def bad(tmp_path_factory):
    """Inputs the tracker must refuse, by name."""
    d = tmp_path_factory.mktemp("bad")
    rng = np.random.default_rng(5)
    (d / "empty.avi").write_bytes(b"")
    (d / "random.avi").write_bytes(rng.integers(0, 256, 20_000, dtype=np.uint8).tobytes())
    (d / "empty_folder").mkdir()
    (d / "text_folder").mkdir()
    (d / "text_folder" / "notes.txt").write_text("not an image\n")
    (d / "text_folder" / "data.csv").write_text("a,b\n1,2\n")
    (d / "broken_pngs").mkdir()
    (d / "broken_pngs" / "frame_000.png").write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(64))
    (d / "a_file").write_text("in the way\n")
    write_frames([np.full((120, 160), 0.6) for _ in range(4)], d / "grey.avi")
    return d


# -- help -------------------------------------------------------------------------------

@pytest.mark.parametrize("command", ["track", "calibrate", "render", "demo", "report"])
def test_every_subcommand_has_help_with_an_example(command, capsys):
    assert main([command, "--help"]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"usage: microtube {command}")
    example = out.split("example:", 1)[1]
    assert f"microtube {command}" in example


def test_top_level_help_lists_the_five_subcommands(capsys):
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    for command in ("track", "calibrate", "render", "demo", "report"):
        assert f"    {command}" in out


def test_python_dash_m_pipeline_help_runs_the_same_cli():
    proc = subprocess.run([sys.executable, "-m", "pipeline", "--help"], capture_output=True,
                          text=True, timeout=60, check=False)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("usage: microtube")
    assert "calibrate" in proc.stdout and proc.stderr == ""


@pytest.mark.parametrize("name, why", [
    ("random.avi", "not a readable video (corrupt, or a codec this OpenCV lacks)"),
    # (OpenCV's own log of the PNG decoder's error is kept off stderr too)
    ("broken_pngs/frame_000.png", "not a readable image"),
])
def test_console_script_reports_a_corrupt_file_in_one_line(bad, tmp_path, name, why):
    script = Path(sys.executable).with_name("microtube")
    assert script.exists(), "the microtube console script is not installed beside python"
    proc = subprocess.run([str(script), "track", str(bad / name), "--out",
                           str(tmp_path / "out"), "--um-per-px", "10"],
                          capture_output=True, text=True, timeout=120, check=False,
                          env={k: v for k, v in os.environ.items() if k != "MICROTUBE_DEBUG"})
    assert proc.returncode == 2
    assert proc.stdout == ""
    assert "Traceback" not in proc.stderr
    assert proc.stderr.strip().splitlines() == [f"microtube track: error: {bad / name}: {why}"]
    assert not (tmp_path / "out").exists()


# -- track: bad input -------------------------------------------------------------------

VIDEO = "<video>"  # stands for the rendered scene's frames.avi


@pytest.mark.parametrize("args, match", [
    (["missing.avi", "--um-per-px", "10"], "missing.avi: no such file or folder"),
    (["missing.avi"], "missing.avi: no such file or folder"),  # before the missing scale
    (["empty.avi", "--um-per-px", "10"], "empty.avi: empty file (0 bytes)"),
    (["random.avi", "--um-per-px", "10"], "random.avi: not a readable video"),
    (["empty_folder", "--um-per-px", "10"], "empty_folder: the folder holds no images"),
    (["text_folder", "--um-per-px", "10"], "text_folder: the folder holds no images"),
    (["broken_pngs", "--um-per-px", "10"], "frame_000.png (image 0 of 1): not a readable image"),
    ([VIDEO, "--um-per-px", "0"], "argument --um-per-px: must be a positive number, got '0'"),
    ([VIDEO, "--um-per-px", "-2.5"], "argument --um-per-px: must be a positive number"),
    ([VIDEO, "--um-per-px", "nan"], "argument --um-per-px: must be a positive number, got 'nan'"),
    ([VIDEO, "--um-per-px", "1e999"], "argument --um-per-px: must be a positive number"),
    ([VIDEO, "--um-per-px", "ten"], "argument --um-per-px: not a number: 'ten'"),
    ([VIDEO, "--um-per-px", "10", "--sample", "1"],
     "argument --sample: not allowed with argument --um-per-px"),
    ([VIDEO], "the scale is unknown: give --um-per-px"),
    ([VIDEO, "--sample", "99"], "unknown sample '99'"),
    ([VIDEO, "--um-per-px", "10", "--base", "left"], "--base must be X,Y in pixels, got 'left'"),
    ([VIDEO, "--um-per-px", "10", "--base", "12"], "--base must be X,Y in pixels, got '12'"),
    ([VIDEO, "--um-per-px", "10", "--base", "x,40"], "--base must be X,Y in pixels"),
    ([VIDEO, "--um-per-px", "10", "--base", "nan,40"], "--base must be finite"),
    ([VIDEO, "--um-per-px", "10", "--base", "500,40"], "lies outside the 240x180 image"),
    ([VIDEO, "--um-per-px", "10", "--base", "40,180"], "lies outside the 240x180 image"),
    ([VIDEO, "--um-per-px", "10", "--base=-5,40"], "lies outside the 240x180 image"),
    # argparse reads "-5,40" as an option: the message says how to pass it
    ([VIDEO, "--um-per-px", "10", "--base", "-5,40"], "write a value that starts with '-' as "
                                                      "--option=VALUE"),
    ([VIDEO, "--um-per-px", "10", "--fps", "0"], "argument --fps: must be a positive number"),
    ([VIDEO, "--um-per-px", "10", "--frobnicate"], "unrecognized arguments: --frobnicate"),
])
def test_track_refuses_bad_input_in_one_line_and_writes_nothing(args, match, bad, scene,
                                                                tmp_path, capsys):
    args = [str(scene / "frames.avi") if a == VIDEO else a for a in args]
    if not args[0].startswith(str(scene)):
        args[0] = str(bad / args[0])
    out = tmp_path / "out"
    assert main(["track", *args, "--out", str(out)]) == 2
    assert match in one_line_error(capsys, "track")
    assert not out.exists()


def test_track_refuses_an_output_path_that_is_a_file(bad, scene, capsys):
    before = (bad / "a_file").read_bytes()
    code = main(["track", str(scene / "frames.avi"), "--out", str(bad / "a_file"),
                 "--um-per-px", "10"])
    assert code == 2
    assert f"--out {bad / 'a_file'}: exists and is not a folder" in one_line_error(capsys,
                                                                                   "track")
    assert (bad / "a_file").read_bytes() == before


def test_uniform_grey_video_is_a_clear_error_that_keeps_the_earlier_output(bad, tracked,
                                                                            tmp_path, capsys):
    out = tmp_path / "out"
    shutil.copytree(tracked, out)
    before = snapshot(out)
    code = main(["track", str(bad / "grey.avi"), "--out", str(out), "--um-per-px", "10"])
    assert code == 2
    line = one_line_error(capsys, "track")
    assert "no frame of the 4 could be measured (no tube found: 4 frames)" in line
    assert "nothing written" in line
    assert snapshot(out) == before  # nothing replaced, no staging folder left behind


def test_uniform_grey_video_with_a_sample_scale_is_a_clear_error(bad, tmp_path, capsys):
    out = tmp_path / "new" / "out"
    code = main(["track", str(bad / "grey.avi"), "--out", str(out), "--sample", "1"])
    assert code == 2
    assert "no frame was measured" in one_line_error(capsys, "track")
    assert not (tmp_path / "new").exists()  # folders made for --out are removed again


def test_a_blank_frame_mid_video_is_a_row_with_a_reason_not_an_angle(scene, um_per_px,
                                                                     tmp_path, capsys):
    with open_frames(scene / "frames.avi") as reader:
        frames = list(reader)
    frames[3] = np.full_like(frames[3], int(np.median(frames[3])))
    write_frames(frames, tmp_path / "frames")
    out = tmp_path / "out"
    code = main(["track", str(tmp_path / "frames"), "--out", str(out), "--um-per-px",
                 str(um_per_px), "--fps", "10"])
    assert code == 0
    captured = capsys.readouterr()
    assert captured.err == ""
    assert f"tracked {N_FRAMES - 1}/{N_FRAMES} frames" in captured.out
    tracks = pd.read_csv(out / S.TRACKS_FILE, keep_default_na=False, na_values=[""])
    assert tracks["frame"].tolist() == list(range(N_FRAMES))
    blank = tracks.iloc[3]
    assert blank["status"] not in ("ok", "") and np.isnan(blank["bend_angle_deg"])
    assert tracks.drop(index=3)["status"].eq("ok").all()
    assert 3 not in set(pd.read_csv(out / S.CENTRELINES_FILE)["frame"])


def test_a_truncated_video_is_tracked_as_far_as_it_goes_and_says_so(scene, um_per_px,
                                                                    tmp_path, capfd):
    data = (scene / "frames.avi").read_bytes()
    (tmp_path / "cut.avi").write_bytes(data[: int(0.6 * len(data))])  # mid-frame
    out = tmp_path / "out"
    code = main(["track", str(tmp_path / "cut.avi"), "--out", str(out), "--um-per-px",
                 str(um_per_px)])
    assert code == 0
    captured = capfd.readouterr()
    assert captured.err == ""  # (not even FFmpeg's own complaint about the cut frame)
    n = len(pd.read_csv(out / S.TRACKS_FILE))
    assert 0 < n < N_FRAMES
    assert f"the video ended after {n} of the {N_FRAMES} frames" in captured.out


def test_an_internal_error_is_one_line_with_status_3(monkeypatch, scene, tmp_path, capsys):
    import pipeline.tracks

    def broken(*args, **kwargs):
        raise RuntimeError("boom\nsecond line")

    monkeypatch.delenv("MICROTUBE_DEBUG", raising=False)
    monkeypatch.setattr(pipeline.tracks, "track_video", broken)
    argv = ["track", str(scene / "frames.avi"), "--out", str(tmp_path / "o"), "--um-per-px", "9"]
    assert main(argv) == 3
    err = capsys.readouterr().err
    assert err.strip().splitlines() == [
        "microtube track: internal error: RuntimeError: boom (set MICROTUBE_DEBUG=1 for the "
        "traceback)"]
    monkeypatch.setenv("MICROTUBE_DEBUG", "1")
    with pytest.raises(RuntimeError, match="boom"):
        main(argv)
    assert not (tmp_path / "o").exists()


def test_an_interrupted_track_leaves_no_files(monkeypatch, scene, tracked, tmp_path, capsys):
    import pipeline.tracks

    def interrupted(source, out_dir, **kwargs):
        Path(out_dir, S.TRACKS_FILE).write_text("frame,time_s\n0,")  # half written
        raise KeyboardInterrupt

    monkeypatch.setattr(pipeline.tracks, "track_video", interrupted)
    fresh = tmp_path / "fresh"
    argv = ["track", str(scene / "frames.avi"), "--um-per-px", "9", "--out"]
    assert main([*argv, str(fresh)]) == 130
    assert capsys.readouterr().err.strip() == "microtube: interrupted"
    assert not fresh.exists()
    old = tmp_path / "old"
    shutil.copytree(tracked, old)
    before = snapshot(old)
    assert main([*argv, str(old)]) == 130
    assert snapshot(old) == before


# -- calibrate: bad input ---------------------------------------------------------------

@pytest.mark.parametrize("args, match", [
    (["--sample", "seven", "--p-max", "0.14"], "unknown sample 'seven'"),
    (["--sample", "1", "--p-max", "0.14", "--tracks", "<missing>"], "tracks folder not found"),
    (["--sample", "1", "--p-max", "0.14", "--pressure", "<log>"],
     "give either --pressure or --p-max, not both"),
    (["--sample", "1", "--p-max", "0.14", "--tracking-sd-deg", "-0.5"],
     "argument --tracking-sd-deg: must be a number >= 0, got '-0.5'"),
    (["--sample", "1", "--p-max", "0.14", "--tracking-sd-deg", "nan"],
     "argument --tracking-sd-deg: must be a number >= 0"),
    (["--sample", "1", "--p-max", "-1"], "argument --p-max: must be a positive number"),
    (["--sample", "1", "--p-max", "0.14", "--model", "fem"], "argument --model: invalid choice"),
    (["--sample", "1", "--p-max", "0.14", "--segments", "0"],
     "argument --segments: must be a positive whole number"),
    (["--sample", "1", "--pressure", "<missing>"], "pressure log not found"),
])
def test_calibrate_refuses_bad_input_and_keeps_the_earlier_fit(args, match, tracked, scene,
                                                               tmp_path, capsys):
    fit = tmp_path / "fit.json"
    fit.write_text('{"model": "ls"}\n')  # an earlier result, to be kept
    args = [{"<missing>": str(tmp_path / "missing"),
             "<log>": str(scene / S.PRESSURE_FILE)}.get(a, a) for a in args]
    if "--tracks" not in args:
        args += ["--tracks", str(tracked)]
    assert main(["calibrate", *args, "--out", str(fit)]) == 2
    assert match in one_line_error(capsys, "calibrate")
    assert fit.read_text() == '{"model": "ls"}\n'
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fit.json"]


def test_calibrate_refuses_an_output_that_is_a_folder_or_an_input(tracked, scene, tmp_path,
                                                                  capsys):
    folder = tmp_path / "results"
    folder.mkdir()
    base = ["calibrate", "--sample", "1", "--tracks", str(tracked), "--pressure",
            str(scene / S.PRESSURE_FILE), "--out"]
    assert main([*base, str(folder)]) == 2
    assert f"--out {folder}: is a folder" in one_line_error(capsys, "calibrate")
    assert list(folder.iterdir()) == [] and sorted(p.name for p in tmp_path.iterdir()) == [
        "results"]  # no residuals CSV or overlay PNG beside it either
    before = snapshot(tracked)
    assert main([*base, str(tracked / S.TRACKS_FILE)]) == 2
    assert "would overwrite an input file" in one_line_error(capsys, "calibrate")
    assert snapshot(tracked) == before


# -- render, demo, report: argument errors ----------------------------------------------

@pytest.mark.parametrize("args, match", [
    (["--sample", "1", "--look", "shiny"], "unknown look 'shiny'"),
    (["--sample", "1", "--frames", "0"], "argument --frames: must be a positive whole number"),
    (["--sample", "1", "--frames", "2.5"], "argument --frames: not a whole number"),
    (["--sample", "1", "--size", "10x10"], "--size must be at least 32x32 px"),
    (["--sample", "1", "--size", "large"], "--size must be WIDTHxHEIGHT in px"),
    (["--sample", "0"], "unknown sample '0'"),
    ([], "give exactly one of --sample ID, --scene scene.json or --sample-frames"),
    (["--sample", "1", "--scene", "scene.json"], "give exactly one of"),
    (["--scene", "<missing>"], "no such scene file"),
    (["--sample", "1", "--format", "gif"], "argument --format: invalid choice: 'gif'"),
    (["--sample", "1", "--bit-depth", "16"], "8-bit"),
    (["--sample", "1", "--angle", "nan"], "must be finite"),
])
def test_render_refuses_bad_options(args, match, tmp_path, capsys):
    args = [str(tmp_path / "missing.json") if a == "<missing>" else a for a in args]
    out = tmp_path / "out"
    # a tiny scene by default (a later option wins), in case an error is not caught
    assert main(["render", "--frames", "2", "--size", "64x64", *args, "--out", str(out)]) == 2
    assert match in one_line_error(capsys, "render")
    assert not out.exists()


def test_render_does_not_overwrite_a_foreign_file(bad, capsys):
    before = (bad / "a_file").read_bytes()
    code = main(["render", "--sample", "1", "--frames", "2", "--size", "64x64",
                 "--out", str(bad / "a_file")])
    assert code == 2
    assert "refusing to overwrite" in one_line_error(capsys, "render")
    assert (bad / "a_file").read_bytes() == before


@pytest.mark.parametrize("argv, command, match", [
    (["report", "--out", "<file>"], "report", "exists and is not a folder"),
    (["report", "--fast"], "report", "unrecognized arguments: --fast"),
    (["demo", "--frames", "<missing>"], "demo", "no such scenes folder"),
    (["demo", "--frames", "<empty>"], "demo", "holds no scene folders"),
    (["demo", "--reports", "<file>"], "demo", "--reports"),
    (["demo", "--out", "<file>"], "demo", "--out"),
    (["demo", "extra"], "demo", "unrecognized arguments: extra"),
    ([], "", "the following arguments are required: COMMAND"),
    (["trak"], "", "invalid choice: 'trak'"),
])
def test_report_and_demo_argument_errors(argv, command, match, bad, tmp_path, capsys):
    argv = [{"<file>": str(bad / "a_file"), "<missing>": str(tmp_path / "none"),
             "<empty>": str(bad / "empty_folder")}.get(a, a) for a in argv]
    if command == "demo":  # outputs inside tmp_path by default (a later option wins)
        argv[1:1] = ["--out", str(tmp_path / "out"), "--reports", str(tmp_path / "reports")]
    assert main(argv) == 2
    assert match in one_line_error(capsys, command)
    assert sorted(p.name for p in tmp_path.iterdir()) == []


# -- end to end: render -> track -> calibrate -------------------------------------------

def test_tracks_csv_has_the_documented_columns_and_matches_the_truth(tracked, scene, um_per_px):
    tracks = pd.read_csv(tracked / S.TRACKS_FILE)
    truth = pd.read_csv(scene / S.TRUTH_TRACKS_FILE)
    assert list(tracks.columns[:len(TRACK_COLUMNS)]) == TRACK_COLUMNS
    assert tracks["frame"].tolist() == list(range(N_FRAMES))
    np.testing.assert_allclose(tracks["time_s"], truth["time_s"], atol=1e-9)  # avi at 10 fps
    assert tracks["status"].eq("ok").all()
    assert tracks.notna().all().all()
    np.testing.assert_allclose(tracks["bend_angle_deg"], truth["bend_angle_deg"], atol=6.0)
    for col in ("tip_x_um", "tip_y_um", "base_x_um", "base_y_um"):
        np.testing.assert_allclose(tracks[col], truth[col], atol=2 * um_per_px, err_msg=col)
    np.testing.assert_allclose(tracks["length_um"], truth["length_um"], rtol=0.02)
    run = json.loads((tracked / S.RUN_FILE).read_text())
    assert run["frames"] == run["frames_ok"] == N_FRAMES
    assert run["um_per_px"] == pytest.approx(um_per_px)
    assert (tracked / "overlay.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not [p.name for p in tracked.iterdir() if p.name.startswith(".")]


def test_centrelines_run_base_to_tip_with_points_at_most_one_px_apart(tracked, um_per_px):
    lines = pd.read_csv(tracked / S.CENTRELINES_FILE)
    tracks = pd.read_csv(tracked / S.TRACKS_FILE).set_index("frame")
    assert list(lines.columns) == ["frame", "s_um", "x_um", "y_um"]
    assert sorted(lines["frame"].unique()) == list(range(N_FRAMES))
    rounding = 1e-3  # the CSV holds 0.1 nm
    for frame, line in lines.groupby("frame", sort=False):
        z = line["x_um"].to_numpy() + 1j * line["y_um"].to_numpy()
        s = line["s_um"].to_numpy()
        step = np.abs(np.diff(z))
        assert step.max() <= um_per_px + rounding, frame
        assert s[0] == 0 and np.all(np.diff(s) > 0)
        # s is the arc length along the listed points (chords of a smooth curve)
        np.testing.assert_allclose(np.diff(s), step, rtol=1e-3, atol=rounding)
        row = tracks.loc[frame]
        assert abs(z[0] - complex(row["base_x_um"], row["base_y_um"])) <= rounding
        assert abs(z[-1] - complex(row["tip_x_um"], row["tip_y_um"])) <= 0.5 * um_per_px
        assert s[-1] == pytest.approx(row["length_um"], rel=1e-3)


def test_calibrate_writes_the_documented_json(tracked, scene, tmp_path, capsys):
    out = tmp_path / "fit.json"
    code = main(["calibrate", "--sample", "1", "--tracks", str(tracked), "--pressure",
                 str(scene / S.PRESSURE_FILE), "--out", str(out)])
    assert code == 0
    captured = capsys.readouterr()
    assert captured.err == "" and "eps_max" in captured.out
    doc = json.loads(out.read_text())
    assert FIT_KEYS <= set(doc)
    assert doc["model"] == "ls"
    assert set(doc["parameters"]) == {"eps_min", "eps_max", "k_de", "elongation"}
    for name, p in doc["parameters"].items():
        assert PARAMETER_KEYS <= set(p), name
        assert isinstance(p["fitted"], bool) and isinstance(p["reason"], str)
        assert np.isfinite(p["value"])
        if p["fitted"]:
            lo, hi = p["ci95"]
            assert p["stderr"] > 0 and lo <= p["value"] <= hi and p["reason"] == ""
        else:
            assert p["reason"] and p["ci95"] is None
    assert doc["parameters"]["eps_max"]["fitted"] and doc["parameters"]["k_de"]["fitted"]
    fitted = [k for k, p in doc["parameters"].items() if p["fitted"]]
    assert set(doc["correlation"]) == set(fitted)
    for a in fitted:
        assert doc["correlation"][a][a] == pytest.approx(1.0)
    truth = json.loads((scene / S.SCENE_FILE).read_text())["scene"]
    assert doc["parameters"]["eps_max"]["value"] == pytest.approx(truth["eps_max"], rel=0.01)
    assert doc["parameters"]["k_de"]["value"] == pytest.approx(truth["k_de_per_um"], rel=0.2)
    assert doc["frames_used"] + doc["frames_skipped"] == N_FRAMES
    assert doc["frames_used"] >= N_FRAMES - 1
    assert S.PRESSURE_FILE in doc["pressure_source"]
    for key in ("rms_um", "max_residual_um", "angle_rms_deg", "runtime_s"):
        assert np.isfinite(doc[key]) and doc[key] >= 0, key
    assert doc["rms_um"] <= doc["max_residual_um"]
    assert (tmp_path / "fit_residuals.csv").is_file() and (tmp_path / "fit_overlay.png").is_file()


def test_a_rerun_without_overlay_removes_the_earlier_runs_picture(scene, um_per_px, tmp_path):
    out = tmp_path / "out"
    args = ["track", str(scene / "frames.avi"), "--out", str(out), "--um-per-px",
            str(um_per_px), "-q"]
    assert main(args + ["--overlay"]) == 0 and (out / "overlay.png").is_file()
    assert main(args) == 0
    assert not (out / "overlay.png").exists() and (out / S.TRACKS_FILE).is_file()
