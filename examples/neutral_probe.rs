//! Where a tracked person's neutral mouth sits (research probe for `fit::bound_neutral_mouth`):
//!
//! - `neutral_probe london`: the mouth's width and corner lift ([`mouth_shape`]) of the London
//!   set's 60 neutral and 60 smiling photos, by dlib's points and by the face finder's (the
//!   follower's convention), as mean, deviation and percentiles. The photos are read from
//!   `../shared/data/london` (only two are committed).
//! - `neutral_probe CLIP`: a clip of `../shared/data` (research data, never committed) followed
//!   with spk07's model at 25 fps, one line a frame: the finder's width and lift (every 5th
//!   frame, else 0), dlib's, dlib's inner-lip opening, the follower's neutral's width and lift,
//!   and the largest move of a point from the neutral (over the eye corners' distance) with the
//!   frame's and the neutral's mouth openings: what lets a frame into the neutral.
//!
//! ```sh
//! cargo run --release --example neutral_probe -- london
//! cargo run --release --example neutral_probe -- franck-dev2 > /tmp/np.txt
//! ```
//!
//! [`mouth_shape`]: facemimic::fit::mouth_shape

/// Native only: the probe reads files.
#[cfg(not(any(target_arch = "wasm32", test)))]
fn main() -> std::process::ExitCode {
    match native::run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("neutral_probe: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}

#[cfg(any(target_arch = "wasm32", test))]
fn main() {}

#[cfg(not(any(target_arch = "wasm32", test)))]
mod native {
    use facemimic::fit::{
        mouth_opening, mouth_shape, FaceTracker, FollowOptions, Follower, REST_CORNER_LIFT,
        REST_MOUTH_WIDTH,
    };
    use facemimic::{io, Error, Result};
    use facemimic_testkit as common;

    /// Width and lift, zeros for a shape without them.
    fn shape(p: &[f32]) -> [f32; 2] {
        mouth_shape(p).unwrap_or([0.0; 2])
    }

    fn stats(v: &[f32]) -> String {
        if v.is_empty() {
            return "none".into();
        }
        let n = v.len() as f32;
        let m = v.iter().sum::<f32>() / n;
        let s = (v.iter().map(|x| (x - m) * (x - m)).sum::<f32>() / n).sqrt();
        let mut w = v.to_vec();
        w.sort_by(f32::total_cmp);
        let q = |f: f32| w[((n - 1.0) * f).round() as usize];
        format!(
            "mean {m:.4} sd {s:.4} p5 {:.3} p50 {:.3} p90 {:.3} p95 {:.3} max {:.3} ({} faces)",
            q(0.05),
            q(0.5),
            q(0.9),
            q(0.95),
            w[w.len() - 1],
            w.len()
        )
    }

    pub fn run() -> Result<()> {
        let arg = std::env::args()
            .nth(1)
            .unwrap_or_else(|| "franck-dev2".into());
        let data = common::repo("../shared/data");
        let mut finder = facemimic::FaceFinder::new()?;
        if arg == "london" {
            for kind in ["neutral", "smiling"] {
                let (mut dlib, mut found) = (vec![], vec![]);
                for path in common::clip_frames(&data.join("london").join(kind)) {
                    let t = io::read_training_image(&path)?;
                    dlib.push(shape(&t.landmarks));
                    if let Some(f) = finder.find(&t.image.view()?).into_iter().next() {
                        found.push(shape(&f.landmarks));
                    }
                }
                // `bound_neutral_mouth` holds a mouth wider than at rest, and then its lift.
                let beyond = |v: &[[f32; 2]]| v.iter().filter(|x| x[0] > REST_MOUTH_WIDTH).count();
                let lifted = |v: &[[f32; 2]]| {
                    v.iter()
                        .filter(|x| x[0] > REST_MOUTH_WIDTH && x[1] > REST_CORNER_LIFT)
                        .count()
                };
                println!(
                    "{kind}: wider and also more lifted than at rest: dlib {}, finder {}",
                    lifted(&dlib),
                    lifted(&found)
                );
                println!(
                    "{kind}: wider than a mouth at rest: dlib {} of {}, finder {} of {}",
                    beyond(&dlib),
                    dlib.len(),
                    beyond(&found),
                    found.len()
                );
                for (k, what) in [(0, "width"), (1, "lift")] {
                    let col = |v: &[[f32; 2]]| v.iter().map(|x| x[k]).collect::<Vec<_>>();
                    println!("{kind} {what}: dlib {}", stats(&col(&dlib)));
                    println!("{kind} {what}: finder {}", stats(&col(&found)));
                }
            }
            return Ok(());
        }
        let paths = common::clip_frames(&data.join(&arg));
        if paths.is_empty() {
            return Err(Error::Io(format!("{arg}: no frames under ../shared/data")));
        }
        let mut follower = Follower::new(&common::following::spk07(), FollowOptions::default())?;
        for (i, path) in paths.iter().enumerate() {
            let t = io::read_training_image(path)?;
            follower.track(&t.image.view()?, 1.0 / 25.0)?;
            let (mut most, mut at, mut open, mut rest) = (0f32, 0usize, 0f32, 0f32);
            if let (Some(n), Some(o)) = (follower.neutral(), follower.observed()) {
                if let Some(d) = o.displacement {
                    let iod = (n[90] - n[72]).hypot(n[91] - n[73]);
                    for k in 0..68 {
                        let v = d[2 * k].hypot(d[2 * k + 1]) / iod;
                        if v > most {
                            (most, at) = (v, k);
                        }
                    }
                    let s: Vec<f32> = n.iter().zip(d).map(|(a, b)| a + b).collect();
                    (open, rest) = (mouth_opening(&s), mouth_opening(n));
                }
            }
            let found = if i % 5 == 0 {
                finder
                    .find(&t.image.view()?)
                    .into_iter()
                    .next()
                    .map(|f| shape(&f.landmarks))
                    .unwrap_or([0.0; 2])
            } else {
                [0.0; 2]
            };
            let [dw, dl] = shape(&t.landmarks);
            let [nw, nl] = follower.neutral().map(shape).unwrap_or([0.0; 2]);
            println!(
                "{i} find_w {:.3} find_l {:.3} dlib_w {dw:.3} dlib_l {dl:.3} open {:.3} neutral_w {nw:.3} neutral_l {nl:.3} most {most:.3} at {at} frame_open {open:.3} neutral_open {rest:.3}",
                found[0],
                found[1],
                mouth_opening(&t.landmarks)
            );
        }
        Ok(())
    }
}
