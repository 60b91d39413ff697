#!/usr/bin/env bash
# Sets up everything renderloop needs on a fresh Debian/Ubuntu machine:
#   - Debian packages: libegl1 + libgl1 (headless MuJoCo rendering with MUJOCO_GL=egl), chromium and
#     fonts-dejavu-core (tests/test_report.py opens report.html in it through Playwright, which never downloads a browser),
#     and CPython 3.11 with venv when no python3.11 is on PATH (bpy==5.0.1 needs exactly 3.11);
#   - a virtual environment in .venv with renderloop and its test tools installed.
# Safe to run again: it only installs what is missing.
set -euo pipefail
cd "$(dirname "$0")/.."

as_root() { if [ "$(id -u)" -eq 0 ]; then "$@"; else sudo "$@"; fi; }

missing=()
for pkg in libegl1 libgl1 chromium fonts-dejavu-core; do
  dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || missing+=("$pkg")
done
if ! command -v python3.11 >/dev/null 2>&1; then
  missing+=(python3.11 python3.11-venv)
fi
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing Debian packages: ${missing[*]}"
  as_root apt-get update -qq
  DEBIAN_FRONTEND=noninteractive as_root apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

if [ ! -x .venv/bin/python ] || ! .venv/bin/python -c 'import sys; assert sys.version_info[:2] == (3, 11)' 2>/dev/null; then
  rm -rf .venv
  python3.11 -m venv .venv
fi
.venv/bin/python -m pip install --quiet --disable-pip-version-check --upgrade pip
.venv/bin/python -m pip install --quiet --disable-pip-version-check -e ".[test]"
echo "setup: ready ($(.venv/bin/renderloop --version))"
