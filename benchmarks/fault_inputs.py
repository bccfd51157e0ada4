"""Bad inputs of the fault campaign (benchmarks/fault_campaign.py): numbered, stamped message
feeds standing in for a rig or an estimator, run-time parameter calls (the rcl_interfaces
services `ros2 param set` uses), damaged copies of bags.

Stamps of a feed (Feed.send `stamps`):
  'forward'     1 ms after the previous one (a well-behaved 1 kHz source);
  'past'        10 s before the feed's clock, then 1 ms apart (stale messages);
  'decreasing'  each 1 ms before the previous one;
  'zero'        0 s.
"""

from __future__ import annotations

import math
import shutil
import struct
import time
from pathlib import Path

from pam_common.stamps import ns_stamp, stamp_ns
from pam_common.testing import wait_until

NAN, INF = math.nan, math.inf
HUGE = 1e300          # finite, far outside every physical range
STEP_NS = 1_000_000   # 1 ms
PAST_NS = 10_000_000_000


def set_stamp(header, ns: int) -> None:
    header.stamp = ns_stamp(ns)


class Feed:
    """Numbered, stamped messages published like a rig (sample counter 1, 2, ... as
    Pressures.sample) or an estimator (JointEstimate.sample). `make(value)` builds the message
    of one value; the feed sets its stamp and sample counter (0, "not counted", if not
    `counted`)."""

    def __init__(self, publisher, make, counted: bool = True):
        self.publisher = publisher
        self.make = make
        self.counted = counted
        self.sample = 0
        self.clock_ns = time.time_ns()
        self.sent: list[tuple[int, int]] = []    # (sample, stamp ns) of everything published

    def _stamp(self, mode: str, i: int, base_ns: int) -> int:
        if mode == 'zero':
            return 0
        if mode == 'past':
            return base_ns - PAST_NS + i * STEP_NS
        if mode == 'decreasing':
            return base_ns - (i + 1) * STEP_NS
        self.clock_ns += STEP_NS
        return self.clock_ns

    def send(self, values, stamps: str = 'forward', period: float = 0.001) -> list:
        """Publish one message per value (period s apart; 0: a burst); the (sample, stamp) of
        each."""
        base_ns = self.clock_ns
        out = []
        for i, value in enumerate(values):
            msg = self.make(value)
            self.sample += 1
            msg.sample = self.sample if self.counted else 0
            ns = self._stamp(stamps, i, base_ns)
            set_stamp(msg.header, ns)
            self.publisher.publish(msg)
            out.append((self.sample, ns))
            if period:
                time.sleep(period)
        self.sent += out
        return out

    def close(self, pause: float = 0.3, value=None) -> list:
        """After `pause` s, one good message (it reveals a loss at the end of what came before:
        a gap is seen only when a later sample arrives)."""
        time.sleep(pause)
        return self.send([value], period=0.0)


def pressures_message(value):
    from pam_interfaces.msg import Pressures
    p1, p2 = value if value is not None else (4.5e5, 4.5e5)
    return Pressures(p1=float(p1), p2=float(p2))


def estimate_message(value):
    """A JointEstimate whose angle and torque are `value` (0 if None)."""
    from pam_interfaces.msg import JointEstimate
    v = 0.0 if value is None else float(value)
    return JointEstimate(angle=v, torque=v, p1=4.5e5, p2=4.5e5)


def command_message(u1: float, u2: float, ns: int | None = None):
    """A ValveCommand stamped `ns` (now if None)."""
    from pam_interfaces.msg import ValveCommand
    msg = ValveCommand(u1=float(u1), u2=float(u2))
    set_stamp(msg.header, time.time_ns() if ns is None else ns)
    return msg


def unanswered(sent: list, received_stamps: list) -> list:
    """The samples of the sent (sample, stamp) that no output answered: an output answers the
    input with its stamp, each input once (repeated stamps matched as a multiset)."""
    left: dict[int, int] = {}
    for ns in received_stamps:
        left[ns] = left.get(ns, 0) + 1
    missing = []
    for sample, ns in sent:
        if left.get(ns, 0) > 0:
            left[ns] -= 1
        else:
            missing.append(sample)
    return missing


# ---------------------------------------------------------------------------- lockstep rig
def lockstep_command(publisher, pressures, u1: float, u2: float, stamps: str = 'current',
                     timeout: float = 1.0) -> bool:
    """One ValveCommand to a lockstep sim_node, stamped for its current step t_k (the stamp of
    the last pressure sample), 0 ('zero') or for the step before (t_k - 1 ms, 'past'); True if
    the rig stepped (a newer sample arrived within `timeout`)."""
    def last_stamp() -> int:
        items = pressures.messages()
        return stamp_ns(items[-1].header.stamp) if items else -1
    t_k = last_stamp()
    ns = {'current': max(t_k, 0), 'zero': 0, 'past': t_k - STEP_NS}[stamps]
    publisher.publish(command_message(u1, u2, ns))
    return wait_until(lambda: last_stamp() > t_k, timeout, 0.002)


# ---------------------------------------------------------------------------- parameters
class Parameters:
    """`ros2 param set/get` through a node's rcl_interfaces services, from the probe."""

    def __init__(self, probe, node: str, timeout: float = 10.0):
        from rcl_interfaces.srv import GetParameters, SetParameters
        self.node = node
        self.timeout = timeout
        self._set = probe.client(SetParameters, f'{node}/set_parameters')
        self._get = probe.client(GetParameters, f'{node}/get_parameters')

    def _call(self, client, request):
        if not client.wait_for_service(timeout_sec=self.timeout):
            raise RuntimeError(f'{client.srv_name} not available')
        future = client.call_async(request)
        if not wait_until(future.done, self.timeout):
            raise RuntimeError(f'{client.srv_name}: no answer in {self.timeout:g} s')
        return future.result()

    def set(self, name: str, value) -> tuple[bool, str]:
        """(successful, reason) of setting one parameter."""
        from rcl_interfaces.srv import SetParameters
        from rclpy.parameter import Parameter
        request = SetParameters.Request(parameters=[Parameter(name, value=value)
                                                    .to_parameter_msg()])
        result = self._call(self._set, request).results[0]
        return result.successful, result.reason

    def get(self, name: str):
        """The value of a parameter (None if the node does not have it)."""
        from rcl_interfaces.srv import GetParameters
        from rclpy.parameter import parameter_value_to_python
        values = self._call(self._get, GetParameters.Request(names=[name])).values
        return parameter_value_to_python(values[0]) if values else None


# ---------------------------------------------------------------------------- bags
def copy_bag(source: Path, folder: Path) -> Path:
    """A copy of bag directory `source` in `folder`, under its own name (its files name it)."""
    return Path(shutil.copytree(source, folder / source.name))


def mcap_files(bag: Path) -> list[Path]:
    return sorted(bag.glob('*.mcap'))


def chunk_offsets(mcap: Path) -> list[tuple[int, int]]:
    """(offset, length) of the body of every Chunk record of an MCAP file."""
    data = mcap.read_bytes()
    pos, found = 8, []
    while pos + 9 <= len(data):
        opcode, length = struct.unpack_from('<BQ', data, pos)
        if opcode == 0x06:
            found.append((pos + 9, length))
        pos += 9 + length
    return found


def flip_in_chunk(bag: Path, index: int = 2, nbytes: int = 16) -> str:
    """Flip `nbytes` bytes in the middle of chunk `index` of the bag's first file (zstd sees
    it: the chunk does not decompress); what was done."""
    mcap = mcap_files(bag)[0]
    offset, length = chunk_offsets(mcap)[index]
    at = offset + length * 3 // 4
    data = bytearray(mcap.read_bytes())
    for i in range(at, at + nbytes):
        data[i] ^= 0xFF
    mcap.write_bytes(data)
    return f'{nbytes} bytes flipped at {at} in chunk {index} of {mcap.name}'


def flip_unnoticed(bag: Path, index: int = 2) -> str:
    """Damage chunk `index` of the bag's first file so that it still decompresses into complete
    records, only other ones (pam_common.testing.damage_chunk): only a CRC tells."""
    from pam_bag.testing import damage_chunk
    mcap = mcap_files(bag)[0]
    at = damage_chunk(mcap, index)
    return f'8 bytes flipped at {at} in chunk {index} of {mcap.name} (zstd does not notice)'


def truncate(bag: Path, fraction: float = 0.6) -> str:
    """Cut the bag's last file to `fraction` of its size (mid-chunk, no summary)."""
    mcap = mcap_files(bag)[-1]
    size = mcap.stat().st_size
    with mcap.open('r+b') as f:
        f.truncate(int(size * fraction))
    return f'{mcap.name} cut from {size} to {int(size * fraction)} bytes'


def remove_split_file(bag: Path, index: int = 1) -> str:
    """Delete file `index` of a split bag (metadata.yaml still lists it)."""
    mcap = mcap_files(bag)[index]
    mcap.unlink()
    return f'{mcap.name} deleted'


def remove_metadata(bag: Path) -> str:
    (bag / 'metadata.yaml').unlink()
    return 'metadata.yaml deleted'
