//! Drawing one face into one picture: alone (uploaded and warped by the stage's one
//! [`FaceDrawer`]) or composited into its model's backdrop (by the face's [`Compositor`]),
//! with the stage timings.

use tiny_skia::PixmapMut;

use super::picture::{Framing, PictureOptions};
use super::timing::{Clock, Timings};
use crate::error::Result;
use crate::model::Model;
use crate::render::{fit_view, picture_view, Compositor, FaceDrawer};
use crate::similarity::Similarity;

/// One face to draw: its model, its appearance on the frame (`3N`), its landmarks in image
/// coordinates (`2n`) and the box a fitted view centres ([`Framing::Fitted`]).
#[derive(Clone, Copy, Debug)]
pub(super) struct Face<'a> {
    pub model: &'a Model,
    pub appearance: &'a [f32],
    pub shape: &'a [f32],
    pub bbox: [f32; 4],
}

/// The stage's drawing state: the one drawer (every model of a stage shares the source's
/// reference frame), the timings of the frame and the clock they are read from.
#[derive(Debug)]
pub(super) struct Painter {
    pub drawer: FaceDrawer,
    pub timings: Timings,
    pub clock: Clock,
}

impl Painter {
    /// Milliseconds now.
    pub fn now(&self) -> f64 {
        (self.clock)()
    }

    /// Paints `face` into `pixmap` with `options`: the background, then the face composited
    /// into its backdrop (with `compositor`, made on first use) when asked and possible, else
    /// the face alone framed as asked.
    ///
    /// Requires: `compositor` is `None` or made for `face.model`. Ensures: the timings grow
    /// by this draw's upload (`synth`) and fill and warp (`raster`).
    pub fn paint(
        &mut self,
        face: Face<'_>,
        compositor: &mut Option<Compositor>,
        options: &PictureOptions,
        pixmap: &mut PixmapMut<'_>,
    ) -> Result<()> {
        let frame = face.model.frame();
        let t0 = self.now();
        let composite = options.composite && face.model.backdrop().is_some();
        if !composite {
            self.drawer.set_options(options.draw);
            self.drawer.upload(frame, face.appearance)?;
        } else if compositor.is_none() {
            *compositor = Some(Compositor::new(face.model, options.draw)?);
        }
        let t1 = self.now();
        self.timings.synth += t1 - t0;
        pixmap.fill(options.background);
        let r = match compositor.as_mut().filter(|_| composite) {
            // The backdrop letterboxed to the pixmap ([`picture_view`]), the head and the face in it.
            Some(c) => {
                c.set_options(options.draw);
                c.set_keep_whole(options.keep_whole);
                let (bw, bh) = c.size();
                let view = picture_view(bw, bh, pixmap.width(), pixmap.height());
                c.draw(face.model, face.appearance, face.shape, &view, pixmap)
            }
            None => {
                let view = match options.framing {
                    Framing::Fitted => fit_view(face.bbox, pixmap.width(), pixmap.height()),
                    Framing::Image => Similarity::IDENTITY,
                };
                self.drawer.warp(frame, face.shape, &view, pixmap)
            }
        };
        self.timings.raster += self.now() - t1;
        r
    }
}
