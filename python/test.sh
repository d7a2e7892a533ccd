#!/usr/bin/env bash
# Installs the Python package with pip (maturin builds it) into a virtual environment under
# target/, then runs its tests, which compare it with the `moreau` binary of `cargo build --release`.
set -euo pipefail
cd "$(dirname "$0")/.."
# The software adapter on the calling thread, as for cargo's processes (.cargo/config.toml).
export LP_NUM_THREADS="${LP_NUM_THREADS:-0}"
venv=target/python-venv
[ -x "$venv/bin/python" ] || python3 -m venv "$venv"
[ -x target/release/moreau ] || cargo build --release --bin moreau
"$venv/bin/pip" install -q --disable-pip-version-check "./python[test]"
"$venv/bin/python" -m pytest -q python/tests
