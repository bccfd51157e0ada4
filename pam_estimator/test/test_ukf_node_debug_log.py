"""ukf_node's DEBUG lines: with `--log-level pam.ukf_node:=debug` a filter
reset (a stamp from the past), a sample the NIS gate rejects (a pressure far from the prediction)
and an invalid one (out of range) each give a line from our own code; without it the same feed
prints no DEBUG line at all."""


import pytest

from pam_common.stamps import ns_stamp
from pam_common.testing import assert_no_debug_lines, wait_for_log
from pam_interfaces.msg import JointEstimate, Pressures
from test_ukf_node_topics import answered_then_reset

LOGGER = 'pam.ukf_node'


def pressures(sample: int, stamp_s: float, p1: float = 4.5e5) -> Pressures:
    msg = Pressures(p1=p1, p2=4.5e5, sample=sample)
    msg.header.stamp = ns_stamp(round(stamp_s * 1e9))
    return msg


@pytest.mark.parametrize('debug', [True, False], ids=['debug', 'default'])
def test_reset_and_rejections_at_debug_only(node_process, probe, debug):
    args = ['-p', 'nis_gate:=13.8'] + (['--log-level', f'{LOGGER}:=debug'] if debug else [])
    ukf = node_process('ukf_node', 'pam_estimator', *args)
    estimates = probe.subscribe(JointEstimate, '/pam/estimate', depth=1000)
    pub = probe.publisher(Pressures, '/pam/pressures')
    ukf.wait_for(lambda: pub.get_subscription_count() > 0, 60.0, 'ukf_node matched')
    answered_then_reset(probe, estimates, lambda k: pub.publish(pressures(0, 1.0 + k * 1e-3)))
    feed = [pressures(k, 100.0 + k * 1e-3) for k in range(1, 21)]
    feed += [pressures(21, 100.021, p1=9.0e5),          # 450 kPa off the prediction: gated
             pressures(22, 100.022, p1=5.0e6),          # above pressure_max: invalid
             pressures(23, 100.023),
             pressures(24, 50.0)]                       # a stamp from the past: reset
    for msg in feed:
        pub.publish(msg)
    ukf.wait_for(lambda: len(estimates) >= len(feed), 30.0, 'an estimate per sample')
    got = {m.sample: m for m in estimates.messages()}
    assert got[21].update_skipped and got[22].update_skipped and not got[23].update_skipped
    if not debug:
        assert_no_debug_lines(ukf)
        return
    lines = wait_for_log(ukf, 'DEBUG', LOGGER, 'filter reset at sample 24')
    gated = [line for line in lines if 'sample 21: pressures (900000, 450000) Pa' in line]
    assert len(gated) == 1 and 'rejected by the NIS gate: NIS' in gated[0], lines
    assert '> nis_gate 13.8' in gated[0], gated
    invalid = [line for line in lines if 'sample 22: pressures (5e+06, 450000) Pa' in line]
    assert len(invalid) == 1 and 'rejected as invalid' in invalid[0], lines
    reset = [line for line in lines if 'filter reset at sample 24' in line]
    assert len(reset) == 1 and 'time went backwards by 50.023 s' in reset[0], lines
    assert ukf.alive()
