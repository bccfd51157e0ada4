"""driver_node's serial session with the DAQ board, without ROS (pam_driver/PROTOCOL.md).

SerialSession owns the port and the reader thread: open the port for exclusive use, HELLO and
wait for HELLO_ACK (handshake_timeout s), check the device (the same protocol major version, a
sample rate above 0), stream (SAMPLE and DEVICE_HEARTBEAT frames, a HEARTBEAT after
heartbeat_period s without a frame to the device, the device lost after stream_timeout s
without a sample), and reconnect after reconnect_backoff[0] s, doubled after each failure up to
reconnect_backoff[1] s. It counts
what the link did (CRC errors, garbage bytes, lost frames, protocol errors, handshake failures,
board vents) and numbers the samples from the device's tick (TickCounter).

The line carries at most one of the loop's COMMAND frames per read of SAMPLE frames, the
newest output (send_command(..., paced=True)): a command given when one has already gone since
the last SAMPLE is kept, a newer one replaces it, and it goes when it has waited a whole sample
slot without being replaced. A 1 kHz loop gives one command per sample, so in steady state every
command goes at once; a host that fell behind (its commands queued during a stall, two SAMPLEs
read at once) sends the board one frame a period, not a burst at the line rate that an 8-bit
board spends its period receiving. Safety outputs (the safe output, a shutdown)
go at once and drop a waiting command. A HEARTBEAT goes only when no frame went for
heartbeat_period: any valid host frame feeds the board's watchdog.

Every decision about the valves stays with the node's DriverCore: the session hands each event
to its SessionEvents (the node), from the reader thread, and writes the frames it is given
(send_command, send_arm) under its own I/O lock, so a decision and its COMMAND frame can be one
step under the node's lock. Tested against pam-emulator over a real pseudo-terminal, without ROS
(test_serial_session.py).
"""

from __future__ import annotations

import math
import threading
import time
from typing import Protocol

from pam_driver import daq_protocol as proto
from pam_driver.driver_config import LinkConfig

__all__ = ['DeviceLost', 'IncompatibleDevice', 'InjectedError', 'SerialSession',
           'SessionEvents', 'check_device']

READ_TIMEOUT = 0.002     # s, a read returns after this long without bytes
WRITE_TIMEOUT = 0.1      # s, a write blocked this long fails (the device is lost)


class DeviceLost(Exception):
    """The device stopped answering (no samples, failed handshake)."""


class IncompatibleDevice(DeviceLost):
    """The device answered the handshake but cannot be driven (another major protocol version,
    an impossible sample rate): it is not streamed from and gets no COMMAND frame."""


class InjectedError(RuntimeError):
    """The internal error of driver_node's inject_internal_error parameter (tests of the
    exception path)."""


class SessionEvents(Protocol):
    """What the session tells its owner, from the reader thread (monotonic times, s)."""

    def on_thread_start(self) -> None:
        """The reader thread runs (e.g. apply the real-time knobs to it)."""

    def on_connected(self, info: proto.DeviceInfo) -> bool:
        """A compatible device answered the handshake; the session streams from it next.
        Returns whether its SAMPLE frames are parsed with the supply-pressure field."""

    def on_sample(self, sample: proto.Sample, number: int, now: float) -> None:
        """A SAMPLE frame; `number` counts the device's ticks from 1 (a gap is a lost sample)."""

    def on_tick(self, now: float) -> None:
        """After each read of the port (about every READ_TIMEOUT s while streaming)."""

    def on_refused(self, why: str, backoff: float) -> None:
        """The device is incompatible (`why`); the next attempt in `backoff` s."""

    def on_connect_failed(self, error: str, backoff: float) -> None:
        """The port could not be opened, or no handshake, or the device was lost; the next
        attempt in `backoff` s."""

    def on_internal_error(self, error: str) -> None:
        """An unexpected exception in the reader thread (it goes on: reconnects)."""

    def on_link_down(self, error: str, stopping: bool) -> None:
        """The port is closed (after any of the above, or at stop when `stopping`)."""


def check_device(info: proto.DeviceInfo) -> None:
    """Raise IncompatibleDevice unless the HELLO_ACK describes a device this driver drives."""
    if info.major != proto.PROTOCOL_MAJOR:
        raise IncompatibleDevice(
            f'protocol version mismatch: the device speaks {info.major}.{info.minor}, this '
            f'driver {proto.PROTOCOL_MAJOR}.{proto.PROTOCOL_MINOR} (major versions must be equal)')
    if info.rate == 0:
        raise IncompatibleDevice('the device reports a sample rate of 0 Hz')


class SerialSession:
    """The link to one DAQ board on `config.port`; start() runs it in a reader thread until
    stop(). Counters are read with report_values() (any thread)."""

    def __init__(self, config: LinkConfig, events: SessionEvents):
        self.config = config
        self._events = events
        self._stop = threading.Event()
        self._io_lock = threading.Lock()      # the serial object, the sequence number, writes
        self._lock = threading.Lock()         # the counters
        self._serial = None
        self._tx_seq = 0
        self._last_write = -math.inf          # monotonic time of the last frame written
        self._slot_used = False               # a paced COMMAND went since the last SAMPLE
        self._waiting: tuple[int, int] | None = None   # a paced COMMAND kept for later
        self._waiting_old = False             # ... and it already waited one whole slot
        self._decoder = proto.Decoder()
        self._rx_seq = proto.SequenceTracker()
        self._ticks = proto.TickCounter()
        self._vents = proto.BoardVents()
        self._early_frames: list[proto.Frame] = []   # read with the HELLO_ACK, after it
        self._supply = False                  # SAMPLE frames carry the supply field
        self._thread: threading.Thread | None = None
        #: monotonic time at which the reader raises InjectedError (once); None: never
        self.inject_at: float | None = None
        self.device: proto.DeviceInfo | None = None
        self.device_heartbeat: tuple | None = None
        self.handshake_failures = 0
        self.protocol_errors = 0
        self.samples = 0
        self.commands_superseded = 0          # paced commands replaced before they went
        self.incompatible = ''                # why the device was refused ('' when not)
        self.last_error = ''

    # ------------------------------------------------------------------ lifecycle
    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name='driver_reader', daemon=True)
        self._thread.start()

    def stop(self, timeout: float = 2.0) -> None:
        """Stop the reader thread; it closes the port on its way out."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=timeout)

    @property
    def stopping(self) -> bool:
        return self._stop.is_set()

    # ------------------------------------------------------------------ output
    def _send(self, build) -> bool:
        """Write the frame build(seq) with the next sequence number; False if there is no port
        or the write failed (the reader thread notices and reconnects)."""
        with self._io_lock:
            return self._write(build)

    def _write(self, build) -> bool:
        """_send's body; the caller holds self._io_lock."""
        ser = self._serial
        if ser is None:
            return False
        seq = self._tx_seq
        self._tx_seq = (self._tx_seq + 1) & 0xFFFF
        try:
            ser.write(build(seq))
        except Exception as exc:  # noqa: BLE001 - the reader thread notices and reconnects
            self.last_error = f'write failed: {type(exc).__name__}: {exc}'
            return False
        self._last_write = time.monotonic()
        return True

    def send_command(self, dac1: int, dac2: int, paced: bool = False) -> bool:
        """A COMMAND frame with the DAC counts. paced (the loop's commands): at once if no paced
        COMMAND went since the last SAMPLE, else kept for later (replacing one kept before).
        Not paced (safety outputs): at once, and a kept command is dropped. False if there is no
        port or the write failed."""
        with self._io_lock:
            if self._serial is None:
                return False
            if self._waiting is not None:
                with self._lock:
                    self.commands_superseded += 1
            if paced and self._slot_used:
                self._waiting, self._waiting_old = (dac1, dac2), False
                return True
            self._waiting = None
            self._slot_used = self._slot_used or paced
            return self._write(lambda seq: proto.command(seq, dac1, dac2))

    def send_arm(self) -> bool:
        return self._send(proto.arm)

    def _next_slot(self) -> None:
        """The reader read a SAMPLE (the first of a read: samples read together came while the
        host was late, and their commands would reach the board in one period): a kept command
        that already waited a whole slot goes now and takes this slot; a younger one waits one
        more slot for a newer command to replace it (otherwise every command would wait for the
        next SAMPLE from then on)."""
        with self._io_lock:
            waiting = self._waiting
            if waiting is not None and self._waiting_old:
                self._waiting = None
                self._slot_used = True
                self._write(lambda seq: proto.command(seq, *waiting))
            else:
                self._slot_used = False
                self._waiting_old = waiting is not None

    # ------------------------------------------------------------------ the reader thread
    def _run(self) -> None:
        self._events.on_thread_start()
        import serial
        first, longest = self.config.reconnect_backoff
        backoff = first
        while not self._stop.is_set():
            try:
                self._connect(serial)
                backoff = first
                self._stream()
            except IncompatibleDevice as exc:
                self.last_error = self.incompatible = str(exc)
                self._events.on_refused(str(exc), backoff)
            except DeviceLost as exc:
                self.last_error, self.incompatible = str(exc), ''
                self._events.on_connect_failed(self.last_error, backoff)
            except (serial.SerialException, OSError) as exc:
                self.last_error, self.incompatible = f'{type(exc).__name__}: {exc}', ''
                self._events.on_connect_failed(self.last_error, backoff)
            except Exception as exc:  # noqa: BLE001 - never die: report, reconnect
                self.last_error = f'internal error: {type(exc).__name__}: {exc}'
                self._events.on_internal_error(self.last_error)
            finally:
                try:
                    self._disconnect()
                except Exception as exc:  # noqa: BLE001 - the thread must not die
                    self.last_error = f'internal error: {type(exc).__name__}: {exc}'
            if self._stop.wait(backoff):
                break
            backoff = min(2.0 * backoff, longest)

    def _connect(self, serial) -> None:
        # exclusive: an advisory lock (flock) on the port, so that a second driver_node (or any
        # other pyserial program asking for one) cannot share the board and steal its bytes
        ser = serial.Serial(self.config.port, self.config.baud, timeout=READ_TIMEOUT,
                            write_timeout=WRITE_TIMEOUT, exclusive=True)
        ser.reset_input_buffer()
        with self._io_lock:
            self._serial = ser
            self._waiting, self._slot_used = None, False
        self._decoder.reset()
        self._rx_seq.reset()
        self._early_frames = []
        self._send(proto.hello)
        deadline = time.monotonic() + self.config.handshake_timeout
        info = None
        while info is None and time.monotonic() < deadline and not self._stop.is_set():
            frames = self._decoder.feed(ser.read(max(ser.in_waiting, 1)))
            for i, frame in enumerate(frames):
                if frame.type == proto.HELLO_ACK:
                    info = proto.parse_hello_ack(frame)
                    self._early_frames = frames[i + 1:]   # already streamed: _stream's
                    break
        try:
            if info is None:
                raise DeviceLost('no HELLO_ACK within handshake_timeout')
            check_device(info)
        except DeviceLost:
            with self._lock:
                self.handshake_failures += 1
            raise
        with self._lock:
            self.device = info
        self.incompatible = ''
        self._supply = self._events.on_connected(info)

    def _disconnect(self) -> None:
        with self._io_lock:
            ser, self._serial = self._serial, None
        if ser is not None:
            try:
                ser.close()
            except Exception:  # noqa: BLE001
                pass
        self._events.on_link_down(self.last_error, self._stop.is_set())

    def _stream(self) -> None:
        ser = self._serial
        last_sample = time.monotonic()
        early, self._early_frames = self._early_frames, []
        while not self._stop.is_set():
            data = ser.read(max(ser.in_waiting, 1))
            now = time.monotonic()
            if self.inject_at is not None and now >= self.inject_at:
                self.inject_at = math.inf   # once
                raise InjectedError('injected by the inject_internal_error parameter')
            frames, early = early + (self._decoder.feed(data) if data else []), []
            slot = True
            for frame in frames:
                self._rx_seq.update(frame.seq)
                try:
                    if frame.type == proto.SAMPLE:
                        if slot:
                            self._next_slot()
                            slot = False
                        self._on_sample(proto.parse_sample(frame, self._supply), now)
                        last_sample = now
                    elif frame.type == proto.DEVICE_HEARTBEAT:
                        heartbeat = frame.fields()
                        with self._lock:
                            self.device_heartbeat = heartbeat
                            self._vents.on_heartbeat(heartbeat[2])
                    elif frame.type != proto.HELLO_ACK:
                        frame.fields()  # raises for an unknown type
                except proto.ProtocolError:
                    self.count_protocol_error()
            self._events.on_tick(now)
            if (now - self._last_write >= self.config.heartbeat_period
                    and not self._send(proto.heartbeat)):
                raise DeviceLost(self.last_error or 'write failed')
            if now - last_sample > self.config.stream_timeout:
                raise DeviceLost(f'no sample for {self.config.stream_timeout * 1e3:g} ms')

    def _on_sample(self, sample: proto.Sample, now: float) -> None:
        number = self._ticks.update(sample.tick)
        self._events.on_sample(sample, number, now)
        with self._lock:
            self.samples += 1
            self._vents.on_sample(sample.status)

    def count_protocol_error(self) -> None:
        with self._lock:
            self.protocol_errors += 1

    # ------------------------------------------------------------------ diagnostics
    def report_values(self) -> dict:
        """The link's counters for /diagnostics."""
        d = self._decoder
        with self._lock:
            info = self.device
            values = {
                'device protocol': f'{info.major}.{info.minor}' if info else 'none',
                'encoder fitted': bool(info and info.has_encoder),
                'torque meter fitted': bool(info and info.has_torque),
                'supply transducer fitted': bool(info and info.has_supply),
                'samples received': self.samples,
                'commands superseded': self.commands_superseded,
                'handshake failures': self.handshake_failures,
                'device refused': self.incompatible or 'none',
                'crc errors': d.crc_errors,
                'garbage bytes': d.garbage_bytes,
                'lost frames': self._rx_seq.lost,
                'sequence gaps': self._rx_seq.gaps,
                'protocol errors': self.protocol_errors,
                'last error': self.last_error or 'none',
                'board vents': self._vents.count,
                'board vented now': self._vents.vented,
                'last sample counter': self._ticks.value,
                'device restarts (tick went back)': self._ticks.restarts,
            }
            if self.device_heartbeat is not None:
                rx, crc, trips, _ = self.device_heartbeat
                values.update({'device rx frames': rx, 'device rx crc errors': crc,
                               'device watchdog trips': trips})
        return values
