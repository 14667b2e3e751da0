"""Model reports: the paper table, convergence orders and the written files."""

import numpy as np
import pandas as pd
import pytest

from models import PAPER_SAMPLES, PAPER_TABLE2, eb_bend_angle
from pipeline.model_report import (
    CONVERGENCE_EB_FILE,
    CONVERGENCE_LS_FILE,
    CONVERGENCE_PNG,
    PAPER_TABLE_FILE,
    SPEED_FILE,
    best_time,
    eb_convergence,
    loglog_order,
    ls_convergence,
    model_report_markdown,
    model_speed,
    paper_table2,
    time_calls,
    write_model_reports,
)
from pipeline.stability import STABILITY_FILE


@pytest.fixture(scope="module")
def table():
    return paper_table2()


def test_paper_table_has_the_three_samples_and_the_required_columns(table):
    required = {"sample", "pressure_mpa", "eb_deg", "paper_eb_deg", "paper_ls_deg",
                "experiment_deg", "eb_error_pct", "E_eff_mpa", "eb_eff_deg",
                "eb_eff_error_pct", "eb_to_paper_eb"}
    assert required <= set(table.columns)
    assert table["sample"].tolist() == [1, 2, 3]
    assert table["pressure_mpa"].tolist() == [0.14, 0.14, 0.17]
    assert table["paper_eb_deg"].tolist() == [332.7, 180.8, 243.8]
    assert table["paper_ls_deg"].tolist() == [292.7, 198.2, 283.1]
    assert table["experiment_deg"].tolist() == [306.4, 175.7, 273.2]
    for row in table.itertuples():
        ours = np.degrees(eb_bend_angle(PAPER_SAMPLES[row.sample], row.pressure_mpa, E_mpa=1.4))
        assert row.eb_deg == pytest.approx(ours, rel=1e-14)
        exp = PAPER_TABLE2[row.sample]["experiment_deg"]
        assert row.eb_error_pct == pytest.approx(100 * (ours - exp) / exp)
        assert row.eb_to_paper_eb == pytest.approx(ours / row.paper_eb_deg)


def test_effective_modulus_minimises_the_squared_error(table):
    a = table["eb_deg"].to_numpy() * 1.4  # angle · E, deg·MPa
    exp = table["experiment_deg"].to_numpy()

    def sse(E):
        return np.sum((a / E - exp) ** 2)

    E_eff = table["E_eff_mpa"].iloc[0]
    assert (table["E_eff_mpa"] == E_eff).all()
    for factor in (0.9, 0.99, 0.999, 1.001, 1.01, 1.1):
        assert sse(E_eff * factor) > sse(E_eff)
    np.testing.assert_allclose(table["eb_eff_deg"], a / E_eff, rtol=1e-14)
    np.testing.assert_allclose(table["eb_eff_error_pct"], 100 * (a / E_eff - exp) / exp,
                               rtol=1e-12)


def test_loglog_order_recovers_a_power_law_and_skips_the_floor():
    n = np.array([10, 100, 1000, 10_000])
    assert loglog_order(n, 5.0 * n**-3.0) == pytest.approx(3.0, rel=1e-12)
    assert loglog_order(n, [1e-2, 1e-4, 1e-20, 0.0], floor=1e-15) == pytest.approx(2.0)
    assert np.isnan(loglog_order(n, [1.0, 0.0, 0.0, 0.0]))


def test_best_time_is_positive_and_calls_the_function():
    calls = []
    assert best_time(lambda: calls.append(1), repeats=2, min_time=0.0) > 0
    assert len(calls) >= 3  # warm-up plus two repeats
    best, median = time_calls(lambda: calls.append(1), repeats=3, min_time=0.0)
    assert 0 < best <= median


def test_trapezoid_converges_at_second_order():
    eb = eb_convergence(n_points=(100, 200, 400, 800, 1600, 3200), repeats=1, min_time=0.0)
    trap = eb[eb["evaluator"] == "eb_trapezoid"]
    assert abs(trap["observed_order"].iloc[0] - 2.0) < 0.3
    assert np.all(np.diff(trap["max_position_error_um"]) < 0)
    closed = eb[eb["evaluator"] == "eb_closed_form"]
    assert closed["max_position_error_um"].max() < 1e-9
    assert (eb["seconds"] > 0).all()


def test_line_segment_angle_change_converges_at_second_order():
    ls = ls_convergence(n_segments=tuple(2**k for k in range(8, 15)), repeats=1, min_time=0.0)
    assert abs(ls["angle_order"].iloc[0] - 2.0) < 0.3
    change = ls["angle_change_deg"].dropna()
    assert len(change) == len(ls) - 1 and np.all(np.diff(change) < 0)
    assert (ls["ls_cumsum_s"] > 0).all() and (ls["ls_closed_s"] > 0).all()


def test_speed_table_has_one_row_per_benchmark():
    speed = model_speed(repeats=2)
    assert list(speed.columns) == ["benchmark", "value", "median", "unit", "target",
                                   "meets_target", "detail"]
    assert (speed["value"] > 0).all() and (speed["median"] >= speed["value"]).all()
    assert (speed["meets_target"] == (speed["value"] <= speed["target"])).all()


def test_write_model_reports_writes_every_file(tmp_path):
    paths = write_model_reports(tmp_path, benchmarks=False)
    names = {p.name for p in paths}
    assert names == {STABILITY_FILE, PAPER_TABLE_FILE, CONVERGENCE_EB_FILE,
                     CONVERGENCE_LS_FILE, CONVERGENCE_PNG}
    assert {p.name for p in tmp_path.iterdir()} == names  # no temporary files left
    assert all(p.stat().st_size > 0 for p in paths)
    assert (tmp_path / CONVERGENCE_PNG).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert pd.read_csv(tmp_path / STABILITY_FILE)["passed"].all()
    text = model_report_markdown(tmp_path)
    for name in names:
        assert name in text
    assert SPEED_FILE not in text
    assert "E_eff" in text and "observed order" in text
