"""The models' own compute per sample on this machine, now: the baseline a stack's CPU is read
against, and a fingerprint of the machine.

A stack's CPU per sample means little across machines, even across machines of one kind (the
same benchmark has given 23 % of a core on one and 81 % on another). What the stack's own models
cost on the same machine, measured in the same run, is the yardstick: benchmarks/stack_load.py
prints the stack's CPU per sample as a multiple of it, and pam-demo prints it beside the timer
floor, so that a run on another machine can be read against the figures of the README's.

Measured: the simulated rig's step and sample (the scenario's plant and effects), the UKF step
(the model ukf_node runs: nominal, or a pam-identify output with its extensions), the PI step
(bringup.yaml's angle gains); each back to back after a warm-up, then the three together once per
1 ms deadline (sleeping to each, as sim_node's sampler does): a loop that wakes a thousand times
a second pays its wake-ups and finds its caches cold, a floor no 1 kHz stack of these models
gets under. The wake-up alone is timed too, by a bare sleep loop (the same paced loop doing
nothing): on the 2-core development VM it is 16-20 us of CPU per wake-up, the same for the loop
written in C
(benchmarks/wake_up.c): the hypervisor's timer, not Python, and most of the difference between
the paced and the back-to-back figures. No ROS here.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass
from pathlib import Path

import yaml

from .stack import default_params_file

WARM_UP = 200           # steps before each back-to-back timing
PERIOD = 1e-3           # s, the rig's sample period in the paced timing


@dataclass(frozen=True)
class ModelCost:
    """The models' compute per sample (s): back to back, each, and the three paced at 1 kHz
    (this thread's CPU per sample, the sleep's own cost included); wake_up: a bare sleep loop
    paced the same way (CPU per deadline, s: the sleep and the wake-up alone)."""

    sim: float
    ukf: float
    pi: float
    paced: float
    wake_up: float
    scenario: str
    model: str              # 'nominal' or the pam-identify directory

    @property
    def back_to_back(self) -> float:
        return self.sim + self.ukf + self.pi

    @property
    def with_wake_up(self) -> float:
        """The models back to back with one wake-up (s): what a 1 kHz loop of these models
        needs per sample at the least (their caches warm); steadier than the paced figure,
        which moves 2-3 x from run to run on a shared VM."""
        return self.back_to_back + self.wake_up

    def line(self) -> str:
        return (f"the models' compute per sample (the '{self.scenario}' rig, the {self.model} "
                f'UKF, PI): {self.back_to_back * 1e6:.1f} us back to back (sim step '
                f'{self.sim * 1e6:.1f} + UKF step {self.ukf * 1e6:.1f} + PI '
                f'{self.pi * 1e6:.1f}), {self.paced * 1e6:.1f} us paced at 1 kHz (of which '
                f'{self.wake_up * 1e6:.1f} us is one wake-up of a bare sleep loop)')

    def as_dict(self) -> dict:
        return {**asdict(self), 'back_to_back': self.back_to_back,
                'with_wake_up': self.with_wake_up}


def measure_model_cost(scenario: str | None = None, identified: Path | None = None,
                       samples: int = 3000, paced: int = 3000) -> ModelCost:
    """Time the models (see the module docstring): `samples` steps of each back to back,
    `paced` deadlines of the bare sleep loop, then as many of the three together; scenario
    None: bringup.yaml's."""
    if samples < 1 or paced < 1:
        raise ValueError(f'samples and paced must be >= 1, got {samples!r}, {paced!r}')
    from pam_controller.pi import PiController, PiGains
    from pam_estimator.pam_ukf import PamUkf
    from pam_model.mismatch import load_scenario
    from pam_model.model import PamModel
    from pam_model.model_extensions import NO_EXTENSIONS
    from pam_model.parameters import load_parameters
    from pam_model.rig import SimulatedRig
    from pam_model.valve_map import load_valve_map
    stack = yaml.safe_load(default_params_file().read_text())
    sim = stack['/pam/sim_node']['ros__parameters']
    pi = stack['/pam/pi_node']['ros__parameters']
    scenario = scenario or sim['scenario']
    nominal = PamModel(params=load_parameters('default'), valve_map=load_valve_map('default'))
    plan = load_scenario(scenario)
    plant = PamModel(params=plan.apply(nominal.params), valve_map=nominal.valve_map)
    x0 = sim['initial_state']
    rig = SimulatedRig(plant, x0, plan.sensor, 0, tuple(sim['initial_command']),
                       effects=plan.effects)
    if identified is not None:
        from pam_estimator.calibration_runs import load_identified
        model, extensions = load_identified(identified)
    else:
        model, extensions = nominal, NO_EXTENSIONS
    ukf = PamUkf(model=model, x0=tuple(x0), extensions=extensions)
    controller = PiController(PiGains(pi['kp_angle'], pi['ki_angle'], pi['beta'], pi['u_min'],
                                      pi['u_max']))
    u = tuple(sim['initial_command'])

    def timed(step) -> float:
        for _ in range(WARM_UP):
            step()
        t0 = time.perf_counter()
        for _ in range(samples):
            step()
        return (time.perf_counter() - t0) / samples

    def rig_step() -> None:
        rig.step()
        rig.sample()
    p = rig.sample().p_measured
    sim_s = timed(rig_step)
    ukf_s = timed(lambda: ukf.step(p, u))
    pi_s = timed(lambda: controller.step(0.01, 1e-3))

    def paced_loop(step) -> float:
        """This thread's CPU per 1 ms deadline (s), sleeping to each and then calling step."""
        start = time.monotonic() + 0.01
        cpu = time.thread_time()
        for n in range(paced):
            delay = start + n * PERIOD - time.monotonic()
            if delay > 0.0:
                time.sleep(delay)
            step()
        return (time.thread_time() - cpu) / paced

    def models_step() -> None:
        rig_step()
        ukf.step(p, u)
        controller.step(0.01, PERIOD)
    wake_up_s = paced_loop(lambda: None)
    paced_s = paced_loop(models_step)
    return ModelCost(sim_s, ukf_s, pi_s, paced_s, wake_up_s, scenario,
                     'nominal' if identified is None else f'identified ({identified})')
