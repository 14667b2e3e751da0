import numpy as np
import pytest

from pipeline.steps import trend_level_fit, two_level_fit


def test_two_level_fit_matches_each_split_fitted_on_its_own():
    rng = np.random.default_rng(5)
    x = rng.normal(size=37) * 3 + 10
    sse, before, after = two_level_fit(x)
    assert sse.shape == before.shape == after.shape == (36,)
    for k in range(1, 37):
        a, b = x[:k], x[k:]
        assert before[k - 1] == pytest.approx(a.mean())
        assert after[k - 1] == pytest.approx(b.mean())
        rss = ((a - a.mean()) ** 2).sum() + ((b - b.mean()) ** 2).sum()
        assert sse[k - 1] == pytest.approx(rss)


def test_two_level_fit_puts_the_least_residual_at_a_noisy_step():
    rng = np.random.default_rng(6)
    x = np.r_[np.full(40, 2.0), np.full(25, 5.0)] + rng.normal(scale=0.3, size=65)
    sse, before, after = two_level_fit(x)
    assert int(np.argmin(sse)) + 1 == 40
    assert before[39] == pytest.approx(2.0, abs=0.15) and after[39] == pytest.approx(5.0, abs=0.15)


def test_two_level_fit_of_a_flat_sequence_leaves_no_residual_anywhere():
    sse, before, after = two_level_fit(np.full(10, 7.0))
    assert np.allclose(sse, 0.0) and np.allclose(before, 7.0) and np.allclose(after, 7.0)


def test_trend_level_fit_matches_each_split_fitted_on_its_own():
    rng = np.random.default_rng(7)
    x = rng.normal(size=29) * 2 + 5
    sse, end, after = trend_level_fit(x)
    assert sse.shape == end.shape == after.shape == (27,)
    for k in range(2, 29):
        i = np.arange(k)
        line = np.polyfit(i, x[:k], 1)
        rss = (((np.polyval(line, i) - x[:k]) ** 2).sum()
               + ((x[k:] - x[k:].mean()) ** 2).sum())
        assert sse[k - 2] == pytest.approx(rss, abs=1e-9)
        assert end[k - 2] == pytest.approx(np.polyval(line, k - 1))
        assert after[k - 2] == pytest.approx(x[k:].mean())


def test_trend_level_fit_finds_a_step_after_a_taper_that_two_levels_miss():
    # a pipette narrowing from 21 to 12 px, then a tube 15.6 px wide: the
    # pipette's mean width is about the tube's
    rng = np.random.default_rng(8)
    x = np.r_[np.linspace(21.0, 12.0, 130), np.full(200, 15.6)] + rng.normal(0, 0.4, 330)
    sse, end, after = trend_level_fit(x)
    k = int(np.argmin(sse)) + 2
    assert abs(k - 130) <= 2
    assert end[k - 2] == pytest.approx(12.0, abs=0.3)
    assert after[k - 2] == pytest.approx(15.6, abs=0.1)
    two = int(np.argmin(two_level_fit(x)[0])) + 1
    assert abs(two - 130) > 20
