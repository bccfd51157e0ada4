"""driver_node against the reference board's firmware on simavr (pam_driver/firmware): the same
processes and pty as with pam-emulator, the board's own code behind the pty. The handshake and
the 1 kHz stream; the board's safety as the driver sees it (communication-loss vent, unplug and
replug, the AVR watchdog resetting a hung firmware, e-stop input, pressure and command limits,
a board of another major protocol version); and the sensor-less closed loop (driver_node +
ukf_node + pi_node) through the emulated board against the same loop through pam-emulator, same
plant and seed. Run by `make firmware-test` (PAM_FIRMWARE_TEST=1); the figures of the closed-loop
run (CPU cycles per tick, UART use, COMMAND -> DAC delay, the loops' errors) are written to
pam_driver/firmware/build/figures.json for `make firmware-test` to print."""

from __future__ import annotations

import importlib
import json
import os
import signal
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from std_srvs.srv import Trigger

from pam_bringup.stack import default_params_file
from pam_common.qos import RECORD_DEPTH
from pam_common.stamps import stamp_ns
from pam_common.testing import STOP_TIMEOUT, DriverRigProbe
from pam_interfaces.msg import (
    JointEstimate,
    JointMeasurement,
    Pressures,
    Reference,
    ValveCommand,
)

# the board's tools are files of the repository (pam_driver/firmware/tools), not a package
FIRMWARE = Path(__file__).resolve().parents[2] / 'pam_driver' / 'firmware'
sys.path.insert(0, str(FIRMWARE))
bt = importlib.import_module('tools.board_tool')
_sim = importlib.import_module('tools.sim')
BUILD, CALIBRATION, SimBoard, build = _sim.BUILD, _sim.CALIBRATION, _sim.SimBoard, _sim.build

from pam_driver.calibration import load  # noqa: E402

pytestmark = pytest.mark.skipif(not os.environ.get('PAM_FIRMWARE_TEST'),
                                reason='run by `make firmware-test` (PAM_FIRMWARE_TEST=1)')
STARTUP = 45.0
CAL = load(str(CALIBRATION))
FIGURES = BUILD / 'figures.json'


@pytest.fixture(scope='module', autouse=True)
def firmware():
    build('all', 'harness')


def image(**options) -> bytes:
    return bt.BoardCalibration(**options).to_bytes() + b'\xff' * (4096 - 36)


def codes(*volts) -> list:
    return [CAL.dac_counts(v) for v in volts]


class BoardRig(DriverRigProbe):
    """pam-board-sim (firmware + plant) and driver_node on its pty, with the probe's topics."""

    def __init__(self, node_process, probe, tmp_path, plant_args=(), eeprom=None,
                 driver_params=(), elf=None, streams=True):
        self.probe = probe
        kwargs = {'elf': elf} if elf else {}
        self.board = SimBoard(tmp_path, plant_args, eeprom=eeprom, **kwargs)
        self.pressures = probe.subscribe(Pressures, '/pam/pressures', depth=2000)
        self.joint = probe.subscribe(JointMeasurement, '/pam/joint_measured', depth=100)
        self.diagnostics = probe.subscribe(DiagnosticArray, '/diagnostics', depth=10)
        self.commands = probe.publisher(ValveCommand, '/pam/valve_command')
        params = []
        for p in (f'port:={self.board.link}', f'calibration_file:={CALIBRATION}',
                  'baud:=1000000', *driver_params):
            params += ['-p', p]
        self.driver = node_process('driver_node', 'pam_driver', *params)
        if streams:
            self.driver.wait_for(lambda: len(self.pressures) > 0, STARTUP, 'the first pressures')
            self.driver.wait_for(lambda: self.commands.get_subscription_count() > 0, 10.0,
                                 'valve_command matched')
        else:
            self.driver.wait_for(lambda: bool(self.values()), STARTUP, 'driver diagnostics')

    def arm(self) -> Trigger.Response:
        """driver_node's ~/arm; its reply."""
        client = self.probe.client(Trigger, '/pam/driver_node/arm')
        assert client.wait_for_service(timeout_sec=10.0)
        future = client.call_async(Trigger.Request())
        end = time.monotonic() + 10.0
        while not future.done() and time.monotonic() < end:
            time.sleep(0.01)
        self.probe.node.destroy_client(client)
        assert future.done(), '~/arm did not answer in 10 s'
        return future.result()

    def stop(self) -> None:
        self.driver.stop()
        self.board.stop()


@pytest.fixture
def board_rig(node_process, probe, tmp_path):
    rigs = []

    def start(**kwargs):
        rigs.append(BoardRig(node_process, probe, tmp_path, **kwargs))
        return rigs[-1]
    yield start
    for r in rigs:
        r.stop()


def test_driver_streams_and_commands_through_the_board(board_rig):
    r = board_rig(driver_params=('watchdog_timeout:=0.3',))
    values = r.wait_values(lambda v: v.get('connected') == 'true', 10.0, 'connected')
    assert values['device protocol'] == '1.2', values
    start = time.monotonic() + 0.2
    time.sleep(1.4)
    window = [m for t, m in r.pressures.items() if start <= t < start + 1.0]
    stamps = [stamp_ns(m.header.stamp) * 1e-9 for m in window]
    rate = (len(stamps) - 1) / (stamps[-1] - stamps[0])
    # every sample of the board's counter arrived; the rate is the simulated board's, which
    # falls below 1 kHz of wall time when this machine cannot keep simavr in real time (771 Hz
    # under load once): the bound says the board streams per sample (1 kHz, not a fraction of
    # it); how close to real time simavr runs here is the firmware benchmark's figure
    counters = [m.sample for m in window]
    assert counters == list(range(counters[0], counters[0] + len(counters))), 'a gap'
    assert 500 <= rate <= 1050, (rate, len(window), r.board.status())
    assert all(95e3 < m.p1 < 500e3 for m in window), window[-1]     # venting from 450 kPa
    r.send(7.0, 3.0, duration=0.5)
    s = r.board.wait_status(lambda s: s['dac_codes'] == codes(7.0, 3.0), 2.0, 'the command')
    assert s['dac_volts'] == pytest.approx([7.0, 3.0], abs=CAL.valve_volts(1) + 1e-6)
    # the joint swings: the encoder through the board is the plant's
    r.send(7.0, 3.0, duration=2.0)
    angle = r.joint.messages()[-1].angle
    assert abs(angle - CAL.angle(r.board.status()['encoder'])) < 0.01 and abs(angle) > 0.02, \
        (angle, r.board.status())


def test_board_safety_reaches_the_driver(board_rig):
    """Communication loss (the driver stalled), unplug and replug, the AVR watchdog resetting a
    hung firmware (latched until ARM), the e-stop input: the board vents by itself, the driver
    reports it."""
    safe = codes(1.0, 1.0)
    r = board_rig(eeprom=image(safe_code=tuple(safe), cmd_max=(4095, CAL.dac_counts(8.0))),
                  driver_params=('watchdog_timeout:=0.0', 'stream_timeout:=1.0'))
    r.send(3.0, 9.0, duration=0.3)
    r.board.wait_status(lambda s: s['dac_codes'] == codes(3.0, 8.0), 2.0,
                        'the command, u2 clipped to the board limit 8 V')
    # the driver stalls 0.5 s (SIGSTOP): the board vents after 250 ms on its own
    r.driver.proc.send_signal(signal.SIGSTOP)
    try:
        r.board.wait_status(lambda s: s['dac_codes'] == safe, 1.0, 'the vent')
    finally:
        r.driver.proc.send_signal(signal.SIGCONT)
    r.send(3.0, 5.0, duration=0.3)
    r.wait_values(lambda v: int(v['board vents']) >= 1, 5.0, 'the vent on /diagnostics')
    r.board.wait_status(lambda s: s['dac_codes'] == codes(3.0, 5.0), 2.0, 'commanding again')
    # unplug for 0.5 s: the board vents, the driver loses it, reconnects to the new pty
    r.board.command('unplug 500')
    r.board.wait_status(lambda s: s['dac_codes'] == safe, 2.0, 'the vent when unplugged')
    r.driver.wait_for(lambda: 'device lost' in r.driver.stderr, 5.0, "'device lost'")
    r.wait_values(lambda v: v['connected'] == 'true' and int(v.get('connects', '2')) >= 2
                  if 'connects' in v else v['connected'] == 'true', 10.0, 'reconnected')
    n = len(r.pressures)
    r.driver.wait_for(lambda: len(r.pressures) > n + 500, 5.0, 'samples after the replug')
    r.arm()
    r.send(3.0, 5.0, duration=0.3)
    r.board.wait_status(lambda s: s['dac_codes'] == codes(3.0, 5.0), 3.0, 'commanding again')
    # a hung firmware (a dead SPI bus): the AVR watchdog resets it into its safe output, the
    # driver reconnects; the reset is a latched fault: the board stays vented, the driver says
    # so, and its ~/arm sends ARM with its own re-arm (the board announced 1.2)
    r.board.command('spi_stall 100')
    r.board.wait_status(lambda s: s['resets'] >= 1 and s['dac_codes'] == safe, 3.0,
                        'the watchdog reset')
    since = time.monotonic()
    r.driver.wait_for(lambda: r.driver.stderr.count('device lost') >= 2, 5.0,
                      "'device lost' at the reset")
    values = r.wait_values(lambda v: v['connected'] == 'true' and v['board vented now'] == 'true',
                           10.0, 'the latched vent on /diagnostics')
    assert r.board.status()['dac_codes'] == safe, 'latched until ARM'
    assert r.status(since).level >= DiagnosticStatus.WARN, values
    reply = r.arm()
    assert reply.success and 'ARM sent to the board' in reply.message, reply
    r.send(3.0, 5.0, duration=0.3)
    r.board.wait_status(lambda s: s['dac_codes'] == codes(3.0, 5.0), 3.0,
                        'commanding again after ~/arm cleared the reset latch')
    r.stop()
    # the e-stop input and the re-arm by board_tool (its ARM, without a driver)
    board = r.board = SimBoard(r.board.status_file.parent, eeprom=None, name='board')
    client = bt.Board(board.link)
    client.hello()
    client.send(bt.ARM)
    client.send(0x02, bytes.fromhex('d007d007'))           # COMMAND 2000 2000
    board.wait_status(lambda s: s['dac_codes'] == [2000, 2000], 2.0, 'armed after the reset')
    board.command('estop 1')
    board.wait_status(lambda s: s['dac_codes'] == safe, 1.0, 'the e-stop vent')
    client.close()


def test_estop_and_overpressure_reach_the_driver(board_rig):
    limit = CAL.pressure_counts(0, 350e3 + CAL.atmosphere)
    safe = codes(0.0, 0.0)
    r = board_rig(eeprom=image(safe_code=tuple(safe), p_max_counts=limit),
                  driver_params=('watchdog_timeout:=0.0', 'stream_timeout:=1.0'))
    r.send(5.0, 5.0, duration=0.3)
    r.board.wait_status(lambda s: s['dac_codes'] == codes(5.0, 5.0), 2.0, 'the command')
    since = time.monotonic()
    r.board.command('estop 1')
    r.board.wait_status(lambda s: s['dac_codes'] == safe, 1.0, 'the e-stop vent')
    r.send(5.0, 5.0, duration=0.5)
    r.driver.wait_for(lambda: (s := r.status(since)) is not None
                      and s.level == DiagnosticStatus.ERROR and 'board vented' in s.message,
                      5.0, "an ERROR 'board vented'")
    r.board.command('estop 0')
    r.send(5.0, 5.0, duration=0.3)
    assert r.board.status()['dac_codes'] == safe, 'latched until ARM'
    # the driver stayed armed all along (the board vented, not the driver): its commands were
    # ignored by the latched board; ~/arm sends ARM and they apply again
    assert r.values()['armed'] == 'true', r.values()
    reply = r.arm()
    assert reply.success and 'ARM sent to the board' in reply.message, reply
    r.send(5.0, 5.0, duration=0.3)
    r.board.wait_status(lambda s: s['dac_codes'] == codes(5.0, 5.0), 3.0,
                        'commanding again after ~/arm')
    r.wait_values(lambda v: v['board ARMs sent'] == '1' and v['board vented now'] == 'false',
                  5.0, 'the ARM and the end of the vent on /diagnostics')
    r.stop()
    # over-pressure: the board's own limit (350 kPa gauge) trips while the driver commands
    r = board_rig(eeprom=image(safe_code=tuple(safe), p_max_counts=limit),
                  driver_params=('watchdog_timeout:=0.0', 'stream_timeout:=1.0',
                                 'pressure_limits:=[50000.0, 1500000.0]'))
    since = time.monotonic()
    r.send(10.0, 0.0, duration=3.0)
    r.board.wait_status(lambda s: s['dac_codes'] == safe, 3.0, 'the over-pressure vent')
    values = r.wait_values(lambda v: v['board vented now'] == 'true', 5.0, 'the vent reported')
    assert max(m.p1 for m in r.pressures.messages()) > 350e3 + CAL.atmosphere - 10e3, values


def test_board_of_another_major_version_is_refused(board_rig):
    r = board_rig(elf=BUILD / 'pam_board_major2.elf', streams=False)
    values = r.wait_values(lambda v: int(v['handshake failures']) >= 2, 10.0,
                           'a second refused handshake')
    assert 'protocol version mismatch' in values['device refused'], values
    assert 'speaks 2.2' in values['device refused'], values
    assert len(r.pressures) == 0 and values['connected'] == 'false', values


# ---- a lab's path: pam-bringup --rig driver on the board (firmware/README.md) -----------------
def lab_params(tmp_path, port: str) -> Path:
    """What firmware/README.md tells a lab to write: a copy of pam-bringup's params file with
    driver_node's port and calibration set to the board's, and the 0.5 s command watchdog it
    advises for the emulated board on a shared machine (its other settings the file's)."""
    data = yaml.safe_load(default_params_file().read_text())
    data['/pam/driver_node']['ros__parameters'].update(
        port=port, calibration_file=str(CALIBRATION), watchdog_timeout=0.5)
    path = tmp_path / 'my_board.yaml'
    path.write_text(yaml.safe_dump(data))
    return path


def test_pam_bringup_rig_driver_on_the_board(node_process, probe, ros_domain, tmp_path):
    """`pam-bringup --rig driver --params-file my_board.yaml` on a fresh board (empty EEPROM:
    the firmware's defaults) as the firmware README has a lab run it: the whole stack (composed,
    the default) connects, pam-bringup arms driver_node once pi_node's commands flow (the board
    announced 1.2: ARM sent with it), the estimate flows and pi_node's commands reach the board's
    DAC; Ctrl-C stops it cleanly."""
    board = SimBoard(tmp_path, ('--mismatch', 'mild'), name='lab')
    try:
        estimates = probe.subscribe(JointEstimate, '/pam/estimate', depth=100)
        applied = probe.subscribe(ValveCommand, '/pam/driver_node/applied_command', depth=100)
        run = node_process('pam-bringup', 'pam_bringup', '--domain-id', str(ros_domain),
                           '--rig', 'driver', '--params-file',
                           str(lab_params(tmp_path, board.link)), raw=True)
        run.wait_for(lambda: '/pam/driver_node/arm: armed' in run.stdout, STARTUP + 30.0,
                     'pam-bringup arming driver_node')
        arming = next(line for line in run.stdout.splitlines() if 'driver_node/arm: armed' in line)
        assert 'ARM sent to the board' in arming, arming
        assert f'connected to {board.link}: protocol 1.2' in run.stdout, run.stdout[-3000:]
        run.wait_for(lambda: len(estimates) >= 100, 10.0, '/pam/estimate flowing')
        run.wait_for(lambda: any((m.u1, m.u2) != (0.0, 0.0) for m in applied.messages()), 10.0,
                     "pi_node's commands applied by driver_node")
        start = board.status()
        status = board.wait_status(
            lambda s: s['command_frames'] >= start['command_frames'] + 500
            and s['dac_codes'] != [0, 0], 10.0, "pi_node's commands on the board's DAC")
        assert status['resets'] == 0, status
        assert run.alive() and 'died' not in run.stdout, run.stdout[-3000:]
        run.proc.send_signal(signal.SIGINT)
        code = run.wait_exit(timeout=STOP_TIMEOUT + 10.0)
        assert code == 0, run.stdout[-3000:] + run.stderr[-2000:]
        assert 'all nodes stopped cleanly' in run.stdout, run.stdout[-3000:]
    finally:
        board.stop()


# ---- the closed loop through the board against the same loop through pam-emulator ------------
PRE, HOLD, LAST, LEVEL = 2.0, 6.0, 1.0, 0.25   # s at 0, s at LEVEL (rad), steady-state window
NOISE_STD = 2000.0                             # Pa, the 'mild' scenario's
TOLERANCE = 0.012                              # rad: |error(board) - error(emulator)|
# watchdog 0.5 s and stream timeout 3 s: this test is about tracking (the watchdog and the
# device-lost detection are tested above) and the whole loop (six processes and the simulated
# board) shares this 2-core machine with whatever else runs
LOOP_PARAMS = ('safe_output:=[5.5, 5.5]', 'watchdog_timeout:=0.5', 'stream_timeout:=3.0')
PLANT = ('--mismatch', 'mild', '--noise-std', str(NOISE_STD), '--initial-command', '5.5', '5.5',
         '--seed', '0')


def wait_samples(driver, truth, since: int | None, duration: float) -> int:
    """The index of the joint_measured message `duration` s of 1 kHz samples after message
    `since` (None: the newest), once it arrived."""
    since = len(truth) if since is None else since
    target = since + round(duration * 1000)
    driver.wait_for(lambda: len(truth) >= target, 10 * duration + 30.0,
                    f'{duration} s of samples')
    return target


def run_loop(node_process, probe, tmp_path, rig: str) -> dict:
    """driver_node on the board (or pam-emulator), ukf_node, pi_node (angle): 0 then LEVEL."""
    truth = probe.subscribe(JointMeasurement, '/pam/joint_measured', depth=RECORD_DEPTH)
    reference = probe.publisher(Reference, '/pam/reference')
    board = None
    if rig == 'board':
        board = SimBoard(tmp_path, PLANT, eeprom=image(safe_code=tuple(codes(5.5, 5.5))),
                         name='loop')
        port, calibration = board.link, str(CALIBRATION)
        processes = []
    else:
        port, calibration = str(tmp_path / 'emulator_tty'), 'default'
        emulator = node_process('pam-emulator', 'pam_driver', '--link', port, *PLANT, raw=True)
        emulator.wait_for(lambda: os.path.islink(port), STARTUP, 'the emulator pty link')
        processes = [emulator]
    params = []
    for p in (f'port:={port}', f'calibration_file:={calibration}', *LOOP_PARAMS):
        params += ['-p', p]
    driver = node_process('driver_node', 'pam_driver', *params)
    ukf = node_process('ukf_node', 'pam_estimator')
    pi = node_process('pi_node', 'pam_controller', '-p', 'mode:=angle',
                      '-p', 'initial_reference:=0.0')
    processes += [driver, ukf, pi]
    try:
        estimates = probe.subscribe(JointEstimate, '/pam/estimate', depth=10)
        commands = probe.subscribe(ValveCommand, '/pam/valve_command', depth=10)
        for process, collector, what in ((driver, truth, 'the first joint_measured'),
                                         (ukf, estimates, 'the first estimate'),
                                         (pi, commands, 'the first valve_command')):
            process.wait_for(lambda c=collector: len(c) > 0, STARTUP, what)
        probe.unsubscribe(estimates)
        probe.unsubscribe(commands)
        pi.wait_for(lambda: reference.get_subscription_count() > 0, STARTUP, 'pi_node')
        client = probe.client(Trigger, '/pam/driver_node/arm')
        assert client.wait_for_service(timeout_sec=10.0)
        future = client.call_async(Trigger.Request())
        end = time.monotonic() + 10.0
        while not future.done() and time.monotonic() < end:
            time.sleep(0.01)
        probe.node.destroy_client(client)
        # the phases are counted in the rig's samples, not in wall time: the simulated board
        # slows down when this machine is overloaded (its lag is dropped, never caught up), and
        # the loop lives in the board's time (one plant step, UKF step and PI step per sample)
        reference.publish(Reference(mode=Reference.ANGLE, value=0.0))
        first = wait_samples(driver, truth, None, PRE)
        reference.publish(Reference(mode=Reference.ANGLE, value=LEVEL))
        step = wait_samples(driver, truth, first, HOLD)
        time.sleep(0.2)
        status = board.status() if board else None
        for process in processes:
            assert process.alive(), f'{process.name} died:\n{process.stderr[-2000:]}'
        disturbed = [line for line in driver.stderr.splitlines() if 'device lost' in line]
        if os.environ.get('PAM_FIRMWARE_DEBUG'):
            print(rig, 'driver log:', driver.stderr[-3000:], board.output[-2000:] if board else '')
    finally:
        for process in reversed(processes):
            process.stop()
        if board:
            board.stop()
        probe.unsubscribe(truth)
        probe.node.destroy_publisher(reference)
    window = np.array([m.angle for m in truth.messages()[step - round(LAST * 1000):step]])
    return {'error': float(np.mean(LEVEL - window)), 'std': float(np.std(window)),
            'samples': len(window), 'board': status, 'disturbed': disturbed}


def test_closed_loop_through_the_board_as_through_pam_emulator(node_process, probe, tmp_path):
    """Same plant ('mild' mismatch, 2 kPa noise, seed 0, valves at 5.5 V until the first
    command), same estimator and controller; the board's side is our firmware on simavr in one
    run and pam-emulator in the other. The steady-state errors must agree within TOLERANCE.

    Measured on this 2-core machine, shared with other jobs (load 4-9): board -0.0127 / -0.0144
    rad, pam-emulator -0.0179 .. -0.0233 rad over five runs (pam_controller's
    test_closed_loop_driver: -0.0183 .. -0.0195); differences +0.0065 and +0.0089 rad. The
    board's loop settles a little nearer the reference: its ADC reads the plant one millisecond
    later (the harness's pipelining), its ADC and DAC transfers differ by the 4095/4096 the
    calibration absorbs, and the emulated board slows down when the machine is overloaded (the
    loop runs in the board's samples, its wall-clock pacing does not). TOLERANCE 0.012 rad (0.7
    deg, 5 % of the step) is about 1.4 x the largest difference seen: wider than the 0.005 rad
    between driver_node and sim_node, as two real-time loops on a loaded machine differ by
    +-0.003 rad from run to run already. A wrong sign, gain or transfer on the board's side moves
    the loop by far more (the driver test: 1 % of gain on P1 is +0.023 N m in torque mode)."""
    results = {rig: run_loop(node_process, probe, tmp_path, rig) for rig in ('board', 'emulator')}
    board, emulator = results['board'], results['emulator']
    s = board['board']
    figures = {
        'closed_loop': {'level_rad': LEVEL, 'window_s': LAST, 'tolerance_rad': TOLERANCE,
                        'error_board_rad': board['error'], 'error_emulator_rad': emulator['error'],
                        'difference_rad': board['error'] - emulator['error'],
                        'samples_in_window': {k: r['samples'] for k, r in results.items()}},
        'board': s,
    }
    FIGURES.write_text(json.dumps(figures, indent=1))
    summary = (f"steady-state error at {LEVEL} rad: board {board['error']:+.4f} rad, pam-emulator "
               f"{emulator['error']:+.4f} rad, difference {board['error'] - emulator['error']:+.4f}"
               f" (tolerance {TOLERANCE}); disturbances {board['disturbed']} "
               f"{emulator['disturbed']}")
    print(summary)
    assert board['samples'] >= 0.8 * LAST * 1000 and emulator['samples'] >= 0.8 * LAST * 1000, \
        summary
    assert abs(board['error']) < 0.05, summary
    assert abs(board['error'] - emulator['error']) <= TOLERANCE, summary
    # the board's CPU during the loop: the mean within half a tick. The worst tick period is
    # printed by `make firmware-test` against its 50 % target, not asserted: a burst of host
    # frames after a stall of driver_node arrives at the line rate (a byte every 11 us), faster
    # than the firmware handles a COMMAND (firmware/README.md), and takes a whole tick
    assert s['tick_cycles_mean'] <= 0.5 * s['cycles_per_ms'], s
    assert s['command_delays'] > 1000 and s['command_delay_mean_us'] < 500, s
