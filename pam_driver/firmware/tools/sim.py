"""The emulated reference board for tests and benchmarks: pam-board-sim (the firmware's ELF on
simavr) with its plant, as one child process; its control commands and its JSON status.

    with SimBoard(tmp_path, eeprom=image) as board:
        board.command('estop 1'); board.status()['dac_codes']
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

FIRMWARE = Path(__file__).resolve().parents[1]
BUILD = FIRMWARE / 'build'
ELF = BUILD / 'pam_board.elf'
HARNESS = BUILD / 'pam-board-sim'
CALIBRATION = FIRMWARE / 'board_calibration.yaml'
TOOLCHAIN = ('apt-get install -y --no-install-recommends gcc-avr binutils-avr avr-libc simavr '
             'libsimavr-dev libsimavrparts1')


def build(*targets: str) -> None:
    """make -C firmware TARGETS (quiet, incremental); RuntimeError naming the toolchain."""
    done = subprocess.run(check=False, capture_output=True,
                          args=['make', '-s', '-C', str(FIRMWARE), *targets],
                          text=True)
    if done.returncode:
        raise RuntimeError(f'building the firmware failed (toolchain: {TOOLCHAIN}):\n'
                           f'{done.stdout}{done.stderr}')


class SimBoard:
    """pam-board-sim ELF --link DIR/board ... -- python sim/plant.py PLANT_ARGS."""

    def __init__(self, workdir: Path, plant_args=(), eeprom: bytes | None = None,
                 elf: Path = ELF, name: str = 'board'):
        workdir = Path(workdir)
        self.link = str(workdir / f'{name}_tty')
        self.status_file = workdir / f'{name}_status.json'
        self.eeprom = workdir / f'{name}_eeprom.bin'
        if eeprom is not None:
            self.eeprom.write_bytes(eeprom)
        self._out = tempfile.TemporaryFile(mode='w+b')    # noqa: SIM115 - closed by stop()
        args = [str(HARNESS), str(elf), '--link', self.link, '--status-file',
                str(self.status_file), '--eeprom', str(self.eeprom), '--',
                sys.executable, str(FIRMWARE / 'sim' / 'plant.py'), '--calibration',
                str(CALIBRATION), *plant_args]
        self.proc = subprocess.Popen(args, stdin=subprocess.PIPE, stdout=self._out,
                                     stderr=subprocess.STDOUT)
        self.wait_for(lambda: os.path.islink(self.link) and self.status() is not None, 45.0,
                      'the board pty')

    @property
    def output(self) -> str:
        # pread, not seek + read: the harness's stdout shares this file's offset, and a seek
        # here would make its next line overwrite the start of the file
        fd = self._out.fileno()
        return os.pread(fd, os.fstat(fd).st_size, 0).decode(errors='replace')

    def alive(self) -> bool:
        return self.proc.poll() is None

    def command(self, line: str) -> None:
        self.proc.stdin.write(f'{line}\n'.encode())
        self.proc.stdin.flush()

    def status(self) -> dict | None:
        try:
            return json.loads(self.status_file.read_text())
        except (OSError, ValueError):
            return None

    def wait_for(self, predicate, timeout: float, what: str):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            value = predicate()
            if value:
                return value
            if not self.alive():
                raise AssertionError(f'pam-board-sim exited ({self.proc.returncode}) waiting for '
                                     f'{what}:\n{self.output[-3000:]}')
            time.sleep(0.02)
        raise AssertionError(f'timed out waiting for {what}; pam-board-sim:\n'
                             f'{self.output[-3000:]}')

    def wait_status(self, predicate, timeout: float, what: str) -> dict:
        return self.wait_for(lambda: (s := self.status()) is not None and predicate(s) and s,
                             timeout, what)

    def stop(self) -> dict | None:
        if self.alive():
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(timeout=10.0)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        trace = os.environ.get('PAM_BOARD_SIM_TRACE')   # FILE: the harness's output kept there
        if trace and not self._out.closed:
            with open(trace, 'a') as f:
                f.write(self.output)
        self._out.close()
        return self.status()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.stop()
