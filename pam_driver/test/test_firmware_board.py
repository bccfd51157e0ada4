"""The reference board's firmware (pam_driver/firmware) on simavr's ATmega2560, spoken to directly
over its pty (no ROS): the session of PROTOCOL.md, the calibration in EEPROM, auto-zero, the
latched faults and their re-arm, the limits and the AVR watchdog. Run by `make firmware-test`
(PAM_FIRMWARE_TEST=1), which builds the ELF and the harness first; the core's host unit tests are
`make -C pam_driver/firmware unit`."""

from __future__ import annotations

import importlib
import os
import struct
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

# the board's tools are files of the repository (pam_driver/firmware/tools), not a package
FIRMWARE = Path(__file__).resolve().parents[1] / 'firmware'
sys.path.insert(0, str(FIRMWARE))
bt = importlib.import_module('tools.board_tool')
_sim = importlib.import_module('tools.sim')
SimBoard, build = _sim.SimBoard, _sim.build

from pam_driver import daq_protocol as proto  # noqa: E402
from pam_driver.calibration import load  # noqa: E402

pytestmark = pytest.mark.skipif(not os.environ.get('PAM_FIRMWARE_TEST'),
                                reason='run by `make firmware-test` (PAM_FIRMWARE_TEST=1)')
CAL = load(str(FIRMWARE / 'board_calibration.yaml'))
VENTED = ('--x0', '0', '0', '101300', '101300')       # the muscles at atmosphere


@pytest.fixture(scope='module', autouse=True)
def firmware():
    build('all', 'harness')


def image(**options) -> bytes:
    c = bt.BoardCalibration(**options)
    return c.to_bytes() + b'\xff' * (4096 - 36)


def command(board: bt.Board, u1: int, u2: int) -> None:
    board.send(proto.COMMAND, struct.pack('<HH', u1, u2))


def heartbeat_where(board: bt.Board, predicate, timeout: float = 1.0) -> dict:
    """The first DEVICE_HEARTBEAT satisfying predicate (one in flight may predate a request)."""
    end = time.monotonic() + timeout
    hb = None
    while time.monotonic() < end:
        hb = board.heartbeat(max(end - time.monotonic(), 0.01))
        if predicate(hb):
            return hb
    raise AssertionError(f'no such heartbeat: the last {hb}')


def samples(frames) -> list:
    return [proto.parse_sample(f, True) for f in frames if f.type == proto.SAMPLE]


def test_session_stream_and_commands(tmp_path):
    with SimBoard(tmp_path, VENTED, eeprom=image(safe_code=(100, 200), cmd_max=(4095, 3000))) \
            as sim:
        sim.wait_status(lambda s: s['dac_codes'] == [100, 200], 5.0, 'the safe output at boot')
        board = bt.Board(sim.link)
        board.keepalive = False
        assert board.frames(0.3) == []                   # silent until HELLO
        board.keepalive = True
        info = board.hello()
        assert (info.major, info.minor, info.rate, info.adc_bits, info.dac_bits, info.flags) == \
            (1, 2, 1000, 12, 12, 7)
        got = samples(board.frames(1.0))
        ticks = [s.tick for s in got]
        assert len(got) >= 900 and ticks == list(range(ticks[0], ticks[0] + len(ticks)))
        p1 = CAL.pressure(0, got[-1].adc_p1)
        assert abs(p1 - 101300) < 5000, p1                # the plant's P1, through the ADC
        assert abs(CAL.torque(got[-1].adc_torque)) < 0.2
        command(board, 3000, 3500)
        s = sim.wait_status(lambda s: s['dac_codes'] == [3000, 3000], 2.0, 'the command')
        assert s['dac_volts'][0] == pytest.approx(CAL.valve_volts(3000), abs=1e-3)
        hb = heartbeat_where(board, lambda hb: hb['dac'] == [3000, 3000])
        assert hb['clipped_commands'] == 1
        assert hb['reset_cause'] == ['power-on'] and hb['faults'] == []
        # the joint moves: the encoder counts through the quadrature lines
        command(board, 3500, 500)
        moved = samples(board.frames(1.0))[-1].encoder
        assert abs(moved - sim.status()['encoder']) < 50 and moved != 0, moved
        # communication loss: vent to the safe codes after 250 ms, counted, cleared by a COMMAND
        board.keepalive = False
        t0 = time.monotonic()
        sim.wait_status(lambda s: s['dac_codes'] == [100, 200], 2.0, 'the vent')
        assert time.monotonic() - t0 < 0.6
        vented = samples(board.frames(0.1))
        assert vented and vented[-1].status & 1          # the newest samples say so
        command(board, 1000, 1000)
        board.keepalive = True
        sim.wait_status(lambda s: s['dac_codes'] == [1000, 1000], 1.0, 'the command after')
        heartbeat_where(board, lambda hb: hb['dac'] == [1000, 1000] and hb['state'] == 0)
        assert board.heartbeat()['comm_loss_vents'] == 1
        # another major version: answered, not streamed
        board.send(proto.HELLO, bytes((2, 0)))
        ack = proto.parse_hello_ack(board.wait(proto.HELLO_ACK))
        assert ack.major == 1
        board.frames(0.05)
        assert samples(board.frames(0.3)) == []
        board.close()


def test_received_bytes_garbage_split_and_corrupted_frames(tmp_path):
    """The firmware takes a frame whole once its last byte is in, and hands anything else to its
    resynchronising decoder: garbage before a frame, a frame written in pieces, a corrupted
    frame or a bad length just before a good one, back-to-back frames in one write."""
    with SimBoard(tmp_path, VENTED, eeprom=image(safe_code=(100, 200))) as sim:
        sim.wait_status(lambda s: s['dac_codes'] == [100, 200], 5.0, 'the safe output at boot')
        board = bt.Board(sim.link)
        board.hello()
        base = board.heartbeat()

        def write(data: bytes) -> None:
            os.write(board.fd, data)
            board._last_sent = time.monotonic()

        def applied(codes, what):
            sim.wait_status(lambda s: s['dac_codes'] == codes, 2.0, what)

        def cmd(u1, u2, seq=7) -> bytes:
            return proto.encode_frame(proto.COMMAND, seq, struct.pack('<HH', u1, u2))

        write(b'\x00\x11' + bytes((proto.SYNC[0], 0x22, proto.SYNC[0])) + cmd(1001, 1002))
        applied([1001, 1002], 'a COMMAND after garbage')
        frame = cmd(1101, 1102)
        for a, b in ((0, 1), (1, 5), (5, 9), (9, len(frame))):  # SYNC, header, payload, CRC
            write(frame[a:b])
            time.sleep(0.02)
        applied([1101, 1102], 'a COMMAND written in pieces')
        bad = bytearray(cmd(1201, 1202))
        bad[-1] ^= 0xFF                                 # its CRC broken
        write(bytes(bad) + cmd(1301, 1302))
        applied([1301, 1302], 'the COMMAND after a corrupted one')
        long = bytearray(cmd(1401, 1402))
        long[5] = 200                                   # a length beyond 64
        write(bytes(long) + cmd(1501, 1502))
        applied([1501, 1502], 'the COMMAND after a bad length')
        write(b''.join(cmd(1600 + k, 1700 + k, seq=k) for k in range(5)))
        applied([1604, 1704], 'the newest of five COMMANDs in one write')
        hb = heartbeat_where(board, lambda hb: hb['dac'] == [1604, 1704])
        # every good frame counted (the keepalive HEARTBEATs too), the corrupted one not
        assert 2 <= hb['crc_errors'] - base['crc_errors'] <= 10, (base, hb)
        assert hb['host_frames'] - base['host_frames'] >= 9
        got = samples(board.frames(0.3))
        assert len(got) >= 250                          # still streaming, in sync
        board.close()


def test_heartbeats_keep_their_rate_under_a_command_every_period(tmp_path):
    """A DEVICE_HEARTBEAT due waits for a tick period that has received no frame before 0.8 ms,
    at most 20 periods: with a host writing COMMANDs faster than the periods (no period without
    one) the heartbeats still come at 10 Hz, none later than 20 ms after its moment."""
    with SimBoard(tmp_path, VENTED) as sim:
        sim.wait_status(lambda s: s['ms'] > 100, 5.0, 'the board running')
        board = bt.Board(sim.link)
        board.hello()
        board.decoder = proto.Decoder()
        arrivals = []
        end = time.monotonic() + 2.0
        k = 0
        while time.monotonic() < end:                   # about three COMMANDs a period
            command(board, 1000 + k % 500, 2000)
            k += 1
            try:                                        # not Board._read: it sleeps 2 ms
                frames = board.decoder.feed(os.read(board.fd, 4096))
            except BlockingIOError:
                frames = []
            arrivals += [time.monotonic() for f in frames if f.type == proto.DEVICE_HEARTBEAT]
            time.sleep(0.0002)
        status = sim.status()
        board.close()
    gaps = np.diff(arrivals)
    assert k > 2000 and 17 <= len(arrivals) <= 21, (k, len(arrivals))
    assert gaps.max() < 0.1 + 0.02 + 0.05, gaps      # 100 ms, 20 ms of waiting, the host's lag
    assert status['command_frames'] >= 0.9 * k


def test_the_build_refuses_code_that_uses_the_uart_isrs_registers(tmp_path):
    """r2-r4 are the UART ISRs' (-ffixed-r2/r3/r4): built without reserving them, the compiler
    uses them elsewhere and the build's check of the linked ELF fails, leaving no ELF behind."""
    done = subprocess.run(['make', '-s', '-C', str(FIRMWARE), f'BUILD={tmp_path}', 'ISR_REGS=',
                           str(tmp_path / 'pam_board.elf')],
                          capture_output=True, text=True, check=False)
    assert done.returncode != 0
    assert 'r2-r4 used outside the UART ISRs' in done.stdout + done.stderr
    assert not (tmp_path / 'pam_board.elf').exists()
    done = subprocess.run(['make', '-s', '-C', str(FIRMWARE), f'BUILD={tmp_path}',
                           str(tmp_path / 'pam_board.elf')],
                          capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stdout + done.stderr
    assert (tmp_path / 'pam_board.elf').exists()


def test_calibration_eeprom_and_auto_zero(tmp_path):
    # the transducers read 0.05 V high (P1) and 0.03 V low (P2): 41 and -25 counts
    plant = (*VENTED, '--offset-volts', '0.05', '-0.03')
    with SimBoard(tmp_path, plant) as sim:                # a blank EEPROM: the defaults
        board = bt.Board(sim.link)
        board.hello()
        hb = board.heartbeat(1.0)
        assert hb['calibration_defaulted']
        raw = samples(board.frames(0.3))
        assert abs(sum(s.adc_p1 for s in raw) / len(raw) - (410 + 41)) < 4
        result, cal = board.cal(bt.ZERO)
        assert result == 'started'
        reply = board.wait(bt.CAL, 2.0)
        assert bt.CAL_RESULTS[reply.payload[0]] == 'ok'
        zeroed = bt.BoardCalibration.from_bytes(reply.payload[1:])
        assert abs(zeroed.zero_offset[0] - 41) <= 2 and abs(zeroed.zero_offset[1] + 25) <= 2
        got = samples(board.frames(0.3))
        assert abs(sum(s.adc_p1 for s in got) / len(got) - 410) < 3
        assert abs(sum(s.adc_p2 for s in got) / len(got) - 410) < 3
        # a calibration write: safe codes for a closed-centre valve, limits
        new = bt.BoardCalibration(**{**zeroed.__dict__, 'safe_code': (2048, 2048),
                                     'cmd_max': (3500, 3500)})
        result, stored = board.cal(bt.CAL_WRITE, new.to_bytes()[:34])
        assert result == 'ok' and stored.safe_code == (2048, 2048)
        sim.wait_status(lambda s: s['dac_codes'] == [2048, 2048], 1.0, 'the new safe output')
        bad = bt.BoardCalibration(**{**new.__dict__, 'cmd_min': (4000, 0)})
        assert board.cal(bt.CAL_WRITE, bad.to_bytes()[:34])[0] == 'invalid'
        board.close()
    # a power cycle: the EEPROM kept it (CRC checked by the firmware)
    with SimBoard(tmp_path, plant, eeprom=None) as sim:
        sim.wait_status(lambda s: s['dac_codes'] == [2048, 2048], 5.0, 'the stored safe output')
        board = bt.Board(sim.link)
        board.hello()
        result, cal = board.cal(bt.CAL_READ)
        assert cal.zero_offset[:2] == zeroed.zero_offset[:2] and cal.cmd_max == (3500, 3500)
        assert not board.heartbeat()['calibration_defaulted']
        board.close()
    # a corrupted EEPROM byte: the CRC fails, the defaults are used (and said so)
    data = bytearray((tmp_path / 'board_eeprom.bin').read_bytes())
    data[20] ^= 0x01
    with SimBoard(tmp_path, plant, eeprom=bytes(data)) as sim:
        board = bt.Board(sim.link)
        board.hello()
        assert board.heartbeat()['calibration_defaulted']
        assert board.cal(bt.CAL_READ)[1].safe_code == (0, 0)
        board.close()


def test_estop_overpressure_and_rearm(tmp_path):
    limit = CAL.pressure_counts(0, 300e3 + CAL.atmosphere)     # 300 kPa gauge
    with SimBoard(tmp_path, VENTED, eeprom=image(safe_code=(0, 0), p_max_counts=limit)) as sim:
        board = bt.Board(sim.link)
        board.hello()
        command(board, 2000, 2000)
        sim.wait_status(lambda s: s['dac_codes'] == [2000, 2000], 1.0, 'the command')
        sim.command('estop 1')
        sim.wait_status(lambda s: s['dac_codes'] == [0, 0], 0.5, 'the e-stop vent')
        got = samples(board.frames(0.1))
        assert got and all(s.status & 0b111 == 0b111 for s in got[-5:])
        command(board, 2000, 2000)                       # latched: ignored
        board.send(bt.ARM)                               # cause still present: stays latched
        command(board, 2000, 2000)
        time.sleep(0.2)
        assert sim.status()['dac_codes'] == [0, 0]
        heartbeat_where(board, lambda hb: hb['faults'] == ['e-stop'])
        sim.command('estop 0')
        time.sleep(0.1)
        command(board, 2000, 2000)                       # released, not re-armed
        time.sleep(0.2)
        assert sim.status()['dac_codes'] == [0, 0]
        board.send(bt.ARM)
        command(board, 2000, 2000)
        sim.wait_status(lambda s: s['dac_codes'] == [2000, 2000], 1.0, 'the command after ARM')
        # over-pressure: fill P1 beyond 300 kPa gauge -> latched, vented, re-armed once below
        command(board, 4095, 0)
        t0 = time.monotonic()
        while time.monotonic() - t0 < 5.0 and sim.status()['dac_codes'] != [0, 0]:
            command(board, 4095, 0)                      # keep the host alive
            time.sleep(0.05)
        assert sim.status()['dac_codes'] == [0, 0], 'no over-pressure trip'
        heartbeat_where(board, lambda hb: hb['faults'] == ['over-pressure'])
        time.sleep(1.0)                                  # vented: the pressure falls
        board.frames(0.01)
        board.send(bt.ARM)
        command(board, 1000, 1000)
        sim.wait_status(lambda s: s['dac_codes'] == [1000, 1000], 1.0, 're-armed')
        board.close()


def test_watchdog_resets_a_hung_firmware_into_its_safe_output(tmp_path):
    with SimBoard(tmp_path, VENTED, eeprom=image(safe_code=(1000, 1500))) as sim:
        board = bt.Board(sim.link)
        board.hello()
        command(board, 3000, 3000)
        sim.wait_status(lambda s: s['dac_codes'] == [3000, 3000], 1.0, 'the command')
        sim.command('spi_stall 100')            # the tick ISR waits for SPIF forever
        sim.wait_status(lambda s: s['resets'] >= 1 and s['dac_codes'] == [1000, 1500], 2.0,
                            'the watchdog reset into the safe output')
        time.sleep(0.2)                         # the bus stays dead 100 ms: each boot hangs again
        resets = sim.status()['resets']         # and resets again (the watchdog is on first)
        assert 1 <= resets <= 4, resets
        board.frames(0.05)
        info = board.hello()                    # the reset board waits for a HELLO again
        assert info.rate == 1000
        heartbeat_where(board, lambda hb: hb['reset_cause'] == ['watchdog']
                        and hb['faults'] == ['watchdog reset'])
        command(board, 3000, 3000)              # latched until ARM
        time.sleep(0.2)
        assert sim.status()['dac_codes'] == [1000, 1500]
        board.send(bt.ARM)
        command(board, 3000, 3000)
        sim.wait_status(lambda s: s['dac_codes'] == [3000, 3000], 1.0, 'the command after ARM')
        assert sim.status()['resets'] == resets  # the watchdog stays quiet while the loop runs
        board.close()
