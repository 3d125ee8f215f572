//! The appearance storage of version 2 and later: `f32`, `f16`, `i8` or `i6` with a scale per
//! mode, and the bit packing.

use super::*;
use crate::model::appearance::AppearanceModel;

/// How a version-2 file stores the appearance base `A0` and modes (everything else is always
/// stored exactly, as `f32` / `u32`). Specified in `docs/model-format.md`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Storage {
    /// Exact: `f32` base and modes (tag 0; the only storage of version 1).
    F32,
    /// IEEE binary16 base and modes (tag 1): half the bytes, relative rounding `2^-11`.
    F16,
    /// Tag 2: the base as `u8` levels `q / 255`, each mode as `i8` values `q * scale_i` with one
    /// `f32` scale per mode; about a quarter of the bytes.
    I8,
    /// The compact default (tag 3): as [`Storage::I8`] with the mode values packed in 6 bits
    /// (about a fifth of the bytes).
    #[default]
    I6,
}

impl Storage {
    /// Every storage, in tag order.
    pub const ALL: [Storage; 4] = [Storage::F32, Storage::F16, Storage::I8, Storage::I6];

    /// The tag stored at header offset 12 in version 2.
    pub fn tag(self) -> u32 {
        match self {
            Storage::F32 => 0,
            Storage::F16 => 1,
            Storage::I8 => 2,
            Storage::I6 => 3,
        }
    }

    /// The storage of a tag.
    pub fn from_tag(tag: u32) -> Option<Storage> {
        Storage::ALL.into_iter().find(|s| s.tag() == tag)
    }

    /// Its name: `f32`, `f16`, `i8` or `i6` (as `facemimic build --precision` takes it).
    pub fn name(self) -> &'static str {
        match self {
            Storage::F32 => "f32",
            Storage::F16 => "f16",
            Storage::I8 => "i8",
            Storage::I6 => "i6",
        }
    }

    /// Bits per stored mode value.
    pub fn mode_bits(self) -> u32 {
        match self {
            Storage::F32 => 32,
            Storage::F16 => 16,
            Storage::I8 => 8,
            Storage::I6 => 6,
        }
    }
}

impl std::fmt::Display for Storage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Storage {
    type Err = String;
    fn from_str(s: &str) -> Result<Storage, String> {
        Storage::ALL
            .into_iter()
            .find(|x| x.name() == s)
            .ok_or_else(|| format!("unknown precision '{s}' (expected f32, f16, i8 or i6)"))
    }
}

/// The header field at offset 12: reserved flags (0) in version 1, the storage tag in version 2.
pub(super) fn parse_storage_field(version: u32, value: u32) -> Result<Storage, FormatError> {
    if version == 1 {
        return match value {
            0 => Ok(Storage::F32),
            _ => Err(FormatError::ReservedFlags { value }),
        };
    }
    Storage::from_tag(value).ok_or(FormatError::BadStorageTag { tag: value })
}

/// Bytes of the appearance section (base, modes, variances and, for i8, the scales) for `3N =
/// px3` values per vector and `l` modes; `None` on overflow.
pub(super) fn appearance_bytes(storage: Storage, px3: u64, l: u64) -> Option<u64> {
    let values = px3.checked_mul(l)?.checked_add(px3)?;
    match storage {
        Storage::F32 => values.checked_add(l)?.checked_mul(4),
        Storage::F16 => round4(values.checked_mul(2)?)?.checked_add(4 * l),
        Storage::I8 | Storage::I6 => {
            let bits = px3
                .checked_mul(l)?
                .checked_mul(storage.mode_bits() as u64)?;
            round4(px3.checked_add(bits.checked_add(7)? / 8)?)?.checked_add(8 * l)
        }
    }
}

pub(super) fn round4(x: u64) -> Option<u64> {
    x.checked_add(3).map(|v| v & !3)
}

/// Decodes an IEEE binary16 value.
pub(super) fn f16_to_f32(bits: u16) -> f32 {
    half::f16::from_bits(bits).to_f32()
}

/// The scale and `bits`-bit values of one mode: `q = round(v / s0)` with `s0 = max|v| / qmax`,
/// `qmax = 2^(bits-1) - 1`, then the scale `1 / |q|` so that the decoded mode `q * scale` has
/// unit norm like the `f32` one (a model read from such a file encodes back to the same bytes).
pub(super) fn quantise_mode(mode: &[f32], bits: u32, q: &mut Vec<i8>) -> f32 {
    let qmax = ((1i32 << (bits - 1)) - 1) as f32;
    let peak = mode.iter().fold(0f32, |a, &v| a.max(v.abs()));
    let s0 = if peak > 0.0 && peak.is_finite() {
        peak / qmax
    } else {
        1.0
    };
    let mut norm2 = 0f64;
    for &v in mode {
        let k = (v / s0).round().clamp(-qmax, qmax) as i8;
        norm2 += (k as f64) * (k as f64);
        q.push(k);
    }
    if norm2 > 0.0 {
        (1.0 / norm2.sqrt()) as f32
    } else {
        s0
    }
}

/// Writes the appearance section (layout in `docs/model-format.md`, "Appearance storage").
pub(super) fn write_appearance(out: &mut Vec<u8>, a: &AppearanceModel, storage: Storage) {
    let f32le = |out: &mut Vec<u8>, v: f32| out.extend_from_slice(&v.to_le_bytes());
    let start = out.len();
    let a = a.linear();
    match storage {
        Storage::F32 => {
            for &v in a.base.iter().chain(&a.modes) {
                f32le(out, v);
            }
        }
        Storage::F16 => {
            for &v in a.base.iter().chain(&a.modes) {
                out.extend_from_slice(&half::f16::from_f32(v).to_bits().to_le_bytes());
            }
        }
        Storage::I8 | Storage::I6 => {
            let d = a.base.len();
            let bits = storage.mode_bits();
            let mut q = Vec::with_capacity(a.modes.len());
            let scales: Vec<f32> = if d == 0 {
                Vec::new()
            } else {
                a.modes
                    .chunks_exact(d)
                    .map(|m| quantise_mode(m, bits, &mut q))
                    .collect()
            };
            scales.iter().for_each(|&s| f32le(out, s));
            let base_start = out.len();
            out.extend(
                a.base
                    .iter()
                    .map(|&v| (v.clamp(0.0, 1.0) * 255.0).round() as u8),
            );
            pack_bits(&q, bits, out);
            let pad = pad4((out.len() - base_start) as u64) as usize;
            out.extend(std::iter::repeat_n(0u8, pad));
        }
    }
    if storage == Storage::F16 {
        let pad = pad4((out.len() - start) as u64) as usize;
        out.extend(std::iter::repeat_n(0u8, pad));
    }
    a.variances.iter().for_each(|&v| f32le(out, v));
}

/// Reads and validates the appearance section, expanded to `f32`
/// (non-finite values, scales that are not positive and non-zero padding are rejected).
pub(super) fn read_appearance(
    c: &mut Cursor<'_>,
    storage: Storage,
    px3: usize,
    l: usize,
) -> Result<AppearanceModel, FormatError> {
    let values = px3 * (l + 1);
    let (base, modes) = match storage {
        Storage::F32 => (
            c.f32s(px3, "appearance base")?,
            c.f32s(px3 * l, "appearance modes")?,
        ),
        Storage::F16 => {
            let bytes = c.take(2 * values)?;
            let mut base = Vec::with_capacity(px3);
            let mut modes = Vec::with_capacity(px3 * l);
            for (i, h) in bytes.chunks_exact(2).enumerate() {
                let v = f16_to_f32(u16::from_le_bytes(le_at(h, 0)));
                let (array, index, dst) = if i < px3 {
                    ("appearance base", i, &mut base)
                } else {
                    ("appearance modes", i - px3, &mut modes)
                };
                if !v.is_finite() {
                    return Err(FormatError::NonFinite {
                        array,
                        index: index as u64,
                    });
                }
                dst.push(v);
            }
            check_padding(c, 2 * values)?;
            (base, modes)
        }
        Storage::I8 | Storage::I6 => {
            let bits = storage.mode_bits() as usize;
            let scales = c.f32s(l, "appearance mode scales")?;
            if let Some(i) = scales.iter().position(|&s| s <= 0.0) {
                return Err(FormatError::InvalidScale {
                    array: "appearance mode scales",
                    index: i as u32,
                    value: scales[i],
                });
            }
            let base = c.take(px3)?.iter().map(|&q| q as f32 / 255.0).collect();
            let packed = c.take((px3 * l * bits).div_ceil(8))?;
            let mut modes = Vec::with_capacity(px3 * l);
            let mut values = unpack_bits(packed, bits as u32);
            for &s in &scales {
                modes.extend(values.by_ref().take(px3).map(|k| k as f32 * s));
            }
            check_padding(c, px3 + packed.len())?;
            (base, modes)
        }
    };
    let variances = c.f32s(l, "appearance variances")?;
    Ok(AppearanceModel::new(base, modes, variances))
}

/// Consumes the zero padding after `len` bytes of 1- or 2-byte values.
pub(super) fn check_padding(c: &mut Cursor<'_>, len: usize) -> Result<(), FormatError> {
    let pad = pad4(len as u64) as usize;
    if c.take(pad)?.iter().any(|&b| b != 0) {
        return Err(FormatError::NonZeroPadding);
    }
    Ok(())
}

/// Appends `q` as `bits`-bit two's-complement values, packed least significant bit first (value
/// `k` occupies stream bits `[k*bits, (k+1)*bits)`, stream bit `j` being bit `j mod 8` of byte
/// `j / 8`); the last byte's unused high bits are 0. With 8 bits this is plain `i8` bytes.
pub(super) fn pack_bits(q: &[i8], bits: u32, out: &mut Vec<u8>) {
    let mask = (1u32 << bits) - 1;
    let (mut acc, mut n) = (0u32, 0u32);
    for &k in q {
        acc |= (k as i32 as u32 & mask) << n;
        n += bits;
        while n >= 8 {
            out.push(acc as u8);
            acc >>= 8;
            n -= 8;
        }
    }
    if n > 0 {
        out.push(acc as u8);
    }
}

/// The `bits`-bit two's-complement values packed by [`pack_bits`] (sign-extended).
pub(super) fn unpack_bits(bytes: &[u8], bits: u32) -> impl Iterator<Item = i32> + '_ {
    let shift = 32 - bits;
    let (mut acc, mut n) = (0u32, 0u32);
    let mut it = bytes.iter();
    std::iter::from_fn(move || {
        while n < bits {
            acc |= (*it.next()? as u32) << n;
            n += 8;
        }
        let v = ((acc << shift) as i32) >> shift;
        acc >>= bits;
        n -= bits;
        Some(v)
    })
}
