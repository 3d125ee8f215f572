#!/usr/bin/env bash
# Sets up what is missing, builds the wasm package and the default models, and serves the demo
# on 127.0.0.1:${PORT:-8080} until stopped (`--lan`: on every interface, for a call between two
# machines of a LAN; docs/call.md). Safe to run again: finished steps are skipped.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
bash scripts/build-wasm.sh
bash scripts/build-models.sh
exec node scripts/serve.mjs "$@" www
