//! The finder's weight files (`data/weights/*.fmw`, made by `scripts/convert-weights.mjs`).
//!
//! Layout (little-endian): the magic `FMW1`, a `u32` tensor count, then per tensor a `u32` name
//! length and the UTF-8 name (the tfjs manifest's name, e.g. `conv1/depthwise_filter`), a `u32`
//! rank and that many `u32` dimensions (tfjs order: `[kh, kw, in, out]` for convolutions), a
//! `u32` encoding (0: float32 values; 1: uint8 values `q` with `f32` scale and `f32` min before
//! them, value = min + scale * q; 2: float16 values, as MediaPipe's TFLite files store them,
//! written by `scripts/convert-mediapipe.py`) and the values.

use crate::error::{Error, Result};

/// One named tensor, dequantised to `f32`.
#[derive(Clone, Debug)]
pub(crate) struct Tensor {
    pub name: String,
    pub shape: Vec<usize>,
    pub data: Vec<f32>,
}

/// All tensors of one weight file.
#[derive(Clone, Debug)]
pub(crate) struct Weights {
    tensors: Vec<Tensor>,
}

/// An [`Error::Weights`] saying `msg` (what a weight file or a graph built from one lacks).
pub(super) fn bad(msg: impl Into<String>) -> Error {
    Error::Weights(msg.into())
}

struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8]> {
        let end = self
            .pos
            .checked_add(n)
            .filter(|&e| e <= self.bytes.len())
            .ok_or_else(|| bad("truncated weight file"))?;
        let s = &self.bytes[self.pos..end];
        self.pos = end;
        Ok(s)
    }
    fn u32(&mut self) -> Result<u32> {
        let b = self.take(4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }
    fn f32(&mut self) -> Result<f32> {
        Ok(f32::from_bits(self.u32()?))
    }
}

impl Weights {
    /// Parses a weight file.
    pub fn parse(bytes: &[u8]) -> Result<Self> {
        let mut r = Reader { bytes, pos: 0 };
        if r.take(4)? != b"FMW1" {
            return Err(bad("not a weight file (magic)"));
        }
        let count = r.u32()? as usize;
        if count > 4096 {
            return Err(bad(format!("{count} tensors")));
        }
        let mut tensors = Vec::with_capacity(count);
        for _ in 0..count {
            let n = r.u32()? as usize;
            let name = std::str::from_utf8(r.take(n)?)
                .map_err(|_| bad("tensor name is not UTF-8"))?
                .to_string();
            let rank = r.u32()? as usize;
            if rank > 4 {
                return Err(bad(format!("{name}: rank {rank}")));
            }
            let mut shape = Vec::with_capacity(rank);
            let mut len = 1usize;
            for _ in 0..rank {
                let d = r.u32()? as usize;
                len = len
                    .checked_mul(d)
                    .filter(|&l| l <= bytes.len())
                    .ok_or_else(|| bad(format!("{name}: size beyond the file")))?;
                shape.push(d);
            }
            let data = match r.u32()? {
                0 => r
                    .take(len * 4)?
                    .chunks_exact(4)
                    .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                    .collect(),
                1 => {
                    let scale = r.f32()?;
                    let min = r.f32()?;
                    r.take(len)?
                        .iter()
                        .map(|&q| min + scale * q as f32)
                        .collect()
                }
                2 => r
                    .take(len * 2)?
                    .chunks_exact(2)
                    .map(|b| half::f16::from_le_bytes([b[0], b[1]]).to_f32())
                    .collect(),
                e => return Err(bad(format!("{name}: encoding {e}"))),
            };
            tensors.push(Tensor { name, shape, data });
        }
        if r.pos != bytes.len() {
            return Err(bad("trailing bytes after the last tensor"));
        }
        Ok(Weights { tensors })
    }

    /// The tensor `name`, with its shape (`None` when absent).
    #[cfg_attr(not(feature = "mesh-finder"), allow(dead_code))]
    pub fn tensor(&self, name: &str) -> Option<&Tensor> {
        self.tensors.iter().find(|t| t.name == name)
    }

    /// The tensor `name`, checked to have `shape`.
    pub fn get(&self, name: &str, shape: &[usize]) -> Result<Vec<f32>> {
        let t = self
            .tensors
            .iter()
            .find(|t| t.name == name)
            .ok_or_else(|| bad(format!("missing tensor {name}")))?;
        if t.shape != shape {
            return Err(bad(format!(
                "{name}: shape {:?}, expected {shape:?}",
                t.shape
            )));
        }
        Ok(t.data.clone())
    }
}
