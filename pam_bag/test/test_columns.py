"""A topic's messages decoded as numpy columns at once (pam_bag._columns): the same numbers as
the typestore's message-by-message reading, for real CDR from the typestore's own serialiser, and
no columns (the caller reads message by message) whenever the layout does not allow them."""

import math

import numpy as np
import pytest

from pam_bag._columns import header_columns, header_scalars
from pam_bag.bags import make_typestore
from pam_common.stamps import stamp_ns

pytestmark = pytest.mark.unit

PRESSURES = 'pam_interfaces/msg/Pressures'


@pytest.fixture(scope='module')
def store():
    return make_typestore()


def pressures(store, n, frame_id='pam_joint', start=0):
    Msg, Header, Time = (store.types[t] for t in (PRESSURES, 'std_msgs/msg/Header',
                                                  'builtin_interfaces/msg/Time'))
    out = []
    for k in range(start, start + n):
        p1 = math.nan if k == 3 else 1.0e5 + 0.25 * k
        out.append(store.serialize_cdr(Msg(
            header=Header(stamp=Time(sec=1_700_000_000 + k // 1000, nanosec=(k % 1000) * 10**6),
                          frame_id=frame_id),
            p1=p1, p2=-3.5e5 - k, sample=2**63 + k), PRESSURES))
    return out


@pytest.mark.parametrize('frame_id', ['pam_joint', '', 'abcdefg', 'abcdefgh', 'x' * 30])
def test_the_columns_are_the_typestores_reading(store, frame_id):
    datas = pressures(store, 50, frame_id)
    columns = header_columns(datas, store, PRESSURES)
    assert columns is not None
    for j, data in enumerate(datas):
        msg = store.deserialize_cdr(data, PRESSURES)
        assert columns['stamp_ns'][j] == stamp_ns(msg.header.stamp)
        assert columns['p1'][j] == msg.p1 or (math.isnan(msg.p1) and np.isnan(columns['p1'][j]))
        assert columns['p2'][j] == msg.p2
        assert int(columns['sample'][j]) == msg.sample
    assert columns['stamp_ns'].dtype == np.int64 and columns['sample'].dtype == np.uint64


def test_no_columns_where_the_layout_does_not_allow_them(store):
    assert header_scalars(store, 'sensor_msgs/msg/JointState') is None   # arrays, strings
    assert header_scalars(store, 'std_msgs/msg/Float64') is None         # no header
    assert header_scalars(store, 'sensor_msgs/msg/FluidPressure') == [
        ('fluid_pressure', '<f8'), ('variance', '<f8')]
    assert header_columns([], store, PRESSURES) is None
    # frame_ids that differ (even of the same length), lengths that differ
    assert header_columns(pressures(store, 5, 'aa') + pressures(store, 5, 'bb', 5), store,
                          PRESSURES) is None
    assert header_columns(pressures(store, 5, 'a') + pressures(store, 5, 'bbbbbbbbbbbb', 5), store,
                          PRESSURES) is None
    # not little-endian CDR, or bytes that do not read as the type
    datas = pressures(store, 5)
    assert header_columns([b'\x00\x00' + d[2:] for d in datas], store, PRESSURES) is None
    assert header_columns([d[:-8] for d in datas], store, PRESSURES) is None
