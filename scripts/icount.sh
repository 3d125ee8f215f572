#!/usr/bin/env bash
# Speed of two commits compared by instruction counts (valgrind's callgrind counts the
# instructions a run executes, so the figure does not move with the machine's load, unlike a
# timing on a shared 2-core machine).
#
#   scripts/icount.sh BEFORE [AFTER] [WORK...]
#
# BEFORE, AFTER: commits (AFTER defaults to the working tree). WORK: clone render scanline track find
# (default all). Each commit is checked out in a temporary worktree with this checkout's
# examples/icount.rs (so an older commit is measured by the same program), built in release with
# the same profile, and run under callgrind with 0 and N iterations; the figure is
# (instructions at N - at 0) / N, i.e. per clone_frame / render / tracked frame / find.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)
command -v valgrind >/dev/null || { echo "icount: needs valgrind (apt-get install valgrind)" >&2; exit 2; }
[ $# -ge 1 ] || { sed -n 2,12p "$0" >&2; exit 2; }
BEFORE=$1; shift
AFTER=WORKTREE
if [ $# -ge 1 ] && git rev-parse --verify -q "$1^{commit}" >/dev/null; then AFTER=$1; shift; fi
WORK=("$@"); [ ${#WORK[@]} -gt 0 ] || WORK=(clone render scanline track find)
declare -A N=([clone]=20 [render]=20 [scanline]=20 [track]=30 [find]=3)

TMP=$(mktemp -d /tmp/icount.XXXXXX)
cleanup() { for d in "$TMP"/wt-*; do [ -d "$d" ] && git worktree remove --force "$d" >/dev/null 2>&1 || true; done; rm -rf "$TMP"; }
trap cleanup EXIT

# The example built at `rev` (WORKTREE: this checkout); prints the binary's path.
build() {
  local rev=$1 dir
  if [ "$rev" = WORKTREE ]; then dir=$ROOT; else
    dir=$TMP/wt-$rev
    git worktree add -q --detach "$dir" "$rev"
    cp examples/icount.rs "$dir/examples/icount.rs"
  fi
  if ! (cd "$dir" && CARGO_TARGET_DIR=${ICOUNT_TARGET_DIR:-$ROOT/target/icount} cargo build -q --release --example icount >&2); then
    # An API renamed since `rev`: measure it with its own copy of the program (the same work).
    [ "$rev" != WORKTREE ] || exit 1
    echo "icount: this checkout's examples/icount.rs does not build at $rev; using $rev's own" >&2
    git -C "$dir" checkout -q -- examples/icount.rs
    (cd "$dir" && CARGO_TARGET_DIR=${ICOUNT_TARGET_DIR:-$ROOT/target/icount} cargo build -q --release --example icount >&2)
  fi
  local bin=$TMP/icount-$rev
  cp "${ICOUNT_TARGET_DIR:-$ROOT/target/icount}/release/examples/icount" "$bin"
  echo "$bin"
}

# Instructions executed by `bin work n`.
count() {
  local out
  out=$(cd "$ROOT" && valgrind --tool=callgrind --callgrind-out-file=/dev/null "$1" "$2" "$3" 2>&1 >/dev/null)
  echo "$out" | sed -n 's/.*Collected : \([0-9]*\).*/\1/p' | tail -1
}

B=$(build "$BEFORE")
A=$(build "$AFTER")
printf '%-8s %16s %16s %9s\n' work "before Ir/iter" "after Ir/iter" change
for w in "${WORK[@]}"; do
  n=${N[$w]:?unknown work $w}
  b=$(( ($(count "$B" "$w" "$n") - $(count "$B" "$w" 0)) / n ))
  a=$(( ($(count "$A" "$w" "$n") - $(count "$A" "$w" 0)) / n ))
  printf '%-8s %16d %16d %+8.3f%%\n' "$w" "$b" "$a" "$(echo "($a - $b) * 100 / $b" | bc -l)"
done
