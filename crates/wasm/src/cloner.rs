//! `Cloner` for JavaScript: one source driving many targets, drawn into canvases. A thin shell
//! over [`facemimic::Stage`]: it parses, passes and blits.

use crate::JsError;
use std::str::FromStr;

use wasm_bindgen::prelude::*;
use web_sys::ImageData;

use super::model::{model_info, JsModel};
use super::surface::{now_ms, paint_whole, params_into, put_rgba, Ctx, RenderOptions, Sink};
use super::tracker::WasmTracker;
use super::{install_panic_hook, js_err, params_to_js, Context2dArg, RenderOptionsArg};
use facemimic::clone::{CloneOptions, Method};
use facemimic::{Params, Picture, PictureOptions, Stage};

/// A method's name (an unknown name is a bad argument, whatever the core calls it).
fn parse_method(method: &str) -> Result<Method, JsError> {
    Method::from_str(method).map_err(|e| JsError::new(&e.to_string()))
}

/// Render options read from JS as the core's picture options.
fn picture_options(options: Option<RenderOptionsArg>) -> Result<PictureOptions, JsError> {
    Ok(RenderOptions::from_js(&options.map(JsValue::from))?.picture())
}

/// The source is drawn face only, whatever the options say (`composite` is for targets).
fn source_options(options: Option<RenderOptionsArg>) -> Result<PictureOptions, JsError> {
    let mut o = picture_options(options)?;
    o.composite = false;
    Ok(o)
}

/// The canvases registered for [`JsCloner::draw_frame`]: the source's, one slot per target
/// (kept in step with the targets) and one per compare view of the stage.
#[derive(Default)]
struct Canvases {
    source: Option<Ctx>,
    targets: Vec<Option<Ctx>>,
    compare: Vec<Ctx>,
}

/// One source model cloned onto any number of targets (the paper's section 3), with rendering
/// into canvases. Models are shared with the `Model` objects, not copied (freeing a `Model`
/// leaves the cloner's share alive).
#[wasm_bindgen(js_name = Cloner)]
pub struct JsCloner {
    stage: Stage,
    /// Scratch for `setSourceParams` (sized like the source's parameters).
    pending: Params,
    canvases: Canvases,
}

impl JsCloner {
    /// The core stage.
    pub fn stage(&self) -> &Stage {
        &self.stage
    }

    /// The Rust cloner (the stage's).
    pub fn cloner(&self) -> &facemimic::clone::Cloner {
        self.stage.cloner()
    }

    /// The options used by `update()`.
    pub fn options(&self) -> &CloneOptions {
        self.stage.options()
    }

    fn check_index(&self, index: u32) -> Result<usize, JsError> {
        let i = index as usize;
        if i < self.stage.n_targets() {
            Ok(i)
        } else {
            Err(JsError::new(&format!(
                "target index {index} out of range ({} target(s))",
                self.stage.n_targets()
            )))
        }
    }

    /// The current options changed by `change`, checked and set (the old ones stay on error).
    fn change_options(&mut self, change: impl FnOnce(&mut CloneOptions)) -> Result<(), JsError> {
        let mut o = self.stage.options().clone();
        change(&mut o);
        self.stage.set_options(o).map_err(js_err)
    }

    /// Draws with `draw` into the sink through the shared pixmap of its size, adding the blit
    /// time to the stage's timings.
    fn paint_into(
        &mut self,
        sink: Sink<'_>,
        opaque: bool,
        draw: impl FnOnce(&mut Stage, &mut facemimic::tiny_skia::PixmapMut<'_>) -> facemimic::Result<()>,
    ) -> Result<(), JsError> {
        let stage = &mut self.stage;
        let stages = paint_whole(sink, opaque, |pixmap, _, _| {
            draw(stage, pixmap).map_err(js_err)
        })?;
        self.stage.add_blit_ms(stages.blit);
        Ok(())
    }

    /// Sizes a picture to its canvas (none: unsized) and shows it as `shown` says.
    fn fit_picture(picture: &mut Picture, ctx: Option<&Ctx>, shown: bool) -> Result<(), JsError> {
        let (w, h) = match ctx {
            Some(c) => c.size()?,
            None => (0, 0),
        };
        let (w, h) = if w == 0 || h == 0 { (0, 0) } else { (w, h) };
        picture.set_size(w, h).map_err(js_err)?;
        picture.set_shown(shown);
        Ok(())
    }

    /// Sizes every registered picture to its canvas and applies the `shown` flags (source,
    /// targets, compare views; missing flags show).
    fn fit_pictures(&mut self, shown: &[u8]) -> Result<(), JsError> {
        let flag = |k: usize| shown.get(k).is_none_or(|&v| v != 0);
        let c = &self.canvases;
        Self::fit_picture(self.stage.source_picture_mut(), c.source.as_ref(), flag(0))?;
        for i in 0..self.stage.n_targets() {
            let ctx = c.targets.get(i).and_then(Option::as_ref);
            let picture = self.stage.target_picture_mut(i).map_err(js_err)?;
            Self::fit_picture(picture, ctx, flag(1 + i))?;
        }
        let base = 1 + self.stage.n_targets();
        for (k, ctx) in c.compare.iter().enumerate() {
            if let Some(view) = self.stage.compare_view_mut(k) {
                Self::fit_picture(view.picture_mut(), Some(ctx), flag(base + k))?;
            }
        }
        Ok(())
    }

    /// Blits every registered, shown and drawn picture into its canvas.
    fn blit_pictures(&mut self) -> Result<(), JsError> {
        let t0 = now_ms();
        let c = &self.canvases;
        let s = &self.stage;
        let targets = (0..s.n_targets()).filter_map(|i| {
            let ctx = c.targets.get(i).and_then(Option::as_ref)?;
            Some((ctx, s.target_picture(i)?))
        });
        let compare = c
            .compare
            .iter()
            .zip(s.compare_views())
            .filter(|_| s.compare_target().is_some())
            .map(|(ctx, v)| (ctx, v.picture()));
        let source = c.source.as_ref().map(|ctx| (ctx, s.source_picture()));
        for (ctx, picture) in source.into_iter().chain(targets).chain(compare) {
            if picture.shown() && picture.drawn() {
                let (w, h) = picture.size();
                put_rgba(ctx, picture.rgba(), w, h)?;
            }
        }
        self.stage.add_blit_ms(now_ms() - t0);
        Ok(())
    }
}

#[wasm_bindgen(js_class = Cloner)]
impl JsCloner {
    /// A cloner driven by `source` (shared, not copied), with no targets yet.
    #[wasm_bindgen(constructor)]
    pub fn new(source: &JsModel) -> Result<JsCloner, JsError> {
        install_panic_hook();
        let model = source.shared();
        let pending = model.base_params();
        let mut stage = Stage::new(model).map_err(js_err)?;
        stage.set_clock(now_ms);
        Ok(JsCloner {
            stage,
            pending,
            canvases: Canvases::default(),
        })
    }

    /// Replaces the source model (shared). Throws if it is inconsistent or a target is
    /// incompatible with it; the cloner is unchanged then. The source parameters reset to the
    /// new source's base face, and per-mode gains longer than its mode counts are dropped.
    #[wasm_bindgen(js_name = setSource)]
    pub fn set_source(&mut self, source: &JsModel) -> Result<(), JsError> {
        let model = source.shared();
        let pending = model.base_params();
        self.stage.set_source(model).map_err(js_err)?;
        self.pending = pending;
        Ok(())
    }

    /// Adds a target (shared) and returns its index. Throws `incompatible models: ...` naming
    /// what differs when it is not built in the source's reference frame.
    #[wasm_bindgen(js_name = addTarget)]
    pub fn add_target(&mut self, target: &JsModel) -> Result<u32, JsError> {
        let i = self.stage.add_target(target.shared()).map_err(js_err)?;
        self.canvases.targets.resize_with(i + 1, || None);
        Ok(i as u32)
    }

    /// Removes target `index`; later targets (and their registered canvases) move down by one.
    #[wasm_bindgen(js_name = removeTarget)]
    pub fn remove_target(&mut self, index: u32) -> Result<(), JsError> {
        let i = self.check_index(index)?;
        self.stage.remove_target(i).map_err(js_err)?;
        if i < self.canvases.targets.len() {
            self.canvases.targets.remove(i);
        }
        Ok(())
    }

    /// Replaces target `index` with `target` (shared); on error nothing changes. Its
    /// registered canvas stays.
    #[wasm_bindgen(js_name = replaceTarget)]
    pub fn replace_target(&mut self, index: u32, target: &JsModel) -> Result<(), JsError> {
        let i = self.check_index(index)?;
        self.stage
            .replace_target(i, target.shared())
            .map_err(js_err)
    }

    /// Number of targets.
    #[wasm_bindgen(getter, js_name = targetCount)]
    pub fn target_count(&self) -> u32 {
        self.stage.n_targets() as u32
    }

    /// The source model's info (see `Model.info()`).
    #[wasm_bindgen(js_name = sourceInfo, unchecked_return_type = "ModelInfo")]
    pub fn source_info(&self) -> Result<JsValue, JsError> {
        model_info(self.stage.source())
    }

    /// Target `index`'s model info.
    #[wasm_bindgen(js_name = targetInfo, unchecked_return_type = "ModelInfo")]
    pub fn target_info(&self, index: u32) -> Result<JsValue, JsError> {
        let i = self.check_index(index)?;
        match self.stage.cloner().get_target(i) {
            Some(m) => model_info(m),
            None => Err(JsError::new("target index out of range")),
        }
    }

    /// Sets the source parameters for the next `update()` (the model's: a face a follower
    /// observed is dropped). Throws (and keeps the old ones) unless the lengths match the
    /// source model and every value is finite.
    #[wasm_bindgen(js_name = setSourceParams)]
    pub fn set_source_params(
        &mut self,
        #[wasm_bindgen(unchecked_param_type = "ParamsInput")] params: JsValue,
    ) -> Result<(), JsError> {
        // Read into the scratch copy (sized like the source's parameters), then the stage
        // validates and takes it: no allocation, and the old parameters stay on error.
        params_into(&params, &mut self.pending)?;
        self.stage.set_source_params(&self.pending).map_err(js_err)
    }

    /// Takes the source parameters from a `Tracker`'s last frame (either path), inside wasm
    /// (no parameters object crosses to JS and back): its shape and appearance and its
    /// `placed` pose, and from a follower the face it observed (the expressive method's look
    /// and whole expression against the person's own neutral). A lost or unsure
    /// frame, or none yet, is not taken (the parameters and observed face stay the last good
    /// ones). Returns whether the fit was taken. Throws when the tracker's model does not fit
    /// the source.
    #[wasm_bindgen(js_name = sourceFromTracker)]
    pub fn source_from_tracker(&mut self, tracker: &WasmTracker) -> Result<bool, JsError> {
        self.stage
            .source_from_tracker(tracker.face_tracker())
            .map_err(js_err)
    }

    /// Damps the head's motion in the poses taken from trackers (`sourceFromTracker`) from now
    /// on: each pose's deviation from a running anchor of the poses (time constant `tau`
    /// seconds; 0 keeps the first pose as the anchor) scaled by `factor` (0 holds the head
    /// still, 1 passes it unchanged, above 1 exaggerates): the core's pose anchor, as
    /// `PoseDamper`. New settings keep the anchor. Throws for a negative or non-finite `tau` or
    /// a non-finite `factor`.
    #[wasm_bindgen(js_name = setHeadDamping)]
    pub fn set_head_damping(&mut self, tau: f32, factor: f32) -> Result<(), JsError> {
        self.stage.set_head_damping(tau, factor).map_err(js_err)
    }

    /// Stops damping the head (poses are taken as fitted) and forgets the anchor.
    #[wasm_bindgen(js_name = clearHeadDamping)]
    pub fn clear_head_damping(&mut self) {
        self.stage.clear_head_damping();
    }

    /// The current source parameters.
    #[wasm_bindgen(js_name = sourceParams, unchecked_return_type = "Params")]
    pub fn source_params(&self) -> Result<JsValue, JsError> {
        params_to_js(self.stage.source_params())
    }

    /// The source's landmarks for the current parameters (image coordinates, `2n` values).
    #[wasm_bindgen(js_name = sourceLandmarks)]
    pub fn source_landmarks(&mut self) -> Result<js_sys::Float32Array, JsError> {
        let shape = self.stage.source_landmarks().map_err(js_err)?;
        Ok(js_sys::Float32Array::from(shape))
    }

    /// The cloning method, one of `methods()`' names: `"substitute"` (Fig. 4 A), `"map"`
    /// (Eq. 3), `"map-residual"` (Eq. 4) or `"expressive"`.
    #[wasm_bindgen(js_name = setMethod)]
    pub fn set_method(
        &mut self,
        #[wasm_bindgen(unchecked_param_type = "Method")] method: &str,
    ) -> Result<(), JsError> {
        let method = parse_method(method)?;
        self.change_options(|o| o.method = method)
    }

    /// The current method.
    #[wasm_bindgen(getter, unchecked_return_type = "Method")]
    pub fn method(&self) -> String {
        self.stage.options().method.name().to_string()
    }

    /// Global gain on the source parameters (0 = the target's reference face, 1 = faithful,
    /// >1 exaggerated). Must be finite.
    #[wasm_bindgen(js_name = setGain)]
    pub fn set_gain(&mut self, gain: f32) -> Result<(), JsError> {
        self.change_options(|o| o.gain = gain)
    }

    /// The global gain.
    #[wasm_bindgen(getter)]
    pub fn gain(&self) -> f32 {
        self.stage.options().gain
    }

    /// Per source shape mode gains, multiplied with the global gain (empty = all 1; a shorter
    /// array leaves the remaining modes at 1).
    #[wasm_bindgen(js_name = setShapeGains)]
    pub fn set_shape_gains(&mut self, gains: &[f32]) -> Result<(), JsError> {
        self.change_options(|o| o.shape_gains = gains.to_vec())
    }

    /// Per source appearance mode gains (same rules as `setShapeGains`).
    #[wasm_bindgen(js_name = setAppearanceGains)]
    pub fn set_appearance_gains(&mut self, gains: &[f32]) -> Result<(), JsError> {
        self.change_options(|o| o.appearance_gains = gains.to_vec())
    }

    /// The constraint: mapped target parameters limited to `+-k` standard deviations of the
    /// target's modes; `null` turns it off. Default 3.
    #[wasm_bindgen(js_name = setClamp)]
    pub fn set_clamp(&mut self, k: Option<f32>) -> Result<(), JsError> {
        self.change_options(|o| o.clamp = k)
    }

    /// The constraint's `k`, or `undefined` when off.
    #[wasm_bindgen(getter)]
    pub fn clamp(&self) -> Option<f32> {
        self.stage.options().clamp
    }

    /// The expressive method's gains per region (each multiplied with the global gain):
    /// `mouth` (lips, jaw and the mouth's shading), `eyes` (lids and blinks), `brows`. 1 = as
    /// the source does. Must be finite.
    #[wasm_bindgen(js_name = setRegionGains)]
    pub fn set_region_gains(&mut self, mouth: f32, eyes: f32, brows: f32) -> Result<(), JsError> {
        self.change_options(|o| o.regions = facemimic::clone::RegionGains { mouth, eyes, brows })
    }

    /// The region gains, `[mouth, eyes, brows]`.
    #[wasm_bindgen(getter, js_name = regionGains)]
    pub fn region_gains(&self) -> Vec<f32> {
        let r = self.stage.options().regions;
        vec![r.mouth, r.eyes, r.brows]
    }

    /// The expressive method's style: 0 = the target's own range (its modes, limited), 1 (the
    /// default) = the source's full motion; in between, a blend.
    #[wasm_bindgen(js_name = setStyle)]
    pub fn set_style(&mut self, style: f32) -> Result<(), JsError> {
        self.change_options(|o| o.style = style)
    }

    /// The style (see `setStyle`).
    #[wasm_bindgen(getter)]
    pub fn style(&self) -> f32 {
        self.stage.options().style
    }

    /// `true`: targets follow the source's head motion relative to its mean pose; `false`
    /// (default): each target stays at its own mean pose and, with the expressive method, its
    /// own view and light (the source's head turning to the side, and the light falling on it
    /// from one side, are not carried as expression).
    #[wasm_bindgen(js_name = setFollowPose)]
    pub fn set_follow_pose(&mut self, on: bool) {
        // The current options are valid and the flag has no range: this cannot fail.
        let _ = self.change_options(|o| o.follow_pose = on);
    }

    /// Whether targets follow the source's pose.
    #[wasm_bindgen(getter, js_name = followPose)]
    pub fn follow_pose(&self) -> bool {
        self.stage.options().follow_pose
    }

    /// Maps the current source parameters onto every target and synthesises their shapes and
    /// appearances (one call per frame). Resets the stage timings. Allocates nothing.
    pub fn update(&mut self) -> Result<(), JsError> {
        self.stage.update().map_err(js_err)
    }

    /// Target `index`'s parameters of the last `update()` (pose, `p*`, `lambda*`).
    #[wasm_bindgen(js_name = targetParams, unchecked_return_type = "Params")]
    pub fn target_params(&self, index: u32) -> Result<JsValue, JsError> {
        let i = self.check_index(index)?;
        params_to_js(self.stage.cloner().target_params(i))
    }

    /// Target `index`'s landmarks of the last `update()` (image coordinates, `2n` values).
    #[wasm_bindgen(js_name = targetLandmarks)]
    pub fn target_landmarks(&self, index: u32) -> Result<js_sys::Float32Array, JsError> {
        let i = self.check_index(index)?;
        Ok(js_sys::Float32Array::from(
            self.stage.cloner().target_shape(i),
        ))
    }
}

#[wasm_bindgen(js_class = Cloner)]
impl JsCloner {
    /// Renders the source face (current parameters) into a 2D canvas context at the canvas's
    /// own pixel size, centred and scaled (a view fitted to the model's mean placement).
    #[wasm_bindgen(js_name = renderSource)]
    pub fn render_source(
        &mut self,
        ctx: Context2dArg,
        options: Option<RenderOptionsArg>,
    ) -> Result<(), JsError> {
        let ctx = Ctx::from_js(&ctx)?;
        let o = source_options(options)?;
        self.paint_into(Sink::Canvas(&ctx), o.background.is_opaque(), |s, p| {
            s.draw_source_into(&o, p)
        })
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
        let o = picture_options(options)?;
        self.paint_into(Sink::Canvas(&ctx), o.background.is_opaque(), |s, p| {
            s.draw_target_into(i, &o, p)
        })
    }

    /// Renders target `index` as of the last `update()` into a new `ImageData` of the given
    /// size (for workers, compositing or saving; a browser's or a worker's `ImageData`).
    #[wasm_bindgen(js_name = renderTargetImageData)]
    pub fn render_target_image_data(
        &mut self,
        index: u32,
        width: u32,
        height: u32,
        options: Option<RenderOptionsArg>,
    ) -> Result<ImageData, JsError> {
        let data = self.render_target_rgba(index, width, height, options)?;
        as_image_data(data, width, height)
    }

    /// Renders target `index` as of the last `update()` into new straight RGBA bytes,
    /// `width * height * 4`, rows top to bottom: for batch work where there is no `ImageData`
    /// (Node) or the pixels go to an encoder.
    #[wasm_bindgen(js_name = renderTargetRGBA)]
    pub fn render_target_rgba(
        &mut self,
        index: u32,
        width: u32,
        height: u32,
        options: Option<RenderOptionsArg>,
    ) -> Result<js_sys::Uint8ClampedArray, JsError> {
        let i = self.check_index(index)?;
        let o = picture_options(options)?;
        rgba_out(width, height, |sink| {
            self.paint_into(sink, o.background.is_opaque(), |s, p| {
                s.draw_target_into(i, &o, p)
            })
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
        let data = self.render_source_rgba(width, height, options)?;
        as_image_data(data, width, height)
    }

    /// Renders the source face into new straight RGBA bytes of the given size (see
    /// `renderTargetRGBA`).
    #[wasm_bindgen(js_name = renderSourceRGBA)]
    pub fn render_source_rgba(
        &mut self,
        width: u32,
        height: u32,
        options: Option<RenderOptionsArg>,
    ) -> Result<js_sys::Uint8ClampedArray, JsError> {
        let o = source_options(options)?;
        rgba_out(width, height, |sink| {
            self.paint_into(sink, o.background.is_opaque(), |s, p| {
                s.draw_source_into(&o, p)
            })
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
        let o = picture_options(options)?;
        self.paint_into(Sink::Canvas(&ctx), o.background.is_opaque(), |s, p| {
            s.draw_compare_into(i, method, &o, p)
        })
    }

    /// Registers the canvas `drawFrame` draws the source face into (face only, as
    /// `renderSource`), with its options; `null` unregisters it.
    #[wasm_bindgen(js_name = setSourceCanvas)]
    pub fn set_source_canvas(
        &mut self,
        ctx: Option<Context2dArg>,
        options: Option<RenderOptionsArg>,
    ) -> Result<(), JsError> {
        let ctx = ctx.map(|c| Ctx::from_js(&c)).transpose()?;
        let o = source_options(options)?;
        if ctx.is_none() {
            self.stage
                .source_picture_mut()
                .set_size(0, 0)
                .map_err(js_err)?;
        }
        self.stage.source_picture_mut().set_options(o);
        self.canvases.source = ctx;
        Ok(())
    }

    /// Registers the canvas `drawFrame` draws target `index` into (as `renderTarget`), with
    /// its options; `null` unregisters it. The registration follows the target:
    /// `removeTarget` moves later ones down, `replaceTarget` keeps it.
    #[wasm_bindgen(js_name = setTargetCanvas)]
    pub fn set_target_canvas(
        &mut self,
        index: u32,
        ctx: Option<Context2dArg>,
        options: Option<RenderOptionsArg>,
    ) -> Result<(), JsError> {
        let i = self.check_index(index)?;
        let ctx = ctx.map(|c| Ctx::from_js(&c)).transpose()?;
        let o = picture_options(options)?;
        let picture = self.stage.target_picture_mut(i).map_err(js_err)?;
        if ctx.is_none() {
            picture.set_size(0, 0).map_err(js_err)?;
        }
        picture.set_options(o);
        self.canvases
            .targets
            .resize_with(self.stage.n_targets(), || None);
        self.canvases.targets[i] = ctx;
        Ok(())
    }

    /// Registers the compare view of `method`: `drawFrame` draws the compared target
    /// (`setCompareTarget`) cloned with `method` into this canvas (as
    /// `renderTargetWithMethod`); `null` removes the view. One canvas per method.
    #[wasm_bindgen(js_name = setCompareCanvas)]
    pub fn set_compare_canvas(
        &mut self,
        #[wasm_bindgen(unchecked_param_type = "Method")] method: &str,
        ctx: Option<Context2dArg>,
        options: Option<RenderOptionsArg>,
    ) -> Result<(), JsError> {
        let method = parse_method(method)?;
        let ctx = ctx.map(|c| Ctx::from_js(&c)).transpose()?;
        let o = picture_options(options)?;
        let found = self
            .stage
            .compare_views()
            .iter()
            .position(|v| v.method() == method);
        match (found, ctx) {
            (Some(k), None) => {
                self.stage.remove_compare_view(k).map_err(js_err)?;
                self.canvases.compare.remove(k);
            }
            (Some(k), Some(ctx)) => {
                if let Some(v) = self.stage.compare_view_mut(k) {
                    v.picture_mut().set_options(o);
                }
                self.canvases.compare[k] = ctx;
            }
            (None, Some(ctx)) => {
                self.stage.add_compare_view(method, o);
                self.canvases.compare.push(ctx);
            }
            (None, None) => {}
        }
        Ok(())
    }

    /// The target the compare view shows (`null` or `undefined`: none, the compare canvases
    /// are not drawn).
    #[wasm_bindgen(js_name = setCompareTarget)]
    pub fn set_compare_target(&mut self, index: Option<u32>) -> Result<(), JsError> {
        let i = index.map(|i| self.check_index(i)).transpose()?;
        self.stage.set_compare_target(i).map_err(js_err)
    }

    /// One frame in one call: `update()`, then every registered canvas drawn at its own size
    /// (`setSourceCanvas`, `setTargetCanvas`, `setCompareCanvas`) and blitted. `shown`
    /// (optional): a flag per canvas, in the order source, targets, compare views (as
    /// registered); a `0` skips that canvas this frame (it keeps its last picture), missing
    /// flags draw.
    #[wasm_bindgen(js_name = drawFrame)]
    pub fn draw_frame(
        &mut self,
        #[wasm_bindgen(unchecked_optional_param_type = "Uint8Array | ArrayLike<number> | null")]
        shown: Option<Box<[u8]>>,
    ) -> Result<(), JsError> {
        self.stage.update().map_err(js_err)?;
        self.fit_pictures(shown.as_deref().unwrap_or(&[]))?;
        self.stage.draw().map_err(js_err)?;
        self.blit_pictures()
    }

    /// Milliseconds per stage since the last `update()`: `mapMs` (mapping and target synthesis
    /// in `update()`, plus compare-view cloning), `synthMs` (source synthesis and texture
    /// uploads), `rasterMs` (clearing and warping into the pixmaps), `blitMs` (into canvases).
    #[wasm_bindgen(unchecked_return_type = "Timings")]
    pub fn timings(&self) -> Result<JsValue, JsError> {
        let t = self.stage.timings();
        let o = js_sys::Object::new();
        for (k, v) in [
            ("mapMs", t.map),
            ("synthMs", t.synth),
            ("rasterMs", t.raster),
            ("blitMs", t.blit),
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
            .field("source", &self.stage.source().name())
            .field("targets", &self.stage.n_targets())
            .finish_non_exhaustive()
    }
}

/// `rgba_out`'s pixels as an `ImageData` (which exists in browsers and workers, not in Node).
fn as_image_data(
    data: js_sys::Uint8ClampedArray,
    width: u32,
    height: u32,
) -> Result<ImageData, JsError> {
    ImageData::new_with_js_u8_clamped_array_and_sh(&data, width, height).map_err(|e| {
        JsError::new(&format!(
            "ImageData: {} (in Node use renderTargetRGBA / renderSourceRGBA)",
            crate::surface::describe(&e)
        ))
    })
}

/// New straight RGBA bytes of `width x height` that `draw` renders into.
fn rgba_out(
    width: u32,
    height: u32,
    draw: impl FnOnce(Sink<'_>) -> Result<(), JsError>,
) -> Result<js_sys::Uint8ClampedArray, JsError> {
    let mut out = None;
    draw(Sink::Image {
        width,
        height,
        out: &mut out,
    })?;
    out.ok_or_else(|| JsError::coded("internal", "internal error: no image produced"))
}
