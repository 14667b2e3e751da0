"""Parameter recovery, identifiability, outputs and failure paths of the calibration.

"Measured" data are written exactly as the tracker writes them (tracks.csv,
centrelines.csv in µm, y up, points ≈ 1 px apart), from model shapes with known
parameters placed at an arbitrary base point and angle, with smooth and white
noise of ~1.5 µm, base jitter, one grossly mistracked frame and one lost frame.
"""

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from models import PAPER_SAMPLES, LSParams, eb_shape, ls_shape
from pipeline import schema as S
from pipeline.atomic import write_csv
from pipeline.calibrate import calibrate, calibrate_folder, read_tracks
from pipeline.cli import main
from pipeline.paper_fit import paper_leave_one_out, write_paper_leave_one_out
from pipeline.tracks import track_video

TRUE_EPS_MAX = 0.58
TRUE_K = -0.002
UM_PER_PX = 12.0
SAMPLE_FRAMES = Path(__file__).resolve().parents[2] / "sample_frames"


def scene(sample, shapes, *, n_frames=50, n_points=None, noise_um=1.5, seed=0,
          base=(1500.0, -800.0), angle_deg=-70.0, bad_frame=30, lost_frame=5, mirror=False,
          length_noise=0.0):
    """tracks and centrelines tables of ``shapes(p, n_points)`` over a 0 → p_max ramp."""
    rng = np.random.default_rng(seed)
    p = sample.p_max_mpa * np.arange(n_frames) / (n_frames - 1)
    n_points = n_points or int(sample.length_um / UM_PER_PX) + 1
    sh = shapes(p, n_points)
    sign = -1 if mirror else 1
    rows, lines = [], []
    for f in range(n_frames):
        z0 = sh.x_um[f] + 1j * sign * sh.y_um[f]
        z = z0 * np.exp(1j * np.radians(angle_deg)) + complex(*base)
        s = sh.s_um[f]
        t = s / s[-1]
        tangent = np.gradient(z)
        normal = 1j * tangent / np.abs(tangent)
        smooth = sum(rng.normal(0, noise_um / 2) * np.sin((k + 1) * np.pi * t + rng.uniform(0, 6))
                     for k in range(3))
        z = z + smooth * normal + np.array([1, 1j]) @ rng.normal(0, noise_um / 2, (2, z.size))
        if f == bad_frame:
            z = z + 400 * np.sin(np.pi * t) * normal
        status = "lost" if f == lost_frame else S.STATUS_OK
        rows.append({S.FRAME: f, S.TIME: f / 10, S.BEND: sign * float(sh.bend_angle_deg[f]),
                     S.TIP_X: z[-1].real, S.TIP_Y: z[-1].imag, S.BASE_X: z[0].real,
                     S.BASE_Y: z[0].imag,
                     S.LENGTH: s[-1] * (1 + rng.normal(0, length_noise)), S.STATUS: status,
                     S.BASE_ANGLE: angle_deg + rng.normal(0, 0.02)})
        if status == S.STATUS_OK:
            lines.append(pd.DataFrame({S.FRAME: f, S.S: s, S.X: z.real, S.Y: z.imag}))
    return pd.DataFrame(rows, columns=S.TRACK_COLUMNS), pd.concat(lines, ignore_index=True)


def ls_shapes(sample, **params):
    par = LSParams(**params)
    return lambda p, n: ls_shape(sample, p, par, n_points=n)


def write_scene(folder, tracks, lines):
    folder.mkdir(parents=True, exist_ok=True)
    write_csv(tracks, folder / S.TRACKS_FILE)
    write_csv(lines, folder / S.CENTRELINES_FILE)
    return folder


@pytest.fixture(scope="module")
def s1_folder(tmp_path_factory):
    s1 = PAPER_SAMPLES[1]
    tracks, lines = scene(s1, ls_shapes(s1, eps_max=TRUE_EPS_MAX, k_de_per_um=TRUE_K))
    return write_scene(tmp_path_factory.mktemp("s1") / "tracked", tracks, lines)


@pytest.fixture(scope="module")
def s1_fit(s1_folder):
    out = s1_folder.parent / "fit.json"
    return calibrate_folder(1, s1_folder, p_max=0.14, out_json=out), out


def test_recovers_delta_eps_and_k_with_intervals_containing_the_truth(s1_fit):
    res, _ = s1_fit
    d_eps = TRUE_EPS_MAX - 0.5
    assert res.delta_eps == pytest.approx(d_eps, rel=0.02)
    eps_max, k = res.parameters["eps_max"], res.parameters["k_de"]
    assert eps_max.fitted and k.fitted
    assert k.value == pytest.approx(TRUE_K, rel=0.05)
    assert eps_max.ci95[0] <= TRUE_EPS_MAX <= eps_max.ci95[1]
    assert k.ci95[0] <= TRUE_K <= k.ci95[1]
    assert eps_max.stderr > 0 and k.stderr > 0
    assert not res.parameters["eps_min"].fitted and "delta_eps" in res.parameters["eps_min"].reason
    elong = res.parameters["elongation"]
    assert not elong.fitted and elong.value == 1.0 and "length" in elong.reason
    # one mistracked frame does not pull the fit: the other frames fit to the noise level
    table = res.residuals.set_index(S.FRAME)
    assert table.loc[30, "rms_um"] > 100 and table.loc[30, "weight"] < 0.5
    assert table.drop(index=30)["rms_um"].max() < 10.0
    assert res.frames_used == 49 and res.frames_skipped == 1
    assert res.angle_rms_deg < 1.0 and res.success


def test_json_residuals_and_overlay_are_written(s1_fit):
    res, out = s1_fit
    doc = json.loads(out.read_text())
    assert set(doc) >= {"model", "parameters", "correlation", "rms_um", "max_residual_um",
                        "angle_rms_deg", "frames_used", "frames_skipped", "pressure_source",
                        "runtime_s", "n_segments"}
    assert doc["model"] == "ls" and doc["n_segments"] == 1000
    assert set(doc["parameters"]) == {"eps_min", "eps_max", "k_de", "elongation"}
    for p in doc["parameters"].values():
        assert set(p) == {"value", "stderr", "ci95", "tracking_sd", "fitted", "reason"}
    assert doc["parameters"]["eps_max"]["fitted"] is True
    assert len(doc["parameters"]["eps_max"]["ci95"]) == 2
    assert doc["correlation"]["eps_max"]["k_de"] == pytest.approx(
        doc["correlation"]["k_de"]["eps_max"])
    assert "ramp" in doc["pressure_source"]
    csv = pd.read_csv(out.with_name("fit_residuals.csv"))
    assert len(csv) == 49 and {"frame", "pressure_mpa", "rms_um"} <= set(csv.columns)
    png = out.with_name("fit_overlay.png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not list(out.parent.glob(".*part*"))  # nothing half-written left behind
    assert "eps_max" in res.summary() and len(res.summary().splitlines()) >= 4


def test_k_is_not_determined_when_sections_barely_differ_in_d_e():
    s3 = PAPER_SAMPLES[3]  # |d_e| = 56.0 and 54.4 µm
    tracks, lines = scene(s3, ls_shapes(s3, eps_max=0.56, k_de_per_um=TRUE_K), seed=1)
    res = calibrate(s3, tracks, lines, p_max=s3.p_max_mpa)
    k = res.parameters["k_de"]
    assert not k.fitted and k.value == 0.0 and "near-null" in k.reason
    assert res.parameters["eps_max"].fitted
    # Δε absorbs the (nearly uniform) gain 1 + k|d_e|
    gain = 1 + TRUE_K * np.abs(s3.geometry.d_e_um).mean()
    assert res.delta_eps == pytest.approx(0.06 * gain, rel=0.02)


def test_twenty_random_starts_give_the_same_answer(s1_folder):
    tracks, lines = read_tracks(s1_folder)
    rng = np.random.default_rng(7)
    s1 = PAPER_SAMPLES[1]
    k_lo = -0.99 / np.abs(s1.geometry.d_e_um).max()
    answers = []
    for _ in range(20):
        start = {"delta_eps": rng.uniform(0.005, 0.7), "k_de": rng.uniform(k_lo, 0.01)}
        res = calibrate(s1, tracks, lines, p_max=0.14, initial=start, n_bootstrap=10)
        answers.append((res.delta_eps, res.value("k_de")))
    answers = np.array(answers)
    np.testing.assert_allclose(answers, np.broadcast_to(answers[0], answers.shape), rtol=1e-4)


def test_elongation_is_fitted_when_the_length_grows_with_pressure():
    s2 = PAPER_SAMPLES[2]
    tracks, lines = scene(s2, ls_shapes(s2, eps_max=0.56, k_de_per_um=TRUE_K, elongation=1.08),
                          seed=2, length_noise=5e-4)
    res = calibrate(s2, tracks, lines, p_max=s2.p_max_mpa)
    lam = res.parameters["elongation"]
    assert lam.fitted and lam.value == pytest.approx(1.08, abs=0.005)
    assert res.delta_eps == pytest.approx(0.06, rel=0.02)


def test_euler_bernoulli_modulus_and_a_mirrored_view():
    s2 = PAPER_SAMPLES[2]
    tracks, lines = scene(s2, lambda p, n: eb_shape(s2, p, E_mpa=0.5, n_points=n), seed=3,
                          mirror=True)
    res = calibrate(s2, tracks, lines, p_max=s2.p_max_mpa, model="eb")
    e = res.parameters["E_eff_mpa"]
    assert res.mirrored and e.fitted
    assert e.value == pytest.approx(0.5, rel=0.01) and e.ci95[0] <= 0.5 <= e.ci95[1]
    assert set(res.parameters) == {"E_eff_mpa"} and res.n_segments is None


def test_fifty_frames_of_two_hundred_points_recover_delta_eps():
    # the benchmark size (its speed is measured in reports/calibration_speed.csv)
    s1 = PAPER_SAMPLES[1]
    tracks, lines = scene(s1, ls_shapes(s1, eps_max=TRUE_EPS_MAX, k_de_per_um=TRUE_K),
                          n_points=200, seed=4)
    res = calibrate(s1, tracks, lines, p_max=0.14)
    assert res.delta_eps == pytest.approx(TRUE_EPS_MAX - 0.5, rel=0.02)
    assert res.parameters["k_de"].value == pytest.approx(TRUE_K, rel=0.05)


@pytest.fixture(scope="module")
def tracked_scenes(tmp_path_factory):
    """The committed sample scenes, rendered with known parameters, tracked here."""
    out = {}
    for name in ("sample1", "sample2", "sample3"):
        folder = SAMPLE_FRAMES / name
        record = json.loads((folder / S.SCENE_FILE).read_text(encoding="utf-8"))
        tracked = tmp_path_factory.mktemp(name) / "tracked"
        track_video(folder / record["frames_file"], tracked,
                    um_per_px=record["layout"]["um_per_px"])
        fit = calibrate_folder(record["scene"]["sample"], tracked,
                               pressure_csv=folder / S.PRESSURE_FILE,
                               n_segments=record["scene"].get("n_segments"),
                               out_json=tracked / "fit.json")
        out[name] = record["scene"], fit, tracked
    return out


@pytest.mark.parametrize("name", ["sample1", "sample2"])
def test_tracked_frames_recover_delta_eps_and_k_within_their_intervals(tracked_scenes, name):
    truth, res, _ = tracked_scenes[name]
    d_eps = truth["eps_max"] - truth["eps_min"]
    assert res.delta_eps == pytest.approx(d_eps, rel=0.02)
    eps_max, k = res.parameters["eps_max"], res.parameters["k_de"]
    assert k.fitted and k.value == pytest.approx(truth["k_de_per_um"], rel=0.05)
    assert eps_max.ci95[0] <= truth["eps_max"] <= eps_max.ci95[1]
    assert k.ci95[0] <= truth["k_de_per_um"] <= k.ci95[1]
    # the tracker's systematic error is part of the interval, and is reported
    assert eps_max.tracking_sd > 0 and k.tracking_sd > 0
    assert res.frames_skipped == 0


def test_tracked_frames_with_near_equal_d_e_leave_k_undetermined(tracked_scenes):
    truth, res, _ = tracked_scenes["sample3"]
    k = res.parameters["k_de"]
    assert not k.fitted and "near-null" in k.reason
    eps_max = res.parameters["eps_max"]
    assert res.delta_eps == pytest.approx(truth["eps_max"] - truth["eps_min"], rel=0.02)
    assert eps_max.ci95[0] <= truth["eps_max"] <= eps_max.ci95[1]


def test_without_pressures_each_frame_ratio_is_fitted(tracked_scenes):
    truth, _, tracked = tracked_scenes["sample1"]
    tracks, lines = read_tracks(tracked)
    res = calibrate(1, tracks, lines, n_segments=truth.get("n_segments"))
    assert res.pressure_source.startswith("free")
    assert any("most bent" in note for note in res.notes)
    assert res.delta_eps == pytest.approx(truth["eps_max"] - truth["eps_min"], rel=0.02)
    k = res.parameters["k_de"]
    assert k.fitted and k.value == pytest.approx(truth["k_de_per_um"], rel=0.05)
    assert k.ci95[0] <= truth["k_de_per_um"] <= k.ci95[1]
    log = pd.read_csv(SAMPLE_FRAMES / "sample1" / S.PRESSURE_FILE).set_index(S.FRAME)
    true_ratio = log[S.PRESSURE] / log[S.PRESSURE].max()
    fitted = res.residuals.set_index(S.FRAME)["p_over_p_max"]
    assert np.abs(fitted - true_ratio.loc[fitted.index]).max() < 0.01
    # only the shared parameters are reported as parameters
    assert set(res.parameters) == {"eps_min", "eps_max", "k_de", "elongation"}


def test_the_tracker_error_term_widens_the_bootstrap_interval(tracked_scenes):
    truth, res, tracked = tracked_scenes["sample1"]
    tracks, lines = read_tracks(tracked)
    bare = calibrate(1, tracks, lines, pressure_csv=SAMPLE_FRAMES / "sample1" / S.PRESSURE_FILE,
                     n_segments=truth.get("n_segments"), tracking_sd_deg=0.0)
    for name in ("eps_max", "k_de"):
        wide, narrow = res.parameters[name], bare.parameters[name]
        assert wide.value == narrow.value
        assert wide.ci95[0] < narrow.ci95[0] < narrow.ci95[1] < wide.ci95[1]
        assert wide.tracking_sd > narrow.tracking_sd


def test_pressure_log_by_time_and_the_cli(s1_folder, tmp_path, capsys):
    log = tmp_path / "log.csv"
    t = np.linspace(0, 4.9, 8)
    pd.DataFrame({S.TIME: t, S.PRESSURE: 0.14 * t / 4.9}).to_csv(log, index=False)
    out = tmp_path / "cli.json"
    code = main(["calibrate", "--sample", "1", "--tracks", str(s1_folder), "--pressure",
                 str(log), "--out", str(out)])
    assert code == 0 and "eps_max" in capsys.readouterr().out
    doc = json.loads(out.read_text())
    assert "time_s" in doc["pressure_source"]
    assert doc["parameters"]["eps_max"]["value"] == pytest.approx(TRUE_EPS_MAX, rel=0.002)


@pytest.mark.parametrize("change, args, match", [
    (None, {"sample": 9}, "unknown sample"),
    (None, {"sample": 2}, "um long"),  # 8.38 mm sample against a 12.29 mm tube
    ("short_log", {}, "does not cover"),
    ("one_frame", {"p_max": 0.14}, "fewer than two usable frames"),
    ("no_lines", {"p_max": 0.14}, "centrelines.csv not found"),
    ("no_column", {"p_max": 0.14}, "lacks column"),
    ("nan_log", {}, "finite"),
    (None, {"pressure_csv": "x.csv", "p_max": 0.1}, "not both"),
    (None, {"p_max": None, "model": "eb"}, "no pressures"),
])
def test_bad_input_gives_one_line_errors(s1_folder, tmp_path, change, args, match):
    folder = s1_folder
    tracks, lines = read_tracks(s1_folder)
    kwargs = {"sample": 1, "p_max": 0.14} | args
    if change is not None:
        folder = tmp_path / "bad"
        if change == "one_frame":
            tracks = tracks.assign(status=np.where(tracks[S.FRAME] == 0, "ok", "lost"))
        if change == "no_column":
            tracks = tracks.drop(columns=[S.BASE_ANGLE])
        write_scene(folder, tracks, lines)
        if change == "no_lines":
            (folder / S.CENTRELINES_FILE).unlink()
        if change in ("short_log", "nan_log"):
            log = tmp_path / "log.csv"
            p = [0.0, 0.1] if change == "short_log" else [0.0, np.nan]
            pd.DataFrame({S.FRAME: [0, 20 if change == "short_log" else 49],
                          S.PRESSURE: p}).to_csv(log, index=False)
            kwargs |= {"pressure_csv": log, "p_max": None}
    sample = kwargs.pop("sample")
    with pytest.raises(ValueError, match=match) as info:
        calibrate_folder(sample, folder, out_json=tmp_path / "x.json", **kwargs)
    assert "\n" not in str(info.value)
    assert not (tmp_path / "x.json").exists()


def test_cli_turns_bad_input_into_exit_status_2(s1_folder, tmp_path, capsys):
    code = main(["calibrate", "--sample", "2", "--tracks", str(s1_folder), "--p-max", "0.14",
                 "--out", str(tmp_path / "x.json")])
    err = capsys.readouterr().err
    assert code == 2 and "error" in err and len(err.strip().splitlines()) == 1


def test_paper_leave_one_out_table(tmp_path):
    table = paper_leave_one_out()
    assert list(table.columns[:6]) == ["sample", "model", "predicted_deg", "experiment_deg",
                                       "error_pct", "paper_error_pct"]
    assert len(table) == 3 * 5  # eb, and ls / ls+k for both strain readings
    assert set(table["sample"]) == {"#1", "#2", "#3"}
    assert set(table["model"]) == {"eb", "ls", "ls+k"}
    np.testing.assert_allclose(table["error_pct"],
                               100 * (table["predicted_deg"] / table["experiment_deg"] - 1))
    eb = table[table["model"] == "eb"].set_index("sample")
    assert eb.loc["#3", "paper_error_pct"] == pytest.approx(100 * (243.8 / 273.2 - 1))
    assert np.isfinite(table["predicted_deg"]).all() and (table["predicted_deg"] > 0).all()
    paths = write_paper_leave_one_out(tmp_path)
    assert paths["csv"].exists() and "| #1 |" in paths["md"].read_text()


def test_a_failure_while_writing_leaves_no_output_behind(s1_fit, tmp_path, monkeypatch):
    import pipeline.calibrate as cal

    res, _ = s1_fit

    def broken(result, path, **_):
        raise OSError("disk full")

    monkeypatch.setattr(cal, "write_overlay", broken)
    with pytest.raises(OSError, match="disk full"):
        cal.write_result(res, tmp_path / "fit.json")
    assert list(tmp_path.iterdir()) == []


def test_a_binary_pressure_log_is_named_as_such(s1_folder, tmp_path):
    log = tmp_path / "log.csv"
    log.write_bytes(bytes(range(256)) * 4)
    with pytest.raises(ValueError, match="pressure log") as info:
        calibrate_folder(1, s1_folder, pressure_csv=log, out_json=tmp_path / "x.json")
    assert "\n" not in str(info.value) and "{" not in str(info.value)
