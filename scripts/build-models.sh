#!/usr/bin/env bash
# The default models and the bundled source track in www/models/, built from the GRID frames in
# data/grid (CC BY 4.0). They are committed, so the demo needs no native build; this script
# makes them again.
#   scripts/build-models.sh           rebuild www/models/ (after a change to the builder or the
#                                     format; commit the result)
#   scripts/build-models.sh --check   rebuild into a temporary directory and compare byte for
#                                     byte with www/models/ (the test suite runs this)
# What is made:
#   spk07.fmm             the source (spk07, 20 training frames of spk07_pwij3p)
#   spkNN.fmm             every other speaker
#   spk07-track.json      spk07's unseen clip (75 frames) projected into the source
#   manifest.json         what the page loads by default
# Every model is built in the canonical reference frame (src/canonical_frame.txt).
set -euo pipefail
cd "$(dirname "$0")/.."
CHECK=0
[ "${1:-}" = "--check" ] && CHECK=1
bin=${CARGO_TARGET_DIR:-target}/release/facemimic
cargo build --release -p facemimic-cli --bin facemimic -q

if [ "$CHECK" = 1 ]; then
  out=$(mktemp -d "${TMPDIR:-/tmp}/facemimic-models.XXXXXX")
  trap 'rm -rf "$out"' EXIT
else
  out=www/models
  mkdir -p "$out"
fi

source_clip=data/grid/spk07_pwij3p
"$bin" build --name spk07 --out "$out/spk07.fmm" --list "$source_clip/train20.txt"
targets=()
for dir in data/grid/spk*_*; do
  clip=$(basename "$dir")
  spk=${clip%%_*}
  [ "$spk" = spk07 ] && continue
  "$bin" build --name "$spk" --out "$out/$spk.fmm" --list "$dir/train20.txt"
  targets+=("$spk")
done

# The source track: every frame of the unseen clip, projected from its landmarks.
track_clip=data/grid/spk07_id2_vcd_swwp2s
{
  echo '['
  first=1
  for img in "$track_clip"/*.jpg; do
    [ $first = 1 ] || echo ','
    first=0
    "$bin" project --model "$out/spk07.fmm" "$img"
  done
  echo ']'
} > "$out/spk07-track.json.tmp"
mv "$out/spk07-track.json.tmp" "$out/spk07-track.json"

# The manifest (plain shell: no interpreter beyond bash is needed).
json_list() { local sep='' t; printf '['; for t in "$@"; do printf '%s"%s.fmm"' "$sep" "$t"; sep=', '; done; printf ']'; }
default=()
for t in spk02 spk03 spk06 spk10; do
  for have in "${targets[@]}"; do [ "$have" = "$t" ] && default+=("$t"); done
done
cat > "$out/manifest.json" <<JSON
{
  "source": "spk07.fmm",
  "track": {
    "file": "spk07-track.json",
    "fps": 25,
    "description": "GRID speaker 7, clip id2_vcd_swwp2s (unseen), projected from its landmarks"
  },
  "targets": $(json_list "${default[@]}"),
  "library": $(json_list "${targets[@]}"),
  "credits": "GRID audio-visual corpus (Cooke, Barker, Cunningham & Shao, 2006), CC BY 4.0"
}
JSON

if [ "$CHECK" = 1 ]; then
  bad=0
  for f in "$out"/*; do
    name=$(basename "$f")
    if ! cmp -s "$f" "www/models/$name"; then
      echo "build-models: www/models/$name differs from a fresh build" >&2
      bad=1
    fi
  done
  extra=$(comm -13 <(ls "$out") <(ls www/models))
  [ -z "$extra" ] || { echo "build-models: www/models has files no build makes: $extra" >&2; bad=1; }
  if [ "$bad" = 1 ]; then
    echo "build-models: the committed models are stale: run scripts/build-models.sh and commit www/models" >&2
    exit 1
  fi
  echo "build-models: www/models matches a fresh build byte for byte ($(ls "$out" | wc -l) files)" >&2
else
  echo "build-models: $(ls "$out"/*.fmm | wc -l) models and a $(ls "$track_clip"/*.jpg | wc -l)-frame track in $out" >&2
fi
