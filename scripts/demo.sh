#!/usr/bin/env bash
# Sets up what is missing, builds the wasm package, and serves the demo on
# 127.0.0.1:${PORT:-8080} until stopped (`--lan`: on every interface, for a call between two
# machines of a LAN; docs/call.md). The default models are committed in www/models (GRID,
# CC BY 4.0; scripts/build-models.sh makes them again), so no native build is needed. Safe to
# run again: finished steps are skipped.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh --no-bindgen
# On a first run wasm-bindgen-cli is compiled beside the wasm crate: the two builds share the
# cores, and each one's single-threaded stretches (the LTO link) leave room for the other.
bash scripts/setup.sh &
setup_pid=$!
if ! bash scripts/build-wasm.sh --check-only 2>/dev/null; then
  cargo build -p facemimic-wasm --lib --release --target wasm32-unknown-unknown
fi
wait "$setup_pid"
bash scripts/build-wasm.sh
exec node scripts/serve.mjs "$@" www
