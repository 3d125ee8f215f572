#!/usr/bin/env python3
"""Reference outputs of MediaPipe's two nets, layer by layer, from the TFLite interpreter, for
the Rust test in src/find/reference.rs (`mesh_nets_match_tflite_layer_by_layer`).

How to run (the venv of scripts/convert-mediapipe.py, plus the interpreter and Pillow):

    /work/venv-mp/bin/pip install ai-edge-litert pillow tflite numpy
    /work/venv-mp/bin/python scripts/mediapipe-reference.py /tmp/mp/mediapipe/modules

Inputs (written as raw RGB8 beside the outputs, in tests/data/finder/): the committed GRID frame
`spk01_bbaf2n/000004` letterboxed (centred on black) into 128x128 for the detector, and the faces
of `spk01_bbaf2n/000004` and `spk05_lrwp9a/000008` (the square 1.5 times the longer side of the
dlib landmarks' box, about their centre) resized to 192x192 for the mesh. Pillow makes these
bytes; both runtimes read the same bytes, so the resampling does not matter.

Outputs (`mp-*.json`): per layer of the converted graph (in its order), the output's shape, mean,
largest magnitude and 16 values at fixed positions; and the nets' final outputs: the detector's
896 score logits and the 16 regression values of every anchor scoring above 0.5, the mesh's
1404 values and its face logit. The interpreter runs without delegates (TFLite's own float
kernels) and keeps every intermediate tensor.
"""
import json
import os
import sys

import numpy as np
from ai_edge_litert.interpreter import Interpreter, OpResolverType
from PIL import Image

sys.path.insert(0, os.path.dirname(__file__))
convert = __import__('convert-mediapipe')

ROOT = os.path.join(os.path.dirname(__file__), '..')
OUT = os.path.join(ROOT, 'tests', 'data', 'finder')


def pts(path):
    lines = open(path).read().split('{')[1].split('}')[0].split()
    return np.array(lines, float).reshape(-1, 2) - 1.0


def detector_input(frame):
    im = Image.open(os.path.join(ROOT, 'data', 'grid', frame + '.jpg')).convert('RGB')
    w, h = im.size
    s = 128 / max(w, h)
    small = im.resize((round(w * s), round(h * s)), Image.BILINEAR)
    canvas = Image.new('RGB', (128, 128))
    canvas.paste(small, ((128 - small.size[0]) // 2, (128 - small.size[1]) // 2))
    return np.asarray(canvas, np.uint8)


def mesh_input(frame):
    im = Image.open(os.path.join(ROOT, 'data', 'grid', frame + '.jpg')).convert('RGB')
    p = pts(os.path.join(ROOT, 'data', 'grid', frame + '.pts'))
    lo, hi = p.min(0), p.max(0)
    c, side = (lo + hi) / 2, 1.5 * (hi - lo).max()
    box = tuple(int(round(v)) for v in (c[0] - side / 2, c[1] - side / 2, c[0] + side / 2,
                                         c[1] + side / 2))
    return np.asarray(im.crop(box).resize((192, 192), Image.BILINEAR), np.uint8)


def layers(model, x):
    it = Interpreter(model_path=model, experimental_preserve_all_tensors=True,
                     experimental_op_resolver_type=OpResolverType.BUILTIN_WITHOUT_DEFAULT_DELEGATES)
    it.allocate_tensors()
    it.set_tensor(it.get_input_details()[0]['index'], x[None].astype(np.float32))
    it.invoke()
    _, _, _, slots = convert.graph_of(model)
    by_slot = {s: t for t, s in slots.items()}
    out = []
    for k in range(1, len(slots)):
        v = it.get_tensor(by_slot[k]).astype(np.float64)
        flat = v.reshape(-1)
        n = flat.size
        idx = [(i * n) // 16 + (n // 32) for i in range(16)]
        out.append({'shape': list(v.shape[1:]), 'mean': float(flat.mean()),
                    'max_abs': float(np.abs(flat).max()), 'index': idx,
                    'values': [float(flat[i]) for i in idx]})
    finals = [it.get_tensor(d['index']) for d in it.get_output_details()]
    return out, finals


def main():
    if len(sys.argv) < 2:
        raise SystemExit(__doc__)
    modules = sys.argv[1]
    det = os.path.join(modules, 'face_detection', 'face_detection_short_range.tflite')
    mesh = os.path.join(modules, 'face_landmark', 'face_landmark.tflite')
    x = detector_input('spk01_bbaf2n/000004')
    x.tofile(os.path.join(OUT, 'mp-detector-128.rgb'))
    per_layer, (reg, cls) = layers(det, x / 127.5 - 1.0)
    cls = cls.reshape(-1)
    reg = reg.reshape(-1, 16)
    keep = [int(i) for i in np.nonzero(1 / (1 + np.exp(-cls)) > 0.5)[0]]
    json.dump({'layers': per_layer, 'scores': cls.tolist(),
               'regressions': {str(i): reg[i].tolist() for i in keep}},
              open(os.path.join(OUT, 'mp-detector-128.json'), 'w'))
    print('detector: anchors above 0.5:', keep)
    for name, frame in [('a', 'spk01_bbaf2n/000004'), ('b', 'spk05_lrwp9a/000008')]:
        x = mesh_input(frame)
        x.tofile(os.path.join(OUT, f'mp-mesh-{name}-192.rgb'))
        per_layer, (lm, flag) = layers(mesh, x / 255.0)
        json.dump({'layers': per_layer, 'landmarks': lm.reshape(-1).tolist(),
                   'face': float(flag.reshape(-1)[0])},
                  open(os.path.join(OUT, f'mp-mesh-{name}-192.json'), 'w'))
        print(f'mesh {name}: face logit {float(flag.reshape(-1)[0]):.3f}')


if __name__ == '__main__':
    main()
