#!/usr/bin/env bash
# The whole test suite: the Rust tests, then the Python package built into a fresh virtual
# environment (sharing the cargo target directory and the test profile's compiled
# dependencies) and its pytest suite.
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$PWD/target}"
# No display: keep Mesa's device-select layer from looking for one (and saying so) in the
# Python tests too; cargo sets it for its own test binaries (.cargo/config.toml).
export NODEVICE_SELECT=1

cargo test --locked --workspace

VENV="${ISOMESH_VENV:-$CARGO_TARGET_DIR/python-venv}"
rm -rf "$VENV"
python3 -m venv "$VENV"
"$VENV/bin/python" -m pip install --quiet --upgrade pip
"$VENV/bin/python" -m pip install --quiet pytest numpy meshio trimesh "dask[distributed]"
# The wheel is built with the dev profile (opt-level 2 like the tests) and the features the
# tests gave its dependencies (`share-test-build`): the isomesh crate and every dependency that
# the Rust tests compiled are reused; only pyo3, numpy and the bindings compile here.
MATURIN_PEP517_ARGS="--profile dev --locked --features share-test-build" \
    "$VENV/bin/python" -m pip install --quiet ./python
export ISOMESH_CLI="$CARGO_TARGET_DIR/debug/isomesh"
cd python/tests
set +e
"$VENV/bin/python" -m pytest -q
status=$?
set -e
if [ "$status" = 5 ]; then
    echo "pytest collected no tests" >&2
    exit 1
fi
exit "$status"
