//! The two nets of face-api.js (Vincent Mühler; weights as shipped by `@vladmandic/face-api`
//! 1.7.15, MIT): the tiny face detector (a Tiny-YOLOv2 with depthwise-separable convolutions)
//! and the 68-point landmark net (four dense blocks of separable convolutions and a
//! fully-connected layer). The forward passes follow face-api.js's `TinyYolov2Base.runMobilenet`
//! and `FaceFeatureExtractor` / `FaceLandmark68Net`; the batch norms are already folded into the
//! shipped weights.

use super::nn::{self, Map};
use super::weights::Weights;
use crate::error::Result;

/// The detector's box anchors (width, height in grid cells).
pub(crate) const ANCHORS: [(f32, f32); 5] = [
    (1.603231, 2.094468),
    (6.041143, 7.080126),
    (2.882459, 3.518061),
    (4.266906, 5.178857),
    (9.041765, 10.66308),
];
/// Mean RGB subtracted from the detector's input (then divided by 255).
pub(crate) const DETECTOR_MEAN: [f32; 3] = [117.001, 114.697, 97.404];
/// Mean RGB subtracted from the landmark net's input (then divided by 255).
pub(crate) const LANDMARK_MEAN: [f32; 3] = [122.782, 117.001, 104.298];
/// The landmark net's input side.
pub const LANDMARK_INPUT: usize = 112;

struct SepConv {
    depthwise: Vec<f32>,
    pointwise: Vec<f32>,
    bias: Vec<f32>,
}

impl SepConv {
    fn load(w: &Weights, prefix: &str, cin: usize, cout: usize) -> Result<Self> {
        Ok(SepConv {
            depthwise: w.get(&format!("{prefix}/depthwise_filter"), &[3, 3, cin, 1])?,
            pointwise: w.get(&format!("{prefix}/pointwise_filter"), &[1, 1, cin, cout])?,
            bias: w.get(&format!("{prefix}/bias"), &[cout])?,
        })
    }

    /// Depthwise 3x3 (stride, `same`) then pointwise plus bias: `x -> y`, `tmp` scratch.
    fn run(&self, x: &Map, stride: usize, tmp: &mut Map, y: &mut Map) {
        let (oh, pad) = nn::same(x.h, 3, stride);
        let (ow, _) = nn::same(x.w, 3, stride);
        nn::depthwise3x3(x, &self.depthwise, stride, pad, (oh, ow), tmp);
        nn::pointwise(tmp, &self.pointwise, &self.bias, y);
    }
}

/// Scratch feature maps, kept between runs.
#[derive(Default)]
pub(crate) struct Scratch {
    a: Map,
    b: Map,
    t: Map,
    d: [Map; 4],
}

/// The tiny face detector.
pub(crate) struct Detector {
    conv0_f: Vec<f32>,
    conv0_b: Vec<f32>,
    convs: Vec<SepConv>,
    conv8_f: Vec<f32>,
    conv8_b: Vec<f32>,
}

impl Detector {
    pub fn load(bytes: &[u8]) -> Result<Self> {
        let w = Weights::parse(bytes)?;
        let sizes = [16, 32, 64, 128, 256, 512];
        let convs = (1..6)
            .map(|i| SepConv::load(&w, &format!("conv{i}"), sizes[i - 1], sizes[i]))
            .collect::<Result<Vec<_>>>()?;
        Ok(Detector {
            conv0_f: w.get("conv0/filters", &[3, 3, 3, 16])?,
            conv0_b: w.get("conv0/bias", &[16])?,
            convs,
            conv8_f: w.get("conv8/filters", &[1, 1, 512, 25])?,
            conv8_b: w.get("conv8/bias", &[25])?,
        })
    }

    /// Runs the net on a normalised `s x s x 3` input (`s` a multiple of 32); returns the raw
    /// output grid, `cells x cells x 25` (per anchor: tx, ty, tw, th, score logit), in `out`.
    pub fn run(&self, input: &Map, s: &mut Scratch, out: &mut Map) {
        let (h, w) = (input.h - 2, input.w - 2);
        nn::conv3x3(input, &self.conv0_f, &self.conv0_b, 1, 0, (h, w), &mut s.a);
        nn::leaky(&mut s.a);
        nn::maxpool2(&s.a, 2, &mut s.b);
        for (i, conv) in self.convs.iter().enumerate() {
            // b -> a (conv, leaky) -> b (pool)
            conv.run(&s.b, 1, &mut s.t, &mut s.a);
            nn::leaky(&mut s.a);
            nn::maxpool2(&s.a, if i == 4 { 1 } else { 2 }, &mut s.b);
        }
        nn::pointwise(&s.b, &self.conv8_f, &self.conv8_b, out);
    }
}

/// The 68-point landmark net.
pub(crate) struct LandmarkNet {
    conv0_f: Vec<f32>,
    conv0_b: Vec<f32>,
    /// 4 blocks x 4 separable convs (block 0's first conv is `conv0_*`, its slot unused).
    blocks: Vec<Vec<SepConv>>,
    fc_w: Vec<f32>,
    fc_b: Vec<f32>,
}

impl LandmarkNet {
    pub fn load(bytes: &[u8]) -> Result<Self> {
        let w = Weights::parse(bytes)?;
        let sizes = [3, 32, 64, 128, 256];
        let mut blocks = Vec::new();
        for b in 0..4 {
            let mut convs = Vec::new();
            for c in 0..4 {
                if b == 0 && c == 0 {
                    continue;
                }
                let cin = if c == 0 { sizes[b] } else { sizes[b + 1] };
                convs.push(SepConv::load(
                    &w,
                    &format!("dense{b}/conv{c}"),
                    cin,
                    sizes[b + 1],
                )?);
            }
            blocks.push(convs);
        }
        Ok(LandmarkNet {
            conv0_f: w.get("dense0/conv0/filters", &[3, 3, 3, 32])?,
            conv0_b: w.get("dense0/conv0/bias", &[32])?,
            blocks,
            fc_w: w.get("fc/weights", &[256, 136])?,
            fc_b: w.get("fc/bias", &[136])?,
        })
    }

    /// Runs the net on a normalised `112 x 112 x 3` input; writes the 136 raw outputs
    /// (x0, y0, x1, ... as fractions of the input square) into `out`.
    pub fn run(&self, input: &Map, s: &mut Scratch, out: &mut [f32; 136]) {
        let Scratch { a, b, t, d } = s;
        let [out1, out2, out3, cur] = d;
        for (bi, block) in self.blocks.iter().enumerate() {
            // out1 = relu(conv0(x)), stride 2
            let x: &Map = if bi == 0 { input } else { cur };
            if bi == 0 {
                let (oh, pad) = nn::same(x.h, 3, 2);
                let (ow, _) = nn::same(x.w, 3, 2);
                nn::conv3x3(x, &self.conv0_f, &self.conv0_b, 2, pad, (oh, ow), out1);
            } else {
                block[0].run(x, 2, t, out1);
            }
            nn::relu(&mut out1.data);
            let convs = if bi == 0 { &block[..] } else { &block[1..] };
            // out2 = conv1(out1); out3 = conv2(relu(out1 + out2))
            convs[0].run(out1, 1, t, out2);
            sum(&[out1, out2], a);
            nn::relu(&mut a.data);
            convs[1].run(a, 1, t, out3);
            // out4 = conv3(relu(out1 + out2 + out3)); block out = relu(out1 + ... + out4)
            sum(&[out1, out2, out3], a);
            b.reset(a.h, a.w, a.c);
            for (o, v) in b.data.iter_mut().zip(&a.data) {
                *o = v.max(0.0);
            }
            convs[2].run(b, 1, t, cur);
            for (o, v) in cur.data.iter_mut().zip(&a.data) {
                *o = (*o + v).max(0.0);
            }
        }
        // 7x7 average pool (valid) over the 7x7x256 map -> 256 features.
        let c = cur.c;
        let feat = &mut t.data;
        feat.clear();
        feat.resize(c, 0.0);
        for px in cur.data.chunks_exact(c) {
            for (f, v) in feat.iter_mut().zip(px) {
                *f += v;
            }
        }
        let n = (cur.h * cur.w) as f32;
        for f in feat.iter_mut() {
            *f /= n;
        }
        nn::dense(feat, &self.fc_w, &self.fc_b, out);
    }
}

/// `y = sum of maps` (all the same size).
fn sum(maps: &[&Map], y: &mut Map) {
    let m0 = maps[0];
    y.reset(m0.h, m0.w, m0.c);
    y.data.copy_from_slice(&m0.data);
    for m in &maps[1..] {
        for (o, v) in y.data.iter_mut().zip(&m.data) {
            *o += v;
        }
    }
}
