//! The compare view (the paper's Fig. 4 side by side): one target cloned from the same source
//! parameters with other methods than the stage's, each into its own picture.

use tiny_skia::PixmapMut;

use crate::clone::{Method, TargetFrame};
use crate::error::{Error, Result};

use super::paint_target;
use super::picture::{Picture, PictureOptions};

/// One picture of the compare view: the compared target cloned with `method`.
#[derive(Debug)]
pub struct CompareView {
    method: Method,
    picture: Picture,
}

impl CompareView {
    /// The method this view clones with.
    pub fn method(&self) -> Method {
        self.method
    }

    /// Changes the method (used from the next draw).
    pub fn set_method(&mut self, method: Method) {
        self.method = method;
    }

    /// The view's picture.
    pub fn picture(&self) -> &Picture {
        &self.picture
    }

    /// The view's picture, to size, show or hide and set options on.
    pub fn picture_mut(&mut self) -> &mut Picture {
        &mut self.picture
    }
}

/// The compare view's state: which target, its views, and the clone output they share (made
/// for the compared target once, dropped when the targets change).
#[derive(Debug, Default)]
pub(super) struct Compare {
    /// The compared target, `None`: off.
    pub target: Option<usize>,
    pub views: Vec<CompareView>,
    /// The output buffer, for the target index it was made for.
    pub out: Option<(usize, TargetFrame)>,
}

impl Compare {
    /// Adds a view of `method` drawn with `options` and returns its index.
    pub fn add(&mut self, method: Method, options: PictureOptions) -> usize {
        self.views.push(CompareView {
            method,
            picture: Picture::new(options),
        });
        self.views.len() - 1
    }

    /// Follows a change of the targets: `removed` (an index removed; later ones move down) or
    /// any other change (`None`: a replaced target or a new source). The shared output is
    /// made again on the next draw.
    pub fn targets_changed(&mut self, removed: Option<usize>) {
        self.out = None;
        if let (Some(r), Some(t)) = (removed, self.target) {
            self.target = match t.cmp(&r) {
                std::cmp::Ordering::Less => Some(t),
                std::cmp::Ordering::Equal => None,
                std::cmp::Ordering::Greater => Some(t - 1),
            };
        }
    }
}

impl super::Stage {
    /// Draws every sized, shown compare view when a target is compared: the target cloned
    /// from the current source parameters with the view's method (the other options as the
    /// stage's), leaving the targets' own outputs untouched.
    pub fn draw_compare(&mut self) -> Result<()> {
        let Some(index) = self.compare.target else {
            return Ok(());
        };
        for k in 0..self.compare.views.len() {
            let view = &mut self.compare.views[k];
            let (method, options) = (view.method, *view.picture.options());
            if view.picture.target().is_none() {
                continue;
            }
            self.clone_compare(index, method)?;
            let view = &mut self.compare.views[k];
            let Some(pixmap) = view.picture.target() else {
                continue;
            };
            paint_target(
                (&mut self.painter, &mut self.targets),
                (&self.cloner, Some(compare_output(&self.compare.out)?)),
                index,
                &options,
                &mut pixmap.as_mut(),
            )?;
            view.picture.finish();
        }
        Ok(())
    }

    /// Target `index` cloned from the current source parameters with `method` (the other
    /// options as the stage's), drawn into the caller's `pixmap` with `options`: one compare
    /// view without a picture of its own.
    pub fn draw_compare_into(
        &mut self,
        index: usize,
        method: Method,
        options: &PictureOptions,
        pixmap: &mut PixmapMut<'_>,
    ) -> Result<()> {
        self.check_index(index)?;
        self.clone_compare(index, method)?;
        paint_target(
            (&mut self.painter, &mut self.targets),
            (&self.cloner, Some(compare_output(&self.compare.out)?)),
            index,
            options,
            pixmap,
        )
    }

    /// Clones target `index` with `method` into the compare output (made for it first when
    /// it was made for another target or the targets changed), adding to the map time.
    fn clone_compare(&mut self, index: usize, method: Method) -> Result<()> {
        if !matches!(&self.compare.out, Some((i, _)) if *i == index) {
            let out = self
                .cloner
                .target_frame(index)
                .ok_or_else(|| super::out_of_range(index, self.cloner.n_targets()))?;
            self.compare.out = Some((index, out));
        }
        let Some((_, out)) = self.compare.out.as_mut() else {
            return Err(Error::Params("internal error: no compare output".into()));
        };
        let t0 = self.painter.now();
        // Only the method differs; the options were validated when set.
        let saved = self.options.method;
        self.options.method = method;
        let r = self
            .cloner
            .clone_target(index, &self.params, &self.options, out);
        self.options.method = saved;
        self.painter.timings.map += self.painter.now() - t0;
        r
    }
}

/// The compare view's output (made by `clone_compare` before every use).
fn compare_output(out: &Option<(usize, TargetFrame)>) -> Result<&TargetFrame> {
    match out {
        Some((_, frame)) => Ok(frame),
        None => Err(Error::Params("internal error: no compare output".into())),
    }
}
