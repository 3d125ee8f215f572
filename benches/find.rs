//! Benchmarks of the face finder (`FaceFinder`), native, single thread.
//!
//! The frame: GRID `data/grid/spk01_bbaf2n/000004.jpg` (360x288, committed) upscaled 1.5x
//! (nearest) to 540x432 and centred on a 640x480 black frame (one face, about 150 px wide), the
//! size of a typical webcam frame.
//!
//! - `find/find/640x480`: `FaceFinder::find` (the detector, then two mesh passes on its face).
//! - `find/landmarks/640x480`: `FaceFinder::landmarks_into` given the box `find` returned (two
//!   mesh passes).
//! - `find/follow/640x480`: `FaceFinder::follow_into`, the next frame of a followed face (one
//!   mesh pass on the region of the last mesh; what the `Follower` runs per frame).
//! - `find/no_face/640x480`: `FaceFinder::find` on the frame blacked out (the detector alone:
//!   what a search costs while the face is away).
//! - `find/find_without_local/640x480`: `find` with the local correction off, and
//!   `find/local_correction/640x480`: the correction alone on that face's points (both stages).
//!
//! Run: `cargo bench --bench find`.

use std::path::Path;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use facemimic::find::{LocalCorrection, LocalScratch};
use facemimic::{io, FaceFinder, Image};

/// The GRID frame upscaled 1.5x and padded to 640x480.
fn frame_640x480() -> Image {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/grid/spk01_bbaf2n/000004.jpg");
    let src = io::read_image(&path).expect("GRID frame");
    let (w, h) = (640u32, 480u32);
    let (sw, sh) = (src.width * 3 / 2, src.height * 3 / 2);
    assert!(sw <= w && sh <= h, "{sw}x{sh} does not fit");
    let (ox, oy) = ((w - sw) / 2, (h - sh) / 2);
    let mut data = vec![0u8; (w * h * 4) as usize];
    for i in (3..data.len()).step_by(4) {
        data[i] = 255;
    }
    for y in 0..sh {
        let syy = (y * 2 / 3).min(src.height - 1);
        for x in 0..sw {
            let sx = (x * 2 / 3).min(src.width - 1);
            let s = ((syy * src.width + sx) * 4) as usize;
            let d = (((y + oy) * w + x + ox) * 4) as usize;
            data[d..d + 4].copy_from_slice(&src.data[s..s + 4]);
        }
    }
    Image {
        width: w,
        height: h,
        data,
    }
}

fn bench_find(c: &mut Criterion) {
    let image = frame_640x480();
    let view = image.view().expect("view");
    let mut finder = FaceFinder::new().expect("finder");
    let faces = finder.find(&view);
    assert_eq!(faces.len(), 1, "expected one face in the benchmark frame");
    let bbox = faces[0].bbox;
    println!(
        "find: 640x480 frame, face box {:.0}x{:.0} at ({:.0}, {:.0}), score {:.2}",
        bbox.width, bbox.height, bbox.x, bbox.y, faces[0].score
    );

    let mut group = c.benchmark_group("find");
    group.throughput(Throughput::Elements(1));
    group.sample_size(20);
    group.bench_function("find/640x480", |b| b.iter(|| finder.find(&view)));
    let mut out = vec![0.0f32; 136];
    group.bench_function("landmarks/640x480", |b| {
        b.iter(|| {
            finder
                .landmarks_into(&view, bbox, &mut out)
                .expect("landmarks")
        })
    });
    group.bench_function("follow/640x480", |b| {
        b.iter(|| finder.follow_into(&view, &mut out).expect("follow"))
    });
    let black = Image {
        data: vec![0; image.data.len()],
        ..image.clone()
    };
    let black = black.view().expect("view");
    assert!(finder.find(&black).is_empty());
    group.bench_function("no_face/640x480", |b| b.iter(|| finder.find(&black)));
    // The local correction alone, on the face's points before it.
    finder.set_local_correction(false);
    group.bench_function("find_without_local/640x480", |b| {
        b.iter(|| finder.find(&view))
    });
    let before = finder.find(&view).remove(0).landmarks;
    let local = LocalCorrection::shipped().expect("the shipped correction");
    let mut scratch = LocalScratch::default();
    group.bench_function("local_correction/640x480", |b| {
        b.iter(|| {
            out.copy_from_slice(&before);
            local.apply(&view, &mut out, &mut scratch);
        })
    });
    group.finish();
}

criterion_group!(benches, bench_find);
criterion_main!(benches);
