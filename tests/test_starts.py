"""Latin-hypercube starts from beta distributions."""

import numpy as np
import pytest

from jaxbox.fit import DEFAULT_CONCENTRATION, latin_hypercube, make_transform


@pytest.fixture
def tr():
    return make_transform(
        ["R_wal", "gA", "T_zon0"], [1e-5, 0.0, -3.0], [10.0, 50.0, 37.0], [0.01, 2.0, 17.0]
    )


def test_samples_in_bounds_and_reproducible(tr):
    a = latin_hypercube(tr, [0.01, 2.0, 17.0], 50, seed=4)
    b = latin_hypercube(tr, [0.01, 2.0, 17.0], 50, seed=4)
    c = latin_hypercube(tr, [0.01, 2.0, 17.0], 50, seed=5)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    assert np.all(a > tr.lower) and np.all(a < tr.upper)


def test_stratified_per_parameter(tr):
    from scipy import stats

    n = 40
    guess = [0.01, 2.0, 17.0]
    s = latin_hypercube(tr, guess, n, seed=1)
    pos = tr.relative_position(s)  # in the transform's own scale
    for i, g in enumerate(tr.relative_position(np.asarray(guess))):
        k = DEFAULT_CONCENTRATION
        a, b = 1 + k * g, 1 + k * (1 - g)
        strata = np.floor(stats.beta.cdf(pos[:, i], a, b) * n).astype(int)
        assert sorted(strata) == list(range(n)), "one sample in each equal-probability stratum"


def test_symmetric_when_central_and_skewed_towards_guess(tr):
    n = 400
    central = latin_hypercube(tr, [np.sqrt(1e-5 * 10), 25.0, 17.0], n, seed=0)
    pos = tr.relative_position(central)
    assert np.median(pos[:, 1]) == pytest.approx(0.5, abs=0.02)
    assert np.median(pos[:, 0]) == pytest.approx(0.5, abs=0.02)
    low = latin_hypercube(tr, [1e-4, 2.0, 0.0], n, seed=0)
    plow = tr.relative_position(low)
    assert np.all(np.median(plow, axis=0) < 0.35)
    # the mode of the samples sits near the guess
    hist, edges = np.histogram(plow[:, 1], bins=10, range=(0, 1))
    assert edges[np.argmax(hist)] <= tr.relative_position(np.array([1e-4, 2.0, 0.0]))[1] + 0.1
