//! Box plots of per-trial outcomes (the paper's Fig. 4–5).

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::{PALETTE, PlotError, draw_err, encode_png, font_ready};

/// Tukey's box: quartiles (linear interpolation) and whiskers at the furthest values within
/// 1.5 IQR of the box.
#[derive(Debug, Clone, Copy, PartialEq)]
struct BoxStats {
    low: f64,
    q1: f64,
    median: f64,
    q3: f64,
    high: f64,
}

impl BoxStats {
    fn of(values: &[f64]) -> Self {
        let mut v = values.to_vec();
        v.sort_by(f64::total_cmp);
        let q = |p: f64| {
            let pos = p * (v.len() - 1) as f64;
            let i = pos.floor() as usize;
            let next = v[(i + 1).min(v.len() - 1)];
            v[i] + (pos - pos.floor()) * (next - v[i])
        };
        let (q1, median, q3) = (q(0.25), q(0.5), q(0.75));
        let iqr = q3 - q1;
        let low = v
            .iter()
            .copied()
            .find(|&x| x >= q1 - 1.5 * iqr)
            .unwrap_or(q1);
        let high = v
            .iter()
            .rev()
            .copied()
            .find(|&x| x <= q3 + 1.5 * iqr)
            .unwrap_or(q3);
        Self {
            low,
            q1,
            median,
            q3,
            high,
        }
    }
}

/// Series with fewer values than this are drawn as a strip plot (their points and a median
/// tick, no box): quartiles and whiskers of two or three trials would suggest a spread that
/// was never measured.
pub(crate) const STRIP_BELOW: usize = 5;

/// One box of a box plot: a label and its values (one per trial).
#[derive(Debug, Clone, PartialEq)]
pub struct BoxSeries {
    /// Category label (x axis).
    pub label: String,
    /// The values; non-finite ones are left out.
    pub values: Vec<f64>,
}

/// A box plot with each trial drawn as a dot over its box; a series with fewer than
/// five values (`STRIP_BELOW`) is drawn as a strip plot (the dots and a median tick only).
#[derive(Debug, Clone, PartialEq)]
pub struct BoxPlot {
    /// Title above the plot.
    pub title: String,
    /// Label of the category axis.
    pub x_label: String,
    /// Label of the value axis, with units.
    pub y_label: String,
    /// The boxes, left to right.
    pub series: Vec<BoxSeries>,
    /// A horizontal reference line (value, legend text), e.g. the goal.
    pub reference: Option<(f64, String)>,
    /// Size in pixels (width, height).
    pub size: (u32, u32),
}

impl BoxPlot {
    fn value_range(&self) -> Result<(f32, f32), PlotError> {
        let mut lo = f64::INFINITY;
        let mut hi = f64::NEG_INFINITY;
        let values = self
            .series
            .iter()
            .flat_map(|s| s.values.iter())
            .chain(self.reference.iter().map(|r| &r.0));
        for &v in values.filter(|v| v.is_finite()) {
            lo = lo.min(v);
            hi = hi.max(v);
        }
        if !lo.is_finite() {
            return Err(PlotError::Empty("no finite value in any box"));
        }
        let pad = ((hi - lo) * 0.08).max(1e-3);
        Ok(((lo - pad) as f32, (hi + pad) as f32))
    }

    fn draw<DB: DrawingBackend>(&self, root: DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        font_ready()?;
        if self.series.is_empty() {
            return Err(PlotError::Empty("no boxes"));
        }
        let (lo, hi) = self.value_range()?;
        // Room above the boxes for the reference's legend (upper right), so it covers no trial.
        let hi = if self.reference.is_some() {
            hi + 0.12 * (hi - lo)
        } else {
            hi
        };
        root.fill(&WHITE).map_err(draw_err)?;
        let n = self.series.len();
        let labels: Vec<&str> = self.series.iter().map(|s| s.label.as_str()).collect();
        let x_range = -0.5f32..n as f32 - 0.5;
        let mut chart = ChartBuilder::on(&root)
            .caption(&self.title, ("sans-serif", 22))
            .margin(16)
            .x_label_area_size(48)
            .y_label_area_size(72)
            .build_cartesian_2d(x_range.clone(), lo..hi)
            .map_err(draw_err)?;
        let name = |x: &f32| {
            let i = x.round();
            if (x - i).abs() < 1e-3 && i >= 0.0 && (i as usize) < n {
                labels[i as usize].to_string()
            } else {
                String::new()
            }
        };
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(n)
            .x_label_formatter(&name)
            .x_desc(&self.x_label)
            .y_desc(&self.y_label)
            .label_style(("sans-serif", 14))
            .axis_desc_style(("sans-serif", 16))
            .draw()
            .map_err(draw_err)?;
        for (i, s) in self.series.iter().enumerate() {
            let finite: Vec<f64> = s.values.iter().copied().filter(|v| v.is_finite()).collect();
            if finite.is_empty() {
                continue;
            }
            let color = PALETTE[i % PALETTE.len()];
            let style = color.stroke_width(2);
            let b = BoxStats::of(&finite);
            let x = i as f32;
            let (w, cap) = (0.18f32, 0.09f32);
            let y = |v: f64| v as f32;
            let strip = finite.len() < STRIP_BELOW;
            if strip {
                chart
                    .draw_series([PathElement::new(
                        [(x - w, y(b.median)), (x + w, y(b.median))],
                        color.mix(0.6).stroke_width(1),
                    )])
                    .map_err(draw_err)?;
            }
            if !strip {
                chart
                    .draw_series([Rectangle::new([(x - w, y(b.q1)), (x + w, y(b.q3))], style)])
                    .map_err(draw_err)?;
                chart
                    .draw_series([
                        // The median, the whiskers to the furthest trial within 1.5 IQR, their caps.
                        PathElement::new([(x - w, y(b.median)), (x + w, y(b.median))], style),
                        PathElement::new([(x, y(b.q3)), (x, y(b.high))], color.stroke_width(1)),
                        PathElement::new([(x, y(b.q1)), (x, y(b.low))], color.stroke_width(1)),
                        PathElement::new([(x - cap, y(b.high)), (x + cap, y(b.high))], style),
                        PathElement::new([(x - cap, y(b.low)), (x + cap, y(b.low))], style),
                    ])
                    .map_err(draw_err)?;
            }
            // Trials as dots, spread across the box so equal values stay visible.
            let m = finite.len();
            chart
                .draw_series(finite.iter().enumerate().map(|(j, &v)| {
                    let dx = if m > 1 {
                        (j as f32 / (m - 1) as f32 - 0.5) * 1.6 * w
                    } else {
                        0.0
                    };
                    Circle::new((x + dx, y(v)), 3, color.mix(0.7).filled())
                }))
                .map_err(draw_err)?;
        }
        if let Some((value, text)) = &self.reference {
            chart
                .draw_series(DashedLineSeries::new(
                    [(x_range.start, *value as f32), (x_range.end, *value as f32)],
                    8,
                    5,
                    BLACK.stroke_width(1),
                ))
                .map_err(draw_err)?
                .label(text.as_str())
                .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], BLACK));
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .label_font(("sans-serif", 14))
                .position(SeriesLabelPosition::UpperRight)
                .draw()
                .map_err(draw_err)?;
        }
        root.present().map_err(draw_err)
    }

    /// The plot as an SVG document.
    pub fn svg(&self) -> Result<String, PlotError> {
        let mut out = String::new();
        {
            let root = SVGBackend::with_string(&mut out, self.size).into_drawing_area();
            self.draw(root)?;
        }
        Ok(out)
    }

    /// The plot as a PNG file's bytes.
    pub fn png(&self) -> Result<Vec<u8>, PlotError> {
        let (w, h) = self.size;
        let mut rgb = vec![0u8; w as usize * h as usize * 3];
        {
            let root = BitMapBackend::with_buffer(&mut rgb, self.size).into_drawing_area();
            self.draw(root)?;
        }
        encode_png(&rgb, w, h)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::PlotError;

    fn plot() -> BoxPlot {
        BoxPlot {
            title: "Card: distance to goal".into(),
            x_label: "method".into(),
            y_label: "distance (cm)".into(),
            series: vec![
                BoxSeries {
                    label: "dips".into(),
                    values: vec![0.4, 0.6, 0.5, 1.2],
                },
                BoxSeries {
                    label: "csvto-sampled".into(),
                    values: vec![2.0, 4.5, f64::NAN, 3.0],
                },
            ],
            reference: Some((0.0, "goal".into())),
            size: (640, 400),
        }
    }

    #[test]
    fn svg_has_title_axes_and_labels() {
        let svg = plot().svg().unwrap();
        for text in [
            "Card: distance to goal",
            "distance (cm)",
            "method",
            "dips",
            "csvto-sampled",
            "goal",
        ] {
            assert!(svg.contains(text), "missing {text}");
        }
    }

    #[test]
    fn png_is_a_png_of_the_size_with_ink() {
        let bytes = plot().png().unwrap();
        let dec = png::Decoder::new(std::io::Cursor::new(bytes));
        let mut r = dec.read_info().unwrap();
        let mut buf = vec![0; r.output_buffer_size().unwrap()];
        let info = r.next_frame(&mut buf).unwrap();
        assert_eq!((info.width, info.height), (640, 400));
        let dark = buf.chunks(3).filter(|p| p.iter().all(|&c| c < 80)).count();
        assert!(dark > 500, "only {dark} dark pixels: no text or axes drawn");
    }

    #[test]
    fn fewer_than_five_trials_are_a_strip_plot_without_a_box() {
        let rects = |values: Vec<f64>| {
            let mut p = plot();
            p.reference = None;
            p.series = vec![BoxSeries {
                label: "dips".into(),
                values,
            }];
            p.svg().unwrap().matches("<rect").count()
        };
        let boxed = rects(vec![1.0, 2.0, 3.0, 4.0, 5.0]);
        assert_eq!(rects(vec![2.21, 1.89]), boxed - 1, "two trials: no box");
        assert_eq!(rects(vec![1.0, 2.0, 3.0, 4.0]), boxed - 1, "four: no box");
    }

    #[test]
    fn whiskers_stop_at_the_furthest_trial_within_the_fences() {
        let b = BoxStats::of(&[1.0, 2.0, 3.0, 4.0, 100.0]);
        assert_eq!((b.q1, b.median, b.q3), (2.0, 3.0, 4.0));
        assert_eq!((b.low, b.high), (1.0, 4.0));
        let one = BoxStats::of(&[5.0]);
        assert_eq!(
            (one.low, one.q1, one.median, one.q3, one.high),
            (5.0, 5.0, 5.0, 5.0, 5.0)
        );
    }

    #[test]
    fn empty_plots_are_errors() {
        let mut p = plot();
        p.series.clear();
        assert!(matches!(p.svg(), Err(PlotError::Empty(_))));
        p.series.push(BoxSeries {
            label: "x".into(),
            values: vec![f64::NAN],
        });
        p.reference = None;
        assert!(matches!(p.png(), Err(PlotError::Empty(_))));
    }
}
