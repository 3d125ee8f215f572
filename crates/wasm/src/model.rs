//! `Model` for JavaScript: load, inspect, project, render, and the inspector's `renderMode`.

use crate::JsError;
use std::cell::RefCell;
use std::sync::Arc;

use serde::Serialize;
use wasm_bindgen::prelude::*;

use super::surface::{paint, Ctx, RenderOptions, Sink};
use super::{
    install_panic_hook, js_err, params_from_js, params_to_js, Context2dArg, RenderOptionsArg,
};
use facemimic::ImageRef;
use facemimic::{base_box, fit_view, FaceDrawer};
use facemimic::{Model, Params, Reference};

/// The plain object `Model.info()` returns (see the TypeScript `ModelInfo`).
#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
pub(crate) struct ModelInfo {
    name: String,
    landmarks: usize,
    triangles: usize,
    frame_width: u32,
    frame_height: u32,
    pixels: usize,
    channels: u32,
    shape_modes: usize,
    appearance_modes: usize,
    shape_sigma: Vec<f32>,
    appearance_sigma: Vec<f32>,
    shape_variance_share: Vec<f32>,
    appearance_variance_share: Vec<f32>,
    fingerprint: String,
    reference: String,
    image_width: u32,
    image_height: u32,
    backdrop: Option<BackdropInfo>,
    backdrop_notice: Option<String>,
    is_photo: bool,
}

/// `ModelInfo.backdrop`.
#[derive(Serialize)]
pub(crate) struct BackdropInfo {
    width: u32,
    height: u32,
    bytes: usize,
}

pub(crate) fn model_info(m: &Model) -> Result<JsValue, JsError> {
    model_info_with(m, None)
}

/// [`model_info`] with the notice a file's reader left (a damaged backdrop).
pub(crate) fn model_info_with(m: &Model, notice: Option<&str>) -> Result<JsValue, JsError> {
    let info = ModelInfo {
        name: m.name().to_string(),
        landmarks: m.landmarks(),
        triangles: m.frame().triangles().len(),
        frame_width: m.frame().width(),
        frame_height: m.frame().height(),
        pixels: m.frame().n_pixels(),
        channels: 3,
        shape_modes: m.shape().n_modes(),
        appearance_modes: m.appearance().n_modes(),
        shape_sigma: m.shape().sigmas(),
        appearance_sigma: m.appearance().sigmas(),
        shape_variance_share: m.shape().variance_shares(),
        appearance_variance_share: m.appearance().variance_shares(),
        fingerprint: format!("{:016x}", m.frame().fingerprint()),
        reference: match &m.reference() {
            Reference::Mean => "mean".into(),
            Reference::Training(name) => name.clone(),
        },
        image_width: m.image_size()[0],
        image_height: m.image_size()[1],
        backdrop: m.backdrop().map(|b| BackdropInfo {
            width: b.width(),
            height: b.height(),
            bytes: b.jpeg().len(),
        }),
        backdrop_notice: notice.map(str::to_string),
        is_photo: m.is_photo(),
    };
    // `None` as `null`, as the TypeScript type says (`to_value` would give `undefined`).
    let ser = serde_wasm_bindgen::Serializer::new().serialize_missing_as_null(true);
    info.serialize(&ser)
        .map_err(|e| JsError::core("model info", e))
}

/// The plain object `modelSummary()` returns (see the TypeScript `ModelSummary`).
#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
struct SummaryJs {
    name: String,
    version: u32,
    landmarks: usize,
    shape_modes: usize,
    appearance_modes: usize,
    frame_pixels: usize,
    fingerprint: String,
    image_width: u32,
    image_height: u32,
    is_photo: bool,
    file_bytes: usize,
}

/// What a model file says of itself (header, names, length and checksum checked) without
/// building the model: lists kept models cheaply. Throws a JS `Error` naming what is wrong with
/// a file that is not a model (`fromBytes` may still refuse one this accepts, for what only a
/// full read sees).
#[wasm_bindgen(js_name = modelSummary, unchecked_return_type = "ModelSummary")]
pub fn model_summary(
    #[wasm_bindgen(unchecked_param_type = "Uint8Array")] bytes: &[u8],
) -> Result<JsValue, JsError> {
    let s = facemimic::format::read_summary(bytes).map_err(|e| js_err(e.into()))?;
    let js = SummaryJs {
        name: s.name,
        version: s.version,
        landmarks: s.landmarks,
        shape_modes: s.shape_modes,
        appearance_modes: s.appearance_modes,
        frame_pixels: s.frame_pixels,
        fingerprint: format!("{:016x}", s.fingerprint),
        image_width: s.image_size[0],
        image_height: s.image_size[1],
        is_photo: s.is_photo,
        file_bytes: s.file_bytes,
    };
    serde_wasm_bindgen::to_value(&js).map_err(|e| JsError::core("model summary", e))
}

/// Per-model rendering scratch (created on the first render, reused afterwards).
pub(crate) struct ModelScratch {
    drawer: FaceDrawer,
    params: Params,
    bbox: [f32; 4],
}

impl ModelScratch {
    fn new(model: &Model) -> Result<ModelScratch, JsError> {
        Ok(ModelScratch {
            drawer: FaceDrawer::new(model.frame(), Default::default()).map_err(js_err)?,
            params: model.base_params(),
            bbox: base_box(model),
        })
    }

    /// Renders `self.params` of `model` into `ctx`.
    fn render(&mut self, model: &Model, ctx: &Ctx, options: &RenderOptions) -> Result<(), JsError> {
        model.check_params(&self.params).map_err(js_err)?;
        let (drawer, params, bbox) = (&mut self.drawer, &self.params, self.bbox);
        drawer.set_options(options.draw);
        paint(Sink::Canvas(ctx), options.background, |pixmap, w, h| {
            drawer
                .render(model, params, &fit_view(bbox, w, h), pixmap)
                .map_err(js_err)
        })?;
        Ok(())
    }
}

/// A person-specific Active Appearance Model (shape model, appearance model, reference frame),
/// loaded from a `.fmm` file.
#[wasm_bindgen(js_name = Model)]
pub struct JsModel {
    pub(crate) model: Arc<Model>,
    scratch: RefCell<Option<Box<ModelScratch>>>,
    /// Why the file's backdrop was left out, if it was.
    notice: Option<String>,
}

impl From<Model> for JsModel {
    fn from(model: Model) -> Self {
        install_panic_hook();
        JsModel {
            model: Arc::new(model),
            scratch: RefCell::new(None),
            notice: None,
        }
    }
}

impl JsModel {
    /// The Rust model.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The Rust model, shared (a `Cloner` holds it without copying the expanded appearance).
    pub fn shared(&self) -> Arc<Model> {
        Arc::clone(&self.model)
    }

    fn with_scratch<T>(
        &self,
        f: impl FnOnce(&Model, &mut ModelScratch) -> Result<T, JsError>,
    ) -> Result<T, JsError> {
        let mut slot = self
            .scratch
            .try_borrow_mut()
            .map_err(|_| JsError::coded("busy", "model: render called re-entrantly"))?;
        if slot.is_none() {
            *slot = Some(Box::new(ModelScratch::new(&self.model)?));
        }
        match slot.as_deref_mut() {
            Some(s) => f(&self.model, s),
            None => Err(JsError::coded("internal", "internal error: model scratch")),
        }
    }
}

#[wasm_bindgen(js_class = Model)]
impl JsModel {
    /// Parses and validates a `.fmm` model file. Throws an `Error` naming the problem
    /// (corrupt, truncated, unsupported version, limits exceeded).
    #[wasm_bindgen(js_name = fromBytes)]
    pub fn from_bytes(
        #[wasm_bindgen(unchecked_param_type = "Uint8Array")] bytes: &[u8],
    ) -> Result<JsModel, JsError> {
        install_panic_hook();
        let (model, info) =
            facemimic::format::read_model_info(bytes).map_err(|e| js_err(e.into()))?;
        let mut m = JsModel::from(model);
        m.notice = info.backdrop_notice;
        Ok(m)
    }

    /// A target made from one photo (straight RGBA, `width x height`) and the face's landmarks
    /// in it (`2n` values, image pixels, centres on integers; e.g. a `FaceFinder` face's):
    /// the photo's face is the model's base and the photo its backdrop; cloning onto it
    /// substitutes the source's modes (Fig. 4 A). Throws when the landmarks fall outside the
    /// photo, the face is under 64 pixels wide, or the photo is outside the size limits.
    #[wasm_bindgen(js_name = fromPhoto)]
    pub fn from_photo(
        name: &str,
        #[wasm_bindgen(unchecked_param_type = "Uint8Array | Uint8ClampedArray")] rgba: &[u8],
        width: u32,
        height: u32,
        landmarks: &[f32],
    ) -> Result<JsModel, JsError> {
        install_panic_hook();
        let image = ImageRef::new(width, height, rgba).map_err(js_err)?;
        let frame = facemimic::canonical_frame();
        let model = facemimic::photo_model(name, &image, landmarks, frame).map_err(js_err)?;
        Ok(JsModel::from(model))
    }

    /// Serialises the model as a `.fmm` file (the newest version, compact `i6` storage).
    /// Throws (writing nothing) if the model is one `fromBytes` would reject.
    #[wasm_bindgen(js_name = toBytes)]
    pub fn to_bytes(&self) -> Result<Vec<u8>, JsError> {
        facemimic::format::write_model_checked(&self.model).map_err(|e| js_err(e.into()))
    }

    /// The model's name (e.g. `"spk07"`).
    #[wasm_bindgen(getter)]
    pub fn name(&self) -> String {
        self.model.name().to_string()
    }

    /// Sizes, variances and identity of the model.
    #[wasm_bindgen(unchecked_return_type = "ModelInfo")]
    pub fn info(&self) -> Result<JsValue, JsError> {
        model_info_with(&self.model, self.notice.as_deref())
    }

    /// The reference face at its mean pose (all shape and appearance parameters zero).
    #[wasm_bindgen(js_name = baseParams, unchecked_return_type = "Params")]
    pub fn base_params(&self) -> Result<JsValue, JsError> {
        params_to_js(&self.model.base_params())
    }

    /// Projects a face into the model: `landmarks` (`2n` values, image coordinates, pixel
    /// centres on integers) give the pose and shape parameters, the RGBA image sampled at them
    /// gives the appearance parameters.
    #[wasm_bindgen(unchecked_return_type = "Params")]
    pub fn project(
        &self,
        landmarks: &[f32],
        #[wasm_bindgen(unchecked_param_type = "Uint8Array | Uint8ClampedArray")] rgba: &[u8],
        width: u32,
        height: u32,
    ) -> Result<JsValue, JsError> {
        let image = ImageRef::new(width, height, rgba).map_err(js_err)?;
        let params = self.model.project(&image, landmarks).map_err(js_err)?;
        params_to_js(&params)
    }

    /// The landmarks (image coordinates, `2n` values) of an instance.
    #[wasm_bindgen(js_name = landmarks)]
    pub fn landmarks_of(
        &self,
        #[wasm_bindgen(unchecked_param_type = "ParamsInput")] params: JsValue,
    ) -> Result<Vec<f32>, JsError> {
        let params = params_from_js(&params)?;
        let mut out = vec![0.0; self.model.shape().base.len()];
        self.model.image_shape(&params, &mut out).map_err(js_err)?;
        Ok(out)
    }

    /// Checks parameters against this model: the mode counts, every value finite and within
    /// the library's bounds, a positive pose scale. Throws an `Error` naming the first problem.
    #[wasm_bindgen(js_name = checkParams)]
    pub fn check_params(
        &self,
        #[wasm_bindgen(unchecked_param_type = "ParamsInput")] params: JsValue,
    ) -> Result<(), JsError> {
        let params = params_from_js(&params)?;
        self.model.check_params(&params).map_err(js_err)
    }

    /// The view (a pose: image coordinates -> canvas pixels) used when this model is drawn
    /// into a `width x height` canvas: the face's mean placement centred, its bounding box at
    /// 85% of the smaller side. Use it to overlay landmarks (`x' = scale (cos r x - sin r y) + tx`).
    #[wasm_bindgen(js_name = viewFor, unchecked_return_type = "Pose")]
    pub fn view_for(&self, width: u32, height: u32) -> Result<JsValue, JsError> {
        serde_wasm_bindgen::to_value(&super::canvas_view(&self.model, width, height))
            .map_err(|e| JsError::core("view", e))
    }

    /// A copy of the model.
    #[wasm_bindgen(js_name = clone)]
    pub fn clone_model(&self) -> JsModel {
        JsModel {
            model: self.model.clone(),
            scratch: RefCell::new(None),
            notice: self.notice.clone(),
        }
    }

    /// Renders an instance of this model into a 2D canvas context, centred and scaled to the
    /// canvas (the view is fitted to the model's mean placement, so pose changes are visible).
    pub fn render(
        &self,
        #[wasm_bindgen(unchecked_param_type = "ParamsInput")] params: JsValue,
        ctx: Context2dArg,
        options: Option<RenderOptionsArg>,
    ) -> Result<(), JsError> {
        let params = params_from_js(&params)?;
        self.model.check_params(&params).map_err(js_err)?;
        let ctx = Ctx::from_js(&ctx)?;
        let options = RenderOptions::from_js(&options.map(JsValue::from))?;
        self.with_scratch(|model, s| {
            s.params = params;
            s.render(model, &ctx, &options)
        })
    }
}

/// Which parameter block [`render_mode`] varies.
fn mode_kind(kind: &str) -> Result<bool, JsError> {
    match kind {
        "shape" => Ok(true),
        "appearance" => Ok(false),
        other => Err(JsError::new(&format!(
            "renderMode: kind must be \"shape\" or \"appearance\", got {other:?}"
        ))),
    }
}

/// Inspector (the paper's Fig. 1): renders the model's base face moved `sigmas` standard
/// deviations along one shape or appearance mode (`sigmas = 0` shows the base), at the mean
/// pose, into a 2D canvas context. Allocation-free after the first call for a model.
#[wasm_bindgen(js_name = renderMode)]
pub fn render_mode(
    model: &JsModel,
    #[wasm_bindgen(unchecked_param_type = "\"shape\" | \"appearance\"")] kind: &str,
    mode: u32,
    sigmas: f32,
    ctx: Context2dArg,
    options: Option<RenderOptionsArg>,
) -> Result<(), JsError> {
    let shape = mode_kind(kind)?;
    if !sigmas.is_finite() {
        return Err(JsError::new(&format!(
            "renderMode: sigmas must be finite, got {sigmas}"
        )));
    }
    let m = &model.model;
    let (count, variances) = if shape {
        (m.shape().n_modes(), &m.shape().variances[..])
    } else {
        (m.appearance().n_modes(), m.appearance().variances())
    };
    let i = mode as usize;
    let Some(var) = variances.get(i) else {
        return Err(JsError::new(&format!(
            "renderMode: {kind} mode {mode} out of range (the model has {count})"
        )));
    };
    let value = sigmas * var.sqrt();
    let ctx = Ctx::from_js(&ctx)?;
    let options = RenderOptions::from_js(&options.map(JsValue::from))?;
    model.with_scratch(|model, s| {
        s.params.pose = model.mean_pose();
        s.params.shape.iter_mut().for_each(|v| *v = 0.0);
        s.params.appearance.iter_mut().for_each(|v| *v = 0.0);
        let block = if shape {
            &mut s.params.shape
        } else {
            &mut s.params.appearance
        };
        if let Some(v) = block.get_mut(i) {
            *v = value;
        }
        s.render(model, &ctx, &options)
    })
}

impl std::fmt::Debug for JsModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("JsModel")
            .field("name", &self.model.name())
            .finish_non_exhaustive()
    }
}
