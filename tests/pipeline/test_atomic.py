"""Atomic CSV output: both writers give the same plain CSV, and nothing half-written."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from pipeline import atomic
from pipeline.atomic import write_csv


def numbers(n=50, seed=0):
    rng = np.random.default_rng(seed)
    return pd.DataFrame({
        "frame": np.repeat(np.arange(n // 10), 10),
        "s_um": rng.uniform(0, 1e4, n),
        "x_um": rng.normal(0, 1e3, n) * 10.0 ** rng.integers(-20, 20, n),
        "y_um": np.r_[np.nan, -np.inf, np.inf, 0.1 + 0.2, -0.0, rng.normal(size=n - 5)],
    })


def test_numeric_table_reads_back_exactly_with_a_plain_header(tmp_path):
    table = numbers()
    path = write_csv(table, tmp_path / "c.csv")
    text = path.read_text()
    assert text.splitlines()[0] == "frame,s_um,x_um,y_um"
    assert '"' not in text
    back = pd.read_csv(path)
    assert list(back.dtypes) == [np.int64, np.float64, np.float64, np.float64]
    # every float, NaN and ±inf included, is the same number after the round trip
    np.testing.assert_array_equal(back.to_numpy(), table.to_numpy())


def test_numeric_table_is_written_as_pandas_would_read_it_from_pandas(tmp_path):
    # the fast writer and pandas' own give tables that read back identically
    table = numbers(seed=1)
    write_csv(table, tmp_path / "fast.csv")
    table.to_csv(tmp_path / "pandas.csv", index=False)
    pd.testing.assert_frame_equal(pd.read_csv(tmp_path / "fast.csv"),
                                  pd.read_csv(tmp_path / "pandas.csv"))


def test_text_columns_and_float_format_stay_unquoted(tmp_path):
    table = pd.DataFrame({"frame": [0, 1], "status": ["ok", "no tube found"],
                          "angle": [1.23456789, np.nan]})
    text = write_csv(table, tmp_path / "t.csv").read_text()
    assert text.splitlines() == ["frame,status,angle", "0,ok,1.23456789", "1,no tube found,"]
    text = write_csv(table[["frame", "angle"]], tmp_path / "f.csv",
                     float_format="%.3g").read_text()
    assert text.splitlines() == ["frame,angle", "0,1.23", "1,"]


def test_failed_write_leaves_the_old_file(tmp_path, monkeypatch):
    path = write_csv(numbers(), tmp_path / "c.csv")
    before = path.read_text()

    def half_then_fail(frame, tmp):
        tmp.write_text("frame,s_um\n0,")
        raise OSError("disk full")

    monkeypatch.setattr(atomic, "_write_numeric_csv", half_then_fail)
    with pytest.raises(OSError, match="disk full"):
        write_csv(numbers(seed=2), path)
    assert path.read_text() == before
    assert [p.name for p in tmp_path.iterdir()] == ["c.csv"]
