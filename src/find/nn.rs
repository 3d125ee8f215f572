//! The kernels under the finder's layers (`graph.rs`), on channels-last (`[h][w][c]`) `f32`
//! feature maps. Every layer writes into a caller-owned buffer that keeps its capacity, so
//! a net run after the first allocates nothing.
//!
//! Padding follows TensorFlow's `same` rule: `total = max((out - 1) * stride + k - in, 0)`, with
//! `total / 2` (rounded down) before and the rest after.

/// A channels-last feature map.
#[derive(Clone, Debug, Default)]
pub(crate) struct Map {
    pub h: usize,
    pub w: usize,
    pub c: usize,
    pub data: Vec<f32>,
}

impl Map {
    /// Resizes to `h x w x c` (contents unspecified), keeping the allocation when it is enough.
    pub fn reset(&mut self, h: usize, w: usize, c: usize) {
        self.h = h;
        self.w = w;
        self.c = c;
        self.data.clear();
        self.data.resize(h * w * c, 0.0);
    }

    /// [`Map::reset`] for a layer that then writes every value: no pass clearing the old
    /// values first (they stay where the sizes overlap).
    pub fn reshape(&mut self, h: usize, w: usize, c: usize) {
        self.h = h;
        self.w = w;
        self.c = c;
        self.data.resize(h * w * c, 0.0);
    }
}

/// Output size and padding before, for TensorFlow `same` padding.
pub(crate) fn same(input: usize, k: usize, stride: usize) -> (usize, usize) {
    let out = input.div_ceil(stride);
    let total = ((out - 1) * stride + k).saturating_sub(input);
    (out, total / 2)
}

/// A 1x1 convolution (`filters` `[cin][cout]`) plus bias: a matrix product per pixel
/// ([`matmul`]), each sum then passed through `post` as it is stored (with `post.residual`, `y`
/// holds the map added and keeps its size).
pub(crate) fn pointwise(x: &Map, filters: &[f32], bias: &[f32], post: Post, y: &mut Map) {
    let cout = bias.len();
    debug_assert_eq!(filters.len(), x.c * cout);
    if post.residual {
        debug_assert_eq!((y.h, y.w, y.c), (x.h, x.w, cout));
    } else {
        y.reshape(x.h, x.w, cout);
    }
    matmul(&x.data, x.c, filters, cout, bias, post, &mut y.data);
}

/// An activation applied to values as they are stored (a layer fused with the ReLU or PReLU
/// after it).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) enum Act<'a> {
    /// None: the values as they are.
    #[default]
    None,
    /// ReLU ([`relu1`]).
    Relu,
    /// PReLU ([`prelu1`]) with these slopes, one a channel (from the first channel written).
    Prelu(&'a [f32]),
}

impl<'a> Act<'a> {
    /// The activation of channels `c0..` (PReLU's slopes from `c0`).
    #[inline(always)]
    fn at_channel(self, c0: usize) -> Act<'a> {
        match self {
            Act::Prelu(a) => Act::Prelu(&a[c0..]),
            other => other,
        }
    }

    /// Applies the activation to `v`, the values of channels `0..v.len()`.
    #[inline(always)]
    pub fn apply(self, v: &mut [f32]) {
        match self {
            Act::None => {}
            Act::Relu => v.iter_mut().for_each(|v| *v = relu1(*v)),
            Act::Prelu(a) => prelu_slice(v, a),
        }
    }
}

/// What [`matmul`] does with each sum: stores `act(sum)`, or with `residual` `act(out +
/// sum)` (an addition after the layer, fused: `out` holds the other map).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Post<'a> {
    /// The activation.
    pub act: Act<'a>,
    /// Whether the sum is added to the value already in `out` first.
    pub residual: bool,
}

impl<'a> Post<'a> {
    /// The post-processing of channels `c0..`.
    #[inline(always)]
    fn at_channel(self, c0: usize) -> Post<'a> {
        Post {
            act: self.act.at_channel(c0),
            ..self
        }
    }
}

/// `out[p][o] = bias[o] + sum_i a[p][i] f[i][o]` for every row `p` of `a` (rows of `k`
/// values; `out` rows of `bias.len()` values); `f` has rows of `fs >= bias.len()` values (a
/// caller may pad them). What the 1x1 convolutions are, and the larger ones once their
/// windows are gathered into rows.
///
/// This is where the nets spend most of their time, so it is blocked like a small matrix
/// product: [`BLOCK_COUT`] output channels by [`BLOCK_ROWS`] rows at a time, whose
/// accumulators stay in registers, then blocks of 4 channels and one of the last 1-3
/// channels, and single rows for the rest. Each output still sums `bias + a0 f0 + a1 f1 + ...`
/// in input order, so the result is bit-identical to the plain loop.
///
/// Each sum then passes through `post` as it leaves the registers: `out[p][o] = act(sum)`, or
/// `act(out[p][o] + sum)` with `post.residual`; the very values of the product followed by a
/// separate addition (`out += sum`, the same two operands) and activation pass.
pub(crate) fn matmul(
    a: &[f32],
    k: usize,
    f: &[f32],
    fs: usize,
    bias: &[f32],
    post: Post,
    out: &mut [f32],
) {
    let p = Product {
        a,
        k,
        rows: a.len().checked_div(k).unwrap_or(0),
        f,
        fs,
        bias,
        post,
    };
    #[cfg(target_arch = "x86_64")]
    {
        // The same loops compiled for 256-bit registers where the CPU has them ([`arch`]):
        // plain multiplies and adds in the same order (no fused multiply-add), so the results
        // are the same bits as with SSE2 and in wasm32.
        arch().dispatch(MatMul { p, out });
    }
    #[cfg(not(target_arch = "x86_64"))]
    matmul_in(p, out);
}

/// The CPU's instruction sets, checked once: `pulp`'s dispatch runs a kernel compiled for the
/// widest registers the CPU has (AVX2 on x86-64 CPUs from 2013 on), safely.
#[cfg(target_arch = "x86_64")]
pub(crate) fn arch() -> &'static pulp::Arch {
    static ARCH: std::sync::OnceLock<pulp::Arch> = std::sync::OnceLock::new();
    ARCH.get_or_init(pulp::Arch::new)
}

/// [`matmul`]'s operands: `rows` rows of `k` values in `a`, `f` with rows of `fs` values,
/// one output channel per value of `bias`, each sum through `post`.
#[derive(Clone, Copy)]
struct Product<'a> {
    a: &'a [f32],
    k: usize,
    rows: usize,
    f: &'a [f32],
    fs: usize,
    bias: &'a [f32],
    post: Post<'a>,
}

impl<'a> Product<'a> {
    /// The product's output channels `c..`: `f`, `bias` and `post` from channel `c` on.
    #[inline(always)]
    fn at_channel(self, c: usize) -> Product<'a> {
        Product {
            f: &self.f[c..],
            bias: &self.bias[c..],
            post: self.post.at_channel(c),
            ..self
        }
    }
}

/// [`matmul`]'s operands and output, for `pulp`'s dispatch.
#[cfg(target_arch = "x86_64")]
struct MatMul<'a> {
    p: Product<'a>,
    out: &'a mut [f32],
}

#[cfg(target_arch = "x86_64")]
impl pulp::WithSimd for MatMul<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) {
        matmul_in(self.p, self.out);
    }
}

/// [`matmul`]'s loops, inlined into its caller (so into `pulp`'s dispatch, compiled for the
/// CPU's registers). Blocks of 16 channels under AVX2 were slower than 8 (measured).
#[inline(always)]
fn matmul_in(p: Product, out: &mut [f32]) {
    let n = p.bias.len();
    debug_assert!(p.fs >= n && (p.k == 0 || p.f.len() >= (p.k - 1) * p.fs + n));
    debug_assert_eq!(out.len(), p.rows * n);
    let c0 = channel_blocks::<BLOCK_COUT>(0, p, out);
    let c0 = channel_blocks::<4>(c0, p, out);
    // The last `n % 4` channels: a block of their own (sums in registers, not in `out`).
    match n - c0 {
        1 => channel_blocks::<1>(c0, p, out),
        2 => channel_blocks::<2>(c0, p, out),
        3 => channel_blocks::<3>(c0, p, out),
        _ => c0,
    };
}

/// Output channels `c0..` of [`matmul_in`] (`n = bias.len()` in all) in blocks of `N` while a
/// whole block fits ([`channel_block`]); the first channel left.
#[inline(always)]
fn channel_blocks<const N: usize>(c0: usize, p: Product, out: &mut [f32]) -> usize {
    let n = p.bias.len();
    let mut c = c0;
    while c + N <= n {
        channel_block::<N>(p.at_channel(c), &mut out[c..], n);
        c += N;
    }
    c
}

/// Output channels `0..N` of `p` (taken from the block's first channel on, `out` too) for all
/// its rows, `out` having rows of `n` values: [`BLOCK_ROWS`] rows at a time, then one at a
/// time.
#[inline(always)]
fn channel_block<const N: usize>(p: Product, out: &mut [f32], n: usize) {
    let Product {
        a,
        k,
        rows,
        f,
        fs,
        bias,
        post,
    } = p;
    let b: &[f32; N] = bias[..N].try_into().unwrap();
    let mut r = 0;
    while r + BLOCK_ROWS <= rows {
        kernel::<N, BLOCK_ROWS>(
            &a[r * k..][..BLOCK_ROWS * k],
            k,
            f,
            fs,
            b,
            post,
            &mut out[r * n..],
            n,
        );
        r += BLOCK_ROWS;
    }
    while r < rows {
        kernel::<N, 1>(&a[r * k..][..k], k, f, fs, b, post, &mut out[r * n..], n);
        r += 1;
    }
}

/// `P` rows of `a` (`P x k` values) times `N` columns of `f`: `P x N` accumulators.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn kernel<const N: usize, const P: usize>(
    a: &[f32],
    k: usize,
    f: &[f32],
    fs: usize,
    b: &[f32; N],
    post: Post,
    out: &mut [f32],
    n: usize,
) {
    let mut acc = [*b; P];
    let rows: [&[f32]; P] = std::array::from_fn(|r| &a[r * k..][..k]);
    for ci in 0..k {
        let fr: &[f32; N] = f[ci * fs..][..N].try_into().unwrap();
        for (acc, row) in acc.iter_mut().zip(&rows) {
            let v = row[ci];
            for (o, &w) in acc.iter_mut().zip(fr) {
                *o += v * w;
            }
        }
    }
    for (r, acc) in acc.iter().enumerate() {
        let o: &mut [f32; N] = (&mut out[r * n..][..N]).try_into().unwrap();
        store(acc, post, o);
    }
}

/// Stores the sums `acc` through `post` into `o` (fixed-size arrays throughout, so the sums
/// stay in registers).
#[inline(always)]
fn store<const N: usize>(acc: &[f32; N], post: Post, o: &mut [f32; N]) {
    let mut v = *acc;
    if post.residual {
        for (v, &o) in v.iter_mut().zip(o.iter()) {
            // `o + v`, the operands in the order of the addition layer (`y += x`, `y` the other
            // map): the same value even for a NaN's payload.
            #[allow(clippy::assign_op_pattern)]
            {
                *v = o + *v;
            }
        }
    }
    match post.act {
        Act::None => {}
        Act::Relu => {
            for v in &mut v {
                *v = relu1(*v);
            }
        }
        Act::Prelu(a) => {
            let a: &[f32; N] = a[..N].try_into().unwrap();
            for (v, &a) in v.iter_mut().zip(a) {
                *v = prelu1(*v, a);
            }
        }
    }
    *o = v;
}

/// Output channels per register block of [`matmul`].
const BLOCK_COUT: usize = 8;
/// Rows (pixels) per register block of [`matmul`].
const BLOCK_ROWS: usize = 4;

/// ReLU, in place: the sign bit's mask clears the negative values (to +0.0), sixteen at a
/// time. Integer operations on fixed-size arrays, so that it vectorises in wasm32 too
/// (`f32::max` is a call of libm's `fmaxf` per value there: Rust's NaN rule for `max` is not
/// wasm's `f32.max`).
pub(crate) fn relu(x: &mut [f32]) {
    const L: usize = 16;
    let mut chunks = x.chunks_exact_mut(L);
    for v in &mut chunks {
        let v: &mut [f32; L] = v.try_into().unwrap();
        for v in v {
            *v = relu1(*v);
        }
    }
    for v in chunks.into_remainder() {
        *v = relu1(*v);
    }
}

/// PReLU in place on the channels of one pixel (`slopes` from the same channel): negative
/// values times their channel's slope, as a select so that it vectorises (not
/// `f32::max`/`min`, which wasm32 compiles to a call of libm's `fmaxf` per value: its NaN rule
/// is not wasm's). In wasm32 four channels at a time as fixed-size arrays (3.3 times faster
/// there than the plain loop, 2.5 times slower natively: measured).
#[inline(always)]
pub(crate) fn prelu_slice(v: &mut [f32], slopes: &[f32]) {
    let full = if cfg!(target_arch = "wasm32") {
        v.len() - v.len() % 4
    } else {
        0
    };
    let (head, tail) = v.split_at_mut(full);
    for (v, a) in head.chunks_exact_mut(4).zip(slopes.chunks_exact(4)) {
        let v: &mut [f32; 4] = v.try_into().unwrap();
        let a: &[f32; 4] = a.try_into().unwrap();
        for (v, &a) in v.iter_mut().zip(a) {
            *v = prelu1(*v, a);
        }
    }
    for (v, &a) in tail.iter_mut().zip(&slopes[full..]) {
        *v = prelu1(*v, a);
    }
}

/// One PReLU value: `v` times `a` when negative, a select.
#[inline(always)]
pub(crate) fn prelu1(v: f32, a: f32) -> f32 {
    v * if v < 0.0 { a } else { 1.0 }
}

/// One ReLU value: negative values (and -0.0) to +0.0, by the sign bit.
#[inline(always)]
pub(crate) fn relu1(v: f32) -> f32 {
    let b = v.to_bits();
    f32::from_bits(b & !(((b as i32) >> 31) as u32))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map(h: usize, w: usize, c: usize, f: impl Fn(usize) -> f32) -> Map {
        Map {
            h,
            w,
            c,
            data: (0..h * w * c).map(f).collect(),
        }
    }

    #[test]
    fn same_padding_matches_tensorflow() {
        assert_eq!(same(112, 3, 2), (56, 0));
        assert_eq!(same(113, 3, 2), (57, 1));
        assert_eq!(same(56, 3, 1), (56, 1));
        assert_eq!(same(207, 2, 2), (104, 0));
        assert_eq!(same(13, 2, 1), (13, 0));
    }

    #[test]
    fn pointwise_blocks_match_the_plain_product_exactly() {
        // 7 pixels (one block of 4 and a tail of 3) and 37 outputs (four blocks of 8, one of 4
        // and one plain channel).
        let x = map(1, 7, 5, |i| (i as f32 * 0.29).sin());
        let f: Vec<f32> = (0..5 * 37).map(|i| (i as f32 * 0.13).cos()).collect();
        let b: Vec<f32> = (0..37).map(|i| i as f32 * 0.01 - 0.2).collect();
        let mut y = Map::default();
        pointwise(&x, &f, &b, Post::default(), &mut y);
        assert_eq!((y.h, y.w, y.c), (1, 7, 37));
        for p in 0..7 {
            for co in 0..37 {
                let mut s = b[co];
                for ci in 0..5 {
                    s += x.data[p * 5 + ci] * f[ci * 37 + co];
                }
                assert_eq!(
                    y.data[p * 37 + co].to_bits(),
                    s.to_bits(),
                    "pixel {p} channel {co}"
                );
            }
        }
    }

    #[test]
    fn matmul_reads_filter_rows_of_a_longer_stride() {
        // 9 rows of 6 inputs, 13 outputs read from filter rows of 16 (the rest ignored).
        let (rows, k, n, fs) = (9, 6, 13, 16);
        let a: Vec<f32> = (0..rows * k).map(|i| (i as f32 * 0.41).sin()).collect();
        let f: Vec<f32> = (0..k * fs).map(|i| (i as f32 * 0.17).cos()).collect();
        let b: Vec<f32> = (0..n).map(|i| 0.3 - i as f32 * 0.02).collect();
        let mut out = vec![f32::NAN; rows * n];
        matmul(&a, k, &f, fs, &b, Post::default(), &mut out);
        for p in 0..rows {
            for o in 0..n {
                let mut s = b[o];
                for i in 0..k {
                    s += a[p * k + i] * f[i * fs + o];
                }
                assert_eq!(out[p * n + o].to_bits(), s.to_bits(), "row {p} output {o}");
            }
        }
    }
}
