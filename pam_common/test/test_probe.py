"""pam_common.testing.Probe, the test process's node: its entities are made by its spin thread
(the EventsExecutor is not safe against entities added from another thread while it spins:
about one subscription in 25 made from the test thread never received a message)."""

import threading

from std_msgs.msg import Float64


def test_entities_are_made_by_the_spin_thread(probe):
    seen = []
    made = probe._in_spin_thread(lambda: seen.append(threading.current_thread()) or 'made')
    assert made == 'made'
    assert seen == [probe._thread]


def test_subscriptions_made_while_a_publisher_runs_all_receive(probe):
    publisher = probe.publisher(Float64, '/probe_test/x')
    timer = probe._in_spin_thread(
        lambda: probe.node.create_timer(0.002, lambda: publisher.publish(Float64(data=1.0))))
    import time
    collectors = []
    for _ in range(10):
        collectors.append(probe.subscribe(Float64, '/probe_test/x'))
        time.sleep(0.1)
    end = time.monotonic() + 10.0
    while time.monotonic() < end and not all(len(c.messages()) > 0 for c in collectors):
        time.sleep(0.05)
    probe._in_spin_thread(lambda: probe.node.destroy_timer(timer))
    assert [len(c.messages()) > 0 for c in collectors] == [True] * 10
