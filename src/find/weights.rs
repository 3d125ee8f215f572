//! The finder's weight files (`data/weights/*.fmw`, made by `scripts/convert-mediapipe.py` and
//! `scripts/quantise-fmw.py`).
//!
//! Layout (little-endian): the magic `FMW1`, a `u32` tensor count, then per tensor a `u32` name
//! length and the UTF-8 name (e.g. `op12/w`), a `u32` rank and that many `u32` dimensions (the
//! layout of `scripts/convert-mediapipe.py`'s header), a `u32` encoding and the values:
//!
//! - 0: float32 values;
//! - 1: no longer read (face-api.js's per-tensor uint8, whose nets the crate no longer ships);
//! - 2: float16 values, as MediaPipe's TFLite files store them (`scripts/convert-mediapipe.py`);
//! - 3: int8 values per channel, symmetric (`scripts/quantise-fmw.py`): a `u32` axis (below the
//!   rank: the output-channel axis, e.g. 0 for MediaPipe's convolutions `[cout, kh, kw, cin]`, 3
//!   for its depthwise filters `[1, kh, kw, c]`), one `f32` scale per index along that axis
//!   (finite, not negative), then the values as `i8` `q` in row-major order; value = scale of
//!   the value's index along the axis * q.

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
    /// The next `n` values of `size` bytes each.
    fn items(&mut self, n: usize, size: usize) -> Result<&'a [u8]> {
        let bytes = n
            .checked_mul(size)
            .ok_or_else(|| bad("truncated weight file"))?;
        self.take(bytes)
    }
}

/// Encoding 3 (see the module's documentation): per-channel symmetric int8 of `shape`.
fn int8_per_channel(r: &mut Reader, name: &str, shape: &[usize], len: usize) -> Result<Vec<f32>> {
    let axis = r.u32()? as usize;
    if axis >= shape.len() {
        return Err(bad(format!(
            "{name}: channel axis {axis} of a rank {} tensor",
            shape.len()
        )));
    }
    let channels = shape[axis];
    // The stride of the axis in row-major order (the dimensions after it).
    let inner: usize = shape[axis + 1..].iter().product();
    let scales: Vec<f32> = r
        .items(channels, 4)?
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    if let Some(s) = scales.iter().find(|s| !(s.is_finite() && **s >= 0.0)) {
        return Err(bad(format!("{name}: channel scale {s}")));
    }
    Ok(r.take(len)?
        .iter()
        .enumerate()
        .map(|(i, &q)| scales[(i / inner) % channels] * q as i8 as f32)
        .collect())
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
                    .items(len, 4)?
                    .chunks_exact(4)
                    .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                    .collect(),
                2 => r
                    .items(len, 2)?
                    .chunks_exact(2)
                    .map(|b| half::f16::from_le_bytes([b[0], b[1]]).to_f32())
                    .collect(),
                3 => int8_per_channel(&mut r, &name, &shape, len)?,
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
    pub fn tensor(&self, name: &str) -> Option<&Tensor> {
        self.tensors.iter().find(|t| t.name == name)
    }

    /// The tensor `name`, checked to have `shape` (the format's tests).
    #[cfg(test)]
    pub fn get(&self, name: &str, shape: &[usize]) -> Result<Vec<f32>> {
        let t = self
            .tensor(name)
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A weight file of one tensor: `name`, `shape`, `encoding` and the bytes after it.
    fn file(shape: &[u32], encoding: u32, body: &[u8]) -> Vec<u8> {
        let mut b = b"FMW1".to_vec();
        b.extend(1u32.to_le_bytes());
        b.extend(1u32.to_le_bytes());
        b.push(b'w');
        b.extend((shape.len() as u32).to_le_bytes());
        for d in shape {
            b.extend(d.to_le_bytes());
        }
        b.extend(encoding.to_le_bytes());
        b.extend(body);
        b
    }

    /// Encoding 3's body: axis, scales, values.
    fn int8_body(axis: u32, scales: &[f32], q: &[i8]) -> Vec<u8> {
        let mut b = axis.to_le_bytes().to_vec();
        for s in scales {
            b.extend(s.to_le_bytes());
        }
        b.extend(q.iter().map(|&v| v as u8));
        b
    }

    fn weights_error(bytes: &[u8]) -> String {
        match Weights::parse(bytes) {
            Err(Error::Weights(m)) => m,
            other => panic!("expected a weights error, got {other:?}"),
        }
    }

    #[test]
    fn int8_per_channel_dequantises_along_its_axis() {
        let q = [1, -2, 3, 127, -127, 0];
        // [2, 3], channels along axis 0: rows scaled by 0.5 and 2.
        let w = Weights::parse(&file(&[2, 3], 3, &int8_body(0, &[0.5, 2.0], &q))).unwrap();
        assert_eq!(
            w.get("w", &[2, 3]).unwrap(),
            [0.5, -1.0, 1.5, 254.0, -254.0, 0.0]
        );
        // The same values with channels along axis 1: columns scaled by 1, 0.25 and 0.
        let w = Weights::parse(&file(&[2, 3], 3, &int8_body(1, &[1.0, 0.25, 0.0], &q))).unwrap();
        assert_eq!(
            w.get("w", &[2, 3]).unwrap(),
            [1.0, -0.5, 0.0, 127.0, -31.75, 0.0]
        );
        // A middle axis of a rank-4 tensor: [1, 2, 1, 2], axis 1.
        let w = Weights::parse(&file(&[1, 2, 1, 2], 3, &int8_body(1, &[1.0, 3.0], &q[..4])));
        assert_eq!(
            w.unwrap().get("w", &[1, 2, 1, 2]).unwrap(),
            [1.0, -2.0, 9.0, 381.0]
        );
    }

    #[test]
    fn int8_per_channel_rejects_bad_files() {
        let good = file(&[2, 3], 3, &int8_body(0, &[0.5, 2.0], &[1, 2, 3, 4, 5, 6]));
        Weights::parse(&good).unwrap();
        // Every truncation is an error, never a panic.
        for n in 0..good.len() {
            assert!(Weights::parse(&good[..n]).is_err(), "{n} bytes");
            weights_error(&good[..n]);
        }
        let mut long = good.clone();
        long.push(0);
        assert!(weights_error(&long).contains("trailing"));
        // The axis must be below the rank.
        let m = weights_error(&file(&[2, 3], 3, &int8_body(2, &[1.0, 1.0], &[0; 6])));
        assert!(m.contains("axis"), "{m}");
        // Scales: finite and not negative.
        for s in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -1.0] {
            let m = weights_error(&file(&[2, 3], 3, &int8_body(0, &[1.0, s], &[0; 6])));
            assert!(m.contains("scale"), "{s}: {m}");
        }
        // A scalar has no channel axis.
        let m = weights_error(&file(&[], 3, &int8_body(0, &[], &[0])));
        assert!(m.contains("axis"), "{m}");
        // Huge channel counts with no values: an error, not an overflow or an allocation.
        let m = weights_error(&file(&[0, u32::MAX], 3, &int8_body(1, &[], &[])));
        assert!(m.contains("truncated"), "{m}");
        // Unknown encodings.
        let m = weights_error(&file(&[1], 4, &[0]));
        assert!(m.contains("encoding 4"), "{m}");
    }

    #[test]
    fn float_encodings_still_parse() {
        let w = Weights::parse(&file(&[2], 0, &[0, 0, 128, 63, 0, 0, 0, 192])).unwrap();
        assert_eq!(w.get("w", &[2]).unwrap(), [1.0, -2.0]);
        let w = Weights::parse(&file(&[2], 2, &[0, 60, 0, 192])).unwrap();
        assert_eq!(w.get("w", &[2]).unwrap(), [1.0, -2.0]);
        // Encoding 1 (face-api.js's uint8) is refused now that nothing ships in it.
        let m = weights_error(&file(&[2], 1, &[0, 0, 0, 63, 0, 0, 128, 63, 0, 4]));
        assert!(m.contains("encoding 1"), "{m}");
        let m = weights_error(&file(&[4], 2, &[0, 60, 0, 192]));
        assert!(m.contains("truncated"), "{m}");
    }
}
