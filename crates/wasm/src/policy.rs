//! `policy()`: the core's front-end policy, so the page, the call page and a package user
//! decide nothing of their own (work-frame size, photo targets, enrolment sampling, cloning
//! defaults).

use crate::JsError;
use serde::Serialize;
use wasm_bindgen::prelude::*;

use facemimic::clone::CloneOptions;
use facemimic::fit::WORK_SIDE;
use facemimic::{EnrolSampling, PHOTO_FIT_PASSES, PHOTO_MAX_SIDE};

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
struct PolicyJs {
    work_side: u32,
    photo: PhotoJs,
    enrol: EnrolJs,
    clone: CloneJs,
}

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
struct PhotoJs {
    max_side: u32,
    find_side: u32,
    fit_passes: u32,
}

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
struct EnrolJs {
    want: usize,
    min_frames: usize,
    max_candidates: usize,
    max_side: u32,
    sample_ms: u32,
    video_samples: usize,
}

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
struct CloneJs {
    method: &'static str,
    gain: f32,
    clamp: Option<f32>,
    follow_pose: bool,
    mouth: f32,
    eyes: f32,
    brows: f32,
    style: f32,
}

/// The core's front-end policy as a plain object (see the TypeScript `Policy`): the work-frame
/// side video is scaled down to before tracking and finding; photo targets' picture size, the
/// side a photo is searched at and the fitting passes of a still source; how enrolment samples
/// frames; and the cloning defaults a new `Cloner` starts with.
#[wasm_bindgen(unchecked_return_type = "Policy")]
pub fn policy() -> Result<JsValue, JsError> {
    let s = EnrolSampling::DEFAULT;
    let c = CloneOptions::default();
    let p = PolicyJs {
        work_side: WORK_SIDE,
        photo: PhotoJs {
            max_side: PHOTO_MAX_SIDE,
            find_side: WORK_SIDE,
            fit_passes: PHOTO_FIT_PASSES,
        },
        enrol: EnrolJs {
            want: s.want,
            min_frames: s.min_frames,
            max_candidates: s.max_candidates,
            max_side: WORK_SIDE,
            sample_ms: s.sample_ms,
            video_samples: s.video_samples,
        },
        clone: CloneJs {
            method: c.method.name(),
            gain: c.gain,
            clamp: c.clamp,
            follow_pose: c.follow_pose,
            mouth: c.regions.mouth,
            eyes: c.regions.eyes,
            brows: c.regions.brows,
            style: c.style,
        },
    };
    let ser = serde_wasm_bindgen::Serializer::new().serialize_missing_as_null(true);
    p.serialize(&ser).map_err(|e| JsError::core("policy", e))
}
