"""Which end is the base, and where exactly the tube leaves the pipette."""

import json

import numpy as np
import pandas as pd
import pytest

from pipeline import schema as S
from pipeline.accuracy import score_folder
from pipeline.motion import end_motion
from pipeline.render import default_scene, render_scene
from pipeline.segment import AMBIGUOUS_BASE, detect, longest_path
from pipeline.track import as_float
from pipeline.tracks import track_video

#: A fluorescent tube whose glass pipette does not show: one frame cannot tell
#: its ends apart, and the straight first frame puts the tip nearer the border.
INVISIBLE_PIPETTE = {"name": "fluorescent", "pipette_depth": 0.0}


def _scene(tmp_path, **changes):
    kw = dict(n_frames=10, seed=5, look=INVISIBLE_PIPETTE, base_angle_deg=90.0, width=480,
              height=360, mirror=True)
    kw.update(changes)
    return render_scene(default_scene(1, **kw), tmp_path / "scene", fmt="png")


def _frames(folder):
    from pipeline.frames import open_frames

    with open_frames(folder / "frames") as reader:
        return [np.array(f) for f in reader]


def test_one_frame_cannot_tell_the_ends_apart_without_a_pipette(tmp_path):
    folder = _scene(tmp_path)
    det = detect(as_float(_frames(folder)[0]))
    assert det is not None
    assert det.base_source == AMBIGUOUS_BASE


@pytest.mark.parametrize("look", [INVISIBLE_PIPETTE, {"name": "dic", "pipette_depth": 0.0}],
                         ids=["fluorescent", "dic"])
def test_the_static_end_is_the_base(tmp_path, look):
    # (in relief the tube's lit and shaded flanks change with opposite signs,
    # which cancel on its centreline unless the change is taken in magnitude)
    folder = _scene(tmp_path, look=look)
    frames = _frames(folder)
    det = detect(as_float(frames[0]))
    a, b = det.path[0], det.path[-1]
    motion = end_motion(iter(frames), np.c_[-det.path.imag, det.path.real], det.half_width)
    assert motion.decided
    truth = pd.read_csv(folder / "truth_tracks.csv")
    scale = json.loads((folder / "scene.json").read_text())["layout"]["um_per_px"]
    base = (truth[S.BASE_X][0] + 1j * truth[S.BASE_Y][0]) / scale  # px, y up
    static = b if motion.base_is_last else a
    moving = a if motion.base_is_last else b
    assert abs(static - base) < abs(moving - base)


def test_tracking_takes_the_base_from_the_motion_and_says_so(tmp_path):
    folder = _scene(tmp_path)
    scale = json.loads((folder / "scene.json").read_text())["layout"]["um_per_px"]
    run = track_video(folder / "frames", tmp_path / "out", um_per_px=scale)
    assert any("base end chosen by motion" in n for n in run.notes)
    assert run.base_source.startswith("the static end over the video")
    tracks = pd.read_csv(tmp_path / "out" / S.TRACKS_FILE)
    truth = pd.read_csv(folder / "truth_tracks.csv")
    assert (tracks[S.STATUS] == S.STATUS_OK).all()
    err_px = np.hypot(tracks[S.BASE_X] - truth[S.BASE_X], tracks[S.BASE_Y] - truth[S.BASE_Y])
    assert err_px.max() / scale < 1.5
    # clockwise curl: negative angles near the truth (a tube tracked from the
    # wrong end would be off by its whole bend); this small, dim scene (15 px
    # wide) is not an accuracy benchmark
    assert np.median(np.abs(tracks[S.BEND] - truth[S.BEND])) < 4.0
    assert tracks[S.BEND].iloc[-1] < -90


def test_a_static_video_leaves_the_base_ambiguous_and_says_so(tmp_path):
    folder = _scene(tmp_path, pressures_mpa=(0.0,) * 6, n_frames=6)
    scale = json.loads((folder / "scene.json").read_text())["layout"]["um_per_px"]
    run = track_video(folder / "frames", tmp_path / "out", um_per_px=scale)
    assert any("base end ambiguous" in n and "--base" in n for n in run.notes)


@pytest.mark.parametrize("look", [{"name": "transmitted", "blur_px": 1.5, "photons": 600.0,
                                   "read_noise": 0.01}, "opaque"])
def test_base_is_where_the_tube_leaves_a_blurred_pipette(tmp_path, look):
    folder = render_scene(default_scene(3, n_frames=2, seed=23, width=480, height=360,
                                        base_angle_deg=30.0, look=look),
                          tmp_path / "scene", fmt="png")
    scale = json.loads((folder / "scene.json").read_text())["layout"]["um_per_px"]
    track_video(folder / "frames", tmp_path / "out", um_per_px=scale)
    tracks = pd.read_csv(tmp_path / "out" / S.TRACKS_FILE)
    truth = pd.read_csv(folder / "truth_tracks.csv")
    err_px = np.hypot(tracks[S.BASE_X] - truth[S.BASE_X],
                      tracks[S.BASE_Y] - truth[S.BASE_Y]) / scale
    assert err_px.max() < 1.5


@pytest.mark.parametrize("look", ["opaque", "transmitted"])
def test_base_is_where_the_tube_leaves_a_holder_wider_than_itself(tmp_path, look):
    """A tube pushed into a capillary 2.2 times its width: the step at the
    holder's end is the base, not the image border (which put the base 160 px
    into the holder, and lost every frame)."""
    folder = render_scene(default_scene(3, n_frames=4, seed=23, width=480, height=360,
                                        base_angle_deg=30.0, look=look, pipette_ratio=2.2),
                          tmp_path / "scene", fmt="png")
    track_video(folder / "frames", tmp_path / "out",
                um_per_px=json.loads((folder / "scene.json").read_text())["layout"]["um_per_px"])
    errors, acc = score_folder(folder, tmp_path / "out")
    assert acc.frames_lost == 0
    assert errors["base_error_px"].max() < 1.0
    assert acc.length_error_max_pct < 0.5
    run = json.loads((tmp_path / "out" / "run.json").read_text())
    assert run["base_source"].startswith("holder width step")


SMALL_DIM = {
    "dim-6px-fluorescent": dict(sample=4, seed=1018, look="fluorescent", width=320, height=240,
                                base_angle_deg=103.0),
    "faint-pipette": dict(sample=8, seed=1000, look={"name": "low_contrast", "photons": 1100.0},
                          width=480, height=360, base_angle_deg=121.3),
}


@pytest.mark.parametrize("case", SMALL_DIM)
def test_the_end_that_stays_is_the_base_on_small_dim_tubes(tmp_path, case):
    """A 6 px fluorescent tube: its held end's shot noise (bright tube) varied
    more over time than the dark background its tip left early, and the
    temporal-deviation test picked the tip as the base (9 of 16 frames lost).
    A faint pipette the mask misses leaves both ends free in one frame too
    (13 of 16 lost). The change from the first frame, near each end, tells
    them apart."""
    kw = dict(SMALL_DIM[case])
    folder = render_scene(default_scene(kw.pop("sample"), n_frames=16, **kw),
                          tmp_path / "scene", fmt="avi")
    from pipeline.frames import open_frames

    with open_frames(folder / "frames.avi") as reader:
        frames = [np.array(f) for f in reader]
    det = detect(as_float(frames[0]))
    assert det.base_source == AMBIGUOUS_BASE
    motion = end_motion(iter(frames), np.c_[-det.path.imag, det.path.real], det.half_width)
    assert motion.decided
    truth = pd.read_csv(folder / "truth_tracks.csv")
    scale = json.loads((folder / "scene.json").read_text())["layout"]["um_per_px"]
    base = (truth[S.BASE_X][0] + 1j * truth[S.BASE_Y][0]) / scale  # px, y up
    static = det.path[-1] if motion.base_is_last else det.path[0]
    assert abs(static - base) < 2 * det.half_width


def test_a_branch_out_of_the_frame_wins_over_a_dust_spur_of_its_length():
    # a band from the left of the frame to its right border, with a speck of dust
    # stuck to it near the border: its spur is as long as the band's last stretch
    skel = np.zeros((60, 120), bool)
    skel[30, 10:120] = True               # runs out of the frame on the right
    for k in range(14):                   # the spur: up and right from (30, 104)
        skel[29 - k, 105 + k // 3] = True
    plain = longest_path(skel)
    assert plain[-1].tolist() != [30, 119] and plain[0].tolist() != [30, 119]
    path = longest_path(skel, border_bonus=10.0, margin=3.0)
    assert [30, 119] in (path[0].tolist(), path[-1].tolist())
    assert [30, 10] in (path[0].tolist(), path[-1].tolist())


def test_a_pipette_reaching_a_dark_dusty_corner_is_still_the_base(tmp_path):
    """Sample 7, strong vignetting and 57 dust specks, 16-bit TIFF: a speck stuck
    to the pipette near the border made a skeleton spur as long as the pipette's
    last stretch; the skeleton ended in it, short of the border, the pipette was
    not taken for one, and the tracked tube ran 154 px on into it (30 % long)."""
    look = {"name": "transmitted", "gradient": 0.2969009967353381,
            "vignetting": 0.49990384039106345, "dust": 57, "blur_px": 1.492966833040871}
    scene = default_scene(7, n_frames=20, seed=9011, look=look, width=640, height=480,
                          base_angle_deg=185.3319807479148)
    folder = render_scene(scene, tmp_path / "scene", fmt="tiff", bit_depth=16)
    track_video(folder / "frames.tif", tmp_path / "out", um_per_px=19.41799589910608)
    errors, acc = score_folder(folder, tmp_path / "out")
    assert acc.frames_lost == 0
    assert acc.base_error_max_px < 3.0
    assert acc.length_error_max_pct < 1.0


def test_a_faint_pipette_as_wide_as_noise_allows_is_not_tracked(tmp_path):
    """Low contrast at 320×240 with the pipette as faint as the tube: its edges,
    averaged over strips of lines, passed for the tube's, the width learnt at
    the curve's start was partly the pipette's, and the base search then found
    nothing to cut: the base sat 11 px into the pipette, length +7.6 %."""
    look = {"name": "low_contrast", "photons": 1390.88, "blur_px": 1.55}
    scene = default_scene(3, n_frames=6, seed=5029, look=look, width=320, height=240,
                          base_angle_deg=133.16)
    folder = render_scene(scene, tmp_path / "scene", fmt="avi")
    scale = json.loads((folder / S.SCENE_FILE).read_text(encoding="utf-8"))["layout"]["um_per_px"]
    track_video(folder / "frames.avi", tmp_path / "out", um_per_px=scale)
    errors, acc = score_folder(folder, tmp_path / "out")
    assert acc.frames_lost == 0
    assert acc.base_error_max_px < 2.0
    assert acc.length_error_max_pct < 1.0


@pytest.mark.parametrize("polarity", [-1, 1])
def test_a_base_given_where_no_pipette_shows_is_where_the_tube_starts(polarity):
    # the skeleton of a tube that starts free in the image stops a half-width
    # short of that end: the base given is where the tube is taken to start
    from tests.pipeline.synthetic import tube_image

    base = 120 - 300j
    img = tube_image((400, 640), base, 0.2, 380.0, 1 / 400, 14.0, polarity=polarity,
                     noise=0.01)
    det = detect(img, base_hint=(base.real, -base.imag))
    assert abs(det.base - base) < 1.0
    assert det.base_source == "given (--base)"


def test_each_end_is_judged_along_its_stretch_however_the_path_is_sampled():
    """The change near an end is the median along the path's last stretch,
    whatever its points: a skeleton's path ends with a straight step carried
    past the skeleton, and within a half-width of the end it may hold only
    that one point (a rendered scene's base end judged by it alone: 2.4x less
    change than the tip, undecided; along the stretch, decided)."""
    rng = np.random.default_rng(0)
    rows, cols = 200, 120
    frames = []
    for k in range(8):
        img = 0.2 + 0.01 * rng.standard_normal((rows, cols))
        img[:, 60:] += 0.1 * k * np.linspace(0.0, 1.0, rows)[:, None] ** 6  # more lower down
        frames.append(img.astype(np.float32))
    dense = np.c_[np.arange(20.0, 181.0), np.full(161, 70.0)]
    sparse = dense[[0, 100, 146, 160]]  # the same straight path, points 14-100 px apart
    a = end_motion(iter(frames), dense, 16.0)
    b = end_motion(iter(frames), sparse, 16.0)
    assert b.first == pytest.approx(a.first, rel=0.02)
    assert b.last == pytest.approx(a.last, rel=0.02)
    assert a.last > 2.0 * a.first


def _faded_start(fade_px):
    """A dark tube whose first ``fade_px`` do not show (a relief fades where the
    tube runs along its shear; a faint base section), and its true base."""
    from tests.pipeline.synthetic import tube_image

    base, angle, length = 120 - 300j, 0.2, 380.0
    kw = dict(shape=(400, 640), base=base, angle=angle, length=length, kappa=1 / 400,
              half_width=10.0, noise=0.01)
    img = tube_image(**kw)
    plain = tube_image(**kw, contrast=0.0, seed=1)
    rr, cc = np.mgrid[0:400, 0:640]
    faded = (((cc - 1j * rr) - base) * np.exp(-1j * angle)).real < fade_px
    img[faded] = plain[faded]
    return img, base, angle, length


def test_a_base_given_before_where_the_tube_shows_is_bridged_to():
    # the given base stands: the tube is carried back to it, not started 50 px
    # on where it first shows (there its tangent has turned, and the length is short)
    from pipeline.track import initialise

    img, base, angle, length = _faded_start(50.0)
    det = detect(img, base_hint=(base.real, -base.imag))
    assert abs(det.base - base) < 1.0
    assert "bridged" in det.base_source
    r, _, source = initialise(img, base_hint=(base.real, -base.imag))
    assert abs(r.curve.base - base) < 1.0
    assert abs(np.degrees(r.curve.base_angle - angle)) < 1.0
    assert abs(r.curve.length / length - 1) < 0.01


def test_a_base_given_off_the_tubes_line_is_not_bridged_to():
    img, base, angle, _ = _faded_start(50.0)
    aside = base + 1j * np.exp(1j * angle) * 80.0   # 80 px beside the tube's start
    det = detect(img, base_hint=(aside.real, -aside.imag))
    assert abs(det.base - aside) > 40.0
    assert "bridged" not in det.base_source
    assert "the base taken at the tube's nearest point" in det.base_source


def test_the_end_that_moved_first_is_the_tip_though_the_curl_comes_back_over_the_base():
    # the tip sweeps away from the first frames on; a tube that curls past a
    # turn later passes over its own base (here a dark disc there on the last
    # frames), and the largest change over the whole video saw the base move
    # most (206 against 117 in noise units: left ambiguous)
    from tests.pipeline.synthetic import tube_image

    base, hw = 380 - 300j, 6.0
    rr, cc = np.mgrid[0:480, 0:640]
    frames = []
    for k in range(16):
        kappa = -np.pi * min(k, 9) / 9 / 300.0
        img = tube_image((480, 640), base, np.pi, 300.0, kappa + 1e-12, hw, noise=0.02, seed=k)
        if k >= 10:
            img = img * (1 - 0.6 * (np.hypot(rr - 300, cc - 380) < 3 * hw))
        frames.append((np.clip(img, 0, 1) * 255).astype(np.uint8))
    path = np.c_[np.full(301, 300.0), np.linspace(380, 80, 301)]   # (row, col), base first
    motion = end_motion(iter(frames), path, hw)
    assert motion.decided
    assert not motion.base_is_last
    assert motion.frames < 10     # told before the curl came back



@pytest.mark.parametrize(("turn_deg", "curl", "in_line"), [
    (0.0, 0.0, True),        # a pipette on the tube's axis
    (75.0, 0.0, False),      # a dust fibre from the tube's end, turning away
    (0.0, 300.0, True),      # on the axis of a tube curled 300 deg from it
])
def test_a_narrower_stretch_is_a_pipette_only_in_line_with_the_tube(turn_deg, curl, in_line):
    # (an independent scene: a fibre touching the tube's tip and the frame's
    # border was taken for a pipette there, and the ends swapped: 14 of 30
    # frames lost; the fibre turned 74-78 deg from the tube's line)
    from pipeline.segment import _in_line

    hw, n_narrow, n_tube = 8.0, 80, 300
    narrow = np.arange(-n_narrow, 0)[:, None] * np.array([[0.0, 1.0]])
    turn = np.radians(turn_deg)
    narrow = narrow @ np.array([[1.0, 0.0], [0.0, 1.0]])
    narrow = np.c_[-np.sin(turn) * narrow[:, 1], np.cos(turn) * narrow[:, 1]]
    s = np.arange(n_tube, dtype=float)
    kappa = np.radians(curl) / n_tube
    phi = kappa * s
    tube = np.c_[np.cumsum(np.sin(phi)), np.cumsum(np.cos(phi))] - [0.0, 1.0]
    path = np.r_[narrow, tube]
    assert _in_line(path, n_narrow, 2.0, hw) == in_line
    assert _in_line(path[::-1], len(path) - n_narrow, 0.5, hw) == in_line
