//! The HTML document builder: well-formed, self-contained, escaped, written atomically.

use super::{Cell, Report, Table};
use roxmltree::Document;

fn assert_finite_text(s: &str) {
    for tok in s.split(|c: char| !(c.is_ascii_alphanumeric())) {
        let t = tok.to_ascii_lowercase();
        assert!(
            t != "nan" && t != "inf" && t != "infinity",
            "non-finite number `{tok}` in output"
        );
    }
}

/// Two small SVG figures, enough for the builder's checks.
fn figure(label: &str) -> String {
    crate::plot::Chart::new(label)
        .scatter("a", &[(0.0, 0.0), (1.0, 1.0)])
        .to_svg()
}

fn sample_report() -> Report {
    let mut r = Report::new("Bias report <demo> & more");
    r.intro("Random seeks in a 250-track range.");
    r.section("Headline")
        .headline(&[("error std", "7.9 counts"), ("reduction", "58 %")])
        .paragraph("Errors < 8 & \"Gaussian\".")
        .table(
            Table::new(&["model", "std (counts)", "n"])
                .caption("Error by model")
                .row(vec![
                    "position + direction".into(),
                    19.04.into(),
                    300usize.into(),
                ])
                .row(vec![
                    "calibration".into(),
                    Cell::Fixed(7.9, 2),
                    Cell::Number(f64::NAN),
                ]),
        );
    r.section("Figures")
        .figure(figure("position"), "Bias vs position.")
        .figure(figure("errors"), "Errors by model.");
    r.section("Bad figure")
        .figure("<script>alert(1)</script>", "not svg");
    r
}

#[test]
fn report_is_well_formed_and_self_contained() {
    let html = sample_report().to_html();
    assert!(html.starts_with("<!DOCTYPE html>\n"));
    assert!(!html.to_ascii_lowercase().contains("<script"));
    assert!(!html.contains("http"), "no URL of any kind");
    assert_finite_text(&html);
    let body = html.trim_start_matches("<!DOCTYPE html>\n");
    let doc = Document::parse(body).unwrap_or_else(|e| panic!("report is not well-formed: {e}"));
    let root = doc.root_element();
    assert!(root.has_tag_name("html"));
    let count_tag = |t: &str| doc.descendants().filter(|n| n.has_tag_name(t)).count();
    assert_eq!(count_tag("svg"), 2);
    assert_eq!(count_tag("figure"), 3);
    assert_eq!(count_tag("section"), 3);
    assert_eq!(count_tag("style"), 1);
    // Table of contents links to every section id.
    let links: Vec<&str> = doc
        .descendants()
        .filter_map(|n| n.attribute("href"))
        .collect();
    assert_eq!(links, ["#section-1", "#section-2", "#section-3"]);
    for l in links {
        let id = &l[1..];
        assert!(
            doc.descendants().any(|n| n.attribute("id") == Some(id)),
            "{id}"
        );
    }
    // Escaping and number alignment.
    let title = doc.descendants().find(|n| n.has_tag_name("h1")).unwrap();
    assert_eq!(title.text(), Some("Bias report <demo> & more"));
    let nums: Vec<&str> = doc
        .descendants()
        .filter(|n| n.has_tag_name("td") && n.attribute("class") == Some("num"))
        .map(|n| n.text().unwrap_or(""))
        .collect();
    assert_eq!(nums, ["19.04", "300", "7.90", "n/a"]);
    let captions: Vec<String> = doc
        .descendants()
        .filter(|n| n.has_tag_name("figcaption"))
        .map(|n| n.text().unwrap_or("").to_string())
        .collect();
    assert_eq!(captions[0], "Figure 1. Bias vs position.");
    assert!(html.contains("figure omitted"));
}

#[test]
fn report_is_written_atomically() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("report.html");
    sample_report().write(&path).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert_eq!(text, sample_report().to_html());
    if let Ok(d) = std::env::var("BIASCTL_PLOT_DIR") {
        std::fs::write(std::path::Path::new(&d).join("report.html"), &text).unwrap();
    }
    let missing = dir.path().join("no/such/dir/report.html");
    assert!(sample_report().write(&missing).is_err());
}
