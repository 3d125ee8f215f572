#!/usr/bin/env bash
# Idempotent machine set-up for facemimic: everything the demo and the tests need.
# Usage: scripts/setup.sh [--browser] [--no-bindgen]
#   --browser     also installs Debian chromium + npm test deps
#   --no-bindgen  skips wasm-bindgen-cli (scripts/demo.sh installs it beside the wasm build)
set -euo pipefail
cd "$(dirname "$0")/.."

WASM_BINDGEN_VERSION=$(grep -A1 '^name = "wasm-bindgen"$' Cargo.lock 2>/dev/null | sed -n 's/^version = "\(.*\)"/\1/p' | head -1 || true)
WASM_BINDGEN_VERSION=${WASM_BINDGEN_VERSION:-0.2.130}

log() { echo "setup: $*" >&2; }
BROWSER=0
BINDGEN=1
for arg in "$@"; do
  case "$arg" in
    --browser) BROWSER=1 ;;
    --no-bindgen) BINDGEN=0 ;;
    *) log "unknown option $arg"; exit 2 ;;
  esac
done

if ! rustup target list --installed | grep -q '^wasm32-unknown-unknown$'; then
  log "adding the wasm32-unknown-unknown target"
  rustup target add wasm32-unknown-unknown
fi

if [ "$BINDGEN" = 1 ] && { ! command -v wasm-bindgen >/dev/null 2>&1 || [ "$(wasm-bindgen --version | awk '{print $2}')" != "$WASM_BINDGEN_VERSION" ]; }; then
  log "installing wasm-bindgen-cli $WASM_BINDGEN_VERSION (a few minutes, once)"
  # Built at opt-level 1: it makes the same bytes (compared on our package) in the same time
  # (0.4 s a build), and compiles in 3.7 min instead of about 10 on 2 cores.
  CARGO_PROFILE_RELEASE_OPT_LEVEL=1 CARGO_PROFILE_RELEASE_DEBUG=false \
    cargo install wasm-bindgen-cli --version "=$WASM_BINDGEN_VERSION" --force
fi

if [ "$BROWSER" = 1 ]; then
  if ! command -v chromium >/dev/null 2>&1 || ! command -v chromedriver >/dev/null 2>&1; then
    log "installing Debian chromium and chromium-driver"
    # apt-get needs root: use sudo when not root (it asks for a password if it must).
    sudo=()
    if [ "$(id -u)" != 0 ]; then
      command -v sudo >/dev/null 2>&1 || { log "error: installing chromium needs root or sudo"; exit 1; }
      sudo=(sudo)
    fi
    "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get update -qq
    "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium chromium-driver >/dev/null
  fi
fi

if [ -f package.json ] && { [ ! -d node_modules ] || [ package.json -nt node_modules/.facemimic-stamp ]; }; then
  log "installing npm packages"
  npm install --no-audit --no-fund --loglevel=error
  touch node_modules/.facemimic-stamp
fi
