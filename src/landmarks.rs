//! Landmark files: iBUG `.pts` (read and write) and IMM / AAM-API `.asf` (read).
//!
//! Every function returns shapes as interleaved 0-based image coordinates
//! `(x1, y1, ..., xn, yn)` where integer coordinates are pixel centres.

use crate::error::{Error, Result};

/// For each iBUG-68 point, the index of its mirror image (left and right swapped).
pub const MIRROR_68: [usize; 68] = [
    16, 15, 14, 13, 12, 11, 10, 9, 8, 7, 6, 5, 4, 3, 2, 1, 0, // jaw
    26, 25, 24, 23, 22, 21, 20, 19, 18, 17, // brows
    27, 28, 29, 30, // nose bridge
    35, 34, 33, 32, 31, // nostrils
    45, 44, 43, 42, 47, 46, // eyes
    39, 38, 37, 36, 41, 40, //
    54, 53, 52, 51, 50, 49, 48, // outer lips
    59, 58, 57, 56, 55, //
    64, 63, 62, 61, 60, // inner lips
    67, 66, 65,
];

/// The iBUG-68 outer eye corners (0-based; 37 and 46 in the 1-based `.pts` numbering): the
/// line between them is the face's horizontal (the shape model's gauge, the finder's face frame)
/// and their distance the unit of every landmark error and of the compositor's rings.
pub const OUTER_EYE_CORNERS: [usize; 2] = [36, 45];

/// The iBUG-68 points an expression hardly moves: the nose (27-35) and the eye corners (36, 39,
/// 42, 45). The similarity between two shapes of one face fitted on these alone
/// ([`crate::Similarity::align_points`]) is the head's own motion; fitted on all 68, a laugh's
/// dropped jaw and widened mouth pull it too, and part of the laugh is taken for the head
/// growing and moving.
pub const STABLE_POINTS: [usize; 13] = [27, 28, 29, 30, 31, 32, 33, 34, 35, 36, 39, 42, 45];

/// The vector from the left outer eye corner to the right one of a 68-point shape
/// (interleaved `x, y`), or `None` for another number of points.
pub fn eye_line(points: &[f32]) -> Option<[f32; 2]> {
    if points.len() != 136 {
        return None;
    }
    let [l, r] = OUTER_EYE_CORNERS;
    Some([
        points[2 * r] - points[2 * l],
        points[2 * r + 1] - points[2 * l + 1],
    ])
}

/// The 68 points (interleaved `x, y`, pixel-centre coordinates) of a face seen in the mirror
/// image of a picture `width` pixels wide, as that face's own points: `x` mirrored to
/// `width - 1 - x` and each point renumbered by [`MIRROR_68`] (the mirror's left eye is the
/// face's right). Requires 136 values in `points` and `out`.
pub fn mirror_points(points: &[f32], width: f32, out: &mut [f32]) {
    for (i, &j) in MIRROR_68.iter().enumerate() {
        out[2 * i] = width - 1.0 - points[2 * j];
        out[2 * i + 1] = points[2 * j + 1];
    }
}

/// Most landmarks a file may hold (guards against absurd inputs).
pub const MAX_LANDMARKS: usize = 4096;

/// Largest magnitude of a landmark coordinate in pixels (= [`crate::model::limits::MAX_PARAM`]):
/// no image is larger, and it keeps every computation on landmarks finite.
pub const MAX_COORDINATE: f32 = 1e6;

/// Parses an iBUG `.pts` file. Its coordinates are 1-based pixel coordinates: 1 is subtracted.
///
/// Requires: `version: 1`, `n_points: N`, `{`, N lines of two finite numbers, `}`.
/// Ensures: a vector of `2N` finite values.
pub fn parse_pts(text: &str) -> Result<Vec<f32>> {
    let mut lines = text
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with("//"));
    let mut n_points: Option<usize> = None;
    loop {
        let line = lines
            .next()
            .ok_or_else(|| Error::Landmarks("no '{' found: not a .pts file".into()))?;
        if line == "{" {
            break;
        }
        if let Some(rest) = line.strip_prefix("n_points:") {
            let n: usize = rest
                .trim()
                .parse()
                .map_err(|_| Error::Landmarks(format!("bad n_points value '{}'", rest.trim())))?;
            if n == 0 || n > MAX_LANDMARKS {
                return Err(Error::Landmarks(format!(
                    "n_points {n} out of range 1..={MAX_LANDMARKS}"
                )));
            }
            n_points = Some(n);
        } else if !line.starts_with("version:") {
            return Err(Error::Landmarks(format!("unexpected header line '{line}'")));
        }
    }
    let n = n_points.ok_or_else(|| Error::Landmarks("missing n_points header".into()))?;
    let mut out = Vec::with_capacity(2 * n);
    for line in lines {
        if line == "}" {
            if out.len() != 2 * n {
                return Err(Error::Landmarks(format!(
                    "n_points says {n} but {} points were given",
                    out.len() / 2
                )));
            }
            return Ok(out);
        }
        let mut it = line.split_whitespace();
        let (x, y) = match (it.next(), it.next(), it.next()) {
            (Some(x), Some(y), None) => (x, y),
            _ => return Err(Error::Landmarks(format!("bad point line '{line}'"))),
        };
        let parse = |s: &str| -> Result<f32> {
            s.parse::<f32>()
                .ok()
                .filter(|v| v.abs() <= MAX_COORDINATE)
                .ok_or_else(|| {
                    Error::Landmarks(format!(
                        "bad coordinate '{s}' (a finite number within +-{MAX_COORDINATE:e} is expected)"
                    ))
                })
        };
        if out.len() >= 2 * n {
            return Err(Error::Landmarks(format!("more than n_points = {n} points")));
        }
        out.push(parse(x)? - 1.0);
        out.push(parse(y)? - 1.0);
    }
    Err(Error::Landmarks("missing closing '}'".into()))
}

/// Writes a shape (0-based coordinates) as an iBUG `.pts` file (1-based coordinates).
pub fn write_pts(shape: &[f32]) -> String {
    let mut s = format!("version: 1\nn_points: {}\n{{\n", shape.len() / 2);
    for p in shape.chunks_exact(2) {
        s.push_str(&format!("{:.3} {:.3}\n", p[0] + 1.0, p[1] + 1.0));
    }
    s.push_str("}\n");
    s
}

/// Parses an IMM / AAM-API `.asf` file, whose coordinates are relative to the image size:
/// `x = rel_x * width`, `y = rel_y * height`.
///
/// Requires: the point count on the first non-comment line, then that many point lines
/// `<path> <type> <x> <y> <index> <from> <to>`; `width`, `height` > 0.
pub fn parse_asf(text: &str, width: u32, height: u32) -> Result<Vec<f32>> {
    if width == 0 || height == 0 {
        return Err(Error::Landmarks("image size is zero".into()));
    }
    let mut lines = text
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'));
    let first = lines
        .next()
        .ok_or_else(|| Error::Landmarks("empty .asf file".into()))?;
    let n: usize = first
        .parse()
        .map_err(|_| Error::Landmarks(format!("bad point count '{first}' in .asf")))?;
    if n == 0 || n > MAX_LANDMARKS {
        return Err(Error::Landmarks(format!(
            "point count {n} out of range 1..={MAX_LANDMARKS}"
        )));
    }
    let mut out = Vec::with_capacity(2 * n);
    for _ in 0..n {
        let line = lines
            .next()
            .ok_or_else(|| Error::Landmarks(format!(".asf ends before its {n} points")))?;
        let f: Vec<&str> = line.split_whitespace().collect();
        if f.len() < 4 {
            return Err(Error::Landmarks(format!("bad .asf point line '{line}'")));
        }
        let rx: f32 = f[2]
            .parse()
            .ok()
            .filter(|v: &f32| v.is_finite())
            .ok_or_else(|| Error::Landmarks(format!("bad relative x '{}' in .asf", f[2])))?;
        let ry: f32 = f[3]
            .parse()
            .ok()
            .filter(|v: &f32| v.is_finite())
            .ok_or_else(|| Error::Landmarks(format!("bad relative y '{}' in .asf", f[3])))?;
        // The product can overflow (1e38 x 640): bounded like every coordinate.
        for (rel, size, axis) in [(rx, width, "x"), (ry, height, "y")] {
            let v = rel as f64 * size as f64;
            if !(v.abs() <= MAX_COORDINATE as f64) {
                return Err(Error::Landmarks(format!(
                    "relative {axis} {rel} times the image size {size} is {v:e}, beyond +-{MAX_COORDINATE:e}"
                )));
            }
            out.push(v as f32);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mirror_points_twice_is_the_identity_and_swaps_the_eyes() {
        let p: Vec<f32> = (0..136)
            .map(|i| (i as f32 * 0.7).sin() * 40.0 + 50.0)
            .collect();
        let (mut m, mut back) = ([0.0; 136], [0.0; 136]);
        mirror_points(&p, 100.0, &mut m);
        mirror_points(&m, 100.0, &mut back);
        assert!(p.iter().zip(&back).all(|(a, b)| (a - b).abs() < 1e-4));
        // The mirror's point 45 is the face's 36, across the picture.
        assert_eq!(m[2 * 45], 99.0 - p[2 * 36]);
        assert_eq!(m[2 * 45 + 1], p[2 * 36 + 1]);
    }

    #[test]
    fn mirror_is_an_involution_that_swaps_sides() {
        for (i, &j) in MIRROR_68.iter().enumerate() {
            assert_eq!(MIRROR_68[j], i);
        }
        assert_eq!(MIRROR_68[36], 45); // outer eye corners
        assert_eq!(MIRROR_68[48], 54); // mouth corners
        assert_eq!(MIRROR_68[8], 8); // chin
        assert_eq!(MIRROR_68[30], 30); // nose tip
        let [l, r] = OUTER_EYE_CORNERS;
        assert_eq!(MIRROR_68[l], r);
    }

    #[test]
    fn eye_line_is_left_to_right_corner() {
        let mut p = vec![0.0f32; 136];
        p[72] = 10.0;
        p[73] = 20.0;
        p[90] = 40.0;
        p[91] = 24.0;
        assert_eq!(eye_line(&p), Some([30.0, 4.0]));
        assert_eq!(eye_line(&p[..134]), None);
    }

    #[test]
    fn pts_round_trip_is_zero_based() {
        let text = "version: 1\nn_points: 2\n{\n1 1\n10.5 20\n}\n";
        let s = parse_pts(text).unwrap();
        assert_eq!(s, vec![0.0, 0.0, 9.5, 19.0]);
        assert_eq!(parse_pts(&write_pts(&s)).unwrap(), s);
    }

    #[test]
    fn pts_errors() {
        for bad in [
            "",
            "version: 1\nn_points: 2\n{\n1 1\n}\n",
            "version: 1\nn_points: 1\n{\n1 x\n}\n",
            "version: 1\nn_points: 1\n{\n1 1\n",
            "version: 1\n{\n1 1\n}\n",
            "version: 1\nn_points: 1\n{\n1 1\n2 2\n}\n",
            "version: 1\nn_points: 1\n{\nNaN 1\n}\n",
            "version: 1\nn_points: 99999999\n{\n}\n",
        ] {
            assert!(parse_pts(bad).is_err(), "accepted {bad:?}");
        }
    }

    #[test]
    fn asf_relative() {
        let text = "# comment\n2\n0 0 0.5 0.25 0 1 1\n0 0 0.1 0.2 1 0 0\nimage.jpg\n";
        let s = parse_asf(text, 200, 100).unwrap();
        assert_eq!(s, vec![100.0, 25.0, 20.0, 20.0]);
        assert!(parse_asf("3\n0 0 0.5 0.5 0 0 0\n", 10, 10).is_err());
        // A relative coordinate of 1e38 times the image size overflowed to +inf.
        let e = parse_asf("1\n0 0 1e38 0.5 0 0 0\n", 640, 480).unwrap_err();
        assert!(e.to_string().contains("relative x"), "{e}");
        assert!(parse_pts("version: 1\nn_points: 1\n{\n3e38 1\n}\n").is_err());
    }
}
