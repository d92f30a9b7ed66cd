//! Writing without panicking: `println!` and `eprintln!` panic when their stream is a closed
//! pipe (`dips … 2>&1 | head -1`, quitting `less`) or a full disk. Results on stdout go through
//! [`line()`], which returns the error (the binary turns a closed pipe into a quiet exit); notes
//! and progress on stderr go through [`note()`], which drops them, so the work and its files
//! complete whatever became of the stream.

use std::io::Write;

/// Write `text` and a newline to stdout and flush.
pub fn line(text: &str) -> anyhow::Result<()> {
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())
        .and_then(|()| out.write_all(b"\n"))
        .and_then(|()| out.flush())
        .map_err(|e| anyhow::Error::new(e).context("cannot write to stdout"))
}

/// Write `text` and a newline to stderr for a person watching; errors are ignored (a closed
/// or full stderr must not stop the work, nor lose what it writes to files).
pub fn note(text: &str) {
    let mut err = std::io::stderr().lock();
    let _ = err
        .write_all(format!("{text}\n").as_bytes())
        .and_then(|()| err.flush());
}

/// `eprintln!` that never panics: [`note()`] of the `format!` arguments.
#[macro_export]
macro_rules! note {
    ($($arg:tt)*) => {
        $crate::output::note(&format!($($arg)*))
    };
}

/// `e` and its causes joined by `: ` as `{e:#}` writes them, each in the command line's words
/// ([`crate::words::of`]: flags where the libraries name settings), without a cause that the
/// message before it already ends with (errors such as `{path}: {source}` that also name their
/// source would otherwise print it twice: "No such file or directory (os error 2): No such file
/// or directory (os error 2)").
pub fn causes(e: &anyhow::Error) -> String {
    let mut text = String::new();
    for cause in e.chain() {
        let c = crate::words::of(cause).unwrap_or_else(|| cause.to_string());
        if text.is_empty() {
            text = c;
        } else if !text.ends_with(&c) {
            text.push_str(": ");
            text.push_str(&c);
        }
    }
    text
}

/// Whether `e` is (caused by) a closed pipe.
pub fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

/// Print a command's figures: JSON with `--json` (`json`), else the same figures as indented
/// `key: value` lines for a person (numbers as JSON writes them, short lists of scalars on one
/// line).
pub fn figures(json: bool, value: &serde_json::Value) -> anyhow::Result<()> {
    if json {
        return line(&serde_json::to_string_pretty(value)?);
    }
    let mut text = String::new();
    readable(value, 0, &mut text);
    line(text.trim_end_matches('\n'))
}

/// Whether `v` prints on one line.
fn scalar(v: &serde_json::Value) -> bool {
    !v.is_object() && !v.is_array()
}

fn readable(value: &serde_json::Value, depth: usize, out: &mut String) {
    let pad = "  ".repeat(depth);
    match value {
        serde_json::Value::Object(map) => {
            for (k, v) in map {
                match v {
                    serde_json::Value::Array(items)
                        if items.iter().all(scalar) && items.len() <= 16 =>
                    {
                        let list: Vec<String> = items.iter().map(one_line).collect();
                        out.push_str(&format!("{pad}{k}: [{}]\n", list.join(", ")));
                    }
                    v if scalar(v) => out.push_str(&format!("{pad}{k}: {}\n", one_line(v))),
                    v => {
                        out.push_str(&format!("{pad}{k}:\n"));
                        readable(v, depth + 1, out);
                    }
                }
            }
        }
        serde_json::Value::Array(items) => {
            for (i, v) in items.iter().enumerate() {
                if scalar(v) {
                    out.push_str(&format!("{pad}- {}\n", one_line(v)));
                } else {
                    out.push_str(&format!("{pad}- [{i}]\n"));
                    readable(v, depth + 1, out);
                }
            }
        }
        v => out.push_str(&format!("{pad}{}\n", one_line(v))),
    }
}

/// A scalar as text: strings without quotes, everything else as JSON writes it.
fn one_line(v: &serde_json::Value) -> String {
    match v {
        serde_json::Value::String(s) => s.clone(),
        v => v.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn readable_figures_name_every_value() {
        let v = serde_json::json!({
            "bench": "search",
            "settings": {"k": 16, "depth": 7},
            "calls": [{"seconds": 0.5, "modes": ["turn", "index-regrasp"]}],
            "p": [1, 2.5]
        });
        let mut text = String::new();
        readable(&v, 0, &mut text);
        assert_eq!(
            text,
            "bench: search\ncalls:\n  - [0]\n    modes: [turn, index-regrasp]\n    seconds: 0.5\n\
             p: [1, 2.5]\nsettings:\n  depth: 7\n  k: 16\n"
        );
    }
}
