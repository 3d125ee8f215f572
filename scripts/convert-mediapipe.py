#!/usr/bin/env python3
"""Converts MediaPipe's face detector (BlazeFace, short range) and face mesh (468 points) from
their TFLite files into the crate's weight format (`FMW1`, read by src/find/weights.rs), graph
included, so that src/find/graph.rs runs them with the crate's own layers.

How to run (offline after the first two commands; nothing here is needed at build or run time):

    python3 -m venv /work/venv-mp && /work/venv-mp/bin/pip install tflite numpy
    /work/venv-mp/bin/pip download mediapipe==0.10.14 --no-deps -d /tmp/mp
    (cd /tmp/mp && unzip -o mediapipe-0.10.14-*.whl 'mediapipe/modules/*')
    /work/venv-mp/bin/python scripts/convert-mediapipe.py /tmp/mp/mediapipe/modules [OUT_DIR]

It reads `face_detection/face_detection_short_range.tflite` and
`face_landmark/face_landmark.tflite` (Apache-2.0, Google LLC; see data/weights/LICENSE-mediapipe)
and writes `blazeface_short.fmw` and `face_mesh.fmw` to OUT_DIR (default data/weights).

The TFLite files store their weights as float16 (dequantised at load by DEQUANTIZE ops); they
are kept as float16 here (encoding 2), so the converted nets compute with exactly the same
weights. scripts/quantise-fmw.py then makes the smaller files the crate embeds
(`*_q8.fmw`): the filters `op{i}/w` requantised to encoding 3 of `FMW1` (src/find/weights.rs: a
`u32` axis, one `f32` scale per index along it, `i8` values, value = scale * q), per output
channel: axis 0 of a convolution's `[cout, kh, kw, cin]`, axis 3 of a depthwise `[1, kh, kw, c]`;
biases, PReLU slopes (one value per channel) and the `graph`/`outputs` tensors unchanged. Besides the weights, each file holds two float32 tensors that describe the graph:

- `graph` `[ops, 8]`: one row per layer, `[kind, out, in0, in1, stride, same, kernel, extra]`,
  where `out`/`in*` are activation slots (slot 0 is the input image, -1 none), `same` is 1 for
  TensorFlow `same` padding and 0 for `valid`, and `kind` is 0 convolution (weights `op{i}/w`
  `[cout, kh, kw, cin]` and `op{i}/b`), 1 depthwise convolution (`op{i}/w` `[1, kh, kw, c]`,
  `op{i}/b`), 2 ReLU, 3 PReLU (`op{i}/a` `[c]`), 4 addition, 5 channel padding (`extra` zero
  channels after), 6 max pooling (`kernel` x `kernel`, `stride`);
- `outputs` `[n]`: the slots of the net's outputs (the maps before TFLite's final reshapes).
"""
import os
import struct
import sys

import numpy as np
import tflite

KIND = {'CONV_2D': 0, 'DEPTHWISE_CONV_2D': 1, 'RELU': 2, 'PRELU': 3, 'ADD': 4, 'PAD': 5,
        'MAX_POOL_2D': 6}
NAMES = {v: k for k, v in tflite.BuiltinOperator.__dict__.items() if not k.startswith('_')}


def graph_of(path):
    """The net's layers and constant tensors, from its TFLite flatbuffer."""
    buf = open(path, 'rb').read()
    m = tflite.Model.GetRootAsModel(buf, 0)
    g = m.Subgraphs(0)
    codes = [max(m.OperatorCodes(i).BuiltinCode(), m.OperatorCodes(i).DeprecatedBuiltinCode())
             for i in range(m.OperatorCodesLength())]

    def const(t):
        tensor = g.Tensors(t)
        b = m.Buffers(tensor.Buffer())
        if b.DataLength() == 0:
            return None
        dtype = {tflite.TensorType.FLOAT16: np.float16, tflite.TensorType.FLOAT32: np.float32,
                 tflite.TensorType.INT32: np.int32}[tensor.Type()]
        return np.frombuffer(b.DataAsNumpy().tobytes(), dtype).reshape(tensor.ShapeAsNumpy())

    dequant = {}  # output tensor of a DEQUANTIZE -> its float16 constant
    slots = {g.Inputs(0): 0}
    alias = {}  # RESHAPE / CONCATENATION outputs -> their inputs (not layers of their own)
    ops, tensors = [], []
    for i in range(g.OperatorsLength()):
        op = g.Operators(i)
        name = NAMES[codes[op.OpcodeIndex()]]
        ins = [op.Inputs(j) for j in range(op.InputsLength())]
        out = op.Outputs(0)
        if name == 'DEQUANTIZE':
            dequant[out] = const(ins[0])
            continue
        if name in ('RESHAPE', 'CONCATENATION'):
            alias[out] = ins
            continue
        if name not in KIND:
            raise SystemExit(f'{path}: layer {name} not supported')

        def weight(t):
            v = dequant.get(t)
            return v if v is not None else const(t)

        row = [KIND[name], len(slots), slots[ins[0]], -1, 1, 0, 0, 0]
        k = len(ops)
        if name in ('CONV_2D', 'DEPTHWISE_CONV_2D'):
            o = tflite.Conv2DOptions() if name == 'CONV_2D' else tflite.DepthwiseConv2DOptions()
            t = op.BuiltinOptions()
            o.Init(t.Bytes, t.Pos)
            assert o.FusedActivationFunction() == 0 and o.DilationHFactor() == 1
            assert o.StrideH() == o.StrideW()
            w, b = weight(ins[1]), weight(ins[2])
            row[4] = o.StrideH()
            row[5] = 1 if o.Padding() == tflite.Padding.SAME else 0
            row[6] = w.shape[1]
            assert w.shape[1] == w.shape[2]
            tensors.append((f'op{k}/w', w))
            tensors.append((f'op{k}/b', b))
        elif name == 'PRELU':
            a = weight(ins[1])
            tensors.append((f'op{k}/a', a.reshape(-1)))
        elif name == 'ADD':
            o = tflite.AddOptions()
            t = op.BuiltinOptions()
            o.Init(t.Bytes, t.Pos)
            assert o.FusedActivationFunction() == 0
            row[3] = slots[ins[1]]
        elif name == 'PAD':
            pads = const(ins[1]).reshape(-1, 2)
            assert (pads[:3] == 0).all() and pads[3][0] == 0, pads
            row[7] = int(pads[3][1])
        elif name == 'MAX_POOL_2D':
            o = tflite.Pool2DOptions()
            t = op.BuiltinOptions()
            o.Init(t.Bytes, t.Pos)
            assert o.FusedActivationFunction() == 0 and o.FilterHeight() == o.FilterWidth()
            row[4] = o.StrideH()
            row[5] = 1 if o.Padding() == tflite.Padding.SAME else 0
            row[6] = o.FilterHeight()
        slots[out] = row[1]
        ops.append(row)

    def leaves(t):
        if t in alias:
            return [s for i in alias[t] for s in leaves(i)]
        return [slots[t]]

    outputs = [s for j in range(g.OutputsLength()) for s in leaves(g.Outputs(j))]
    return ops, tensors, outputs, slots


def write(path, ops, tensors, outputs):
    chunks = []
    u32 = lambda v: chunks.append(struct.pack('<I', v))
    entries = [('graph', np.array(ops, np.float32)), ('outputs', np.array(outputs, np.float32))]
    entries += tensors
    u32_magic = b'FMW1'
    chunks.append(u32_magic)
    u32(len(entries))
    for name, v in entries:
        nb = name.encode()
        u32(len(nb))
        chunks.append(nb)
        u32(v.ndim)
        for d in v.shape:
            u32(int(d))
        if v.dtype == np.float16:
            u32(2)
            chunks.append(v.astype('<f2').tobytes())
        else:
            u32(0)
            chunks.append(v.astype('<f4').tobytes())
    data = b''.join(chunks)
    open(path, 'wb').write(data)
    return len(data)


def main():
    if len(sys.argv) < 2:
        raise SystemExit(__doc__)
    src = sys.argv[1]
    out_dir = sys.argv[2] if len(sys.argv) > 2 else os.path.join(
        os.path.dirname(__file__), '..', 'data', 'weights')
    for rel, name in [('face_detection/face_detection_short_range.tflite', 'blazeface_short.fmw'),
                      ('face_landmark/face_landmark.tflite', 'face_mesh.fmw')]:
        ops, tensors, outputs, _ = graph_of(os.path.join(src, rel))
        n = write(os.path.join(out_dir, name), ops, tensors, outputs)
        print(f'{name}: {len(ops)} layers, outputs {outputs}, {n} bytes')


if __name__ == '__main__':
    main()
