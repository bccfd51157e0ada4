"""pam_bag.read_ahead: order, bounded memory, errors in place, close."""

import threading
import time

import pytest

from pam_bag.read_ahead import END, ReadAhead


class Source:
    """An endless or finite source that counts what has been taken from it."""

    def __init__(self, n=None, fail_at=None):
        self.n, self.fail_at, self.taken = n, fail_at, 0

    def __iter__(self):
        while self.n is None or self.taken < self.n:
            if self.taken == self.fail_at:
                raise ValueError(f'damaged at {self.taken}')
            self.taken += 1
            yield self.taken - 1


def settled(source, quiet=0.3, timeout=5.0) -> int:
    """source.taken once it has stopped growing for `quiet` s."""
    end = time.monotonic() + timeout
    last = -1
    while time.monotonic() < end:
        if source.taken == last:
            return last
        last = source.taken
        time.sleep(quiet)
    raise AssertionError('the reader never stopped reading')


def take(ahead, n):
    return [ahead.get(timeout=5.0) for _ in range(n)]


def test_every_item_in_order_then_end():
    ahead = ReadAhead(Source(n=1234), capacity=300, batch=50)
    assert take(ahead, 1234) == list(range(1234))
    assert ahead.get(timeout=5.0) is END and ahead.get(timeout=5.0) is END
    ahead.close()


def test_reads_ahead_up_to_the_capacity_and_no_further():
    """An endless source: the reader fills the queue (capacity items) plus at most the batch
    in its hands, and refills as the consumer takes."""
    source = Source()
    ahead = ReadAhead(source, capacity=1000, batch=100)
    assert 1000 <= settled(source) <= 1100
    assert take(ahead, 500) == list(range(500))
    assert 1500 <= settled(source) <= 1600
    assert 900 <= ahead.buffered() <= 1100
    ahead.close()


def test_the_source_error_comes_after_the_items_before_it():
    ahead = ReadAhead(Source(n=500, fail_at=250), capacity=100, batch=30)
    assert take(ahead, 250) == list(range(250))
    with pytest.raises(ValueError, match='damaged at 250'):
        ahead.get(timeout=5.0)
    with pytest.raises(ValueError):   # and stays failed
        ahead.get(timeout=5.0)
    ahead.close()


def test_close_stops_a_reader_blocked_on_a_full_queue():
    ahead = ReadAhead(Source(), capacity=100, batch=10, name='probe_reader')
    time.sleep(0.3)
    ahead.close()
    assert not any(t.name == 'probe_reader' for t in threading.enumerate())


def test_bad_sizes_are_refused():
    with pytest.raises(ValueError, match='capacity and batch'):
        ReadAhead(Source(n=1), capacity=0)
