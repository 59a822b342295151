#!/usr/bin/env bash
# The web page's drawing times beside native `infer` on one thread: builds the page
# (scripts/web.sh) and the release `infer`, serves the page on a free local port, and runs
# crates/web/tests/bench_page.py, which feeds each image to the page ROUNDS times through its
# file input (headless Chromium, Selenium, as scripts/web-tests.sh) and reads the time the page
# shows, then times `RAYON_NUM_THREADS=1 infer IMAGE --metrics` as often. Prints a line per image
# (medians) and the totals: what docs/web.md's table is.
#
# Usage: scripts/web-bench.sh [IMAGE...]   (default: data/eval/photos/*; ROUNDS=3)
set -euo pipefail
cd "$(dirname "$0")/.."
target="${CARGO_TARGET_DIR:-target}"
scripts/web.sh --build-only
cargo build --release -p infer
source scripts/serve-page.sh
if [ $# -eq 0 ]; then set -- data/eval/photos/*; fi
WEB_URL="http://127.0.0.1:$port/" INFER="$(realpath "$target/release/infer")" \
  "$python" crates/web/tests/bench_page.py "$@"
