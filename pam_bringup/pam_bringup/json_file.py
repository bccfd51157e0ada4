"""The JSON result files of pam_bringup's tools (tracking_report's `summary`, pam-demo's
demo_summary.json): strict JSON, written whole.

A non-finite number (the settling time of a step that never settled is inf) is written as null,
so that any JSON reader takes the file; numpy scalars become plain numbers. The file is written
to a temporary sibling and renamed, so a reader never sees half of it.
"""

from __future__ import annotations

import json
import math
import numbers
import os
from pathlib import Path


def plain(value):
    """value with mappings, sequences and numbers made strict-JSON-ready (non-finite: None)."""
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return value
    if isinstance(value, numbers.Integral):
        return int(value)
    if isinstance(value, numbers.Real):
        number = float(value)
        return number if math.isfinite(number) else None
    return value


def write_json(path, data) -> Path:
    """Write data (plain()'d) as indented JSON to path; returns the path."""
    path = Path(path)
    tmp = path.with_name(path.name + '.tmp')
    tmp.write_text(json.dumps(plain(data), indent=2, allow_nan=False) + '\n')
    os.replace(tmp, path)
    return path
