//! Three-view drawings of a scene (the hand, the object, contacts, goals): one chart per
//! orthographic view, side by side, each with its title, axes and units, under a heading and
//! over a legend. Every view keeps equal scales on its two axes, so shapes are not distorted.

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::{PlotError, Rgb, color_of, draw_err, encode_png, font_ready};

/// One mark of a view, in the view's data units (the axes' units).
#[derive(Debug, Clone, PartialEq)]
pub enum Mark {
    /// A line segment.
    Line {
        /// Start.
        a: [f64; 2],
        /// End.
        b: [f64; 2],
        /// Colour.
        color: Rgb,
        /// Width in pixels.
        width: u32,
        /// Dashed instead of solid.
        dashed: bool,
    },
    /// An arrow from `from` to `to`, its head drawn at `to`.
    Arrow {
        /// Tail.
        from: [f64; 2],
        /// Head.
        to: [f64; 2],
        /// Colour.
        color: Rgb,
        /// Width in pixels.
        width: u32,
    },
    /// A circle of radius `r` in data units (at least one pixel is drawn).
    Circle {
        /// Centre.
        c: [f64; 2],
        /// Radius.
        r: f64,
        /// Colour.
        color: Rgb,
        /// Filled or outline.
        fill: bool,
    },
    /// A closed polygon.
    Polygon {
        /// Vertices.
        pts: Vec<[f64; 2]>,
        /// Colour of the outline.
        color: Rgb,
        /// Opacity of a fill in the same colour (0: no fill).
        fill_alpha: f64,
        /// Dashed outline.
        dashed: bool,
    },
    /// A text label whose left end is at `at`, shifted by `offset_px` pixels (right, down).
    Text {
        /// Anchor point.
        at: [f64; 2],
        /// Pixel offset from the anchor (x right, y down).
        offset_px: (i32, i32),
        /// The text.
        text: String,
        /// Colour.
        color: Rgb,
        /// Font size in pixels.
        size: u32,
    },
}

impl Mark {
    fn extend_bounds(&self, lo: &mut [f64; 2], hi: &mut [f64; 2]) {
        let mut add = |p: [f64; 2], r: f64| {
            for i in 0..2 {
                if p[i].is_finite() {
                    lo[i] = lo[i].min(p[i] - r);
                    hi[i] = hi[i].max(p[i] + r);
                }
            }
        };
        match self {
            Mark::Line { a, b, .. } => {
                add(*a, 0.0);
                add(*b, 0.0);
            }
            Mark::Arrow { from, to, .. } => {
                add(*from, 0.0);
                add(*to, 0.0);
            }
            Mark::Circle { c, r, .. } => add(*c, *r),
            Mark::Polygon { pts, .. } => pts.iter().for_each(|p| add(*p, 0.0)),
            Mark::Text { at, .. } => add(*at, 0.0),
        }
    }
}

/// One view: a title, axis labels with units and its marks.
#[derive(Debug, Clone, PartialEq)]
pub struct ScenePanel {
    /// Title above the view (e.g. "front (x–z)").
    pub title: String,
    /// Horizontal axis label with units.
    pub x_label: String,
    /// Vertical axis label with units.
    pub y_label: String,
    /// The marks, drawn in order.
    pub marks: Vec<Mark>,
    /// The data range shown (`[x_lo, y_lo]`, `[x_hi, y_hi]`); `None`: fitted to the marks.
    /// Either way it is widened so both axes have the same scale.
    pub range: Option<([f64; 2], [f64; 2])>,
}

impl ScenePanel {
    /// The bounding box of the marks, padded by 8 % of its larger side.
    pub fn fitted_range(&self) -> ([f64; 2], [f64; 2]) {
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        for m in &self.marks {
            m.extend_bounds(&mut lo, &mut hi);
        }
        if !(lo[0].is_finite() && lo[1].is_finite()) {
            return ([0.0, 0.0], [1.0, 1.0]);
        }
        let pad = 0.08 * (hi[0] - lo[0]).max(hi[1] - lo[1]).max(1e-6);
        ([lo[0] - pad, lo[1] - pad], [hi[0] + pad, hi[1] + pad])
    }
}

/// One legend entry: a colour swatch and its meaning.
#[derive(Debug, Clone, PartialEq)]
pub struct LegendEntry {
    /// What the colour shows.
    pub label: String,
    /// The colour.
    pub color: Rgb,
}

/// A drawing of views side by side under a heading and over a legend.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneFigure {
    /// Heading line(s) above the views (`\n` separates lines).
    pub heading: String,
    /// The views, left to right.
    pub panels: Vec<ScenePanel>,
    /// Legend entries below the views.
    pub legend: Vec<LegendEntry>,
    /// Width of one view in pixels (views are square plus their title and axes).
    pub panel_px: u32,
}

const HEADING_LINE_PX: u32 = 20;
const LEGEND_PX: u32 = 30;

impl SceneFigure {
    /// Pixel size of the whole figure (width, height).
    pub fn size(&self) -> (u32, u32) {
        let lines = self.heading.lines().count().max(1) as u32;
        (
            self.panel_px * self.panels.len().max(1) as u32,
            lines * HEADING_LINE_PX + 8 + self.panel_px + LEGEND_PX,
        )
    }

    /// Fix every view's range to the union of its fitted ranges over `frames` (so an
    /// animation's views do not jump between frames).
    pub fn share_ranges(frames: &mut [SceneFigure]) {
        let Some(n) = frames.iter().map(|f| f.panels.len()).max() else {
            return;
        };
        for p in 0..n {
            let mut lo = [f64::INFINITY; 2];
            let mut hi = [f64::NEG_INFINITY; 2];
            for f in frames.iter() {
                if let Some(panel) = f.panels.get(p) {
                    let (l, h) = panel.range.unwrap_or_else(|| panel.fitted_range());
                    for i in 0..2 {
                        lo[i] = lo[i].min(l[i]);
                        hi[i] = hi[i].max(h[i]);
                    }
                }
            }
            for f in frames.iter_mut() {
                if let Some(panel) = f.panels.get_mut(p) {
                    panel.range = Some((lo, hi));
                }
            }
        }
    }

    fn draw<DB: DrawingBackend>(&self, root: DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        font_ready()?;
        if self.panels.is_empty() {
            return Err(PlotError::Empty("no views"));
        }
        root.fill(&WHITE).map_err(draw_err)?;
        let lines = self.heading.lines().count().max(1) as u32;
        let (head, rest) = root.split_vertically(lines * HEADING_LINE_PX + 8);
        for (i, line) in self.heading.lines().enumerate() {
            head.draw(&Text::new(
                line.to_string(),
                (8, 4 + (i as u32 * HEADING_LINE_PX) as i32),
                ("sans-serif", if i == 0 { 17 } else { 14 }).into_font(),
            ))
            .map_err(draw_err)?;
        }
        let (views, legend) = rest.split_vertically(self.panel_px);
        for (area, panel) in views
            .split_evenly((1, self.panels.len()))
            .iter()
            .zip(&self.panels)
        {
            draw_panel(area, panel)?;
        }
        let mut x = 10i32;
        for e in &self.legend {
            let c = color_of(e.color);
            legend
                .draw(&Rectangle::new([(x, 9), (x + 14, 21)], c.filled()))
                .map_err(draw_err)?;
            let style = ("sans-serif", 13).into_font();
            legend
                .draw(&Text::new(e.label.clone(), (x + 19, 8), style.clone()))
                .map_err(draw_err)?;
            let (w, _) = legend
                .estimate_text_size(&e.label, &TextStyle::from(style.clone()))
                .map_err(draw_err)?;
            x += 19 + w as i32 + 16;
        }
        root.present().map_err(draw_err)
    }

    /// The figure as an SVG document.
    pub fn svg(&self) -> Result<String, PlotError> {
        let mut out = String::new();
        {
            let root = SVGBackend::with_string(&mut out, self.size()).into_drawing_area();
            self.draw(root)?;
        }
        Ok(out)
    }

    /// The figure as an RGB buffer (width × height × 3 bytes, rows top to bottom).
    pub fn rgb(&self) -> Result<Vec<u8>, PlotError> {
        let (w, h) = self.size();
        let mut buf = vec![0u8; w as usize * h as usize * 3];
        {
            let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
            self.draw(root)?;
        }
        Ok(buf)
    }

    /// The figure as a PNG file's bytes.
    pub fn png(&self) -> Result<Vec<u8>, PlotError> {
        let (w, h) = self.size();
        encode_png(&self.rgb()?, w, h)
    }
}

/// Widen `(lo, hi)` so that data units per pixel are equal on both axes of a `w × h` plot.
fn equal_scale(lo: [f64; 2], hi: [f64; 2], w: u32, h: u32) -> ([f64; 2], [f64; 2]) {
    let (w, h) = (f64::from(w.max(1)), f64::from(h.max(1)));
    let span = [(hi[0] - lo[0]).max(1e-9), (hi[1] - lo[1]).max(1e-9)];
    let per_px = (span[0] / w).max(span[1] / h);
    let want = [per_px * w, per_px * h];
    let mid = [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0];
    (
        [mid[0] - want[0] / 2.0, mid[1] - want[1] / 2.0],
        [mid[0] + want[0] / 2.0, mid[1] + want[1] / 2.0],
    )
}

fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    panel: &ScenePanel,
) -> Result<(), PlotError> {
    const MARGIN: u32 = 6;
    const X_AREA: u32 = 34;
    const Y_AREA: u32 = 46;
    const CAPTION: u32 = 22;
    let (w, h) = area.dim_in_pixel();
    let plot_w = w.saturating_sub(2 * MARGIN + Y_AREA);
    let plot_h = h.saturating_sub(2 * MARGIN + X_AREA + CAPTION);
    let (lo, hi) = panel.range.unwrap_or_else(|| panel.fitted_range());
    let (lo, hi) = equal_scale(lo, hi, plot_w, plot_h);
    let mut chart = ChartBuilder::on(area)
        .caption(&panel.title, ("sans-serif", 15))
        .margin(MARGIN)
        .x_label_area_size(X_AREA)
        .y_label_area_size(Y_AREA)
        .build_cartesian_2d(lo[0]..hi[0], lo[1]..hi[1])
        .map_err(draw_err)?;
    chart
        .configure_mesh()
        .light_line_style(RGBColor(238, 238, 238))
        .bold_line_style(RGBColor(215, 215, 215))
        .x_labels(6)
        .y_labels(6)
        .x_desc(&panel.x_label)
        .y_desc(&panel.y_label)
        .label_style(("sans-serif", 11))
        .axis_desc_style(("sans-serif", 12))
        .draw()
        .map_err(draw_err)?;
    let (pw, _) = chart.plotting_area().dim_in_pixel();
    let per_px = (hi[0] - lo[0]) / f64::from(pw.max(1));
    let plot = chart.plotting_area();
    for m in &panel.marks {
        match m {
            Mark::Line {
                a,
                b,
                color,
                width,
                dashed,
            } => {
                let style = color_of(*color).stroke_width(*width);
                if *dashed {
                    for seg in dashed_path(&[*a, *b], per_px, style) {
                        plot.draw(&seg).map_err(draw_err)?;
                    }
                } else {
                    plot.draw(&PathElement::new(vec![(a[0], a[1]), (b[0], b[1])], style))
                        .map_err(draw_err)?;
                }
            }
            Mark::Arrow {
                from,
                to,
                color,
                width,
            } => {
                let style = color_of(*color).stroke_width(*width);
                let d = [to[0] - from[0], to[1] - from[1]];
                let len = (d[0] * d[0] + d[1] * d[1]).sqrt();
                if len <= 0.0 {
                    continue;
                }
                let head = (7.0 * per_px).min(0.5 * len);
                let u = [d[0] / len, d[1] / len];
                let wing = |s: f64| {
                    (
                        to[0] - head * u[0] + s * 0.5 * head * u[1],
                        to[1] - head * u[1] - s * 0.5 * head * u[0],
                    )
                };
                plot.draw(&PathElement::new(
                    vec![(from[0], from[1]), (to[0], to[1])],
                    style,
                ))
                .map_err(draw_err)?;
                plot.draw(&PathElement::new(
                    vec![wing(1.0), (to[0], to[1]), wing(-1.0)],
                    style,
                ))
                .map_err(draw_err)?;
            }
            Mark::Circle { c, r, color, fill } => {
                let px = ((r / per_px).round() as i32).max(1);
                let c2 = (c[0], c[1]);
                let style = if *fill {
                    color_of(*color).filled()
                } else {
                    color_of(*color).stroke_width(1)
                };
                plot.draw(&Circle::new(c2, px, style)).map_err(draw_err)?;
            }
            Mark::Polygon {
                pts,
                color,
                fill_alpha,
                dashed,
            } => {
                if pts.len() < 2 {
                    continue;
                }
                let xy: Vec<(f64, f64)> = pts.iter().map(|p| (p[0], p[1])).collect();
                if *fill_alpha > 0.0 {
                    plot.draw(&Polygon::new(
                        xy.clone(),
                        color_of(*color).mix(*fill_alpha).filled(),
                    ))
                    .map_err(draw_err)?;
                }
                let mut closed = pts.clone();
                closed.push(pts[0]);
                let style = color_of(*color).stroke_width(1);
                if *dashed {
                    for seg in dashed_path(&closed, per_px, style) {
                        plot.draw(&seg).map_err(draw_err)?;
                    }
                } else {
                    let mut ring = xy;
                    ring.push(ring[0]);
                    plot.draw(&PathElement::new(ring, style))
                        .map_err(draw_err)?;
                }
            }
            Mark::Text {
                at,
                offset_px,
                text,
                color,
                size,
            } => {
                let style = ("sans-serif", *size)
                    .into_font()
                    .color(&color_of(*color))
                    .pos(Pos::new(HPos::Left, VPos::Center));
                plot.draw(
                    &(EmptyElement::at((at[0], at[1]))
                        + Text::new(text.clone(), *offset_px, style)),
                )
                .map_err(draw_err)?;
            }
        }
    }
    Ok(())
}

/// A polyline broken into 6-pixel dashes with 4-pixel gaps (`per_px`: data units per pixel).
fn dashed_path(pts: &[[f64; 2]], per_px: f64, style: ShapeStyle) -> Vec<PathElement<(f64, f64)>> {
    let (dash, gap) = (6.0 * per_px, 4.0 * per_px);
    let period = dash + gap;
    let mut out = Vec::new();
    if !(period > 0.0 && period.is_finite()) {
        return out;
    }
    let mut c0 = 0.0; // distance along the polyline where this segment starts
    for pair in pts.windows(2) {
        let (a, b) = (pair[0], pair[1]);
        let len = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
        if !(len > 0.0 && len.is_finite()) {
            continue;
        }
        let c1 = c0 + len;
        let at = |c: f64| {
            let t = ((c - c0) / len).clamp(0.0, 1.0);
            (a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t)
        };
        // Dash k covers [k·period, k·period + dash] along the polyline.
        let first = (c0 / period).floor() as i64;
        let last = (c1 / period).ceil() as i64;
        for k in first..=last.min(first + 100_000) {
            let (d0, d1) = (k as f64 * period, k as f64 * period + dash);
            let (s, e) = (d0.max(c0), d1.min(c1));
            if e > s {
                out.push(PathElement::new(vec![at(s), at(e)], style));
            }
        }
        c0 = c1;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn figure() -> SceneFigure {
        let panel = |title: &str| ScenePanel {
            title: title.into(),
            x_label: "x (cm)".into(),
            y_label: "z (cm)".into(),
            marks: vec![
                Mark::Line {
                    a: [0.0, 0.0],
                    b: [4.0, 2.0],
                    color: [60, 60, 200],
                    width: 2,
                    dashed: false,
                },
                Mark::Line {
                    a: [0.0, 2.0],
                    b: [4.0, 0.0],
                    color: [0, 0, 0],
                    width: 1,
                    dashed: true,
                },
                Mark::Arrow {
                    from: [1.0, 1.0],
                    to: [1.0, 3.0],
                    color: [20, 150, 40],
                    width: 2,
                },
                Mark::Circle {
                    c: [2.0, 1.0],
                    r: 0.5,
                    color: [30, 30, 140],
                    fill: false,
                },
                Mark::Polygon {
                    pts: vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]],
                    color: [200, 120, 20],
                    fill_alpha: 0.3,
                    dashed: false,
                },
                Mark::Text {
                    at: [2.0, 1.0],
                    offset_px: (6, 0),
                    text: "thumb".into(),
                    color: [0, 0, 0],
                    size: 12,
                },
            ],
            range: None,
        };
        SceneFigure {
            heading: "card · step 3/12\nmode: index".into(),
            panels: vec![panel("front (x–z)"), panel("top (x–y)")],
            legend: vec![LegendEntry {
                label: "contact force".into(),
                color: [20, 150, 40],
            }],
            panel_px: 300,
        }
    }

    #[test]
    fn svg_carries_heading_views_axes_labels_and_legend() {
        let svg = figure().svg().unwrap();
        for text in [
            "card · step 3/12",
            "mode: index",
            "front (x–z)",
            "top (x–y)",
            "x (cm)",
            "z (cm)",
            "thumb",
            "contact force",
        ] {
            assert!(svg.contains(text), "missing {text}");
        }
    }

    #[test]
    fn views_keep_equal_scales() {
        let (lo, hi) = equal_scale([0.0, 0.0], [4.0, 1.0], 200, 100);
        assert!(((hi[0] - lo[0]) / 200.0 - (hi[1] - lo[1]) / 100.0).abs() < 1e-12);
        assert!(hi[0] - lo[0] >= 4.0 && hi[1] - lo[1] >= 1.0);
    }

    #[test]
    fn shared_ranges_cover_every_frame() {
        let mut frames = vec![figure(), figure()];
        frames[1].panels[0].marks.push(Mark::Circle {
            c: [10.0, 10.0],
            r: 1.0,
            color: [0, 0, 0],
            fill: true,
        });
        SceneFigure::share_ranges(&mut frames);
        let r0 = frames[0].panels[0].range.unwrap();
        assert_eq!(r0, frames[1].panels[0].range.unwrap());
        assert!(r0.1[0] >= 11.0 && r0.1[1] >= 11.0);
        let rgb = frames[0].rgb().unwrap();
        let (w, h) = frames[0].size();
        assert_eq!(rgb.len(), (w * h * 3) as usize);
    }
}
