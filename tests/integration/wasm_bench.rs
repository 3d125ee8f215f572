//! Timings of the core operations, natively and in wasm under Node, with one harness (a
//! wasm-bindgen test that also runs natively). As a test (the default) it runs every stage a
//! few times and asserts what the timings rest on: the build and the projection are
//! deterministic, the render paints a face (the timings themselves are figures, printed, not
//! asserted: a time cannot be wrong, only slow). The timing
//! windows are long (seconds per stage, the figures) only when `FACEMIMIC_BENCH` was set when
//! the test was BUILT (`option_env!`), so that CI does not pay for them:
//!
//! ```text
//! FACEMIMIC_BENCH=1 cargo test --release --target wasm32-unknown-unknown --test integration wasm_bench:: -- --nocapture
//! FACEMIMIC_BENCH=1 cargo test --release --test integration wasm_bench:: -- --nocapture
//! ```
//!
//! No files are read (the wasm test has none), so the 20 training images are synthetic 360x288
//! RGBA images with the REAL spk07 train20 landmarks (compiled in); the cost of building,
//! sampling and rendering does not depend on the pixel values. Figures:
//! docs/core-figures.md.

use facemimic::tiny_skia::{Color, Pixmap};
use facemimic::{
    landmarks, BuildOptions, Builder, DrawOptions, FaceDrawer, Image, Model, Params, Similarity,
    TrainingImage,
};
use wasm_bindgen_test::wasm_bindgen_test;

macro_rules! pts {
    ($($stem:literal),*) => { [$(($stem, include_str!(concat!("../../data/grid/spk07_pwij3p/", $stem, ".pts")))),*] };
}

const TRAIN: [(&str, &str); 20] = pts!(
    "000000", "000004", "000011", "000012", "000013", "000019", "000020", "000021", "000028",
    "000033", "000034", "000035", "000037", "000038", "000042", "000044", "000045", "000049",
    "000051", "000065"
);
const PROBE: &str = include_str!("../../data/grid/spk07_pwij3p/000030.pts");

/// Milliseconds from an arbitrary origin.
fn now_ms() -> f64 {
    #[cfg(target_arch = "wasm32")]
    {
        js_sys::Date::now()
    }
    #[cfg(not(target_arch = "wasm32"))]
    {
        use std::sync::OnceLock;
        static T0: OnceLock<std::time::Instant> = OnceLock::new();
        T0.get_or_init(std::time::Instant::now)
            .elapsed()
            .as_secs_f64()
            * 1e3
    }
}

fn say(s: &str) {
    #[cfg(target_arch = "wasm32")]
    wasm_bindgen_test::console_log!("{}", s);
    #[cfg(not(target_arch = "wasm32"))]
    println!("{s}");
}

/// CPU time of this thread (native: `/proc/thread-self/schedstat`) or of the Node process
/// (`process.cpuUsage()`), in ms; `None` where unavailable. On a shared, loaded machine it
/// is a steadier measure than wall time (time spent waiting for a core is not counted).
fn cpu_ms() -> Option<f64> {
    #[cfg(target_arch = "wasm32")]
    {
        use wasm_bindgen::JsCast;
        let process = js_sys::Reflect::get(&js_sys::global(), &"process".into()).ok()?;
        let f = js_sys::Reflect::get(&process, &"cpuUsage".into())
            .ok()?
            .dyn_into::<js_sys::Function>()
            .ok()?;
        let u = f.call0(&process).ok()?;
        let user = js_sys::Reflect::get(&u, &"user".into()).ok()?.as_f64()?;
        let system = js_sys::Reflect::get(&u, &"system".into()).ok()?.as_f64()?;
        Some((user + system) / 1e3)
    }
    #[cfg(not(target_arch = "wasm32"))]
    {
        let s = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
        Some(s.split_whitespace().next()?.parse::<f64>().ok()? / 1e6)
    }
}

/// Whether the timing windows are the figures' (`FACEMIMIC_BENCH` set at build time) or none.
const BENCH: bool = option_env!("FACEMIMIC_BENCH").is_some();

/// Runs `f` for at least `min_ms` of wall time and at least 3 times, after 2 warm-up calls;
/// without [`BENCH`], once with no warm-up. Returns the mean wall time and CPU time per call
/// in ms.
fn time(min_ms: f64, mut f: impl FnMut()) -> (f64, Option<f64>) {
    let (min_ms, min_calls) = if BENCH {
        f();
        f();
        (min_ms, 3)
    } else {
        (0.0, 1)
    };
    let (t0, c0, mut n) = (now_ms(), cpu_ms(), 0u32);
    while n < min_calls || now_ms() - t0 < min_ms {
        f();
        n += 1;
    }
    let cpu = c0.zip(cpu_ms()).map(|(a, b)| (b - a) / n as f64);
    ((now_ms() - t0) / n as f64, cpu)
}

fn image(seed: u32) -> Image {
    let (w, h) = (360u32, 288u32);
    let mut data = Vec::with_capacity((w * h * 4) as usize);
    for y in 0..h {
        for x in 0..w {
            let v = (x.wrapping_mul(31) ^ y.wrapping_mul(17) ^ seed.wrapping_mul(97)) as u8;
            data.extend_from_slice(&[v, v.wrapping_add(60), v.wrapping_add(120), 255]);
        }
    }
    Image {
        width: w,
        height: h,
        data,
    }
}

/// The synthetic training set: the spk07 landmarks of `TRAIN`, each on its own patterned image.
fn training_images() -> Vec<TrainingImage> {
    TRAIN
        .iter()
        .enumerate()
        .map(|(i, (name, text))| TrainingImage {
            name: name.to_string(),
            image: image(i as u32),
            landmarks: landmarks::parse_pts(text).unwrap(),
        })
        .collect()
}

/// The render at `params` painted the face over the background of `pixmap`: about the frame's
/// pixels times the pose's scale squared.
fn check_face_painted(model: &Model, params: &Params, pixmap: &Pixmap) {
    let [r, g, b, _] = [32u8, 32, 36, 255];
    let face = pixmap
        .pixels()
        .iter()
        .filter(|p| (p.red(), p.green(), p.blue()) != (r, g, b))
        .count();
    // The face covers about the frame's pixels times the pose's scale squared.
    let expected = model.frame().n_pixels() as f32 * params.pose.scale().powi(2);
    assert!(
        face as f32 > 0.5 * expected,
        "the render painted {face} pixels, about {expected} expected"
    );
}

#[wasm_bindgen_test(unsupported = test)]
fn core_timings() {
    let target = if cfg!(target_arch = "wasm32") {
        "wasm32 (Node)"
    } else {
        "native"
    };
    let images = training_images();
    let builder = Builder::new(BuildOptions {
        name: "spk07".into(),
        ..BuildOptions::default()
    });
    let model = builder.build(&images, None).unwrap();
    let probe_image = image(99);
    let probe = landmarks::parse_pts(PROBE).unwrap();
    let view = probe_image.view().unwrap();
    let params = model.project(&view, &probe).unwrap();
    say(&format!(
        "[{target}] model: {} shape modes, {} appearance modes, {} frame pixels",
        model.shape().n_modes(),
        model.appearance().n_modes(),
        model.frame().n_pixels()
    ));

    let build = time(3000.0, || {
        std::hint::black_box(builder.build(&images, None).unwrap());
    });
    let mut renderer = FaceDrawer::new(model.frame(), DrawOptions::default()).unwrap();
    let mut pixmap = Pixmap::new(360, 288).unwrap();
    pixmap.fill(Color::from_rgba8(32, 32, 36, 255));
    let render = time(2000.0, || {
        renderer
            .render(&model, &params, &Similarity::IDENTITY, &mut pixmap.as_mut())
            .unwrap();
    });
    let mut appearance = vec![0f32; model.appearance().len()];
    let synth = time(1000.0, || {
        model
            .appearance()
            .instance_unchecked(&params.appearance, &mut appearance)
    });
    let upload = time(1000.0, || {
        renderer.upload(model.frame(), &appearance).unwrap()
    });
    let mut shape = vec![0f32; model.landmarks() * 2];
    model.image_shape(&params, &mut shape).unwrap();
    let warp = time(2000.0, || {
        renderer
            .warp(
                model.frame(),
                &shape,
                &Similarity::IDENTITY,
                &mut pixmap.as_mut(),
            )
            .unwrap();
    });
    let mut g = vec![0f32; model.appearance().len()];
    let sample = time(2000.0, || {
        facemimic::numerics::sample_rgb(model.frame(), &view, &probe, &mut g).unwrap()
    });
    let project = time(2000.0, || {
        std::hint::black_box(model.project(&view, &probe).unwrap());
    });
    // What the timings rest on.
    assert!(
        builder.build(&images, None).unwrap() == model,
        "the build is not deterministic"
    );
    assert_eq!(model.project(&view, &probe).unwrap(), params);
    check_face_painted(&model, &params, &pixmap);
    assert!(appearance.iter().all(|v| v.is_finite()));
    for (what, ms) in [
        ("build spk07 (20 images)", build),
        ("render 360x288 (synthesis + upload + warp)", render),
        ("appearance synthesis (Eq. 2)", synth),
        ("upload appearance to texture", upload),
        ("warp texture onto 360x288 (tiny-skia)", warp),
        ("sample_rgb image -> frame", sample),
        ("project (pose, shape, appearance)", project),
    ] {
        let cpu = ms.1.map_or("n/a".to_string(), |c| format!("{c:.3} ms"));
        say(&format!(
            "[{target}] {what}: wall {:.3} ms, cpu {cpu}",
            ms.0
        ));
    }
}
