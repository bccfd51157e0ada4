"""The hybrid model of MODEL.md section 2, vectorised path: many states at once with numpy.

An independent implementation of :mod:`pam_model.physics` (same equations, same guards, written
with array operations and ``np.where`` instead of branches) over states X of shape (N, 4) =
[psi, psi_dot, P1, P2] (rad, rad/s, Pa abs, Pa abs) and openings alpha of shape (N, 2) or (2,).
The two paths agree to about 1e-14 relative; a test holds them to 1e-12. The friction law and
the force model may be given as a member of FrictionLaw / ForceModel, its name or its integer
value; anything else is a ValueError listing the names.
"""

import numpy as np

from .model_choices import ForceModel, FrictionLaw
from .physics import DP_MIN, OMEGA_MAX, P_MAX, P_MIN, PSI_MAX, V_MIN


def clamp_states(X):
    """States (N, 4) limited to the guard box of pam_model.physics."""
    X = np.array(X, dtype=float, ndmin=2)
    return np.stack([np.clip(X[:, 0], -PSI_MAX, PSI_MAX), np.clip(X[:, 1], -OMEGA_MAX, OMEGA_MAX),
                     np.clip(X[:, 2], P_MIN, P_MAX), np.clip(X[:, 3], P_MIN, P_MAX)], axis=1)


def muscle_lengths(psi, p):
    """l1, l2 (m) for angles psi (rad)."""
    delta_L = p.r * np.sin(psi)
    return p.L0 - delta_L, p.L0 + delta_L


def muscle_volume(l, p):
    """V(l) (m^3), floored at V_MIN."""
    return np.maximum(p.D1 * l * l + p.D2 * l + p.D3, V_MIN)


def orifice_coefficient(phi, p):
    """C_ch where phi <= c*, C_un(phi) elsewhere; phi in [0, 1] (clipped)."""
    k = p.k
    c_star = (2.0 / (k + 1.0)) ** (k / (k - 1.0))
    C_ch = np.sqrt(k / p.R * (2.0 / (k + 1.0)) ** ((k + 1.0) / (k - 1.0)))
    phi_un = np.clip(phi, c_star, 1.0)
    C_un = (np.sqrt(2.0 * k / (p.R * (k - 1.0))) * phi_un ** (1.0 / k)
            * np.sqrt(np.maximum(1.0 - phi_un ** ((k - 1.0) / k), 0.0)))
    return np.where(phi <= c_star, C_ch, C_un)


def mass_flows(P, alpha, A1, A2, p):
    """m (kg/s) of one valve for pressures P (Pa abs) and openings alpha (both (N,))."""
    sqrt_T = np.sqrt(p.T)
    m_in = np.where(P >= p.P_tank, 0.0,
                    p.P_tank / sqrt_T * orifice_coefficient(P / p.P_tank, p))
    P_safe = np.maximum(P, p.P_out)
    m_out = np.where(P <= p.P_out, 0.0, P_safe / sqrt_T * orifice_coefficient(p.P_out / P_safe, p))
    m_tilde = alpha * m_in - (1.0 - alpha) * m_out
    return np.where(m_tilde > 0.0, A1, A2) * m_tilde


def muscle_forces(psi, P1, P2, p, force_model=ForceModel.PROPOSED):
    """F1, F2 (N) for angles psi (rad) and pressures (Pa abs); force_model as in physics."""
    force_model = ForceModel.coerce(force_model)
    l1, l2 = muscle_lengths(psi, p)
    if force_model == ForceModel.LENGTH_INDEPENDENT:
        l1 = l2 = np.full_like(np.asarray(psi, dtype=float), p.L0)
    F1 = (p.p_v1_1 * l1 + p.p_v2_1) * P1
    F2 = (p.p_v1_2 * l2 + p.p_v2_2) * P2
    if force_model != ForceModel.NO_OFFSET:
        F1 = F1 + (p.p_w1_1 * l1 + p.p_w2_1)
        F2 = F2 + (p.p_w1_2 * l2 + p.p_w2_2)
    return F1, F2


def joint_torque(psi, F1, F2, p):
    """tau = r cos(psi) (F1 - F2) (N m)."""
    return p.r * np.cos(psi) * (F1 - F2)


def friction_torque(X, h, p, friction_law=FrictionLaw.PROPOSED,
                    force_model=ForceModel.PROPOSED):
    """Kikuuwe friction (N m) and sliding flags for clamped states X (N, 4), step h (s)."""
    friction_law = FrictionLaw.coerce(friction_law)
    psi, psi_dot, P1, P2 = X.T
    if friction_law == FrictionLaw.NONE:
        return np.zeros(len(X)), np.ones(len(X), dtype=bool)
    F1, F2 = muscle_forces(psi, P1, P2, p, force_model)
    z = h / p.J
    omega_star = psi_dot + z * (joint_torque(psi, F1, F2, p) - p.k_s * psi)
    c = p.c_s
    if friction_law == FrictionLaw.PROPOSED:
        dP1 = np.maximum(P1 - p.P_out, DP_MIN)
        dP2 = np.maximum(P2 - p.P_out, DP_MIN)
        T_c = (p.r_p * p.mu_s * np.abs(F1 + F2 - p.M * p.g)
               + p.mu_p * (1.0 / (dP1 * dP1) + 1.0 / (dP2 * dP2)))
    elif friction_law == FrictionLaw.LINEAR:
        T_c = np.zeros_like(psi)
    elif friction_law == FrictionLaw.COULOMB:
        T_c, c = np.full_like(psi, p.r_p * p.F_r), 0.0
    elif friction_law == FrictionLaw.TONDU:
        T_c, c = (p.f_s - p.f_k) * np.exp(-np.abs(psi_dot) / p.xdot_k) + p.f_k, 0.0
    else:
        raise NotImplementedError(f'friction law {friction_law} has no vectorised form')
    sliding = np.abs(omega_star) > z * T_c
    T_slide = (np.copysign(T_c, omega_star) + c * omega_star) / (1.0 + z * c)
    return np.where(sliding, T_slide, omega_star / z), sliding


def state_derivatives(X, alpha, T_f, p, force_model=ForceModel.PROPOSED, locked=False):
    """f(x) of (11a) for states X (N, 4) with T_f (N,) held; returns (N, 4) in SI rates."""
    psi, psi_dot, P1, P2 = X.T
    l1, l2 = muscle_lengths(psi, p)
    V1, V2 = muscle_volume(l1, p), muscle_volume(l2, p)
    if locked:
        omega = np.zeros_like(psi)
        psi_ddot = np.zeros_like(psi)
    else:
        omega = psi_dot
        F1, F2 = muscle_forces(psi, P1, P2, p, force_model)
        psi_ddot = (joint_torque(psi, F1, F2, p) - T_f - p.k_s * psi) / p.J
    l_dot = p.r * np.cos(psi) * omega
    m1 = mass_flows(P1, alpha[:, 0], p.A1_1, p.A2_1, p)
    m2 = mass_flows(P2, alpha[:, 1], p.A1_2, p.A2_2, p)
    V1_dot = (2.0 * p.D1 * l1 + p.D2) * (-l_dot)
    V2_dot = (2.0 * p.D1 * l2 + p.D2) * l_dot
    gain = p.k1 * p.R * p.T
    P1_dot = gain * m1 / V1 - p.k2 * (V1_dot / V1) * P1
    P2_dot = gain * m2 / V2 - p.k2 * (V2_dot / V2) * P2
    return np.stack([omega, psi_ddot, P1_dot, P2_dot], axis=1)


def subsystem_indices(sliding, P1, P2, p):
    """sigma in 1..18 for each state: 1 + 9 sliding + 3 region(P1) + region(P2)."""
    c_star = (2.0 / (p.k + 1.0)) ** (p.k / (p.k - 1.0))
    edges = np.array([p.P_out / c_star, np.nextafter(c_star * p.P_tank, np.inf)])
    return 1 + 9 * sliding.astype(int) + 3 * np.searchsorted(edges, P1, side='right') \
        + np.searchsorted(edges, P2, side='right')


def rk4_steps(X, alpha, h, p, friction_law=FrictionLaw.PROPOSED, force_model=ForceModel.PROPOSED,
              locked=False):
    """One RK4 step of length h (s) for every state of X (N, 4), friction held.

    alpha: openings (N, 2) or (2,) in [0, 1]. Returns (X_next (N, 4), T_f (N,), sigma (N,)).
    """
    friction_law = FrictionLaw.coerce(friction_law)
    force_model = ForceModel.coerce(force_model)
    X = clamp_states(X)
    alpha = np.broadcast_to(np.asarray(alpha, dtype=float), (len(X), 2))
    if locked:
        X[:, 1] = 0.0
        T_f, sliding = np.zeros(len(X)), np.zeros(len(X), dtype=bool)
    else:
        T_f, sliding = friction_torque(X, h, p, friction_law, force_model)
    sigma = subsystem_indices(sliding, X[:, 2], X[:, 3], p)
    k1 = state_derivatives(X, alpha, T_f, p, force_model, locked)
    k2 = state_derivatives(X + 0.5 * h * k1, alpha, T_f, p, force_model, locked)
    k3 = state_derivatives(X + 0.5 * h * k2, alpha, T_f, p, force_model, locked)
    k4 = state_derivatives(X + h * k3, alpha, T_f, p, force_model, locked)
    return X + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4), T_f, sigma
