//! Figures of dips, drawn with [plotters]: box plots of per-trial outcomes (the paper's
//! Fig. 4–5, [`BoxPlot`]), three-view drawings of the hand and the object ([`SceneFigure`]),
//! stacked plots over an episode's time ([`Timeline`]) and GIF animations of scene frames
//! ([`GifWriter`]).
//!
//! Text is laid out with an embedded DejaVu Sans (`assets/fonts/`, Bitstream Vera licence),
//! registered once as plotters' `sans-serif`, so figures look the same on a fresh machine
//! without system fonts. Bitmaps are drawn into an RGB buffer and encoded with the `png` crate
//! or, for animations, the `gif` crate; writing files (atomically) is the caller's.

mod animation;
mod boxplot;
mod scene;
mod timeline;

use std::sync::OnceLock;

use plotters::style::{FontStyle, RGBColor, register_font};

pub use animation::GifWriter;
pub use boxplot::{BoxPlot, BoxSeries};
pub use scene::{LegendEntry, Mark, SceneFigure, ScenePanel};
pub use timeline::{Series, SeriesStyle, TimePanel, Timeline};

/// An RGB colour.
pub type Rgb = [u8; 3];

/// The embedded font.
const FONT: &[u8] = include_bytes!("../../../assets/fonts/DejaVuSans.ttf");

/// The categorical colours of series and boxes (matplotlib's `tab10`, first eight).
pub const PALETTE: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
];

/// Why a figure could not be drawn.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// The figure has nothing to draw.
    #[error("nothing to plot: {0}")]
    Empty(&'static str),
    /// The drawing backend failed.
    #[error("drawing failed: {0}")]
    Draw(String),
    /// PNG encoding failed.
    #[error("PNG encoding failed: {0}")]
    Png(String),
    /// GIF encoding failed, or a frame does not fit the animation.
    #[error("GIF encoding failed: {0}")]
    Gif(String),
}

pub(crate) fn draw_err<E: std::fmt::Debug>(e: E) -> PlotError {
    PlotError::Draw(format!("{e:?}"))
}

pub(crate) fn font_ready() -> Result<(), PlotError> {
    static READY: OnceLock<bool> = OnceLock::new();
    if *READY.get_or_init(|| register_font("sans-serif", FontStyle::Normal, FONT).is_ok()) {
        Ok(())
    } else {
        Err(PlotError::Draw("the embedded font did not load".into()))
    }
}

pub(crate) fn color_of(c: Rgb) -> RGBColor {
    RGBColor(c[0], c[1], c[2])
}

/// Encode an RGB buffer as PNG.
pub fn encode_png(rgb: &[u8], width: u32, height: u32) -> Result<Vec<u8>, PlotError> {
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, width, height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc
            .write_header()
            .map_err(|e| PlotError::Png(e.to_string()))?;
        w.write_image_data(rgb)
            .map_err(|e| PlotError::Png(e.to_string()))?;
    }
    Ok(out)
}
