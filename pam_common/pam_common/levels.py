"""The /diagnostics levels, without ROS: the byte values of diagnostic_msgs/DiagnosticStatus's
OK, WARN, ERROR and STALE, so that a node's ROS-free core (sim_core.SimCore, ...) can decide a
level that pam_common.diagnostics publishes as it is (they are ordered: max() picks the worst)."""

OK = b'\x00'
WARN = b'\x01'
ERROR = b'\x02'
STALE = b'\x03'

LEVEL_NAMES = {OK: 'OK', WARN: 'WARN', ERROR: 'ERROR', STALE: 'STALE'}
