"""A holder taken for the tube's base stretch, told apart over the video.

One frame cannot always tell a pipette from the tube it holds: a glass
capillary shows as two dark lines about as far apart as the tube's edges, a
wider one may show the tube inside it, a dark band may be no wider than the
tube. The detector then runs the tube on into the holder, to the border, and
every frame's base, length and centreline carry the holder with them (the bend
angle does not: the tube leaves the holder along its axis).

The video tells. The tube bends; its holder does not move. So when the
stretch from the tracked base over which every well-bent frame lies on the
first frame's centreline is long (several tube widths), it is looked at:

- in the first frame: if the profiles across it step at one place (glass to
  tube, band to tube) by far more than their own scatter, and a steady trend
  along it (a shading, a taper) does not explain them as well, that place is
  where the tube leaves the holder;
- else in the bent frames: a tube clamped at ``s0`` leaves the line it lay on
  by ``κ(s − s0)²/2``. Fitted to every bent frame, ``s0`` is where the tube
  leaves the holder when it fits far better than the tracked base does (a
  holder of the tube's own look, a tapered glass whose profiles change
  steadily).

Where the motion does not tell (a stage that drifts carries the holder with
it; a tube bent too little for its own base stretch to leave its line; a fit
that wobbles inside the glass), the profiles alone are looked at along most of
the tube: the farthest step of theirs (each against the tube's profile just
past it) before which the stretch kept its shape on the frames, shifts aside
(:func:`rigid_wobble`), and, where frames bent far, bent as a tube clamped
there would (far better than one clamped at the tracked base: a short first
section of other walls keeps its shape nearly as well).

Every frame's centreline is then cut there, its base tangent the holder's
axis: the tube's own direction past it where it runs straight on the first
frame (:func:`holder_axis`). Not run where the base is given
(``--base``). A tube's own base stretch, free, moves off the first frame's
line once it bends (by κs²/2); on a thin or little-bent tube it may stay within
a pixel for a few widths, and the hinge fit then finds it at the tracked base.
"""

from __future__ import annotations

import warnings
from dataclasses import replace
from functools import cache

import numpy as np
from scipy.ndimage import gaussian_filter1d, map_coordinates

from .centreline import Curve, angle_coef, basis_of, cut_base, evaluate, make_basis, resample
from .profiles import sample_lines
from .segment import EDGES_BEGIN, HOLDER_STEP, PIPETTE_STEP
from .track import FrameTrack

#: Frames bent at least this much (deg) away from the first frame's bend tell
#: the static stretch (a tube held bent, the same on every frame, tells none:
#: all of it stands still).
MIN_BEND_DEG = 45.0
#: A point stays on the first frame's centreline within this (px, at least;
#: and a fifth of the tube's half-width).
STILL_PX = 1.0
#: The stretch that stood still must be at least this many tube widths long ...
MIN_WIDTHS = 2.0
#: ... but the holder's end within it (the profiles' step from the holder to
#: the tube, or the hinge the bent frames fit) is looked for from this many
#: on: the fit may have run on into the holder by less than :data:`MIN_WIDTHS`
#: (23 px, 1.6 widths, into an independent scene's glass; a glass 1.99 widths
#: long before a tube 85 px wide, whose hinge the bent frames told to 3.5 px),
#: and the profiles' step tells the holder where the motion cannot.
STEP_WIDTHS = 1.0
#: Where the start was found at a holder's width step (the tracked structure
#: begins at its mouth), a holder's end found within this many tube widths of
#: the tracked base is that mouth's own shading or end face, and nothing is
#: cut: an independent renderer's capillary and tapered pipette, the start at
#: their mouths, had 8 and 16 px of tube cut (then moved 10 px on along the
#: axis), the bases 18.5 and 27 px into the tube on every frame. (A long
#: oblique holder whose step the start found at its far end: cut 4.4 widths
#: on, as it must be.) Nor is a stretch cut there that the motion alone told
#: (no profile step): a tube whose first section does not bend stands as
#: still as a holder (the same capillary's tube: its first 128 px, 30 %).
#: (So too where the start was found where the tube's edges begin past a
#: faint pipette the mask ran on into: an independent renderer's opaque tube
#: had its first 1 px "cut", its base moved 1.6 px on.)
AT_STEP_WIDTHS = 1.5
#: ... unless the profiles step there by this much at least (a material's
#: change, not a section's) a width or more from the start and the stretch
#: stood still: a faint glass band as wide as the tube, the start found 19 px
#: into it (the mask's pipette step; the tube's edges taken on along the
#: glass), its profiles stepping 60x their scatter at the mouth, 17.6 px in.
SURE_CHANGE = 40.0
#: The tube beyond it must keep at least this share of the length tracked. A
#: holder may cross much of the frame before the tube: an independent
#: renderer's pipette over half a 1280 px frame, before 90 px of tube (13 %);
#: at 0.4 it was not looked for and the base was put at the border, 595 px off.
#: (0.1 moved nothing else on 139 scenes of four renderers.)
MIN_TUBE_SHARE = 0.1
#: A frame's tube beyond the holder's end must be within this share of the
#: first frame's (an inflated tube lengthens by a few %: 1.2 % at most over 232
#: rendered scenes); else that frame found something else beyond the holder.
LENGTH_OFF = 0.3
#: The change in the profiles at the holder's end, at least: the mean squared
#: difference of the holder's last two widths' mean profile from the tube's,
#: over the tube's scatter about its own (see :func:`profile_change`; a tube's
#: profiles along a stretch of one look: about 1; holders measured on two
#: independent renderers' scenes, glass capillaries tapered or not, wide
#: glass, blocks: 14-550).
MIN_CHANGE = 7.0
#: ... and a straight trend along the holder with the tube's own profile past
#: it must fit the profiles this much better (residual sum of squares) than
#: one straight trend along the whole stretch: a shading changes the tube's
#: profiles too, but steadily (a linear shading: 0.96; the same holders
#: 1.3-22, tapered capillaries at the low end, 1.3-1.8).
STEP_OVER_TREND = 1.2
#: The tube's own profile is the median of this many widths past the stretch
#: searched.
REFERENCE_WIDTHS = 2.0
#: The holder's profiles just before its end must differ from the tube's by at
#: least this (mean squared difference, over the tube's scatter about its own).
HOLDER_CHI2 = 4.0
#: ... and the tube's past it, mostly (their median), from the far tube's by
#: at most this (a drift along the tube, uneven light, stays within it: 1-6).
TUBE_MATCH_CHI2 = 8.0
#: Where the profiles do not step (a tapered glass changes them steadily; a
#: holder of the tube's own look), the bent frames' sideways deviations from
#: the first frame's line are fitted as ``c·max(0, s − s0)²`` (a clamped tube
#: bending at steady curvature), over each frame's stretch until it is this many
#: px off (or half the tube's half-width, if more)...
HINGE_SPAN_PX = 2.0
#: ... and the hinge ``s0`` is taken when it lowers the residual against one at
#: the tracked base by at least this many times the residual variance per point
#: (an F-like statistic: holders gave 3·10^4 to 2·10^6; a tube's own base, 0 on
#: the tests; a stiff first section of the tube 4·10^4, which the spread below
#: tells)...
MIN_HINGE_GAIN = 100.0
#: ... and every bent frame (at least :data:`MIN_HINGE_FRAMES` of them), fitted
#: alone, puts it within this many px (at least; and a quarter of the tube's
#: half-width) of the others: a holder is where it is whatever the bend, while
#: a stiff first section of the tube (it bends, slightly) seems to end earlier
#: the more the tube bends (a section at 1/25 of the rest's curvature: 12 px
#: over the video; holders 1-1.5 px).
HINGE_SPREAD_PX = 2.0
MIN_HINGE_FRAMES = 3
#: The holder's end is looked for this many half-widths past the static
#: stretch: a spline through holder and tube, whose curvature cannot step,
#: leaves the holder's line before the holder ends (an independent
#: renderer's tapered pipette under a tube curling to 500 deg: 5.5
#: half-widths before), and the tube's reference profiles must lie past the
#: halo its end casts in phase contrast (1.4 more).
HOLDER_REACH_HW = 8.0
#: Where the motion does not tell the holder, the stretch before the profiles'
#: step must keep its shape (:func:`rigid_wobble`) to this many of the tube's
#: half-widths (and :data:`STILL_PX`) on this share of the frames at least: a
#: fit may wobble inside the glass on a few (holders on an independent
#: renderer's scenes: 0.005-0.24 half-widths); a tube's own stretch bends with
#: the rest, by κs²/2 (first sections of other walls: 0.41 and 0.43). A stage
#: that drifts bends the stretch too (0.29-0.32: the base is held where it was
#: found), and is left alone.
RIGID_HW = 0.3
WOBBLE_QUANTILE = 0.8
#: ... and the motion looked at there on at most this many frames, spread
#: over the video (those scenes had 14-36) ...
MOTION_FRAMES = 24
#: ... and only where the tube bent by at least this on some frame (deg, from
#: the first frame's bend): a video that does not bend cannot tell a holder
#: from a first section of other walls, whose profiles step too.
PROFILE_MIN_BEND_DEG = 20.0
#: Where the motion cannot tell a holder (a tube bent too little, a holder
#: the camera shakes with it), a stretch at the tracked structure's start
#: (not one the tube lies over further on) whose edges lie at least this
#: many times as far apart as the tube's past it does
#: (:func:`wide_holder_end`): no tube's sections differ by as much (Table 1:
#: at most 1.25, 810 against 650 µm), where glass capillaries the tube is
#: pushed into measured 1.5-1.6 on an independent renderer's scenes (the
#: detection's mask, read off a threshold, gave them 1.3-1.4) ...
HOLDER_EDGE_RATIO = 1.35
#: ... on this share of its profiles from the structure's start on.
HOLDER_EDGE_SHARE = 0.8
#: A stretch between such a holder's end and a holder's end told further on by
#: the motion is a stiff first section where its edges' span is steady to this
#: (its halves' medians), not a tapered holder narrowing to its tip.
SECTION_STEADY = 0.05
#: An edge there is a peak of the profile's gradient of at least this share
#: of the tube's own edges' (their median over the tube's share of the curve).
HOLDER_EDGE = 0.25
#: The profiles' spacing across the tube, px, and their smoothing (px).
EDGE_STEP_PX = 0.5
EDGE_SMOOTH_PX = 1.0
#: ... and the tube's edges' strength from every this many px past the first part.
FAR_STRIDE = 4
#: The tube past the holder, from this many of its half-widths past the
#: holder's end on (and as far short of its own end), gives the holder's axis
#: where it turns by at most
#: :data:`STRAIGHT_DEG` along its length (:func:`holder_axis`).
AXIS_CLEAR_HW = 4.0
#: Where it does not run straight, the holder's profiles out to this many
#: half-widths either side are mirrored about their centres
#: (:func:`symmetric_axis`: a capillary up to 4 times the tube's radius), ...
SYMMETRY_HW = 5.0
#: ... their centres looked for within two half-widths of the fit (a fit may
#: wander 12 px off a tapered capillary's axis); a profile's centre counts
#: where its mirror misses by at most this share of its typical candidate's
#: (a relief's profiles are antisymmetric), and not at the search's limit;
#: at least this share of the profiles must count ...
SYMMETRY_CONTRAST = 0.25
SYMMETRY_KEEP = 0.6
#: ... and their centres lie on a line to this (RMS, px: the holders of an
#: independent renderer, 0.01-0.2 px), its direction known to this (deg).
SYMMETRY_LINE_PX = 0.5
SYMMETRY_SE_DEG = 0.2
STRAIGHT_DEG = 2.0
#: Where no centre shows (half of the holder out of the frame), the axis is
#: the direction of the holder's straight edges alone (:func:`edge_axis`),
#: from its end back this many half-widths (at least the holder's stretch of
#: the curve), on each side the line through one of the strong edges (at
#: least EDGE_CANDIDATE of the profile's strongest) of at least
#: EDGE_AXIS_KEEP of the profiles in the frame, to EDGE_AXIS_LINE_PX (RMS,
#: px), its direction known to SYMMETRY_SE_DEG.
EDGE_AXIS_HW = 12.0
EDGE_AXIS_KEEP = 0.6
EDGE_AXIS_LINE_PX = 0.5
EDGE_CANDIDATE = 0.5
#: A fit through a holder and the tube, its curvature smooth, hooks sideways
#: where the edges step from the holder's to the tube's: cut there, its base
#: lay 2-4 px beside the tube's axis (an independent renderer's capillaries,
#: 1.5x the tube's width). The cut curve's first UNHOOK_HW half-widths (at
#: most UNHOOK_SHARE of it) are replaced by the arc of constant curvature that
#: leaves along the holder's axis and meets the fit there, on its tangent
#: (:func:`unhooked`), where that moves the first frame's base at least
#: UNHOOK_MIN_PX aside: elsewhere the fit had no hook to take out, and the
#: arc, which stands for the tube's curvature only on average, would move the
#: base by less than it would add (0.1-0.5 px on an independent renderer's
#: scenes, a tube unbending from a curl).
UNHOOK_HW = 3.0
UNHOOK_SHARE = 0.25
UNHOOK_MIN_PX = 1.0
#: A fit through a holder off the tube's axis, or wider than it, also runs
#: through the holder's end face aslant, and the profiles across it mix the
#: holder's with the tube's: the end found along it lay 2-4 px past the face
#: (an independent renderer's pipettes 1.6x the tube's width, the fit 7 px off
#: the tube's axis inside one; 19 px past it beside a holder 4 px off the
#: tube's axis). So the end is looked for again along the tube's own axis
#: (the first frame's curve cut there and unhooked, carried straight back into
#: the holder) and moved to where the profiles along it step by at least
#: MIN_CHANGE, up to REPLACE_HW half-widths away.
REPLACE_HW = 6.0
#: ... where it is at least MIN_SHIFT_PX away (the search along a curve already
#: on the axis finds the same end to a few hundredths, which would only jitter
#: it). Up to STRAIGHT_HW half-widths, every frame's cut curve is then carried
#: straight on or back along the axis, where a bent frame's tube bends by
#: under a tenth of a pixel (a holder's end 2-4 px off: the bases measured
#: 0.2-0.5 px from the truth, against 0.5-1.8 px cut anew); farther, where
#: its tube may bend by pixels, each frame is cut anew where its curve
#: crosses the end face (the bases 18 -> 0.6 px off on an independent
#: renderer's dark-field scene).
MIN_SHIFT_PX = 0.5
STRAIGHT_HW = 1.0
#: Status of a frame whose centreline does not pass where the holder ends:
#: further than this many half-widths (and 2 px) from where the first frame's
#: does.
OFF_HOLDER_HW = 1.0
OFF_HOLDER = "lost: the tube's start not found at the holder's end"
#: ... and of one whose tube beyond it is far from the first frame's length.
OFF_LENGTH = "lost: the tube beyond the holder far from its length on the first frame"


def _first_and_bent(results: list[FrameTrack]) -> tuple[Curve | None, list[FrameTrack]]:
    """The first ok frame's curve, and the later ok frames bent at least
    :data:`MIN_BEND_DEG` away from it."""
    ok = [r for r in results if r.ok]
    bent = [r for r in ok[1:] if _bent_from(r, ok[0]) >= np.radians(MIN_BEND_DEG)]
    return (ok[0].curve if ok else None), bent


def _bent_from(r: FrameTrack, first: FrameTrack) -> float:
    """How far frame ``r`` has bent away from the ``first`` frame's bend, rad."""
    return abs(r.bend_angle_rad - first.bend_angle_rad)


def static_stretch(results: list[FrameTrack], half_width: float, at_least: float = 0.0
                   ) -> float:
    """Arc length from the tracked base (px) over which every ok frame bent by at
    least :data:`MIN_BEND_DEG` lies on the first ok frame's centreline; 0 when
    no frame bent that far. Looked at only until it falls below ``at_least``."""
    from scipy.spatial import cKDTree

    first, bent = _first_and_bent(results)
    if not bent:
        return 0.0
    _, ref = resample(first, 0.5)
    tree = cKDTree(np.c_[ref.real, ref.imag])
    tol = max(STILL_PX, 0.2 * half_width)
    still = np.inf
    for r in bent:
        s, z = resample(r.curve, 1.0)
        near = s <= min(still, s[-1])
        dist, _ = tree.query(np.c_[z[near].real, z[near].imag])
        off = dist > tol
        # (a frame that keeps all of it keeps it whole: its last point within
        # reach lies up to a resampling step short, which over a long video's
        # bent frames wore a 102 px stretch down to 53, a px a frame)
        still = min(still, float(s[near][np.argmax(off)]) if off.any() else float(s[-1]))
        if still < at_least:
            break
    return still


def rigid_wobble(results: list[FrameTrack], s: float) -> float:
    """How far the first ``s`` px of the ok frames' centrelines move off the
    first ok frame's, once each is shifted to fit it best: the
    :data:`WOBBLE_QUANTILE` quantile over the frames of each frame's largest
    distance, px (0 with fewer than two ok frames).

    A holder keeps its shape, wherever a drifting stage takes it; a tube's
    own stretch bends with the rest."""
    from scipy.spatial import cKDTree

    ok = [r for r in results if r.ok]
    if len(ok) < 2:
        return 0.0
    arc, ref = resample(ok[0].curve, 0.5)
    tree = cKDTree(np.c_[ref.real, ref.imag][arc <= s])
    worst = []
    for r in ok[1:]:
        arc, z = resample(r.curve, 1.0)
        z = z[arc <= s] - (r.curve.base - ok[0].curve.base)
        for _ in range(3):
            # (the shift that best lays it on the first frame's, from the bases')
            _, k = tree.query(np.c_[z.real, z.imag])
            z = z + np.mean(tree.data[k, 0] + 1j * tree.data[k, 1] - z)
        dist, _ = tree.query(np.c_[z.real, z.imag])
        worst.append(float(dist.max()))
    return float(np.quantile(worst, WOBBLE_QUANTILE))


def motion_hinge(results: list[FrameTrack], half_width: float, upto: float
                 ) -> tuple[float, float, float]:
    """Where along the first ok frame's centreline the well-bent frames leave it.

    A tube clamped at ``s0`` and bending at steady curvature κ leaves the line
    it lay on by ``κ·(s − s0)²/2``: every frame bent at least
    :data:`MIN_BEND_DEG` is fitted so, with a curvature of its own and ``s0``
    shared, over its first stretch still within :data:`HINGE_SPAN_PX` (or half
    the half-width) of the line.

    Parameters
    ----------
    results : list of FrameTrack
        The tracked frames, px.
    half_width : float
        The tube's, px.
    upto : float
        Largest ``s0`` looked at, px of arc from the tracked base.

    Returns
    -------
    s0 : float
        Arc length of the first ok frame's centreline where the tube leaves
        it, px (on a 0.5-px grid); 0 without bent frames.
    gain : float
        How much better ``s0`` fits than a hinge at the tracked base: the drop
        in the residual sum of squares over the residual variance per point;
        0 without bent frames.
    spread : float
        How far ``s0`` fitted to each bent frame alone moves with the bend:
        the median of the more bent half of them less that of the less bent
        half, px; infinite with fewer than :data:`MIN_HINGE_FRAMES` bent
        frames.
    """
    from scipy.spatial import cKDTree

    first, bent = _first_and_bent(results)
    if not bent or upto <= 0:
        return 0.0, 0.0, np.inf
    arc, ref, _, normal = _sampled(first, 0.25)
    tree = cKDTree(np.c_[ref.real, ref.imag])
    grid = np.arange(0.0, upto + 0.25, 0.5)
    span = max(HINGE_SPAN_PX, 0.5 * half_width)
    sse = np.zeros((len(bent), grid.size))
    n_points = 0
    for i, r in enumerate(bent):
        _, z = resample(r.curve, 1.0)
        _, k = tree.query(np.c_[z.real, z.imag])
        dev = ((z - ref[k]) * np.conj(normal[k])).real
        far = np.abs(dev) > span
        n = int(np.argmax(far)) if far.any() else dev.size
        s, dev = arc[k[:n]], dev[:n]
        x = np.clip(s[:, None] - grid[None, :], 0.0, None) ** 2
        xx = np.einsum("ij,ij->j", x, x)
        xd = dev @ x
        sse[i] = dev @ dev - np.where(xx > 0, xd**2 / np.maximum(xx, 1e-300), 0.0)
        n_points += n
    total = sse.sum(axis=0)
    best = int(np.argmin(total))
    dof = n_points - len(bent) - 1
    if dof < 1:
        return 0.0, 0.0, np.inf
    var = max(total[best] / dof, 1e-12)
    each = grid[np.argmin(sse, axis=1)]
    if len(bent) < MIN_HINGE_FRAMES:
        return float(grid[best]), float((total[0] - total[best]) / var), np.inf
    # how far the frames' own hinges move with the bend: the more bent half's
    # median against the less bent half's (not their range, which a noisy
    # video's frames widen at random: a dim fluorescent tube's held one 91 px
    # inside its holder, each frame's within 81.5-94 px, the halves' medians
    # 1 px apart, against a stiff first section's hinge moving 12 px)
    first_ok = next(r for r in results if r.ok)
    order = np.argsort([_bent_from(r, first_ok) for r in bent])
    half = len(bent) // 2
    spread = abs(float(np.median(each[order[-half:]]) - np.median(each[order[:half]])))
    return float(grid[best]), float((total[0] - total[best]) / var), spread


def _sampled(curve: Curve, spacing_px: float = 1.0):
    """Arc lengths, points, tangent angles and unit normals ``spacing_px`` apart."""
    n = int(np.ceil(curve.length / spacing_px)) + 1
    basis = basis_of(curve, max(n, 2))
    smp = evaluate(curve, basis)
    return basis.u * curve.length, smp.z, smp.phi, smp.normal


def wide_holder_end(image: np.ndarray, curve: Curve, half_width: float,
                    section_to: float | None = None) -> tuple[float, float] | None:
    """Where a holder wider than the tube ends along ``curve``, and how
    many times the tube's width its edges lie apart.

    Parameters
    ----------
    image : (rows, cols) float ndarray
        The frame ``curve`` was measured on.
    curve : Curve
        The tracked structure's centreline, holder and tube, px (y up).
    half_width : float
        The tube's, px: the profiles span four on each side.
    section_to : float, optional
        Arc length, px, past the holder's end: the stretch from the end to
        there must be a section of the tube, its edges' span steady (the
        medians over its two halves within :data:`SECTION_STEADY` of each
        other), not the narrowing end of a tapered holder.

    Returns
    -------
    (s, ratio) or None
        ``s`` the holder's end, px of arc length from the curve's start;
        ``ratio`` its edges' distance over the tube's (median). None where
        the curve's first stretch shows no such holder (see
        :data:`HOLDER_EDGE_RATIO`).

    Notes
    -----
    Each profile across the curve (to four half-widths on each side) is
    reduced to its edges, the peaks of its gradient, and their span (the
    outermost two's distance). The holder ends at a step down in the span
    (its median over a tube width before against after) along the curve's
    first part (the tube's share, :data:`MIN_TUBE_SHARE`, left past it): the
    largest before which the span is :data:`HOLDER_EDGE_RATIO` times the
    tube's width (the span over the two widths past the step) or more on
    :data:`HOLDER_EDGE_SHARE` of the profiles from the structure's start."""
    arc, z, _, normal = _sampled(curve)
    k = max(2, int(round(2 * half_width)))      # a tube width, in profiles 1 px apart
    last = int(np.searchsorted(arc, (1.0 - MIN_TUBE_SHARE) * curve.length))
    far = np.flatnonzero(arc > (1.0 - MIN_TUBE_SHARE) * curve.length)[::FAR_STRIDE]
    if far.size < 4 or last - k <= MIN_WIDTHS * k:
        return None
    # (the profiles over the first part, one per px, and every few px of the
    # tube's share beyond for its edges' strength)
    rows = np.concatenate([np.arange(min(last + 2 * k, arc.size)), far])
    d = np.arange(-4.0 * half_width, 4.0 * half_width + 0.5 * EDGE_STEP_PX, EDGE_STEP_PX)
    pts = z[rows, None] + normal[rows, None] * d[None, :]
    prof = map_coordinates(image, [-pts.imag.ravel(), pts.real.ravel()], order=1,
                           mode="nearest").reshape(pts.shape)
    grad = np.abs(np.gradient(gaussian_filter1d(prof, EDGE_SMOOTH_PX / EDGE_STEP_PX, axis=1),
                              EDGE_STEP_PX, axis=1))
    n = rows.size - far.size
    tail = grad[n:]
    own = np.minimum(np.where(d < 0, tail, 0).max(1), np.where(d > 0, tail, 0).max(1))
    floor = HOLDER_EDGE * float(np.median(own))
    # edges: the gradient's local maxima above the floor; the span, the
    # outermost two's distance (NaN with fewer than two)
    g = grad[:n]
    peak = np.zeros(g.shape, bool)
    peak[:, 1:-1] = (g[:, 1:-1] > g[:, :-2]) & (g[:, 1:-1] >= g[:, 2:]) & (g[:, 1:-1] >= floor)
    first = np.argmax(peak, axis=1)
    final = d.size - 1 - np.argmax(peak[:, ::-1], axis=1)
    span = np.where(peak.sum(axis=1) >= 2, d[final] - d[first], np.nan)
    windows = np.lib.stride_tricks.sliding_window_view(span, k)
    with warnings.catch_warnings():
        # (a window without edges has no median: NaN, never the step)
        warnings.simplefilter("ignore", RuntimeWarning)
        level = np.nanmedian(windows, axis=1)
    at = np.arange(int(MIN_WIDTHS * k), last - k)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = level[at - k] / level[at]
    # the steps down, largest first, each a width from the larger ones: the
    # holder's is the largest whose stretch before it is all wide (a scratch
    # across the tube further on widens its edges' span over a width or so,
    # and steps down by more: 2.0x, against the clear pipette's 1.5x)
    order = [int(i) for i in np.argsort(-np.where(np.isfinite(ratio), ratio, -np.inf),
                                        kind="stable")
             if ratio[i] >= HOLDER_EDGE_RATIO]
    tried: list[int] = []
    for i in order:
        j = int(at[i])
        if any(abs(j - t) <= k for t in tried):
            continue
        tried.append(j)
        # (the medians step over half a window: the step itself is the first
        # profile past there narrower than halfway between the two)
        half = 0.5 * (level[j - k] + level[j])
        narrow = np.flatnonzero(span[j:j + k] < half)
        j += int(narrow[0]) if narrow.size else 0
        past = span[j:j + 2 * k]
        if np.isnan(past).mean() > 0.5:
            continue
        width = float(np.nanmedian(past))
        wide = span[:j] >= HOLDER_EDGE_RATIO * width
        if width > 0 and wide.mean() >= HOLDER_EDGE_SHARE:
            break
    else:
        return None
    s_end = float(arc[j])
    if section_to is not None:
        stretch = span[j + k // 2:min(int(np.searchsorted(arc, section_to)) - k // 2, span.size)]
        halves = np.array_split(stretch, 2)
        if stretch.size < 2 * k or any(np.isnan(h).mean() > 0.5 for h in halves):
            return None
        first_half, second_half = (float(np.nanmedian(h)) for h in halves)
        if abs(first_half / second_half - 1.0) > SECTION_STEADY:
            return None
    # (not where the tube lies over itself: a coil over the base is a wider
    # structure too; the rest: farther along than a half turn of that reach)
    reach = 4 * half_width
    stretch, rest = z[arc <= s_end], z[arc > s_end + np.pi * reach]
    if rest.size and np.abs(stretch[:, None] - rest[None, :]).min() < reach:
        return None
    return s_end, float(np.nanmedian(span[:j][wide]) / width)


def profile_change(image: np.ndarray, curve: Curve, half_width: float, upto: float, *,
                   match_tube: bool = True, no_trend: bool = True
                   ) -> tuple[float, float]:
    """Where along ``curve``'s first ``upto`` px the holder ends and the tube's
    own profile begins, and by how much the profiles change there.

    The tube looks the same all along (across it, one profile); a holder need
    not (a tapered glass widens steadily away from the tube). So the tube's
    profile is taken from the :data:`REFERENCE_WIDTHS` widths past ``upto``
    (tube, whatever the holder), each profile's mean squared difference from
    it is measured in units of the tube's own scatter about it, and the
    holder ends where that difference drops most sharply (by the ratio of its
    means over a half-width either side), from at least :data:`HOLDER_CHI2`
    before; placed, to a fraction of a pixel, at the steepest fall of that
    difference just before (:func:`_end_edge`). Past it, the profiles must
    mostly match the far tube's (:data:`TUBE_MATCH_CHI2`).

    Parameters
    ----------
    image : (rows, cols) float ndarray
        The frame ``curve`` was measured on.
    curve : Curve
        px (y up).
    half_width : float
        The tube's, px: the profiles span three on each side.
    upto : float
        Arc length searched, px; the first profile like the tube's past the
        change is at least :data:`STEP_WIDTHS` tube widths from the base (the
        change itself, the blurred edge before it, up to two half-widths
        nearer: :func:`_end_edge`).
    match_tube : bool
        Whether the profiles past the change must be the far tube's (see
        ``change`` below); without, a holder already told is only placed.
    no_trend : bool
        Whether the change must be no steady trend's (see ``change``).

    Returns
    -------
    s : float
        Arc length of the holder's end, px; 0 when the curve is too short
        for the search and its reference.
    change : float
        The mean squared difference between the holder's last
        :data:`MIN_WIDTHS` widths' mean profile and the tube's, over the
        tube's scatter (per sample). 0 where no profile differs from the
        tube's by :data:`HOLDER_CHI2`; where those past the change do not
        match the far tube's (:data:`TUBE_MATCH_CHI2`: a section of other
        walls); and where a straight trend along the whole stretch fits the
        profiles nearly as well as a trend along the holder with the tube's
        one profile past it (:data:`STEP_OVER_TREND`: a shading).
    """
    s, z, _, normal = _sampled(curve)
    width_px = 2 * half_width
    k_min = int(np.ceil(MIN_WIDTHS * width_px))
    k_step = int(np.ceil(STEP_WIDTHS * width_px))
    n = min(int(np.floor(upto)) + 1, s.size)
    n_ref = min(int(np.ceil(REFERENCE_WIDTHS * width_px)), s.size - n)
    if n - k_min < 3 or n_ref < max(8, 0.5 * REFERENCE_WIDTHS * width_px):
        return 0.0, 0.0
    off = np.arange(-3.0 * half_width, 3.0 * half_width + 0.25, 0.5)
    pts = z[:n + n_ref, None] + normal[:n + n_ref, None] * off[None, :]
    prof = map_coordinates(image, [-pts.imag, pts.real], order=1, mode="nearest")
    ref = prof[n:]
    tube = np.median(ref, axis=0)
    # (medians: dust or a bubble on a few of the reference's profiles)
    scatter = max(float(np.median(np.mean((ref - tube) ** 2, axis=1))), 1e-12)
    dev = np.mean((prof[:n] - tube) ** 2, axis=1) / scatter
    # the holder ends where the profiles' difference from the tube's drops most
    # sharply, as a ratio of its means over a half-width either side: a slow
    # drift along the tube (uneven light, a taper) changes it by little over
    # that reach, the holder's end by 10-40 times
    w = max(int(round(half_width)), 3)
    c = np.r_[0.0, np.cumsum(dev)]
    k = np.arange(max(k_step, w), n - w + 1)
    if not k.size:
        return 0.0, 0.0
    before = (c[k] - c[k - w]) / w
    after = (c[k + w] - c[k]) / w
    ratio = np.where(before >= HOLDER_CHI2, before / np.maximum(after, 1e-12), 0.0)
    at = int(k[np.argmax(ratio)])
    if ratio.max() <= 0.0:
        return float(s[at]), 0.0    # nothing there differs from the tube
    if match_tube and np.median(dev[at:]) > TUBE_MATCH_CHI2:
        # past it the profiles are not the far tube's: a section whose walls
        # differ (a stiff first section that stood still), not a holder's end
        return float(s[at]), 0.0
    if no_trend:
        # a shading along the tube changes its profiles steadily too: a straight
        # trend along the stretch about the change (as far before it as the
        # tube, its reference too, reaches past it) then fits as well as one
        # along the holder with the tube's own profile past it. (Over the
        # whole holder, a tapered pipette's profiles, which change unlike
        # any line, outweighed the step at its end: taken for a shading.)
        lo = max(2 * at - len(prof), 0)
        if _a_trend(s[lo:len(prof)], prof[lo:], at - lo):
            return float(s[at]), 0.0
    last = prof[max(at - k_min, 0):at].mean(axis=0)
    return _end_edge(s, dev, at, half_width), float(np.mean((last - tube) ** 2) / scatter)


def _a_trend(s: np.ndarray, prof: np.ndarray, at: int) -> bool:
    """Whether a straight trend along the whole stretch fits the profiles
    ``prof`` (one per arc length ``s``) nearly as well as one along the holder
    (to profile ``at``) with the tube's one profile past it
    (:data:`STEP_OVER_TREND`): a shading, not a holder's end."""
    design = np.c_[np.ones(s.size), s]
    trend, *_ = np.linalg.lstsq(design, prof, rcond=None)
    sse_trend = float(((prof - design @ trend) ** 2).sum())
    held, *_ = np.linalg.lstsq(design[:at], prof[:at], rcond=None)
    sse = float(((prof[:at] - design[:at] @ held) ** 2).sum()
                + ((prof[at:] - prof[at:].mean(axis=0)) ** 2).sum())
    return sse_trend < STEP_OVER_TREND * sse


def _end_edge(s: np.ndarray, dev: np.ndarray, at: int, half_width: float) -> float:
    """Where, before profile ``at`` (the first like the tube's), the profiles'
    difference from the tube's falls most steeply (in amplitude: ``dev`` is
    squared): the blurred edge of the holder's end. Profile ``at`` lies out
    in that edge's tail, 1-2 px past it, or further where the holder's end
    casts a halo onto the tube (phase contrast: a tail 12 px long, its
    half-way point 9 px past the glass's end)."""
    amp = np.sqrt(np.maximum(dev, 0.0))
    w = max(int(round(half_width)), 3)
    lo = max(at - 2 * w, 1)
    hi = min(at + 2, amp.size)
    if hi - lo < 4:
        return float(s[at])
    # (the drop between neighbouring profiles, 1 px apart, up to the one into
    # ``at``: the steepest of those after which, within a half-width, the
    # difference has fallen half-way to the tube's own level: a holder's end,
    # not a feature along the holder (the end of a tube inside the glass:
    # 25 -> 14 there, 13 -> 1.5 at the glass's end); placed to a fraction of
    # a profile by a parabola through it and its neighbours)
    drop = amp[lo - 1:hi - 1] - amp[lo:hi]
    floor = float(np.median(amp[at:at + w])) if at < amp.size else 0.0
    ends = np.array([amp[lo + i:lo + i + w + 1].min() - floor
                     <= 0.5 * (amp[lo + i - 1] - floor) for i in range(drop.size)])
    ends[[0, -1]] = False
    if not ends.any():
        return float(s[at])
    j = int(np.argmax(np.where(ends, drop, -np.inf)))
    y0, y1, y2 = drop[j - 1], drop[j], drop[j + 1]
    den = y0 - 2 * y1 + y2
    frac = float(np.clip(0.5 * (y0 - y2) / den, -0.5, 0.5)) if den < 0 else 0.0
    # (drop[j] lies between profiles lo + j - 1 and lo + j)
    pos = lo + j - 0.5 + frac
    k = int(np.floor(pos))
    return float(s[k] + (s[min(k + 1, s.size - 1)] - s[k]) * (pos - k))


def axis_angle(curve: Curve, s: float) -> float:
    """The mean tangent angle over the middle half of ``curve``'s first ``s`` px, rad."""
    arc, _, phi, _ = _sampled(curve, 0.5)
    return float(np.mean(phi[(arc >= 0.25 * s) & (arc <= 0.75 * s)]))


def holder_axis(curve: Curve, s: float, half_width: float,
                image: np.ndarray | None = None) -> float:
    """The axis of a holder whose end is ``s`` px along ``curve`` (the
    first frame's, on ``image``), rad.

    The tube's own direction where it runs straight on past the holder (a
    tube leaves its holder along the holder's axis, and its straight stretch,
    long and clear of the holder, tells that better than a fit through the
    holder, which may wobble by degrees where the glass and the tube inside it
    change). Else, a bent tube: the line through the holder's own centres of
    symmetry (:func:`symmetric_axis`), where it is a line; else the fit's
    mean direction through the holder (:func:`axis_angle`).
    """
    arc, _, phi, _ = _sampled(curve, 0.5)
    # (clear of the holder's end and of the tube's: a fit's end wanders)
    past = phi[(arc >= s + AXIS_CLEAR_HW * half_width)
               & (arc <= curve.length - AXIS_CLEAR_HW * half_width)]
    if past.size >= 4 * half_width and np.ptp(past) <= np.radians(STRAIGHT_DEG):
        return float(np.mean(past))
    axis = None if image is None else holder_line(image, curve, s, half_width)
    return axis_angle(curve, s) if axis is None else axis


def holder_line(image: np.ndarray, curve: Curve, s: float, half_width: float
                ) -> float | None:
    """The axis of the holder ``curve``'s first ``s`` px run through, rad: the
    line of its profiles' centres of symmetry (:func:`symmetric_axis`), or of
    its edges (:func:`edge_axis`); None where neither is a line."""
    for way in (symmetric_axis, edge_axis):
        axis = way(image, curve, s, half_width)
        if axis is not None:
            return axis
    return None


def _direction_known(rms: float, n: int, span: float) -> bool:
    """Whether a line through ``n`` points ``rms`` px off it, spanning
    ``span`` px along it, has its direction to :data:`SYMMETRY_SE_DEG` (its
    slope's standard error)."""
    return bool(rms * np.sqrt(12.0 / n) <= np.radians(SYMMETRY_SE_DEG) * max(span, 1e-9))


def edge_axis(image: np.ndarray, curve: Curve, s: float,
              half_width: float) -> float | None:
    """The axis of the holder whose end is ``s`` px along ``curve``, rad,
    from its edges alone: the line of each side's strongest edge on profiles
    across the holder, from its end back along the fit's mean direction
    through it (:data:`EDGE_AXIS_HW`); a pipette's walls and the tube inside
    it all run along its axis. Where both sides' edges lie on lines, their
    mean direction; one side's where only one does (the other out of the
    frame: a pipette along the frame's border, a fit through it 5 deg off);
    None where neither does (:data:`EDGE_AXIS_KEEP`,
    :data:`EDGE_AXIS_LINE_PX`).

    Parameters as :func:`symmetric_axis`.
    """
    arc, z, _, _ = _sampled(curve, 0.5)
    end = complex(np.interp(s, arc, z.real), np.interp(s, arc, z.imag))
    ahead = np.exp(1j * axis_angle(curve, s))
    behind = np.arange(half_width, max(s, EDGE_AXIS_HW * half_width), 1.0)
    if behind.size < 8:
        return None
    stations = end - behind * ahead
    normal = 1j * ahead
    reach = SYMMETRY_HW * half_width
    off = np.arange(-reach, reach + EDGE_STEP_PX / 2, EDGE_STEP_PX)
    prof = sample_lines(image, stations, normal, off)
    grad = np.abs(np.gradient(prof, EDGE_STEP_PX, axis=1))
    directions = []
    for side in (off < 0, off > 0):
        g = grad[:, side]
        # (profiles mostly in the frame: the holder runs on out of it)
        seen = np.isfinite(g).mean(axis=1) >= 0.5
        if seen.sum() < 8:
            continue
        line = _edge_line(stations[seen], normal, off[side], g[seen])
        if line is None or line[1] < EDGE_AXIS_KEEP * seen.sum():
            continue
        d, kept, rms, span = line
        if not _direction_known(rms, kept, span):
            continue
        directions.append(d if (d * np.conj(ahead)).real > 0 else -d)
    if not directions:
        return None
    return float(np.angle(np.mean(directions)))


def _edge_line(stations: np.ndarray, normal: complex, off: np.ndarray, grad: np.ndarray
               ) -> tuple[complex, int, float, float] | None:
    """The line through one strong edge of most profiles: its direction, how
    many profiles it passes within :data:`EDGE_AXIS_LINE_PX` of one of their
    edges, those edges' RMS distance from it (their line fitted) and their
    span along it (px); None where no line passes that near three.

    ``stations`` (N,) are the profiles' centres, px (y up), sampled at
    ``off`` px along ``normal``; ``grad`` (N, M) their gradient magnitude.
    A profile's edges are its gradient's local maxima of at least
    :data:`EDGE_CANDIDATE` of its strongest. A glass wall shows two edges of
    about one strength: the strongest alone hops between them, and no one
    line went through those (a pipette along a frame's border: its axis left
    to a fit through it, 6 deg off, on the mirror image of a scene whose
    edges had passed). The line is the one through an edge of a first-
    quarter and an edge of a last-quarter profile that most profiles pass.
    """
    g = np.where(np.isfinite(grad), grad, -np.inf)
    peak = np.zeros(g.shape, bool)
    peak[:, 1:-1] = (g[:, 1:-1] > g[:, :-2]) & (g[:, 1:-1] >= g[:, 2:])
    peak &= g >= EDGE_CANDIDATE * g.max(axis=1, keepdims=True)
    row, col = np.nonzero(peak)
    if row.size < 3:
        return None
    pts = stations[row] + normal * off[col]
    n = stations.size
    first = np.flatnonzero(row < n // 4)
    last = np.flatnonzero(row >= n - n // 4)
    if not first.size or not last.size:
        return None
    a, b = pts[first][:, None], pts[last][None, :]
    u = (b - a) / np.maximum(np.abs(b - a), 1e-9)
    # (each candidate line's distance to every edge; a profile passed where
    # the nearest of its edges lies within reach)
    dist = np.abs(((pts[None, None, :] - a[..., None]) * np.conj(u[..., None])).imag)
    # (the edges come row by row: each profile's nearest, per line, at once)
    starts = np.flatnonzero(np.r_[True, row[1:] != row[:-1]])
    passed = (np.minimum.reduceat(dist, starts, axis=-1) <= EDGE_AXIS_LINE_PX).sum(axis=-1)
    i, j = np.unravel_index(int(np.argmax(passed)), passed.shape)
    if passed[i, j] < 3:
        return None
    # (the edges it passes, one per profile - its nearest, the first of a tie -
    # their line fitted)
    order = np.lexsort((dist[i, j], row))
    nearest = order[np.flatnonzero(np.r_[True, row[order][1:] != row[order][:-1]])]
    xy = pts[nearest[dist[i, j, nearest] <= EDGE_AXIS_LINE_PX]]
    centre = xy.mean()
    _, _, vt = np.linalg.svd(np.c_[(xy - centre).real, (xy - centre).imag], full_matrices=False)
    d = complex(vt[0, 0], vt[0, 1])
    resid = ((xy - centre) * np.conj(d)).imag
    rms = float(np.sqrt(np.mean(resid**2)))
    if rms > EDGE_AXIS_LINE_PX:
        return None
    along = ((xy - centre) * np.conj(d)).real
    return d, int(xy.size), rms, float(np.ptp(along))


def symmetric_axis(image: np.ndarray, curve: Curve, s: float,
                   half_width: float) -> float | None:
    """The axis of the holder along ``curve``'s first ``s`` px, rad: the line
    through the centres about which its profiles (across ``curve``, out to
    :data:`SYMMETRY_HW` half-widths) are most nearly mirror images; a glass
    capillary, a band and the tube inside them are symmetric about it, and
    a fit through them may wander by several px (12 px inside a tapered
    capillary). None where too few profiles show a centre, or their centres
    do not lie on a line (:data:`SYMMETRY_LINE_PX`, :data:`SYMMETRY_SE_DEG`).

    Parameters
    ----------
    image : (rows, cols) float ndarray
        The frame ``curve`` was measured on.
    curve : Curve
        px (y up).
    s : float
        The holder's length along ``curve``, px.
    half_width : float
        The tube's, px.
    """
    arc, z, phi, normal = _sampled(curve, 1.0)
    # (every other px along: the line needs no more)
    sel = np.flatnonzero((arc >= 0.1 * s) & (arc <= 0.9 * s))[::2]
    if sel.size < 8:
        return None
    step = 0.25
    reach = SYMMETRY_HW * half_width
    wide = 2.0 * half_width                     # the centres looked for
    off = np.arange(-reach - wide, reach + wide + step / 2, step)
    # (off the frame: NaN; a profile that leaves it is judged on the pairs it
    # keeps)
    prof = sample_lines(image, z[sel], normal[sel], off)
    k = np.arange(0, int(reach / step) + 1, 2)          # t = k·step, 0.5 px apart
    centre = int(round(wide / step))
    cands = np.arange(-centre, centre + 1) + int(round((reach + wide) / step))
    miss = np.full((sel.size, cands.size), np.nan)
    for j, c in enumerate(cands):
        pair = (prof[:, c + k] - prof[:, c - k]) ** 2
        enough = np.isfinite(pair).mean(axis=1) >= 0.5
        with np.errstate(all="ignore"):
            miss[enough, j] = np.nanmean(pair[enough], axis=1)
    usable = np.isfinite(miss).any(axis=1)
    best = np.full(sel.size, -1)
    best[usable] = np.nanargmin(miss[usable], axis=1)
    score = np.where(usable, miss[np.arange(sel.size), np.maximum(best, 0)], np.nan)
    typical = np.full(sel.size, np.nan)
    typical[usable] = np.nanmedian(miss[usable], axis=1)
    # a centre at the search's limit is none (a fit further off, a profile not
    # symmetric at all), nor one hardly better than the profile's typical
    # mirror (a relief's antisymmetric profile)
    keep = (usable & (best > 0) & (best < cands.size - 1)
            & (score <= SYMMETRY_CONTRAST * typical))
    if keep.sum() < max(8, SYMMETRY_KEEP * sel.size):
        return None
    centres = z[sel][keep] + normal[sel][keep] * (off[cands[best[keep]]])
    xy = np.c_[centres.real, centres.imag]
    xy = xy - xy.mean(axis=0)
    _, sv, vt = np.linalg.svd(xy, full_matrices=False)
    rms = sv[1] / np.sqrt(xy.shape[0])
    span = float(np.ptp(xy @ vt[0]))
    if rms > SYMMETRY_LINE_PX or not _direction_known(rms, xy.shape[0], span):
        return None
    d = complex(vt[0, 0], vt[0, 1])
    # (pointing from the holder to the tube, as the fit does)
    if (d * np.exp(-1j * np.mean(phi[sel]))).real < 0:
        d = -d
    return float(np.angle(d))


def _profile_holder(ok: list[FrameTrack], image: np.ndarray, half_width: float,
                    least: float) -> tuple[float, float, float | None] | None:
    """A holder's end told by the profiles along the first of the ``ok``
    frames' centrelines, where the motion did not tell it: ``(s, change,
    wobble)``, ``s`` its arc length (px), ``change`` the profiles' step there,
    ``wobble`` how far the stretch before it moved (px; None where it seemed
    to bend and the bent frames' hinge told it instead); None where none.

    The profiles are looked at along most of the tube, ever further, each
    search against the tube's profile just past it (a tube's sections further
    on may have other walls). The farthest step whose stretch keeps its shape
    on the frames is the holder's end (one nearer is a step along the holder,
    a taper's or a shading's); a tube's own section of other walls does not
    keep its shape once it bends."""
    first = ok[0].curve
    reach = (1.0 - MIN_TUBE_SHARE) * first.length
    # (the motion looked at on frames spread over the video, as many as the
    # scenes it was measured on had at most: a long video's first frames'
    # work stays short)
    spread = [ok[k] for k in np.unique(np.linspace(0, len(ok) - 1, MOTION_FRAMES)
                                       .round().astype(int))]
    bent = bool(_first_and_bent(spread)[1])
    rigid = max(STILL_PX, RIGID_HW * half_width)
    found = None
    for upto in np.unique(np.minimum(2 * least * 1.5 ** np.arange(12), reach)):
        at, change = profile_change(image, first, half_width, upto)
        if change < MIN_CHANGE or (found and at <= found[0] + 1.0):
            continue
        wobble = rigid_wobble(spread, at)
        hinge, gain, _ = (motion_hinge(spread, half_width, at + 2 * half_width) if bent
                          else (0.0, 0.0, np.inf))
        if wobble > rigid:
            # this stretch bends (so does every longer one), unless the bent
            # frames leave its line right there, as from a clamp: frames whose
            # base moved along the tube (a restart) shift the stretch compared
            # onto the tube beyond the holder
            if not (gain >= MIN_HINGE_GAIN and abs(hinge - at) <= max(2.0, half_width)):
                break
            found = (at, change, None)
        # where frames bent far, they must also bend as a tube clamped there
        # would, far better than one clamped at the tracked base: a short first
        # section of other walls keeps its shape nearly as well (a 35 px
        # section, 2.7 px; hinge gain 24, holders 577-6800), and clamped at the
        # step: a tube from a clear pipette, its base at the pipette's mouth,
        # bent as one clamped there (the hinge 1 px from the base, gain 1031),
        # and so kept its first, little-curved 16 px, whose profiles stepped
        # into the rest's (78x their scatter)
        elif bent and (gain < MIN_HINGE_GAIN or abs(hinge - at) > max(2.0, half_width)):
            break
        else:
            found = (at, change, wobble)
    return found


def on_first_stage(results: list[FrameTrack]) -> list[FrameTrack]:
    """``results`` with each frame's curves moved back by the stage's drift
    since the first frame (:attr:`FrameTrack.stage_shift`): a drifting stage
    carries the holder, and the base the tracker followed it with, so a holder
    keeps its place only where the stage stood still."""
    origin = results[0].stage_shift if results else 0j
    return [r.moved(origin - r.stage_shift) for r in results]


def unhooked(curve: Curve, reach: float) -> Curve:
    """``curve`` with its first ``reach`` px the arc of constant curvature
    leaving its base along its base tangent that meets it at ``reach``, on its
    tangent there; the base moved to where that arc starts (the points past
    ``reach`` stay where they were).

    Parameters
    ----------
    curve : Curve
        px (y up); its base tangent the holder's axis (:func:`cut_base`).
    reach : float
        px, under the curve's length.
    """
    arc, z, phi, _ = _sampled(curve, 0.25)
    at = complex(np.interp(reach, arc, z.real), np.interp(reach, arc, z.imag))
    turn = float(np.interp(reach, arc, phi)) - curve.base_angle
    start = np.exp(1j * curve.base_angle)
    # (the arc's chord: ∫ exp(i(φ0 + turn·s/reach)) ds over [0, reach])
    chord = (reach * start if abs(turn) < 1e-9
             else reach * start * (np.exp(1j * turn) - 1) / (1j * turn))
    ramp = np.where(arc < reach, curve.base_angle + turn * arc / reach, phi)
    fit = make_basis(curve.coef.size, basis_of(curve).n_grid, curve.joints)
    coef = angle_coef(fit, np.interp(fit.u * curve.length, arc, ramp) - curve.base_angle)
    return replace(curve, base=at - chord, coef=coef)


def drop_holder(results: list[FrameTrack], first_frame, half_width: float,
                px: float = 1.0, frames=None) -> tuple[list[FrameTrack], str | None]:
    """Cut a holder taken for the tube off every frame's centreline.

    The holder is told by the frames' motion (a stretch from the tracked base
    that stood still while the rest bent, :func:`static_stretch`, or the
    hinge the bent frames leave its line at, :func:`motion_hinge`), by the
    profiles along it (:func:`profile_change`), or by edges wider apart than
    the tube's (:func:`wide_holder_end`). Where the first frame's start was
    found at a holder's width step (the tracked structure begins at its
    mouth), only a holder end its profiles show, :data:`AT_STEP_WIDTHS` or
    more from the tracked base, is cut.

    Parameters
    ----------
    results : list of FrameTrack
        The tracked frames, px of the first frame.
    first_frame : callable
        Returns the first frame, (rows, cols) float ndarray: read only where
        a holder is looked for along the profiles (a stretch from the base
        stood still, or the frames bent) and to take a holder's axis.
    half_width : float
        The tube's half-width, px.
    px : float
        Full-frame pixels per pixel of the frames (binning), for the note.
    frames : iterable of (rows, cols) ndarray, optional
        The frames again, first to last, as tracked: once a holder is cut,
        its mouth's region is registered on each (:func:`_mouth_drift`).

    Returns
    -------
    results : list of FrameTrack
        The same frames, their curves (and fits) cut where the tube leaves the
        holder, their base tangent the holder's axis; a frame whose centreline
        does not pass the holder's end is marked :data:`OFF_HOLDER`, one whose
        tube beyond it is more than :data:`LENGTH_OFF` off the first frame's
        length :data:`OFF_LENGTH`.
    note : str or None
        A line for the run's notes when a holder was cut off.
    """
    if not results or not results[0].ok:
        return results, None
    first_frame = cache(first_frame)      # (read once, where needed at all)
    least = MIN_WIDTHS * 2 * half_width
    origin = results[0].stage_shift
    results = on_first_stage(results)
    still = static_stretch(results, half_width, least)
    first = results[0].curve
    told = None
    # (a holder's end told by its profiles may lie nearer the tracked base than
    # ``least``: see STEP_WIDTHS)
    profiled = True
    # (whether its profiles step at the holder's end, however it was found)
    stepped = False
    change = 0.0
    if still >= least:
        s, change = profile_change(first_frame(), first, half_width,
                                   still + HOLDER_REACH_HW * half_width)
        told = (f"the tracked structure's first {s * px:.0f} px stood still on every frame "
                f"while the rest bent, and its profile stepped there by {change:.0f}x its "
                "scatter" if change >= MIN_CHANGE else None)
        if told is None:
            profiled = False
            # (a hinge at the end of the stretch searched may lie beyond it: a
            # thin pipette 53 px long whose fit stood still for only 21 px
            # had its hinge put at the search's end, 28 px)
            s, gain, spread = motion_hinge(results, half_width, still + 2 * half_width)
            if (gain >= MIN_HINGE_GAIN and spread <= max(HINGE_SPREAD_PX, 0.25 * half_width)
                    and s <= still + half_width):
                told = (f"the tracked structure's first {s * px:.0f} px stood still on every "
                        "frame while the rest bent, and the bent frames leave its line there "
                        "as a tube clamped there would")
    ok = [r for r in results if r.ok]
    moved = (len(ok) >= MIN_HINGE_FRAMES
             and max(_bent_from(r, ok[0]) for r in ok) >= np.radians(PROFILE_MIN_BEND_DEG))
    if told is not None and not profiled and moved:
        # the bent frames' hinge tells the holder; where the profiles along it
        # step within a half-width of there, they place its end (to a pixel:
        # the hinge put it 1.5 px short of a pipette's end the profiles found)
        found = _profile_holder(ok, first_frame(), half_width, least)
        if found is not None and abs(found[0] - s) <= half_width:
            s, stepped = found[0], True
            told += (f"; its end placed where the profiles along it stepped by "
                     f"{found[1]:.0f}x their scatter")
    if told is None and moved:
        # the motion did not tell (a stage that drifts carries the holder with
        # it; a tube bent too little; a fit that wobbles inside the glass)
        found = _profile_holder(ok, first_frame(), half_width, least)
        if found is not None:
            (s, change, wobble), stepped = found, True
            kept = ("the bent frames leave its line there as a tube clamped there would"
                    if wobble is None else f"that stretch kept its shape on the frames (to "
                    f"{wobble * px:.1f} px, its drift aside)")
            told = (f"the profiles along the tracked structure stepped by {change:.0f}x "
                    f"their scatter {s * px:.0f} px from its start, and {kept}")
    # the motion did not tell, or could not (a tube bent too little, a holder
    # the camera shakes): a stretch at the structure's start whose edges lie
    # wider apart than any section's tells it. Where the motion told a holder
    # ending further on, a stiff first section (that stood still, its profile
    # stepping at the joint) lies in a wider holder's edges ending first
    found = wide_holder_end(first_frame(), first, half_width,
                            section_to=None if told is None else s)
    if found is not None and (told is None or found[0] < s - STEP_WIDTHS * 2 * half_width):
        s, ratio = found
        at, change = profile_change(first_frame(), first, half_width,
                                    s + HOLDER_REACH_HW * half_width)
        placed = change >= MIN_CHANGE and abs(at - s) <= half_width
        s = at if placed else s
        profiled = True
        told = (f"the tracked structure's first {s * px:.0f} px had its edges {ratio:.2f}x "
                "as far apart as the tube's past them"
                + (f", and its profiles stepped there by {change:.0f}x their scatter"
                   if placed else ""))
    if (told is None or (s < STEP_WIDTHS * 2 * half_width and not profiled)
            or first.length - s < MIN_TUBE_SHARE * first.length
            or (results[0].base_source.startswith((HOLDER_STEP, PIPETTE_STEP, EDGES_BEGIN))
                and ((s < AT_STEP_WIDTHS * 2 * half_width
                      and not (profiled and change >= SURE_CHANGE
                               and s >= STEP_WIDTHS * 2 * half_width))
                     or not (profiled or stepped)))):
        return [r.moved(r.stage_shift - origin) for r in results], None
    axis = holder_axis(first, s, half_width, first_frame())
    hook = _hook(first, s, axis, half_width)
    cut = _cut(first, s, axis, hook)
    shift = _end_on_axis(first_frame(), cut, s, half_width)
    if shift:
        told += f"; its end moved {shift * px:+.1f} px along the tube's own axis"
    face = (_crossing(first, cut.base + shift * np.exp(1j * axis), axis)
            if abs(shift) > STRAIGHT_HW * half_width else None)
    if face is not None:
        # every frame is cut where its curve crosses the end face so found (the
        # frames' curves run alike through the holder, which stands still)
        s, shift = face, 0.0
        hook = _hook(first, s, axis, half_width)
    arc, z, _, _ = _sampled(first, 0.25)
    end = complex(np.interp(s, arc, z.real), np.interp(s, arc, z.imag))
    # (within the tube's half-width: a fit through a holder the camera shakes,
    # its base held at the border, passes its end up to 4.7 px aside)
    tol = max(2.0, OFF_HOLDER_HW * half_width)
    tube = first.length - s
    drift = (None if frames is None else
             _mouth_drift(frames, _cut(first, s, axis, hook, shift), results,
                          half_width, origin))
    if drift is not None:
        told += (f"; the holder's mouth then registered on a second read of the frames: it "
                 f"moved up to {max(abs(d) for d in drift) * px:.1f} px along its axis "
                 "beyond the drift followed while tracking, and each frame was cut there")
    out = []
    for i, r in enumerate(results):
        if not r.ok:
            out.append(r)
            continue
        # each frame cut where its own centreline passes the holder's end (near
        # its start: a tube curled past a turn may pass it again further on)
        mouth = end + (drift[i] if drift is not None else 0j)
        arc, z, _, _ = _sampled(r.curve, 0.25)
        k = int(np.argmin(np.where(arc <= s + least + abs(mouth - end), np.abs(z - mouth),
                                   np.inf)))
        at = float(arc[k])
        missed = (OFF_HOLDER if abs(z[k] - mouth) > tol
                  else OFF_LENGTH if abs((r.curve.length - at) / tube - 1) > LENGTH_OFF
                  else None)
        if missed:
            out.append(replace(r, status=missed, curve=None, fit=None, last_section=None))
            continue
        # (the fit shares the curve's base: cut at the same arc length; the
        # last section's record describes the uncut spline, and goes)
        out.append(replace(
            r, curve=_cut(r.curve, at, axis, hook, shift) if at >= 1.0 else r.curve,
            fit=(_cut(r.fit, min(at, 0.5 * r.fit.length), axis, hook, shift)
                 if r.fit is not None and at >= 1.0 else r.fit),
            last_section=None).moved(r.stage_shift - origin))
    return out, (f"{told}: a holder (pipette) taken for the tube, cut off every frame (its "
                 "axis the base tangent)")


def _mouth_drift(frames, mouth: Curve,
                 staged: list[FrameTrack], half_width: float, origin: complex
                 ) -> list[complex] | None:
    """How far the holder's mouth moved along its axis on each frame beyond
    the stage's drift the tracker followed, px (y up, along ``mouth``'s base
    tangent); None where it did not (a still stage, or a drift already
    followed).

    The holder's region at its mouth (``mouth``'s base, the first frame's
    tube cut there) is registered on every frame
    (:func:`pipeline.drift.holder_path`: a second read of ``frames``, each
    frame's tube past the mouth left out). Along the holder's axis only: across
    it, each frame's centreline is cut where it passes nearest. Followed
    once it has moved :data:`pipeline.drift.FOLLOW_MIN_PX` along the axis on
    :data:`pipeline.drift.FOLLOW_FRAMES` frames in a row; a frame not measured
    keeps the last one's (the first frames, none)."""
    from .drift import FOLLOW_FRAMES, FOLLOW_MIN_PX, holder_path

    # (each frame's tube past the mouth, where it lies on the frame: the
    # holder's stretch of the tracked structure would hide the region)
    tubes = []
    for r in staged:
        if not r.ok:
            tubes.append(None)
            continue
        arc, z, _, _ = _sampled(r.curve, 0.25)
        at = float(arc[int(np.argmin(np.abs(z - mouth.base)))])
        tube = _cut(r.curve, at, mouth.base_angle, 0.0)
        tubes.append(replace(tube, base=tube.base + r.stage_shift - origin)
                     if at < r.curve.length - 1.0 else None)
    path = holder_path(frames, mouth, tubes, half_width)
    if path is None or len(path) != len(staged):
        return None
    axis = np.exp(1j * mouth.base_angle)
    beyond, last = [], 0j
    for p, r in zip(path, staged, strict=True):
        last = last if p is None else p
        # (the frames were moved back by the drift followed while tracking:
        # the mouth lies where it moved beyond that)
        beyond.append(float(((last - (r.stage_shift - origin)) * axis.conjugate()).real))
    run = 0
    for b in beyond:
        run = run + 1 if abs(b) >= FOLLOW_MIN_PX else 0
        if run >= FOLLOW_FRAMES:
            return [b * axis for b in beyond]
    return None


def _hook(first: Curve, s: float, axis: float, half_width: float) -> float:
    """How far past a holder's end, ``s`` px along the ``first`` frame's
    curve, the fit's hook is taken out (px: :data:`UNHOOK_HW` half-widths, at
    most :data:`UNHOOK_SHARE` of the tube), or 0 where taking it out moves
    the base less than :data:`UNHOOK_MIN_PX` aside."""
    cut = cut_base(first, s, axis)
    reach = min(UNHOOK_HW * half_width, UNHOOK_SHARE * cut.length)
    aside = ((unhooked(cut, reach).base - cut.base) * np.exp(-1j * axis)).imag
    return reach if abs(aside) >= UNHOOK_MIN_PX else 0.0


def _cut(curve: Curve, s: float, axis: float, hook: float, shift: float = 0.0) -> Curve:
    """``curve`` cut ``s`` px from its base, its base tangent ``axis`` (rad),
    its first ``hook`` px past the cut unhooked (:func:`unhooked`; none for
    0), and then its base moved ``shift`` px along the axis (cut further, or
    for ``shift < 0`` carried straight back)."""
    cut = cut_base(curve, s, axis)
    cut = unhooked(cut, min(hook, UNHOOK_SHARE * cut.length)) if hook > 0 else cut
    return cut_base(cut, shift, axis) if shift else cut


def _crossing(curve: Curve, face: complex, axis: float) -> float | None:
    """Arc length (px) at which ``curve`` first crosses the line through
    ``face`` square to ``axis`` (rad), going forwards along it, leaving the
    tube its share (:data:`MIN_TUBE_SHARE`) past it; None where it does not."""
    arc, z, _, _ = _sampled(curve, 0.25)
    along = ((z - face) * np.exp(-1j * axis)).real
    k = np.flatnonzero((along[:-1] < 0) & (along[1:] >= 0)
                       & (arc[1:] <= (1.0 - MIN_TUBE_SHARE) * curve.length))
    if not k.size:
        return None
    k = int(k[0])
    return float(arc[k] + (arc[k + 1] - arc[k]) * -along[k] / (along[k + 1] - along[k]))


def _end_on_axis(image: np.ndarray, cut: Curve, back: float, half_width: float) -> float:
    """How far along the tube's axis the holder's end lies past the base of
    ``cut`` (the first frame's curve, cut and unhooked: its base on the tube's
    axis), px; 0 where the profiles along the axis, ``back`` px into the
    holder, do not step by :data:`MIN_CHANGE` within :data:`REPLACE_HW`
    half-widths of it (see :data:`REPLACE_HW`)."""
    probe = cut_base(cut, -back, cut.base_angle)
    at, change = profile_change(image, probe, half_width,
                                back + HOLDER_REACH_HW * half_width, match_tube=False)
    shift = at - back
    return (shift if change >= MIN_CHANGE and MIN_SHIFT_PX <= abs(shift) <= REPLACE_HW * half_width
            else 0.0)
