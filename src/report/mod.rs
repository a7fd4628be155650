//! One self-contained `report.html`: inline SVG figures, inline CSS, no script, no network.
//!
//! A `Report` holds a title, an introduction and numbered sections; each section holds blocks
//! in order: paragraphs, "headline" key–value boxes, tables (numbers right-aligned), figures with
//! captions. The output is HTML5 that is also well-formed XML (every element closed, only the
//! five XML entities), with a table of contents linking to the sections. All text is escaped;
//! figures must be SVG text from [`crate::plot`] (anything else is replaced by a notice).
//! `story` tells the whole story (the built-in drive, or a user's log) as one report: it
//! computes a run (`run`, no HTML), writes its files and assembles the page from the
//! `sections` the demo and the data report share.
//!
//! The public entry points are [`data_report`] (a user's log) and [`demo_report`] (the built-in
//! drive); the HTML builder itself is internal.

pub(crate) mod run;
pub(crate) mod sections;
pub(crate) mod story;

use std::fmt::Write;
use std::path::Path;

use crate::io::{OutputError, write_string_atomic};
use crate::plot::svg::{esc, fmt_num};

// The namespace's public items that live in its submodules (the crate root keeps only the
// names most users need; see `biasctl::prelude`).
pub use run::{
    DataRun, DemoRun, DiagnosedRun, MAX_SEEKS, PaperRobustWhy, ScoredModel, SettleRun, StoryError,
    compute_data, compute_demo,
};
pub use story::{
    CheckedStoryOptions, Progress, StoryOptions, StoryOutcome, data_report, demo_report,
};

/// A table cell: text (left-aligned) or a number (right-aligned, compact format).
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Cell {
    /// Text, left-aligned.
    Text(String),
    /// A number, right-aligned; non-finite values show as "n/a".
    Number(f64),
    /// A number with exactly this many decimals, right-aligned.
    Fixed(f64, usize),
}

impl From<&str> for Cell {
    fn from(s: &str) -> Self {
        Cell::Text(s.to_string())
    }
}

impl From<String> for Cell {
    fn from(s: String) -> Self {
        Cell::Text(s)
    }
}

impl From<f64> for Cell {
    fn from(x: f64) -> Self {
        Cell::Number(x)
    }
}

impl From<usize> for Cell {
    fn from(x: usize) -> Self {
        Cell::Number(x as f64)
    }
}

/// A table with a header row.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Table {
    /// Column headings.
    pub header: Vec<String>,
    /// Rows of cells (short rows are padded with empty cells).
    pub rows: Vec<Vec<Cell>>,
    /// Caption shown above the table (may be empty).
    pub caption: String,
}

impl Table {
    /// A table with these column headings and no rows.
    pub(crate) fn new(header: &[&str]) -> Self {
        Table {
            header: header.iter().map(|s| s.to_string()).collect(),
            rows: Vec::new(),
            caption: String::new(),
        }
    }

    /// Adds a row.
    pub(crate) fn row(mut self, cells: Vec<Cell>) -> Self {
        self.rows.push(cells);
        self
    }

    /// Sets the caption.
    pub(crate) fn caption(mut self, caption: impl Into<String>) -> Self {
        self.caption = caption.into();
        self
    }
}

/// One block of a section.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Block {
    /// A paragraph of plain text.
    Paragraph(String),
    /// Key–value boxes for the headline numbers.
    Headline(Vec<(String, String)>),
    /// A table.
    Table(Table),
    /// An inline SVG figure with its caption.
    Figure {
        /// SVG text from [`crate::plot`].
        svg: String,
        /// Caption (plain text).
        caption: String,
    },
}

/// A section: a heading and its blocks.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Section {
    /// The heading.
    pub heading: String,
    /// The blocks, in order.
    pub blocks: Vec<Block>,
}

impl Section {
    /// Adds a paragraph.
    pub(crate) fn paragraph(&mut self, text: impl Into<String>) -> &mut Self {
        self.blocks.push(Block::Paragraph(text.into()));
        self
    }

    /// Adds headline boxes `(key, value)`.
    pub(crate) fn headline<K: AsRef<str>, V: AsRef<str>>(&mut self, items: &[(K, V)]) -> &mut Self {
        self.blocks.push(Block::Headline(
            items
                .iter()
                .map(|(k, v)| (k.as_ref().to_string(), v.as_ref().to_string()))
                .collect(),
        ));
        self
    }

    /// Adds a table.
    pub(crate) fn table(&mut self, table: Table) -> &mut Self {
        self.blocks.push(Block::Table(table));
        self
    }

    /// Adds a figure: SVG text from [`crate::plot`] and a caption.
    pub(crate) fn figure(
        &mut self,
        svg: impl Into<String>,
        caption: impl Into<String>,
    ) -> &mut Self {
        self.blocks.push(Block::Figure {
            svg: svg.into(),
            caption: caption.into(),
        });
        self
    }
}

/// The report: title, introduction, sections.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Report {
    /// Title (the `<title>` and the top heading).
    pub title: String,
    /// Introductory paragraphs before the table of contents.
    pub intro: Vec<String>,
    /// Sections, numbered in order.
    pub sections: Vec<Section>,
}

const CSS: &str = "\
body{font-family:sans-serif;max-width:72rem;margin:2rem auto;padding:0 1rem;color:#222;line-height:1.45}
h1{font-size:1.7rem;margin-bottom:.3rem}h2{font-size:1.3rem;border-bottom:1px solid #ccc;padding-bottom:.2rem;margin-top:2.2rem}
nav ol{padding-left:1.4rem}nav a{color:#0b5394}
.headline{display:flex;flex-wrap:wrap;gap:.8rem;margin:1rem 0}
.headline div{border:1px solid #bcd;border-radius:6px;padding:.5rem .9rem;background:#f3f8fc;min-width:9rem}
.headline .key{font-size:.8rem;color:#555}.headline .value{font-size:1.3rem;font-weight:bold}
table{border-collapse:collapse;margin:1rem 0}caption{text-align:left;font-weight:bold;padding-bottom:.3rem}
th,td{border:1px solid #ccc;padding:.25rem .6rem}th{background:#f0f0f0;text-align:left}
td.num{text-align:right;font-variant-numeric:tabular-nums}
figure{margin:1.2rem 0}figure svg{max-width:100%;height:auto}figcaption{font-size:.9rem;color:#444;margin-top:.3rem}
pre{background:#f6f6f6;padding:.6rem;overflow-x:auto}
";

impl Report {
    /// An empty report with a title.
    pub(crate) fn new(title: impl Into<String>) -> Self {
        Report {
            title: title.into(),
            ..Default::default()
        }
    }

    /// Adds an introductory paragraph.
    pub(crate) fn intro(&mut self, text: impl Into<String>) -> &mut Self {
        self.intro.push(text.into());
        self
    }

    /// Starts a new section and returns it for adding blocks.
    pub(crate) fn section(&mut self, heading: impl Into<String>) -> &mut Section {
        self.sections.push(Section {
            heading: heading.into(),
            blocks: Vec::new(),
        });
        let last = self.sections.len() - 1;
        &mut self.sections[last]
    }

    /// Renders the whole document.
    pub(crate) fn to_html(&self) -> String {
        let mut h = String::new();
        let title = esc(&self.title);
        let _ = write!(
            h,
            "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\"/>\n\
             <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\"/>\n\
             <title>{title}</title>\n<style>\n{CSS}</style>\n</head>\n<body>\n<h1>{title}</h1>\n"
        );
        for p in &self.intro {
            let _ = writeln!(h, "<p>{}</p>", esc(p));
        }
        if !self.sections.is_empty() {
            h.push_str("<nav>\n<h2>Contents</h2>\n<ol>\n");
            for (i, s) in self.sections.iter().enumerate() {
                let _ = writeln!(
                    h,
                    "<li><a href=\"#section-{}\">{}</a></li>",
                    i + 1,
                    esc(&s.heading)
                );
            }
            h.push_str("</ol>\n</nav>\n");
        }
        let mut figure_no = 0;
        for (i, s) in self.sections.iter().enumerate() {
            let _ = writeln!(
                h,
                "<section id=\"section-{n}\">\n<h2>{n}. {}</h2>",
                esc(&s.heading),
                n = i + 1
            );
            for b in &s.blocks {
                render_block(&mut h, b, &mut figure_no);
            }
            h.push_str("</section>\n");
        }
        h.push_str("</body>\n</html>\n");
        h
    }

    /// Writes the report atomically to `path`.
    pub(crate) fn write(&self, path: &Path) -> Result<(), OutputError> {
        write_string_atomic(path, &self.to_html())
    }
}

fn render_block(h: &mut String, b: &Block, figure_no: &mut usize) {
    match b {
        Block::Paragraph(p) => {
            let _ = writeln!(h, "<p>{}</p>", esc(p));
        }
        Block::Headline(items) => {
            h.push_str("<div class=\"headline\">\n");
            for (k, v) in items {
                let _ = writeln!(
                    h,
                    "<div><div class=\"key\">{}</div><div class=\"value\">{}</div></div>",
                    esc(k),
                    esc(v)
                );
            }
            h.push_str("</div>\n");
        }
        Block::Table(t) => {
            h.push_str("<table>\n");
            if !t.caption.is_empty() {
                let _ = writeln!(h, "<caption>{}</caption>", esc(&t.caption));
            }
            h.push_str("<thead><tr>");
            for c in &t.header {
                let _ = write!(h, "<th>{}</th>", esc(c));
            }
            h.push_str("</tr></thead>\n<tbody>\n");
            let width = t.rows.iter().map(Vec::len).fold(t.header.len(), usize::max);
            for row in &t.rows {
                h.push_str("<tr>");
                for i in 0..width {
                    let _ = match row.get(i) {
                        Some(Cell::Text(s)) => write!(h, "<td>{}</td>", esc(s)),
                        Some(Cell::Number(x)) => {
                            write!(h, "<td class=\"num\">{}</td>", fmt_num(*x))
                        }
                        Some(Cell::Fixed(x, d)) => write!(
                            h,
                            "<td class=\"num\">{}</td>",
                            if x.is_finite() {
                                crate::log::fmt_fixed(*x, (*d).min(12))
                            } else {
                                "n/a".into()
                            }
                        ),
                        None => write!(h, "<td></td>"),
                    };
                }
                h.push_str("</tr>\n");
            }
            h.push_str("</tbody>\n</table>\n");
        }
        Block::Figure { svg, caption } => {
            *figure_no += 1;
            h.push_str("<figure>\n");
            if is_plot_svg(svg) {
                // The HTML parser puts inline <svg> in the SVG namespace by itself; dropping the
                // attribute keeps the document free of any URL.
                h.push_str(&svg.trim().replacen(SVG_NS_ATTR, "", 1));
                h.push('\n');
            } else {
                h.push_str(
                    "<p class=\"notice\">(figure omitted: not SVG text from biasctl::plot)</p>\n",
                );
            }
            let _ = writeln!(
                h,
                "<figcaption>Figure {}. {}</figcaption>\n</figure>",
                figure_no,
                esc(caption)
            );
        }
    }
}

const SVG_NS_ATTR: &str = " xmlns=\"http://www.w3.org/2000/svg\"";

/// Whether `svg` looks like a standalone SVG element without script or external references.
fn is_plot_svg(svg: &str) -> bool {
    let t = svg.trim();
    let lower = t.to_ascii_lowercase();
    t.starts_with("<svg")
        && t.ends_with("</svg>")
        && !lower.contains("<script")
        && !lower.contains("href")
        && !lower.contains("<foreignobject")
        && !lower.replacen(SVG_NS_ATTR, "", 1).contains("http")
}

#[cfg(test)]
mod tests;
