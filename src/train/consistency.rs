//! Enrolment input that is wrong as a whole, not frame by frame (issue 33): a camera that
//! froze (the same picture again and again) and frames of two different people.
//!
//! - **frozen** ([`same_picture`]): two pictures of one size whose luminance, on a 64x64 grid,
//!   differs by less than `FROZEN_DIFF` on average. A live camera's noise alone moves a
//!   still face's picture by more; a repeated JPEG (or a stalled stream) by nothing.
//! - **two people** ([`identity_split`]): the faces, sampled into the canonical frame with
//!   their luminance normalised (as the occlusion check), split into two groups by 2-means;
//!   one person's expressions differ locally (the mouth, the eyes), two people's faces differ
//!   everywhere, so the groups' centres lie far apart relative to how far the faces lie from
//!   their own centre. A split with at least `MIN_GROUP` faces (and a fifth of them) on each
//!   side, a ratio over `MAX_IDENTITY_RATIO` and a separation of at least
//!   `MIN_IDENTITY_SEPARATION` names the smaller group.

use crate::error::Result;
use crate::image::ImageRef;

/// Mean absolute luminance difference (0..1) under which two pictures are the same.
pub const FROZEN_DIFF: f32 = 0.002;
/// The two groups' separation over their spread beyond which they are two people.
pub const MAX_IDENTITY_RATIO: f32 = 1.8;
/// Least separation of the groups' centres (mean absolute difference, in deviations of the
/// faces' luminance) for two people: on GRID one speaker's groups lie 0.07-0.12 apart, two
/// speakers' 0.29-0.82 (and identical synthetic faces split by nothing but rounding).
pub const MIN_IDENTITY_SEPARATION: f32 = 0.2;
/// Fewest faces on each side of an identity split.
pub const MIN_GROUP: usize = 2;

/// Whether `a` and `b` show the same picture (a frozen camera); pictures of different sizes
/// never do.
pub fn same_picture(a: &ImageRef, b: &ImageRef) -> bool {
    if a.width() != b.width() || a.height() != b.height() {
        return false;
    }
    if a.data() == b.data() {
        return true;
    }
    picture_difference(a, b) < FROZEN_DIFF
}

/// Mean absolute luminance difference of two pictures of one size, on a 64x64 grid.
pub fn picture_difference(a: &ImageRef, b: &ImageRef) -> f32 {
    const N: usize = 64;
    let (w, h) = (a.width() as f32, a.height() as f32);
    let mut sum = 0.0;
    for gy in 0..N {
        for gx in 0..N {
            let x = w * (gx as f32 + 0.5) / N as f32 - 0.5;
            let y = h * (gy as f32 + 0.5) / N as f32 - 0.5;
            let (p, q) = (a.sample_rgb(x, y), b.sample_rgb(x, y));
            let l = |c: [f32; 3]| 0.299 * c[0] + 0.587 * c[1] + 0.114 * c[2];
            sum += (l(p) - l(q)).abs();
        }
    }
    sum / (N * N) as f32
}

/// Indices of the smaller of two groups of faces (each a picture and its 68 landmarks) that
/// look like two different people, or `None` (see the module). Fewer than `2 * MIN_GROUP`
/// faces: `None`.
pub fn identity_split(faces: &[(ImageRef, &[f32])]) -> Result<Option<Vec<usize>>> {
    Ok(identity_ratio(faces)?
        .and_then(|(ratio, group)| (ratio > MAX_IDENTITY_RATIO).then_some(group)))
}

/// The best 2-means split's separation over spread (0 when the separation is under
/// `MIN_IDENTITY_SEPARATION`) and its smaller group (when each side has at least
/// `MIN_GROUP` faces and a fifth of them).
pub fn identity_ratio(faces: &[(ImageRef, &[f32])]) -> Result<Option<(f32, Vec<usize>)>> {
    if faces.len() < 2 * MIN_GROUP {
        return Ok(None);
    }
    let v = crate::train::quality::normalised_faces(faces)?;
    let d = |a: &[f32], b: &[f32]| {
        a.iter().zip(b).map(|(x, y)| (x - y).abs()).sum::<f32>() / a.len() as f32
    };
    // Start from the face farthest from the first, and the face farthest from that one.
    let far = |from: &[f32]| {
        (0..v.len())
            .max_by(|&a, &b| d(&v[a], from).total_cmp(&d(&v[b], from)))
            .unwrap_or(0)
    };
    let a0 = far(&v[0]);
    let b0 = far(&v[a0]);
    let mut centres = [v[a0].clone(), v[b0].clone()];
    let mut side = vec![0usize; v.len()];
    for _ in 0..8 {
        for (i, f) in v.iter().enumerate() {
            side[i] = usize::from(d(f, &centres[1]) < d(f, &centres[0]));
        }
        for (k, centre) in centres.iter_mut().enumerate() {
            let members: Vec<&Vec<f32>> = v
                .iter()
                .zip(&side)
                .filter(|(_, &s)| s == k)
                .map(|(f, _)| f)
                .collect();
            if members.is_empty() {
                return Ok(None);
            }
            for (p, c) in centre.iter_mut().enumerate() {
                *c = members.iter().map(|m| m[p]).sum::<f32>() / members.len() as f32;
            }
        }
    }
    // The side with fewer members.
    let small = usize::from(side.iter().filter(|&&s| s == 1).count() * 2 <= v.len());
    let group: Vec<usize> = (0..v.len()).filter(|&i| side[i] == small).collect();
    if group.len() < MIN_GROUP.max(v.len() / 5) {
        return Ok(None);
    }
    let spread = v
        .iter()
        .zip(&side)
        .map(|(f, &s)| d(f, &centres[s]))
        .sum::<f32>()
        / v.len() as f32;
    let separation = d(&centres[0], &centres[1]);
    if separation < MIN_IDENTITY_SEPARATION {
        return Ok(Some((0.0, group)));
    }
    Ok(Some((separation / spread.max(1e-6), group)))
}

// Native only: the tests read GRID frames from disk.
#[cfg(all(test, not(target_arch = "wasm32")))]
mod tests {
    use super::*;
    use crate::image::Image;

    /// GRID frames of a speaker folder: pictures and landmarks.
    pub(crate) fn grid(speaker: &str) -> Vec<(Image, Vec<f32>)> {
        let dir = format!("{}/data/grid/{speaker}", env!("CARGO_MANIFEST_DIR"));
        let mut names: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .filter_map(|e| e.ok())
            .map(|e| e.path())
            .filter(|p| p.extension().is_some_and(|x| x == "jpg"))
            .collect();
        names.sort();
        names
            .iter()
            .map(|p| {
                let img = crate::io::read_image(p).unwrap();
                let text = std::fs::read_to_string(p.with_extension("pts")).unwrap();
                (img, crate::landmarks::parse_pts(&text).unwrap())
            })
            .collect()
    }

    fn ratio(set: &[&(Image, Vec<f32>)]) -> Option<(f32, Vec<usize>)> {
        let faces: Vec<(ImageRef, &[f32])> = set
            .iter()
            .map(|(i, l)| (i.view().unwrap(), l.as_slice()))
            .collect();
        identity_ratio(&faces).unwrap()
    }

    const SPEAKERS: [&str; 6] = [
        "spk01_bbaf2n",
        "spk02_brbk7n",
        "spk03_lbax4n",
        "spk05_lrwp9a",
        "spk07_pwij3p",
        "spk08_sbia1a",
    ];

    /// One speaker's frames never split (ratios 0.76-1.28); two speakers' frames alternating
    /// always do (2.54-7.8), and the group named is one speaker's.
    #[test]
    fn two_grid_speakers_split_and_one_does_not() {
        let all: Vec<Vec<(Image, Vec<f32>)>> = SPEAKERS.iter().map(|s| grid(s)).collect();
        for (k, a) in all.iter().enumerate() {
            let r = ratio(&a.iter().collect::<Vec<_>>()).map_or(0.0, |r| r.0);
            assert!(r < MAX_IDENTITY_RATIO, "{}: {r}", SPEAKERS[k]);
            for (j, b) in all.iter().enumerate().skip(k + 1) {
                let mix: Vec<&(Image, Vec<f32>)> = a
                    .iter()
                    .take(20)
                    .zip(b.iter().take(20))
                    .flat_map(|(x, y)| [x, y])
                    .collect();
                let (r, group) = ratio(&mix).unwrap();
                assert!(
                    r > MAX_IDENTITY_RATIO,
                    "{} + {}: {r}",
                    SPEAKERS[k],
                    SPEAKERS[j]
                );
                let odd = group.iter().filter(|i| *i % 2 == 1).count();
                assert!(odd == 0 || odd == group.len(), "{group:?}");
            }
        }
    }

    /// Four frames of another person among sixteen are named.
    #[test]
    fn a_minority_of_another_person_is_named() {
        let (a, b) = (grid(SPEAKERS[4]), grid(SPEAKERS[0]));
        let mut mix: Vec<&(Image, Vec<f32>)> = a.iter().take(16).collect();
        for (k, f) in b.iter().take(4).enumerate() {
            mix.insert(3 + 4 * k, f);
        }
        let faces: Vec<(ImageRef, &[f32])> = mix
            .iter()
            .map(|(i, l)| (i.view().unwrap(), l.as_slice()))
            .collect();
        assert_eq!(identity_split(&faces).unwrap(), Some(vec![3, 7, 11, 15]));
    }

    #[test]
    fn the_same_picture_is_frozen_and_a_changed_one_is_not() {
        let a = grid(SPEAKERS[4]);
        let (p, q) = (a[0].0.view().unwrap(), a[1].0.view().unwrap());
        assert!(same_picture(&p, &p));
        assert!(!same_picture(&p, &q));
        // One level (1/255) on every pixel, less than a live camera's noise, is not frozen.
        let mut noisy = a[0].0.clone();
        noisy.data.iter_mut().for_each(|v| *v = v.saturating_add(1));
        assert!(!same_picture(&p, &noisy.view().unwrap()));
        let d = picture_difference(&p, &q);
        assert!(d > 2.0 * FROZEN_DIFF, "{d}");
    }
}
