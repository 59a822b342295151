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
stage="$(mktemp -d)"
port="$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')"
python3 -m http.server --bind 127.0.0.1 --directory crates/web/www "$port" >"$stage/server.log" 2>&1 &
server=$!
trap 'kill $server 2>/dev/null; rm -rf "$stage"' EXIT
python3 -m venv "$stage/venv"
"$stage/venv/bin/pip" install --quiet pytest selenium
if [ $# -eq 0 ]; then set -- data/eval/photos/*; fi
WEB_URL="http://127.0.0.1:$port/" INFER="$(realpath "$target/release/infer")" \
  "$stage/venv/bin/python" crates/web/tests/bench_page.py "$@"
