//! Plots over an episode's time: panels stacked on one shared time axis, with the episode's
//! phases (its contact modes) shaded and named, each panel with its title, units and legend.

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::{PlotError, Rgb, color_of, draw_err, encode_png, font_ready};

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SeriesStyle {
    /// Points joined by straight lines.
    Line,
    /// Points joined by a dashed line.
    Dashed,
    /// A dashed staircase: each value holds until the next point (targets, limits).
    Steps,
    /// Dots only.
    Points,
}

/// One series of a panel.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Legend text.
    pub label: String,
    /// Colour.
    pub color: Rgb,
    /// Style.
    pub style: SeriesStyle,
    /// `(time, value)` points; non-finite values break the line and are left out.
    pub points: Vec<(f64, f64)>,
}

/// One panel: a title, the value axis label with units, its series.
#[derive(Debug, Clone, PartialEq)]
pub struct TimePanel {
    /// Title above the panel.
    pub title: String,
    /// Value axis label with units.
    pub y_label: String,
    /// The series.
    pub series: Vec<Series>,
}

/// Panels stacked over one time axis.
#[derive(Debug, Clone, PartialEq)]
pub struct Timeline {
    /// Title above the panels.
    pub title: String,
    /// Time axis label with units.
    pub x_label: String,
    /// The panels, top to bottom.
    pub panels: Vec<TimePanel>,
    /// Phases as `(start time, name)`, in order; each lasts until the next one starts (the
    /// last until the end of the axis). Shaded alternately and named in the top panel.
    pub phases: Vec<(f64, String)>,
    /// Width and height of one panel in pixels.
    pub panel_size: (u32, u32),
}

const TITLE_PX: u32 = 34;

impl Timeline {
    /// Pixel size of the whole figure.
    pub fn size(&self) -> (u32, u32) {
        (
            self.panel_size.0,
            TITLE_PX + self.panel_size.1 * self.panels.len().max(1) as u32,
        )
    }

    fn time_range(&self) -> (f64, f64) {
        let mut lo = f64::INFINITY;
        let mut hi = f64::NEG_INFINITY;
        let xs = self
            .panels
            .iter()
            .flat_map(|p| p.series.iter())
            .flat_map(|s| s.points.iter().map(|p| p.0))
            .chain(self.phases.iter().map(|p| p.0));
        for x in xs.filter(|x| x.is_finite()) {
            lo = lo.min(x);
            hi = hi.max(x);
        }
        if !lo.is_finite() {
            return (0.0, 1.0);
        }
        if hi - lo < 1e-9 {
            hi = lo + 1.0;
        }
        (lo, hi)
    }

    fn draw<DB: DrawingBackend>(&self, root: DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        font_ready()?;
        if self.panels.is_empty() {
            return Err(PlotError::Empty("no panels"));
        }
        root.fill(&WHITE).map_err(draw_err)?;
        let (head, body) = root.split_vertically(TITLE_PX);
        head.draw(&Text::new(
            self.title.clone(),
            (10, 8),
            ("sans-serif", 18).into_font(),
        ))
        .map_err(draw_err)?;
        let (t0, t1) = self.time_range();
        for (k, (area, panel)) in body
            .split_evenly((self.panels.len(), 1))
            .iter()
            .zip(&self.panels)
            .enumerate()
        {
            self.draw_panel(area, panel, (t0, t1), k == 0)?;
        }
        root.present().map_err(draw_err)
    }

    fn draw_panel<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
        panel: &TimePanel,
        (t0, t1): (f64, f64),
        name_phases: bool,
    ) -> Result<(), PlotError> {
        let mut lo = f64::INFINITY;
        let mut hi = f64::NEG_INFINITY;
        for &(_, y) in panel.series.iter().flat_map(|s| s.points.iter()) {
            if y.is_finite() {
                lo = lo.min(y);
                hi = hi.max(y);
            }
        }
        if !lo.is_finite() {
            (lo, hi) = (0.0, 1.0);
        }
        let pad = ((hi - lo) * 0.08).max(1e-6 + 1e-3 * hi.abs().max(lo.abs()));
        let (lo, hi) = (
            lo - pad,
            hi + pad
                + if name_phases {
                    0.18 * (hi - lo + pad)
                } else {
                    0.0
                },
        );
        // Room above the data for the legend (upper right), so it never covers a line: one
        // 16 px row per series drawn, out of the plot's height in pixels.
        let entries = panel
            .series
            .iter()
            .filter(|s| s.points.iter().any(|p| p.1.is_finite()))
            .count();
        let plot_px = (f64::from(self.panel_size.1) - 72.0).max(60.0);
        let legend = if entries > 0 {
            ((16.0 * entries as f64 + 10.0) / plot_px).min(0.6)
        } else {
            0.0
        };
        let hi = hi + (hi - lo) * legend / (1.0 - legend);
        let mut chart = ChartBuilder::on(area)
            .caption(&panel.title, ("sans-serif", 15))
            .margin(8)
            .x_label_area_size(36)
            .y_label_area_size(64)
            .build_cartesian_2d(t0..t1, lo..hi)
            .map_err(draw_err)?;
        chart
            .configure_mesh()
            .light_line_style(RGBColor(240, 240, 240))
            .bold_line_style(RGBColor(220, 220, 220))
            .x_desc(&self.x_label)
            .y_desc(&panel.y_label)
            .label_style(("sans-serif", 12))
            .axis_desc_style(("sans-serif", 13))
            .draw()
            .map_err(draw_err)?;
        for (i, (start, name)) in self.phases.iter().enumerate() {
            let end = self.phases.get(i + 1).map_or(t1, |p| p.0);
            if i % 2 == 1 {
                chart
                    .draw_series([Rectangle::new(
                        [(*start, lo), (end, hi)],
                        RGBColor(120, 120, 120).mix(0.08).filled(),
                    )])
                    .map_err(draw_err)?;
            }
            chart
                .draw_series([PathElement::new(
                    vec![(*start, lo), (*start, hi)],
                    RGBColor(150, 150, 150).stroke_width(1),
                )])
                .map_err(draw_err)?;
            if name_phases {
                chart
                    .draw_series([Text::new(
                        name.clone(),
                        (*start, hi),
                        ("sans-serif", 11)
                            .into_font()
                            .color(&RGBColor(80, 80, 80))
                            .pos(plotters::style::text_anchor::Pos::new(
                                plotters::style::text_anchor::HPos::Left,
                                plotters::style::text_anchor::VPos::Top,
                            )),
                    )])
                    .map_err(draw_err)?;
            }
        }
        let mut labelled = false;
        for s in &panel.series {
            let color = color_of(s.color);
            let runs = finite_runs(&s.points);
            if runs.iter().all(Vec::is_empty) {
                continue;
            }
            let mut first = true;
            for run in runs {
                let anno = match s.style {
                    SeriesStyle::Line => chart
                        .draw_series(LineSeries::new(run, color.stroke_width(2)))
                        .map_err(draw_err)?,
                    SeriesStyle::Dashed => chart
                        .draw_series(DashedLineSeries::new(run, 7, 4, color.stroke_width(2)))
                        .map_err(draw_err)?,
                    SeriesStyle::Steps => {
                        let mut stairs = Vec::with_capacity(2 * run.len());
                        for (j, &(x, y)) in run.iter().enumerate() {
                            if j > 0 {
                                stairs.push((x, run[j - 1].1));
                            }
                            stairs.push((x, y));
                        }
                        chart
                            .draw_series(DashedLineSeries::new(stairs, 7, 4, color.stroke_width(2)))
                            .map_err(draw_err)?
                    }
                    SeriesStyle::Points => chart
                        .draw_series(
                            run.iter()
                                .map(|&(x, y)| Circle::new((x, y), 3, color.filled())),
                        )
                        .map_err(draw_err)?,
                };
                if first {
                    anno.label(s.label.as_str()).legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
                    });
                    first = false;
                    labelled = true;
                }
            }
        }
        if labelled {
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(RGBColor(180, 180, 180))
                .label_font(("sans-serif", 12))
                .position(SeriesLabelPosition::UpperRight)
                .draw()
                .map_err(draw_err)?;
        } else {
            chart
                .draw_series([Text::new(
                    "no data".to_string(),
                    (t0 + 0.45 * (t1 - t0), (lo + hi) / 2.0),
                    ("sans-serif", 14).into_font(),
                )])
                .map_err(draw_err)?;
        }
        Ok(())
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

    /// The figure as a PNG file's bytes.
    pub fn png(&self) -> Result<Vec<u8>, PlotError> {
        let (w, h) = self.size();
        let mut buf = vec![0u8; w as usize * h as usize * 3];
        {
            let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
            self.draw(root)?;
        }
        encode_png(&buf, w, h)
    }
}

/// The points split at non-finite values into runs of finite ones.
fn finite_runs(points: &[(f64, f64)]) -> Vec<Vec<(f64, f64)>> {
    let mut runs = vec![Vec::new()];
    for &(x, y) in points {
        if x.is_finite() && y.is_finite() {
            runs.last_mut().expect("never empty").push((x, y));
        } else if !runs.last().expect("never empty").is_empty() {
            runs.push(Vec::new());
        }
    }
    runs.retain(|r| !r.is_empty());
    runs
}

#[cfg(test)]
mod tests {
    use super::*;

    fn timeline() -> Timeline {
        Timeline {
            title: "screwdriver · dips · seed 3".into(),
            x_label: "time (s)".into(),
            panels: vec![
                TimePanel {
                    title: "object yaw".into(),
                    y_label: "yaw (rad)".into(),
                    series: vec![
                        Series {
                            label: "yaw".into(),
                            color: [31, 119, 180],
                            style: SeriesStyle::Line,
                            points: vec![(0.0, 0.0), (1.0, -0.1), (2.0, f64::NAN), (3.0, -0.5)],
                        },
                        Series {
                            label: "mode goal".into(),
                            color: [0, 0, 0],
                            style: SeriesStyle::Steps,
                            points: vec![(0.0, -0.52), (2.0, -1.04)],
                        },
                    ],
                },
                TimePanel {
                    title: "empty".into(),
                    y_label: "force (N)".into(),
                    series: vec![],
                },
            ],
            phases: vec![(0.0, "turn".into()), (2.0, "index regrasp".into())],
            panel_size: (700, 240),
        }
    }

    #[test]
    fn svg_names_every_panel_series_and_phase() {
        let svg = timeline().svg().unwrap();
        for text in [
            "screwdriver · dips · seed 3",
            "time (s)",
            "yaw (rad)",
            "force (N)",
            "mode goal",
            "index regrasp",
            "no data",
        ] {
            assert!(svg.contains(text), "missing {text}");
        }
    }

    #[test]
    fn non_finite_values_split_a_series() {
        let runs = finite_runs(&[(0.0, 1.0), (1.0, f64::NAN), (2.0, 2.0), (3.0, 3.0)]);
        assert_eq!(runs, vec![vec![(0.0, 1.0)], vec![(2.0, 2.0), (3.0, 3.0)]]);
    }

    #[test]
    fn png_has_the_stacked_size() {
        let t = timeline();
        let bytes = t.png().unwrap();
        let r = png::Decoder::new(std::io::Cursor::new(bytes))
            .read_info()
            .unwrap();
        let info = r.info();
        assert_eq!((info.width, info.height), (700, 34 + 2 * 240));
    }
}
