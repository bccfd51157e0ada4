"""The joint as sensor_msgs/JointState, for the standard tools (robot_state_publisher, RViz, the
joint panels of Foxglove and PlotJuggler): one joint, position (rad), velocity (rad/s), effort
(N m). The project's own messages (pam_interfaces) stay the contract between the stack's nodes;
JointState is a copy of them for the outside.

    rate = values['joint_states_rate']                                        # Hz, 0: off
    pub = guard.wrap(node.create_publisher(JointState, JOINT_STATES, SAMPLE_QOS)) if rate else None
    joint_states = JointStates(pub, JointState(), values['joint_name'], frame_id, rate,
                               sample_rate)        # None: set_sample_rate() when it is known
    ...
    joint_pub.publish(joint)                  # the project's message, through its FiniteGuard
    joint_states.publish(joint.header.stamp, sample, joint.angle, joint.angular_velocity,
                         joint.torque)

The node creates the publisher (inside FiniteGuard.wrap: pam_controller/test/
test_finite_publishers.py reads the node modules for that) and owns the sensor_msgs dependency;
this module imports no message package.

Cheap on the 1 kHz path: nothing is done while no subscription (in any process, on any host)
matches the publisher, since nothing in the loop reads JointState; the message is built once
(name, frame_id, one-element arrays) and each published sample only sets the stamp and the three
values in place. Because the message is reused, its guard cannot hold the last finite value (the
last message it saw is the same object): the values are taken from the project's message AFTER
its own guard (hold=True) has replaced a non-finite value by the last finite one, so they are
finite already; the JointState guard is the rule's second line (substitute 0.0).

Decimation (joint_states_rate below the sample rate): every n-th sample, n =
round(sample_rate / joint_states_rate), chosen by the rig's sample counter (Pressures.sample,
1 for the first sample): samples 1, 1 + n, 1 + 2n, ... So the rig's joint_states and ukf_node's
estimate/joint_states at the same rate carry the same samples (the same stamps). A sample
without a counter (0) is counted locally instead. A lockstep rig re-publishing its current sample
re-publishes its JointState with it (when that sample is one of the published ones).

Not thread-safe: one thread publishes (the node's sampling thread or its executor).
"""

from __future__ import annotations

from functools import cache

from pam_common.joint_description import JointDescriptionError, default_joint_name
from pam_common.node_params import Deferred, ParamSpec, fail

RATE_RANGE = (0.0, 10000.0)     # Hz; 0: off
#: The default rate: every sample at the stack's 1 kHz, and every sample of a slower rig too
#: (a rig run at rate:=500 is not refused for the default it did not choose).
DEFAULT_RATE = 1000.0


@cache
def urdf_joint_name() -> tuple[str, str]:
    """(the revolute joint's name in pam_description's URDF, '') or ('', why there is none):
    the default of joint_name, read when first needed (a Deferred default: importing a node's
    parameter table reads no file and needs no AMENT_PREFIX_PATH). Without the URDF installed the
    default is '' and a node refuses to start unless joint_name is given (check_joint_states)."""
    try:
        return default_joint_name(), ''
    except JointDescriptionError as error:
        return '', str(error)


def joint_state_params(topic: str, what: str, note: str = '') -> tuple[ParamSpec, ParamSpec]:
    """The joint_name and joint_states_rate rows of a node's parameter table; `topic` is the
    JointState topic ('joint_states'), `what` what it carries ('the measured joint'), `note`
    added to the rate's description."""
    return (
        ParamSpec('joint_name', Deferred(lambda: urdf_joint_name()[0]), 'string', '',
                  f'Name of the joint in the sensor_msgs/JointState on {topic} ({what}); '
                  "default: the revolute joint of pam_description's URDF."),
        ParamSpec('joint_states_rate', DEFAULT_RATE, 'double', 'Hz',
                  f'Rate of the sensor_msgs/JointState on {topic}: 1 sample in '
                  'round(sample rate / joint_states_rate) (the default: every sample, of a '
                  'slower rig too); at most the sample rate; 0: not published.'
                  + (f' {note}' if note else ''), range=RATE_RANGE),
    )


def check_joint_states(values: dict, sample_rate: float | None) -> dict:
    """Check joint_name (not empty) and joint_states_rate (its range is the ParamSpec's, checked
    by check_all: here at most `sample_rate` Hz when the node knows it; None for a rate known
    later, e.g. a DAQ board's). Raises ConfigError naming the parameter; returns values."""
    if not values['joint_name'].strip():
        name, why = urdf_joint_name()
        fail('joint_name', f"empty; give the joint's name (the URDF's is {name!r})" if name
             else f'empty, and no default from the URDF: {why}')
    rate = values['joint_states_rate']
    if sample_rate is not None and above_sample_rate(rate, sample_rate):
        fail('joint_states_rate', f'{rate:g} Hz is above the sample rate {sample_rate:g} Hz '
             '(at most one JointState per sample; 0: off)')
    return values


def above_sample_rate(rate: float, sample_rate: float) -> bool:
    """True if `rate` asks for more than one JointState per sample (the default never does: it
    means every sample)."""
    return rate != DEFAULT_RATE and rate > sample_rate * (1.0 + 1e-9)


def every_nth_sample(rate: float, sample_rate: float) -> int:
    """A stream of `sample_rate` Hz thinned to `rate` Hz (JointState, sim_node's /clock): every
    n-th sample, n = round(sample_rate / rate) (at least 1); 0 if rate is 0 (off). A rate above
    sample_rate gives 1 (every sample)."""
    if rate <= 0.0:
        return 0
    return max(1, round(sample_rate / rate))


class JointStates:
    """One joint's JointState, filled into one message and published at `rate` Hz: every n-th
    sample of a `sample_rate` Hz stream (every_nth_sample). Never without a publisher, with
    rate 0, or while the sample rate is not known (None)."""

    def __init__(self, publisher, message, joint_name: str, frame_id: str, rate: float,
                 sample_rate: float | None):
        self.publisher = publisher
        self.rate = rate
        self.every = 0
        if sample_rate is not None:
            self.set_sample_rate(sample_rate)
        self.message = message
        message.header.frame_id = frame_id
        message.name = [joint_name]
        message.position = [0.0]
        message.velocity = [0.0]
        message.effort = [0.0]
        self.published = 0
        self._uncounted = 0

    def set_sample_rate(self, sample_rate: float) -> bool:
        """Publish 1 sample in round(sample_rate / rate) from now on; False if rate is above
        sample_rate (above_sample_rate: then every sample is published)."""
        self.every = (every_nth_sample(self.rate, sample_rate)
                      if self.publisher is not None else 0)
        return not above_sample_rate(self.rate, sample_rate)

    def describe(self) -> str:
        """'/pam/joint_states (every sample)', '... (1 sample in 10)'; 'no JointState' when
        off."""
        if self.publisher is None:
            return 'no JointState'
        if not self.every:
            return f'{self.publisher.topic_name} (once the sample rate is known)'
        which = 'every sample' if self.every == 1 else f'1 sample in {self.every}'
        return f'{self.publisher.topic_name} ({which})'

    def due(self, sample: int) -> bool:
        """True if the sample with counter `sample` (0: not counted) is one to publish."""
        every = self.every
        if every == 1:
            return True
        if not every:
            return False
        if not sample:
            self._uncounted += 1
            sample = self._uncounted
        return (sample - 1) % every == 0

    def publish(self, stamp, sample: int, position: float, velocity: float,
                effort: float | None = None) -> None:
        """Publish the joint at `stamp` (builtin_interfaces/Time) if sample `sample` is due:
        position rad, velocity rad/s, effort N m (None: no effort measured, an empty array)."""
        if not self.due(sample) or not self.publisher.get_subscription_count():
            return      # nobody listens: not even built (the loop itself never reads it)
        msg = self.message
        msg.header.stamp = stamp
        msg.position[0] = position
        msg.velocity[0] = velocity
        efforts = msg.effort
        if effort is None:
            if len(efforts):
                msg.effort = []
        elif len(efforts):
            efforts[0] = effort
        else:
            msg.effort = [effort]
        self.publisher.publish(msg)
        self.published += 1
