"""ukf_node's model extensions and measured supply pressure as a real process on an isolated
domain (docs/model_extensions.md): an extensions.yaml written by save_extensions reaches the
filter (its estimates are those of PamUkf with the same extensions, number for number), the
start log and /diagnostics name it; a bad file is one line and exit code 2; with
use_supply_pressure the latest supply reading is P_tank, a stale one is counted."""

import math
import subprocess
import time
from dataclasses import replace

from diagnostic_msgs.msg import DiagnosticArray
from sensor_msgs.msg import FluidPressure

from pam_common.diagnostics import status_values
from pam_common.stamps import ns_stamp, stamp_ns
from pam_common.testing import diagnostic_statuses, executable, wait_until
from pam_estimator.pam_ukf import PamUkf
from pam_interfaces.msg import JointEstimate, Pressures
from pam_model.effects import Effects
from pam_model.model import PamModel
from pam_model.model_extensions import NO_EXTENSIONS, load_extensions, save_extensions
from test_ukf_node_topics import answered_then_reset

EXTENSIONS = Effects(valve_time_constant=0.005, dead_volume=6.0e-6, hysteresis_band=2.0,
                     sensor_offset=(2000.0, -3000.0), sensor_gain_error=(0.005, -0.005))
X0 = (0.0, 0.0, 4.5e5, 4.5e5)
START_S = 100.0
SAMPLES = 60


def readings(k: int) -> tuple[float, float]:
    """Pressures (Pa abs) of sample k: an antagonistic swing the filter has to follow."""
    swing = 0.6e5 * math.sin(0.2 * k)
    return 4.5e5 + swing, 4.5e5 - swing


def start(node_process, probe, *args):
    ukf = node_process('ukf_node', 'pam_estimator', '-p', 'joint_states_rate:=0.0', *args)
    estimates = probe.subscribe(JointEstimate, '/pam/estimate', depth=1000)
    diagnostics = probe.subscribe(DiagnosticArray, '/diagnostics', depth=100)
    pub = probe.publisher(Pressures, '/pam/pressures')
    ukf.wait_for(lambda: pub.get_subscription_count() > 0, 60.0, 'ukf_node subscribed')
    return ukf, estimates, diagnostics, pub


def warm_up(probe, estimates, pub, stamp_s: float) -> None:
    """ukf_node answered a sample (stamps from stamp_s s, no counter), then reset: see
    test_ukf_node_topics.answered_then_reset."""
    answered_then_reset(probe, estimates, lambda k: feed(pub, 0, stamp_s + k * 1e-4))


def feed(pub, k: int, stamp_s: float) -> None:
    msg = Pressures(sample=k)
    msg.p1, msg.p2 = readings(k)
    msg.header.stamp = ns_stamp(round(stamp_s * 1e9))
    pub.publish(msg)
    time.sleep(0.002)


def ukf_values(diagnostics) -> dict:
    statuses = diagnostic_statuses(diagnostics, 'ukf_node')
    return status_values(statuses[-1]) if statuses else {}


def offline(extensions, supply=None) -> list:
    """The same samples through PamUkf: [(angle, torque)] per sample (u = initial_command)."""
    ukf = PamUkf(model=PamModel(), x0=X0, extensions=extensions)
    out = []
    for k in range(1, SAMPLES + 1):
        o = ukf.step(readings(k), (5.5, 5.5), supply)
        out.append((float(o.x[0]), float(o.torque)))
    return out


def test_an_extensions_file_reaches_the_filter(node_process, probe, tmp_path):
    path = tmp_path / 'extensions.yaml'
    save_extensions(EXTENSIONS, path)
    assert load_extensions(path) == EXTENSIONS
    ukf, estimates, diagnostics, pub = start(node_process, probe,
                                             '-p', f'model_extensions:={path}')
    warm_up(probe, estimates, pub, 1.0)
    for k in range(1, SAMPLES + 1):
        feed(pub, k, START_S + k * 1e-3)
    ukf.wait_for(lambda: len(estimates) >= SAMPLES, 30.0, f'{SAMPLES} estimates')
    got = [(m.angle, m.torque) for m in estimates.messages()]
    assert got == offline(EXTENSIONS)
    assert got != offline(replace(EXTENSIONS, hysteresis_band=0.0))
    described = EXTENSIONS.describe()
    assert f'model extensions: {described} ({path})' in ukf.stderr + ukf.stdout
    ukf.wait_for(lambda: ukf_values(diagnostics).get('model extensions') == described, 10.0,
                 f'/diagnostics naming the extensions; last: {ukf_values(diagnostics)}')


def test_a_bad_extensions_file_is_one_line_and_exit_2(tmp_path):
    node = executable('ukf_node', 'pam_estimator')
    state = tmp_path / 'state.yaml'
    state.write_text('extensions:\n  supply_droop: 10000.0\n')
    typo = tmp_path / 'typo.yaml'
    typo.write_text('extensions:\n  dead_volum: 1.0e-6\n')
    for path, message in [(tmp_path / 'none.yaml', 'cannot read'),
                          (state, 'is a state of the rig'), (typo, "unknown key 'dead_volum'")]:
        result = subprocess.run([node, '--ros-args', '-p', f'model_extensions:={path}'],
                                capture_output=True, text=True, timeout=60)
        assert result.returncode == 2, result.stderr
        lines = [line for line in result.stderr.splitlines() if line.strip()]
        assert len(lines) == 1 and "'model_extensions'" in lines[0] and message in lines[0], \
            result.stderr
        assert 'Traceback' not in result.stderr


def test_the_measured_supply_pressure_is_p_tank(node_process, probe):
    supply = 4.0e5       # Pa abs, 2 bar under the model's P_tank
    ukf, estimates, diagnostics, pub = start(node_process, probe,
                                             '-p', 'use_supply_pressure:=true')
    supply_pub = probe.publisher(FluidPressure, '/pam/supply_pressure')
    assert wait_until(lambda: supply_pub.get_subscription_count() > 0, 30.0)

    def publish_supply(stamp_s):
        msg = FluidPressure(fluid_pressure=supply)
        msg.header.stamp = ns_stamp(round(stamp_s * 1e9))
        supply_pub.publish(msg)

    publish_supply(START_S)
    time.sleep(0.5)                 # held before the first sample
    warm_up(probe, estimates, pub, START_S)    # with the supply reading: none falls back
    for k in range(1, SAMPLES + 1):
        feed(pub, k, START_S + k * 1e-3)
        publish_supply(START_S + k * 1e-3)
    ukf.wait_for(lambda: len(estimates) >= SAMPLES, 30.0, f'{SAMPLES} estimates')
    got = [(m.angle, m.torque) for m in estimates.messages()]
    assert got == offline(NO_EXTENSIONS, supply)
    assert got != offline(NO_EXTENSIONS)
    feed(pub, SAMPLES + 1, START_S + 1.0)             # 0.94 s after the last supply reading
    ukf.wait_for(lambda: len(estimates) >= SAMPLES + 1, 30.0, 'the stale sample')
    ukf.wait_for(lambda: ukf_values(diagnostics).get(
        'samples with the nominal P_tank (supply stale or not finite)', '0') not in ('0', ''),
        10.0, f'the stale supply counted; last: {ukf_values(diagnostics)}')
    ukf.wait_for(lambda: 'nominal P_tank used' in ukf.stderr + ukf.stdout, 10.0, 'the WARN')
    assert ukf.alive()
    assert stamp_ns(estimates.messages()[-1].header.stamp) == round((START_S + 1.0) * 1e9)
