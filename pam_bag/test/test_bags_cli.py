"""pam-bag-info and pam-bag-recover as a user runs them on a damaged bag (8 bytes flipped in
chunk 1 where zstd still decompresses: only the chunk's CRC shows it) and on a split bag with a
file missing; the exit code for bad input is 2 (docs/stopping.md, Exit codes)."""

import shutil
import subprocess

import pytest

from pam_bag.bags import make_typestore
from pam_bag.testing import damage_chunk
from pam_common.testing import executable
from test_bags_lib import write_bag  # the same test folder (pytest's prepend import mode)

BAD_INPUT = 2


def run(name, *args):
    return subprocess.run([executable(name, 'pam_bag'), *map(str, args)],
                          capture_output=True, text=True, timeout=60)


@pytest.fixture(scope='module')
def good(tmp_path_factory):
    """A complete bag of 25000 messages in two zstd chunks."""
    path = tmp_path_factory.mktemp('good') / 'b'
    write_bag(make_typestore(), path, n=25_000)
    return path


@pytest.fixture
def damaged(good, tmp_path):
    """A copy of `good` with 8 bytes flipped in chunk 1; (the bag, the flipped byte's offset)."""
    bag = tmp_path / 'b'
    shutil.copytree(good, bag)
    return bag, damage_chunk(bag / 'b.mcap', 1)


def test_bag_info_verify_reports_what_it_checked(good):
    out = run('pam-bag-info', good, '--verify')
    assert out.returncode == 0, out.stderr
    assert 'Count: 25000 ' in out.stdout
    assert ('Verified:          1 files, 2 chunks read; chunk CRCs: 2 of 2, data section CRCs: '
            '1 of 1 files') in out.stdout


def test_bag_info_refuses_a_damaged_bag_naming_the_chunk(damaged):
    bag, _ = damaged
    out = run('pam-bag-info', bag)
    assert out.returncode == BAD_INPUT and out.stdout == ''
    assert out.stderr.count('\n') == 1, out.stderr
    assert out.stderr.startswith(f'pam-bag-info: error: {bag}: b.mcap: chunk 1 at byte '), \
        out.stderr
    assert 'CRC mismatch' in out.stderr and f'pam-bag-recover {bag}' in out.stderr

    verify = run('pam-bag-info', bag, '--verify')
    assert verify.returncode == BAD_INPUT
    assert 'Count: 25000 ' in verify.stdout       # the summary is intact: the info is printed
    lines = verify.stderr.splitlines()
    assert lines[0] == (f'pam-bag-info: error: {bag}: 2 problem(s) found (`pam-bag-recover '
                        f'{bag}` rebuilds the bag without the damaged parts):'), lines
    assert lines[1].startswith('  b.mcap: chunk 1 at byte ') and 'CRC mismatch' in lines[1]
    assert lines[2].startswith('  b.mcap: data section CRC mismatch')
    assert len(lines) == 3


def test_bag_recover_rebuilds_a_damaged_bag_without_the_chunk(damaged):
    bag, _ = damaged
    fixed = run('pam-bag-recover', bag)
    assert fixed.returncode == 0, fixed.stderr
    assert 'CRC mismatch' in fixed.stdout and 'missing' not in fixed.stdout
    assert run('pam-bag-info', bag, '--verify').returncode == 0


def test_bag_recover_names_a_missing_file_and_the_messages_lost(tmp_path):
    """A split bag (4 files: 2000, 2000, 2000, 1000 messages) with b_2.mcap deleted: the rest
    is recovered (files keep their names), the error line names b_2.mcap and its 2000
    messages, exit 2."""
    bag = tmp_path / 'b'
    write_bag(make_typestore(), bag, n=7000, max_bag_duration=2.0)
    (bag / 'b_2.mcap').unlink()
    out = run('pam-bag-recover', bag)
    assert out.returncode == BAD_INPUT
    assert out.stderr == (f'pam-bag-recover: error: {bag}: missing b_2.mcap (2000 messages): '
                          '2000 messages lost (the bag was rebuilt from the other files)\n')
    assert '  missing:  b_2.mcap (2000 messages): listed in the bag, not there' in out.stdout
    assert 'messages: 5000' in out.stdout
    assert (bag / 'b_3.mcap').is_file() and not (bag / 'b_2.mcap').exists()
    assert run('pam-bag-info', bag).returncode == 0


def test_bad_input_exits_2(tmp_path):
    for args, error in (((tmp_path / 'nope',), 'no such bag directory'),
                        ((tmp_path,), 'metadata.yaml: missing')):
        out = run('pam-bag-info', *args)
        assert out.returncode == BAD_INPUT and error in out.stderr, out.stderr
        assert out.stderr.count('\n') == 1
