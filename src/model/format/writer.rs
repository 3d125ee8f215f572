//! Writing a model: the header, the arrays, the appearance (through the codec), the sections
//! and the checksum.

use super::*;
use crate::model::{LandmarkScheme, Model, Reference};

/// Serialises a model into the `.fmm` format (version [`FORMAT_VERSION`]) with the default,
/// compact appearance storage ([`Storage::I8`]); see [`write_model_as`].
pub fn write_model(model: &Model) -> Vec<u8> {
    write_model_as(model, Storage::default())
}

/// Serialises a model into the `.fmm` format (version [`FORMAT_VERSION`]), the appearance base
/// and modes stored as `storage` says.
///
/// Infallible: it writes what the model holds. A model from [`crate::Builder::build`] or
/// [`read_model`] within the [`LIMITS`] reads back equal with [`Storage::F32`]
/// (`read_model(&write_model_as(&m, Storage::F32)) == Ok(m)`), and within the storage's
/// rounding otherwise (a model read from a file of that storage writes back byte for byte); a
/// model that breaks its invariants or the limits is written faithfully and rejected by
/// [`read_model`].
pub fn write_model_as(model: &Model, storage: Storage) -> Vec<u8> {
    let n2 = model.shape().base.len();
    let m = model.shape().variances.len();
    let l = model.appearance().n_modes();
    let frame = &model.frame();
    let name = model.name().as_bytes();
    let (ref_tag, ref_name): (u32, &[u8]) = match &model.reference() {
        Reference::Mean => (REFERENCE_MEAN, &[]),
        Reference::Training(s) => (REFERENCE_TRAINING, s.as_bytes()),
    };
    let names = name.len() + ref_name.len();
    let padding = pad4(names as u64) as usize;
    let floats = model.shape().base.len()
        + model.shape().modes.len()
        + m
        + frame.vertices().len()
        + 3 * frame.triangles().len();
    let appearance = appearance_bytes(
        storage,
        model.appearance().len() as u64,
        model.appearance().n_modes() as u64,
    )
    .unwrap_or(0) as usize;
    let sections = sections_of(model);
    let total =
        HEADER_LEN + names + padding + 4 * floats + appearance + sections.len() + CHECKSUM_LEN;
    let mut out = Vec::with_capacity(total);
    let u32le = |out: &mut Vec<u8>, v: u32| out.extend_from_slice(&v.to_le_bytes());
    let f32le = |out: &mut Vec<u8>, v: f32| out.extend_from_slice(&v.to_le_bytes());
    let as_u32 = |v: usize| u32::try_from(v).unwrap_or(u32::MAX);

    out.extend_from_slice(&MAGIC);
    u32le(&mut out, FORMAT_VERSION);
    u32le(&mut out, storage.tag());
    out.extend_from_slice(&(total as u64).to_le_bytes());
    u32le(&mut out, as_u32(n2 / 2));
    u32le(&mut out, as_u32(frame.triangles().len()));
    u32le(&mut out, frame.width());
    u32le(&mut out, frame.height());
    f32le(&mut out, frame.origin()[0]);
    f32le(&mut out, frame.origin()[1]);
    u32le(&mut out, as_u32(model.appearance().len() / 3));
    u32le(&mut out, 3);
    u32le(&mut out, as_u32(m));
    u32le(&mut out, as_u32(l));
    u32le(
        &mut out,
        match model.scheme() {
            LandmarkScheme::Ibug68 => SCHEME_IBUG68,
            LandmarkScheme::Generic(_) => SCHEME_GENERIC,
        },
    );
    u32le(&mut out, ref_tag);
    u32le(&mut out, as_u32(name.len()));
    u32le(&mut out, as_u32(ref_name.len()));
    let p = model.mean_pose();
    for v in [p.a, p.b, p.tx, p.ty] {
        f32le(&mut out, v);
    }
    u32le(&mut out, model.image_size()[0]);
    u32le(&mut out, model.image_size()[1]);
    out.extend_from_slice(&frame.fingerprint().to_le_bytes());
    debug_assert_eq!(out.len(), HEADER_LEN);

    out.extend_from_slice(name);
    out.extend_from_slice(ref_name);
    out.extend(std::iter::repeat_n(0u8, padding));
    let arrays: [&[f32]; 4] = [
        &model.shape().base,
        &model.shape().modes,
        &model.shape().variances,
        frame.vertices(),
    ];
    for a in arrays {
        a.iter().for_each(|&v| f32le(&mut out, v));
    }
    frame
        .triangles()
        .iter()
        .flatten()
        .for_each(|&i| u32le(&mut out, i));
    write_appearance(&mut out, model.appearance(), storage);
    out.extend_from_slice(&sections);
    let crc = crc32(&out);
    u32le(&mut out, crc);
    debug_assert_eq!(out.len(), total);
    out
}

/// The sections' bytes for `model` (empty when it has no backdrop).
pub(super) fn sections_of(model: &Model) -> Vec<u8> {
    let mut out = Vec::new();
    if let Some(b) = model.backdrop() {
        let mut payload = Vec::with_capacity(16 + 4 * b.landmarks().len() + b.jpeg().len());
        payload.extend_from_slice(&b.width().to_le_bytes());
        payload.extend_from_slice(&b.height().to_le_bytes());
        payload.extend_from_slice(&((b.landmarks().len() / 2) as u32).to_le_bytes());
        b.landmarks()
            .iter()
            .for_each(|v| payload.extend_from_slice(&v.to_le_bytes()));
        payload.extend_from_slice(&(b.jpeg().len() as u32).to_le_bytes());
        payload.extend_from_slice(b.jpeg());
        out.extend_from_slice(&SECTION_BACKDROP.to_le_bytes());
        out.extend_from_slice(&(payload.len() as u32).to_le_bytes());
        out.extend_from_slice(&payload);
        out.extend(std::iter::repeat_n(
            0u8,
            pad4(payload.len() as u64) as usize,
        ));
    }
    out
}

/// [`write_model_as`], refusing what [`read_model`] would reject: the bytes are read back with
/// the full validation before they are returned, so a file written is always a file read.
pub fn write_model_checked_as(model: &Model, storage: Storage) -> Result<Vec<u8>, FormatError> {
    crate::model::bounds::check_model_values(model)?;
    let bytes = write_model_as(model, storage);
    read_model(&bytes)?;
    Ok(bytes)
}

/// [`write_model_checked_as`] with the default storage (as [`write_model`]).
pub fn write_model_checked(model: &Model) -> Result<Vec<u8>, FormatError> {
    write_model_checked_as(model, Storage::default())
}
