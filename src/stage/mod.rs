//! The whole pipeline of a front end in one value: a [`Stage`] holds a source (its model,
//! its current parameters and optionally the tracker that reads them from video), any number of
//! targets with their compositors and views, the compare view and the timings, and draws every
//! face into a picture it owns. The page (through the npm package's `Cloner`), the CLI, a batch
//! job or a test drive the same value: parameters or pixels in, pictures out.
//!
//! - `picture.rs`: [`Picture`], [`PictureOptions`], [`Framing`] (one picture and how it is drawn).
//! - `paint.rs`: drawing one face, alone or composited, with the timings.
//! - `compare.rs`: [`CompareView`] (one target cloned with other methods).
//! - `source.rs`: the source's parameters from a fit or a [`FaceTracker`].
//! - `timing.rs`: [`Timings`], [`Clock`].

use std::sync::Arc;
use tiny_skia::PixmapMut;

use crate::clone::{CloneOptions, Cloner, Method, TargetFrame};
use crate::error::{Error, Result};
use crate::fit::FaceTracker;
use crate::model::{Model, Params};
use crate::render::{base_box, Compositor, FaceDrawer};

mod compare;
mod paint;
mod picture;
mod source;
mod timing;

// Native: they read the committed GRID frames from disk.
#[cfg(all(test, not(target_arch = "wasm32")))]
mod tests;

pub use compare::CompareView;
pub use picture::{
    check_picture_size, Framing, Picture, PictureOptions, DEFAULT_BACKGROUND, MAX_PICTURE_PIXELS,
};
pub use timing::{default_clock, Clock, Timings};

use compare::Compare;
use paint::{Face, Painter};

/// The source's drawing state: its compositor (made on first composited draw), the scratch
/// its instance is synthesised into, and the box its fitted view centres.
#[derive(Debug)]
struct SourceFace {
    face: TargetFace,
    appearance: Vec<f32>,
    shape: Vec<f32>,
}

impl SourceFace {
    fn new(model: &Model) -> SourceFace {
        SourceFace {
            face: TargetFace::new(model),
            appearance: vec![0.0; model.appearance().len()],
            shape: vec![0.0; model.shape().base.len()],
        }
    }
}

/// A face's drawing state (a target's, and the source's within [`SourceFace`]): its compositor
/// (made on first composited draw) and the box its fitted view centres (its mean placement).
#[derive(Debug)]
struct TargetFace {
    compositor: Option<Compositor>,
    bbox: [f32; 4],
}

impl TargetFace {
    fn new(model: &Model) -> TargetFace {
        TargetFace {
            compositor: None,
            bbox: base_box(model),
        }
    }
}

/// One source face cloned onto any number of targets and drawn: the pipeline a front end
/// runs once per frame.
///
/// **Represents** the source (its [`Model`], its current [`Params`], optionally a
/// [`FaceTracker`] reading them from video), the targets (each a model, the
/// [`Cloner`]'s per-pair precomputation and output, a compositor for a model with a backdrop,
/// its view box), one [`CloneOptions`] every target follows, the compare view (one target
/// cloned with other methods, [`CompareView`]), a [`Picture`] per face and the [`Timings`] of
/// the frame.
///
/// **Requires** every target to be built in the source's reference frame (checked by
/// [`Stage::add_target`]); pictures sized by the caller ([`Picture::set_size`]) before they
/// are drawn.
///
/// **Ensures** one call a frame: [`Stage::frame_from_params`] (parameters in) or
/// [`Stage::frame_from_pixels`] (a video frame in, through the tracker) clones onto every target
/// and draws every sized, shown picture; the pictures' pixels are then read with
/// [`Picture::rgba`] or [`Picture::pixmap`]. Pictures drawn from the same parameters and
/// options are bit for bit those of a [`Cloner`] with a [`FaceDrawer`] or a [`Compositor`].
/// After the first frame (which makes the compositors), a frame allocates nothing. Bad input
/// gives an [`Error`] and leaves the state as it was; nothing panics.
#[derive(Debug)]
pub struct Stage {
    cloner: Cloner,
    options: CloneOptions,
    params: Params,
    /// Scratch for incoming parameters (validated, then swapped with `params`).
    pending: Params,
    tracker: Option<Box<dyn FaceTracker>>,
    painter: Painter,
    source: SourceFace,
    source_picture: Picture,
    targets: Vec<TargetFace>,
    target_pictures: Vec<Picture>,
    /// The options a new target's picture starts with.
    target_defaults: PictureOptions,
    compare: Compare,
    /// Head-motion damping of the poses taken from fits, if any.
    head: Option<crate::fit::HeadDamper>,
}

impl Stage {
    /// A stage driven by `source` at its base face, with no targets, the default
    /// [`CloneOptions`] and unsized pictures. Models are shared, not copied (pass an `Arc<Model>`
    /// to keep using one elsewhere). Fails as [`Cloner::new`] does.
    pub fn new(source: impl Into<Arc<Model>>) -> Result<Stage> {
        let source: Arc<Model> = source.into();
        let drawer = FaceDrawer::new(source.frame(), Default::default())?;
        let params = source.base_params();
        let face = SourceFace::new(&source);
        let cloner = Cloner::new(source)?;
        Ok(Stage {
            cloner,
            options: CloneOptions::default(),
            pending: params.clone(),
            params,
            tracker: None,
            painter: Painter {
                drawer,
                timings: Timings::default(),
                clock: default_clock,
            },
            source: face,
            source_picture: Picture::new(PictureOptions::default()),
            targets: Vec::new(),
            target_pictures: Vec::new(),
            target_defaults: PictureOptions::default(),
            compare: Compare::default(),
            head: None,
        })
    }

    /// Sets the clock the timings are read from (on wasm32, `performance.now()`).
    pub fn set_clock(&mut self, clock: Clock) {
        self.painter.clock = clock;
    }

    /// The cloner: the source and target models, each target's parameters, shape and
    /// appearance of the last [`Stage::update`].
    pub fn cloner(&self) -> &Cloner {
        &self.cloner
    }

    /// The source model.
    pub fn source(&self) -> &Model {
        self.cloner.source()
    }

    /// Number of targets.
    pub fn n_targets(&self) -> usize {
        self.cloner.n_targets()
    }

    /// Replaces the source model. On error (it is inconsistent, or a target is incompatible
    /// with it) nothing changes. Ensures: the source parameters are its base face, per-mode
    /// gains longer than its mode counts are dropped, the tracker is dropped (it followed the
    /// old model), the pictures and their options are kept.
    pub fn set_source(&mut self, source: impl Into<Arc<Model>>) -> Result<()> {
        let source: Arc<Model> = source.into();
        let drawer = FaceDrawer::new(source.frame(), Default::default())?;
        let params = source.base_params();
        let face = SourceFace::new(&source);
        let (m, l) = (source.shape().n_modes(), source.appearance().n_modes());
        self.cloner.set_source(source)?;
        self.painter.drawer = drawer;
        self.pending = params.clone();
        self.params = params;
        self.source = face;
        self.tracker = None;
        if let Some(h) = &mut self.head {
            h.restart();
        }
        self.options.shape_gains.truncate(m);
        self.options.appearance_gains.truncate(l);
        self.targets.iter_mut().for_each(|t| t.compositor = None);
        self.compare.targets_changed(None);
        Ok(())
    }

    /// Adds a target and returns its index; its picture is unsized and drawn with the
    /// options of [`Stage::set_target_defaults`]. Fails with [`Error::Incompatible`] naming
    /// what differs when it is not in the source's reference frame (nothing changes then).
    pub fn add_target(&mut self, target: impl Into<Arc<Model>>) -> Result<usize> {
        let target: Arc<Model> = target.into();
        let face = TargetFace::new(&target);
        let i = self.cloner.add_target(target)?;
        self.targets.push(face);
        self.target_pictures
            .push(Picture::new(self.target_defaults));
        self.compare.targets_changed(None);
        Ok(i)
    }

    /// Removes target `index` and returns its model; later targets (and their pictures) move
    /// down by one. The compare view follows its target (off when it was this one).
    pub fn remove_target(&mut self, index: usize) -> Result<Arc<Model>> {
        let model = self.cloner.remove_target(index)?;
        self.targets.remove(index);
        self.target_pictures.remove(index);
        self.compare.targets_changed(Some(index));
        Ok(model)
    }

    /// Replaces target `index` (same checks as [`Stage::add_target`]; on error nothing
    /// changes); its picture and options are kept.
    pub fn replace_target(&mut self, index: usize, target: impl Into<Arc<Model>>) -> Result<()> {
        let target: Arc<Model> = target.into();
        let face = TargetFace::new(&target);
        self.cloner.replace_target(index, target)?;
        self.targets[index] = face;
        self.compare.targets_changed(None);
        Ok(())
    }

    /// The options new targets' pictures start with (default [`PictureOptions::default`]).
    pub fn set_target_defaults(&mut self, options: PictureOptions) {
        self.target_defaults = options;
    }

    /// The cloning options every target follows.
    pub fn options(&self) -> &CloneOptions {
        &self.options
    }

    /// Replaces the cloning options after checking them against the source
    /// ([`CloneOptions::validate`]); on error the old ones stay.
    pub fn set_options(&mut self, options: CloneOptions) -> Result<()> {
        options.validate(self.cloner.source())?;
        self.options = options;
        Ok(())
    }

    /// The source's picture.
    pub fn source_picture(&self) -> &Picture {
        &self.source_picture
    }

    /// The source's picture, to size, show or hide and set options on.
    pub fn source_picture_mut(&mut self) -> &mut Picture {
        &mut self.source_picture
    }

    /// Target `index`'s picture, `None` when out of range.
    pub fn target_picture(&self, index: usize) -> Option<&Picture> {
        self.target_pictures.get(index)
    }

    /// Target `index`'s picture, to size, show or hide and set options on; an error names an
    /// index out of range.
    pub fn target_picture_mut(&mut self, index: usize) -> Result<&mut Picture> {
        let n = self.target_pictures.len();
        self.target_pictures
            .get_mut(index)
            .ok_or_else(|| out_of_range(index, n))
    }

    /// Target `index`'s last drawing as straight RGBA8 (see [`Picture::rgba`]).
    pub fn target_rgba(&self, index: usize) -> Result<&[u8]> {
        self.target_picture(index)
            .map(Picture::rgba)
            .ok_or_else(|| out_of_range(index, self.n_targets()))
    }

    /// The compared target (`None`: the compare view is off).
    pub fn compare_target(&self) -> Option<usize> {
        self.compare.target
    }

    /// Compares target `index` (`None` turns the compare view off); an error names an index
    /// out of range.
    pub fn set_compare_target(&mut self, index: Option<usize>) -> Result<()> {
        if let Some(i) = index {
            self.check_index(i)?;
        }
        self.compare.target = index;
        Ok(())
    }

    /// Adds a compare view cloning with `method`, drawn with `options` (unsized until
    /// [`Picture::set_size`]); returns its index.
    pub fn add_compare_view(&mut self, method: Method, options: PictureOptions) -> usize {
        self.compare.add(method, options)
    }

    /// The compare views, in the order they were added.
    pub fn compare_views(&self) -> &[CompareView] {
        &self.compare.views
    }

    /// Compare view `index`, `None` when out of range.
    pub fn compare_view_mut(&mut self, index: usize) -> Option<&mut CompareView> {
        self.compare.views.get_mut(index)
    }

    /// Removes compare view `index` (later ones move down); an error when out of range.
    pub fn remove_compare_view(&mut self, index: usize) -> Result<CompareView> {
        let n = self.compare.views.len();
        if index >= n {
            return Err(Error::Params(format!(
                "compare view {index} out of range ({n} view(s))"
            )));
        }
        Ok(self.compare.views.remove(index))
    }

    /// The timings since the last [`Stage::update`].
    pub fn timings(&self) -> Timings {
        self.painter.timings
    }

    /// Adds the time a shell spent copying pictures out to [`Timings::blit`].
    pub fn add_blit_ms(&mut self, ms: f64) {
        self.painter.timings.blit += ms;
    }

    /// Milliseconds on the stage's clock.
    pub fn now_ms(&self) -> f64 {
        self.painter.now()
    }

    /// Clones the current source parameters onto every target (the [`Cloner::clone_frame`]
    /// of the options) and resets the timings. Allocates nothing. On error (an output that
    /// overflows) the targets' outputs must not be drawn.
    pub fn update(&mut self) -> Result<()> {
        self.painter.timings = Timings::default();
        let t0 = self.painter.now();
        let r = self.cloner.clone_frame(&self.params, &self.options);
        self.painter.timings.map = self.painter.now() - t0;
        r
    }

    /// Draws every sized and shown picture: the source, each target as of the last
    /// [`Stage::update`], and the compare views when a target is compared.
    pub fn draw(&mut self) -> Result<()> {
        self.draw_source()?;
        for i in 0..self.targets.len() {
            self.draw_target(i)?;
        }
        self.draw_compare()
    }

    /// One frame from parameters: [`Stage::set_source_params`], [`Stage::update`],
    /// [`Stage::draw`].
    pub fn frame_from_params(&mut self, params: &Params) -> Result<()> {
        self.set_source_params(params)?;
        self.update()?;
        self.draw()
    }

    /// Draws the source's picture (when sized and shown) from the current parameters.
    pub fn draw_source(&mut self) -> Result<()> {
        let options = *self.source_picture.options();
        if let Some(pixmap) = self.source_picture.target() {
            paint_source(
                (&mut self.painter, &mut self.source),
                (self.cloner.source(), &self.params),
                &options,
                &mut pixmap.as_mut(),
            )?;
            self.source_picture.finish();
        }
        Ok(())
    }

    /// Draws target `index`'s picture (when sized and shown) as of the last update.
    pub fn draw_target(&mut self, index: usize) -> Result<()> {
        self.check_index(index)?;
        let picture = &mut self.target_pictures[index];
        let options = *picture.options();
        if let Some(pixmap) = picture.target() {
            paint_target(
                (&mut self.painter, &mut self.targets),
                (&self.cloner, None),
                index,
                &options,
                &mut pixmap.as_mut(),
            )?;
            picture.finish();
        }
        Ok(())
    }

    /// Draws the source face into the caller's `pixmap` (any size) with `options`.
    pub fn draw_source_into(
        &mut self,
        options: &PictureOptions,
        pixmap: &mut PixmapMut<'_>,
    ) -> Result<()> {
        paint_source(
            (&mut self.painter, &mut self.source),
            (self.cloner.source(), &self.params),
            options,
            pixmap,
        )
    }

    /// Draws target `index` as of the last update into the caller's `pixmap` with `options`.
    pub fn draw_target_into(
        &mut self,
        index: usize,
        options: &PictureOptions,
        pixmap: &mut PixmapMut<'_>,
    ) -> Result<()> {
        self.check_index(index)?;
        paint_target(
            (&mut self.painter, &mut self.targets),
            (&self.cloner, None),
            index,
            options,
            pixmap,
        )
    }

    /// The source's landmarks for the current parameters (image coordinates, `2n` values).
    pub fn source_landmarks(&mut self) -> Result<&[f32]> {
        self.cloner
            .source()
            .image_shape(&self.params, &mut self.source.shape)?;
        Ok(&self.source.shape)
    }

    fn check_index(&self, index: usize) -> Result<()> {
        if index < self.n_targets() {
            Ok(())
        } else {
            Err(out_of_range(index, self.n_targets()))
        }
    }
}

/// The error for target `index` out of range of `n`.
fn out_of_range(index: usize, n: usize) -> Error {
    Error::Params(format!("target index {index} out of range ({n} target(s))"))
}

/// Target `index`'s face as of the last update.
fn target_face<'a>(
    cloner: &'a Cloner,
    targets: &[TargetFace],
    index: usize,
    out: Option<&'a TargetFrame>,
) -> Result<Face<'a>> {
    let (Some(model), Some(t)) = (cloner.get_target(index), targets.get(index)) else {
        return Err(out_of_range(index, cloner.n_targets()));
    };
    let (appearance, shape) = match out {
        Some(o) => (o.appearance(), o.shape()),
        None => (cloner.target_appearance(index), cloner.target_shape(index)),
    };
    Ok(Face {
        model,
        appearance,
        shape,
        bbox: t.bbox,
    })
}

/// Paints target `index` (the cloner's output for it, or `out`: the compare view's) with its
/// compositor and view box into `pixmap`.
fn paint_target(
    (painter, targets): (&mut Painter, &mut [TargetFace]),
    (cloner, out): (&Cloner, Option<&TargetFrame>),
    index: usize,
    options: &PictureOptions,
    pixmap: &mut PixmapMut<'_>,
) -> Result<()> {
    let face = target_face(cloner, targets, index, out)?;
    painter.paint(face, &mut targets[index].compositor, options, pixmap)
}

/// Synthesises the source instance of `params` (Eq. 1 posed, Eq. 2) into its scratch and
/// paints it.
fn paint_source(
    (painter, face): (&mut Painter, &mut SourceFace),
    (model, params): (&Model, &Params),
    options: &PictureOptions,
    pixmap: &mut PixmapMut<'_>,
) -> Result<()> {
    let t0 = painter.now();
    model.image_shape(params, &mut face.shape)?;
    // Eq. 2 (the parameters were checked by `image_shape`).
    model
        .appearance()
        .instance_unchecked(&params.appearance, &mut face.appearance);
    painter.timings.synth += painter.now() - t0;
    let f = Face {
        model,
        appearance: &face.appearance,
        shape: &face.shape,
        bbox: face.face.bbox,
    };
    painter.paint(f, &mut face.face.compositor, options, pixmap)
}
