#!/usr/bin/env python3
"""How the independent judge (fer_judge.py) reads REAL smiles, by skin tone.

facemimic's judge figure (the targets' "happy" over the source's) is read on targets of every
skin tone; this script asks what the judge itself gives real people's real smiles. It scores
each London person's own smiling photo (`../shared/data/london`, 60 people, research data
never committed), measures the person's skin luminance on the neutral photo (two cheek patches
between the jaw and the nose, 0.16 of the outer eye corners' distance square, Rec. 601 luma of
sRGB in 0..1) and the smile's size from the dlib landmarks (mouth width change and the inner
lips' opening, both over the outer eye corners' distance), and prints the judge's mean "happy"
per third of the people by skin luminance, the same over the open-mouthed smiles, and a
least-squares fit of "happy" on skin luminance, width change and opening.

Usage (the judge's venv, see scripts/eval/README.md):
    PY=$(bash scripts/eval/setup-fer.sh | tail -1)
    $PY scripts/eval/judge_skin.py [--data ../shared/data] [--work /tmp/judge-skin]
"""
import argparse
import csv
import os
import subprocess
import sys

import numpy as np
from PIL import Image

HERE = os.path.dirname(os.path.abspath(__file__))
# An open-mouthed smile: the inner lips at least this far apart (outer eye corners' distances).
OPEN = 0.06


def points(path):
    """The 68 (x, y) points of a .pts file."""
    text = open(path).read()
    values = [float(v) for v in text.split("{")[1].split("}")[0].split()]
    return np.array(values).reshape(68, 2)


def iod(p):
    return np.linalg.norm(p[45] - p[36])


def width(p):
    return np.linalg.norm(p[54] - p[48]) / iod(p)


def opening(p):
    return np.mean([np.linalg.norm(p[u] - p[l]) for u, l in ((61, 67), (62, 66), (63, 65))]) / iod(p)


def skin_luma(image, p):
    """Mean luma of two cheek patches of the neutral photo."""
    rgb = np.asarray(Image.open(image).convert("RGB"), dtype=float) / 255.0
    r = max(1, int(0.08 * iod(p)))
    lumas = []
    for a, b in ((2, 31), (14, 35)):
        cx, cy = ((p[a] + p[b]) / 2).astype(int)
        patch = rgb[cy - r : cy + r, cx - r : cx + r]
        lumas.append(float((patch @ [0.299, 0.587, 0.114]).mean()))
    return float(np.mean(lumas))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", default=os.path.join(HERE, "..", "..", "..", "shared", "data"))
    ap.add_argument("--work", default="/tmp/judge-skin")
    a = ap.parse_args()
    london = os.path.abspath(os.path.join(a.data, "london"))
    ids = sorted(f[:-4] for f in os.listdir(os.path.join(london, "smiling")) if f.endswith(".jpg"))
    os.makedirs(a.work, exist_ok=True)
    manifest = os.path.join(a.work, "manifest.csv")
    with open(manifest, "w") as f:
        f.write("id,source,target\n")
        for i in ids:
            f.write(f"{i},{london}/neutral/{i}.jpg,{london}/smiling/{i}.jpg\n")
    scores = os.path.join(a.work, "scores.csv")
    subprocess.run(
        [sys.executable, os.path.join(HERE, "fer_judge.py"), manifest, "--out", scores],
        check=False,
        stderr=subprocess.DEVNULL,
    )
    rows = []
    for r in csv.DictReader(open(scores)):
        if r["error"] or not r["target_happy"]:
            print(f"{r['id']}: not scored ({r['error']})")
            continue
        n = points(f"{london}/neutral/{r['id']}.pts")
        s = points(f"{london}/smiling/{r['id']}.pts")
        skin = skin_luma(f"{london}/neutral/{r['id']}.jpg", n)
        rows.append((skin, width(s) - width(n), opening(s), float(r["target_happy"])))
    rows.sort()
    print(f"{len(rows)} of {len(ids)} people's real smiles scored")
    third = len(rows) // 3
    parts = (("darkest", rows[:third]), ("middle", rows[third : 2 * third]), ("lightest", rows[2 * third :]))
    for name, part in parts:
        v = np.array(part)
        opened = v[v[:, 2] >= OPEN]
        print(
            f"{name} third: skin luma {v[0, 0]:.2f}-{v[-1, 0]:.2f}, width change {v[:, 1].mean():.3f}, "
            f"opening {v[:, 2].mean():.3f}; the judge's happy on the real smile {v[:, 3].mean():.2f} "
            f"({len(opened)} open-mouthed: {opened[:, 3].mean() if len(opened) else float('nan'):.2f})"
        )
    v = np.array(rows)
    x = np.column_stack([np.ones(len(v)), v[:, 0], v[:, 1], v[:, 2]])
    b = np.linalg.lstsq(x, v[:, 3], rcond=None)[0]
    print(f"happy ~ {b[0]:+.2f} {b[1]:+.2f} skin luma {b[2]:+.2f} width change {b[3]:+.2f} opening (least squares)")


if __name__ == "__main__":
    main()
