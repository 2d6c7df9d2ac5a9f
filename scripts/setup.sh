#!/usr/bin/env bash
# Take a fresh Debian 12 machine (root, Python 3.11) to a working holoview install.
#
# Idempotent: apt packages already present are skipped, and the virtual environment
# (.venv in the repository) is rebuilt only when the requirement files or this script
# change. A second run takes about a second.
#
# Environment: PYTHON (default python3) picks the interpreter for the venv;
# HOLOVIEW_SKIP_APT=1 skips the system packages (for machines you do not administer).
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="$repo/.venv"
python="${PYTHON:-python3}"
say() { printf 'setup: %s\n' "$*" >&2; }

apt_packages=(
  # build
  python3-venv python3-dev build-essential pkg-config
  # Qt runtime for the PyQt6 wheels
  libgl1 libegl1 libopengl0 libglib2.0-0 libfontconfig1 libfreetype6 libdbus-1-3
  libxkbcommon0 libxkbcommon-x11-0 libx11-6 libx11-xcb1 libxcb1 libxcb-cursor0
  libxcb-icccm4 libxcb-image0 libxcb-keysyms1 libxcb-randr0 libxcb-render0
  libxcb-render-util0 libxcb-shape0 libxcb-shm0 libxcb-sync1 libxcb-xfixes0
  libxcb-xkb1 libxcb-glx0 fonts-dejavu-core
  # virtual display and screenshots
  xvfb xauth imagemagick x11-apps
  # Aravis (GenICam) and what PyGObject builds against
  libaravis-0.8-0 gir1.2-aravis-0.8 aravis-tools-cli libgirepository1.0-dev
  gobject-introspection libcairo2-dev
  # FFmpeg codecs for OpenCV video replay come with the wheel; nothing more here
  # the system's netCDF-C tools (ncdump, 4.9.0 on Debian 12): the tests read results.h5 with them
  netcdf-bin
)

install_apt() {
  if [[ "${HOLOVIEW_SKIP_APT:-0}" == 1 ]]; then say "skipping apt (HOLOVIEW_SKIP_APT=1)"; return; fi
  if ! command -v dpkg-query >/dev/null || ! command -v apt-get >/dev/null; then
    say "no apt here: install the system packages listed in scripts/setup.sh yourself"; return
  fi
  local missing=() p
  for p in "${apt_packages[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  if ((${#missing[@]} == 0)); then return; fi
  local sudo=()
  if [[ $(id -u) != 0 ]]; then sudo=(sudo); fi
  say "installing ${#missing[@]} system packages: ${missing[*]}"
  "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get update -qq
  "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
}

install_venv() {
  local stamp="$venv/.holoview-stamp" want
  want="$(cat "$repo/requirements.txt" "$repo/requirements-dev.txt" "$repo/pyproject.toml" "$0" | sha256sum | cut -c1-16)"
  if [[ -x "$venv/bin/python" && -f "$stamp" && "$(cat "$stamp")" == "$want" ]]; then return; fi
  if [[ ! -x "$venv/bin/python" ]]; then
    say "creating $venv with $("$python" --version 2>&1)"
    "$python" -m venv "$venv"
  fi
  say "installing Python packages (about a minute the first time)"
  "$venv/bin/python" -m pip install -q --disable-pip-version-check --upgrade pip
  "$venv/bin/python" -m pip install -q --disable-pip-version-check \
    -r "$repo/requirements.txt" -r "$repo/requirements-dev.txt"
  "$venv/bin/python" -m pip install -q --disable-pip-version-check --no-deps -e "$repo"
  echo "$want" >"$stamp"
}

start=$SECONDS
install_apt
install_venv
say "ready in $((SECONDS - start)) s ($venv)"
