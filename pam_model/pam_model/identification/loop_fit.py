"""The form of the joint's hysteresis loop, chosen on data the fits did not see.

Locked runs: the forms a locked joint can show (no loop, the Maxwell slip driven by the nominal
force, a Bouc-Wen loop driven by the pressure) are each fitted with the force coefficients on all
locked runs but one and scored by the torque residual on the one left out, each lock angle in
turn (leave one out); the lowest held-out RMS wins, a loop only if it beats no loop by MARGIN,
and the winner fitted on every locked run is kept only above its significance (hysteresis_fit).

Free runs:

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

from ..physics_vectorised import muscle_forces
from .fit_result import Estimate, GroupFit, NotIdentifiable
from .force_fit import fit_forces, usable_records
from .friction_fit import (
    LOOP_DRIVERS,
    NO_LOOP,
    Loop,
    filtered_pressures,
    fit_friction,
    free_runs,
    simulated_angles,
)
from .hysteresis_fit import (
    FORM_NAMES,
    LOCKED_FORMS,
    fit_hysteresis,
    low_passed,
    nominal_forces,
    unit_loops,
)

#: a loop must lower the held-out RMS by this fraction against the form without one
MARGIN = 0.05
#: and its band B_w, fitted on the whole runs, must exceed this many sigma
SIGNIFICANCE = 3.0
FOLDS = 2
CANDIDATES = (None, *LOOP_DRIVERS)           # None: no loop


def form_name(driver: str | None) -> str:
    return 'no loop' if driver is None else f'Bouc-Wen loop driven by the {driver}'


def locked_form_name(form: str | None) -> str:
    return 'no loop' if form is None else FORM_NAMES[form]


def held_out_torque(records, prior, elements: int, form: str | None) -> float:
    """N m: the torque RMS of `form` over each usable locked run, fitted on the others (inf when
    a fold cannot be fitted: too few lock angles left)."""
    used = usable_records(records)
    squares, count = 0.0, 0
    for j, rec in enumerate(used):
        others = used[:j] + used[j + 1:]
        try:
            if form is None:
                _, changes = fit_forces(others, prior)
                band, travel = 0.0, None
            else:
                _, changes, _, (band, travel) = fit_hysteresis(others, prior, elements, form)
        except NotIdentifiable:
            return float('inf')
        params = prior.replace(**changes)
        F1, F2 = muscle_forces(rec.psi, rec.P[:, 0], rec.P[:, 1], params)
        torque = params.r * np.cos(rec.psi) * (F1 - F2)
        if band != 0.0:
            pressures = [low_passed(rec)]
            torque = torque + band * unit_loops([rec], nominal_forces([rec], params, pressures),
                                                pressures, travel, elements,
                                                float(prior.P_out), float(prior.r), form)
        error = torque - rec.tau
        squares += float(np.sum(error ** 2))
        count += error.size
    return float(np.sqrt(squares / count)) if count else float('inf')


def fit_forces_and_loop(records, prior, elements: int):
    """The force coefficients and the loop form of the locked runs, chosen by their held-out
    torque RMS. Returns (the force fit, the Parameters changes, the loop's GroupFit, the kept
    loop as (form or None, B, travel))."""
    forms = (None, *LOCKED_FORMS)
    scores = {form: held_out_torque(records, prior, elements, form) for form in forms}
    if len(usable_records(records)) < 2 or not np.isfinite(scores[None]):
        best, why = 'maxwell', ('no held-out choice (too few lock angles to leave one out): '
                                'the Maxwell slip, kept by its significance')
    else:
        best, why = choose(scores, locked_form_name)
    if best is None:
        group, changes = fit_forces(records, prior)
        loop = GroupFit('hysteresis', (Estimate('hysteresis_band', 0.0, float('nan'), 0.0, 'N',
                                                'no loop chosen'),), group.residual_rms, 'N m',
                        group.samples, ())
        kept = (None, 0.0, None)
    else:
        group, changes, loop, (band, travel) = fit_hysteresis(records, prior, elements, best)
        kept = (best if band != 0.0 else None, band, travel)
    notes = tuple(f'{locked_form_name(f)}: held-out torque RMS {scores[f]:.4g} N m'
                  + (' <- chosen' if f == best else '') for f in forms)
    notes += (f'chosen: {locked_form_name(best)}: {why}',
              'leave one out: fitted on all locked runs but one, scored on that one')
    return group, changes, replace(loop, notes=loop.notes + notes), kept


def halves(runs) -> list:
    """[first halves, second halves] of the runs (each run cut at its middle sample)."""
    parts = [[], []]
    for rec in runs:
        middle = len(rec.t) // 2
        parts[0].append(rec.between(0, middle))
        parts[1].append(rec.between(middle, len(rec.t)))
    return parts


def held_out_rms(runs, params, hysteresis, driver: str | None, fixed: Loop = NO_LOOP) -> float:
    """deg: the angle RMS of `driver`'s form over each half of the runs, fitted on the other
    (fixed: a loop already identified, in the model joint of every form)."""
    folds = halves(runs)
    squares, count = 0.0, 0
    for k in range(FOLDS):
        fitted_on, scored_on = folds[k], folds[1 - k]
        try:
            _, changes, _, loop = fit_friction(fitted_on, params, hysteresis, driver,
                                               strict=False, fixed=fixed)
        except NotIdentifiable:
            return float('inf')
        inputs = [(r, filtered_pressures(r)) for r in scored_on]
        error = np.degrees(simulated_angles(inputs, params.replace(**changes), hysteresis, loop)
                           - np.concatenate([r.psi for r in scored_on]))
        squares += float(np.sum(error ** 2))
        count += error.size
    return float(np.sqrt(squares / count))


def choose(scores: dict, name=form_name) -> tuple[str | None, str]:
    """(the winning form, why) from {form: held-out RMS} (None: no loop), the free runs' and
    the locked runs' rule alike; name(form) names a form in the why."""
    best = min(scores, key=scores.get)
    plain = scores[None]
    if best is None:
        return None, 'no loop form fits the held-out data better'
    gain = 1.0 - scores[best] / plain if plain > 0.0 else 0.0
    if gain < MARGIN:
        return None, (f'the best loop ({name(best)}) lowers the held-out RMS by only '
                      f'{100 * gain:.1f} % (< {100 * MARGIN:g} %)')
    return best, (f'lowest held-out RMS, {100 * gain:.0f} % below the form without a loop '
                  f'(>= {100 * MARGIN:g} % needed)')


def fit_friction_and_loop(records, params, hysteresis=(0.0, 1, 1.0), fixed: Loop = NO_LOOP):
    """The friction coefficients and the loop form of the free runs, chosen by their held-out
    RMS. Returns (the friction fit, the Parameters changes, what was not identified, the form's
    GroupFit, the Loop: NO_LOOP when none won). fixed: a Bouc-Wen loop the locked runs chose,
    in the model joint of every form; the free runs then add none (one Bouc-Wen loop a joint)."""
    runs = free_runs(records)
    candidates = CANDIDATES if fixed.band == 0.0 else (None,)
    scores = {driver: held_out_rms(runs, params, hysteresis, driver, fixed)
              for driver in candidates}
    winner, why = choose(scores)
    group, changes, skipped, loop = fit_friction(runs, params, hysteresis, winner, fixed=fixed)
    band = next((e for e in group.estimates if e.name == 'bouc_wen_band'), None)
    if band is not None and not abs(band.value) > SIGNIFICANCE * band.std:
        why = (f'{form_name(winner)} won on held-out data, but its band over the whole runs, '
               f'{band.value:+.3g} +- {band.std:.2g} N, is below {SIGNIFICANCE:g} sigma: no '
               'loop kept')
        winner = None
        group, changes, skipped, loop = fit_friction(runs, params, hysteresis, None,
                                                     fixed=fixed)
    notes = tuple(f'{form_name(d)}: held-out angle RMS {scores[d]:.4g} deg'
                  + (' <- chosen' if d == winner else '') for d in candidates)
    if fixed.band != 0.0:
        notes += (f'the locked runs\' {form_name(fixed.driver)} (B_w {fixed.band:+.3g} N) is in '
                  'the model joint; no second Bouc-Wen loop is tried',)
    notes += (f'chosen: {form_name(winner)}: {why}',
              f'{FOLDS}-fold: fitted on one half of each free run, scored on the other')
    estimates = tuple(e for e in group.estimates if e.name.startswith('bouc_wen'))
    group = replace(group, estimates=tuple(e for e in group.estimates if e not in estimates))
    if not estimates:
        estimates = (Estimate('bouc_wen_band', 0.0, float('nan'), 0.0, 'N',
                              'no loop chosen'),)
    form = GroupFit('hysteresis form', estimates, scores[winner], 'deg', group.samples, notes)
    return group, changes, skipped, form, loop

