//! Self-contained HTML reports (no network, relative paths only) and the small formatting
//! helpers the `compare` and `sweep` pages share. Each report's folder also gets the studies
//! (docs/studies.md as of this build, [`write_studies`]) that its answer links to.

use std::fmt::Write;
use std::path::Path;

use pulldown_cmark::{Event, Options, Parser, Tag, TagEnd};

/// docs/studies.md as of this build: the measurements behind the answer.
const STUDIES_MD: &str = include_str!("../../docs/studies.md");

/// The studies page's name in a report's folder.
pub const STUDIES_HTML: &str = "studies.html";

/// A GitHub-style anchor for a heading: lower case, punctuation dropped, spaces to hyphens
/// (the anchors docs/studies.md's own contents use).
pub fn heading_anchor(text: &str) -> String {
    text.chars()
        .filter_map(|c| match c {
            ' ' => Some('-'),
            c if c.is_alphanumeric() || c == '-' || c == '_' => Some(c.to_ascii_lowercase()),
            _ => None,
        })
        .collect()
}

/// The studies as one HTML page: headings get the anchors the markdown's links use, and links
/// out of it (to the README, to docs/' other pages) become plain text, since the page lives in
/// a report's folder.
pub fn studies_page() -> String {
    let parser = || Parser::new_ext(STUDIES_MD, Options::ENABLE_TABLES);
    // Each heading's text, in order, for its anchor.
    let mut anchors = Vec::new();
    let mut heading: Option<String> = None;
    for event in parser() {
        match event {
            Event::Start(Tag::Heading { .. }) => heading = Some(String::new()),
            Event::Text(t) | Event::Code(t) => {
                if let Some(h) = heading.as_mut() {
                    h.push_str(&t);
                }
            }
            Event::End(TagEnd::Heading(_)) => {
                anchors.extend(heading.take().map(|h| heading_anchor(&h)));
            }
            _ => {}
        }
    }
    let mut anchors = anchors.into_iter();
    let mut outside_link = false;
    let events = parser().filter_map(|event| match event {
        Event::Start(Tag::Heading {
            level,
            classes,
            attrs,
            ..
        }) => Some(Event::Start(Tag::Heading {
            level,
            id: anchors.next().map(Into::into),
            classes,
            attrs,
        })),
        Event::Start(Tag::Link { ref dest_url, .. }) if leaves_the_report(dest_url) => {
            outside_link = true;
            None
        }
        Event::End(TagEnd::Link) if outside_link => {
            outside_link = false;
            None
        }
        other => Some(other),
    });
    // Prose tables: cells wrap, text reads from the left.
    let mut body = String::from(
        "<style>th, td { white-space: normal; text-align: left; } \
         th:first-child, td:first-child { white-space: nowrap; }</style>\n",
    );
    pulldown_cmark::html::push_html(&mut body, events);
    page("smokeshadow: the studies", &body, "")
}

/// Whether a link of docs/studies.md points out of a report's folder: up (the README) or to
/// another markdown page of docs/ (only the studies are copied into a report).
fn leaves_the_report(dest: &str) -> bool {
    let path = dest.split('#').next().unwrap_or_default();
    dest.starts_with("../") || (!path.is_empty() && !dest.contains("://") && path.ends_with(".md"))
}

/// Writes [`studies_page`] into a report's folder.
pub fn write_studies(dir: &Path) -> anyhow::Result<()> {
    crate::output::write_atomic(&dir.join(STUDIES_HTML), studies_page().as_bytes())
}

/// The paragraph every report carries under its answer: where the measurements behind it are.
pub fn studies_paragraph() -> String {
    format!(
        "<p class=\"muted\">What each technique keeps and how it errs, how the defaults were \
         tuned, and the studies behind this answer: <a href=\"{STUDIES_HTML}\">the studies</a> \
         (docs/studies.md as of this build; {}, {}).</p>\n",
        studies_link("The families side by side", "the families side by side"),
        studies_link("Equal bytes, tuned parameters", "equal bytes and tuning"),
    )
}

/// A link from a report in the same folder to a section of the studies page.
pub fn studies_link(section: &str, text: &str) -> String {
    format!(
        "<a href=\"{STUDIES_HTML}#{}\">{}</a>",
        heading_anchor(section),
        escape(text)
    )
}

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

pub use smokeshadow_core::gpu::memory::bytes;

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
    fn the_studies_page_resolves_its_own_contents_and_the_reports_links() {
        let html = studies_page();
        // Every in-page link of docs/studies.md (its contents) lands on a heading's anchor.
        let targets: Vec<&str> = STUDIES_MD
            .split("](#")
            .skip(1)
            .map(|rest| &rest[..rest.find(')').unwrap()])
            .collect();
        assert!(targets.len() >= 5, "{targets:?}");
        for anchor in targets.iter().copied().chain(
            ["The families side by side", "Equal bytes, tuned parameters"]
                .map(heading_anchor)
                .iter()
                .map(String::as_str),
        ) {
            assert!(
                html.contains(&format!("id=\"{anchor}\"")),
                "no heading with id {anchor}"
            );
        }
        assert!(
            html.contains("<table>") && html.contains("<td>"),
            "tables render"
        );
        assert!(
            !html.contains("href=\"../") && !html.contains(".md\"") && !html.contains(".md#"),
            "no link leaves the report's folder"
        );
        assert!(
            STUDIES_MD.contains("](sweeps.md#"),
            "a link to another page is tested"
        );
        assert_eq!(
            heading_anchor("Between slices, and where DOM's layers start"),
            "between-slices-and-where-doms-layers-start"
        );
    }

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
