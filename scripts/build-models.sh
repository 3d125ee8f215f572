#!/usr/bin/env bash
# Builds the default models and the bundled source track into www/models/ from the GRID frames
# in data/grid (CC BY 4.0). Idempotent: does nothing when the outputs are newer than the inputs.
#   www/models/spk07.fmm             the source (spk07, 20 training frames of spk07_pwij3p)
#   www/models/spkNN.fmm             every other speaker
# Every model is built in the canonical reference frame (src/canonical_frame.txt).
#   www/models/spk07-track.json      spk07's unseen clip (75 frames) projected into the source
#   www/models/manifest.json         what the page loads by default
set -euo pipefail
cd "$(dirname "$0")/.."
out=www/models
bin=${CARGO_TARGET_DIR:-target}/release/facemimic
mkdir -p "$out"

cargo build --release -p facemimic-cli --bin facemimic -q

stamp="$out/.stamp"
if [ -f "$stamp" ] && [ -z "$(find data/grid src/canonical_frame.txt "$bin" -newer "$stamp" -print -quit)" ]; then
  echo "build-models: up to date" >&2
  exit 0
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
cat > "$out/manifest.json" <<EOF
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
EOF
touch "$stamp"
echo "build-models: $(ls "$out"/*.fmm | wc -l) models and a $(ls "$track_clip"/*.jpg | wc -l)-frame track in $out" >&2
