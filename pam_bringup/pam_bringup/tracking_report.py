"""tracking_report: records a closed-loop run from the topics and reports it (the main job's end).

Subscribes reference, joint_measured (the true angle/torque of the simulated rig, or the
encoder/torque meter of a real one), estimate and valve_command for `duration` seconds, then
prints per reference step: the reference, the steady-state error against the MEASURED value (%
of the paper's 40 deg / 4 N m range), the settling time; the estimation error I / M / Q over the
whole record and after the initial `transient` (default 1 s); and writes a PNG like the paper's
Fig. 14 (reference, measured, estimate; valve voltages; errors).

Real-time health (pam_common.run_health): figures of a loop that did not run in time are not
results. When the recording starts, the report calls the rig's `~/reset_statistics`
(`<namespace>/<rig>/reset_statistics`, std_srvs/Trigger, asynchronously; the parameter `rig`,
'sim_node', or 'driver_node' on the real rig), keeps the rig's latest /diagnostics status, and
counts the estimate's sample counters (JointEstimate.sample) over the record: the samples the rig
sent (last - first + 1) against those received. At the end it waits up to 3 s for a rig status
taken after the record, judges the run and prints the health beside the figures; the summary
JSON carries it ('health', with 'valid'). An INVALID run (late rig samples, a long stall, a late
sample -> command latency, late commands, lost samples, or no rig status at all) is printed
with a first line 'tracking_report: INVALID run: ...; the figures below are NOT results', its
figure's title marked INVALID.

Exit codes: 0 a valid report; 1 no report (nothing arrived, too few samples, no step) or an
INVALID run (the figures and the JSON are still written, marked); 2 bad parameters; 130
interrupted (what was recorded is reported).
Run `tracking_report --help`.
"""

from __future__ import annotations

import sys
import time
from bisect import bisect_right
from dataclasses import dataclass

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from rclpy.task import Future
from std_srvs.srv import Trigger

from pam_common.diagnostics import OK, WARN, DiagnosticsPublisher, status_node, status_values
from pam_common.node_params import (
    HARDWARE_ID_PARAM,
    NodeConfig,
    ParamSpec,
    check_all,
    usage_text,
)
from pam_common.node_skeleton import node_main, parameter_values
from pam_common.qos import RECORD_QOS
from pam_common.run_health import counter_gaps, judge_run
from pam_common.stamps import stamp_ns
from pam_common.topics import (
    DEFAULT_NAMESPACE,
    DIAGNOSTICS,
    ESTIMATE,
    JOINT_MEASURED,
    REFERENCE,
    VALVE_COMMAND,
)
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
    ParamSpec('loop_wait', 10.0, 'double', 's',
              'The recording starts only once estimate and valve_command have a publisher '
              '(discovery can take seconds, over a network more), so that every sample recorded '
              'has its estimate; after this long without one, it starts without it (a loop with '
              'no estimator), with a warning. 0: do not wait.', range=(0.0, 3600.0)),
    ParamSpec('rig', 'sim_node', 'string', '',
              "The rig node's name in the report's namespace whose /diagnostics and "
              "~/reset_statistics give the run's real-time health; 'driver_node' on the real "
              'rig.'),
    HARDWARE_ID_PARAM,
)
SUMMARY = ['Closed-loop tracking report (pam_controller): records reference, joint_measured,',
           'estimate and valve_command, then prints per-step metrics and writes a PNG.',
           "Judges the run's real-time health from the rig's /diagnostics: an INVALID run",
           '(not real time) is marked so and exits 1.',
           'Exit codes: 0 a valid report, 1 no report or an INVALID run, 2 bad parameters,',
           "130 interrupted. Default namespace '/pam'."]
RIG_STATUS_WAIT = 3.0       # s after the record for a rig status taken after it
RESET_SERVICE_WAIT = 5.0    # s after the start of the record for the rig's ~/reset_statistics


@dataclass(frozen=True)
class ReportConfig(NodeConfig):
    """tracking_report's checked parameters (the table above: units, ranges, defaults)."""

    duration: float
    start: str
    plot: str
    summary: str
    title: str
    transient: float
    startup_timeout: float
    loop_wait: float
    rig: str
    hardware_id: str


def build_config(values: dict) -> ReportConfig:
    """Check the values against the table; ConfigError names the parameter."""
    return ReportConfig.from_values(check_all(PARAMETERS, values))


class TrackingReport(Node):
    def __init__(self, **kwargs):
        kwargs.setdefault('namespace', DEFAULT_NAMESPACE)
        super().__init__(NODE_NAME, **kwargs)
        self.config = parameter_values(self, PARAMETERS, check=build_config)
        self.references = []        # (stamp ns, mode, value), in arrival order
        self.truth = {}             # stamp -> (angle, torque)
        self.estimates = {}         # stamp -> (angle, torque)
        self.estimate_samples = {}  # stamp -> the estimate's sample counter (0: not counted)
        self.rig_name = (self.get_namespace().rstrip('/') + '/' + self.config.rig)
        self.rig_status = None      # (monotonic receive time, key/values) of the rig's latest
        self.end_time = None        # monotonic time the record ended
        self._reset_client = None
        self._reset_timer = None
        self._reset_started = None
        self._wait_timer = None
        self.commands = {}          # stamp -> (u1, u2)
        self.first_ns = None
        self.step_ns = None         # stamp of the first change of the reference (start 'step')
        self.finished = Future()
        self.create_subscription(Reference, REFERENCE, self._on_reference, RECORD_QOS)
        self.create_subscription(JointMeasurement, JOINT_MEASURED, self._on_truth, RECORD_QOS)
        self._loop_topics = (
            self.create_subscription(JointEstimate, ESTIMATE, self._on_estimate, RECORD_QOS),
            self.create_subscription(ValveCommand, VALVE_COMMAND, self._on_command, RECORD_QOS))
        self._loop_wait_since = None    # monotonic time the record could first have started
        self.create_subscription(DiagnosticArray, DIAGNOSTICS, self._on_diagnostics, RECORD_QOS)
        self._timeout = self.create_timer(self.config.startup_timeout, self._on_timeout)
        DiagnosticsPublisher(self, 'tracking report', self.config.hardware_id, self._report)
        self.get_logger().info(f"recording {self.config.duration:g} s of tracking after the "
                               + ('first reference' if self.config.start == 'reference' else
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
        if self.config.start == 'step' and (self.step_ns is None or t < self.step_ns):
            return
        if self.end_time is not None:
            return
        if self.first_ns is None:
            if not self._loop_published():
                return
            self.first_ns = t
            self._reset_rig_statistics()
        self.truth[t] = (msg.angle, msg.torque)
        if (t - self.first_ns) * 1e-9 >= self.config.duration and not self.finished.done():
            self.end_time = time.monotonic()     # wait for a rig status taken after the record
            self._wait_timer = self.create_timer(0.05, self._wait_for_rig_status)

    def _loop_published(self) -> bool:
        """True once estimate and valve_command have a publisher, or loop_wait s after the
        record could first have started (then with a warning naming what has none)."""
        missing = [s.topic_name for s in self._loop_topics if s.get_publisher_count() == 0]
        if not missing:
            return True
        now = time.monotonic()
        if self._loop_wait_since is None:
            self._loop_wait_since = now
            if self.config.loop_wait > 0.0:
                self.get_logger().info(f"waiting for a publisher of {', '.join(missing)} "
                                       f'(up to {self.config.loop_wait:g} s) before recording')
        if now - self._loop_wait_since < self.config.loop_wait:
            return False
        self.get_logger().warning(f"no publisher of {', '.join(missing)}: recording without "
                                  + ('it' if len(missing) == 1 else 'them'))
        return True

    def _wait_for_rig_status(self):
        fresh = self.rig_status is not None and self.rig_status[0] > self.end_time
        if (fresh or time.monotonic() - self.end_time > RIG_STATUS_WAIT) \
                and not self.finished.done():
            if not fresh:
                self.get_logger().warning(
                    f'no /diagnostics from {self.rig_name} within {RIG_STATUS_WAIT:g} s after '
                    'the record: judging its latest status' if self.rig_status else
                    f'no /diagnostics from {self.rig_name}: real-time health unknown')
            self.destroy_timer(self._wait_timer)
            self.finished.set_result(0)

    def _reset_rig_statistics(self):
        """Start the rig's timing and latency totals afresh at the start of the record, without
        blocking: the call is made once the service is there (a few seconds at most)."""
        service = f'{self.rig_name}/reset_statistics'
        self._reset_client = self.create_client(Trigger, service)
        self._reset_started = time.monotonic()

        def poll():
            if self._reset_client.service_is_ready():
                self.destroy_timer(self._reset_timer)
                future = self._reset_client.call_async(Trigger.Request())
                future.add_done_callback(lambda f: self.get_logger().info(
                    f'{service}: ' + (f.result().message if f.result() is not None
                                      else 'no answer')))
            elif time.monotonic() - self._reset_started > RESET_SERVICE_WAIT:
                self.destroy_timer(self._reset_timer)
                self.get_logger().warning(
                    f'no service {service} within {RESET_SERVICE_WAIT:g} s: the rig\'s '
                    'statistics count from its start, not from the record\'s')
        self._reset_timer = self.create_timer(0.1, poll)

    def _on_diagnostics(self, msg: DiagnosticArray):
        for status in msg.status:
            if status_node(status.name) == self.rig_name:
                self.rig_status = (time.monotonic(), status_values(status))

    def _on_estimate(self, msg: JointEstimate):
        stamp = stamp_ns(msg.header.stamp)
        self.estimates[stamp] = (msg.angle, msg.torque)
        self.estimate_samples[stamp] = msg.sample

    def _on_command(self, msg: ValveCommand):
        self.commands[stamp_ns(msg.header.stamp)] = (msg.u1, msg.u2)

    def _report(self):
        """/diagnostics: the seconds recorded of `duration`, the samples of each topic; WARN
        while no reference and measurement arrived."""
        recorded = ((max(self.truth) - self.first_ns) * 1e-9 if self.truth else 0.0)
        values = {'recorded (s)': recorded, 'duration (s)': self.config.duration,
                  'references': len(self.references), 'measurements': len(self.truth),
                  'estimates': len(self.estimates), 'valve commands': len(self.commands)}
        if self.first_ns is None:
            return WARN, 'waiting for a reference and a measurement', values
        if self.finished.done():
            return OK, 'recording done', values
        return OK, f"recording: {recorded:.1f} of {self.config.duration:g} s", values

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

    def health(self):
        """The run's real-time health (pam_common.run_health.RunHealth): the rig's latest
        status, the estimate's sample counters over the record (first to last truth stamp)."""
        first, last = min(self.truth), max(self.truth)
        counters = [k for s, k in self.estimate_samples.items() if first <= s <= last and k]
        expected = max(counters) - min(counters) + 1 if counters else 0
        return judge_run(self.rig_status[1] if self.rig_status else None, len(set(counters)),
                         expected)

    def lost_where(self) -> str | None:
        """Where the samples lost at the report are in the record (the gaps in the estimate's
        sample counters between the first and the last truth stamps), or None if none was lost."""
        first, last = min(self.truth), max(self.truth)
        stamps = {k: s for s, k in self.estimate_samples.items() if first <= s <= last and k}
        gaps = counter_gaps(stamps)
        if not gaps:
            return None
        before, lost = max(gaps, key=lambda gap: gap[1])
        return (f'samples lost at the report in {len(gaps)} gap(s); the longest: {lost} samples '
                f'after {(stamps[before] - first) * 1e-9:.2f} s of the record')

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
        health = self.health()
        if not health.valid:
            print(f'tracking_report: INVALID run: {health.headline} ('
                  + '; '.join(health.reasons) + '); the figures below are NOT results',
                  flush=True)
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
            transient = self.config.transient
            late = ok & after_transient(t, transient)
            if late.sum() > 1:
                m = metrics(measured[late] * scale, estimate[late] * scale)
                estimation['after_transient'] = m
                print(f'  estimation error after t >= {transient:g} s ({late.sum()} samples): '
                      f'{m.row(" " + unit)}', flush=True)
            else:
                print(f'  estimation error after t >= {transient:g} s: fewer than 2 samples '
                      f'(the record spans {t[-1]:.1f} s)', flush=True)
        print(f'  measurements received: {len(self.truth)}', flush=True)
        for line in health.lines():
            print('  ' + line, flush=True)
        where = self.lost_where()
        if where:
            print('  ' + where, flush=True)
        if self.config.plot:
            title = self.config.title + ('' if health.valid else
                                            f' - INVALID: {health.headline}, not a result')
            path = plot_tracking(t, reference * scale, measured * scale, estimate * scale,
                                 commands, unit, self.config.plot, title)
            print(f'  figure: {path}', flush=True)
        if self.config.summary:
            summary = report_summary('angle' if angle else 'torque', unit, t, report, scale,
                                     estimation, self.config.transient)
            summary['measurements'] = len(self.truth)
            summary['health'] = health.as_dict()
            summary['valid'] = health.valid
            path = write_json(self.config.summary, summary)
            print(f'  summary: {path}', flush=True)
        if interrupted:
            return 130
        return 0 if health.valid else 1


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
