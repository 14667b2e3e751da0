"""Track a microtube through a sequence of frames.

Per frame, only the work the frame needs (cheapest first):

1. **fast** — predict the centreline from the previous two frames (constant
   velocity of the spline coefficients and length), crop the frame to the
   region the predicted tube can occupy, and refine the prediction on the
   crop's edges (:func:`pipeline.refine.refine`, 3 Gauss–Newton rounds by
   default: :class:`TrackSettings`);
2. **crossing** — when the predicted tube touches or crosses itself, profiles
   whose search range reaches the other layer are dropped before measuring,
   and the spline bridges the crossing from both sides; temporal continuity
   (the prediction) keeps the order along the tube and the unwrapped angle.
   A jointed tube's last section, when the crossing hides it, keeps its
   curvature in the ratio to the section before that it had when last seen
   whole (``tip_ratio`` of :func:`pipeline.refine.refine`); without that
   ratio (no joints known, or a section before that barely turns), the
   stretch the crossing hides at its end, in the
   ratio to the stretch before it that the last shape seen whole had
   (``mode``). Of fits that fit the edges alike, the one from the prediction
   is kept (:data:`RESIDUAL_TIE`);
3. **wide** — if the fit fails its checks, search again with a wider window
   on the whole frame, from the prediction and from the previous frame;
4. **redetect** — if that fails too, find the tube from scratch
   (:mod:`pipeline.segment`) keeping the known base, and refine.

Section joints (where the walls change, so the curvature steps) are given by
the sample, or found in the frames (:mod:`pipeline.joints`): as steps in the
tube's outer width, on the first frame and then in the mean width over the
frames so far (looked at after 2, 3, 4, 6, 8, … of the first
:data:`RECORD_FRAMES`, and measured no more once it would show any step
worth keeping: on a clean scene, after two), which shows steps too faint
for one frame and places them to a pixel or two; and as kinks in its shape
each time the bend has grown by a quarter. A joint gets a triple knot in the spline, and once the
joints are known the spline between them is coarser
(:attr:`TrackSettings.jointed_widths_per_coef`).

The base, where the pipette holds the tube, is one point with one tangent for
the whole video (unless given): found on the first frame, then put at the
median of where the first :data:`BASE_VOTE_FRAMES` measured frames show it (its
tangent at the median of those that are little bent, or of all of them when
none is and they agree); those frames are held back
and refitted to it before they are yielded (a bounded buffer: memory stays flat
in the number of frames).

A frame that none of these can measure keeps NaN measurements and a status
saying why; tracking goes on with the last good shape as the prediction.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field, replace

import numpy as np
from scipy import ndimage as ndi

from .centreline import (
    Curve,
    basis_of,
    cut_base,
    evaluate,
    fit_to_polyline,
    n_coef_for,
    resample,
    tip_point,
)
from .drift import StageDrift
from .joints import (
    MAX_SPACING_F,
    WidthRecord,
    find_joints,
    place_steps,
    record_resolves,
    recorded_steps,
    rewritten,
    same_joints,
    spacing_f,
    step_windows,
    width_steps,
)
from .plug import grows_with_bend
from .profiles import gradient_noise, sample_lines
from .refine import (
    END_STEP_ZONES_HW,
    MAD_TO_SD,
    STRIP_LINES,
    STRIP_STEP_PX,
    TIP_OUTPUT_CHI2,
    TIP_RATIO_MIN_TURN,
    LastSection,
    Refined,
    TubeLook,
    antisymmetry,
    edges_at,
    locate_base,
    pipette_axis,
    profile_spacing,
    refine,
    relief_edges,
    relief_shear,
    section_ratio,
    self_contact,
    trend_sample,
    widths_at,
)
from .segment import (
    BORDER_BASE,
    EDGES_BEGIN,
    HOLDER_STEP,
    PIPETTE_STEP,
    base_at_edge,
    detect,
    edge_behind,
    slanted_cut,
)

#: :func:`pipeline.refine.antisymmetry` of the first frame across the tube
#: found, above which it is taken for a relief (its edges are looked for only
#: as a relief's), and above which a relief is tried besides dark and bright
#: edges (the strongest edge pairs decide). Ordinary looks measured at most
#: 0.51 (53 scenes), reliefs 0.79-8 (12 scenes); since, a transparent tube
#: with a bright lumen 0.64-0.66 (an independent renderer's, from the border
#: and from a base given at the pipette's mouth: the latter taken for a
#: relief, its length 2.3 % off). Between 0.66 and 0.79.
RELIEF_SURE = 1.0
RELIEF_MAYBE = 0.72
#: Profiles that must hold a valid edge pair for a fit to be accepted.
MIN_VALID = 0.7
#: ... of the profiles not dropped because the tube crosses itself there.
MIN_COVERAGE = 0.3
#: A fit's residual may reach this many times the edge noise (the centres'
#: scatter from one profile to the next, :attr:`Refined.noise_px`) before it
#: counts as not fitting, however far that is over the fixed limit (0.5 px or
#: 8 % of the half-width): on a noisy frame the centres scatter by more.
#: Fits that were right measured 0.9-2.2x, fits that missed the shape 4-13x
#: (residual over noise). Measured on 111 scenes: 3 frames of a 320x240
#: fluorescent scene no longer lost (its median 1.38 -> 0.70 deg), the
#: rest identical.
NOISE_RESIDUAL_RATIO = 2.5
#: ... but never over this, px: centres that scatter by more are no edges
#: (a start on the wrong structure scattered by 10-29 px, and its fits
#: passed without this: a video that starts curled past 300 deg went from a
#: 3.7 deg median to 610 deg).
NOISE_RESIDUAL_MAX_PX = 1.0
#: A fit's residual may also reach this many times the median of the video's
#: last frames' (:data:`RESIDUAL_JUMP_FRAMES`, accepted, not at crossings), up
#: to RESIDUAL_KEEP_MAX_HW half-widths: edges that have fitted that well all
#: along still fit. A stretch of the fitted tube that always fits badly (a
#: thick-walled holder's lumen, tracked as the tube until it is cut off after
#: the run) holds every frame's residual near the fixed limit, and one frame
#: a little over it was lost (independent renderer, DIC: 5 frames at
#: 1.03-1.1 px, against 0.77-0.93 px on the frames before).
RESIDUAL_KEEP = 1.3
RESIDUAL_KEEP_MAX_HW = 0.15
#: Frames on which the tube's width along its length is recorded, when the
#: joints are looked for in the frames (:class:`pipeline.joints.WidthRecord`):
#: by then the record's scatter is a sixth of one frame's.
RECORD_FRAMES = 32
#: Longest stretch at the tube's end, in half-widths, that a fit may run
#: without finding the tube's side edges: further, its end has run on over the
#: background to some other edge (dust, a blob) taken for the tube's end.
END_GAP_HW = 2.0
#: ... but where the end is found within :data:`LENGTH_JUMP` of the
#: neighbouring frame's length, it may run this far: a tip that moves fast
#: smears sideways over the exposure, and its side edges, wider apart and
#: fainter, are not the tube's (an independent scene, 12.5 deg per frame:
#: 4.5 half-widths without them; the end found 0.1 % off the last frame's
#: length). An end run on to dust or a blob that far lies that far off too.
SMEARED_END_GAP_HW = 6.0
#: Largest accepted change of the tube's length from one frame to the next.
MAX_LENGTH_STEP = 0.08
#: Consecutive lost frames after which the tracker starts from scratch.
RESTART_AFTER = 5
#: The base, where the pipette holds the tube, stands still: it is put at the
#: median of where :func:`pipeline.refine.locate_base` finds it on each of the
#: first this many measured frames, and those frames are held back and refitted
#: to it. (One frame's finding scatters by 0.3-2 px on small, noisy tubes, and
#: an error Δs along the tube takes κ·Δs off every frame's bend.)
BASE_VOTE_FRAMES = 8
#: A base moved by less than this (px) is left where it is.
BASE_MOVE_MIN_PX = 0.25
#: The base tangent likewise goes to the median of the first frames' own
#: measurements of it: the pipette's axis where it shows
#: (:func:`pipeline.refine.pipette_axis`, at any bend); else φ(0) fitted as at
#: the start, of those bent at most
#: BASE_ANGLE_MAX_BEND_DEG (the strong roughness penalty pulls φ(0) with the
#: bend: votes grew by 0.5-1.5° over the first 8 frames of some scenes, most
#: where a joint lies near the base) and within BASE_ANGLE_SPREAD_DEG of the
#: first frame's (a noisy frame can be far off), when at least
#: BASE_ANGLE_MIN_VOTES are. Measured over 153 scenes, against no vote: of the
#: angle medians that moved > 0.02°, 15 fell and 8 rose; scenes meeting every
#: target 123 → 124 (an independent renderer's glow scene 0.95° → 0.43°). Up to
#: 60° of bend: 55 fell and 29 rose, but 123 → 123 (two repo scenes whose base
#: tangent error had offset their tip's fell past the 0.5° line).
BASE_ANGLE_MAX_BEND_DEG = 30.0
BASE_ANGLE_SPREAD_DEG = 3.0
BASE_ANGLE_MIN_VOTES = 3
#: A video that starts bent (deflating, or filmed from under pressure) has no
#: little-bent frame among the first ones: their votes at any bend then count,
#: if they agree (robust SD at most this, deg); a φ(0) pulled with the bend
#: shows as votes that drift, and noisy ones scatter. Measured on 7 evaluation
#: videos played backwards (starting bent 176-305°): 2 more meet every target
#: (one whose base tangent was 1.3° off, its votes -1.2 to -1.6°: median error
#: 1.42 -> 0.14°; one 0.72 -> 0.45°), the others unchanged. Not used when any
#: of the first frames is little bent: on 182 videos that start straight,
#: taking the bent frames' votes as well moved 67 medians (45 down, 22 up) and
#: no more met every target (156 against 155).
BASE_ANGLE_AGREE_DEG = 0.5
#: A base tangent turned by less than this (deg) is left as it is (the
#: pipette's axis, measured on each of the first frames, varies by ~0.01°).
BASE_TURN_MIN_DEG = 0.02
#: A base found at a width step is looked for again this many half-widths
#: either side of it, by the profiles across the tube (:func:`_holder_end`).
HOLDER_END_HW = 4.0
#: Bend (deg) from which the tracker looks for the section joints, where the
#: curvature steps, when they are not given; it looks again each time the bend
#: has grown by :data:`JOINT_CHECK_GROWTH` (a step shows more the more it bends).
JOINT_CHECK_DEG = 45.0
JOINT_CHECK_GROWTH = 1.25
#: A fit whose edges' residual exceeds RESIDUAL_JUMP times the median of the
#: last RESIDUAL_JUMP_FRAMES frames' (and RESIDUAL_JUMP_MIN_PX) is searched
#: again as a failed one is (from the last shape, and the tube found afresh),
#: and the best fit of those kept. At the reversal of an inflate-deflate cycle
#: (a 270° curl) the constant-velocity prediction overshot and fits at 8-14x
#: the video's residual passed the checks, 33-195° off on 7 frames; with this
#: search, 1 (the reversal frame). The 182 evaluation scenes never trigger it.
RESIDUAL_JUMP = 4.0
RESIDUAL_JUMP_MIN_PX = 0.3
RESIDUAL_JUMP_FRAMES = 4
#: A fast fit at a crossing whose last round still moved the centreline by
#: more than this, px, has not settled (its few rounds ran out on a prediction
#: far from the tube: a curl that stopped or turned back, which the
#: constant-velocity prediction carries on); it is redone as the wide search.
#: (Settled fast fits move under 0.4 px in their last round; at a reversal
#: 8-17 px.)
UNSETTLED_MOVE_PX = 0.5
#: A search's fit (wide, from a later frame, at the held length) that ran out
#: of its WIDE_ROUNDS rounds while its centreline still moved by more than
#: UNARRIVED_MOVE_PX px a round is run on for up to UNARRIVED_ROUNDS rounds more,
#: and the longer fit kept where its edges' residual is at most UNARRIVED_GAIN of the
#: stopped one's: a sudden pressure step (a tube that sprang back 88 deg) takes
#: the tube far from the last shape and its prediction, and the fit stopped
#: 6 deg short, still moving 3-15 px a round at 37x the converged residual
#: (arrived at 16 rounds). A fit that only wanders (its end creeping along a
#: faint relief, 4 px a round, its residual all but unchanged) is left as it
#: stopped: more rounds ran its end on past the tube.
WIDE_ROUNDS = 10
UNARRIVED_ROUNDS = 20
UNARRIVED_MOVE_PX = 1.0
UNARRIVED_GAIN = 0.5
#: A fit whose tip tangent turned by more than this fraction of a turn since
#: the last frame is taken for a slip of the unwrapped angle, and the frame
#: lost: a fit a coil further round (or back) turns by about a turn. Half a
#: turn lost a tube that sprang back from 476 to 286 deg in one pressure step,
#: fitted right (its edges at the video's residual).
TURN_SLIP = 0.75
#: At a crossing, a free fit whose length is within this fraction of the
#: tube's own (on the last frames where it did not cross itself) is kept; one
#: further off has found its end in the other layer, and the fit with the
#: length held may replace it (:func:`_held_length_fits`). Lengths jitter by
#: 0.05-0.2 % between frames where the end is seen clearly (a free fit 0.24 %
#: long was 0.8 deg off, the held one 3.2; one 0.47 % long 1.8 deg, held 0.1).
HELD_LENGTH_STEP = 0.003
#: Fits whose residuals are within this factor of each other fit the edges
#: alike: where the tube lies over itself its end hides, and the edges do not
#: tell how far round it has turned. Of those, the fit from the prediction
#: (temporal continuity) is kept, over one that ran its end on into the other
#: layer or one from the last shape (and, for :data:`LENGTH_JUMP`, the fit at
#: the tube's own length over the one whose length jumped).
RESIDUAL_TIE = 1.25
#: A fit whose length is off the tube's own (on the last frames where it did
#: not cross itself) by more than this fraction is fitted again with the
#: length held, and the held fit kept if it fits the edges as well
#: (:data:`RESIDUAL_TIE`): lengths jitter by 0.05-0.2 % between frames, and
#: a tip run onto a holder found its end on the holder's far edge, 1.8 % on.
LENGTH_JUMP = 0.01
#: Fractions of the detection mask's width tried as the tube's width on the
#: first fit (the strongest edge pairs win): the mask of a strong, thin band
#: spreads over its blurred skirts, to twice the width of a 6 px opaque tube;
#: on a mottled background it shrinks to 0.63-0.74 of a transparent tube's width,
#: and from 1.0 down one dark wall was taken for the tube. Adding 1.4: the four
#: textured scenes of an independent renderer went from medians 3.4-62 deg to
#: 0.8-1.4 deg (with RUN_ON_ROUNDS); 136 scenes of the repo's renderer: one moved
#: by > 0.02 deg (v29, 0.88 -> 1.00 deg, failing before and after).
WIDTH_GUESSES = (1.4, 1.0, 0.6, 0.36)
#: ... and these, far narrower, which win only where their edge pairs score
#: over 1/:data:`WEAK_STRETCH` times the best of those (and give the width of
#: any stretch where they are that much stronger: :func:`_strongest_widths`).
#: A fluorescent tube's glow spreads its mask to 5x its width (an independent
#: renderer's 19 px tube: a 100 px mask; pairs 0.27 strong at 0.2 of it,
#: 0.002 at the others), and every frame failed its checks; found now (median
#: 0.45 deg). Taken on the score alone, they found a dyed lumen in a colour
#: frame's luminance (0.056 against the outer pair's 0.050).
FAR_NARROWER = (0.2,)
#: A pair of edges of the other polarity around the one found, at these
#: multiples of its width, is the tube (:func:`_enclosing`) where it is at
#: least ENCLOSING_MIN_RATIO times as wide, found on ENCLOSING_VALID of as many
#: profiles and its edges ENCLOSING_STRENGTH as strong.
ENCLOSING_SCALES = (1.8, 2.3, 2.9)
ENCLOSING_MIN_RATIO = 1.5
ENCLOSING_VALID = 0.8
ENCLOSING_STRENGTH = 0.5
#: ... and standing this many times above the edge filter's noise.
ENCLOSING_NOISE = 3.0
#: A tube whose walls differ in thickness shows, besides its outer edge pair,
#: a pair of one outer edge and the thick wall's lumen edge, of the same
#: polarity, as strong and narrower; among pairs about as strong the one nearest
#: the prediction wins (:func:`pipeline.profiles.edge_pairs`), and a first fit
#: that started nearer the mixed pair's middle kept it. A pair this many times
#: as wide (:func:`_outer_pair`), sharing one of its edges to SHARED_EDGE_PX
#: on SHARED_FRACTION of a width bin's profiles and OUTER_STRENGTH as strong
#: there, is the tube's outer pair. (An independent renderer's gamma-encoded
#: tube 16.7 px wide, its lumen 0.7 px off-centre: found 12.4 px wide, its
#: midline 2.0 px to one side on every frame; bend-angle error median 25.6 ->
#: 0.14 deg.) On four independent sets (120 scenes): 91 -> 92 meet every
#: target, none lost more; the repo's 38 unchanged. A wider pair enclosing the
#: one found without sharing an edge took a holder in (a base 135 px off: 91);
#: scales up to 3 (a thin wall's outer edge paired with its lumen edge), with
#: a search reaching the wide pair's middle, widened holders' stretches: 91.
OUTER_SCALES = (1.15, 1.3, 1.45, 1.65, 1.85)
OUTER_TOL = 0.12
SHARED_EDGE_PX = 0.5
SHARED_FRACTION = 0.6
OUTER_STRENGTH = 0.7
#: A pair encloses the one found where each of its edges lies this far (px)
#: outside the found pair's (:func:`_concentric_outer`).
CONCENTRIC_PX = 1.0
#: ... at least this share as strong as the found pair (an air-filled lumen's
#: walls step more strongly than the outer edges: 0.62 on an independent
#: renderer's tube in water).
CONCENTRIC_STRENGTH = 0.5
#: ... and with the band between them standing off the background by at least
#: this share of the inside's furthest (see :func:`_wall_band`).
CONCENTRIC_BAND = 0.05
#: How many times the first fit is carried on past its end while the tube's
#: edges run on to it (:func:`_run_on`): each time by half its length. Once was
#: not enough for a mask that stopped at a third of the tube (a faint middle
#: section on a mottled background: median 62 deg, 2 frames lost -> 1.35 deg).
RUN_ON_ROUNDS = 4
#: Share of the profiles within a width past the curve's end that must find the
#: edges for the tube to run on: beyond a tube's end, noise forms an edge pair
#: now and then (correlated noise of a frame scaled up 2x: 3 profiles of 5,
#: then the tip ran on 2.5 half-widths past its end and 5 of 8 frames were lost).
RUN_ON_VALID = 0.8
#: Gaussian smoothing (px) of the edge profiles tried when the tracker starts,
#: narrowest first, and the edge-to-noise ratio that is enough (:func:`edge_scale`).
#: Measured on 87 rendered scenes: with 0.8 px alone, two noisy low-contrast
#: scenes lost 21 frames (edge-to-noise 1.8–1.9); with these, none.
EDGE_SCALES = (0.8, 1.2, 1.6, 2.4)
SNR_TARGET = 5.0
#: Where even the widest of those leaves the edges under this edge-to-noise
#: ratio in the profiles' strips (√:data:`STRIP_LINES` times a single line's),
#: the strips are made longer (:attr:`TubeLook.strip_lines`) until they reach
#: it, up to ±:data:`STRIP_MAX_HW` half-widths along the tube (and the
#: profiles spaced as far apart). On every own rendered scene but a relief the
#: strips' ratio was at least 4.8 (all 182 unchanged); on an independent-
#: renderer scene at 6 % contrast (a holder, a tube 17 px wide) it was 2.2 and
#: the edge search followed the noise: every frame wrong or not measured ->
#: median 1.46, p95 1.99 deg with 9 lines. On 24 rendered scenes at 8-12 %
#: contrast in heavy noise (18 of them longer strips): frames lost 86 -> 67,
#: 3 scenes from 7-8 frames lost to none, 2 from 0 and 5 to 7 (one a tube
#: 4.6 px wide, whose start went wrong).
STRIP_SNR = 4.0
STRIP_MAX_HW = 0.5
#: Roughness weight of the fits that measure the base tangent when the tracker
#: starts: strong, so that φ(0) follows the whole tube rather than the few
#: profiles by the base.
BASE_SMOOTHING = 0.1
#: The same for the first of those fits, from the skeleton. There the scatter of
#: the edge midpoints about the curve is mostly the skeleton's misfit, which
#: averaging strips of lines does not lower: divided by the strips' lines to
#: undo their lower noise reference (:func:`pipeline.refine.noise_ref_px`). At
#: the full weight, a blurred MJPG scene lost its first frame (the fit bent 8 px
#: off at the base).
SKELETON_SMOOTHING = BASE_SMOOTHING / STRIP_LINES
#: The end's shape (a flat face or a round cap, :class:`_CapVotes`) is set
#: from this many frames.
CAP_VOTE_FRAMES = 4
#: A share of a round cap below this is a flat end's (:class:`_CapVotes`).
CAP_MIN = 0.5
#: The tip stretch is held to its curvature's trend (:class:`_TrendVotes`)
#: once at least this many frames ...
TREND_VOTE_FRAMES = 5
#: ... tell the curvature's rate of change before it in proportion to the
#: curvature there, with a ratio this many standard errors from nought
#: (:class:`_TrendVotes`). Over whole videos of the independent sets: ramping
#: tubes 8-126 (told by their 5th-14th frame, a few by the 25th), arcs below
#: 2.5 but for a straight plug at the tip (4.5) and an over-curl (9); 3 was
#: reached by chance, on the way, by 8 of alien4's 34 videos (refits of the
#: reported centrelines, not the tracker's own fits).
TREND_MIN_Z = 5.0
#: ... and whose ratio changes the curvature by at least this share of itself
#: over the tube's length (what numerical noise alone would tell on frames
#: that fit the line exactly; ramps of the independent sets: 0.5-3).
TREND_MIN_CHANGE = 0.05
#: The side edges near the tube's end are left out (:class:`_EndVotes`) once at
#: least this many frames ...
END_VOTE_FRAMES = 4
#: ... put their midpoints on average at least this far (px) ...
END_OFFSET_MIN_PX = 0.08
#: ... and this many standard errors off the line the rest of the tube gives.
END_OFFSET_Z = 3.0
#: A dark tube's end's sideways step is told (:class:`_EndStepVotes`)
#: on the same evidence (:data:`END_VOTE_FRAMES`, :data:`END_OFFSET_MIN_PX`,
#: :data:`END_OFFSET_Z`); after this many frames without it, it is not looked
#: for again.
END_STEP_MAX_FRAMES = 12
#: ... and only where the offset also stands this many standard errors (from
#: each frame's edge noise, over the frames) out of the noise: the stretches
#: scanned are many, and a noisy tube's four frames had agreed by chance on
#: -0.29 px over 16 px at 0.35 px of scatter per profile (z 2.9 by this
#: measure; the independent renderer's off-centre lumens: 5-31).
END_STEP_Z = 5.0
#: The last section's curvature is held in proportion to the rest of the
#: tube's (:func:`hold_section_ratio`) once at least this many frames bend
#: the rest enough to tell the ratio, ...
RATIO_MIN_FRAMES = 3
#: ... leaving out frames further than this many of their own standard
#: deviations from the ratio the others agree on, ...
RATIO_OUTLIER_SD = 3.5
#: ... and only where the rest agree on it: their reduced chi-square at most this.
RATIO_MAX_CHI2 = 4.0


@dataclass(frozen=True)
class TrackSettings:
    """The tracker's knobs that trade accuracy for speed.

    The defaults are the tracker's settings everywhere (``microtube track``,
    the demo, the reports); ``reports/tracking_settings.csv`` measures what
    the others cost and gain.

    Attributes
    ----------
    rounds : int
        Gauss–Newton rounds (at most) of the fast path, which refines the
        prediction from the previous two frames on a crop; ≥ 1.
    first_rounds : int
        The same on the frame after a (re)start, where the prediction is only
        the last shape (no velocity yet); ≥ 1.
    tol_px : float
        The refinements that start far from the tube (the start, the wide
        search, a fresh find, a refit with new joints) stop early once no point
        of the centreline moves more than this in a round, px; > 0.
    fast_tol_px : float
        The same for the fast path, which starts from the prediction: within
        this of its last round, a round more only refits the edges' own noise.
        Measured against 0.02 px on 182 rendered scenes: angle medians better on
        52 and worse on 44, their means unchanged (median 0.81, p95 1.43 deg);
        4 scenes at a target's limit crossed it (3 medians by 0.002-0.04 deg,
        one frame's centreline RMS) and 1 of 30 independently rendered scenes
        crossed it the other way; 1.2 ms a frame less (4.9 -> 3.7 ms, 1024x768);
        > 0.
    widths_per_coef : float
        Spacing of the centreline's spline coefficients, in tube widths (one
        coefficient per this many widths, 8 … 48 coefficients; set when the
        tracker starts): wider saves little time and blurs curvature steps at the
        section joints; > 0.
    jointed_widths_per_coef : float
        The same once the section joints are known (given, or found in the
        frames): the curvature steps then have knots of their own, and a
        coarser spline follows the noise less (the tip angle is the least
        constrained part of the curve); > 0.
    """

    rounds: int = 3
    first_rounds: int = 20
    tol_px: float = 0.02
    fast_tol_px: float = 0.1
    widths_per_coef: float = 0.75
    jointed_widths_per_coef: float = 1.5

    def __post_init__(self):
        for name in ("rounds", "first_rounds"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise ValueError(f"TrackSettings.{name} must be an integer >= 1, got {value!r}")
        for name in ("tol_px", "fast_tol_px", "widths_per_coef", "jointed_widths_per_coef"):
            value = getattr(self, name)
            if (isinstance(value, bool) or not isinstance(value, (int, float, np.floating))
                    or not np.isfinite(value) or value <= 0):
                raise ValueError(f"TrackSettings.{name} must be a positive number, "
                                 f"got {value!r}")


@dataclass(frozen=True)
class FrameTrack:
    """The tracker's result for one frame.

    Attributes
    ----------
    frame : int
        0-based frame index.
    status : str
        "ok", or a short reason why the frame could not be measured.
    curve : Curve or None
        The centreline, px (y up), when measured.
    stage : str
        The deepest stage the frame needed: init, fast, crossing, wide,
        redetect, backward (found from a later frame's shape, when lost on the
        way forward before the tracker's start) (or "" when not measured).
    residual_px : float
        RMS offset of the edge midpoints from the fitted centreline, px.
    valid_fraction : float
        Share of the normal profiles that found both edges.
    work_fraction : float
        Share of the frame's pixels the tracker looked at (its crop).
    base_source : str
        How the base was found, on frames that (re)started the tracker.
    smooth_px : float
        The edge profiles' smoothing chosen (:func:`edge_scale`), px, on
        frames that (re)started the tracker; NaN on the others.
    strip_lines : int
        The lines each edge profile averaged (:func:`strip_lines`), on frames
        that (re)started the tracker; 0 on the others.
    half_width_px : float
        The tube's mean half-width as the look learnt it, px, on frames that
        (re)started the tracker; NaN on the others.
    crossing : bool
        The predicted tube touched or crossed itself, so the profiles near
        the contact were left out.
    polarity : int or None
        The look learnt, on frames that (re)started the tracker: −1 dark
        edges, +1 bright, 0 a relief (see :class:`pipeline.refine.TubeLook`).
    shear_deg : float
        A relief's shear direction, deg (y up), on the frame that made it
        known (:func:`pipeline.refine.relief_shear`); NaN on the others.
    fit : Curve or None
        The fit itself, where ``curve`` (the shape reported) holds the tip
        stiffer (:data:`pipeline.refine.TIP_OUTPUT_STIFFNESS`): the next
        frame is predicted from it.
    last_section : LastSection or None
        For :func:`hold_section_ratio`: how ``curve``'s last section could be
        held in proportion to the rest of the tube (jointed fits only).
    end_offset : float
        :attr:`pipeline.refine.Refined.end_offset` of the fit, px (NaN where not
        measured).
    end_clear : bool
        The fit left out the side edges near the tube's end
        (:attr:`pipeline.refine.TubeLook.clears_end`).
    end_steps : (Z, 3) ndarray, optional
        :attr:`pipeline.refine.Refined.end_steps` of the fit.
    told_offset : float
        :attr:`pipeline.refine.Refined.told_offset` of the fit, px.
    end_profile : (M, 3) ndarray, optional
        :attr:`pipeline.refine.Refined.end_profile` of the fit.
    end_step : (float, float), optional
        The stretch at the tube's end told to step sideways, px (its side
        edges left out of the fit, or given an offset of their own), and how
        far its edge midpoints had sat off the rest's line on the frames that
        told it, px (:attr:`pipeline.refine.TubeLook.end_step_px`).
    plug_px : float, optional
        The length of the straight plug at the tube's end that ``curve`` was
        made straight over (:func:`pipeline.plug.straighten_plugs`), px; its
        start is then ``curve``'s last joint, no section joint.
    stage_shift : complex
        How far the stage had carried the holder from where it was when the
        tracker started, px (y up; :class:`pipeline.drift.StageDrift`): the
        shift this frame's base followed (0 until the drift is followed; the
        last measured on frames not measured; interpolated on the frames held
        back for the base's vote).
    cap_shape : float
        :attr:`pipeline.refine.Refined.cap_shape` of the fit.
    cap : float or None
        The look's :attr:`pipeline.refine.TubeLook.cap` once this frame was
        fitted (None: not told yet).
    tip_hold : str
        :attr:`pipeline.refine.Refined.tip_hold` of the fit the shape
        reported came from.
    look : TubeLook or None
        The look as the frames up to this one had told it, on measured frames
        (:func:`hold_tip_trend` refits the frames fitted before it told the
        tip's trend).
    """

    frame: int
    status: str
    curve: Curve | None
    stage: str
    residual_px: float = float("nan")
    valid_fraction: float = float("nan")
    work_fraction: float = 1.0
    base_source: str = ""
    smooth_px: float = float("nan")
    strip_lines: int = 0
    half_width_px: float = float("nan")
    crossing: bool = False
    polarity: int | None = None
    shear_deg: float = float("nan")
    fit: Curve | None = None
    last_section: LastSection | None = None
    end_offset: float = float("nan")
    end_clear: bool = False
    end_steps: np.ndarray | None = None
    end_step: tuple[float, float] | None = None
    plug_px: float | None = None
    told_offset: float = float("nan")
    end_profile: np.ndarray | None = None
    stage_shift: complex = 0j
    cap_shape: float = float("nan")
    cap: float | None = None
    tip_hold: str = ""
    look: TubeLook | None = None

    def moved(self, step: complex) -> FrameTrack:
        """This frame with its curves moved by ``step`` (px, y up)."""
        if not step:
            return self

        def move(curve):
            return None if curve is None else replace(curve, base=curve.base + step)
        return replace(self, curve=move(self.curve), fit=move(self.fit))

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    @property
    def tracked(self) -> Curve | None:
        """The curve the tracker goes on from: the fit, or ``curve``."""
        return self.fit if self.fit is not None else self.curve

    @property
    def bend_angle_rad(self) -> float:
        """Tip tangent relative to the base tangent (φ(1) − φ(0)), rad."""
        return float(self.curve.coef[-1]) if self.curve is not None else float("nan")


def as_float(frame: np.ndarray) -> np.ndarray:
    """A frame (or crop) as float32 in [0, 1], greyscale."""
    if frame.dtype == np.uint8:
        return frame.astype(np.float32) * np.float32(1 / 255)
    if frame.dtype == np.uint16:
        return frame.astype(np.float32) * np.float32(1 / 65535)
    return frame.astype(np.float32, copy=False)


def _learn_widths(refined: Refined, n_bins: int, fallback: float) -> np.ndarray:
    """Median measured half-width in ``n_bins`` bins along the tube."""
    edges = np.linspace(0, 1, n_bins + 1)
    which = np.clip(np.digitize(refined.u, edges) - 1, 0, n_bins - 1)
    out = np.full(n_bins, np.nan)
    for b in range(n_bins):
        w = refined.width[(which == b) & refined.valid]
        if w.size >= 2:
            out[b] = 0.5 * np.median(w)
    if np.all(np.isnan(out)):
        return np.full(n_bins, fallback)
    good = ~np.isnan(out)
    centres = 0.5 * (edges[1:] + edges[:-1])
    return np.interp(centres, centres[good], out[good])


#: A stretch of the first fit (one of its nine width bins) where it finds
#: next to nothing (its edge pairs there under WEAK_STRETCH of its own
#: typical strength) takes the width of another width guess whose pairs
#: there are over 1/WEAK_STRETCH times as strong, as strong as the tube's
#: (half the fit's typical strength at least) and under NARROWER_STRETCH of
#: the width the fit learnt there; and only where such stretches run over
#: MIN_STRETCH_BINS bins together. A tube on a tapered holder many times its
#: width (an independent renderer's 4.8 px tube at the end of a 700 px
#: pipette 22 px wide at the border) has no one width, and the guess that
#: fits the holder found only noise along the tube (pairs 0.004 strong
#: against the tube's 0.18). A single bin is a crossing or a blemish: a
#: tube over-curled on the first frame, where a narrow pair at its crossing
#: took one bin to a quarter of the tube's width; pairs wider than the fit's
#: beside the tube are a neighbouring coil's. (A rim of a hollow tube is never
#: 4x stronger than its outer pair: both are as strong as their weaker edge,
#: and the rim shares an outer one.)
WEAK_STRETCH = 0.25
NARROWER_STRETCH = 0.75
MIN_STRETCH_BINS = 2


def _bin_strengths(image, r: Refined, look: TubeLook, n_bins: int):
    """Per width bin of ``r``: its edge pairs' median strength (0 where none
    is found) and median half-width (NaN where fewer than half are found),
    as ``look`` finds them across ``r``'s curve."""
    e = edges_at(image, r.curve, look, r.u, width_tol=0.4)
    which = np.clip((r.u * n_bins).astype(int), 0, n_bins - 1)
    strength = np.where(e.valid, e.strength, 0.0)
    med = np.zeros(n_bins)
    half = np.full(n_bins, np.nan)
    for b in range(n_bins):
        inside = which == b
        if inside.sum() >= 2:
            med[b] = np.median(strength[inside])
            if e.valid[inside].mean() >= 0.5:
                half[b] = 0.5 * np.median(e.width[inside & e.valid])
    return med, half


def _strongest_widths(image, r: Refined, look: TubeLook, widths: np.ndarray,
                      others) -> np.ndarray:
    """``widths`` (the first fit ``r``'s, learnt with ``look``), with the
    stretches where another of the first fits ``others`` ((Refined,
    TubeLook) pairs) of the same polarity finds the tube and ``r`` does not
    (:data:`WEAK_STRETCH`) at that fit's width."""
    n_bins = widths.size
    own, _ = _bin_strengths(image, r, look, n_bins)
    out = widths.copy()
    best = own.copy()
    for fit, their_look in others:
        if their_look.polarity != look.polarity:
            continue
        strength, half = _bin_strengths(image, fit, their_look, n_bins)
        take = ((strength * WEAK_STRETCH > own) & (strength > best) & np.isfinite(half)
                & (own < WEAK_STRETCH * r.strength) & (strength >= 0.5 * r.strength)
                & (half < NARROWER_STRETCH * widths))
        out[take], best[take] = half[take], strength[take]
    taken = out != widths
    runs, n_runs = ndi.label(taken)
    for k in range(1, n_runs + 1):
        if np.sum(runs == k) < MIN_STRETCH_BINS:
            out[runs == k] = widths[runs == k]
    return out


def _enclosing(image, curve, r, polarity, hw, tol, others=()):
    """The edge pair ``r`` found, or a wider pair of the other polarity around
    it whose edges are about as strong: a transparent tube in transmitted
    light shows a bright lumen between its dark walls, and the detector may
    take the lumen for the tube (a 16 px tube found 7 px wide). A phase
    halo around a dark tube is a band of the other polarity too, but it
    fades outwards: its outer edges are weak.

    ``r`` is the first fit of ``curve`` with ``polarity`` (±1), ``hw`` the
    detection's half-width (px) and ``tol`` the fits' tolerance (px). Returns
    ``(fit, polarity)``: ``r`` and ``polarity``, or the wider pair's fit and
    the other polarity. (The noise is the first fits' edge filter's, at the
    look's default smoothing.)

    ``others``: fits of ``curve`` with the other polarity made already (the
    first fits' width guesses), weighed with those made here: a tube whose
    walls differ in thickness shows, about its lumen, its outer pair and a
    pair of one outer edge and the thicker wall's lumen edge, about as
    strong; of the widths tried here only the latter was found (an
    independent renderer's index-matched tube: 17.4 px wide for 23.4, the
    midline 2 px to one side, the bend up to 26 deg off), which a first fit
    had found."""
    inner = float(np.nanmedian(r.width[r.valid]))
    best = None
    fits = (refine(image, curve, TubeLook(-polarity, np.full(9, 0.5 * inner * scale), 0.0),
                   window=0.6 * hw, iterations=3, width_tol=0.3, fit_length=False,
                   tol_px=tol, tip_stiffness=0.0) for scale in ENCLOSING_SCALES)
    for c in (*others, *fits):
        if not c.valid.any():
            continue
        wide = float(np.nanmedian(c.width[c.valid]))
        if (wide >= ENCLOSING_MIN_RATIO * inner
                and c.valid_fraction >= ENCLOSING_VALID * r.valid_fraction
                and c.strength >= ENCLOSING_STRENGTH * r.strength
                and (best is None or c.valid_fraction * c.strength
                     > best.valid_fraction * best.strength)):
            best = c
    if best is None:
        return r, polarity
    # (in heavy noise any pair is found, as strong as the noise: a faint phase
    # tube's halo, 0.9x the edge filter's noise, was taken for the tube)
    if best.strength < ENCLOSING_NOISE * gradient_noise(image, TubeLook.smooth_px):
        return r, polarity
    return best, -polarity


def _outer_pair(image, r: Refined, look: TubeLook) -> TubeLook | None:
    """``look`` with its half-widths widened in the width bins where a wider
    pair of the same polarity shares one edge with the pair ``r`` found
    (:data:`OUTER_SCALES`): an outer edge and a thick wall's lumen edge taken
    for the tube. None where no bin shows one."""
    n_bins = look.half_width.size
    which = np.clip((r.u * n_bins).astype(int), 0, n_bins - 1)
    found = edges_at(image, r.curve, look, r.u, width_tol=0.2)
    left, right = found.centre - 0.5 * found.width, found.centre + 0.5 * found.width
    widths = look.half_width.copy()
    shared_most = np.zeros(n_bins)
    for scale in OUTER_SCALES:
        wide = edges_at(image, r.curve, replace(look, half_width=look.half_width * scale),
                        r.u, width_tol=OUTER_TOL)
        shared = (found.valid & wide.valid
                  & ((np.abs(wide.centre - 0.5 * wide.width - left) <= SHARED_EDGE_PX)
                     | (np.abs(wide.centre + 0.5 * wide.width - right) <= SHARED_EDGE_PX))
                  & (wide.strength >= OUTER_STRENGTH * found.strength))
        for b in range(n_bins):
            inside = which == b
            share = shared[inside].mean() if inside.any() else 0.0
            if share >= SHARED_FRACTION and share > shared_most[b]:
                shared_most[b] = share
                widths[b] = 0.5 * np.median(wide.width[inside & shared])
    if not shared_most.any():
        return None
    return replace(look, half_width=widths)


def _concentric_outer(image, r: Refined, look: TubeLook) -> TubeLook | None:
    """``look`` widened to a pair of the same polarity that encloses the pair
    ``r`` found, a px or more outside it on both sides, along most of the
    tube (:data:`SHARED_FRACTION` of its profiles, at one of
    :data:`OUTER_SCALES`, at least :data:`CONCENTRIC_STRENGTH` as strong),
    with the band between the two pairs the tube's own (:func:`_wall_band`):
    a lumen whose walls step the way the outer edges do (an air-filled lumen,
    darker than the wall as the wall is than the water) taken for the tube.
    It shares no edge with the outer pair (:func:`_outer_pair`). A holder
    about the tube encloses it only over its first stretch; a fringe about
    it leaves the background between. None where no such pair shows."""
    found = edges_at(image, r.curve, look, r.u, width_tol=0.2)
    if found.valid.sum() < 8:
        return None
    left, right = found.centre - 0.5 * found.width, found.centre + 0.5 * found.width
    best, best_share = None, SHARED_FRACTION
    for scale in OUTER_SCALES:
        wide = edges_at(image, r.curve, replace(look, half_width=look.half_width * scale),
                        r.u, width_tol=OUTER_TOL)
        around = (found.valid & wide.valid
                  & (wide.centre - 0.5 * wide.width < left - CONCENTRIC_PX)
                  & (wide.centre + 0.5 * wide.width > right + CONCENTRIC_PX)
                  & (wide.strength >= CONCENTRIC_STRENGTH * found.strength))
        # (of all the profiles: where the pair found shows on part of the tube
        # only, a holder about that part would pass for the tube's walls)
        share = around.sum() / around.size
        if share >= best_share and _wall_band(image, r, found, wide, around, look.polarity):
            best, best_share = np.median(wide.width[around]) / np.median(found.width[around]), share
    if best is None:
        return None
    return replace(look, half_width=look.half_width * best)


def _wall_band(image, r: Refined, inner, outer, where: np.ndarray, polarity: int) -> bool:
    """Whether the band between the pairs ``inner`` and ``outer`` (Edges at
    ``r.u``, on the profiles ``where``) stands off the background beyond
    ``outer`` the way the tube does (``polarity``), over three quarters of
    it, by at least :data:`CONCENTRIC_BAND` of how far the inside of
    ``inner`` stands off it: a tube's wall does (an air lumen's wall in
    water: 0.1), the gap to a fringe or a ring about the tube does not."""
    at = np.flatnonzero(where)[:: max(1, int(where.sum()) // 40)]
    smp = evaluate(r.curve, basis_of(r.curve))
    grid = np.clip(np.round(r.u[at] * (smp.z.size - 1)).astype(int), 0, smp.z.size - 1)
    reach = float(np.max(outer.width[at])) / 2 + 6.0
    offsets = np.arange(-reach, reach + 0.25, 0.5)
    prof = sample_lines(image, smp.z[grid], smp.normal[grid], offsets)
    band, back, core = [], [], []
    for k, j in enumerate(at):
        c = offsets - inner.centre[j]
        o_half, i_half = 0.5 * outer.width[j], 0.5 * inner.width[j]
        d = np.abs(offsets - outer.centre[j])
        band.append(prof[k][(np.abs(c) > i_half + 1.0) & (d < o_half - 1.0)])
        back.append(prof[k][(d > o_half + 2.0) & (d < o_half + 5.0)])
        core.append(prof[k][np.abs(c) < i_half - 1.0])
    band, back, core = (np.concatenate(v) for v in (band, back, core))
    band, back, core = band[np.isfinite(band)], back[np.isfinite(back)], core[np.isfinite(core)]
    if not (band.size and back.size and core.size):
        return False
    level = np.median(back)
    deepest = np.max(polarity * (core - level))
    # (its least tube-like quarter: a fringe's own band fills part of the gap)
    return bool(deepest > 0 and np.quantile(polarity * (band - level), 0.25)
                >= CONCENTRIC_BAND * deepest)


def initialise(image: np.ndarray, *, base_hint=None, base_end=None, detection=None,
               settings: TrackSettings | None = None,
               joints: tuple[float, ...] | None = None):
    """Find the tube from scratch and learn its look.

    ``settings`` (default :class:`TrackSettings`) sets the spline's size and
    the refinements' convergence tolerance; ``joints`` are the tube's section
    joints, as fractions of its length, where its curvature may step (None:
    not known; ``()``: a single section). The tube is found with the fine
    spline of ``settings.widths_per_coef`` (it follows the skeleton's hooks
    and spurs until the ends are found); with the joints known, it is then
    rewritten with the coarser ``settings.jointed_widths_per_coef``.

    Returns
    -------
    (Refined, TubeLook, str) or None
        The refined first centreline, the learnt look and how the base was
        found; None when no tube stands out.
    """
    settings = settings or TrackSettings()
    tol = settings.tol_px
    det = detection or detect(image, base_hint=base_hint, base_end=base_end)
    if det is None:
        return None
    source = det.base_source
    hw = det.half_width
    length = det.length
    # found without the joints, whose kinks would follow the skeleton's hooks
    # and spurs as readily as the tube (fluorescent sample 1 with its joints
    # given: a wrong end, 47° off); they are put in once the tube is found
    n_coef = spline_size(length, hw, (), settings, known=False)
    curve = fit_to_polyline(det.path, det.base_angle, n_coef=n_coef)
    # dark or bright edges, or a relief (DIC) whose edges step the same way:
    # a relief's profiles across the tube are odd about its midline, the
    # others' even; where that does not tell, the edge pairs found most often
    # and strongest do
    anti = antisymmetry(image, curve, hw)
    polarities = ((0,) if anti >= RELIEF_SURE else (-1, 1, 0) if anti >= RELIEF_MAYBE
                  else (-1, 1))
    # (score, polarity, fit, the look it was fitted with)
    cands, narrow = [], []
    for polarity in polarities:
        for scale in (*WIDTH_GUESSES, *FAR_NARROWER):
            look = TubeLook(polarity, np.full(9, hw * scale), 0.0)
            r = refine(image, curve, look, window=0.6 * hw, iterations=3, width_tol=0.4,
                       fit_length=False, tol_px=tol, tip_stiffness=0.0)
            (cands if scale in WIDTH_GUESSES else narrow).append(
                (r.valid_fraction * r.strength, polarity, r, look))
    first_fits = cands + narrow
    usual = max(c[0] for c in cands)
    cands += [c for c in narrow if c[0] * WEAK_STRETCH > usual]
    polarity = max(cands, key=lambda c: c[0])[1]
    if len(polarities) == 3:
        # not told by the skeleton's curve, which may sit off the tube's middle:
        # a relief is odd about the middle its own edges find (measured, where the
        # skeleton's said 0.79-0.92: 1.6-4.4 on reliefs, 0.36-0.82 otherwise)
        relief = max((c for c in cands if c[1] == 0), key=lambda c: c[0])
        if antisymmetry(image, relief[2].curve, hw) >= RELIEF_SURE:
            polarity = 0
    cands = [c for c in cands if c[1] == polarity]
    best = max(cands, key=lambda c: c[0])
    if polarity == 0:
        # weighed by the width found too: a hollow tube in relief shows its
        # lumen's walls as well as its outer ones, as strongly or, where a wall
        # is thin (its two lines cancel), more strongly; the outer pair is the
        # wider. (Not for dark or bright edges: preferring the wider of the
        # pairs about as strong made 7 of 136 scenes worse and 3 better.)
        best = max(cands, key=lambda c: c[0] * (np.nanmedian(c[2].width)
                                                if c[2].valid.any() else 0.0))
    _, polarity, r, _ = best
    if polarity != 0 and r.valid.any():
        r, polarity = _enclosing(image, curve, r, polarity, hw, tol,
                                 others=[c[2] for c in first_fits if c[1] == -polarity])
    if r.valid_fraction < 0.3:
        return None
    widths = _learn_widths(r, 9, hw)
    # (the look of the first fit r still is: _enclosing may have fitted anew)
    fitted_with = next((c[3] for c in first_fits if c[2] is r), None)
    if polarity != 0 and fitted_with is not None:
        widths = _strongest_widths(image, r, fitted_with, widths,
                                   [(c[2], c[3]) for c in first_fits if c[2] is not r])
    # (the end's sideways step, if any, is told by the frames: see _EndStepVotes)
    look = TubeLook(polarity, widths, r.strength, end_step_px=None)
    # (a lumen's pair enclosed by the outer one first, then a pair sharing one
    # edge with the outer one)
    for widened in ((_concentric_outer, _outer_pair) if polarity != 0 else ()):
        outer = widened(image, r, look)
        if outer is None:
            continue
        # centred on the outer pair, so that the fits below (whose width
        # tolerance takes both pairs in) start nearest it
        wide = refine(image, r.curve, outer, iterations=3, width_tol=OUTER_TOL,
                      fit_length=False, tol_px=tol, tip_stiffness=0.0)
        if wide.valid_fraction >= ENCLOSING_VALID * r.valid_fraction:
            r, look = wide, replace(outer, strength=wide.strength)
    look = edge_scale(image, r.curve, look)
    # the base tangent is measured once, here, with a strong roughness penalty so
    # that φ(0) follows the whole tube rather than the few profiles by the base
    for width_tol in (0.3, 0.2):
        # the skeleton's length is rough (dust, the end's extension): if the tip was
        # not where the curve ends, search wider for it. No extra stiffness at the
        # tip yet: the skeleton's end may still hook into a spur, which a stiff tip
        # would carry on as a curl and so never find the end
        wide_tip = None if r.tip_found else 2.0 * look.mean_half_width
        r = refine(image, r.curve, look, iterations=8, width_tol=width_tol, free_base=True,
                   smoothing=SKELETON_SMOOTHING * STRIP_LINES / look.strip_lines,
                   tip_window=wide_tip, tol_px=tol,
                   tip_stiffness=0.0)
        look = replace(look, half_width=_learn_widths(r, 9, look.mean_half_width),
                       strength=r.strength)
    cut = None if r.tip_found else _cut_to_edges(r, look.mean_half_width)
    if cut is None:
        # the tube's edges run on to the curve's end: the skeleton stopped short
        # of the tip (its mask broke up there), and the tube goes on beyond. An
        # end found there may be a section's joint, where the walls change (a
        # faint middle section lost in a textured background): only a tube going
        # on by more than a width past it counts
        cut = _run_on(image, r, look, tol)
        if (cut is not None and r.tip_found
                and cut.length < r.curve.length + 2.0 * look.mean_half_width):
            cut = None
    if cut is not None:
        r = refine(image, cut, look, iterations=8, free_base=True,
                   smoothing=BASE_SMOOTHING,
                   tip_window=2.0 * look.mean_half_width, tol_px=tol, tip_stiffness=0.0)
    if base_hint is None:
        # the skeleton may run on into a faint pipette that stops short of the
        # border (no width step at the border to tell): then no tube edges are
        # found over the first stretch, and the search for the tube's start
        # must reach past it
        hw0 = float(look.half_width[0])
        reach = max(4.0 * hw0, _edge_gap(r) + 2.0 * hw0)
        start, start_length = r.curve.base, r.curve.length
        r = replace(r, curve=locate_base(image, r.curve, look, reach=reach))
        if (source == BORDER_BASE and abs(r.curve.base - start) > 2.0 * hw0
                and not slanted_cut(r.curve.base, r.curve.base_angle, hw0, image.shape)):
            # (a tube the border cuts obliquely begins its full width that far
            # in: it is carried on to the border later, as any other)
            source = EDGES_BEGIN
        elif source in (PIPETTE_STEP, HOLDER_STEP) and (
                r.curve.base == start
                or (source == HOLDER_STEP and 0.0 < r.curve.length - start_length <= hw0)):
            # (also where the edge pairs moved it back by under a half-width
            # into a holder wider than the tube: a thick glass capillary three
            # times the tube's width shows the tube inside it, and the search
            # went 3.5 px further in from a step the mask had put 20 px inside
            # the mouth. Not where they moved it on: the step lay on the
            # holder's side of the tube's edges, and those place it better,
            # by 0.3-0.6 px on two independent scenes; nor into a pipette
            # narrower than the tube, which cannot hold the tube's edges: there
            # the mask's step lay past where they begin)
            held = _holder_end(image, r.curve, look.mean_half_width, det.half_width)
            if held is not None:
                r = replace(r, curve=held)
                source = (f"{source}; then moved to where the profiles across it become the "
                          "tube's (a holder whose own edges are as far apart as the tube's)")
    r = _base_tangent_fit(image, r.curve, look, tol, r)
    r = refine(image, r.curve, look, iterations=4, tol_px=tol)
    if joints is None:
        # not given: the sections most often differ in their outer width, and a
        # step in the measured width is a joint, seen already on a straight tube
        hw, length = look.mean_half_width, r.curve.length
        coarse = width_steps(r.u, r.width, hw, length)
        if coarse:
            # placed to a fraction of a pixel by widths measured densely about each
            u = step_windows(coarse, hw, length, spacing_px=0.25)
            joints = place_steps(u, widths_at(image, r.curve, look, u), coarse, hw, length)
    if joints is not None:
        n_coef = spline_size(r.curve.length, look.mean_half_width, joints, settings, known=True)
        if (n_coef, tuple(joints)) != (r.curve.coef.size, r.curve.joints):
            # the base tangent again, as above, on the steadier spline
            r = _base_tangent_fit(image, rewritten(r.curve, joints, n_coef), look, tol, r)
            r = refine(image, r.curve, look, iterations=4, tol_px=tol)
    # the pipette's axis, where it shows, is the base tangent without the lean
    # into the bend that a fit to a bent tube gives it (and the base lies on
    # it: a base fitted to a bent tube may sit beside it)
    axis = pipette_axis(image, r.curve, look)
    for lean in (() if axis is not None or base_hint is None else PIPETTE_LEANS_DEG):
        # (a base given on a tube bent far on the frame the tracker starts on:
        # its base tangent leans into the bend by more than the pipette's
        # search allows)
        axis = pipette_axis(image, replace(r.curve, base_angle=r.curve.base_angle
                                           + np.radians(lean)), look)
        if axis is not None:
            break
    if axis is not None:
        direction, on_axis = axis
        turned = moved_base(r.curve, None, direction - r.curve.base_angle)
        r = refine(image, replace(turned, base=on_axis), look, iterations=4, tol_px=tol)
    return r, look, source


def _holder_end(image: np.ndarray, curve: Curve, half_width: float,
                rough_half_width: float = 0.0) -> Curve | None:
    """``curve`` from where, along its base axis, the profiles across it
    become the tube's (:func:`pipeline.pipette.profile_change`, over
    :data:`HOLDER_END_HW` half-widths either side of its base, of the tube's
    or, if wider, of the detection's ``rough_half_width``: its width step is
    off by as much as its mask is too wide), or None where they do not step
    there, or step within a px of its base.

    For a base found at a width step whose edge pairs cannot place it: a
    thick-walled holder whose lumen is as wide as the tube shows the tube's
    edge pair behind the base as strongly as past it
    (:func:`pipeline.refine.locate_base` leaves it where it is), and the
    mask's width changes over a half-width or so about the holder's mouth (an
    independent scene: the base 12 px past the mouth)."""
    from .pipette import HOLDER_CHI2, profile_change

    reach = HOLDER_END_HW * max(half_width, rough_half_width)
    if curve.length < 4.0 * reach:
        return None
    back = cut_base(curve, -reach, curve.base_angle)
    s, change = profile_change(image, back, half_width, 2.0 * reach)
    # (the change a holder's profiles must show to be cut off the tube, where
    # the detector saw none, is more than the frames need to place one it saw:
    # a relief's glass, 6x its scatter)
    if change < HOLDER_CHI2 or abs(s - reach) <= 1.0:
        return None
    return cut_base(back, s, curve.base_angle)


#: Where the base is given and no pipette's axis is found along the start's
#: base tangent, it is looked for along that tangent turned by each of these
#: (deg) in turn: own stress_deflating with --base, the base tangent 4.5 deg
#: off on its first, most bent frame, median 4.7 -> 0.17 deg (alien4 and
#: alien5 with --base unchanged). Not without a base given: there the frames'
#: vote finds the base, and the turned search found other axes on two of
#: alien5's scenes (a reticle, a defocused tip: bases 0.4-0.5 px further off).
PIPETTE_LEANS_DEG = (4.0, -4.0)


def _base_tangent_fit(image: np.ndarray, curve: Curve, look: TubeLook, tol: float,
                      before: Refined) -> Refined:
    """The fit that measures the base tangent (φ(0) free, under
    :data:`BASE_SMOOTHING`), from ``curve``; or, when that fit loses the tube
    (scores under half of ``before``, the fit ``curve`` came from), the plain
    fit, the base tangent held. The strong roughness penalty resists a tube
    curled past a turn, and the fit slid off it (from the true shape of a
    300 deg curl: edges found on 30 % of the profiles, the base tangent 23 deg
    off). The fallback keeps the default roughness: held under the strong
    penalty, two curled starts came out worse (a median 0.17 -> 0.34 deg)."""
    r = _free_base_fit(image, curve, look, tol)
    if _score(r) >= 0.5 * _score(before):
        return r
    return refine(image, curve, look, iterations=6, tol_px=tol)


def _free_base_fit(image: np.ndarray, curve: Curve, look: TubeLook, tol: float) -> Refined:
    """``curve`` fitted with its base tangent φ(0) (and the base's sideways
    place) free, under :data:`BASE_SMOOTHING`: the strong roughness penalty
    makes φ(0) follow the whole tube rather than the few profiles by the
    base. How the base tangent is measured, at the start, by the first
    frames' votes and again past a hooked start."""
    return refine(image, curve, look, iterations=6, free_base=True, smoothing=BASE_SMOOTHING,
                  tol_px=tol)


def edge_scale(image: np.ndarray, curve: Curve, look: TubeLook) -> TubeLook:
    """``look`` with the narrowest profile smoothing at which the tube's edges
    stand :data:`SNR_TARGET` times above the frame's noise (or, if none does,
    the one at which they stand highest).

    A narrow derivative places a sharp edge best, but on a noisy, blurred,
    low-contrast frame it sees mostly noise: the edge pairs scatter and noise
    beyond the tip passes for the tube going on. The edges are measured across
    ``curve`` (the first fit) at each of :data:`EDGE_SCALES`, the noise as the
    spread of the same filter over the whole frame. Where none reaches it,
    the profiles' strips are made longer too (:func:`strip_lines`).
    """
    u = np.linspace(0.02, 0.98, 64)
    # every 4th row: the filter runs along the rows, so this is the same noise
    # at a quarter of the cost
    rows = image[::4]
    snr = np.zeros(len(EDGE_SCALES))
    for i, smooth in enumerate(EDGE_SCALES):
        edges = edges_at(image, curve, replace(look, smooth_px=smooth, strength=0.0), u)
        if edges.valid.sum() >= 8:
            noise = max(gradient_noise(rows, smooth), 1e-12)
            snr[i] = float(np.median(edges.strength[edges.valid])) / noise
        if snr[i] >= SNR_TARGET:
            return replace(look, smooth_px=smooth)
    best = int(np.argmax(snr))
    return replace(look, smooth_px=EDGE_SCALES[best],
                   strip_lines=strip_lines(snr[best], look.mean_half_width))


def strip_lines(snr: float, half_width: float) -> int:
    """How many lines each profile's strip averages (odd, at least
    :data:`STRIP_LINES`), for edges ``snr`` times a single line's noise on a
    tube of ``half_width`` px: enough for :data:`STRIP_SNR` (the noise falls
    as the lines' square root), at most ±:data:`STRIP_MAX_HW` half-widths."""
    if snr <= 0 or np.sqrt(STRIP_LINES) * snr >= STRIP_SNR:
        return STRIP_LINES
    need = int(np.ceil((STRIP_SNR / snr) ** 2))
    most = 2 * int(STRIP_MAX_HW * half_width / STRIP_STEP_PX) + 1
    return max(STRIP_LINES, min(need + 1 - need % 2, most))


def spline_size(length_px: float, half_width_px: float, joints: tuple[float, ...],
                settings: TrackSettings, *, known: bool) -> int:
    """Coefficients of a centreline of this length and width with these joints:
    the spacing of ``settings`` for joints ``known`` or not, and two more
    per joint (its triple knot; the other knots keep their spacing)."""
    per = settings.jointed_widths_per_coef if known else settings.widths_per_coef
    return n_coef_for(length_px, 2 * half_width_px, widths_per_coef=per) + 2 * len(joints)


def _run_on(image: np.ndarray, r: Refined, look: TubeLook, tol: float,
            rounds: int = RUN_ON_ROUNDS) -> Curve | None:
    """When the tube's edges run on to the curve's end, the curve carried on
    straight by half its length, fitted to the edges, and cut back to where
    they stop; carried on again while they still run to its end, up to
    ``rounds`` times (None if they do not run to the end, or never stop)."""
    hw = look.mean_half_width
    for _ in range(rounds):
        if _edge_gap(r, 2, from_tip=True) >= hw:
            return None
        curve = r.curve
        extra = 0.5 * curve.length
        _, z = resample(curve)
        heading = z[-1] - z[max(0, z.size - 1 - int(np.ceil(hw)))]
        if abs(heading) == 0:
            return None
        ahead = z[-1] + np.arange(1.0, extra + 1.0) * heading / abs(heading)
        longer = fit_to_polyline(np.concatenate([z, ahead]), curve.base_angle,
                                 n_coef=int(np.ceil(curve.coef.size * 1.5)))
        longer = replace(longer, base=curve.base)
        r = refine(image, longer, look, iterations=6, fit_length=False, smoothing=0.1,
                   tol_px=tol, tip_stiffness=0.0)
        past = (r.u * r.curve.length > curve.length) & (r.u * r.curve.length
                                                         <= curve.length + 2.0 * hw)
        if past.any() and r.valid[past].mean() < RUN_ON_VALID:
            # the edges stop at the end, and noise beyond passed for a few pairs
            return None
        cut = _cut_to_edges(r, hw)
        if cut is not None:
            return cut
    return None


def _cut_to_edges(r: Refined, half_width: float, run: int = 2) -> Curve | None:
    """The curve cut back to half a width past the last of ``run`` consecutive
    profiles that found the tube's edges, when it runs on a width or more
    beyond them (else None): a skeleton that ran on into a dust speck by the
    tip (16 px too long, and its end then never found on a 320x240 frame)."""
    gap = _edge_gap(r, run, from_tip=True)
    if gap < 2.0 * half_width or gap > 0.5 * r.curve.length:
        return None
    return _cut_to_length(r.curve, r.curve.length - gap + half_width)


def _cut_to_length(curve: Curve, length: float) -> Curve:
    """``curve`` cut back to its first ``length`` px (same spline size and joints)."""
    s, z = resample(curve)
    return fit_to_polyline(z[s <= length], curve.base_angle, n_coef=curve.coef.size,
                           joints=curve.joints)


def _edge_gap(r: Refined, run: int = 3, *, from_tip: bool = False) -> float:
    """Arc length from the base (or the tip) to the first of ``run`` consecutive
    profiles that found the tube's edges, px (0 if there is none)."""
    ok, u = r.valid.astype(int), r.u
    if from_tip:
        ok, u = ok[::-1], 1.0 - u[::-1]
    if ok.size < run:
        return 0.0
    runs = np.convolve(ok, np.ones(run, int), mode="valid") == run
    if not runs.any():
        return 0.0
    return float(u[int(np.argmax(runs))] * r.curve.length)


def _predict(history: list[Curve]) -> Curve:
    if len(history) < 2:
        return history[-1]
    c1, c0 = history[-1], history[-2]
    return c1.with_params(2 * c1.coef - c0.coef, max(2 * c1.length - c0.length, 2.0))


def _crop_box(curve: Curve, margin: float, shape):
    basis = basis_of(curve)
    z = evaluate(curve, basis).z
    col, row = z.real, -z.imag
    r0 = int(max(0, np.floor(row.min() - margin)))
    r1 = int(min(shape[0], np.ceil(row.max() + margin) + 1))
    c0 = int(max(0, np.floor(col.min() - margin)))
    c1 = int(min(shape[1], np.ceil(col.max() + margin) + 1))
    return r0, r1, c0, c1


def _good(r: Refined, look: TubeLook, typical_px: float | None = None, *,
          end_gap_hw: float = END_GAP_HW) -> bool:
    """Whether a fit passes the checks of a tube's edges: enough of them
    found, its end found (or its length held), and their residual within a
    fixed limit (0.5 px or 8 % of the half-width), their own scatter
    (:data:`NOISE_RESIDUAL_RATIO`), or, given ``typical_px`` (the video's
    last frames'), within :data:`RESIDUAL_KEEP` of it."""
    # at a crossing the spline bridges the dropped profiles from both sides, as
    # long as most of the tube is still seen
    limit = max(0.5, 0.08 * look.mean_half_width,
                min(NOISE_RESIDUAL_RATIO * r.noise_px, NOISE_RESIDUAL_MAX_PX))
    if typical_px is not None:
        limit = max(limit, min(RESIDUAL_KEEP * typical_px,
                               RESIDUAL_KEEP_MAX_HW * look.mean_half_width))
    return (r.valid_fraction >= MIN_VALID and r.coverage >= MIN_COVERAGE
            and (r.tip_found or r.length_held)
            and r.end_gap_px <= end_gap_hw * look.mean_half_width
            and r.residual_px <= limit)


def _accepted(r: Refined | None, look: TubeLook, length: float,
              typical_px: float | None = None) -> bool:
    """:func:`_good`, and the length within :data:`MAX_LENGTH_STEP` of
    ``length`` (a neighbouring frame's): a tube does not grow or shrink by a
    tenth between frames, and an end found that far off is noise or dust
    beyond the tip, followed over the rounds. (The stretch it may run at
    its end without the tube's side edges: :func:`_end_gap_hw`.)"""
    return (r is not None and _good(r, look, typical_px, end_gap_hw=_end_gap_hw(r, length))
            and _length_kept(r, length))


def _end_gap_hw(r: Refined, length: float) -> float:
    """How far (half-widths) the fit ``r`` may run at its end without the
    tube's side edges: :data:`SMEARED_END_GAP_HW` where it found the end
    within :data:`LENGTH_JUMP` of ``length`` (a neighbouring frame's), else
    :data:`END_GAP_HW`."""
    kept = r.tip_found and abs(r.curve.length - length) <= LENGTH_JUMP * length
    return SMEARED_END_GAP_HW if kept else END_GAP_HW


def _length_kept(r: Refined, length: float) -> bool:
    """Whether the fit's length is within :data:`MAX_LENGTH_STEP` of ``length``."""
    return abs(r.curve.length - length) <= MAX_LENGTH_STEP * length


def _ran_on(r: Refined, length: float) -> str:
    """Why a fit whose end ran on without the tube's side edges is lost."""
    if not _length_kept(r, length):
        return "lost: the tube's length jumped (end not found)"
    return "lost: the end ran on past the tube's side edges (end not found)"


def _score(r: Refined) -> float:
    return (r.valid_fraction * (1.0 if r.tip_found or r.length_held else 0.5)
            / (1.0 + r.residual_px))


def track_frames(frames: Iterable[np.ndarray], *, base_hint=None, base_end=None,
                 first_detection=None, progress: Callable[[int], None] | None = None,
                 settings: TrackSettings | None = None,
                 joints: tuple[float, ...] | None = None) -> Iterator[FrameTrack]:
    """Track the tube through ``frames`` (2-D arrays, any of uint8/uint16/float).

    Parameters
    ----------
    frames : iterable of (rows, cols) ndarray
        Greyscale frames, streamed.
    base_hint : (col, row), optional
        Where the tube leaves the pipette, px (e.g. from ``--base``): the
        base is held there (moved with a drifting stage); the first frames
        still vote on its tangent (:data:`BASE_VOTE_FRAMES`).
    base_end : (col, row), optional
        A point near the base end of the tube (which end is held), px; the
        base itself is then found along the tube.
    first_detection : Detection, optional
        The first frame's detection, when the caller has already made it.
    progress : callable, optional
        Called with each frame index once it is done.
    settings : TrackSettings, optional
        The knobs that trade accuracy for speed (default: ``TrackSettings()``).
    joints : tuple of float, optional
        The tube's section joints, as fractions of its length from the base
        (e.g. from the sample's sections), where the curvature may step; the
        centreline's spline gets a triple knot at each. ``()`` for a tube of
        one section; None (default) when not known: they are then looked for
        in the frames.

    Yields
    ------
    FrameTrack
        One per frame, in order, as fitted on its own; :func:`hold_section_ratio`
        then holds a jointed tube's last section to the ratio all frames tell
        (as :func:`pipeline.tracks.track_video` does).
    """
    settings = settings or TrackSettings()
    look: TubeLook | None = None
    history: list[Curve] = []
    lost_run = 0
    held_base = base_hint
    # the joints are looked for in the frames only when they were not given;
    # ``known`` is None while they are not known
    search_from = np.radians(JOINT_CHECK_DEG) if joints is None else np.inf
    known = None if joints is None else tuple(float(j) for j in joints)
    given = known is not None
    # the tube's width along its length over the frames, where (joints not
    # given) the joints are looked for as width steps; those it has shown are
    # kept by the kink search
    widths = None if given else WidthRecord()
    # (joints, last section's curvature over the one before's) when last seen whole
    tip_ratio: tuple[tuple[float, ...], float] | None = None
    # the last shape seen whole (not at a crossing): what a hidden end follows
    last_whole: Curve | None = None
    # where the base was found on the first frames, and those frames' results
    # (with the frames) held back until it is settled (with --base, its
    # tangent alone)
    votes = _BaseVotes()
    # a relief's edge steps until its shear direction can be told
    shear_votes = _ShearVotes()
    # how far the edges near the tube's end sit off the rest's line, until that tells
    end_votes = _EndVotes()
    cap_votes = _CapVotes()
    trend_votes = _TrendVotes()
    end_step_votes = _EndStepVotes()
    # the edges' residual on the last frames measured (not at crossings)
    residuals: list[float] = []
    # the tube's length on the last frames measured where it does not cross itself
    lengths: list[float] = []
    # (each with its frame as float32)
    # (with --base, the base point is the user's: the frames vote on its
    # tangent alone)
    pending: list[tuple[FrameTrack, np.ndarray]] | None = []
    # the stage's drift, read from the holder around the base (from the first
    # frame measured on)
    drift: StageDrift | None = None
    # (the shift followed by earlier starts' drifts: a restart finds the base
    # afresh, and its drift is measured from there)
    carried = 0j
    # (the shift measured on each frame held back for the base's vote, where
    # the stage stood on the first frame; from the frame the drift's region
    # was taken on, this start's)
    measured: dict[int, complex] = {}
    # (the region is looked for once per start: on its first frame measured)
    looked = False

    def followed() -> complex:
        return carried + (drift.followed if drift is not None else 0j)
    for index, frame in enumerate(frames):
        if frame.ndim != 2:
            raise ValueError(f"frame {index} is not a greyscale 2-D array: shape {frame.shape}")
        det = first_detection if index == 0 else None
        if drift is not None:
            # a drifting stage carries the held base, and the shapes that predict
            # this frame, with it
            before = followed()
            # (without a motion yet the last shape would leave the tube's own
            # move in the region)
            if drift.due():
                drift.measure(frame, _predict(history) if len(history) >= 2 else None)
            step = followed() - before
            if step:
                history = [replace(h, base=h.base + step) for h in history]
                if held_base is not None and base_hint is None:
                    held_base = (held_base[0] + step.real, held_base[1] - step.imag)
        hint = base_hint
        if base_hint is not None:
            hint = (base_hint[0] + followed().real, base_hint[1] - followed().imag)
        search = bool(history) and abs(history[-1].coef[-1]) >= search_from
        typical = (float(np.median(residuals))
                   if history and len(residuals) >= RESIDUAL_JUMP_FRAMES else None)
        # a restart finds the base afresh, at the end of the tube nearest the one
        # held before (so that the ends cannot swap); only --base fixes it
        restart_end = held_base if base_hint is None and held_base is not None else base_end
        result = _track_one(index, frame, look, history, hint, restart_end, det, settings,
                            known, search, tip_ratio, widths, typical,
                            float(np.median(lengths)) if history and lengths else None,
                            last_whole)
        if isinstance(result, tuple):  # (re)initialised: a new look, a new history
            old_look, (result, look) = look, result
            history, residuals, lengths, last_whole = [], [], [], None
            # (the stage measured from this start's region: an earlier start's
            # may have been on something else)
            carried, drift, measured, looked = followed(), None, {}, False
            if pending is not None:
                # the base is voted on by this start's frames: an earlier start,
                # lost since, may have been on something else (a curl's first
                # frames taken for a short tube: its votes put the base 58 px
                # into the pipette of a video that starts curled past a turn)
                # (a tube entering from the frame's edge: its tangents carried back there)
                votes = _BaseVotes(from_edge=result.base_source.startswith(BORDER_BASE))
            if old_look is not None and old_look.shear is not None and look.polarity == 0:
                look = replace(look, shear=old_look.shear)  # the microscope's, not the tube's
            if old_look is not None and old_look.end_clear:
                look = replace(look, end_clear=True)  # the tube's end and the optics'
            if old_look is not None and old_look.tip_trend:
                look = replace(look, tip_trend=True)  # the tube's own, as its votes are
            if old_look is not None and old_look.end_step_px is not None:
                look = replace(look, end_step_px=old_look.end_step_px,
                               end_step_offset=old_look.end_step_offset)
            if base_hint is None and held_base is not None and result.base_source:
                result = replace(result, base_source=result.base_source
                                 + " (at the end nearest the base of an earlier frame)")
        if search and result.ok:
            search_from = JOINT_CHECK_GROWTH * abs(result.tracked.coef[-1])
        if result.ok and result.curve.joints != (known or ()):
            known = result.curve.joints if result.curve.joints or given else None
        if result.ok and history and ((result.curve.joints, result.curve.coef.size)
                                      != (history[-1].joints, history[-1].coef.size)):
            # joints found (or the spacing changed) on this frame: the shapes that
            # predict the next frames are rewritten alike (their coefficients are
            # extrapolated)
            history = [rewritten(h, result.curve.joints, result.curve.coef.size)
                       for h in history]
        image = None
        if pending is not None:
            # held back with its result until the base is settled (a copy: a
            # reader may hand out the same buffer for every frame)
            image = as_float(frame)
            image = image.copy() if image is frame else image
        if result.ok:
            history = (history + [result.tracked])[-2:]
            if not result.crossing:
                residuals = (residuals + [result.residual_px])[-RESIDUAL_JUMP_FRAMES:]
                lengths = (lengths + [result.curve.length])[-RESIDUAL_JUMP_FRAMES:]
            lost_run = 0
            result = replace(result, end_clear=look.clears_end, cap=look.cap)
            if not result.crossing:
                look = end_votes.add(result.end_offset, look)
                cap_before = look.cap
                look = cap_votes.add(result.cap_shape, look)
                if cap_before is None and look.cap:
                    # the lengths so far ended at the lines' ends, short of a
                    # round cap's apex: a frame measured to its apex would
                    # read as a jump from them and be held at their length
                    lengths = []
                look = end_step_votes.add(result.end_steps, look, result.bend_angle_rad)
                look = trend_votes.add(result.fit, look)
            if look.end_step_px:
                result = replace(result, end_step=_told_step(look))
            result = replace(result, look=look)
            if look.polarity == 0 and look.shear is None and not result.crossing:
                image = as_float(frame) if image is None else image
                look = shear_votes.add(image, result.tracked, look)
                if look.shear is not None:
                    result = replace(result, shear_deg=float(np.degrees(look.shear)))
            if not result.crossing:
                ratio = section_ratio(result.tracked)
                tip_ratio = None if ratio is None else (result.tracked.joints, ratio)
                last_whole = result.tracked
            # the pipette holds the base still: a restart finds the tube from the
            # same base, so the ends cannot swap (which would flip the angle's sign)
            held_base = hint if base_hint is not None else _base_col_row(result.curve)
            if not looked:
                looked = True
                drift = StageDrift.start(frame, result.tracked, look.mean_half_width)
                measured = {index: carried} if drift is not None else {}
            elif drift is not None and pending is not None and drift.fresh:
                measured[index] = carried + drift.shift
            result = replace(result, stage_shift=followed())
            if pending is not None and not result.crossing:
                votes.add(image, result.tracked, look, settings, index, result.stage_shift)
        else:
            result = replace(result, stage_shift=followed())
            lost_run += 1
            if lost_run >= RESTART_AFTER:
                # the last good shape may itself be wrong: start afresh
                history = []
        if pending is not None:
            pending.append((result, image))
            if len(votes.points) < BASE_VOTE_FRAMES:
                continue
            path = _stage_path(pending, drift, measured)
            pending, restaged = _staged(pending, path)
            base, turn = votes.settled(history, followed(), path)
            base = base if base_hint is None else None
            turn, aside = _turn_past_holder(pending, history, base, turn,
                                            look.mean_half_width, look, settings)
            if base is not None or turn:
                history = [moved_base(h, None if base is None else base + followed(), turn,
                                       look.mean_half_width, aside=aside)
                           for h in history]
                if base_hint is None:
                    held_base = _base_col_row(history[-1])
            done, pending = _refitted(pending, base, turn, look, settings, restaged,
                                      aside), None
        else:
            done = [result]
        for r in done:
            yield r
            if progress is not None:
                progress(r.frame)
    if pending:  # a video shorter than the vote
        path = _stage_path(pending, drift, measured)
        pending, restaged = _staged(pending, path)
        base, turn = votes.settled(history, followed(), path)
        for r in _refitted(pending, base if base_hint is None else None, turn, look, settings,
                           restaged):
            yield r
            if progress is not None:
                progress(r.frame)


@dataclass
class _ShearVotes:
    """A relief's signed edge steps over the frames (:func:`relief_edges`),
    until the tube has turned enough for its shear direction to be fitted."""

    theta: list[np.ndarray] = field(default_factory=list)
    signed: list[np.ndarray] = field(default_factory=list)

    def add(self, image: np.ndarray, curve: Curve, look: TubeLook) -> TubeLook:
        """``look`` with its shear, if this frame's steps make it known."""
        theta, signed = relief_edges(image, curve, look)
        self.theta.append(theta)
        self.signed.append(signed)
        shear = relief_shear(np.concatenate(self.theta), np.concatenate(self.signed))
        return look if shear is None else replace(look, shear=shear)


@dataclass
class _EndVotes:
    """The side edges' midpoints near the tube's end against the line the rest
    of the tube's give (:attr:`pipeline.refine.Refined.end_offset`), frame by
    frame, until they show a steady offset: then the end's edges are left out
    (:attr:`pipeline.refine.TubeLook.end_clear`).

    A hollow tube whose walls differ in thickness shows, under blur, its thin
    wall's edge further out than it is (a blurred thin line's flank lies
    outside it), so the edge midpoints sit off the tube's axis by a steady
    amount; near the end the end face's own blur fills the lumen, that pull
    fades, and the last profiles sit back on the axis. The fit then bends the
    tip to reach them. Looked for only where the tube is brighter than its
    surroundings at its edges (fluorescence: a wall glows in proportion to its
    thickness). Under transmitted light the edges are the outer walls' dark
    rims whatever the walls' thickness; there the end's edges, even where they
    sat 0.1-0.2 px off, held the tip tangent better than the extrapolation
    without them (measured on 182 rendered scenes: of the 7 dark-edged scenes
    that showed such an offset, 5 got worse without their end's edges, db00
    0.22 -> 0.37 deg median).
    """

    offsets: list[float] = field(default_factory=list)

    def add(self, offset: float, look: TubeLook) -> TubeLook:
        """``look``, with its end's edges left out once the offsets so far say so."""
        if not look.end_in_question or not np.isfinite(offset):
            return look
        self.offsets.append(offset)
        if len(self.offsets) < END_VOTE_FRAMES:
            return look
        x = np.asarray(self.offsets)
        mean, se = abs(x.mean()), x.std(ddof=1) / np.sqrt(x.size)
        if mean >= END_OFFSET_MIN_PX and mean >= END_OFFSET_Z * se:
            return replace(look, end_clear=True)
        return look


@dataclass
class _CapVotes:
    """The end's shape the first frames' fits saw (:attr:`FrameTrack.cap_shape`),
    until :data:`CAP_VOTE_FRAMES` have: then the look's :attr:`TubeLook.cap`
    is their median, at most 1 (0 where it is under :data:`CAP_MIN`).

    A round cap (an independent renderer's tubes: the lines 0.4 and 0.7
    half-widths off the axis ended 0.08 and 0.28 of them short of the apex,
    a hemisphere's 0.083 and 0.286) put the tip 0.7-2 px short of its apex,
    and the bend short by the curvature times that (up to 1.4 deg on a
    22 px tube curled 320 deg); a flat end face, this package's renderer's,
    shows no such pattern."""

    shares: list[float] = field(default_factory=list)

    def add(self, share: float, look: TubeLook) -> TubeLook:
        """``look``, with its end's shape set once the frames so far tell it."""
        if look.cap is not None or not np.isfinite(share):
            return look
        self.shares.append(share)
        if len(self.shares) < CAP_VOTE_FRAMES:
            return look
        share = float(np.median(self.shares))
        # (a flat end's corners, blurred, end the lines beside the axis a little
        # early too: shares of 0.07-0.26 on this package's blurred scenes)
        return replace(look, cap=float(min(share, 1.0)) if share >= CAP_MIN else 0.0)


@dataclass
class _TrendVotes:
    """The curvature's rate of change g and its mean c over the stretch before
    the tube's stiff end stretch, frame by frame
    (:func:`pipeline.refine.trend_sample`), until :data:`TREND_VOTE_FRAMES`
    tell a ratio ρ = g/c (least squares of g = ρ·c) :data:`TREND_MIN_Z`
    standard errors from nought and changing the curvature by at least
    :data:`TREND_MIN_CHANGE` over the tube's length: then the look's
    :attr:`TubeLook.tip_trend` is set, and stays.

    Under the paper's models every curvature grows with the one load, so ρ is
    the tube's. (A line g = α + ρ·c, which would leave out what the load does
    not bend, told fewer ramps and more arcs on the independent sets: 96
    against 97 of 120 meeting every target, 5 arcs told.)

    The shape reported holds the tip stretch, where the edges say least, to a
    constant curvature unless told so. Held to the trend of the stretch before
    on every frame, it followed a curvature that ramps (an independent set,
    alien7, whose tubes' curvature grows by 10-30 % over their last 60 px:
    bend medians 0.6-1.8 -> 0.2-1.0 deg), but on arcs it carried that
    stretch's noise to the tip (medians up by > 0.02 deg on 51 of 97 scenes
    of the three other sets)."""

    samples: list[tuple[float, float]] = field(default_factory=list)

    def add(self, curve: Curve | None, look: TubeLook) -> TubeLook:
        """``look``, told the trend once the frames so far show one."""
        if look.tip_trend or curve is None:
            return look
        sample = trend_sample(curve, look.mean_half_width)
        if sample is None or not np.all(np.isfinite(sample)):
            return look
        self.samples.append(sample)
        if len(self.samples) < TREND_VOTE_FRAMES:
            return look
        g, c = np.array(self.samples).T
        cc = c @ c
        if not cc > 0:
            return look
        ratio = (g @ c) / cc
        rest = g - ratio * c
        se = np.sqrt((rest @ rest) / (g.size - 1) / cc)
        # (written so that a NaN tells nothing; and frames that fit the line
        # exactly, the same frame over and over, tell only a real change)
        if not (abs(ratio) >= TREND_MIN_Z * se
                and abs(ratio) * curve.length >= TREND_MIN_CHANGE):
            return look
        return replace(look, tip_trend=True)


@dataclass
class _EndStepVotes:
    """How far the edge midpoints over stretches of
    :data:`pipeline.refine.END_STEP_ZONES_HW` half-widths at a dark tube's end
    sit off the line the rest of the tube's give
    (:attr:`pipeline.refine.Refined.end_steps`), frame by frame, until they
    show a steady offset: then that stretch's side edges are left out of the
    fits, or given a sideways offset of their own
    (:attr:`pipeline.refine.TubeLook.end_step_px`,
    :func:`pipeline.refine.end_step_left_out`).

    The stretch is the one whose offset, over the frames so far, lowers the
    residual sum of squares most (offset² times its weight): a shorter one
    than the true step sees the same offset on fewer profiles, a longer one a
    diluted offset. (The offset learned here and taken off instead turned the
    tip the wrong way where it was noise; a free offset of the stretch's own
    left the blurred step's slope in: see the look's ``end_step_px``.)

    On a bright tube only where the offsets also grow with the bend, as a
    straight plug's do (:func:`pipeline.plug.grows_with_bend`): on 7 of the
    182 evaluation scenes' fluorescent tubes the same test alone told a
    "step" 1-2.5 half-widths long (shading across the tube; on 3 its offset
    changed sign along the stretches), and leaving it out moved 3 angle
    medians from 0.2-0.4 to 2-4 deg.
    """

    steps: list[np.ndarray] = field(default_factory=list)
    bends: list[float] = field(default_factory=list)

    def add(self, steps: np.ndarray | None, look: TubeLook, bend: float = np.nan) -> TubeLook:
        """``look``, with its end's stretch set once the frames so far tell it
        (``bend``: the frame's, rad)."""
        if not look.end_step_in_question or steps is None:
            return look
        self.steps.append(steps)
        self.bends.append(bend)
        if len(self.steps) < END_VOTE_FRAMES:
            return look
        x = np.stack(self.steps)
        offset, weight, noise = x[..., 0], x[..., 1], np.maximum(x[..., 2], 1e-6)
        seen = np.isfinite(offset) & np.isfinite(noise)
        best = int(np.argmax(np.where(seen, offset**2 * weight, 0.0).sum(axis=0)))
        col = offset[seen[:, best], best]
        # a step has an end: past it, longer stretches dilute the offset. One
        # that still grows at the longest stretch scanned is the curve's own
        # misfit there (a short, tighter last section), not a step
        if col.size >= END_VOTE_FRAMES and best < len(END_STEP_ZONES_HW) - 1:
            mean, se = abs(col.mean()), col.std(ddof=1) / np.sqrt(col.size)
            # the offsets' mean weighted by their noise, in its standard errors
            inv = 1.0 / noise[seen[:, best], best] ** 2
            z_noise = abs(np.sum(col * inv)) / np.sqrt(np.sum(inv))
            # (a bright tube's only where the offsets grow with the bend, as a
            # straight plug's do: its shading makes steady "steps" of its own)
            if (mean >= END_OFFSET_MIN_PX and mean >= END_OFFSET_Z * se
                    and z_noise >= END_STEP_Z
                    and (look.polarity == -1
                         or grows_with_bend(np.asarray(self.bends)[seen[:, best]], col))):
                px = END_STEP_ZONES_HW[best] * look.mean_half_width
                return replace(look, end_step_px=px, end_step_offset=float(col.mean()))
        if len(self.steps) >= END_STEP_MAX_FRAMES:
            return replace(look, end_step_px=0.0)
        return look


def _lean_from_edge(curve: Curve, half_width: float, shape) -> float:
    """How far (rad) the tangent at the base of a tube entering from the
    frame's edge (:func:`pipeline.segment.base_at_edge`) has turned since the
    edge: its curvature over its first two half-widths times the distance
    back to the edge; 0 for a base away from the edge.

    The fits start the tube at its first whole profile, that far inside (26
    px for a tube 8 px in half-width entering at 60 deg to the edge's
    normal), where a tube held at the edge has turned already as it bends:
    the first frames' base tangents, bent up to 30 deg, leaned into the
    bend by up to 3 deg, and their median held it 0.9 deg off on every
    frame. Only where the base lies a half-width or more from the edge (a
    slanted entry): nearer, the turn is within the fits' own scatter, and
    carrying it back did more harm than good (an independent renderer's
    tube 2.7 px from the edge: a median 0.12 -> 0.26 deg)."""
    d = base_at_edge(curve.base, curve.base_angle, half_width, shape)
    if d is None or d < half_width:
        return 0.0
    return _lean_back(curve, half_width, d)


def _lean_back(curve: Curve, half_width: float, distance: float) -> float:
    """How far (rad) ``curve``'s tangent turns over ``distance`` px back from
    its base, at its curvature over its first two half-widths (0 for a curve
    under two half-widths long)."""
    if curve.length <= 2.0 * half_width or not np.isfinite(distance):
        return 0.0
    basis = basis_of(curve)
    smp = evaluate(curve, basis)
    reach = 2.0 * half_width
    phi = float(np.interp(reach, basis.u * curve.length, smp.phi))
    return (phi - curve.base_angle) / reach * distance


#: A tube entering from the frame's edge has its base tangent voted on from
#: fits that start this many of its half-widths in from its first whole
#: profile (and carried back to the edge, :func:`_lean_back`): the profiles
#: next to an oblique border pulled the base tangent of a straight tube 0.5
#: deg off (an independent renderer's tube entering at 35 deg to the edge
#: near a corner: 55.5 deg for 55.0; from 10-30 px in, 55.0-55.1).
EDGE_SKIP_HW = 2.0


@dataclass
class _BaseVotes:
    """Where the first frames show the base (:data:`BASE_VOTE_FRAMES`), and
    its tangent: the holder's axis where it shows, else a fit with φ(0) free
    (from :data:`EDGE_SKIP_HW` half-widths in, for a tube entering the
    frame's edge at a slant)."""

    #: where each frame shows it, px, and the frame
    points: list[complex] = field(default_factory=list)
    frames: list[int] = field(default_factory=list)
    #: the stage's shift each frame's fit followed, px
    stages: list[complex] = field(default_factory=list)
    #: (|bend|, base tangent measured − the one in use), rad
    turns: list[tuple[float, float]] = field(default_factory=list)
    #: whether the base is where the tube enters from the frame's edge (the
    #: start found no holder): each tangent is then carried back to the edge
    #: (:func:`_lean_from_edge`)
    from_edge: bool = False

    def add(self, image: np.ndarray, curve: Curve, look: TubeLook,
            settings: TrackSettings, frame: int = 0, stage: complex = 0j) -> None:
        """This frame's findings, ``curve`` being its fit on frame ``frame``
        and ``stage`` the stage's shift that fit followed (px)."""
        self.points.append(locate_base(image, curve, look).base)
        self.frames.append(frame)
        self.stages.append(stage)
        # the base tangent as initialise measures it: the pipette's axis, at any
        # bend; else φ(0) free, under the strong roughness penalty that makes it
        # follow the whole tube
        axis = pipette_axis(image, curve, look)
        if axis is not None:
            self.turns.append((0.0, axis[0] - curve.base_angle))
            return
        hw = look.mean_half_width
        # (a slanted entry only: there the first whole profile lies a
        # half-width or more from the edge, and the profiles next to it sit
        # beside the edge on one side)
        at = base_at_edge(curve.base, curve.base_angle, hw, image.shape[:2])
        skip = EDGE_SKIP_HW * hw if self.from_edge and at is not None and at >= hw else 0.0
        start = cut_base(curve, skip) if skip and curve.length > 8.0 * skip else curve
        fit = _free_base_fit(image, start, look, settings.tol_px)
        if _good(fit, look):
            if start is not curve:
                # carried back from there to the edge, as it turns there
                lean = _lean_back(fit.curve, hw, edge_behind(fit.curve.base,
                                                             fit.curve.base_angle,
                                                             image.shape[:2])[0])
            elif self.from_edge:
                lean = _lean_from_edge(fit.curve, hw, image.shape[:2])
            else:
                lean = 0.0
            self.turns.append((abs(curve.coef[-1]), fit.curve.base_angle - lean
                               - curve.base_angle))

    def settled(self, history: list[Curve], stage: complex = 0j,
                path: dict[int, complex] | None = None) -> tuple[complex | None, float]:
        """``(base, turn)``: where the base goes (where the stage stood on
        the first frame; None: where it is) and how far its tangent turns
        (see below). ``stage``: the stage's shift on the last frame of
        ``history``, px; ``path``: its shift on the frames voting, by frame,
        where known (else the one their fits followed)."""
        path = path or {}
        # (where the stage stood on the first frame: a drifting stage carries it)
        points = [p - path.get(f, s)
                  for p, f, s in zip(self.points, self.frames, self.stages, strict=True)]
        return _settled_base(history, points, stage), _settled_turn(self.turns)


def _settled_base(history: list[Curve], votes: list[complex], stage: complex = 0j
                  ) -> complex | None:
    """Where the base goes: the median along the base axis of ``votes``, on the
    axis of the last curve in ``history`` (its base taken back by ``stage``,
    where the stage stood on the first frame, as the votes are); None when
    that is less than :data:`BASE_MOVE_MIN_PX` from its base (or there is
    nothing to move)."""
    if not history or not votes:
        return None
    curve = history[-1]
    axis = np.exp(1j * curve.base_angle)
    base = curve.base - stage
    shift = float(np.median(np.real((np.asarray(votes) - base) * np.conj(axis))))
    return base + shift * axis if abs(shift) > BASE_MOVE_MIN_PX else None


def _settled_turn(angle_votes: list[tuple[float, float]]) -> float:
    """The change of the base tangent (rad) to the median of the first frames'
    measurements of it, ``(|bend|, measured − in use)`` in rad: of those bent
    at most :data:`BASE_ANGLE_MAX_BEND_DEG` and within
    :data:`BASE_ANGLE_SPREAD_DEG` of the one in use; 0 unless there are at
    least :data:`BASE_ANGLE_MIN_VOTES`. When no frame is that little bent (a
    video that starts bent), of all those within the spread, if they agree
    (:data:`BASE_ANGLE_AGREE_DEG`)."""
    spread = [(bend, turn) for bend, turn in angle_votes
              if abs(turn) <= np.radians(BASE_ANGLE_SPREAD_DEG)]
    near = [turn for bend, turn in spread if bend <= np.radians(BASE_ANGLE_MAX_BEND_DEG)]
    if not any(bend <= np.radians(BASE_ANGLE_MAX_BEND_DEG) for bend, _ in angle_votes):
        # a video that starts bent: the votes at any bend, if they agree
        near = np.array([turn for _, turn in spread])
        if len(near) < BASE_ANGLE_MIN_VOTES or (
                MAD_TO_SD * np.median(np.abs(near - np.median(near)))
                > np.radians(BASE_ANGLE_AGREE_DEG)):
            return 0.0
    elif len(near) < BASE_ANGLE_MIN_VOTES:
        return 0.0
    turn = float(np.median(near))
    return turn if abs(turn) >= np.radians(BASE_TURN_MIN_DEG) else 0.0


def _stage_path(pending, drift: StageDrift | None, measured: dict[int, complex]
                ) -> dict[int, complex]:
    """The stage's shift on each measured frame held back since the drift's
    region was taken (the first of ``measured``), by frame, once the drift is
    followed (empty before): the shifts ``measured`` on some of them,
    interpolated between. (Frames of an earlier start keep their own.)"""
    if drift is None or not drift.following or len(measured) < 2:
        return {}
    at = sorted(measured)
    shifts = np.array([measured[k] for k in at])
    return {r.frame: complex(np.interp(r.frame, at, shifts.real),
                             np.interp(r.frame, at, shifts.imag))
            for r, _ in pending if r.ok and r.frame >= at[0]}


def _staged(pending, path: dict[int, complex]):
    """The held-back frames, where the stage had taken them (``path``: its
    shift by frame, see :func:`_stage_path`; not where that is within
    :data:`RESTAGE_MIN_PX` of where they were fitted), and those moved, as
    they were, by frame (to be refitted, or kept as they were where the refit
    fails: :func:`_refitted`)."""
    out, moved = [], {}
    for r, image in pending:
        if r.frame in path and abs(path[r.frame] - r.stage_shift) >= RESTAGE_MIN_PX:
            moved[r.frame] = r
            r = _on_stage(r, path[r.frame])
        out.append((r, image))
    return out, moved


#: A held-back frame is moved where the stage had taken it only from this far
#: (px): a refit for less changes nothing.
RESTAGE_MIN_PX = 0.05


def _on_stage(r: FrameTrack, shift: complex) -> FrameTrack:
    """``r`` with its curves moved to where the stage's ``shift`` (px) takes
    them from where its own :attr:`FrameTrack.stage_shift` did."""
    if not r.ok or shift == r.stage_shift:
        return r
    return replace(r.moved(shift - r.stage_shift), stage_shift=shift)


def moved_base(curve: Curve, base: complex | None, turn: float = 0.0,
                slide_px: float = 0.0, aside: complex = 0j) -> Curve:
    """``curve`` with its base moved along its base axis to abreast of
    ``base`` and its base tangent turned by ``turn`` rad (the shape past the
    first spline span kept: B_0 = 1 − Σ B_k, so φ(0) + d with every other
    coefficient − d changes φ only where B_0 is not 0).

    A move of at most ``slide_px`` (px) slides the whole curve along the axis
    (its tip kept abreast); a longer one cuts it where it first gets that far
    along the axis, or carries it straight back, the shape beyond kept (the
    joints at the same fractions of the length, as the width record and the
    frames after them have them). Where the tracked structure turns off the
    axis near its start (a skeleton that ran into a wide glass at a slant),
    a slide of tens of px put a bent tube's far end as far off the frame's,
    and its refit found no edges. With ``base``, the moved base is then
    shifted by ``aside`` px (see :func:`_turn_past_holder`)."""
    if base is None:
        return replace(curve, base_angle=curve.base_angle + turn, coef=curve.coef - turn)
    axis = np.exp(1j * curve.base_angle)
    shift = float(np.real((base - curve.base) * np.conj(axis)))
    if abs(shift) <= slide_px:
        moved = replace(curve, base=curve.base + shift * axis,
                        length=max(curve.length - shift, 2.0),
                        base_angle=curve.base_angle + turn, coef=curve.coef - turn)
    else:
        if shift > 0:
            shift = _cut_at(curve, base)[0]
        # (the base tangent as before, turned: the votes measured it against that)
        moved = cut_base(curve, min(shift, curve.length - 2.0), curve.base_angle + turn,
                         curve.joints)
    return replace(moved, base=moved.base + aside) if aside else moved


def _cut_at(curve: Curve, base: complex) -> tuple[float, float]:
    """How far along ``curve`` (px of arc) it first gets as far along its base
    axis as ``base``, and its tangent there, rad (for a ``base`` ahead of
    its own: ``(0, base tangent)`` otherwise)."""
    axis = np.exp(1j * curve.base_angle)
    shift = float(np.real((base - curve.base) * np.conj(axis)))
    if shift <= 0:
        return 0.0, curve.base_angle
    basis = basis_of(curve, int(np.ceil(curve.length / 0.25)) + 1)
    smp = evaluate(curve, basis)
    along = np.real((smp.z - curve.base) * np.conj(axis)) >= shift
    k = int(np.argmax(along)) if along.any() else smp.z.size - 1
    return float(basis.u[k] * curve.length), float(smp.phi[k])


def _turn_past_holder(pending, history: list[Curve], base: complex | None, turn: float,
                      half_width: float, look: TubeLook | None = None,
                      settings: TrackSettings | None = None) -> tuple[float, complex]:
    """The base tangent's turn (rad) once the base is settled at ``base``
    (px, where the stage stood on the first frame; None: not moved): ``turn``
    (the first frames' votes), unless the base moved forward, along the
    curves, by more than ``half_width``: then the median of the held-back
    frames' own tangents where their curves pass the new base (of those bent
    at most :data:`BASE_ANGLE_MAX_BEND_DEG`, or of all where none is), less
    the base tangent in use.

    The votes were measured on fits from the old base, whose first stretch
    lay in the holder (a glass wider than the tube, which the first frame's
    skeleton ran into at a slant: φ(0) 15° off the glass's axis), and
    the spline carries that turn on past the new base.

    With ``look`` (and ``settings``), each of those tangents is measured
    again from the new base (:func:`_free_base_fit` on the frame's curve
    cut there), where that
    fit passes the checks: the curves' own tangent there still carries the
    hook they made into the holder (a 40 px tube whose capillary's first
    36 px were cut: the bend 4.8 deg off on every frame). Those fits' base
    also moves sideways onto the tube: the median of how far is returned
    too (px; 0 otherwise), for the base to follow (the same tube's base
    had stayed 2.8 px aside of its axis, on the hooked curve).

    Returns
    -------
    (turn, aside)
        rad, and px (y up)."""
    if base is None or not history:
        return turn, 0j
    ref = history[-1]
    held = [(r, image) for r, image in pending if r.ok]
    cuts = [(abs(r.bend_angle_rad), *_cut_at(r.tracked, base + r.stage_shift))
            for r, _ in held]
    if not cuts or np.median([s for _, s, _ in cuts]) <= half_width:
        return turn, 0j
    little = [k for k, (bend, _, _) in enumerate(cuts)
              if bend <= np.radians(BASE_ANGLE_MAX_BEND_DEG)] or list(range(len(cuts)))
    phis = np.asarray([cuts[k][2] for k in little])
    if look is not None and all(held[k][1] is not None for k in little):
        tol = (settings or TrackSettings()).tol_px
        again, asides = [], []
        for k in little:
            (r, image), (_, s, phi) = held[k], cuts[k]
            if s >= r.tracked.length - 4.0 * half_width:
                continue
            cut = cut_base(r.tracked, s, phi)
            fit = _free_base_fit(image, cut, look, tol)
            if _good(fit, look):
                # (the holder's axis where it shows, as the votes take it: a
                # fit to a bent tube leans into the bend; else the line of the
                # held-back curve's stretch through the holder, its centres of
                # symmetry or its edges: a pipette the skeleton ran 76 px into,
                # that fit 0.6 deg off on every frame)
                axis = pipette_axis(image, fit.curve, look)
                axis = (axis[0] if axis is not None
                        else _holder_line(image, r.tracked, s, half_width))
                again.append(fit.curve.base_angle if axis is None else axis)
                asides.append(locate_base(image, fit.curve, look).base - cut.base)
        if again:
            aside = complex(np.median(np.real(asides)), np.median(np.imag(asides)))
            return float(np.median(again)) - ref.base_angle, aside
    return float(np.median(phis)) - ref.base_angle, 0j


def _holder_line(image: np.ndarray, curve: Curve, s: float, half_width: float
                 ) -> float | None:
    """:func:`pipeline.pipette.holder_line` (imported here: pipette imports
    this module)."""
    from .pipette import holder_line

    return holder_line(image, curve, s, half_width)


def _refitted(pending, base: complex | None, turn: float, look: TubeLook | None,
              settings: TrackSettings, restaged: dict | None = None,
              aside: complex = 0j) -> list[FrameTrack]:
    """The held-back results, each measured frame refitted from its base moved
    to ``base`` (where the stage stood on the first frame: each frame's own
    stage shift is added) and its base tangent turned by ``turn``, to its end's
    round cap if the frames told one (:class:`_CapVotes`), and with its end's
    sideways step if the frames after it told one (:class:`_EndStepVotes`;
    kept as it was if that fit fails the checks); the frame that found the
    base says it was moved. The frames ``restaged`` (moved where a drifting
    stage had taken them, by frame, as they were: :func:`_staged`) are
    refitted too, and kept as they were where that fails. Frames lost before
    a measured one are then tracked backwards from it."""
    restaged = restaged or {}
    out = []
    moves = base is not None or bool(turn)
    # (a round cap told after the first frames: theirs were fitted short of it)
    capped = look is not None and bool(look.cap)
    for result, image in pending:
        stepped = (look is not None and bool(look.end_step_px) and result.ok
                   and result.end_step is None)
        if not result.ok or look is None or not (moves or stepped or capped
                                                 or result.frame in restaged):
            out.append(result)
            continue
        moved = (moved_base(result.tracked, None if base is None else base + result.stage_shift,
                             turn, look.mean_half_width, aside=aside)
                 if moves else result.tracked)
        if result.base_source and moves:
            shift = result.tracked.length - moved.length
            said = ([f"moved {abs(shift):.1f} px " + ("towards the tip" if shift > 0 else
                                                     "back along the pipette axis")]
                    if base is not None else [])
            said += [f"its tangent turned {np.degrees(turn):+.2f} deg"] if turn else []
            result = replace(result, base_source=(
                f"{result.base_source}; then {' and '.join(said)}, to the median of what the "
                "first frames show"))
        r = refine(image, moved, look, iterations=settings.first_rounds,
                   avoid_contact=result.crossing, tol_px=settings.tol_px)
        out.append(replace(result, curve=_reported(r), fit=r.curve, residual_px=r.residual_px,
                           valid_fraction=r.valid_fraction, last_section=r.last_section,
                           end_clear=look.clears_end, end_step=_told_step(look),
                           end_offset=r.end_offset, end_steps=r.end_steps,
                           told_offset=r.told_offset, end_profile=r.end_profile,
                           tip_hold=r.tip_hold)
                   if _good(r, look) else restaged.get(result.frame, result))
    # a held-back frame that bent away from the frames either side of it and
    # back (the frame after a start has no motion to be predicted from, and a
    # fresh detection can hook into noise by a faint tip and fit as well) is
    # tracked again, backwards from the frame after it, as a lost one is
    # (the farthest off first: a frame next to a spike is off from its mean too)
    bends = np.array([r.bend_angle_rad if r.ok else np.nan for r in out])
    off = np.abs(bends[1:-1] - 0.5 * (bends[:-2] + bends[2:]))
    for i in 1 + np.argsort(-np.nan_to_num(off, nan=-1.0), kind="stable"):
        if (out[i].ok and out[i - 1].ok and out[i + 1].ok
                and _spike(bends[i - 1], bends[i], bends[i + 1])):
            out[i] = replace(out[i], status=SPIKE, curve=None, fit=None, last_section=None)
    # a frame lost before a later one was measured (a first frame the tracker
    # could not start on, that the next one started on) is tracked backwards
    # from the nearest measured frame after it (and the motion from the one
    # after that)
    later = after = None
    stage = 0j
    for i in range(len(out) - 1, -1, -1):
        if not out[i].ok and later is not None and look is not None:
            crossing = self_contact(later, look.mean_half_width)
            r = _from_later(pending[i][1], later, look, settings, crossing, after)
            if r is not None:
                # (where the stage stood on the frame it was found from)
                out[i] = FrameTrack(out[i].frame, "ok", _reported(r), "backward", r.residual_px,
                                    r.valid_fraction, fit=r.curve, crossing=crossing,
                                    last_section=r.last_section,
                                    end_step=_told_step(look), stage_shift=stage,
                                    told_offset=r.told_offset, end_profile=r.end_profile,
                                    tip_hold=r.tip_hold)
        # a motion only between consecutive frames
        after = later if out[i].ok and i + 1 < len(out) and out[i + 1].ok else None
        later, stage = (out[i].tracked, out[i].stage_shift) if out[i].ok else (later, stage)
    return out


#: A frame's bend that lies this far (deg) from the mean of the frames either
#: side of it, and farther than they lie from each other, bent away and back.
#: (An independent-renderer scene, a faint tip in noise: 62.7 deg between
#: -1.9 and -22.1 on the frame after the start, every other frame within
#: 6 deg of the truth.)
SPIKE_DEG = 20.0
#: The status of a frame found to have bent away and back, where tracking it
#: again from the frame after it failed too.
SPIKE = "lost: bent away from the frames on either side of it and back"


def _spike(before: float, at: float, after: float) -> bool:
    """Whether the bend ``at`` (rad) between ``before`` and ``after`` is a
    spike: :data:`SPIKE_DEG` from their mean, and farther than they are apart."""
    off = abs(at - 0.5 * (before + after))
    return bool(off > np.radians(SPIKE_DEG) and off > abs(after - before))


def _told_step(look: TubeLook) -> tuple[float, float] | None:
    """:attr:`FrameTrack.end_step` of a fit with ``look``."""
    return (look.end_step_px, look.end_step_offset) if look.end_step_px else None


def _from_later(image: np.ndarray, later: Curve, look: TubeLook, settings: TrackSettings,
                crossing: bool, after: Curve | None = None) -> Refined | None:
    """The tube in ``image`` found from the shape of a later frame (which
    touches itself if ``crossing``), as the wide and redetect searches would
    from an earlier one; None if the fits fail the checks (:func:`_accepted`).
    With ``after``, the frame after that, also from the two shapes' motion
    carried on backwards (the better-scored fit kept)."""
    starts = [later]
    if after is not None:
        # backwards, the motion between the later frames carries on as it does
        # forwards (a deflating curl: 25 deg a frame, which the later shape
        # alone leaves too far behind on a tight curl); the frame after may be
        # written with other joints or spacing (found on it), as the history is
        # rewritten going forwards
        if (after.coef.size, after.joints) != (later.coef.size, later.joints):
            after = rewritten(after, later.joints, later.coef.size)
        starts.append(_predict([after, later]))
    fits = [_refine_on(image, start, look, window=1.5 * look.mean_half_width,
                       avoid_contact=crossing or (start is not later
                                                  and self_contact(start, look.mean_half_width)),
                       tol_px=settings.tol_px) for start in starts]
    fits = [r for r in fits if _accepted(r, look, later.length)]
    if fits:
        return max(fits, key=_score)
    # moved too far for that: found afresh from the later frame's base
    r = _redetect(image, later, look, settings)
    return r if _accepted(r, look, later.length) else None


def _track_one(index, frame, look, history, base_hint, base_end, detection, settings,
               known, search=False, tip_ratio=None, widths: WidthRecord | None = None,
               typical_residual: float | None = None, typical_length: float | None = None,
               last_whole: Curve | None = None):
    if look is None or not history:
        image = as_float(frame)
        init = initialise(image, base_hint=base_hint, base_end=base_end, detection=detection,
                          settings=settings, joints=known)
        if init is None:
            return FrameTrack(index, "no tube found", None, "")
        r, look, source = init
        status = "ok" if _good(r, look) else "tube found but its edges do not fit"
        if widths is not None and status == "ok":
            if widths.u.size == 0:
                widths.start(r.curve.length)
            if widths.frames < RECORD_FRAMES and not widths.resolved:
                widths.add(widths_at(image, r.curve, look, widths.u))
            if not widths.joints:
                widths.joints = r.curve.joints
        return (FrameTrack(index, status, _reported(r) if status == "ok" else None, "init",
                           r.residual_px, r.valid_fraction, base_source=source,
                           smooth_px=look.smooth_px, strip_lines=look.strip_lines,
                           half_width_px=look.mean_half_width,
                           polarity=look.polarity,
                           fit=r.curve if status == "ok" else None,
                           last_section=r.last_section if status == "ok" else None,
                           end_offset=r.end_offset, end_steps=r.end_steps,
                           told_offset=r.told_offset, end_profile=r.end_profile,
                           cap_shape=r.cap_shape, tip_hold=r.tip_hold), look)
    hw = look.mean_half_width
    pred = _predict(history)
    last_length = history[-1].length

    def accept(r: Refined) -> bool:
        return _accepted(r, look, last_length, typical_residual)

    def steady(r: Refined) -> bool:
        # the edges fit about as well as on the last frames: a fit that passes
        # the checks with residuals many times the video's own has settled on a
        # wrong shape (from a prediction that the motion's reversal left behind)
        return (typical_residual is None or crossing
                or r.residual_px <= max(RESIDUAL_JUMP_MIN_PX, RESIDUAL_JUMP * typical_residual))

    def rank(r: Refined) -> float:
        # of several fits, the best scored that passes the checks
        return _score(r) * (1.0 if accept(r) and steady(r) else 0.3 if accept(r) else 0.1)

    crossing = self_contact(pred, hw)
    # a section the crossing hides keeps its curvature in step with the one before
    held = tip_ratio[1] if tip_ratio is not None and tip_ratio[0] == pred.joints else None
    # without that ratio, the last shape seen whole tells a hidden end's curvature
    mode = _whole_mode(last_whole, pred) if held is None else None
    # fast: refine the prediction inside the region it can occupy
    # the crop must hold where the tube can have moved: twice the last step's
    # tip motion; a fit that reaches the crop's edge anyway is redone on the frame
    if len(history) >= 2:
        motion = 2 * abs(tip_point(history[-1]) - tip_point(history[-2]))
        r0, r1, c0, c1 = _crop_box(pred, 3 * hw + 8 + motion, frame.shape)
    else:
        # no velocity yet (the frame after a start): the tube may have moved
        # anywhere its length allows, so the whole frame, once per start
        r0, r1, c0, c1 = 0, frame.shape[0], 0, frame.shape[1]
    crop = as_float(frame[r0:r1, c0:c1])
    # without a velocity yet (second frame after a start) the prediction is only
    # the last shape: give Gauss–Newton more rounds
    rounds = settings.rounds if len(history) >= 2 else settings.first_rounds
    tol = settings.tol_px
    r = refine(crop, pred, look, origin=(c0, r0), iterations=rounds, avoid_contact=crossing,
               tol_px=settings.fast_tol_px if len(history) >= 2 else tol, tip_ratio=held,
               mode=mode)
    stage = "crossing" if crossing else "fast"
    work = crop.size / frame.size
    whole = (r0, r1, c0, c1) == (0, frame.shape[0], 0, frame.shape[1])
    image = crop if whole else None      # the float frame, made once when needed
    cut = not whole and _reaches_crop_edge(r.curve, hw, (r0, r1, c0, c1), frame.shape)
    # (at a crossing only: a coil that lies over itself fits about as well a
    # step further round, so the checks cannot tell an unsettled fit there;
    # elsewhere they do, and a fit still moving its end along a fading relief
    # is the best there is)
    unsettled = crossing and r.last_move_px > UNSETTLED_MOVE_PX
    if cut or unsettled or not accept(r) or not steady(r):
        image = as_float(frame) if image is None else image
        cands = [] if cut or unsettled else [r]
        # without a velocity the prediction is the last shape itself: one start
        starts = (pred,) if pred is history[-1] else (pred, history[-1])
        for start in starts:
            cands.append(_refine_on(image, start, look, window=1.5 * hw,
                                    avoid_contact=crossing or self_contact(start, hw),
                                    tol_px=tol, tip_ratio=held, mode=mode))
        stage = "wide"
        held_fits = []
        if typical_length is not None and (crossing or not any(accept(c) for c in cands)):
            # (also where no fit keeps the tube's length: a faint tip's end
            # found in the noise beyond it, or short of it)
            held_fits, freed = _held_length_fits(image, starts, look, typical_length, tol, held,
                                                 avoid_contact=crossing, mode=mode)
            if crossing:
                cands += freed
            else:
                # (not a tube whose end may have left the frame: held at its
                # length, it runs on past the border)
                held_fits = [f for f in held_fits if _in_view_on(f)]
        r = max(cands, key=rank)
        # (at a crossing every fit is steady: its residual is no test there)
        if held_fits and not (accept(r) and abs(r.curve.length - typical_length)
                              <= HELD_LENGTH_STEP * typical_length):
            # the length held wins unless freeing it fits the edges better
            passed = [f for f in held_fits if accept(f)]
            h = _least_residual(passed)
            if h is not None and (not accept(r) or h.residual_px <= RESIDUAL_TIE * r.residual_px):
                r, stage = h, "length held"
        work = 1.0
        # the frame after a start (no velocity yet) also gets a fresh detection
        # when the fast fit failed: a coarse jointed spline, pulled far from the
        # last shape, can settle on a wrong curl that fits well enough (320x240,
        # sample 7: 127° where the tube bent −18°, accepted; found afresh: −18.6°)
        if (not (accept(r) and steady(r)) or len(history) < 2) and not crossing:
            cand = _redetect(image, history[-1], look, settings)
            if cand is not None and rank(cand) > rank(r):
                r = cand
            stage = "redetect"
    elif len(history) < 2 and not crossing and _moved(r.curve, history[-1]) > hw:
        # the frame after a start: without a velocity the last shape may be too
        # far from this one for Gauss–Newton (a fast bend: 100° per frame ended
        # 60° short and looked fine), so the tube is also found afresh and the
        # better fit kept; once per start. Not needed when the fit found the
        # tube's edges all along within a half-width of the last shape: the
        # tube is there (a detection costs as much as ten fast frames)
        cand = _redetect(image, history[-1], look, settings)
        if cand is not None and accept(cand) and _score(cand) > _score(r):
            r, stage, work = cand, "redetect", 1.0
    if (typical_length is not None and not r.length_held and accept(r)
            and abs(r.curve.length - typical_length) > LENGTH_JUMP * typical_length
            and abs(last_length - typical_length) <= LENGTH_JUMP * typical_length):
        # a tube keeps its length from frame to frame: an end found this far
        # off is on something the tip has run onto (a holder's far edge)
        # (not while the lengths themselves are settling: the first frames'
        # still run into the holder until the base is voted on)
        image = as_float(frame) if image is None else image
        held_fits, _ = _held_length_fits(image, (r.curve, pred), look, typical_length, tol,
                                         held, avoid_contact=crossing, mode=mode, free=False)
        # (not a fit that runs on past the border at that length: the tip may
        # have left the frame)
        h = _least_residual([f for f in held_fits if accept(f) and _in_view_on(f)])
        if h is not None and h.residual_px <= RESIDUAL_TIE * r.residual_px:
            r, stage, work = h, "length held", 1.0
    if not accept(r):
        reason = ("lost: the tube hides too much of itself" if r.coverage < MIN_COVERAGE
                  else "lost: the tube's length jumped (end not found)"
                  if _good(r, look, typical_residual)
                  else "lost: edges not found along the tube" if r.valid_fraction < MIN_VALID
                  else "lost: tip not found" if not r.tip_found
                  else _ran_on(r, last_length)
                  if r.end_gap_px > _end_gap_hw(r, last_length) * look.mean_half_width
                  else "lost: edges do not fit a smooth tube")
        return FrameTrack(index, reason, None, stage, r.residual_px, r.valid_fraction, work,
                          crossing=crossing)
    if (widths is not None and widths.frames < RECORD_FRAMES and not widths.resolved
            and not crossing):
        # (not where the tube crosses itself: a width across both layers)
        # (on the crop, when the fit needed no more: it holds the tube)
        img, at = (image, (0, 0)) if image is not None else (crop, (c0, r0))
        widths.add(widths_at(img, r.curve, look, widths.u, origin=at))
        if _due(widths.frames):
            r = _width_joints(img, at, r, look, widths, settings, accept, crossing)
    if search:
        search_keep = widths.joints if widths is not None else ()
        # where the tube kinks away from the fit, a section joint: refit with a
        # triple knot there (kept only if that fit passes the same checks)
        # (afresh on every look: the more the tube bends, the clearer its kinks)
        # (the test is calibrated on the fine spline of unknown joints)
        length = r.curve.length
        fine = rewritten(r.curve, (), spline_size(length, hw, (), settings, known=False))
        found = find_joints(fine, r.u, r.midpoints, hw, keep=search_keep)
        if not same_joints(found, r.curve.joints, 0.2 * hw / length):
            image = as_float(frame) if image is None else image
            # the coarser spacing only while every joint is one seen as a width
            # step: a kink found means the width steps missed a joint, and others
            # may still be missed, whose curvature steps a coarse spline cannot
            # follow (sample 5 without its width steps: 30° off at 195°)
            complete = bool(found) and len(found) == len(search_keep)
            n_coef = spline_size(length, hw, found, settings, known=complete)
            cand = refine(image, rewritten(r.curve, found, n_coef), look, iterations=10,
                          avoid_contact=crossing, tol_px=tol)
            if accept(cand):
                r = cand
        # a coarse spline that misses a curvature step (a joint whose width does
        # not step) shows as a finer spline fitting the midpoints better
        fine_n = spline_size(r.curve.length, hw, r.curve.joints, settings, known=False)
        if (r.curve.coef.size < fine_n
                and spacing_f(r.curve, fine_n, r.u, r.midpoints) >= MAX_SPACING_F):
            image = as_float(frame) if image is None else image
            cand = refine(image, rewritten(r.curve, r.curve.joints, fine_n), look,
                          iterations=10, avoid_contact=crossing, tol_px=tol)
            if accept(cand):
                r = cand
    # the unwrapped angle must move continuously: a jump of about a turn is a
    # slip (the fit a coil further round, or back), not the tube's own motion
    jump = abs(r.curve.coef[-1] - history[-1].coef[-1])
    if jump > TURN_SLIP * 2 * np.pi:
        return FrameTrack(index, "lost: bend angle jumped by about a turn", None, stage,
                          r.residual_px, r.valid_fraction, work, crossing=crossing)
    return FrameTrack(index, "ok", _reported(r), stage, r.residual_px, r.valid_fraction, work,
                      crossing=crossing, fit=r.curve, last_section=r.last_section,
                      end_offset=r.end_offset, end_steps=r.end_steps,
                      told_offset=r.told_offset, end_profile=r.end_profile,
                      cap_shape=r.cap_shape, tip_hold=r.tip_hold)


def _whole_mode(last_whole: Curve | None, pred: Curve) -> np.ndarray | None:
    """The coefficients of ``last_whole``, the last shape seen whole, in the
    spline of ``pred`` (the prediction), for the hold of an end the crossing
    hides (``mode`` of :func:`pipeline.refine.refine`); None without one.

    Rewritten where the joints changed since it was seen whole: the search for
    kinks runs on crossing frames too, and a shape in another spline was
    dropped, which left a hidden end to the roughness penalty alone (an
    independent renderer's tube curled over its holder: 16-33 deg off)."""
    if last_whole is None:
        return None
    return rewritten(last_whole, pred.joints, pred.coef.size).coef


def _in_view_on(fit: Refined) -> bool:
    """Whether ``fit``'s profiles from :data:`HELD_VIEW_U` of its length on
    all lie in the frame."""
    return fit.in_view is not None and bool(fit.in_view[fit.u >= HELD_VIEW_U].all())


def _least_residual(fits: list[Refined]) -> Refined | None:
    """Of ``fits`` (in order of preference: the caller's starts, the
    prediction or the fit it came from first), the first whose residual is
    within :data:`RESIDUAL_TIE` of the least; None if there are none."""
    if not fits:
        return None
    least = min(f.residual_px for f in fits)
    return next(f for f in fits if f.residual_px <= RESIDUAL_TIE * least)


def _reported(r: Refined) -> Curve:
    """The shape a frame reports: the fit with its tip held stiffer
    (:data:`pipeline.refine.TIP_OUTPUT_STIFFNESS`)."""
    c = r.curve
    if r.tip_correction is None or r.tip_correction.size != c.coef.size:
        return c
    return c.with_params(c.coef + r.tip_correction, c.length)


def hold_tip_trend(frames, results: list[FrameTrack], settings: TrackSettings | None = None
                   ) -> tuple[list[FrameTrack], int]:
    """The frames measured before the frames told the tube's curvature trend
    along its end (:class:`_TrendVotes`), their tip stretch held to it again
    in the shape reported, where their edges do not tell against it; and how
    many were.

    A tube whose curvature ramps towards its tip shows it more clearly the
    more it bends: the trend was told on an independent scene's 20th frame of
    30 (curvature 0.4 -> 1.6 of its mean along the tube), and the frames
    before, their tip stretch held to a constant curvature, bent 1-2.7 deg
    too little. Each is fitted once more, from its own fit, with the look the
    frames told (one Gauss-Newton round, the frames read again); the shape
    reported is kept as it was where the edges tell against the trend or the
    refit's residual grows by over :data:`REHOLD_RESIDUAL`.

    Parameters
    ----------
    frames : iterable of (rows, cols) ndarray
        The frames ``results`` were tracked on, re-iterable.
    results : list of FrameTrack
        :func:`track_frames`' results, in the frames' own px.
    settings : TrackSettings, optional
    """
    settings = settings or TrackSettings()
    told = next((r for r in results if r.ok and r.look is not None and r.look.tip_trend),
                None)
    if told is None:
        return results, 0
    # (a frame bent far less than the one that told it shows the trend less)
    least = REHOLD_BENT * abs(told.bend_angle_rad)
    todo = {i for i, r in enumerate(results)
            if r.ok and r.look is not None and not r.look.tip_trend and not r.crossing
            and r.tip_hold == "constant" and r.fit is not None and r.stage != "backward"
            and abs(r.bend_angle_rad) >= least}
    if not todo:
        return results, 0
    out = list(results)
    held = 0
    last = max(todo)
    for i, frame in enumerate(frames):
        if i > last:
            break
        if i not in todo:
            continue
        r = results[i]
        # (its own look, but for the trend: what this frame was fitted with)
        look = replace(r.look, tip_trend=True)
        refit = refine(as_float(frame), r.fit, look, iterations=1, tol_px=settings.tol_px,
                       fit_length=False)
        if (refit.tip_hold == "trend"
                and refit.residual_px <= REHOLD_RESIDUAL * max(r.residual_px, 1e-3)):
            out[i] = replace(r, curve=_reported(refit), fit=refit.curve,
                             residual_px=refit.residual_px, tip_hold=refit.tip_hold)
            held += 1
    return out, held


#: A refit that holds the tip to the trend is kept unless its residual grows
#: by more than this factor over the frame's own fit (:func:`hold_tip_trend`).
REHOLD_RESIDUAL = 1.1
#: ... on frames bent at least this share of the bend of the frame that told
#: the trend.
REHOLD_BENT = 0.5


def hold_section_ratio(results: list[FrameTrack]) -> tuple[list[FrameTrack], str]:
    """The frames' shapes with each last section's mean curvature held in
    proportion to the rest of the tube's (base to last joint), at the one ratio
    that the bent frames tell together; and a line saying what was done, or
    left out and why.

    Under both of the paper's models every section's curvature grows with the
    same load (κ_i ∝ p·c_i), so the ratio is the tube's. Estimated from every
    frame on which the rest turns at least
    :data:`pipeline.refine.TIP_RATIO_MIN_TURN` (not at a crossing), by
    weighted least squares, each frame weighted by how well its fit knows the
    two curvatures (:class:`pipeline.refine.LastSection`), after dropping
    frames off by more than :data:`RATIO_OUTLIER_SD`. Held only where the
    frames agree on it (their reduced chi-square at most
    :data:`RATIO_MAX_CHI2`: a tube whose sections do not keep in proportion
    is left as fitted), and on each frame only where holding it raises the
    edges' residuals by at most :data:`pipeline.refine.TIP_OUTPUT_CHI2` of
    their variance. Frames fitted with other joints than most are left as
    they are.
    """
    have = [r for r in results if r.ok and r.last_section is not None]
    if not have:
        return results, "last section not held to the rest of the tube (no section joints)"
    joints = Counter(r.last_section.joints for r in have).most_common(1)[0][0]
    bent = [r.last_section for r in have if r.last_section.joints == joints and not r.crossing
            and abs(r.last_section.before_turn) >= TIP_RATIO_MIN_TURN]
    what = "last section not held to the rest of the tube"
    if len(bent) < RATIO_MIN_FRAMES:
        return results, (f"{what}: {len(bent)} frames bend the rest by >= "
                         f"{np.degrees(TIP_RATIO_MIN_TURN):g} deg, too few to tell their ratio")
    ratio, chi2, used = _pooled_ratio(bent)
    if used < RATIO_MIN_FRAMES or not chi2 <= RATIO_MAX_CHI2:
        return results, (f"{what}: the frames do not agree on one ratio of their curvatures "
                         f"(reduced chi-square {chi2:.1f})")
    out, held = [], 0
    for r in results:
        sec = r.last_section
        if r.ok and sec is not None and sec.joints == joints:
            delta, rise = sec.held(ratio)
            if rise <= TIP_OUTPUT_CHI2:
                c = r.curve
                r = replace(r, curve=c.with_params(c.coef + delta[:-1],
                                                   max(c.length + delta[-1], 2.0)))
                held += 1
        out.append(r)
    return out, (f"last section's mean curvature held at {ratio:.3f} times the rest of the "
                 f"tube's on {held} of {len(results)} frames (the ratio {used} bent frames "
                 f"agree on, reduced chi-square {chi2:.1f})")


def _pooled_ratio(sections: list[LastSection]) -> tuple[float, float, int]:
    """The ratio of the last section's mean curvature to the rest's that ``sections``
    agree on (weighted least squares, with outliers dropped), their reduced
    chi-square about it, and how many were kept."""
    last = np.array([s.last for s in sections])
    before = np.array([s.before for s in sections])
    cov = np.array([s.cov for s in sections])
    var = np.array([s.var for s in sections])

    def spread(ratio: float) -> np.ndarray:
        # the sd of last − ratio·before on each frame, both being noisy
        h = np.array([1.0, -ratio])
        return np.sqrt(var * np.einsum("i,fij,j->f", h, cov, h))

    ratio = float(np.median(last / before))
    keep = np.ones(last.size, bool)
    for _ in range(3):
        sd = spread(ratio)
        keep = np.abs(last - ratio * before) <= RATIO_OUTLIER_SD * sd
        if keep.sum() < RATIO_MIN_FRAMES:
            break
        w = 1.0 / sd[keep] ** 2
        ratio = float(np.sum(w * last[keep] * before[keep]) / np.sum(w * before[keep] ** 2))
    sd = spread(ratio)
    chi2 = float(np.mean(((last - ratio * before)[keep] / sd[keep]) ** 2)) if keep.any() else np.inf
    return ratio, chi2, int(keep.sum())


def _due(frames: int) -> bool:
    """Whether the width record is looked at for steps after ``frames``
    frames: at 2, 3, 4, 6, 8, 12, 16, 24, 32, … (each look's scatter about
    1.2 times less than the one before's, at a few milliseconds a look)."""
    if frames < 2:
        return False
    for base in (1, 3):
        n, rem = divmod(frames, base)
        if rem == 0 and n & (n - 1) == 0:
            return True
    return False


def _width_joints(image, origin, r: Refined, look: TubeLook, widths: WidthRecord,
                  settings: TrackSettings, accept, crossing: bool) -> Refined:
    """``r`` refitted with the joints the width record shows (new ones, or
    ones it places more than 1.5 px from where they are, or no longer shows),
    when that fit passes ``accept``; else ``r``. ``image``: the frame, or a
    crop of it holding the tube, whose top-left pixel is at ``origin``.

    Once the curve has the record's joints and the record tells every step
    that would be kept, it is marked resolved: more frames would show nothing
    new (a clean scene: after two frames)."""
    hw, length = look.mean_half_width, r.curve.length
    width_u = 2.0 * hw / length
    # the record holds every frame the earlier looks had: what it shows now
    # replaces what they showed
    steps = list(recorded_steps(widths, hw, length, profile_spacing(hw)))
    # and the kinks found in the shape, unless a width step is one
    kinks = [j for j in r.curve.joints
             if j not in widths.joints and all(abs(j - k) > width_u for k in steps)]
    joints = tuple(sorted(steps + kinks))
    # (a joint is placed to a pixel, and the record is a pixel apart: moving it
    # by that is no news)
    if same_joints(joints, r.curve.joints, 1.5 / length):
        widths.resolved = record_resolves(widths, hw, length, profile_spacing(hw))
        return r
    n_coef = spline_size(length, hw, joints, settings, known=not kinks)
    cand = refine(image, rewritten(r.curve, joints, n_coef), look, origin=origin,
                  iterations=10, avoid_contact=crossing, tol_px=settings.tol_px)
    if not accept(cand):
        return r
    widths.joints = tuple(steps)
    widths.resolved = record_resolves(widths, hw, length, profile_spacing(hw))
    return cand


def _redetect(image, prev: Curve, look: TubeLook, settings: TrackSettings) -> Refined | None:
    """Find the tube afresh from the held base and refine it; None if not found.

    As on a start, the skeleton is first followed by the fine spline without
    joints (a coarse one cannot follow its hooks and spurs, and lands far
    off), then rewritten as ``prev`` is (its joints and spacing); where that
    no longer fits and the fine spline does, it keeps the fine spacing (with
    ``prev``'s joints if that fits, else none). A tube found longer than
    ``prev`` by more than a length step has its end looked for again at
    ``prev``'s length, before the rewrite and after it (:func:`_length_held`)."""
    det = detect(image, base_hint=_base_col_row(prev))
    if det is None:
        return None
    tol = settings.tol_px
    hw = look.mean_half_width
    length = det.length
    n_fine = spline_size(length, hw, (), settings, known=False)
    start = fit_to_polyline(det.path, prev.base_angle, n_coef=n_fine)
    start = replace(start, base=prev.base)
    r = refine(image, start, look, iterations=10, tol_px=tol)
    if not r.tip_found:
        # a skeleton's length is rough (its end stops short of a rounded tip,
        # or runs into a spur): look for the end farther out, as on a start
        reach = max(2.0 * hw, 0.1 * r.curve.length)
        r = refine(image, r.curve, look, iterations=10, tol_px=tol, tip_window=reach)
    r = _length_held(image, r, prev, look, tol)
    if (r.curve.coef.size, r.curve.joints) == (prev.coef.size, prev.joints):
        return r
    fine = r
    r = refine(image, rewritten(fine.curve, prev.joints, prev.coef.size), look,
               iterations=6, tol_px=tol)
    n_fine = spline_size(length, hw, prev.joints, settings, known=False)
    if not _good(r, look) and _good(fine, look) and prev.coef.size < n_fine:
        # the fine spline follows the tube and the last frame's coarser one
        # cannot: a curvature step at a joint not known (the coarse spacing is
        # for joints all known), which bends more with every frame (sample 5
        # whose 0.6 joint's faint width step went unseen: lost from 100 deg on).
        # Kept at the fine spacing, with the joints that are known
        cand = refine(image, rewritten(fine.curve, prev.joints, n_fine), look,
                      iterations=6, tol_px=tol)
        r = cand if _good(cand, look) else fine
    # (the coarser spline, with fewer profiles' worth of freedom near the end,
    # can also run on where the fine one stopped short of the length step: a
    # faint MP4 frame, +5.5 % fine, then +9.8 %)
    return _length_held(image, r, prev, look, tol)


#: A fit at the tube's own length on a frame without a crossing is used only
#: where its search range lies in the frame from this fraction of the length
#: on (a base at the border is no tip run out of view).
HELD_VIEW_U = 0.5


def _refine_on(image, start: Curve, look: TubeLook, **kwargs) -> Refined:
    """:func:`refine` from ``start`` for :data:`WIDE_ROUNDS` rounds, run on
    where it stopped still moving (:data:`UNARRIVED_ROUNDS`) and the longer fit
    fitted the edges clearly better (:data:`UNARRIVED_GAIN`); ``kwargs`` as for
    :func:`refine`, bar ``iterations``."""
    r = refine(image, start, look, iterations=WIDE_ROUNDS, **kwargs)
    if r.iterations < WIDE_ROUNDS or r.last_move_px <= UNARRIVED_MOVE_PX:
        return r
    on = refine(image, r.curve, look, iterations=UNARRIVED_ROUNDS, **kwargs)
    return on if on.residual_px <= UNARRIVED_GAIN * r.residual_px else r


def _held_length_fits(image, starts, look: TubeLook, length: float, tol: float,
                      tip_ratio: float | None, *, avoid_contact: bool = True,
                      mode: np.ndarray | None = None, free: bool = True
                      ) -> tuple[list[Refined], list[Refined]]:
    """Fits of a tube that crosses itself from each of ``starts`` with its
    length held at ``length`` (the tube's own on the last frames where it did
    not cross itself), px; and the fits freed again from each of those.

    Where the tube lies over itself its end hides in the other layer, and a
    free length wanders with the end search, dragging the shape with it: at a
    curl that stopped or turned back, 24-34 deg off and then lost. A tube keeps
    its length from frame to frame, and at that length the coil's edges tell
    how far round it turns. (Also asked, without ``avoid_contact`` and not
    freed, of a frame where no fit kept the tube's length; and, not
    ``free``d, of one whose fit's length jumped: :data:`LENGTH_JUMP`.)"""
    held, freed = [], []
    for start in starts:
        fit = _refine_on(image, start.with_params(start.coef, length), look,
                         window=1.5 * look.mean_half_width, fit_length=False,
                         avoid_contact=avoid_contact, tol_px=tol, tip_ratio=tip_ratio, mode=mode)
        held.append(replace(fit, length_held=True))
        if avoid_contact and free:
            freed.append(refine(image, fit.curve, look, iterations=10, avoid_contact=True,
                                tol_px=tol, tip_ratio=tip_ratio, mode=mode))
    return held, freed


def _length_held(image, r: Refined, prev: Curve, look: TubeLook, tol: float) -> Refined:
    """``r``, or where its tube is longer than ``prev`` by more than
    :data:`MAX_LENGTH_STEP`, the fit from it cut to ``prev``'s length if that
    passes the checks (:func:`_accepted`).

    The skeleton runs on past the tip into something that touches it (a label,
    a scale bar, a dark corner of the field, noise beyond a faint tip) and the
    end is found there; the tube keeps its length from frame to frame, so its
    end is looked for again where the last frame's length puts it."""
    if r.curve.length <= (1.0 + MAX_LENGTH_STEP) * prev.length:
        return r
    cand = refine(image, _cut_to_length(r.curve, prev.length), look, iterations=10, tol_px=tol)
    return cand if _accepted(cand, look, prev.length) else r


def _moved(curve: Curve, last: Curve) -> float:
    """Largest distance between two centrelines at the same fractions of
    their lengths, px."""
    u = np.linspace(0.0, 1.0, 65)

    def points(c: Curve) -> np.ndarray:
        basis = basis_of(c)
        z = evaluate(c, basis).z
        return np.interp(u, basis.u, z.real) + 1j * np.interp(u, basis.u, z.imag)

    return float(np.abs(points(curve) - points(last)).max())


def _reaches_crop_edge(curve: Curve, hw: float, box, shape) -> bool:
    """Whether the tube, drawn with this centreline, comes within reach of a
    side of the crop that is not the image's border: the tube may go on
    beyond it, and the crop's edge may have been taken for the tube's end."""
    r0, r1, c0, c1 = box
    r_lo, r_hi, c_lo, c_hi = _crop_box(curve, hw + 2.0, (np.inf, np.inf))
    return bool((r0 > 0 and r_lo < r0) or (r1 < shape[0] and r_hi > r1)
                or (c0 > 0 and c_lo < c0) or (c1 < shape[1] and c_hi > c1))


def _base_col_row(curve: Curve):
    return (curve.base.real, -curve.base.imag)
