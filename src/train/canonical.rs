//! The canonical reference frame shipped with the crate.
//!
//! Cloning needs the source and every target to live in one reference frame (one coordinate
//! system for shapes, one pixel grid for appearance). Rather than making each target in the
//! source's frame, every 68-point model is built by default in one frame shipped with the crate,
//! so that any two models built separately can be cloned between, whichever role each plays.
//!
//! The frame is the one of the original default source model (GRID speaker 7, its 20 training
//! frames of `data/grid/spk07_pwij3p`, base face 150 frame pixels wide, built in its own frame).
//! It is stored as text in `src/canonical_frame.txt` (base mesh vertices, triangles, grid size,
//! origin and the fingerprint), written by `cargo run --example canonical_frame`; the file, not
//! that recipe, is the definition: rebuilding it would change the fingerprint only if the
//! triangulation or the training data changed, and every model built in the old frame would then
//! be refused as incompatible with new ones. See docs/model-format.md.

use std::sync::OnceLock;

use crate::error::{Error, Result};
use crate::model::frame::ReferenceFrame;

/// The asset, embedded in the library.
pub const CANONICAL_FRAME_TEXT: &str = include_str!("canonical_frame.txt");

/// Landmarks of the canonical frame (the iBUG 68-point layout).
pub const CANONICAL_LANDMARKS: usize = 68;

/// Fingerprint of the canonical frame (also written in the asset and checked when it is parsed).
pub const CANONICAL_FINGERPRINT: u64 = 0xf334_69e7_338a_4632;

/// The canonical reference frame (68 landmarks, iBUG layout), parsed once.
pub fn canonical_frame() -> &'static ReferenceFrame {
    static FRAME: OnceLock<ReferenceFrame> = OnceLock::new();
    FRAME.get_or_init(|| {
        parse_frame(CANONICAL_FRAME_TEXT).expect("the embedded canonical frame is valid (tested)")
    })
}

/// Writes a frame in the asset's text format (f32 values in Rust's shortest round-trip form,
/// so parsing gives back the exact bits).
pub fn write_frame(frame: &ReferenceFrame, comment: &str) -> String {
    let mut s = String::new();
    for line in comment.lines() {
        s.push_str(&format!("# {line}\n"));
    }
    s.push_str(&format!("fingerprint {:016x}\n", frame.fingerprint()));
    s.push_str(&format!("size {} {}\n", frame.width(), frame.height()));
    let o = frame.origin();
    s.push_str(&format!("origin {:?} {:?}\n", o[0], o[1]));
    s.push_str(&format!("vertices {}\n", frame.landmarks()));
    for p in frame.vertices().chunks_exact(2) {
        s.push_str(&format!("{:?} {:?}\n", p[0], p[1]));
    }
    s.push_str(&format!("triangles {}\n", frame.triangles().len()));
    for t in frame.triangles() {
        s.push_str(&format!("{} {} {}\n", t[0], t[1], t[2]));
    }
    s
}

/// Parses a frame written by [`write_frame`], rebuilding its pixels and checking that the
/// recomputed fingerprint equals the recorded one.
pub fn parse_frame(text: &str) -> Result<ReferenceFrame> {
    let bad = |m: &str| Error::Training(format!("reference frame text: {m}"));
    let lines: Vec<&str> = text
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .collect();
    let mut at = 0usize;
    // The words of the next line, after checking its keyword (`None`: a data line).
    let mut next = |key: Option<&str>| -> Result<Vec<&str>> {
        let l = lines.get(at).ok_or_else(|| bad("ends early"))?;
        at += 1;
        let mut w: Vec<&str> = l.split_whitespace().collect();
        if let Some(k) = key {
            if w.first() != Some(&k) {
                return Err(bad(&format!("expected '{k}', found '{l}'")));
            }
            w.remove(0);
        }
        Ok(w)
    };
    fn get<T: std::str::FromStr>(w: &[&str], i: usize) -> Result<T> {
        w.get(i).and_then(|s| s.parse().ok()).ok_or_else(|| {
            Error::Training(format!(
                "reference frame text: bad value in '{}'",
                w.join(" ")
            ))
        })
    }
    let fp = next(Some("fingerprint"))?;
    let fingerprint = u64::from_str_radix(fp.first().copied().unwrap_or(""), 16)
        .map_err(|_| bad("bad fingerprint"))?;
    let size = next(Some("size"))?;
    let (w, h): (u32, u32) = (get(&size, 0)?, get(&size, 1)?);
    let o = next(Some("origin"))?;
    let origin: [f32; 2] = [get(&o, 0)?, get(&o, 1)?];
    let nv: usize = get(&next(Some("vertices"))?, 0)?;
    if nv > 1024 {
        return Err(bad("too many vertices"));
    }
    let mut vertices = Vec::with_capacity(2 * nv);
    for _ in 0..nv {
        let l = next(None)?;
        vertices.extend([get::<f32>(&l, 0)?, get::<f32>(&l, 1)?]);
    }
    let nt: usize = get(&next(Some("triangles"))?, 0)?;
    if nt > 8192 {
        return Err(bad("too many triangles"));
    }
    let mut triangles = Vec::with_capacity(nt);
    for _ in 0..nt {
        let l = next(None)?;
        triangles.push([get(&l, 0)?, get(&l, 1)?, get(&l, 2)?]);
    }
    let frame = ReferenceFrame::new(vertices, triangles, w, h, origin)?;
    if frame.fingerprint() != fingerprint {
        return Err(bad(&format!(
            "recorded fingerprint {fingerprint:016x} differs from the recomputed {:016x}",
            frame.fingerprint()
        )));
    }
    Ok(frame)
}
