#!/usr/bin/env python3
"""Markdown tables of fer_judge.py scores, grouped by what the harnesses' ids encode.

Standard library only (any python3). Two layouts, chosen by --layout:

- franck: the dump of examples/expression_eval.rs (--dump-dir). Ids are
  `<clip>-<frame>-<target>-<method>`; the dump's frames.csv says which frames are "laughing"
  (top 10% of source mouth width + lift) and which "random". One table per group, rows per
  method and target, and each method over all targets.
- london: the dump of examples/london_eval.rs (--dump-dir). Ids are `<X>_<Y>_<kind>`, kind a
  method or Y's own photos `neutral` / `smiling` (references: Y's real neutral and smile).

Columns: rows scored; mean source happy; mean target happy; their ratio (mean target / mean
source, the headline); over the rows whose source happy >= --threshold (0.5): their count, the
median and the mean of target / source, and the share with ratio >= --ratio-min (0.8).

    python3 scripts/eval/fer_tables.py --layout franck DIR/scores.csv --frames DIR/frames.csv
    python3 scripts/eval/fer_tables.py --layout london DIR/scores.csv
"""
import argparse
import csv
import re
import statistics
import sys

LAYOUTS = {
    "franck": re.compile(r"^(?P<clip>.+)-(?P<frame>\d{6})-(?P<target>[^-]+)-(?P<method>.+)$"),
    "london": re.compile(r"^(?P<x>\d+)_(?P<y>\d+)_(?P<method>.+)$"),
}


def read_scores(path, pattern):
    rows = []
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            if r.get("error"):
                continue
            m = pattern.match(r["id"])
            if not m:
                raise SystemExit(f"{path}: id {r['id']!r} does not fit the layout")
            item = m.groupdict()
            item["s"] = float(r["source_happy"])
            item["t"] = float(r["target_happy"])
            rows.append(item)
    return rows


def summary(rows, threshold, ratio_min):
    s = [r["s"] for r in rows]
    t = [r["t"] for r in rows]
    sel = [r["t"] / r["s"] for r in rows if r["s"] >= threshold]
    ms, mt = statistics.fmean(s), statistics.fmean(t)
    return [
        f"{len(rows)}",
        f"{ms:.3f}",
        f"{mt:.3f}",
        f"**{mt / ms:.2f}**" if ms > 0 else "",
        f"{len(sel)}",
        f"{statistics.median(sel):.2f}" if sel else "",
        f"{statistics.fmean(sel):.2f}" if sel else "",
        f"{sum(x >= ratio_min for x in sel) / len(sel):.0%}" if sel else "",
    ]


def table(title, groups, args):
    head = ["", "rows", "source happy", "target happy", "mean t / mean s",
            f"rows s >= {args.threshold}", "median t/s", "mean t/s",
            f"t/s >= {args.ratio_min}"]
    print(f"\n### {title}\n")
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for name, rows in groups:
        if rows:
            print("| " + " | ".join([name] + summary(rows, args.threshold, args.ratio_min)) + " |")


def ordered(values):
    seen = []
    for v in values:
        if v not in seen:
            seen.append(v)
    return seen


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scores", help="fer_judge.py's output CSV")
    ap.add_argument("--layout", choices=sorted(LAYOUTS), required=True)
    ap.add_argument("--frames", help="franck: the dump's frames.csv (the groups)")
    ap.add_argument("--threshold", type=float, default=0.5)
    ap.add_argument("--ratio-min", type=float, default=0.8)
    args = ap.parse_args(argv)
    rows = read_scores(args.scores, LAYOUTS[args.layout])
    methods = ordered(r["method"] for r in rows)
    if args.layout == "london":
        table("London pairs: X's smile (source) -> Y", [(m, [r for r in rows if r["method"] == m])
                                                         for m in methods], args)
        return 0
    if not args.frames:
        ap.error("--layout franck needs --frames")
    group = {}
    with open(args.frames, newline="") as f:
        for r in csv.DictReader(f):
            group[(r["clip"], r["frame"])] = r["group"]
    for r in rows:
        r["group"] = group.get((r["clip"], r["frame"]), "?")
    targets = ordered(r["target"] for r in rows)
    for g in ordered(r["group"] for r in rows):
        in_g = [r for r in rows if r["group"] == g]
        frames = len({(r["clip"], r["frame"]) for r in in_g})
        groups = []
        for m in methods:
            for t in targets:
                groups.append((f"{m} {t}", [r for r in in_g if r["method"] == m and r["target"] == t]))
            groups.append((f"**{m} all**", [r for r in in_g if r["method"] == m]))
        table(f"{g} frames ({frames} source frames)", groups, args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
