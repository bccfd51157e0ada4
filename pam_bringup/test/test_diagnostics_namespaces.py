"""/diagnostics with two complete stacks side by side on one domain.

Real processes: `pam-bringup` (sim_node, ukf_node, pi_node, reference_node) in /pam and again
with `--namespace /joint2`, plus one of each tool: bag_record in /pam (hardware_id given as a
parameter), bag_play (paused) and tracking_report in /joint2, profile_player alone in /player
(waiting for a rig). Every node's status is there, named by its fully qualified node name
('/joint2/sim_node: simulated rig'), one status name per node, and hardware_id is the node's
namespace (so it differs by stack) unless the parameter says otherwise.
"""

from __future__ import annotations

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus

from pam_common.diagnostics import status_node, status_values
from pam_common.testing import STARTUP_TIMEOUT

STACK = ('sim_node', 'ukf_node', 'pi_node', 'reference_node')
NAMESPACES = ('/pam', '/joint2')
TOOLS = {'/pam/bag_record', '/joint2/bag_play', '/joint2/tracking_report',
         '/player/profile_player'}
RECORDER_ID = 'lab-recorder'
LEVELS = {DiagnosticStatus.OK, DiagnosticStatus.WARN, DiagnosticStatus.ERROR,
          DiagnosticStatus.STALE}
#: s: twelve Python processes starting at once on a loaded 2-core machine, then DDS discovery
#: (up to one 3 s announcement period) and a 1 s diagnostics period
TIMEOUT = 2.0 * STARTUP_TIMEOUT


def write_paused_bag(path):
    """A small bag bag_play can open (std_msgs/String on /joint2/chatter); played paused, so
    nothing of it is published."""
    from pam_bag.bags import BagWriter, make_qos, make_typestore
    store = make_typestore()
    string = 'std_msgs/msg/String'
    writer = BagWriter(path, typestore=store)
    writer.add_topic('/joint2/chatter', string, [make_qos()])
    for k in range(10):
        writer.write('/joint2/chatter', 10**18 + k * 10**8,
                     store.serialize_cdr(store.types[string](data=f'message {k}'), string))
    writer.close()
    return path


def test_two_stacks_are_told_apart(node_process, probe, ros_domain, tmp_path):
    diagnostics = probe.subscribe(DiagnosticArray, '/diagnostics', depth=1000)
    domain = ('--domain-id', str(ros_domain))
    stacks = [node_process('pam-bringup', 'pam_bringup', *domain, '--namespace', ns, raw=True)
              for ns in NAMESPACES]
    tools = [
        node_process('bag_record', 'pam_bag', '-r', '__ns:=/pam', '-p',
                     f'output:={tmp_path / "recorded"}', '-p', 'topics:=/pam/reference', '-p',
                     f'hardware_id:={RECORDER_ID}'),
        node_process('bag_play', 'pam_bag', '-r', '__ns:=/joint2', '-p',
                     f'bag:={write_paused_bag(tmp_path / "played")}', '-p', 'start_paused:=true'),
        node_process('tracking_report', 'pam_bringup', '-r', '__ns:=/joint2', '-p',
                     'duration:=600.0'),
        node_process('profile_player', 'pam_controller', '-r', '__ns:=/player', '-p',
                     'startup_timeout:=3600.0'),
    ]
    expected = {f'{ns}/{node}' for ns in NAMESPACES for node in STACK} | TOOLS

    def latest() -> dict:
        """The last status of each status name."""
        return {s.name: s for array in diagnostics.messages() for s in array.status}

    def seen() -> set:
        return {status_node(name) for name in latest()}

    stacks[0].wait_for(lambda: expected <= seen(), TIMEOUT,
                       f'a status of every node ({sorted(expected)})')
    dead = [p.name for p in stacks + tools if not p.alive()]
    assert not dead, f'exited: {dead}'

    statuses = latest()
    assert seen() == expected, sorted(statuses)
    names = sorted(statuses)
    # one status name per node, and it starts with the node's fully qualified name
    assert len(names) == len(expected) == len({status_node(n) for n in names}), names
    for name, status in statuses.items():
        node = status_node(name)
        namespace = node.rsplit('/', 1)[0]
        assert name.startswith(f'{node}: ') and len(name) > len(node) + 2, name
        assert namespace in (*NAMESPACES, '/player'), name
        assert status.hardware_id == (RECORDER_ID if node == '/pam/bag_record' else namespace), (
            name, status.hardware_id)
        assert status.level in LEVELS and status.message, (name, status.message)
        assert status_values(status), name
    # the two stacks' rigs: the same title, told apart by name and hardware_id
    rigs = [statuses[f'{ns}/sim_node: simulated rig'] for ns in NAMESPACES]
    assert [r.hardware_id for r in rigs] == list(NAMESPACES)

    # the tools say what they do
    play = status_values(statuses['/joint2/bag_play: bag player'])
    assert play['paused'] == 'true' and play['messages in the bag'] == '10', play
    assert play['messages played'] == '0', play
    record = status_values(statuses['/pam/bag_record: bag recorder'])
    assert record['bag'] == str(tmp_path / 'recorded') and 'split files closed' in record, record
    player = statuses['/player/profile_player: profile player']
    assert player.level == DiagnosticStatus.WARN and 'waiting' in player.message, player.message
    assert status_values(player)['samples played'] == '0'
    assert 'recorded (s)' in status_values(statuses['/joint2/tracking_report: tracking report'])
