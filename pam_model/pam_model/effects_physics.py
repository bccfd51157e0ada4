"""The plant with unmodelled effects (numba): its RK4 step, the supply tank's load, Maxwell-slip
hysteresis.

The step is :func:`pam_model.physics.rk4_step` itself, given the effects' two terms (0 in the
paper's model):

* ``V_d`` (m^3), the dead volume of each muscle's air line: eq. (4) becomes
  dP/dt = k1 R T m / (V + V_d) - k2 (V_dot / (V + V_d)) P, with V_dot = dV/dt of the muscle alone
  (the line's volume does not change);
* ``F_h1``, ``F_h2`` (N), the hysteresis forces, held over the step: F_i = v(l_i) P_i + w(l_i) +
  F_h,i enters eq. (8) (torque) and the friction law's F1 + F2 (eq. 10).

The supply pressure P_tank and the temperature T of a step come in the record ``p`` (the caller
writes them); the valve openings come in already lagged.
"""

import numpy as np
from numba import njit

from .physics import gas_constants, inflow_per_area, rk4_step


@njit(cache=True)
def step_with_effects(x, alpha1, alpha2, h, p_array, friction_law, force_model, locked, V_d,
                      F_h1, F_h2, x_next):
    """physics.rk4_step of length h (s) from x (4,) with openings alpha1, alpha2 in [0, 1], the
    dead volume V_d (m^3) and the hysteresis forces F_h1, F_h2 (N); writes x_next (4,), returns
    (T_f N m, sigma 1..18). p_array: a one-row parameter record."""
    x_next[0], x_next[1], x_next[2], x_next[3], T_f, sigma = rk4_step(
        x[0], x[1], x[2], x[3], alpha1, alpha2, h, p_array[0], friction_law, force_model, locked,
        V_d, F_h1, F_h2)
    return T_f, sigma


@njit(cache=True)
def supply_inflow(P1, P2, alpha1, alpha2, p_array):
    """Mass flow (kg/s) the two valves draw from the supply tank over a step from muscle
    pressures P1, P2 (Pa) with openings alpha1, alpha2, at the P_tank and T of the record
    p_array[0]: alpha_i A1_i m_in tilde(P_i) summed (the supply droop's load)."""
    p = p_array[0]
    gas = gas_constants(p)
    return (0.0 + alpha1 * p.A1_1 * inflow_per_area(P1, p, gas)
            + alpha2 * p.A1_2 * inflow_per_area(P2, p, gas))


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
