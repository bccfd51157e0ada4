"""pam_common.latency.LatencyHistogram against exact percentiles of the same latencies."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pam_common.latency import RATIO, LatencyHistogram


@pytest.mark.parametrize('seed', [0, 1, 2])
def test_percentiles_within_one_bin_of_the_exact_ones(seed):
    rng = np.random.default_rng(seed)
    # a realistic mix: most commands in 0.2-1 ms, a tail to 50 ms, a few tiny ones
    latencies = np.concatenate([rng.lognormal(math.log(4e-4), 0.4, 20000),
                                rng.uniform(1e-3, 5e-2, 300), rng.uniform(0.0, 1e-6, 5)])
    histogram = LatencyHistogram()
    for x in latencies:
        histogram.record(float(x), late=x > 1e-3)
    assert histogram.count == latencies.size
    assert histogram.late == int(np.sum(latencies > 1e-3))
    assert histogram.max == latencies.max()
    for q in (50.0, 90.0, 99.0, 99.9, 100.0):
        exact = float(np.percentile(latencies, q, method='inverted_cdf'))
        assert exact <= histogram.percentile(q) <= exact * RATIO * (1 + 1e-12), q


def test_empty_reset_and_bad_values():
    histogram = LatencyHistogram()
    assert math.isnan(histogram.percentile(50.0))
    assert math.isnan(histogram.summary()['latency max (ms)'])
    for bad in (math.nan, math.inf, -math.inf):
        histogram.record(bad, late=True)
    assert histogram.count == 0 and histogram.late == 0
    histogram.record(1e4)            # beyond the last edge: the open last bin, max exact
    histogram.record(-1.0)           # a stamp from the future (clock step): bin 0
    assert histogram.count == 2
    assert histogram.percentile(100.0) == 1e4
    assert histogram.percentile(50.0) <= 1e-6
    summary = histogram.summary()
    assert summary['commands timed'] == 2 and summary['latency max (ms)'] == 1e7
    histogram.reset()
    assert histogram.count == 0 and histogram.max == 0.0 and histogram.late == 0
