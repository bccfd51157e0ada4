"""pam-evaluate and pam-identify on a bag recorded before Pressures had its sample counter: one
error line naming the topic, the type and both RIHS01 hashes, exit code 2 (docs/stopping.md, Exit
codes), nothing written (they stopped with rosbags' "Could not deserialize" traceback, exit 1). A
bag whose channel claims today's definition over messages of the old one: one line naming the
first message that cannot be read, exit 2."""

import subprocess

import pytest

from pam_bag.testing import PRESSURES_BEFORE_SAMPLE_RIHS01, write_bag_before_sample
from pam_common.testing import executable

BAD_INPUT = 2


def run(*args):
    return subprocess.run([str(a) for a in args], capture_output=True, text=True, timeout=300)


@pytest.fixture(scope='module')
def old_bag(tmp_path_factory):
    return write_bag_before_sample(tmp_path_factory.mktemp('old') / 'old')


def assert_one_line(out, *parts):
    assert out.returncode == BAD_INPUT, out.stdout + out.stderr
    lines = out.stderr.splitlines()
    assert len(lines) == 1 and all(p in lines[0] for p in parts), out.stderr


def refusal(bag) -> tuple:
    return (f'error: {bag / "old.mcap"}: topic /pam/pressures was recorded with a different '
            f'definition of pam_interfaces/msg/Pressures (bag {PRESSURES_BEFORE_SAMPLE_RIHS01}, '
            'installed RIHS01_', 're-record or convert the bag')


def test_pam_evaluate_refuses_a_bag_of_the_old_pressures(old_bag):
    out = run(executable('pam-evaluate', 'pam_estimator'), old_bag)
    assert_one_line(out, *refusal(old_bag))
    assert 'model alone' not in out.stdout


def test_pam_identify_refuses_it_and_writes_nothing(old_bag, tmp_path):
    out = run(executable('pam-identify', 'pam_estimator'), old_bag, '-o', tmp_path / 'result')
    assert_one_line(out, *refusal(old_bag))
    assert not (tmp_path / 'result').exists()


def test_messages_that_do_not_match_their_channel_are_named(tmp_path):
    bag = write_bag_before_sample(tmp_path / 'old', labelled_as_now=True)
    out = run(executable('pam-evaluate', 'pam_estimator'), bag)
    assert_one_line(out, f'error: {bag}: message 1 of /pam/pressures is not a valid '
                         'pam_interfaces/msg/Pressures (', 'another definition of the type?')
