"""The whole identification: the four fits in the paper's order (kappa before the transients it
drives), the parameter set and valve map they give, and a printable report.

identify() raises IdentificationError listing everything the runs lack (and which parameters each
gap leaves unidentified) unless partial=True, in which case those parameters keep their prior
values and the report says so. The result is a complete, validated parameter set either way.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..parameters import ParameterError, Parameters, validate_parameters
from ..valve_map import ValveMap
from .fit_result import NotIdentifiable
from .flow_fit import fit_flow
from .force_fit import fit_forces, intercept_combinations
from .friction_fit import PARAMETERS as FRICTION_PARAMETERS, fit_friction
from .valve_fit import fit_valve_map


class IdentificationError(ValueError):
    """The runs cannot identify what was asked; the message lists each gap."""


@dataclass(frozen=True)
class Identification:
    """params: the identified set (prior values where not identified); valve_map: kappa(u);
    fits: the GroupFit of each fit that ran; missing: the gaps (NotIdentifiable) left at prior."""

    params: Parameters
    valve_map: ValveMap
    fits: tuple
    missing: tuple

    @property
    def complete(self) -> bool:
        return not self.missing


def describe_missing(missing) -> str:
    return '\n'.join(f'  - {m.what} [not identified: {", ".join(m.parameters)}]'
                     for m in missing)


def identify(records, prior: Parameters, prior_map: ValveMap, partial: bool = False,
             log=lambda line: None) -> Identification:
    """Identify from CalibrationRecords, starting from `prior` and `prior_map`."""
    missing, fits = [], []
    changes = {}

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

    forces = attempt('force coefficients', lambda: fit_forces(records, prior))
    if forces:
        changes.update(forces[0])
        friction = attempt('friction', lambda: fit_friction(records, prior.replace(**changes)))
        if friction:
            changes.update(friction[0])
            missing.extend(friction[1])
    else:
        missing.append(NotIdentifiable('mu_s and mu_p need the force coefficients identified '
                                       'first (the friction fit compares angles the forces set)',
                                       FRICTION_PARAMETERS))
    kappa = attempt('valve map kappa(u)', lambda: fit_valve_map(records, prior, prior_map))
    valve_map = kappa[0] if kappa else prior_map
    flow = attempt('valve areas and k2', lambda: fit_flow(records, prior, valve_map))
    if flow:
        changes.update(flow[0])
        missing.extend(flow[1])
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
    return Identification(params, valve_map, tuple(fits), tuple(missing))


def _format_value(value: float) -> str:
    return f'{value:11.5g}' if math.isfinite(value) else f'{"-":>11}'


def true_value(name: str, truth: Parameters, truth_map: ValveMap | None, prior: Parameters):
    """The plant's value of a reported quantity (effective areas: k1_true A_true / k1_prior)."""
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
                  truth_map: ValveMap | None = None) -> str:
    """The estimates of every fit (prior, identified +- 1 sigma, and the truth when known)."""
    head = f'{"quantity":<24}{"unit":<9}{"prior":>11}{"identified":>12}{"+- 1 sigma":>12}'
    if truth is not None:
        head += f'{"true":>12}{"error":>9}'
    lines = []
    for fit in ident.fits:
        lines += ['', f'[{fit.group}] residual RMS {fit.residual_rms:.4g} {fit.residual_unit} '
                      f'over {fit.samples} samples', head]
        for e in fit.estimates:
            row = (f'{e.name:<24}{e.unit:<9}{_format_value(e.prior)} {_format_value(e.value)} '
                   f'{_format_value(e.std)}')
            if truth is not None:
                true = true_value(e.name, truth, truth_map, prior)
                err = (e.value - true) / abs(true) if true else math.nan
                row += f' {_format_value(true)} {100 * err:7.2f}%' if math.isfinite(err) else \
                    f' {_format_value(true)} {"-":>8}'
            if e.note:
                row += f'   ({e.note})'
            lines.append(row)
        lines += [f'  note: {n}' for n in fit.notes]
    if ident.missing:
        lines += ['', 'NOT identified (prior values kept):', describe_missing(ident.missing)]
    return '\n'.join(lines).lstrip('\n')

