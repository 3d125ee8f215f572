#!/usr/bin/env python3
"""Quantises the convolution weights of MediaPipe's converted nets (`FMW1` files written by
scripts/convert-mediapipe.py, float16 weights) to 8 bits per value, about halving the files.

    python3 scripts/quantise-fmw.py                      # the two shipped nets, see below
    python3 scripts/quantise-fmw.py IN.fmw OUT.fmw [--keep op0,op96]

Without arguments it reads data/weights/blazeface_short.fmw and data/weights/face_mesh.fmw and
writes data/weights/blazeface_short_q8.fmw (filters of layers 77, 81 and 83 kept in float16, see
KEEP) and data/weights/face_mesh_q8.fmw (every filter int8). Python 3 only (no numpy); the output
is a pure function of the input (same bytes on every run and machine).

What changes: the filters of every convolution (`op{k}/w` where row k of the `graph` tensor has
kind 0, layout `[cout, kh, kw, cin]`, channel axis 0) and depthwise convolution (kind 1,
`[1, kh, kw, c]`, channel axis 3) become encoding 3 of `FMW1` (src/find/weights.rs): one float32
scale per output channel, `scale = max |w| / 127` over that channel's values, and int8
`q = round(w / scale)` (ties to even, in -127..127), so `w ~ scale * q` with an error of at most
scale / 2 (0 for an all-zero channel: scale 0). `--keep` (or KEEP below) leaves the listed
layers' filters in float16. Everything else is copied byte for byte: the `graph` and `outputs` tensors (float32,
exact), the biases `op{k}/b` and the PReLU slopes `op{k}/a` (float16: one value per channel, so
a per-channel scale would save nothing).

Encoding 3, after the tensor's `u32` encoding: a `u32` axis, one little-endian `f32` scale per
index along that axis, then the tensor's values as `i8`, row-major; value = scale[index along
the axis] * q.
"""
import os
import struct
import sys


# Layers whose filters stay float16 in the shipped files. BlazeFace: op77 (the last 1x1
# convolution of the 8x8 branch, 96x96) alone moved the 8x8 anchors' boxes by up to 2.7 px of the
# 128-pixel input on the reference frame (0.56 px kept in float16), op81 and op83 (that branch's
# score and box heads) moved the face's score logits by 0.45 (0.13 kept); together 18 KB. The
# mesh: only op96 (the 1404-channel output layer, two thirds of the file) matters on its own
# (half of the points' 0.12 px mean deviation), too large to keep; every other layer's share is
# small, so all are int8. Measured by the tests `int8_*_stays_near_tflite` of
# src/find/reference.rs with one layer kept at a time.
KEEP = {'blazeface_short': ('op77', 'op81', 'op83'), 'face_mesh': ()}


def read(path):
    """The tensors of an FMW1 file: [(name, shape, encoding, raw value bytes)]."""
    b = open(path, 'rb').read()
    if b[:4] != b'FMW1':
        raise SystemExit(f'{path}: not an FMW1 file')
    pos = 4

    def u32():
        nonlocal pos
        v = struct.unpack_from('<I', b, pos)[0]
        pos += 4
        return v

    tensors = []
    for _ in range(u32()):
        n = u32()
        name = b[pos:pos + n].decode()
        pos += n
        shape = [u32() for _ in range(u32())]
        enc = u32()
        count = 1
        for d in shape:
            count *= d
        if enc not in (0, 2):
            raise SystemExit(f'{path}: {name} has encoding {enc}; expected float32 or float16')
        size = count * (4 if enc == 0 else 2)
        tensors.append((name, shape, enc, b[pos:pos + size]))
        pos += size
    if pos != len(b):
        raise SystemExit(f'{path}: trailing bytes')
    return tensors


def f32(x):
    """x rounded to float32."""
    return struct.unpack('<f', struct.pack('<f', x))[0]


def quantise(shape, raw, axis):
    """Encoding 3's body for the float16 values `raw` of `shape`, channels along `axis`."""
    values = struct.unpack(f'<{len(raw) // 2}e', raw)
    channels = shape[axis]
    inner = 1
    for d in shape[axis + 1:]:
        inner *= d
    peak = [0.0] * channels
    for i, v in enumerate(values):
        c = (i // inner) % channels
        peak[c] = max(peak[c], abs(v))
    scales = [f32(p / 127) for p in peak]
    q = bytearray(len(values))
    for i, v in enumerate(values):
        s = scales[(i // inner) % channels]
        k = max(-127, min(127, round(v / s))) if s > 0 else 0
        q[i] = k & 0xFF
    return struct.pack('<I', axis) + struct.pack(f'<{channels}f', *scales) + bytes(q)


def convert(src, dst, keep=()):
    tensors = read(src)
    graph = next(t for t in tensors if t[0] == 'graph')
    rows = struct.unpack(f'<{len(graph[3]) // 4}f', graph[3])
    kind = {k: int(rows[k * 8]) for k in range(graph[1][0])}
    out = [b'FMW1', struct.pack('<I', len(tensors))]
    quantised = 0
    for name, shape, enc, raw in tensors:
        nb = name.encode()
        out += [struct.pack('<I', len(nb)), nb, struct.pack('<I', len(shape)),
                struct.pack(f'<{len(shape)}I', *shape)]
        layer, _, part = name.partition('/')
        k = int(layer[2:]) if layer.startswith('op') else None
        if part == 'w' and enc == 2 and layer not in keep and kind.get(k) in (0, 1):
            axis = 0 if kind[k] == 0 else 3
            out += [struct.pack('<I', 3), quantise(shape, raw, axis)]
            quantised += 1
        else:
            out += [struct.pack('<I', enc), raw]
    data = b''.join(out)
    open(dst, 'wb').write(data)
    print(f'{dst}: {len(data)} bytes ({quantised} filters int8, from {os.path.getsize(src)})')


def main():
    args = sys.argv[1:]
    keep = None
    if '--keep' in args:
        i = args.index('--keep')
        keep = tuple(args[i + 1].split(','))
        del args[i:i + 2]
    if args:
        if len(args) != 2:
            raise SystemExit(__doc__)
        convert(args[0], args[1], keep or ())
        return
    d = os.path.relpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', 'data',
                                     'weights'))
    for name in ('blazeface_short', 'face_mesh'):
        convert(os.path.join(d, f'{name}.fmw'), os.path.join(d, f'{name}_q8.fmw'),
                KEEP[name] if keep is None else keep)


if __name__ == '__main__':
    main()
