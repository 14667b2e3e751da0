import numpy as np
import pytest

from pipeline.centreline import (
    Curve,
    evaluate,
    fit_to_polyline,
    make_basis,
    n_grid_for,
    tip_point,
)
from pipeline.refine import (
    STRIP_LINES,
    STRIP_STEP_PX,
    TubeLook,
    _strip_shifts,
    contact_mask,
    locate_base,
    refine,
    section_ratio,
    self_contact,
    widths_at,
)
from tests.pipeline.synthetic import _signed_position, arc_axis, tube_image, two_sections

SHAPE = (480, 640)
BASE = 120 - 420j


def _base(kappa):
    # bending up (κ > 0) from low in the frame, down from high in it
    return BASE if kappa >= 0 else 120 - 130j


def _truth(kappa, length=450.0, angle=0.0):
    z, _ = arc_axis(_base(kappa), angle, length, kappa)
    return fit_to_polyline(z, angle, n_coef=12)


def _errors(curve, truth):
    basis = make_basis(truth.coef.size, n_grid_for(truth.length))
    zt = evaluate(truth, basis)
    zc = evaluate(curve.with_params(curve.coef, curve.length), basis)
    return (np.degrees(abs(curve.coef[-1] - truth.coef[-1])), np.abs(zc.z - zt.z).max(),
            abs(curve.length - truth.length))


@pytest.mark.parametrize("kappa", [0.0, 1 / 250, -1 / 300])
@pytest.mark.parametrize("polarity", [-1, 1])
def test_refine_converges_from_a_perturbed_prediction(kappa, polarity):
    truth = _truth(kappa)
    img = tube_image(SHAPE, _base(kappa), 0.0, 450.0, kappa, 16.0, polarity=polarity,
                     noise=0.01)
    look = TubeLook(polarity, np.full(5, 16.0), 0.05)
    start = truth.with_params(truth.coef * 0.97 + 0.01, truth.length * 0.985)
    r = refine(img, start, look, iterations=12, tol_px=0.005)
    angle_err, pos_err, len_err = _errors(r.curve, truth)
    assert r.valid_fraction > 0.95 and r.tip_found
    assert angle_err < 0.3 and pos_err < 0.3 and len_err < 1.0


def test_refine_in_a_crop_matches_the_full_frame():
    truth = _truth(1 / 300)
    img = tube_image(SHAPE, BASE, 0.0, 450.0, 1 / 300, 16.0)
    look = TubeLook(-1, np.full(5, 16.0), 0.05)
    full = refine(img, truth, look, iterations=3)
    r0, c0 = 100, 60
    crop = refine(img[r0:, c0:], truth, look, origin=(c0, r0), iterations=3)
    assert np.allclose(full.curve.coef, crop.curve.coef, atol=1e-9)


def test_free_base_recovers_the_base_tangent():
    truth = _truth(0.0, angle=0.2)
    img = tube_image(SHAPE, BASE, 0.2, 450.0, 0.0, 16.0, noise=0.01)
    look = TubeLook(-1, np.full(5, 16.0), 0.05)
    start = Curve(truth.base + 1.5j, 0.2 + np.radians(3), truth.length, truth.coef * 0)
    # a strong roughness penalty: φ(0) must follow the rest of the tube
    r = refine(img, start, look, iterations=12, free_base=True, smoothing=0.1)
    assert abs(np.degrees(r.curve.base_angle - 0.2)) < 0.1
    assert abs(np.degrees(r.curve.coef[-1])) < 0.2  # straight: no bend left over


def test_a_narrow_tube_s_tip_angle_does_not_follow_the_edge_noise():
    """A tube 6 px wide at a signal-to-noise of ~5: one width at the tip is a
    handful of profiles, so the stiff tip stretch has a floor in pixels
    (RMS over 12 noise draws: 1.4° with a stretch of one width, 0.6° now)."""
    base, length, kappa, hw = 40 - 200j, 200.0, 1 / 80, 3.0
    z, _ = arc_axis(base, 0.0, length, kappa)
    truth = fit_to_polyline(z, 0.0, n_coef=16)
    look = TubeLook(-1, np.full(5, hw), 0.05)
    errors = []
    for seed in range(12):
        img = tube_image((240, 320), base, 0.0, length, kappa, hw, contrast=0.2, noise=0.03,
                         seed=seed)
        r = refine(img, truth, look, iterations=6)
        errors.append(np.degrees(r.curve.coef[-1] - truth.coef[-1]))
    assert np.sqrt(np.mean(np.square(errors))) < 1.0
    # and a noise-free arc keeps its tip angle: the stiff stretch holds the
    # curvature constant, not the direction
    clean = refine(tube_image((240, 320), base, 0.0, length, kappa, hw, contrast=0.2), truth,
                   look, iterations=6)
    assert abs(np.degrees(clean.curve.coef[-1] - truth.coef[-1])) < 0.2



def test_the_reported_tip_is_held_stiffer_than_the_fit():
    """The fit's last few pixels follow the edge noise; the shape reported
    (``tip_correction`` added) holds the tip's curvature firmer: over 16 noise
    draws on a tube 9 px wide, the tip angle's RMS error 0.59 -> 0.50 deg,
    and a noise-free arc keeps its tip angle."""
    base, length, kappa, hw = 40 - 200j, 200.0, 1 / 80, 4.5
    z, _ = arc_axis(base, 0.0, length, kappa)
    truth = fit_to_polyline(z, 0.0, n_coef=16)
    look = TubeLook(-1, np.full(5, hw), 0.05)
    fit, reported = [], []
    for seed in range(16):
        img = tube_image((240, 320), base, 0.0, length, kappa, hw, contrast=0.2, noise=0.02,
                         seed=seed)
        r = refine(img, truth, look, iterations=6)
        fit.append(r.curve.coef[-1] - truth.coef[-1])
        reported.append(r.curve.coef[-1] + r.tip_correction[-1] - truth.coef[-1])
    assert np.sqrt(np.mean(np.square(reported))) < 0.9 * np.sqrt(np.mean(np.square(fit)))
    clean = refine(tube_image((240, 320), base, 0.0, length, kappa, hw, contrast=0.2), truth,
                   look, iterations=6)
    assert abs(np.degrees(clean.curve.coef[-1] + clean.tip_correction[-1]
                          - truth.coef[-1])) < 0.2
    # the base-tangent fit (free_base) reports its own curve
    assert refine(img, truth, look, iterations=2, free_base=True).tip_correction is None


def test_on_a_noisy_frame_the_stiff_tip_stretch_grows_with_the_noise(monkeypatch):
    """Where the edge midpoints scatter well above their reference, a stiff
    stretch of fixed length holds the tip tangent on too few samples' worth of
    information: grown with the scatter (up to 3x), the reported tip angle's
    RMS error over 16 noise draws on a tube 8 px wide falls 1.03 -> 0.63 deg; a
    noise-free arc keeps its tip angle."""
    base, length, kappa, hw = 60 - 400j, 300.0, 1 / 150, 4.0
    z, _ = arc_axis(base, 0.0, length, kappa)
    truth = fit_to_polyline(z, 0.0, n_coef=16)
    look = TubeLook(-1, np.full(5, hw), 0.05)
    frames = [tube_image((480, 640), base, 0.0, length, kappa, hw, contrast=0.2, noise=0.05,
                         seed=seed) for seed in range(16)]

    def rms_tip_error():
        errors = []
        for img in frames:
            r = refine(img, truth, look, iterations=6)
            held = 0.0 if r.tip_correction is None else r.tip_correction[-1]
            errors.append(r.curve.coef[-1] + held - truth.coef[-1])
        return np.degrees(np.sqrt(np.mean(np.square(errors))))

    grown = rms_tip_error()
    monkeypatch.setattr("pipeline.refine.TIP_NOISE_STRETCH_MAX", 1.0)
    fixed = rms_tip_error()
    assert grown < 0.75 * fixed
    monkeypatch.undo()
    clean = refine(tube_image((480, 640), base, 0.0, length, kappa, hw, contrast=0.2), truth,
                   look, iterations=6)
    assert abs(np.degrees(clean.curve.coef[-1] + clean.tip_correction[-1]
                          - truth.coef[-1])) < 0.2


def test_the_grown_tip_stretch_stops_at_its_caps_and_at_the_last_joint():
    from pipeline.refine import _tip_rough, _tip_span

    def over(basis, share):  # ∫φ''² over the last ``share`` of the tube
        rows = basis.quad_second[basis.quad_u > 1.0 - share]
        return rows.T @ rows

    basis = make_basis(16, 301)
    assert np.isclose(_tip_span(30.0, 300.0, 0.4), 0.1)  # clean
    assert np.isclose(_tip_span(30.0, 300.0, 2.0), 0.2)
    assert np.isclose(_tip_span(30.0, 300.0, 9.0), 0.3)  # 3x
    assert np.isclose(_tip_span(30.0, 200.0, 3.0), 0.3)  # 0.3 L
    assert np.allclose(_tip_rough(basis, 0.2), over(basis, 0.2))
    # the stretch holds the curvature constant: not into the section before
    assert np.isclose(_tip_span(30.0, 300.0, 3.0, (0.85,)), 0.15)
    assert np.isclose(_tip_span(30.0, 300.0, 3.0, (0.95,)), 0.1)


def test_section_ratio_is_the_last_section_s_curvature_over_the_one_before_s():
    assert section_ratio(two_sections(1 / 100, 1 / 400)) == pytest.approx(0.25, abs=0.01)
    # sections bending opposite ways: no load bends a tube so (a holder's
    # mouth, hooked, taken for the section before)
    assert section_ratio(two_sections(-1 / 100, 1 / 200)) is None
    assert section_ratio(two_sections(1 / 100, -1 / 400)) is None
    assert section_ratio(two_sections(-1 / 100, -1 / 200)) == pytest.approx(0.5, abs=0.01)
    # no joints, or a section before too straight to scale from: no ratio
    assert section_ratio(_truth(1 / 250)) is None
    assert section_ratio(two_sections(1e-4, 1 / 100)) is None


def test_locate_base_finds_where_the_tube_leaves_a_narrower_pipette():
    img = tube_image(SHAPE, BASE, 0.0, 450.0, 0.0, 16.0, pipette_half_width=8.0)
    truth = _truth(0.0)
    look = TubeLook(-1, np.full(5, 16.0), 0.05)
    moved = Curve(truth.base + 9.0, 0.0, truth.length - 9.0, truth.coef)
    found = locate_base(img, moved, look)
    assert abs(found.base - BASE) < 1.0
    assert abs(found.length - 450.0) < 1.0


def test_locate_base_is_not_misled_by_a_pipette_width_learnt_at_the_start():
    """A curve running 20 px on into the pipette learns, over its first stretch, a
    width between the pipette's and the tube's; the base is still found."""
    img = tube_image(SHAPE, BASE, 0.0, 450.0, 0.0, 16.0, pipette_half_width=8.0)
    truth = _truth(0.0)
    look = TubeLook(-1, np.r_[11.0, np.full(8, 16.0)], 0.05)
    into_pipette = Curve(truth.base - 20.0, 0.0, truth.length + 20.0, truth.coef)
    found = locate_base(img, into_pipette, look)
    assert abs(found.base - BASE) < 1.0
    assert abs(found.length - 450.0) < 1.0


def test_locate_base_is_not_misled_by_a_width_learnt_off_at_one_place():
    """The learnt width dips where the base search ends (on a thin, noisy tube
    with an off-centre lumen, the lumen's edge pair taken for the tube's
    there): the base is still found where the tube begins, from a curve that
    starts short of it, or past it (it had been left 20 px into the tube)."""
    img = tube_image(SHAPE, BASE, 0.0, 450.0, 0.0, 16.0, noise=0.01)
    truth = _truth(0.0)
    look = TubeLook(-1, np.r_[16.0, 12.0, np.full(7, 16.0)], 0.05)
    for start in (-6.0, 6.0):
        curve = Curve(truth.base + start, 0.0, truth.length - start, truth.coef)
        found = locate_base(img, curve, look)
        assert abs(found.base - BASE) < 1.0
        assert abs(found.length - 450.0) < 1.0


@pytest.mark.parametrize("start", [-6.0, 6.0])
def test_locate_base_finds_a_tube_that_is_seen_inside_its_pipette_too(start):
    """Through a clear pipette the tube shows behind its base as well, its edges
    fainter: every profile of the search finds its edge pair, and the base is
    where their strength steps (it had been left where the first fit put it,
    5 px off on a fluorescent scene). A tube as strong behind the search as
    past it shows no step: its base is left where it was."""
    truth = _truth(0.0)
    curve = Curve(truth.base + start, 0.0, truth.length - start, truth.coef)
    look = TubeLook(-1, np.full(9, 16.0), 0.05)
    clad = tube_image(SHAPE, BASE, 0.0, 450.0, 0.0, 16.0, pipette_half_width=16.0,
                      pipette_contrast=0.4, noise=0.01)
    found = locate_base(clad, curve, look)
    assert abs(found.base - BASE) < 1.0
    assert abs(found.length - 450.0) < 1.0
    bare = tube_image(SHAPE, BASE, 0.0, 450.0, 0.0, 16.0, pipette_half_width=16.0,
                      pipette_contrast=1.0, noise=0.01)
    assert locate_base(bare, curve, look).base == curve.base


def test_locate_base_follows_a_bent_tube_past_a_long_run_of_pipette():
    """A pipette shown only by its two thin glass walls, as wide as the tube once
    thresholded: the first fit ran 110 px along it from the image border. The
    base search reaches past it, and must follow the curve there, not the
    pipette's axis, which the bent tube leaves (it found no tube at all and
    kept the base at the border: length +50 %)."""
    kappa = 1 / 250
    img = tube_image(SHAPE, BASE, 0.0, 450.0, kappa, 16.0)
    rr, cc = np.mgrid[0:SHAPE[0], 0:SHAPE[1]]
    rel = (cc - 1j * rr) - BASE
    walls = (rel.real < 0) & (np.abs(np.abs(rel.imag) - 10.0) < 1.0)
    img[walls] *= 0.75
    z, _ = arc_axis(BASE, 0.0, 450.0, kappa)
    along_pipette = fit_to_polyline(np.r_[BASE - np.arange(110.0, 0.0, -1.0), z], 0.0,
                                    n_coef=16)
    look = TubeLook(-1, np.full(9, 16.0), 0.05)
    found = locate_base(img, along_pipette, look, reach=130.0)
    assert abs(found.base - BASE) < 1.0
    assert abs(found.length - 450.0) < 1.5
    assert abs(tip_point(found) - z[-1]) < 1.0


STRIP_HALF_PX = 0.5 * (STRIP_LINES - 1) * STRIP_STEP_PX


def test_strips_shorten_at_the_ends_of_the_tube():
    s = np.array([0.0, 0.4, 5.0, 97.5, 98.0, 100.0])
    shifts = _strip_shifts(s, 100.0)
    assert shifts.shape == (6, STRIP_LINES)
    assert np.allclose(shifts[2], np.linspace(-STRIP_HALF_PX, STRIP_HALF_PX, STRIP_LINES))
    # never behind the base, nor within 2 px of the end face
    assert (s[:, None] + shifts >= 0).all()
    assert (s[:, None] + shifts <= np.maximum(98.0, s)[:, None]).all()
    assert np.allclose(shifts[0], [0.0, 0.0, STRIP_HALF_PX])
    assert np.allclose(shifts[4], [-STRIP_HALF_PX, 0.0, 0.0])
    # a longer strip keeps its lines 1 px apart, and is cut short the same way
    long = _strip_shifts(s, 100.0, lines=9)
    assert np.allclose(long[2], np.arange(-4, 5) * STRIP_STEP_PX)
    assert np.allclose(long[1], np.clip(np.arange(-4, 5), -0.4, 4))
    assert (s[:, None] + long <= np.maximum(98.0, s)[:, None]).all()


def test_self_contact_is_seen_only_when_the_tube_meets_itself():
    open_arc = _truth(1 / 200)                      # ~130°
    curl = _truth(1.15 * 2 * np.pi / 450.0)         # 1.15 turns: crosses its base region
    assert not self_contact(open_arc, 16.0)
    assert self_contact(curl, 16.0)


def _polyline(points, gap=2.0):
    """Points every ``gap`` px along a polyline (complex px)."""
    pts = np.asarray(points, dtype=complex)
    s = np.r_[0.0, np.cumsum(np.abs(np.diff(pts)))]
    q = np.arange(0.0, s[-1] + 1e-9, gap)
    return np.interp(q, s, pts.real) + 1j * np.interp(q, s, pts.imag)


def test_a_tip_ending_against_the_body_keeps_its_side_profiles():
    hw, gap = 10.0, 2.0
    reach = hw * 2.2 + 0.5 * hw + 2.0  # the reach refine uses (width_tol 0.2)
    # the body runs up x = 220, loops far away and comes back as the last part,
    # along y = 0, which ends 20 px short of the body's axis (touching its edge)
    z = _polyline([220 - 100j, 220 + 100j, 220 + 400j, -300 + 400j, -300 + 0j, 200 + 0j], gap)
    last = np.nonzero((np.abs(z.imag) < 1e-9) & (z.real > 0))[0]
    normals = np.full(last.size, 1j)
    round_ = contact_mask(z, last, reach=reach, gap=gap)
    along_lines = contact_mask(z, last, reach=reach, gap=gap, normals=normals, half_width=hw)
    # a round neighbourhood drops the last width of profiles, which run beside
    # the body, not into it; the profiles' own lines do not reach it
    assert round_[-1] and round_.sum() >= hw / 3
    assert not along_lines.any()
    # a coil running beside that part, 25 px away, does lie across its profiles
    z = _polyline([0 + 25j, 200 + 25j, 200 + 400j, -300 + 400j, -300 + 0j, 200 + 0j], gap)
    last = np.nonzero((np.abs(z.imag) < 1e-9) & (z.real > 10))[0]
    beside = contact_mask(z, last, reach=reach, gap=gap, normals=np.full(last.size, 1j),
                          half_width=hw)
    assert beside[(z[last].real > 10) & (z[last].real < 190)].all()


@pytest.mark.parametrize("kappa", [0.0, 1 / 250])
def test_widths_at_measures_the_outer_width_anywhere_along_the_tube(kappa):
    truth = _truth(kappa)
    img = tube_image(SHAPE, _base(kappa), 0.0, 450.0, kappa, 16.0, noise=0.01)
    look = TubeLook(-1, np.full(5, 16.0), 0.05)
    u = np.linspace(0.1, 0.9, 333)  # any spacing, here under 1.1 px
    width = widths_at(img, truth, look, u)
    assert np.isfinite(width).all()
    assert np.abs(np.median(width) - 32.0) < 0.2 and np.std(width) < 0.3
    if kappa == 0:
        # off the tube (100 px beside it, on blank background) no width is found
        away = Curve(truth.base + 100j, truth.base_angle, truth.length, truth.coef)
        assert np.isnan(widths_at(img, away, look, u)).all()
    # on a crop holding the tube, placed by its origin: the same widths (to the
    # float32 image's rounding of the sample positions)
    r0, c0 = 100, 60
    cropped = widths_at(img[r0:, c0:], truth, look, u, origin=(c0, r0))
    assert np.allclose(cropped, width, atol=1e-4, rtol=0)


def test_a_noisy_sealed_tip_is_placed_at_its_end_not_pushed_beyond_it():
    # a small bright (fluorescent) tube whose last 2.5 px are a solid plug,
    # brighter than the hollow tube: the wide filter a noisy frame needs puts
    # the end 1-2 px beyond it, away from the plug's inner step
    base, length, hw = 40 - 120j, 110.0, 4.0
    img = tube_image((240, 200), base, 0.0, length, 0.0, hw, polarity=1, background=0.05,
                     contrast=0.6, edge_px=0.8)
    rr, cc = np.mgrid[0:240, 0:200]
    s, d = _signed_position(cc - 1j * rr, base, 0.0, length, 0.0)
    img = img + 0.05 * ((s > length - 2.5) & (s < length) & (np.abs(d) < hw))
    img = img + np.random.default_rng(4).normal(0, 0.004, img.shape)
    look = TubeLook(1, np.full(5, hw), 0.005, smooth_px=2.4)
    start = Curve(base, 0.0, length - 2.0, np.zeros(6))
    r = refine(img.astype(np.float32), start, look, iterations=12, tol_px=0.005)
    assert r.tip_found
    assert abs(r.curve.length - length) < 0.45  # the wide filter alone: +0.65 px


@pytest.mark.parametrize("polarity", [-1, 1])
def test_the_pipette_s_axis_is_the_base_tangent(polarity):
    from dataclasses import replace

    from pipeline.refine import pipette_axis

    # a tube bent from its base, held in a pipette 0.6 of its width, both along 0.3 rad
    angle, kappa, hw = 0.3, 1 / 250, 12.0
    base = 300 - 300j
    img = tube_image(SHAPE, base, angle, 300.0, kappa, hw, polarity=polarity, noise=0.01,
                     pipette_half_width=0.6 * hw)
    z, _ = arc_axis(base, angle, 300.0, kappa)
    look = TubeLook(polarity, np.full(5, hw), 0.05)
    for lean, aside in ((np.radians(1.5), 0.0), (np.radians(-0.8), 2.5)):
        # a base tangent leaning into the bend, as fitted to a bent tube, and a
        # base beside the axis
        curve = replace(fit_to_polyline(z, angle, n_coef=12), base_angle=angle + lean,
                        base=base + 1j * np.exp(1j * angle) * aside)
        direction, on_axis = pipette_axis(img, curve, look)
        assert abs(np.degrees(direction - angle)) < 0.05
        assert abs(on_axis - base) < 0.1
    # pairs behind the base on a line 4 px (a third of a half-width) aside of the
    # tube's: not its pipette's (a tube refracted aside inside a thick glass):
    # their direction is taken, the base stays on the tube
    aside_img = tube_image(SHAPE, base, angle, 300.0, kappa, hw, polarity=polarity, noise=0.01,
                           pipette_half_width=0.6 * hw, pipette_offset=4.0)
    curve = fit_to_polyline(z, angle, n_coef=12)
    direction, on_axis = pipette_axis(aside_img, curve, look)
    assert abs(np.degrees(direction - angle)) < 0.05
    assert on_axis == curve.base
    # no pipette in view: no axis
    bare = tube_image(SHAPE, base, angle, 300.0, kappa, hw, polarity=polarity, noise=0.01)
    assert pipette_axis(bare, fit_to_polyline(z, angle, n_coef=12), look) is None


@pytest.mark.parametrize("polarity", [-1, 1])
def test_a_holder_wider_than_the_tube_gives_the_base_tangent_s_direction(polarity):
    from dataclasses import replace

    from pipeline.refine import pipette_axis

    # a tube bent from its base, held in a clamp 2.5 times its width and as dark
    # (or bright) as the tube, both along 0.3 rad; the tube sits 4 px off the
    # clamp's midline
    angle, kappa, hw = 0.3, 1 / 250, 9.0
    base = 300 - 300j
    z, _ = arc_axis(base, angle, 300.0, kappa)
    look = TubeLook(polarity, np.full(5, hw), 0.05)
    for offset in (0.0, 4.0):
        img = tube_image(SHAPE, base, angle, 300.0, kappa, hw, polarity=polarity,
                         noise=0.01, pipette_half_width=2.5 * hw, pipette_contrast=1.0,
                         pipette_offset=offset)
        for lean in (np.radians(1.5), np.radians(-0.8)):
            # a base tangent leaning into the bend, as fitted to a bent tube
            curve = replace(fit_to_polyline(z, angle, n_coef=12), base_angle=angle + lean)
            direction, on_axis = pipette_axis(img, curve, look)
            assert abs(np.degrees(direction - angle)) < 0.05
            # the tube need not sit on the clamp's midline: the base stays
            assert on_axis == curve.base


def test_locate_base_carries_a_curled_tube_back_without_moving_the_rest_of_it():
    """A curve starting 9 px into a tube curled 300 deg: the base is carried
    back along its axis to the pipette, and the curve past it stays where it
    is. (Shifting the whole curve back took the tip 9 px off the tube, and
    the next fit, starting that far off, slid off the curl.)"""
    kappa = np.radians(300.0) / 450.0
    img = tube_image(SHAPE, BASE, 0.0, 450.0, kappa, 12.0, pipette_half_width=6.0)
    z, _ = arc_axis(BASE, 0.0, 450.0, kappa)
    s = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(z)))])
    ahead = z[s >= 9.0]
    moved = fit_to_polyline(ahead, float(np.angle(ahead[1] - ahead[0])), n_coef=16)
    look = TubeLook(-1, np.full(9, 12.0), 0.05)
    found = locate_base(img, moved, look)
    # carried back along the curve's tangent at its start, 6 deg off the axis
    assert abs(found.base - BASE) < 1.5
    assert abs(found.length - 450.0) < 1.5
    assert abs(tip_point(found) - z[-1]) < 1.0
