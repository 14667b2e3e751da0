"""The numerical-stability matrix, run case by case as tests (issue "Models" §7)."""

import numpy as np
import pandas as pd
import pytest

from pipeline.stability import CASES, COLUMNS, STABILITY_FILE, _run, run_case, write_stability


@pytest.mark.parametrize("name", list(CASES))
def test_stability_case_passes(name):
    result = run_case(name)
    assert result.passed, f"{name}: worst {result.worst_check} = {result.worst_deviation:.3g} " \
                          f"(tolerance {result.tolerance:.3g}); {result.detail}"
    assert result.n_checks >= 1


def test_a_check_past_its_tolerance_fails_the_case():
    def case(checks):
        checks.add("fine", 1e-14, 1e-12)
        checks.add("too big", 2.0, 1.0)
        return "note"

    result = _run("demo", case)
    assert not result.passed
    assert result.worst_check == "too big" and result.worst_deviation == 2.0
    assert result.detail.startswith("note.")


def test_nan_deviations_and_crashes_fail_instead_of_raising():
    nan_case = _run("nan", lambda checks: checks.add("nan", np.nan, 1.0))
    assert not nan_case.passed and nan_case.worst_deviation == np.inf

    def boom(checks):
        raise RuntimeError("broken")

    crashed = _run("boom", boom)
    assert not crashed.passed and "RuntimeError" in crashed.worst_check


def test_unknown_case_is_refused():
    with pytest.raises(ValueError, match="unknown stability case"):
        run_case("no such case")


def test_write_stability_writes_the_given_table(tmp_path):
    table = pd.DataFrame([_run("x", lambda c: c.add("ok", 0.0, 1.0)).__dict__], columns=COLUMNS)
    path = write_stability(tmp_path / "out", table)
    assert path == tmp_path / "out" / STABILITY_FILE
    back = pd.read_csv(path)
    assert list(back.columns) == COLUMNS and back["passed"].tolist() == [True]
    assert [p.name for p in path.parent.iterdir()] == [STABILITY_FILE]  # no temporary left
