#!/usr/bin/env bash
# The web page's tests in a real browser: builds the page (scripts/web.sh) and the native
# `infer` it is compared with (the workspace's own build, as README's test command makes it, so
# nothing is compiled twice), serves the page on a free local port, and runs
# crates/web/tests/test_page.py with Selenium against Debian's chromium and chromium-driver.
# SCREENSHOT=docs/web.png also saves the page as the first test leaves it.
#
# Usage: scripts/web-tests.sh [pytest arguments]
set -euo pipefail
cd "$(dirname "$0")/.."
target="${CARGO_TARGET_DIR:-target}"
scripts/web.sh --build-only
cargo build --workspace --features wgpu
source scripts/serve-page.sh
WEB_URL="http://127.0.0.1:$port/" INFER="$(realpath "$target/debug/infer")" \
  "$python" -m pytest -q -s -p no:cacheprovider crates/web/tests "$@"
