import numpy as np
import pandas as pd
import pytest

from pipeline import schema as S
from pipeline.pressure import frame_pressures, pressures_from_ramp, read_pressure_log


def _tracks(n=11, fps=10.0):
    f = np.arange(n)
    return pd.DataFrame({S.FRAME: f, S.TIME: f / fps, S.STATUS: "ok"})


def _write(tmp_path, **cols):
    path = tmp_path / "pressure.csv"
    pd.DataFrame(cols).to_csv(path, index=False)
    return path


def test_log_by_frame_is_interpolated(tmp_path):
    path = _write(tmp_path, frame=[0, 10], pressure_mpa=[0.0, 0.1])
    fp = frame_pressures(_tracks(), [0, 3, 10], pressure_csv=path)
    np.testing.assert_allclose(fp.pressure_mpa, [0.0, 0.03, 0.1])
    assert fp.kind == "log:frame" and "by frame" in fp.source and "pressure.csv" in fp.source


def test_log_by_time_uses_the_tracks_times(tmp_path):
    path = _write(tmp_path, time_s=[0.5, 0.0, 1.0], pressure_mpa=[0.05, 0.0, 0.2])  # unsorted
    fp = frame_pressures(_tracks(), [0, 2, 5, 10], pressure_csv=path)
    np.testing.assert_allclose(fp.pressure_mpa, [0.0, 0.02, 0.05, 0.2])
    assert fp.kind == "log:time"


def test_ramp_runs_over_all_frames_of_the_table():
    fp = pressures_from_ramp(_tracks(), [0, 5, 10], 0.14)
    np.testing.assert_allclose(fp.pressure_mpa, [0.0, 0.07, 0.14])
    assert fp.kind == "ramp" and "0.14" in fp.source and fp.p_max_mpa == 0.14


@pytest.mark.parametrize("cols, match", [
    ({"frame": [0, 5], "pressure_mpa": [0.0, 0.1]}, "does not cover"),
    ({"frame": [0, 10], "pressure_mpa": [0.0, np.nan]}, "finite"),
    ({"frame": [0, 10], "pressure_mpa": [0.0, -0.1]}, ">= 0"),
    ({"frame": [0, 10], "p": [0.0, 0.1]}, "pressure_mpa"),
    ({"index": [0, 10], "pressure_mpa": [0.0, 0.1]}, "frame' or 'time_s"),
    ({"frame": [0, 0, 10], "pressure_mpa": [0.0, 0.0, 0.1]}, "unique"),
    ({"frame": [0], "pressure_mpa": [0.0]}, "two rows"),
])
def test_bad_logs_raise_one_line_errors(tmp_path, cols, match):
    path = _write(tmp_path, **cols)
    with pytest.raises(ValueError, match=match) as info:
        frame_pressures(_tracks(), np.arange(11), pressure_csv=path)
    assert "\n" not in str(info.value)


def test_time_log_needs_times_in_the_tracks(tmp_path):
    path = _write(tmp_path, time_s=[0.0, 1.0], pressure_mpa=[0.0, 0.1])
    tracks = _tracks().assign(time_s=np.nan)
    with pytest.raises(ValueError, match="no time"):
        frame_pressures(tracks, [0, 1], pressure_csv=path)


def test_source_choice_is_checked(tmp_path):
    path = _write(tmp_path, frame=[0, 10], pressure_mpa=[0.0, 0.1])
    with pytest.raises(ValueError, match="not both"):
        frame_pressures(_tracks(), [0], pressure_csv=path, p_max=0.1)
    with pytest.raises(ValueError, match="no pressures"):
        frame_pressures(_tracks(), [0])
    with pytest.raises(ValueError, match="not found"):
        read_pressure_log(tmp_path / "missing.csv")
    with pytest.raises(ValueError, match="p_max"):
        pressures_from_ramp(_tracks(), [0], -1.0)
