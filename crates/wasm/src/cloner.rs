//! `Cloner` for JavaScript: one source driving many targets, rendered into canvases.

use std::str::FromStr;

use wasm_bindgen::prelude::*;
use web_sys::ImageData;

use super::model::{model_info, JsModel};
use super::surface::{now_ms, paint, params_into, Ctx, RenderOptions, Sink, Stages};
use super::{install_panic_hook, js_err, params_to_js, Context2dArg, RenderOptionsArg};
use facemimic::clone::{CloneOptions, Cloner, Method, TargetFrame};
use facemimic::ReferenceFrame;
use facemimic::{base_box, fit_view, picture_view, Compositor, FaceDrawer};
use facemimic::{Model, Params};

/// Stage timings accumulated since the last `update()`.
#[derive(Clone, Copy, Debug, Default)]
struct Timings {
    map: f64,
    synth: f64,
    raster: f64,
    blit: f64,
}

/// The compare view's output: one target cloned with another method than the main one,
/// into its own buffers (made again when the targets change).
struct Compare {
    /// Which target of the main cloner it mirrors, and the main cloner's generation then.
    index: usize,
    generation: u64,
    out: TargetFrame,
}

/// One face to draw: an appearance on the frame, a shape in image coordinates, and the box
/// the canvas view is fitted to.
struct Face<'a> {
    frame: &'a ReferenceFrame,
    appearance: &'a [f32],
    shape: &'a [f32],
    bbox: [f32; 4],
}

/// One source model cloned onto any number of targets (the paper's section 3), with rendering
/// into canvases. Models are copied in; the cloner owns its copies.
#[wasm_bindgen(js_name = Cloner)]
pub struct JsCloner {
    cloner: Cloner,
    options: CloneOptions,
    source_params: Params,
    /// Scratch for `setSourceParams` (same lengths as `source_params`).
    pending: Params,
    drawer: FaceDrawer,
    /// Scratch: source appearance (3N) and source landmarks (2n).
    appearance: Vec<f32>,
    shape: Vec<f32>,
    /// Bounding boxes of the mean placements: source, then one per target.
    source_box: [f32; 4],
    target_boxes: Vec<[f32; 4]>,
    timings: Timings,
    compare: Option<Compare>,
    /// Per target, its compositor (made on its first composited render; cleared when the
    /// targets change).
    compositors: Vec<Option<Compositor>>,
    /// Bumped whenever the source or the targets change.
    generation: u64,
}

/// The box target `index`'s view is fitted to (its mean placement).
fn target_box(boxes: &[[f32; 4]], index: usize, model: &Model) -> [f32; 4] {
    boxes.get(index).copied().unwrap_or_else(|| base_box(model))
}

fn parse_method(method: &str) -> Result<Method, JsError> {
    Method::from_str(method).map_err(js_err)
}

impl JsCloner {
    /// The Rust cloner.
    pub fn cloner(&self) -> &Cloner {
        &self.cloner
    }

    /// The options used by `update()`.
    pub fn options(&self) -> &CloneOptions {
        &self.options
    }

    fn check_index(&self, index: u32) -> Result<usize, JsError> {
        let i = index as usize;
        if i < self.cloner.n_targets() {
            Ok(i)
        } else {
            Err(JsError::new(&format!(
                "target index {index} out of range ({} target(s))",
                self.cloner.n_targets()
            )))
        }
    }

    fn set_options(&mut self, options: CloneOptions) -> Result<(), JsError> {
        options.validate(self.cloner.source()).map_err(js_err)?;
        self.options = options;
        Ok(())
    }

    /// Uploads the face's appearance and warps its shape into the sink with the drawer,
    /// adding the stage times.
    fn draw(
        drawer: &mut FaceDrawer,
        timings: &mut Timings,
        face: Face<'_>,
        sink: Sink<'_>,
        options: &RenderOptions,
    ) -> Result<(), JsError> {
        let t0 = now_ms();
        drawer.set_options(options.draw);
        drawer.upload(face.frame, face.appearance).map_err(js_err)?;
        timings.synth += now_ms() - t0;
        let stages: Stages = paint(sink, options.background, |pixmap, w, h| {
            let view = fit_view(face.bbox, w, h);
            drawer
                .warp(face.frame, face.shape, &view, pixmap)
                .map_err(js_err)
        })?;
        timings.raster += stages.raster;
        timings.blit += stages.blit;
        Ok(())
    }

    fn render_source_into(
        &mut self,
        sink: Sink<'_>,
        options: &RenderOptions,
    ) -> Result<(), JsError> {
        let model = self.cloner.source();
        let t0 = now_ms();
        model
            .image_shape(&self.source_params, &mut self.shape)
            .map_err(js_err)?;
        // Eq. 2 for the source, cache-blocked (bit-identical to `instance_unchecked`).
        facemimic::numerics::synthesise(
            &model.appearance().base,
            &model.appearance().modes,
            &self.source_params.appearance,
            &mut self.appearance,
        );
        self.timings.synth += now_ms() - t0;
        let face = Face {
            frame: model.frame(),
            appearance: &self.appearance,
            shape: &self.shape,
            bbox: self.source_box,
        };
        Self::draw(&mut self.drawer, &mut self.timings, face, sink, options)
    }

    fn render_target_into(
        &mut self,
        index: usize,
        sink: Sink<'_>,
        options: &RenderOptions,
    ) -> Result<(), JsError> {
        let Some(model) = self.cloner.get_target(index) else {
            return Err(JsError::new(&format!("target index {index} out of range")));
        };
        if options.composite && model.backdrop().is_some() {
            let face = (
                self.cloner.target_appearance(index),
                self.cloner.target_shape(index),
            );
            return Self::composite(
                &mut self.compositors,
                &mut self.timings,
                (index, model),
                face,
                sink,
                options,
            );
        }
        let face = Face {
            frame: model.frame(),
            appearance: self.cloner.target_appearance(index),
            shape: self.cloner.target_shape(index),
            bbox: target_box(&self.target_boxes, index, model),
        };
        Self::draw(&mut self.drawer, &mut self.timings, face, sink, options)
    }

    fn changed(&mut self) {
        self.generation += 1;
        self.compare = None;
        self.compositors.clear();
    }

    /// Composites a face of target `index` (`model`), its appearance and its landmarks in
    /// the backdrop's pixels, into the target's backdrop letterboxed to the sink, with the
    /// target's compositor (made on first use).
    fn composite(
        compositors: &mut Vec<Option<Compositor>>,
        timings: &mut Timings,
        (index, model): (usize, &Model),
        (appearance, shape): (&[f32], &[f32]),
        sink: Sink<'_>,
        options: &RenderOptions,
    ) -> Result<(), JsError> {
        if compositors.len() <= index {
            compositors.resize_with(index + 1, || None);
        }
        if compositors[index].is_none() {
            let t0 = now_ms();
            compositors[index] = Some(Compositor::new(model, options.draw).map_err(js_err)?);
            timings.synth += now_ms() - t0;
        }
        let Some(c) = compositors[index].as_mut() else {
            return Err(JsError::new("internal error: compositor"));
        };
        c.set_options(options.draw);
        let (bw, bh) = c.size();
        let stages: Stages = paint(sink, options.background, |pixmap, w, h| {
            let view = picture_view(bw, bh, w, h);
            c.draw(model, appearance, shape, &view, pixmap)
                .map_err(js_err)
        })?;
        timings.raster += stages.raster;
        timings.blit += stages.blit;
        Ok(())
    }
}

#[wasm_bindgen(js_class = Cloner)]
impl JsCloner {
    /// A cloner driven by `source` (copied), with no targets yet.
    #[wasm_bindgen(constructor)]
    pub fn new(source: &JsModel) -> Result<JsCloner, JsError> {
        install_panic_hook();
        let model: Model = source.model().clone();
        let drawer = FaceDrawer::new(model.frame(), Default::default()).map_err(js_err)?;
        let source_params = model.base_params();
        let appearance = vec![0.0; model.appearance().len()];
        let shape = vec![0.0; model.shape().base.len()];
        let source_box = base_box(&model);
        let cloner = Cloner::new(model).map_err(js_err)?;
        Ok(JsCloner {
            cloner,
            options: CloneOptions::default(),
            pending: source_params.clone(),
            source_params,
            drawer,
            appearance,
            shape,
            source_box,
            target_boxes: Vec::new(),
            timings: Timings::default(),
            compare: None,
            compositors: Vec::new(),
            generation: 0,
        })
    }

    /// Replaces the source model (copied). Throws if it is inconsistent or a target is
    /// incompatible with it; the cloner is unchanged then. The source parameters reset to the
    /// new source's base face, and per-mode gains longer than its mode counts are dropped.
    #[wasm_bindgen(js_name = setSource)]
    pub fn set_source(&mut self, source: &JsModel) -> Result<(), JsError> {
        let model = source.model().clone();
        let drawer = FaceDrawer::new(model.frame(), Default::default()).map_err(js_err)?;
        let params = model.base_params();
        let source_box = base_box(&model);
        let (m, l) = (model.shape().n_modes(), model.appearance().n_modes());
        let (n2, d) = (model.shape().base.len(), model.appearance().len());
        self.cloner.set_source(model).map_err(js_err)?;
        self.drawer = drawer;
        self.pending = params.clone();
        self.source_params = params;
        self.source_box = source_box;
        self.appearance = vec![0.0; d];
        self.shape = vec![0.0; n2];
        self.options.shape_gains.truncate(m);
        self.options.appearance_gains.truncate(l);
        self.changed();
        Ok(())
    }

    /// Adds a target (copied) and returns its index. Throws `incompatible models: ...` naming
    /// what differs when it is not built in the source's reference frame.
    #[wasm_bindgen(js_name = addTarget)]
    pub fn add_target(&mut self, target: &JsModel) -> Result<u32, JsError> {
        let model = target.model().clone();
        let bbox = base_box(&model);
        let i = self.cloner.add_target(model).map_err(js_err)?;
        self.target_boxes.push(bbox);
        self.changed();
        Ok(i as u32)
    }

    /// Removes target `index`; later targets move down by one.
    #[wasm_bindgen(js_name = removeTarget)]
    pub fn remove_target(&mut self, index: u32) -> Result<(), JsError> {
        let i = self.check_index(index)?;
        self.cloner.remove_target(i).map_err(js_err)?;
        if i < self.target_boxes.len() {
            self.target_boxes.remove(i);
        }
        self.changed();
        Ok(())
    }

    /// Replaces target `index` with `target` (copied); on error nothing changes.
    #[wasm_bindgen(js_name = replaceTarget)]
    pub fn replace_target(&mut self, index: u32, target: &JsModel) -> Result<(), JsError> {
        let i = self.check_index(index)?;
        let model = target.model().clone();
        let bbox = base_box(&model);
        self.cloner.replace_target(i, model).map_err(js_err)?;
        if let Some(b) = self.target_boxes.get_mut(i) {
            *b = bbox;
        }
        self.changed();
        Ok(())
    }

    /// Number of targets.
    #[wasm_bindgen(getter, js_name = targetCount)]
    pub fn target_count(&self) -> u32 {
        self.cloner.n_targets() as u32
    }

    /// The source model's info (see `Model.info()`).
    #[wasm_bindgen(js_name = sourceInfo, unchecked_return_type = "ModelInfo")]
    pub fn source_info(&self) -> Result<JsValue, JsError> {
        model_info(self.cloner.source())
    }

    /// Target `index`'s model info.
    #[wasm_bindgen(js_name = targetInfo, unchecked_return_type = "ModelInfo")]
    pub fn target_info(&self, index: u32) -> Result<JsValue, JsError> {
        let i = self.check_index(index)?;
        match self.cloner.get_target(i) {
            Some(m) => model_info(m),
            None => Err(JsError::new("target index out of range")),
        }
    }

    /// Sets the source parameters for the next `update()`. Throws (and keeps the old ones)
    /// unless the lengths match the source model and every value is finite.
    #[wasm_bindgen(js_name = setSourceParams)]
    pub fn set_source_params(
        &mut self,
        #[wasm_bindgen(unchecked_param_type = "ParamsInput")] params: JsValue,
    ) -> Result<(), JsError> {
        // Read into the scratch copy (sized like the source's parameters), validate, swap:
        // no allocation, and the old parameters stay on error.
        params_into(&params, &mut self.pending)?;
        self.cloner
            .source()
            .check_params(&self.pending)
            .map_err(js_err)?;
        std::mem::swap(&mut self.pending, &mut self.source_params);
        Ok(())
    }

    /// The current source parameters.
    #[wasm_bindgen(js_name = sourceParams, unchecked_return_type = "Params")]
    pub fn source_params(&self) -> Result<JsValue, JsError> {
        params_to_js(&self.source_params)
    }

    /// The source's landmarks for the current parameters (image coordinates, `2n` values).
    #[wasm_bindgen(js_name = sourceLandmarks)]
    pub fn source_landmarks(&mut self) -> Result<js_sys::Float32Array, JsError> {
        let model = self.cloner.source();
        model
            .image_shape(&self.source_params, &mut self.shape)
            .map_err(js_err)?;
        Ok(js_sys::Float32Array::from(&self.shape[..]))
    }

    /// The cloning method, one of `methods()`' names: `"substitute"` (Fig. 4 A), `"map"`
    /// (Eq. 3), `"map-residual"` (Eq. 4) or `"expressive"`.
    #[wasm_bindgen(js_name = setMethod)]
    pub fn set_method(
        &mut self,
        #[wasm_bindgen(unchecked_param_type = "Method")] method: &str,
    ) -> Result<(), JsError> {
        self.options.method = parse_method(method)?;
        Ok(())
    }

    /// The current method.
    #[wasm_bindgen(getter, unchecked_return_type = "Method")]
    pub fn method(&self) -> String {
        self.options.method.name().to_string()
    }

    /// Global gain on the source parameters (0 = the target's reference face, 1 = faithful,
    /// >1 exaggerated). Must be finite.
    #[wasm_bindgen(js_name = setGain)]
    pub fn set_gain(&mut self, gain: f32) -> Result<(), JsError> {
        let mut o = self.options.clone();
        o.gain = gain;
        self.set_options(o)
    }

    /// The global gain.
    #[wasm_bindgen(getter)]
    pub fn gain(&self) -> f32 {
        self.options.gain
    }

    /// Per source shape mode gains, multiplied with the global gain (empty = all 1; a shorter
    /// array leaves the remaining modes at 1).
    #[wasm_bindgen(js_name = setShapeGains)]
    pub fn set_shape_gains(&mut self, gains: &[f32]) -> Result<(), JsError> {
        let mut o = self.options.clone();
        o.shape_gains = gains.to_vec();
        self.set_options(o)
    }

    /// Per source appearance mode gains (same rules as `setShapeGains`).
    #[wasm_bindgen(js_name = setAppearanceGains)]
    pub fn set_appearance_gains(&mut self, gains: &[f32]) -> Result<(), JsError> {
        let mut o = self.options.clone();
        o.appearance_gains = gains.to_vec();
        self.set_options(o)
    }

    /// The constraint: mapped target parameters limited to `+-k` standard deviations of the
    /// target's modes; `null` turns it off. Default 3.
    #[wasm_bindgen(js_name = setClamp)]
    pub fn set_clamp(&mut self, k: Option<f32>) -> Result<(), JsError> {
        let mut o = self.options.clone();
        o.clamp = k;
        self.set_options(o)
    }

    /// The constraint's `k`, or `undefined` when off.
    #[wasm_bindgen(getter)]
    pub fn clamp(&self) -> Option<f32> {
        self.options.clamp
    }

    /// The expressive method's gains per region (each multiplied with the global gain):
    /// `mouth` (lips, jaw and the mouth's shading), `eyes` (lids and blinks), `brows`. 1 = as
    /// the source does. Must be finite.
    #[wasm_bindgen(js_name = setRegionGains)]
    pub fn set_region_gains(&mut self, mouth: f32, eyes: f32, brows: f32) -> Result<(), JsError> {
        let mut o = self.options.clone();
        o.regions = facemimic::clone::RegionGains { mouth, eyes, brows };
        self.set_options(o)
    }

    /// The region gains, `[mouth, eyes, brows]`.
    #[wasm_bindgen(getter, js_name = regionGains)]
    pub fn region_gains(&self) -> Vec<f32> {
        let r = self.options.regions;
        vec![r.mouth, r.eyes, r.brows]
    }

    /// The expressive method's style: 0 = the target's own range (its modes, limited), 1 (the
    /// default) = the source's full motion; in between, a blend.
    #[wasm_bindgen(js_name = setStyle)]
    pub fn set_style(&mut self, style: f32) -> Result<(), JsError> {
        let mut o = self.options.clone();
        o.style = style;
        self.set_options(o)
    }

    /// The style (see `setStyle`).
    #[wasm_bindgen(getter)]
    pub fn style(&self) -> f32 {
        self.options.style
    }

    /// `true`: targets follow the source's head motion relative to its mean pose; `false`
    /// (default): each target stays at its own mean pose.
    #[wasm_bindgen(js_name = setFollowPose)]
    pub fn set_follow_pose(&mut self, on: bool) {
        self.options.follow_pose = on;
    }

    /// Whether targets follow the source's pose.
    #[wasm_bindgen(getter, js_name = followPose)]
    pub fn follow_pose(&self) -> bool {
        self.options.follow_pose
    }

    /// Maps the current source parameters onto every target and synthesises their shapes and
    /// appearances (one call per frame). Resets the stage timings. Allocates nothing.
    pub fn update(&mut self) -> Result<(), JsError> {
        self.timings = Timings::default();
        let t0 = now_ms();
        self.cloner
            .clone_frame(&self.source_params, &self.options)
            .map_err(js_err)?;
        self.timings.map = now_ms() - t0;
        Ok(())
    }

    /// Target `index`'s parameters of the last `update()` (pose, `p*`, `lambda*`).
    #[wasm_bindgen(js_name = targetParams, unchecked_return_type = "Params")]
    pub fn target_params(&self, index: u32) -> Result<JsValue, JsError> {
        let i = self.check_index(index)?;
        params_to_js(self.cloner.target_params(i))
    }

    /// Target `index`'s landmarks of the last `update()` (image coordinates, `2n` values).
    #[wasm_bindgen(js_name = targetLandmarks)]
    pub fn target_landmarks(&self, index: u32) -> Result<js_sys::Float32Array, JsError> {
        let i = self.check_index(index)?;
        Ok(js_sys::Float32Array::from(self.cloner.target_shape(i)))
    }

    /// Renders the source face (current parameters) into a 2D canvas context at the canvas's
    /// own pixel size, centred and scaled (a view fitted to the model's mean placement).
    #[wasm_bindgen(js_name = renderSource)]
    pub fn render_source(
        &mut self,
        ctx: Context2dArg,
        options: Option<RenderOptionsArg>,
    ) -> Result<(), JsError> {
        let ctx = Ctx::from_js(&ctx)?;
        let options = RenderOptions::from_js(&options.map(JsValue::from))?;
        self.render_source_into(Sink::Canvas(&ctx), &options)
    }

    /// Renders target `index` as of the last `update()` into a 2D canvas context.
    #[wasm_bindgen(js_name = renderTarget)]
    pub fn render_target(
        &mut self,
        index: u32,
        ctx: Context2dArg,
        options: Option<RenderOptionsArg>,
    ) -> Result<(), JsError> {
        let i = self.check_index(index)?;
        let ctx = Ctx::from_js(&ctx)?;
        let options = RenderOptions::from_js(&options.map(JsValue::from))?;
        self.render_target_into(i, Sink::Canvas(&ctx), &options)
    }

    /// Renders target `index` as of the last `update()` into a new `ImageData` of the given
    /// size (for workers, compositing or saving).
    #[wasm_bindgen(js_name = renderTargetImageData)]
    pub fn render_target_image_data(
        &mut self,
        index: u32,
        width: u32,
        height: u32,
        options: Option<RenderOptionsArg>,
    ) -> Result<ImageData, JsError> {
        let i = self.check_index(index)?;
        let options = RenderOptions::from_js(&options.map(JsValue::from))?;
        image_data(width, height, |sink| {
            self.render_target_into(i, sink, &options)
        })
    }

    /// Renders the source face into a new `ImageData` of the given size.
    #[wasm_bindgen(js_name = renderSourceImageData)]
    pub fn render_source_image_data(
        &mut self,
        width: u32,
        height: u32,
        options: Option<RenderOptionsArg>,
    ) -> Result<ImageData, JsError> {
        let options = RenderOptions::from_js(&options.map(JsValue::from))?;
        image_data(width, height, |sink| {
            self.render_source_into(sink, &options)
        })
    }

    /// The compare view (the paper's Fig. 4): target `index` cloned from the current source
    /// parameters with `method` (and the other current options), rendered into a canvas,
    /// without changing the cloner's method or its targets' state; `composite` in the options draws
    /// the whole picture as `renderTarget` does.
    #[wasm_bindgen(js_name = renderTargetWithMethod)]
    pub fn render_target_with_method(
        &mut self,
        index: u32,
        #[wasm_bindgen(unchecked_param_type = "Method")] method: &str,
        ctx: Context2dArg,
        options: Option<RenderOptionsArg>,
    ) -> Result<(), JsError> {
        let i = self.check_index(index)?;
        let method = parse_method(method)?;
        let ctx = Ctx::from_js(&ctx)?;
        let render_options = RenderOptions::from_js(&options.map(JsValue::from))?;
        let fresh =
            matches!(&self.compare, Some(c) if c.index == i && c.generation == self.generation);
        if !fresh {
            let Some(out) = self.cloner.target_frame(i) else {
                return Err(JsError::new("target index out of range"));
            };
            self.compare = Some(Compare {
                index: i,
                generation: self.generation,
                out,
            });
        }
        let Some(compare) = self.compare.as_mut() else {
            return Err(JsError::new("internal error: compare output"));
        };
        let t0 = now_ms();
        // Only the method differs; the options were validated when set.
        let saved = self.options.method;
        self.options.method = method;
        let r = self
            .cloner
            .clone_target(i, &self.source_params, &self.options, &mut compare.out);
        self.options.method = saved;
        r.map_err(js_err)?;
        self.timings.map += now_ms() - t0;
        let model = self.cloner.target(i);
        if render_options.composite && model.backdrop().is_some() {
            return Self::composite(
                &mut self.compositors,
                &mut self.timings,
                (i, model),
                (compare.out.appearance(), compare.out.shape()),
                Sink::Canvas(&ctx),
                &render_options,
            );
        }
        let face = Face {
            frame: model.frame(),
            appearance: compare.out.appearance(),
            shape: compare.out.shape(),
            bbox: target_box(&self.target_boxes, i, model),
        };
        Self::draw(
            &mut self.drawer,
            &mut self.timings,
            face,
            Sink::Canvas(&ctx),
            &render_options,
        )
    }

    /// Milliseconds per stage since the last `update()`: `mapMs` (mapping and target synthesis
    /// in `update()`, plus compare-view cloning), `synthMs` (source synthesis and texture
    /// uploads), `rasterMs` (clearing and warping into the pixmaps), `blitMs` (into canvases).
    #[wasm_bindgen(unchecked_return_type = "Timings")]
    pub fn timings(&self) -> Result<JsValue, JsError> {
        let o = js_sys::Object::new();
        for (k, v) in [
            ("mapMs", self.timings.map),
            ("synthMs", self.timings.synth),
            ("rasterMs", self.timings.raster),
            ("blitMs", self.timings.blit),
        ] {
            js_sys::Reflect::set(&o, &JsValue::from_str(k), &JsValue::from_f64(v))
                .map_err(|_| JsError::new("timings: cannot build the result"))?;
        }
        Ok(o.into())
    }
}

impl std::fmt::Debug for JsCloner {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("JsCloner")
            .field("source", &self.cloner.source().name())
            .field("targets", &self.cloner.n_targets())
            .finish_non_exhaustive()
    }
}

/// A new `ImageData` of `width x height` that `draw` renders into.
fn image_data(
    width: u32,
    height: u32,
    draw: impl FnOnce(Sink<'_>) -> Result<(), JsError>,
) -> Result<ImageData, JsError> {
    let mut out = None;
    draw(Sink::Image {
        width,
        height,
        out: &mut out,
    })?;
    out.ok_or_else(|| JsError::new("internal error: no image produced"))
}
