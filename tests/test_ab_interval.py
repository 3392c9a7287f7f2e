"""benchmarks/ab.py's interval around the median of per-round ratios."""

import sys
from pathlib import Path

import pytest
from scipy.stats import binom

BENCHMARKS = str(Path(__file__).resolve().parent.parent / "benchmarks")
sys.path.insert(0, BENCHMARKS)  # benchmarks/ is scripts, not a package
try:
    from ab import median_interval
finally:
    sys.path.remove(BENCHMARKS)


@pytest.mark.parametrize("n", range(1, 6))
def test_no_interval_below_six_rounds(n):
    # With 5 values even [min, max] misses the median with chance 2/32 > 5 %.
    assert median_interval([float(v) for v in range(n)]) is None


@pytest.mark.parametrize("n", range(6, 31))
def test_the_interval_is_the_narrowest_that_covers_the_median_at_95_percent(n):
    values = [float(v) for v in reversed(range(n))]  # unsorted on purpose
    lo, hi = median_interval(values)
    k = int(lo) + 1  # lo is the k-th smallest, hi the k-th largest
    assert hi == n - k
    covers = 1 - 2 * binom.cdf(k - 1, n, 0.5)
    narrower = 1 - 2 * binom.cdf(k, n, 0.5)
    assert covers >= 0.95 > narrower
