"""Print the reference board's figures measured by `make firmware-test` (README.md, firmware):
flash and RAM from the ELF, and from the closed-loop run on simavr (build/figures.json, written by
pam_bringup/test/test_firmware_driver.py): CPU cycles per 1 ms tick, UART use, the COMMAND -> DAC
delay and the loop's steady-state error against pam-emulator's."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

BUILD = Path(__file__).resolve().parents[1] / 'build'
FLASH, RAM = 262144, 8192
LINE = 100000.0                 # bytes/s of a 1 Mbaud 8N1 line (10 bits a byte)


def sizes(elf: Path) -> tuple[int, int]:
    out = subprocess.run(['avr-size', '-A', str(elf)], capture_output=True, text=True,
                         check=True).stdout
    s = {f[0]: int(f[1]) for f in (line.split() for line in out.splitlines()) if len(f) >= 2
         and f[0].startswith('.') and f[1].isdigit()}
    return s.get('.text', 0) + s.get('.data', 0), \
        s.get('.data', 0) + s.get('.bss', 0) + s.get('.noinit', 0)


def main() -> int:
    flash, ram = sizes(BUILD / 'pam_board.elf')
    print('reference board (ATmega2560 @ 16 MHz, firmware on simavr 1.6):')
    print(f'  flash {flash} B of {FLASH} ({100 * flash / FLASH:.1f} %), static RAM {ram} B of '
          f'{RAM} ({100 * ram / RAM:.1f} %)')
    path = BUILD / 'figures.json'
    if not path.exists():
        print(f'  no closed-loop figures ({path} missing: the closed-loop test did not run)')
        return 1
    f = json.loads(path.read_text())
    b, loop = f['board'], f['closed_loop']
    per = b['cycles_per_ms']
    print(f"  CPU per 1 ms tick period (ISRs included, during the closed loop): worst "
          f"{b['tick_cycles_worst']} cycles = {100 * b['tick_cycles_worst'] / per:.0f} % "
          f"(target <= 50 %: {'met' if b['tick_cycles_worst'] <= per / 2 else 'MISSED'}), "
          f"mean {b['tick_cycles_mean']:.0f} = {100 * b['tick_cycles_mean'] / per:.0f} %")
    if 'tick_cycles_p99' in b:
        print(f"    99 % of the {b['ticks']} periods <= {100 * b['tick_cycles_p99'] / per:.0f} %, "
              f"99.9 % <= {100 * b['tick_cycles_p999'] / per:.0f} %; {b['ticks_over_half']} "
              f"periods above 50 %")
    print(f"  UART at 1 Mbaud: board -> host {b['tx_bytes_per_s']:.0f} B/s = "
          f"{100 * b['tx_bytes_per_s'] / LINE:.1f} % of the line, host -> board "
          f"{b['rx_bytes_per_s']:.0f} B/s = {100 * b['rx_bytes_per_s'] / LINE:.1f} %")
    print(f"  COMMAND frame's last byte -> both DAC outputs (LDAC): worst "
          f"{b['command_delay_worst_us']:.1f} us, mean {b['command_delay_mean_us']:.1f} us over "
          f"{b['command_delays']} commands")
    print(f"  closed loop (driver_node + ukf_node + pi_node, angle step {loop['level_rad']} rad, "
          f"'mild' plant, seed 0): steady-state error through the board "
          f"{loop['error_board_rad']:+.4f} rad, through pam-emulator "
          f"{loop['error_emulator_rad']:+.4f} rad, difference {loop['difference_rad']:+.4f} rad "
          f"(tolerance {loop['tolerance_rad']} rad)")
    print(f"  simulation: {b['ms']} ms simulated, {b['late_ms']} ms more than 2 ms behind the "
          f"wall clock, {b['dropped_lag_ms']} ms of lag dropped (an overloaded machine)")
    return 0


if __name__ == '__main__':
    sys.exit(main())
