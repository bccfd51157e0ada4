"""The metrics after the initial transient (pam_model.metrics.metrics_after) on a hand-computed
case: a big error at t = 0 sets the headline M, not the post-transient one."""

import math

import numpy as np
import pytest

from pam_model.metrics import DEFAULT_TRANSIENT, after_transient, metrics, metrics_after

T = np.array([0.0, 0.5, 1.0, 1.5, 2.0])          # s
MEASURED = np.array([0.0, 1.0, 2.0, 3.0, 4.0])
ERROR = np.array([10.0, 0.0, 1.0, -2.0, 1.0])    # the big one at t = 0, as a filter's start


def test_headline_m_is_the_early_error_the_post_transient_m_is_not():
    estimated = MEASURED - ERROR
    whole = metrics(MEASURED, estimated)
    assert whole.M == pytest.approx(10.0)
    assert whole.I == pytest.approx(math.sqrt((100 + 0 + 1 + 4 + 1) / 5))
    assert whole.Q == pytest.approx(10.0 / 4.0)
    after = metrics_after(T, MEASURED, estimated, 1.0)   # samples at t = 1.0, 1.5, 2.0
    assert after.M == pytest.approx(2.0)
    assert after.I == pytest.approx(math.sqrt((1 + 4 + 1) / 3))
    assert after.Q == pytest.approx(2.0 / (4.0 - 2.0))   # xi's range over the same samples
    # no transient: the paper's definition
    assert metrics_after(T, MEASURED, estimated, 0.0) == whole


def test_the_transient_counts_from_the_first_stamp():
    assert DEFAULT_TRANSIENT == 1.0
    assert after_transient(T + 100.0, 1.0).tolist() == [False, False, True, True, True]


@pytest.mark.parametrize('transient', [-0.1, math.nan, math.inf])
def test_a_bad_transient_is_refused(transient):
    with pytest.raises(ValueError, match='initial transient'):
        metrics_after(T, MEASURED, MEASURED, transient)


def test_a_record_shorter_than_the_transient_is_refused():
    with pytest.raises(ValueError, match='no sample after the initial transient of 3 s'):
        metrics_after(T, MEASURED, MEASURED, 3.0)
