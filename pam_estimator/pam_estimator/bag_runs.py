"""A recorded bag as a run for the offline evaluation (pam-evaluate), without rclpy.

From a Jazzy MCAP bag (pam_bag.bags) holding /pam/pressures, /pam/valve_command and
/pam/joint_measured, build the SimulationResult the evaluation reads:

* samples: the pressure messages, ordered by header stamp (a stamp seen again, e.g. a lockstep
  simulator re-publishing its sample, is one sample); t = stamp - first stamp (s);
* u[k]: the command in effect at sample k: the latest valve command whose header stamp is at or
  before sample k's stamp (among equal stamps, the last received); before any command 5.5 V
  (the rig's and the estimator's initial command). The UKF steps at sample k with u[k-1], which is
  what ukf_node does live (the command for sample k-1 arrives between samples k-1 and k);
* x: measured angle and angular velocity (joint_measured at the sample's stamp; linearly
  interpolated over stamps for samples whose measurement is missing) and the measured
  pressures; torque: the measured torque; force, friction, subsystem: not measured (NaN / 0);
* locked: the measured angle stays within LOCKED_TOLERANCE (0.2 deg) over the bag, unless given;
* supply (optional): if the bag holds /pam/supply_pressure (sensor_msgs/FluidPressure, Pa abs),
  the latest reading stamped at or before each sample's stamp and at most SUPPLY_STALE (0.1 s)
  older (NaN otherwise: the UKF then uses its model's P_tank); None without the topic.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pam_common import topics as stack_topics
from pam_common.stamps import ns_pair
from pam_model.rest import REST_COMMAND
from pam_model.simulate import SimulationResult

from .estimator_core import SUPPLY_STALE

PRESSURES = stack_topics.absolute(stack_topics.PRESSURES)
COMMAND = stack_topics.absolute(stack_topics.VALVE_COMMAND)
MEASURED = stack_topics.absolute(stack_topics.JOINT_MEASURED)
SUPPLY = stack_topics.absolute(stack_topics.SUPPLY_PRESSURE)
INITIAL_COMMAND = REST_COMMAND
LOCKED_TOLERANCE = math.radians(0.2)   # rad: a locked rig's encoder may jitter by a count or two


@dataclass
class BagRun:
    """A bag converted to a run, with what the conversion had to fill in."""

    run: SimulationResult
    stamps_ns: np.ndarray        # (N,) header stamps of the samples
    commands: int                # valve commands in the bag
    measured_missing: int        # samples without their own joint_measured (interpolated)
    duplicates: int              # pressure messages with an already seen stamp (ignored)
    first_commanded: int = 0     # first sample with a recorded command in effect (0 if none)
    supply: np.ndarray | None = None   # (N,) Pa abs, the measured supply (NaN: none fresh)


def is_bag(path) -> bool:
    """A bag directory (metadata.yaml) or its .mcap file."""
    path = Path(path)
    return (path.is_dir() and (path / 'metadata.yaml').is_file()) or path.suffix == '.mcap'


def load_bag_run(path, locked: bool | None = None,
                 namespace: str = stack_topics.DEFAULT_NAMESPACE) -> BagRun:
    """The run recorded in a bag (see the module doc); BagError / ValueError if it cannot be."""
    from pam_bag.bags import BagError, bag_files, check_definitions, load_bag, make_typestore
    topics = [stack_topics.absolute(t, namespace) for t in
              (stack_topics.PRESSURES, stack_topics.VALVE_COMMAND, stack_topics.JOINT_MEASURED)]
    contents = load_bag(path, check_types=False)
    for topic in (topics[0], topics[2]):
        if topic not in contents.topics:
            raise BagError(f'{contents.path}: no {topic} in the bag (it has: '
                           f'{", ".join(sorted(contents.topics)) or "nothing"}); a run needs '
                           f'{", ".join(topics)}')
    supply_topic = stack_topics.absolute(stack_topics.SUPPLY_PRESSURE, namespace)
    has_supply = supply_topic in contents.topics
    store = make_typestore()
    check_definitions(bag_files(contents.path), topics + [supply_topic] * has_supply,
                      store)   # only the topics read
    pressures = contents.columns(topics[0], store, ('p1', 'p2'))
    commands = contents.columns(topics[1], store, ('u1', 'u2'))
    measured = contents.columns(topics[2], store, ('angle', 'angular_velocity', 'torque'))
    n_pressures, n_commands = len(pressures['stamp_ns']), len(commands['stamp_ns'])
    if n_pressures < 2 or not len(measured['stamp_ns']):
        raise BagError(f'{contents.path}: too few samples ({n_pressures} pressures, '
                       f'{len(measured["stamp_ns"])} joint measurements)')

    # samples: unique stamps, first message of each
    p_stamps = pressures['stamp_ns']
    order = np.argsort(p_stamps, kind='stable')
    stamps, first = np.unique(p_stamps[order], return_index=True)
    keep = order[first]
    p = np.column_stack([pressures['p1'][keep], pressures['p2'][keep]])

    # commands in effect: last command with stamp <= sample stamp
    u = np.tile(np.asarray(INITIAL_COMMAND, dtype=float), (len(stamps), 1))
    first_commanded = 0
    if n_commands:
        c_stamps = commands['stamp_ns']
        c_order = np.argsort(c_stamps, kind='stable')
        c_sorted = c_stamps[c_order]
        c_u = np.column_stack([commands['u1'][c_order], commands['u2'][c_order]])
        idx = np.searchsorted(c_sorted, stamps, side='right') - 1
        has = idx >= 0
        u[has] = c_u[idx[has]]
        first_commanded = int(np.argmax(has)) if has.any() else len(stamps)

    # joint measurement at each sample's stamp
    m_stamps = measured['stamp_ns']
    m_order = np.argsort(m_stamps, kind='stable')
    m_sorted, m_first = np.unique(m_stamps[m_order], return_index=True)
    m_vals = np.column_stack([measured[f][m_order[m_first]]
                              for f in ('angle', 'angular_velocity', 'torque')])
    pos = np.searchsorted(m_sorted, stamps)
    exact = (pos < len(m_sorted)) & (m_sorted[np.minimum(pos, len(m_sorted) - 1)] == stamps)
    rel = (m_sorted - stamps[0]).astype(float)
    t_rel = (stamps - stamps[0]).astype(float)
    truth = np.column_stack([np.interp(t_rel, rel, m_vals[:, c]) for c in range(3)])

    angle = truth[:, 0]
    if locked is None:
        locked = bool(np.ptp(m_vals[:, 0]) <= LOCKED_TOLERANCE)
    n = len(stamps)
    run = SimulationResult(
        t=t_rel * 1e-9, u=u, x=np.column_stack([angle, truth[:, 1], p]), torque=truth[:, 2],
        force=np.full((n, 2), np.nan), friction=np.zeros(n), subsystem=np.zeros(n, dtype=int),
        p_measured=p.copy(), locked=bool(locked))
    supply = (_supply_at(contents.columns(supply_topic, store, ('fluid_pressure',)), stamps)
              if has_supply else None)
    return BagRun(run=run, stamps_ns=stamps, commands=n_commands,
                  measured_missing=int(n - exact.sum()), duplicates=n_pressures - n,
                  first_commanded=first_commanded, supply=supply)


def _supply_at(readings: dict, stamps) -> np.ndarray:
    """(N,) supply pressure (Pa abs) at each sample stamp: the latest reading at or before it,
    NaN if none or older than SUPPLY_STALE; readings: the topic's columns (stamp_ns,
    fluid_pressure)."""
    supply = np.full(len(stamps), np.nan)
    if not len(readings['stamp_ns']):
        return supply
    order = np.argsort(readings['stamp_ns'], kind='stable')
    s_stamps, values = readings['stamp_ns'][order], readings['fluid_pressure'][order]
    idx = np.searchsorted(s_stamps, stamps, side='right') - 1
    fresh = (idx >= 0) & ((stamps - s_stamps[np.maximum(idx, 0)]) * 1e-9 <= SUPPLY_STALE)
    supply[fresh] = values[idx[fresh]]
    return supply


def load_run(path, locked: bool | None = None) -> SimulationResult:
    """A run from a bag directory (or .mcap) or a pam-simulate file (.npz / .csv)."""
    if is_bag(path):
        return load_bag_run(path, locked).run
    if not Path(path).is_file():
        raise FileNotFoundError(f'{path}: no such file or bag directory')
    run = SimulationResult.load(path)
    if locked is not None:
        run.locked = bool(locked)
    return run


#: Header stamp of the first sample of a bag written from a simulated run (ns): a fixed date, so the
#: same run gives the same bag.
SIMULATED_START_NS = 1_700_000_000 * 1_000_000_000


def write_run_bag(run: SimulationResult, path, frame_id: str = 'pam_joint',
                  start_ns: int = SIMULATED_START_NS,
                  namespace: str = stack_topics.DEFAULT_NAMESPACE, supply=None) -> Path:
    """Write a simulated run as the bag the live stack records (the inverse of load_bag_run).

    Per sample k, stamped start_ns + t[k]: /pam/pressures (the sensor readings p_measured,
    sample counter k + 1 as sim_node sets it),
    /pam/joint_measured (the true angle, velocity and torque) and /pam/valve_command (u[k]),
    which is what sim_node, profile_player and bag_record write for the same profile; with
    supply (N,) Pa abs also /pam/supply_pressure (sensor_msgs/FluidPressure). The output
    directory must not exist.
    """
    from pam_bag.bags import BagWriter
    writer = BagWriter(Path(path))
    store = writer.typestore
    names = {'pressures': stack_topics.absolute(stack_topics.PRESSURES, namespace),
             'command': stack_topics.absolute(stack_topics.VALVE_COMMAND, namespace),
             'measured': stack_topics.absolute(stack_topics.JOINT_MEASURED, namespace)}
    msg_types = {'pressures': 'pam_interfaces/msg/Pressures',
                 'command': 'pam_interfaces/msg/ValveCommand',
                 'measured': 'pam_interfaces/msg/JointMeasurement'}
    if supply is not None:
        names['supply'] = stack_topics.absolute(stack_topics.SUPPLY_PRESSURE, namespace)
        msg_types['supply'] = 'sensor_msgs/msg/FluidPressure'
    for key, topic in names.items():
        writer.add_topic(topic, msg_types[key])
    classes = {key: store.types[msgtype] for key, msgtype in msg_types.items()}
    Header = store.types['std_msgs/msg/Header']
    Time = store.types['builtin_interfaces/msg/Time']
    stamps = start_ns + np.round(np.asarray(run.t) * 1e9).astype(np.int64)
    try:
        for k, stamp in enumerate(stamps.tolist()):
            sec, nanosec = ns_pair(stamp)
            header = Header(stamp=Time(sec=sec, nanosec=nanosec), frame_id=frame_id)
            rows = {
                'pressures': classes['pressures'](header=header, p1=float(run.p_measured[k, 0]),
                                                  p2=float(run.p_measured[k, 1]), sample=k + 1),
                'measured': classes['measured'](header=header, angle=float(run.x[k, 0]),
                                                angular_velocity=float(run.x[k, 1]),
                                                torque=float(run.torque[k])),
                'command': classes['command'](header=header, u1=float(run.u[k, 0]),
                                              u2=float(run.u[k, 1])),
            }
            if supply is not None:
                rows['supply'] = classes['supply'](header=header,
                                                   fluid_pressure=float(supply[k]), variance=0.0)
            for key in rows:
                writer.write(names[key], stamp, store.serialize_cdr(rows[key], msg_types[key]))
    finally:
        writer.close()
    return Path(path)
