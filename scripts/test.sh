#!/usr/bin/env bash
# Set up what the tests need and run them: bash scripts/test.sh [PYTEST ARGS]
#   (no args: the fast tier; -m slow: the whole-video tier; -m "slow or not slow": both, as CI)
# Makes .venv (a stock Debian python refuses a bare pip install), installs the package with its
# test and segment extras (the person segmenter's tests run too: tracker.video.segmenter), and, as
# root, Debian's chromium for the browser test of track --view (skipped with a reason without
# it).
set -euo pipefail
cd "$(dirname "$0")/.."

as_root() { if [ "$(id -u)" = 0 ]; then "$@"; elif command -v sudo >/dev/null; then sudo "$@"; else return 1; fi; }
apt_install() {   # apt-get install "$@", tried up to three times (Debian's mirrors hiccup)
    export DEBIAN_FRONTEND=noninteractive
    for attempt in 1 2 3; do
        if as_root apt-get update -qq && as_root apt-get install -y -qq "$@" >/dev/null; then
            return 0
        fi
        echo "apt-get install $* failed (attempt $attempt)" >&2
        sleep 5
    done
    return 1
}

if [ -x .venv/bin/python ] && ! .venv/bin/python -m pip --version >/dev/null 2>&1; then
    rm -rf .venv          # a venv made without pip (python3-venv missing then): made again
fi
if [ ! -x .venv/bin/python ]; then
    if ! python3 -m venv .venv 2>/dev/null; then
        rm -rf .venv
        apt_install python3-venv
        python3 -m venv .venv
    fi
fi
if ! command -v chromium >/dev/null 2>&1; then
    apt_install chromium || echo "chromium not installed: the browser test will be skipped" >&2
fi
.venv/bin/python -m pip install --quiet --upgrade pip
.venv/bin/python -m pip install --quiet -e ".[test,segment]"
exec .venv/bin/python -m pytest -q "$@"
