#!/usr/bin/env bash
# Builds the web app (scripts/web-build.sh) and serves it on http://127.0.0.1:PORT/ (default
# 8080) until interrupted. Open it in a browser with WebGPU (recent Chrome, Edge, Safari; Firefox
# with WebGPU enabled). Needs python3 for the server.
#
#   scripts/web-serve.sh [PORT]
set -euo pipefail
cd "$(dirname "$0")/.."
port=${1:-8080}
scripts/web-build.sh target/web/site
echo "serving smokeshadow at http://127.0.0.1:$port/ (Ctrl-C stops it)"
exec python3 -m http.server "$port" --bind 127.0.0.1 --directory target/web/site
