"""sim_node's supply_pressure (publish_supply_pressure), a real process over DDS.

On the `realistic` plant (supply droop 20 kPa at both valves fully open, ripple +-5 kPa at
0.2 Hz): with both valves at 0 V (alpha 0: nothing drawn from the supply) the readings are the
scenario's P_tank plus the ripple, within the sensor's noise; with both at 10 V on vented muscles
(alpha 1, choked inflow) they droop by about 20 kPa. The ripple of each reading is known from its
sample counter (t = (sample - 1) h), so it is taken out before comparing.

The samples are chosen by the plant, not by when the probe received them: the muscles start at
about 450 kPa and take seconds to vent, and a muscle near 0.45 P_tank leaves the choked range
within tens of ms of opening, so the test waits until both are well vented, and the drawing
samples start at the first sample whose lower muscle has risen clearly above its vented level
(the valves are open by then: before it, a sample may still have been taken at 0 V, since a rig
running behind takes its late samples with the command it holds when it takes them).
"""

from __future__ import annotations

import math
import statistics
import time

from sensor_msgs.msg import FluidPressure

from pam_driver.sim_config import build_config
from pam_interfaces.msg import Pressures, ValveCommand

STARTUP = 45.0        # s, first message from a fresh process (loaded machine)
H = 1e-3              # s, the model step at the default 1 kHz
VENTING = 15.0        # s, venting from the initial ~450 kPa takes about 4 s (at 0 V), filling ~1 s
VENTED = 0.3          # of P_tank: both muscles below it before opening (~213 kPa: ~0.4 s choked)
CHOKED = 0.45         # of P_tank: below it the inflow is choked (c* ~ 0.53), the droop is D
RISE_BASE = 50        # samples before the opening that give the vented level
RISE_SIGMAS = 5.0     # the rise (in sensor noise std) that says the valves are open


def _hold(publisher, u: float) -> float:
    """Both valves at u V (sent a few times: sim_node holds the last); the monotonic time
    before the first was sent."""
    sent = time.monotonic()
    for _ in range(3):
        publisher.publish(ValveCommand(u1=u, u2=u))
        time.sleep(0.005)
    return sent


def _vented(pressures, p_tank: float) -> bool:
    """Both muscles' last readings below VENTED P_tank."""
    last = pressures.messages()[-RISE_BASE:]
    return len(last) == RISE_BASE and all(max(m.p1, m.p2) < VENTED * p_tank for m in last)


def test_supply_pressure_droops_when_both_valves_open(sim_node, probe, helpers):
    config = build_config({'scenario': 'realistic'})
    effects = config.scenario.effects
    p_tank, noise = config.parameters.P_tank, config.sensor.noise_std
    sim = sim_node('-p', 'scenario:=realistic', '-p', 'publish_supply_pressure:=true',
                   '-p', 'initial_command:=[0.0, 0.0]')
    supply = probe.subscribe(FluidPressure, '/pam/supply_pressure', depth=5000)
    pressures = probe.subscribe(Pressures, '/pam/pressures', depth=5000)
    commands = probe.publisher(ValveCommand, '/pam/valve_command')
    sim.wait_for(lambda: len(supply) > 0 and commands.get_subscription_count() > 0, STARTUP,
                 'the first supply_pressure and the valve_command subscription')
    assert 'supply pressure: published' in sim.stderr
    closed = _hold(commands, 0.0)
    time.sleep(1.0)                                    # the muscles vent towards atmosphere
    sim.wait_for(lambda: _vented(pressures, p_tank), VENTING,
                 f'both muscles below {VENTED} P_tank')
    before = pressures.messages()[-RISE_BASE:]
    opened = _hold(commands, 10.0)
    sim.wait_for(lambda: max(pressures.messages()[-1].p1, pressures.messages()[-1].p2)
                 >= CHOKED * p_tank, VENTING, f'a muscle above {CHOKED} P_tank')

    by_stamp = {helpers.stamp_ns(m.header.stamp): m for m in pressures.messages()}
    # the valves are open from the first sample whose lower muscle rose clearly above its level
    vented = statistics.fmean(min(m.p1, m.p2) for m in before)
    rise = vented + RISE_SIGMAS * noise
    first_open = min(m.sample for m in pressures.messages()
                     if m.sample > before[-1].sample and min(m.p1, m.p2) > rise)

    def without_ripple(keep):
        """Readings minus the ripple of their sample, of the samples `keep` accepts."""
        values = []
        for received, m in supply.items():
            p = by_stamp.get(helpers.stamp_ns(m.header.stamp))
            if p is None or not keep(received, p):
                continue
            t = (p.sample - 1) * H
            ripple = effects.supply_ripple * math.sin(2 * math.pi
                                                      * effects.supply_ripple_frequency * t)
            values.append(m.fluid_pressure - ripple)
        return values

    at_rest = without_ripple(lambda received, p: closed + 0.5 <= received < opened
                             and p.sample <= before[-1].sample)
    drawing = without_ripple(lambda received, p: p.sample >= first_open
                             and max(p.p1, p.p2) < CHOKED * p_tank)
    assert len(at_rest) >= 200 and len(drawing) >= 100, (len(at_rest), len(drawing))
    rest, droop = statistics.fmean(at_rest), p_tank - statistics.fmean(drawing)
    assert abs(rest - p_tank) <= 4 * noise / math.sqrt(len(at_rest)) + 300.0, (rest, p_tank)
    assert 0.9 * effects.supply_droop <= droop <= 1.1 * effects.supply_droop, droop
    # the sensor model: the scenario's noise (2 kPa) about it, said in the variance
    assert 0.5 * noise <= statistics.pstdev(at_rest) <= 1.5 * noise
    reading = supply.messages()[-1]
    assert math.isclose(reading.variance, noise ** 2 + config.sensor.resolution ** 2 / 12)
    assert reading.header.frame_id == 'pam_joint'
    stamps = [helpers.stamp_ns(m.header.stamp) for m in supply.messages()]
    assert sum(s in by_stamp for s in stamps) >= 0.95 * len(stamps), 'stamped as its sample'
