//! Self-contained HTML pages: inline style, no network; images and links point only at
//! files beside the page (relative paths), so the directory can be copied or opened anywhere.
//! The only script is an episode's 3D view ([`crate::scene3d`]), inlined whole.

use std::fmt::Write;

/// Escape text for HTML.
pub fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// A table cell: text, or text linking to a relative path.
#[derive(Debug, Clone, PartialEq)]
pub enum Cell {
    /// Plain text.
    Text(String),
    /// A link: text and relative target.
    Link(String, String),
}

impl From<String> for Cell {
    fn from(s: String) -> Self {
        Cell::Text(s)
    }
}

impl From<&str> for Cell {
    fn from(s: &str) -> Self {
        Cell::Text(s.to_string())
    }
}

const STYLE: &str = "body{font-family:'DejaVu Sans',Arial,sans-serif;margin:24px auto;max-width:1280px;\
color:#222;padding:0 16px}h1{font-size:24px}h2{font-size:19px;margin-top:28px;border-bottom:1px solid #ddd}\
h3{font-size:16px}table{border-collapse:collapse;margin:8px 0}td,th{border:1px solid #ccc;\
padding:4px 8px;font-size:13px;text-align:left;vertical-align:top}th{background:#f3f3f3}\
img{max-width:100%;border:1px solid #eee;margin:6px 0;display:block}p.note{color:#555;font-size:13px}\
nav a{margin-right:12px}.scene3d-view{width:100%;border:1px solid #ddd;min-height:120px}\
.scene3d-view canvas{display:block}.scene3d-controls{display:flex;gap:8px;align-items:center;margin:6px 0}\
.scene3d-controls input{flex:1}p.scene3d-label{font-size:13px;margin:4px 0}";

/// A page being built, section by section.
#[derive(Debug, Clone)]
pub struct Page {
    title: String,
    body: String,
}

impl Page {
    /// A page with a title (also its first heading).
    pub fn new(title: &str) -> Self {
        Self {
            title: title.to_string(),
            body: format!("<h1>{}</h1>\n", escape(title)),
        }
    }

    /// A section heading (`level` 2 or 3) with an anchor id.
    pub fn heading(&mut self, level: u8, id: &str, text: &str) -> &mut Self {
        let l = level.clamp(2, 4);
        let _ = writeln!(
            self.body,
            "<h{l} id=\"{}\">{}</h{l}>",
            escape(id),
            escape(text)
        );
        self
    }

    /// A paragraph of text.
    pub fn paragraph(&mut self, text: &str) -> &mut Self {
        let _ = writeln!(self.body, "<p>{}</p>", escape(text));
        self
    }

    /// A smaller, greyed note.
    pub fn note(&mut self, text: &str) -> &mut Self {
        let _ = writeln!(self.body, "<p class=\"note\">{}</p>", escape(text));
        self
    }

    /// Links in one line (text, relative target).
    pub fn links(&mut self, links: &[(String, String)]) -> &mut Self {
        self.body.push_str("<nav>");
        for (text, target) in links {
            let _ = write!(
                self.body,
                "<a href=\"{}\">{}</a>",
                escape(target),
                escape(text)
            );
        }
        self.body.push_str("</nav>\n");
        self
    }

    /// An image beside the page, with its alternative text.
    pub fn image(&mut self, src: &str, alt: &str) -> &mut Self {
        let _ = writeln!(
            self.body,
            "<img src=\"{}\" alt=\"{}\" loading=\"lazy\">",
            escape(src),
            escape(alt)
        );
        self
    }

    /// Markup written as it is: only for markup this crate builds (e.g.
    /// [`crate::scene3d::scene_html`]), never for outside text.
    pub fn raw(&mut self, markup: &str) -> &mut Self {
        self.body.push_str(markup);
        self
    }

    /// A table with a header row.
    pub fn table(&mut self, header: &[&str], rows: &[Vec<Cell>]) -> &mut Self {
        self.body.push_str("<table><thead><tr>");
        for h in header {
            let _ = write!(self.body, "<th>{}</th>", escape(h));
        }
        self.body.push_str("</tr></thead><tbody>\n");
        for row in rows {
            self.body.push_str("<tr>");
            for c in row {
                match c {
                    Cell::Text(t) => {
                        let _ = write!(self.body, "<td>{}</td>", escape(t));
                    }
                    Cell::Link(t, href) => {
                        let _ = write!(
                            self.body,
                            "<td><a href=\"{}\">{}</a></td>",
                            escape(href),
                            escape(t)
                        );
                    }
                }
            }
            self.body.push_str("</tr>\n");
        }
        self.body.push_str("</tbody></table>\n");
        self
    }

    /// The whole document.
    pub fn render(&self) -> String {
        format!(
            "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
             <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n\
             <title>{}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n{}</body>\n</html>\n",
            escape(&self.title),
            self.body
        )
    }
}

/// Every `src` and `href` target in a page, unescaped, in order.
pub fn referenced_files(html: &str) -> Vec<String> {
    let mut out = Vec::new();
    for attr in ["src=\"", "href=\""] {
        let mut rest = html;
        while let Some(i) = rest.find(attr) {
            rest = &rest[i + attr.len()..];
            if let Some(j) = rest.find('"') {
                out.push(
                    rest[..j]
                        .replace("&quot;", "\"")
                        .replace("&#39;", "'")
                        .replace("&lt;", "<")
                        .replace("&gt;", ">")
                        .replace("&amp;", "&"),
                );
                rest = &rest[j..];
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_is_escaped_and_references_are_found() {
        let mut p = Page::new("a <b> & c");
        p.image("x y/épisode.gif", "alt \"q\"")
            .table(
                &["k"],
                &[vec![Cell::Link("r".into(), "d/result.json".into())]],
            )
            .links(&[("t".into(), "a&b.svg".into())]);
        let html = p.render();
        assert!(html.contains("<title>a &lt;b&gt; &amp; c</title>"));
        assert!(!html.contains("http"), "no network reference");
        assert_eq!(
            referenced_files(&html),
            vec!["x y/épisode.gif", "d/result.json", "a&b.svg"]
        );
    }
}
