"""The tracker's start: finding the tube on the first frame with no prediction.

Each case hands :func:`pipeline.track.initialise` (or
:func:`pipeline.segment.detect`) a frame rendered with known truth, and checks
what the start learns: the tube's width, its length, where it lies.
"""

import cv2
import numpy as np
import pytest
from scipy import ndimage as ndi

from models import get_sample
from pipeline import segment, track
from pipeline.centreline import Curve, fit_to_polyline, from_image, resample
from pipeline.refine import TubeLook, refine
from pipeline.render import Renderer, default_scene, truth_tables
from tests.pipeline.synthetic import profile_image, tube_image


def _first_frame(sample, look, **changes):
    """Frame 0 of a straight-ish scene and its true centreline (px, y up)."""
    scene = default_scene(sample, n_frames=2, seed=3, width=480, height=360,
                          base_angle_deg=0.0, look=look, **changes)
    renderer = Renderer(scene)
    _, lines, _ = truth_tables(scene, renderer.layout)
    first = lines[lines["frame"] == 0]
    scale = renderer.layout.um_per_px
    z = from_image(first["x_um"].to_numpy() / scale, -first["y_um"].to_numpy() / scale)
    return renderer.frame(0), z


def _given(z, half_width):
    """A detection along the true centreline, with the given rough half-width."""
    return segment.Detection(z, complex(z[0]), float(np.angle(z[5] - z[0])), half_width,
                             "given")


@pytest.mark.parametrize("fraction", [0.62, 0.7])
def test_a_mask_narrower_than_the_tube_still_gives_the_tube_s_width(fraction):
    """On a mottled background the mask came out at 0.63-0.74 of the tube's width,
    and the first fit, trying only that width and narrower ones, took one dark
    wall of a transparent tube for the tube (half-width 6 px for 13.5). A width
    1.4x the mask's is now tried too, and the strongest edge pairs win."""
    image, z = _first_frame(3, "transmitted")
    _, look, _ = track.initialise(image)
    _, narrow, _ = track.initialise(image, detection=_given(z, fraction * look.mean_half_width))
    assert narrow.mean_half_width == pytest.approx(look.mean_half_width, rel=0.05)


@pytest.mark.parametrize("factor", [2.5, 6.0, 8.0])
def test_a_mask_far_wider_than_the_tube_still_gives_the_tube_s_width(factor):
    """A fluorescent tube's glow (or a tiny tube's blur at the working scale)
    spreads its mask to 2.6-5x the tube's width (an independent renderer's
    19 px tube in a haze: a 100 px mask). Trying down to 0.36 of the mask's
    width, no edge pair within 40 % of the tube's was sought, and every frame
    failed its checks. 0.2 of it is now tried too."""
    image, z = _first_frame(3, "fluorescent")
    _, look, _ = track.initialise(image)
    r, wide, _ = track.initialise(image, detection=_given(z, factor * look.mean_half_width))
    assert wide.mean_half_width == pytest.approx(look.mean_half_width, rel=0.05)
    assert r.curve.length == pytest.approx(float(np.abs(np.diff(z)).sum()), rel=0.01)


def test_a_tube_in_a_glow_is_found_at_its_own_width():
    """A bright tube whose light spreads into a haze twice its width across
    (a fluorescent wall's glow): the mask is 5x the tube's width, and the
    first fit took the haze's skirts for the tube (half-width 12.6 px for 6,
    the base 6 px off the tube's axis)."""
    base, hw = complex(0.0, -240.0), 6.0
    image = tube_image((480, 640), base, 0.0, 380.0, 1 / 900, hw, polarity=1,
                       background=0.05, contrast=14.0, noise=0.01)
    glow = ndi.gaussian_filter(image - 0.05, 2.0 * hw)
    image = np.clip(image + 0.2 * glow / glow.max(), 0.0, 1.0).astype(np.float32)
    assert segment.detect(image).half_width > 4 * hw
    r, look, _ = track.initialise(image)
    assert look.mean_half_width == pytest.approx(hw, rel=0.05)
    assert abs(r.curve.base - base) <= 1.0
    assert r.curve.length == pytest.approx(380.0, rel=0.01)


def _first_fits(image, curve, guesses, window):
    """The start's first fits of ``curve`` at each guessed half-width, with their looks."""
    fits = []
    for hw in guesses:
        look = TubeLook(-1, np.full(9, hw), 0.0)
        fits.append((refine(image, curve, look, window=window, iterations=3,
                                  width_tol=0.4, fit_length=False, tol_px=0.02,
                                  tip_stiffness=0.0), look))
    return fits


def test_a_tube_on_a_holder_many_times_its_width_takes_its_own_width_there():
    """A 5 px tube at the end of a 560 px holder tapering from 4.5x its width
    at the border to 1.6x: the first fit at the holder's width finds only
    noise along the tube (half-widths 6.9-7.4 px learnt for 2.5), and the
    tube's edges were never sought. Each stretch now takes the width of the
    guess whose edge pairs there are over 4x as strong."""
    from scipy.special import erf

    hw, length, holder = 2.5, 160.0, 560.0
    base = complex(holder, -240.0)
    image = tube_image((480, 800), base, 0.0, length, 1e-12, hw, noise=0.01)
    rr, cc = np.mgrid[0:480, 0:800]
    rel = (cc - 1j * rr) - base
    radius = hw * (1.6 + 2.9 * np.clip(-rel.real, 0, None) / holder)
    glass = 0.25 * (1 + erf(-rel.real / 0.7)) * (1 + erf((radius - np.abs(rel.imag)) / 0.7))
    image = (image * (1 - 0.175 * glass)).astype(np.float32)
    curve = Curve(complex(0, -240), 0.0, holder + length, np.zeros(12))
    (wide, look), *others = _first_fits(image, curve, (8.0, 4.5, 2.5), 4.8)
    learnt = track._learn_widths(wide, 9, 8.0)
    assert np.all(learnt[-2:] > 2 * hw)
    widths = track._strongest_widths(image, wide, look, learnt, others)
    assert widths[-2:] == pytest.approx([hw, hw], rel=0.05)
    np.testing.assert_array_equal(widths[:6], learnt[:6])


def test_a_hollow_tube_keeps_its_outer_width_in_every_stretch():
    """Narrower guesses on a tube with dark walls 2.5 px thick and a clear
    lumen (one wall is a dark band too) never displace the outer pair."""
    from scipy.special import erf

    hw, wall = 10.0, 2.5
    rr, cc = np.mgrid[0:480, 0:640]
    d = np.abs(rr - 240.0)
    walls = 0.25 * (1 + erf((hw - d) / 0.7)) * (1 + erf((d - (hw - wall)) / 0.7)) * (cc < 420)
    image = (0.8 * (1 - 0.35 * walls)
             + np.random.default_rng(0).normal(0, 0.01, rr.shape)).astype(np.float32)
    curve = Curve(complex(0, -240), 0.0, 420.0, np.zeros(12))
    (outer, look), *others = _first_fits(image, curve, (10.0, 6.0, 3.6, 2.0), 6.0)
    learnt = track._learn_widths(outer, 9, hw)
    assert learnt == pytest.approx(np.full(9, hw), rel=0.03)
    np.testing.assert_array_equal(track._strongest_widths(image, outer, look, learnt, others),
                                  learnt)


@pytest.mark.parametrize("fraction", [0.25, 0.4])
def test_a_mask_that_stops_far_short_of_the_tip_is_carried_on_to_it(fraction):
    """A mask that breaks up at a faint section (a thin-walled middle section on
    a mottled background) leaves the first fit a fraction of the tube. Carried
    on once by half its length it still ended on the tube, and the fit kept
    the fraction; it is now carried on again while the edges run to its end."""
    image, z = _first_frame(3, "transmitted")
    length = float(np.abs(np.diff(z)).sum())
    _, look, _ = track.initialise(image)
    short = _given(z[:int(fraction * z.size)], look.mean_half_width)
    r, _, _ = track.initialise(image, detection=short)
    assert r.curve.length == pytest.approx(length, rel=0.01)


def test_a_transparent_tube_on_a_mottled_background_is_found_by_its_outline():
    """A transparent tube on a textured background (mottle of 5 % at 2, 6 and
    20 px) is no darker than the darker patches: the contrast's mask finds
    nothing. Its outline, sharp where the mottle is smooth, still stands out."""
    image, z = _first_frame(2, {"name": "transmitted", "texture": 0.05})
    f = segment.working_scale(image.shape)
    contrast, _ = segment.contrast_image(image, f)
    assert segment.foreground(contrast).sum() == 0
    det = segment.detect(image)
    assert det is not None
    # the whole tube (and the pipette, the skeleton's path runs into it), lying
    # along the true centreline
    length = float(np.abs(np.diff(z)).sum())
    assert np.abs(np.diff(det.path)).sum() >= 0.95 * length
    ahead = np.real((det.path - z[0]) * np.conj(z[5] - z[0])) > 0
    on_tube = det.path[ahead]
    near = np.min(np.abs(on_tube[:, None] - z[None, ::4]), axis=1)
    assert np.median(near) <= 1.5


@pytest.mark.parametrize("noise", [0.045, 0.07])
def test_a_tube_lost_in_noise_at_the_working_scale_is_found_at_a_coarser_one(noise):
    """A faint transparent tube under strong camera noise (4.5-7 % of full
    scale, per pixel): at the working scale the mask finds nothing or a speck
    of noise, while by eye, and at a coarser scale, the tube is plain."""
    image, z = _first_frame(2, {"name": "low_contrast", "read_noise": noise})
    f = segment.working_scale(image.shape)
    fine = segment._detect_at(image, f, None, None)
    length = float(np.abs(np.diff(z)).sum())
    assert fine is None or fine.length < 0.5 * length
    det = segment.detect(image)
    assert det is not None
    # the whole tube (with a bit of the pipette), lying along the true
    # centreline, at its width (27 px)
    assert 0.95 * length <= det.length <= 1.1 * length
    ahead = np.real((det.path - z[0]) * np.conj(z[5] - z[0])) > 0
    near = np.min(np.abs(det.path[ahead][:, None] - z[None, ::4]), axis=1)
    assert np.median(near) <= 2.5
    assert 2 * det.half_width == pytest.approx(27.0, rel=0.25)


@pytest.mark.parametrize("sample, angle, look, seed", [
    (1, 235.0, {"name": "low_contrast", "photons": 816.0}, 1),
    (1, 235.0, {"name": "low_contrast", "photons": 816.0}, 5),
    (1, 235.0, {"name": "low_contrast", "photons": 816.0}, 11),
    # thick walls: the closings fill the lumen over several radii, of which
    # only the first is under a 2.5th of the tube's width (on one such frame,
    # mean width 7 -> 8.8 -> 17.5 -> 24.6 -> 27.5 px at radii 4, 6, 8, 11, 16)
    (3, 9.0, {"name": "low_contrast", "photons": 900.0, "gradient": 0.44}, 4),
    (3, 9.0, {"name": "low_contrast", "photons": 900.0, "gradient": 0.44}, 6),
    (2, 189.0, {"name": "low_contrast", "photons": 620.0, "contrast": 0.32}, 2),
])
def test_rims_that_join_over_two_closings_still_fill_the_tube(sample, angle, look, seed):
    """A faint, noisy transparent tube's rims are dotted: one closing joins
    them over a stretch, the next all along (mean width 6 -> 8 -> 17 -> 20 px,
    no single step followed by a plateau). Left unfilled, the skeleton ran
    down one rim and back up the other: a path about twice the tube's length
    and a rim's width (these seeds; 9 of 12 filled before in the first case,
    and 9 and 11 of 12 in the others)."""
    scene = default_scene(sample, n_frames=1, seed=seed, width=480, height=360,
                          base_angle_deg=angle, mirror=sample == 1, look=look)
    renderer = Renderer(scene)
    _, lines, _ = truth_tables(scene, renderer.layout)
    length = lines["s_um"].max() / renderer.layout.um_per_px
    det = segment.detect(renderer.frame(0))
    assert det is not None
    assert length <= det.length <= 1.15 * length
    tube = get_sample(sample)
    outer_um = min(tube.r_in_um + 0.5 * (x.t_top_um + x.t_bot_um) for x in tube.sections)
    assert det.half_width >= 0.8 * outer_um / renderer.layout.um_per_px


@pytest.mark.parametrize("sample", [2, 3])
def test_rims_no_closing_joins_are_taken_for_the_tube_found_coarser(sample):
    """A faint transparent tube (12 % contrast, read noise 1.5 %) whose rims
    come out of the mask 2-4 px thick and 20 px apart: the closing that joins
    them gives a width under 2.5x its radius, so none counts as filling the
    tube, and the skeleton ran up one rim, round the tip and back down the
    other (1.6-1.9x the tube's length, a rim's width). The whole tube found at
    half the scale, half that length, was refused for being shorter; it is now
    taken, as the thin path runs along its walls."""
    look = {"name": "low_contrast", "contrast": 0.12, "read_noise": 0.015, "photons": 0.0,
            "dust": 0}
    scene = default_scene(sample, n_frames=8, seed=2, width=480, height=360, look=look)
    renderer = Renderer(scene)
    _, lines, _ = truth_tables(scene, renderer.layout)
    length = lines["s_um"].max() / renderer.layout.um_per_px
    image = renderer.frame(0)
    fine = segment._detect_at(image, segment.working_scale(image.shape), None, None)
    assert fine.length > 1.5 * length and fine.half_width < segment.THIN_HALF_WIDTH
    det = segment.detect(image)
    assert 0.95 * length <= det.length <= 1.1 * length
    first = lines[lines["frame"] == 0]
    scale = renderer.layout.um_per_px
    z = from_image(first["x_um"].to_numpy() / scale, -first["y_um"].to_numpy() / scale)
    near = np.min(np.abs(det.path[:, None] - z[None, ::4]), axis=1)
    assert np.median(near) <= 2.5
    tube = get_sample(sample)
    outer_um = min(tube.r_in_um + 0.5 * (x.t_top_um + x.t_bot_um) for x in tube.sections)
    assert det.half_width >= 0.8 * outer_um / scale


@pytest.mark.parametrize(("sample", "frame"), [(1, 0), (2, 2), (3, 3)])
def test_thin_rims_no_blur_brings_out_are_found_along_their_own_direction(sample, frame):
    """A transparent tube at 8 % contrast in 2.5 % read noise: its rims, a
    pixel or two wide, stand at about 3x the noise of a pixel, and no scale
    of the isotropic blur brings them out (nothing found at any scale: the
    frame not measured). Averaged along their own direction they stand out,
    and the tube is found on its centreline."""
    look = {"name": "low_contrast", "contrast": 0.08, "read_noise": 0.025, "photons": 0.0,
            "dust": 0}
    scene = default_scene(sample, n_frames=8, seed=2, width=480, height=360, look=look)
    renderer = Renderer(scene)
    _, lines, _ = truth_tables(scene, renderer.layout)
    image = renderer.frame(frame)
    f = segment.working_scale(image.shape)
    assert all(segment._detect_at(image, k * f, None, None) is None
               for k in (1, *segment.COARSER))
    det = segment.detect(image)
    assert det is not None
    truth = lines[lines["frame"] == frame]
    scale = renderer.layout.um_per_px
    z = from_image(truth["x_um"].to_numpy() / scale, -truth["y_um"].to_numpy() / scale)
    length = truth["s_um"].max() / scale
    assert 0.9 * length <= det.length <= 1.15 * length
    off = np.min(np.abs(det.path[:, None] - z[None, ::2]), axis=1)
    assert np.median(off) <= 1.5
    covered = np.min(np.abs(z[::2, None] - det.path[None, :]), axis=1) < 5.0
    assert covered.mean() >= 0.8


def test_line_filters_find_nothing_in_noise_alone():
    rng = np.random.default_rng(0)
    for _ in range(3):
        image = (0.6 + 0.02 * rng.standard_normal((360, 480))).astype(np.float32)
        assert not segment.line_foreground(segment.contrast_image(image, 1)[0]).any()
        assert segment.detect(image) is None


def test_a_thin_path_is_the_rims_of_a_tube_only_when_it_runs_along_its_walls():
    """:func:`segment._rims_of` on drawn paths: a path up one wall and down the
    other is the tube's rims; the same tube's centreline, or a thin tube
    coiled inside a wide blob, is not."""
    wide = segment.Detection(np.linspace(0, 300, 151) + 0j, 0j, 0.0, 14.0, "drawn")

    def thin(path):
        return segment.Detection(path, complex(path[0]), 0.0, 2.0, "drawn")

    up = np.linspace(0, 305, 300) + 12j
    rims = np.concatenate([up, 305 + 12j * np.cos(np.linspace(0, np.pi, 20)), up[::-1] - 24j])
    assert segment._rims_of(thin(rims), wide)
    assert not segment._rims_of(thin(np.linspace(0, 300, 300) + 1j), wide)
    t = np.linspace(0, 6 * np.pi, 600)
    coil = 150 + (3 + 2 * t) * np.exp(1j * t)
    assert not segment._rims_of(thin(coil), wide)


def test_the_outline_wins_over_a_fragment_the_contrast_found_whatever_its_width():
    """:func:`segment._outline_wins` on drawn detections. A transparent tube on
    a mottled background: its contrast found 104 px of it (at the tube's own
    width) and, given the base, drew 290 px straight to it; its outline
    followed the whole tube. Judged by the drawn length, and refused for its
    wider band, the outline lost, and 11 of 13 frames were lost with it
    (independent scene a11). Where the contrast finds the tube whole, a
    longer, wider outline (running on along a pipette's walls) still loses."""
    def drawn(length, half_width, bridged=0.0):
        path = np.linspace(0.0, length, int(length) + 1) + 0j
        return segment.Detection(path, 0j, 0.0, half_width, "drawn", bridged)

    fragment = drawn(394.0, 15.0, bridged=290.0)
    assert fragment.found_length == pytest.approx(104.0)
    outline = drawn(1080.0, 21.6)
    assert segment._outline_wins(fragment, outline)
    assert not segment._outline_wins(drawn(780.0, 15.0), drawn(1000.0, 21.6))
    # a rim (narrow), or nothing, found by the contrast: the outline, as before
    assert segment._outline_wins(drawn(780.0, 3.0), drawn(1000.0, 21.6))
    assert segment._outline_wins(None, outline)
    assert not segment._outline_wins(fragment, None)


def test_a_detection_drawn_to_a_given_base_says_how_much_was_drawn():
    """A tube whose first stretch did not stand out is carried straight back to
    the base given (``--base``): what was drawn is kept apart from what was
    found, so that the two detections of a frame are compared on what each
    found."""
    image, z = _first_frame(2, {"name": "transmitted", "texture": 0.05})
    rr, cc = np.mgrid[0:image.shape[0], 0:image.shape[1]]
    # a darker stretch from 40 % to 55 % of the tube: the contrast finds the
    # tube from there on
    stretch = z[int(0.4 * z.size):int(0.55 * z.size):3]
    near = np.min(np.abs((cc - 1j * rr)[..., None] - stretch[None, None, :]), axis=-1) < 12
    image = np.where(near, 0.7 * image, image).astype(np.float32)
    found = segment.detect(image)
    assert found.bridged_px == 0.0
    given = segment.detect(image, base_hint=(z[0].real, -z[0].imag))
    assert given.bridged_px > 50.0
    assert abs(given.base - z[0]) < 1.0
    assert given.found_length == pytest.approx(found.length, rel=0.05)


@pytest.mark.parametrize("seed", range(6))
def test_skeleton_over_the_bounding_box_is_the_whole_frames_skeleton(seed):
    from skimage.morphology import skeletonize

    rng = np.random.default_rng(seed)
    rows, cols = rng.integers(8, 90, 2)
    mask = np.zeros((rows, cols), bool)
    for _ in range(4):  # blobs, some cut by the border
        r, c = rng.integers(0, rows), rng.integers(0, cols)
        hr, hc = rng.integers(1, 25, 2)
        mask[max(r - hr, 0):r + hr, max(c - hc, 0):c + hc] = True
    mask ^= rng.random(mask.shape) < 0.05  # ragged edges, specks, holes
    np.testing.assert_array_equal(segment._skeleton(mask), skeletonize(mask))
    assert not segment._skeleton(np.zeros((5, 7), bool)).any()


def _curl_mask(curl_radius, hollow_px=0, width_px=14, span_deg=320):
    """A tube's mask, in from the left border and curled ``span_deg`` about a
    circle of ``curl_radius`` px; with ``hollow_px`` its lumen left out (two rims)."""
    def draw(thick):
        m = np.zeros((160, 200), np.uint8)
        cv2.line(m, (0, 120), (100, 120), 255, thick)
        cv2.ellipse(m, (100, 120 - curl_radius), (curl_radius, curl_radius), 90, 0,
                    -span_deg, 255, thick)
        return m > 0
    mask = draw(width_px)
    return mask & ~draw(hollow_px) if hollow_px else mask


@pytest.mark.parametrize("curl_radius", [18, 22])
def test_a_solid_curled_tube_is_not_closed_over_the_background_it_encloses(curl_radius):
    """A closing wide enough to shut the curl's opening fills the round
    background inside it, and the mean width jumps as a hollow tube's does
    when its rims join (a 306 deg curl: 17.7 -> 43.5 px at radius 16). The
    start then took a blob for the tube (half-width 48 px)."""
    mask = _curl_mask(curl_radius)
    filled, radius = segment.fill_tube(mask)
    assert radius == 0
    np.testing.assert_array_equal(filled, mask)


def test_a_hollow_curled_tube_is_still_filled_by_joining_its_rims():
    mask = _curl_mask(22, hollow_px=6)
    filled, radius = segment.fill_tube(mask)
    assert 3 <= radius <= 6
    solid = _curl_mask(22)
    # the lumen filled, the curl's inside not
    assert (filled & ~solid).sum() < 0.05 * solid.sum()
    assert (solid & ~filled).sum() < 0.02 * solid.sum()


def test_the_base_tangent_fit_keeps_a_curled_tube():
    """The fit that measures the base tangent frees it under a strong
    roughness penalty, which resists a tube curled past 300 deg: from the
    true shape it slid off the curl (edges on 30 % of the profiles, the base
    tangent 23 deg off). It then falls back to the plain fit."""
    scene = default_scene(1, n_frames=8, seed=26, width=640, height=480,
                          base_angle_deg=300.0)
    scene = scene.replace(pressures_mpa=(scene.p_max_mpa,))
    renderer = Renderer(scene)
    _, lines, _ = truth_tables(scene, renderer.layout)
    scale = renderer.layout.um_per_px
    z = from_image(lines["x_um"].to_numpy() / scale, -lines["y_um"].to_numpy() / scale)
    image = track.as_float(renderer.frame(0))
    _, look, _ = track.initialise(image)
    truth = fit_to_polyline(z, np.radians(300.0), n_coef=24)
    before = track.refine(image, truth, look, iterations=4)
    r = track._base_tangent_fit(image, truth, look, 0.02, before)
    assert r.valid_fraction >= 0.8
    assert abs(np.degrees(r.curve.base_angle) - 300.0 + 360.0 * round(
        (np.degrees(r.curve.base_angle) - 300.0) / 360.0)) < 2.0


def test_the_background_surface_follows_the_illumination_not_the_tube():
    """The robust polynomial through a thumbnail: uneven light (a quartic
    gradient) is followed into the corners, a dark tube across it is not."""
    rows, cols = np.mgrid[0:96, 0:128]
    x, y = cols / 127 * 2 - 1, rows / 95 * 2 - 1
    light = 0.6 + 0.1 * x - 0.05 * y + 0.04 * x * y + 0.03 * x**4
    tube = np.where(np.abs(y - 0.3 * x) < 0.06, -0.3, 0.0)
    surface = segment._smooth_surface(light + tube)
    assert np.abs(surface - light).max() < 2e-3


def _bright_lumen(lumen_gain, seed=0, halo=False):
    """A transparent tube in transmitted light, 16 px wide: dark walls around
    a lumen ``lumen_gain`` times as bright as the background, sealed 15 px
    short of the tip; or (``halo``) a dark tube in a bright halo that fades
    outwards, as phase contrast shows it."""
    from tests.pipeline.synthetic import _signed_position

    rr, cc = np.mgrid[0:360, 0:480]
    s, d = _signed_position(cc - 1j * rr, 60 - 200j, 0.1, 360.0, 1 / 500)
    along = (s >= 0) & (s <= 360.0)
    img = np.full((360, 480), 0.6)
    if halo:
        # a dark tube 16 px wide, its halo 12 px wide and fading outwards
        out = np.clip((np.abs(d) - 8.0) / 12.0, 0.0, 1.0)
        img = np.where(along & (np.abs(d) > 8.0), 0.6 + 0.25 * (1 - out), img)
        img[along & (np.abs(d) <= 8.0)] = 0.35
    else:
        img[along & (np.abs(d) <= 8.0)] = 0.35
        img[(s >= 0) & (s <= 345.0) & (np.abs(d - 1.0) <= 3.5)] = 0.6 * lumen_gain
    img = cv2.GaussianBlur(img, (0, 0), 0.8)
    img += np.random.default_rng(seed).normal(0, 0.01, img.shape)
    return np.clip(img, 0, 1).astype(np.float32)


@pytest.mark.parametrize("gain", [1.1, 1.3])
def test_a_bright_lumen_is_not_taken_for_the_tube(gain):
    # the lumen, brighter than the background between the dark walls, stands
    # out as a bright tube 7 px wide and 15 px short; the dark walls around it
    # are the tube (found 3.5 px half-wide, 344 px long before)
    r, look, _ = track.initialise(_bright_lumen(gain))
    assert look.polarity == -1
    assert look.mean_half_width == pytest.approx(8.0, abs=0.5)
    assert r.curve.length == pytest.approx(360.0, abs=2.0)


def test_a_phase_halo_is_not_taken_for_the_tube():
    # a bright band around a dark tube too, but fading outwards: its outer
    # edges are weak, and the dark tube stays the tube
    r, look, _ = track.initialise(_bright_lumen(1.0, halo=True))
    assert look.polarity == -1
    assert look.mean_half_width == pytest.approx(8.0, abs=0.5)


#: Across an independent renderer's defocused, index-matched hollow tube
#: (radius 11 px, its lumen 0.7 px off centre, the walls' far side thicker),
#: at 0.5 px steps from -20 to +20 px about its true midline: one step down
#: into the thin wall, two (a shoulder) into the thick one.
_ECCENTRIC_PROFILE = np.array([
    0.808, 0.808, 0.808, 0.808, 0.808, 0.809, 0.810, 0.811, 0.810, 0.808, 0.806, 0.804, 0.800,
    0.793, 0.781, 0.768, 0.754, 0.741, 0.726, 0.712, 0.697, 0.682, 0.667, 0.652, 0.639, 0.629,
    0.625, 0.626, 0.633, 0.648, 0.666, 0.688, 0.709, 0.728, 0.741, 0.751, 0.757, 0.761, 0.762,
    0.762, 0.761, 0.756, 0.747, 0.735, 0.719, 0.700, 0.679, 0.656, 0.639, 0.627, 0.621, 0.623,
    0.632, 0.644, 0.659, 0.673, 0.684, 0.691, 0.694, 0.696, 0.699, 0.707, 0.719, 0.737, 0.755,
    0.772, 0.785, 0.794, 0.799, 0.803, 0.805, 0.806, 0.806, 0.806, 0.807, 0.808, 0.808, 0.808,
    0.808, 0.808, 0.808])


def test_the_pairs_about_a_lumen_include_the_first_fits(monkeypatch):
    """Taken for the tube, a lumen's bright middle gives way to a dark pair
    about it (:func:`pipeline.track._enclosing`): the first fits' pairs of
    that polarity are weighed with those tried about the lumen. On an
    independent renderer's defocused, index-matched tube with walls of two
    thicknesses, the widths tried about the lumen found only the pair of
    the thin wall's outer edge and the thick wall's lumen edge (17.4 px for
    23.4: the midline 2 px to one side, the bend up to 26 deg off), which a
    first fit had found whole."""
    from pipeline.refine import TubeLook, refine

    img, _ = _eccentric_tube()
    det = segment.detect(img)
    curve = fit_to_polyline(det.path, det.base_angle, n_coef=12)

    def fit(polarity, half_width, tol):
        return refine(img, curve, TubeLook(polarity, np.full(9, half_width), 0.0),
                      window=0.6 * det.half_width, iterations=3, width_tol=tol,
                      fit_length=False, tol_px=0.02, tip_stiffness=0.0)

    lumen, outer = fit(+1, 3.6, 0.4), fit(-1, 11.0, 0.4)
    assert np.nanmedian(lumen.width[lumen.valid]) < 9.0
    # (none tried about the lumen here: only what the first fits found)
    monkeypatch.setattr(track, "ENCLOSING_SCALES", ())
    assert track._enclosing(img, curve, lumen, +1, det.half_width, 0.02) == (lumen, +1)
    got, polarity = track._enclosing(img, curve, lumen, +1, det.half_width, 0.02,
                                     others=[outer])
    assert polarity == -1 and got is outer


def _eccentric_tube():
    """:data:`_ECCENTRIC_PROFILE` along a straight tube from the left border,
    its midline at row 240, its end a round cap at col 450; and that end col."""
    rows, cols = 480, 640
    rr, cc = np.mgrid[0:rows, 0:cols].astype(float)
    centre, end = 240.0, 450.0
    across = rr - centre
    # (past the end, the profile about the cap's centre: a round cap)
    radial = np.where(cc > end, np.sign(across) * np.hypot(cc - end, across), across)
    offsets = np.arange(-20.0, 20.25, 0.5)
    img = np.interp(radial, offsets, _ECCENTRIC_PROFILE, left=0.808, right=0.808)
    img += np.random.default_rng(2).normal(0.0, 0.004, img.shape)
    return img.astype(np.float32), end


def test_an_eccentric_hollow_tube_is_found_at_its_outer_walls():
    """That profile along a straight tube: the start takes its outer pair,
    not the lumen nor the pair of one outer edge and one lumen edge."""
    img, end = _eccentric_tube()
    centre = 240.0
    r, look, _ = track.initialise(img)
    assert look.polarity == -1
    # (the outer pair about 22 px apart, the mixed one about 17.5)
    assert look.mean_half_width > 10.0, look.mean_half_width
    _, z = resample(r.curve)
    inner = (z.real > 40) & (z.real < end - 40)
    # (the outer pair's midpoint: 0.5 px to the thick side, as the profile has it)
    assert np.abs(np.median(z.imag[inner]) + centre) < 1.0, np.median(z.imag[inner])


#: Across an independent renderer's hollow tube in gamma-encoded bright field
#: (16.7 px wide, its lumen 10 px wide and 0.7 px off-centre), every pixel from
#: 10 px on one side of its axis to 11 px on the other (8-bit grey): the outer
#: edges, a dark rim at each lumen wall, and the lighter band of the thick wall.
HOLLOW_PROFILE = (226, 204, 165, 136, 117, 88, 74, 105, 150, 181, 175, 138, 95, 83, 114,
                  145, 150, 145, 168, 205, 225, 229)


@pytest.mark.parametrize("angle_deg", [0.0, 35.0])
@pytest.mark.parametrize(("aside", "mask_hw"), [(-1.0, 6.0), (-2.0, 14.0)])
def test_a_thick_wall_s_lumen_edge_is_not_taken_for_the_tube_s_edge(angle_deg, aside, mask_hw):
    """Such a tube shows, beside its outer edge pair, a pair of one outer edge
    and the thick wall's lumen edge, as strong and 12.4 px apart. A first fit
    whose start lay nearer that pair's middle kept it: the tube 6.2 px wide
    each side of a midline 2 px to one side, on every frame (a mask 14 px wide
    across a holder, its skeleton 2 px off the axis). The wider pair sharing
    one of its edges, as strong, is now taken for the tube."""
    offsets = np.arange(-10.0, 12.0)
    values = np.asarray(HOLLOW_PROFILE, dtype=float) / 255.0
    angle = np.radians(angle_deg)
    base = complex(0.0, -150.0) if angle_deg == 0 else complex(0.0, -300.0)
    image = profile_image((360, 480), base, angle, 380.0, 0.0, offsets, values,
                          background=230 / 255, noise=0.005)
    normal = np.exp(1j * (angle + np.pi / 2))
    start = base + np.linspace(0.0, 380.0, 200) * np.exp(1j * angle) + aside * normal
    mask = segment.Detection(start, complex(start[0]), angle, mask_hw, "given")
    r, look, _ = track.initialise(image, detection=mask)
    assert look.mean_half_width == pytest.approx(8.35, abs=0.3)
    # the measured midline against the outer pair's middle, 0.15 px beside the axis
    s, z = resample(r.curve)
    mid = z[(s > 0.2 * s[-1]) & (s < 0.8 * s[-1])]
    offset = np.real((mid - base) * np.conj(normal))
    assert np.all(np.abs(offset - 0.15) <= 0.3)


#: Across a fifth independent renderer's tube in water with an air-filled lumen
#: (30 px wide, its lumen 18 px wide and 1.2 px off-centre), 8-bit grey every px
#: from 18 px on one side of its axis to 18 px on the other: the outer edges
#: step down as the lumen's walls do, and those more strongly.
AIR_LUMEN_PROFILE = (195, 188, 162, 125, 109, 130, 160, 174, 173, 150, 101, 45, 12, 2, 3, 15,
                     49, 103, 152, 175, 169, 135, 80, 31, 8, 2, 6, 29, 77, 129, 147, 128, 109,
                     124, 162, 187, 194)


@pytest.mark.parametrize("angle_deg", [0.0, -25.0, 40.0])
def test_a_lumen_stepping_as_the_outer_edges_do_is_not_taken_for_the_tube(angle_deg):
    """The lumen's pair, stronger than the outer one and sharing no edge with
    it, was taken for the tube: 18 px wide for 30, the tip put at the lumen's
    end and the end stretch hooked. The pair enclosing it along the tube, of
    the same polarity and over half as strong, is now taken."""
    offsets = np.arange(-18.0, 19.0)
    values = np.asarray(AIR_LUMEN_PROFILE, dtype=float) / 255.0
    angle = np.radians(angle_deg)
    base = complex(0.0, {0.0: -150.0, -25.0: -100.0, 40.0: -300.0}[angle_deg])
    image = profile_image((360, 480), base, angle, 380.0, 0.0, offsets, values,
                          background=195 / 255, noise=0.005)
    _, look, _ = track.initialise(image)
    # (the pair's edges lie outside the outer surface by a px, as on the frames)
    assert look.mean_half_width == pytest.approx(15.8, abs=1.0)


@pytest.mark.parametrize("angle_deg", [0.0, 30.0])
def test_a_fringe_about_the_tube_is_not_taken_for_its_walls(angle_deg):
    """A dark ring about a dark tube (a defocus fringe, a coating's rim) is a
    pair of its polarity enclosing the tube along its length, as a hollow
    tube's outer pair encloses its lumen's; but the band between them is the
    background, where a tube's wall is not (before: 12.7 px for 8)."""
    offsets = np.arange(-20.0, 21.0)
    d = np.abs(offsets)
    values = np.where(d < 8, 0.8 * 0.65, np.where((d > 10.5) & (d < 13), 0.6, 0.8))
    angle = np.radians(angle_deg)
    base = complex(0.0, -150.0 if angle_deg == 0 else -300.0)
    image = profile_image((360, 480), base, angle, 380.0, 0.0, offsets, values,
                          background=0.8, noise=0.005)
    _, look, _ = track.initialise(image)
    assert look.mean_half_width == pytest.approx(7.5, abs=0.7)
