//! Is the face finder's difference from the dlib landmarks a fixed bias (a convention) or noise?
//! For each clip in ../shared/data (research data, never committed): the finder's most confident
//! face on every `STEP`th frame, its offset from dlib per point in the face's own frame (x along
//! the finder's outer-eye-corner line, in units of that distance), the mean offset (bias) and the
//! error left after removing a bias learned on *another* clip.
//!
//!   cargo run --release --example finder_bias -- [STEP]
#![cfg_attr(target_arch = "wasm32", no_main)]

#[cfg(not(any(target_arch = "wasm32", test)))]
use native::main;

/// Native only: the example reads files.
#[cfg(not(any(target_arch = "wasm32", test)))]
mod native {
    use std::path::Path;

    use facemimic::{io, FaceFinder};

    fn frame_of(p: &[f32]) -> (f32, f32, f32, f32) {
        // Unit vector along the outer eye corners (36 -> 45) and their distance; origin at their mean.
        let (dx, dy) = (p[90] - p[72], p[91] - p[73]);
        let d = (dx * dx + dy * dy).sqrt();
        (dx / d, dy / d, d, 0.0)
    }

    fn offsets(finder: &[f32], dlib: &[f32]) -> Vec<f32> {
        let (c, s, d, _) = frame_of(finder);
        (0..68)
            .flat_map(|i| {
                let (ex, ey) = (
                    finder[2 * i] - dlib[2 * i],
                    finder[2 * i + 1] - dlib[2 * i + 1],
                );
                [(c * ex + s * ey) / d, (-s * ex + c * ey) / d]
            })
            .collect()
    }

    fn corrected(finder: &[f32], bias: &[f32]) -> Vec<f32> {
        let (c, s, d, _) = frame_of(finder);
        (0..68)
            .flat_map(|i| {
                let (bx, by) = (bias[2 * i] * d, bias[2 * i + 1] * d);
                [
                    finder[2 * i] - (c * bx - s * by),
                    finder[2 * i + 1] - (s * bx + c * by),
                ]
            })
            .collect()
    }

    fn error(a: &[f32], truth: &[f32]) -> f32 {
        let iod = ((truth[90] - truth[72]).powi(2) + (truth[91] - truth[73]).powi(2)).sqrt();
        (0..68)
            .map(|i| {
                ((a[2 * i] - truth[2 * i]).powi(2) + (a[2 * i + 1] - truth[2 * i + 1]).powi(2))
                    .sqrt()
            })
            .sum::<f32>()
            / 68.0
            / iod
    }

    /// (finder, dlib) landmark pairs of one clip.
    type Pairs = Vec<(Vec<f32>, Vec<f32>)>;

    pub(crate) fn main() {
        let step: usize = std::env::args()
            .nth(1)
            .map(|s| s.parse().unwrap())
            .unwrap_or(10);
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
        let mut finder = FaceFinder::new().unwrap();
        let mut find = |image: &facemimic::ImageRef| finder.find(image);
        let clips = [
            "franck-dev",
            "franck-dev2",
            "grid/spk02_brbk7n",
            "grid/spk07_pwij3p",
            "webcam-dev",
        ];
        let mut data: Vec<(String, Pairs)> = Vec::new();
        for clip in clips {
            let dir = root.join(clip);
            let mut stems: Vec<_> = std::fs::read_dir(&dir)
                .unwrap()
                .filter_map(|e| e.ok())
                .map(|e| e.path())
                .filter(|p| p.extension().is_some_and(|x| x == "jpg"))
                .collect();
            stems.sort();
            let mut pairs = Vec::new();
            let limit = if clip == "webcam-dev" {
                600
            } else {
                usize::MAX
            };
            for p in stems.iter().take(limit).step_by(step) {
                let t = io::read_training_image(p).unwrap();
                if let Some(f) = find(&t.image.view().unwrap()).first() {
                    pairs.push((f.landmarks.clone(), t.landmarks.clone()));
                }
            }
            data.push((clip.to_string(), pairs));
        }
        let bias_of = |pairs: &[(Vec<f32>, Vec<f32>)]| {
            let mut b = vec![0.0f32; 136];
            for (f, d) in pairs {
                for (x, o) in b.iter_mut().zip(offsets(f, d)) {
                    *x += o / pairs.len() as f32;
                }
            }
            b
        };
        let biases: Vec<Vec<f32>> = data.iter().map(|(_, p)| bias_of(p)).collect();
        let names: Vec<&str> = data.iter().map(|(n, _)| n.as_str()).collect();
        println!("rows: clip measured; columns: raw finder error, then after removing the bias of each clip ({})", names.join(", "));
        for (k, (name, pairs)) in data.iter().enumerate() {
            let raw: f32 = pairs.iter().map(|(f, d)| error(f, d)).sum::<f32>() / pairs.len() as f32;
            let cols: Vec<String> = biases
                .iter()
                .map(|b| {
                    let e: f32 = pairs
                        .iter()
                        .map(|(f, d)| error(&corrected(f, b), d))
                        .sum::<f32>()
                        / pairs.len() as f32;
                    format!("{e:.4}")
                })
                .collect();
            println!(
                "{name:22} n={:4} raw {raw:.4} | {}",
                pairs.len(),
                cols.join(" ")
            );
            let mag: Vec<f32> = (0..68)
                .map(|i| (biases[k][2 * i].powi(2) + biases[k][2 * i + 1].powi(2)).sqrt())
                .collect();
            println!(
                "   bias magnitude: jaw {:.4} brows {:.4} nose {:.4} eyes {:.4} mouth {:.4}",
                mag[0..17].iter().sum::<f32>() / 17.0,
                mag[17..27].iter().sum::<f32>() / 10.0,
                mag[27..36].iter().sum::<f32>() / 9.0,
                mag[36..48].iter().sum::<f32>() / 12.0,
                mag[48..68].iter().sum::<f32>() / 20.0
            );
        }
    }
}
