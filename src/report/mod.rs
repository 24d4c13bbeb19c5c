//! Self-contained HTML reports (no network, relative paths only) and the small formatting
//! helpers the `compare` and `sweep` pages share.

use std::fmt::Write;

/// Escapes text for HTML element content and attribute values.
pub fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
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

/// Bytes as a short human figure (binary units: 12.0 MiB).
pub fn bytes(n: u64) -> String {
    const UNITS: [&str; 4] = ["B", "KiB", "MiB", "GiB"];
    let mut value = n as f64;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < UNITS.len() {
        value /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{n} B")
    } else {
        format!("{value:.1} {}", UNITS[unit])
    }
}

/// A whole page: `title`, the shared style, `body` (already HTML) and an optional script.
pub fn page(title: &str, body: &str, script: &str) -> String {
    let mut out = String::new();
    let _ = write!(
        out,
        "<!doctype html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n\
         <title>{}</title>\n<style>\n{STYLE}</style>\n</head>\n<body>\n{body}\n",
        escape(title)
    );
    if !script.is_empty() {
        let _ = write!(out, "<script>\n{script}\n</script>\n");
    }
    out.push_str("</body>\n</html>\n");
    out
}

const STYLE: &str = "\
body { font: 14px/1.45 system-ui, sans-serif; margin: 24px auto; max-width: 1400px; padding: 0 16px; color: #1c1e21; }
h1 { font-size: 22px; } h2 { font-size: 18px; margin-top: 32px; }
table { border-collapse: collapse; margin: 8px 0 16px; }
th, td { padding: 3px 9px; border-bottom: 1px solid #ddd; text-align: right; white-space: nowrap; }
th:first-child, td:first-child { text-align: left; }
th { background: #f3f4f6; position: sticky; top: 0; }
td.best { background: #d9f2dc; font-weight: 600; }
.muted { color: #6b7280; }
.grid { display: grid; gap: 10px; align-items: start; }
.grid figure { margin: 0; }
.grid img { width: 100%; height: auto; display: block; border: 1px solid #ccc; image-rendering: auto; }
.grid figcaption { font-size: 12px; color: #374151; margin-top: 2px; }
.rowhead { font-weight: 600; padding-top: 40px; }
.toolbar { position: sticky; top: 0; background: #fff; padding: 6px 0; z-index: 2; border-bottom: 1px solid #eee; }
.toolbar button { margin-right: 6px; padding: 4px 10px; border: 1px solid #bbb; border-radius: 4px; background: #fafafa; cursor: pointer; }
.toolbar button.on { background: #1d4ed8; color: #fff; border-color: #1d4ed8; }
";

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escapes_markup_and_formats_bytes() {
        assert_eq!(
            escape("<a href=\"x\">&'"),
            "&lt;a href=&quot;x&quot;&gt;&amp;&#39;"
        );
        assert_eq!(bytes(512), "512 B");
        assert_eq!(bytes(12_582_944), "12.0 MiB");
        let html = page("t<1>", "<p>x</p>", "");
        assert!(html.contains("<title>t&lt;1&gt;</title>") && !html.contains("<script"));
    }
}
