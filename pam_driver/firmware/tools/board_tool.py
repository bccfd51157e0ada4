"""board_tool: the reference board's calibration and re-arm over its serial port (protocol 1.2).

    board_tool.py PORT status                      HELLO, then the first DEVICE_HEARTBEAT decoded
    board_tool.py PORT read                        the calibration stored in the board's EEPROM
    board_tool.py PORT write [options]             change fields of it (only while the board holds
                                                   its safe output: no host commanding)
    board_tool.py PORT zero                        auto-zero P1 and P2 (muscles vented!)
    board_tool.py PORT arm                         clear the latched faults whose cause is gone
    board_tool.py --image FILE write [options]     an EEPROM image of the defaults + options
                                                   (pam-board-sim --eeprom FILE; on a board:
                                                   avrdude ... -U eeprom:w:FILE:r)

Options of write: --safe-volts U1 U2 (the valves' output in every safe state, V; a 5/3 valve's
closed centre is about 5 V), --command-volts MIN MAX (COMMANDs clipped to it), --pressure-max-pa P
(gauge Pa: above it for 5 samples -> latched fault), --fitted encoder,torque,supply. Volts and
pascals are converted with the board's driver calibration (board_calibration.yaml beside this
tool, or --calibration).

The layout mirrors core/calib.h (36 bytes, little-endian, CRC-16 over the first 34).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import struct
import sys
import time
import tty
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1]))           # pam_driver's source when not installed
from pam_driver import daq_protocol as proto  # noqa: E402

LAYOUT = struct.Struct('<HBB3h3HH2H2H2HHBB')        # the fields before the CRC (34 bytes)
MAGIC, VERSION = 0x4350, 1
ARM, ZERO, CAL_WRITE, CAL_READ, CAL = 0x04, 0x05, 0x06, 0x07, 0x86
CAL_RESULTS = {0: 'ok', 1: 'invalid', 2: 'refused: the board is not at its safe output',
               3: 'refused: P1/P2 not at atmosphere', 4: 'started'}
FITTED = {'encoder': 1, 'torque': 2, 'supply': 4}
FAULTS = {1: 'e-stop', 2: 'over-pressure', 4: 'watchdog reset'}
RESETS = {1: 'power-on', 2: 'external', 4: 'brown-out', 8: 'watchdog'}


@dataclasses.dataclass
class BoardCalibration:
    fitted: int = 7
    zero_offset: tuple = (0, 0, 0)
    gain_q14: tuple = (16384, 16384, 16384)
    nominal_zero: int = 410
    safe_code: tuple = (0, 0)
    cmd_min: tuple = (0, 0)
    cmd_max: tuple = (4095, 4095)
    p_max_counts: int = 3686
    p_max_samples: int = 5

    def to_bytes(self) -> bytes:
        body = LAYOUT.pack(MAGIC, VERSION, self.fitted, *self.zero_offset, *self.gain_q14,
                           self.nominal_zero, *self.safe_code, *self.cmd_min, *self.cmd_max,
                           self.p_max_counts, self.p_max_samples, 0)
        return body + struct.pack('<H', proto.crc16(body))

    @classmethod
    def from_bytes(cls, data: bytes) -> BoardCalibration:
        f = LAYOUT.unpack(data[:LAYOUT.size])
        crc, = struct.unpack('<H', data[LAYOUT.size:LAYOUT.size + 2])
        if f[0] != MAGIC or f[1] != VERSION or crc != proto.crc16(data[:LAYOUT.size]):
            raise ValueError('not a valid board calibration (magic, version or CRC)')
        return cls(f[2], f[3:6], f[6:9], f[9], f[10:12], f[12:14], f[14:16], f[16], f[17])


class Board:
    """The board's serial port, raw (a pty of pam-board-sim or /dev/ttyACM0 at 1 Mbaud)."""

    def __init__(self, port: str, baud: int = 1_000_000):
        self.fd = os.open(port, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        tty.setraw(self.fd)
        if not os.path.realpath(port).startswith('/dev/pts/'):
            import termios
            attrs = termios.tcgetattr(self.fd)
            speed = getattr(termios, f'B{baud}')
            attrs[4] = attrs[5] = speed
            termios.tcsetattr(self.fd, termios.TCSANOW, attrs)
        self.decoder = proto.Decoder()
        self.seq = 0
        self.keepalive = True           # a HEARTBEAT every 50 ms while waiting, as a host does
        self._last_sent = time.monotonic()

    def close(self) -> None:
        os.close(self.fd)

    def send(self, frame_type: int, payload: bytes = b'') -> None:
        os.write(self.fd, proto.encode_frame(frame_type, self.seq, payload))
        self.seq = (self.seq + 1) & 0xFFFF
        self._last_sent = time.monotonic()

    def _read(self) -> list:
        if self.keepalive and time.monotonic() - self._last_sent > 0.05:
            self.send(proto.HEARTBEAT)
        try:
            return self.decoder.feed(os.read(self.fd, 4096))
        except BlockingIOError:
            time.sleep(0.002)
            return []

    def wait(self, frame_type: int, timeout: float = 1.0):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            for frame in self._read():
                if frame.type == frame_type:
                    return frame
        raise TimeoutError(f'no frame 0x{frame_type:02x} from the board in {timeout} s')

    def frames(self, duration: float) -> list:
        end, out = time.monotonic() + duration, []
        while time.monotonic() < end:
            out += self._read()
        return out

    def hello(self, major: int = proto.PROTOCOL_MAJOR, minor: int = 2) -> proto.DeviceInfo:
        """HELLO until HELLO_ACK (a board still booting misses the first), its DeviceInfo."""
        for attempt in range(4):
            self.send(proto.HELLO, bytes((major, minor)))
            try:
                return proto.parse_hello_ack(self.wait(proto.HELLO_ACK, 0.5))
            except TimeoutError:
                if attempt == 3:
                    raise
        raise AssertionError('unreachable')

    def cal(self, frame_type: int, payload: bytes = b'', timeout: float = 1.0):
        """(result text, BoardCalibration) of a CAL_READ / CAL_WRITE / ZERO request."""
        self.send(frame_type, payload)
        reply = self.wait(CAL, timeout)
        return CAL_RESULTS.get(reply.payload[0], str(reply.payload[0])), \
            BoardCalibration.from_bytes(reply.payload[1:])

    def heartbeat(self, timeout: float = 1.0) -> dict:
        return decode_heartbeat(self.wait(proto.DEVICE_HEARTBEAT, timeout).payload)


def decode_heartbeat(p: bytes) -> dict:
    rx, crc, trips, state = struct.unpack_from('<IIIB', p)
    out = {'host_frames': rx, 'crc_errors': crc, 'comm_loss_vents': trips, 'state': state}
    if len(p) >= 32:       # 1.2
        faults, reset, defaulted, overruns, worst, uart, perr, clipped, d1, d2 = \
            struct.unpack_from('<BBBHHHHIHH', p, 13)
        out.update(faults=[n for b, n in FAULTS.items() if faults & b],
                   reset_cause=[n for b, n in RESETS.items() if reset & b],
                   calibration_defaulted=bool(defaulted), loop_overruns=overruns,
                   worst_tick_us=worst, uart_errors=uart, protocol_errors=perr,
                   clipped_commands=clipped, dac=[d1, d2])
    return out


def apply_options(c: BoardCalibration, args, cal) -> BoardCalibration:
    if args.safe_volts:
        c.safe_code = tuple(cal.dac_counts(v) for v in args.safe_volts)
    if args.command_volts:
        c.cmd_min = (cal.dac_counts(args.command_volts[0]),) * 2
        c.cmd_max = (cal.dac_counts(args.command_volts[1]),) * 2
    if args.pressure_max_pa is not None:
        c.p_max_counts = cal.pressure_counts(0, args.pressure_max_pa + cal.atmosphere)
    if args.fitted is not None:
        c.fitted = sum(FITTED[n] for n in args.fitted.split(',') if n)
    return c


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog='board_tool.py', description=__doc__.splitlines()[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter,
                                epilog='\n'.join(__doc__.splitlines()[1:]))
    p.add_argument('port', nargs='?', help='serial port of the board')
    p.add_argument('action', choices=('status', 'read', 'write', 'zero', 'arm'))
    p.add_argument('--image', metavar='FILE', help='write an EEPROM image instead of a board')
    p.add_argument('--calibration', default=str(HERE.parent / 'board_calibration.yaml'))
    p.add_argument('--safe-volts', type=float, nargs=2, metavar=('U1', 'U2'))
    p.add_argument('--command-volts', type=float, nargs=2, metavar=('MIN', 'MAX'))
    p.add_argument('--pressure-max-pa', type=float, metavar='PA')
    p.add_argument('--fitted', metavar='LIST', help='e.g. encoder,torque (default: all three)')
    return p


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    from pam_driver.calibration import load
    cal = load(args.calibration)
    if args.image:
        if args.action != 'write':
            raise SystemExit('--image: only the action write')
        image = apply_options(BoardCalibration(), args, cal).to_bytes()
        Path(args.image).write_bytes(image + b'\xff' * (4096 - len(image)))
        print(f'board_tool: EEPROM image {args.image}')
        return 0
    if not args.port:
        raise SystemExit('board_tool: give the PORT (or --image)')
    board = Board(args.port)
    try:
        info = board.hello()
        print(f'board: protocol {info.major}.{info.minor}, {info.rate} Hz, flags {info.flags}')
        if args.action == 'status':
            print(board.heartbeat(1.5))
        elif args.action == 'read':
            print(board.cal(CAL_READ))
        elif args.action == 'write':
            _, current = board.cal(CAL_READ)
            new = apply_options(current, args, cal)
            result, stored = board.cal(CAL_WRITE, new.to_bytes()[:LAYOUT.size])
            print(result, stored)
            return 0 if result == 'ok' else 1
        elif args.action == 'zero':
            result, _ = board.cal(ZERO)
            if result != 'started':
                print(result)
                return 1
            reply = board.wait(CAL, 2.0)
            result = CAL_RESULTS.get(reply.payload[0])
            print(result, BoardCalibration.from_bytes(reply.payload[1:]))
            return 0 if result == 'ok' else 1
        elif args.action == 'arm':
            board.send(ARM)
            print(board.heartbeat(1.5))
    finally:
        board.close()
    return 0


if __name__ == '__main__':
    sys.exit(main())
