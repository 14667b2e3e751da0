"""Which frames before the tracker's last start are tracked again backwards,
and how the backward pass's results replace the forward pass's
(:mod:`pipeline.backtrack`). End to end, on a video that starts curled over
itself: ``test_a_video_that_starts_curled_over_itself_finds_its_base_at_the_restart``
in ``test_tracking_accuracy.py``."""

from dataclasses import replace

import numpy as np
import pytest

from pipeline import backtrack
from pipeline.backtrack import OFF_THE_TUBE, _to_redo, track_back
from pipeline.centreline import Curve
from pipeline.track import FrameTrack

BASE = 10 - 100j


def _ok(frame: int, length: float, source: str = "", bend: float = 0.0,
        stage: complex = 0j) -> FrameTrack:
    curve = Curve(BASE + stage, 0.0, length, np.full(6, bend))
    return FrameTrack(frame, "ok", curve, "fast", base_source=source, stage_shift=stage,
                      half_width_px=8.0 if source else float("nan"))


def _lost(frame: int) -> FrameTrack:
    return FrameTrack(frame, "lost: tip not found", None, "")


def test_lost_frames_and_an_earlier_start_on_part_of_the_tube_are_redone():
    # frames 0-2 an earlier start on half the tube, 3-4 lost, 5-9 the last start
    results = ([_ok(0, 150.0, "border"), _ok(1, 151.0), _ok(2, 150.0), _lost(3), _lost(4)]
               + [_ok(5, 300.0, "pipette width step")] + [_ok(i, 300.0) for i in range(6, 10)])
    assert _to_redo(results, 5, 300.0) == [0, 1, 2, 3, 4]


def test_an_earlier_start_that_measured_more_frames_is_kept():
    # the earlier start measured 6 frames at 150 px, the last one 3 at 300:
    # which is the tube is not clear, and only the lost frame is redone
    results = ([_ok(0, 150.0, "border")] + [_ok(i, 150.0) for i in range(1, 6)] + [_lost(6)]
               + [_ok(7, 300.0, "restart")] + [_ok(i, 300.0) for i in range(8, 10)])
    assert _to_redo(results, 7, 300.0) == [6]


def test_frames_found_backwards_from_the_last_start_are_not_redone():
    # frame 0 found from frame 1's shape by the forward pass, that start the last
    results = ([FrameTrack(0, "ok", Curve(BASE, 0.0, 340.0, np.zeros(6)), "backward"),
                _ok(1, 340.0, "border")] + [_ok(i, 300.0) for i in range(2, 8)])
    assert _to_redo(results, 1, 300.0) == []


def test_frames_found_backwards_from_an_earlier_start_count_as_its_own():
    # frame 0 found from frame 1's, whose start measured fewer frames than
    # the last one and at another length
    results = ([FrameTrack(0, "ok", Curve(BASE, 0.0, 150.0, np.zeros(6)), "backward"),
                _ok(1, 150.0, "border"), _lost(2), _ok(3, 300.0, "restart")]
               + [_ok(i, 300.0) for i in range(4, 8)])
    assert _to_redo(results, 3, 300.0) == [0, 1, 2]


def test_frames_measured_at_the_tubes_length_are_not_redone():
    results = ([_ok(0, 300.0, "border"), _ok(1, 302.0), _lost(2), _lost(3)]
               + [_ok(4, 300.0, "restart")] + [_ok(i, 300.0) for i in range(5, 8)])
    assert _to_redo(results, 4, 300.0) == [2, 3]


def test_frames_where_the_tube_crossed_itself_are_not_taken_for_another_start_s():
    # frame 1 of the earlier start crossed itself, its end hidden: shorter
    results = ([_ok(0, 300.0, "border"), _ok(1, 270.0), _lost(2)]
               + [_ok(3, 300.0, "restart")] + [_ok(i, 300.0) for i in range(4, 9)])
    results[1] = FrameTrack(1, "ok", results[1].curve, "crossing", crossing=True)
    assert _to_redo(results, 3, 300.0) == [2]


class _Frames:
    """Stand-in frames, re-iterable; counts the frames read."""

    def __init__(self, n: int):
        self.n, self.read = n, 0

    def __iter__(self):
        for i in range(self.n):
            self.read += 1
            yield np.full((8, 8), float(i), np.float32)


def _fake_backward(found: dict[int, float], drift: complex = 0j, asked=None):
    """A stand-in for :func:`pipeline.track.track_frames` run backwards:
    each frame (told by its value) measured at the length ``found`` gives it,
    lost where it gives none, the stage drifting ``drift`` px a frame back
    from the first frame it is given; what it was asked goes into ``asked``."""
    def run(frames, **kwargs):
        if asked is not None:
            asked.update(kwargs)
        hint = kwargs.get("base_hint")
        # (the base held at the one given, (col, row), carried by the stage)
        at = complex(hint[0], -hint[1]) - BASE if hint is not None else 0j
        for j, frame in enumerate(frames):
            i = int(frame[0, 0])
            r = _ok(j, found[i], bend=-i, stage=j * drift) if i in found else _lost(j)
            yield replace(r, curve=replace(r.curve, base=r.curve.base + at)) if r.ok else r
    return run


def test_the_backward_pass_replaces_what_it_found_and_unmeasures_what_was_off(monkeypatch):
    results = ([_ok(0, 150.0, "border"), _ok(1, 150.0), _lost(2), _lost(3)]
               + [_ok(4, 300.0, "restart")] + [_ok(i, 300.0) for i in range(5, 9)])
    # frame 0 not found backwards, 1-3 found at the tube's length
    monkeypatch.setattr(backtrack, "track_frames",
                        _fake_backward({4: 300.0, 3: 300.0, 2: 301.0, 1: 299.0}))
    frames = _Frames(9)
    out, note = track_back(frames, results)
    assert frames.read == 5  # read again up to the start only
    assert [r.status for r in out[:4]] == [OFF_THE_TUBE, "ok", "ok", "ok"]
    assert [r.frame for r in out] == list(range(9))
    assert [r.stage for r in out[1:4]] == ["backward"] * 3
    # each frame's own result (its bend told its frame), at the start's base
    assert [r.bend_angle_rad for r in out[1:4]] == [-1.0, -2.0, -3.0]
    assert all(abs(r.curve.base - BASE) < 1e-9 for r in out[1:4])
    assert out[4:] == results[4:]
    assert "4 frames before the tracker's start on frame 4" in note
    assert "3 found" in note and "1 measured on something else" in note


def test_a_drifting_stage_carries_the_given_base_and_each_frame_s(monkeypatch):
    # the stage had carried the holder 3 px right, 2 px up by the start on
    # frame 2; going backwards it drifts back 1 px left a frame
    start_shift = 3 + 2j
    results = [_lost(0), _lost(1), _ok(2, 300.0, "restart", stage=start_shift),
               _ok(3, 300.0, stage=start_shift)]
    asked = {}
    monkeypatch.setattr(backtrack, "track_frames",
                        _fake_backward({2: 300.0, 1: 300.0, 0: 300.0}, drift=-1 + 0j,
                                       asked=asked))
    out, _ = track_back(_Frames(4), results, base_hint=(10.0, 100.0))
    # (--base, (col, row), given on frame 0: where the stage stood on frame 2)
    assert asked["base_hint"] == pytest.approx((13.0, 98.0))
    for i in (0, 1):
        back = (2 - i) * (-1 + 0j)
        assert out[i].ok and out[i].stage_shift == pytest.approx(start_shift + back)
        assert out[i].curve.base == pytest.approx(BASE + start_shift + back)


def test_a_frame_found_off_the_tube_keeps_nothing_its_start_learnt(monkeypatch):
    results = [_ok(0, 150.0, "border"), _ok(1, 300.0, "restart"), _ok(2, 300.0),
               _ok(3, 300.0)]
    monkeypatch.setattr(backtrack, "track_frames", _fake_backward({1: 300.0}))
    out, note = track_back(_Frames(4), results)
    assert out[0].status == OFF_THE_TUBE and out[0].curve is None
    assert out[0].base_source == "" and np.isnan(out[0].half_width_px)


def test_a_backward_result_off_the_tubes_length_is_not_taken(monkeypatch):
    results = [_lost(0), _ok(1, 300.0, "restart"), _ok(2, 300.0)]
    monkeypatch.setattr(backtrack, "track_frames", _fake_backward({1: 300.0, 0: 200.0}))
    out, note = track_back(_Frames(3), results)
    assert not out[0].ok and out[0].status == results[0].status
    assert "0 found" in note


def test_frames_past_the_memory_allowed_are_left_as_they_were(monkeypatch):
    results = [_lost(i) for i in range(6)] + [_ok(6, 300.0, "restart"), _ok(7, 300.0)]
    monkeypatch.setattr(backtrack, "track_frames",
                        _fake_backward({i: 300.0 for i in range(7)}))
    # room for three frames of 8x8 float32
    monkeypatch.setattr(backtrack, "MEMORY_BYTES", 3 * 8 * 8 * 4)
    out, note = track_back(_Frames(8), results)
    assert [r.ok for r in out[:6]] == [False] * 4 + [True] * 2
    assert "frames before 4 left as they were" in note


def test_nothing_is_tracked_when_every_frame_to_redo_lies_past_the_memory(monkeypatch):
    # frames 0-1 lost, 2-5 measured well by a longer start, the last start on
    # frame 6: room for 2 frames, the start's and frame 5
    results = ([_lost(0), _lost(1), _ok(2, 300.0, "border")] + [_ok(i, 300.0) for i in (3, 4, 5)]
               + [_ok(6, 300.0, "restart"), _ok(7, 300.0)])
    monkeypatch.setattr(backtrack, "MEMORY_BYTES", 2 * 8 * 8 * 4)

    def refused(*args, **kwargs):
        raise AssertionError("tracked backwards for nothing")

    monkeypatch.setattr(backtrack, "track_frames", refused)
    out, note = track_back(_Frames(8), results)
    assert out == results
    assert "farther back than the 2 frames held in memory" in note


@pytest.mark.parametrize("results", [
    [],
    [FrameTrack(0, "ok", Curve(BASE, 0.0, 300.0, np.zeros(6)), "init", base_source="b")],
    [_lost(0), _lost(1)],
])
def test_nothing_is_redone_without_a_later_start(results):
    out, note = track_back(_Frames(len(results)), results)
    assert out == results and note is None
