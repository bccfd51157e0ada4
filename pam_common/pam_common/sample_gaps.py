"""SampleGaps: the rig's samples lost on their way to a consumer, from the rig's sample counter
(pam_interfaces/Pressures.sample, carried on in JointEstimate.sample). No ROS in here.

The counter is 1 for the rig's first sample and +1 per sample; 0 means "not counted" (a
publisher that does not set it). Each counter value received is one of:

* the next one (last + 1): in order;
* further ahead: a *gap*; the samples in between are *lost* (a subscriber's keep-last queue
  overflowing, frames lost on the serial line, a non-finite sample the rig suppressed);
* equal to the last one: a *repeat* (a lockstep rig re-publishing its current sample, the
  estimator repeating its estimate for a duplicate stamp), not a loss;
* behind the last one: a *late* sample (reordered) if it is one of the missing samples of the
  last TRACKED_GAPS gaps (it is taken back out of the lost count), else a repeat of an older one;
* 1 after a later one, or more than RESTART_DISTANCE behind: the rig *restarted* (a bag
  replayed again, a new simulator): counted, the count goes on from there;
* 0: counted as *uncounted*, nothing checked.

/diagnostics: report(warn_ratio), a check for DiagnosticsPublisher.add_check: the values below
and, when the loss in the last diagnostics period exceeds warn_ratio * (the samples due in that
period), a WARN 'samples lost: ...'.
"""

from __future__ import annotations

from dataclasses import dataclass

from pam_common.node_params import ParamSpec

RESTART_DISTANCE = 1000     # samples back: farther than this, the rig restarted
TRACKED_GAPS = 64           # recent gaps whose missing samples a late sample is looked up in

#: The parameter of ukf_node and pi_node that sets the WARN threshold of problem().
WARN_RATIO_PARAM = ParamSpec(
    'lost_samples_warn_ratio', 0.001, 'double', '',
    "Diagnostics go WARN when more than this fraction of the rig's samples due in the last "
    'diagnostics period was lost (gaps in the sample counter); 0: any loss.', range=(0.0, 1.0))


@dataclass
class PeriodLoss:
    """The samples of one diagnostics period: lost (gaps) and due (received in order + lost)."""

    lost: int
    due: int


class SampleGaps:
    """Counts the gaps in a stream of sample counters (see the module docstring)."""

    def __init__(self):
        self.last: int | None = None
        self.received = 0       # counted samples received (repeats included)
        self.lost = 0
        self.gaps = 0
        self.repeats = 0
        self.late = 0
        self.restarts = 0
        self.uncounted = 0
        self._missing: list[list[int]] = []   # [first, end) of recent gaps, oldest first
        self._period_start = (0, 0, 0)         # (lost, received, repeats) at the period start

    def update(self, sample: int) -> int:
        """Record one received counter; returns the number of samples lost just before it."""
        if sample == 0:
            self.uncounted += 1
            return 0
        self.received += 1
        last = self.last
        if last is None or sample == last + 1:
            self.last = sample
            return 0
        if sample == last:
            self.repeats += 1
            return 0
        if sample > last:
            missing = sample - last - 1
            self.lost += missing
            self.gaps += 1
            self._missing.append([last + 1, sample])
            del self._missing[:-TRACKED_GAPS]
            self.last = sample
            return missing
        if sample == 1 or last - sample > RESTART_DISTANCE:
            self.restarts += 1
            self._missing.clear()
            self.last = sample
            return 0
        if self._take_back(sample):
            self.late += 1
        else:
            self.repeats += 1
        return 0

    def _take_back(self, sample: int) -> bool:
        """A late sample: remove it from the recorded gaps (True) if it was missing there."""
        for i, (first, end) in enumerate(self._missing):
            if first <= sample < end:
                pieces = [r for r in ([first, sample], [sample + 1, end]) if r[0] < r[1]]
                self._missing[i:i + 1] = pieces
                self.lost -= 1
                return True
        return False

    def take_period(self) -> PeriodLoss:
        """The loss since the last call (one diagnostics period)."""
        lost0, received0, repeats0 = self._period_start
        self._period_start = (self.lost, self.received, self.repeats)
        lost = max(self.lost - lost0, 0)
        in_order = (self.received - received0) - (self.repeats - repeats0)
        return PeriodLoss(lost, max(in_order, 0) + lost)

    def values(self) -> dict:
        """The /diagnostics key/values."""
        return {'samples lost': self.lost, 'sample gaps': self.gaps,
                'repeated samples': self.repeats, 'late samples (reordered)': self.late,
                'sample counter restarts': self.restarts,
                'samples without counter': self.uncounted}

    def problem(self, warn_ratio: float) -> str:
        """'' or the WARN message about the last period's loss (ends the period)."""
        period = self.take_period()
        if period.lost and period.lost > warn_ratio * period.due:
            return (f'samples lost: {period.lost} of {period.due} in the last period '
                    f'({self.lost} since start)')
        return ''

    def report(self, warn_ratio: float) -> tuple:
        """(level, problem, values) for DiagnosticsPublisher.add_check (ends the period)."""
        return 'WARN', self.problem(warn_ratio), self.values()


def loss_summary(values) -> str:
    """One line from the values of report() (or of a node's /diagnostics status, as strings):
    for the benchmarks."""
    if 'samples lost' not in values:
        return 'no sample counter reported'
    return (f"samples lost {values['samples lost']} in {values['sample gaps']} gaps, repeated "
            f"{values['repeated samples']}, late {values['late samples (reordered)']}, without "
            f"counter {values['samples without counter']}")
