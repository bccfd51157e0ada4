"""The hybrid model of MODEL.md section 2, scalar path: one state at a time, compiled with numba.

State x = [psi, psi_dot, P1, P2] (rad, rad/s, Pa abs, Pa abs); input alpha = kappa(u) in [0, 1].
Every function is pure; the parameters come in as a :class:`pam_model.parameters.Parameters`
NamedTuple ``p``. Each function is also callable as plain Python through ``.py_func`` (the filter's
reference oracle uses that path). The friction law and the force model arrive as plain integers,
``int(FrictionLaw...)`` and ``int(ForceModel...)`` of :mod:`pam_model.model_choices` (PamModel
checks the user's names and passes them so).

Guards, so that no finite input yields NaN or inf (the UKF evaluates sigma points far from the
estimate, and full-range inputs drive the plant itself close to V = 0 near |psi| = 34.9 deg):

* the state entering a step is clamped to the box ``|psi| <= PSI_MAX``, ``|psi_dot| <= OMEGA_MAX``,
  ``P_MIN <= P_i <= P_MAX``; inside the working envelope (|psi| <= 25 deg, 200-700 kPa) the box is
  never active;
* the muscle volume is floored at ``V_MIN`` (about 3 % of V(L0));
* the tube-friction term uses ``max(P_i - P_out, DP_MIN)`` (T_p diverges as P_i -> P_out);
* inflow stops at P_i >= P_tank, outflow at P_i <= P_out (orifice ratios clipped to [0, 1]);
* a non-finite valve voltage is read as 0 V (venting), voltages are clipped to [0, 10] V.
"""

import math
from typing import NamedTuple

from numba import njit

from .model_choices import ForceModel, FrictionLaw
from .valve_voltage import U_MAX, U_MIN

PSI_MAX = math.radians(60.0)    # rad, state clamp on the joint angle
OMEGA_MAX = 100.0               # rad/s, state clamp on the joint velocity
P_MIN = 1.0e3                   # Pa abs, state clamp, lower
P_MAX = 5.0e6                   # Pa abs, state clamp, upper
V_MIN = 1.0e-6                  # m^3, floor of the muscle volume
DP_MIN = 1.0e4                  # Pa, floor of P_i - P_out in the tube friction T_p


@njit(cache=True)
def clip(value, low, high):
    """value limited to [low, high]."""
    return min(max(value, low), high)


@njit(cache=True)
def clamp_state(psi, psi_dot, P1, P2):
    """The state limited to the guard box (rad, rad/s, Pa, Pa)."""
    return (clip(psi, -PSI_MAX, PSI_MAX), clip(psi_dot, -OMEGA_MAX, OMEGA_MAX),
            clip(P1, P_MIN, P_MAX), clip(P2, P_MIN, P_MAX))


@njit(cache=True)
def sanitised_voltage(u):
    """u (V) as a valve reads it (valve_voltage.sanitise_command's rule, compiled): non-finite
    as U_MIN (vent), else clipped to [U_MIN, U_MAX]."""
    if not math.isfinite(u):
        return U_MIN
    return clip(u, U_MIN, U_MAX)


@njit(cache=True)
def valve_opening(u, kappa_u, kappa_alpha):
    """alpha = kappa(u) in [0, 1] by linear interpolation of the kappa table; u in V.

    A non-finite voltage reads as 0 V (vent), out-of-range voltages clip to [0, 10] V.
    """
    u = sanitised_voltage(u)
    n = kappa_u.shape[0]
    if u <= kappa_u[0]:
        return kappa_alpha[0]
    for j in range(1, n):
        if u <= kappa_u[j]:
            w = (u - kappa_u[j - 1]) / (kappa_u[j] - kappa_u[j - 1])
            return kappa_alpha[j - 1] + w * (kappa_alpha[j] - kappa_alpha[j - 1])
    return kappa_alpha[n - 1]


# --- geometry, eqs. (2), (3) -------------------------------------------------------------------

@njit(cache=True)
def muscle_lengths(psi, p):
    """l1, l2 (m) at joint angle psi (rad): l1 = L0 - r sin(psi), l2 = L0 + r sin(psi)."""
    delta_L = p.r * math.sin(psi)
    return p.L0 - delta_L, p.L0 + delta_L


@njit(cache=True)
def muscle_volume(l, p):
    """V(l) = D1 l^2 + D2 l + D3 (m^3), floored at V_MIN."""
    return max(p.D1 * l * l + p.D2 * l + p.D3, V_MIN)


@njit(cache=True)
def volume_rate(l, l_dot, p):
    """dV/dt = (2 D1 l + D2) dl/dt (m^3/s)."""
    return (2.0 * p.D1 * l + p.D2) * l_dot


# --- valve flow, eq. (5) and the orifice equations -----------------------------------------------

class GasConstants(NamedTuple):
    """Constants of the orifice equations, derived once per step from Table II."""

    c_star: float     # -, critical pressure ratio (2/(k+1))^(k/(k-1)), about 0.528
    C_ch: float       # sqrt(kg K/J), choked coefficient sqrt(k/R (2/(k+1))^((k+1)/(k-1)))
    C_un0: float      # sqrt(kg K/J), prefactor of C_un: sqrt(2k/(R(k-1)))
    inv_k: float      # -, 1/k
    sqrt_T: float     # sqrt(K)


@njit(cache=True)
def gas_constants(p):
    """GasConstants of the parameter set p."""
    k = p.k
    return GasConstants(c_star=(2.0 / (k + 1.0)) ** (k / (k - 1.0)),
                        C_ch=math.sqrt(k / p.R * (2.0 / (k + 1.0)) ** ((k + 1.0) / (k - 1.0))),
                        C_un0=math.sqrt(2.0 * k / (p.R * (k - 1.0))),
                        inv_k=1.0 / k, sqrt_T=math.sqrt(p.T))


@njit(cache=True)
def orifice_coefficient(phi, gas):
    """C_ch if phi <= c*, else C_un(phi) = C_un0 phi^(1/k) sqrt(1 - phi^((k-1)/k)) (sqrt(kg K/J));
    phi = downstream/upstream pressure ratio, clipped to <= 1. Uses phi^((k-1)/k) = phi/phi^(1/k).
    """
    if phi <= gas.c_star:
        return gas.C_ch
    phi = min(phi, 1.0)
    root = phi ** gas.inv_k
    return gas.C_un0 * root * math.sqrt(max(1.0 - phi / root, 0.0))


@njit(cache=True)
def inflow_per_area(P, p, gas):
    """m_in tilde (kg/(s m^2)): flow from the tank into a muscle at pressure P (Pa)."""
    if P >= p.P_tank:
        return 0.0
    return p.P_tank / gas.sqrt_T * orifice_coefficient(P / p.P_tank, gas)


@njit(cache=True)
def outflow_per_area(P, p, gas):
    """m_out tilde (kg/(s m^2)): flow from a muscle at pressure P (Pa) to the atmosphere."""
    if P <= p.P_out:
        return 0.0
    return P / gas.sqrt_T * orifice_coefficient(p.P_out / P, gas)


@njit(cache=True)
def mass_flow(P, alpha, A1, A2, p, gas):
    """m = A_0 (alpha m_in - (1 - alpha) m_out) (kg/s); A_0 = A1 when charging, A2 otherwise."""
    m_tilde = alpha * inflow_per_area(P, p, gas) - (1.0 - alpha) * outflow_per_area(P, p, gas)
    if m_tilde > 0.0:
        return A1 * m_tilde
    return A2 * m_tilde


@njit(cache=True)
def pressure_rate(P, V, V_dot, m, p):
    """Eq. (4): dP/dt = k1 R T m / V - k2 (V_dot / V) P (Pa/s)."""
    return p.k1 * p.R * p.T * m / V - p.k2 * (V_dot / V) * P


@njit(cache=True)
def pressure_region(P, p):
    """0: P < P_out/c* (inflow choked, outflow not); 1: both choked; 2: P > c* P_tank."""
    c_star = gas_constants(p).c_star
    if P < p.P_out / c_star:
        return 0
    if P <= c_star * p.P_tank:
        return 1
    return 2


# --- force and torque, eqs. (6)-(9) ---------------------------------------------------------------

@njit(cache=True)
def contraction_force(l, P, p_v1, p_v2, p_w1, p_w2, L0, force_model):
    """F = v(l) P + w(l) (N), v = p_v1 l + p_v2, w = p_w1 l + p_w2; l in m, P in Pa abs.

    force_model: int(ForceModel): PROPOSED (eq. 6-7); LENGTH_INDEPENDENT (coefficients frozen at
    l = L0); NO_OFFSET (w = 0, F = v(l) P).
    """
    if force_model == ForceModel.LENGTH_INDEPENDENT:
        l = L0
    v = p_v1 * l + p_v2
    if force_model == ForceModel.NO_OFFSET:
        return v * P
    return v * P + (p_w1 * l + p_w2)


@njit(cache=True)
def muscle_forces(psi, P1, P2, p, force_model, F_h1=0.0, F_h2=0.0):
    """F1, F2 (N) at angle psi (rad) and pressures P1, P2 (Pa abs): eq. (6)-(7), plus the
    hysteresis forces F_h1, F_h2 (N) of a plant with unmodelled effects (0 in the paper's model:
    then exactly eq. (6)-(7))."""
    l1, l2 = muscle_lengths(psi, p)
    F1 = contraction_force(l1, P1, p.p_v1_1, p.p_v2_1, p.p_w1_1, p.p_w2_1, p.L0, force_model)
    F2 = contraction_force(l2, P2, p.p_v1_2, p.p_v2_2, p.p_w1_2, p.p_w2_2, p.L0, force_model)
    return F1 + F_h1, F2 + F_h2


@njit(cache=True)
def joint_torque(psi, F1, F2, p):
    """Eq. (8): tau = r cos(psi) (F1 - F2) (N m)."""
    return p.r * math.cos(psi) * (F1 - F2)


# --- friction, eq. (10) and Table III -----------------------------------------------------------

@njit(cache=True)
def coulomb_level(psi_dot, P1, P2, F1, F2, p, friction_law):
    """T_c (N m) and viscous coefficient c (N m s/rad) of the friction law int(FrictionLaw).

    PROPOSED: T_c = r_p mu_s |F1 + F2 - M g| + mu_p (1/(P1-P_out)^2 + 1/(P2-P_out)^2), c = c_s
    LINEAR:   T_c = 0, c = c_s (viscous only)
    COULOMB:  T_c = r_p F_r (simple Coulomb force F_r at the shaft radius), c = 0
    TONDU:    T_c = (f_s - f_k) exp(-|psi_dot|/xdot_k) + f_k, c = 0
    NONE:     no friction
    """
    if friction_law == FrictionLaw.PROPOSED:
        dP1 = max(P1 - p.P_out, DP_MIN)
        dP2 = max(P2 - p.P_out, DP_MIN)
        T_sh = p.r_p * p.mu_s * abs(F1 + F2 - p.M * p.g)
        T_p = p.mu_p * (1.0 / (dP1 * dP1) + 1.0 / (dP2 * dP2))
        return T_sh + T_p, p.c_s
    if friction_law == FrictionLaw.LINEAR:
        return 0.0, p.c_s
    if friction_law == FrictionLaw.COULOMB:
        return p.r_p * p.F_r, 0.0
    if friction_law == FrictionLaw.TONDU:
        return (p.f_s - p.f_k) * math.exp(-abs(psi_dot) / p.xdot_k) + p.f_k, 0.0
    return 0.0, 0.0


@njit(cache=True)
def friction_torque(psi, psi_dot, P1, P2, h, p, friction_law, force_model, F_h1=0.0, F_h2=0.0):
    """Kikuuwe's implicit-Euler friction, once per step of length h (s).

    Returns (T_f in N m, sliding flag). T0 = tau - k_s psi; omega* = psi_dot + (h/J) T0;
    sliding when |omega*| > (h/J) T_c: T_f = (T_c sgn(omega*) + c omega*) / (1 + (h/J) c);
    sticking otherwise: T_f = (J/h) omega*. Every law of Table III goes through this form.
    F_h1, F_h2 (N): hysteresis forces in the muscle forces (muscle_forces).
    """
    if friction_law == FrictionLaw.NONE:
        return 0.0, True
    F1, F2 = muscle_forces(psi, P1, P2, p, force_model, F_h1, F_h2)
    return friction_from_forces(psi, psi_dot, P1, P2, F1, F2, h, p, friction_law)


@njit(cache=True)
def friction_from_forces(psi, psi_dot, P1, P2, F1, F2, h, p, friction_law):
    """friction_torque's Kikuuwe step given the muscle forces F1, F2 (N); friction_law is not
    NONE. Returns (T_f in N m, sliding flag)."""
    T0 = joint_torque(psi, F1, F2, p) - p.k_s * psi
    z = h / p.J
    omega_star = psi_dot + z * T0
    T_c, c = coulomb_level(psi_dot, P1, P2, F1, F2, p, friction_law)
    if abs(omega_star) > z * T_c:
        return (math.copysign(T_c, omega_star) + c * omega_star) / (1.0 + z * c), True
    return omega_star / z, False


# --- state equation (11a), RK4 ------------------------------------------------------------------

@njit(cache=True)
def state_derivative(psi, psi_dot, P1, P2, alpha1, alpha2, T_f, p, gas, force_model, locked,
                     V_d=0.0, F_h1=0.0, F_h2=0.0):
    """f(x) of (11a) with the friction torque T_f held: (psi_dot, psi_ddot, P1_dot, P2_dot).

    Units: rad/s, rad/s^2, Pa/s, Pa/s; gas = gas_constants(p). With locked=True the joint is held.
    A plant with unmodelled effects adds V_d (m^3), the dead volume of each muscle's air line, to
    V in eq. (4) (V_dot stays the muscle's: the line's volume does not change), and the
    hysteresis forces F_h1, F_h2 (N) to eq. (6)-(7) (muscle_forces); with the defaults (0) this
    is exactly the paper's (11a).
    """
    l1, l2 = muscle_lengths(psi, p)
    V1 = muscle_volume(l1, p)
    V2 = muscle_volume(l2, p)
    if locked:
        omega = 0.0
        psi_ddot = 0.0
    else:
        omega = psi_dot
        F1, F2 = muscle_forces(psi, P1, P2, p, force_model, F_h1, F_h2)
        psi_ddot = (joint_torque(psi, F1, F2, p) - T_f - p.k_s * psi) / p.J
    l_dot = p.r * math.cos(psi) * omega          # l2_dot = +l_dot, l1_dot = -l_dot
    m1 = mass_flow(P1, alpha1, p.A1_1, p.A2_1, p, gas)
    m2 = mass_flow(P2, alpha2, p.A1_2, p.A2_2, p, gas)
    P1_dot = pressure_rate(P1, V1 + V_d, volume_rate(l1, -l_dot, p), m1, p)
    P2_dot = pressure_rate(P2, V2 + V_d, volume_rate(l2, l_dot, p), m2, p)
    return omega, psi_ddot, P1_dot, P2_dot


@njit(cache=True)
def subsystem_index(sliding, P1, P2, p):
    """sigma in 1..18: 1 + 9 * sliding + 3 * region(P1) + region(P2) (see pressure_region)."""
    return 1 + 9 * (1 if sliding else 0) + 3 * pressure_region(P1, p) + pressure_region(P2, p)


@njit(cache=True)
def rk4_step(psi, psi_dot, P1, P2, alpha1, alpha2, h, p, friction_law, force_model, locked,
             V_d=0.0, F_h1=0.0, F_h2=0.0):
    """One classic RK4 step of length h (s) with T_f computed at the start and held.

    Returns (psi, psi_dot, P1, P2) at k+1, the friction torque T_f (N m) used, and sigma (1..18)
    of the state at the start of the step. V_d (m^3), F_h1, F_h2 (N): a plant's dead volume and
    hysteresis forces, held over the step (state_derivative; 0 in the paper's model).
    """
    psi, psi_dot, P1, P2 = clamp_state(psi, psi_dot, P1, P2)
    if locked:
        psi_dot = 0.0
        T_f, sliding = 0.0, False
    else:
        T_f, sliding = friction_torque(psi, psi_dot, P1, P2, h, p, friction_law, force_model,
                                       F_h1, F_h2)
    sigma = subsystem_index(sliding, P1, P2, p)
    a = (alpha1, alpha2, T_f, p, gas_constants(p), force_model, locked, V_d, F_h1, F_h2)
    k1 = state_derivative(psi, psi_dot, P1, P2, *a)
    k2 = state_derivative(psi + 0.5 * h * k1[0], psi_dot + 0.5 * h * k1[1],
                          P1 + 0.5 * h * k1[2], P2 + 0.5 * h * k1[3], *a)
    k3 = state_derivative(psi + 0.5 * h * k2[0], psi_dot + 0.5 * h * k2[1],
                          P1 + 0.5 * h * k2[2], P2 + 0.5 * h * k2[3], *a)
    k4 = state_derivative(psi + h * k3[0], psi_dot + h * k3[1],
                          P1 + h * k3[2], P2 + h * k3[3], *a)
    w = h / 6.0
    return (psi + w * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0]),
            psi_dot + w * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1]),
            P1 + w * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2]),
            P2 + w * (k1[3] + 2.0 * k2[3] + 2.0 * k3[3] + k4[3]),
            T_f, sigma)


@njit(cache=True)
def step_array(x, u1, u2, h, p_array, kappa_u, kappa_alpha, friction_law, force_model, locked,
               x_next):
    """rk4_step for a state array x (4,) and voltages u1, u2 (V) through kappa; writes x_next (4,)
    and returns (T_f, sigma). p_array is Parameters.as_record_array() (cheap to pass from Python).
    """
    alpha1 = valve_opening(u1, kappa_u, kappa_alpha)
    alpha2 = valve_opening(u2, kappa_u, kappa_alpha)
    x_next[0], x_next[1], x_next[2], x_next[3], T_f, sigma = rk4_step(
        x[0], x[1], x[2], x[3], alpha1, alpha2, h, p_array[0], friction_law, force_model, locked)
    return T_f, sigma


@njit(cache=True)
def outputs_array(x, p_array, force_model):
    """Eq. (6)-(8) at one state array x (4,): (F1 N, F2 N, tau N m); p_array as step_array's.
    The same numbers as physics_vectorised's forces and torque, without numpy's per-call cost."""
    p = p_array[0]
    F1, F2 = muscle_forces(x[0], x[2], x[3], p, force_model)
    return F1, F2, joint_torque(x[0], F1, F2, p)
