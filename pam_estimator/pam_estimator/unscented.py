"""Generic unscented-transform pieces (Julier sigma points, MODEL.md section 5), compiled with
numba.

Arrays only, no model: the PAM filter composes them with the model step (pam_ukf.py), and the
linear-case test composes them with a matrix to compare against a closed-form Kalman filter.
"""

import numpy as np
from numba import njit

#: Smallest eigenvalue kept when a covariance has to be repaired (fallback of sqrt_psd).
EIGEN_FLOOR = 1e-12


@njit(cache=True)
def cholesky_lower(A):
    """(L, ok): lower-triangular L with L L^T = A; ok is False if A is not positive definite."""
    n = A.shape[0]
    L = np.zeros_like(A)
    for j in range(n):
        s = A[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not s > 0.0:          # also catches NaN
            return L, False
        L[j, j] = np.sqrt(s)
        for i in range(j + 1, n):
            s = A[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = s / L[j, j]
    return L, True


@njit(cache=True)
def symmetrise(P):
    """(P + P^T) / 2."""
    return 0.5 * (P + P.T)


@njit(cache=True)
def repair_covariance(P):
    """P with its eigenvalues clipped to >= EIGEN_FLOOR * max(1, trace scale) (symmetric PD)."""
    w, V = np.linalg.eigh(symmetrise(P))
    floor = EIGEN_FLOOR * max(1.0, np.max(np.abs(w)))
    for i in range(w.shape[0]):
        if not w[i] > floor:
            w[i] = floor
    return symmetrise((V * w) @ V.T)


@njit(cache=True)
def sqrt_psd(P):
    """(L, repaired, P_used): a Cholesky factor of P, falling back to an eigenvalue clip of P."""
    L, ok = cholesky_lower(P)
    if ok:
        return L, False, P
    P_fixed = repair_covariance(P)
    L, ok = cholesky_lower(P_fixed)
    return L, True, P_fixed


@njit(cache=True)
def julier_weights(n, kappa):
    """W_0 = kappa/(n+kappa), W_i = 1/(2(n+kappa)), i = 1..2n (mean and covariance alike)."""
    W = np.full(2 * n + 1, 0.5 / (n + kappa))
    W[0] = kappa / (n + kappa)
    return W


@njit(cache=True)
def julier_sigma_points(x, P, kappa):
    """(sigmas (2n+1, n), repaired): x, then x + and x - the columns of sqrt((n+kappa) P)."""
    n = x.shape[0]
    L, repaired, _ = sqrt_psd((n + kappa) * P)
    sigmas = np.empty((2 * n + 1, n))
    sigmas[0] = x
    for i in range(n):
        for j in range(n):
            sigmas[1 + i, j] = x[j] + L[j, i]
            sigmas[1 + n + i, j] = x[j] - L[j, i]
    return sigmas, repaired


@njit(cache=True)
def weighted_cross_covariance(A, a_mean, B, b_mean, W):
    """sum_i W_i (A_i - a_mean)(B_i - b_mean)^T for rows A (k, n), B (k, m): (n, m).

    Plain loops: for 4 x 2 matrices they beat BLAS calls, whose overhead dominates."""
    n, m = A.shape[1], B.shape[1]
    C = np.zeros((n, m))
    for i in range(A.shape[0]):
        for r in range(n):
            dr = W[i] * (A[i, r] - a_mean[r])
            for c in range(m):
                C[r, c] += dr * (B[i, c] - b_mean[c])
    return C


@njit(cache=True)
def weighted_mean(A, W):
    """sum_i W_i A_i over rows A (k, n)."""
    mean = np.zeros(A.shape[1])
    for i in range(A.shape[0]):
        for r in range(A.shape[1]):
            mean[r] += W[i] * A[i, r]
    return mean


@njit(cache=True)
def inverse(S):
    """S^-1, C-contiguous; closed form for 1x1 and 2x2 (the PAM filter's P_yy), LAPACK otherwise
    (its Fortran-ordered result copied: one layout for every branch, else numba types the result
    'A' and each product with it warns NumbaPerformanceWarning at the first compile)."""
    m = S.shape[0]
    if m == 1:
        return 1.0 / S
    if m == 2:
        det = S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
        inv = np.empty((2, 2))
        inv[0, 0] = S[1, 1] / det
        inv[1, 1] = S[0, 0] / det
        inv[0, 1] = -S[0, 1] / det
        inv[1, 0] = -S[1, 0] / det
        return inv
    return np.ascontiguousarray(np.linalg.inv(S))


@njit(cache=True)
def unscented_transform(sigmas, W, noise):
    """(mean, covariance + noise) of weighted points sigmas (2n+1, m)."""
    mean = weighted_mean(sigmas, W)
    return mean, weighted_cross_covariance(sigmas, mean, sigmas, mean, W) + noise


@njit(cache=True)
def measurement_update(x_prior, P_prior, sigmas, Y, W, R, y, nis_gate):
    """Kalman update from prior sigma points sigmas (2n+1, n) and their outputs Y (2n+1, m).

    K = P_xy P_yy^-1; returns (x, P, nis, accepted). When nis_gate > 0 and the normalised
    innovation squared exceeds it, the update is rejected and the prior is returned.
    """
    y_hat, P_yy = unscented_transform(Y, W, R)
    P_xy = weighted_cross_covariance(sigmas, x_prior, Y, y_hat, W)
    P_yy_inv = inverse(P_yy)
    innovation = y - y_hat
    nis = innovation @ (P_yy_inv @ innovation)
    if not np.isfinite(nis) or (nis_gate > 0.0 and nis > nis_gate):
        return x_prior, P_prior, nis, False
    K = P_xy @ P_yy_inv
    x = x_prior + K @ innovation
    P = symmetrise(P_prior - K @ P_yy @ K.T)
    return x, P, nis, True
