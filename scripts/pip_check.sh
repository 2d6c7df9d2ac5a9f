#!/usr/bin/env bash
# The pip route without root: `pip install .` into a fresh virtual environment with
# nothing but what pyproject.toml asks for, then the built wheel (`pip wheel --no-deps`)
# in place of the package. After each, the headless commands run there (simulate,
# peaks, process, info) and are checked: their outputs exist, and they loaded no Qt
# module and none of the system's X, OpenGL or D-Bus libraries (what the apt packages of
# scripts/setup.sh bring). GenICam is optional: `holoview info` must say it is not
# usable, and why.
#
# Run by .ci/run (a few minutes: pip installs about 600 MB of wheels; from its cache
# faster). Environment: PYTHON (default python3) makes the environments.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
python="${PYTHON:-python3}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
say() { printf 'pip_check: %s\n' "$*" >&2; }
fail() { say "FAILED: $*"; exit 1; }

# Run the headless commands with the environment $1 in a folder of their own, away from
# the checkout (so that `import holoview` finds the installed package).
check_environment() {
  local env="$1" run
  run="$(mktemp -d "$work/run.XXXX")"
  cd "$run"
  local where
  where="$("$env/bin/python" -c 'import holoview; print(holoview.__file__)')"
  [[ "$where" == "$env"/* ]] || fail "holoview imported from $where, not from $env"
  "$env/bin/holoview" --version
  "$env/bin/holoview" info >info.txt || fail "holoview info: exit status $?"
  grep -q "^GenICam (Aravis)  no: PyGObject is not installed" info.txt \
    || fail "holoview info does not say GenICam is unusable: $(cat info.txt)"
  "$env/bin/holoview" -q simulate sim.h5 --scenario evaporation --size 128 --frames 40 \
    --fps 20 --seed 1 --png sim.png
  "$env/bin/holoview" peaks sim.h5 --json >experiment.json
  "$env/bin/holoview" -q process sim.h5 --out out --experiment experiment.json --maps \
    --report-format pdf
  for f in sim.png out/trends.csv out/summary.json out/results.h5 out/report.pdf; do
    [[ -s "$f" ]] || fail "$f missing or empty"
  done
  # the same commands in one interpreter: what they loaded
  "$env/bin/python" - <<'EOF' || fail "the headless commands loaded Qt or X libraries"
import contextlib
import io
import sys

from holoview.cli import main

assert main(["-q", "simulate", "again.h5", "--size", "64", "--frames", "10", "--png", "a.svg"]) == 0
with contextlib.redirect_stdout(io.StringIO()):
    assert main(["-q", "peaks", "again.h5", "--json"]) == 0
assert main(["-q", "process", "again.h5", "--out", "again", "--frames", ":8"]) == 0
qt = sorted(m for m in sys.modules if m.split(".")[0] in ("PyQt6", "PyQt5", "PySide6", "pyqtgraph"))
with open("/proc/self/maps") as maps:
    libraries = {line.split()[-1] for line in maps if ".so" in line}
system_x = sorted(
    p for p in libraries
    if p.rsplit("/", 1)[-1].startswith(("libX", "libxcb", "libGL", "libEGL", "libxkb", "libdbus"))
    and not p.startswith(sys.prefix)
)
print("Qt modules:", qt, "system X/GL/D-Bus libraries:", system_x, file=sys.stderr)
sys.exit(1 if qt or system_x else 0)
EOF
  say "simulate, peaks, process, info work with $where; no Qt, no X"
  cd "$repo"
}

start=$SECONDS
env="$work/env"
say "pip install . into a fresh environment"
"$python" -m venv "$env"
"$env/bin/python" -m pip install -q --disable-pip-version-check "$repo"
check_environment "$env"

say "pip wheel --no-deps ., then the wheel in place of the package"
"$env/bin/python" -m pip wheel -q --disable-pip-version-check --no-deps -w "$work/dist" "$repo"
wheel=("$work"/dist/holoview-*.whl)
[[ -f "${wheel[0]}" ]] || fail "no wheel built"
"$env/bin/python" -m pip uninstall -q -y holoview
"$env/bin/python" -m pip install -q --disable-pip-version-check --no-deps "${wheel[0]}"
"$env/bin/python" -m pip check || fail "the wheel's requirements are not met by pip install ."
check_environment "$env"
say "passed in $((SECONDS - start)) s"
