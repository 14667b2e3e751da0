"""Refine a predicted centreline on one frame: edges along normals → Gauss–Newton.

Each iteration samples intensity profiles along the normals of the current
curve, finds the tube's outer edge pairs (:mod:`pipeline.profiles`) and the
tube's end along the tip tangent, and takes one damped, robustly weighted
Gauss–Newton step on the spline coefficients and the length. The residual of
a profile is the offset of the measured centre along the normal, i.e. the
signed distance of the tube's midline from the curve, which stays meaningful
where the tube crosses itself: such profiles are dropped by their width.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np
from scipy.interpolate import BSpline
from scipy.special import ndtri

from .centreline import (
    Curve,
    angle_spline,
    basis_of,
    evaluate,
    fit_to_polyline,
    jacobian,
    knot_vector,
    resample,
)
from .profiles import (
    FADED_COS,
    Edges,
    edge_pairs,
    end_edge,
    sample_lines,
    sample_strips,
    side_edges,
)
from .steps import two_level_fit

#: Each edge profile is the mean of this many parallel lines, spread over
#: ±1 px along the tube. The profiles lie 2–12 px apart,
#: so a single line leaves most of the pixels between them unread; averaging
#: three lines over ±1 px cuts the noise of each midpoint by up to √3. Measured
#: on 132 rendered scenes (five sets, none of them the tests'): scenes meeting
#: every target 93 → 109, the mean angle median falling on every set (e.g.
#: 0.44 → 0.41° on 32 scenes, 0.41 → 0.34° on the report's 27); five lines over
#: ±1.5 px were worse on two sets of the five.
STRIP_LINES = 3
#: ... 1 px apart: the lines of a longer strip (:attr:`TubeLook.strip_lines`)
#: keep this spacing.
STRIP_STEP_PX = 1.0
#: The stretches at the tube's end, in half-widths, over which a fit measures
#: how far the edge midpoints there step sideways from the line the rest of
#: the tube gives (:attr:`Refined.end_steps`, :attr:`TubeLook.end_step_px`).
#: A sealed tube's plug, where the lumen that pulls the body's midpoints off
#: its axis has ended, is 1.3-1.7 half-widths long behind a round cap.
END_STEP_ZONES_HW = tuple(np.arange(0.5, 3.01, 0.25))
#: Once a stretch is told, the edge midpoints over this many half-widths at
#: the end are measured off the curve the rest alone fits
#: (:attr:`Refined.end_profile`): a plug up to about 5 half-widths long is
#: fitted to them.
END_PROFILE_HW = 6.0
#: A told stretch's side edges are left out of the fits where it is at most
#: this share of the last section (the whole tube, without joints): the tip's
#: direction is then the continuation of an arc at least three times as long.
#: A longer one keeps them, with a sideways offset of its own: left out, it
#: had taken the last section's bend with it (sample 1's last 38 px, 24 of
#: them told: 0.1 -> 2.3 deg).
END_STEP_LEAVE_OUT = 0.25
#: ... and where its offset is at most this, px: an off-centre lumen's, under
#: blur, is a fraction of a pixel (0.09-0.28 on the 5 of 182 evaluation
#: scenes that told one, 0.09-0.36 on 9 of the independent renderer's 30). A
#: larger one is a bend the fit misses (a joint
#: not found yet: -1.16 px over 37 px, whose edges left out let the tip turn
#: 25 deg away), which the stretch's edges must go on holding.
END_STEP_LEAVE_OUT_MAX_PX = 0.5
#: Where a tube's end face pulls its side edges off the rest's line
#: (:attr:`TubeLook.end_clear`), the profiles stop this many half-widths short
#: of its end (2 px otherwise), and :attr:`Refined.end_offset` is measured over
#: the profiles that near. On three fluorescent scenes (a noise-free render of
#: sample 1, the report's stress_no_pipette and stress_fluorescent), angle
#: medians 0.16/0.48/0.07 deg at 0.5; 0.32/0.49/0.26 at 0.3; 0.17/0.80/0.11 at 0.7.
END_CLEAR_HW = 0.5
#: A frame's lines along the tip tangent tell the end's shape
#: (:attr:`Refined.cap_shape`) where they fit a flat face or a share of a round
#: cap to this many half-widths (RMS), the share within this range (a tube
#: curled over itself: 1.4-1.9, its tip lying against its body).
CAP_FIT_HW = 0.12
CAP_SHARES = (-0.5, 1.3)
#: In a relief, the end's shape is told by the lines this many half-widths
#: off the axis or more (within a hollow tube's walls).
RELIEF_CAP_LINES_HW = 0.65
#: On a round cap (:attr:`TubeLook.cap`), the side edges within this many
#: half-widths of its apex are left out of the fits.
CAP_CLEAR_HW = 0.6
#: ... and, for the shape reported (the output solve, as
#: :data:`TIP_OUTPUT_STIFFNESS`), those within this many: the whole cap (its
#: hemisphere is one half-width long) and the blur's reach past it. Where the
#: outline closes in, the blurred edges found along a curved tube's normals need
#: not sit evenly about its axis, and the tip tangent followed them; the fit itself
#: keeps them, to hold on to a tip that moves fast (left out there too, frames
#: were lost: 5 against 3 on two sets, and a deflating tube's median 0.37 ->
#: 4.8 deg at 0.9). Measured on four independent sets (120 scenes, round caps):
#: scenes meeting every target 89 -> 90, angle medians better / worse by
#: > 0.02 deg on 55 / 25, no frame more lost (oblique light 0.47 -> 0.23, a
#: 300 deg curl in 8 frames 0.39 -> 0.12, a curvature ramp 0.58 -> 0.35 deg);
#: worse where the curvature ramps up to the tip (0.94 -> 1.18) or the frame
#: is noisy (0.49 -> 0.60). 1.0: 89 and 56 / 22; 1.5: 91 but 38 / 34. The
#: own 38 scenes (flat ends) are unchanged.
CAP_OUTPUT_CLEAR_HW = 1.2
#: The line a pipette's edge pairs give moves the base onto it by at most
#: this many of the tube's half-widths (:func:`pipette_axis`); farther, the
#: pairs behind the base are not the pipette's own: a tube seen through a
#: thick glass capillary is refracted aside (an independent renderer's: 0.33
#: of them, the base put 2.6 px off the tube's axis, and its first stretch
#: hooked back to it); a base fitted beside a pipette's axis lay within 0.12
#: of it on five renderers' first frames but for two whose "pipette" was a
#: long oblique holder or a scratch (0.26-0.33: left where they were, their
#: figures as before).
PIPETTE_MAX_ASIDE_HW = 0.25
#: The fraction of the profiles past a base step found that must show the
#: tube's edge pair for the step to stand (:func:`locate_base`).
BASE_STEP_VALID = 0.5
#: Where the tube's edge pair is found on every profile of the base search
#: (the tube seen through a clear pipette, or running on out of the frame),
#: a base step stands only where the pairs' mean strength behind it is at
#: most this fraction of theirs past it (:func:`locate_base`).
BASE_STEP_CLAD = 0.5
#: Edge-midpoint scatter (px) of single-line profiles up to which the
#: roughness penalty keeps its nominal weight; noisier frames get it scaled by
#: (scatter / reference)². A strip's scatter is √ its lines lower for the same
#: frame, and the reference with it (:func:`noise_ref_px`).
NOISE_REF_LINE_PX = 0.05
#: In a relief image a profile whose direction is this close to square with
#: the shear (|cos| below it) sees the tube's edges at under this fraction of
#: their full step: the tube fades there, and such profiles neither pull the
#: fit nor count against it.
RELIEF_MIN_COS = FADED_COS
#: ... and a shear is not taken where most of the steps seen lie where it
#: says they are under this share of their full size (half that of the
#: fading): a tube that has not turned, a few of whose profiles (a stretch the
#: fit missed, a few degrees off the rest) step the other way, pins a shear
#: just short of the fading, which its edges do not show (alien5's DIC tube:
#: one along the tube, which dropped 94 % of its profiles on the next frames).
#: At the fading's own share, shears told on oblique light's strong,
#: saturated edges, which show even there, were refused too.
RELIEF_TOLD_COS = 0.5 * RELIEF_MIN_COS
#: The shear of a relief is taken once the tube's edges pin it down to a run
#: of directions no wider than this, deg.
RELIEF_MAX_SPREAD_DEG = 30.0
#: The pipette's axis (:func:`pipette_axis`) is read over this many tube
#: widths behind the base, and trusted when at least PIPETTE_MIN_PROFILES of
#: its profiles agree to PIPETTE_MAX_SCATTER_PX (RMS about a line) and it
#: turns the base tangent by at most PIPETTE_MAX_TURN_DEG. (Over 4 or 8
#: widths, and a direction's standard error of 0.05° or 0.1°, measured on 153
#: scenes: none flipped; 8 and 0.1° moved the most angle medians down.)
PIPETTE_WIDTHS = 8.0
PIPETTE_MIN_PROFILES = 10
PIPETTE_MAX_SCATTER_PX = 0.3
PIPETTE_MAX_TURN_DEG = 3.0
#: Half-widths of a pipette's edge pairs, as fractions of the tube's.
PIPETTE_RATIOS = (0.35, 0.5, 0.65, 0.8)
#: ... and, where none of those shows, of a holder wider than the tube (a
#: clamp's jaws, a capillary the tube is pushed into), whose outer edges give
#: the axis's direction. On alien5's tube deflating from a 380° curl out of a
#: clamp 2.5 times its width, where the start's base tangent leaned 1.1° into
#: the bend: bend-angle error median 1.02 → 0.19°.
WIDE_HOLDER_RATIOS = (1.5, 2.0, 2.5, 3.0, 4.0)
#: ... and the axis's direction is known to this standard error, deg.
PIPETTE_MAX_SE_DEG = 0.1
#: Extra weight of the roughness penalty over the last :data:`TIP_STIFF_WIDTHS`
#: tube widths: the curvature there is held all but constant, so the tip
#: tangent is the continuation of the arc before it rather than the slope of
#: the last, least constrained spline span. Measured on 12 rendered scenes
#: (other seeds, sizes, looks and formats than the tests'): tip-angle error
#: medians fall on 9, e.g. 1.29° → 0.41° on a 9 px wide tube and 0.27° → 0.06°
#: on sample 1; a fluorescent tube worsens (0.86° → 1.55°), where the measured
#: centre already sits 0.2–0.5 px off the true one and the stiff tip carries
#: that on. A stretch of 2 widths was worse on 8 of the 12.
TIP_STIFFNESS = 10.0
TIP_STIFF_WIDTHS = 1.0
#: The same weight for the shape reported. The last profiles' midpoints
#: scatter by 0.02-0.05 px on a tube 9 px wide, yet the fit's last few pixels
#: followed that scatter: the tangent 0.1 deg off 10 px from the end, 1-2 deg
#: off at the end. Held stiffer in the fit itself, it followed a fast-moving
#: tip worse (30: 3 scenes of 111 broke, frames lost or p95 12 deg), so the
#: stiffer tip is solved once more from the fit's last round, for the output
#: only (the next frame is predicted from the fit). Measured on 111 scenes
#: (other seeds than the tests' and the report's): 80 -> 83 meet every target,
#: none fewer; 18 angle medians fell and 7 rose by > 0.02 deg (6 by at most
#: 0.06; sample 1 at 71 um/px, whose last section is 17 px, 9.5 -> 10.3 deg,
#: failing either way); 100 was better on 19 and worse on 12.
TIP_OUTPUT_STIFFNESS = 30.0
#: ... unless that raises the edges' residual sum of squares by more than this
#: many times their residual variance (chi-square of one degree of freedom at
#: 5 %): a curvature step within the stretch (sample 5 with a joint the fit
#: has not found: bend error 4.6 -> 5.5 deg without this check).
TIP_OUTPUT_CHI2 = 3.84
#: ... but never shorter than this, px. How far a curvature change at the tip
#: can hide scales with the tube's width; how noisy the tip tangent is scales
#: with how many edge samples hold it, i.e. with the stretch's length in pixels.
#: On a tube 6 px wide one width is a handful of profiles, and the tip angle
#: followed the noise (±3–4° per frame on 320×240 scenes). Measured on 132
#: rendered scenes (five sets): scenes meeting every target 109 → 111, angle
#: medians 0.83 → 0.73° and 0.41 → 0.34° on the two random sets, 21 scenes
#: better and 9 worse by > 0.02°; 12 and 20 px helped less, 45 px was worse on
#: one set of the five. Tubes wider than 30 px are unaffected.
TIP_STIFF_MIN_PX = 30.0
# Where the frames tell that the tube's curvature changes along its end
# (TubeLook.tip_trend), the shape reported holds the tip stretch's curvature
# not constant but to the trend it had over the stretch before (_tip_trend): a
# tube stiffer toward its base curls more toward its tip, and a
# constant-curvature tip stretch under-measured it (0.2-1.2 deg on an
# independent set's ramps). Where the edges tell against the trend
# (TIP_OUTPUT_CHI2), the constant hold is tried next.
#: Midpoint nodes of the trend's integral over the stretch (:func:`_tip_trend`).
TIP_TREND_NODES = 24
#: Where the edge midpoints scatter from one profile to the next by σ above
#: their reference (see :data:`NOISE_REF_LINE_PX`), the stiff stretch grows
#: with σ / ref, up to this many times its length, to at most this share of
#: the tube and not past the last joint (:func:`_tip_span`): the tip tangent
#: then rests on about as many edge samples' worth of information as on a
#: clean frame. A tube 8 px wide at 0.05 noise: tip angle RMS 1.03 -> 0.63°.
#: On four independent sets (120 scenes): scenes meeting every target 88 -> 89,
#: angle medians better / worse by > 0.02° on 28 / 5 (alien4 deflating 0.50 ->
#: 0.37°, dic_diag p95 2.27 -> 1.28°, hard_lowsnr_blur 2.35 -> 1.24°,
#: fluor_lowsnr 0.91 -> 0.60°); worse where the curvature ramps up towards the
#: tip, which a stiffer tip under-measures (alien7 lowcontrast_highsnr, a ramp
#: 0.5 -> 1.5: 0.47 -> 0.64°; corner_pipette 0.69 -> 1.44°). Own 38 scenes: 36
#: pass either way, medians 9 better, 5 worse.
TIP_NOISE_STRETCH_MAX = 3.0
TIP_STRETCH_MAX_SHARE = 0.3
#: Where a crossing hides most of a jointed tube's last section (the tip lying
#: over the base or the body), nothing but the prediction holds that section's
#: curvature, and a prediction extrapolated from fits that are themselves
#: unobserved there drifts: 4–5° more per frame on sample 7 curling past 360°.
#: Its mean curvature is then held at the multiple of the section before's that
#: it had when last seen whole. Under both of the paper's models each section's
#: curvature grows in proportion to the same load (κ_i ∝ p·c_i), so that ratio
#: does not change with the pressure. The weight is relative to the data's
#: mean diagonal (1: a firm hold, which the data of a section still half seen
#: can outweigh). Measured on 12 over-curl scenes (310–520°, samples 1–4, 6, 7):
#: 9 → 11 meet every target; sample 7 at 640 px max 24 → 1.6°, sample 3 at
#: 507° length error 4.7 → 0.8 %; the mean 95th percentile 1.9 → 1.0°. Not
#: enough where a coil hides half the tube, the middle sections too (sample 7,
#: low contrast, 800 px: max 3.3 → 8.4°). The 132 scenes that do not curl
#: past a turn are unchanged.
TIP_RATIO_WEIGHT = 1.0
#: The same hold where no section ratio is held (no joints known, or the
#: section before barely turned: :func:`_tail_hold`):
#: wherever the crossing hides at least this many half-widths at its end, that
#: stretch's mean curvature is held at the multiple of the stretch before it
#: that the last shape seen whole had.
TAIL_HOLD_MIN_HW = 2.0
#: Standard deviation per median absolute deviation of a normal distribution.
MAD_TO_SD = float(1.0 / ndtri(0.75))
#: Profile smoothing, px, with which the tube's end is placed again once a wider
#: one (on a noisy frame) has found it: the narrowest of
#: :data:`pipeline.track.EDGE_SCALES`. Measured over 136 rendered scenes: of the
#: medians that moved by > 0.02°, 9 fell (v05 0.65° → 0.49°, v03 1.36° → 1.01°)
#: and 7 rose (at most 0.07°), one scene more meets every target.
TIP_FOCUS_PX = 0.8
#: Half the span, in half-widths, of the lines whose mean finds a noisy tube's end
#: (:func:`_pooled_end`): the lines :func:`_tip_offset` looks along, as one strip.
TIP_POOL_HW = 0.7
#: The section before must turn at least this much (rad) for a ratio to it to
#: mean anything.
TIP_RATIO_MIN_TURN = np.radians(10.0)
#: Where another layer of the tube (a coil, or the holder tracked as the
#: tube's first stretch) lies over one side of a profile, running within this
#: angle (deg) of it, the profile's edge on the other side still places the
#: tube (:func:`pipeline.profiles.side_edges`; independent renderers' coils
#: lying along each other over a quarter turn, the pairs left out there: p95
#: 2.7 -> 1.8 deg, 15 -> 2.8 on two full turns whose coils touch) ...
SIDE_PARALLEL_DEG = 30.0
#: ... with this weight relative to an edge pair's (one edge, √2 its noise) ...
SIDE_WEIGHT = 0.5
#: ... where the edge is as strong as the tube's (from this share to
#: SIDE_STRONGEST times the look's strength: a step much stronger is
#: something else's) ...
SIDE_WEAKEST = 0.5
SIDE_STRONGEST = 2.5
#: ... and not within this many half-widths of the end: the end stretch is
#: where the fit is least held, and an edge a few tenths of a px off (the
#: half-width learnt there, the cap closing in) turned the tip (3.5 deg on a
#: tip reaching its base, own renderer, its pairs 0.25 px narrower there than
#: the look's).
SIDE_END_HW = 3.0


@dataclass(frozen=True)
class TubeLook:
    """What the tracker has learnt about the tube's appearance.

    Attributes
    ----------
    polarity : int
        +1 if the tube is brighter than the background just inside its edge,
        −1 if darker.
    half_width : (W,) ndarray
        Outer half-width along the tube at W evenly spaced fractions of its
        length (from base to tip), px.
    strength : float
        Typical inward intensity step at the edges, per px (sets thresholds).
    smooth_px : float
        Gaussian smoothing along the profiles before the edges are taken, px:
        wider on noisy, blurred frames, where a narrow derivative sees mostly
        noise (see :func:`pipeline.track.edge_scale`).
    shear : float, optional
        With ``polarity`` 0 (a relief image: differential interference
        contrast, oblique light), the shear direction: a flank whose inward
        normal faces it shows bright, rad, counter-clockwise from +x (y up);
        see :func:`relief_shear`. Where the tube runs along it, its edges fade.
    end_clear : bool
        Leave out the side edges within :data:`END_CLEAR_HW` half-widths of the
        tube's end (else within 2 px): set once the frames show that the end
        face's blur pulls them off the line the rest of the tube's edges give
        (see :attr:`Refined.end_offset`). A relief leaves them out whether
        or not this is set (:attr:`clears_end`).
    end_step_px : float or None
        The stretch at the tube's end, px, whose edge midpoints sit off the
        line the rest of the tube's give by a steady amount (0: none; None:
        not known yet, fits measure it, see :attr:`Refined.end_steps`). A
        tube whose walls differ in thickness (its lumen off-centre) shows its
        edge midpoints off its axis by a fraction of a pixel all along the
        lumen, under blur; past the lumen's end (a sealed tip's plug) they
        come back to it, and a fit that followed them turned the tip tangent
        1-4 deg. Fits leave the stretch's side edges out
        (:func:`end_step_left_out`): the tip's direction is then the
        continuation of the arc before it. A sideways offset of the stretch's
        own, free on each frame, is the fallback where the stretch is too
        much of the last section: under blur the midpoints come back over a
        ramp as long as the stretch, and its slope still turns the tip
        (independent renderer: 3.0 deg median on a tube 7 px wide, 0.8 with
        the stretch left out; three tubes 9-15 px wide from 0.8-1.5 to
        0.1-0.5 deg).
    strip_lines : int
        How many parallel lines, :data:`STRIP_STEP_PX` apart along the tube,
        each edge profile averages (:data:`STRIP_LINES`; more on a frame
        whose noise hides the tube's edges, see
        :func:`pipeline.track.edge_scale`).
    end_step_offset : float
        How far the stretch's midpoints sat off the rest's line on the frames
        that told it, px (along the curve's left normal): reported only (a
        learned value taken off them instead had turned the tip 0.1-0.5 deg
        the wrong way on tubes whose end was merely noisy).
    cap : float or None
        The tube's end as a share of a round cap of its own radius: 0 a flat
        (cut) end face, 1 a hemisphere (None: not known yet, fits measure it,
        see :attr:`Refined.cap_shape`). The lines along the tip tangent that
        find the end (:func:`_tip_offset`) lie beside the axis, and beside it
        a round cap ends short of its apex by ``r − √(r² − y²)``: the end
        is put that much (their median) beyond the lines' median end.
    tip_trend : bool
        The frames told that the tube's curvature changes along its end
        (:class:`pipeline.track._TrendVotes`): the shape reported holds the
        tip stretch to its curvature's trend from the stretch before
        (:func:`_tip_trend`), not to a constant curvature.
    """

    polarity: int
    half_width: np.ndarray
    strength: float
    smooth_px: float = 0.8
    shear: float | None = None
    end_clear: bool = False
    end_step_px: float | None = 0.0
    end_step_offset: float = 0.0
    strip_lines: int = STRIP_LINES
    cap: float | None = None
    tip_trend: bool = False

    @property
    def strip_half_px(self) -> float:
        """How far along the tube each profile's strip reaches either side, px."""
        return strip_half_px(self.strip_lines)

    def facing(self, normals: np.ndarray):
        """Which way a relief's edges step along profiles in the directions
        ``normals`` (±1), and whether they show there at all (bool); None, None
        for other looks or an unknown shear."""
        if self.polarity != 0 or self.shear is None:
            return None, None
        c = np.real(normals * np.exp(-1j * self.shear))
        return np.where(c >= 0, 1.0, -1.0), np.abs(c) >= RELIEF_MIN_COS

    @property
    def clears_end(self) -> bool:
        """Whether fits leave out the side edges within :data:`END_CLEAR_HW`
        half-widths of the tube's end: once :attr:`end_clear` is set, and on
        every relief, which shows its end face as a line pair as strong as the
        tube's edges, whose flanks the profiles nearest the end run along (DIC,
        end face across the shear: a tip bent 10 deg on 2 of 8 scenes)."""
        return self.end_clear or self.polarity == 0

    @property
    def end_in_question(self) -> bool:
        """Whether fits measure :attr:`Refined.end_offset`: a tube brighter than
        its surroundings at its edges whose end's edges are still in (see
        :class:`pipeline.track._EndVotes` for why only those)."""
        return self.polarity == 1 and not self.end_clear

    @property
    def end_step_in_question(self) -> bool:
        """Whether fits measure :attr:`Refined.end_steps`: while
        :attr:`end_step_px` is not known, on a tube darker or brighter than
        its surroundings at its edges (a relief leaves its end's edges out;
        on a bright one only a straight plug is told from them, see
        :class:`pipeline.track._EndStepVotes`)."""
        return self.polarity in (-1, 1) and self.end_step_px is None

    def half_width_at(self, u) -> np.ndarray:
        grid = np.linspace(0.0, 1.0, self.half_width.size)
        return np.interp(u, grid, self.half_width)

    @property
    def mean_half_width(self) -> float:
        return float(np.mean(self.half_width))


@dataclass(frozen=True)
class LastSection:
    """How a jointed fit's last section could be held in proportion to the
    rest of the tube, once the frames tell the proportion
    (:func:`pipeline.track.hold_section_ratio`).

    Both of the paper's models bend every section in proportion to one load
    (κ_i ∝ p·c_i), so the ratio of the last section's mean curvature to the
    rest's is the tube's, not the frame's; yet a short last section
    (10-12 % of the length in three of the paper's eight samples) holds its
    curvature on a few profiles only, and the tip angle followed their noise.

    Attributes
    ----------
    joints : tuple of float
        The fit's joints (a ratio applies to fits with the same sections).
    last, before : float
        Mean curvature of the last section and of the tube before it (from
        the base to the last joint) in the shape reported, rad per unit of
        the length fraction.
    before_turn : float
        How far the tube turns before the last joint, rad.
    gain : (K + 1, 2) ndarray
        The fit's system solved for the two curvatures' rows (coefficients,
        then the length): how the shape moves to change either.
    cov : (2, 2) ndarray
        The two curvatures' rows through that solve (a covariance, in units
        of ``var``).
    var : float
        The edge residuals' variance (their sum of squares per degree of
        freedom).
    """

    joints: tuple[float, ...]
    last: float
    before: float
    before_turn: float
    gain: np.ndarray
    cov: np.ndarray
    var: float

    def held(self, ratio: float) -> tuple[np.ndarray, float]:
        """The change of (coefficients, length) that makes the last section's
        mean curvature ``ratio`` times the rest of the tube's, and the rise it
        brings to the residual sum of squares, in units of ``var`` (a
        chi-square of one degree of freedom where the ratio is the tube's)."""
        h = np.array([1.0, -ratio])
        off = self.last - ratio * self.before
        spread = float(h @ self.cov @ h)
        if not spread > 0:
            return np.zeros(self.gain.shape[0]), np.inf
        return -(self.gain @ h) * (off / spread), off**2 / spread / self.var


def _last_section(system: np.ndarray, coef: np.ndarray, joints: tuple[float, ...],
                  var: float) -> LastSection:
    """:class:`LastSection` of the shape ``coef`` whose fit solved ``system``."""
    k = coef.size
    turns, spans = _rest_turns(k, joints)
    rows = np.zeros((system.shape[0], 2))
    rows[:k, 0] = turns[1] / spans[1]
    rows[:k, 1] = turns[0] / spans[0]
    gain = np.linalg.solve(system, rows)
    last, before = rows[:k].T @ coef
    return LastSection(joints, float(last), float(before), float(turns[0] @ coef),
                       gain[:k + 1], rows.T @ gain, float(var))


@dataclass(frozen=True)
class Refined:
    """Outcome of refining a curve on one frame.

    Attributes
    ----------
    curve : Curve
    u : (M,) ndarray
        Profile positions (fractions of the length).
    width : (M,) ndarray
        Measured width at each profile, px (NaN where invalid).
    valid : (M,) bool ndarray
    residual_px : float
        RMS offset of the valid profiles' centres from the final curve, px.
    tip_found : bool
    iterations : int
    strength : float
        Median inward edge step of the valid profiles, intensity per px.
    usable : (M,) bool ndarray, optional
        Profiles not dropped because the tube crosses itself there, or (in a
        relief image) because it runs along the shear there and fades.
    midpoints : (M,) complex ndarray, optional
        The measured centre of the tube on each profile (midway between its
        edges), full-frame px (y up); NaN where invalid.
    tip_correction : (K,) ndarray, optional
        Change of ``curve.coef`` (rad) that holds the tip stretch as
        :data:`TIP_OUTPUT_STIFFNESS` asks (to its curvature's trend, else to
        a constant curvature: ``tip_hold``): added for the shape reported,
        not for the next frame's fit.
    noise_px : float
        The valid profiles' centres' scatter from one profile to the next
        (robust, per profile), px: the edge noise, which a smooth misfit
        does not raise.
    last_section : LastSection, optional
        On a jointed fit: what it takes to hold its last section's curvature
        in proportion to the rest of the tube's, for the shape reported.
    end_offset : float
        How far the edge midpoints within :data:`END_CLEAR_HW` half-widths of
        the tube's end lie, on average, from the curve the other profiles
        alone give, px (along the curve's left normal); NaN where not measured
        (see :attr:`TubeLook.end_in_question`) or no valid profile is that near.
    in_view : (n,) bool ndarray, optional
        Profiles whose whole search range lies within the image.
    last_move_px : float
        How far the last round moved the centreline (its largest step), px:
        a fit whose rounds ran out while it still moved has not settled.
    length_held : bool
        The length was not fitted but held at the tube's own from other frames
        (the caller's say: :func:`refine` with ``fit_length=False`` leaves it
        False); such a fit counts as having its end.
    end_steps : (Z, 3) ndarray, optional
        For each stretch of :data:`END_STEP_ZONES_HW` half-widths at the end:
        the same mean offset there (NaN where no valid profile is that near),
        the weight of the profiles it is the mean of, and its standard error
        from the edges' residual variance, px; measured while
        :attr:`TubeLook.end_step_in_question`.
    told_offset : float
        Once the stretch at the end is told (:attr:`TubeLook.end_step_px`),
        the mean offset of its edge midpoints from the curve fitted, px
        (along the left normal; NaN where not told or no valid profile lies
        there): what :attr:`end_steps` measured before, on every frame after.
    end_profile : (M, 3) ndarray, optional
        Once the stretch is told: the valid profiles within
        :data:`END_PROFILE_HW` half-widths of the end, each's distance from
        it, its edge midpoints' offset from the curve that the profiles
        farther off alone fit (px, along the left normal) and its weight;
        what a straight plug's length is fitted to
        (:func:`pipeline.plug.fitted_length`).
    cap_shape : float
        The end's shape the lines along the tip tangent saw on the fit's last
        round: the share of a round cap of the tube's radius (0 flat, 1 a
        hemisphere; :attr:`TubeLook.cap`) that fits their ends best (NaN
        where too few lines found the end).
    tip_hold : str
        How ``tip_correction`` holds the tip stretch: ``"trend"`` (its
        curvature's trend from the stretch before, :func:`_tip_trend`),
        ``"constant"`` (a constant curvature), or ``""`` (not held: none
        asked for, or the edges told against both).
    sided : (M,) bool ndarray, optional
        Profiles dropped where another part of the tube lies against it that
        placed the tube by the side edge that part left clear (counted in
        :attr:`coverage`).
    """

    curve: Curve
    u: np.ndarray
    width: np.ndarray
    valid: np.ndarray
    residual_px: float
    tip_found: bool
    iterations: int
    strength: float
    usable: np.ndarray | None = None
    midpoints: np.ndarray | None = None
    tip_correction: np.ndarray | None = None
    noise_px: float = float("inf")
    last_section: LastSection | None = None
    end_offset: float = float("nan")
    end_steps: np.ndarray | None = None
    in_view: np.ndarray | None = None
    last_move_px: float = 0.0
    length_held: bool = False
    told_offset: float = float("nan")
    end_profile: np.ndarray | None = None
    cap_shape: float = float("nan")
    tip_hold: str = ""
    sided: np.ndarray | None = None

    @property
    def valid_fraction(self) -> float:
        """Share of the usable profiles (not dropped at a crossing) that found the tube."""
        mask = self.usable if self.usable is not None else np.ones(self.valid.size, bool)
        return float(self.valid[mask].mean()) if mask.any() else 0.0

    @property
    def end_gap_px(self) -> float:
        """How far the last profiles, up to the tube's end, run without the
        tube's side edges, px along the curve (0 where a crossing dropped any
        of them, where the spline bridges the gap by design, or where any of
        them reaches the image's border: :func:`pipeline.view.cut_by_border`
        tells those frames)."""
        if self.valid.size == 0 or not self.valid.any():
            return float(self.curve.length)
        last = int(np.flatnonzero(self.valid)[-1])
        if self.usable is not None and not self.usable[last:].all():
            return 0.0
        if self.in_view is not None and not self.in_view[last:].all():
            return 0.0
        return float((self.u[-1] - self.u[last]) * self.curve.length)

    @property
    def coverage(self) -> float:
        """Share of the profiles usable at all (1 unless the tube crosses
        itself), or that placed the tube by the one side edge another part
        lying against it left clear (:attr:`sided`)."""
        if self.usable is None:
            return 1.0
        return float((self.usable | self.sided).mean() if self.sided is not None
                     else self.usable.mean())


def profile_spacing(half_width: float) -> float:
    """How far apart along the tube the refinement's normal profiles are, px."""
    return float(np.clip(half_width / 3.0, 2.0, 12.0))


def _profile_layout(curve: Curve, look: TubeLook, n_grid: int, window: float, width_tol: float,
                    clear: float = 2.0):
    hw = look.mean_half_width
    # a longer strip's profiles lie no nearer than it is long: overlapping
    # strips share their noise, and the midpoints' scatter from one profile to
    # the next, which the fit is judged against, would understate it (rendered
    # scenes at 8 % contrast: 7 -> 0 frames lost on one, a p95 14.6 -> 2.7 deg)
    spacing = max(profile_spacing(hw), 2.0 * look.strip_half_px)
    start = 0.25 * hw / curve.length
    # up to the end: a profile across a flat end still meets both side edges,
    # and one across a rounded end has the wrong width and is dropped
    stop = 1.0 - clear / curve.length
    n = max(int((stop - start) * curve.length / spacing), 8)
    u = np.linspace(start, stop, n)
    idx = np.clip(np.round(u * (n_grid - 1)).astype(int), 0, n_grid - 1)
    return (idx, *_profile_offsets(hw, window, width_tol))


def _tip_span(stiff_px: float, length: float, noise: float = 1.0,
              joints: tuple[float, ...] = ()) -> float:
    """The length of the tube's stiff end stretch, as a fraction of its length.

    Parameters
    ----------
    stiff_px : float
        The stretch's length on a clean frame, px.
    length : float
        The tube's length, px.
    noise : float
        The edge midpoints' scatter over its reference (≤ 1: a clean frame):
        the stretch grows in proportion, by at most
        :data:`TIP_NOISE_STRETCH_MAX` times, to at most
        :data:`TIP_STRETCH_MAX_SHARE` of the tube and not past the last
        section joint (never below ``stiff_px``).
    joints : tuple of float
        Section joints, as fractions of the length.
    """
    grow = min(max(noise, 1.0), TIP_NOISE_STRETCH_MAX)
    reach = TIP_STRETCH_MAX_SHARE * length
    if joints:
        reach = min(reach, (1.0 - joints[-1]) * length)
    return max(stiff_px, min(grow * stiff_px, reach)) / length


def _tip_rough(basis, span: float) -> np.ndarray:
    """The roughness matrix ∫φ''² du over the last ``span`` of the tube
    (:func:`_tip_span`): it holds the curvature there constant."""
    rows = basis.quad_second[basis.quad_u > 1.0 - span]
    return rows.T @ rows


def _trend_start(span: float, joints: tuple[float, ...]) -> float | None:
    """Where the stretch before the last ``span`` of the tube begins (a
    fraction of its length), or None where it would reach back to the last
    section joint (a step of the curvature there is no trend) or to the base."""
    start = 1.0 - 2.0 * span
    return None if start <= 0.0 or (joints and joints[-1] >= start) else start


def _tip_trend(n_coef: int, joints: tuple[float, ...], span: float) -> np.ndarray | None:
    """The matrix of ∫(φ''(u) − φ''(u − span))² du over the last ``span`` of
    the tube: it holds the rate of change of the curvature there (φ'') to
    what it was one stretch before, so that the curvature keeps the trend it
    had, constant or ramping, rather than its value.

    None where that stretch before cannot be read (:func:`_trend_start`).
    """
    if _trend_start(span, joints) is None:
        return None
    spline = angle_spline(n_coef, joints)
    u = 1.0 - span + span * (np.arange(TIP_TREND_NODES) + 0.5) / TIP_TREND_NODES
    # (midpoint rule; B_0, held, left out)
    rows = (spline(u, nu=2) - spline(u - span, nu=2))[:, 1:] * np.sqrt(span / TIP_TREND_NODES)
    return rows.T @ rows


def tip_stiff_px(half_width: float) -> float:
    """The stiff end stretch's length on a clean frame, px."""
    return max(TIP_STIFF_WIDTHS * 2 * half_width, TIP_STIFF_MIN_PX)


def trend_sample(curve: Curve, half_width: float) -> tuple[float, float] | None:
    """The curvature's rate of change (rad/px²) and its mean (rad/px) over the
    stretch before the clean frame's stiff end stretch (:func:`_tip_span`),
    from ``curve``'s spline; None where that stretch cannot be read
    (:func:`_trend_start`)."""
    span = _tip_span(tip_stiff_px(half_width), curve.length)
    a, b = _trend_start(span, curve.joints), 1.0 - span
    if a is None:
        return None
    spline = angle_spline(curve.coef.size, curve.joints)
    phi = spline([a, b])[:, 1:] @ curve.coef
    slope = spline([a, b], nu=1)[:, 1:] @ curve.coef
    length = curve.length
    return (float((slope[1] - slope[0]) / (span * length**2)),
            float((phi[1] - phi[0]) / (span * length)))


def _grain(centres: np.ndarray) -> float:
    """The scatter of edge midpoints from one profile to the next, px: robust
    (normal-scaled MAD) and blind to how far the curve is off them, which
    moves neighbours together (``centres`` in order along the tube)."""
    d2 = centres[2:] - 2.0 * centres[1:-1] + centres[:-2]
    return MAD_TO_SD * float(np.median(np.abs(d2 - np.median(d2)))) / np.sqrt(6.0)


def noise_ref_px(lines: int = STRIP_LINES) -> float:
    """The roughness penalty's scatter reference for strips of ``lines``
    lines (:data:`NOISE_REF_LINE_PX` over √lines), px."""
    return NOISE_REF_LINE_PX / float(np.sqrt(lines))


def strip_half_px(lines: int = STRIP_LINES) -> float:
    """How far along the tube a strip of ``lines`` lines reaches either side
    of its profile, px."""
    return 0.5 * (lines - 1) * STRIP_STEP_PX


def _strip_shifts(s: np.ndarray, length: float, clear: float = 2.0,
                  lines: int = STRIP_LINES) -> np.ndarray:
    """Where each profile's ``lines`` parallel lines lie along the tube, px
    from it: :data:`STRIP_STEP_PX` apart about it, pulled in where that would
    reach past the base or to within ``clear`` px of the tube's end (the end
    face is no side edge)."""
    half = strip_half_px(lines)
    shifts = np.linspace(-half, half, lines)
    return np.clip(shifts[None, :], -s[:, None],
                   np.maximum(length - clear - s, 0.0)[:, None])


def _profile_offsets(hw: float, window: float, width_tol: float):
    """Sample offsets across the tube (wide enough for both edges of a tube up
    to ``width_tol`` wider, anywhere within ``window``), and their step, px."""
    step = float(np.clip(hw / 24.0, 0.25, 1.0))
    half = hw * (1 + width_tol) + window + 3.0
    return np.arange(-np.ceil(half / step), np.ceil(half / step) + 1) * step, step


def refine(image: np.ndarray, curve: Curve, look: TubeLook, *, origin=(0.0, 0.0),
           window: float | None = None, iterations: int = 3, width_tol: float = 0.2,
           fit_length: bool = True, tol_px: float = 0.02, smoothing: float = 1e-3,
           free_base: bool = False, avoid_contact: bool = False,
           tip_window: float | None = None, tip_stiffness: float = TIP_STIFFNESS,
           output_stiffness: float = TIP_OUTPUT_STIFFNESS,
           tip_ratio: float | None = None, mode: np.ndarray | None = None) -> Refined:
    """Fit ``curve`` to the tube in ``image``, starting from the curve itself.

    Parameters
    ----------
    image : (rows, cols) float32 ndarray
        The frame, or a crop of it.
    curve : Curve
        Prediction, in full-frame px (y up).
    look : TubeLook
    origin : (col, row)
        Position of ``image[0, 0]`` in the full frame.
    window : float, optional
        Search range of the tube's centre around the curve, px (default:
        half the tube's half-width).
    iterations : int
        Maximum number of profile → step rounds.
    width_tol : float
        Accepted relative deviation of a profile's width from the expected one.
    fit_length : bool
        Fit the length to the tube's end (else keep it).
    tol_px : float
        Stop when no grid point moves more than this, px.
    smoothing : float
        Weight of the roughness penalty ∫φ''² du relative to the data (scaled
        by the trace of both): it damps the poorly observed wobble of the
        last spline span, which would otherwise turn tiny edge noise near the
        tip into tip-angle noise, and leaves arcs of constant curvature alone.
        Scaled up by (σ / ref)² when the edge midpoints scatter by σ > ref
        (robust estimate on each round; ref from :func:`noise_ref_px`).
    tip_stiffness : float
        Extra weight, relative to ``smoothing``, of the roughness over the last
        :data:`TIP_STIFF_WIDTHS` tube widths, or :data:`TIP_STIFF_MIN_PX` if
        longer (0: none).
    output_stiffness : float
        The same, for the shape reported (:attr:`Refined.tip_correction`):
        the last round's step solved once more with this weight, and without
        the side edges on a round cap (:data:`CAP_OUTPUT_CLEAR_HW`). Not with
        ``free_base``.
    free_base : bool
        Also fit the base direction φ(0) (through the first B-spline, the
        only one non-zero at the base) and a sideways shift of the base:
        used when the tracker starts, to measure the base tangent; afterwards
        both stay fixed.
    avoid_contact : bool
        Drop, before measuring, every profile whose search range reaches
        another part of the same tube (a crossing or a touching coil), so
        that the other layer's edges cannot be taken for this one's. The fit
        then bridges the crossing with the spline, from both sides.
    tip_window : float, optional
        How far from the curve's end to look for the tube's end, px (default:
        the side window plus half a width; wider when the length is rough).
    tip_ratio : float, optional
        With ``avoid_contact``, on a jointed curve: the last section's mean
        curvature as a multiple of the previous section's (see
        :func:`section_ratio`), held on every round on which fewer than half of
        the last section's profiles are left (:data:`TIP_RATIO_WEIGHT`).
    mode : (K,) ndarray, optional
        With ``avoid_contact`` and no ``tip_ratio``: the coefficients of the
        tube's last shape seen whole (the same spline). Where the crossing
        hides the tube's end stretch, that stretch's mean curvature is held
        at the multiple of the stretch before it that ``mode`` gives
        (:func:`_tail_hold`).
    """
    hw = look.mean_half_width
    window = 0.5 * hw if window is None else window
    shift = _crop_shift(origin)
    basis = basis_of(curve)
    clear = max(2.0, END_CLEAR_HW * hw) if look.clears_end else 2.0
    # (a round cap's side edges close in towards its apex: 10 % narrower a
    # little over half a half-width before it)
    clear = max(clear, CAP_CLEAR_HW * hw * (look.cap or 0.0))
    idx, offsets, step = _profile_layout(curve, look, basis.n_grid, window, width_tol, clear)
    u = basis.u[idx]
    hw_u = look.half_width_at(u)
    strips = _strip_shifts(u * curve.length, curve.length, clear, look.strip_lines)
    noise_ref = noise_ref_px(look.strip_lines)
    end_offset = np.nan
    k = curve.coef.size
    n_extra = 2 if free_base else 0
    n_par = k + 1 + n_extra
    end_steps = None
    told_offset = np.nan
    end_profile = None
    min_strength = 0.25 * look.strength
    stiff_px = tip_stiff_px(hw)
    clean_span = _tip_span(stiff_px, curve.length)
    clean_rough = _tip_rough(basis, clean_span)
    hold = None
    if avoid_contact and tip_ratio is not None and curve.joints:
        turns, spans = _section_turns(curve.coef.size, curve.joints)
        hold = _ratio_row(turns, spans, tip_ratio)
        in_last = u > curve.joints[-1]
    tip_found = False
    cap_shape = np.nan
    edges = None
    tip_correction = None
    tip_hold = ""
    last_section = None
    var = np.inf
    it = 0
    move = 0.0
    for it in range(1, iterations + 1):  # noqa: B007 (it is reported)
        smp = evaluate(curve, basis)
        normals = smp.normal[idx]
        from_end = (1.0 - u) * curve.length  # each profile's distance from the end, px
        profiles = sample_strips(image, smp.z[idx] - shift, normals, offsets, strips)
        facing, shown = look.facing(normals)
        edges = edge_pairs(profiles, step, hw_u, polarity=look.polarity, window=window,
                           smooth_px=look.smooth_px, facing=facing, directions=normals,
                           width_tol=width_tol, min_strength=min_strength)
        contact = np.zeros(idx.size, bool)
        free = None
        side_reach = min(window, 0.35 * hw) + 1.0
        if avoid_contact:
            # (the 2 px spare also holds the default strips' ±1 px)
            contact, free = contact_sides(
                smp.z, smp.tangent, idx, reach=hw * (2 + width_tol) + window + 2.0
                + max(look.strip_half_px - STRIP_STEP_PX, 0.0),
                gap=basis.u[1] * curve.length, normals=normals, half_width=hw,
                clear=2.0 * side_reach + look.smooth_px)
        dropped = contact.copy()
        if shown is None and look.polarity == 0:
            # a relief whose shear is not known yet: this frame's own edges may
            # tell it (where the tube runs along it, and fades, for the first time)
            shear = relief_shear(np.angle(normals),
                                 np.where(edges.valid, edges.facing * edges.strength, 0.0))
            if shear is not None:
                shown = np.abs(np.real(normals * np.exp(-1j * shear))) >= RELIEF_MIN_COS
        if shown is not None:
            dropped |= ~shown
        if dropped.any():
            edges = replace(edges, valid=edges.valid & ~dropped)
        dz_da, dz_dl = jacobian(curve, basis, smp)
        columns = [dz_da, dz_dl[:, None]]
        if free_base:
            base_normal = 1j * np.exp(1j * curve.base_angle)
            d_first = np.zeros((basis.n_grid, 1), dtype=complex)
            np.cumsum(1j * smp.chords * basis.first_mid, out=d_first[1:, 0])
            columns += [d_first, np.full((basis.n_grid, 1), base_normal)]
        dz = np.concatenate(columns, axis=1)
        rows = np.real(np.conj(normals)[:, None] * dz[idx])
        valid = edges.valid
        delta = np.where(valid, edges.centre, 0.0)
        weights = valid.astype(float)
        sig = np.inf
        tip_rough, tip_span = clean_rough, clean_span
        if valid.sum() >= 4:
            # (the normal-scaled MAD by hand, from the deviations the weights need:
            # scipy.stats.median_abs_deviation costs 9x as much per call, 15 % of
            # a tracking run in this loop)
            dev = np.abs(delta[valid] - np.median(delta[valid]))
            sig = MAD_TO_SD * np.median(dev)
            weights[valid] = np.minimum(1.0, max(1.0, 3.0 * sig) / np.maximum(dev, 1e-9))
        a_rows = [rows * weights[:, None]]
        b_rows = [delta * weights]
        # (not in a relief, whose two edges step alike: one alone is no side)
        single = (contact & (free != 0) & (from_end >= SIDE_END_HW * hw)
                  if free is not None and look.polarity != 0 else None)
        sided = np.zeros(idx.size, bool)
        if single is not None and single.any():
            # the side a coil over the profile leaves clear still places the tube
            at = np.flatnonzero(single)
            c_one, _, ok = side_edges(profiles[at], step, hw_u[at], free[at].astype(float),
                                      polarity=look.polarity, reach=side_reach,
                                      smooth_px=look.smooth_px,
                                      min_strength=SIDE_WEAKEST * look.strength,
                                      max_strength=SIDE_STRONGEST * look.strength)
            at, c_one = at[ok], c_one[ok]
            sided[at] = True
            if at.size:
                ref = float(np.median(delta[valid])) if valid.sum() >= 4 else 0.0
                w_one = SIDE_WEIGHT * np.minimum(
                    1.0, max(1.0, 3.0 * sig) / np.maximum(np.abs(c_one - ref), 1e-9))
                a_rows.append(rows[at] * w_one[:, None])
                b_rows.append(c_one * w_one)
        if look.end_step_px:
            zone = from_end < look.end_step_px
            if end_step_left_out(curve, look.end_step_px, look.end_step_offset):
                a_rows[0] = a_rows[0] * ~zone[:, None]
                b_rows[0] = b_rows[0] * ~zone
            else:
                a_rows[0], b_rows[0] = _own_offset(a_rows[0], b_rows[0], weights, zone)
        tip_found = False
        if fit_length:
            tip_off, tip_found, cap_shape = _tip_offset(
                image, smp, shift, look, window, step, nearest=avoid_contact,
                tip_window=tip_window)
            if tip_found:
                # the end sets the length only (ΔL = how far the tube's end lies
                # beyond the curve's, along the tangent); the shape is the side
                # edges' job, and their rows carry the rescaling a change of L
                # brings in this u-parametrisation
                w_tip = max(3.0, 0.05 * weights.sum())
                row = np.zeros(n_par)
                row[k] = w_tip
                a_rows.append(row[None, :])
                cap = window if tip_window is None else tip_window
                b_rows.append(np.array([w_tip * np.clip(tip_off, -cap, cap)]))
        a_mat = np.concatenate(a_rows)
        b_vec = np.concatenate(b_rows)
        lhs = a_mat.T @ a_mat
        rhs = a_mat.T @ b_vec
        pen = smoothing * np.trace(lhs[:k, :k]) / basis.roughness_trace
        if valid.sum() >= 8:
            # a smoothing spline's penalty weighs against the data's scatter: on
            # noisy frames (blur, shot noise, low contrast) the tip tangent, the
            # least constrained part of the curve, would otherwise follow the noise.
            # The scatter about the current curve (not only profile-to-profile
            # noise, measured: second differences) also counts what the fit cannot
            # yet follow, which keeps a tip bridged over a crossing stiffer (over-
            # curl scene: max error 3.9° against 10.8°)
            pen *= max(sig / noise_ref, 1.0) ** 2
            # The stiff tip stretch grows with the noise alone: grown with the
            # scatter about the curve too, it held stiff a tip whose curvature
            # steps where no joint is known, which the curve cannot yet follow
            # (sample 5, its tip joint unseen: max error 6.5° against 4.6°)
            grain = _grain(delta[valid]) / noise_ref
            if grain > 1.0:  # (else the clean frame's stretch, already built)
                tip_span = _tip_span(stiff_px, curve.length, grain, curve.joints)
                tip_rough = _tip_rough(basis, tip_span)
        rough = basis.roughness + tip_stiffness * tip_rough
        lhs[:k, :k] += pen * rough
        rhs[:k] -= pen * rough @ curve.coef
        held_tail = None
        if hold is not None and in_last.any() and valid[in_last].mean() < 0.5:
            held_tail = hold
        elif hold is None and mode is not None and mode.size == k and contact.any():
            held_tail = _tail_hold(mode, curve.joints, u, contact, hw / curve.length)
        if held_tail is not None:
            w_hold = (TIP_RATIO_WEIGHT * np.trace(lhs[:k, :k]) / k
                      / (held_tail @ held_tail))
            lhs[:k, :k] += w_hold * np.outer(held_tail, held_tail)
            rhs[:k] -= w_hold * held_tail * (held_tail @ curve.coef)

        if free_base:
            # the base direction's B_0 joins the penalty: φ(0) then follows the
            # curvature of the rest instead of kinking to fit the first few profiles
            r0 = basis.roughness_first
            j = k + 1
            lhs[j, j] += pen * r0[0]
            lhs[:k, j] += pen * r0[1:]
            lhs[j, :k] += pen * r0[1:]
            rhs[j] -= pen * r0[1:] @ curve.coef
        # Marquardt damping keeps coefficients that no valid profile constrains
        # (crossings) at their prediction; the length is held unless the tip was found
        damp = 1e-3 * np.diag(lhs) + 1e-6 * (np.trace(lhs) / n_par) + 1e-9
        if not tip_found:
            damp[k] = 1e12
        step_x = np.linalg.solve(lhs + np.diag(damp), rhs)
        move = np.abs(dz @ step_x).max()
        last = move < tol_px or it == iterations
        if last and not free_base:
            miss = a_mat @ step_x - b_vec
            n_data = int(np.count_nonzero(a_mat[:, :k].any(axis=1)))
            var = (miss @ miss) / max(n_data - k, 1)
            system, step_rep = lhs + np.diag(damp), step_x
            if look.end_in_question:
                end_offset = _end_offset(a_mat, b_vec, weights, lhs, rhs, damp,
                                         from_end < END_CLEAR_HW * hw)
            if look.end_step_px:
                told_offset = _told_offset(rows, delta, weights, zone, a_mat, b_vec,
                                           lhs + np.diag(damp), rhs)
                end_profile = _end_profile(rows, delta, weights, from_end,
                                           END_PROFILE_HW * hw, a_mat, b_vec,
                                           lhs + np.diag(damp), rhs)
            if look.end_step_in_question:
                end_steps = np.array([
                    (_end_offset(a_mat, b_vec, weights, lhs, rhs, damp, near),
                     weights[near].sum(), np.sqrt(var / max(weights[near].sum(), 1e-9)))
                    for near in (from_end < z * hw for z in END_STEP_ZONES_HW)])
        if last and output_stiffness > tip_stiffness and not free_base:
            # the same step with the tip held stiffer, for the shape reported
            # (one more solve of the same small system; the fit itself, which
            # must follow a tip that moves fast, keeps tip_stiffness)
            lhs_out, rhs_out = lhs.copy(), rhs.copy()
            # (and without the side edges on a round cap: their rows' share of
            # the normal equations taken out again)
            keep = slice(None)  # (a flat end, or none so near: no copies)
            cap_px = CAP_OUTPUT_CLEAR_HW * hw * (look.cap or 0.0)
            if (from_end < cap_px).any():
                keep = np.ones(b_vec.size, bool)
                keep[:idx.size] = from_end >= cap_px
                a_cap, b_cap = a_mat[~keep], b_vec[~keep]
                lhs_out -= a_cap.T @ a_cap
                rhs_out -= a_cap.T @ b_cap
            # held to the trend of its curvature (the fit's own constant hold
            # taken out again) where one can be read, else to a constant one
            holds = [("constant", pen * (output_stiffness - tip_stiffness) * tip_rough)]
            trend = _tip_trend(k, curve.joints, tip_span) if look.tip_trend else None
            if trend is not None:
                holds.insert(0, ("trend", pen * (output_stiffness * trend
                                                 - tip_stiffness * tip_rough)))
            tip_hold = ""
            for hold_kind, extra in holds:
                lhs_try = lhs_out + np.diag(damp)
                lhs_try[:k, :k] += extra
                rhs_try = rhs_out.copy()
                rhs_try[:k] -= extra @ curve.coef
                step_out = np.linalg.solve(lhs_try, rhs_try)
                # kept unless the edges tell against it: the rise of the residual
                # sum of squares, in units of the fit's residual variance, is a
                # chi-square of about one degree of freedom (a curvature step
                # within the stretch, a joint the fit has not found, rises 27-34)
                # (over the edges it was solved with)
                miss_out = (a_mat @ step_out - b_vec)[keep]
                if miss_out @ miss_out - miss[keep] @ miss[keep] <= TIP_OUTPUT_CHI2 * var:
                    tip_correction = step_out[:k] - step_x[:k]
                    system, step_rep = lhs_try, step_out
                    tip_hold = hold_kind
                    break
        if (last and not free_base and curve.joints and np.isfinite(var) and var > 0
                and not (hold is not None and in_last.any() and valid[in_last].mean() < 0.5)):
            # (not where the fit itself already held the last section, to the one before)
            last_section = _last_section(system, curve.coef + step_rep[:k], curve.joints, var)
        curve = curve.with_params(curve.coef + step_x[:k], max(curve.length + step_x[k], 2.0))
        if free_base:
            # B_0 = 1 − Σ_{k≥1} B_k (partition of unity): a change d of the first
            # coefficient is a new base angle φ0 + d with every other coefficient − d
            d = step_x[k + 1]
            curve = replace(curve, base_angle=curve.base_angle + d, coef=curve.coef - d,
                            base=curve.base + base_normal * step_x[k + 2])
        if last:
            break
    # residual of the last measurement against the curve it was measured from
    res = edges.centre[edges.valid]
    rms = float(np.sqrt(np.mean(res**2))) if res.size else np.inf
    # the centres' own scatter, from one profile to the next: what a smooth
    # misfit leaves out and noise does not
    jumps = np.diff(res)
    noise = (float(MAD_TO_SD * np.median(np.abs(jumps - np.median(jumps))) / np.sqrt(2))
             if jumps.size >= 4 else np.inf)
    width = np.where(edges.valid, edges.width, np.nan)
    strength = float(np.median(edges.strength[edges.valid])) if res.size else 0.0
    mids = np.where(edges.valid, smp.z[idx] + normals * np.where(edges.valid, edges.centre, 0),
                    np.nan)
    reach = float(np.abs(offsets).max()) + 1.0
    at = smp.z[idx] - shift
    in_view = ((at.real >= reach) & (at.real <= image.shape[1] - 1 - reach)
               & (-at.imag >= reach) & (-at.imag <= image.shape[0] - 1 - reach))
    return Refined(curve, u, width, edges.valid, rms, tip_found, it, strength, ~dropped, mids,
                   tip_correction, noise, last_section, end_offset, end_steps, in_view=in_view,
                   last_move_px=float(move), told_offset=told_offset, end_profile=end_profile,
                   cap_shape=cap_shape, tip_hold=tip_hold, sided=sided)


def end_step_left_out(curve: Curve, step_px: float, offset_px: float) -> bool:
    """Whether a fit of ``curve`` leaves out the side edges of the told
    stretch of ``step_px`` at its end, whose midpoints sat ``offset_px`` off
    the rest's line (:attr:`TubeLook.end_step_px`, ``end_step_offset``),
    rather than give them a sideways offset of their own: where the stretch
    is at most :data:`END_STEP_LEAVE_OUT` of the last section (the whole
    tube, on a curve without joints) and its offset a lumen's, at most
    :data:`END_STEP_LEAVE_OUT_MAX_PX`."""
    last = 1.0 - (curve.joints[-1] if curve.joints else 0.0)
    return (0.0 < step_px <= END_STEP_LEAVE_OUT * last * curve.length
            and abs(offset_px) <= END_STEP_LEAVE_OUT_MAX_PX)


def _own_offset(a_w, b_w, weights, zone):
    """The weighted rows ``a_w``, ``b_w`` of the side edges' least squares with
    the profiles in ``zone`` given a sideways offset of their own: the same
    solution as an extra unknown for it, eliminated (each of those rows less
    the zone's mean, weighted as the rows are)."""
    w = np.where(zone, weights, 0.0)
    total = w @ w
    if total <= 0.0:
        return a_w, b_w
    a_w, b_w = a_w.copy(), b_w.copy()
    a_w[zone] -= np.outer(weights[zone], (w @ a_w) / total)
    b_w[zone] -= weights[zone] * ((w @ b_w) / total)
    return a_w, b_w


def _off_rest(rows, delta, zone, a_mat, b_vec, system, rhs) -> np.ndarray:
    """Each profile's edge midpoint offset from the curve that the profiles
    outside ``zone`` alone fit, px (along the left normal). ``rows``,
    ``delta``: the profiles' rows and offsets before weighting; ``a_mat``,
    ``b_vec``: the rows as fitted (the profiles' first); ``system``, ``rhs``:
    the normal equations solved, damping and penalties in."""
    used = np.flatnonzero(zone)
    a_e, b_e = a_mat[used], b_vec[used]
    x = np.linalg.solve(system - a_e.T @ a_e, rhs - a_e.T @ b_e)
    return delta - rows @ x


def _told_offset(rows, delta, weights, zone, a_mat, b_vec, system, rhs) -> float:
    """The weighted mean offset of the edge midpoints in ``zone`` (the told
    stretch at the end, which the fit left out or gave an offset of its own)
    from the curve that the other profiles alone fit (:func:`_off_rest`), px;
    NaN where no valid profile lies there."""
    near = zone & (weights > 0)
    if not near.any():
        return np.nan
    off = _off_rest(rows, delta, zone, a_mat, b_vec, system, rhs)
    return float(np.sum(weights[near] * off[near]) / np.sum(weights[near]))


def _end_profile(rows, delta, weights, from_end, reach_px, a_mat, b_vec, system,
                 rhs) -> np.ndarray | None:
    """The valid profiles within ``reach_px`` of the end: their distance from
    it (px), their edge midpoints' offset from the curve the profiles farther
    off alone fit (:func:`_off_rest`, px) and their weight, as rows; None
    where none is valid."""
    zone = from_end < reach_px
    near = zone & (weights > 0)
    if not near.any():
        return None
    off = _off_rest(rows, delta, zone, a_mat, b_vec, system, rhs)
    return np.c_[from_end[near], off[near], weights[near]]


def _end_offset(a_mat, b_vec, weights, lhs, rhs, damp, near_end) -> float:
    """How far the edge midpoints near the tube's end lie, on average, from the
    curve that the other profiles alone would fit (px, along the curve's left
    normal); NaN when no valid profile is that near."""
    rows = np.flatnonzero(near_end & (weights > 0))
    if rows.size == 0:
        return np.nan
    a_e, b_e = a_mat[rows], b_vec[rows]
    x = np.linalg.solve(lhs - a_e.T @ a_e + np.diag(damp), rhs - a_e.T @ b_e)
    return float(np.sum(b_e - a_e @ x) / np.sum(weights[rows]))


def _tail_hold(mode: np.ndarray, joints: tuple[float, ...], u: np.ndarray,
               hidden: np.ndarray, hw_u: float) -> np.ndarray | None:
    """The row H with ``H @ coef = 0`` holding a hidden end stretch's mean
    curvature at the multiple of the stretch before it (as long, or the rest
    of the tube if shorter) that the shape ``mode`` has; None where the
    profiles at the end are not hidden over at least
    :data:`TAIL_HOLD_MIN_HW` half-widths (``hw_u``: a half-width as a
    fraction of the length), or the stretch before turns less than
    :data:`TIP_RATIO_MIN_TURN` in ``mode``.

    ``u``: the profiles' positions (ascending fractions of the length);
    ``hidden``: which of them the crossing hides."""
    if not hidden[-1]:
        return None
    seen = np.flatnonzero(~hidden)
    if not seen.size:
        return None
    # (rounded, so that the turns' rows are reused from frame to frame)
    start = round(float(u[seen[-1] + 1]), 3)
    if 1.0 - start < TAIL_HOLD_MIN_HW * hw_u:
        return None
    span = min(1.0 - start, start)
    turns, spans = _turns_between(mode.size, joints, (start - span, start, 1.0))
    ratio = _stretch_ratio(turns, spans, mode)
    return None if ratio is None else _ratio_row(turns, spans, ratio)


def _stretch_ratio(turns: np.ndarray, spans: np.ndarray, coef: np.ndarray) -> float | None:
    """Mean curvature of the second stretch of ``turns``/``spans``
    (:func:`_turns_between`) over the first's, in the shape ``coef``; None
    where the first turns less than :data:`TIP_RATIO_MIN_TURN`."""
    before, last = turns @ coef
    if abs(before) < TIP_RATIO_MIN_TURN:
        return None
    return float((last / spans[1]) / (before / spans[0]))


def _ratio_row(turns: np.ndarray, spans: np.ndarray, ratio: float) -> np.ndarray:
    """The row H with ``H @ coef = 0`` where the second stretch's mean
    curvature is ``ratio`` times the first's."""
    return turns[1] / spans[1] - ratio * turns[0] / spans[0]


def _section_turns(n_coef: int, joints: tuple[float, ...]):
    """Rows T with ``T @ coef`` the turns (rad) of a jointed curve's
    second-to-last and last sections, and those sections' lengths (fractions)."""
    return _turns_between(n_coef, joints, (joints[-2] if len(joints) > 1 else 0.0,
                                           joints[-1], 1.0))


def _rest_turns(n_coef: int, joints: tuple[float, ...]):
    """As :func:`_section_turns`, for the whole tube before the last joint
    and the last section."""
    return _turns_between(n_coef, joints, (0.0, joints[-1], 1.0))


@lru_cache(maxsize=64)
def _turns_between(n_coef: int, joints: tuple[float, ...], ends: tuple[float, ...]):
    """Rows T with ``T @ coef`` the turns (rad) between consecutive ``ends``
    (fractions of the length), and the stretches' lengths (fractions)."""
    ends = np.array(ends)
    # φ − φ(0) is the spline without its first function (whose coefficient is 0)
    values = BSpline.design_matrix(ends, knot_vector(n_coef, joints), 3).toarray()[:, 1:]
    turns, spans = np.diff(values, axis=0), np.diff(ends)
    for arr in (turns, spans):
        arr.flags.writeable = False
    return turns, spans


def section_ratio(curve: Curve) -> float | None:
    """Mean curvature of a jointed curve's last section over the previous one's.

    None without joints, when the previous section turns less than
    :data:`TIP_RATIO_MIN_TURN` (a ratio to a nearly straight section is noise),
    or when the last turns the other way by as much: both of the paper's
    models bend every section the same way under one load, so such a ratio
    is no tube's (a
    holder's mouth tracked as the tube's first stretch, hooked, its width
    steps taken for joints: -0.7 and -2.8 on two independent over-curls,
    whose tips over the holder were then held to it, 16-33 deg off).
    """
    if not curve.joints:
        return None
    turns, spans = _section_turns(curve.coef.size, curve.joints)
    ratio = _stretch_ratio(turns, spans, curve.coef)
    # (a nearly straight last section turns either way by noise: held to its
    # small ratio, as before)
    opposite = (ratio is not None and ratio < 0.0
                and abs(turns[1] @ curve.coef) >= TIP_RATIO_MIN_TURN)
    return None if opposite else ratio


def widths_at(image: np.ndarray, curve: Curve, look: TubeLook, u: np.ndarray, *,
              width_tol: float = 0.3, origin=(0.0, 0.0)) -> np.ndarray:
    """The tube's outer width measured across ``curve`` at fractions ``u`` of
    its length (any spacing, e.g. 1 px apart about a section joint), px; NaN
    where no edge pair of a plausible width is found. ``image`` may be a crop
    whose top-left pixel is at ``origin`` (col, row) of the frame."""
    edges = edges_at(image, curve, look, u, width_tol=width_tol, origin=origin)
    return np.where(edges.valid, edges.width, np.nan)


def edges_at(image: np.ndarray, curve: Curve, look: TubeLook, u: np.ndarray, *,
             width_tol: float = 0.3, origin=(0.0, 0.0)) -> Edges:
    """The tube's edge pairs across ``curve`` at fractions ``u`` of its length
    (offsets from the curve, px), as ``look`` finds them; ``image`` may be a
    crop whose top-left pixel is at ``origin`` (col, row) of the frame."""
    return _edges_across(image, curve, look, np.asarray(u, dtype=float), width_tol, origin)[0]


def _edges_across(image, curve: Curve, look: TubeLook, u: np.ndarray, width_tol: float,
                  origin):
    """:func:`edges_at`'s edges, and the profiles' points on the curve (in the
    crop), their directions and their sample offsets (px)."""
    z, normal = _across(curve, u, origin)
    hw = look.mean_half_width
    window = 0.3 * hw
    offsets, step = _profile_offsets(hw, window, width_tol)
    edges = edge_pairs(sample_lines(image, z, normal, offsets), step, look.half_width_at(u),
                       smooth_px=look.smooth_px,
                       polarity=look.polarity, window=window, width_tol=width_tol,
                       min_strength=0.25 * look.strength)
    return edges, z, normal, offsets


def antisymmetry(image: np.ndarray, curve: Curve, half_width: float) -> float:
    """How odd the image is across ``curve``: ‖odd part‖ / ‖even part‖.

    Profiles across the tube (±1.3 half-widths, on 58 points along it) less
    their background (the median of their ends) are split into the parts
    even and odd about the curve. A tube that is darker or brighter than the
    background, or has rims, is even; a relief (differential interference
    contrast) is odd: lit on one flank, shaded on the other. Measured on 53
    rendered scenes of ordinary looks: at most 0.51; on 12 reliefs: 0.8-8.
    """
    basis = basis_of(curve)
    smp = evaluate(curve, basis)
    idx = np.linspace(0, basis.n_grid - 1, 64).round().astype(int)[3:-3]
    offsets = np.linspace(-1.3 * half_width, 1.3 * half_width, 53)
    prof = sample_lines(image, smp.z[idx], 1j * np.exp(1j * smp.phi[idx]), offsets)
    prof = prof[~np.isnan(prof).any(axis=1)]
    if prof.size == 0:
        return 0.0
    dev = prof - np.median(np.concatenate([prof[:, :4], prof[:, -4:]], axis=1), axis=1,
                           keepdims=True)
    even = float(np.sum((dev + dev[:, ::-1]) ** 2))
    odd = float(np.sum((dev - dev[:, ::-1]) ** 2))
    return float(np.sqrt(odd / even)) if even > 0 else np.inf


def relief_edges(image: np.ndarray, curve: Curve, look: TubeLook, *,
                 origin=(0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """The tube's edge steps in a relief image, signed by the way they step.

    On 96 profiles across ``curve`` the edge pair is found both ways (both
    edges stepping up along the profile, or both down: see
    :func:`pipeline.profiles.edge_pairs`) and the stronger kept. ``image``
    may be a crop whose top-left pixel is at ``origin`` (col, row) of the frame.

    Returns
    -------
    theta : (K,) ndarray
        Directions of the profiles that lie in the image, rad (y up).
    signed : (K,) ndarray
        Their steps, intensity per px, negative if down; 0 where no pair was
        found (where the tube runs along the shear its edges fade).
    """
    u = np.linspace(0.02, 0.98, 96)
    e, z, normal, offsets = _edges_across(image, curve, replace(look, polarity=0, shear=None),
                                          u, 0.3, origin)
    # (the profiles wholly inside the image; the others are left out)
    ends = z[:, None] + normal[:, None] * offsets[[0, -1]][None, :]
    rows, cols = image.shape[:2]
    inside = ((ends.real >= 0) & (ends.real <= cols - 1)
              & (-ends.imag >= 0) & (-ends.imag <= rows - 1)).all(axis=1)
    signed = np.where(e.valid, e.facing * e.strength, 0.0)
    return np.angle(normal[inside]), signed[inside]


def _across(curve: Curve, u: np.ndarray, origin) -> tuple[np.ndarray, np.ndarray]:
    """Points of ``curve`` at fractions ``u`` of its length in a crop whose
    top-left pixel is at ``origin`` (col, row) of the frame, and the left
    normals there (px, y up)."""
    basis = basis_of(curve)
    smp = evaluate(curve, basis)
    z = np.interp(u, basis.u, smp.z.real) + 1j * np.interp(u, basis.u, smp.z.imag)
    return z - _crop_shift(origin), 1j * np.exp(1j * np.interp(u, basis.u, smp.phi))


def _crop_shift(origin) -> complex:
    """Where a crop whose top-left pixel is at ``origin`` (col, row) of the
    frame starts, in the frame's y-up px: subtracted, it takes frame points
    into the crop."""
    return complex(origin[0], -origin[1])


def relief_shear(theta: np.ndarray, signed: np.ndarray) -> float | None:
    """The shear direction of a relief image from the tube's signed edge steps.

    In differential interference contrast (or oblique light) the image is,
    to first order, the slope of the optical thickness along a fixed
    direction e: the tube's flank whose inward normal faces e shows bright,
    the other dark, with a step ∝ cos(normal, e), fading where the tube runs
    along e. So a profile of direction θ steps up where cos(θ − e) > 0 and
    down where it is < 0. Every e (on a 0.5° grid) is scored by the steps
    ``signed`` (:func:`relief_edges`, of one frame or several) whose sign it
    gets wrong, plus the profiles that found no edges where it expects a
    step (|cos| ≥ :data:`RELIEF_MIN_COS`); the middle of the best-scored run
    of e is taken. The step's size is not used: it saturates on strong edges.

    Returns
    -------
    float or None
        e, rad, counter-clockwise from +x (y up). None while that run is
        wider than :data:`RELIEF_MAX_SPREAD_DEG` or not the only one (the
        tube's profiles have not yet pointed both ways about the direction
        where it fades), when the best e still gets more than a tenth as
        many wrong as there are steps, while neither both ways nor one way
        and faded are each seen on a tenth of the profiles (at least 4), or
        when most of the steps seen lie where the best e says they are under
        :data:`RELIEF_TOLD_COS` of their full size.
    """
    theta = np.asarray(theta, dtype=float)
    signed = np.asarray(signed, dtype=float)
    seen = signed != 0
    enough = max(4, 0.1 * signed.size)
    up, down, faded = (signed > 0).sum(), (signed < 0).sum(), (~seen).sum()
    if not (min(up, down) >= enough or min(max(up, down), faded) >= enough):
        # e is bounded on both sides by steps of both ways, or by steps one
        # way and a faded stretch, each on enough profiles that a stray pair
        # cannot set it
        return None
    grid = np.radians(np.arange(0.0, 360.0, 0.5))
    c = np.cos(theta[:, None] - grid[None, :])
    wrong = np.where(seen[:, None], np.sign(c) != np.sign(signed)[:, None],
                     np.abs(c) >= RELIEF_MIN_COS)
    cost = wrong.sum(axis=0)
    best = cost == cost.min()
    if best.all() or cost.min() > 0.1 * seen.sum():
        return None  # no e explains the signs: not a relief's edges, or too few
    # rolled to start where e is not best, the best e are runs that do not wrap
    k = int(np.argmin(best))
    edges = np.diff(np.roll(best, -k).astype(int), append=0)
    starts, ends = np.flatnonzero(edges == 1) + 1, np.flatnonzero(edges == -1) + 1
    if starts.size != 1 or (ends[0] - starts[0]) * 0.5 > RELIEF_MAX_SPREAD_DEG:
        return None  # e not yet pinned down
    centre = grid[0] + np.radians(0.5 * (k + 0.5 * (starts[0] + ends[0] - 1)))
    if np.median(np.abs(np.cos(theta[seen] - centre))) < RELIEF_TOLD_COS:
        return None  # most steps seen where e says they are all but faded
    return float(np.angle(np.exp(1j * centre)))


def _tip_offset(image, smp, shift, look: TubeLook, window: float, step: float, *,
                nearest: bool = False, tip_window: float | None = None):
    """Offset of the tube's end (its apex) from the curve's end along the tip
    tangent, px; whether it was found; and the end's shape the lines saw
    (:attr:`Refined.cap_shape`)."""
    hw = look.mean_half_width
    tangent = smp.tangent[-1]
    normal = 1j * tangent
    # across the whole end face: a hollow tube's end is strongest near its walls
    relief = look.polarity == 0
    lateral = np.array([-0.85, -0.7, -0.4, 0.0, 0.4, 0.7, 0.85] if relief
                       else [-0.7, -0.4, 0.0, 0.4, 0.7]) * hw
    # how far short of its apex a round cap of the tube's radius ends on each line
    short = hw - np.sqrt(np.maximum(hw**2 - lateral**2, 0.0))
    starts = smp.z[-1] - shift + normal * lateral
    reach = window + 0.5 * hw if tip_window is None else tip_window
    half = reach + 0.5 * hw + 3.0
    offsets = np.arange(-np.ceil(half / step), np.ceil(half / step) + 1) * step
    prof = sample_lines(image, starts, np.full(lateral.size, tangent), offsets)
    # a relief shows a cut end face as a thin line, a round cap as a lobe:
    # sharp outside, where the path through the cap falls to nothing, and
    # with no face's inner flank inside (see end_edge's face_line)
    face_line = not (relief and bool(look.cap))
    off, strength = end_edge(prof, step, polarity=look.polarity, window=reach,
                             smooth_px=look.smooth_px,
                             nearest=nearest, face_line=face_line)
    good = np.isfinite(off) & (strength > 0.25 * look.strength)
    if good.sum() < 2:
        return 0.0, False, np.nan
    shaped = good & _cap_lines(lateral, hw, relief)
    cap_shape = _cap_shape(off[shaped], short[shaped], hw)
    used = np.flatnonzero(good)
    if relief:
        # an end face square to the shear fades, and the lines across the lumen
        # then stop at the lumen's end (a sealed tip's plug); the lines within
        # the walls, where the walls' strong relief stops, reach the end: the
        # median of the three lines whose end steps are strongest
        strongest = np.argsort(np.where(good, strength, -np.inf))[::-1][:3]
        used = strongest[good[strongest]]
    coarse = float(np.median(off[used]))
    # (a round cap's apex lies beyond the lines' median end by the median of
    # how far short each line ends: added to that median, not to each line
    # first, which a tip tangent turned off the tube's amplified into a
    # runaway where the outer lines left the cap through its side)
    if not relief:
        to_apex = (look.cap or 0.0) * float(np.median(short[used]))
    else:
        # the three strongest lines lie unevenly about the axis (over a
        # hollow tube's end, the lumen's end shows on some as strongly as the
        # cap), and the median of their shortfalls belonged to another line
        # than the median end: the median line's (or the two middle lines')
        # own. (On every look it moved the tip 1-3 px on a few fast or
        # blurred frames, one runaway to 6x the tube's length: 4 of 120
        # independent scenes' medians worse, 3 better.)
        order = used[np.argsort(off[used], kind="stable")]
        middle = order[(order.size - 1) // 2: order.size // 2 + 1]
        to_apex = (look.cap or 0.0) * float(np.mean(short[middle]))
    lines = starts[good]
    if look.strip_lines > STRIP_LINES and not relief:
        pooled = _pooled_end(image, smp.z[-1] - shift, tangent, look, reach, offsets, step,
                             nearest)
        if pooled is not None:
            (coarse, lines), to_apex = pooled, 0.0
    if look.smooth_px <= TIP_FOCUS_PX:
        return coarse + to_apex, True, cap_shape
    # edge focusing (coarse to fine): the wide filter a noisy frame needs to find
    # the end also moves it, away from a step of the other sign close by (a
    # sealed tip's plug, brighter or darker than the hollow tube: +1 to 2 px on a
    # small fluorescent tube, 1.7 % of its length). Placed again with the narrow
    # filter within reach of where the wide one put it, on the mean of the lines
    # (averaged, their noise falls by the square root of their number)
    reach = look.smooth_px + 1.0
    half = reach + 3.0 * TIP_FOCUS_PX
    offsets = np.arange(-np.ceil(half / step), np.ceil(half / step) + 1) * step
    prof = sample_lines(image, lines + tangent * coarse, np.full(lines.size, tangent), offsets)
    fine, _ = end_edge(_lines_mean(prof), step, polarity=look.polarity, window=reach,
                       smooth_px=TIP_FOCUS_PX, nearest=True, face_line=face_line)
    return (coarse + (float(fine[0]) if np.isfinite(fine[0]) else 0.0) + to_apex, True,
            cap_shape)


def _pooled_end(image, end, tangent, look: TubeLook, reach: float, offsets, step: float,
                nearest: bool) -> tuple[float, np.ndarray] | None:
    """The apex's offset along ``tangent`` from the curve's ``end`` (image
    px), found on the mean of lines along the tangent across the end face
    (:data:`TIP_POOL_HW`, one per :attr:`TubeLook.strip_lines`), each moved
    back by how far short of the apex the tube's cap ends on it, and the
    lines' starts; None where the mean shows no end.

    On a frame whose noise needed longer strips for the side edges: there,
    each line's outermost strong step within reach is as often a noise
    bump beyond the end as the end itself, and their median runs on frame
    after frame; the mean of n lines has 1/√n of their noise."""
    hw = look.mean_half_width
    lateral = np.linspace(-TIP_POOL_HW, TIP_POOL_HW, look.strip_lines) * hw
    short = hw - np.sqrt(np.maximum(hw**2 - lateral**2, 0.0))
    normal = 1j * tangent
    starts = end + normal * lateral - tangent * (look.cap or 0.0) * short
    prof = sample_lines(image, starts, np.full(lateral.size, tangent), offsets)
    off, strength = end_edge(_lines_mean(prof), step, polarity=look.polarity, window=reach,
                             smooth_px=look.smooth_px, nearest=nearest)
    if not (np.isfinite(off[0]) and strength[0] > 0.25 * look.strength):
        return None
    return float(off[0]), starts


def _lines_mean(prof: np.ndarray) -> np.ndarray:
    """The mean of parallel lines' profiles (rows), each sample over the lines
    that have it (NaN off the image): one profile, shape (1, samples)."""
    seen = np.isfinite(prof).sum(axis=0)
    return np.where(seen > 0, np.nansum(prof, axis=0) / np.maximum(seen, 1), np.nan)[None, :]


def _cap_lines(lateral: np.ndarray, half_width: float, relief: bool) -> np.ndarray:
    """Which of the lines along the tip tangent, ``lateral`` px off the axis,
    tell the end's shape (:func:`_cap_shape`): all of them; in a relief, those
    within a hollow tube's walls (:data:`RELIEF_CAP_LINES_HW`). There the lines
    across the lumen end on the lumen's end (a sealed tip's plug), 1-12 px
    short of the cap the walls' lines trace (an independent renderer's DIC
    tube 10 px in half-width): fitted with them the cap's shape missed, the
    end was voted flat, and the tip put 3.7 px short of its apex on every
    frame."""
    if not relief:
        return np.ones(lateral.shape, bool)
    return np.abs(lateral) >= RELIEF_CAP_LINES_HW * half_width


def _cap_shape(off: np.ndarray, short: np.ndarray, half_width: float) -> float:
    """The share of a round cap that the lines' ends ``off`` (px along the
    tip tangent) fit best, each ``short`` (px) short of the apex on a full
    one: least squares of ``off = apex − share·short``. NaN where the lines
    that found the end do not span both the axis and the walls, where they do
    not fit that pattern (:data:`CAP_FIT_HW`: a tip that lies against the
    tube's own body, or a tip tangent turned off the tube's, ends them
    unevenly), or where the share lies outside :data:`CAP_SHARES`."""
    if off.size < 3 or np.ptp(short) < 0.1 * half_width:
        return np.nan
    design = np.c_[np.ones(off.size), -short]
    coef, *_ = np.linalg.lstsq(design, off, rcond=None)
    misfit = float(np.sqrt(np.mean((off - design @ coef) ** 2)))
    share = float(coef[1])
    if misfit > CAP_FIT_HW * half_width or not CAP_SHARES[0] <= share <= CAP_SHARES[1]:
        return np.nan
    return share


def contact_mask(z: np.ndarray, idx: np.ndarray, *, reach: float, gap: float,
                 normals: np.ndarray | None = None,
                 half_width: float | None = None) -> np.ndarray:
    """Which profile points have another part of the curve within ``reach`` px.

    "Another part" is any point farther along the curve than ``reach`` plus
    half a turn's worth of arc: neighbours along the tube are always near.

    Parameters
    ----------
    z : (Q,) complex ndarray
        Curve points (grid spacing ``gap`` px).
    idx : (M,) int ndarray
        Grid indices of the profile points.
    normals : (M,) complex ndarray, optional
        Unit normals of the profiles: then only another part whose tube (of
        ``half_width``) reaches the profile's line counts, within ``reach``
        along it. A tip that ends against the tube's own body keeps the
        profiles that run beside that body rather than into it (over-curl:
        they bridged the last width blind and put the tip 3 px astray).
    half_width : float, optional
        The tube's half-width, px (with ``normals``).
    """
    if normals is not None:
        return _parts_on_lines(z, idx, reach, gap, normals, half_width)[0].any(axis=1)
    stride = max(1, int(reach / (3 * gap)))
    pts = z[::stride]
    pos = np.arange(0, z.size, stride)
    far = np.abs(idx[:, None] - pos[None, :]) * gap > np.pi * reach
    return np.any((np.abs(pts[None, :] - z[idx][:, None]) < reach) & far, axis=1)


def _parts_on_lines(z, idx, reach, gap, normals, half_width):
    """Which other parts of the curve reach each profile's line.

    Parameters
    ----------
    z : (Q,) complex ndarray
        Curve points, ``gap`` px apart.
    idx : (M,) int ndarray
        Grid indices of the profile points.
    reach, gap : float
        Reach along the profile, and the grid spacing, px.
    normals : (M,) complex ndarray
        The profiles' unit normals.
    half_width : float
        The tube's, px.

    Returns
    -------
    crosses : (M, P) bool ndarray
        For every ``stride``-th curve point farther along the curve than
        half a turn of ``reach``: whether its tube reaches the profile's
        line within ``reach`` px along it.
    rel : (M, P) complex ndarray
        Those points' offsets from the profile's point, px (real: across
        the tube, along the profile; imaginary: along the tube).
    stride : int
    """
    # other points at most half a width (plus a stride) off the profile's line
    stride = max(1, int(0.5 * half_width / gap))
    pts = z[::stride]
    pos = np.arange(0, z.size, stride)
    rel = (pts[None, :] - z[idx][:, None]) * np.conj(normals)[:, None]
    far = np.abs(idx[:, None] - pos[None, :]) * gap > np.pi * reach
    crosses = (far & (np.abs(rel.real) < reach)
               & (np.abs(rel.imag) < half_width + stride * gap + 1.0))
    return crosses, rel, stride


def contact_sides(z: np.ndarray, tangent: np.ndarray, idx: np.ndarray, *, reach: float,
                  gap: float, normals: np.ndarray, half_width: float,
                  clear: float) -> tuple[np.ndarray, np.ndarray]:
    """Which profiles another part of the curve reaches (as
    :func:`contact_mask` with ``normals``), and which side of each such
    profile it leaves clear.

    Parameters
    ----------
    z, tangent : (Q,) complex ndarray
        Curve points (grid spacing ``gap`` px) and their unit tangents.
    idx : (M,) int ndarray
        Grid indices of the profile points.
    reach, gap, normals, half_width
        As :func:`contact_mask`.
    clear : float
        How far (px) off the profile's point every other part must lie on
        the one side for the other side to count as clear.

    Returns
    -------
    contact : (M,) bool ndarray
        Whether another part of the curve reaches the profile.
    free : (M,) ndarray of {−1, 0, +1}
        The side (along the profile's normal) that every other part leaves
        clear: they all lie on the other side, at least ``clear`` off, and run
        within :data:`SIDE_PARALLEL_DEG` of the profile's own stretch (a
        crossing at a steep angle lies over both edges); 0 where none is.
    """
    crosses, rel, stride = _parts_on_lines(z, idx, reach, gap, normals, half_width)
    contact = crosses.any(axis=1)
    # (a part crossing at a steep angle lies over both of the profile's edges)
    turn = tangent[::stride][None, :] * np.conj(tangent[idx])[:, None]
    steep = (crosses & (np.abs(turn.imag) > np.sin(np.radians(SIDE_PARALLEL_DEG)))).any(axis=1)
    above = (crosses & (rel.real > 0)).any(axis=1)
    below = (crosses & (rel.real < 0)).any(axis=1)
    nearest = np.where(crosses, np.abs(rel.real), np.inf).min(axis=1)
    free = np.where(above & ~below, -1, np.where(below & ~above, 1, 0))
    free[steep | (nearest < clear)] = 0
    return contact, free


def self_contact(curve: Curve, half_width: float) -> bool:
    """Whether the tube, drawn with this centreline, touches or crosses itself."""
    basis = basis_of(curve)
    z = evaluate(curve, basis).z
    gap = basis.u[1] * curve.length
    idx = np.arange(0, z.size, max(1, int(half_width / (2 * gap))))
    return bool(contact_mask(z, idx, reach=2.2 * half_width, gap=gap).any())


def pipette_axis(image: np.ndarray, curve: Curve, look: TubeLook, *,
                 origin=(0.0, 0.0)) -> tuple[float, complex] | None:
    """The axis of the pipette that holds the tube, or None.

    The tube leaves the pipette along its axis, so the axis is the base
    tangent, measured apart from the tube's bend (a base tangent fitted to a
    bent tube leans 0.6-0.7° into the bend). Profiles across the base axis
    behind the base, over :data:`PIPETTE_WIDTHS` of the tube's width, find the
    pipette's edge pairs (at the narrower widths a pipette has), and a robust
    line through their midpoints gives the axis. Where no such pairs show,
    the outer edges of a holder wider than the tube (a clamp, or a capillary
    the tube is pushed into: :data:`WIDE_HOLDER_RATIOS`) give its direction.
    None unless at least :data:`PIPETTE_MIN_PROFILES` agree to
    :data:`PIPETTE_MAX_SCATTER_PX` (no holder in view, or something else
    behind the base) and give its direction to :data:`PIPETTE_MAX_SE_DEG` (a
    short or faint holder), or if the axis is more than
    :data:`PIPETTE_MAX_TURN_DEG` off the curve's base tangent.

    Returns
    -------
    (direction, base) or None
        The axis's direction, rad (y up), pointing to the tube, and the point
        on it abreast of the curve's base, full-frame px (y up): the tube
        leaves a pipette on its axis. A wide holder's midline need not be the
        tube's (a tube off-centre in its clamp): there the base is the curve's;
        so too where the line lies over :data:`PIPETTE_MAX_ASIDE_HW` off it.
    """
    hw = float(look.half_width[0])
    found = _holder_line(image, curve, look, origin, PIPETTE_RATIOS, 0.4 * hw)
    if found is not None:
        turn, aside = found
        aside = aside if abs(aside) <= PIPETTE_MAX_ASIDE_HW * hw else 0.0
        return (float(curve.base_angle + turn),
                complex(curve.base + 1j * np.exp(1j * curve.base_angle) * aside))
    # (searched wider: the tube may sit anywhere between a wide holder's edges)
    found = _holder_line(image, curve, look, origin, WIDE_HOLDER_RATIOS,
                         0.5 * max(WIDE_HOLDER_RATIOS) * hw)
    if found is not None:
        return float(curve.base_angle + found[0]), complex(curve.base)
    return None


def _holder_line(image: np.ndarray, curve: Curve, look: TubeLook, origin,
                 ratios: tuple[float, ...], window: float) -> tuple[float, float] | None:
    """The line through the midpoints of the holder's edge pairs behind
    ``curve``'s base (within ``window`` px of its base axis), at the one of
    the half-widths ``ratios`` (× the tube's) whose pairs are found most
    often: its turn from the base tangent, rad, and its offset to the left of
    the base, px; None where it does not stand (see :func:`pipette_axis`)."""
    hw = float(look.half_width[0])
    axis = np.exp(1j * curve.base_angle)
    ratios = np.asarray(ratios, dtype=float)
    s = np.arange(0.5 * hw, PIPETTE_WIDTHS * 2 * hw, max(1.0, hw / 6))
    step = 0.25
    reach = ratios.max() * hw + window
    offsets = np.arange(-reach, reach + step / 2, step)
    prof = sample_lines(image, curve.base - _crop_shift(origin) - s * axis,
                        np.full(s.size, 1j * axis), offsets)
    # every width tried in one call (the profiles stacked once per width), and
    # the width whose pairs are found most often kept
    m = s.size
    pairs = edge_pairs(np.tile(prof, (ratios.size, 1)), step, np.repeat(ratios * hw, m),
                       polarity=look.polarity, window=window, width_tol=0.25,
                       smooth_px=look.smooth_px, min_strength=0.25 * look.strength)
    pick = int(np.argmax(pairs.valid.reshape(ratios.size, m).sum(axis=1)))
    best = Edges(*(getattr(pairs, f)[pick * m:(pick + 1) * m]
                   for f in ("centre", "width", "strength", "valid")))
    keep = best.valid.copy()
    for _ in range(3):
        if keep.sum() < PIPETTE_MIN_PROFILES:
            return None
        slope, icpt = np.polyfit(s[keep], best.centre[keep], 1)
        res = np.where(best.valid, best.centre - (slope * s + icpt), np.inf)
        spread = MAD_TO_SD * np.median(np.abs(res[keep]))
        keep = best.valid & (np.abs(res) <= max(3.0 * spread, 0.1))
    if keep.sum() < PIPETTE_MIN_PROFILES or np.std(res[keep]) > PIPETTE_MAX_SCATTER_PX:
        return None
    # how well the line's direction is known: its slope's standard error
    slope_se = np.std(res[keep]) / (np.sqrt(keep.sum()) * max(float(np.std(s[keep])), 1e-9))
    if np.degrees(slope_se) > PIPETTE_MAX_SE_DEG:
        return None
    # offsets along the left normal grow by slope per px behind the base: the
    # axis, pointing from the pipette to the tube, turns by −atan(slope)
    turn = -np.arctan(slope)
    if abs(turn) > np.radians(PIPETTE_MAX_TURN_DEG):
        return None
    return float(turn), float(icpt)


def _base_step(image, starts, phi, hw: float, look: TubeLook, step: float):
    """Where the profiles at ``starts`` (every ``step`` px along the base
    search) step from "not the tube" to "the tube": the index of the first profile
    past the step, or None (also where every profile shows the tube's edge
    pair and their strength does not step by :data:`BASE_STEP_CLAD`); and
    whether at least a tube's width of profiles lies past it, most of them
    showing the tube's edge pair (:data:`BASE_STEP_VALID`): a step at the
    search's far end rests on a profile or two of chance pairs, and one before
    a stretch of scattered pairs on a width that is not the tube's."""
    offsets = np.arange(-np.ceil(2 * hw), np.ceil(2 * hw) + 1, 0.5)
    prof = sample_lines(image, starts, 1j * np.exp(1j * phi), offsets)
    edges = edge_pairs(prof, 0.5, hw, polarity=look.polarity, window=0.3 * hw,
                       smooth_px=look.smooth_px,
                       width_tol=0.15, min_strength=0.25 * look.strength)
    # each profile's evidence of the tube: its edge step where an edge pair of the
    # tube's width is found, else 0. Behind the base, noise or the pipette's wall
    # now and then forms a pair of about that width too, but a weak one: a
    # yes/no validity would put the base at such a chance pair.
    score = np.where(edges.valid, edges.strength, 0.0)
    if edges.valid.sum() < 4:
        return None, False
    # best step from "not the tube" to "the tube": two-level least-squares fit
    n = score.size
    sse, mean_before, mean_after = two_level_fit(score)
    sse = np.where(mean_after > mean_before, sse, np.inf)
    if not np.isfinite(sse).any():
        return None, False
    best = int(np.argmin(sse)) + 1  # (split k puts score[:k] before: sse[k - 1])
    if edges.valid.all() and mean_before[best - 1] > BASE_STEP_CLAD * mean_after[best - 1]:
        # the tube is seen behind as well, as strongly: nothing steps there
        return None, False
    return best, bool((n - best) * step >= 2.0 * hw
                      and edges.valid[best:].mean() >= BASE_STEP_VALID)


def locate_base(image: np.ndarray, curve: Curve, look: TubeLook, *, origin=(0.0, 0.0),
                reach: float | None = None) -> Curve:
    """Move the base along the base axis to where the tube's full width begins.

    The pipette that holds the tube is narrower (or wider) than the tube, or
    absent beyond the image border; along the base axis, profiles behind the base
    therefore find no edge pair of the tube's width and profiles after it do
    (or, through a clear pipette, find the tube's pair behind the base too,
    but fainter). The base is put at the change, to half a profile step, and
    the length adjusted so that the tip stays where it is. Behind the base the
    profiles lie along the base axis, past it along the curve; a base found
    ahead of the curve's start cuts the curve there (a jointed curve is only
    shifted).
    """
    reach = 4.0 * float(look.half_width[0]) if reach is None else reach
    shift = _crop_shift(origin)
    axis = np.exp(1j * curve.base_angle)
    step = 0.5
    s = np.arange(-reach, min(reach, 0.5 * curve.length), step)
    # behind the base along the base axis (the pipette's), past it along the
    # curve: a long search (a pipette the first fit ran along) would otherwise
    # leave the tube wherever the curve turns off that axis
    basis = basis_of(curve)
    smp = evaluate(curve, basis)
    grid = basis.u * curve.length
    ahead = np.clip(s, 0.0, None)
    phi = np.where(s > 0, np.interp(ahead, grid, smp.phi), curve.base_angle)
    starts = np.where(s > 0, np.interp(ahead, grid, smp.z.real)
                      + 1j * np.interp(ahead, grid, smp.z.imag), curve.base + s * axis) - shift
    # the tube's width as learnt just past the search, not at the curve's start:
    # where the curve ran on into a faint pipette whose edges passed for the
    # tube's, the width learnt there is partly the pipette's (a low-contrast
    # 320×240 scene: base 19 px into the pipette, length +12 %). Where that
    # finds no step with a tube's width of profiles past it, the width learnt
    # along the whole tube (the median): on a thin, noisy tube with an
    # off-centre lumen, the width learnt at one place may be the lumen's edge
    # pair's, which few profiles near the base match (a fluorescent tube 7.7 px
    # wide: the step put at the search's far end, the base 20 px into the tube,
    # the length 12 % short)
    local = float(look.half_width_at(min(reach, 0.5 * curve.length) / curve.length))
    found, credible = _base_step(image, starts, phi, local, look, step)
    median = float(np.median(look.half_width))
    if not credible and median != local:
        # (the median's step only if it stands: else the first width's, as before)
        again, credible = _base_step(image, starts, phi, median, look, step)
        found = again if credible else found
    if found is None:
        return curve
    s_base = s[found] - 0.5 * step
    if s_base <= -step:
        # behind: the curve carried back along the base axis, the rest of it
        # kept where it is (shifting it all would take a curled tube's tip off
        # the tube by as much)
        _, z = resample(curve, 0.5)
        back = curve.base + np.arange(s_base, -0.5 * step, step) * axis
        joints = tuple((j * curve.length - s_base) / (curve.length - s_base)
                       for j in curve.joints)
        return fit_to_polyline(np.concatenate([back, z]), curve.base_angle,
                               n_coef=curve.coef.size, joints=joints)
    if s_base <= 0 or curve.joints:
        return replace(curve, base=curve.base + s_base * axis,
                       length=max(curve.length - s_base, 2.0))
    # forward: the curve from there on, its tangent there the base direction
    arc, z = resample(curve, 0.5)
    keep = arc >= s_base
    return fit_to_polyline(z[keep], float(np.interp(s_base, grid, smp.phi)),
                           n_coef=curve.coef.size)
