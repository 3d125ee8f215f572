//! A small interpreter for the layer lists that `scripts/convert-mediapipe.py` writes from
//! MediaPipe's TFLite files (the `graph` and `outputs` tensors of an `FMW1` file; format in that
//! script's header): convolutions of any square kernel and stride, depthwise convolutions,
//! ReLU, PReLU, additions, channel padding and max pooling, channels-last `f32` maps, as
//! TFLite's reference kernels compute them.
//!
//! The activations live in a few buffers reused from layer to layer (a buffer is handed to the
//! next layer once the last layer reading it has run), kept in [`GraphScratch`], so a run after
//! the first allocates nothing.

use super::nn::{self, Act, Map, Post};
use super::weights::{bad, Weights};
use crate::error::{Error, Result};

/// The detector's weights: filters in int8 per channel (`scripts/quantise-fmw.py`), biases and
/// slopes float16 (`scripts/convert-mediapipe.py`); here, below the pipeline that runs them
/// (`mesh.rs`), so the graph's own tests can load them.
pub const BLAZEFACE_WEIGHTS: &[u8] = include_bytes!("../../data/weights/blazeface_short_q8.fmw");
/// The face mesh's weights (int8 filters, like the detector's).
pub const MESH_WEIGHTS: &[u8] = include_bytes!("../../data/weights/face_mesh_q8.fmw");
/// The detector's float16 weights, as TFLite computes with them: tests only (the
/// layer-by-layer reference).
#[cfg(all(test, not(target_arch = "wasm32")))]
pub const BLAZEFACE_WEIGHTS_F16: &[u8] = include_bytes!("../../data/weights/blazeface_short.fmw");
/// The face mesh's float16 weights: tests only.
#[cfg(all(test, not(target_arch = "wasm32")))]
pub const MESH_WEIGHTS_F16: &[u8] = include_bytes!("../../data/weights/face_mesh.fmw");

/// What a layer computes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Conv,
    Depthwise,
    Relu,
    Prelu,
    Add,
    PadChannels,
    MaxPool,
}

/// One layer: its kind, its buffers and its parameters.
#[derive(Clone, Debug)]
struct Layer {
    kind: Kind,
    /// The buffer written.
    out: usize,
    /// The buffers read (the second only for additions).
    inputs: [usize; 2],
    stride: usize,
    /// TensorFlow `same` padding (else `valid`).
    same: bool,
    kernel: usize,
    /// Zero channels appended (channel padding).
    extra: usize,
    /// Output channels (convolutions).
    cout: usize,
    /// Elementwise layers whose first input is read by no later layer write over it.
    in_place: bool,
    /// Convolution filters, rearranged: `[cin][cout]` for 1x1, `[kh][kw][cin][cout]` for
    /// larger kernels, `[kh][kw][c]` for depthwise; PReLU slopes `[c]`.
    w: Vec<f32>,
    bias: Vec<f32>,
}

/// A net read from a converted weight file.
#[derive(Clone, Debug)]
pub(crate) struct Graph {
    layers: Vec<Layer>,
    /// How many buffers the layers need at once.
    buffers: usize,
    /// The buffers holding the net's outputs after [`Graph::run`], in the file's order.
    outputs: Vec<usize>,
    /// The expected input: side and channels.
    input: (usize, usize),
    /// The layers as [`Graph::run_fast`] runs them, fused where it can.
    plan: Vec<Step>,
    /// For the layer-by-layer reference test: each layer's buffer (the logical slot it wrote).
    #[cfg(all(test, not(target_arch = "wasm32")))]
    pub slots: Vec<usize>,
}

/// A step of [`Graph::run_fast`]: a layer, or a layer and the one or two after it in one pass
/// (see [`plan`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Step {
    /// Layer `i` alone.
    One(usize),
    /// Layer `i` (a convolution or an addition), then the activation `i + 1` (in place on its
    /// output) applied as its values are stored.
    Act(usize),
    /// The 1x1 convolution `i`, the addition `i + 1` of its output to another map (in place
    /// on that map) and the activation `i + 2` (in place): the sums added and activated as they
    /// are stored, straight into the other map; the convolution's own output is never written.
    AddAct(usize),
}

/// The fused steps of layers `rows` (logical slots: before [`assign_buffers`]; `last_use` of
/// [`last_uses`]): an activation right after the layer making its
/// input, when it could run in place (that input read by no later layer), joins that layer
/// (a convolution or an addition); a 1x1 convolution whose output only the addition right
/// after it reads, itself followed by such an activation, joins both (the addition's other
/// input then takes the sums). Every fused value is the value the layers compute one by one,
/// bit for bit (test `fused_run_matches_the_layer_by_layer_run`).
fn plan(rows: &[Layer], last_use: &[usize]) -> Vec<Step> {
    // Layer `j` is an activation that may run in place on the output of layer `j - 1`.
    let act_after = |j: usize| {
        rows.get(j).is_some_and(|a| {
            matches!(a.kind, Kind::Relu | Kind::Prelu)
                && a.inputs[0] == rows[j - 1].out
                && a.inputs[0] != 0
                && last_use[a.inputs[0]] == j
        })
    };
    let mut steps = Vec::new();
    let mut i = 0;
    while i < rows.len() {
        let l = &rows[i];
        let pointwise = l.kind == Kind::Conv && l.kernel == 1 && l.stride == 1;
        let add_act = pointwise
            && rows.get(i + 1).is_some_and(|a| {
                let [skip, sum] = a.inputs;
                a.kind == Kind::Add
                    && sum == l.out
                    && skip != l.out
                    && skip != l.inputs[0]
                    && skip != 0
                    && last_use[skip] == i + 1
                    && last_use[l.out] == i + 1
            })
            && act_after(i + 2);
        if add_act {
            steps.push(Step::AddAct(i));
            i += 3;
        } else if matches!(l.kind, Kind::Conv | Kind::Add) && act_after(i + 1) {
            steps.push(Step::Act(i));
            i += 2;
        } else {
            steps.push(Step::One(i));
            i += 1;
        }
    }
    steps
}

/// The activation layer `l` applies, as a fused step applies it.
fn act_of(l: &Layer) -> Act<'_> {
    match l.kind {
        Kind::Relu => Act::Relu,
        Kind::Prelu => Act::Prelu(&l.w),
        _ => Act::None,
    }
}

/// The activation buffers of a [`Graph`] run.
#[derive(Default, Debug)]
pub(crate) struct GraphScratch {
    maps: Vec<Map>,
    /// The gathered windows of one output row of a convolution larger than 1x1.
    patches: Vec<f32>,
}

/// A graph entry as a slot index (`None` for -1, "no slot"); anything else is an error.
fn as_index(v: f32) -> Result<Option<usize>> {
    if v == -1.0 {
        Ok(None)
    } else if (0.0..1e6).contains(&v) && v.fract() == 0.0 {
        Ok(Some(v as usize))
    } else {
        Err(bad(format!("graph entry {v}")))
    }
}

/// Layer `i` from its graph row (kind, output slot, input slots, stride, same, kernel, extra)
/// and its tensors in `w`, checked against the channels of the slots before it; `out` and
/// `inputs` are still logical slots (see [`assign_buffers`]).
fn parse_layer(w: &Weights, i: usize, row: &[f32], channels: &[usize]) -> Result<Layer> {
    let get = |k: usize| as_index(row[k]);
    let kind = match get(0)? {
        Some(0) => Kind::Conv,
        Some(1) => Kind::Depthwise,
        Some(2) => Kind::Relu,
        Some(3) => Kind::Prelu,
        Some(4) => Kind::Add,
        Some(5) => Kind::PadChannels,
        Some(6) => Kind::MaxPool,
        k => return Err(bad(format!("layer {i}: kind {k:?}"))),
    };
    let out = get(1)?.ok_or_else(|| bad("layer without output"))?;
    let in0 = get(2)?.ok_or_else(|| bad("layer without input"))?;
    let in1 = get(3)?;
    if out != channels.len() || in0 >= out || in1.is_some_and(|s| s >= out) {
        return Err(bad(format!("layer {i}: slots out of order")));
    }
    let cin = channels[in0];
    let stride = get(4)?.unwrap_or(1).max(1);
    let same = get(5)? == Some(1);
    let kernel = get(6)?.unwrap_or(0);
    let extra = get(7)?.unwrap_or(0);
    let mut layer = Layer {
        kind,
        out,
        inputs: [in0, in1.unwrap_or(in0)],
        stride,
        same,
        kernel,
        extra,
        cout: cin,
        in_place: false,
        w: Vec::new(),
        bias: Vec::new(),
    };
    let tensor = |name: &str| {
        w.tensor(&format!("op{i}/{name}"))
            .ok_or_else(|| bad(format!("layer {i}: no {name}")))
    };
    match kind {
        Kind::Conv => {
            let f = tensor("w")?;
            let [cout, kh, kw, c] = f.shape[..] else {
                return Err(bad(format!("layer {i}: filter shape {:?}", f.shape)));
            };
            if kh != kernel || kw != kernel || c != cin || kernel == 0 {
                return Err(bad(format!("layer {i}: filter shape {:?}", f.shape)));
            }
            // [cout][kh][kw][cin] -> [kh][kw][cin][cout]
            let mut r = vec![0.0; f.data.len()];
            for o in 0..cout {
                for t in 0..kh * kw {
                    for ci in 0..cin {
                        r[(t * cin + ci) * cout + o] = f.data[(o * kh * kw + t) * cin + ci];
                    }
                }
            }
            layer.w = r;
            layer.cout = cout;
            layer.bias = tensor("b")?.data.clone();
        }
        Kind::Depthwise => {
            let f = tensor("w")?;
            if f.shape != [1, kernel, kernel, cin] || kernel == 0 {
                return Err(bad(format!("layer {i}: filter shape {:?}", f.shape)));
            }
            layer.w = f.data.clone();
            layer.bias = tensor("b")?.data.clone();
        }
        Kind::Prelu => layer.w = tensor("a")?.data.clone(),
        Kind::PadChannels => layer.cout = cin + extra,
        Kind::Add => {
            if channels[layer.inputs[1]] != cin {
                return Err(bad(format!("layer {i}: adding maps of other depths")));
            }
        }
        Kind::Relu => {}
        Kind::MaxPool => {
            if kernel == 0 {
                return Err(bad(format!("layer {i}: pooling kernel 0")));
            }
        }
    }
    if (matches!(kind, Kind::Conv | Kind::Depthwise) && layer.bias.len() != layer.cout)
        || (kind == Kind::Prelu && layer.w.len() != cin)
    {
        return Err(bad(format!("layer {i}: bias or slope size")));
    }
    Ok(layer)
}

/// For each logical slot of `rows` (the input, then each layer's output), the last layer that
/// reads it; `usize::MAX` for the net's `outputs`, which stay to the end.
fn last_uses(rows: &[Layer], outputs: &[usize]) -> Vec<usize> {
    let mut last_use = vec![0usize; rows.len() + 1];
    for (i, l) in rows.iter().enumerate() {
        for &s in &l.inputs {
            last_use[s] = i;
        }
    }
    for &o in outputs {
        last_use[o] = usize::MAX;
    }
    last_use
}

/// Gives every logical slot of `rows` (`last_use` of [`last_uses`]) a buffer, reusing a buffer once the
/// last layer reading its slot has run and running ReLU, PReLU and Add in place on an input
/// read by nobody else; slot 0 (the input) keeps buffer 0 and `outputs` are never freed.
/// Rewrites each layer's `out` and `inputs` as buffers; returns the number of buffers and each
/// slot's last buffer.
fn assign_buffers(rows: &mut [Layer], last_use: &[usize]) -> (usize, Vec<usize>) {
    // Buffers: a slot's buffer is free again after the last layer reading it.
    let slots = last_use.len();
    let mut buffer_of = vec![usize::MAX; slots];
    buffer_of[0] = 0;
    let mut free: Vec<usize> = Vec::new();
    let mut buffers = 1;
    for (i, l) in rows.iter_mut().enumerate() {
        let [in0, in1] = l.inputs;
        l.in_place = matches!(l.kind, Kind::Relu | Kind::Prelu | Kind::Add)
            && in0 != 0
            && last_use[in0] == i
            && (l.kind != Kind::Add || in1 != in0);
        let b = if l.in_place {
            let b = buffer_of[in0];
            // The buffer now holds `out`: `in0` no longer frees it.
            buffer_of[in0] = usize::MAX;
            b
        } else {
            free.pop().unwrap_or_else(|| {
                buffers += 1;
                buffers - 1
            })
        };
        l.inputs = [in0, in1].map(|s| {
            if s == in0 && l.in_place {
                b
            } else {
                buffer_of[s]
            }
        });
        buffer_of[l.out] = b;
        l.out = b;
        for s in 0..slots {
            // The input (buffer 0) stays the input.
            if s != 0
                && last_use[s] == i
                && buffer_of[s] != usize::MAX
                && !free.contains(&buffer_of[s])
            {
                free.push(buffer_of[s]);
            }
        }
    }
    (buffers, buffer_of)
}

/// Output size and padding before for a kernel `k` and stride `s` on `input` pixels.
fn geometry(input: usize, k: usize, s: usize, same: bool) -> Option<(usize, usize)> {
    if same {
        Some(nn::same(input, k, s))
    } else {
        (input >= k).then(|| ((input - k) / s + 1, 0))
    }
}

impl Graph {
    /// Reads a converted net; `input` is its input side and channels (checked against the
    /// first layer's weights).
    pub fn load(bytes: &[u8], input: (usize, usize)) -> Result<Self> {
        let w = Weights::parse(bytes)?;
        let g = w
            .tensor("graph")
            .ok_or_else(|| bad("no graph in the weight file"))?;
        if g.shape.len() != 2 || g.shape[1] != 8 {
            return Err(bad(format!("graph shape {:?}", g.shape)));
        }
        // Channels of every logical slot, to check the weights' shapes.
        let mut channels = vec![input.1];
        let mut rows = Vec::new();
        for (i, row) in g.data.chunks_exact(8).enumerate() {
            let layer = parse_layer(&w, i, row, &channels)?;
            channels.push(layer.cout);
            rows.push(layer);
        }
        if rows.is_empty() {
            return Err(bad("empty graph"));
        }
        let outputs_t = w.tensor("outputs").ok_or_else(|| bad("no outputs"))?;
        let mut outputs = Vec::new();
        for &v in &outputs_t.data {
            let s = as_index(v)?.filter(|&s| s < channels.len());
            outputs.push(s.ok_or_else(|| bad(format!("output slot {v}")))?);
        }
        #[cfg(all(test, not(target_arch = "wasm32")))]
        let logical: Vec<usize> = rows.iter().map(|l| l.out).collect();
        let last_use = last_uses(&rows, &outputs);
        let plan = plan(&rows, &last_use);
        let (buffers, buffer_of) = assign_buffers(&mut rows, &last_use);
        Ok(Graph {
            layers: rows,
            buffers,
            outputs: outputs.iter().map(|&s| buffer_of[s]).collect(),
            input,
            plan,
            #[cfg(all(test, not(target_arch = "wasm32")))]
            slots: logical,
        })
    }

    /// Runs the net on `s.input()` (filled by the caller, `side x side x channels`); the outputs
    /// are then [`GraphScratch::output`]. `each` is called after every layer with the layer's
    /// index and its output (for the reference test and the profile; pass `|_, _| {}`). Layer
    /// by layer, nothing fused: the finder runs [`Graph::run_fast`].
    #[cfg(any(test, not(target_arch = "wasm32")))]
    pub fn run(&self, s: &mut GraphScratch, mut each: impl FnMut(usize, &Map)) -> Result<()> {
        self.prepare(s)?;
        for (i, l) in self.layers.iter().enumerate() {
            self.layer(l, Act::None, s)?;
            each(i, &s.maps[l.out]);
        }
        Ok(())
    }

    /// [`Graph::run`] without a look at each layer, the activations (and some additions) fused
    /// into the layers before them ([`plan`]): the same outputs bit for bit, in fewer passes
    /// over the maps. What the finder runs.
    pub fn run_fast(&self, s: &mut GraphScratch) -> Result<()> {
        self.prepare(s)?;
        for &step in &self.plan {
            match step {
                Step::One(i) => self.layer(&self.layers[i], Act::None, s)?,
                Step::Act(i) => self.layer(&self.layers[i], act_of(&self.layers[i + 1]), s)?,
                Step::AddAct(i) => {
                    let (c, a) = (&self.layers[i], &self.layers[i + 1]);
                    let x = &s.maps[c.inputs[0]];
                    let skip = &s.maps[a.out];
                    if (skip.h, skip.w, skip.c) != (x.h, x.w, c.cout) {
                        // Maps of other sizes: the layers one by one, as `run` does.
                        for l in &self.layers[i..i + 3] {
                            self.layer(l, Act::None, s)?;
                        }
                        continue;
                    }
                    let mut y = std::mem::take(&mut s.maps[a.out]);
                    let post = Post {
                        act: act_of(&self.layers[i + 2]),
                        residual: true,
                    };
                    nn::pointwise(&s.maps[c.inputs[0]], &c.w, &c.bias, post, &mut y);
                    s.maps[a.out] = y;
                }
            }
        }
        Ok(())
    }

    /// Runs layer `l` on the maps of `s`, then `act` on its values (fused: as they are
    /// stored; only for convolutions and additions).
    fn layer(&self, l: &Layer, act: Act, s: &mut GraphScratch) -> Result<()> {
        let mut y = std::mem::take(&mut s.maps[l.out]);
        if l.in_place {
            match l.kind {
                Kind::Relu => nn::relu(&mut y.data),
                Kind::Prelu => prelu(&mut y, &l.w),
                _ => add_then(&mut y, &s.maps[l.inputs[1]].data, act),
            }
            s.maps[l.out] = y;
            return Ok(());
        }
        let x = &s.maps[l.inputs[0]];
        match l.kind {
            Kind::Conv if l.kernel == 1 && l.stride == 1 => {
                let post = Post {
                    act,
                    residual: false,
                };
                nn::pointwise(x, &l.w, &l.bias, post, &mut y)
            }
            Kind::Conv => conv(x, l, act, &mut s.patches, &mut y)?,
            Kind::Depthwise => depthwise(x, l, &mut y)?,
            Kind::Relu => {
                copy(x, &mut y);
                nn::relu(&mut y.data);
            }
            Kind::Prelu => {
                copy(x, &mut y);
                prelu(&mut y, &l.w);
            }
            Kind::Add => {
                copy(x, &mut y);
                add_then(&mut y, &s.maps[l.inputs[1]].data, act);
            }
            Kind::PadChannels => {
                y.reshape(x.h, x.w, x.c + l.extra);
                for (o, i) in y.data.chunks_exact_mut(y.c).zip(x.data.chunks_exact(x.c)) {
                    o[..x.c].copy_from_slice(i);
                    o[x.c..].fill(0.0);
                }
            }
            Kind::MaxPool => maxpool(x, l, &mut y)?,
        }
        s.maps[l.out] = y;
        Ok(())
    }

    /// Sizes the buffers of `s` for a run and checks its input.
    fn prepare(&self, s: &mut GraphScratch) -> Result<()> {
        if s.maps.len() < self.buffers {
            s.maps.resize_with(self.buffers, Map::default);
        }
        let x = &s.maps[0];
        if x.h != self.input.0 || x.w != self.input.0 || x.c != self.input.1 {
            return Err(Error::Image(format!(
                "net input {}x{}x{}, expected {}x{}x{}",
                x.h, x.w, x.c, self.input.0, self.input.0, self.input.1
            )));
        }
        Ok(())
    }
}

impl GraphScratch {
    /// The input buffer, to be filled as `side x side x channels` before [`Graph::run`].
    pub fn input(&mut self) -> &mut Map {
        if self.maps.is_empty() {
            self.maps.push(Map::default());
        }
        &mut self.maps[0]
    }

    /// Output `k` (in the converted file's order) of the last run of `graph`.
    pub fn output(&self, graph: &Graph, k: usize) -> &Map {
        &self.maps[graph.outputs[k]]
    }
}

/// PReLU in place, pixel by pixel ([`nn::prelu_slice`]).
fn prelu(y: &mut Map, slopes: &[f32]) {
    for px in y.data.chunks_exact_mut(y.c) {
        nn::prelu_slice(px, slopes);
    }
}

/// `y += x`, then `act` on `y`: pixel by pixel when there is an activation (the sums still in
/// the cache), the same values as the two passes.
fn add_then(y: &mut Map, x: &[f32], act: Act) {
    if let Act::None = act {
        return add(&mut y.data, x);
    }
    for (y, x) in y.data.chunks_exact_mut(y.c).zip(x.chunks_exact(y.c)) {
        add(y, x);
        act.apply(y);
    }
}

/// `y += x`, elementwise (the two have the same length).
fn add(y: &mut [f32], x: &[f32]) {
    const L: usize = 16;
    let mut ys = y.chunks_exact_mut(L);
    let mut xs = x.chunks_exact(L);
    for (y, x) in (&mut ys).zip(&mut xs) {
        let y: &mut [f32; L] = y.try_into().unwrap();
        let x: &[f32; L] = x.try_into().unwrap();
        for (y, &x) in y.iter_mut().zip(x) {
            *y += x;
        }
    }
    for (y, &x) in ys.into_remainder().iter_mut().zip(xs.remainder()) {
        *y += x;
    }
}

fn copy(x: &Map, y: &mut Map) {
    y.reshape(x.h, x.w, x.c);
    y.data.copy_from_slice(&x.data);
}

fn too_small(l: &Layer) -> Error {
    Error::Image(format!(
        "map smaller than a {}x{} kernel",
        l.kernel, l.kernel
    ))
}

/// A full convolution of any square kernel and stride, plus bias (filters `[kh][kw][cin][cout]`):
/// each output row's windows are gathered into `patches` (a row of `kh kw cin` values a pixel,
/// zeros for the padding) and multiplied by the filters with [`nn::matmul`], the blocked
/// product the 1x1 convolutions use. The sums are made in the same order as a direct loop
/// (`ky`, `kx`, input channel), the padding adding zeros.
fn conv(x: &Map, l: &Layer, act: Act, patches: &mut Vec<f32>, y: &mut Map) -> Result<()> {
    let (k, s, cin, cout) = (l.kernel, l.stride, x.c, l.cout);
    let (oh, py) = geometry(x.h, k, s, l.same).ok_or_else(|| too_small(l))?;
    let (ow, px) = geometry(x.w, k, s, l.same).ok_or_else(|| too_small(l))?;
    y.reshape(oh, ow, cout);
    let row = k * k * cin;
    let span = k * cin;
    patches.clear();
    patches.resize(ow * row, 0.0);
    for (oy, out) in y.data.chunks_exact_mut(ow * cout).enumerate() {
        for (ox, patch) in patches.chunks_exact_mut(row).enumerate() {
            let ix0 = (ox * s) as isize - px as isize;
            for (ky, seg) in patch.chunks_exact_mut(span).enumerate() {
                let iy = (oy * s + ky) as isize - py as isize;
                if iy < 0 || iy >= x.h as isize {
                    seg.fill(0.0);
                    continue;
                }
                let line = &x.data[iy as usize * x.w * cin..][..x.w * cin];
                if ix0 >= 0 && ix0 as usize + k <= x.w {
                    seg.copy_from_slice(&line[ix0 as usize * cin..][..span]);
                    continue;
                }
                for (kx, tap) in seg.chunks_exact_mut(cin).enumerate() {
                    let ix = ix0 + kx as isize;
                    if ix < 0 || ix >= x.w as isize {
                        tap.fill(0.0);
                    } else {
                        tap.copy_from_slice(&line[ix as usize * cin..][..cin]);
                    }
                }
            }
        }
        let post = Post {
            act,
            residual: false,
        };
        nn::matmul(patches, row, &l.w, cout, &l.bias, post, out);
    }
    Ok(())
}

/// The input pixels under the kernel at output `(oy, ox)`: calls `tap(t, i)` with `t` the
/// filter tap (`ky * k + kx`) and `i` the input pixel, in increasing `ky`, then `kx`.
#[inline(always)]
fn taps(
    x: &Map,
    l: &Layer,
    py: usize,
    px: usize,
    oy: usize,
    ox: usize,
    mut tap: impl FnMut(usize, usize),
) {
    let (k, s) = (l.kernel, l.stride);
    for ky in 0..k {
        let iy = (oy * s + ky) as isize - py as isize;
        if iy < 0 || iy >= x.h as isize {
            continue;
        }
        for kx in 0..k {
            let ix = (ox * s + kx) as isize - px as isize;
            if ix < 0 || ix >= x.w as isize {
                continue;
            }
            tap(ky * k + kx, iy as usize * x.w + ix as usize);
        }
    }
}

/// Slides a `kernel x kernel` window with the layer's stride and padding over `x`: `y` takes
/// the output's size, each output cell (its `c` channels) is set by `init`, then `tap(cell,
/// input cell, t)` runs for every input cell of its window inside `x` (padding is skipped), `t`
/// being the tap's index in the window (`ky * kernel + kx`). What depthwise convolution and
/// max pooling share.
fn windows(
    x: &Map,
    l: &Layer,
    y: &mut Map,
    init: impl Fn(&mut [f32]),
    mut tap: impl FnMut(&mut [f32], &[f32], usize),
) -> Result<()> {
    let (k, s, c) = (l.kernel, l.stride, x.c);
    let (oh, py) = geometry(x.h, k, s, l.same).ok_or_else(|| too_small(l))?;
    let (ow, px) = geometry(x.w, k, s, l.same).ok_or_else(|| too_small(l))?;
    y.reshape(oh, ow, c);
    for oy in 0..oh {
        for ox in 0..ow {
            let o = &mut y.data[(oy * ow + ox) * c..][..c];
            init(o);
            taps(x, l, py, px, oy, ox, |t, i| {
                tap(o, &x.data[i * c..][..c], t)
            });
        }
    }
    Ok(())
}

/// A depthwise convolution (filters `[kh][kw][c]`) plus bias. For a 3x3 kernel the windows
/// wholly inside the map (all but the border pixels) take [`depthwise3x3_row`]; the rest take
/// the general loop. Both sum `bias + tap 0 + tap 1 + ...` in the window's order.
fn depthwise(x: &Map, l: &Layer, y: &mut Map) -> Result<()> {
    let (k, s, c) = (l.kernel, l.stride, x.c);
    if k != 3 {
        return depthwise_any(x, l, y);
    }
    let (oh, py) = geometry(x.h, k, s, l.same).ok_or_else(|| too_small(l))?;
    let (ow, px) = geometry(x.w, k, s, l.same).ok_or_else(|| too_small(l))?;
    y.reshape(oh, ow, c);
    let line = x.w * c;
    // Output columns whose window is inside the map: `lo..hi`.
    let lo = px.div_ceil(s).min(ow);
    let hi = if x.w + px >= 3 {
        ((x.w + px - 3) / s + 1).clamp(lo, ow)
    } else {
        lo
    };
    for (oy, out) in y.data.chunks_exact_mut(ow * c).enumerate() {
        let iy0 = (oy * s) as isize - py as isize;
        let inside = iy0 >= 0 && iy0 as usize + 3 <= x.h;
        let border = |ox: usize, o: &mut [f32]| {
            o.copy_from_slice(&l.bias);
            taps(x, l, py, px, oy, ox, |t, i| {
                let inp = &x.data[i * c..][..c];
                let f = &l.w[t * c..][..c];
                for ((oo, &a), &ff) in o.iter_mut().zip(inp).zip(f) {
                    *oo += a * ff;
                }
            });
        };
        if !inside {
            for (ox, o) in out.chunks_exact_mut(c).enumerate() {
                border(ox, o);
            }
            continue;
        }
        let rows: [&[f32]; 3] =
            std::array::from_fn(|ky| &x.data[(iy0 as usize + ky) * line..][..line]);
        depthwise3x3_row(&rows, c, s, px, lo..hi, &l.w, &l.bias, out);
        for ox in (0..lo).chain(hi..ow) {
            border(ox, &mut out[ox * c..][..c]);
        }
    }
    Ok(())
}

/// Output columns `cols` of one row of a 3x3 depthwise convolution whose windows lie inside
/// the three input `rows` (`c` channels, stride `s`, `px` padding columns before): four
/// channels at a time, their nine filter taps held in registers along the row.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn depthwise3x3_row(
    rows: &[&[f32]; 3],
    c: usize,
    s: usize,
    px: usize,
    cols: std::ops::Range<usize>,
    w: &[f32],
    bias: &[f32],
    out: &mut [f32],
) {
    const L: usize = 4;
    let full = c - c % L;
    for j in (0..full).step_by(L) {
        let f: [[f32; L]; 9] = std::array::from_fn(|t| w[t * c + j..][..L].try_into().unwrap());
        let b: [f32; L] = bias[j..j + L].try_into().unwrap();
        for ox in cols.clone() {
            let at = (ox * s - px) * c + j;
            let mut acc = b;
            for (ky, row) in rows.iter().enumerate() {
                for kx in 0..3 {
                    let a: &[f32; L] = row[at + kx * c..][..L].try_into().unwrap();
                    for ((o, &a), &f) in acc.iter_mut().zip(a).zip(&f[ky * 3 + kx]) {
                        *o += a * f;
                    }
                }
            }
            out[ox * c + j..][..L].copy_from_slice(&acc);
        }
    }
    for j in full..c {
        for ox in cols.clone() {
            let at = (ox * s - px) * c + j;
            let mut acc = bias[j];
            for (ky, row) in rows.iter().enumerate() {
                for kx in 0..3 {
                    acc += row[at + kx * c] * w[(ky * 3 + kx) * c + j];
                }
            }
            out[ox * c + j] = acc;
        }
    }
}

/// A depthwise convolution of any kernel, plainly.
fn depthwise_any(x: &Map, l: &Layer, y: &mut Map) -> Result<()> {
    let c = x.c;
    windows(
        x,
        l,
        y,
        |o| o.copy_from_slice(&l.bias),
        |o, inp, t| {
            let f = &l.w[t * c..][..c];
            for ((oo, &a), &ff) in o.iter_mut().zip(inp).zip(f) {
                *oo += a * ff;
            }
        },
    )
}

/// Max pooling (padded cells never win).
fn maxpool(x: &Map, l: &Layer, y: &mut Map) -> Result<()> {
    windows(
        x,
        l,
        y,
        |o| o.fill(f32::NEG_INFINITY),
        |o, inp, _| {
            for (oo, &a) in o.iter_mut().zip(inp) {
                // Not `f32::max` (a libm call in wasm32): a select.
                *oo = if a > *oo { a } else { *oo };
            }
        },
    )
}

/// The time of MediaPipe's two nets by layer kind, on one fixed input: what
/// `examples/finder_profile.rs` prints (a profile, not a check). Minima over the runs, the
/// figure least moved by other work on a shared machine.
#[cfg(any(test, not(target_arch = "wasm32")))]
#[derive(Clone, Debug, PartialEq)]
pub struct NetProfile {
    /// The net's input side: 128 for BlazeFace, 192 for the face mesh.
    pub side: usize,
    /// Seconds a run: the fastest run (the run the finder makes, activations fused).
    pub run: f64,
    /// Seconds a run: the median run.
    pub median: f64,
    /// Per layer kind (`"Conv k3 s1"`, ...: kind, kernel and stride), the seconds a run its
    /// layers take (each layer's fastest time over `reps` other runs made layer by layer,
    /// nothing fused; summed), by name.
    pub layers: Vec<(String, f64)>,
}

/// Runs BlazeFace (128) and the face mesh (192) `reps` times each on a fixed input after one
/// warm-up run and times them, layer by layer (native only: it reads the clock).
#[cfg(not(target_arch = "wasm32"))]
pub fn profile_mesh_nets(reps: usize) -> Result<Vec<NetProfile>> {
    let t0 = std::time::Instant::now();
    profile_nets(reps, || t0.elapsed().as_secs_f64())
}

/// [`profile_mesh_nets`] with `clock` (seconds from any origin).
#[cfg(any(test, not(target_arch = "wasm32")))]
fn profile_nets(reps: usize, clock: impl Fn() -> f64) -> Result<Vec<NetProfile>> {
    let reps = reps.max(1);
    let mut out = Vec::new();
    for (bytes, n) in [(BLAZEFACE_WEIGHTS, 128), (MESH_WEIGHTS, 192)] {
        let g = Graph::load(bytes, (n, 3))?;
        let mut s = GraphScratch::default();
        let x = s.input();
        x.reset(n, n, 3);
        for (i, v) in x.data.iter_mut().enumerate() {
            *v = ((i * 7919) % 255) as f32 / 255.0;
        }
        g.run(&mut s, |_, _| {})?;
        let mut best = vec![f64::INFINITY; g.layers.len()];
        for _ in 0..reps {
            let mut last = clock();
            g.run(&mut s, |i, _| {
                let now = clock();
                best[i] = best[i].min(now - last);
                last = now;
            })?;
        }
        let mut runs = Vec::with_capacity(reps);
        for _ in 0..reps {
            let t0 = clock();
            g.run_fast(&mut s)?;
            runs.push(clock() - t0);
        }
        let mut times = std::collections::BTreeMap::<String, f64>::new();
        for (l, t) in g.layers.iter().zip(&best) {
            let key = format!("{:?} k{} s{}", l.kind, l.kernel, l.stride);
            *times.entry(key).or_default() += t;
        }
        runs.sort_by(f64::total_cmp);
        out.push(NetProfile {
            side: n,
            run: runs[0],
            median: runs[reps / 2],
            layers: times.into_iter().collect(),
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layer(
        kind: Kind,
        kernel: usize,
        stride: usize,
        same: bool,
        cin: usize,
        cout: usize,
    ) -> Layer {
        let wlen = if kind == Kind::Depthwise {
            kernel * kernel * cin
        } else {
            kernel * kernel * cin * cout
        };
        Layer {
            kind,
            out: 1,
            inputs: [0, 0],
            stride,
            same,
            kernel,
            extra: 0,
            cout,
            in_place: false,
            w: (0..wlen).map(|i| (i as f32 * 0.71).sin()).collect(),
            bias: (0..cout).map(|i| i as f32 * 0.1 - 0.3).collect(),
        }
    }

    fn map(h: usize, w: usize, c: usize) -> Map {
        Map {
            h,
            w,
            c,
            data: (0..h * w * c).map(|i| (i as f32 * 0.37).cos()).collect(),
        }
    }

    /// The direct sum of a convolution (`depthwise`: one input channel per output) at every
    /// output, padding skipped.
    fn direct(x: &Map, l: &Layer, depthwise: bool) -> Map {
        let (k, s) = (l.kernel, l.stride);
        let (oh, py) = geometry(x.h, k, s, l.same).unwrap();
        let (ow, px) = geometry(x.w, k, s, l.same).unwrap();
        let mut y = Map::default();
        y.reset(oh, ow, l.cout);
        for oy in 0..oh {
            for ox in 0..ow {
                for co in 0..l.cout {
                    let mut v = l.bias[co];
                    for ky in 0..k {
                        for kx in 0..k {
                            let iy = (oy * s + ky) as isize - py as isize;
                            let ix = (ox * s + kx) as isize - px as isize;
                            if iy < 0 || ix < 0 || iy >= x.h as isize || ix >= x.w as isize {
                                continue;
                            }
                            let i = (iy as usize * x.w + ix as usize) * x.c;
                            let t = ky * k + kx;
                            if depthwise {
                                v += x.data[i + co] * l.w[t * x.c + co];
                            } else {
                                for ci in 0..x.c {
                                    v += x.data[i + ci] * l.w[(t * x.c + ci) * l.cout + co];
                                }
                            }
                        }
                    }
                    y.data[(oy * ow + ox) * l.cout + co] = v;
                }
            }
        }
        y
    }

    /// An output buffer holding NaNs from an earlier use: a value a layer does not write
    /// stays NaN.
    fn stale() -> Map {
        Map {
            data: vec![f32::NAN; 4096],
            ..Map::default()
        }
    }

    fn assert_close(got: &Map, want: &Map, what: &str) {
        assert_eq!((got.h, got.w, got.c), (want.h, want.w, want.c), "{what}");
        for (i, (a, b)) in got.data.iter().zip(&want.data).enumerate() {
            assert!((a - b).abs() < 1e-5, "{what}: element {i}: {a} vs {b}");
        }
    }

    #[test]
    fn depthwise_matches_a_direct_sum_inside_and_on_the_border() {
        // 6 channels (one block of 4 and 2 plainly), odd and even sizes, both paddings.
        for (h, w) in [(7, 9), (8, 8), (3, 4), (2, 2)] {
            for stride in [1, 2] {
                for same in [true, false] {
                    let x = map(h, w, 6);
                    let l = layer(Kind::Depthwise, 3, stride, same, 6, 6);
                    if geometry(h, 3, stride, same).is_none()
                        || geometry(w, 3, stride, same).is_none()
                    {
                        continue;
                    }
                    let mut y = stale();
                    depthwise(&x, &l, &mut y).unwrap();
                    let what = format!("{h}x{w} stride {stride} same {same}");
                    assert_close(&y, &direct(&x, &l, true), &what);
                }
            }
        }
    }

    #[test]
    fn fused_run_matches_the_layer_by_layer_run() {
        for (bytes, n, fused) in [(BLAZEFACE_WEIGHTS, 128, 22), (MESH_WEIGHTS, 192, 28)] {
            let g = Graph::load(bytes, (n, 3)).unwrap();
            let joined = g.layers.len() - g.plan.len();
            assert_eq!(joined, fused, "layers joined in the {n} net's plan");
            let (mut a, mut b) = (GraphScratch::default(), GraphScratch::default());
            let x = a.input();
            x.reset(n, n, 3);
            for (i, v) in x.data.iter_mut().enumerate() {
                *v = ((i * 7919) % 255) as f32 / 127.5 - 1.0;
            }
            *b.input() = a.input().clone();
            g.run(&mut a, |_, _| {}).unwrap();
            // Twice: the second run starts from the first's stale buffers.
            g.run_fast(&mut b).unwrap();
            g.run_fast(&mut b).unwrap();
            for k in 0..g.outputs.len() {
                let (x, y) = (a.output(&g, k), b.output(&g, k));
                assert_eq!((x.h, x.w, x.c), (y.h, y.w, y.c), "net {n} output {k}");
                for (i, (p, q)) in x.data.iter().zip(&y.data).enumerate() {
                    assert_eq!(p.to_bits(), q.to_bits(), "net {n} output {k} value {i}");
                }
            }
        }
    }

    #[test]
    fn conv_matches_a_direct_sum() {
        let mut patches = Vec::new();
        for (k, stride, same, cin, cout) in [
            (5, 2, true, 3, 10),
            (3, 2, true, 3, 16),
            (3, 1, false, 2, 5),
            (3, 3, false, 4, 13),
        ] {
            for (h, w) in [(9, 7), (6, 6)] {
                let x = map(h, w, cin);
                let l = layer(Kind::Conv, k, stride, same, cin, cout);
                let mut y = stale();
                conv(&x, &l, Act::None, &mut patches, &mut y).unwrap();
                let what = format!("{h}x{w} k{k} s{stride} same {same}");
                assert_close(&y, &direct(&x, &l, false), &what);
            }
        }
    }
}

/// The nets' and the finder's speed in wasm under Node (V8, Chromium's engine), the native
/// profile's figures and the finder's, printed, not checked: `cargo test --release --target
/// wasm32-unknown-unknown --lib graph::wasm_speed -- --nocapture`.
#[cfg(all(test, target_arch = "wasm32"))]
mod wasm_speed {
    use wasm_bindgen::prelude::wasm_bindgen;
    use wasm_bindgen_test::{console_log, wasm_bindgen_test};

    #[wasm_bindgen]
    extern "C" {
        /// `performance.now()`: milliseconds, with a fraction in Node.
        #[wasm_bindgen(js_namespace = performance)]
        fn now() -> f64;
    }

    #[wasm_bindgen_test]
    fn nets_in_wasm() {
        for net in super::profile_nets(100, || now() / 1e3).unwrap() {
            console_log!(
                "wasm net {}: {:.2} ms a run (fastest), {:.2} ms (median)",
                net.side,
                net.run * 1e3,
                net.median * 1e3
            );
            for (kind, t) in net.layers {
                console_log!("  {kind}: {:.3} ms", t * 1e3);
            }
        }
    }

    /// The fastest and the median of `reps` runs of `f` (after one more), in milliseconds.
    fn time(reps: usize, mut f: impl FnMut()) -> (f64, f64) {
        f();
        let mut t: Vec<f64> = (0..reps)
            .map(|_| {
                let t0 = now();
                f();
                now() - t0
            })
            .collect();
        t.sort_by(f64::total_cmp);
        (t[0], t[reps / 2])
    }

    /// The finder on a 640x480 frame with no face (a search: letterbox and detector), then the
    /// landmarks of a box in it (two mesh crops and passes): together about a find of one face.
    #[wasm_bindgen_test]
    fn finder_in_wasm() {
        let (w, h) = (640u32, 480u32);
        let data: Vec<u8> = (0..w * h * 4)
            .map(|i| {
                let (x, y) = ((i / 4) % w, (i / 4) / w);
                ((x * 3 + y * 5 + (i % 4) * 40) % 251) as u8
            })
            .collect();
        let image = crate::image::ImageRef::new(w, h, &data).unwrap();
        let mut finder = crate::find::FaceFinder::new().unwrap();
        let (fast, median) = time(50, || {
            finder.find(&image);
        });
        console_log!("wasm search 640x480: {fast:.2} ms (fastest), {median:.2} ms (median)");
        let bbox = crate::geometry::BBox {
            x: 220.0,
            y: 140.0,
            width: 200.0,
            height: 190.0,
        };
        let mut out = vec![0.0; 136];
        let (fast, median) = time(50, || {
            finder.landmarks_into(&image, bbox, &mut out).unwrap();
        });
        console_log!("wasm landmarks 640x480: {fast:.2} ms (fastest), {median:.2} ms (median)");
        finder.set_local_correction(false);
        let (fast, median) = time(50, || {
            finder.landmarks_into(&image, bbox, &mut out).unwrap();
        });
        console_log!(
            "wasm landmarks 640x480 without the local correction: {fast:.2} ms (fastest), {median:.2} ms (median)"
        );
    }
}
