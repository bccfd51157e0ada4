"""Console-script entry points that stop quietly when SIGINT or SIGTERM arrives during start-up.

Importing a node or tool module (rclpy, numpy, numba, the compiled kernels) takes a second or
more. A Ctrl-C in that time, or pam-bringup stopping a node that is still importing, printed a
50-line KeyboardInterrupt traceback from inside some import. So every console script of the
project points at a function made by entry('package.module:main', ...), in the small
`entry_points` module of its package, which imports nothing heavy:

- before the module is imported, SIGINT and SIGTERM get a handler that ends the process at once,
  silently, with exit code 128 + the signal number: 130 (SIGINT) or 143 (SIGTERM), what a shell
  reports for a process ended by that signal, and the code run_cli gives a tool stopped by
  Ctrl-C. pam-bringup counts both as a clean stop (its CLEAN_STOP_CODES). A signal the process
  was started with ignored (SIG_IGN, e.g. `cmd &` in a script) stays ignored.
- a node (own_handlers=True: run_node's StopSignals, pam-bringup, ...) keeps that handler until
  it installs its own: a signal before then still ends it quietly; after, the node stops
  cleanly (exit code 0) as run_node documents.
- a tool (own_handlers=False) gets Python's default handlers back once its module is imported:
  Ctrl-C raises KeyboardInterrupt where the tool expects it (run_cli: exit code 130).
"""

from __future__ import annotations

import importlib
import os
import signal
import sys
from collections.abc import Callable

STARTUP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


def exit_code_for(signum: int) -> int:
    """The exit code of a process stopped by `signum` during start-up (128 + signum)."""
    return 128 + signum


def _exit_quietly(signum, frame) -> None:
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except Exception:  # noqa: BLE001 - exiting anyway
            pass
    os._exit(exit_code_for(signum))    # no traceback, no clean-up of half-imported modules


def launch(target: str, own_handlers: bool) -> int:
    """Import `module:function` with the quiet start-up handlers installed, then call it."""
    previous = {}
    for sig in STARTUP_SIGNALS:
        if signal.getsignal(sig) is not signal.SIG_IGN:
            previous[sig] = signal.signal(sig, _exit_quietly)
    module, _, function = target.partition(':')
    main = getattr(importlib.import_module(module), function)
    if not own_handlers:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    return main()


def entry(target: str, own_handlers: bool = False) -> Callable[[], int]:
    """A console-script function that runs `module:function` (see the module docstring)."""
    def run() -> int:
        return launch(target, own_handlers)
    run.__doc__ = f'{target}, quiet on SIGINT/SIGTERM during start-up.'
    return run
