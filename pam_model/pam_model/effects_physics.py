"""The RK4 step of the plant with unmodelled effects (numba): MODEL.md's step with a dead volume
in eq. (4) and a hysteresis force added to each muscle's eq. (6) force.

It is :func:`pam_model.physics.rk4_step` with two more inputs, built from the same helpers:

* ``V_d`` (m^3), the dead volume of each muscle's air line: eq. (4) becomes
  dP/dt = k1 R T m / (V + V_d) - k2 (V_dot / (V + V_d)) P, with V_dot = dV/dt of the muscle alone
  (the line's volume does not change);
* ``F_h1``, ``F_h2`` (N), the hysteresis forces, held over the step: F_i = v(l_i) P_i + w(l_i) +
  F_h,i enters eq. (8) (torque) and the friction law's F1 + F2 (eq. 10).

The supply pressure P_tank and the temperature T of a step come in the record ``p`` (the caller
writes them); the valve openings come in already lagged. With V_d = F_h1 = F_h2 = 0 it computes
what ``physics.rk4_step`` computes. The paper's model (``physics.py``) is untouched.
"""

import math

import numpy as np
from numba import njit

from .model_choices import FrictionLaw
from .physics import (
    clamp_state,
    friction_from_forces,
    gas_constants,
    inflow_per_area,
    joint_torque,
    mass_flow,
    muscle_forces,
    muscle_lengths,
    muscle_volume,
    pressure_rate,
    subsystem_index,
    volume_rate,
)


@njit(cache=True)
def forces_with_hysteresis(psi, P1, P2, p, force_model, F_h1, F_h2):
    """F1 + F_h1, F2 + F_h2 (N): eq. (6)-(7) plus the hysteresis forces."""
    F1, F2 = muscle_forces(psi, P1, P2, p, force_model)
    return F1 + F_h1, F2 + F_h2


@njit(cache=True)
def friction_with_hysteresis(psi, psi_dot, P1, P2, h, p, friction_law, force_model, F_h1, F_h2):
    """physics.friction_torque with the hysteresis forces in the muscle forces.

    Returns (T_f N m, sliding flag)."""
    if friction_law == FrictionLaw.NONE:
        return 0.0, True
    F1, F2 = forces_with_hysteresis(psi, P1, P2, p, force_model, F_h1, F_h2)
    return friction_from_forces(psi, psi_dot, P1, P2, F1, F2, h, p, friction_law)


@njit(cache=True)
def derivative_with_effects(psi, psi_dot, P1, P2, alpha1, alpha2, T_f, p, g, force_model, locked,
                            V_d, F_h1, F_h2):
    """(11a) with the dead volume V_d (m^3) in eq. (4) and the hysteresis forces (N) in eq. (8)."""
    l1, l2 = muscle_lengths(psi, p)
    V1 = muscle_volume(l1, p)
    V2 = muscle_volume(l2, p)
    if locked:
        omega = 0.0
        psi_ddot = 0.0
    else:
        omega = psi_dot
        F1, F2 = forces_with_hysteresis(psi, P1, P2, p, force_model, F_h1, F_h2)
        psi_ddot = (joint_torque(psi, F1, F2, p) - T_f - p.k_s * psi) / p.J
    l_dot = p.r * math.cos(psi) * omega
    m1 = mass_flow(P1, alpha1, p.A1_1, p.A2_1, p, g)
    m2 = mass_flow(P2, alpha2, p.A1_2, p.A2_2, p, g)
    P1_dot = pressure_rate(P1, V1 + V_d, volume_rate(l1, -l_dot, p), m1, p)
    P2_dot = pressure_rate(P2, V2 + V_d, volume_rate(l2, l_dot, p), m2, p)
    return omega, psi_ddot, P1_dot, P2_dot


@njit(cache=True)
def step_with_effects(x, alpha1, alpha2, h, p_array, friction_law, force_model, locked, V_d,
                      F_h1, F_h2, x_next):
    """One RK4 step of length h (s) from x (4,) with openings alpha1, alpha2 in [0, 1]; writes
    x_next (4,), returns (T_f N m, sigma 1..18). p_array: a one-row parameter record."""
    p = p_array[0]
    psi, psi_dot, P1, P2 = clamp_state(x[0], x[1], x[2], x[3])
    if locked:
        psi_dot = 0.0
        T_f, sliding = 0.0, False
    else:
        T_f, sliding = friction_with_hysteresis(psi, psi_dot, P1, P2, h, p, friction_law,
                                                force_model, F_h1, F_h2)
    sigma = subsystem_index(sliding, P1, P2, p)
    g = gas_constants(p)
    k1 = derivative_with_effects(psi, psi_dot, P1, P2, alpha1, alpha2, T_f, p, g, force_model,
                                 locked, V_d, F_h1, F_h2)
    k2 = derivative_with_effects(psi + 0.5 * h * k1[0], psi_dot + 0.5 * h * k1[1],
                                 P1 + 0.5 * h * k1[2], P2 + 0.5 * h * k1[3], alpha1, alpha2, T_f,
                                 p, g, force_model, locked, V_d, F_h1, F_h2)
    k3 = derivative_with_effects(psi + 0.5 * h * k2[0], psi_dot + 0.5 * h * k2[1],
                                 P1 + 0.5 * h * k2[2], P2 + 0.5 * h * k2[3], alpha1, alpha2, T_f,
                                 p, g, force_model, locked, V_d, F_h1, F_h2)
    k4 = derivative_with_effects(psi + h * k3[0], psi_dot + h * k3[1], P1 + h * k3[2],
                                 P2 + h * k3[3], alpha1, alpha2, T_f, p, g, force_model, locked,
                                 V_d, F_h1, F_h2)
    w = h / 6.0
    x_next[0] = psi + w * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0])
    x_next[1] = psi_dot + w * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1])
    x_next[2] = P1 + w * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2])
    x_next[3] = P2 + w * (k1[3] + 2.0 * k2[3] + 2.0 * k3[3] + k4[3])
    return T_f, sigma


@njit(cache=True)
def supply_inflow(P1, P2, alpha1, alpha2, p_array):
    """Mass flow (kg/s) the two valves draw from the supply tank over a step from muscle
    pressures P1, P2 (Pa) with openings alpha1, alpha2, at the P_tank and T of the record
    p_array[0]: alpha_i A1_i m_in tilde(P_i) summed (the supply droop's load)."""
    p = p_array[0]
    g = gas_constants(p)
    return (0.0 + alpha1 * p.A1_1 * inflow_per_area(P1, p, g)
            + alpha2 * p.A1_2 * inflow_per_area(P2, p, g))


@njit(cache=True)
def ordered_sum(values, n):
    """values[0] + ... + values[n-1] added as numpy's sum adds them (numpy 2: one by one below 8
    terms; eight running sums, combined pairwise, from 8 to 128 terms), so that a kernel gives
    what the array form gives, bit for bit."""
    if n < 8:
        total = 0.0
        for j in range(n):
            total += values[j]
        return total
    r0, r1, r2, r3 = values[0], values[1], values[2], values[3]
    r4, r5, r6, r7 = values[4], values[5], values[6], values[7]
    j = 8
    while j + 8 <= n:
        r0 += values[j]
        r1 += values[j + 1]
        r2 += values[j + 2]
        r3 += values[j + 3]
        r4 += values[j + 4]
        r5 += values[j + 5]
        r6 += values[j + 6]
        r7 += values[j + 7]
        j += 8
    total = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while j < n:
        total += values[j]
        j += 1
    return total


@njit(cache=True)
def maxwell_slip_update(s, P, slip, stiffness, p_out, p_band, anchor, force):
    """One sample of Maxwell-slip hysteresis for each muscle i (pam_model.effects.MaxwellSlip):
    element j with stiffness k_j (N/N) and slip force f_j c(P_i) (N), c(P) = max(P - P_out, 0) /
    (p_band - P_out), moves with the input s_i (N): F_ij = clip(k_j (s_i - a_ij), -f_j c, f_j c),
    its anchor a_ij = s_i - F_ij / k_j; force[i] = sum_j F_ij (N, summed as numpy sums:
    ordered_sum). anchor (count, n) and force (count,) are updated in place."""
    count, n = anchor.shape
    element = np.empty(n)
    for i in range(count):
        c = max(P[i] - p_out, 0.0) / (p_band - p_out)
        for j in range(n):
            limit = slip[j] * c
            f = min(max(stiffness[j] * (s[i] - anchor[i, j]), -limit), limit)
            anchor[i, j] = s[i] - f / stiffness[j]
            element[j] = f
        force[i] = ordered_sum(element, n)
