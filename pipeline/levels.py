"""Bring a video whose intensities use a small part of their type's range to the full range.

The tracker reads frames as float32 in [0, 1] (8-bit by 255, 16-bit by 65535)
and a few of its floors are set in that unit: the noise floor of half a grey
level of 8-bit video under which a frame's noise is taken as rendered or
denoised, a blank margin's least jump. A camera of 10 to 14 bits writes its
counts into 16-bit files, so a 10-bit video reaches 1023 of 65535: in [0, 1]
it spans 0.016, its noise lies under those floors, and its pipette's faint
edges were lost (a 640x480 scene written as 10-bit counts: the base put 44 px
into the pipette, the length 13 % long; as 12-bit counts it was tracked as the
8-bit original). Float frames may come in any unit (photon counts, 0-4095).

Such a video is brought, from its first frame, to the range of a full-scale
one: its darkest level taken off (a camera's black level, or a dim exposure
high in the range: 10-bit counts from 30000 up were lost the same way), the
rest divided by the full scale of the bits it spans (1023 for a span of up to
1023 counts) or, floats, by its span. Later frames that are brighter or darker
simply go past [0, 1] (nothing is clipped).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: A 16-bit or float video whose first frame's levels span at most this share
#: of the full range (1: 65535, or 1.0) is brought to it: under it the floors
#: set in 8-bit grey levels weigh 8x or more against the video's own levels.
LOW_RANGE = 1 / 8


@dataclass(frozen=True)
class Levels:
    """How a video's frames are brought to the full range: ``(frame − black) / full``.

    Attributes
    ----------
    black : float
        The first frame's darkest level, in the frames' own units.
    full : float
        The full scale of the first frame's span above it, in the frames' own
        units (a bit depth's 2^b − 1, or a float frame's span); 0 when nothing
        is done (a video that uses its range).
    dtype : str
        The frames' pixel type.
    """

    black: float = 0.0
    full: float = 0.0
    dtype: str = "uint8"

    def __bool__(self) -> bool:
        return self.full > 0.0

    def frame(self, frame: np.ndarray) -> np.ndarray:
        """``frame`` as float32 on the full range (unchanged if nothing is done)."""
        if not self:
            return frame
        out = np.asarray(frame).astype(np.float32)
        out -= np.float32(self.black)
        out *= np.float32(1.0 / self.full)
        return out

    def describe(self) -> str:
        """One line for the run's record."""
        if self.dtype == "uint16":
            bits = int(round(np.log2(self.full + 1)))
            return (f"intensities: the first frame's counts span {self.full:.0f} ({bits}-bit) "
                    f"from {self.black:.0f} up, of the 16-bit range: brought to the full range "
                    f"(x{65535 / self.full:.0f})")
        return (f"intensities: float frames spanning {self.full:.4g} from {self.black:.4g} up "
                "on the first frame: brought to [0, 1]")


def levels_of(first: np.ndarray) -> Levels:
    """The :class:`Levels` for a video whose first frame is ``first``.

    8-bit frames; 16-bit frames whose levels span more than :data:`LOW_RANGE`
    of the range; and float frames within [0, 1] that span more than
    :data:`LOW_RANGE` of it: left as they are.
    """
    first = np.asarray(first)
    if first.dtype == np.uint16:
        if first.size == 0:
            return Levels(dtype="uint16")
        black, top = int(first.min()), int(first.max())
        span = top - black
        if span == 0 or span > LOW_RANGE * 65535:
            return Levels(dtype="uint16")
        return Levels(float(black), float(2 ** int(np.ceil(np.log2(span + 1))) - 1), "uint16")
    if np.issubdtype(first.dtype, np.floating):
        values = first[np.isfinite(first)]
        if values.size == 0:
            return Levels(dtype=str(first.dtype))
        black, top = float(values.min()), float(values.max())
        span = top - black
        if span <= 0.0 or (span > LOW_RANGE and black >= 0.0 and top <= 1.0):
            return Levels(dtype=str(first.dtype))
        return Levels(black, span, str(first.dtype))
    return Levels(dtype=str(first.dtype))
