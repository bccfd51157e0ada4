"""The whole identification: the four fits in the paper's order (kappa before the transients it
drives), the parameter set and valve map they give, and a printable report.

identify() raises IdentificationError listing everything the runs lack (and which parameters each
gap leaves unidentified) unless partial=True, in which case those parameters keep their prior
values and the report says so. The result is a complete, validated parameter set either way.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..effects import Effects
from ..model_extensions import NO_EXTENSIONS
from ..parameters import ParameterError, Parameters, validate_parameters
from ..valve_map import ValveMap
from .fit_result import Estimate, GroupFit, NotIdentifiable
from .flow_fit import fit_flow
from .force_fit import fit_forces, intercept_combinations
from .friction_fit import NO_LOOP, PARAMETERS as FRICTION_PARAMETERS, Loop, fit_friction
from .loop_fit import fit_forces_and_loop, fit_friction_and_loop
from .sensor_fit import corrected, fit_sensors
from .valve_fit import fit_valve_map

#: The valve spool's lag is not fitted: at 1 kHz, 5 ms of lag against pressure time constants of
#: 0.1-4 s changes the transients by less than the sensor noise (invisible).
VALVE_LAG_NOTE = ('not identified: a spool lag of a few ms is invisible against the 0.1-4 s '
                  'pressure transients of the calibration runs; kept 0')


class IdentificationError(ValueError):
    """The runs cannot identify what was asked; the message lists each gap."""


@dataclass(frozen=True)
class Identification:
    """params: the identified set (prior values where not identified); valve_map: kappa(u);
    fits: the GroupFit of each fit that ran; missing: the gaps (NotIdentifiable) left at prior;
    extensions: the estimator's extensions identified (pam_model.model_extensions; none when
    the fit was off or nothing was seen)."""

    params: Parameters
    valve_map: ValveMap
    fits: tuple
    missing: tuple
    extensions: Effects = NO_EXTENSIONS

    @property
    def complete(self) -> bool:
        return not self.missing


def describe_missing(missing) -> str:
    return '\n'.join(f'  - {m.what} [not identified: {", ".join(m.parameters)}]'
                     for m in missing)


def identify(records, prior: Parameters, prior_map: ValveMap, partial: bool = False,
             log=lambda line: None, extensions: bool = True) -> Identification:
    """Identify from CalibrationRecords, starting from `prior` and `prior_map`.

    extensions: also identify the estimator's extensions where the runs reveal them (sensor
    offsets from the vented holds, first: the other fits then see corrected pressures; the force
    hysteresis with the force coefficients; the form of a loop the free runs show (none, or a
    Bouc-Wen loop driven by the length or the pressure) with the friction, chosen on held-out
    data (loop_fit); the dead volume with the valve areas); each stays 0 unless it is seen above
    its fit's significance or wins on held-out data. False: the paper's model only."""
    missing, fits = [], []
    changes = {}
    found = {}

    def attempt(name, fit):
        """Run one fit: what it returns after its GroupFit, or None when not identifiable."""
        log(f'fitting {name} ...')
        try:
            group, *rest = fit()
        except NotIdentifiable as gap:
            missing.append(gap)
            log(f'  {name}: not identified: {gap.what}')
            return None
        fits.append(group)
        return rest

    elements = NO_EXTENSIONS.hysteresis_elements
    hysteresis = (0.0, elements, NO_EXTENSIONS.hysteresis_travel)
    fixed = NO_LOOP                  # a Bouc-Wen loop the locked runs chose
    if extensions:
        sensors = attempt('sensor offsets', lambda: fit_sensors(records, prior))
        if any(sensors[0]):
            found['sensor_offset'] = sensors[0]
            records = corrected(records, *sensors)
        forces = attempt('force coefficients and the loop form',
                         lambda: fit_forces_and_loop(records, prior, elements))
        if forces:
            fits.append(forces[1])
            form, band, travel = forces[2]
            if form == 'maxwell':
                found.update(hysteresis_band=band, hysteresis_travel=travel)
                hysteresis = (band, elements, travel)
            elif form == 'pressure':
                fixed = Loop(band, 'pressure', travel)
                found.update(fixed.effects())
    else:
        forces = attempt('force coefficients', lambda: fit_forces(records, prior))
    if forces:
        changes.update(forces[0])
        forced = prior.replace(**changes)
        if extensions:
            friction = attempt('friction and the loop form',
                               lambda: fit_friction_and_loop(records, forced, hysteresis, fixed))
        else:
            friction = attempt('friction', lambda: fit_friction(records, forced, hysteresis))
        if friction:
            changes.update(friction[0])
            missing.extend(friction[1])
        if friction and extensions:
            fits.append(friction[2])
            found.update(friction[3].effects())      # the fixed loop's again, or the free runs'

    else:
        missing.append(NotIdentifiable('mu_s and mu_p need the force coefficients identified '
                                       'first (the friction fit compares angles the forces set)',
                                       FRICTION_PARAMETERS))
    kappa = attempt('valve map kappa(u)', lambda: fit_valve_map(records, prior, prior_map))
    valve_map = kappa[0] if kappa else prior_map
    flow = attempt('valve areas and k2' + (' and dead volume' if extensions else ''),
                   lambda: fit_flow(records, prior, valve_map, dead_volume=extensions))
    if flow:
        changes.update(flow[0])
        missing.extend(flow[1])
        if extensions and flow[2] > 0.0:
            found['dead_volume'] = flow[2]
    if extensions:
        fits.append(GroupFit('valve lag', (Estimate('valve_time_constant', 0.0, float('nan'),
                                                    0.0, 's', VALVE_LAG_NOTE),), 0.0, 's', 0))
    if missing and not partial:
        raise IdentificationError('the calibration runs cannot identify everything:\n'
                                  + describe_missing(missing)
                                  + '\n(add the runs named above, or use partial '
                                    'identification to keep those parameters at their prior '
                                    'values)')
    try:
        params = validate_parameters(prior.replace(**changes), 'identified parameters')
    except ParameterError as exc:
        raise IdentificationError(f'the fits gave an impossible parameter set: {exc}') from exc
    return Identification(params, valve_map, tuple(fits), tuple(missing), Effects(**found))


def _format_value(value: float) -> str:
    return f'{value:11.5g}' if math.isfinite(value) else f'{"-":>11}'


EXTENSION_NAMES = ('valve_time_constant', 'dead_volume', 'hysteresis_band', 'hysteresis_travel',
                   'bouc_wen_band', 'bouc_wen_length_travel', 'bouc_wen_pressure_travel',
                   'sensor_offset', 'sensor_gain_error')


def true_value(name: str, truth: Parameters, truth_map: ValveMap | None, prior: Parameters,
               truth_effects: Effects | None = None):
    """The plant's value of a reported quantity (effective areas: k1_true A_true / k1_prior;
    extensions: the plant's effects, none when truth_effects is None)."""
    key, _, sensor = name.partition(' P')
    if key in EXTENSION_NAMES:
        effects = truth_effects if truth_effects is not None else NO_EXTENSIONS
        if key == 'hysteresis_travel' and not effects.hysteresis_band:
            return math.nan
        if key.startswith('bouc_wen_') and key.endswith('_travel') and (
                not effects.bouc_wen_band or key != f'bouc_wen_{effects.bouc_wen_driver}_travel'):
            return math.nan
        value = getattr(effects, key)
        return float(value[int(sensor) - 1]) if sensor else float(value)
    if name.startswith('kappa('):
        return float(truth_map(float(name[6:].split()[0]))) if truth_map is not None else math.nan
    if name == 'w1(L0) - w2(L0)':
        return intercept_combinations(truth)[0]
    if name == 'pam1.p_w1 + pam2.p_w1':
        return intercept_combinations(truth)[1]
    section, _, key = name.rpartition('.')
    field = f'{key}_{section[-1]}' if section else key
    value = getattr(truth, field)
    if key in ('A1', 'A2'):
        value *= truth.k1 / prior.k1
    return value


def format_report(ident: Identification, prior: Parameters, truth: Parameters | None = None,
                  truth_map: ValveMap | None = None, truth_effects: Effects | None = None) -> str:
    """The estimates of every fit (prior, identified +- 1 sigma, and the truth when known: the
    plant's parameters, valve map and unmodelled effects), then the extensions kept."""
    head = f'{"quantity":<26}{"unit":<9}{"prior":>11}{"identified":>12}{"+- 1 sigma":>12}'
    if truth is not None:
        head += f'{"true":>12}{"error":>9}'
    lines = []
    for fit in ident.fits:
        lines += ['', (f'[{fit.group}] residual RMS {fit.residual_rms:.4g} {fit.residual_unit} '
                       f'over {fit.samples} samples') if fit.residual_rms > 0.0 else
                  f'[{fit.group}] from {fit.samples} settled holds' if fit.samples else
                  f'[{fit.group}]', head]
        for e in fit.estimates:
            row = (f'{e.name:<26}{e.unit:<9}{_format_value(e.prior)} {_format_value(e.value)} '
                   f'{_format_value(e.std)}')
            if truth is not None:
                true = true_value(e.name, truth, truth_map, prior, truth_effects)
                err = (e.value - true) / abs(true) if true else math.nan
                row += f' {_format_value(true)} {100 * err:7.2f}%' if math.isfinite(err) else \
                    f' {_format_value(true)} {"-":>8}'
            if e.note:
                row += f'   ({e.note})'
            lines.append(row)
        lines += [f'  note: {n}' for n in fit.notes]
    if ident.missing:
        lines += ['', 'NOT identified (prior values kept):', describe_missing(ident.missing)]
    if any(f.group in ('sensors', 'hysteresis', 'hysteresis form') for f in ident.fits):
        lines += ['', f'extensions kept (extensions.yaml): {ident.extensions.describe()}']
    return '\n'.join(lines).lstrip('\n')



def expected_fits(model, runs, extensions: bool = True) -> Identification:
    """What a planned campaign would identify, expected at the prior: `runs`, the campaign
    simulated on `model` (the prior: its parameters, valve map and the paper's equations) and
    read through the transducers' noise and ADC (campaign.simulate_campaign with the sensor),
    identified from that same prior (partial). Each Estimate's std is then the fit's own 1-sigma
    at the prior (its Jacobian and the residuals the noise leaves: the Fisher information of the
    fit), and `missing` lists what the campaign cannot identify at all. A lab reads it before
    running anything on its rig."""
    from .campaign import records_of
    return identify(records_of(runs), model.params, model.valve_map, partial=True,
                    extensions=extensions)


def format_plan(ident: Identification) -> str:
    """expected_fits' result as a table: each identified quantity's prior value, expected 1-sigma
    and its size relative to the value, then what the campaign leaves unidentified."""
    lines = [f'{"quantity":<26}{"unit":<9}{"prior":>11}{"expected 1 sigma":>18}{"relative":>10}']
    for fit in ident.fits:
        lines.append(f'{fit.group}:')
        for e in fit.estimates:
            if not math.isfinite(e.std):
                lines.append(f'  {e.name:<24}{e.unit:<9}{_format_value(e.prior)}'
                             f'{"-":>18}{"":>10}  {e.note}')
                continue
            relative = abs(e.std / e.prior) if e.prior else math.inf
            text = f'{100.0 * relative:9.3g}%' if math.isfinite(relative) else f'{"-":>10}'
            lines.append(f'  {e.name:<24}{e.unit:<9}{_format_value(e.prior)}'
                         f'{e.std:18.4g}{text}')
    if ident.missing:
        lines.append('not identifiable with this campaign (kept at the prior):')
        lines.append(describe_missing(ident.missing))
    return '\n'.join(lines)
