"""Our node processes ask FastDDS for asynchronous publication unless the user chose a mode:
the 1 kHz loop's publish() then only queues the sample (pam_common.executors)."""

import os

from pam_common import executors


def test_asynchronous_unless_the_user_chose(monkeypatch):
    variable = executors.PUBLICATION_MODE_VARIABLE
    monkeypatch.delenv(variable, raising=False)
    assert executors.prefer_asynchronous_publication() == 'ASYNCHRONOUS'
    assert os.environ[variable] == 'ASYNCHRONOUS'
    monkeypatch.setenv(variable, 'SYNCHRONOUS')
    assert executors.prefer_asynchronous_publication() == 'SYNCHRONOUS'
    assert os.environ[variable] == 'SYNCHRONOUS'


def test_lockstep_runs_synchronous_unless_the_user_chose():
    """A lockstep loop is latency-bound: its launchers give the children synchronous
    publication, and keep a mode already in the environment."""
    variable = executors.PUBLICATION_MODE_VARIABLE
    env = {}
    assert executors.lockstep_publication(env) == 'SYNCHRONOUS'
    assert env == {variable: 'SYNCHRONOUS'}
    env = {variable: 'ASYNCHRONOUS'}
    assert executors.lockstep_publication(env) == 'ASYNCHRONOUS'
