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

Such a video is scaled, from its first frame, to the range of a full-scale
one: integers by the full scale of the bits the first frame uses (1023 for
counts up to 1023), floats by the first frame's largest value. Later frames
that are brighter simply go above 1 (nothing is clipped).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: A 16-bit or float video whose first frame reaches at most this share of the
#: full range (1: 65535, or 1.0) is scaled up: under it the floors set in 8-bit
#: grey levels weigh 8x or more against the video's own levels.
LOW_RANGE = 1 / 8


@dataclass(frozen=True)
class Levels:
    """The factor a video's frames are multiplied by after :func:`pipeline.frames.to_float`.

    Attributes
    ----------
    gain : float
        1 for a video that uses its range (nothing done).
    full : float
        The first frame's full scale in its own units (a bit depth's
        2^b − 1, or a float frame's largest value); 0 when nothing is done.
    dtype : str
        The frames' pixel type.
    """

    gain: float = 1.0
    full: float = 0.0
    dtype: str = "uint8"

    def __bool__(self) -> bool:
        return self.gain != 1.0

    def frame(self, frame: np.ndarray) -> np.ndarray:
        """``frame`` as float32, scaled to the full range (unchanged if nothing is done)."""
        if not self:
            return frame
        from .frames import to_float

        return to_float(frame) * np.float32(self.gain)

    def describe(self) -> str:
        """One line for the run's record."""
        if self.dtype == "uint16":
            bits = int(round(np.log2(self.full + 1)))
            return (f"intensities: the first frame's counts reach at most {self.full:.0f} "
                    f"({bits}-bit) of the 16-bit range: scaled x{self.gain:.0f} to full range")
        return (f"intensities: float frames reaching {self.full:.4g} on the first frame: "
                f"scaled by {self.gain:.4g} to [0, 1]")


def levels_of(first: np.ndarray) -> Levels:
    """The :class:`Levels` for a video whose first frame is ``first``.

    8-bit frames, and 16-bit or float frames that reach more than
    :data:`LOW_RANGE` of their range (and, floats, at most 1), are left as
    they are.
    """
    first = np.asarray(first)
    if first.dtype == np.uint16:
        top = int(first.max()) if first.size else 0
        if top == 0 or top > LOW_RANGE * 65535:
            return Levels(dtype="uint16")
        full = float(2 ** int(np.ceil(np.log2(top + 1))) - 1)
        return Levels(65535.0 / full, full, "uint16")
    if np.issubdtype(first.dtype, np.floating):
        values = first[np.isfinite(first)]
        top = float(values.max()) if values.size else 0.0
        if top <= 0.0 or LOW_RANGE < top <= 1.0:
            return Levels(dtype=str(first.dtype))
        return Levels(1.0 / top, top, str(first.dtype))
    return Levels(dtype=str(first.dtype))
