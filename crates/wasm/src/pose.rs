//! Pose helpers for JavaScript (the page's re-centring of a tracked or recorded head).

use crate::JsError;
use wasm_bindgen::prelude::*;

use facemimic::{PoseJson, Similarity};

fn pose_from_js(what: &str, v: JsValue) -> Result<Similarity, JsError> {
    serde_wasm_bindgen::from_value(v).map_err(|e| JsError::new(&format!("{what}: {e}")))
}

/// A pose as the JS `Pose` object every function here returns.
fn pose_to_js(pose: Similarity) -> Result<JsValue, JsError> {
    serde_wasm_bindgen::to_value(&PoseJson::from(pose)).map_err(|e| JsError::core("pose", e))
}

/// The mean of poses (`Similarity::mean`: geometric in scale, circular in angle, arithmetic in
/// translation), the one pose average of the package. Throws for an empty list, a pose that is
/// not `{ scale > 0, rotation, tx, ty }` with finite values, or rotations that cancel out.
#[wasm_bindgen(js_name = meanPose, unchecked_return_type = "Pose")]
pub fn mean_pose(
    #[wasm_bindgen(unchecked_param_type = "Pose[]")] poses: JsValue,
) -> Result<JsValue, JsError> {
    let poses: Vec<Similarity> =
        serde_wasm_bindgen::from_value(poses).map_err(|e| JsError::core("meanPose", e))?;
    let m = Similarity::mean(&poses).ok_or_else(|| {
        JsError::new("meanPose: no poses, an invalid pose, or rotations that cancel out")
    })?;
    pose_to_js(m)
}

/// `target ∘ anchor⁻¹ ∘ pose` (`Similarity::recentred`): `pose` moved so that where `anchor`
/// places a face, `target` does, keeping the motion relative to `anchor` exactly. Throws for a
/// pose that is not `{ scale > 0, rotation, tx, ty }` with finite values.
#[wasm_bindgen(js_name = recentrePose, unchecked_return_type = "Pose")]
pub fn recentre_pose(
    #[wasm_bindgen(unchecked_param_type = "Pose")] pose: JsValue,
    #[wasm_bindgen(unchecked_param_type = "Pose")] anchor: JsValue,
    #[wasm_bindgen(unchecked_param_type = "Pose")] target: JsValue,
) -> Result<JsValue, JsError> {
    let pose = pose_from_js("pose", pose)?;
    let anchor = pose_from_js("anchor", anchor)?;
    let target = pose_from_js("target", target)?;
    let r = pose
        .recentred(&anchor, &target)
        .ok_or_else(|| JsError::new("recentrePose: the anchor pose has no inverse"))?;
    pose_to_js(r)
}

/// The pose `u` of the way from `from` to `to` (`Similarity::lerp`: the scale geometrically,
/// the rotation the short way round, the translation linearly; the convention of `meanPose`).
/// Throws for a pose that is not `{ scale > 0, rotation, tx, ty }` with finite values, or a
/// `u` that is not finite.
#[wasm_bindgen(js_name = lerpPose, unchecked_return_type = "Pose")]
pub fn lerp_pose(
    #[wasm_bindgen(unchecked_param_type = "Pose")] from: JsValue,
    #[wasm_bindgen(unchecked_param_type = "Pose")] to: JsValue,
    u: f32,
) -> Result<JsValue, JsError> {
    let from = pose_from_js("from", from)?;
    let to = pose_from_js("to", to)?;
    if !u.is_finite() {
        return Err(JsError::new(&format!(
            "lerpPose: u is {u}, not a finite number"
        )));
    }
    pose_to_js(from.lerp(&to, u))
}

/// Head-motion damping: the core's `fit::HeadDamper` (what `Cloner.setHeadDamping` applies inside
/// the cloner) over its running pose anchor
/// (`PoseAnchor`: an exponential running mean of the poses, geometric in scale, the short way
/// round in angle, time constant `tau` seconds), and each pose's deviation from it scaled.
#[wasm_bindgen(js_name = PoseDamper)]
#[derive(Debug)]
pub struct JsPoseDamper {
    /// The core's damper (its factor is set on each `apply`).
    inner: facemimic::fit::HeadDamper,
}

#[wasm_bindgen(js_class = PoseDamper)]
impl JsPoseDamper {
    /// A damper whose anchor follows the head with time constant `tau` seconds (default 2; 0:
    /// it stays at the first pose). Throws for a `tau` that is not a finite non-negative number.
    #[wasm_bindgen(constructor)]
    pub fn new(tau: Option<f32>) -> Result<JsPoseDamper, JsError> {
        super::install_panic_hook();
        let inner = facemimic::fit::HeadDamper::new(tau.unwrap_or(2.0), 1.0)
            .map_err(|e| JsError::core("PoseDamper", e))?;
        Ok(JsPoseDamper { inner })
    }

    /// Forgets the anchor: the next pose becomes it.
    pub fn reset(&mut self) {
        self.inner.restart();
    }

    /// Moves the anchor towards `pose` for the time since the last call (`now`, a clock in
    /// milliseconds, e.g. `performance.now()`; a clock going back counts as no time) and
    /// returns `anchor + factor * (pose - anchor)` (`lerpPose(anchor, pose, factor)`: 0 holds
    /// the head at the anchor, 1 gives `pose`, above 1 exaggerates). Throws for a pose that is
    /// not `{ scale > 0, rotation, tx, ty }` with finite values, or a `now` or `factor` that is
    /// not finite.
    #[wasm_bindgen(unchecked_return_type = "Pose")]
    pub fn apply(
        &mut self,
        #[wasm_bindgen(unchecked_param_type = "Pose")] pose: JsValue,
        now: f64,
        factor: f32,
    ) -> Result<JsValue, JsError> {
        let pose = pose_from_js("PoseDamper: pose", pose)?;
        if !(now.is_finite() && factor.is_finite() && pose.is_valid()) {
            return Err(JsError::new(&format!(
                "PoseDamper: a valid pose and a finite now ({now}) and factor ({factor}) are needed"
            )));
        }
        let tau = self.inner.tau();
        self.inner
            .set(tau, factor)
            .map_err(|e| JsError::core("PoseDamper", e))?;
        pose_to_js(self.inner.apply(pose, now))
    }
}
