"""Executor choice, spinning and the stop on Ctrl-C/SIGTERM shared by the PAM nodes.

rclpy.experimental.EventsExecutor cuts the cost of a 1 kHz subscription to about half of the
default executor's. But with the Jazzy wheels (ros-rclpy 7.1.6 on PyPI) its blocking spin() with
no timeout busy-waits (a full core while idle) and never returns on Ctrl-C. Spinning it in bounded
slices (spin_until_future_complete with a timeout) blocks properly. Use spin(executor, stop)
below instead of executor.spin().

The slice's timeout only holds while the executor has idle moments: with callbacks always ready
(a stack that cannot keep up, e.g. two composed stacks on two cores) one slice lasted 3 to 7 s
(measured: a subscription at 3 kHz whose callback takes 1 ms). Completing the slice's future
stops it at the next callback boundary (measured: 1 to 4 ms under that load), so a stop request
completes it from a thread of its own (SliceWaker).

Stopping: run_node does not install rclpy's signal handlers. Those shut the ROS context down from
a thread of their own and raise KeyboardInterrupt wherever the main thread happens to be (often
inside a subscription callback run by the EventsExecutor's C++ loop); at that moment, rarely, a
node hung for good (pi_node, then ukf_node, in CI: deaf to SIGINT and SIGTERM, killed) or failed
with "Unable to convert call argument". StopSignals instead only records the request; the spin
loop sees it within SPIN_SLICE and returns, and the main thread stops the node (its stop hook,
e.g. driver_node's safe output, with ROS still up) and then shuts the context down itself,
outside any callback. A second signal raises KeyboardInterrupt (a node that does not stop is
interrupted where it is).

EventsExecutor timers do not follow /clock faithfully under use_sim_time: when /clock runs ahead
of the node they fire several times at one /clock time and off their period's grid (reference_node
fed /clock at 4x real time: repeated stamps in 4 of 8 runs; on the default executor in none of 6;
test_reference_profiles.py). Nodes on simulated time get rclpy's default executor, which costs
more per message (its wait set is rebuilt in Python: reference_node takes about 250 us of CPU
per /clock message).
"""

from __future__ import annotations

import faulthandler
import gc
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import rclpy
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.signals import SignalHandlerOptions
from rclpy.task import Future

from .stack_dump import enable_stack_dump

SPIN_SLICE = 0.25  # s, longest time the executor blocks before seeing a stop request
SHUTDOWN_GRACE = 4.5  # s a node has to exit after Ctrl-C/SIGTERM (pam-bringup escalates at 5 s)
SHUTDOWN_SETTLE = 1.0  # s an executor error may precede the context's shutdown on Ctrl-C


def make_executor(events: bool = True, context=None):
    """EventsExecutor if events and available, else SingleThreadedExecutor."""
    if events:
        try:
            from rclpy.experimental import EventsExecutor
            return EventsExecutor(context=context)
        except ImportError:
            pass
    return SingleThreadedExecutor(context=context)


def is_events_executor(executor) -> bool:
    return not isinstance(executor, Executor)


class StopSignals:
    """SIGINT and SIGTERM of a node process (main thread only). The first one is only recorded
    (`requested`): no rclpy call, no lock, no exception in the signal handler, which can run in
    the middle of any callback. A second one raises KeyboardInterrupt."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self):
        self.requested: int | None = None      # the first signal received

    def install(self) -> None:
        for sig in self.SIGNALS:
            signal.signal(sig, self._on_signal)

    def _on_signal(self, signum, frame) -> None:
        if self.requested is not None:
            raise KeyboardInterrupt
        self.requested = signum


class SliceWaker:
    """Ends the EventsExecutor's current slice soon after a stop is requested or `until`
    completes, from a thread of its own that looks every POLL s: it completes the slice's
    future, whose done callback stops the executor's loop after the callback it is running.
    (The signal handler itself takes no lock: completing the future there could deadlock on the
    future's lock, held by the main thread it interrupts.) A new future per slice: the wheels'
    EventsExecutor adds a done callback to the future at each spin_until_future_complete and
    never removes it, so one future for a whole run would collect four callbacks a second."""

    POLL = 0.05   # s

    def __init__(self, stop: StopSignals, until: Future):
        self._stop = stop
        self._until = until
        self._over = False
        self.slice = Future()
        self._thread = threading.Thread(target=self._run, name='slice_waker', daemon=True)
        self._thread.start()

    def next_slice(self) -> Future:
        self.slice = Future()
        return self.slice

    def _run(self) -> None:
        while not self._over:
            if self._stop.requested is not None or self._until.done():
                # again at each look until the spin ends: the main thread may have started
                # one more slice after the one completed
                current = self.slice
                if not current.done():
                    current.set_result(None)
            time.sleep(self.POLL)

    def close(self) -> None:
        self._over = True
        self._thread.join(timeout=1.0)


def spin(executor, stop: StopSignals, until: Future | None = None, context=None) -> None:
    """Execute callbacks in SPIN_SLICE slices until `until` completes or a stop is requested
    (returns; the caller shuts the context down), or the context went down (raises
    ExternalShutdownException: catch it in main())."""
    context = context if context is not None else executor.context
    until = until if until is not None else Future()       # never completes
    events = is_events_executor(executor)
    waker = SliceWaker(stop, until) if events else None
    try:
        _spin_slices(executor, stop, until, context, waker)
    finally:
        if waker is not None:
            waker.close()
    if not context.ok():
        raise ExternalShutdownException()


def _spin_slices(executor, stop: StopSignals, until: Future, context,
                 waker: SliceWaker | None) -> None:
    while context.ok() and stop.requested is None and not until.done():
        try:
            if waker is not None:
                executor.spin_until_future_complete(waker.next_slice(), timeout_sec=SPIN_SLICE)
            else:   # rclpy's Executor returns after one callback (or the timeout)
                executor.spin_once(timeout_sec=SPIN_SLICE)
        except ExternalShutdownException:
            break
        except RuntimeError:
            # The wheels' EventsExecutor can raise "Unable to convert call argument" when the
            # context shuts down under it, and when a second stop signal's KeyboardInterrupt
            # lands while it converts a callback's argument (seen: an overloaded composed stack
            # still running its callbacks 4 s after SIGINT, then SIGTERM): both are a stop, not
            # a failure.
            if stop.requested is not None:
                break
            if not shuts_down(context):
                raise


def shuts_down(context, within: float = SHUTDOWN_SETTLE) -> bool:
    """True if the context is shut down or goes down within `within` s. When the context is
    shut down under a spinning executor (by rclpy's signal handlers, which run_node no longer
    installs, or by a node's own rclpy.shutdown()), the executor can fail a moment before the
    context reads as shut down: an error then is part of the shutdown, not a failure."""
    end = time.monotonic() + within
    while context.ok():
        if time.monotonic() >= end:
            return False
        time.sleep(0.01)
    return True


@contextmanager
def interrupts_deferred():
    """SIGINT and SIGTERM ignored inside the block (main thread only): a node finishing its
    output, e.g. bag_record closing its bag, is not cut short by a second Ctrl-C."""
    try:
        previous = {s: signal.signal(s, signal.SIG_IGN) for s in (signal.SIGINT, signal.SIGTERM)}
    except ValueError:          # not the main thread: nothing to defer
        previous = {}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


class ShutdownWatchdog:
    """Once a node stops (Ctrl-C, SIGTERM: its spin ended, or the ROS context went down), the
    process must be gone within `grace` s; if not, faulthandler (a C thread, it needs no GIL)
    prints every thread's stack to stderr and exits with code 1. A node that hangs at shutdown
    (seen in CI: pi_node, then ukf_node, ignored SIGINT and SIGTERM and were killed; not
    reproduced here) then ends with a diagnosis instead of waiting for SIGKILL. arm() when the
    stop begins (the context may go down only at the end of it); disarm() before intended work
    after a stop (a finite node's finish(), e.g. bag_record closing its bag)."""

    def __init__(self, context, grace: float = SHUTDOWN_GRACE):
        self._lock = threading.Lock()
        self._armed = False
        self._disarmed = False
        self._grace = grace
        threading.Thread(target=self._watch, args=(context,), name='shutdown_watchdog',
                         daemon=True).start()

    def _watch(self, context) -> None:
        while context.ok():
            time.sleep(0.1)
        self.arm()

    def arm(self) -> None:
        """Start the countdown (once; not after disarm())."""
        with self._lock:
            if not (self._armed or self._disarmed):
                self._armed = True
                faulthandler.dump_traceback_later(self._grace, exit=True)

    def disarm(self) -> None:
        with self._lock:
            self._disarmed = True
            faulthandler.cancel_dump_traceback_later()


@dataclass(frozen=True)
class Component:
    """A node as a composable component, with one lifecycle for every node: its name (the node
    name), how to build it (`factory(**node_kwargs)`, e.g. namespace=..., cli_args=[...]: its
    parameters checked, its interfaces made, nothing running yet), and optionally how to start
    it (`start(node)`, e.g. a rig's sampling thread: once every node of the process is built and
    on the executor) and what to do when it stops with ROS still up (`stop(node)`, e.g.
    driver_node's safe output)."""

    name: str
    factory: Callable[..., Any]
    stop: Callable[[Any], None] | None = None
    start: Callable[[Any], None] | None = None


def run_node(node_factory, name: str, args=None, stop=None) -> int:
    """The main() of a PAM node: init, build the node, spin, shut down.

    Returns the exit code: 0 after Ctrl-C/SIGTERM, 2 when the node's configuration is invalid
    (ConfigError; or a bad params file or -p rule, found before rclpy.init by params_files),
    printed as one line. Ctrl-C/SIGTERM (StopSignals) ends the spin within SPIN_SLICE; one while
    the node is still starting stops it once started; a second one interrupts
    (KeyboardInterrupt) wherever the node is.
    The executor is an EventsExecutor unless the node runs on simulated time.
    A node with a `finished` Future runs until it completes (or Ctrl-C: ROS is then shut down
    first), and its `finish()` gives the exit code; further SIGINT/SIGTERM are ignored while it
    finishes. `stop(node)`, if given, runs with ROS still up (its threads may still publish),
    then the node is destroyed and ROS shut down. Any other node must be gone SHUTDOWN_GRACE s
    after its spin ends or the context goes down (ShutdownWatchdog). SIGUSR1 prints every
    thread's stack (stack_dump).
    """
    return run_nodes([Component(name, node_factory, stop)], name, args=args)


#: FastDDS's publication mode (rmw_fastrtps reads this variable when it creates a publisher)
PUBLICATION_MODE_VARIABLE = 'RMW_FASTRTPS_PUBLICATION_MODE'
PUBLICATION_MODE = 'ASYNCHRONOUS'


def prefer_asynchronous_publication() -> str:
    """FastDDS publishes asynchronously in our node processes unless the user chose otherwise
    (RMW_FASTRTPS_PUBLICATION_MODE set): the publishing thread only puts the sample in the
    writer's history and FastDDS's own sending thread delivers it, in C++, without the GIL.
    Synchronous publication (the Jazzy default) delivers to every reader of another process
    inside publish(): measured on the 2-core development machine, the composed stack's 1 kHz
    sampling thread spent a third of its time there once tracking_report subscribed (about
    270 us a sample), and 4.8 % of the rig's samples were late instead of 1.5 %. The cost: one
    more thread hop before a sample leaves the process (tens of us), and a reader slower than
    the writer's history (depth 100: 0.1 s at 1 kHz) loses samples instead of slowing the
    publisher, which a real-time loop must never do anyway. Returns the mode in force.
    Not for a finite tool (finite_tool): see there."""
    return os.environ.setdefault(PUBLICATION_MODE_VARIABLE, PUBLICATION_MODE)


def finite_tool(component: Component) -> bool:
    """A node that ends by itself and says how in finish() (bag_record, bag_play,
    profile_player, tracking_report; foxglove_view, whose finish() reports a server that could
    not start): its process keeps FastDDS's synchronous publication. Its
    last lines (the summary, also on /rosout) are published just before the process ends, and
    an asynchronous writer destroyed at exit had not sent them yet (seen in CI: bag_record's
    summary never reached a /rosout subscriber, its earlier lines did)."""
    return callable(getattr(component.factory, 'finish', None))


#: FastDDS's publication mode for a lockstep stack (sim_node timing:=lockstep and its loop)
LOCKSTEP_PUBLICATION_MODE = 'SYNCHRONOUS'


def lockstep_publication(env: dict) -> str:
    """Synchronous publication in `env` (a child environment) unless it names a mode: a
    lockstep loop is bound by latency, not by a sampling thread's deadline. Each step waits for
    its sample to go round the loop (sim_node -> ukf_node -> pi_node -> sim_node), and every hop
    through FastDDS's sending thread adds a wake-up: measured on the 2-core development machine,
    three nodes on loopback made 370 steps/s asynchronous and 794 steps/s synchronous.
    Returns the mode in force."""
    return env.setdefault(PUBLICATION_MODE_VARIABLE, LOCKSTEP_PUBLICATION_MODE)


#: s, the interpreter's thread switch interval in our node processes (Python's default: 5 ms)
SWITCH_INTERVAL = 0.0005


def shorten_switch_interval() -> float:
    """A thread waiting for the GIL gets it after SWITCH_INTERVAL s instead of Python's 5 ms: a
    sampling thread (sim_node's realtime sampler, driver_node's serial reader) competes for the
    GIL with the executor thread, and must not miss a 1 kHz deadline behind a callback. A
    process-wide knob, so set here once for every node process and container, whichever nodes
    it holds (the nodes themselves leave it alone). Returns the interval in force."""
    sys.setswitchinterval(SWITCH_INTERVAL)
    return sys.getswitchinterval()


def freeze_heap() -> None:
    """Move every object alive now (the imported modules, numba's compiled kernels, the nodes)
    out of the garbage collector's reach (gc.freeze), once the nodes are built: a full
    collection then walks only what the loop allocated since, not the whole heap. Without it,
    a full collection in a process holding rclpy, numpy and numba walked hundreds of thousands
    of objects in one go, a pause of tens of ms in the 1 kHz loop now and then. A process-wide
    knob, set here once for every node process and container."""
    gc.collect()
    gc.freeze()


def run_nodes(components: Sequence[Component], name: str, args=None,
              node_kwargs: Sequence[dict] | None = None,
              on_started: Callable[[list], None] | None = None) -> int:
    """Several nodes in one process on one executor (composition), each built by its
    component's factory with its `node_kwargs` entry (default: none), in order, and stopped and
    destroyed in reverse order; otherwise as run_node (which is this with one component). A
    ConfigError of any node is one line naming that node, exit code 2, and the nodes already
    built are destroyed. Only a single node may be a finite one (a `finished` Future). Once
    every node is built and on the executor, each component's `start` runs, in order, then
    `on_started(nodes)`. The process-wide
    knobs are set here, for whichever nodes the process holds: FastDDS's publication mode
    (prefer_asynchronous_publication, unless a node is a finite_tool), the thread switch
    interval (shorten_switch_interval), the frozen heap (freeze_heap, once every node is built
    and before any starts)."""
    from .node_params import ConfigError
    from .params_files import report_ros_args_problem
    code = report_ros_args_problem(sys.argv if args is None else args, name)
    if code is not None:            # a bad params file or -p rule: one line, before rclpy.init
        return code
    kwargs = list(node_kwargs) if node_kwargs is not None else [{} for _ in components]
    if not any(finite_tool(component) for component in components):
        prefer_asynchronous_publication()
    shorten_switch_interval()
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    stop_signals = StopSignals()
    stop_signals.install()
    enable_stack_dump()
    context = rclpy.get_default_context()
    watchdog = ShutdownWatchdog(context)
    built: list[tuple[Component, Any]] = []
    finished = None
    try:
        try:
            for component, node_kw in zip(components, kwargs, strict=True):
                try:
                    built.append((component, component.factory(**node_kw)))
                except ConfigError as exc:
                    if len(components) == 1:
                        raise
                    ns = node_kw.get('namespace')
                    label = f"{ns.rstrip('/')}/{component.name}" if ns else component.name
                    raise ConfigError(f'{label}: {exc}') from exc
            nodes = [node for _, node in built]
            if len(nodes) == 1:
                finished = getattr(nodes[0], 'finished', None)
            sim_time = any(node.get_parameter('use_sim_time').value for node in nodes)
            executor = make_executor(events=not sim_time)
            for node in nodes:
                executor.add_node(node)
            # before any node starts: the full collection takes tens of ms, which a started
            # sampling thread (sim_node's) would spend stalled behind the GIL
            freeze_heap()
            for component, node in built:
                if component.start is not None:
                    component.start(node)
            if on_started is not None:
                on_started(nodes)
            spin(executor, stop_signals, until=finished)
        except ConfigError as exc:
            print(f'[{name}] error: {exc}', file=sys.stderr)
            return 2
        except (KeyboardInterrupt, ExternalShutdownException):
            pass
        except Exception:
            if not shuts_down(context):
                raise
        if finished is not None:   # also after an early Ctrl-C
            if stop_signals.requested is not None:
                context.try_shutdown()     # stopped by Ctrl-C: it finishes with ROS down
            watchdog.disarm()
            with interrupts_deferred():
                return built[0][1].finish()
        return 0
    finally:
        watchdog.arm()      # a no-op after disarm(): a finite node's finish() is done by now
        for component, node in reversed(built):
            if component.stop is not None:
                component.stop(node)
            node.destroy_node()
        rclpy.try_shutdown()
