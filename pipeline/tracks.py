"""From tracked curves to the tracker's tables, in micrometres.

``tracks.csv`` has one row per frame and ``centrelines.csv`` one row per
centreline point (long format, base → tip, ≤ 1 px apart); column names are
in :mod:`pipeline.schema`. Pixel (col, row) becomes ``x_um = col·scale``,
``y_um = −row·scale``: the tracker's curves are already in px with y up, so
only the scale is applied here.
"""

from __future__ import annotations

import time
from collections import Counter
from contextlib import ExitStack
from dataclasses import asdict, dataclass, replace
from functools import partial
from pathlib import Path

import cv2
import numpy as np
import pandas as pd

from . import schema as S
from .atomic import write_csv, write_json
from .backtrack import track_back
from .binning import Binning
from .centreline import Curve, fit_to_polyline, resample, tip_point
from .colour import ChannelChoice, choose_channel
from .drift import FOLLOW_MIN_PX
from .field import field_stop
from .frames import first_colour
from .levels import levels_of
from .margins import blank_margins
from .pipette import drop_holder
from .plug import straighten_plugs
from .refine import (
    END_CLEAR_HW,
    END_STEP_LEAVE_OUT,
    END_STEP_LEAVE_OUT_MAX_PX,
    STRIP_LINES,
    end_step_left_out,
    strip_half_px,
)
from .segment import AMBIGUOUS_BASE, BORDER_BASE, detect, held_between
from .static_mask import MARGIN_PX, static_mask
from .track import (
    EDGE_SCALES,
    JOINT_CHECK_DEG,
    SNR_TARGET,
    STRIP_SNR,
    FrameTrack,
    TrackSettings,
    as_float,
    hold_section_ratio,
    hold_tip_trend,
    spline_size,
    track_frames,
)
from .view import base_to_border, cut_by_border


def scale_from_length(results: list[FrameTrack], length_um: float) -> tuple[float, int]:
    """µm per px from a known free length, measured on the least-bent good frame.

    Returns
    -------
    scale : float
        µm per px.
    frame : int
        The frame it was measured on.

    Raises
    ------
    ValueError
        When no frame was measured.
    """
    good = [r for r in results if r.ok]
    if not good:
        raise ValueError("cannot set the scale from the sample's length: no frame was measured")
    least = min(good, key=lambda r: abs(r.bend_angle_rad))
    return float(length_um / least.curve.length), least.frame


def tracks_table(results: list[FrameTrack], scale: float, fps: float | None) -> pd.DataFrame:
    """One row per frame (``schema.TRACK_COLUMNS``); NaN measurements where not ok."""
    rows = []
    for r in results:
        row = {S.FRAME: r.frame,
               S.TIME: r.frame / fps if fps else np.nan,
               S.STATUS: r.status}
        if r.ok:
            c = r.curve
            tip = tip_point(c)
            row.update({S.BEND: np.degrees(r.bend_angle_rad),
                        S.TIP_X: tip.real * scale, S.TIP_Y: tip.imag * scale,
                        S.BASE_X: c.base.real * scale, S.BASE_Y: c.base.imag * scale,
                        S.LENGTH: c.length * scale,
                        S.BASE_ANGLE: np.degrees(c.base_angle)})
        else:
            row.update(dict.fromkeys((S.BEND, S.TIP_X, S.TIP_Y, S.BASE_X, S.BASE_Y, S.LENGTH,
                                      S.BASE_ANGLE), np.nan))
        rows.append(row)
    return pd.DataFrame(rows, columns=S.TRACK_COLUMNS)


def centrelines_table(results: list[FrameTrack], scale: float,
                      spacing_px: float = 1.0) -> pd.DataFrame:
    """Long-format centrelines of the measured frames, points ≤ ``spacing_px`` apart."""
    frames, arcs, points = [], [], []
    for r in results:
        if not r.ok:
            continue
        s, z = resample(r.curve, spacing_px)
        frames.append(np.full(s.size, r.frame))
        arcs.append(s)
        points.append(z)
    if not frames:
        return pd.DataFrame(columns=S.CENTRELINE_COLUMNS)
    # one table built at the end: a DataFrame per frame cost a third of the writing
    s, z = np.concatenate(arcs) * scale, np.concatenate(points) * scale
    # 0.1 nm is far below any image's resolution, and short numbers halve the
    # time spent writing the CSV (a fifth of a fast run otherwise)
    return pd.DataFrame({S.FRAME: np.concatenate(frames), S.S: np.round(s, 4),
                         S.X: np.round(z.real, 4), S.Y: np.round(z.imag, 4)},
                        columns=S.CENTRELINE_COLUMNS)


def curve_record(curve: Curve) -> dict:
    """A curve as plain JSON-able numbers (for run.json / re-use)."""
    return {"base_col": curve.base.real, "base_row": -curve.base.imag,
            "base_angle_deg": float(np.degrees(curve.base_angle)),
            "length_px": curve.length, "coef": [float(c) for c in curve.coef],
            "joints": [float(j) for j in curve.joints]}


# -- the whole job: frames in, files out ----------------------------------------------

@dataclass(frozen=True)
class TrackRun:
    """Summary of one ``track`` run (also written as ``run.json``)."""

    out_dir: Path
    n_frames: int
    n_ok: int
    um_per_px: float
    scale_source: str
    base_source: str
    stages: dict
    runtime_s: float
    notes: tuple[str, ...]

    @property
    def frames_per_s(self) -> float:
        return self.n_frames / self.runtime_s if self.runtime_s > 0 else float("nan")


def _parse_base(base):
    if base is None:
        return None
    if isinstance(base, str):
        parts = base.replace(" ", "").split(",")
        if len(parts) != 2:
            raise ValueError(f"--base must be X,Y in pixels, got {base!r}")
        try:
            base = (float(parts[0]), float(parts[1]))
        except ValueError:
            raise ValueError(f"--base must be X,Y in pixels, got {base!r}") from None
    col, row = (float(v) for v in base)
    if not (np.isfinite(col) and np.isfinite(row)):
        raise ValueError(f"--base must be finite, got {base!r}")
    return col, row


def track_video(source, out_dir, *, um_per_px: float | None = None, sample=None,
                base=None, fps: float | None = None, overlay: bool = False,
                progress=None, settings: TrackSettings | None = None) -> TrackRun:
    """Track every frame of ``source`` and write the tracker's files into ``out_dir``.

    Parameters
    ----------
    source : str or Path
        A video, a folder of images or a multi-page TIFF (see
        :func:`pipeline.frames.open_frames`).
    out_dir : str or Path
        Created if needed; ``tracks.csv``, ``centrelines.csv`` and ``run.json``
        are written atomically (and ``overlay.png`` if asked).
    um_per_px : float, optional
        Image scale, µm per px.
    sample : Sample or str, optional
        Instead of a scale: a sample whose free length L_tot sets the scale on
        the least-bent frame.
    base : (col, row) or "X,Y", optional
        Where the tube leaves the pipette, px; found automatically otherwise.
    fps : float, optional
        Frame rate for ``time_s`` when the file does not carry one.
    overlay : bool
        Also write ``overlay.png``: tracked centrelines on a few frames.
    progress : callable, optional
        ``progress(done, total)`` after every frame (total may be None).
    settings : TrackSettings, optional
        The tracker's knobs that trade accuracy for speed (default:
        ``TrackSettings()``); recorded in ``run.json``.

    Raises
    ------
    ValueError
        On conflicting or invalid options and unreadable input (one line).
    """
    from models import get_sample

    from .frames import open_frames, require_source

    require_source(source)  # (first: a mistyped path is what to fix before any option)
    if um_per_px is not None and sample is not None:
        raise ValueError("give either --um-per-px or --sample for the scale, not both")
    if um_per_px is None and sample is None:
        raise ValueError("the scale is unknown: give --um-per-px S, or --sample ID_OR_TOML "
                         "to take it from the sample's length")
    if um_per_px is not None:
        um_per_px = float(um_per_px)
        if not np.isfinite(um_per_px) or um_per_px <= 0:
            raise ValueError(f"--um-per-px must be a positive number, got {um_per_px!r}")
    if sample is not None:
        sample = get_sample(sample)
    if fps is not None and (not np.isfinite(fps) or fps <= 0):
        raise ValueError(f"--fps must be a positive number, got {fps!r}")
    base_hint = _parse_base(base)
    settings = settings or TrackSettings()
    # the sample's section joints, where the tube's curvature steps
    # (none for a single section; looked for in the frames when no sample is given)
    joints = (None if sample is None
              else tuple(float(f) for f in np.cumsum(sample.fractions)[:-1]))
    out_dir = Path(out_dir)
    start = time.perf_counter()
    with ExitStack() as opened:
        reader = opened.enter_context(open_frames(source))
        total = len(reader)
        rows, cols = reader.frame_shape
        if base_hint is not None and not (0 <= base_hint[0] < cols and 0 <= base_hint[1] < rows):
            raise ValueError(f"--base {base_hint} lies outside the {cols}x{rows} image")
        rate = fps or reader.fps
        given_base = base_hint
        levels, margins, stop, frames, base_hint, first_det = _prepared(reader, given_base)
        colour = _colour_choice(reader, margins, first_det, base_hint, settings)
        if colour is not None and colour.channel is not None:
            channel = opened.enter_context(open_frames(source, channel=colour.channel))
            prepared = _prepared(channel, given_base)
            if prepared[-1] is not None or first_det is None:
                reader = channel
                levels, margins, stop, frames, base_hint, first_det = prepared
            else:
                # (the channel's own start found no tube where the luminance's did)
                colour = replace(colour, channel=None, lost=True)
        kept = margins.crop(reader.first).shape[:2]

        def tick(i):
            if progress is not None:
                progress(i + 1, total)

        # a tube many pixels wide is tracked on binned frames (see pipeline.binning)
        binning = (Binning.for_half_width(first_det.half_width) if first_det is not None
                   else Binning())
        if binning:
            wide_hw = first_det.half_width
            frames = _Mapped(frames, binning.frame)
            if base_hint is not None:
                base_hint = binning.to_binned(*base_hint)
            first_det = _first_detection(frames, base_hint)
        base_end, motion_note = None, None
        if base_hint is None:
            base_end, motion_note, first_det = _static_end(frames, first_det)
        results = list(track_frames(iter(frames), base_hint=base_hint, base_end=base_end,
                                    first_detection=first_det, progress=tick,
                                    settings=settings, joints=joints))
        results, back_note = track_back(frames, results, base_hint=base_hint,
                                        settings=settings, joints=joints)
        unmeasured = not any(r.ok for r in results)
        results, still_note, still = _stood_still(frames, results, first_det)
        if still is not None:
            # the tube may be there all the same, fainter than what stood still
            # (also tracked on the frames as they are where nothing was measured
            # on it: a reticle's line, which the tube may cross)
            found = _past_still(frames, still, base_hint, settings, joints,
                                also_plain=unmeasured)
            if isinstance(found, str):
                still_note = f"{still_note}; {found}"
            else:
                # (tracked afresh past what stood still: the backward pass's
                # note was of the results set aside)
                frames, results, first_det, still_note = found
                back_note = None
        results, reheld = hold_tip_trend(frames, results, settings)
        results, holder_note = _without_holder(frames, results, first_det, base_hint,
                                               binning.factor)
        if holder_note and joints is not None:
            holder_note += (f"; sample {sample.name}'s section joints were placed on the length "
                            "with the holder: give --base X,Y where the tube leaves it to place "
                            "them on the tube")
    if not results:
        raise ValueError(f"{source}: no frames to track")
    rows, cols = kept
    disc = None
    if stop:
        col, row = binning.to_binned(stop.centre.real, stop.centre.imag)
        disc = (complex(col, row), stop.lit_radius / binning.factor)
    view = (rows // binning.factor, cols // binning.factor)
    results, view_note = cut_by_border(results, view, disc)
    border_note = None
    if (base_hint is None and holder_note is None and disc is None
            and _base_source(results).startswith(BORDER_BASE)):
        results, gap = base_to_border(results, view, _learnt_half_width(results) or 0.0)
        if gap:
            border_note = (f"the tube enters from the image's border: its centreline carried "
                           f"{gap * binning.factor:.1f} px back along its base tangent, from "
                           "the first whole profile across it to the border")
    results, ratio_note = hold_section_ratio(results)
    results, plug_note = straighten_plugs(results, _learnt_half_width(results),
                                          binning.factor)
    if binning:
        results = [binning.track_back(r) for r in results]
    if margins:
        results = [r.moved(margins.offset) for r in results]
    runtime = time.perf_counter() - start
    if um_per_px is not None:
        scale, scale_source = um_per_px, "given (--um-per-px)"
    else:
        scale, frame = scale_from_length(results, sample.length_um)
        scale_source = (f"sample {sample.name}: L_tot = {sample.length_um:g} um over the "
                        f"tracked length of frame {frame} (the least bent)")
    tracks = tracks_table(results, scale, rate)
    lines = centrelines_table(results, scale)
    stages = Counter(r.stage for r in results if r.stage)
    notes = _notes(results, stages, base_hint is not None, rate)
    notes.append(_joints_note(results, sample))
    notes.append(ratio_note)
    if plug_note:
        notes.append(plug_note)
    notes.append(_look_note(results))
    notes.append(_smoothing_note(results, binning))
    strips_note = _strips_note(results, binning)
    if strips_note:
        notes.append(strips_note)
    notes.append(_tip_hold_note(results))
    if reheld:
        notes.append(f"tip stretch held to its curvature's trend afterwards on {reheld} frames "
                     "measured before the frames told it (each fitted once more, the video "
                     "read again)")
    notes.append(_end_note(results))
    notes.append(_cap_note(results))
    notes.append(_drift_note(results, base_hint is not None))
    step_note = _end_step_note(results)
    if step_note:
        notes.append(step_note)
    if back_note:
        notes.append(back_note)
    if view_note:
        notes.append(view_note)
    if border_note:
        notes.append(border_note)
    if still_note:
        notes.append(still_note)
    if holder_note:
        notes.append(holder_note)
    if motion_note:
        notes.append(motion_note)
    if colour is not None:
        notes.append(colour.describe())
    if levels:
        notes.append(levels.describe())
    if margins:
        notes.append(margins.describe())
    if stop:
        notes.append(stop.describe((margins.left, margins.top)))
    if binning:
        notes.append(binning.describe(wide_hw))
    if total and len(results) < total:
        # a video's header count: a truncated file decodes fewer frames, silently
        notes.append(f"the video ended after {len(results)} of the {total} frames its header "
                     "announces (a truncated file, or a header that counts wrong)")
    base_source = _base_source(results) or ("given (--base)" if base_hint else "not found")
    if holder_note:
        base_source = ("where the tube leaves a holder that stood still while the tube bent "
                       f"(first found as: {base_source})")
    n_ok = int(sum(r.ok for r in results))
    run = TrackRun(out_dir, len(results), n_ok, scale, scale_source,
                   base_source, dict(stages), runtime,
                   tuple(notes))
    out_dir.mkdir(parents=True, exist_ok=True)
    write_csv(tracks, out_dir / S.TRACKS_FILE)
    write_csv(lines, out_dir / S.CENTRELINES_FILE)
    write_json(_run_record(run, source, rate, results, settings), out_dir / S.RUN_FILE)
    if overlay:
        from .overlay import write_overlay

        write_overlay(source, results, out_dir / "overlay.png")
    return run


class _Mapped:
    """A reader's frames, each passed through ``view`` (re-iterable, as the
    reader): brought to the full range, without their blank margins, binned."""

    def __init__(self, frames, view):
        self._frames, self._view = frames, view

    def __iter__(self):
        return map(self._view, self._frames)

    @property
    def first(self) -> np.ndarray:
        """The first frame, seen through ``view`` (the reader decodes it once)."""
        return self._view(self._frames.first)


def _prepared(reader, base_hint):
    """The reader's frames as the tracker sees them, and the tube found on the first.

    Parameters
    ----------
    reader : pipeline.frames.FrameReader
    base_hint : (col, row) or None
        Where the base is, px (``--base``), in the frame as stored.

    Returns
    -------
    tuple
        ``(levels, margins, stop, frames, base_hint, detection)``: the
        frames' levels, blank margins and field stop (each falsy where there
        is none), the frames with all three applied, ``base_hint`` on them
        (without the margins), and the tube found on the first (or None).
    """
    # (a 10-bit camera's counts in 16-bit files: scaled to the full range first)
    levels = levels_of(reader.first)
    source_frames = _Mapped(reader, levels.frame) if levels else reader
    margins = blank_margins(source_frames.first)
    frames = _Mapped(source_frames, margins.crop) if margins else source_frames
    kept = margins.crop(source_frames.first).shape[:2]
    # (on the frame without its margins: a letterboxed field stop)
    stop = field_stop(margins.crop(source_frames.first))
    if stop:
        frames = _Mapped(frames, stop.fill)
    if base_hint is not None and margins:
        base_hint = (base_hint[0] - margins.left, base_hint[1] - margins.top)
        if not (0 <= base_hint[0] < kept[1] and 0 <= base_hint[1] < kept[0]):
            raise ValueError(f"--base lies in the frame's blank margin ({margins.sides()})")
    return levels, margins, stop, frames, base_hint, _first_detection(frames, base_hint)


def _colour_choice(reader, margins, detection, base_hint, settings
                   ) -> ChannelChoice | None:
    """Which grey a colour source is tracked in (:mod:`pipeline.colour`).

    Parameters
    ----------
    reader : pipeline.frames.FrameReader
    margins : pipeline.margins.Margins
        The frames' blank margins, cut off the colour frame too.
    detection : pipeline.segment.Detection or None
        The tube found on the first frame's luminance.
    base_hint : (col, row) or None
        ``--base``, px, on the frames without their margins.
    settings : TrackSettings

    Returns
    -------
    ChannelChoice or None
        None for a grey source.
    """
    rgb = first_colour(reader)
    if rgb is None:
        return None
    rgb = np.dstack([margins.crop(rgb[:, :, k]) for k in range(3)])
    binning = (Binning.for_half_width(detection.half_width) if detection is not None
               else Binning())
    if binning:
        # compared where they would be tracked: a wide tube on binned frames
        # (four starts on a 2560x1920 frame's 149 px wide tube took 6.3 s)
        rgb = binning.frame(rgb)
        hint = None if base_hint is None else binning.to_binned(*base_hint)
        detection = detect(as_float(cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)), base_hint=hint)
        base_hint = hint
    return choose_channel(rgb, detection, base_hint=base_hint, settings=settings)


def _first_detection(frames, base_hint=None):
    """The tube found on the first of ``frames`` (None if none), its base at
    ``base_hint`` (col, row) if given."""
    return detect(as_float(frames.first), base_hint=base_hint)


#: A tracked tube whose tip stayed within this many half-widths (and 2 px) of
#: its first place, on every frame, stood still.
STILL_HALF_WIDTHS = 1.0
#: ... and the scene moved elsewhere, over this share of the tube's own area:
#: another structure bent (an inflated tube sweeps about its own area).
MOVED_ELSEWHERE = 0.5
#: The status of the frames of a tube that stood still while another moved.
NOT_THE_TUBE = ("the structure tracked stood still while another one moved (a fibre, a "
                "scratch or an edge taken for the tube?)")


def _stood_still(frames, results, det):
    """The frames, not measured if what was tracked stood still while the scene
    moved elsewhere; a note then (else None); and what stood still, as
    ``(curve, half_width)`` px (else None).

    A fibre, a scratch or a chamber's edge in the frame can be longer and
    stand out more than the tube, and be taken for it: its angle is then no
    bend of the tube. A tube being inflated bends; so the scene's change over
    the video (:func:`pipeline.motion.moved_elsewhere`) is looked at, once,
    only where the tracked tube's tip stayed put on every frame.
    """
    from .motion import moved_elsewhere

    ok = [r for r in results if r.ok]
    if det is None or len(results) < 3:
        return results, None, None
    if not ok:
        # nothing measured on what the first frame showed: a reticle's line or
        # a dish's wall, found for the tube, whose edges no tube's fit matched
        # on any frame; looked at as it was found
        if det.length < 2 * det.half_width:
            return results, None, None
        n_coef = spline_size(det.length, det.half_width, (), TrackSettings(), known=False)
        found = fit_to_polyline(det.path, det.base_angle, n_coef=max(n_coef, 4))
        _, z = resample(found)
        share = moved_elsewhere(iter(frames), np.c_[-z.imag, z.real], det.half_width)
        if share < MOVED_ELSEWHERE:
            return results, None, None
        return results, (f"what the first frame showed most (a structure {2 * det.half_width:.0f}"
                         f" px wide) could not be measured on any frame as a tube, while "
                         f"{share:.1f}x its area moved elsewhere"), (found, det.half_width)
    if len(ok) < 2:
        return results, None, None
    tips = np.array([tip_point(r.curve) for r in ok])
    if np.abs(tips - tips[0]).max() > max(2.0, STILL_HALF_WIDTHS * det.half_width):
        return results, None, None
    _, z = resample(ok[0].curve)
    share = moved_elsewhere(iter(frames), np.c_[-z.imag, z.real], det.half_width)
    if share < MOVED_ELSEWHERE:
        return results, None, None
    marked = [replace(r, status=NOT_THE_TUBE, curve=None, fit=None, last_section=None)
              if r.ok else r for r in results]
    # its width as the tracker learnt it where it started on it (the first
    # frame's detection may have been the tube itself)
    learnt = _learnt_half_width(results)
    half_width = learnt if learnt is not None else det.half_width
    return marked, (f"the structure tracked stood still over the video, while {share:.1f}x "
                    "its area moved elsewhere (another structure bent there: the tube?): "
                    "its frames are not measured"), (ok[0].tracked, half_width)


#: A tube found past a hidden structure whose end lies within this many of
#: the tube's half-widths of the structure's free end (beyond the mask's
#: margin) starts there: the structure holds it.
HELD_AT_END_HW = 3.0


def _past_still(frames, still, base_hint, settings, joints, also_plain=False):
    """The video tracked again with the structure that stood still hidden
    (:mod:`pipeline.static_mask`): a faint tube next to a holder, a fibre or a
    scratch that stands out more.

    ``still`` is ``(curve, half_width)`` from :func:`_stood_still`. What is
    found past it may stand still too (the rest of a fibre the first track
    followed only part of): it is hidden as well, up to :data:`HIDDEN_MAX`
    structures in all. The tube is found on the frames with them hidden, and
    tracked there too; with ``also_plain`` also on the frames as they are,
    and the track that measured more frames kept (a structure the tube
    crosses, hidden, hides the tube there; one the tube lies along may draw
    its fit, shown). Returns
    ``(frames, results, detection, note)``, the frames being those tracked;
    or, where no tube is found past them that can be measured, a line saying
    why.
    """
    view = frames.first
    hides = []
    while len(hides) < HIDDEN_MAX:
        hides.append(static_mask(*still, view.shape[:2]))
        hidden = _Mapped(frames, partial(_hidden, hides))
        image = as_float(_hidden(hides, view))
        det, base_end, held = _found_past(hidden, image, hides[0], base_hint)
        if det is None:
            return "with it hidden, no tube was found past it"
        results = list(track_frames(iter(hidden), base_hint=base_hint, base_end=base_end,
                                    first_detection=det, settings=settings, joints=joints))
        results, again, still = _stood_still(hidden, results, det)
        if again is None:
            break
    else:
        return f"with it hidden, what was found next stood still too ({HIDDEN_MAX} hidden)"
    tracked = hidden
    if also_plain and not all(r.ok for r in results):
        plain = list(track_frames(iter(frames), base_hint=base_hint, base_end=base_end,
                                  first_detection=det, settings=settings, joints=joints))
        if sum(r.ok for r in plain) > sum(r.ok for r in results):
            tracked, results = frames, plain
    lengths = np.array([r.curve.length for r in results if r.ok])
    if lengths.size == 0:
        return "with it hidden, the tube found past it could not be measured on any frame"
    if lengths.size < HIDDEN_MIN_SHARE * len(results):
        return (f"with it hidden, what was found past it was measured on only {lengths.size} "
                f"of {len(results)} frames (another still structure, only partly hidden?): "
                "not measured")
    if _jitter(lengths) > HIDDEN_LENGTH_JITTER:
        return (f"with it hidden, a tube was found past it, but its length jumped by "
                f"{_jitter(lengths):.1%} from frame to frame (its end not found): not measured")
    widths = ", ".join(f"{2 * h.half_width:.0f}" for h in hides)
    return tracked, results, det, (
        f"{len(hides)} structure(s) ({widths} px wide) stood still over the video where the "
        "tube was looked for, while the scene moved elsewhere: hidden (their pixels replaced "
        "by the background about them) and the tube "
        + ("tracked again past them" if tracked is hidden
           else "found past them, then tracked on the frames as they are")
        + ("; the tube starts at the first one's end (a holder)" if held else ""))


#: Structures that stood still hidden at most, before the tube is given up.
HIDDEN_MAX = 2
#: The tube tracked past hidden structures is kept only where it was measured
#: on at least this share of the frames: what was found past a reticle's
#: hidden arms was the rest of another arm, measured on 5 frames of 28, each
#: of them wrong.
HIDDEN_MIN_SHARE = 0.5
#: The tube tracked past hidden structures is kept only where its length
#: changes from one measured frame to the next by at most this share, in the
#: median. What stood out more than the tube leaves a faint tube, whose end a
#: fit may follow into the background: an independent-renderer scene (a holder
#: 93 px wide, a tube at 6 % contrast) came out with its length jumping by
#: 3.8 % per frame and every angle from its third frame on wrong, where a tube
#: tracked as it should keeps its length to 1 % overall (one that grows as it
#: is inflated changes it smoothly, by a fraction of that per frame).
HIDDEN_LENGTH_JITTER = 0.01


def _jitter(lengths: np.ndarray) -> float:
    """The median change of ``lengths`` from one to the next, over their median."""
    if lengths.size < 2:
        return 0.0
    return float(np.median(np.abs(np.diff(lengths))) / np.median(lengths))


def _hidden(hides, frame):
    """``frame`` with each of the ``hides`` (:class:`StaticMask`) filled in turn."""
    for hide in hides:
        frame = hide.fill(frame)
    return frame


def _found_past(hidden, image, hide, base_hint):
    """The tube found on ``image`` (the first frame with what stood still
    hidden): ``(detection, base_end, held)``, ``base_end`` (col, row) a point
    near its base end where the frames told it, ``held`` whether it starts
    at the end of ``hide`` (a holder); the detection None when no tube is
    found."""
    det = detect(image, base_hint=base_hint)
    if det is None or base_hint is not None:
        return det, None, False
    ends = det.path[[0, -1]]
    gaps = np.abs(ends - hide.end)
    if gaps.min() <= MARGIN_PX + HELD_AT_END_HW * det.half_width:
        end = ends[int(np.argmin(gaps))]
        base_end = (end.real, -end.imag)
        held = detect(image, base_end=base_end)
        if held is not None:
            return replace(held, base_source="where the tube leaves a still structure (a "
                           "holder) that was hidden"), base_end, True
    base_end, _, found = _static_end(hidden, det)
    return (found if found is not None else detect(image, base_end=base_end)), base_end, False


def _without_holder(frames, results, det, base_hint, px):
    """:func:`pipeline.pipette.drop_holder`, where the base is not given (a
    narrower pipette's width step may be a step along the holder itself).

    Also where the first frame's detection was set aside (the base end chosen
    by motion: a tapered capillary whose wide end the detector did not take
    for the tube leaves the tube's end unseen).

    With the half-width the tracker learnt from the tube's edges where it
    started, not the detection's: that one is read off a threshold's mask
    and came out 1.4x the tube's on blurred rims, so that a holder showing
    for under three tube widths seemed shorter than the two widths a holder's
    stretch must have (an independent renderer's short pipettes: bases 55 and
    74 px inside them, lengths 11 % long)."""
    if base_hint is not None:
        return results, None
    half_width = _learnt_half_width(results)
    if half_width is None and det is not None:
        half_width = det.half_width
    if half_width is None:
        return results, None
    return drop_holder(results, lambda: as_float(frames.first), half_width, px, frames=frames)


def _base_source(results) -> str:
    """How the base was found: that of a start that was measured, where one
    was ("" where none says)."""
    sources = [r.base_source for r in sorted(results, key=lambda r: not r.ok) if r.base_source]
    return sources[0] if sources else ""


def _learnt_half_width(results) -> float | None:
    """The median half-width the tracker learnt where it started (px), over
    ``results``; None if it never started."""
    widths = [r.half_width_px for r in results if np.isfinite(r.half_width_px)]
    return float(np.median(widths)) if widths else None


def _static_end(reader, det):
    """Which end is held, from the video, when the first frame cannot tell.

    ``det`` is the first frame's detection. Returns ``(base_end, note,
    detection)``: a point near the base end (col, row) or None, a line for the
    run's notes (None when the test was not needed), and the first frame's
    detection when it stands as it is, or cut to the tube between its two
    holders' steps (:attr:`pipeline.segment.Detection.held_at`), from the one
    told.
    """
    from .motion import end_motion

    if det is None or det.base_source != AMBIGUOUS_BASE:
        return None, None, det
    if det.held_at is not None:
        # the base is where one of the two structures at the path's ends holds
        # the tube: the motion is compared there, not at the path's own ends
        # (both of which may stand still, in the holder and in a fibre)
        tube = held_between(det, det.held_at[0])
        ends = tube.path[[0, -1]]
        seen = "a narrower stretch at one end and a wider holder at the other"
    else:
        tube, ends, seen = det, det.path[[0, -1]], "no pipette or border seen"
    motion = end_motion(iter(reader), np.c_[-tube.path.imag, tube.path.real], det.half_width)
    if not motion.decided:
        if det.held_at is not None:
            # (the wider holder holds, rather than a narrower stretch that may
            # be a fibre: the tube tracked between them either way)
            end = det.held_at[1]
            return (end.real, -end.imag), (
                f"base end ambiguous ({seen}, and both moved alike over {motion.frames} "
                "frames): took the wider holder's; give --base X,Y if it is wrong"), \
                held_between(det, end)
        return None, (f"base end ambiguous ({seen}, and both ends moved "
                      f"alike over {motion.frames} frames): took the end nearer the border; "
                      "give --base X,Y if it is wrong"), det
    end = ends[1] if motion.base_is_last else ends[0]
    return (end.real, -end.imag), (
        f"base end chosen by motion: {seen}, and the other end moved "
        f"{max(motion.first, motion.last) / max(min(motion.first, motion.last), 1.0):.0f}x "
        f"more over the first {motion.frames} frames"), (
            None if det.held_at is None else held_between(det, end))


def _notes(results, stages, base_given: bool, rate) -> list[str]:
    n = len(results)
    notes = []
    work = [r.work_fraction for r in results if r.stage in ("fast", "crossing")]
    if work:
        notes.append(f"cropped to the tube's region: {100 * np.mean(work):.0f}% of each frame's "
                     "pixels on average")
    n_cross = stages.get("crossing", 0)
    notes.append(f"crossing handling ran on {n_cross} of {n} frames" +
                 ("" if n_cross else " (the tube never touched itself)") +
                 (" (only frames whose predicted tube touches itself need it)" if n_cross else ""))
    for stage, why in (("wide", "the fast fit failed its checks"),
                       ("length held", "where the tube crossed itself and its end hid in "
                        "the other layer, or no fit found its end where its length puts it (a "
                        "faint tip): the shape fitted at the tube's own length"),
                       ("redetect", "the wide search failed too")):
        k = stages.get(stage, 0)
        notes.append(f"{stage} search ran on {k} of {n} frames" +
                     (f" ({why})" if k else " (never needed)"))
    k = stages.get("backward", 0)
    if k:
        notes.append(f"tracked backwards on {k} of {n} frames (lost on the way forward before "
                     "a later frame started the tracker, or among the first frames bent away "
                     "from the frames either side and back; found from the next frame's shape)")
    if base_given:
        notes.append("base given: automatic base search left out")
    if not rate:
        notes.append("frame rate unknown: time_s left empty (give --fps)")
    lost = [r for r in results if not r.ok]
    if lost:
        reasons = Counter(r.status for r in lost)
        notes.append("not measured: " + "; ".join(f"{k} ({v} frames)" for k, v in reasons.items()))
    return notes


def _joints_note(results, sample) -> str:
    """Where the centreline was allowed to kink (section joints), and why."""
    good = [r for r in results if r.ok]
    last = _section_joints(good[-1]) if good else ()
    where = ", ".join(f"{j:.3f}" for j in last)
    if sample is not None:
        if not last:
            return (f"section joints: none (sample {sample.name} is a single section: "
                    "not looked for)")
        return f"section joints from sample {sample.name}'s sections at u = {where} of the length"
    if last:
        first = next(r.frame for r in good if _section_joints(r))
        return (f"section joints found in the frames at u = {where} of the length (first on "
                f"frame {first}: steps in the tube's width, or kinks in its shape once bent >= "
                f"{JOINT_CHECK_DEG:g} deg)")
    return ("section joints: none found (the tube's width did not step, nor its curvature on "
            f"frames bent >= {JOINT_CHECK_DEG:g} deg); give --sample to use its sections")


def _section_joints(track: FrameTrack) -> tuple[float, ...]:
    """The section joints of a frame's curve: not the start of a straight
    end plug (:attr:`FrameTrack.plug_px`), which is its last joint."""
    joints = track.curve.joints
    return joints[:-1] if track.plug_px is not None else joints


def _look_note(results) -> str:
    """How the tube looked: which edges the tracker followed."""
    names = {-1: "darker than its surroundings at its edges (transmitted light, an opaque "
                 "tube)",
             1: "brighter than its surroundings at its edges (fluorescence)",
             0: "a relief (differential interference contrast): lit on one flank, shaded on "
                "the other, both edges stepping the same way"}
    seen = [r.polarity for r in results if r.polarity is not None]
    if not seen:
        return "tube look: no start found a tube"
    note = "tube look: " + "; then ".join(names[p] for p in dict.fromkeys(seen))
    shear = [(r.frame, r.shear_deg) for r in results if np.isfinite(r.shear_deg)]
    if 0 in seen:
        note += (f"; its shear at {shear[0][1]:.0f} deg (y up), told on frame {shear[0][0]}: "
                 "where the tube runs along it, it fades and is bridged" if shear else
                 "; its shear never told (the tube never turned across it): each frame's "
                 "edges were read the one way that fits them best")
    return note


def _end_step_note(results) -> str | None:
    """Whether the tube's end stepped sideways off the rest's line (a
    lumen's step, or a straight plug's), and what the fits did about it (None
    where it was not looked for)."""
    told = [r for r in results if r.ok and r.end_step is not None]
    if told and told[0].plug_px is not None:
        px, offset = told[0].end_step
        return (f"the last {px:.1f} px of the tube sat off the line the rest of the tube's give "
                f"from frame {told[0].frame} on ({offset:+.2f} px then), more the more it "
                "bent: a straight plug (above); its side edges left out of the fits or given "
                "an offset of their own, and the tube made straight over it")
    if told:
        px, offset = told[0].end_step
        out = sum(end_step_left_out(r.curve, *r.end_step) for r in told)
        how = (f"their side edges left out of the fits on {out} of {len(told)} frames (the "
               "tip's direction is the arc's before them)")
        lumen = abs(offset) <= END_STEP_LEAVE_OUT_MAX_PX
        if out < len(told):
            why = (f"the stretch over {END_STEP_LEAVE_OUT:.0%} of the last section" if lumen
                   else f"the offset over {END_STEP_LEAVE_OUT_MAX_PX} px")
            how += (f", given a sideways offset of their own on the other {len(told) - out} "
                    f"({why}: left out, they would take the bend there with them)")
        cause = ("a sealed end past an off-centre lumen" if lumen
                 else "too far for an off-centre lumen's end: a bend the fits miss")
        return (f"the last {px:.1f} px of the tube stepped sideways from frame "
                f"{told[0].frame} on: their edge midpoints sat {offset:+.2f} px off the line "
                f"the rest of the tube's give, steadily ({cause}); {how}")
    if any(r.ok and r.end_steps is not None for r in results):
        return ("the tube's end did not step sideways: its edge midpoints sat on the line "
                "the rest of the tube's give")
    return None


def _drift_note(results, base_given: bool) -> str:
    """A line on the stage's drift the base followed (:mod:`pipeline.drift`)."""
    moved = [abs(r.stage_shift) for r in results if r.ok]
    held = "as given" if base_given else "where the first frames show it"
    if moved and max(moved) > 0:
        return (f"stage drift followed: the holder, and the base with it, moved up to "
                f"{max(moved):.1f} px from {held} (the holder's region behind the base "
                "registered against the first frame's: on every other frame while still, on "
                "every one once it drifts)")
    return (f"stage drift: none followed (the base held {held}: the holder's region did not "
            f"move by {FOLLOW_MIN_PX:g} px on three frames in a row, or no holder showed, or "
            "the tube entered from the frame's border)")


def _cap_note(results) -> str:
    """What the tube's end was taken for: a flat face or a round cap."""
    told = [r.cap for r in results if r.ok and r.cap is not None]
    if not told:
        return "tube's end: taken for a flat face (too few frames to tell its shape)"
    if not told[-1]:
        return ("tube's end: a flat face (the lines beside its axis ended where the axis's "
                "did)")
    return (f"tube's end: a round cap ({told[-1]:.2f} of a hemisphere of its radius, from "
            "where the lines beside its axis ended): the tip put at its apex, the side "
            "edges on the cap left out")


def _tip_hold_note(results) -> str:
    """How the shape reported held the tube's end stretch, on how many frames."""
    counts = Counter(r.tip_hold for r in results if r.ok)
    n = sum(counts.values())
    return (f"tip stretch held to its curvature's trend from the stretch before on "
            f"{counts['trend']} of {n} frames, to a constant curvature on {counts['constant']} "
            "(the frames so far did not tell the curvature change along the end, a section "
            "joint lay within two stretches of the end, or the edges told against the trend), "
            f"left as fitted on {counts['']} (the edges told against both, or the base's own "
            "fit)")


def _end_note(results) -> str:
    """Whether the side edges near the tube's end were left out, and why."""
    seen = np.array([r.end_offset for r in results if r.ok and np.isfinite(r.end_offset)])
    told = f"{seen.mean():+.2f} px on average over {seen.size} frames" if seen.size else ""
    cleared = [r.frame for r in results if r.ok and r.end_clear]
    if cleared and not told:
        # (a relief's are left out on every frame, without a measurement)
        return (f"side edges within {END_CLEAR_HW:g} half-widths of the tube's end left out: "
                "a relief shows its end face as a line as strong as the tube's edges")
    if cleared:
        return (f"side edges within {END_CLEAR_HW:g} half-widths of the tube's end left out "
                f"from frame {cleared[0]} on: before, they sat off the line the rest of the "
                f"tube's edges give ({told}; the end face's blur pulled them)")
    if not told:
        return ("side edges kept up to 2 px from the tube's end (looked at only on a tube "
                "brighter than its surroundings, with a profile that near its end)")
    return ("side edges kept up to 2 px from the tube's end: they sat on the line the rest of "
            f"the tube's edges give ({told})")


def _smoothing_note(results, binning: Binning) -> str:
    """How much the edge profiles were smoothed, and why."""
    chosen = sorted({r.smooth_px for r in results if np.isfinite(r.smooth_px)})
    if not chosen:
        return "edge profiles: no start found a tube"
    px = "binned px" if binning else "px"
    if chosen == [EDGE_SCALES[0]]:
        return (f"edge profiles smoothed over {chosen[0]:g} {px}, the narrowest tried: the "
                "tube's edges stood clear of the frame's noise")
    why = (f"where the narrowest ({EDGE_SCALES[0]:g} {px}) left the tube's edges less than "
           f"{SNR_TARGET:g}x above the frame's noise")
    if len(chosen) == 1:
        return f"edge profiles smoothed over {chosen[0]:g} {px}, not the narrowest: {why}"
    where = ", ".join(f"{s:g}" for s in chosen)
    return f"edge profiles smoothed over {where} {px}, chosen afresh at each start: wider {why}"


def _strips_note(results, binning: Binning) -> str | None:
    """How many lines each edge profile averaged, where more than the usual
    (None where every start kept :data:`STRIP_LINES`)."""
    lines = sorted({r.strip_lines for r in results if r.strip_lines > STRIP_LINES})
    if not lines:
        return None
    px = "binned px" if binning else "px"
    where = " or ".join(f"{n} (±{strip_half_px(n):g} {px})" for n in lines)
    return (f"each edge profile averaged {where} parallel lines along the tube, not "
            f"{STRIP_LINES}: even the widest smoothing left the tube's edges under "
            f"{STRIP_SNR:g}x the noise of {STRIP_LINES} lines")


def _run_record(run: TrackRun, source, rate, results, settings: TrackSettings) -> dict:
    good = [r for r in results if r.ok]
    return {
        "input": str(source),
        "frames": run.n_frames,
        "frames_ok": run.n_ok,
        "fps": rate,
        "um_per_px": run.um_per_px,
        "scale_source": run.scale_source,
        "base_source": run.base_source,
        "stages": run.stages,
        "tracker_settings": asdict(settings),
        "runtime_s": round(run.runtime_s, 3),
        "frames_per_s": round(run.frames_per_s, 1),
        "median_residual_px": float(np.median([r.residual_px for r in good])) if good else None,
        "left_out_and_why": list(run.notes),
        "first_curve": curve_record(good[0].curve) if good else None,
    }
