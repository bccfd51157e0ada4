"""The sensor-less closed loop through the hardware driver: pam-emulator (the DAQ board on a pty,
the 'mild' mismatched plant, 2 kPa sensor noise as sim_node's scenario) + driver_node + ukf_node +
pi_node as real processes in real time; a probe publishes the reference (0, then +0.25 rad) and
reads the true angle from /pam/joint_measured (the emulator's encoder through the calibration).

Compared with the same plant, sensor noise, UKF, PI gains and reference on the batch simulator
(pam_controller.closed_loop.simulate_closed_loop, the loop of sim_node + ukf_node + pi_node in
lockstep): the steady-state error over the last second of the step must agree within TOLERANCE.

Why a tolerance and not equality: the emulator quantises the pressures to the 12-bit ADC of the
calibration (305 Pa a count, vs the scenario's 244 Pa), draws other noise samples, starts from
vented muscles (the driver holds safe_output 0 V until the first valve_command, the batch loop
5.5 V), and runs in real time (1 kHz samples over a pty, processes scheduled by a loaded 2-core
machine: jitter, the odd late sample). The residual error of the sensor-less loop is the UKF's
angle bias on the mismatched plant (about -0.02 rad here: the joint settles beyond the
reference), a property of the plant and the estimator, so both loops must show it (measured:
driver -0.0205 rad, batch -0.0193 rad); TOLERANCE = 0.01 rad (0.6 deg, 4 % of the step) leaves room
for the differences above and still catches a loop that does not settle or a sign/scale error.

The driver runs with a 0.5 s command watchdog (not 50 ms) so that a loaded machine's stall does
not latch it safe mid-run; it is armed through ~/arm before the step; a run during which it still
reports a safe output or a lost device is redone once, and fails the test the second time.
"""

from __future__ import annotations

import os
import time

import numpy as np
from pam_interfaces.msg import JointEstimate, JointMeasurement, Reference, ValveCommand
from std_srvs.srv import Trigger

from pam_driver.testing import stamp_ns

STARTUP = 45.0            # s, a fresh process on a loaded 2-core machine
LEVEL = 0.25              # rad, the step
PRE = 2.0                 # s at reference 0 once the loop runs (and the driver is armed)
HOLD = 6.0                # s at LEVEL
LAST = 1.0                # s, steady-state window at the end of HOLD
TOLERANCE = 0.01          # rad, |steady-state error driver - batch|; see the module docstring
GAINS = (40.0, 50.0)      # kp V/rad, ki V/(rad s): pi_node's defaults
NOISE_STD = 2000.0        # Pa, the 'mild' scenario's sensor noise (as sim_node's)
MIN_RATE = 800.0          # Hz of /pam/joint_measured in the steady-state window
ATTEMPTS = 2              # a run the driver reports disturbed (safe output, device lost) is redone


def batch_steady_state_error() -> float:
    from pam_model.mismatch import load_scenario
    from pam_model.model import PamModel
    from pam_model.parameters import load_parameters
    from pam_controller.closed_loop import simulate_closed_loop

    scenario = load_scenario('mild')
    t = np.arange(int(round((PRE + HOLD) * 1000))) * 1e-3
    reference = np.where(t < PRE, 0.0, LEVEL)
    run, = simulate_closed_loop(PamModel(params=scenario.apply(load_parameters())), PamModel(),
                                reference, [GAINS], sensor=scenario.sensor, seed=0)
    last = t >= t[-1] - LAST
    return float(np.mean(reference[last] - run.truth[last]))


def test_driver_closed_loop_matches_the_batch_simulator(node_process, probe, tmp_path):
    link = str(tmp_path / 'pam_daq')
    emulator = node_process('pam-emulator', 'pam_driver', '--link', link, '--mismatch', 'mild',
                            '--noise-std', str(NOISE_STD), raw=True)
    emulator.wait_for(lambda: os.path.islink(link), STARTUP, 'the emulator pty link')
    truth = probe.subscribe(JointMeasurement, '/pam/joint_measured', depth=1000)
    estimates = probe.subscribe(JointEstimate, '/pam/estimate', depth=1000)
    commands = probe.subscribe(ValveCommand, '/pam/valve_command', depth=1000)
    reference = probe.publisher(Reference, '/pam/reference')
    # watchdog 0.5 s and stream timeout 1 s instead of 50 ms / 0.2 s: this test is about tracking
    # (the watchdog and the device-lost detection are tested in pam_driver's test_driver_node.py),
    # and `make test` may run it on a loaded machine where a process stalls for 50 ms
    driver = node_process('driver_node', 'pam_driver', '-p', f'port:={link}',
                          '-p', 'watchdog_timeout:=0.5', '-p', 'stream_timeout:=1.0')
    ukf = node_process('ukf_node', 'pam_estimator')
    pi = node_process('pi_node', 'pam_controller', '-p', 'initial_reference:=0.0')
    for process, collector, what in ((driver, truth, 'the first /pam/joint_measured'),
                                     (ukf, estimates, 'the first /pam/estimate'),
                                     (pi, commands, 'the first /pam/valve_command')):
        process.wait_for(lambda c=collector: len(c) > 0, STARTUP, what)
    pi.wait_for(lambda: reference.get_subscription_count() > 0, 10.0, 'pi_node on /pam/reference')

    for attempt in range(1, ATTEMPTS + 1):
        result = run_step(probe, reference, truth, driver)
        if result['disturbed'] is None:
            break
        print(f'attempt {attempt}: the loop was disturbed ({result["disturbed"]}): again')
    for process in (emulator, driver, ukf, pi):
        assert process.alive(), f'{process.name} died:\n{process.stderr[-2000:]}'
    assert result['disturbed'] is None, (
        f'the real-time loop was disturbed in {ATTEMPTS} attempts (machine too loaded?): '
        f'{result["disturbed"]}; driver_node log:\n{driver.stderr[-3000:]}')
    assert result['rate'] >= MIN_RATE, f'/pam/joint_measured at {result["rate"]:.0f} Hz'
    # it did track the step (not a loop that happens to sit near the reference)
    assert abs(result['before']) < 0.05, f'not at 0 before the step: {result["before"]:.3f} rad'
    driver_error = result['error']
    batch_error = batch_steady_state_error()
    print(f'steady-state error over the last {LAST:g} s: driver loop {driver_error:+.4f} rad, '
          f'batch loop {batch_error:+.4f} rad, difference {driver_error - batch_error:+.4f} rad; '
          f'ripple (std) {result["std"]:.4f} rad; {result["rate"]:.0f} Hz')
    assert abs(driver_error - batch_error) <= TOLERANCE, (driver_error, batch_error)
    assert abs(driver_error) < 0.05


DISTURBANCES = ('safe output', 'device lost')


def run_step(probe, reference, truth, driver) -> dict:
    """Arm, reference 0 for PRE s, LEVEL for HOLD s; the true angle's statistics."""
    # Arming: driver_node starts armed (arm_at_start) but a start-up stall of the loop longer than
    # the command watchdog latches it SAFE; ~/arm (harmless when armed) makes the run
    # independent of how the processes happened to start.
    arm = probe.node.create_client(Trigger, '/pam/driver_node/arm')
    assert arm.wait_for_service(timeout_sec=10.0), 'no /pam/driver_node/arm'
    future = arm.call_async(Trigger.Request())
    deadline = time.monotonic() + 10.0
    while not future.done() and time.monotonic() < deadline:
        time.sleep(0.01)
    assert future.done() and future.result().success, future.result()
    probe.node.destroy_client(arm)
    log_before = driver.stderr

    # windows on the samples' header stamps (driver_node's clock = system time at receipt), not on
    # when the probe got them: a loaded test process may receive in bursts
    reference.publish(Reference(mode=Reference.ANGLE, value=0.0))
    time.sleep(PRE)
    t_step = time.time()
    reference.publish(Reference(mode=Reference.ANGLE, value=LEVEL))
    time.sleep(HOLD)
    t_end = time.time()
    time.sleep(0.3)   # the last samples of the window on their way

    new_log = driver.stderr[len(log_before):]
    disturbed = [line for line in new_log.splitlines() if any(d in line for d in DISTURBANCES)]
    samples = [(stamp_ns(m.header.stamp) * 1e-9, m.angle) for m in truth.messages()]
    window = [a for t, a in samples if t_end - LAST <= t <= t_end]
    before = [a for t, a in samples if t_step - 0.5 <= t <= t_step]
    angles = np.array(window or [np.nan])
    return {'disturbed': '; '.join(disturbed) or None, 'rate': len(window) / LAST,
            'error': float(np.mean(LEVEL - angles)), 'std': float(np.std(angles)),
            'before': float(np.mean(before)) if before else np.nan}
