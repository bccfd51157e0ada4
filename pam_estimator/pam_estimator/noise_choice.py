"""The UKF's process noise of the joint's velocity on an identified model, chosen on the lab's own
free calibration runs (their encoder known), without ROS.

What an identified model still lacks (a loop of another form than its own, a valve of another
order, a drifting supply) shows as an error in the joint's acceleration that the default tuning's
small velocity noise (1e-6 (rad/s)^2 a step) makes the filter slow to follow. How much more the
filter needs is a property of the joint and its model, so it is chosen on the joint's data: the
UKF runs over each free calibration run with the identified model and its extensions, once per
candidate Q of psi_dot, and the angle RMS against the encoder scores it. A larger noise must
lower that RMS by MARGIN to replace the tuning's own (a rule, not a fit: four values tried, none
fitted; on a model that is right the smallest noise wins and nothing changes).

pam-identify writes the choice as ukf_node's ``process_noise`` (tuning.yaml beside params.yaml);
docs/model_extensions.md has what it changes on the plant families.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import NamedTuple

import numpy as np

from pam_model.effects import Effects
from pam_model.identification.fit_result import NotIdentifiable
from pam_model.identification.friction_fit import free_runs
from pam_model.model import PamModel

from .evaluation import filter_samples, read_pressures
from .pam_ukf import DEFAULT_TUNING, PamUkf, UkfTuning

__all__ = ['CANDIDATES', 'MARGIN', 'NoiseChoice', 'angle_rms', 'choose_velocity_noise', 'pick',
           'with_velocity_noise']

#: (rad/s)^2: the Q of psi_dot tried beside the tuning's own, one decade apart.
CANDIDATES = (1e-5, 1e-4, 1e-3)
#: The fraction by which a larger noise must lower the angle RMS to be chosen.
MARGIN = 0.05


class NoiseChoice(NamedTuple):
    """The chosen Q of psi_dot ((rad/s)^2), every candidate's angle RMS (rad), and why."""

    q_velocity: float
    scores: dict
    why: str

    def tuning(self, base: UkfTuning = DEFAULT_TUNING) -> UkfTuning:
        """base with the chosen Q of psi_dot."""
        return with_velocity_noise(base, self.q_velocity)

    def report(self) -> list[str]:
        """The report's lines: each candidate's angle RMS and the choice."""
        lines = ["UKF velocity process noise (the free calibration runs, the UKF's angle RMS "
                 'against the encoder):']
        for q, rms in self.scores.items():
            mark = '  <- chosen' if q == self.q_velocity else ''
            lines.append(f'  Q(psi_dot) {q:8.0e} (rad/s)^2: {np.degrees(rms):.4f} deg{mark}')
        lines.append(f'  chosen {self.q_velocity:.0e} (rad/s)^2: {self.why}')
        return lines


def with_velocity_noise(base: UkfTuning, q_velocity: float) -> UkfTuning:
    """base with Q of psi_dot = q_velocity ((rad/s)^2)."""
    q = list(base.Q)
    q[1] = float(q_velocity)
    return base._replace(Q=tuple(q))


def angle_rms(record, model: PamModel, extensions: Effects,
              tuning: UkfTuning = DEFAULT_TUNING) -> float:
    """rad: the UKF's angle RMS against the encoder over one free calibration record (a
    pam_model.identification.records.CalibrationRecord), started from its first encoder reading
    and pressures (read through the extensions' sensor offset and gain error, as the UKF reads
    them), predicting with u[k-1] and updating with P[k] as pam-evaluate does."""
    p0 = read_pressures(record.P[0], extensions)
    ukf = PamUkf(model=replace(model, locked=False), tuning=tuning,
                 x0=(float(record.psi[0]), float(record.psi_dot[0]), float(p0[0]),
                     float(p0[1])), extensions=extensions)
    psi = filter_samples(ukf, record.P, record.u)[0][:, 0]
    return float(np.sqrt(np.mean((psi - record.psi) ** 2)))


def choose_velocity_noise(records, model: PamModel, extensions: Effects,
                          base: UkfTuning = DEFAULT_TUNING) -> NoiseChoice | None:
    """The Q of psi_dot for `model` and `extensions`, from the free runs among `records` (their
    angle RMS pooled over the runs); None when there is no free run with travel (nothing to
    choose on: the tuning stays as it is)."""
    try:
        runs = free_runs(records)
    except NotIdentifiable:
        return None
    own = float(base.Q[1])
    candidates = (own, *[q for q in CANDIDATES if q > own])
    scores = {}
    for q in candidates:
        tuning = with_velocity_noise(base, q)
        squares = [angle_rms(r, model, extensions, tuning) ** 2 * len(r.t) for r in runs]
        rms = float(np.sqrt(sum(squares) / sum(len(r.t) for r in runs)))
        scores[q] = rms if math.isfinite(rms) else math.inf     # a filter that diverged

    q, why = pick(scores, own)
    return NoiseChoice(q, scores, why)


def pick(scores: dict, own: float) -> tuple[float, str]:
    """(the chosen Q of psi_dot, why) from {Q: angle RMS}: the lowest RMS, if it is the tuning's
    `own` or at least MARGIN below own's; else own."""
    best = min(scores, key=scores.get)
    if best == own:
        return own, "the tuning's own gives the lowest angle RMS"
    gain = 1.0 - scores[best] / scores[own] if scores[own] > 0.0 else 0.0
    if gain < MARGIN:
        return own, (f'{best:.0e} lowers the angle RMS by only {100 * gain:.1f} % '
                     f"(< {100 * MARGIN:g} %): the tuning's own kept")
    return best, (f'the lowest angle RMS, {100 * gain:.0f} % below the tuning\'s own {own:.0e} '
                  f'(>= {100 * MARGIN:g} % needed)')
