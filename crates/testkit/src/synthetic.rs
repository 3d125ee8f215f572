//! The synthetic training set: face-like landmarks on textured RGBA images, built in memory (no
//! files), so the model-file tests, the hostile-input tests and the fuzz harness run anywhere,
//! wasm included.

use facemimic::{Image, TrainingImage};

use super::Rng;

/// `n` face-like landmarks: a Fermat-spiral point set (well spread over an ellipse) under two
/// smooth deformations (a smile, a squash) and a random similarity: scale `scale` (+-8%), a
/// small rotation, centre `centre` (+-`jitter` in x and y). Returns the interleaved points and
/// the centre.
pub fn face_landmarks(
    rng: &mut Rng,
    n: usize,
    scale: f32,
    centre: f32,
    jitter: f32,
) -> (Vec<f32>, [f32; 2]) {
    let (smile, squash) = (rng.sym(), rng.sym());
    let scale = scale * (1.0 + 0.08 * rng.sym());
    let rot = 0.12 * rng.sym();
    let (tx, ty) = (centre + jitter * rng.sym(), centre + jitter * rng.sym());
    let mut landmarks = Vec::with_capacity(2 * n);
    for i in 0..n {
        let r = ((i as f32 + 0.5) / n as f32).sqrt();
        let th = i as f32 * 2.399_963;
        let (x, y) = (r * th.cos(), 1.2 * r * th.sin());
        let y = y + 0.15 * smile * x * x;
        let x = x * (1.0 + 0.1 * squash * y);
        let (c, s) = (rot.cos(), rot.sin());
        landmarks.push(scale * (c * x - s * y) + tx);
        landmarks.push(scale * (s * x + c * y) + ty);
    }
    (landmarks, [tx, ty])
}

/// A `side`x`side` RGBA test image: two sinusoidal gratings shifted by `phase`, brightened by
/// `bright` levels in red, and a blue pattern centred on (`cx`, `cy`).
pub fn texture(side: u32, phase: f32, bright: f32, [cx, cy]: [f32; 2]) -> Image {
    let k = 96.0 / side as f32; // the gratings' periods scale with the image
    let mut data = Vec::with_capacity((side * side * 4) as usize);
    for y in 0..side {
        for x in 0..side {
            let (xf, yf) = (x as f32, y as f32);
            let r = 128.0 + 90.0 * (0.2 * k * xf + phase).sin() + bright;
            let g = 128.0 + 90.0 * (0.15 * k * yf - phase).cos();
            let b = 64.0 + ((xf - cx) * (yf - cy) * 0.05 * k * k).abs().min(180.0);
            data.extend_from_slice(&[
                r.clamp(0.0, 255.0) as u8,
                g.clamp(0.0, 255.0) as u8,
                b.clamp(0.0, 255.0) as u8,
                255,
            ]);
        }
    }
    Image {
        width: side,
        height: side,
        data,
    }
}

/// `count` face-like training images with `n` landmarks (named `{prefix}{k}`) on
/// `side`x`side` RGBA images: the face (`face_landmarks`) about 5/8 of the image wide, at its
/// centre (+-1/24 of the side), on a texture that depends on the face's place.
pub fn training_set(
    n: usize,
    count: usize,
    seed: u64,
    side: u32,
    prefix: &str,
) -> Vec<TrainingImage> {
    let mut rng = Rng::new(seed);
    let s = side as f32;
    (0..count)
        .map(|k| {
            let (landmarks, centre) = face_landmarks(&mut rng, n, s * 0.3125, s / 2.0, s / 24.0);
            let phase = rng.sym() * 3.0;
            let bright = 40.0 * rng.sym();
            TrainingImage {
                name: format!("{prefix}{k}"),
                image: texture(side, phase, bright, centre),
                landmarks,
            }
        })
        .collect()
}
