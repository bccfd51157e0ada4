"""Which sections of a ROS 2 params file apply to a node (rcl's matching of the keys).

A params file has one section per node, keyed by the node's full name (`/pam/sim_node:`); a
leading '/' is implied, '*' stands for one name token and '**' for any number of them, so
`/**/sim_node:` is sim_node in any namespace and `/**:` every node. A bare `sim_node:` key means
/sim_node: it does NOT apply under /pam (the mistake warned about: section_warning).
"""

from __future__ import annotations

import re
from pathlib import Path

from pam_common.params_files import check_params_file


def key_pattern(key: str) -> re.Pattern:
    """rcl's node-name matching of a params-file key, as a regular expression of full names."""
    tokens = key.strip('/').split('/') if key.strip('/') else []
    regex = ''
    for token in tokens:
        if token == '**':
            regex += '(?:/[^/]+)*'
        else:
            regex += '/' + ''.join('[^/]*' if c == '*' else re.escape(c) for c in token)
    return re.compile(f'^{regex}$')


def section_keys(path: Path) -> list[str]:
    """The node sections of a params file (nested keys joined with '/'); raises ValueError
    (ParamsFileError: one line, with the line number where there is one)."""
    return check_params_file(path)


def sections_for(node_fqn: str, keys: list[str]) -> list[str]:
    """The keys of `keys` that apply to the node of full name `node_fqn`."""
    return [k for k in keys if key_pattern(k).match(node_fqn)]


def section_warning(node_fqn: str, keys: list[str]) -> str | None:
    """A warning when no section but `/**` applies to the node (it runs with its defaults), else
    None."""
    matching = sections_for(node_fqn, keys)
    if [k for k in matching if k.strip('/') != '**']:
        return None
    return (f'warning: no section of the params file is for {node_fqn} (sections: '
            f'{", ".join(keys) or "none"}): it runs with its defaults'
            + (' and /**' if matching else ''))
