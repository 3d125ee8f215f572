#!/usr/bin/env bash
# Sets up what is missing and runs every test: native unit + integration tests (numerics, real
# data, model file, CLI, cloning, fitting), the same numerics compiled to wasm under Node, the
# canvas path in headless Chromium (wasm-bindgen-test), and the end-to-end browser tests of the
# page and the npm package (playwright-core + Debian chromium). Safe to run again.
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TERM_COLOR=never
step() { printf '\n==== %s ====\n' "$*"; }

step "set-up"
bash scripts/setup.sh --browser

step "format and lints"
cargo fmt --all -- --check
cargo clippy --workspace --all-targets -q -- -D warnings
cargo clippy -p facemimic-wasm --all-targets --target wasm32-unknown-unknown -q -- -D warnings
RUSTDOCFLAGS=-Dwarnings cargo doc --workspace --exclude facemimic-wasm --no-deps -q
RUSTDOCFLAGS=-Dwarnings cargo doc -p facemimic-wasm --target wasm32-unknown-unknown --no-deps -q

step "native tests"
cargo test --workspace --all-targets

step "build the wasm packages; check the committed default models against a fresh build"
bash scripts/build-wasm.sh
bash scripts/build-faces.sh
bash scripts/build-models.sh --check

step "wasm tests (Node, then headless Chromium)"
cargo test -p facemimic -p facemimic-wasm --target wasm32-unknown-unknown

step "signalling server tests (the call page's WebSocket endpoint, hostile clients)"
node --test --test-concurrency=1 --test-force-exit --test-timeout=600000 tests/server/

step "end-to-end browser tests"
node --test --test-concurrency=1 --test-force-exit --test-timeout=600000 tests/e2e/
