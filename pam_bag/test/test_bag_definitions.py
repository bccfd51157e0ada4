"""A bag recorded with an older definition of a type (Pressures before its sample counter) is
refused with one line naming the topic, the type and both RIHS01 hashes, exit code 2, before
anything is played or read: a subscriber of today's type could not read a message of it (bag_play
used to send the 22210 messages of such a bag to nobody and report success). Topics whose type did
not change still play. A bag without hashes is checked by its embedded definitions;
pam-bag-recover keeps the recorded definitions."""

import shutil

import pytest

from pam_bag import bags
from pam_bag.testing import PRESSURES_BEFORE_SAMPLE_RIHS01, write_bag_before_sample
from pam_common.testing import wait_until

SAMPLES = 100
PRESSURES = 'pam_interfaces/msg/Pressures'


@pytest.fixture(scope='module')
def old_bag(tmp_path_factory):
    return write_bag_before_sample(tmp_path_factory.mktemp('old') / 'old', SAMPLES)


def refusal(mcap) -> str:
    installed = bags.make_typestore().hash_rihs01(PRESSURES)
    return (f'{mcap}: topic /pam/pressures was recorded with a different definition of '
            f'{PRESSURES} (bag {PRESSURES_BEFORE_SAMPLE_RIHS01}, installed {installed}): '
            're-record or convert the bag')


def hashes(bag) -> dict:
    return {topic: rihs01 for _, topic, _, rihs01 in bags.recorded_types(bags.bag_files(bag))}


def test_the_bag_is_as_the_old_recordings(old_bag):
    """The hash of its Pressures channel is the one the bags recorded before had."""
    assert hashes(old_bag)['/pam/pressures'] == PRESSURES_BEFORE_SAMPLE_RIHS01
    assert PRESSURES_BEFORE_SAMPLE_RIHS01 != bags.make_typestore().hash_rihs01(PRESSURES)


def test_bag_play_refuses_it_and_publishes_nothing(node_process, probe, old_bag):
    from pam_interfaces.msg import JointMeasurement, ValveCommand
    from test_bags_nodes import resumed_player  # the same test folder (prepend import mode)
    remap = 'remap:=' + ','.join(f'/pam/{t}:=/old_bag/{t}'     # topics of this test only
                                 for t in ('pressures', 'joint_measured', 'valve_command'))
    measured = probe.subscribe(JointMeasurement, '/old_bag/joint_measured')
    commands = probe.subscribe(ValveCommand, '/old_bag/valve_command')
    player = node_process('bag_play', 'pam_bag', '-p', f'bag:={old_bag}', '-p', remap)
    assert player.wait_exit(60.0) == 2, player.stdout + player.stderr
    assert player.stderr.splitlines() == [f'[bag_play] error: {refusal(old_bag / "old.mcap")}']
    assert 'published' not in player.stdout
    # the topics of unchanged types play, and the probe receives them
    player = resumed_player(node_process, probe, '/old_bag/joint_measured', '-p', remap,
                            '-p', f'bag:={old_bag}',
                            '-p', 'topics:=/pam/joint_measured,/pam/valve_command')
    assert player.wait_exit(60.0) == 0, player.stderr
    assert wait_until(lambda: len(measured) == len(commands) == SAMPLES, 10.0), \
        (len(measured), len(commands))


def test_load_bag_refuses_it_unless_the_topic_is_left_out(old_bag):
    with pytest.raises(bags.BagError) as refused:
        bags.load_bag(old_bag)
    assert str(refused.value) == refusal(old_bag / 'old.mcap')
    assert len(bags.load_bag(old_bag, ['/pam/joint_measured']).data) == SAMPLES


def rewritten(bag, out, schema_data, channel_metadata):
    """A copy of `bag` whose schemas' data and channels' metadata are what
    schema_data(schema) and channel_metadata(channel) give; metadata.yaml without hashes."""
    from mcap.reader import make_reader
    from mcap.writer import CompressionType, Writer
    from ruamel.yaml import YAML
    shutil.copytree(bag, out)
    mcap = out / f'{bag.name}.mcap'
    with (bag / mcap.name).open('rb') as f, mcap.open('wb') as g:
        reader = make_reader(f)
        summary = reader.get_summary()
        writer = Writer(g, compression=CompressionType.ZSTD)
        writer.start(profile='ros2', library='test')
        schemas = {i: writer.register_schema(s.name, s.encoding, schema_data(s))
                   for i, s in summary.schemas.items()}
        channels = {i: writer.register_channel(c.topic, c.message_encoding, schemas[c.schema_id],
                                               channel_metadata(c))
                    for i, c in summary.channels.items()}
        for _, channel, message in reader.iter_messages(log_time_order=False):
            writer.add_message(channels[channel.id], message.log_time, message.data,
                               message.publish_time, message.sequence)
        writer.finish()
    yaml = YAML(typ='safe')
    meta = yaml.load((out / 'metadata.yaml').read_text())
    for entry in meta['rosbag2_bagfile_information']['topics_with_message_count']:
        entry['topic_metadata']['type_description_hash'] = ''
    with (out / 'metadata.yaml').open('w') as f:
        yaml.dump(meta, f)
    return out


def without_hash(channel) -> dict:
    return {k: v for k, v in channel.metadata.items() if k != 'topic_type_hash'}


def test_a_bag_without_hashes_is_checked_by_its_definitions(old_bag, tmp_path):
    """As a rosbag2 older than Jazzy records: the hash of the embedded definition is the old
    one; with no definition either (an empty schema), the topics are reported unchecked."""
    bag = rewritten(old_bag, tmp_path / 'nohash', lambda s: s.data, without_hash)
    assert hashes(bag)['/pam/pressures'] == PRESSURES_BEFORE_SAMPLE_RIHS01
    with pytest.raises(bags.BagError) as refused:
        bags.open_bag(bag)
    assert str(refused.value) == refusal(bag / 'old.mcap')
    bare = rewritten(old_bag, tmp_path / 'bare', lambda s: b'', without_hash)
    assert bags.open_bag(bare).unchecked == ['/pam/joint_measured', '/pam/pressures',
                                             '/pam/valve_command']


def test_recover_keeps_the_recorded_definition(old_bag, tmp_path):
    """pam-bag-recover on a crashed recording of the old type: the rebuilt channel keeps the
    recorded hash and definition (it took today's: a bag that lied about its messages)."""
    crashed = tmp_path / 'old'
    crashed.mkdir()
    data = (old_bag / 'old.mcap').read_bytes()
    (crashed / 'old.mcap').write_bytes(data[:-10])      # the summary cut: no footer
    bags.recover_bag(crashed)
    assert hashes(crashed) == hashes(old_bag)
    with pytest.raises(bags.BagError) as refused:
        bags.load_bag(crashed)
    assert str(refused.value) == refusal(crashed / 'old.mcap')
