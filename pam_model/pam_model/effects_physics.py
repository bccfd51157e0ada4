"""The plant with unmodelled effects (numba): its RK4 step, the supply tank's load, Maxwell-slip
and Bouc-Wen hysteresis, the second-order valve spool, the finite supply tank with its compressor
(equations: pam_model.effects' docstring).

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
def band_scale(P, p_out, p_band):
    """c(P) (-) = max(P - P_out, 0) / (p_band - P_out): a hysteresis band's scale with the gauge
    pressure (1 at p_band, 0 vented), P, P_out and p_band in Pa abs; the one kernel of it for the
    plant's loops, their fits and the UKF's."""
    return max(P - p_out, 0.0) / (p_band - p_out)


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
        c = band_scale(P[i], p_out, p_band)
        for j in range(n):
            limit = slip[j] * c
            f = min(max(stiffness[j] * (s[i] - anchor[i, j]), -limit), limit)
            anchor[i, j] = s[i] - f / stiffness[j]
            element[j] = f
        force[i] = ordered_sum(element, n)


@njit(cache=True)
def bouc_wen_advance(z, dx):
    """The Bouc-Wen state z (-) after the driver's increment dx (driver divided by its travel,
    -): dz = dx - (|dx| z + dx |z|) / 2, solved exactly: linear up to z = 0 while z opposes dx,
    then z = sgn(dx) (1 - (1 - |z|) e^(-|dx|))."""
    if dx == 0.0:
        return z
    sign = 1.0 if dx > 0.0 else -1.0
    w = sign * z                         # z along the motion
    step = abs(dx)
    if w < 0.0:                          # reversal: dz/dx = 1 until z = 0
        if step <= -w:
            w += step
            step = 0.0
        else:
            step += w
            w = 0.0
    if step > 0.0:
        w = 1.0 - (1.0 - w) * np.exp(-step)
    return sign * w


@njit(cache=True)
def bouc_wen_update(drive, drive_before, z, band, P, p_out, p_band, force):
    """One sample of the Bouc-Wen hysteresis of each muscle i (pam_model.effects.BoucWen):
    z_i (-) moves with the driver's increment dx = drive[i] - drive_before[i] (driver already
    divided by its travel, -) as bouc_wen_advance. force[i] = band c(P_i) z_i (N), c(P) =
    max(P - P_out, 0) / (p_band - P_out). z and force updated in place; drive_before takes
    drive."""
    for i in range(z.size):
        dx = drive[i] - drive_before[i]
        drive_before[i] = drive[i]
        z[i] = bouc_wen_advance(z[i], dx)
        force[i] = band * band_scale(P[i], p_out, p_band) * z[i]


@njit(cache=True)
def spool_second_order(u1, u2, state, transition, mean):
    """One step of the second-order valve spools (pam_model.effects.SecondOrderValve) with the
    voltages u1, u2 (V) held: state (2, 2) rows [u_f V, du_f/dt V/s] per valve, advanced in place
    by the step's exact transition (3, 3): rows u_f, du_f/dt and (integral of u_f over the step)
    / h, each a combination of the columns u_f, du_f/dt, u. mean (2,) gets each spool's mean
    voltage over the step (V)."""
    for i in range(2):
        u = u1 if i == 0 else u2
        position, rate = state[i, 0], state[i, 1]
        state[i, 0] = transition[0, 0] * position + transition[0, 1] * rate + transition[0, 2] * u
        state[i, 1] = transition[1, 0] * position + transition[1, 1] * rate + transition[1, 2] * u
        mean[i] = transition[2, 0] * position + transition[2, 1] * rate + transition[2, 2] * u


@njit(cache=True)
def tank_update(P_t, running, inflow, compressor_flow, h, R, T, V_t, cut_in, cut_out):
    """One step of the finite supply tank (pam_model.effects.SupplyTank): isothermal,
    P_t + h (R T / V_t) (m_c on - m_in) (Pa abs) with the valves' inflow m_in (kg/s) and the
    compressor's m_c (kg/s) while it runs; then the pressure switch: on at P_t <= cut_in, off at
    P_t >= cut_out (Pa abs), unchanged between. Returns (P_t Pa, running)."""
    supplied = compressor_flow if running else 0.0
    P_next = P_t + h * R * T / V_t * (supplied - inflow)
    if P_next <= cut_in:
        running = True
    elif P_next >= cut_out:
        running = False
    return P_next, running
