#!/usr/bin/env bash
# The web app tested in a real browser: builds it (scripts/web-build.sh), serves it on
# localhost, and drives headless Chromium with WebGPU through it (scripts/web-test/drive.mjs,
# Playwright's driver from npm, Debian's chromium): the thesis scene with osm at 24 channels
# beside exact, FLIP vs exact within 0.002 of the native CLI's figure at the same size, a
# dropped PLY of ours, a broken file's one line, a sweep from the page's controls (byte and memory
# budgets, two map resolutions) whose downloaded results.csv/results.json have the CLI's
# columns, cells, bytes and tuned shapes and its errors within 0.002, a dropped numbered PLY
# sequence stepped from its first frame to its last, and a dropped OpenVDB sequence.
# Prints flip_vs_exact=VALUE last.
#
# Needs: chromium (apt-get install -y chromium), node and npm, python3 (the server), and what
# web-build.sh installs. Without a GPU Chromium's WebGPU adapter is SwiftShader (software).
#
#   scripts/web-test.sh [SIZE]      (default 320x240: a software adapter renders it in seconds)
set -euo pipefail
cd "$(dirname "$0")/.."
size=${1:-320x240}
command -v chromium > /dev/null || { echo "error: chromium is not installed (apt-get install -y chromium)" >&2; exit 2; }
command -v npm > /dev/null || { echo "error: npm is not installed" >&2; exit 2; }

scripts/web-build.sh target/web/site
# The CLI as `cargo test` builds it (a debug build: the GPU's work is the same).
cargo build --bin smokeshadow
work=$(mktemp -d)
server=""
trap 'rm -rf "$work"; [[ -n $server ]] && kill "$server" 2> /dev/null || true' EXIT

# The native figure: the CLI's renders of the same scene at the same size, FLIP between them.
cli=target/debug/smokeshadow
"$cli" render --technique osm --channels 24 --size "$size" -o "$work/osm.png" > /dev/null
"$cli" render --technique exact --size "$size" -o "$work/exact.png" > /dev/null
native=$("$cli" diff --json "$work/exact.png" "$work/osm.png" | python3 -c 'import json, sys; print(json.load(sys.stdin)["metrics"]["flip_mean"])')

# The CLI's sweep the page's is held to (drive.mjs runs the same one from the page's controls).
"$cli" sweep --techniques osm,fom --channels 24,8 --bytes-per-texel 24 --memory 3MiB \
    --shadow-res 256,512 --frames 3 --size 160x120 -o "$work/sweep" > /dev/null

# A particle file of ours to drop, and a broken one.
"$cli" particles column -o "$work/column.ply" > /dev/null
count=$(awk '/^element vertex/ { print $3; exit }' "$work/column.ply")
# A numbered sequence of three frames of the thesis plume, each with more particles.
mkdir "$work/sequence"
"$cli" particles --frames 4..6 --fps 4 -o "$work/sequence/smoke.%04d.ply" > /dev/null
# Two frames of an OpenVDB sequence (OpenUSD's smoke, twice).
mkdir "$work/volumes"
for frame in 1 2; do cp tests/data/volumes/openusd_smoke_000003.vdb "$work/volumes/smoke.000$frame.vdb"; done
printf 'ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nend_header\n1 2\n' > "$work/broken.ply"

(cd scripts/web-test && npm ci --no-audit --no-fund --silent)
port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
python3 -m http.server "$port" --bind 127.0.0.1 --directory target/web/site > "$work/server.log" 2>&1 &
server=$!
python3 - "$port" << 'PY'
import socket, sys, time
for _ in range(100):
    try:
        socket.create_connection(("127.0.0.1", int(sys.argv[1])), timeout=1).close()
        break
    except OSError:
        time.sleep(0.1)
PY
node scripts/web-test/drive.mjs "http://127.0.0.1:$port/" "$native" "$size" "$work/column.ply" "$count" "$work/broken.ply" "$work/sweep" "$work/sequence" \
    "$work/volumes"
