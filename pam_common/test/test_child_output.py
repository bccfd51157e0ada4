"""pam_common.testing.read_child_output: reading a child's output file while it writes loses and
garbles nothing (the child shares the file's offset; a seek-based read let its next line
overwrite the start of the file)."""

import subprocess
import sys
import tempfile

from pam_common.testing import read_child_output

LINES = 20000
WRITER = (f'import sys\nfor i in range({LINES}):\n'
          '    sys.stderr.write(f"line {i}\\n")\n    sys.stderr.flush()\n')


def test_reading_while_the_child_writes_loses_nothing():
    with tempfile.TemporaryFile(mode='w+b') as f:
        proc = subprocess.Popen([sys.executable, '-c', WRITER], stderr=f)
        reads = 0
        while proc.poll() is None:
            read_child_output(f)
            reads += 1
        assert proc.wait() == 0
        text = read_child_output(f)
    assert reads > 10, 'the child ended before the test could read while it wrote'
    assert text.splitlines() == [f'line {i}' for i in range(LINES)]
