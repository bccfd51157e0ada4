"""The simulated supply-pressure transducer: P_tank of a SimulatedRig, measured.

sim_node (publish_supply_pressure) and pam-emulator (--supply-sensor) read the supply line of
the plant they step through it. No ROS in here.

The true value of a sample is the tank pressure P_tank (Pa abs) the valves drew from over the
step that led to it (pam_model.effects.EffectsPlant.tank_pressure: the droop with the inflow and
the compressor ripple, when the scenario's effects have them; before the first step, and for a
plant without effects, the plant's nominal P_tank). The transducer adds the rig's pressure sensor
model (pam_model.sensor.PressureSensor: white noise, ADC range and quantisation) with its own
random generator, so the muscles' readings draw the same noise whether it is read or not. The
muscles' transducer effects (offset, gain error, filter) are theirs: not applied here.
"""

from __future__ import annotations

import numpy as np

#: Mixed with the seed into the transducer's own generator (numpy SeedSequence entropy).
SUPPLY_STREAM = 0x5C


class SupplySensor:
    """rig: pam_model.rig.SimulatedRig; sensor: pam_model.sensor.PressureSensor; seed: int."""

    def __init__(self, rig, sensor, seed: int):
        self.rig = rig
        self.sensor = sensor
        self._rng = np.random.default_rng([seed, SUPPLY_STREAM])

    def true_pressure(self) -> float:
        """P_tank (Pa abs) of the rig's current sample (see the module docstring)."""
        plant = self.rig.plant
        if plant is None:
            return float(self.rig.model.params.P_tank)
        return float(plant.record['P_tank'][0])

    def measure(self) -> float:
        """The transducer's reading (Pa abs) of the current sample (draws its noise)."""
        return float(self.sensor.measure(self.true_pressure(), self._rng))

    @property
    def variance(self) -> float:
        """Of a reading about the true value (Pa^2): the noise's plus the quantisation's
        (resolution^2 / 12)."""
        return self.sensor.noise_std ** 2 + self.sensor.resolution ** 2 / 12.0
