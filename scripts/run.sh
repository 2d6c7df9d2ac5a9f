#!/usr/bin/env bash
# Set up if needed, then run holoview (with no arguments: the live GUI on the simulated camera).
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$repo/scripts/setup.sh"
exec "$repo/.venv/bin/holoview" "$@"
