"""pam-emulator: the DAQ board of the PAM rig on a pseudo-terminal (driver_node without hardware).

It speaks the protocol of PROTOCOL.md (pam_driver.daq_protocol) on the master side of a pty and
simulates the rig with pam_model.rig.SimulatedRig, one model step per sample, paced at 1 kHz by
absolute deadlines (pam_common.timing.DeadlineSchedule). The measured values go through the
calibration in reverse (SI -> volts -> ADC counts / encoder counts), the DAC counts of the
host's COMMAND frames through it forwards (counts -> V).

It prints the slave device path ("device: /dev/pts/N") and, with --link, keeps a symlink to the
current slave at a fixed path: after an emulated unplug/replug the pty is new (a new /dev/pts/N)
and the link is moved to it, as udev would for a USB device.

Device-side behaviour: the sample stream starts after a HELLO of the device's major protocol
version (--protocol-version announces another one: a HELLO of this driver's version is then
answered but no sample is streamed); the device vents both valves (0 V) when no host frame arrived
for --device-watchdog s, and stops streaming after 1 s of silence (a new HELLO restarts it).

What the device saw, for tests and for the curious: --status-file PATH is rewritten (atomically,
JSON) ten times a second and at exit: the host sessions (one per accepted HELLO) with the number
of COMMAND frames and the first and last command (V) of each, the HELLOs refused for their
version, the device watchdog trips, the samples sent and the faults injected. The exit line on
stdout says the last command too.

Supply pressure (PROTOCOL.md 1.1): --supply-sensor fits the supply line's transducer: the
device reports it in HELLO_ACK and appends its ADC reading to every SAMPLE, the plant's P_tank
of that sample (with the scenario's droop and ripple when its effects have them) through the
same noise as P1, P2 and the calibration's pressure.supply channel
(pam_driver.supply_sensor). Without it the frames are those of a board without the transducer,
byte for byte.

Faults (times in s after the first handshake): --garbage-every (random bytes between frames),
--corrupt-every (one byte of a sample frame flipped: CRC error), --drop-every (a sample frame not
sent: sequence gap), --disconnect-at/--disconnect-for (the device disappears: pty closed, link
removed; then a new pty), --stuck-sensor p1|p2 --stuck-at (that ADC channel frozen),
--broken-sensor p1|p2|supply --broken-at (that ADC channel reads 0 counts from then on: a wire
break).
"""

from __future__ import annotations

import argparse
import json
import os
import random
import signal
import sys
import time
import tty

from pam_common.timing import DeadlineSchedule
from pam_driver import daq_protocol as proto
from pam_driver.calibration import SUPPLY
from pam_model.rest import REST_STATE

MAX_PENDING = 65536   # bytes queued for a host that does not read: beyond, dropped
HOST_SILENCE_STOP = 1.0  # s without host frames: stop streaming


def build_parser() -> argparse.ArgumentParser:
    from pam_model.cli.common import add_model_arguments
    parser = argparse.ArgumentParser(
        prog='pam-emulator',
        description='Emulate the PAM rig DAQ board (protocol of pam_driver/PROTOCOL.md) on a '
                    'pseudo-terminal, with the plant simulated by pam_model, and inject faults.',
        epilog='Example: pam-emulator --link /tmp/pam_daq --locked & driver_node --ros-args -p '
               'port:=/tmp/pam_daq')
    parser.add_argument('--link', metavar='PATH',
                        help='keep a symlink to the current pty slave at PATH (stable across '
                             'emulated replugs)')
    parser.add_argument('--calibration', default='default', metavar='FILE',
                        help='calibration YAML (default: the shipped driver_calibration.yaml)')
    parser.add_argument('--rate', type=int, default=1000, help='sample rate in Hz (default 1000)')
    parser.add_argument('--x0', type=float, nargs=4, default=list(REST_STATE),
                        metavar=('PSI', 'PSI_DOT', 'P1', 'P2'),
                        help='initial state in rad, rad/s, Pa, Pa (default: 0 0 450e3 450e3)')
    parser.add_argument('--initial-command', type=float, nargs=2, default=[0.0, 0.0],
                        metavar=('U1', 'U2'),
                        help='valve voltages before the first COMMAND frame, in [0, 10] V '
                             '(default: 0 0, a board powering up with both muscles vented; 5.5 '
                             "5.5 starts at rest like sim_node's default initial_command)")
    parser.add_argument('--noise-std', type=float, default=500.0, metavar='PA',
                        help='pressure sensor noise std in Pa before the ADC (default 500)')
    parser.add_argument('--seed', type=int, default=0, help='noise and fault seed (default 0)')
    parser.add_argument('--freeze', action='store_true',
                        help='do not step the plant (static readings, calibration checks)')
    parser.add_argument('--no-encoder', action='store_true', help='report no encoder fitted')
    parser.add_argument('--no-torque', action='store_true', help='report no torque meter fitted')
    parser.add_argument('--supply-sensor', action='store_true',
                        help="fit a supply-pressure transducer (protocol 1.1): the plant's P_tank "
                             'in every SAMPLE, with the noise of --noise-std; the calibration '
                             'needs a pressure.supply section')
    parser.add_argument('--device-watchdog', type=float, default=0.25, metavar='S',
                        help='vent both valves after this long without host frames (default 0.25)')
    parser.add_argument('--duration', type=float, default=0.0, metavar='S',
                        help='exit after this long (default 0: run until SIGINT/SIGTERM)')
    parser.add_argument('--protocol-version', type=protocol_version,
                        default=(proto.PROTOCOL_MAJOR, proto.PROTOCOL_MINOR),
                        metavar='MAJOR.MINOR',
                        help='protocol version the device announces in HELLO_ACK (default '
                             f'{proto.PROTOCOL_MAJOR}.{proto.PROTOCOL_MINOR}); it streams only to '
                             'a HELLO of the same major version')
    parser.add_argument('--status-file', metavar='PATH',
                        help='keep a JSON summary of what the device received (host sessions, '
                             'commands, refused HELLOs, watchdog trips) at PATH, rewritten 10 '
                             'times a second and at exit')
    add_model_arguments(parser)
    faults = parser.add_argument_group('fault injection (times from the first handshake, s)')
    faults.add_argument('--garbage-every', type=float, default=0.0, metavar='S',
                        help='insert 1-16 random bytes between two frames every S s')
    faults.add_argument('--corrupt-every', type=float, default=0.0, metavar='S',
                        help='flip one byte of a sample frame every S s (a CRC error)')
    faults.add_argument('--drop-every', type=float, default=0.0, metavar='S',
                        help='do not send one sample frame every S s (a sequence gap)')
    faults.add_argument('--disconnect-at', type=float, default=-1.0, metavar='S',
                        help='unplug the device at S s (pty closed, link removed)')
    faults.add_argument('--disconnect-for', type=float, default=1.0, metavar='S',
                        help='replug after S s on a new pty (default 1.0)')
    faults.add_argument('--stuck-sensor', choices=('p1', 'p2'),
                        help='freeze this pressure ADC channel at --stuck-at')
    faults.add_argument('--stuck-at', type=float, default=1.0, metavar='S',
                        help='when the stuck sensor freezes (default 1.0)')
    faults.add_argument('--broken-sensor', choices=('p1', 'p2', 'supply'),
                        help='this pressure ADC channel reads 0 counts (a wire break) from '
                             '--broken-at on')
    faults.add_argument('--broken-at', type=float, default=1.0, metavar='S',
                        help='when the broken sensor breaks (default 1.0)')
    return parser


def protocol_version(text: str) -> tuple[int, int]:
    """'MAJOR.MINOR' -> (major, minor), each 0-255 (an argparse type)."""
    try:
        major, minor = (int(v) for v in text.split('.'))
    except ValueError:
        raise argparse.ArgumentTypeError(f'expected MAJOR.MINOR, got {text!r}') from None
    if not (0 <= major <= 255 and 0 <= minor <= 255):
        raise argparse.ArgumentTypeError(f'versions are bytes (0-255), got {text!r}')
    return major, minor


class Port:
    """One pty: master (the device side, non-blocking), slave kept open so it never hangs up."""

    def __init__(self, link: str | None):
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        os.set_blocking(self.master, False)
        self.path = os.ttyname(self.slave)
        self.link = link
        self.pending = bytearray()
        self.dropped_bytes = 0
        if link:
            tmp = f'{link}.tmp{os.getpid()}'
            if os.path.lexists(tmp):
                os.unlink(tmp)
            os.symlink(self.path, tmp)
            os.replace(tmp, link)

    def read(self) -> bytes:
        try:
            return os.read(self.master, 4096)
        except (BlockingIOError, InterruptedError):
            return b''
        except OSError:
            return b''

    def write(self, data: bytes) -> None:
        self.pending.extend(data)
        if len(self.pending) > MAX_PENDING:
            self.dropped_bytes += len(self.pending)
            self.pending.clear()
            return
        try:
            n = os.write(self.master, self.pending)
            del self.pending[:n]
        except (BlockingIOError, InterruptedError):
            pass
        except OSError:
            self.dropped_bytes += len(self.pending)
            self.pending.clear()

    def close(self) -> None:
        if self.link and os.path.islink(self.link) and os.readlink(self.link) == self.path:
            os.unlink(self.link)
        for fd in (self.master, self.slave):
            try:
                os.close(fd)
            except OSError:
                pass


class Every:
    """A periodic fault: due(t) is True once per period."""

    def __init__(self, period: float):
        self.period = period
        self.next = period

    def due(self, t: float) -> bool:
        if self.period <= 0.0 or t < self.next:
            return False
        self.next += self.period
        return True


class Emulator:
    def __init__(self, args):
        from pam_driver.calibration import load
        from pam_driver.supply_sensor import SupplySensor
        from pam_model.cli.common import build_model
        from pam_model.model import PamModel
        from pam_model.rig import SimulatedRig
        from pam_model.sensor import PressureSensor

        self.args = args
        self.cal = load(args.calibration)
        if args.supply_sensor and not self.cal.has_supply:
            raise ValueError(f'--supply-sensor: the calibration {self.cal.source} has no '
                             'pressure.supply section')
        if args.broken_sensor == 'supply' and not args.supply_sensor:
            raise ValueError('--broken-sensor supply needs --supply-sensor')
        model, scenario = build_model(args)
        if args.rate != 1000:
            model = PamModel(params=model.params, valve_map=model.valve_map,
                             friction=model.friction, force=model.force, locked=model.locked,
                             h=1.0 / args.rate)
        sensor = PressureSensor(noise_std=max(args.noise_std, 0.0), bits=0,
                                range_min=0.0, range_max=2e6)
        u0 = tuple(args.initial_command)
        if not all(0.0 <= u <= 10.0 for u in u0):
            raise ValueError(f'--initial-command must be within [0, 10] V, got {list(u0)}')
        self.rig = SimulatedRig(model, args.x0, sensor=sensor, seed=args.seed, u0=u0,
                                effects=scenario.effects)
        self.supply = SupplySensor(self.rig, sensor, args.seed) if args.supply_sensor else None
        self.rng = random.Random(args.seed)
        flags = (0 if args.no_encoder else proto.FLAG_ENCODER) | (
            0 if args.no_torque else proto.FLAG_TORQUE) | (
            proto.FLAG_SUPPLY if args.supply_sensor else 0)
        major, minor = args.protocol_version
        self.info = proto.DeviceInfo(major, minor, args.rate, self.cal.adc_bits,
                                     self.cal.dac_bits, flags)
        self.decoder = proto.Decoder()
        self.seq = 0
        self.tick = 0
        self.streaming = False
        self.last_host = -1e9
        self.t0 = None                    # monotonic time of the first handshake
        self.watchdog_tripped = False
        self.watchdog_trips = 0
        self.rx_frames = 0
        self.stuck_value = None
        self.broken = False
        self.faults = {'garbage': Every(args.garbage_every), 'corrupt': Every(args.corrupt_every),
                       'drop': Every(args.drop_every)}
        self.counts = {'garbage': 0, 'corrupt': 0, 'drop': 0, 'disconnect': 0}
        self.port = None
        self.disconnected_until = None
        self.disconnect_done = False
        self.samples_sent = 0
        self.sessions = []                # per accepted HELLO: commands, first, last (V)
        self.refused = {}                 # host version of the HELLOs refused -> how many
        self.next_status = 0.0

    def _next_seq(self) -> int:
        seq = self.seq
        self.seq = (self.seq + 1) & 0xFFFF
        return seq

    def open(self) -> None:
        self.port = Port(self.args.link)
        print(f'pam-emulator: device: {self.port.path}'
              + (f' (link {self.args.link})' if self.args.link else ''), flush=True)

    # ---- host frames -------------------------------------------------------------------------
    def handle_host(self, now: float) -> None:
        data = self.port.read()
        if not data:
            return
        for frame in self.decoder.feed(data):
            try:
                fields = frame.fields()
            except proto.ProtocolError:
                continue
            self.rx_frames += 1
            self.last_host = now
            if frame.type == proto.HELLO:
                self.port.write(proto.hello_ack(self._next_seq(), self.info))
                if fields[0] == self.info.major:
                    self.streaming = True
                    self.sessions.append({'commands': 0, 'first': None, 'last': None})
                    if self.t0 is None:
                        self.t0 = now
                        print('pam-emulator: host connected', flush=True)
                else:
                    self.streaming = False
                    if not self.refused:
                        print(f'pam-emulator: host speaks protocol {fields[0]}.{fields[1]}, the '
                              f'device {self.info.major}.{self.info.minor}: not streaming',
                              flush=True)
                    version = f'{fields[0]}.{fields[1]}'
                    self.refused[version] = self.refused.get(version, 0) + 1
            elif frame.type == proto.COMMAND:
                u1, u2 = (self.cal.valve_volts(c) for c in fields)
                self.rig.set_command(u1, u2)
                self.watchdog_tripped = False
                if self.sessions:
                    session = self.sessions[-1]
                    session['commands'] += 1
                    session['last'] = [u1, u2]
                    if session['first'] is None:
                        session['first'] = [u1, u2]
            elif frame.type == proto.HEARTBEAT:
                pass

    # ---- one sample --------------------------------------------------------------------------
    def sample_frame(self, t_fault: float) -> bytes:
        s = self.rig.sample()
        cal = self.cal
        adc1 = cal.pressure_counts(0, float(s.p_measured[0]))
        adc2 = cal.pressure_counts(1, float(s.p_measured[1]))
        if self.args.stuck_sensor and t_fault >= self.args.stuck_at:
            if self.stuck_value is None:
                self.stuck_value = adc1 if self.args.stuck_sensor == 'p1' else adc2
                print(f'pam-emulator: sensor {self.args.stuck_sensor} stuck', flush=True)
            if self.args.stuck_sensor == 'p1':
                adc1 = self.stuck_value
            else:
                adc2 = self.stuck_value
        encoder = cal.encoder_counts(float(s.x[0])) if not self.args.no_encoder else 0
        torque = cal.torque_counts(float(s.torque)) if not self.args.no_torque else 0
        status = proto.STATUS_VENTED if self.watchdog_tripped else 0
        supply = None
        if self.supply is not None:
            supply = cal.pressure_counts(SUPPLY, self.supply.measure())
        if self.args.broken_sensor and t_fault >= self.args.broken_at:
            if not self.broken:
                self.broken = True
                print(f'pam-emulator: sensor {self.args.broken_sensor} broken', flush=True)
            adc1, adc2, supply = (0 if self.args.broken_sensor == name else value for name, value
                                  in (('p1', adc1), ('p2', adc2), ('supply', supply)))
        return proto.sample(self._next_seq(), proto.Sample(self.tick, adc1, adc2, encoder,
                                                           torque, status, supply))

    def step(self, now: float) -> None:
        args = self.args
        t_fault = now - self.t0 if self.t0 is not None else -1.0
        # unplug / replug
        if self.disconnected_until is not None:
            if now >= self.disconnected_until:
                self.disconnected_until = None
                self.open()
        elif (not self.disconnect_done and args.disconnect_at >= 0.0
              and t_fault >= args.disconnect_at):
            self.disconnect_done = True
            self.counts['disconnect'] += 1
            print('pam-emulator: unplugged', flush=True)
            self.port.close()
            self.port = None
            self.streaming = False
            self.decoder.reset()
            self.disconnected_until = now + args.disconnect_for
        if self.port is not None:
            self.handle_host(now)
        if self.streaming and now - self.last_host > args.device_watchdog:
            if not self.watchdog_tripped:
                self.watchdog_tripped = True
                self.watchdog_trips += 1
                self.rig.set_command(0.0, 0.0)
            if now - self.last_host > HOST_SILENCE_STOP:
                self.streaming = False
        if not args.freeze and self.tick > 0:
            self.rig.step()
        self.tick += 1
        if self.port is None or not self.streaming:
            return
        frame = self.sample_frame(t_fault)
        if self.faults['drop'].due(t_fault):
            self.counts['drop'] += 1
            return
        if self.faults['corrupt'].due(t_fault):
            self.counts['corrupt'] += 1
            b = bytearray(frame)
            i = self.rng.randrange(proto.HEADER_SIZE, len(b) - proto.CRC.size)
            b[i] ^= 0x5A
            frame = bytes(b)
        if self.faults['garbage'].due(t_fault):
            self.counts['garbage'] += 1
            noise = bytes(self.rng.randrange(256) for _ in range(self.rng.randint(1, 16)))
            frame = noise.replace(b'\xa5', b'\x00') + frame  # no false SYNC: pure garbage
        if self.tick % max(self.info.rate // 10, 1) == 0:
            frame += proto.device_heartbeat(self._next_seq(), self.rx_frames,
                                            self.decoder.crc_errors, self.watchdog_trips,
                                            proto.STATUS_VENTED if self.watchdog_tripped else 0)
        self.port.write(frame)
        self.samples_sent += 1

    # ---- what the device saw -----------------------------------------------------------------
    def status(self) -> dict:
        last = next((x['last'] for x in reversed(self.sessions) if x['last'] is not None), None)
        return {'protocol': f'{self.info.major}.{self.info.minor}', 'streaming': self.streaming,
                'sessions': self.sessions, 'last_command': last,
                'refused_hellos': self.refused,
                'host_frames': self.rx_frames, 'device_watchdog_trips': self.watchdog_trips,
                'samples_sent': self.samples_sent, 'faults': self.counts}

    def write_status(self, now: float, force: bool = False) -> None:
        path = self.args.status_file
        if not path or (now < self.next_status and not force):
            return
        self.next_status = now + 0.1
        tmp = f'{path}.tmp{os.getpid()}'
        with open(tmp, 'w') as f:
            json.dump(self.status(), f)
        os.replace(tmp, path)

    def run(self) -> int:
        stop = []
        signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
        signal.signal(signal.SIGINT, lambda *_: stop.append(1))
        self.open()
        period = 1.0 / self.args.rate
        start = time.monotonic()
        schedule = DeadlineSchedule(period, start, 10)
        end = start + self.args.duration if self.args.duration > 0 else None
        try:
            while not stop:
                delay = schedule.deadline - time.monotonic()
                if delay > 0.0:
                    time.sleep(delay)
                now = time.monotonic()
                if end is not None and now >= end:
                    break
                self.step(now)
                self.write_status(now)
                schedule.advance(now)
        finally:
            if self.port is not None:
                self.port.close()
            self.write_status(time.monotonic(), force=True)
            last = self.status()['last_command']
            # the wall-clock time, to set beside the driver's log (a driver stopped after the
            # emulator logs 'device lost' then: the pty it had open closed under it)
            print(f'pam-emulator: stopped at {time.time():.3f}; last command {last} V, host '
                  f'sessions {len(self.sessions)}, faults injected: {self.counts}', flush=True)
        return 0


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    from pam_model.cli.common import run_cli
    return run_cli(lambda _: Emulator(args).run(), argv)


if __name__ == '__main__':
    sys.exit(main())
