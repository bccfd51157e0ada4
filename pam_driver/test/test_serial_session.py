"""pam_driver.serial_session without ROS: a SerialSession against pam-emulator (a real process)
over a real pseudo-terminal; its events recorded by a plain object, as driver_node receives them."""

from __future__ import annotations

import json
import os
import threading
import time

import pytest

from pam_common.testing import wait_until
from pam_driver import daq_protocol as proto
from pam_driver.calibration import load
from pam_driver.driver_config import LinkConfig
from pam_driver.serial_session import SerialSession

STARTUP = 30.0      # s, a fresh emulator process on a loaded 2-core machine
CAL = load('default')


class Recorder:
    """The events of a session, in order, as (name, arguments); samples counted apart."""

    def __init__(self, supply: bool = False):
        self.lock = threading.Lock()
        self.events: list[tuple] = []
        self.numbers: list[int] = []
        self.thread_names: list[str] = []
        self.supply = supply

    def _add(self, *event) -> None:
        with self.lock:
            self.events.append(event)

    def names(self) -> list[str]:
        with self.lock:
            return [e[0] for e in self.events]

    def of(self, name: str) -> list[tuple]:
        with self.lock:
            return [e[1:] for e in self.events if e[0] == name]

    def on_thread_start(self):
        self.thread_names.append(threading.current_thread().name)

    def on_connected(self, info):
        self._add('connected', info)
        return self.supply

    def on_sample(self, sample, number, now):
        with self.lock:
            self.numbers.append(number)

    def on_tick(self, now):
        pass

    def on_refused(self, why, backoff):
        self._add('refused', why, backoff)

    def on_connect_failed(self, error, backoff):
        self._add('connect_failed', error, backoff)

    def on_internal_error(self, error):
        self._add('internal_error', error)

    def on_link_down(self, error, stopping):
        self._add('link_down', error, stopping)


def link_config(port, **overrides) -> LinkConfig:
    values = dict(port=str(port), baud=1000000, handshake_timeout=0.5, stream_timeout=0.2,
                  heartbeat_period=0.05, reconnect_backoff=(0.05, 0.4))
    values.update(overrides)
    return LinkConfig(**values)


@pytest.fixture
def emulator(node_process, tmp_path):
    """Factory: emulator(*args) starts pam-emulator on a pty linked at tmp_path/pam_daq;
    returns (process, link, status()) with status() the emulator's status file, parsed."""
    def start(*args):
        link = tmp_path / 'pam_daq'
        status_file = tmp_path / 'status.json'
        process = node_process('pam-emulator', 'pam_driver', '--link', str(link),
                               '--status-file', str(status_file), *args, raw=True)
        process.wait_for(lambda: os.path.islink(link), STARTUP, 'the emulator pty link')

        def status() -> dict:
            try:
                return json.loads(status_file.read_text())
            except (OSError, ValueError):
                return {}
        return process, link, status
    return start


@pytest.fixture
def session_of():
    """Factory: session_of(config, events) -> a started SerialSession, stopped at teardown."""
    sessions = []

    def start(config, events):
        session = SerialSession(config, events)
        sessions.append(session)
        session.start()
        return session
    yield start
    for session in sessions:
        session.stop()


def test_handshake_stream_commands_and_heartbeat(emulator, session_of):
    _, link, status = emulator()
    events = Recorder()
    session = session_of(link_config(link), events)
    assert wait_until(lambda: len(events.numbers) >= 1500, 15.0), events.events
    (info,), = events.of('connected')
    assert (info.major, info.rate) == (proto.PROTOCOL_MAJOR, 1000)
    assert events.thread_names == ['driver_reader']
    # numbered from the device's tick: 1, 2, 3, ... without a gap (the emulator drops none)
    numbers = list(events.numbers)
    assert numbers[0] == 1 and numbers == list(range(1, len(numbers) + 1))
    # a COMMAND reaches the device as written (DAC counts -> the emulator's volts)
    assert session.send_command(CAL.dac_counts(7.0), CAL.dac_counts(3.0))
    assert wait_until(lambda: status().get('last_command') is not None, 5.0), status()
    assert status()['last_command'] == pytest.approx([7.0, 3.0], abs=0.01)
    # the heartbeat keeps the stream alive past the emulator's 1 s host-silence stop (no
    # command after the one above: only HEARTBEAT frames)
    before = len(events.numbers)
    time.sleep(1.5)
    assert len(events.numbers) - before > 1000
    values = session.report_values()
    assert values['device protocol'] == f'{info.major}.{info.minor}'
    assert values['samples received'] >= len(numbers)
    assert values['handshake failures'] == 0 and values['crc errors'] == 0
    assert values['device refused'] == 'none'
    assert events.of('link_down') == []
    session.stop()
    assert events.of('link_down')[-1][1] is True            # stopping
    assert not session.send_command(0, 0)                    # the port is closed


def test_an_incompatible_device_is_refused_with_growing_backoff(emulator, session_of):
    _, link, status = emulator('--protocol-version', f'{proto.PROTOCOL_MAJOR + 1}.0')
    events = Recorder()
    session = session_of(link_config(link, reconnect_backoff=(0.05, 0.2)), events)
    assert wait_until(lambda: len(events.of('refused')) >= 4, 15.0), events.events
    session.stop()
    refused = events.of('refused')
    assert all('protocol version mismatch' in why for why, _ in refused), refused
    assert [b for _, b in refused[:4]] == [0.05, 0.1, 0.2, 0.2]
    assert events.of('connected') == [] and events.numbers == []
    assert session.report_values()['handshake failures'] >= 4
    # nothing but HELLO was sent: no session, no command at the device
    assert status().get('sessions', []) == []


def test_the_device_lost_and_back(emulator, session_of):
    _, link, _ = emulator('--disconnect-at', '0.5', '--disconnect-for', '1.0')
    events = Recorder()
    session = session_of(link_config(link), events)
    assert wait_until(lambda: len(events.of('connected')) >= 2, 20.0), events.events
    names = events.names()
    first_down = names.index('link_down')
    assert names[0] == 'connected' and first_down < names.index('connected', 1)
    error, stopping = events.of('link_down')[0]
    assert not stopping and error, events.events
    # the samples go on after the reconnection
    count = len(events.numbers)
    assert wait_until(lambda: len(events.numbers) > count + 200, 5.0)
    assert session.report_values()['samples received'] == len(events.numbers)


def test_no_port_retries_with_backoff(tmp_path, session_of):
    events = Recorder()
    session_of(link_config(tmp_path / 'nothing_here', reconnect_backoff=(0.05, 0.1)), events)
    assert wait_until(lambda: len(events.of('connect_failed')) >= 3, 10.0), events.events
    failed = events.of('connect_failed')
    assert [b for _, b in failed[:3]] == [0.05, 0.1, 0.1]
    assert 'nothing_here' in failed[0][0], failed[0]
    assert events.of('connected') == []


def connected_session(emulator, session_of):
    """A session streaming from a fresh pam-emulator: (session, events, status)."""
    _, link, status = emulator()
    events = Recorder()
    session = session_of(link_config(link), events)
    assert wait_until(lambda: len(events.numbers) >= 200, 15.0), events.events
    return session, events, status


def commands_at_device(status) -> int:
    return sum(s['commands'] for s in status().get('sessions', []))


def settled(status, expected: list[float]) -> bool:
    last = status().get('last_command')
    return last is not None and last == pytest.approx(expected, abs=0.01)


def test_paced_commands_go_once_per_sample_the_newest_last(emulator, session_of):
    """A burst of the loop's commands (a host that stalled and catches up) reaches the board as
    the first frame at once and the newest at the next SAMPLE: never one frame per command."""
    session, events, status = connected_session(emulator, session_of)
    volts = [1.0 + 0.25 * k for k in range(30)]
    for _ in range(5):      # five bursts: each its own try (a sample may fall inside one)
        before, samples = commands_at_device(status), len(events.numbers)
        superseded = session.report_values()['commands superseded']
        for u in volts:
            assert session.send_command(CAL.dac_counts(u), CAL.dac_counts(10.0 - u), paced=True)
        burst_samples = len(events.numbers) - samples
        assert wait_until(lambda: settled(status, [volts[-1], 10.0 - volts[-1]]), 5.0), status()
        went = commands_at_device(status) - before
        # one frame for the slot the burst started in, one per SAMPLE read during the burst,
        # and the newest after the next SAMPLE; every other command replaced, none lost twice
        assert went <= 2 + burst_samples, status()
        assert went + session.report_values()['commands superseded'] - superseded == len(volts)
        volts.reverse()


def test_a_safety_output_goes_at_once_and_drops_a_waiting_command(emulator, session_of):
    session, events, status = connected_session(emulator, session_of)
    for _ in range(5):
        session.send_command(CAL.dac_counts(6.0), CAL.dac_counts(6.0), paced=True)
        session.send_command(CAL.dac_counts(9.0), CAL.dac_counts(9.0), paced=True)  # waits
        assert session.send_command(CAL.dac_counts(0.0), CAL.dac_counts(0.0))        # at once
        assert wait_until(lambda: settled(status, [0.0, 0.0]), 5.0), status()
        count = len(events.numbers) + 20
        assert wait_until(lambda n=count: len(events.numbers) > n, 5.0)
        time.sleep(0.25)             # the status file is rewritten every 0.1 s
        # the waiting 9 V command was dropped, not written after the safe output
        assert settled(status, [0.0, 0.0]), status()


def test_a_heartbeat_only_when_no_frame_went_for_a_heartbeat_period(emulator, session_of):
    """Any valid host frame feeds the board's watchdog: while the loop's commands flow the
    session sends no HEARTBEAT; when they stop it sends one every heartbeat_period."""
    session, _, status = connected_session(emulator, session_of)
    period = session.config.heartbeat_period

    def heartbeats() -> int:         # host frames that were neither COMMAND nor HELLO
        s = status()
        return s['host_frames'] - commands_at_device(status) - len(s['sessions'])

    gaps, last = 0, time.monotonic()
    start = None
    begin = last
    while (now := time.monotonic()) < begin + 1.5:   # a command every 2 ms for 1.5 s
        if start is None and now >= begin + 0.3:     # the status file lags up to 0.1 s
            start, gaps = heartbeats(), 0
        gaps += now - last >= period           # a gap of this host: a heartbeat may go in it
        last = now
        session.send_command(CAL.dac_counts(5.0), CAL.dac_counts(5.0), paced=True)
        time.sleep(0.002)
    during = heartbeats() - start              # read while the commands still flowed
    assert during <= gaps + 1, (during, gaps)
    time.sleep(1.0)                  # silence: a HEARTBEAT every 50 ms
    assert heartbeats() - start - during >= 0.5 / period
