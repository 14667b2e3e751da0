"""Track a tube that is wide in pixels on frames binned down to a usual width.

The tracker's edge search is built for tubes a few to a few tens of pixels
wide: its profiles' smoothing, the tip's search window, the run-on and width
checks are set in pixels or against the noise of a few pixels. A tube filmed at
high magnification or on a large sensor (a 0.4 mm tube at 6 µm/px is 65 px
wide) shows the camera's noise, and the noise a rescaling leaves correlated,
as structures of the tube's scale; the tip then ran on into the background
(a 480x360 scene scaled up 3x: 5 of 6 frames lost). Binning such frames by an
integer factor (the mean of each d x d block) brings the tube back to a width
the search is built for, averages the noise down, and cuts the work by d².
The curves found are then scaled back to the frame's own pixels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import cv2
import numpy as np

#: Tubes whose half-width the first frame's detection puts above this (px) are
#: tracked on binned frames, binned by the smallest integer factor that brings
#: it to at most this. Measured: 15 rendered scenes with tubes 48-70 px wide met
#: every target unbinned, and binned 2x2 their angle medians rose on 9 (0.19 ->
#: 0.42 deg at most); rendered scenes scaled up 3x (cubic), tubes 80-124 px
#: wide: 3 of 7 met every target unbinned (one lost 11 of 12 frames), 5 of 7
#: binned. (Binned above 24 px: 155 -> 156 of 182 scenes, but those 9 medians
#: rose.)
MAX_HALF_WIDTH_PX = 36.0


@dataclass(frozen=True)
class Binning:
    """Integer binning of frames, and the way back to the frames' own pixels.

    Attributes
    ----------
    factor : int
        Each binned pixel is the mean of a ``factor`` x ``factor`` block.
    """

    factor: int = 1

    def __bool__(self) -> bool:
        return self.factor > 1

    @classmethod
    def for_half_width(cls, half_width: float) -> Binning:
        """The binning a tube of ``half_width`` px needs (none up to
        :data:`MAX_HALF_WIDTH_PX`)."""
        if not np.isfinite(half_width) or half_width <= MAX_HALF_WIDTH_PX:
            return cls(1)
        return cls(int(math.ceil(half_width / MAX_HALF_WIDTH_PX)))

    def frame(self, image: np.ndarray) -> np.ndarray:
        """``image`` binned (rows and columns past the last whole block left out)."""
        d = self.factor
        if d == 1:
            return image
        rows, cols = image.shape[:2]
        whole = image[: rows - rows % d, : cols - cols % d]
        # INTER_AREA at an integer factor is the block mean
        return cv2.resize(whole, (cols // d, rows // d), interpolation=cv2.INTER_AREA)

    def to_binned(self, col: float, row: float) -> tuple[float, float]:
        """A point in the frame's pixels (col, row) in the binned frame's."""
        d = self.factor
        return (col - 0.5 * (d - 1)) / d, (row - 0.5 * (d - 1)) / d

    def curve_back(self, curve):
        """A curve (px, y up) of the binned frame in the frame's own pixels: the
        binned pixel (c, r) is the block whose centre is d·(c, r) + (d − 1)/2."""
        if curve is None or self.factor == 1:
            return curve
        d = self.factor
        corner = 0.5 * (d - 1) * (1 - 1j)
        return replace(curve, base=d * curve.base + corner, length=d * curve.length)

    def track_back(self, track):
        """A :class:`pipeline.track.FrameTrack` of the binned frames in the frame's
        own pixels: its curves, its residuals and its half-width (the edge profiles' smoothing,
        a setting of the search, stays in the binned frames' pixels)."""
        if self.factor == 1:
            return track
        d = self.factor
        return replace(track, curve=self.curve_back(track.curve),
                       fit=self.curve_back(track.fit), residual_px=d * track.residual_px,
                       half_width_px=d * track.half_width_px,
                       end_offset=d * track.end_offset, told_offset=d * track.told_offset,
                       end_profile=(None if track.end_profile is None
                                    else track.end_profile * np.array([d, d, 1.0])),
                       end_steps=(None if track.end_steps is None
                                  else track.end_steps * np.array([d, 1.0, d])),
                       end_step=(None if track.end_step is None
                                 else (d * track.end_step[0], d * track.end_step[1])),
                       plug_px=None if track.plug_px is None else d * track.plug_px,
                       stage_shift=d * track.stage_shift)

    def describe(self, half_width: float) -> str:
        """A line for the run's notes; ``half_width`` is the tube's, px."""
        return (f"tracked on frames binned {self.factor}x{self.factor} (each pixel the mean "
                f"of a block): the tube is about {2 * half_width:.0f} px wide, over the "
                f"{2 * MAX_HALF_WIDTH_PX:g} px the edge search is built for; the curves are "
                "given in the frames' own pixels")

