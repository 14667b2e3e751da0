"""The stage's drift, read from the holder's image around the tube's base.

The tracker holds the base where the first frames show it: the pipette holds
the tube still. A stage (or a micromanipulator, or the tubing pulling on it)
that drifts carries the holder, and the base with it, a few px over a video.
A base held where it was then bends every frame's fit to reach the tube, and
a holder taken for the tube no longer keeps its shape from frame to frame,
so it is not told (an independent renderer's scenes drifting 4-5 px: bases
56-73 px inside the glass, centrelines 9-17 px RMS off).

The holder's stretch behind the base (a band along the base's line, from a
half-width past it back some twelve half-widths: a capillary's mouth, a tube's
end inside it; not the background, where a camera's dust and shading stay put
while the stage drifts), without the tube past its first widths (it bends; a
coil may pass over the holder), is registered against the first frame's (on
every other frame while the stage stands still, then on every one): a
translation, with a gain and an offset for the light's flicker, fitted by
Gauss-Newton on the smoothed images (Lucas-Kanade), residuals weighed down
past two robust SDs. A straight holder shows no shift along itself: a
direction measured no better than 0.05 px keeps its last shift, so a tube
entering from the border is not slid along it by noise. The tracker follows
the drift only once it has been measured half a pixel away on three frames in
a row: a still stage leaves the tracking as it was. Not looked for where no
holder shows (the region's detail all at the tube's own end), where the base
lies at the frame's border, nor on frames whose tube lies over the holder.

(scikit-image's ``phase_cross_correlation`` takes masks but then gives whole
pixels only; OpenCV's ``findTransformECC`` takes one mask and fails where a
direction is undetermined. The masked fit here is short and does both.)
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from .centreline import Curve, resample

#: The region looked at reaches this many of the tube's half-widths from the
#: base (and at least / at most these px): a holder's mouth and some of it,
#: where the base tracked lies inside the holder (a tube seen inside a glass
#: capillary, 6 widths in).
REGION_HW = 12.0
REGION_MIN_PX = 24
REGION_MAX_PX = 128
#: The holder is looked for this far from the base's line (the tube's
#: half-widths, and at least px): a glass capillary twice the tube's width
#: (the independent renderer's, 1.35-4 times its radius).
HOLDER_HW = 4.0
HOLDER_MIN_PX = 10.0
#: The holder must show: at least this share of the region's gradient energy
#: lies behind the base (past a half-width) or beside the tube (past
#: BESIDE_HW half-widths from its line). (Holders: pipettes, capillaries, a
#: clamp's edge, on two renderers: 0.21-0.91; a fluorescent tube whose pipette
#: does not show: 0.02, its glow registered as a creeping 0.6 px drift.)
HOLDER_SHARE = 0.1
BESIDE_HW = 1.5
#: A base within this many half-widths of the frame's border is where the tube
#: enters the view, not a holder's mouth: it is not followed.
BORDER_HW = 2.0
#: The tube is left out from this many half-widths past its base on (plus its
#: clearance, so that the holder's mouth stays in), to this far from its
#: centreline (half-widths, plus CLEAR_PX), on the first frame and where it is
#: predicted: it bends; a coil may pass over the holder.
TUBE_FROM_HW = 1.0
CLEAR_HW = 1.2
CLEAR_PX = 2.0
#: A frame whose predicted tube covers more than this share of the holder's
#: region is not measured: the tube curls over its holder, and what is left
#: tells too little (sample 3 curling to 440 deg over a stage drifting 4 px:
#: at 0.02 the frames from 280 deg on were not measured and the base ended
#: 6.8 px off, length 1.4 %; at 0.3, 4.1 px and 0.79 %; the still scene's
#: shift stayed within 0.25 px either way).
COVERED = 0.3
#: The pixels registered: those whose gradient is at least this quantile of
#: the region's (the flat background tells nothing) ...
GRADIENT_QUANTILE = 0.5
#: ... at most this many of them (every k-th beyond).
MAX_PIXELS = 1500
#: Residuals past this many robust SDs are weighed down (Huber): what moves
#: other than the stage (the tube where the prediction missed it, flicker of
#: dust).
HUBER_SD = 2.0
#: Smoothing of the images registered, px: coarse (reach: shifts of a few px
#: per frame) then fine (precision).
SCALES_PX = (2.5, 1.0)
ROUNDS = 8
#: The coarse scale is skipped where no frame due was missed since the last
#: measured and that one moved less than this (px): the fine one reaches that
#: far.
COARSE_STEP_PX = 0.5
#: Rounds stop once the shift changes by less than this, px.
TOL_PX = 0.02
#: A direction whose gradient energy is below this share of the region's
#: strongest is not fitted at all (numerically degenerate) ...
APERTURE = 1e-3
#: ... and one whose shift is measured no better than this (standard error,
#: px, as if the residuals were independent: an empirical bar, they are
#: smoothed) keeps its start (a straight holder along itself: 0.1-1; a
#: capillary's mouth, a tube's end inside it: 0.01-0.05). (Bilinear sampling
#: places to 1/32 px: the registration is good to a few hundredths.)
MAX_SE_PX = 0.05
#: The drift is followed once it has been measured at least this far (px)
#: from the start, on this many frames measured in a row: a stage that stands still
#: leaves the tracking as it was, whatever the registration's scatter (0.01-0.15
#: px on still scenes; up to 0.55 on single frames of a noisy fluorescent one,
#: no pipette in view). (The frames held back for the base's vote are then
#: moved where the stage had taken them.)
FOLLOW_MIN_PX = 0.5
FOLLOW_FRAMES = 3
#: While the drift is not followed, the region is registered on every this
#: many frames only (then on every one): a still stage needs little watching.
STILL_EVERY = 2
#: A frame whose shift lies farther than this (px per frame) from the last
#: one measured is not measured: a stage drifts, it does not jump.
MAX_STEP_PX = 3.0
#: ... a frame read again once the holder's mouth is known
#: (:func:`holder_path`) may lie this many of the tube's half-widths from the
#: last: a camera shakes.
SHAKE_STEP_HW = 1.0
#: The fit must explain at least this share of the region's variance (a region
#: hidden or changed, a frame of something else: not measured).
MIN_R2 = 0.5


@dataclass
class StageDrift:
    """The first frame's region around the base, and the shift measured since.

    Attributes
    ----------
    box : (r0, r1, c0, c1)
        The region, rows and columns of the frame.
    ref : dict
        The region's image at each smoothing of :data:`SCALES_PX`, float32.
    inside : (rows, cols) bool ndarray
        The region's pixels that tell a shift: along the base's line behind it,
        with a gradient, off the tube past its first widths.
    line : (N,) complex ndarray
        The first frame's centreline, 1 px apart, px (y up).
    half_width : float
        The tube's, px.
    shift : complex
        The stage's shift from the first frame, px (y up).
    step : complex
        The shift's change on the last frame measured, px.
    fresh : bool
        Whether the last frame looked at was measured.
    largest : float
        The largest shift measured so far, px.
    away : int
        Frames in a row, up to the last, measured at least
        :data:`FOLLOW_MIN_PX` from the start.
    following : bool
        Whether the drift is followed (see :attr:`followed`).
    measured, missed : int
        Frames looked at, and those not measured among them (the tube over
        the holder, the fit failed or jumped).
    since : int
        Frames since the last one measured.
    max_step_px : float
        A frame measured farther than this from the last one measured (px
        per frame since) is not taken (:data:`MAX_STEP_PX`).
    """

    box: tuple[int, int, int, int]
    ref: dict
    inside: np.ndarray
    line: np.ndarray
    half_width: float
    shift: complex = 0j
    largest: float = 0.0
    step: complex = 0j
    fresh: bool = False
    away: int = 0
    since: int = 0
    following: bool = False
    measured: int = 0
    missed: int = 0
    max_step_px: float = MAX_STEP_PX

    @classmethod
    def start(cls, image: np.ndarray, curve: Curve, half_width: float) -> StageDrift | None:
        """The holder's region behind ``curve``'s base on ``image``.

        Parameters
        ----------
        image : (rows, cols) ndarray
            The frame the tracker started on, any dtype (the gain is fitted).
        curve : Curve
            The tube found on it, px (y up).
        half_width : float
            The tube's half-width, px.

        Returns
        -------
        StageDrift or None
            None where the base lies at the frame's border (:data:`BORDER_HW`),
            no holder shows (:data:`HOLDER_SHARE`) or too little of the region
            tells a shift.
        """
        reach = float(np.clip(REGION_HW * half_width, REGION_MIN_PX, REGION_MAX_PX))
        col, row = curve.base.real, -curve.base.imag
        rows, cols = image.shape
        if min(col, row, cols - 1 - col, rows - 1 - row) < BORDER_HW * half_width:
            # the tube enters from the border: no holder in view to follow
            return None
        r0, r1 = max(int(row - reach), 0), min(int(row + reach) + 1, rows)
        c0, c1 = max(int(col - reach), 0), min(int(col + reach) + 1, cols)
        patch = image[r0:r1, c0:c1].astype(np.float32)
        ref = {s: cv2.GaussianBlur(patch, (0, 0), s) for s in SCALES_PX}
        yy, xx = np.mgrid[r0:r1, c0:c1]
        # the holder's stretch: within HOLDER_HW of the base's line behind it
        # (the background is left out: a camera's dust and shading stay put
        # while the stage drifts)
        along = (xx - col) * np.cos(curve.base_angle) - (yy - row) * np.sin(curve.base_angle)
        across = (xx - col) * np.sin(curve.base_angle) + (yy - row) * np.cos(curve.base_angle)
        inside = ((along >= -reach) & (along <= TUBE_FROM_HW * half_width)
                  & (np.abs(across) <= max(HOLDER_HW * half_width, HOLDER_MIN_PX)))
        fine = ref[min(SCALES_PX)]
        grad = np.hypot(cv2.Sobel(fine, cv2.CV_32F, 1, 0), cv2.Sobel(fine, cv2.CV_32F, 0, 1))
        inside &= grad >= np.quantile(grad[inside], GRADIENT_QUANTILE)
        inside &= grad > 0
        region = cls((r0, r1, c0, c1), ref, inside, resample(curve, 1.0)[1], half_width)
        # (the tube past its first widths left out: it bends)
        inside &= ~region._drawn([region.line[_tube_start(half_width):]])
        # a holder in view: the region's detail lies behind the base or beside
        # the tube (not only at the tube's own end: a fluorescent tube whose
        # pipette does not show, whose glow bends with it)
        holder = inside & ((along < -half_width) | (np.abs(across) > BESIDE_HW * half_width))
        if (inside.sum() < REGION_MIN_PX**2 // 4
                or np.sum(grad[holder] ** 2) < HOLDER_SHARE * np.sum(grad[inside] ** 2)):
            return None
        region.inside = inside
        return region

    @property
    def followed(self) -> complex:
        """The shift the tracker follows, px: :attr:`shift` once the drift has
        stayed :data:`FOLLOW_MIN_PX` away on :data:`FOLLOW_FRAMES` frames in a
        row, else 0."""
        return self.shift if self.following else 0j

    def due(self) -> bool:
        """Whether this frame is to be measured (:data:`STILL_EVERY`); if not,
        it is counted as passed (call :meth:`measure` or this once a frame)."""
        if self.following or self.since + 1 >= STILL_EVERY:
            return True
        self.since += 1
        self.fresh = False
        return False

    def measure(self, image: np.ndarray, predicted: Curve | None) -> complex:
        """The stage's shift on this frame from the first.

        Parameters
        ----------
        image : (rows, cols) ndarray
            The frame, any dtype (the gain is fitted).
        predicted : Curve or None
            Where the tube is expected on it, px (y up), if known from its
            motion: where it lies over the region it is left out, and where
            it covers more than :data:`COVERED` of it the frame is not
            measured. None: the whole tube past its first widths on the
            first frame is left out.

        Returns
        -------
        complex
            The shift, px (y up): the last one measured where this frame does
            not tell it (:attr:`fresh` says which).
        """
        r0, r1, c0, c1 = self.box
        # (not extrapolated: a direction the region does not tell stays put)
        guess = self.shift
        self.since += 1
        self.fresh = False
        keep = self.inside
        self.measured += 1
        if predicted is not None:
            # (the prediction lies where the stage was on the last frame)
            pz = resample(predicted, 1.0)[1] - self.shift
            over = keep & self._drawn([pz[_tube_start(self.half_width):]])
            if over.sum() > COVERED * keep.sum():
                # the tube curls over its holder: what the region shows moves
                # with the tube as much as with the stage
                self.missed += 1
                return self.shift
            # (not in place: the region stays the first frame's)
            keep = keep & ~over
        pad = int(np.ceil(abs(guess))) + 2 + int(3 * max(SCALES_PX))
        rows, cols = image.shape
        w0, w1 = max(r0 - pad, 0), min(r1 + pad, rows)
        v0, v1 = max(c0 - pad, 0), min(c1 + pad, cols)
        window = image[w0:w1, v0:v1].astype(np.float32)
        yy, xx = np.nonzero(keep)
        if yy.size > MAX_PIXELS:
            yy, xx = yy[::yy.size // MAX_PIXELS + 1], xx[::yy.size // MAX_PIXELS + 1]
        xs = (xx + c0 - v0).astype(np.float32)
        ys = (yy + r0 - w0).astype(np.float32)
        d = np.array([guess.real, -guess.imag])    # (cols, rows)
        fit = None
        # (the coarse scale only where the stage may have moved far since)
        scales = (SCALES_PX if self.since > STILL_EVERY or abs(self.step) > COARSE_STEP_PX
                  else SCALES_PX[1:])
        if yy.size >= REGION_MIN_PX**2 // 4:
            for s in scales:
                smooth = cv2.GaussianBlur(window, (0, 0), s)
                gx = cv2.Sobel(smooth, cv2.CV_32F, 1, 0, ksize=3, scale=1 / 8)
                gy = cv2.Sobel(smooth, cv2.CV_32F, 0, 1, ksize=3, scale=1 / 8)
                fit = _register(smooth, gx, gy, self.ref[s][yy, xx], xs, ys, d)
                if fit is None:
                    break
                d = fit[0]
        new = complex(d[0], -d[1])
        if (fit is None or not (fit[1] >= MIN_R2) or not np.isfinite(new)
                or abs(new - self.shift) > self.max_step_px * self.since):
            self.missed += 1
            return self.shift
        self.step, self.shift, self.since, self.fresh = new - self.shift, new, 0, True
        self.largest = max(self.largest, abs(new))
        self.away = self.away + 1 if abs(new) >= FOLLOW_MIN_PX else 0
        self.following = self.following or self.away >= FOLLOW_FRAMES
        return new

    def _drawn(self, runs: list[np.ndarray]) -> np.ndarray:
        """The region's pixels within the tube's clearance of the polylines
        ``runs`` (points, px)."""
        r0, r1, c0, c1 = self.box
        mask = np.zeros((r1 - r0, c1 - c0), np.uint8)
        thick = max(int(round(2 * (CLEAR_HW * self.half_width + CLEAR_PX))), 1)
        # (fixed point with 2 fractional bits: the line lies where the curve does)
        lines = [np.round(np.c_[z.real - c0, -z.imag - r0] * 4).astype(np.int32)
                 .reshape(-1, 1, 2) for z in runs if z.size]
        if lines:
            cv2.polylines(mask, lines, False, 1, thickness=thick, shift=2)
        return mask.astype(bool)


def holder_path(frames, base: Curve, curves: list[Curve | None], half_width: float
                ) -> list[complex | None] | None:
    """The holder's shift on every frame from the first, registered at a base
    found after the frames were tracked (a second read of them).

    Where the tracker took a holder for the tube, the region it watched lay at
    the tracked structure's start, not at the holder's mouth: along a
    straight holder it tells nothing, and a base held at the frame's border
    is not watched at all. Once the mouth is known (the holder cut off), its
    region is registered on every frame as :class:`StageDrift` does.

    Parameters
    ----------
    frames : iterable of (rows, cols) ndarray
        The frames, first to last, as tracked (any dtype).
    base : Curve
        The first frame's tube, its base at the holder's mouth and its base
        tangent the holder's axis, px (y up).
    curves : list of Curve or None
        Each frame's tracked centreline, px (y up): left out of the region
        where it lies over it (None: nothing left out).
    half_width : float
        The tube's, px.

    Returns
    -------
    list of complex or None, or None
        Per frame, the shift from the first frame, px (y up), None where the
        frame was not measured (:meth:`StageDrift.measure`); None where no
        holder shows at the mouth (:meth:`StageDrift.start`).
    """
    it = iter(frames)
    first = next(it, None)
    region = None if first is None else StageDrift.start(first, base, half_width)
    if region is None:
        return None
    # (a camera that shakes moves the holder by pixels between frames: 5.6 px
    # on an independent renderer's scene)
    region.max_step_px = SHAKE_STEP_HW * half_width
    path: list[complex | None] = [0j]
    for image, curve in zip(it, curves[1:], strict=False):
        shift = region.measure(image, curve)
        path.append(shift if region.fresh else None)
    return path


def _tube_start(half_width: float) -> int:
    """Arc length (px, whole) from which the tube is left out of the region:
    its clearance then keeps clear of the holder's mouth."""
    return int(np.ceil((TUBE_FROM_HW + CLEAR_HW) * half_width + CLEAR_PX))


def _register(image, gx, gy, ref, xs, ys, d0):
    """Gauss-Newton fit of ``image(x + d) ≈ g·ref + o``, residuals weighed by
    Huber's rule (:data:`HUBER_SD`).

    Parameters
    ----------
    image, gx, gy : (rows, cols) float32 ndarray
        The smoothed window of the frame and its gradients (per px).
    ref : (N,) ndarray
        The first frame's smoothed values at the points.
    xs, ys : (N,) float32 ndarray
        The points, the window's columns and rows.
    d0 : (2,) array
        The start, (columns, rows) px.

    Returns
    -------
    (d, r2) or None
        The shift (columns, rows) px, and the share of the points' variance
        the fit explains; None where no direction is measured. Directions
        below :data:`APERTURE` of the gradient energy, or measured no better
        than :data:`MAX_SE_PX`, keep ``d0``'s.
    """
    if not np.ptp(ref) > 0:
        return None
    try:
        return _registered(image, gx, gy, ref, xs, ys, np.asarray(d0, float))
    except np.linalg.LinAlgError:
        # (a region whose first-frame values do not tell the gain from the
        # offset, or a frame that does not tell a shift: a dim fluorescent
        # holder's glow in a 12-bit camera's few counts, all alike)
        return None


def _registered(image, gx, gy, ref, xs, ys, d0):
    """:func:`_register`'s fit; LinAlgError where its normal equations are
    singular."""
    d = d0.copy()
    ref = ref.astype(np.float32)
    one = np.ones_like(ref)
    w = one
    go = np.zeros(2)
    basis = None
    for k in range(ROUNDS):
        mx = (xs + np.float32(d[0])).reshape(-1, 1)
        my = (ys + np.float32(d[1])).reshape(-1, 1)
        val, ix, iy = (cv2.remap(m, mx, my, cv2.INTER_LINEAR,
                                 borderMode=cv2.BORDER_REPLICATE).ravel()
                       for m in (image, gx, gy))
        if k == 0:
            # (the gain and offset's start: the least-squares line of val on ref)
            go = np.polyfit(ref, val, 1)
        e = val - go[0] * ref - go[1]
        sd = 1.4826 * float(np.median(np.abs(e))) + 1e-12
        w = np.minimum(1.0, HUBER_SD * sd / np.maximum(np.abs(e), 1e-12))
        jac = np.stack([ix, iy, -ref, -one], axis=1).astype(np.float64)
        h = (jac * w[:, None]).T @ jac
        g = (jac * w[:, None]).T @ e
        if basis is None:
            # the shift's normal matrix with the gain and offset taken out
            schur = h[:2, :2] - h[:2, 2:] @ np.linalg.solve(h[2:, 2:], h[2:, :2])
            ev, vec = np.linalg.eigh(schur)
            if ev[-1] <= 0:
                return None
            basis = vec[:, ev >= APERTURE * ev[-1]]
        # (the shift within the basis, the gain and offset free)
        t = np.zeros((4, basis.shape[1] + 2))
        t[:2, :basis.shape[1]] = basis
        t[2:, basis.shape[1]:] = np.eye(2)
        step = t @ np.linalg.solve(t.T @ h @ t, -(t.T @ g))
        d, go = d + step[:2], go + step[2:]
        if np.hypot(*step[:2]) < TOL_PX:
            break
    # a direction measured no better than MAX_SE_PX (its standard error, from
    # the residuals' scatter) keeps its start: a tube's shoulders at a narrow
    # pipette's mouth mark a place along it only faintly
    schur = h[:2, :2] - h[:2, 2:] @ np.linalg.solve(h[2:, 2:], h[2:, :2])
    ev, vec = np.linalg.eigh(schur)
    told = vec[:, sd / np.sqrt(np.maximum(ev, 1e-300)) <= MAX_SE_PX]
    if told.shape[1] == 0:
        return None
    d = d0 + told @ (told.T @ (d - d0))
    # (r² of the last round's residuals, before its step: the fit's quality,
    # not its last hundredth of a pixel)
    mean = np.average(val, weights=w)
    total = float(np.sum(w * (val - mean) ** 2))
    r2 = 1.0 - float(np.sum(w * e**2)) / total if total > 0 else 0.0
    return d, r2
