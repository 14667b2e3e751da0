import numpy as np
import pytest
from scipy.special import erf

from pipeline.profiles import (
    edge_pairs,
    end_edge,
    gradient_noise,
    sample_lines,
    sample_strips,
    side_edges,
)


def _profiles(centres, half_widths, polarity=-1, step=0.5, half=40.0, noise=0.0, seed=0,
              edge=0.8, extra_edge=None):
    off = np.arange(-half, half + step / 2, step)
    c = np.asarray(centres)[:, None]
    hw = np.asarray(half_widths)[:, None]
    inside = 0.5 * (1 + erf((hw - np.abs(off[None, :] - c)) / edge))
    prof = 0.8 * (1 + polarity * 0.3 * inside)
    if extra_edge is not None:  # a second tube further out (e.g. another coil)
        prof *= 1 + polarity * 0.3 * 0.5 * (1 + erf((6 - np.abs(off - extra_edge)) / edge))
    rng = np.random.default_rng(seed)
    return prof + rng.normal(0, noise, prof.shape), step


@pytest.mark.parametrize("polarity", [-1, 1])
def test_edge_pairs_find_centres_and_widths_sub_pixel(polarity):
    centres = np.linspace(-6, 6, 25)
    prof, step = _profiles(centres, np.full(25, 15.0), polarity=polarity)
    e = edge_pairs(prof, step, 15.0, polarity=polarity, window=8.0)
    assert e.valid.all()
    assert np.abs(e.centre - centres).max() < 0.02
    assert np.abs(e.width - 30.0).max() < 0.1


def test_wrong_polarity_or_width_is_invalid():
    prof, step = _profiles(np.zeros(5), np.full(5, 15.0), polarity=-1)
    wrong_pol = edge_pairs(prof, step, 15.0, polarity=1, window=8.0, min_strength=0.01)
    wrong_width = edge_pairs(prof, step, 22.0, polarity=-1, window=8.0, min_strength=0.01)
    assert not wrong_pol.valid.any()
    assert not wrong_width.valid.any()


def test_noise_keeps_the_centre_unbiased():
    centres = np.full(400, 1.3)
    prof, step = _profiles(centres, np.full(400, 12.0), noise=0.01, seed=3)
    e = edge_pairs(prof, step, 12.0, polarity=-1, window=6.0)
    assert e.valid.mean() > 0.98
    assert abs(np.mean(e.centre[e.valid]) - 1.3) < 0.01
    assert np.std(e.centre[e.valid]) < 0.1


def test_the_pair_nearest_the_prediction_wins_over_a_neighbouring_tube():
    # another 12-px tube sits 24 px to the side: the nearer pair must be chosen
    prof, step = _profiles(np.array([2.0]), np.array([6.0]), extra_edge=26.0, half=45)
    e = edge_pairs(prof, step, 6.0, polarity=-1, window=20.0)
    assert e.valid[0] and abs(e.centre[0] - 2.0) < 0.05


@pytest.mark.parametrize("polarity", [-1, 1])
def test_one_edge_places_the_tube_where_another_layer_lies_over_its_other_side(polarity):
    # a 12 px tube at +0.7 px, and another layer of it 9 px off on the + side
    # (a coil lying half over it): the pair is gone, the − side's edge is not
    off = np.arange(-30.0, 30.25, 0.25)
    edge = 0.8

    def body(c):
        return 0.5 * (1 + erf((6.0 - np.abs(off - c)) / edge))

    # (the other layer on top, hiding what lies under it)
    top = body(9.7)
    prof = (0.8 * (1 + polarity * 0.3 * body(0.7)) * (1 - top)
            + 0.8 * (1 + polarity * 0.3) * top)[None, :]
    centre, strength, valid = side_edges(prof, 0.25, 6.0, np.array([-1.0]),
                                         polarity=polarity, reach=2.0)
    assert valid[0] and strength[0] > 0
    assert centre[0] == pytest.approx(0.7, abs=0.03)
    # the covered side's edge lies under the other layer: it misplaces the tube
    centre, _, valid = side_edges(prof, 0.25, 6.0, np.array([1.0]), polarity=polarity,
                                  reach=2.0)
    assert not (valid[0] and abs(centre[0] - 0.7) < 0.5)
    # no edge of the tube's polarity within reach: none
    _, _, valid = side_edges(prof, 0.25, 6.0, np.array([-1.0]), polarity=-polarity,
                             reach=2.0, min_strength=1e-3)
    assert not valid[0]


def test_nan_samples_never_make_an_edge():
    prof, step = _profiles(np.zeros(3), np.full(3, 10.0))
    prof[:, : prof.shape[1] // 2] = np.nan  # left half outside the image
    e = edge_pairs(prof, step, 10.0, polarity=-1, window=5.0)
    assert not e.valid.any()


def test_a_profile_running_off_the_image_shows_no_step_at_the_border():
    """A blurred dark tube's end (at 0), then a background that darkens towards
    the image's border (vignetting), which the profile leaves at +25 px. Its
    missing samples were filled with the mean of all samples, brighter than the
    darkened border: a brightening step there, as strong as the blurred end,
    and the outermost, so the end was put at the border."""
    off = np.arange(-35, 35.25, 0.25)
    body = 0.5 * (1 + erf((0.0 - off) / (4.0 * np.sqrt(2))))   # end blurred by 4 px
    background = 0.8 - 0.45 * (np.clip(off - 10, 0, None) / 15.0) ** 2
    prof = body * 0.3 + (1 - body) * background
    prof[off > 25.0] = np.nan
    pos, strength = end_edge(prof[None, :], 0.25, polarity=-1, window=30.0)
    assert abs(pos[0]) < 0.25 and strength[0] > 0


def test_end_edge_takes_the_outermost_strong_step():
    off = np.arange(-30, 30.25, 0.25)
    body = 0.5 * (1 + erf((0.0 - off) / 0.8))           # tube ends at 0
    lumen = 0.5 * (1 + erf((-8.0 - off) / 0.8))          # lumen ends 8 px inside
    prof = 0.8 * (1 - 0.3 * body + 0.2 * lumen)
    pos, strength = end_edge(prof[None, :], 0.25, polarity=-1, window=20.0)
    assert abs(pos[0]) < 0.05 and strength[0] > 0


def test_sample_lines_reads_bilinear_values_and_nan_outside():
    img = np.add.outer(np.arange(20.0), 100 * np.arange(30.0)).astype(np.float32)  # row + 100 col
    starts = np.array([5.0 - 7.0j])   # col 5, row 7
    got = sample_lines(img, starts, np.array([1.0 + 0j]), np.array([0.0, 0.5, 100.0]))
    assert got[0, 0] == pytest.approx(7 + 500)
    assert got[0, 1] == pytest.approx(7 + 550)
    assert np.isnan(got[0, 2])


@pytest.mark.parametrize("smooth", [0.8, 1.6, 2.4])
def test_gradient_noise_is_the_spread_of_the_edge_filter_on_white_noise(smooth):
    sigma = 0.02
    img = 0.5 + np.random.default_rng(5).normal(0, sigma, (400, 400))
    # a derivative of a Gaussian of scale s passes white noise with a spread of
    # σ·(4·√π·s³)^(−1/2)
    expected = sigma / np.sqrt(4 * np.sqrt(np.pi) * smooth**3)
    assert gradient_noise(img, smooth) == pytest.approx(expected, rel=0.03)
    # a tube's two strong edges move the robust spread little
    img[:, 100:124] += 0.3
    assert gradient_noise(img, smooth) == pytest.approx(expected, rel=0.1)
    img[:5, :5] = np.nan  # outside a crop: left out
    assert np.isfinite(gradient_noise(img, smooth))


def test_a_strip_is_the_mean_of_its_parallel_lines():
    rng = np.random.default_rng(3)
    img = rng.random((60, 80)).astype(np.float32)
    starts = np.array([30 - 20j, 41.5 - 33.2j, 1.0 - 1.0j])
    normals = np.exp(1j * np.array([0.3, 2.0, np.pi / 2]))
    offsets = np.arange(-5.0, 5.5, 0.5)
    shifts = np.array([[-1.0, 0.0, 1.0], [-0.5, 0.0, 0.7], [0.0, 0.0, 0.0]])
    got = sample_strips(img, starts, normals, offsets, shifts)
    tangents = -1j * normals  # the lines' copies lie along the tube
    want = np.mean([sample_lines(img, starts + shifts[:, k] * tangents, normals, offsets)
                    for k in range(3)], axis=0)
    assert got.shape == (3, offsets.size)
    assert np.allclose(got, want, equal_nan=True)
    # a copy outside the image makes that sample NaN, as for a single line
    assert np.isnan(got[2]).any() and not np.isnan(got[0]).any()


def _walled_profile(origins, step: float = 0.25, half: float = 20.0):
    """A hollow tube's profiles (outer edges at ±9 px, its thick walls' dark
    lumen rims at -6..-4 and +3..+5, every step falling on entering from the
    left or rising on leaving at the right, as a dark-rimmed tube's do), seen
    from profiles whose origins lie at ``origins`` px."""
    off = np.arange(-half, half + step / 2, step)[None, :] + np.asarray(origins)[:, None]

    def up(x):  # 0 -> 1 across x, over about a pixel
        return 0.5 * (1 + erf((off - x) / 0.8))
    level = (1.0 - 0.4 * up(-9) - 0.5 * up(-6) + 0.45 * up(-4) - 0.45 * up(3)
             + 0.5 * up(5) + 0.4 * up(9))
    return level, step


def test_a_known_width_takes_the_outer_pair_over_one_sharing_its_edge_with_a_lumen_rim():
    # predictions along a stretch of the tube sit at the middle of the pair made
    # of the left rim and the right outer edge (15 px wide, 1.5 px off the
    # tube's middle)
    prof, step = _walled_profile(np.full(6, 1.5))
    known = edge_pairs(prof, step, 9.0, polarity=-1, window=6.0, width_tol=0.2)
    assert known.valid.all()
    assert np.all(np.abs(known.width - 18.0) < 0.2) and np.all(np.abs(known.centre + 1.5) < 0.1)
    # a guessed width (a wide tolerance) does not say which pair is the tube:
    # the nearest to the prediction is taken
    guessed = edge_pairs(prof, step, 9.0, polarity=-1, window=6.0, width_tol=0.4)
    assert np.all(np.abs(guessed.width - 15.0) < 0.3) and np.all(np.abs(guessed.centre) < 0.2)
    # nor is a profile switched alone, among profiles predicted well: a chance
    # pair of lines, not a stretch of the tube taken by its wrong pair
    prof, step = _walled_profile([0.0, 0.0, 1.5, 0.0, 0.0])
    e = edge_pairs(prof, step, 9.0, polarity=-1, window=6.0, width_tol=0.2)
    assert np.all(np.abs(e.width[[0, 1, 3, 4]] - 18.0) < 0.2)
    assert np.all(np.abs(e.centre[[0, 1, 3, 4]]) < 0.1)
    assert abs(e.width[2] - 15.0) < 0.3
