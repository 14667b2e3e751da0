"""Which of a colour video's channels the tube is tracked in.

A colour camera's luminance is the grey the tracker works on by default: it
averages the channels' noise down, and a tube seen in white light shows in all
of them. A dyed tube (a yellow dye takes the blue out of the light it passes,
and little else) or a fluorescent one on a colour camera shows in one channel
only, and the luminance then mixes that channel's contrast with the others'
noise: an independent renderer's yellow tube kept 12 % of its contrast there.

On the first frame, with the tube found in its luminance (or, where it is not,
in a channel), the tracker's start (:func:`pipeline.track.initialise`) is run
in the luminance and in each channel alone, and the scatter of the edge pairs'
midpoints from one profile to the next (:attr:`pipeline.refine.Refined.noise_px`:
how precisely the centreline is measured there) compared. A channel is taken
alone where its scatter is at most 1/:data:`CHANNEL_GAIN` of the luminance's;
otherwise the luminance is kept. (On eight colour scenes of three independent
renderers, the luminance's scatter was the lowest or within 1.4x of the best
channel's on all but the yellow tube, 1.8x its blue channel's; an RMS contrast
to noise of the tube's pixels told that tube only 1.15x clearer in blue, its
refraction rims showing in every channel: what the look mixes, the edges tell.)
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from .frames import CHANNELS, to_float
from .segment import detect
from .track import initialise

#: A channel alone is taken where the edge midpoints scatter by at most
#: 1/CHANNEL_GAIN of the luminance's.
CHANNEL_GAIN = 1.5


@dataclass(frozen=True)
class ChannelChoice:
    """The grey a colour source is tracked in.

    Attributes
    ----------
    channel : str or None
        The channel taken alone (a name of :data:`pipeline.frames.CHANNELS`);
        None: the luminance.
    scatter : dict of str to float
        The edge midpoints' scatter in each grey looked at, px, by name
        (``"luminance"`` and the channels'; inf where the tube was not found
        there); empty where no tube was found to compare them on.
    lost : bool
        A channel was chosen, but the tracker's start found no tube in it
        over the whole first frame (where the luminance's did): the
        luminance is kept.
    """

    channel: str | None
    scatter: dict
    lost: bool = False

    def describe(self) -> str:
        """One line for the run's record of what was done and why."""
        if not self.scatter:
            return ("colour frames: tracked on their luminance (no tube found to compare the "
                    "channels on)")
        each = ", ".join(f"{k} {v:.3f}" for k, v in self.scatter.items())
        if self.lost:
            return (f"colour frames: tracked on their luminance (the channel whose edges were "
                    f"measured most precisely showed no tube over the whole first frame; the "
                    f"edge midpoints' scatter on it, px: {each})")
        if not np.isfinite(self.scatter["luminance"]):
            return (f"colour frames: tracked on the {self.channel} channel alone: no tube was "
                    f"found in their luminance (the edge midpoints' scatter on the first frame, "
                    f"px: {each})")
        if self.channel is None:
            return (f"colour frames: tracked on their luminance (in no channel alone are the "
                    f"tube's edges measured {CHANNEL_GAIN:g}x as precisely; the edge midpoints' "
                    f"scatter on the first frame, px: {each})")
        gain = self.scatter["luminance"] / max(self.scatter[self.channel], 1e-12)
        return (f"colour frames: tracked on the {self.channel} channel alone, where the "
                f"tube's edges are measured {gain:.1f}x as precisely as in the luminance (the "
                f"edge midpoints' scatter on the first frame, px: {each})")


def choose_channel(rgb: np.ndarray, detection=None, *, base_hint=None,
                   settings=None) -> ChannelChoice:
    """The grey to track a colour source in (see the module's notes).

    Parameters
    ----------
    rgb : (rows, cols, 3) ndarray
        The first frame in colour, RGB, any dtype :func:`pipeline.frames.to_float` takes.
    detection : pipeline.segment.Detection, optional
        The tube found in its luminance; None: looked for in each grey.
    base_hint : (col, row), optional
        Where the base is, px (``--base``), for finding the tube.
    settings : pipeline.track.TrackSettings, optional
        The tracker's settings, for its start (default: its defaults).

    Returns
    -------
    ChannelChoice
    """
    rgb = to_float(rgb)
    # (a camera's 10-14 bits in 16-bit files, float frames in any unit: brought
    # to about the range the tracker sees its grey frames in, pipeline.levels)
    top = float(rgb.max())
    rgb = rgb / top if top > 0 and not 0.5 <= top <= 1.0 else rgb
    greys = {"luminance": cv2.cvtColor(np.ascontiguousarray(rgb), cv2.COLOR_RGB2GRAY)}
    greys.update({name: np.ascontiguousarray(rgb[:, :, k]) for name, k in CHANNELS.items()})
    scatter = {}
    for name, grey in greys.items():
        det = detection or detect(grey, base_hint=base_hint)
        got = None if det is None else initialise(grey, base_hint=base_hint, detection=det,
                                                   settings=settings)
        scatter[name] = (float(got[0].noise_px) if got is not None
                         and np.isfinite(got[0].noise_px) else np.inf)
    if not np.isfinite(min(scatter.values())):
        return ChannelChoice(None, {})
    best = min(CHANNELS, key=lambda name: scatter[name])
    take = CHANNEL_GAIN * scatter[best] <= scatter["luminance"]
    return ChannelChoice(best if take else None, scatter)
