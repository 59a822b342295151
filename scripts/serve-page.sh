# Sourced by scripts/web-tests.sh and scripts/web-bench.sh: serves the built page
# (crates/web/www) on a free local port and makes a Python environment with Selenium and pytest,
# both in a temporary folder that goes when the script exits. Sets `stage` (the folder), `port`
# and `python` (the environment's interpreter).
stage="$(mktemp -d)"
port="$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')"
python3 -m http.server --bind 127.0.0.1 --directory crates/web/www "$port" >"$stage/server.log" 2>&1 &
server=$!
trap 'kill $server 2>/dev/null; rm -rf "$stage"' EXIT
python3 -m venv "$stage/venv"
"$stage/venv/bin/pip" install --quiet pytest selenium
python="$stage/venv/bin/python"
