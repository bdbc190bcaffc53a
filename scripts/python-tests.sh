#!/usr/bin/env bash
# Builds the Python package (release, abi3 wheel, from crates/python) into a virtual environment
# in the cargo target folder and runs its pytest suite against the command-line binary of the
# same target folder (build that first: cargo build --release -p shapespace-cli, or cargo test
# --release --workspace). Installs numpy, pandas, pytest, maturin, dask and distributed from
# the Python registry into that environment. Run from anywhere; exit code that of pytest, and a
# run that collects no tests (pytest's 5) fails.
set -euo pipefail
cd "$(dirname "$0")/.."
target="${CARGO_TARGET_DIR:-$PWD/target}"
venv="$target/python-venv"
python="${PYTHON:-python3}"
if [ ! -x "$venv/bin/python" ]; then
    "$python" -m venv "$venv"
fi
"$venv/bin/pip" install --quiet --disable-pip-version-check numpy pandas pytest 'maturin>=1.5,<2' dask distributed
# (the same cargo target folder: the workspace crates built by cargo test --release are reused)
CARGO_TARGET_DIR="$target" "$venv/bin/pip" install --quiet --disable-pip-version-check \
    --no-build-isolation --force-reinstall --no-deps ./crates/python
export SHAPESPACE_BIN="${SHAPESPACE_BIN:-$target/release/shapespace}"
status=0
"$venv/bin/python" -m pytest -q -ra crates/python/tests "$@" || status=$?
if [ "$status" -eq 5 ]; then
    echo "python-tests: pytest collected no tests" >&2
fi
exit "$status"
