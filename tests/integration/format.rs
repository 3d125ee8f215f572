//! The `.fmm` model file: exact round trips, a table of corrupt / truncated / hostile files each
//! rejected with the expected error, random bytes and random mutations that never panic, and
//! hostile headers that neither allocate nor take time.
//!
//! The models are synthetic (built in memory from generated landmarks and RGBA images), so the
//! numeric tests also run under wasm (`cargo test --target wasm32-unknown-unknown --test
//! format`). The allocation-counting test is native only.

use facemimic_testkit as common;
use facemimic_testkit::fuzz as engine;

use std::sync::OnceLock;

use common::Rng;

use facemimic::format::{
    crc32, offsets, read_model, read_model_info, write_model, write_model_as, FileInfo,
    FormatError, Storage, FORMAT_VERSION, HEADER_LEN, LIMITS, MAGIC, OLDEST_VERSION,
};
use Expect::{Exact, Like};
use FormatError as E;

use facemimic::{
    BuildOptions, Builder, FrameChoice, Model, Reference, ReferenceChoice, TrainingImage,
};

// ------------------------------------------------------------------------------------------
// Synthetic models.

/// `count` synthetic training images (`common::synthetic`) with `n` landmarks on 96x96 images.
fn training_set(n: usize, count: usize, seed: u64, prefix: &str) -> Vec<TrainingImage> {
    common::synthetic::training_set(n, count, seed, 96, prefix)
}

struct Models {
    /// 68 landmarks (iBUG scheme), its own frame, mean reference, name of 7 bytes (1 pad byte).
    a: Model,
    /// Built in `a`'s frame with a named reference and a non-ASCII name.
    b: Model,
    /// 30 landmarks (generic scheme), no modes at all (a mean-only model).
    c: Model,
}

fn models() -> &'static Models {
    static MODELS: OnceLock<Models> = OnceLock::new();
    MODELS.get_or_init(|| {
        let opts = |name: &str| BuildOptions {
            name: name.into(),
            face_width: 40.0,
            frame: FrameChoice::Own,
            ..BuildOptions::default()
        };
        let a = Builder::new(opts("synth-a"))
            .build(&training_set(68, 6, 7, "a"), None)
            .unwrap();
        let b = Builder::new(BuildOptions {
            reference: ReferenceChoice::Named("b3".into()),
            ..opts("synth-b \u{2713}")
        })
        .build(&training_set(68, 6, 99, "b"), Some(&a))
        .unwrap();
        let c = Builder::new(BuildOptions {
            max_shape_modes: 0,
            max_appearance_modes: 0,
            ..opts("c")
        })
        .build(&training_set(30, 6, 3, "c"), None)
        .unwrap();
        Models { a, b, c }
    })
}

// ------------------------------------------------------------------------------------------
// Byte surgery.

fn get_u32(b: &[u8], off: usize) -> u32 {
    u32::from_le_bytes(b[off..off + 4].try_into().unwrap())
}
fn set_u32(b: &mut [u8], off: usize, v: u32) {
    b[off..off + 4].copy_from_slice(&v.to_le_bytes());
}
fn set_u64(b: &mut [u8], off: usize, v: u64) {
    b[off..off + 8].copy_from_slice(&v.to_le_bytes());
}
fn set_f32(b: &mut [u8], off: usize, v: f32) {
    set_u32(b, off, v.to_bits());
}
fn get_f32(b: &[u8], off: usize) -> f32 {
    f32::from_bits(get_u32(b, off))
}
/// Rewrites the trailing CRC-32 so that the checksum is not what rejects the file.
fn fix_crc(b: &mut [u8]) {
    let body = b.len() - 4;
    let c = crc32(&b[..body]);
    set_u32(b, body, c);
}
fn patched(v: &[u8], off: usize, val: u32) -> Vec<u8> {
    let mut b = v.to_vec();
    set_u32(&mut b, off, val);
    b
}

/// Byte offsets of the arrays of a written model.
struct Layout {
    pad: usize,
    shape_base: usize,
    shape_modes: usize,
    shape_variances: usize,
    vertices: usize,
    triangles: usize,
    app_base: usize,
    app_modes: usize,
    app_variances: usize,
    crc: usize,
}

fn layout(m: &Model) -> Layout {
    let names = m.name().len()
        + match &m.reference() {
            Reference::Mean => 0,
            Reference::Training(s) => s.len(),
        };
    let pad = HEADER_LEN + names;
    let shape_base = pad + (4 - names % 4) % 4;
    let shape_modes = shape_base + 4 * m.shape().base.len();
    let shape_variances = shape_modes + 4 * m.shape().modes.len();
    let vertices = shape_variances + 4 * m.shape().variances.len();
    let triangles = vertices + 4 * m.frame().vertices().len();
    let app_base = triangles + 12 * m.frame().triangles().len();
    let app_modes = app_base + 4 * m.appearance().len();
    let app_variances = app_modes + 4 * m.appearance().len() * m.appearance().n_modes();
    let crc = app_variances + 4 * m.appearance().n_modes();
    Layout {
        pad,
        shape_base,
        shape_modes,
        shape_variances,
        vertices,
        triangles,
        app_base,
        app_modes,
        app_variances,
        crc,
    }
}

// ------------------------------------------------------------------------------------------
// Round trips.

#[wasm_bindgen_test::wasm_bindgen_test(unsupported = test)]
fn round_trip_is_exact() {
    let ms = models();
    for m in [&ms.a, &ms.b, &ms.c] {
        let bytes = write_model_as(m, Storage::F32);
        assert_eq!(&bytes[..8], &MAGIC);
        assert_eq!(get_u32(&bytes, offsets::VERSION), FORMAT_VERSION);
        assert_eq!(bytes.len(), layout(m).crc + 4, "layout of '{}'", m.name());
        let back = read_model(&bytes).unwrap_or_else(|e| panic!("'{}': {e}", m.name()));
        assert_eq!(&back, m);
        // Fields PartialEq on the frame does not cover: the recomputed pixels and padding.
        assert_eq!(back.frame().pixels(), m.frame().pixels());
        assert_eq!(back.frame().padding(), m.frame().padding());
        assert_eq!(back.frame().fingerprint(), m.frame().fingerprint());
        // Writing is deterministic: a second round gives the same bytes.
        assert_eq!(write_model_as(&back, Storage::F32), bytes);
    }
    // The three models exercise the scheme tags, both reference kinds and zero modes.
    assert_eq!(ms.a.scheme(), facemimic::LandmarkScheme::Ibug68);
    assert_eq!(ms.c.scheme(), facemimic::LandmarkScheme::Generic(30));
    assert_eq!(*ms.b.reference(), Reference::Training("b3".into()));
    assert_eq!(ms.b.frame(), ms.a.frame());
    assert!(ms.a.shape().n_modes() > 1 && ms.a.appearance().n_modes() > 1);
    assert_eq!(
        (ms.c.shape().n_modes(), ms.c.appearance().n_modes()),
        (0, 0)
    );
}

/// Bytes of the appearance section of a version-2 file (the spec's formula, re-derived here).
fn appearance_section_len(m: &Model, s: Storage) -> usize {
    let (px3, l) = (m.appearance().len(), m.appearance().n_modes());
    let round4 = |x: usize| x.div_ceil(4) * 4;
    match s {
        Storage::F32 => 4 * (px3 + px3 * l + l),
        Storage::F16 => round4(2 * (px3 + px3 * l)) + 4 * l,
        Storage::I8 => 4 * l + round4(px3 + px3 * l) + 4 * l,
        Storage::I6 => 4 * l + round4(px3 + (6 * px3 * l).div_ceil(8)) + 4 * l,
    }
}

/// Every storage reads back within its rounding, everything but the appearance base and modes
/// exactly; a model read from a file writes back the same bytes in the same storage; the sizes
/// follow the specification's formula.
#[wasm_bindgen_test::wasm_bindgen_test(unsupported = test)]
fn every_storage_round_trips_within_its_rounding() {
    let ms = models();
    for m in [&ms.a, &ms.b, &ms.c] {
        let mut sizes = Vec::new();
        for s in Storage::ALL {
            let bytes = write_model_as(m, s);
            let what = format!("'{}' as {s}", m.name());
            assert_eq!(get_u32(&bytes, offsets::VERSION), FORMAT_VERSION, "{what}");
            assert_eq!(get_u32(&bytes, offsets::STORAGE), s.tag(), "{what}");
            assert_eq!(
                bytes.len(),
                layout(m).app_base + appearance_section_len(m, s) + 4,
                "{what}: length"
            );
            let (back, info) = read_model_info(&bytes).unwrap_or_else(|e| panic!("{what}: {e}"));
            assert_eq!(
                info,
                FileInfo {
                    version: FORMAT_VERSION,
                    storage: s,
                    backdrop_bytes: 0,
                    backdrop_notice: None,
                }
            );
            // Everything but the appearance base and modes is exact.
            let mut same = back.clone().into_parts();
            let (_, _, variances) = same.appearance.into_arrays();
            same.appearance = facemimic::AppearanceModel::new(
                m.appearance().base().to_vec(),
                (0..m.appearance().n_modes())
                    .flat_map(|i| m.appearance().mode(i).unwrap_or(&[]).to_vec())
                    .collect(),
                variances,
            );
            assert_eq!(&Model::new(same).unwrap(), m, "{what}");
            // The base within its rounding.
            let base_tol = |v: f32| match s {
                Storage::F32 => 0.0,
                Storage::F16 => v.abs() / 2048.0,
                Storage::I8 | Storage::I6 => 0.5 / 255.0 + 1e-6,
            };
            for (a, b) in back.appearance().base().iter().zip(m.appearance().base()) {
                assert!((a - b).abs() <= base_tol(*b), "{what}: base {a} vs {b}");
            }
            // Each mode within one quantisation step, and still of unit norm.
            let modes = |m: &Model| {
                (0..m.appearance().n_modes())
                    .map(|i| m.appearance().mode(i).unwrap_or(&[]).to_vec())
                    .collect::<Vec<_>>()
            };
            for (i, (q, v)) in modes(&back).iter().zip(&modes(m)).enumerate() {
                let peak = v.iter().fold(0f32, |a, x| a.max(x.abs()));
                let step = match s {
                    Storage::F32 => 0.0,
                    Storage::F16 => peak / 2048.0,
                    Storage::I8 => 1.01 * peak / 127.0,
                    Storage::I6 => 1.01 * peak / 31.0,
                };
                let worst = q.iter().zip(v).fold(0f32, |a, (x, y)| a.max((x - y).abs()));
                assert!(
                    worst <= step,
                    "{what}: mode {i} off by {worst}, step {step}"
                );
                let norm: f64 = q.iter().map(|&x| x as f64 * x as f64).sum();
                assert!((norm - 1.0).abs() < 1e-4, "{what}: mode {i} norm^2 {norm}");
            }
            // Converting again changes nothing: the same bytes.
            assert_eq!(write_model_as(&back, s), bytes, "{what}: second round");
            sizes.push(bytes.len());
        }
        if m.appearance().n_modes() > 0 {
            assert!(
                sizes.windows(2).all(|w| w[1] < w[0]),
                "'{}': sizes {sizes:?} not decreasing f32 > f16 > i8 > i6",
                m.name()
            );
        }
    }
    // The default is the compact storage.
    assert_eq!(Storage::default(), Storage::I6);
    assert_eq!(write_model(&ms.a), write_model_as(&ms.a, Storage::I6));
    for s in Storage::ALL {
        assert_eq!(s.name().parse::<Storage>(), Ok(s));
        assert_eq!(Storage::from_tag(s.tag()), Some(s));
    }
    assert!("f64".parse::<Storage>().is_err());
}

/// A version-1 file kept in the repository (`tests/data/tiny-v1.fmm`, written by the version-1
/// writer before version 2 existed: 6 frames of GRID spk07, a 28-pixel face, 3 shape and 4
/// appearance modes) still loads, equal to what it was: version 2 with exact storage is version
/// 1's layout, so saving it again changes only the version field and the checksum.
#[wasm_bindgen_test::wasm_bindgen_test(unsupported = test)]
fn a_version_1_file_still_loads_as_it_was() {
    let v1: &[u8] = include_bytes!("../data/tiny-v1.fmm");
    assert_eq!(v1.len(), 46768);
    assert_eq!(get_u32(v1, offsets::VERSION), OLDEST_VERSION);
    // The fixture is the one written by the version-1 writer (its stored CRC-32).
    assert_eq!(get_u32(v1, v1.len() - 4), 0x5995_483b);
    let (m, info) = read_model_info(v1).expect("the version-1 file loads");
    assert_eq!(
        info,
        FileInfo {
            version: 1,
            storage: Storage::F32,
            backdrop_bytes: 0,
            backdrop_notice: None,
        }
    );
    assert_eq!(m.name(), "tiny-v1");
    assert_eq!(m.scheme(), facemimic::LandmarkScheme::Ibug68);
    assert_eq!((m.shape().n_modes(), m.appearance().n_modes()), (3, 4));
    assert_eq!(
        (m.frame().width(), m.frame().height(), m.frame().n_pixels()),
        (36, 39, 709)
    );
    assert_eq!(m.frame().fingerprint(), 0xcade_b8ab_086e_0def);
    assert_eq!(m.image_size(), [360, 288]);
    // Convert on save: every byte but the version and the checksum as it was.
    let v2 = write_model_as(&m, Storage::F32);
    assert_eq!(v2.len(), v1.len());
    assert_eq!(get_u32(&v2, offsets::VERSION), FORMAT_VERSION);
    assert_eq!(&v2[..8], &v1[..8]);
    assert_eq!(&v2[12..v1.len() - 4], &v1[12..v1.len() - 4]);
    assert_eq!(read_model(&v2).unwrap(), m);
    // And into the compact default, within its rounding.
    let compact = read_model(&write_model(&m)).unwrap();
    assert_eq!(compact.shape(), m.shape());
    assert_eq!(compact.frame(), m.frame());
    let worst = compact
        .appearance()
        .base()
        .iter()
        .zip(m.appearance().base())
        .fold(0f32, |a, (x, y)| a.max((x - y).abs()));
    assert!(worst <= 0.5 / 255.0 + 1e-6, "base off by {worst}");
}

/// Version-2 specific bad files: the storage's scales, values, padding and lengths.
fn compact_bad_cases() -> Vec<Case> {
    let mut cases = quantised_cases(Storage::I8);
    cases.extend(quantised_cases(Storage::I6));
    cases.extend(f16_cases());
    cases
}

/// Model `a` stored as `s` (i8 or i6): its scales, quantised values, padding and label.
fn quantised_cases(s: Storage) -> Vec<Case> {
    let a = &models().a;
    let lay = layout(a);
    let (px3, l) = (a.appearance().len(), a.appearance().n_modes());
    let v = write_model_as(a, s);
    let v = &v;
    let scales = lay.app_base;
    let array = "appearance mode scales";
    let scale_times = |index: usize, factor: f32| {
        fixed(v, |x| {
            let at = scales + 4 * index;
            let value = get_f32(x, at);
            set_f32(x, at, factor * value)
        })
    };
    let mode_bytes = (px3 * l * s.mode_bits() as usize).div_ceil(8);
    let packed_end = scales + 4 * l + px3 + mode_bytes;
    let variances = v.len() - 4 - 4 * l;
    assert!(packed_end <= variances);
    let other = if s == Storage::I8 {
        Storage::I6
    } else {
        Storage::I8
    };
    let mut cases = vec![
        case(
            format!("{s}: NaN scale"),
            fixed(v, |x| set_f32(x, scales + 4, f32::NAN)),
            Exact(E::NonFinite { array, index: 1 }),
        ),
        case(
            format!("{s}: infinite scale"),
            fixed(v, |x| set_f32(x, scales, f32::INFINITY)),
            Exact(E::NonFinite { array, index: 0 }),
        ),
        case(
            format!("{s}: zero scale"),
            fixed(v, |x| set_f32(x, scales + 8, 0.0)),
            Exact(E::InvalidScale {
                array,
                index: 2,
                value: 0.0,
            }),
        ),
        case(
            format!("{s}: negative scale"),
            scale_times(0, -1.0),
            Like("InvalidScale", |e| {
                matches!(e, E::InvalidScale { index: 0, .. })
            }),
        ),
        case(
            format!("{s}: scale doubled"),
            scale_times(1, 2.0),
            Like("NotOrthonormal of mode 1", |e| {
                matches!(e, E::NotOrthonormal { i: 1, j: 1, .. })
            }),
        ),
        case(
            format!("{s}: negative appearance variance"),
            fixed(v, |x| set_f32(x, variances, -1.0)),
            Like("NegativeVariance", |e| {
                matches!(e, E::NegativeVariance { .. })
            }),
        ),
        case(
            format!("{s}: a mode byte flipped"),
            changed(v, |x| x[scales + 4 * l + px3 + 3] ^= 0x10),
            checksum_mismatch(),
        ),
        case(
            format!("{s}: truncated by one byte"),
            v[..v.len() - 1].to_vec(),
            truncated(v.len() as u64, v.len() as u64 - 1),
        ),
        // A label implying more bytes than the file has is a length mismatch; one implying
        // fewer leaves bytes that version 3 would read as sections, and the checksum (over a
        // header that was changed) refuses the file first.
        case(
            format!("{s}: labelled {other}"),
            patched(v, offsets::STORAGE, other.tag()),
            Like("LengthMismatch or ChecksumMismatch", |e| {
                matches!(e, E::LengthMismatch { .. } | E::ChecksumMismatch { .. })
            }),
        ),
        case(
            format!("{s}: labelled version 1"),
            patched(v, offsets::VERSION, 1),
            Exact(E::ReservedFlags { value: s.tag() }),
        ),
    ];
    if packed_end < variances {
        cases.push(case(
            format!("{s}: non-zero padding after the modes"),
            fixed(v, |x| x[variances - 1] = 1),
            Exact(E::NonZeroPadding),
        ));
    }
    cases
}

/// Model `a` stored as f16: non-finite values, padding, modes no longer orthonormal.
fn f16_cases() -> Vec<Case> {
    let a = &models().a;
    let (px3, l) = (a.appearance().len(), a.appearance().n_modes());
    let v = write_model_as(a, Storage::F16);
    let v = &v;
    let base = layout(a).app_base;
    let modes = base + 2 * px3;
    let half_at = |at: usize, h: u16| fixed(v, |x| x[at..at + 2].copy_from_slice(&h.to_le_bytes()));
    let mut cases = vec![
        case(
            "f16: NaN in the base",
            half_at(base, 0x7E00),
            non_finite("appearance base", 0),
        ),
        case(
            "f16: infinity in the modes",
            half_at(modes + 6, 0xFC00),
            non_finite("appearance modes", 3),
        ),
        case(
            "f16: mode 0 scaled by 2",
            fixed(v, |x| {
                for k in 0..px3 {
                    let o = modes + 2 * k;
                    let h = u16::from_le_bytes([x[o], x[o + 1]]);
                    // +1 to the exponent doubles a normal binary16 value.
                    if h & 0x7C00 != 0 && h & 0x7C00 != 0x7800 {
                        x[o..o + 2].copy_from_slice(&(h + 0x0400).to_le_bytes());
                    }
                }
            }),
            Like("NotOrthonormal of mode 0", |e| {
                matches!(e, E::NotOrthonormal { i: 0, j: 0, .. })
            }),
        ),
    ];
    if (2 * px3 * (l + 1)) % 4 != 0 {
        let at = modes + 2 * px3 * l;
        cases.push(case(
            "f16: non-zero padding",
            fixed(v, |x| x[at] = 7),
            Exact(E::NonZeroPadding),
        ));
    }
    cases
}

#[wasm_bindgen_test::wasm_bindgen_test(unsupported = test)]
fn crc32_matches_the_standard_check_value() {
    assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
    assert_eq!(crc32(b""), 0);
}

// ------------------------------------------------------------------------------------------
// The table of bad files.

enum Expect {
    Exact(FormatError),
    Like(&'static str, fn(&FormatError) -> bool),
}

/// A bad file: its name, its bytes and the error expected of it.
type Case = (String, Vec<u8>, Expect);

fn case(name: impl Into<String>, bytes: Vec<u8>, expect: Expect) -> Case {
    (name.into(), bytes, expect)
}

/// `v` changed by `f` (the checksum left as it was).
fn changed(v: &[u8], f: impl FnOnce(&mut Vec<u8>)) -> Vec<u8> {
    let mut x = v.to_vec();
    f(&mut x);
    x
}

/// `v` changed by `f` with the checksum rewritten, so that the validation itself must fire.
fn fixed(v: &[u8], f: impl FnOnce(&mut Vec<u8>)) -> Vec<u8> {
    let mut x = changed(v, f);
    fix_crc(&mut x);
    x
}

fn truncated(needed: u64, available: u64) -> Expect {
    Exact(E::Truncated { needed, available })
}

fn trailing(expected: u64, found: u64) -> Expect {
    Exact(E::TrailingBytes { expected, found })
}

fn length_mismatch(stated: u64, implied: u64) -> Expect {
    Exact(E::LengthMismatch { stated, implied })
}

fn unsupported(found: u32) -> Expect {
    Exact(E::UnsupportedVersion {
        found,
        supported: FORMAT_VERSION,
    })
}

fn over_limit(what: &'static str, value: u32, limit: u32) -> Expect {
    Exact(E::LimitExceeded {
        what,
        value: value as u64,
        limit: limit as u64,
    })
}

fn below(what: &'static str, value: u32, minimum: u32) -> Expect {
    Exact(E::BelowMinimum {
        what,
        value: value as u64,
        minimum: minimum as u64,
    })
}

fn non_finite(array: &'static str, index: u64) -> Expect {
    Exact(E::NonFinite { array, index })
}

fn checksum_mismatch() -> Expect {
    Like("ChecksumMismatch", |e| {
        matches!(e, E::ChecksumMismatch { .. })
    })
}

fn inconsistent() -> Expect {
    Like("InconsistentDimensions", |e| {
        matches!(e, E::InconsistentDimensions(_))
    })
}

/// A header that implies fewer bytes than the file has, with its checksum repaired: version 3
/// reads the rest as sections, so the arrays or the sections' framing refuse it.
fn any_error() -> Expect {
    Like("any error (arrays or sections)", |_| true)
}

/// What the bad files are made from: model `a` written as f32, its length and layout.
struct Base {
    a: &'static Model,
    v: Vec<u8>,
    len: u64,
    lay: Layout,
    /// `a`'s landmarks.
    n: u32,
}

impl Base {
    fn new() -> Base {
        let a = &models().a;
        let v = write_model_as(a, Storage::F32);
        Base {
            a,
            len: v.len() as u64,
            lay: layout(a),
            n: a.landmarks() as u32,
            v,
        }
    }
}

fn bad_cases() -> Vec<Case> {
    let base = Base::new();
    let mut cases = magic_version_and_length_cases(&base);
    cases.extend(header_range_cases(&base));
    cases.extend(header_cases(&base));
    cases.extend(dimension_cases(&base));
    cases.extend(hostile_header_cases(&base));
    cases.extend(payload_cases(&base));
    cases.extend(mode_cases(&base));
    cases.extend(mesh_cases(&base));
    cases
}

/// Magic, version, truncation and trailing bytes.
fn magic_version_and_length_cases(base: &Base) -> Vec<Case> {
    let (v, len) = (&base.v, base.len);
    let n = v.len();
    vec![
        case("empty file", vec![], truncated(HEADER_LEN as u64, 0)),
        case("magic only", MAGIC.to_vec(), truncated(112, 8)),
        case("4 bytes of magic", MAGIC[..4].to_vec(), truncated(112, 4)),
        case(
            "a GIF",
            b"GIF89a\x01\x00\x01\x00".to_vec(),
            Exact(E::BadMagic),
        ),
        case("one byte, not magic", vec![0x00], Exact(E::BadMagic)),
        case(
            "first magic byte changed",
            changed(v, |x| x[0] = b'F'),
            Exact(E::BadMagic),
        ),
        // A text-mode transfer turning \r\n into \n would shift this byte.
        case(
            "CR of the magic changed",
            changed(v, |x| x[4] = b'\n'),
            Exact(E::BadMagic),
        ),
        case("version 0", patched(v, offsets::VERSION, 0), unsupported(0)),
        case(
            "version + 1",
            patched(v, offsets::VERSION, FORMAT_VERSION + 1),
            unsupported(FORMAT_VERSION + 1),
        ),
        case(
            "version u32::MAX in a 12-byte file",
            patched(&v[..12], offsets::VERSION, u32::MAX),
            unsupported(u32::MAX),
        ),
        case("truncated at 50", v[..50].to_vec(), truncated(112, 50)),
        case("truncated at 111", v[..111].to_vec(), truncated(112, 111)),
        case("header only", v[..HEADER_LEN].to_vec(), truncated(len, 112)),
        case(
            "half the file",
            v[..n / 2].to_vec(),
            truncated(len, len / 2),
        ),
        case(
            "checksum missing",
            v[..n - 4].to_vec(),
            truncated(len, len - 4),
        ),
        case(
            "last byte missing",
            v[..n - 1].to_vec(),
            truncated(len, len - 1),
        ),
        case(
            "one trailing byte",
            changed(v, |x| x.push(0)),
            trailing(len, len + 1),
        ),
        case(
            "trailing garbage",
            changed(v, |x| x.extend_from_slice(b"garbage after the model")),
            trailing(len, len + 23),
        ),
        case(
            "two models concatenated",
            changed(v, |x| x.extend_from_slice(v)),
            trailing(len, 2 * len),
        ),
    ]
}

/// The header's counts and sizes out of their range: each below its minimum (0 and the
/// minimum - 1, where there is one), one over its limit, and `u32::MAX`.
fn header_range_cases(base: &Base) -> Vec<Case> {
    // (the name in the cases, the field, the name in the error, its minimum, its limit)
    let ranges = [
        ("landmarks", offsets::LANDMARKS, "landmarks", Some(3), 1024),
        ("triangles", offsets::TRIANGLES, "triangles", Some(1), 8192),
        (
            "frame width",
            offsets::FRAME_WIDTH,
            "frame width",
            Some(1),
            2048,
        ),
        (
            "frame height",
            offsets::FRAME_HEIGHT,
            "frame height",
            Some(1),
            2048,
        ),
        (
            "pixels",
            offsets::PIXELS,
            "frame pixels",
            Some(1),
            4_194_304,
        ),
        (
            "shape modes",
            offsets::SHAPE_MODES,
            "shape modes",
            None,
            256,
        ),
        (
            "appearance modes",
            offsets::APPEARANCE_MODES,
            "appearance modes",
            None,
            256,
        ),
        (
            "name length",
            offsets::NAME_LEN,
            "model name length",
            None,
            256,
        ),
    ];
    let v = &base.v;
    let mut cases = Vec::new();
    for (name, field, what, minimum, limit) in ranges {
        if let Some(min) = minimum {
            let mut lows = vec![0, min - 1];
            lows.dedup();
            for low in lows {
                cases.push(case(
                    format!("{name} {low}"),
                    patched(v, field, low),
                    below(what, low, min),
                ));
            }
        }
        for (label, value) in [("limit+1", limit + 1), ("u32::MAX", u32::MAX)] {
            let bytes = patched(v, field, value);
            cases.push(case(
                format!("{name} {label}"),
                bytes,
                over_limit(what, value, limit),
            ));
        }
    }
    let wb = write_model_as(&models().b, Storage::F32);
    let (image_width, image_height) = (offsets::IMAGE_WIDTH, offsets::IMAGE_HEIGHT);
    cases.extend([
        case(
            "reference name length limit+1",
            patched(&wb, offsets::REFERENCE_NAME_LEN, 257),
            over_limit("reference name length", 257, 256),
        ),
        case(
            "image width 0",
            patched(v, image_width, 0),
            below("image width", 0, 1),
        ),
        case(
            "image height limit+1",
            patched(v, image_height, 8193),
            over_limit("image height", 8193, 8192),
        ),
    ]);
    cases
}

/// `v` with the header's u32 `fields` set: `(offset, value)`.
fn fields(v: &[u8], fields: &[(usize, u32)]) -> Vec<u8> {
    let mut x = v.to_vec();
    for &(off, value) in fields {
        set_u32(&mut x, off, value);
    }
    x
}

/// Header fields: the storage, flags, stated length, tags, origin and pose.
fn header_cases(base: &Base) -> Vec<Case> {
    use offsets::{FILE_LENGTH, ORIGIN_X, ORIGIN_Y, POSE, STORAGE};
    let (v, len) = (&base.v, base.len);
    let i6 = Storage::I6.tag();
    let length = |stated: u64| changed(v, |x| set_u64(x, FILE_LENGTH, stated));
    let f32_at = |off: usize, value: f32| changed(v, |x| set_f32(x, off, value));
    // Values the reader does not know.
    let mut cases = vec![
        case(
            "unknown storage tag",
            patched(v, STORAGE, 4),
            Exact(E::BadStorageTag { tag: 4 }),
        ),
        case(
            "storage tag u32::MAX",
            patched(v, STORAGE, u32::MAX),
            Exact(E::BadStorageTag { tag: u32::MAX }),
        ),
        case(
            "scheme tag 2",
            patched(v, offsets::SCHEME, 2),
            Exact(E::BadSchemeTag { tag: 2 }),
        ),
        case(
            "reference tag 7",
            patched(v, offsets::REFERENCE, 7),
            Exact(E::BadReferenceTag { tag: 7 }),
        ),
    ];
    for found in [4, 0] {
        let bytes = patched(v, offsets::CHANNELS, found);
        let e = Exact(E::UnsupportedChannels { found });
        cases.push(case(format!("channels {found}"), bytes, e));
    }
    cases.extend([
        case(
            "version 1 with reserved flags set",
            fields(v, &[(offsets::VERSION, 1), (offsets::FLAGS, 1)]),
            Exact(E::ReservedFlags { value: 1 }),
        ),
        // Version 3 allows a stated length beyond what the dimensions imply (the sections'
        // bytes): a header that implies fewer bytes than the file has meets the checksum first,
        // and with the checksum repaired, the arrays or the sections' framing.
        case(
            "f32 data labelled i6",
            patched(v, STORAGE, i6),
            checksum_mismatch(),
        ),
        case(
            "f32 data labelled i6, checksum repaired",
            fixed(v, |x| set_u32(x, STORAGE, i6)),
            any_error(),
        ),
        case(
            "stated length + 4",
            length(len + 4),
            truncated(len + 4, len),
        ),
        case(
            "stated length u64::MAX",
            length(u64::MAX),
            truncated(u64::MAX, len),
        ),
        case(
            "origin x NaN",
            f32_at(ORIGIN_X, f32::NAN),
            non_finite("frame origin", 0),
        ),
        case(
            "origin y infinite",
            f32_at(ORIGIN_Y, f32::INFINITY),
            non_finite("frame origin", 1),
        ),
        case(
            "mean pose tx infinite",
            f32_at(POSE + 8, f32::NEG_INFINITY),
            non_finite("mean pose", 2),
        ),
        case(
            "mean reference with a name",
            patched(v, offsets::REFERENCE_NAME_LEN, 3),
            inconsistent(),
        ),
    ]);
    cases
}

/// The header's dimensions against each other and against the file's length.
fn dimension_cases(base: &Base) -> Vec<Case> {
    use offsets::{APPEARANCE_MODES, FRAME_HEIGHT, FRAME_WIDTH, LANDMARKS, PIXELS, SCHEME};
    use offsets::{SHAPE_MODES, TRIANGLES};
    let (a, v, len) = (base.a, &base.v, base.len);
    let (t, px) = (
        a.frame().triangles().len() as u32,
        a.frame().n_pixels() as u32,
    );
    let (w, h) = (a.frame().width(), a.frame().height());
    let (m, l) = (a.shape().n_modes() as u64, a.appearance().n_modes() as u64);
    let mut cases = vec![
        case(
            "landmarks 69 with the iBUG-68 scheme",
            patched(v, LANDMARKS, 69),
            inconsistent(),
        ),
        case(
            "landmarks 69 (generic)",
            fields(v, &[(LANDMARKS, 69), (SCHEME, 0)]),
            length_mismatch(len, len + 4 * (2 * 2 + 2 * m)),
        ),
        case(
            "triangles + 1",
            patched(v, TRIANGLES, t + 1),
            length_mismatch(len, len + 12),
        ),
        case(
            "pixels more than the grid holds",
            patched(v, PIXELS, w * h + 1),
            inconsistent(),
        ),
        case(
            "pixels + 1",
            patched(v, PIXELS, px + 1),
            length_mismatch(len, len + 12 * (1 + l)),
        ),
        case(
            "2048x2048 frame with few pixels",
            fields(v, &[(FRAME_WIDTH, 2048), (FRAME_HEIGHT, 2048)]),
            Exact(E::LimitExceeded {
                what: "frame area (width x height) for the pixel count",
                value: 2048 * 2048,
                limit: 4 * px as u64 + LIMITS.area_slack,
            }),
        ),
        case(
            "more shape modes than shape values",
            fields(v, &[(LANDMARKS, 3), (SCHEME, 0), (SHAPE_MODES, 7)]),
            inconsistent(),
        ),
        case(
            "more appearance modes than appearance values",
            fields(v, &[(PIXELS, 1), (APPEARANCE_MODES, 4)]),
            inconsistent(),
        ),
    ];
    // Fewer bytes implied than the file has: version 3 reads the rest as sections; the
    // checksum refuses the changed header first.
    for (name, field) in [("shape", SHAPE_MODES), ("appearance", APPEARANCE_MODES)] {
        let (zero, repaired) = (patched(v, field, 0), fixed(v, |x| set_u32(x, field, 0)));
        cases.push(case(format!("{name} modes 0"), zero, checksum_mismatch()));
        cases.push(case(
            format!("{name} modes 0, checksum repaired"),
            repaired,
            any_error(),
        ));
    }
    cases
}

/// Hostile headers: a small file claiming a huge model.
fn hostile_header_cases(base: &Base) -> Vec<Case> {
    use offsets::{APPEARANCE_MODES, FRAME_HEIGHT, FRAME_WIDTH, PIXELS, SHAPE_MODES, TRIANGLES};
    let hostile = fields(
        &base.v[..HEADER_LEN],
        &[
            (FRAME_WIDTH, 2048),
            (FRAME_HEIGHT, 2048),
            (PIXELS, 4_194_304),
            (SHAPE_MODES, 136),
            (APPEARANCE_MODES, 256),
            (TRIANGLES, 8192),
        ],
    );
    let huge =
        112 + 8 + 4 * (2 * 68 * 136 + 4 * 68 + 136 + 3 * 8192 + 3 * 4_194_304 * 257 + 256) + 4;
    // The hostile header stating `stated` bytes, in a file of 200.
    let stating = |stated: u64| {
        changed(&hostile, |x| {
            set_u64(x, offsets::FILE_LENGTH, stated);
            x.resize(200, 0);
        })
    };
    vec![
        case(
            "200 bytes claiming 256 modes x 4M pixels",
            stating(huge),
            truncated(huge, 200),
        ),
        case(
            "hostile header stating its real length",
            stating(200),
            length_mismatch(200, huge),
        ),
    ]
}

/// Payload corruption: with the checksum as it was (the checksum refuses the file), then with
/// the checksum rewritten (the arrays' validation must).
fn payload_cases(base: &Base) -> Vec<Case> {
    let mut cases = checksum_cases(base);
    cases.extend(payload_value_cases(base));
    cases.extend(payload_structure_cases(base));
    cases
}

/// [`payload_cases`]: flipped bits the checksum refuses.
fn checksum_cases(base: &Base) -> Vec<Case> {
    let (v, lay) = (&base.v, &base.lay);
    vec![
        case(
            "flipped payload bit",
            changed(v, |x| x[lay.app_base + 101] ^= 0x10),
            checksum_mismatch(),
        ),
        case(
            "flipped checksum bit",
            changed(v, |x| x[lay.crc] ^= 0x01),
            checksum_mismatch(),
        ),
        case(
            "flipped fingerprint bit, CRC left",
            changed(v, |x| x[offsets::FINGERPRINT] ^= 0x80),
            checksum_mismatch(),
        ),
    ]
}

/// [`payload_cases`], the checksum rewritten: non-finite values and negative variances.
fn payload_value_cases(base: &Base) -> Vec<Case> {
    let (v, lay) = (&base.v, &base.lay);
    let f32_at = |off: usize, value: f32| fixed(v, |x| set_f32(x, off, value));
    let negative = |array: &'static str, index: u32, value: f32| {
        Exact(E::NegativeVariance {
            array,
            index,
            value,
        })
    };
    vec![
        case(
            "NaN in the shape base",
            f32_at(lay.shape_base, f32::NAN),
            non_finite("shape base", 0),
        ),
        case(
            "infinity in the shape modes",
            f32_at(lay.shape_modes + 4 * 5, f32::INFINITY),
            non_finite("shape modes", 5),
        ),
        case(
            "NaN in the frame vertices",
            f32_at(lay.vertices + 4 * 9, f32::NAN),
            non_finite("frame vertices", 9),
        ),
        case(
            "NaN in the appearance modes",
            f32_at(lay.app_modes + 4 * 17, f32::NAN),
            non_finite("appearance modes", 17),
        ),
        case(
            "NaN in the appearance variances",
            f32_at(lay.app_variances, f32::NAN),
            non_finite("appearance variances", 0),
        ),
        case(
            "negative shape variance",
            f32_at(lay.shape_variances + 4, -1.0),
            negative("shape variances", 1, -1.0),
        ),
        case(
            "negative appearance variance",
            f32_at(lay.app_variances, -0.5),
            negative("appearance variances", 0, -0.5),
        ),
    ]
}

/// [`payload_cases`], the checksum rewritten: triangle indices out of range, names that are
/// not UTF-8 and non-zero padding.
fn payload_structure_cases(base: &Base) -> Vec<Case> {
    let (v, lay, n) = (&base.v, &base.lay, base.n);
    let bad_index = |triangle: u32, index: u32| {
        Exact(E::InvalidTriangleIndex {
            triangle,
            index,
            landmarks: n,
        })
    };
    let wb = write_model_as(&models().b, Storage::F32);
    let lay_b = layout(&models().b);
    assert!(
        lay.shape_base > lay.pad,
        "model a's names must need padding"
    );
    vec![
        case(
            "triangle index = landmarks",
            fixed(v, |x| set_u32(x, lay.triangles + 4, n)),
            bad_index(0, n),
        ),
        case(
            "triangle index u32::MAX",
            fixed(v, |x| set_u32(x, lay.triangles + 12 * 5 + 8, u32::MAX)),
            bad_index(5, u32::MAX),
        ),
        case(
            "model name not UTF-8",
            fixed(v, |x| x[HEADER_LEN + 2] = 0xFF),
            Exact(E::InvalidUtf8 {
                field: "model name",
            }),
        ),
        // The last byte of the reference name: a truncated 2-byte sequence.
        case(
            "reference name not UTF-8",
            fixed(&wb, |x| x[lay_b.pad - 1] = 0xC0),
            Exact(E::InvalidUtf8 {
                field: "reference name",
            }),
        ),
        case(
            "non-zero padding",
            fixed(v, |x| x[lay.pad] = 1),
            Exact(E::NonZeroPadding),
        ),
    ]
}

/// Multiplies the `count` f32 values at `off` by `factor`.
fn scale_f32s(x: &mut [u8], off: usize, count: usize, factor: f32) {
    for k in 0..count {
        let at = off + 4 * k;
        let value = get_f32(x, at);
        set_f32(x, at, factor * value);
    }
}

/// The modes' orthonormality and the frame's fingerprint, with the checksum rewritten.
fn mode_cases(base: &Base) -> Vec<Case> {
    let (a, v, lay) = (base.a, &base.v, &base.lay);
    let d = 8 * base.n as usize; // bytes of one shape mode
    let d3 = 12 * a.frame().n_pixels(); // bytes of one appearance mode
    vec![
        case(
            "shape mode 0 doubled",
            fixed(v, |x| {
                scale_f32s(x, lay.shape_modes, 2 * base.n as usize, 2.0)
            }),
            Like(
                "NotOrthonormal{shape modes, 0, 0}",
                |e| matches!(e, E::NotOrthonormal { array: "shape modes", i: 0, j: 0, dot } if (dot - 4.0).abs() < 1e-3),
            ),
        ),
        case(
            "shape mode 1 a copy of mode 0",
            fixed(v, |x| {
                x.copy_within(lay.shape_modes..lay.shape_modes + d, lay.shape_modes + d)
            }),
            Like(
                "NotOrthonormal{shape modes, 1, 0}",
                |e| matches!(e, E::NotOrthonormal { array: "shape modes", i: 1, j: 0, dot } if (dot - 1.0).abs() < 1e-3),
            ),
        ),
        case(
            "appearance mode 1 zeroed",
            fixed(v, |x| x[lay.app_modes + d3..lay.app_modes + 2 * d3].fill(0)),
            Exact(E::NotOrthonormal {
                array: "appearance modes",
                i: 1,
                j: 1,
                dot: 0.0,
            }),
        ),
        case(
            "wrong fingerprint",
            fixed(v, |x| x[offsets::FINGERPRINT] ^= 1),
            Exact(E::FingerprintMismatch {
                stored: a.frame().fingerprint() ^ 1,
                recomputed: a.frame().fingerprint(),
            }),
        ),
    ]
}

/// The mesh: shrunk, degenerate, or with triangles whose rasterisation is too much work.
fn mesh_cases(base: &Base) -> Vec<Case> {
    let (a, v, lay, n) = (base.a, &base.v, &base.lay, base.n as usize);
    // The leftmost, rightmost, lowest and topmost vertices.
    let ext = {
        let vs = a.frame().vertices();
        let arg = |f: &dyn Fn(usize) -> f32| {
            (0..n).max_by(|&i, &j| f(i).total_cmp(&f(j))).unwrap() as u32
        };
        [
            arg(&|i| -vs[2 * i]),
            arg(&|i| vs[2 * i]),
            arg(&|i| vs[2 * i + 1]),
            arg(&|i| -vs[2 * i + 1]),
        ]
    };
    let t = a.frame().triangles().len();
    vec![
        case(
            "mesh shrunk (pixel count no longer matches)",
            fixed(v, |x| scale_f32s(x, lay.vertices, 2 * n, 0.8)),
            Like("PixelCountMismatch", |e| {
                matches!(e, E::PixelCountMismatch { .. })
            }),
        ),
        case(
            "all triangles degenerate",
            fixed(v, |x| x[lay.triangles..lay.app_base].fill(0)),
            Like("BadFrame", |e| matches!(e, E::BadFrame(_))),
        ),
        // Every triangle spans the whole mesh: the rasterisation work exceeds its limit.
        case(
            "overlapping triangles covering the grid",
            fixed(v, |x| {
                for k in 0..t {
                    let last = if k % 2 == 0 { ext[2] } else { ext[3] };
                    for (c, i) in [ext[0], ext[1], last].into_iter().enumerate() {
                        set_u32(x, lay.triangles + 12 * k + 4 * c, i);
                    }
                }
            }),
            Like("LimitExceeded{sum of triangle bounding boxes}", |e| {
                matches!(
                    e,
                    E::LimitExceeded {
                        what: "sum of triangle bounding boxes (grid cells)",
                        ..
                    }
                )
            }),
        ),
    ]
}

#[wasm_bindgen_test::wasm_bindgen_test(unsupported = test)]
fn corrupt_truncated_and_hostile_files_are_rejected_with_the_expected_error() {
    let mut cases = bad_cases();
    cases.extend(compact_bad_cases());
    assert!(cases.len() >= 25, "only {} cases", cases.len());
    eprintln!("{} corrupt, truncated and hostile files", cases.len());
    let mut failures = Vec::new();
    for (name, bytes, expect) in &cases {
        let got = read_model(bytes);
        let ok = match (&got, expect) {
            (Err(e), Expect::Exact(want)) => e == want,
            (Err(e), Expect::Like(_, f)) => f(e),
            (Ok(_), _) => false,
        };
        if !ok {
            let want = match expect {
                Expect::Exact(w) => format!("{w:?}"),
                Expect::Like(s, _) => s.to_string(),
            };
            failures.push(format!(
                "{name}: expected {want}, got {:?}",
                got.as_ref().map(|m| m.name())
            ));
        }
        // Every message is one readable line.
        if let Err(e) = got {
            let msg = e.to_string();
            assert!(
                !msg.is_empty() && !msg.contains('\n'),
                "{name}: message {msg:?}"
            );
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} cases failed:\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n")
    );
}

// ------------------------------------------------------------------------------------------
// Fuzzing: random bytes and random mutations never panic.

#[wasm_bindgen_test::wasm_bindgen_test(unsupported = test)]
fn random_bytes_and_mutations_never_panic() {
    let ms = models();
    let valid: Vec<Vec<u8>> = [&ms.a, &ms.b, &ms.c]
        .iter()
        .flat_map(|m| Storage::ALL.map(|s| write_model_as(m, s)))
        .collect();
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let (mut ok, mut err) = (0usize, 0usize);
    let mut tally = |r: Result<Model, FormatError>| match r {
        Ok(_) => ok += 1,
        Err(_) => err += 1,
    };

    // 1. Random buffers: plain noise, noise behind the magic, noise behind a valid header.
    for i in 0..3000 {
        let len = rng.below(if i % 10 == 0 { 4000 } else { 400 });
        let mut x: Vec<u8> = (0..len).map(|_| rng.next_u64() as u8).collect();
        match i % 3 {
            0 => {}
            1 => {
                let k = len.min(12);
                let mut head = MAGIC.to_vec();
                head.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
                x[..k].copy_from_slice(&head[..k]);
            }
            _ => {
                let src = &valid[rng.below(3)];
                let k = len.min(HEADER_LEN);
                x[..k].copy_from_slice(&src[..k]);
                if len >= HEADER_LEN {
                    set_u64(&mut x, offsets::FILE_LENGTH, len as u64);
                }
            }
        }
        tally(read_model(&x));
    }

    // 2. Mutations of valid files: byte flips, header fields set to random or boundary values,
    //    truncations, splices, with the length and checksum fixed up half of the time so that
    //    the deeper validation runs too.
    // Interesting header values: boundaries, the 68-point scheme, powers of two, extremes.
    let specials = engine::INTS;
    for i in 0..3000 {
        let src = &valid[i % 3];
        let mut x = src.clone();
        match rng.below(5) {
            0 => {
                for _ in 0..1 + rng.below(4) {
                    let k = rng.below(x.len());
                    x[k] ^= 1 << rng.below(8);
                }
            }
            1 => {
                let off = 8 + 4 * rng.below((HEADER_LEN - 8) / 4);
                let val = if rng.below(2) == 0 {
                    rng.next_u64() as u32
                } else {
                    specials[rng.below(specials.len())]
                };
                set_u32(&mut x, off, val);
            }
            2 => x.truncate(rng.below(x.len())),
            3 => {
                let (from, to) = (rng.below(x.len()), rng.below(x.len()));
                let k = rng.below(64).min(x.len() - from.max(to));
                let piece = x[from..from + k].to_vec();
                x[to..to + k].copy_from_slice(&piece);
            }
            _ => {
                // An array value replaced by a random bit pattern (NaNs, huge, tiny, negative).
                let k = HEADER_LEN + 4 * rng.below((x.len() - HEADER_LEN - 4) / 4);
                set_u32(&mut x, k, rng.next_u64() as u32);
            }
        }
        if i % 2 == 0 && x.len() >= HEADER_LEN + 4 {
            let n = x.len() as u64;
            set_u64(&mut x, offsets::FILE_LENGTH, n);
            fix_crc(&mut x);
        }
        tally(read_model(&x));
    }
    assert_eq!(ok + err, 6000);
    assert!(err > 5000, "{err} rejections of 6000 random inputs");
}

// ------------------------------------------------------------------------------------------
// Hostile headers: quick, and (natively, with a counting allocator) no allocation.

#[wasm_bindgen_test::wasm_bindgen_test(unsupported = test)]
fn hostile_header_is_rejected_before_any_allocation_of_its_arrays() {
    let v = write_model_as(&models().a, Storage::F32);
    let mut x = v[..HEADER_LEN].to_vec();
    x.resize(200, 0);
    set_u32(&mut x, offsets::FRAME_WIDTH, 2048);
    set_u32(&mut x, offsets::FRAME_HEIGHT, 2048);
    set_u32(&mut x, offsets::PIXELS, LIMITS.max_pixels);
    set_u32(
        &mut x,
        offsets::SHAPE_MODES,
        136, /* = 2n, the most 68 landmarks allow */
    );
    set_u32(
        &mut x,
        offsets::APPEARANCE_MODES,
        LIMITS.max_appearance_modes,
    );
    let implied = 112
        + 8
        + 4 * (2 * 68 * 136 + 4 * 68 + 136 + 3 * v_triangles(&v) + 3 * 4_194_304 * 257 + 256)
        + 4;
    set_u64(&mut x, offsets::FILE_LENGTH, implied);
    #[cfg(not(target_arch = "wasm32"))]
    {
        let start = std::time::Instant::now();
        let (r, peak) = crate::counting::peak_during(|| read_model(&x));
        let elapsed = start.elapsed();
        assert_eq!(
            r,
            Err(FormatError::Truncated {
                needed: implied,
                available: 200
            })
        );
        assert!(
            implied > 12_000_000_000,
            "the header claims {implied} bytes"
        );
        assert!(
            peak <= 1024,
            "rejecting a 200-byte hostile file allocated {peak} bytes"
        );
        // No work in proportion to the claim (12 GB would take minutes): a bound far above the
        // microseconds it takes, so a loaded machine that pauses the thread cannot fail it.
        assert!(elapsed.as_millis() < 2000, "took {elapsed:?}");
        eprintln!("hostile 200-byte header claiming {implied} bytes: rejected in {elapsed:?}, peak allocation {peak} bytes");
    }
    #[cfg(target_arch = "wasm32")]
    assert_eq!(
        read_model(&x),
        Err(FormatError::Truncated {
            needed: implied,
            available: 200
        })
    );
}

fn v_triangles(v: &[u8]) -> u64 {
    get_u32(v, offsets::TRIANGLES) as u64
}

/// Reading a valid file allocates a bounded multiple of its size, and a file whose header
/// claims a huge frame grid for few pixels is rejected without allocating the grid.
#[cfg(not(target_arch = "wasm32"))]
#[test]
fn allocations_are_bounded_by_the_file_size() {
    for (m, s) in [&models().a, &models().b, &models().c]
        .into_iter()
        .flat_map(|m| Storage::ALL.map(|s| (m, s)))
    {
        let v = write_model_as(m, s);
        let (r, peak) = crate::counting::peak_during(|| read_model(&v));
        assert!(r.is_ok());
        let ratio = peak as f64 / v.len() as f64;
        eprintln!(
            "'{}' ({s}): {} bytes, peak allocation while reading {peak} bytes ({ratio:.2}x)",
            m.name(),
            v.len()
        );
        assert!(
            peak <= 16 * v.len() + 64 * 1024,
            "'{}': peak {peak} for a {}-byte file",
            m.name(),
            v.len()
        );
    }
    let v = write_model(&models().a);
    let mut x = patched(&v, offsets::FRAME_WIDTH, 2048);
    set_u32(&mut x, offsets::FRAME_HEIGHT, 2048);
    fix_crc(&mut x);
    let (r, peak) = crate::counting::peak_during(|| read_model(&x));
    assert!(matches!(r, Err(FormatError::LimitExceeded { .. })), "{r:?}");
    assert!(peak <= 1024, "peak {peak}");
}

/// `read_summary` reads what the header says without building the model: the same name, sizes
/// and frame fingerprint as the full read, for every storage; a file the header checks refuse
/// (damaged checksum, truncated, another file type) is refused with the same error kind as
/// `read_model`'s, and a model file whose modes only a full read can judge passes the summary.
#[wasm_bindgen_test::wasm_bindgen_test(unsupported = test)]
fn a_summary_is_the_header_of_a_full_read() {
    use facemimic::format::{read_summary, write_model_as};
    for (m, s) in [&models().a, &models().b, &models().c]
        .into_iter()
        .flat_map(|m| [Storage::F32, Storage::I6].map(|s| (m, s)))
    {
        let bytes = write_model_as(m, s);
        let sum = read_summary(&bytes).unwrap();
        assert_eq!(sum.name, m.name());
        assert_eq!(sum.storage, s);
        assert_eq!(sum.landmarks, m.landmarks());
        assert_eq!(sum.shape_modes, m.shape().n_modes());
        assert_eq!(sum.appearance_modes, m.appearance().n_modes());
        assert_eq!(sum.frame_pixels, m.frame().n_pixels());
        assert_eq!(sum.fingerprint, m.frame().fingerprint());
        assert_eq!(sum.image_size, m.image_size());
        assert_eq!(sum.is_photo, m.is_photo());
        assert_eq!(sum.file_bytes, bytes.len());
    }
    let good = write_model(&models().a);
    let mut bad = good.clone();
    let mid = bad.len() / 2;
    bad[mid] ^= 0x40;
    let kind = |e: &FormatError| std::mem::discriminant(e);
    let (es, em) = (
        read_summary(&bad).unwrap_err(),
        read_model(&bad).unwrap_err(),
    );
    assert_eq!(kind(&es), kind(&em), "{es} / {em}");
    assert!(read_summary(&good[..good.len() - 1]).is_err());
    assert!(read_summary(b"\x89PNG\r\n\x1a\n not a model").is_err());
    assert!(read_summary(&[]).is_err());
}
