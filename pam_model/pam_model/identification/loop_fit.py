"""The form of the joint's hysteresis loop, chosen on data the fits did not see.

A force hysteresis driven by the muscle's LENGTH (braid friction, the contraction-driven loops of
Vo-Minh et al. 2011) or by its PRESSURE (Aschemann and Schindele's Bouc-Wen force
characteristic) does not show in the locked runs as a loop of the nominal force (the Maxwell
slip that hysteresis_fit looks for there): a length-driven loop stands still in a locked run,
and in the free run it opposes the motion and grows with the pressure, as the shaft friction
does. So the friction fit alone absorbs it (mu_s far too high) and the estimator's angle pays.

Each candidate form is fitted with the friction coefficients on the free runs (friction_fit):
no loop (the paper's friction alone), a Bouc-Wen loop driven by the length, one driven by the
pressure, each with its band B_w free in sign (the loop's orientation is the data's, never
assumed) and its travel. The free runs are cut in two halves; each candidate is fitted on one
half and its angle residual measured on the other, both ways (two-fold cross-validation). The
held-out RMS decides: the lowest wins, but a loop must beat the form without one by MARGIN (its
two more parameters must earn their place on data they did not fit); the winner is then fitted
on the whole runs, and a loop is kept only if its band exceeds SIGNIFICANCE sigma there. The
report shows every candidate's held-out score and why the winner won.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .fit_result import Estimate, GroupFit, NotIdentifiable
from .friction_fit import (
    LOOP_DRIVERS,
    filtered_pressures,
    fit_friction,
    free_runs,
    simulated_angles,
)

#: a loop must lower the held-out RMS by this fraction against the form without one
MARGIN = 0.05
#: and its band B_w, fitted on the whole runs, must exceed this many sigma
SIGNIFICANCE = 3.0
FOLDS = 2
CANDIDATES = (None, *LOOP_DRIVERS)           # None: no loop


def form_name(driver: str | None) -> str:
    return 'no loop' if driver is None else f'Bouc-Wen loop driven by the {driver}'


def halves(runs) -> list:
    """[first halves, second halves] of the runs (each run cut at its middle sample)."""
    parts = [[], []]
    for rec in runs:
        middle = len(rec.t) // 2
        parts[0].append(rec.between(0, middle))
        parts[1].append(rec.between(middle, len(rec.t)))
    return parts


def held_out_rms(runs, params, hysteresis, driver: str | None) -> float:
    """deg: the angle RMS of `driver`'s form over each half of the runs, fitted on the other."""
    folds = halves(runs)
    squares, count = 0.0, 0
    for k in range(FOLDS):
        fitted_on, scored_on = folds[k], folds[1 - k]
        try:
            _, changes, _, loop = fit_friction(fitted_on, params, hysteresis, driver,
                                               strict=False)
        except NotIdentifiable:
            return float('inf')
        inputs = [(r, filtered_pressures(r)) for r in scored_on]
        error = np.degrees(simulated_angles(inputs, params.replace(**changes), hysteresis, loop)
                           - np.concatenate([r.psi for r in scored_on]))
        squares += float(np.sum(error ** 2))
        count += error.size
    return float(np.sqrt(squares / count))


def choose(scores: dict) -> tuple[str | None, str]:
    """(the winning driver, why) from {driver: held-out RMS (deg)}."""
    best = min(scores, key=scores.get)
    plain = scores[None]
    if best is None:
        return None, 'no loop form fits the held-out half better'
    gain = 1.0 - scores[best] / plain if plain > 0.0 else 0.0
    if gain < MARGIN:
        return None, (f'the best loop ({form_name(best)}) lowers the held-out RMS by only '
                      f'{100 * gain:.1f} % (< {100 * MARGIN:g} %)')
    return best, (f'lowest held-out RMS, {100 * gain:.0f} % below the form without a loop '
                  f'(>= {100 * MARGIN:g} % needed)')


def fit_friction_and_loop(records, params, hysteresis=(0.0, 1, 1.0)):
    """The friction coefficients and the loop form of the free runs, chosen by their held-out
    RMS. Returns (the friction fit, the Parameters changes, what was not identified, the form's
    GroupFit, the Loop: NO_LOOP when none won)."""
    runs = free_runs(records)
    scores = {driver: held_out_rms(runs, params, hysteresis, driver) for driver in CANDIDATES}
    winner, why = choose(scores)
    group, changes, skipped, loop = fit_friction(runs, params, hysteresis, winner)
    band = next((e for e in group.estimates if e.name == 'bouc_wen_band'), None)
    if band is not None and not abs(band.value) > SIGNIFICANCE * band.std:
        why = (f'{form_name(winner)} won on held-out data, but its band over the whole runs, '
               f'{band.value:+.3g} +- {band.std:.2g} N, is below {SIGNIFICANCE:g} sigma: no '
               'loop kept')
        winner = None
        group, changes, skipped, loop = fit_friction(runs, params, hysteresis, None)
    notes = tuple(f'{form_name(d)}: held-out angle RMS {scores[d]:.4g} deg'
                  + (' <- chosen' if d == winner else '') for d in CANDIDATES)
    notes += (f'chosen: {form_name(winner)}: {why}',
              f'{FOLDS}-fold: fitted on one half of each free run, scored on the other')
    estimates = tuple(e for e in group.estimates if e.name.startswith('bouc_wen'))
    group = replace(group, estimates=tuple(e for e in group.estimates if e not in estimates))
    if not estimates:
        estimates = (Estimate('bouc_wen_band', 0.0, float('nan'), 0.0, 'N',
                              'no loop chosen'),)
    form = GroupFit('hysteresis form', estimates, scores[winner], 'deg', group.samples, notes)
    return group, changes, skipped, form, loop

