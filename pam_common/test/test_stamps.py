"""pam_common.stamps: the one stamp conversion, one stamp and many at once, agree."""

import numpy as np
import pytest

from pam_common.stamps import ns_pair, stamp_ns, stamps_ns

pytestmark = pytest.mark.unit


class Stamp:
    def __init__(self, sec, nanosec):
        self.sec, self.nanosec = sec, nanosec


def test_one_stamp_and_many_agree_and_go_back():
    pairs = [(0, 0), (1, 999_999_999), (1_700_000_000, 123_456_789), (2**31 - 1, 5)]
    many = stamps_ns(np.array([s for s, _ in pairs], dtype=np.int32),
                     np.array([n for _, n in pairs], dtype=np.uint32))
    assert many.dtype == np.int64
    for (sec, nanosec), ns in zip(pairs, many, strict=True):
        assert ns == stamp_ns(Stamp(sec, nanosec)) == int(f'{sec}{nanosec:09d}')
        assert ns_pair(ns) == (sec, nanosec)
