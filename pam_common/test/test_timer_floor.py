"""pam_common.timer_floor: a bare sleep loop's lateness, counted as the rig counts it."""

import threading
import time

import pytest

from pam_common.timer_floor import measure_timer_floor


def test_a_quiet_loop_and_its_line():
    floor = measure_timer_floor(rate=1000.0, duration=0.3)
    assert floor.deadlines == 300 and 0 <= floor.late <= floor.deadlines
    assert 0.0 <= floor.p99 <= floor.worst
    assert floor.scheduling == 'SCHED_OTHER'
    assert floor.line().startswith('a bare 1000 Hz sleep loop (SCHED_OTHER, 300 deadlines): ')
    assert floor.as_dict()['late_fraction'] == pytest.approx(floor.late / 300)


def test_a_stall_counts_every_period_it_covers():
    """A thread that holds the GIL in one C call (sum over a long range) stalls the loop: the
    worst lateness is the stall and every deadline it covered is late."""
    def stall():
        time.sleep(0.1)
        t0 = time.monotonic()
        sum(range(8_000_000))           # one C call: the GIL is not handed over meanwhile
        held.append(time.monotonic() - t0)

    held: list = []
    thread = threading.Thread(target=stall)
    thread.start()
    floor = measure_timer_floor(rate=1000.0, duration=1.0)
    thread.join()
    assert held[0] > 0.03, f'the stall was only {held[0] * 1e3:.1f} ms: no test'
    assert floor.worst >= 0.8 * held[0], (floor, held)
    assert floor.late >= 0.8 * held[0] * 1000.0 - 2, (floor, held)


def test_bad_arguments_are_refused():
    with pytest.raises(ValueError, match='rate and duration'):
        measure_timer_floor(rate=0.0)
