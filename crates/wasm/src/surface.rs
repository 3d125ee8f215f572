//! Canvas plumbing shared by every render entry point: the 2D context (on-screen or offscreen),
//! the render options read from JS, the reusable tiny-skia pixmaps (one per canvas size), the
//! blit and the clock. What is drawn, and where in the canvas, is the core's
//! ([`facemimic::FaceDrawer`], [`facemimic::fit_view`]).

use crate::JsError;
use std::cell::RefCell;

use facemimic::tiny_skia::{Color, Pixmap, PixmapMut};
use wasm_bindgen::prelude::*;
use wasm_bindgen::{Clamped, JsCast};
use web_sys::{CanvasRenderingContext2d, ImageData, OffscreenCanvasRenderingContext2d};

use facemimic::Similarity;
use facemimic::MAX_IMAGE_SIDE;
use facemimic::{DrawOptions, Framing, PictureOptions, Rasterizer};

#[wasm_bindgen]
extern "C" {
    /// `performance.now()` (window, worker and Node alike).
    #[wasm_bindgen(js_namespace = performance, js_name = now)]
    fn performance_now() -> f64;
}

/// Milliseconds from a monotonic clock.
pub(crate) fn now_ms() -> f64 {
    performance_now()
}

/// A 2D context to draw into: `CanvasRenderingContext2D` or `OffscreenCanvasRenderingContext2D`.
pub(crate) enum Ctx {
    /// An on-screen canvas.
    Html(CanvasRenderingContext2d),
    /// An offscreen canvas (workers, tests).
    Offscreen(OffscreenCanvasRenderingContext2d),
}

impl Ctx {
    /// Accepts either kind of 2D context, with an error naming what was passed otherwise.
    pub(crate) fn from_js(value: &JsValue) -> Result<Ctx, JsError> {
        if let Some(c) = value.dyn_ref::<CanvasRenderingContext2d>() {
            return Ok(Ctx::Html(c.clone()));
        }
        if let Some(c) = value.dyn_ref::<OffscreenCanvasRenderingContext2d>() {
            return Ok(Ctx::Offscreen(c.clone()));
        }
        Err(JsError::new(&format!(
            "expected a CanvasRenderingContext2D (canvas.getContext(\"2d\")), got {}",
            describe(value)
        )))
    }

    /// The canvas's size in its own pixels.
    pub(crate) fn size(&self) -> Result<(u32, u32), JsError> {
        let (w, h) = match self {
            Ctx::Html(c) => match c.canvas() {
                Some(canvas) => (canvas.width(), canvas.height()),
                None => return Err(JsError::new("the 2D context has no canvas")),
            },
            Ctx::Offscreen(c) => {
                let canvas = c.canvas();
                (canvas.width(), canvas.height())
            }
        };
        if w > MAX_IMAGE_SIDE || h > MAX_IMAGE_SIDE {
            return Err(JsError::new(&format!(
                "canvas {w}x{h} is larger than {MAX_IMAGE_SIDE} pixels on a side"
            )));
        }
        check_area(w, h)?;
        Ok((w, h))
    }

    fn put(&self, image: &ImageData) -> Result<(), JsError> {
        let r = match self {
            Ctx::Html(c) => c.put_image_data(image, 0.0, 0.0),
            Ctx::Offscreen(c) => c.put_image_data(image, 0.0, 0.0),
        };
        r.map_err(|e| JsError::new(&format!("putImageData failed: {}", describe(&e))))
    }
}

/// Most pixels one render target may have (64 MB of RGBA): a larger pixmap could exhaust wasm
/// memory, which aborts instead of failing.
pub(crate) const MAX_RENDER_PIXELS: u64 = facemimic::MAX_PICTURE_PIXELS;

fn check_area(w: u32, h: u32) -> Result<(), JsError> {
    if w as u64 * h as u64 > MAX_RENDER_PIXELS {
        return Err(JsError::new(&format!(
            "{w}x{h} is more than {MAX_RENDER_PIXELS} pixels: render into a smaller canvas"
        )));
    }
    Ok(())
}

/// A short description of a JS value for error messages.
pub(crate) fn describe(value: &JsValue) -> String {
    if value.is_undefined() {
        return "undefined".into();
    }
    if value.is_null() {
        return "null".into();
    }
    if let Some(s) = value.as_string() {
        return format!("the string {s:?}");
    }
    if let Some(n) = value.as_f64() {
        return format!("the number {n}");
    }
    if let Some(e) = value.dyn_ref::<js_sys::Error>() {
        return String::from(e.message());
    }
    let ctor = js_sys::Reflect::get(value, &JsValue::from_str("constructor"))
        .ok()
        .and_then(|c| js_sys::Reflect::get(&c, &JsValue::from_str("name")).ok())
        .and_then(|n| n.as_string());
    match ctor {
        Some(name) => format!("a {name}"),
        None => "an object".into(),
    }
}

/// Parsed [`RenderOptions`](crate) (`{ background?: string, mesh?: boolean, raster?: string }`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct RenderOptions {
    /// Premultiplied background colour.
    pub background: Color,
    /// The rasteriser and the mesh overlay.
    pub draw: DrawOptions,
    /// Composite targets into their backdrops.
    pub composite: bool,
    /// Keep a composited picture whole (follow-pose damped where it would tear).
    pub keep_whole: bool,
}

/// The default background, `#202024`.
pub(crate) const DEFAULT_BACKGROUND: [u8; 4] = facemimic::DEFAULT_BACKGROUND;

impl Default for RenderOptions {
    fn default() -> Self {
        let [r, g, b, a] = DEFAULT_BACKGROUND;
        RenderOptions {
            background: Color::from_rgba8(r, g, b, a),
            draw: DrawOptions::default(),
            composite: false,
            keep_whole: true,
        }
    }
}

thread_local! {
    /// The last background string seen and its parse, so that passing the same options every
    /// frame costs no allocation.
    static LAST_BACKGROUND: RefCell<Option<(JsValue, Color)>> = const { RefCell::new(None) };
}

impl RenderOptions {
    /// The core's options of a picture drawn with these (the face fitted to the canvas).
    pub(crate) fn picture(&self) -> PictureOptions {
        PictureOptions {
            background: self.background,
            draw: self.draw,
            composite: self.composite,
            framing: Framing::Fitted,
            keep_whole: self.keep_whole,
        }
    }

    /// Reads `{ background?, mesh? }` from JS (`undefined`/`null` = defaults).
    pub(crate) fn from_js(value: &Option<JsValue>) -> Result<RenderOptions, JsError> {
        let mut o = RenderOptions::default();
        let Some(value) = value else {
            return Ok(o);
        };
        if value.is_undefined() || value.is_null() {
            return Ok(o);
        }
        if !value.is_object() {
            return Err(JsError::new(&format!(
                "render options: expected an object like {{ background: \"#202024\", mesh: false }}, got {}",
                describe(value)
            )));
        }
        let get = |key: &str| {
            js_sys::Reflect::get(value, &JsValue::from_str(key)).map_err(|e| {
                JsError::new(&format!("render options: reading {key}: {}", describe(&e)))
            })
        };
        let bg = get("background")?;
        if !(bg.is_undefined() || bg.is_null()) {
            let cached = LAST_BACKGROUND.with(|c| {
                c.borrow()
                    .as_ref()
                    .and_then(|(s, col)| js_sys::Object::is(s, &bg).then_some(*col))
            });
            o.background = match cached {
                Some(c) => c,
                None => {
                    let Some(text) = bg.as_string() else {
                        return Err(JsError::new(&format!(
                            "render options: background must be a string like \"#202024\", got {}",
                            describe(&bg)
                        )));
                    };
                    let c = parse_colour(&text).ok_or_else(|| {
                        JsError::new(&format!(
                            "render options: background {text:?} is not a CSS hex colour \
                             (#rgb, #rgba, #rrggbb, #rrggbbaa) or \"transparent\""
                        ))
                    })?;
                    LAST_BACKGROUND.with(|cell| *cell.borrow_mut() = Some((bg.clone(), c)));
                    c
                }
            };
        }
        // A boolean option: `None` when absent (`undefined` or `null`).
        let flag = |key: &str| -> Result<Option<bool>, JsError> {
            let v = get(key)?;
            if v.is_undefined() || v.is_null() {
                return Ok(None);
            }
            v.as_bool().map(Some).ok_or_else(|| {
                JsError::new(&format!(
                    "render options: {key} must be a boolean, got {}",
                    describe(&v)
                ))
            })
        };
        if let Some(mesh) = flag("mesh")? {
            o.draw.mesh = mesh;
        }
        if let Some(composite) = flag("composite")? {
            o.composite = composite;
        }
        if let Some(keep) = flag("keepWhole")? {
            o.keep_whole = keep;
        }
        let raster = get("raster")?;
        if !(raster.is_undefined() || raster.is_null()) {
            o.draw.rasterizer = if js_sys::Object::is(&raster, &JsValue::from_str("scanline")) {
                Rasterizer::Scanline
            } else if js_sys::Object::is(&raster, &JsValue::from_str("tiny-skia")) {
                Rasterizer::TinySkia
            } else {
                return Err(JsError::new(&format!(
                    "render options: raster must be \"scanline\" or \"tiny-skia\", got {}",
                    describe(&raster)
                )));
            };
        }
        Ok(o)
    }
}

/// Parses `#rgb`, `#rgba`, `#rrggbb`, `#rrggbbaa` or `transparent`.
pub(crate) fn parse_colour(text: &str) -> Option<Color> {
    let t = text.trim();
    if t.eq_ignore_ascii_case("transparent") {
        return Some(Color::TRANSPARENT);
    }
    let hex = t.strip_prefix('#')?;
    if !hex.bytes().all(|b| b.is_ascii_hexdigit()) {
        return None;
    }
    let nib = |i: usize| u8::from_str_radix(&hex[i..i + 1], 16).ok();
    let byte = |i: usize| u8::from_str_radix(&hex[i..i + 2], 16).ok();
    let [r, g, b, a] = match hex.len() {
        3 | 4 => {
            let a = if hex.len() == 4 { nib(3)? * 17 } else { 255 };
            [nib(0)? * 17, nib(1)? * 17, nib(2)? * 17, a]
        }
        6 | 8 => {
            let a = if hex.len() == 8 { byte(6)? } else { 255 };
            [byte(0)?, byte(2)?, byte(4)?, a]
        }
        _ => return None,
    };
    Some(Color::from_rgba8(r, g, b, a))
}

/// A reusable pixmap of one canvas size and its straight-alpha copy (for non-opaque
/// backgrounds).
pub(crate) struct Surface {
    pixmap: Pixmap,
    straight: Vec<u8>,
    last_use: u64,
}

/// Pixmaps by canvas size (a few at most), shared by all renders: drawing is synchronous and
/// single-threaded, so one per size suffices. Re-created only when a new size appears.
pub(crate) struct Surfaces {
    list: Vec<Surface>,
    clock: u64,
}

/// Most distinct canvas sizes kept at once.
const MAX_SURFACES: usize = 6;

thread_local! {
    static SURFACES: RefCell<Surfaces> = const { RefCell::new(Surfaces { list: Vec::new(), clock: 0 }) };
}

/// Timings of one render (milliseconds; the drawing's own are the stage's).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Stages {
    /// Copying into the canvas.
    pub blit: f64,
}

/// Where a render goes: a canvas context, or a new `ImageData` of a given size.
pub(crate) enum Sink<'a> {
    /// Blit into this context's canvas (sized by the canvas).
    Canvas(&'a Ctx),
    /// Return a fresh array of this size's straight RGBA pixels (copied out of wasm memory).
    Image {
        /// Width in pixels.
        width: u32,
        /// Height in pixels.
        height: u32,
        /// The result.
        out: &'a mut Option<js_sys::Uint8ClampedArray>,
    },
}

impl Sink<'_> {
    fn size(&self) -> Result<(u32, u32), JsError> {
        match self {
            Sink::Canvas(ctx) => ctx.size(),
            Sink::Image { width, height, .. } => {
                if *width == 0
                    || *height == 0
                    || *width > MAX_IMAGE_SIDE
                    || *height > MAX_IMAGE_SIDE
                {
                    return Err(JsError::new(&format!(
                        "image size {width}x{height} outside 1..={MAX_IMAGE_SIDE}"
                    )));
                }
                check_area(*width, *height)?;
                Ok((*width, *height))
            }
        }
    }
}

/// Runs `draw` on a pixmap the size of the sink filled with `background`, then blits the
/// result into the canvas (or copies it into a new `ImageData`). Returns the blit time. A
/// zero-sized canvas is skipped.
pub(crate) fn paint<F>(sink: Sink<'_>, background: Color, draw: F) -> Result<Stages, JsError>
where
    F: FnOnce(&mut PixmapMut<'_>, u32, u32) -> Result<(), JsError>,
{
    paint_whole(sink, background.is_opaque(), |pixmap, w, h| {
        pixmap.fill(background);
        draw(pixmap, w, h)
    })
}

/// [`paint`] for a `draw` that paints every pixel itself (its background too: a
/// [`facemimic::Stage`] picture): the shared pixmap of the sink's size is not cleared first.
/// `opaque`: the drawing's background is opaque, so its premultiplied pixels are straight.
pub(crate) fn paint_whole<F>(sink: Sink<'_>, opaque: bool, draw: F) -> Result<Stages, JsError>
where
    F: FnOnce(&mut PixmapMut<'_>, u32, u32) -> Result<(), JsError>,
{
    let (w, h) = sink.size()?;
    if w == 0 || h == 0 {
        return Ok(Stages::default());
    }
    SURFACES.with(|cell| {
        let Ok(mut surfaces) = cell.try_borrow_mut() else {
            return Err(JsError::coded("busy", "render called re-entrantly"));
        };
        let surface = surfaces.get(w, h)?;
        draw(&mut surface.pixmap.as_mut(), w, h)?;
        let t1 = now_ms();
        let bytes =
            facemimic::straight_rgba(surface.pixmap.as_ref(), opaque, &mut surface.straight);
        match sink {
            Sink::Canvas(ctx) => put_rgba(ctx, bytes, w, h)?,
            Sink::Image { out, .. } => {
                let array = js_sys::Uint8ClampedArray::new_with_length(bytes.len() as u32);
                array.copy_from(bytes);
                *out = Some(array);
            }
        }
        let t2 = now_ms();
        Ok(Stages { blit: t2 - t1 })
    })
}

impl Surfaces {
    /// The surface of size `w x h`, made (evicting the least recently used beyond
    /// `MAX_SURFACES`) when there is none.
    fn get(&mut self, w: u32, h: u32) -> Result<&mut Surface, JsError> {
        self.clock += 1;
        let clock = self.clock;
        let idx = match self
            .list
            .iter()
            .position(|s| s.pixmap.width() == w && s.pixmap.height() == h)
        {
            Some(i) => i,
            None => {
                let pixmap = Pixmap::new(w, h).ok_or_else(|| {
                    JsError::coded("too-large", format!("cannot allocate a {w}x{h} pixmap"))
                })?;
                if self.list.len() >= MAX_SURFACES {
                    if let Some(oldest) = self
                        .list
                        .iter()
                        .enumerate()
                        .min_by_key(|(_, s)| s.last_use)
                        .map(|(i, _)| i)
                    {
                        self.list.swap_remove(oldest);
                    }
                }
                self.list.push(Surface {
                    pixmap,
                    straight: Vec::new(),
                    last_use: clock,
                });
                self.list.len() - 1
            }
        };
        let Some(surface) = self.list.get_mut(idx) else {
            return Err(JsError::coded("internal", "internal error: surface cache"));
        };
        surface.last_use = clock;
        Ok(surface)
    }
}

/// Puts straight RGBA pixels (`4 * w * h` bytes) into the context's canvas at its origin,
/// through a view on wasm memory consumed at once by `putImageData`.
pub(crate) fn put_rgba(ctx: &Ctx, rgba: &[u8], w: u32, h: u32) -> Result<(), JsError> {
    let image = ImageData::new_with_u8_clamped_array_and_sh(Clamped(rgba), w, h)
        .map_err(|e| JsError::new(&format!("ImageData: {}", describe(&e))))?;
    ctx.put(&image)
}

/// Reads a JS property, naming it in the error.
fn prop(value: &JsValue, key: &str, what: &str) -> Result<JsValue, JsError> {
    js_sys::Reflect::get(value, &JsValue::from_str(key)).map_err(|e| {
        JsError::coded(
            "bad-params",
            format!("parameters: reading {what}: {}", describe(&e)),
        )
    })
}

/// Copies a JS number array (an `Array`, a typed array or any array-like) of exactly
/// `out.len()` numbers into `out`, without allocating.
fn numbers_into(value: &JsValue, out: &mut [f32], what: &str) -> Result<(), JsError> {
    if let Some(a) = value.dyn_ref::<js_sys::Float32Array>() {
        if a.length() as usize != out.len() {
            return Err(JsError::coded(
                "bad-params",
                format!(
                    "parameters: {what} has {} values, the model expects {}",
                    a.length(),
                    out.len()
                ),
            ));
        }
        a.copy_to(out);
        return Ok(());
    }
    if !value.is_object() {
        return Err(JsError::coded(
            "bad-params",
            format!(
                "parameters: {what} must be an array of numbers, got {}",
                describe(value)
            ),
        ));
    }
    let len = prop(value, "length", what)?.as_f64().unwrap_or(-1.0);
    if len != out.len() as f64 {
        return Err(JsError::coded(
            "bad-params",
            format!(
                "parameters: {what} has {} values, the model expects {}",
                if len < 0.0 {
                    "no length: not an array, and no".to_string()
                } else {
                    len.to_string()
                },
                out.len()
            ),
        ));
    }
    for (i, o) in out.iter_mut().enumerate() {
        let v = js_sys::Reflect::get_u32(value, i as u32).map_err(|e| {
            JsError::coded(
                "bad-params",
                format!("parameters: reading {what}[{i}]: {}", describe(&e)),
            )
        })?;
        *o = v.as_f64().ok_or_else(|| {
            JsError::coded(
                "bad-params",
                format!("parameters: {what}[{i}] is not a number ({})", describe(&v)),
            )
        })? as f32;
    }
    Ok(())
}

/// Reads `{ pose: { scale, rotation, tx, ty }, shape, appearance }` into `out`, whose vectors
/// already have the model's lengths (the lengths are checked, nothing is allocated). On error
/// `out` may be partly written: read into a scratch copy and swap on success.
pub(crate) fn params_into(value: &JsValue, out: &mut facemimic::Params) -> Result<(), JsError> {
    if !value.is_object() {
        return Err(JsError::coded("bad-params", format!(
            "parameters: expected {{ pose: {{ scale, rotation, tx, ty }}, shape: [...], appearance: [...] }}, got {}",
            describe(value)
        )));
    }
    let pose = prop(value, "pose", "pose")?;
    if !pose.is_object() {
        return Err(JsError::coded(
            "bad-params",
            format!(
                "parameters: pose must be {{ scale, rotation, tx, ty }}, got {}",
                describe(&pose)
            ),
        ));
    }
    let mut p = [0f32; 4];
    for (o, key) in p.iter_mut().zip(["scale", "rotation", "tx", "ty"]) {
        let v = prop(&pose, key, key)?;
        *o = v.as_f64().ok_or_else(|| {
            JsError::coded(
                "bad-params",
                format!(
                    "parameters: pose.{key} must be a number, got {}",
                    describe(&v)
                ),
            )
        })? as f32;
    }
    out.pose = Similarity::from_parts(p[0], p[1], p[2], p[3]);
    numbers_into(&prop(value, "shape", "shape")?, &mut out.shape, "shape")?;
    numbers_into(
        &prop(value, "appearance", "appearance")?,
        &mut out.appearance,
        "appearance",
    )?;
    Ok(())
}
