"""A bounded read-ahead buffer: a background thread reads an iterable into a queue that holds at
most `capacity` items, so a consumer with deadlines (bag_play) never waits for the reading and
memory stays bounded however long the source (rosbag2's read-ahead queue). No ROS here.

Items go over in batches (one queue operation per `batch` items, not one per item). An
exception raised by the source reaches the consumer at its place in the sequence, after the
items read before it.
"""

from __future__ import annotations

import queue
import threading

END = object()   # get()'s answer once the source is exhausted


class ReadAhead:
    def __init__(self, items, capacity: int = 10000, batch: int = 100,
                 name: str = 'read_ahead'):
        if capacity < 1 or batch < 1:
            raise ValueError(f'capacity and batch must be >= 1, got {capacity}, {batch}')
        self.batch = min(batch, capacity)
        self._queue: queue.Queue = queue.Queue(maxsize=max(1, capacity // self.batch))
        self._current: list = []
        self._pos = 0
        self._quit = threading.Event()
        self._thread = threading.Thread(target=self._read, args=(items,), name=name, daemon=True)
        self._thread.start()

    def _put(self, entry) -> bool:
        """Queue one entry, waiting for room; False once closed."""
        while not self._quit.is_set():
            try:
                self._queue.put(entry, timeout=0.1)
                return True
            except queue.Full:
                continue
        return False

    def _read(self, items) -> None:
        chunk = []
        try:
            for item in items:
                chunk.append(item)
                if len(chunk) >= self.batch:
                    if not self._put(chunk):
                        return
                    chunk = []
        except BaseException as exc:  # noqa: BLE001 - handed to the consumer
            if chunk and not self._put(chunk):
                return
            self._put(exc)
            return
        if chunk and not self._put(chunk):
            return
        self._put(END)

    def get(self, timeout: float | None = None):
        """The next item, or END when the source is exhausted; raises the source's exception
        at its place, and queue.Empty if nothing comes within `timeout` s (None: wait)."""
        if self._pos >= len(self._current):
            entry = self._queue.get(timeout=timeout)
            if entry is END:
                self._queue.put(END)   # stays exhausted
                return END
            if isinstance(entry, BaseException):
                self._queue.put(entry)
                raise entry
            self._current, self._pos = entry, 0
        item = self._current[self._pos]
        self._pos += 1
        return item

    def buffered(self) -> int:
        """Items read but not yet taken (approximate: batches x batch size)."""
        return self._queue.qsize() * self.batch + len(self._current) - self._pos

    def close(self) -> None:
        """Stop reading (the thread ends within ~0.1 s)."""
        self._quit.set()
        try:
            while True:
                self._queue.get_nowait()
        except queue.Empty:
            pass
        self._thread.join(timeout=1.0)
