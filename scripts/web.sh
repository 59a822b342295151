#!/usr/bin/env bash
# The web page: compiles crates/web to WebAssembly (with the bundled networks in it), binds it
# for the browser into crates/web/www/pkg, then serves crates/web/www on 127.0.0.1. The folder
# it builds is the whole site: any static host serves it as it is.
#
# Usage: scripts/web.sh [--port N] [--build-only]   (default port 8080)
set -euo pipefail
cd "$(dirname "$0")/.."
port=8080
serve=1
while [ $# -gt 0 ]; do
  case "$1" in
    --port) port="$2"; shift 2 ;;
    --build-only) serve=0; shift ;;
    *) echo "usage: $0 [--port N] [--build-only]" >&2; exit 2 ;;
  esac
done
target="${CARGO_TARGET_DIR:-target}"

if command -v rustup >/dev/null; then
  rustup target add wasm32-unknown-unknown >/dev/null
fi
# The binding tool must be the exact version of the wasm-bindgen crate the module links.
version="$(sed -n '/^name = "wasm-bindgen"$/{n;s/^version = "\(.*\)"$/\1/p;}' Cargo.lock)"
if [ "$(wasm-bindgen --version 2>/dev/null)" != "wasm-bindgen $version" ]; then
  cargo install wasm-bindgen-cli --version "$version"
fi

# WebAssembly's 128-bit SIMD (every current browser has it; burn's kernels use it), and
# getrandom 0.3's browser backend (crates/web/Cargo.toml says why).
export CARGO_TARGET_WASM32_UNKNOWN_UNKNOWN_RUSTFLAGS='-C target-feature=+simd128 --cfg getrandom_backend="wasm_js"'
cargo build --profile web --target wasm32-unknown-unknown -p web --lib
wasm-bindgen --target web --no-typescript --out-dir crates/web/www/pkg \
  --remove-name-section "$target/wasm32-unknown-unknown/web/web.wasm"

if [ "$serve" = 1 ]; then
  echo "supersvg: http://127.0.0.1:$port/ (Ctrl-C stops)"
  exec python3 -m http.server --bind 127.0.0.1 --directory crates/web/www "$port"
fi
