"""tracking_report: records a closed-loop run from the topics and reports it (the main job's end).

Subscribes reference, joint_measured (the true angle/torque of the simulated rig, or the
encoder/torque meter of a real one), estimate and valve_command for `duration` seconds, then
prints per reference step: the reference, the steady-state error against the MEASURED value (%
of the paper's 40 deg / 4 N m range), the settling time; the estimation error I / M / Q over the
whole record and after the initial `transient` (default 1 s); and writes a PNG like the paper's
Fig. 14 (reference, measured, estimate; valve voltages; errors).
Run `tracking_report --help`.
"""

from __future__ import annotations

import sys
from bisect import bisect_right

import numpy as np
from rclpy.node import Node
from rclpy.task import Future

from pam_common.diagnostics import OK, WARN, DiagnosticsPublisher
from pam_common.node_params import HARDWARE_ID_PARAM, ParamSpec, usage_text
from pam_common.node_skeleton import node_main, parameter_values
from pam_common.qos import RECORD_QOS
from pam_common.stamps import stamp_ns
from pam_common.topics import DEFAULT_NAMESPACE, ESTIMATE, JOINT_MEASURED, REFERENCE, VALVE_COMMAND
from pam_controller.step_metrics import ANGLE_SPAN, TORQUE_SPAN, step_report
from pam_interfaces.msg import JointEstimate, JointMeasurement, Reference, ValveCommand

from .json_file import write_json

NODE_NAME = 'tracking_report'
PARAMETERS = (
    ParamSpec('duration', 64.0, 'double', 's', 'How long to record after the start (see start).',
              range=(1.0, 86400.0)),
    ParamSpec('start', 'reference', 'string', '',
              "When the recording starts: 'reference', at the first reference received; "
              "'step', at the first change of the reference, so that a duration of whole holds "
              'of a stepped profile records whole holds only, whenever the report started '
              '(pam-demo), not a last hold cut short.', choices=('reference', 'step')),
    ParamSpec('plot', '', 'string', '', "PNG path for the figure; '': no figure."),
    ParamSpec('summary', '', 'string', '',
              "JSON path for the report's figures (per step and worst steady-state error in % of "
              "range and settling time in s, estimation I/M/Q whole and after the transient); "
              "'': none. Written to a temporary file, then renamed."),
    ParamSpec('title', 'Sensor-less PI tracking on the simulated rig', 'string', '',
              "The figure's title."),
    ParamSpec('transient', 1.0, 'double', 's',
              'The estimation error is also printed over t >= transient only (t from the first '
              'sample recorded); the headline line covers the whole record.',
              range=(0.0, 86400.0)),
    ParamSpec('startup_timeout', 120.0, 'double', 's',
              'Give up if no reference and measurement arrive within this time.',
              range=(1.0, 3600.0)),
    HARDWARE_ID_PARAM,
)
SUMMARY = ['Closed-loop tracking report (pam_controller): records reference, joint_measured,',
           'estimate and valve_command, then prints per-step metrics and writes a PNG.',
           "Default namespace '/pam'."]


class TrackingReport(Node):
    def __init__(self, **kwargs):
        kwargs.setdefault('namespace', DEFAULT_NAMESPACE)
        super().__init__(NODE_NAME, **kwargs)
        self.values = parameter_values(self, PARAMETERS)
        self.references = []        # (stamp ns, mode, value), in arrival order
        self.truth = {}             # stamp -> (angle, torque)
        self.estimates = {}         # stamp -> (angle, torque)
        self.commands = {}          # stamp -> (u1, u2)
        self.first_ns = None
        self.step_ns = None         # stamp of the first change of the reference (start 'step')
        self.finished = Future()
        self.create_subscription(Reference, REFERENCE, self._on_reference, RECORD_QOS)
        self.create_subscription(JointMeasurement, JOINT_MEASURED, self._on_truth, RECORD_QOS)
        self.create_subscription(JointEstimate, ESTIMATE, self._on_estimate, RECORD_QOS)
        self.create_subscription(ValveCommand, VALVE_COMMAND, self._on_command, RECORD_QOS)
        self._timeout = self.create_timer(self.values['startup_timeout'], self._on_timeout)
        DiagnosticsPublisher(self, 'tracking report', self.values['hardware_id'], self._report)
        self.get_logger().info(f"recording {self.values['duration']:g} s of tracking after the "
                               + ('first reference' if self.values['start'] == 'reference' else
                                  'first change of the reference'))

    def _on_timeout(self):
        self.destroy_timer(self._timeout)
        if self.first_ns is None and not self.finished.done():
            self.get_logger().error('no reference and measurement arrived: is the stack up?')
            self.finished.set_result(1)

    def _on_reference(self, msg: Reference):
        stamp = stamp_ns(msg.header.stamp)
        if self.step_ns is None and self.references and msg.value != self.references[-1][2]:
            self.step_ns = stamp
        self.references.append((stamp, msg.mode, msg.value))

    def _on_truth(self, msg: JointMeasurement):
        t = stamp_ns(msg.header.stamp)
        if not self.references:
            return
        if self.values['start'] == 'step' and (self.step_ns is None or t < self.step_ns):
            return
        if self.first_ns is None:
            self.first_ns = t
        self.truth[t] = (msg.angle, msg.torque)
        if (t - self.first_ns) * 1e-9 >= self.values['duration'] and not self.finished.done():
            self.finished.set_result(0)

    def _on_estimate(self, msg: JointEstimate):
        self.estimates[stamp_ns(msg.header.stamp)] = (msg.angle, msg.torque)

    def _on_command(self, msg: ValveCommand):
        self.commands[stamp_ns(msg.header.stamp)] = (msg.u1, msg.u2)

    def _report(self):
        """/diagnostics: the seconds recorded of `duration`, the samples of each topic; WARN
        while no reference and measurement arrived."""
        recorded = ((max(self.truth) - self.first_ns) * 1e-9 if self.truth else 0.0)
        values = {'recorded (s)': recorded, 'duration (s)': self.values['duration'],
                  'references': len(self.references), 'measurements': len(self.truth),
                  'estimates': len(self.estimates), 'valve commands': len(self.commands)}
        if self.first_ns is None:
            return WARN, 'waiting for a reference and a measurement', values
        if self.finished.done():
            return OK, 'recording done', values
        return OK, f"recording: {recorded:.1f} of {self.values['duration']:g} s", values

    def series(self):
        """t (s), mode, reference, measured, estimate (nan where missing), commands (N, 2)."""
        stamps = np.array(sorted(self.truth))
        refs = sorted(self.references)
        ref_stamps = [r[0] for r in refs]
        mode = refs[-1][1]
        index = [max(bisect_right(ref_stamps, s) - 1, 0) for s in stamps]
        reference = np.array([refs[i][2] for i in index])
        column = 0 if mode == Reference.ANGLE else 1
        measured = np.array([self.truth[s][column] for s in stamps])
        estimate = np.array([self.estimates.get(s, (np.nan, np.nan))[column] for s in stamps])
        commands = np.array([self.commands.get(s, (np.nan, np.nan)) for s in stamps])
        return (stamps - stamps[0]) * 1e-9, mode, reference, measured, estimate, commands

    def finish(self) -> int:
        """Exit code: the report's, or why there is none."""
        if self.finished.done() and self.finished.result() != 0:
            return self.finished.result()
        if self.first_ns is None:
            return 130                      # interrupted before anything was recorded
        return self.report(interrupted=not self.finished.done())

    def report(self, interrupted: bool = False) -> int:
        """Print the report; exit code 0, or 1 (130 if interrupted) when there is nothing to
        report: too few samples, or no reference held long enough to be a step."""
        from pam_model.metrics import after_transient, metrics
        nothing = 130 if interrupted else 1
        if len(self.truth) < 100:
            print('tracking_report: too few samples recorded', flush=True)
            return nothing
        t, mode, reference, measured, estimate, commands = self.series()
        angle = mode == Reference.ANGLE
        span, scale, unit = (ANGLE_SPAN, np.degrees(1.0), 'deg') if angle else (TORQUE_SPAN, 1.0,
                                                                                 'Nm')
        report = step_report(t, reference, measured, span, 2.0)
        if not report.steps:
            print(f'tracking_report: {t[-1]:.1f} s recorded, but no reference was held 2 s or '
                  'more: no step to report', flush=True)
            return nothing
        rate = (len(t) - 1) / max(t[-1], 1e-9)
        print(f'tracking report: {"angle" if angle else "torque"} mode, {t[-1]:.1f} s, '
              f'{len(t)} samples ({rate:.0f} Hz); errors against the measured value, % of the '
              f'{span * scale:.0f} {unit} range', flush=True)
        for line in report.lines(scale, unit):
            print('  ' + line, flush=True)
        ok = ~np.isnan(estimate)
        estimation = {}
        if ok.sum() > 1:
            m = metrics(measured[ok] * scale, estimate[ok] * scale)
            estimation['whole'] = m
            print(f'  estimation error ({ok.sum()} samples): {m.row(" " + unit)}', flush=True)
            transient = self.values['transient']
            late = ok & after_transient(t, transient)
            if late.sum() > 1:
                m = metrics(measured[late] * scale, estimate[late] * scale)
                estimation['after_transient'] = m
                print(f'  estimation error after t >= {transient:g} s ({late.sum()} samples): '
                      f'{m.row(" " + unit)}', flush=True)
            else:
                print(f'  estimation error after t >= {transient:g} s: fewer than 2 samples '
                      f'(the record spans {t[-1]:.1f} s)', flush=True)
        if self.values['plot']:
            path = plot_tracking(t, reference * scale, measured * scale, estimate * scale,
                                 commands, unit, self.values['plot'], self.values['title'])
            print(f'  figure: {path}', flush=True)
        if self.values['summary']:
            path = write_json(self.values['summary'], report_summary(
                'angle' if angle else 'torque', unit, t, report, scale, estimation,
                self.values['transient']))
            print(f'  summary: {path}', flush=True)
        return 0


def report_summary(mode: str, unit: str, t, report, scale: float, estimation: dict,
                   transient: float) -> dict:
    """The report's figures as plain data (the `summary` JSON): errors in % of range, times in
    s (inf for a step that never settled: null in the file), estimation I / M in `unit`, Q in %
    of the measured range."""
    return {
        'mode': mode, 'unit': unit, 'recorded_s': float(t[-1]), 'samples': len(t),
        'steps': [{'t_start_s': s.t_start, 'reference': s.reference * scale,
                   'steady_state_error_pct': s.steady_error, 'settling_time_s': s.settling_time,
                   'overshoot_pct': s.overshoot, 'ripple_pct': s.ripple} for s in report.steps],
        'worst_steady_state_error_pct': report.worst_error,
        'worst_settling_time_s': report.worst_settling,
        'estimation': {key: {'I': m.I, 'M': m.M, 'Q_pct': 100.0 * m.Q}
                       for key, m in estimation.items()},
        'transient_s': transient,
    }


def plot_tracking(t, reference, measured, estimate, commands, unit, path,
                  title='Sensor-less PI tracking on the simulated rig'):
    """The paper's Fig. 14 layout: tracking, valve voltages, errors."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(3, 1, figsize=(10, 8), sharex=True)
    axes[0].plot(t, reference, 'k--', lw=1.0, label='reference')
    axes[0].plot(t, measured, color='tab:blue', lw=1.0, label='measured')
    axes[0].plot(t, estimate, color='tab:green', lw=0.8, label='UKF estimate (feedback)')
    axes[0].set_ylabel(f'angle/torque ({unit})')
    axes[0].legend(loc='upper right', fontsize=8)
    axes[1].plot(t, commands[:, 0], color='tab:blue', lw=0.7, label='u1')
    axes[1].plot(t, commands[:, 1], color='tab:red', lw=0.7, label='u2')
    axes[1].set_ylabel('valve voltage (V)')
    axes[1].legend(loc='upper right', fontsize=8)
    axes[2].plot(t, reference - measured, color='tab:blue', lw=0.8, label='reference - measured')
    axes[2].plot(t, measured - estimate, color='tab:green', lw=0.8, label='measured - estimate')
    axes[2].axhline(0.0, color='0.5', lw=0.5)
    axes[2].set_ylabel(f'error ({unit})')
    axes[2].set_xlabel('time (s)')
    axes[2].legend(loc='upper right', fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def main(args=None) -> int:
    return node_main(TrackingReport, NODE_NAME, usage_text(NODE_NAME, SUMMARY, PARAMETERS), args)

if __name__ == '__main__':
    sys.exit(main())
