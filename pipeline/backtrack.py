"""Frames the tracker lost before its last start, tracked again backwards.

A video that starts with the tube curled past a turn, its coils touching or
closer than the detector can part, gives the tracker nothing to start on: its
first frames are lost, or measured on whatever the detector made of the coil
(a stretch of it, the pipette with it), until a frame it can start on. From
that start on it follows the tube through every frame. Going the other way
from there, each frame's shape is predicted from the later frames', as a
curl is followed forwards as it tightens: the frames before the start are
tracked again backwards, the video read once more up to the start.
"""

from __future__ import annotations

from dataclasses import replace
from itertools import pairwise

import numpy as np

from .track import FrameTrack, TrackSettings, moved_base, track_frames

#: A frame measured before the last start whose length lies this far (share)
#: from the length the frames from the start on show was measured on
#: something else (an earlier start on part of a coil, or on the pipette with
#: the tube: 50 % off on an independent scene that starts curled to 620 deg).
#: A tube keeps its length (the tracker's own check allows 8 % a frame).
LENGTH_OFF = 0.05
#: The frames from the start on whose median length that is.
REFERENCE_FRAMES = 5
#: Frames held in memory for the backward pass at most, in bytes: a video's
#: frames cannot be read backwards, so those before the start are kept as
#: they are read again (1 GiB: some 1300 frames of 1024x768 8-bit, 340 of
#: them in float32; the frames farther back are left as they were, and said so).
MEMORY_BYTES = 1 << 30
#: The status of a frame measured on something else (:data:`LENGTH_OFF`)
#: that the backward pass did not find either.
OFF_THE_TUBE = ("lost: measured on something other than the tube the later frames show "
                "(its length off theirs), and not found tracking backwards")


def _starts(results: list[FrameTrack]) -> list[int]:
    """The indices of the frames that (re)started the tracker (they carry how
    their base was found), measured."""
    return [i for i, r in enumerate(results) if r.ok and r.base_source]


def _to_redo(results: list[FrameTrack], start: int, length: float) -> list[int]:
    """The frames before ``start`` to track again: those lost, and those
    measured more than ``LENGTH_OFF`` off ``length`` (px), not where the tube
    crossed itself, by an earlier start that measured fewer frames than the
    last one (frames measured before the first start were found backwards
    from it, and count as its own)."""
    starts = _starts(results) + [len(results)]
    # frames measured by each start up to the next
    runs = {s: sum(r.ok for r in results[s:e]) for s, e in pairwise(starts)}
    last_run = runs.get(start, 0)
    # (frames measured before the first start were found backwards from it)
    owner = starts[0]
    redo = []
    for i in range(start):
        owner = i if i in runs else owner
        r = results[i]
        if not r.ok:
            redo.append(i)
        elif (runs[owner] < last_run and not r.crossing
              and abs(r.curve.length / length - 1.0) > LENGTH_OFF):
            redo.append(i)
    return redo


def track_back(frames, results: list[FrameTrack], *, base_hint=None,
               settings: TrackSettings | None = None,
               joints: tuple[float, ...] | None = None
               ) -> tuple[list[FrameTrack], str | None]:
    """``results`` with the frames before the tracker's last start that it
    lost, or measured off the tube that start found, tracked again backwards
    from that start.

    Parameters
    ----------
    frames : iterable of (rows, cols) ndarray
        The frames ``results`` were tracked on, re-iterable (read again up
        to the start).
    results : list of FrameTrack
        The forward pass's, one per frame.
    base_hint : (col, row), optional
        ``--base`` as given to the forward pass, px; else the base found on
        the start's frame is held for the backward pass.
    settings, joints
        As given to the forward pass (:func:`pipeline.track.track_frames`).

    Returns
    -------
    results : list of FrameTrack
        The frames found backwards replace the forward pass's (stage
        "backward"); those measured off the tube and not found stay
        unmeasured (:data:`OFF_THE_TUBE`).
    note : str or None
        What was done, for the run's notes; None where nothing needed it.
    """
    starts = _starts(results)
    if not starts or starts[-1] == 0:
        return results, None
    start = starts[-1]
    # (the start's first frames, next to those to redo: a holder taken in at
    # the start may be left behind later, the tube then measured shorter)
    lengths = [r.curve.length for r in results[start:] if r.ok and not r.crossing]
    if not lengths:
        return results, None
    length = float(np.median(lengths[:REFERENCE_FRAMES]))
    redo = _to_redo(results, start, length)
    if not redo:
        return results, None
    first = redo[0]
    kept: list[np.ndarray] = []
    for i, frame in enumerate(frames):
        if i >= first:
            if not kept:
                # the frames farthest back are left out, past the memory allowed
                first = max(first, start + 1 - max(2, MEMORY_BYTES // max(frame.nbytes, 1)))
            if i >= first:
                # (a reader may hand out one buffer for every frame)
                kept.append(np.array(frame, copy=True))
        if i >= start:
            break
    if len(kept) != start - first + 1:
        return results, None  # (the frames read again ended early)
    held_back = redo[0] < first
    redo = [i for i in redo if i >= first]
    if not redo:
        return results, (f"frames before the tracker's start on frame {start} were lost or "
                         "measured off the tube it found there, but lie farther back than "
                         f"the {len(kept)} frames held in memory for a backward pass: left "
                         "as they were")
    anchor = results[start]
    # (the base where it stood on the start's frame: the forward pass carried
    # a given one with the stage's drift)
    shift = anchor.stage_shift
    hint = ((base_hint[0] + shift.real, base_hint[1] - shift.imag) if base_hint is not None
            else (anchor.curve.base.real, -anchor.curve.base.imag))
    back = list(track_frames(reversed(kept), base_hint=hint, settings=settings,
                             joints=joints))
    out = list(results)
    found = off = 0
    for i in redo:
        b = back[start - i]
        if b.ok:
            # the base where the start has it (where the stage stood on this
            # frame): the backward pass, given it, may settle it elsewhere
            # along the holder's axis (a base given inside a pipette taken
            # for the tube: slid to the frame's border), and a holder is
            # told by stretches that stand still on every frame
            at = anchor.curve.base + b.stage_shift
            b = replace(b, curve=moved_base(b.curve, at),
                        fit=None if b.fit is None else moved_base(b.fit, at))
        if b.ok and abs(b.curve.length / length - 1.0) <= LENGTH_OFF:
            out[i] = replace(b, frame=i, stage="backward", base_source="",
                             stage_shift=anchor.stage_shift + b.stage_shift)
            found += 1
        elif out[i].ok:
            # (nothing of what that start learnt stays: its half-width, look)
            out[i] = FrameTrack(i, OFF_THE_TUBE, None, "", stage_shift=out[i].stage_shift)
            off += 1
    note = (f"{len(redo)} frames before the tracker's start on frame {start} were lost or "
            f"measured off the tube it found there: tracked again backwards from it, "
            f"{found} found")
    if off:
        note += f", {off} measured on something else and not found (now unmeasured)"
    if held_back:
        note += (f"; frames before {first} left as they were (only {len(kept)} frames are "
                 "held in memory for the backward pass)")
    return out, note
