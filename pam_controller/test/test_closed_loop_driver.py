"""The sensor-less closed loop through the hardware driver reaches the same tracking result as
with sim_node.

The same live loop runs twice per mode, with two rigs: (a) pam-emulator (the DAQ board on a pty)
+ driver_node, (b) sim_node (realtime, 1 kHz); each time with a fresh ukf_node and pi_node, all as
real processes in real time. Both rigs simulate the 'mild' mismatched plant with 2 kPa pressure
noise; the estimator and the controller run with their defaults (nominal model, default gains).
A probe publishes the reference and reads the TRUE angle / torque from /pam/joint_measured (the
emulator's encoder and torque meter through the driver's calibration, or sim_node's truth).

- angle: free joint, reference 0 then +0.25 rad (pi_node mode angle).
- torque: locked joint (pam-emulator --locked, sim_node / ukf_node joint_mode:=locked, pi_node
  mode:=torque), reference 0 then +1.0 N m.

The steady-state error (mean of reference - truth over the last LAST s of the step) of the driver
loop must agree with that of the sim_node loop within the mode's tolerance. The batch simulator
(pam_controller.closed_loop.simulate_closed_loop: the same plant, sensor noise, UKF, gains and
reference in one compiled loop, i.e. sim_node + ukf_node + pi_node in lockstep) is a third
reference: both live loops must also agree with it within the same tolerance.

Same start: both rigs hold the valves at 5.5 V until the controller's first command (sim_node's
default initial_command; pam-emulator --initial-command 5.5 5.5 and driver_node safe_output 5.5 V
here, instead of a board powering up vented and the driver's default 0 V safe output), so both
plants sit at the 5.5 V equilibrium (450 kPa) when the loop starts. The muscles refill slowly
(about 35 kPa still missing 5 s after a 1 s vent), so with the vented start the driver loop met
the step at 300-350 kPa instead of 450 kPa: the joint stuck 0.5 s, then overshot, and the
steady-state errors differed by 0.002-0.009 rad: a difference of start-up, not of the loop.

Why a tolerance and not equality: the rigs still differ in ways that are not the loop's. The
emulator quantises the pressures with the 12-bit ADC of the driver calibration (305 Pa a count,
sim_node's scenario 244 Pa) and the torque meter to 2.4 mN m a count, draws other noise samples,
and adds a pty hop (sample -> driver -> DDS; command -> DDS -> driver -> pty); both run in real
time on a shared machine (jitter, the odd late sample, an estimate arriving after the next
sample), and the free joint's static friction makes where it finally sticks depend a little on
the path. The residual error itself is the sensor-less loop's UKF bias on the mismatched plant
(the force-intercept mismatch, which the pressures do not reveal), a property of plant and
estimator: all three loops show it, about -0.019 rad (the joint settles beyond the reference) and
-0.128 N m.

Measured (this test, 2-core machine shared with other jobs, load average 4.5-6; 3 runs, then 4
more while developing with the same loop):
  angle, steady-state error: driver -0.0195 .. -0.0183 rad, sim_node -0.0193 .. -0.0192 rad,
    batch -0.0193 rad; |driver - sim_node| 0.0000 / 0.0002 / 0.0009 rad (4 more: <= 0.0007)
  torque: driver -0.1282 .. -0.1270 N m, sim_node -0.1286 .. -0.1277 N m, batch -0.1275 N m;
    |driver - sim_node| 0.0005 / 0.0005 / 0.0009 N m (4 more: <= 0.0012)
Tolerance: angle 0.005 rad (0.29 deg, 2 % of the step), about 5x the largest difference seen;
torque 0.01 N m (1 % of the step), about 8x. Breaking the driver side on purpose fails the test:
a 1 % gain error on p1 in the driver's calibration (pascal_per_volt 250000 -> 252500) moves the
torque loop by +0.023 N m, a 3 % one the angle loop by +0.0067 rad; an encoder sign of -1 gives
an angle error of +0.52 rad, half pi_node's kp_angle in the driver loop leaves the joint at -0.05
rad before the step (both caught by the bounds on each loop). The transient (rise time to 90 %,
peak) is printed, not asserted: it is what real-time jitter changes most (peaks of the two loops
1.20 vs 1.29 N m in one run, within 0.035 N m in the others).

Robustness: driver_node runs with a 0.5 s command watchdog (not 50 ms) and a 1 s stream timeout
so that a loaded machine's stall does not latch it safe mid-run; it is armed through ~/arm before
the step. A run during which the driver reports a safe output or a lost device, or pi_node loses
its feedback (a stall of the estimator > 0.1 s sends the valves to safe_command), or with fewer
than MIN_RATE samples a second in the steady-state window, is redone once (same processes, twice
PRE at 0 first), and fails the test the second time.
"""

from __future__ import annotations

import os
import signal
import subprocess
import time

import numpy as np
import pytest
from std_srvs.srv import Trigger

from pam_common.testing import STOP_TIMEOUT, stamp_ns, wait_until
from pam_interfaces.msg import JointEstimate, JointMeasurement, Reference, ValveCommand

STARTUP = 45.0            # s, a fresh process on a loaded 2-core machine
PRE = 2.0                 # s at reference 0 once the loop runs (and the driver is armed)
HOLD = 6.0                # s at the step's level
LAST = 1.0                # s, steady-state window at the end of HOLD
NOISE_STD = 2000.0        # Pa, the 'mild' scenario's sensor noise (sim_node's with scenario:=mild)
MIN_RATE = 800.0          # Hz of /pam/joint_measured in the steady-state window
INITIAL_COMMAND = ('5.5', '5.5')   # V: valves before the controller's first command, as sim_node
ATTEMPTS = 2              # a disturbed run (safe output, device lost, no feedback, rate): redone

# per mode: the step, the tolerance |error(driver) - error(sim_node)| (see the module docstring),
# the bound on the error of either loop (it did settle near the reference), and the bound on the
# truth before the step (it did start from 0: a loop that sits near the level all along fails)
MODES = {
    'angle': dict(level=0.25, tolerance=0.005, max_error=0.05, max_before=0.05, unit='rad',
                  reference_mode=Reference.ANGLE, field='angle', locked=False),
    'torque': dict(level=1.0, tolerance=0.01, max_error=0.2, max_before=0.25, unit='N m',
                   reference_mode=Reference.TORQUE, field='torque', locked=True),
}
RIGS = ('driver', 'sim_node')

# lines of a node's log that mean the run was disturbed (the loop was opened for a while)
DISTURBANCES = {'driver_node': ('safe output', 'device lost'), 'pi_node': ('no feedback for',)}


def batch_steady_state_error(mode: str) -> float:
    """The same loop on the batch simulator (the lockstep loop of sim_node + ukf_node + pi_node)."""
    from pam_controller.closed_loop import simulate_closed_loop
    from pam_controller.pi_config import PiConfig
    from pam_model.mismatch import load_scenario
    from pam_model.model import PamModel
    from pam_model.parameters import load_parameters

    spec = MODES[mode]
    pi_gains = getattr(PiConfig.default(), mode)
    gains = (pi_gains.kp, pi_gains.ki)   # pi_node's defaults
    scenario = load_scenario('mild')
    t = np.arange(round((PRE + HOLD) * 1000)) * 1e-3
    reference = np.where(t < PRE, 0.0, spec['level'])
    locked = spec['locked']
    run, = simulate_closed_loop(PamModel(params=scenario.apply(load_parameters()), locked=locked),
                                PamModel(locked=locked), reference, [gains],
                                sensor=scenario.sensor, mode=mode, seed=0)
    last = t >= t[-1] - LAST
    return float(np.mean(reference[last] - run.truth[last]))


def start_rig(node_process, tmp_path, rig: str, mode: str) -> list:
    """The rig's processes (pam-emulator + driver_node, or sim_node), ukf_node and pi_node."""
    locked = MODES[mode]['locked']
    joint_mode = 'locked' if locked else 'free'
    if rig == 'driver':
        link = str(tmp_path / 'pam_daq')
        emulator = node_process('pam-emulator', 'pam_driver', '--link', link, '--mismatch',
                                'mild', '--noise-std', str(NOISE_STD), '--initial-command',
                                *INITIAL_COMMAND, *(['--locked'] if locked else []), raw=True)
        emulator.wait_for(lambda: os.path.islink(link), STARTUP, 'the emulator pty link')
        # watchdog 0.5 s and stream timeout 1 s instead of 50 ms / 0.2 s: this test is about
        # tracking (the watchdog and the device-lost detection are tested in pam_driver's
        # test_driver_node.py), and `make test` may run it on a loaded machine where a process
        # stalls for 50 ms
        processes = [emulator, node_process('driver_node', 'pam_driver', '-p', f'port:={link}',
                                            '-p', f'safe_output:=[{", ".join(INITIAL_COMMAND)}]',
                                            '-p', 'watchdog_timeout:=0.5',
                                            '-p', 'stream_timeout:=1.0')]
    else:
        processes = [node_process('sim_node', 'pam_driver', '-p', 'scenario:=mild',
                                  '-p', f'pressure_noise_std:={NOISE_STD}',
                                  '-p', f'joint_mode:={joint_mode}', '-p', 'timing:=realtime')]
    processes.append(node_process('ukf_node', 'pam_estimator', '-p', f'joint_mode:={joint_mode}'))
    processes.append(node_process('pi_node', 'pam_controller', '-p', f'mode:={mode}',
                                  '-p', 'initial_reference:=0.0'))
    return processes


def stop_all(processes: list) -> None:
    """Stop the loop: every node but the rig's first process together, then that one (the driver
    before its emulator); SIGKILL what does not exit within STOP_TIMEOUT."""
    head, rest = processes[0], processes[1:]
    for process in rest:
        if process.alive():
            process.proc.send_signal(signal.SIGINT)
    for process in rest:
        try:
            process.proc.wait(timeout=STOP_TIMEOUT)
        except subprocess.TimeoutExpired:
            process.stop()
    head.stop()


def run_loop(node_process, probe, tmp_path, rig: str, mode: str) -> dict:
    """One live closed loop on `rig`: start it, run the step (once more if disturbed), stop it."""
    spec = MODES[mode]
    started = time.monotonic()
    # fresh subscriptions for each run, stopped at its end
    truth = probe.subscribe(JointMeasurement, '/pam/joint_measured', depth=1000)
    estimates = probe.subscribe(JointEstimate, '/pam/estimate', depth=1000)
    commands = probe.subscribe(ValveCommand, '/pam/valve_command', depth=1000)
    reference = probe.publisher(Reference, '/pam/reference')
    processes = start_rig(node_process, tmp_path, rig, mode)
    rig_node, ukf, pi = processes[-3:]
    for process, collector, what in ((rig_node, truth, 'the first /pam/joint_measured'),
                                     (ukf, estimates, 'the first /pam/estimate'),
                                     (pi, commands, 'the first /pam/valve_command')):
        process.wait_for(lambda c=collector: len(c) > 0, STARTUP, what)
    # only the truth is read from here on: two more 1 kHz topics would load this process (3000
    # messages a second into rclpy) and delay the window's samples
    probe.unsubscribe(estimates)
    probe.unsubscribe(commands)
    pi.wait_for(lambda: reference.get_subscription_count() > 0, 10.0, 'pi_node on /pam/reference')
    watched = [p for p in processes if p.name in DISTURBANCES]
    try:
        for attempt in range(1, ATTEMPTS + 1):
            # a run again: back at 0 for longer first (the joint returning from the level)
            result = run_step(probe, reference, truth, spec, watched, arm=rig == 'driver',
                              pre=PRE * attempt)
            if result['disturbed'] is None:
                break
            print(f'{rig}, {mode}, attempt {attempt}: the loop was disturbed '
                  f'({result["disturbed"]})' + (': again' if attempt < ATTEMPTS else ''))
        for process in processes:
            assert process.alive(), f'{process.name} died:\n{process.stderr[-2000:]}'
    finally:
        stop_all(processes)
        probe.unsubscribe(truth)
        probe.node.destroy_publisher(reference)
    logs = '\n'.join(f'{p.name} log:\n{p.stderr[-3000:]}' for p in watched)
    assert result['disturbed'] is None, (
        f'{rig}, {mode}: the real-time loop was disturbed in {ATTEMPTS} attempts (machine too '
        f'loaded?): {result["disturbed"]}\n{logs}')
    unit = spec['unit']
    # it did track the step (not a loop that happens to sit near the reference)
    assert abs(result['before']) < spec['max_before'], (
        f'{rig}, {mode}: not at 0 before the step: {result["before"]:.3f} {unit}')
    assert abs(result['error']) < spec['max_error'], (
        f'{rig}, {mode}: steady-state error {result["error"]:+.4f} {unit}')
    result['duration'] = time.monotonic() - started
    return result


def run_step(probe, reference, truth, spec: dict, watched: list, arm: bool, pre: float) -> dict:
    """(Arm the driver,) reference 0 for pre s, the level for HOLD s; the truth's statistics."""
    if arm:
        # driver_node starts armed (arm_at_start) but a start-up stall of the loop longer than
        # the command watchdog latches it SAFE; ~/arm (harmless when armed) makes the run
        # independent of how the processes happened to start
        client = probe.client(Trigger, '/pam/driver_node/arm')
        assert client.wait_for_service(timeout_sec=10.0), 'no /pam/driver_node/arm'
        future = client.call_async(Trigger.Request())
        deadline = time.monotonic() + 10.0
        while not future.done() and time.monotonic() < deadline:
            time.sleep(0.01)
        assert future.done() and future.result().success, future.result()
        probe.node.destroy_client(client)
    logs_before = {p: len(p.stderr) for p in watched}

    # windows on the samples' header stamps (the rig's clock = system time at the sample), not on
    # when the probe got them: a loaded test process may receive in bursts
    level, field = spec['level'], spec['field']
    reference.publish(Reference(mode=spec['reference_mode'], value=0.0))
    time.sleep(pre)
    t_step = time.time()
    reference.publish(Reference(mode=spec['reference_mode'], value=level))
    time.sleep(HOLD)
    t_end = time.time()
    # the last samples of the window on their way: wait (bounded) for the first one after it, so
    # that a test process that receives late does not read as a rig that sent too few
    wait_until(lambda: any(stamp_ns(m.header.stamp) * 1e-9 > t_end
                           for m in truth.messages()[-50:]), 5.0)

    disturbed = [f'{p.name}: {line}' for p in watched
                 for line in p.stderr[logs_before[p]:].splitlines()
                 if any(d in line for d in DISTURBANCES[p.name])]
    samples = [(stamp_ns(m.header.stamp) * 1e-9, getattr(m, field)) for m in truth.messages()]
    window = [v for t, v in samples if t_end - LAST <= t <= t_end]
    before = [v for t, v in samples if t_step - 0.5 <= t <= t_step]
    values = np.array(window or [np.nan])
    rate = len(window) / LAST
    if rate < MIN_RATE:
        disturbed.append(f'/pam/joint_measured at {rate:.0f} Hz in the steady-state window')
    start = float(np.mean(before)) if before else np.nan
    # the transient, reported (not asserted: it is what real-time jitter changes most)
    step = [(t - t_step, v) for t, v in samples if t_step <= t <= t_end]
    rise = next((t for t, v in step if v >= start + 0.9 * (level - start)), np.nan)
    return {'disturbed': '; '.join(disturbed) or None, 'rate': rate,
            'error': float(np.mean(level - values)), 'std': float(np.std(values)),
            'before': start, 'rise': rise, 'peak': max((v for _, v in step), default=np.nan)}


@pytest.mark.parametrize('mode', sorted(MODES))
def test_driver_loop_tracks_as_the_sim_node_loop(mode, node_process, probe, tmp_path):
    spec = MODES[mode]
    results = {rig: run_loop(node_process, probe, tmp_path, rig, mode) for rig in RIGS}
    batch = batch_steady_state_error(mode)
    driver, sim = results['driver']['error'], results['sim_node']['error']
    unit, tolerance = spec['unit'], spec['tolerance']
    summary = (f'{mode}: steady-state error over the last {LAST:g} s: driver loop {driver:+.4f} '
               f'{unit}, sim_node loop {sim:+.4f} {unit}, difference {driver - sim:+.4f} {unit} '
               f'(tolerance {tolerance:g}); batch loop {batch:+.4f} {unit}')
    for what, key, form in (('ripple (std)', 'std', '.4f'), ('rise to 90 % (s)', 'rise', '.3f'),
                            (f'peak ({unit})', 'peak', '.4f'), ('rate (Hz)', 'rate', '.0f'),
                            ('run (s)', 'duration', '.1f')):
        summary += f'; {what} ' + ', '.join(f'{rig} {r[key]:{form}}' for rig, r in results.items())
    print(summary)
    assert abs(driver - sim) <= tolerance, summary
    # the batch simulator as a third reference: the same figure without DDS and real time
    assert abs(driver - batch) <= tolerance and abs(sim - batch) <= tolerance, summary
