//! The frame buffer node: takes the Renderers' `Pixels` messages and keeps the picture (8-bit RGB).
//!
//! The model gives it no timing of its own: a message costs nothing beyond the ring's delivery,
//! whose input-queue space it frees on arrival. What it holds is the run's [`FrameBufferImage`].

use pxpl5_renderer::Rect;

/// The frame buffer's image: its whole memory, 8-bit RGB, as a run leaves it (an image as in
/// `pxpl5_renderer::BoardImage`: a unit's complete state).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FrameBufferImage {
    pub width: u32,
    pub height: u32,
    /// Row-major RGB bytes.
    pub rgb: Vec<u8>,
    /// Pixels written so far.
    pub writes: u64,
}

impl FrameBufferImage {
    /// A black image.
    pub(crate) fn new(width: u32, height: u32) -> FrameBufferImage {
        FrameBufferImage {
            width,
            height,
            rgb: vec![0; width as usize * height as usize * 3],
            writes: 0,
        }
    }

    /// Write a readback of `rect`, its pixels' values `px` row by row: its tag is the screen
    /// position of the Renderer array's pixel (0, 0), x in the low 16 bits, y in the high 16;
    /// each value is R, G, B in its low three bytes. Pixels off the screen are dropped (a region
    /// may overhang the screen's edge), and so are those a payload made by a program lacks.
    pub(crate) fn write_pixels(&mut self, tag: u32, rect: Rect, px: &[u64]) {
        let (x, y) = (rect.x + (tag & 0xFFFF), rect.y + (tag >> 16));
        let (width, height) = (rect.width, rect.height);
        for row in 0..height {
            for col in 0..width {
                let (fx, fy) = (x + col, y + row);
                if fx >= self.width || fy >= self.height {
                    continue;
                }
                let Some(&v) = px.get((row * width + col) as usize) else {
                    continue;
                };
                // Frame-buffer rows count from the top of the screen; Renderer rows from the
                // bottom (y up), so flip.
                let i = ((self.height - 1 - fy) * self.width + fx) as usize;
                self.rgb[i * 3] = (v & 0xFF) as u8;
                self.rgb[i * 3 + 1] = ((v >> 8) & 0xFF) as u8;
                self.rgb[i * 3 + 2] = ((v >> 16) & 0xFF) as u8;
                self.writes += 1;
            }
        }
    }
}
