"""Frames on which the tube runs out of the image (or out of a field stop's disc).

A tube curling near the edge of the field of view runs out of it: the
tracker then follows the part still in view, which ends at the image's
border, and that part's end tangent is not the tip's (a scene cut 45 px above
a tube whose tip passed 8 px outside: the bend came out 96-132 deg against
112-160 deg, with the length 6-8 % short). A tube whose outer wall is cut by
the border, its tip in view, loses the edges it is fitted to there (sample 1
curled into the top border: 4.3 % short, the bend 4.2 deg off). Such frames
are told by two things together, neither of which is enough alone: the tube
is shorter than on the frames that show it well inside the image, and the
border lies within that missing length of the fitted centreline (a tube with
a length ΔL missing can only reach the border within ΔL of the part seen).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .centreline import Curve, basis_of, evaluate
from .segment import base_at_edge
from .track import FrameTrack

#: A frame's tube counts as short where its length is this much under the
#: reference (the tracker's length errors are well under 1 %).
SHORT_FRACTION = 0.02
#: Frames whose tube (past :data:`FROM_U`) lies farther than this fraction of
#: its length from every border of the image give the reference length.
CLEAR_FRACTION = 0.1
#: The stretch looked at starts this far along the tube (a fraction of its
#: length): its base may sit at the border, the pipette coming from outside.
FROM_U = 0.2
#: Slack on the border's distance, px: a centreline fitted to a tube cut by
#: the border lies up to about a half-width inside it.
REACH_SLACK_PX = 2.0
#: A centreline this far past the frame's edge (px of the frames tracked)
#: ran out of view, however long it was measured.
OUTSIDE_PX = 1.0
#: The status of a frame whose tube runs out of the image.
OUT_OF_VIEW = "tube cut by the image's border (part of it out of view)"


def _to_border(curve: Curve, rows: int, cols: int, disc) -> float:
    """Least distance from the view's border to ``curve`` past :data:`FROM_U`, px."""
    basis = basis_of(curve)
    z = evaluate(curve, basis).z[basis.u >= FROM_U]
    col, row = z.real, -z.imag
    near = float(np.min([col, row, cols - 1 - col, rows - 1 - row]))
    if disc is not None:
        centre, radius = disc
        near = min(near, float(np.min(radius - np.abs(col + 1j * row - centre))))
    return near


def cut_by_border(results: list[FrameTrack], shape: tuple[int, int], disc=None
                  ) -> tuple[list[FrameTrack], str | None]:
    """Mark the frames whose tube runs out of the image as not measured.

    Parameters
    ----------
    results : list of FrameTrack
        The tracked frames, their curves in the pixels of the frames tracked.
    shape : (rows, cols)
        Size of the frames tracked, px.
    disc : (complex, float), optional
        A round field of view within the frames: its centre (col + 1j·row)
        and radius, px (see :mod:`pipeline.field`).

    Returns
    -------
    results : list of FrameTrack
        The same frames, those whose tube runs out of the image with status
        :data:`OUT_OF_VIEW` and no curve.
    note : str or None
        A line for the run's notes (None when every tube stayed well inside).

    Notes
    -----
    The reference length is the median over the frames whose tube is clear
    of the border: one of them measured short does not move it.
    """
    ok = [i for i, r in enumerate(results) if r.ok]
    if not ok:
        return results, None
    rows, cols = shape
    length = np.array([results[i].curve.length for i in ok])
    to_border = np.array([_to_border(results[i].curve, rows, cols, disc) for i in ok])
    clear = to_border > CLEAR_FRACTION * np.median(length)
    # beyond a field stop's lit disc the frame is filled from the disc's edge:
    # a tube followed out there follows that fill, not the tube
    out = to_border < 0 if disc is not None else np.zeros(len(ok), bool)
    # a centreline past the frame's edge (a fit at the tube's own length, its
    # tip out of view) is a tube the border cuts, however long it was measured
    out |= to_border < -OUTSIDE_PX
    note = None
    if not clear.any():
        note = ("the tube passes near the image's border on every frame: whether it runs "
                "out of view could not be checked (no frame shows it clear)")
    elif not clear.all():
        reference = float(np.median(length[clear]))
        missing = reference - length
        out |= (missing > SHORT_FRACTION * reference) & (to_border <= missing + REACH_SLACK_PX)
    if not out.any():
        return results, note
    marked = list(results)
    for i in np.flatnonzero(out):
        r = results[ok[i]]
        marked[ok[i]] = replace(r, status=OUT_OF_VIEW, curve=None, fit=None, last_section=None)
    border = "the image's border" + (" or the field stop's edge" if disc is not None else "")
    return marked, (f"tube cut by {border} on {int(out.sum())} of {len(results)} frames "
                    f"(shorter there, by over {100 * SHORT_FRACTION:g} %, than on the frames that "
                    "show it clear of the border, or its centreline run on past the frame's "
                    "edge or the field stop's lit disc): those frames are not measured")


def base_to_border(results: list[FrameTrack], shape: tuple[int, int], half_width: float
                   ) -> tuple[list[FrameTrack], float]:
    """Every frame's centreline carried straight back, along its base tangent,
    to the frame's edge, where the tube enters the image from it.

    The tracker starts the tube where a whole profile across it lies in the
    image: a tube entering at a slant reaches the edge a half-width's slant
    before that (an independent scene's tube entering at 20 deg: 3.8 px
    short, its length 1.0 % short). The edge is the image's own, half a pixel
    beyond the outer pixels' centres.

    Parameters
    ----------
    results : list of FrameTrack
        The tracked frames, their curves in the pixels of the frames tracked,
        the tube entering from the border (no holder in view).
    shape : (rows, cols)
        Size of the frames tracked, px.
    half_width : float
        The tube's, px: a base farther from the edge than
        :func:`pipeline.segment.base_at_edge` allows is left where it is.

    Returns
    -------
    results : list of FrameTrack
        The same frames, their curves (and fits) carried back to the edge.
    gap : float
        How far the first measured frame's base was carried, px (0: none).
    """
    from .centreline import cut_base

    rows, cols = shape
    out, gap = [], 0.0
    for r in results:
        d = None if not r.ok else base_at_edge(r.curve.base, r.curve.base_angle, half_width,
                                                 (rows, cols))
        if d is None:
            out.append(r)
            continue
        gap = gap or d
        out.append(replace(
            r, curve=cut_base(r.curve, -d, r.curve.base_angle),
            fit=None if r.fit is None else cut_base(r.fit, -d, r.fit.base_angle),
            last_section=None))
    return out, gap

