#!/usr/bin/env bash
# The Python package's tests against the native module of the workspace's own build
# (`cargo build --workspace --features wgpu`: the same compiled burn as README's test command),
# not a wheel: `pip install ./python` would compile burn a second time, in release, for the
# wheel alone. The package is staged as the wheel lays it out (supersvg/ with _native inside).
#
# Usage: scripts/python-tests.sh [pytest arguments]
set -euo pipefail
cd "$(dirname "$0")/.."
target="${CARGO_TARGET_DIR:-target}"
cargo build --workspace --features wgpu
stage="$(mktemp -d)"
trap 'rm -rf "$stage"' EXIT
cp -r python/supersvg "$stage/"
cp "$target/debug/lib_native.so" "$stage/supersvg/_native.abi3.so"
python3 -m venv "$stage/venv"
"$stage/venv/bin/pip" install --quiet pytest numpy
PYTHONPATH="$stage" "$stage/venv/bin/python" -m pytest -q -p no:cacheprovider python/tests "$@"
