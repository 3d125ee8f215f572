#!/usr/bin/env bash
# Builds the npm package `facemimic` into pkg/ and copies it to www/pkg/ for the demo page.
#
#   scripts/build-wasm.sh [--force | --check-only]
#
# Steps: cargo (crates/wasm, wasm32, release, simd128 from .cargo/config.toml) -> wasm-bindgen --target web
# -> wasm-opt -O3 (npm `binaryen`, never Debian's) -> package.json / README / licences from npm/
# (and the face finder weights' licence from data/weights/).
# Idempotent: does nothing when pkg/ and www/pkg/ are newer than every input.
# Environment: CARGO_TARGET_DIR (default target/), FACEMIMIC_NO_OPT=1 skips wasm-opt.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)

log() { echo "build-wasm: $*" >&2; }
die() { echo "build-wasm: error: $*" >&2; exit 1; }

FORCE=0
CHECK_ONLY=0
[ "${1:-}" = "--force" ] && FORCE=1
# --check-only: exit 0 when pkg/ is up to date, 1 when a build is due (builds nothing).
[ "${1:-}" = "--check-only" ] && CHECK_ONLY=1

TARGET_DIR=${CARGO_TARGET_DIR:-$ROOT/target}
RAW="$TARGET_DIR/wasm32-unknown-unknown/release/facemimic_wasm.wasm"
PKG="$ROOT/pkg"
WWW_PKG="$ROOT/www/pkg"
STAMP="$PKG/.build-stamp"

# Inputs: Rust sources, embedded weights, manifests, the package template and this script.
newest_input() {
  find src crates/wasm data/weights Cargo.toml Cargo.lock .cargo npm scripts/build-wasm.sh -type f -newer "$1" -print -quit 2>/dev/null
}

if [ "$FORCE" = 0 ] && [ -f "$STAMP" ] && [ -f "$WWW_PKG/facemimic_bg.wasm" ] && [ -z "$(newest_input "$STAMP")" ]; then
  log "pkg/ is up to date"
  exit 0
fi
[ "$CHECK_ONLY" = 1 ] && exit 1

command -v cargo >/dev/null || die "cargo not found"
rustup target list --installed 2>/dev/null | grep -q '^wasm32-unknown-unknown$' \
  || die "the wasm32-unknown-unknown target is missing: run scripts/setup.sh"
WANT_BINDGEN=$(grep -A1 '^name = "wasm-bindgen"$' Cargo.lock | sed -n 's/^version = "\(.*\)"/\1/p' | head -1)
command -v wasm-bindgen >/dev/null || die "wasm-bindgen not found: run scripts/setup.sh"
HAVE_BINDGEN=$(wasm-bindgen --version | awk '{print $2}')
[ "$HAVE_BINDGEN" = "$WANT_BINDGEN" ] \
  || die "wasm-bindgen $HAVE_BINDGEN on PATH, Cargo.lock wants $WANT_BINDGEN: run scripts/setup.sh"
WASM_OPT="$ROOT/node_modules/.bin/wasm-opt"
if [ "${FACEMIMIC_NO_OPT:-0}" != 1 ] && [ ! -x "$WASM_OPT" ]; then
  die "node_modules/.bin/wasm-opt missing (npm package binaryen): run scripts/setup.sh"
fi

log "cargo build -p facemimic-wasm --lib --release --target wasm32-unknown-unknown"
cargo build -p facemimic-wasm --lib --release --target wasm32-unknown-unknown

mkdir -p "$PKG"
TMP=$(mktemp -d "${TMPDIR:-/tmp}/facemimic-pkg.XXXXXX")
trap 'rm -rf "$TMP"' EXIT
log "wasm-bindgen --target web"
wasm-bindgen --target web --out-dir "$TMP" --out-name facemimic "$RAW"

if [ "${FACEMIMIC_NO_OPT:-0}" != 1 ]; then
  log "wasm-opt -O3"
  "$WASM_OPT" -O3 --enable-simd --enable-bulk-memory --enable-nontrapping-float-to-int \
    --enable-sign-ext --enable-mutable-globals --enable-reference-types --enable-multivalue \
    "$TMP/facemimic_bg.wasm" -o "$TMP/facemimic_bg.opt.wasm"
  mv "$TMP/facemimic_bg.opt.wasm" "$TMP/facemimic_bg.wasm"
fi

# The package: generated glue + the template, version taken from Cargo.toml.
VERSION=$(sed -n 's/^version = "\(.*\)"/\1/p' Cargo.toml | head -1)
REPOSITORY=$(sed -n 's/^repository = "\(.*\)"/\1/p' Cargo.toml | head -1)
# The generated glue is facemimic_wasm.js; the entry facemimic.js (npm/, by hand) wraps it.
# Its declarations lose `[Symbol.dispose]()` (the JS keeps it where the runtime has
# Symbol.dispose): under `lib: ES2022` without skipLibCheck, tsc rejects the symbol.
rm -f "$PKG"/facemimic* "$PKG"/package.json "$PKG"/README.md "$PKG"/LICENSE*
cp "$TMP"/facemimic.js "$PKG"/facemimic_wasm.js
# The entry's frame overload of the static Model.fromPhoto goes beside the generated one.
grep -v '^\s*\[Symbol\.dispose\](): void;$' "$TMP"/facemimic.d.ts \
  | sed 's|^\(\s*\)static fromPhoto(|\1static fromPhoto(name: string, frame: import("./facemimic.js").FrameSource, landmarks: Float32Array \| number[]): Model;\n\1static fromPhoto(|' \
  >"$PKG"/facemimic_wasm.d.ts
grep -q 'frame: import("./facemimic.js").FrameSource' "$PKG"/facemimic_wasm.d.ts \
  || die "the generated declarations have no 'static fromPhoto(': update the overload above"
cp "$TMP"/facemimic_bg.wasm "$TMP"/facemimic_bg.wasm.d.ts "$PKG"/
cp npm/facemimic.js npm/facemimic.d.ts npm/README.md npm/LICENSE-MIT npm/LICENSE-APACHE "$PKG"/
# The face finder's weights are embedded in the wasm: their MIT licence and credit ship with it.
cp data/weights/LICENSE-mediapipe "$PKG"/
node -e '
  const fs = require("fs");
  const p = JSON.parse(fs.readFileSync(process.argv[1], "utf8"));
  p.version = process.argv[2];
  // The repository is named once, in Cargo.toml ([workspace.package] repository).
  const fill = (s) => s.replace("REPOSITORY", process.argv[4]);
  p.repository.url = "git+" + fill(p.repository.url) + ".git";
  p.homepage = fill(p.homepage);
  p.bugs.url = fill(p.bugs.url);
  fs.writeFileSync(process.argv[3], JSON.stringify(p, null, 2) + "\n");
' npm/package.json "$VERSION" "$PKG/package.json" "$REPOSITORY"

rm -rf "$WWW_PKG"
mkdir -p "$WWW_PKG"
cp "$PKG"/facemimic.js "$PKG"/facemimic.d.ts "$PKG"/facemimic_wasm.js "$PKG"/facemimic_wasm.d.ts \
  "$PKG"/facemimic_bg.wasm "$PKG"/package.json "$WWW_PKG"/
touch "$STAMP"
SIZE=$(wc -c <"$PKG/facemimic_bg.wasm")
GZ=$(gzip -9c "$PKG/facemimic_bg.wasm" | wc -c)
log "pkg/ ready: facemimic $VERSION, wasm $SIZE bytes ($GZ gzipped); copied to www/pkg/"
