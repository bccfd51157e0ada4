"""Arming driver_node once the controller runs (pam-bringup --rig driver with pi_node).

driver_node latches its safe output when the controller's start-up stalls longer than its
command watchdog (or when it starts with arm_at_start false). Once pi_node's valve_command has
flowed steadily for ARM_STEADY s, DriverArmer calls <namespace>/driver_node/arm (std_srvs/Trigger)
from an rclpy node of its own (in a thread), retrying a refusal (board not connected yet, sensor
fault) every ARM_RETRY s for up to ARM_TIMEOUT s. It arms once, at start-up only: a later
watchdog trip or e-stop stays latched until someone calls ~/arm.
"""

from __future__ import annotations

import math
import threading
import time

from pam_common.topics import VALVE_COMMAND

from .stack import RIGS
from .supervisor import READER_JOIN, Output

ARM_STEADY = 1.0         # s of valve_command without a gap > ARM_GAP before ~/arm
ARM_GAP = 0.2            # s
ARM_RETRY = 1.0          # s between ~/arm calls the driver refused
ARM_TIMEOUT = 60.0       # s after start: give up arming (say so)
ARM_SERVICE = f"{RIGS['driver'].name}/arm"   # relative to the namespace


class DriverArmer:
    """Calls <namespace>/driver_node/arm once the controller runs (see the module docstring), in
    a thread with an rclpy context of its own (no signal handlers: pam-bringup keeps its own)."""

    def __init__(self, namespace: str, domain_id: int | None, output: Output):
        self.namespace = namespace
        self.domain_id = domain_id
        self.out = output
        self.armed = False
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name='driver-armer', daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(READER_JOIN)

    def _run(self) -> None:
        try:
            import rclpy
            from rclpy.context import Context
            from rclpy.executors import SingleThreadedExecutor
            from rclpy.signals import SignalHandlerOptions
            context = Context()
            rclpy.init(context=context, domain_id=self.domain_id,
                       signal_handler_options=SignalHandlerOptions.NO)
        except Exception as exc:  # noqa: BLE001 - pam-bringup runs on without it
            self.out.say(f'cannot arm driver_node (rclpy: {exc}): call ~/arm yourself')
            return
        try:
            node = rclpy.create_node('_pam_bringup_armer', namespace=self.namespace,
                                     context=context)
            executor = SingleThreadedExecutor(context=context)
            executor.add_node(node)
            self._arm(node, executor)
        except Exception as exc:  # noqa: BLE001
            if not self._stop.is_set():
                self.out.say(f'arming driver_node failed ({type(exc).__name__}: {exc}): call '
                             '~/arm yourself')
        finally:
            context.try_shutdown()

    def _arm(self, node, executor) -> None:
        from std_srvs.srv import Trigger

        from pam_common.qos import LATEST_QOS
        from pam_interfaces.msg import ValveCommand
        steady = {'since': None, 'last': -math.inf}

        def on_command(_msg) -> None:
            now = time.monotonic()
            if now - steady['last'] > ARM_GAP:
                steady['since'] = now
            steady['last'] = now

        node.create_subscription(ValveCommand, VALVE_COMMAND, on_command, LATEST_QOS)
        client = node.create_client(Trigger, ARM_SERVICE)
        service = f'{node.get_namespace().rstrip("/")}/{ARM_SERVICE}'
        deadline = time.monotonic() + ARM_TIMEOUT
        future, next_call, refused = None, 0.0, ''
        while not self._stop.is_set():
            executor.spin_once(timeout_sec=0.05)
            now = time.monotonic()
            if future is not None and future.done():
                response = future.result()
                future = None
                if response is not None and response.success:
                    self.armed = True
                    self.out.say(f'the controller runs: {service}: {response.message}')
                    return
                message = response.message if response is not None else 'no response'
                if message != refused:
                    self.out.say(f'{service} refused: {message}; retrying every '
                                 f'{ARM_RETRY:g} s for up to {ARM_TIMEOUT:g} s')
                refused = message
                next_call = now + ARM_RETRY
            if now >= deadline:
                self.out.say(f'driver_node not armed {ARM_TIMEOUT:g} s after the start'
                             f'{f" ({refused})" if refused else ""}: call {service} yourself')
                return
            running = (steady['since'] is not None and now - steady['last'] <= ARM_GAP
                       and now - steady['since'] >= ARM_STEADY)
            if future is None and running and now >= next_call and client.service_is_ready():
                future = client.call_async(Trigger.Request())
