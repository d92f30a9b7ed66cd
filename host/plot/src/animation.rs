//! GIF animations of RGB frames, encoded with the `gif` crate (image-rs; pure Rust, no
//! system codec, plays in every browser without a plugin or a network).
//!
//! Frames are mapped onto one fixed global palette (a 6 × 6 × 6 colour cube plus a 39-step
//! grey ramp) instead of a palette learnt per frame: our figures are line drawings in a few
//! flat colours, the mapping is a few operations per pixel, and colours do not flicker between
//! frames. After the first frame, pixels that did not change are written as the palette's
//! last entry, transparent over the kept previous frame, which LZW packs into long runs
//! (an episode's GIF shrinks about threefold).

use std::io::Write;

use gif::{Encoder, Frame, Repeat};

use crate::PlotError;

fn gif_err<E: std::fmt::Display>(e: E) -> PlotError {
    PlotError::Gif(e.to_string())
}

const GREYS: usize = 39;
/// The palette entry that marks "unchanged since the last frame".
const UNCHANGED: u8 = 255;

/// The global palette: 216 cube colours, then 39 greys (black to white), then the
/// transparent entry.
fn palette() -> Vec<u8> {
    let mut p = Vec::with_capacity(256 * 3);
    for r in 0..6u8 {
        for g in 0..6u8 {
            for b in 0..6u8 {
                p.extend_from_slice(&[r * 51, g * 51, b * 51]);
            }
        }
    }
    for k in 0..GREYS {
        let v = (k * 255 / (GREYS - 1)) as u8;
        p.extend_from_slice(&[v, v, v]);
    }
    p.extend_from_slice(&[255, 255, 255]);
    p
}

/// The palette index of one colour: the grey ramp for near-greys, else the nearest cube colour.
fn index_of(px: &[u8]) -> u8 {
    let (r, g, b) = (i32::from(px[0]), i32::from(px[1]), i32::from(px[2]));
    let spread = r.max(g).max(b) - r.min(g).min(b);
    if spread < 12 {
        let v = (r + g + b) / 3;
        let k = (v * (GREYS as i32 - 1) + 127) / 255;
        return (216 + k) as u8;
    }
    let q = |c: i32| (c + 25) / 51;
    (q(r) * 36 + q(g) * 6 + q(b)) as u8
}

/// Writes an endlessly looping GIF frame by frame.
pub struct GifWriter<W: Write> {
    encoder: Encoder<W>,
    width: u16,
    height: u16,
    previous: Option<Vec<u8>>,
}

impl<W: Write> std::fmt::Debug for GifWriter<W> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GifWriter")
            .field("width", &self.width)
            .field("height", &self.height)
            .finish_non_exhaustive()
    }
}

impl<W: Write> GifWriter<W> {
    /// Start an animation of `width × height` pixels (each at most 65 535).
    pub fn new(out: W, width: u32, height: u32) -> Result<Self, PlotError> {
        let w = u16::try_from(width).map_err(|_| gif_err(format!("width {width} > 65535")))?;
        let h = u16::try_from(height).map_err(|_| gif_err(format!("height {height} > 65535")))?;
        let mut encoder = Encoder::new(out, w, h, &palette()).map_err(gif_err)?;
        encoder.set_repeat(Repeat::Infinite).map_err(gif_err)?;
        Ok(Self {
            encoder,
            width: w,
            height: h,
            previous: None,
        })
    }

    /// Append one RGB frame (`width × height × 3` bytes) shown for `delay_cs` hundredths of a
    /// second.
    pub fn frame(&mut self, rgb: &[u8], delay_cs: u16) -> Result<(), PlotError> {
        let n = usize::from(self.width) * usize::from(self.height);
        if rgb.len() != 3 * n {
            return Err(gif_err(format!(
                "frame has {} bytes, a {}×{} RGB frame has {}",
                rgb.len(),
                self.width,
                self.height,
                3 * n
            )));
        }
        let indices: Vec<u8> = rgb.chunks_exact(3).map(index_of).collect();
        let (pixels, transparent) = match &self.previous {
            Some(prev) => (
                indices
                    .iter()
                    .zip(prev)
                    .map(|(&i, &p)| if i == p { UNCHANGED } else { i })
                    .collect(),
                Some(UNCHANGED),
            ),
            None => (indices.clone(), None),
        };
        let mut frame = Frame::from_indexed_pixels(self.width, self.height, pixels, transparent);
        frame.delay = delay_cs;
        frame.dispose = gif::DisposalMethod::Keep;
        self.encoder.write_frame(&frame).map_err(gif_err)?;
        self.previous = Some(indices);
        Ok(())
    }

    /// Finish the file and hand back the writer.
    pub fn finish(self) -> Result<W, PlotError> {
        self.encoder.into_inner().map_err(gif_err)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_round_trip_through_a_decoder() {
        let (w, h) = (20u32, 10u32);
        let mut out = GifWriter::new(Vec::new(), w, h).unwrap();
        let red: Vec<u8> = [255, 0, 0].repeat((w * h) as usize);
        let mut grey: Vec<u8> = [128, 128, 128].repeat((w * h) as usize);
        grey[..3].copy_from_slice(&[255, 0, 0]); // unchanged pixel: kept from frame 1
        out.frame(&red, 50).unwrap();
        out.frame(&grey, 20).unwrap();
        assert!(
            out.frame(&red[3..], 10).is_err(),
            "a short frame is an error"
        );
        let bytes = out.finish().unwrap();
        let mut opts = gif::DecodeOptions::new();
        opts.set_color_output(gif::ColorOutput::RGBA);
        let mut dec = opts.read_info(std::io::Cursor::new(bytes)).unwrap();
        let f1 = dec.read_next_frame().unwrap().unwrap();
        assert_eq!((f1.width, f1.height, f1.delay), (20, 10, 50));
        assert_eq!(&f1.buffer[..4], &[255, 0, 0, 255]);
        let f2 = dec.read_next_frame().unwrap().unwrap();
        assert_eq!(f2.delay, 20);
        let g = f2.buffer[4];
        assert!(
            (i32::from(g) - 128).abs() <= 4 && f2.buffer[5] == g,
            "grey kept: {g}"
        );
        // The unchanged pixel is transparent in frame 2 (the decoder does not composite).
        assert_eq!(f2.transparent, Some(UNCHANGED));
        assert_eq!(f2.buffer[3], 0, "unchanged pixel is transparent");
        assert!(dec.read_next_frame().unwrap().is_none());
    }
}
