"""PNG figures of an offline evaluation, laid out like the paper's Figs. 9-10."""

from __future__ import annotations

from pathlib import Path


def plot_evaluation(run, alone, ukf, path: str | Path, title: str = '') -> Path:
    """Three panels over time: pressures (measured, UKF), angle or torque (measured, model
    alone, UKF), and the two errors. Returns the path written."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    from .evaluation import measured_and_estimated

    t = run.t
    fig, axes = plt.subplots(3, 1, figsize=(10, 8), sharex=True)
    ax = axes[0]
    ax.plot(t, run.p_measured[:, 0] / 1e3, color='tab:blue', lw=0.6, label='P1 measured')
    ax.plot(t, run.p_measured[:, 1] / 1e3, color='tab:red', lw=0.6, label='P2 measured')
    ax.plot(t, ukf.x[:, 2] / 1e3, 'k--', lw=0.6, label='UKF')
    ax.plot(t, ukf.x[:, 3] / 1e3, 'k--', lw=0.6)
    ax.set_ylabel('pressure (kPa abs)')
    ax.legend(loc='upper right', fontsize=8)
    measured, est_model = measured_and_estimated(run, alone)
    _, est_ukf = measured_and_estimated(run, ukf)
    unit = 'N m' if run.locked else 'deg'
    name = 'torque' if run.locked else 'angle'
    ax = axes[1]
    ax.plot(t, measured, color='0.3', lw=1.2, label='measured')
    ax.plot(t, est_model, color='tab:orange', lw=0.8, label='model alone')
    ax.plot(t, est_ukf, color='tab:green', lw=0.8, label='UKF')
    ax.set_ylabel(f'{name} ({unit})')
    ax.legend(loc='upper right', fontsize=8)
    ax = axes[2]
    ax.plot(t, measured - est_model, color='tab:orange', lw=0.8, label='model alone')
    ax.plot(t, measured - est_ukf, color='tab:green', lw=0.8, label='UKF')
    ax.axhline(0.0, color='0.5', lw=0.5)
    ax.set_ylabel(f'error ({unit})')
    ax.set_xlabel('time (s)')
    ax.legend(loc='upper right', fontsize=8)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
