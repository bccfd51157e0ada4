"""The binary serial protocol between driver_node and the DAQ board (spec: pam_driver/PROTOCOL.md).

No ROS and no pyserial in here: frame encoding, payload packing and a streaming decoder that
resynchronises after garbage bytes and CRC errors, counting both.

Frame: SYNC (0xA5 0x5A) | type u8 | seq u16 LE | length u8 | payload | CRC-16 u16 LE
CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection) over type..payload.

Version 1.1 adds the optional supply-pressure channel: HELLO_ACK flag bit 2 (FLAG_SUPPLY), and
then a u16 ADC P_supply at the end of every SAMPLE payload (SUPPLY_FIELD). A board without the
transducer sends the frames of 1.0 byte for byte; a 1.0 host ignores the field (bytes beyond a
payload belong to a later minor version).

Version 1.2 (the reference board, pam_driver/firmware) adds ARM (host -> device, no payload):
the device clears its latched faults whose cause is gone. driver_node sends it on ~/arm to a
device that announced 1.2 or later (DeviceInfo.has_arm); the rest of 1.2 (the board's
calibration frames, the heartbeat's counters) is firmware/tools/board_tool.py's.
"""

from __future__ import annotations

import binascii
import struct
from dataclasses import dataclass

SYNC = b'\xA5\x5A'
HEADER = struct.Struct('<BHB')      # type, seq, length
CRC = struct.Struct('<H')
HEADER_SIZE = len(SYNC) + HEADER.size
OVERHEAD = HEADER_SIZE + CRC.size   # bytes of a frame besides its payload
MAX_PAYLOAD = 64                    # longer length fields are treated as corruption

PROTOCOL_MAJOR = 1
PROTOCOL_MINOR = 1    # 1.1: the optional supply-pressure channel

# host -> device
HELLO = 0x01
COMMAND = 0x02
HEARTBEAT = 0x03
ARM = 0x04              # 1.2: clear the device's latched faults whose cause is gone
ARM_MINOR = 2           # the first minor version (of major 1) with ARM
# device -> host
HELLO_ACK = 0x81
SAMPLE = 0x80
DEVICE_HEARTBEAT = 0x83

FLAG_ENCODER = 0x01
FLAG_TORQUE = 0x02
FLAG_SUPPLY = 0x04      # 1.1: a supply-pressure transducer fitted (SAMPLE carries SUPPLY_FIELD)
STATUS_VENTED = 0x01    # SAMPLE status and DEVICE_HEARTBEAT state: the device watchdog vented

HELLO_PAYLOAD = struct.Struct('<BB')                 # major, minor
# major, minor, rate Hz, adc bits, dac bits, flags
HELLO_ACK_PAYLOAD = struct.Struct('<BBHBBB')
# tick, adc p1, adc p2, encoder, adc torque, status
SAMPLE_PAYLOAD = struct.Struct('<IHHiHB')
# 1.1, after SAMPLE_PAYLOAD when the device reports FLAG_SUPPLY: adc p_supply
SUPPLY_FIELD = struct.Struct('<H')
COMMAND_PAYLOAD = struct.Struct('<HH')               # dac u1, dac u2
# host frames received, CRC errors, device watchdog trips, state
DEVICE_HEARTBEAT_PAYLOAD = struct.Struct('<IIIB')

NAMES = {HELLO: 'HELLO', COMMAND: 'COMMAND', HEARTBEAT: 'HEARTBEAT', ARM: 'ARM',
         HELLO_ACK: 'HELLO_ACK', SAMPLE: 'SAMPLE', DEVICE_HEARTBEAT: 'DEVICE_HEARTBEAT'}
PAYLOADS = {HELLO: HELLO_PAYLOAD, COMMAND: COMMAND_PAYLOAD, HEARTBEAT: None, ARM: None,
            HELLO_ACK: HELLO_ACK_PAYLOAD, SAMPLE: SAMPLE_PAYLOAD,
            DEVICE_HEARTBEAT: DEVICE_HEARTBEAT_PAYLOAD}


class ProtocolError(ValueError):
    """A well-framed frame whose content is wrong (unknown type, bad payload length)."""


def crc16(data: bytes) -> int:
    """CRC-16/CCITT-FALSE of data (check value: crc16(b'123456789') == 0x29B1)."""
    return binascii.crc_hqx(data, 0xFFFF)


def encode_frame(frame_type: int, seq: int, payload: bytes = b'') -> bytes:
    if not 0 <= frame_type <= 0xFF:
        raise ValueError(f'frame type {frame_type} is not a byte')
    if len(payload) > MAX_PAYLOAD:
        raise ValueError(f'payload of {len(payload)} bytes > {MAX_PAYLOAD}')
    body = HEADER.pack(frame_type, seq & 0xFFFF, len(payload)) + payload
    return SYNC + body + CRC.pack(crc16(body))


@dataclass(frozen=True)
class Frame:
    type: int
    seq: int
    payload: bytes

    @property
    def name(self) -> str:
        return NAMES.get(self.type, f'0x{self.type:02x}')

    def fields(self) -> tuple:
        """The payload unpacked by the frame type's struct (ProtocolError if it is shorter).
        Bytes beyond it are fields a later minor version added at the end: ignored."""
        if self.type not in PAYLOADS:
            raise ProtocolError(f'unknown frame type 0x{self.type:02x}')
        layout = PAYLOADS[self.type]
        size = 0 if layout is None else layout.size
        if len(self.payload) < size:
            raise ProtocolError(f'{self.name} payload of {len(self.payload)} bytes, '
                                f'expected {size}')
        return () if layout is None else layout.unpack_from(self.payload)


# ---- payload helpers ---------------------------------------------------------------------------
@dataclass(frozen=True)
class Sample:
    """One SAMPLE's fields; adc_supply is None for a board without the supply transducer
    (or a 1.1 SAMPLE cut short: parse_sample)."""

    tick: int
    adc_p1: int
    adc_p2: int
    encoder: int
    adc_torque: int
    status: int = 0
    adc_supply: int | None = None


@dataclass(frozen=True)
class DeviceInfo:
    major: int
    minor: int
    rate: int
    adc_bits: int
    dac_bits: int
    flags: int

    @property
    def has_encoder(self) -> bool:
        return bool(self.flags & FLAG_ENCODER)

    @property
    def has_torque(self) -> bool:
        return bool(self.flags & FLAG_TORQUE)

    @property
    def has_supply(self) -> bool:
        """A supply-pressure transducer fitted: its SAMPLE frames carry SUPPLY_FIELD (1.1)."""
        return bool(self.flags & FLAG_SUPPLY)

    @property
    def has_arm(self) -> bool:
        """The device takes ARM (1.2 and later minor versions of major 1)."""
        return self.major == PROTOCOL_MAJOR and self.minor >= ARM_MINOR


def hello(seq: int, major: int = PROTOCOL_MAJOR, minor: int = PROTOCOL_MINOR) -> bytes:
    return encode_frame(HELLO, seq, HELLO_PAYLOAD.pack(major, minor))


def hello_ack(seq: int, info: DeviceInfo) -> bytes:
    return encode_frame(HELLO_ACK, seq, HELLO_ACK_PAYLOAD.pack(
        info.major, info.minor, info.rate, info.adc_bits, info.dac_bits, info.flags))


def command(seq: int, dac1: int, dac2: int) -> bytes:
    return encode_frame(COMMAND, seq, COMMAND_PAYLOAD.pack(dac1, dac2))


def heartbeat(seq: int) -> bytes:
    return encode_frame(HEARTBEAT, seq)


def arm(seq: int) -> bytes:
    """ARM (1.2): the device clears its latched faults whose cause is gone."""
    return encode_frame(ARM, seq)


def sample(seq: int, s: Sample) -> bytes:
    """A SAMPLE frame; with s.adc_supply (not None) SUPPLY_FIELD is appended (1.1), without it
    the frame is 1.0's byte for byte."""
    payload = SAMPLE_PAYLOAD.pack(s.tick & 0xFFFFFFFF, s.adc_p1, s.adc_p2, s.encoder,
                                  s.adc_torque, s.status)
    if s.adc_supply is not None:
        payload += SUPPLY_FIELD.pack(s.adc_supply)
    return encode_frame(SAMPLE, seq, payload)


def device_heartbeat(seq: int, rx_frames: int, rx_crc_errors: int, watchdog_trips: int,
                     state: int) -> bytes:
    return encode_frame(DEVICE_HEARTBEAT, seq, DEVICE_HEARTBEAT_PAYLOAD.pack(
        rx_frames & 0xFFFFFFFF, rx_crc_errors & 0xFFFFFFFF, watchdog_trips & 0xFFFFFFFF, state))


def parse_sample(frame: Frame, supply: bool = False) -> Sample:
    """The SAMPLE's fields; with supply (the device reported FLAG_SUPPLY) also SUPPLY_FIELD,
    adc_supply None when the payload ends before it."""
    fields = frame.fields()
    adc_supply = None
    if supply and len(frame.payload) >= SAMPLE_PAYLOAD.size + SUPPLY_FIELD.size:
        (adc_supply,) = SUPPLY_FIELD.unpack_from(frame.payload, SAMPLE_PAYLOAD.size)
    return Sample(*fields, adc_supply=adc_supply)


def parse_hello_ack(frame: Frame) -> DeviceInfo:
    return DeviceInfo(*frame.fields())


# ---- decoding ----------------------------------------------------------------------------------
class Decoder:
    """Streaming decoder: feed() bytes as they come, get the complete, valid frames.

    Bytes before a SYNC are garbage (counted). A header with a length > MAX_PAYLOAD or a frame
    whose CRC does not match counts as a CRC error; the decoder then drops the first SYNC byte
    only and searches again, so a valid frame hidden behind a false SYNC is never lost.
    """

    def __init__(self):
        self._buffer = bytearray()
        self.garbage_bytes = 0
        self.crc_errors = 0
        self.frames = 0

    def reset(self) -> None:
        self._buffer.clear()

    def feed(self, data: bytes) -> list[Frame]:
        buf = self._buffer
        buf.extend(data)
        frames = []
        while True:
            start = buf.find(SYNC)
            if start < 0:
                # keep a trailing first SYNC byte: the second may come with the next read
                keep = 1 if buf.endswith(SYNC[:1]) else 0
                self.garbage_bytes += len(buf) - keep
                del buf[:len(buf) - keep]
                break
            if start:
                self.garbage_bytes += start
                del buf[:start]
            if len(buf) < HEADER_SIZE:
                break
            frame_type, seq, length = HEADER.unpack_from(buf, len(SYNC))
            if length > MAX_PAYLOAD:
                self.crc_errors += 1
                del buf[:1]
                continue
            end = HEADER_SIZE + length + CRC.size
            if len(buf) < end:
                break
            body = bytes(buf[len(SYNC):HEADER_SIZE + length])
            (crc,) = CRC.unpack_from(buf, HEADER_SIZE + length)
            if crc != crc16(body):
                self.crc_errors += 1
                del buf[:1]
                continue
            frames.append(Frame(frame_type, seq, body[HEADER.size:]))
            self.frames += 1
            del buf[:end]
        return frames


class SequenceTracker:
    """Counts frames lost from the gaps in the 16-bit sequence numbers of one direction."""

    def __init__(self):
        self.last = None
        self.lost = 0
        self.gaps = 0

    def reset(self) -> None:
        self.last = None

    def update(self, seq: int) -> int:
        """Record seq; returns the number of frames missing before it (0 if in order)."""
        missing = 0
        if self.last is not None:
            missing = (seq - self.last - 1) & 0xFFFF
            if missing > 0x8000:   # a repeat or reordering, not a loss of 32768 frames
                missing = 0
            if missing:
                self.gaps += 1
                self.lost += missing
        self.last = seq
        return missing


class TickCounter:
    """The rig's sample counter (pam_interfaces/Pressures.sample) from the device's u32 tick:
    1 for the first sample the host received, then +1 per device tick, so that samples the
    device took but the host never got (frames lost or corrupted on the line, the stream down
    while reconnecting) are gaps downstream. A tick behind the last one (the device restarted)
    continues at +1 (counted in restarts): the counter never goes back."""

    def __init__(self):
        self.last_tick = None
        self.value = 0
        self.restarts = 0

    def update(self, tick: int) -> int:
        """The counter of the sample with this tick."""
        if self.last_tick is None:
            self.value = 1
        else:
            step = (tick - self.last_tick) & 0xFFFFFFFF
            if step == 0 or step > 0x7FFFFFFF:   # the same tick again or behind: a restart
                self.restarts += 1
                step = 1
            self.value += step
        self.last_tick = tick
        return self.value


class BoardVents:
    """The times the device's own watchdog vented the valves (no host frame for its watchdog
    time), from what the device reports: the status bit of each SAMPLE (a rising edge is a
    vent) and the trip counter of DEVICE_HEARTBEAT (which also covers a vent whose samples
    were lost). count is the larger of the two, over this host's sessions."""

    def __init__(self):
        self.edges = 0                  # rising edges of SAMPLE status bit 0
        self.trips = 0                  # increase of the heartbeat's counter since the first
        self.vented = False             # status bit 0 of the last SAMPLE
        self._last_heartbeat = None     # the heartbeat's counter last seen

    @property
    def count(self) -> int:
        return max(self.edges, self.trips)

    def on_sample(self, status: int) -> None:
        vented = bool(status & STATUS_VENTED)
        if vented and not self.vented:
            self.edges += 1
        self.vented = vented

    def on_heartbeat(self, watchdog_trips: int) -> None:
        if self._last_heartbeat is None:
            self.trips = self.edges     # the vents seen before the first heartbeat
        else:
            step = (watchdog_trips - self._last_heartbeat) & 0xFFFFFFFF
            if step <= 0x7FFFFFFF:      # else the device restarted: its counter begins again
                self.trips += step
        self._last_heartbeat = watchdog_trips
