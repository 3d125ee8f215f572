#!/usr/bin/env bash
# Builds the companion npm package `facemimic-faces` into pkg-faces/: the default models that
# are committed in www/models (GRID, CC BY 4.0; scripts/build-models.sh regenerates and checks
# them), the source track, the template in npm/faces/ and the GRID notice. Quick (copies);
# idempotent.
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=pkg-faces
VERSION=$(sed -n 's/^version = "\(.*\)"/\1/p' Cargo.toml | head -1)
REPOSITORY=$(sed -n 's/^repository = "\(.*\)"/\1/p' Cargo.toml | head -1)
rm -rf "$OUT"
mkdir -p "$OUT"
for f in spk07 spk02 spk03 spk06 spk10; do
  cp "www/models/$f.fmm" "$OUT/"
done
cp www/models/spk07-track.json npm/faces/index.js npm/faces/index.d.ts npm/faces/README.md \
  data/NOTICE-GRID.md "$OUT/"
node -e '
  const fs = require("fs");
  const [template, version, repository, out] = process.argv.slice(1);
  const p = JSON.parse(fs.readFileSync(template, "utf8"));
  p.version = version;
  p.peerDependencies.facemimic = version;
  p.repository.url = "git+" + repository + ".git";
  p.homepage = repository + "#readme";
  fs.writeFileSync(out, JSON.stringify(p, null, 2) + "\n");
' npm/faces/package.json "$VERSION" "$REPOSITORY" "$OUT/package.json"
echo "build-faces: $OUT/ ready: facemimic-faces $VERSION, $(du -sk "$OUT" | cut -f1) KB" >&2
