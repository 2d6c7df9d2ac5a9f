#!/usr/bin/env bash
# Set up if needed, then run every quality gate: ruff lint and format check, the
# import-linter layering contracts, mypy (the strictness per package in pyproject.toml;
# any error fails), the documentation site (mkdocs build --strict: any warning fails),
# and the pytest suite (Qt offscreen, two processes).
# Extra arguments go to pytest.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$repo/scripts/setup.sh"
cd "$repo"
export QT_QPA_PLATFORM=offscreen
bin="$repo/.venv/bin"
echo "== ruff" && "$bin/ruff" check --no-cache . && "$bin/ruff" format --check --no-cache .
echo "== import-linter" && "$bin/lint-imports" --no-cache
echo "== mypy" && "$bin/mypy" holoview
site="$(mktemp -d)"
echo "== mkdocs"
NO_MKDOCS_2_WARNING=1 "$bin/mkdocs" build --strict --site-dir "$site" || { rm -rf "$site"; exit 1; }
rm -rf "$site"
# the tests in two processes where there are two cores (pytest-xdist; a file's tests stay
# together, so its module fixtures are made once): CI has two and 15 minutes for the suite
workers=$(( $(nproc) >= 2 ? 2 : 1 ))
echo "== pytest ($workers processes)"
exec "$bin/python" -m pytest -n "$workers" --dist loadfile "$@"
