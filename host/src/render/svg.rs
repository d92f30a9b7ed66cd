//! SVG output, written by hand.

use std::fmt::Write;

use super::{Drawing, Prim, Rgb, bounds};

fn color(c: Rgb) -> String {
    format!("rgb({},{},{})", c[0], c[1], c[2])
}

/// The drawing as an SVG document.
pub(crate) fn to_svg(d: &Drawing, px: u32) -> String {
    let px = f64::from(px);
    let head = 28.0;
    let width = px * d.panels.len() as f64;
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{h}" viewBox="0 0 {width} {h}">"#,
        h = px + head
    );
    let _ = writeln!(s, r#"<rect width="100%" height="100%" fill="white"/>"#);
    let _ = writeln!(
        s,
        r#"<text x="6" y="18" font-family="sans-serif" font-size="14">{}</text>"#,
        escape(&d.heading)
    );
    for (i, panel) in d.panels.iter().enumerate() {
        let (lo, hi) = bounds(&panel.prims);
        let scale = (px - 20.0) / (hi[0] - lo[0]).max(hi[1] - lo[1]);
        let ox = i as f64 * px + 10.0;
        let oy = head;
        let map = |p: [f64; 2]| {
            (
                ox + (p[0] - lo[0]) * scale,
                oy + px - 10.0 - (p[1] - lo[1]) * scale,
            )
        };
        let _ = writeln!(
            s,
            r#"<g><rect x="{}" y="{oy}" width="{px}" height="{px}" fill="none" stroke="rgb(220,220,220)"/>"#,
            i as f64 * px
        );
        let _ = writeln!(
            s,
            r#"<text x="{}" y="{}" font-family="sans-serif" font-size="12">{}</text>"#,
            ox,
            oy + 14.0,
            escape(&panel.title)
        );
        for prim in &panel.prims {
            match prim {
                Prim::Line {
                    a,
                    b,
                    color: c,
                    width,
                } => {
                    let (x1, y1) = map(*a);
                    let (x2, y2) = map(*b);
                    let _ = writeln!(
                        s,
                        r#"<line x1="{x1:.2}" y1="{y1:.2}" x2="{x2:.2}" y2="{y2:.2}" stroke="{}" stroke-width="{width}" stroke-linecap="round"/>"#,
                        color(*c)
                    );
                }
                Prim::Circle {
                    c,
                    r,
                    color: col,
                    fill,
                } => {
                    let (cx, cy) = map(*c);
                    let fill = if *fill { color(*col) } else { "none".into() };
                    let _ = writeln!(
                        s,
                        r#"<circle cx="{cx:.2}" cy="{cy:.2}" r="{:.2}" stroke="{}" fill="{fill}"/>"#,
                        r * scale,
                        color(*col)
                    );
                }
                Prim::Polygon { pts, color: c } => {
                    let pts: Vec<String> = pts
                        .iter()
                        .map(|p| {
                            let (x, y) = map(*p);
                            format!("{x:.2},{y:.2}")
                        })
                        .collect();
                    let _ = writeln!(
                        s,
                        r#"<polygon points="{}" stroke="{}" fill="none"/>"#,
                        pts.join(" "),
                        color(*c)
                    );
                }
            }
        }
        let _ = writeln!(s, "</g>");
    }
    let _ = writeln!(s, "</svg>");
    s
}

fn escape(t: &str) -> String {
    t.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}
