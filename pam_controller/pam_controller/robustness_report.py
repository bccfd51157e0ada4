"""pam-robustness's output: the figure table, the ranking of the effects, the JSON document and
the plots (matplotlib), from robustness.run_sweep's results. No ROS."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .robustness_plants import PARAMETERS

FIGURES = ('q_psi', 'q_tau', 'ss_error', 'settling')
FIGURE_LABELS = {'q_psi': 'Q_psi (%)', 'q_tau': 'Q_tau (%)',
                 'ss_error': 'worst steady-state error (% of range)',
                 'settling': 'worst settling (s)'}
HEADERS = {'q_psi': 'Qpsi%', 'q_tau': 'Qtau%', 'ss_error': 'ss%', 'settling': 'set s'}


def table_rows(results, estimators) -> list[dict]:
    """One row per (sweep row, magnitude): the figures per estimator; a Monte Carlo row gives two,
    the mean and the worst over its draws (statistic 'mean' / 'worst', else '')."""
    groups: dict = {}
    for result in results:
        groups.setdefault((result.plant.row, result.plant.magnitude), []).append(result)
    rows = []
    for (row, m), members in groups.items():
        stats = (('mean', np.mean), ('worst', np.max)) if row == PARAMETERS else (('', np.mean),)
        for statistic, reduce in stats:
            figures = {name: {f: float(reduce([r.figures[name][f] for r in members]))
                              for f in FIGURES} for name in estimators}
            rows.append({'row': row, 'magnitude': m, 'statistic': statistic,
                         'plants': len(members), 'figures': figures})
    return rows


def format_table(rows, estimators) -> str:
    """The table: per row and magnitude, Q_psi, Q_tau (%), ss error (% of range), settling (s)
    per estimator."""
    width = 4 * 7
    head = f'{"effect":<24} {"x":>4} ' + ' | '.join(f'{name:^{width}}' for name in estimators)
    sub = f'{"":<24} {"":>4} ' + ' | '.join(
        ''.join(f'{HEADERS[f]:>7}' for f in FIGURES) for _ in estimators)
    lines = [head, sub, '-' * len(sub)]
    for row in rows:
        label = row['row'] + (f' ({row["statistic"]} of {row["plants"]})' if row['statistic']
                              else '')
        cells = ' | '.join(''.join(_cell(row['figures'][name][f]) for f in FIGURES)
                           for name in estimators)
        lines.append(f'{label:<24} {row["magnitude"]:>4g} {cells}')
    return '\n'.join(lines)


def _cell(value: float) -> str:
    return f'{"never":>7}' if math.isinf(value) else f'{value:7.2f}'


def ranking(rows, estimator: str, magnitude: float = 1.0) -> list[dict]:
    """The rows (Monte Carlo: its mean) at `magnitude`, each figure's increase over the same
    row at magnitude 0, sorted by the largest of the Q and steady-state increases."""
    zero = {(r['row'], r['statistic']): r for r in rows if r['magnitude'] == 0.0}
    ranked = []
    for r in rows:
        base = zero.get((r['row'], r['statistic']))
        if r['magnitude'] != magnitude or base is None or r['statistic'] == 'worst':
            continue
        rise = {f: r['figures'][estimator][f] - base['figures'][estimator][f] for f in FIGURES}
        ranked.append({'row': r['row'], 'rise': rise,
                       'score': max(rise['q_psi'], rise['q_tau'], rise['ss_error'])})
    return sorted(ranked, key=lambda item: -item['score'])


def format_ranking(rows, estimators, magnitude: float = 1.0) -> str:
    lines = []
    for name in estimators:
        ranked = ranking(rows, name, magnitude)
        if not ranked:
            continue
        lines.append(f'what matters at {magnitude:g} x the realistic value, {name} estimator '
                     '(increase over magnitude 0: Q_psi / Q_tau / ss error, points of %):')
        lines += [f'  {i}. {item["row"]:<20} {item["rise"]["q_psi"]:+6.2f} / '
                  f'{item["rise"]["q_tau"]:+6.2f} / {item["rise"]["ss_error"]:+6.2f}'
                  for i, item in enumerate(ranked, start=1)]
    return '\n'.join(lines)


def json_document(settings, rows, results, timing, elapsed) -> dict:
    """The machine-readable results (--json): settings, the table rows, every plant, timing."""
    plants = [{'row': r.plant.row, 'magnitude': r.plant.magnitude, 'draw': r.plant.draw,
               'effects': r.plant.effects.describe(), 'figures': r.figures} for r in results]
    return {'base': settings.base.name, 'rows': list(settings.rows),
            'magnitudes': list(settings.magnitudes), 'monte_carlo': settings.monte_carlo,
            'seed': settings.seed, 'validation_duration_s': settings.validation_duration,
            'closed_loop_duration_s': settings.closed_loop_duration,
            'estimators': list(settings.estimators), 'gains': list(settings.gains),
            'table': _finite(rows), 'plants': _finite(plants), 'timing_s': timing,
            'elapsed_s': elapsed}


def _finite(value):
    """inf (a step that never settles) as None, for strict JSON."""
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_finite(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def plot(rows, estimators, directory) -> list[Path]:
    """robustness_<figure>.png per figure: the figure against magnitude, a line per row (the
    Monte Carlo row: its mean), one panel per estimator. Returns the paths written."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    names = list(dict.fromkeys(r['row'] for r in rows))
    paths = []
    for figure in FIGURES:
        fig, axes = plt.subplots(1, len(estimators), figsize=(5.5 * len(estimators), 4.2),
                                 sharey=True, squeeze=False)
        for ax, estimator in zip(axes[0], estimators, strict=True):
            for name in names:
                points = [(r['magnitude'], r['figures'][estimator][figure]) for r in rows
                          if r['row'] == name and r['statistic'] != 'worst']
                x, y = zip(*points, strict=True)
                ax.plot(x, [v if math.isfinite(v) else np.nan for v in y], marker='o',
                        label=name, lw=2.0 if name == 'all' else 1.2)
            ax.set_title(f'{estimator} estimator')
            ax.set_xlabel('magnitude (x the realistic value)')
            ax.grid(alpha=0.3)
        axes[0][0].set_ylabel(FIGURE_LABELS[figure])
        axes[0][-1].legend(fontsize=7)
        fig.tight_layout()
        path = directory / f'robustness_{figure}.png'
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    return paths
