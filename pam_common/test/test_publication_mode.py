"""Our node processes ask FastDDS for asynchronous publication unless the user chose a mode:
the 1 kHz loop's publish() then only queues the sample (pam_common.executors)."""

from pam_common.executors import (PUBLICATION_MODE, PUBLICATION_MODE_VARIABLE,
                                  prefer_asynchronous_publication)


def test_asynchronous_unless_the_user_chose(monkeypatch):
    monkeypatch.delenv(PUBLICATION_MODE_VARIABLE, raising=False)
    assert PUBLICATION_MODE == 'ASYNCHRONOUS'
    assert prefer_asynchronous_publication() == 'ASYNCHRONOUS'
    import os
    assert os.environ[PUBLICATION_MODE_VARIABLE] == 'ASYNCHRONOUS'
    monkeypatch.setenv(PUBLICATION_MODE_VARIABLE, 'SYNCHRONOUS')
    assert prefer_asynchronous_publication() == 'SYNCHRONOUS'
    assert os.environ[PUBLICATION_MODE_VARIABLE] == 'SYNCHRONOUS'
