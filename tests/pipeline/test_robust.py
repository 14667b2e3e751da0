import numpy as np
import pytest
from scipy.stats import median_abs_deviation

from pipeline.robust import robust_sd


@pytest.mark.parametrize("dtype", [np.float32, np.float64, np.uint8])
@pytest.mark.parametrize("axis", [0, 1, None])
def test_robust_sd_gives_scipys_numbers_bit_for_bit(dtype, axis):
    rng = np.random.default_rng(3)
    for _ in range(20):
        x = (rng.normal(size=(int(rng.integers(1, 8)), int(rng.integers(1, 40)))) * 30 + 100)
        x = x.astype(dtype)
        ours = np.asarray(robust_sd(x, axis=axis))
        theirs = np.asarray(median_abs_deviation(x, axis=axis, scale="normal"))
        assert ours.shape == theirs.shape and ours.dtype == theirs.dtype
        assert np.array_equal(ours, theirs)


def test_robust_sd_is_a_normal_samples_sd_and_ignores_a_minority_of_outliers():
    rng = np.random.default_rng(4)
    x = rng.normal(scale=2.0, size=20000)
    assert robust_sd(x) == pytest.approx(2.0, rel=0.03)
    x[:2000] = 1e6
    assert robust_sd(x) == pytest.approx(2.0 * 1.14, rel=0.05)  # 10 % outliers widen it by ~14 %


def test_robust_sd_is_nan_without_values_or_with_a_nan():
    assert np.isnan(robust_sd(np.array([])))
    assert np.isnan(robust_sd(np.array([1.0, np.nan, 3.0])))
    assert np.isnan(robust_sd(np.zeros((3, 0)), axis=1)).all()


def test_the_tracker_does_not_import_scipy_stats():
    import subprocess
    import sys

    code = "import sys, pipeline.tracks, pipeline.cli; print('scipy.stats' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "False"
