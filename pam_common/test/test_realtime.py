"""pam_common.realtime and the ROS-free part of pam_common.realtime_knobs, on real syscalls.

Every knob is tried in a child Python process (the test runner itself is never made real-time
nor locked in RAM), and read back there with sched_getscheduler/sched_getparam,
sched_getaffinity and /proc/self/status (VmLck). This machine runs the tests as root with
SCHED_FIFO permitted; the refused paths run the child without the capabilities: setpriv drops
CAP_SYS_NICE and CAP_IPC_LOCK from its bounding set (so root's exec does not regain them) and the
child's RLIMIT_RTPRIO and RLIMIT_MEMLOCK are set low, as for a user with no limits.conf entry.
"""

from __future__ import annotations

import json
import os
import resource
import shutil
import subprocess
import sys
import textwrap

import pytest

from pam_common.node_params import ConfigError
from pam_common.realtime import cpu_list_text
from pam_common.realtime_knobs import REALTIME_PARAMS, RealtimeRequest, check_realtime

# what every child prints: the calling thread's view after the snippet ran
READ_BACK = '''
def state(tid=0):
    return {'policy': os.sched_getscheduler(tid),
            'priority': os.sched_getparam(tid).sched_priority,
            'cpus': sorted(os.sched_getaffinity(tid))}
'''
DROPPED = ['--inh-caps=-sys_nice,-ipc_lock', '--bounding-set=-sys_nice,-ipc_lock']


def can_grant() -> bool:
    return os.geteuid() == 0


needs_root = pytest.mark.skipif(not can_grant(), reason='the granted paths need root here')
needs_setpriv = pytest.mark.skipif(shutil.which('setpriv') is None or not can_grant(),
                                   reason='setpriv (util-linux) as root drops the capabilities')


def run_child(snippet: str, drop_caps: bool = False, rtprio: int | None = None,
              memlock: int | None = None) -> dict:
    """Run `snippet` (it sets `out`, a dict) in a fresh Python; its `out` as a dict."""
    code = ('import json, os, threading\nfrom pam_common import realtime\n' + READ_BACK
            + textwrap.dedent(snippet) + '\nprint(json.dumps(out))\n')

    def limits():
        if rtprio is not None:
            resource.setrlimit(resource.RLIMIT_RTPRIO, (rtprio, rtprio))
        if memlock is not None:
            resource.setrlimit(resource.RLIMIT_MEMLOCK, (memlock, memlock))
    argv = [sys.executable, '-c', code]
    if drop_caps:
        argv = ['setpriv', *DROPPED, '--', *argv]
    done = subprocess.run(argv, capture_output=True, text=True, timeout=60,
                          preexec_fn=limits)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


@needs_root
def test_sched_fifo_is_granted_to_the_calling_thread_only():
    out = run_child('''
        before = state()
        result = {}
        def worker():
            result['grant'] = realtime.set_sched_fifo(42, 'worker')
            result['tid'] = realtime.thread_id()
            result['state'] = state()
            child = threading.Thread(target=lambda: result.update(child=state()))
            child.start(); child.join()     # a thread it starts inherits the policy
        t = threading.Thread(target=worker); t.start(); t.join()
        out = {'before': before, 'main': state(), **result}
    ''')
    granted, message = out['grant']
    assert granted, message
    assert message == f"SCHED_FIFO priority 42 granted to thread worker (tid {out['tid']})"
    assert out['state'] == {**out['before'], 'policy': os.SCHED_FIFO, 'priority': 42}
    assert out['child']['policy'] == os.SCHED_FIFO and out['child']['priority'] == 42
    assert out['main'] == out['before']                  # the process's main thread untouched
    assert out['before']['policy'] == os.SCHED_OTHER


@needs_root
def test_affinity_is_granted_to_the_calling_thread_only():
    out = run_child('''
        before = state()
        result = {}
        def worker():
            result['grant'] = realtime.set_cpu_affinity([0], 'worker')
            result['state'] = state()
            result['text'] = realtime.cpus_text()
        t = threading.Thread(target=worker); t.start(); t.join()
        out = {'before': before, 'main': state(), **result}
    ''')
    granted, message = out['grant']
    assert granted, message
    assert message.startswith('CPU affinity 0 granted to thread worker (tid ')
    assert out['state']['cpus'] == [0] and out['text'] == '0'
    assert out['main'] == out['before']


@needs_root
def test_memory_lock_is_granted_and_read_back():
    out = run_child('''
        before = realtime.locked_memory_kb()
        grant = realtime.lock_memory()
        out = {'before': before, 'after': realtime.locked_memory_kb(), 'grant': grant}
    ''')
    granted, message = out['grant']
    assert granted, message
    assert out['before'] == 0 and out['after'] > 1024          # kB: the interpreter at least
    assert message.startswith('memory locked (mlockall MCL_CURRENT|MCL_FUTURE): ')


@needs_setpriv
def test_sched_fifo_refused_without_cap_sys_nice_says_what_to_set():
    out = run_child('''
        grant = realtime.set_sched_fifo(80, 'sampler')
        out = {'grant': grant, 'state': state(), 'cap': realtime.has_capability(
            realtime.CAP_SYS_NICE)}
    ''', drop_caps=True, rtprio=0)
    granted, message = out['grant']
    assert not out['cap']
    assert not granted
    assert out['state']['policy'] == os.SCHED_OTHER         # the thread runs on, unchanged
    assert 'SCHED_FIFO priority 80 refused for thread sampler (tid ' in message
    assert 'EPERM: no CAP_SYS_NICE and RLIMIT_RTPRIO 0 < 80' in message
    for fallback in ('SCHED_OTHER', 'ulimit -r', '/etc/security/limits.conf', 'rtprio 98',
                     'LimitRTPRIO', '--cap-add SYS_NICE', '--ulimit rtprio=99'):
        assert fallback in message, fallback
    assert '\n' not in message


@needs_setpriv
@pytest.mark.skipif(resource.getrlimit(resource.RLIMIT_RTPRIO)[1] < 60,
                    reason='the hard RLIMIT_RTPRIO is below 60 and cannot be raised here (no '
                           'CAP_SYS_RESOURCE in this container)')
def test_an_rtprio_limit_permits_up_to_it_without_the_capability():
    """The `ulimit -r` / limits.conf fallback the warning names, for real: no CAP_SYS_NICE,
    RLIMIT_RTPRIO 60: priority 60 is granted, 61 refused."""
    out = run_child('''
        low = realtime.set_sched_fifo(60, 'a')
        high = realtime.set_sched_fifo(61, 'a')
        out = {'low': low, 'high': high, 'state': state()}
    ''', drop_caps=True, rtprio=60)
    assert out['low'][0], out['low'][1]
    assert not out['high'][0] and 'RLIMIT_RTPRIO 60 < 61' in out['high'][1]
    assert out['state']['policy'] == os.SCHED_FIFO and out['state']['priority'] == 60


@needs_setpriv
def test_memory_lock_refused_without_cap_ipc_lock_says_what_to_set():
    out = run_child('''
        grant = realtime.lock_memory()
        out = {'grant': grant, 'locked': realtime.locked_memory_kb()}
    ''', drop_caps=True, memlock=64 * 1024)
    granted, message = out['grant']
    assert not granted and out['locked'] == 0
    assert message.startswith('memory lock refused: ')
    assert 'no CAP_IPC_LOCK and RLIMIT_MEMLOCK 64 KiB' in message
    for fallback in ('ulimit -l unlimited', 'memlock unlimited', 'LimitMEMLOCK=infinity',
                     '--ulimit memlock=-1'):
        assert fallback in message, fallback


def test_affinity_to_a_cpu_this_machine_lacks_is_refused_and_the_thread_runs_on():
    n = os.cpu_count()
    out = run_child(f'''
        before = state()
        none = realtime.set_cpu_affinity([{n}], 'worker')
        some = realtime.set_cpu_affinity([0, {n}], 'worker')
        out = {{'before': before, 'none': none, 'some': some, 'after': state()}}
    ''')
    granted, message = out['none']
    assert not granted
    assert f'CPU affinity {n} refused for thread worker' in message and 'EINVAL' in message
    granted, message = out['some']       # the kernel keeps the CPUs it has: a partial grant
    assert not granted and 'only partly granted' in message
    assert out['after']['cpus'] == [0]


def test_a_priority_outside_1_99_is_refused_without_a_syscall():
    out = run_child('''
        out = {'grant': realtime.set_sched_fifo(100, 'x'), 'state': state()}
    ''')
    assert not out['grant'][0] and 'a priority is 1..99' in out['grant'][1]
    assert out['state']['policy'] == os.SCHED_OTHER


def test_cpu_list_text():
    assert cpu_list_text([5, 0, 1, 2]) == '0-2,5'
    assert cpu_list_text([3]) == '3'
    assert cpu_list_text([]) == 'none'


def test_the_parameter_rows_and_their_checks():
    rows = {spec.name: spec for spec in REALTIME_PARAMS}
    assert rows['thread_priority'].default == 0 and rows['thread_priority'].range == (0, 99)
    assert rows['cpu_affinity'].default == [] and rows['cpu_affinity'].type_name == 'integer[]'
    assert rows['lock_memory'].default is False
    assert all(spec.read_only for spec in REALTIME_PARAMS)
    values = check_realtime({'thread_priority': 80, 'cpu_affinity': [1, 0, 1],
                             'lock_memory': True})
    assert RealtimeRequest.from_values(values) == RealtimeRequest(80, (0, 1), True)
    assert check_realtime({'cpu_affinity': None})['cpu_affinity'] == []    # -p cpu_affinity:=[]
    assert not RealtimeRequest().asked
    with pytest.raises(ConfigError, match=r"parameter 'cpu_affinity': CPU -1 is out of range"):
        check_realtime({'cpu_affinity': [-1]})
    with pytest.raises(ConfigError, match=r"parameter 'cpu_affinity': expected a list"):
        check_realtime({'cpu_affinity': [0.5]})
