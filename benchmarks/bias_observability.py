#!/usr/bin/env python3
"""What the two pressures can tell the UKF about its bias states: a Fisher-information
(Cramer-Rao) analysis of the 7-state model of pam_estimator.bias_ukf along the validation
profile, free joint and locked.

Unknowns theta: the initial psi, psi_dot, P1, P2, the bias states b1, b2 (sensor offsets, Pa)
and b_tau (joint-torque bias, N m); with --parameters also the flow parameters a calibration
identifies (each valve's charging and discharging area A1, A2, and k1, k2 of eq. (4)), as the
mismatch of a real plant. Each unknown's output sensitivity S_j(k) = d y(k) / d theta_j of
y = [P1 + b1, P2 + b2] (central differences through the model's RK4 step, b_tau entering as
bias_ukf's opposite muscle forces), the information F = sum_k S(k)^T R^-1 S(k) with R the
sensor noise (2 kPa std, the 'mild' sensor), and the prior of the default tuning (P(0), the bias
states' variances, 10 % of each parameter): the posterior std sqrt(diag((F + P0^-1)^-1)) after
windows of 1, 10 and 60 s, and the correlation of each bias with the angle and the parameters.
Deterministic (no process noise): the best any filter can do over that window; the bias random
walks of the UKF only lose information.

    .venv/bin/python benchmarks/bias_observability.py [--parameters] [--seed 1]
"""

import argparse
from dataclasses import dataclass

import numpy as np

from pam_estimator.bias_ukf import TORQUE_BIAS_STATES, torque_forces
from pam_estimator.pam_ukf import DEFAULT_TUNING
from pam_model.effects_physics import step_with_effects
from pam_model.model import PamModel
from pam_model.profiles import validation_profile
from pam_model.rest import REST_STATE

NOISE_STD = 2000.0             # Pa, the 'mild' scenario's sensor noise
WINDOWS = (1.0, 10.0, 60.0)    # s
PARAMETER_PRIOR = 0.10         # relative std of a flow parameter before the run
FLOW_PARAMETERS = ('A1_1', 'A2_1', 'A1_2', 'A2_2', 'k1', 'k2')
#: finite-difference steps of the state and bias unknowns (their units)
STATE_STEPS = {'psi': 1e-4, 'psi_dot': 1e-4, 'P1': 50.0, 'P2': 50.0, 'b1': 50.0, 'b2': 50.0,
               'b_tau': 1e-3}


@dataclass(frozen=True)
class Unknown:
    name: str
    step: float          # finite-difference step (its unit)
    prior_std: float     # its std before the run (its unit)
    unit: str


def unknowns(model: PamModel, with_parameters: bool) -> list[Unknown]:
    P0 = np.sqrt(DEFAULT_TUNING.P0)
    bias = TORQUE_BIAS_STATES
    out = [Unknown('psi', STATE_STEPS['psi'], P0[0], 'rad'),
           Unknown('psi_dot', STATE_STEPS['psi_dot'], P0[1], 'rad/s'),
           Unknown('P1', STATE_STEPS['P1'], P0[2], 'Pa'),
           Unknown('P2', STATE_STEPS['P2'], P0[3], 'Pa'),
           Unknown('b1', STATE_STEPS['b1'], np.sqrt(bias.sensor_variance), 'Pa'),
           Unknown('b2', STATE_STEPS['b2'], np.sqrt(bias.sensor_variance), 'Pa'),
           Unknown('b_tau', STATE_STEPS['b_tau'], np.sqrt(bias.torque_variance), 'N m')]
    if with_parameters:
        for name in FLOW_PARAMETERS:
            value = float(model.params_array[0][name])
            out.append(Unknown(name, 1e-3 * value, PARAMETER_PRIOR * value, ''))
    return out


def outputs(model: PamModel, openings: np.ndarray, theta: dict) -> np.ndarray:
    """y (N, 2) Pa of the 7-state model from the unknowns' values `theta` (name -> value)."""
    p_array = model.params_array.copy()
    for name in FLOW_PARAMETERS:
        if name in theta:
            p_array[name] = theta[name]
    p = p_array[0]
    x = np.array([theta['psi'], theta['psi_dot'], theta['P1'], theta['P2']])
    x_next = np.empty(4)
    y = np.empty((len(openings), 2))
    b = np.array([theta['b1'], theta['b2']])
    for k in range(len(openings)):
        y[k] = x[2:4] + b
        F_h1, F_h2 = torque_forces(x[0], theta['b_tau'], p, 0.0, 0.0)
        step_with_effects(x, openings[k, 0], openings[k, 1], model.h, p_array,
                          model.friction_code, model.force_code, model.locked, 0.0, F_h1, F_h2,
                          x_next)
        x[:] = x_next
    return y


def sensitivities(model: PamModel, openings: np.ndarray, items: list[Unknown]) -> np.ndarray:
    """S (N, 2, n): d y / d theta_j by central differences at the nominal values."""
    base = {'psi': REST_STATE[0], 'psi_dot': REST_STATE[1], 'P1': REST_STATE[2],
            'P2': REST_STATE[3], 'b1': 0.0, 'b2': 0.0, 'b_tau': 0.0}
    base.update({name: float(model.params_array[0][name]) for name in FLOW_PARAMETERS})
    S = np.empty((len(openings), 2, len(items)))
    for j, item in enumerate(items):
        up = dict(base, **{item.name: base[item.name] + item.step})
        down = dict(base, **{item.name: base[item.name] - item.step})
        S[:, :, j] = (outputs(model, openings, up) - outputs(model, openings, down)) / (
            2.0 * item.step)
    return S


def posterior(S: np.ndarray, items: list[Unknown], n: int) -> np.ndarray:
    """The posterior covariance after the first n samples."""
    F = np.einsum('kij,kil->jl', S[:n], S[:n]) / NOISE_STD ** 2
    prior = np.diag([1.0 / item.prior_std ** 2 for item in items])
    return np.linalg.inv(F + prior)


def report(model: PamModel, openings: np.ndarray, items: list[Unknown]) -> None:
    S = sensitivities(model, openings, items)
    names = [item.name for item in items]
    print(f'{"unknown":>8} {"prior std":>11}' + ''.join(f' {f"after {w:g} s":>11}'
                                                     for w in WINDOWS) + '  (ratio to prior)')
    covariances = {w: posterior(S, items, round(w / model.h)) for w in WINDOWS}
    for j, item in enumerate(items):
        stds = [np.sqrt(covariances[w][j, j]) for w in WINDOWS]
        print(f'{item.name:>8} {item.prior_std:11.3g}' + ''.join(f' {s:11.3g}' for s in stds)
              + '  (' + ', '.join(f'{s / item.prior_std:.2g}' for s in stds) + f') {item.unit}')
    C = covariances[WINDOWS[-1]]
    d = np.sqrt(np.diag(C))
    corr = C / np.outer(d, d)
    print(f'correlations after {WINDOWS[-1]:g} s:')
    for bias in ('b1', 'b2', 'b_tau'):
        j = names.index(bias)
        others = sorted(((abs(corr[j, i]), names[i], corr[j, i]) for i in range(len(names))
                         if i != j), reverse=True)[:3]
        print(f'  {bias:>5}: ' + ', '.join(f'{name} {c:+.2f}' for _, name, c in others))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--parameters', action='store_true',
                        help='also the flow parameters A1, A2 of each valve and k1, k2 unknown')
    parser.add_argument('--seed', type=int, default=1, help='validation profile seed')
    args = parser.parse_args()
    for locked in (False, True):
        model = PamModel(locked=locked)
        profile = validation_profile(args.seed, max(WINDOWS), model.h)
        openings = model.openings(profile.u)
        items = unknowns(model, args.parameters)
        print(f'\n{"locked joint" if locked else "free joint"}: validation profile seed '
              f'{args.seed}, sensor noise {NOISE_STD:g} Pa, unknowns: '
              + ', '.join(item.name for item in items))
        report(model, openings, items)


if __name__ == '__main__':
    main()
