//! A small RGB rasterizer (thick lines, circles, polygon outlines) and PNG encoding.

use super::{Drawing, Prim, Rgb, bounds};

struct Canvas {
    w: usize,
    h: usize,
    px: Vec<u8>,
}

impl Canvas {
    fn new(w: usize, h: usize) -> Canvas {
        Canvas {
            w,
            h,
            px: vec![255; w * h * 3],
        }
    }

    fn dot(&mut self, x: f64, y: f64, radius: f64, c: Rgb) {
        let r = radius.max(0.5);
        let (x0, x1) = ((x - r).floor() as i64, (x + r).ceil() as i64);
        let (y0, y1) = ((y - r).floor() as i64, (y + r).ceil() as i64);
        for yy in y0..=y1 {
            for xx in x0..=x1 {
                let (dx, dy) = (xx as f64 - x, yy as f64 - y);
                if dx * dx + dy * dy <= r * r
                    && xx >= 0
                    && yy >= 0
                    && (xx as usize) < self.w
                    && (yy as usize) < self.h
                {
                    let i = 3 * (yy as usize * self.w + xx as usize);
                    self.px[i..i + 3].copy_from_slice(&c);
                }
            }
        }
    }

    fn line(&mut self, a: (f64, f64), b: (f64, f64), width: f64, c: Rgb) {
        let len = ((b.0 - a.0).powi(2) + (b.1 - a.1).powi(2)).sqrt();
        let n = (len * 2.0).ceil().max(1.0) as usize;
        for k in 0..=n {
            let t = k as f64 / n as f64;
            self.dot(a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1), width / 2.0, c);
        }
    }
}

/// The drawing as PNG bytes.
pub(crate) fn to_png(d: &Drawing, px: u32) -> Result<Vec<u8>, String> {
    let p = px as usize;
    let mut cv = Canvas::new(p * d.panels.len().max(1), p);
    for (i, panel) in d.panels.iter().enumerate() {
        let (lo, hi) = bounds(&panel.prims);
        let pxf = f64::from(px);
        let scale = (pxf - 20.0) / (hi[0] - lo[0]).max(hi[1] - lo[1]);
        let ox = i as f64 * pxf + 10.0;
        let map = |q: [f64; 2]| {
            (
                ox + (q[0] - lo[0]) * scale,
                pxf - 10.0 - (q[1] - lo[1]) * scale,
            )
        };
        // Panel border.
        let x0 = i as f64 * pxf;
        let grey = [220, 220, 220];
        cv.line((x0, 0.0), (x0, pxf - 1.0), 1.0, grey);
        for prim in &panel.prims {
            match prim {
                Prim::Line { a, b, color, width } => cv.line(map(*a), map(*b), *width, *color),
                Prim::Circle { c, r, color, fill } => {
                    let (cx, cy) = map(*c);
                    let rr = r * scale;
                    if *fill {
                        cv.dot(cx, cy, rr, *color);
                    } else {
                        let n = ((rr * 6.0).ceil() as usize).max(12);
                        for k in 0..n {
                            let a0 = std::f64::consts::TAU * k as f64 / n as f64;
                            let a1 = std::f64::consts::TAU * (k + 1) as f64 / n as f64;
                            cv.line(
                                (cx + rr * a0.cos(), cy + rr * a0.sin()),
                                (cx + rr * a1.cos(), cy + rr * a1.sin()),
                                1.0,
                                *color,
                            );
                        }
                    }
                }
                Prim::Polygon { pts, color } => {
                    for k in 0..pts.len() {
                        cv.line(map(pts[k]), map(pts[(k + 1) % pts.len()]), 1.5, *color);
                    }
                }
            }
        }
    }
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, cv.w as u32, cv.h as u32);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut writer = enc.write_header().map_err(|e| e.to_string())?;
        writer.write_image_data(&cv.px).map_err(|e| e.to_string())?;
        writer.finish().map_err(|e| e.to_string())?;
    }
    Ok(out)
}
