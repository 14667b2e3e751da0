"""A sealed tube's straight end plug, told over the video.

The tube's end is sealed with a plug of solid PDMS: no lumen, so no pressure
inside it to bend it (the wall eccentricity that bends the tube has nothing to
act on), and it stays straight while the rest curls. The tip's direction is
then the plug's, which is the tube's where the plug begins, not the arc's
carried on to the end.

A tube's last stretch whose edge midpoints sit off the line the rest of
the tube's give is found frame by frame (:class:`pipeline.track._EndStepVotes`,
:attr:`pipeline.refine.Refined.end_steps`), and its side edges are left out of
the fits. That offset may be the lumen's (an off-centre bore ending before the
tip: the same offset at every bend), or a straight plug's: the plug leaves the
arc on its outer side by ``κ·(p − d)²/2`` at ``d`` from the tip, in proportion
to the bend. The frames tell which: where the offsets grow in proportion to
the bend (opposite its sense) far better than they stay steady, the stretch
is a plug, and every frame's centreline is made straight over it.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from .centreline import Curve, basis_of, evaluate, make_basis
from .refine import END_PROFILE_HW, END_STEP_ZONES_HW

if TYPE_CHECKING:
    from .track import FrameTrack

#: Frames with the end's offset measured needed to tell a plug, at least ...
MIN_FRAMES = 6
#: ... over a range of bends of at least this, deg.
MIN_BEND_RANGE_DEG = 60.0
#: The offsets in proportion to the bend must leave at most this share of the
#: sum of absolute deviations a steady offset leaves (plugs on an independent
#: renderer's scenes: 0.27-0.53).
PROPORTION_SAD = 0.6
#: The plug's length over the stretch told, where :func:`fitted_length` fixes
#: none: the stretch is the one whose offset, times its weight, is largest,
#: and a plug's offset grows towards the tip, so it is told short (of plugs
#: 17-24 px long, drawn by this package's tests and an independent renderer:
#: 0.80-0.87 of them, a quarter half-width apart; of longer ones, less: the
#: stretches tried end at 3 half-widths).
PLUG_PER_STRETCH = 1.2


def plug_length(results: list[FrameTrack], half_width: float) -> float | None:
    """The length of a straight plug at the tube's end, px, where the frames
    tell one (see the module's notes); else None. (:func:`told_plug` also
    says how the length was found.)

    Parameters
    ----------
    results : list of FrameTrack
        The tracked frames: the stretch told (:attr:`FrameTrack.end_step`),
        and its offsets measured until then (:attr:`FrameTrack.end_steps`)
        and after (:attr:`FrameTrack.told_offset`).
    half_width : float
        The tube's half-width the end's stretches were measured in, px.
    """
    found = told_plug(results, half_width)
    return None if found is None else found[0]


def told_plug(results: list[FrameTrack], half_width: float) -> tuple[float, bool] | None:
    """:func:`plug_length`'s length, and whether it was fitted to the edge
    midpoints near the end (:func:`fitted_length`) rather than carried on
    from the stretch told (:data:`PLUG_PER_STRETCH`); None where no plug is
    told."""
    told = [r.end_step for r in results if r.ok and r.end_step is not None]
    # (not where the tube crossed itself, as the votes did not)
    seen = [r for r in results if r.ok and not r.crossing]
    if not told or half_width <= 0:
        return None
    px = told[0][0]
    zone = int(np.argmin(np.abs(np.asarray(END_STEP_ZONES_HW) * half_width - px)))
    bend = np.array([r.bend_angle_rad for r in seen])
    # measured among the stretches until the stretch was told, and as itself
    # after: every frame bent further adds to what tells a plug from a lumen
    offset = np.array([r.end_steps[zone, 0] if r.end_steps is not None else r.told_offset
                       for r in seen])
    if not grows_with_bend(bend, offset):
        return None
    # (the stretch told, carried on by PLUG_PER_STRETCH, where the profiles
    # near the end fix no length)
    fitted = fitted_length(seen, half_width, px)
    return (fitted, True) if fitted is not None else (float(PLUG_PER_STRETCH * px), False)


#: The plug lengths tried by :func:`fitted_length`, px apart ...
LENGTH_STEP_PX = 0.25
#: ... over the frames measured once the stretch was told, at least this many
#: (a score of profiles each; the plug is told already, by :func:`grows_with_bend`).
FIT_MIN_FRAMES = 3
#: ... fitted to the profiles farther than this many half-widths from the
#: tip: the end's face pulls the edges nearer it (plugs of 21.2 and 39.6 px
#: on an independent renderer's scenes came out at 19.9 and 36.1 px with
#: them, 21.6 and 37.6 without).
FACE_HW = 0.5


def fitted_length(results: list[FrameTrack], half_width: float, told_px: float
                  ) -> float | None:
    """A straight plug's length fitted to the edge midpoints near the end
    (:attr:`FrameTrack.end_profile`) over the frames, px; None where the
    frames do not fix one longer than the stretch told (``told_px``).

    Where the plug begins, at ``p`` from the tip, it leaves the arc: a
    profile ``d`` from the tip sits ``κ·(p − d)²/2`` outside it (``κ`` the
    curvature before the end), nothing further back. The arc is the curve
    the profiles beyond :data:`pipeline.refine.END_PROFILE_HW` half-widths
    alone fit, carried on at its curvature there: the tube's own curvature
    over that stretch may differ (a last section's), which adds
    ``Δκ·(reach − d)²/2``, ``Δκ`` fitted for each frame. ``p`` is the one
    that leaves the least squares over the frames. (The stretch told is the
    one whose mean offset weighs most, 0.6-0.87 of the plug; carried on by
    :data:`PLUG_PER_STRETCH`, a plug longer than the stretches tried, 52 px
    on an independent renderer's scene, came out at 36 px, 53.9 fitted.)

    Lengths from ``told_px`` to a half-width short of the profiles' reach are
    tried: a minimum at either end fixes none (a plug no longer than the
    stretch told, or longer than about 5 half-widths), and the caller falls
    back on :data:`PLUG_PER_STRETCH`. ``half_width`` is the tube's learnt
    one, which the fits' reach was set by (a restart may have learnt another).
    """
    reach = END_PROFILE_HW * half_width
    data = []
    for r in results:
        curve = r.fit if r.fit is not None else r.curve
        if r.end_profile is None or curve is None or curve.length <= reach + 2 * half_width:
            continue
        basis = basis_of(curve)
        s = basis.u * curve.length
        before = (s > curve.length - reach - 2 * half_width) & (s < curve.length - reach)
        if before.sum() < 2:
            continue
        kappa = np.polyfit(s[before], np.unwrap(evaluate(curve, basis).phi[before]), 1)[0]
        d, off, w = r.end_profile[r.end_profile[:, 0] >= FACE_HW * half_width].T
        data.append((kappa, d, off, w, (reach - d) ** 2 / 2))
    if len(data) < FIT_MIN_FRAMES:
        return None
    lengths = np.arange(told_px, reach - half_width, LENGTH_STEP_PX)
    if lengths.size < 3:
        return None
    sse = np.zeros(lengths.size)
    for kappa, d, off, w, g in data:
        # (the plug's share for every length at once; Δκ, a line through 0 in
        # g, eliminated frame by frame)
        rest = off[None, :] + kappa * np.clip(lengths[:, None] - d[None, :], 0, None) ** 2 / 2
        dk = (rest * (w * g)).sum(axis=1) / max(float(np.sum(w * g * g)), 1e-12)
        sse += ((rest - dk[:, None] * g[None, :]) ** 2 * w).sum(axis=1)
    best = int(np.argmin(sse))
    # (a minimum at either end of the lengths tried fixes none)
    return float(lengths[best]) if 0 < best < lengths.size - 1 else None


def grows_with_bend(bend: np.ndarray, offset: np.ndarray) -> bool:
    """Whether an end stretch's offsets (px, along the left normal) over the
    frames grow in proportion to their bends (rad), outwards, as a straight
    plug's do, far better than they stay steady, as a lumen's do (see the
    module's notes): over at least :data:`MIN_FRAMES` frames and
    :data:`MIN_BEND_RANGE_DEG` of bend."""
    bend, offset = np.asarray(bend, float), np.asarray(offset, float)
    keep = np.isfinite(offset) & np.isfinite(bend)
    bend, offset = bend[keep], offset[keep]
    if bend.size < MIN_FRAMES or np.ptp(bend) < np.radians(MIN_BEND_RANGE_DEG):
        return False
    # (absolute deviations, the proportion the median of the bent frames':
    # a frame whose end was misread, 0.66 px where its neighbours sat at
    # 0.05-0.2, sways neither)
    bent = np.abs(bend) >= np.radians(MIN_BEND_RANGE_DEG) / 4
    slope = float(np.median(offset[bent] / bend[bent]))
    steady = float(np.abs(offset - np.median(offset)).sum())
    proportional = float(np.abs(offset - slope * bend).sum())
    # (a plug lies on the outer side of the arc: its offset along the left
    # normal has the sign opposite to the bend's)
    return slope < 0.0 and proportional <= PROPORTION_SAD * steady


def straight_end(curve: Curve, length: float, arc_px: float = 0.0) -> Curve:
    """``curve`` with its last ``length`` px straight, along its direction
    where that stretch begins (a joint there: its curvature may step to 0).

    The shape before it, the base and the total length are kept; the tip's
    direction (``coef[-1]``) is the curve's at the stretch's start. With
    ``arc_px`` > 0, that direction is the arc's from ``arc_px`` to three
    times that before the start (not past the curve's last joint before
    that),
    carried on to it at its curvature, and the last ``arc_px`` before it
    follow that arc: a fit that kept the edges of the plug's first pixels
    (the stretch told short of it) bent less there.
    """
    if not 0.0 < length < curve.length:
        return curve
    u_plug = 1.0 - length / curve.length
    basis = basis_of(curve)
    phi = evaluate(curve, basis).phi - curve.base_angle
    if arc_px > 0.0:
        s, start = basis.u * curve.length, curve.length - length
        # (within the last section: its curvature is the one carried on; a
        # joint within arc_px of the start is the plug's own kink, found)
        since = max([j * curve.length for j in curve.joints
                     if j * curve.length < start - arc_px] + [0.0])
        arc = (s >= max(start - 3.0 * arc_px, since)) & (s <= start - arc_px)
        if arc.sum() >= 3:
            slope, at0 = np.polyfit(s[arc], phi[arc], 1)
            bridge = s > start - arc_px
            phi = np.where(bridge, slope * s + at0, phi)
    target = np.where(basis.u < u_plug, phi, np.interp(u_plug, basis.u, phi))
    joints = tuple(sorted({*(j for j in curve.joints if j < u_plug - 0.02), u_plug}))
    # (a joint costs two coefficients: the shape before it kept as it was)
    new = make_basis(max(curve.coef.size + 2, 3 + 3 * len(joints)), basis.n_grid, joints)
    coef, *_ = np.linalg.lstsq(new.values, target, rcond=None)
    coef[-1] = target[-1]
    return Curve(curve.base, curve.base_angle, curve.length, coef, joints)


def straighten_plugs(results: list[FrameTrack], half_width: float | None, px: float = 1.0
                     ) -> tuple[list[FrameTrack], str | None]:
    """Every ok frame's centreline made straight over the tube's end plug,
    where the frames tell one (:func:`plug_length`); and a line saying so
    (None where none was told). ``px``: full-frame pixels per pixel of the
    frames (binning), for the note."""
    if half_width is None:
        return results, None
    found = told_plug(results, half_width)
    if found is None:
        return results, None
    plug, fitted = found
    # (the last section's record describes the curve before, and goes)
    out = [replace(r, curve=straight_end(r.curve, plug, half_width), plug_px=plug,
                   last_section=None)
           if r.ok else r for r in results]
    how = ("fitted to the edges near the end over the frames" if fitted else
           f"{PLUG_PER_STRETCH:g}x the stretch told: the edges near the end fixed no length")
    return out, (f"the end's sideways offset grew with the bend, opposite its sense: a straight "
                 f"plug {plug * px:.1f} px long ({how}; a sealed end, which the pressure does "
                 "not bend); every frame's tip direction taken where it begins, from the arc "
                 "before it")
