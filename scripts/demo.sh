#!/usr/bin/env bash
# Placeholder: replaced by the demo issue.
set -euo pipefail
echo "demo: not yet wired"
exit 0
