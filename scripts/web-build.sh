#!/usr/bin/env bash
# Builds smokeshadow's web app into a static folder ready to host as it is (default
# target/web/site): the core and web/ compiled for wasm32-unknown-unknown, bound to JavaScript by
# wasm-bindgen, and the page (web/static/). What it needs, installed here when missing: the
# wasm32-unknown-unknown target (rustup) and wasm-bindgen-cli at the version Cargo.lock pins for
# the wasm-bindgen crate (cargo install, a few minutes once).
#
#   scripts/web-build.sh [OUT_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-target/web/site}

if ! rustup target list --installed 2>/dev/null | grep -qx wasm32-unknown-unknown; then
    echo "installing the wasm32-unknown-unknown target (rustup)"
    rustup target add wasm32-unknown-unknown
fi
pinned=$(awk '/^name = "wasm-bindgen"$/ { getline; gsub(/version = |"/, ""); print; exit }' Cargo.lock)
if [[ -z $pinned ]]; then
    echo "error: Cargo.lock pins no wasm-bindgen version" >&2
    exit 2
fi
if [[ $(wasm-bindgen --version 2>/dev/null) != "wasm-bindgen $pinned" ]]; then
    echo "installing wasm-bindgen-cli $pinned (the version Cargo.lock pins; cargo install, once)"
    cargo install wasm-bindgen-cli --version "$pinned"
fi

cargo build -p smokeshadow-web --target wasm32-unknown-unknown --release
mkdir -p "$(dirname "$out")"
staging=$(mktemp -d "$(dirname "$out")/.site.XXXXXX")
chmod 755 "$staging" # (mktemp makes it private; a web server must read it)
trap 'rm -rf "$staging"' EXIT
wasm-bindgen --target web --no-typescript --out-dir "$staging/pkg" \
    target/wasm32-unknown-unknown/release/smokeshadow_web.wasm
cp web/static/* "$staging/"
rm -rf "$out"
mv "$staging" "$out"
trap - EXIT

wasm=$out/pkg/smokeshadow_web_bg.wasm
echo "wrote $out: the page and its module, $(stat -c %s "$wasm") bytes of wasm, $(gzip -9 -c "$wasm" | wc -c) gzipped"
