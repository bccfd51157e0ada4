"""EstimatorCore (pam_estimator.estimator_core), ukf_node's decisions without ROS, called
directly: duplicates and time going backwards, command sanitising, coasting through missing
samples by the rig's counter."""

import numpy as np

from pam_estimator.estimator_core import EstimatorCore
from pam_estimator.pam_ukf import PamUkf
from pam_model.model import PamModel
from pam_model.rest import REST_STATE
from pam_model.simulate import simulate

X0 = REST_STATE


def test_core_ignores_duplicates_and_resets_when_time_goes_backwards():
    core = EstimatorCore(PamUkf(x0=X0))
    assert core.on_pressures(4.5e5, 4.5e5, 1_000_000).kind == 'estimate'
    second = core.on_pressures(4.6e5, 4.5e5, 2_000_000)
    again = core.on_pressures(4.6e5, 4.5e5, 2_000_000)
    assert again.kind == 'duplicate' and again.output is second.output
    assert core.duplicates == 1 and core.samples == 2 and core.ukf.steps == 2
    event = core.on_pressures(4.5e5, 4.5e5, 500_000)
    assert event.kind == 'reset' and 'backwards' in event.message and core.time_resets == 1
    assert core.ukf.steps == 1                       # the filter restarted, then took this sample
    assert core.input_rate() > 0.0 and core.largest_input_gap() >= 0.0
    median, worst = core.step_time_stats()
    assert 0.0 < median <= worst


def test_core_sanitises_commands():
    core = EstimatorCore(PamUkf(x0=X0))
    assert core.on_command(6.0, 5.0)
    assert not core.on_command(np.nan, 12.0)
    np.testing.assert_array_equal(core.u_prev, [0.0, 10.0])
    assert core.bad_commands == 1 and core.commands == 2


def test_core_coasts_through_missing_samples_by_the_counter():
    """Samples 301..340 never came (the rig missed them, or they were lost): with the rig's
    counter the filter coasts through the 40 periods (prediction only, with the held command)
    and stays on the plant's time; without a counter it falls 40 steps behind the moving
    joint. A counter jump beyond MAX_COAST is not coasted (a restarted stream)."""
    from pam_estimator.estimator_core import MAX_COAST
    U = np.tile([7.0, 4.0], (700, 1))
    run = simulate(PamModel(), U, X0)
    gap = range(301, 341)
    counted, blind = EstimatorCore(PamUkf(x0=X0)), EstimatorCore(PamUkf(x0=X0))
    for core in (counted, blind):
        core.on_command(*U[0])
    for k in range(1, 400):
        if k in gap:
            continue
        stamp = k * 1_000_000
        a = counted.on_pressures(*run.p_measured[k], stamp, sample=k)
        b = blind.on_pressures(*run.p_measured[k], stamp)
        if k == gap.stop:
            after = a.output, b.output
    assert counted.coasted == len(gap) and blind.coasted == 0
    assert counted.ukf.steps == 399 and blind.ukf.steps == 399 - len(gap)
    assert counted.ukf.rejected_samples == 0
    truth = run.x[gap.stop, 0]
    coasting, behind = (abs(out.x[0] - truth) for out in after)
    assert coasting < 0.2 * behind, (coasting, behind)
    far = counted.ukf.steps
    counted.on_pressures(*run.p_measured[400], 400_000_000, sample=400 + MAX_COAST + 1)
    assert counted.ukf.steps == far + 1 and counted.coasted == len(gap)
