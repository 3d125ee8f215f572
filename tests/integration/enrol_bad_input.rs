//! Issue 33's bad input for enrolment, through the core's pipeline ([`facemimic::enrol`], which
//! the page's "Create a face", the wasm `buildModel` and the CLI's `build --find-faces` all
//! call): none of these yields a model without saying so. Committed GRID frames only (speaker 7's
//! unseen clip `spk07_id2_vcd_swwp2s` and speaker 2's `spk02_brbk7n`), so it runs everywhere.
//! - every frame occluded (a skin-coloured ellipse over the mouth): an error naming the frames
//!   as occluded;
//! - the face leaving the picture mid-enrolment (the later frames cut at the nose): those frames
//!   are reported (outside, or no face), the model is built from the others;
//! - a frozen webcam (one picture again and again): an error saying the camera seems frozen;
//! - frames alternating between two people: an error saying so, naming the frames.

use crate::enrol_quality::{occlude, try_enrol_clip, Occluder};
use facemimic::TrainingImage;
use facemimic_testkit as common;

/// Frames `0..n` (every 3rd) of a committed GRID clip.
fn clip(name: &str, n: usize) -> Vec<TrainingImage> {
    let dir = common::repo(&format!("data/grid/{name}"));
    common::load(&common::clip_frames(&dir))
        .into_iter()
        .step_by(3)
        .take(n)
        .collect()
}

#[test]
fn a_clip_with_every_frame_occluded_yields_no_model() {
    let frames: Vec<_> = clip("spk07_id2_vcd_swwp2s", 16)
        .iter()
        .enumerate()
        .map(|(k, t)| occlude(t, Occluder::Mouth, k as u32))
        .collect();
    let e = try_enrol_clip(&frames).expect_err("a model from occluded frames");
    let msg = e.to_string();
    assert!(msg.contains("occluded"), "{msg}");
    assert!(msg.contains("a usable face in"), "{msg}");
}

#[test]
fn a_face_leaving_the_picture_is_reported_and_left_out() {
    let frames: Vec<_> = clip("spk07_id2_vcd_swwp2s", 24)
        .iter()
        .enumerate()
        .map(|(k, t)| {
            if k >= 14 {
                occlude(t, Occluder::HalfOut, k as u32)
            } else {
                t.clone()
            }
        })
        .collect();
    let e = try_enrol_clip(&frames).unwrap();
    let left_out: Vec<usize> = e
        .skipped
        .iter()
        .copied()
        .chain(e.rejected.iter().map(|&(i, _)| i))
        .collect();
    for k in 14..24 {
        assert!(
            left_out.contains(&k),
            "frame {k} (half out) not reported: {e:?}",
            e = (&e.skipped, &e.rejected)
        );
    }
    assert!(
        e.used.iter().all(|&i| i < 14),
        "built from half-out frames: {:?}",
        e.used
    );
}

#[test]
fn a_frozen_webcam_yields_no_model() {
    let one = clip("spk07_id2_vcd_swwp2s", 1).remove(0);
    let frames = vec![one; 16];
    let msg = try_enrol_clip(&frames)
        .expect_err("a model from a frozen camera")
        .to_string();
    assert!(msg.contains("the camera seems frozen"), "{msg}");
}

#[test]
fn frames_alternating_between_two_people_yield_no_model() {
    let a = clip("spk07_id2_vcd_swwp2s", 10);
    let b = clip("spk02_brbk7n", 10);
    let frames: Vec<_> = a.into_iter().zip(b).flat_map(|(x, y)| [x, y]).collect();
    let msg = try_enrol_clip(&frames)
        .expect_err("a model from two people")
        .to_string();
    assert!(msg.contains("two different people"), "{msg}");
}
