//! Plots, `report` and `demo`: every SVG parses as XML, holds the expected series and points,
//! puts known data where the axis transform says, survives empty and non-finite data; the report
//! is well-formed, self-contained, holds every section and figure, and lands whole or not at all.

use crate::common::{biasctl, fails_with, log_text, ok, write};
use biasctl::plot::figures::*;
use biasctl::plot::{
    AXIS_PADDING, AxisRange, Chart, ErrorPoint, Panel, SCATTER_CELL_PX, Series, SeriesData,
    from_log,
};
use biasctl::{ColumnMap, Log, StoryOptions, Units, data_report, demo_report};
use roxmltree::{Document, Node};
use std::fmt::Write as _;
use std::path::Path;

fn parse(svg: &str) -> Document<'_> {
    Document::parse(svg).unwrap_or_else(|e| panic!("SVG does not parse: {e}\n{svg}"))
}

fn has_class(n: &Node, class: &str) -> bool {
    n.attribute("class") == Some(class)
}

/// `(data-name, node)` of every series group, in document order.
fn series<'a>(doc: &'a Document<'a>) -> Vec<(String, Node<'a, 'a>)> {
    doc.descendants()
        .filter(|n| n.has_tag_name("g") && has_class(n, "series"))
        .map(|n| (n.attribute("data-name").unwrap_or("").to_string(), n))
        .collect()
}

fn count(n: &Node, tag: &str, class: &str) -> usize {
    n.descendants()
        .filter(|c| c.has_tag_name(tag) && has_class(c, class))
        .count()
}

fn texts_of_class(doc: &Document, class: &str) -> Vec<String> {
    doc.descendants()
        .filter(|n| (n.has_tag_name("text") || n.has_tag_name("desc")) && has_class(n, class))
        .map(|n| n.text().unwrap_or("").to_string())
        .collect()
}

/// The `d` attribute of the first path inside `g`.
fn path_d<'a>(g: &Node<'a, 'a>) -> &'a str {
    g.descendants()
        .find(|n| n.has_tag_name("path"))
        .and_then(|n| n.attribute("d"))
        .expect("a path")
}

fn f(n: &Node, attr: &str) -> f64 {
    n.attribute(attr).unwrap().parse().unwrap()
}

/// No token of the text is a non-finite number.
fn assert_finite_text(s: &str) {
    for tok in s.split(|c: char| !(c.is_ascii_alphanumeric())) {
        let t = tok.to_ascii_lowercase();
        assert!(
            t != "nan" && t != "inf" && t != "infinity",
            "non-finite number `{tok}` in output"
        );
    }
}

/// Parses, checks for non-finite text, optionally saves the SVG for a visual check.
fn check(name: &str, svg: &str) {
    parse(svg);
    assert_finite_text(svg);
    if let Ok(dir) = std::env::var("BIASCTL_PLOT_DIR") {
        std::fs::write(std::path::Path::new(&dir).join(format!("{name}.svg")), svg).unwrap();
    }
}

#[test]
fn series_groups_hold_their_marks() {
    let svg = Chart::new("kinds")
        .x_label("x (tracks)")
        .y_label("y (counts)")
        .scatter(
            "dots",
            &[(0.0, 1.0), (1.0, 2.0), (2.0, 0.5), (3.0, 1.5), (4.0, 1.0)],
        )
        .line("curve", &[(0.0, 0.0), (2.0, 2.0), (4.0, 1.0)])
        .bars("hist", &[0.0, 1.0, 2.0, 3.0, 4.0], &[1.0, 3.0, 2.0, 0.5])
        .error_bars(
            "binned",
            &[
                ErrorPoint {
                    x: 0.5,
                    y: 1.0,
                    spread: 0.2,
                    weight: 10.0,
                },
                ErrorPoint {
                    x: 1.5,
                    y: 1.2,
                    spread: 0.3,
                    weight: 40.0,
                },
                ErrorPoint {
                    x: 2.5,
                    y: 0.8,
                    spread: 0.1,
                    weight: 5.0,
                },
            ],
        )
        .step("stairs", &[(0.0, 0.2), (2.0, 0.4), (4.0, 0.3)])
        .to_svg();
    check("kinds", &svg);
    let doc = parse(&svg);
    let s = series(&doc);
    let names: Vec<&str> = s.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["dots", "curve", "hist", "binned", "stairs"]);
    assert_eq!(count(&s[0].1, "circle", "point"), 5);
    assert_eq!(count(&s[1].1, "path", "line"), 1);
    assert_eq!(count(&s[2].1, "rect", "bar"), 4);
    assert_eq!(count(&s[3].1, "line", "err"), 3);
    assert_eq!(count(&s[3].1, "circle", "point"), 3);
    assert_eq!(count(&s[4].1, "path", "line"), 1);
    // The heaviest bin has the largest marker.
    let radii: Vec<f64> = s[3]
        .1
        .descendants()
        .filter(|n| n.has_tag_name("circle"))
        .map(|n| f(&n, "r"))
        .collect();
    assert!(radii[1] > radii[0] && radii[0] > radii[2], "{radii:?}");
    // A step through 3 points has 2 horizontal and 2 vertical moves.
    let d = path_d(&s[4].1);
    assert_eq!(d.matches('L').count(), 4, "{d}");
    assert_eq!(texts_of_class(&doc, "xlabel"), ["x (tracks)"]);
    assert_eq!(texts_of_class(&doc, "ylabel"), ["y (counts)"]);
    // Every named series is in the legend, with distinct colours.
    let legend: Vec<_> = doc
        .descendants()
        .filter(|n| has_class(n, "legend-item"))
        .collect();
    assert_eq!(legend.len(), 5);
}

#[test]
fn known_points_land_where_the_axis_transform_says() {
    let pts = [(2.0, -1.0), (12.0, 4.0), (7.0, 0.5), (4.0, 3.0)];
    let chart = Chart::new("known").scatter("p", &pts);
    let lay = chart.layout();
    let doc_text = chart.to_svg();
    let doc = parse(&doc_text);
    let circles: Vec<Node> = doc
        .descendants()
        .filter(|n| has_class(n, "point"))
        .collect();
    assert_eq!(circles.len(), pts.len());
    for (c, &(x, y)) in circles.iter().zip(&pts) {
        assert!((f(c, "cx") - lay.px(x)).abs() < 0.006, "x {x}");
        assert!((f(c, "cy") - lay.py(y)).abs() < 0.006, "y {y}");
    }
    // Auto ranges are padded: the extreme points lie AXIS_PADDING / (1 + 2·AXIS_PADDING) of the
    // plot area inside its edges (closed form: the span grows by the padding on both sides).
    let inset = AXIS_PADDING / (1.0 + 2.0 * AXIS_PADDING);
    let (w, h) = (lay.right - lay.left, lay.bottom - lay.top);
    assert!((f(&circles[0], "cx") - (lay.left + inset * w)).abs() < 0.006);
    assert!((f(&circles[1], "cx") - (lay.right - inset * w)).abs() < 0.006);
    assert!((f(&circles[0], "cy") - (lay.bottom - inset * h)).abs() < 0.006);
    assert!((f(&circles[1], "cy") - (lay.top + inset * h)).abs() < 0.006);
    // The frame is the plot area.
    let frame = doc.descendants().find(|n| has_class(n, "frame")).unwrap();
    assert!((f(&frame, "x") - lay.left).abs() < 0.006);
    assert!((f(&frame, "width") - (lay.right - lay.left)).abs() < 0.006);

    // A fixed range puts its midpoint in the middle of the plot area.
    let fixed = Chart::new("fixed")
        .scatter("p", &[(5.0, 2.5), (0.0, 0.0)])
        .x_range(AxisRange::Fixed { lo: 0.0, hi: 10.0 })
        .y_range(AxisRange::Fixed { lo: 0.0, hi: 5.0 });
    let lay = fixed.layout();
    let svg = fixed.to_svg();
    let doc = parse(&svg);
    let c = doc.descendants().find(|n| has_class(n, "point")).unwrap();
    assert!((f(&c, "cx") - (lay.left + lay.right) / 2.0).abs() < 0.006);
    assert!((f(&c, "cy") - (lay.top + lay.bottom) / 2.0).abs() < 0.006);
}

#[test]
fn ticks_are_nice_and_inside_the_range() {
    let chart = Chart::new("t").line("l", &[(-3.2, 0.013), (17.9, 0.087)]);
    let doc_text = chart.to_svg();
    let doc = parse(&doc_text);
    let ticks = texts_of_class(&doc, "tick");
    for want in ["-2", "0", "8", "16", "0.02", "0.08"] {
        assert!(
            ticks.iter().any(|t| t == want),
            "tick {want} missing from {ticks:?}"
        );
    }
    for t in &ticks {
        assert!(t.len() <= 5, "long tick label {t}");
    }
}

#[test]
fn lines_outside_a_fixed_range_are_clipped_to_the_plot_area() {
    let chart = Chart::new("clip")
        .line("l", &[(-10.0, -10.0), (0.5, 0.5), (10.0, 30.0)])
        .x_range(AxisRange::Fixed { lo: 0.0, hi: 1.0 })
        .y_range(AxisRange::Fixed { lo: 0.0, hi: 1.0 });
    let lay = chart.layout();
    let svg = chart.to_svg();
    let doc = parse(&svg);
    let d = doc
        .descendants()
        .find(|n| has_class(n, "line"))
        .unwrap()
        .attribute("d")
        .unwrap()
        .to_string();
    let nums: Vec<f64> = d
        .split(['M', 'L', ' '])
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().unwrap())
        .collect();
    assert!(nums.len() >= 4);
    for xy in nums.chunks(2) {
        assert!(xy[0] >= lay.left - 1e-6 && xy[0] <= lay.right + 1e-6, "{d}");
        assert!(xy[1] >= lay.top - 1e-6 && xy[1] <= lay.bottom + 1e-6, "{d}");
    }
}

#[test]
fn empty_and_single_point_charts_say_so() {
    let empty = Chart::new("empty")
        .x_label("x (s)")
        .scatter("none", &[])
        .to_svg();
    check("empty", &empty);
    let doc = parse(&empty);
    assert_eq!(texts_of_class(&doc, "message"), ["no data"]);
    assert_eq!(series(&doc).len(), 1);

    let one = Chart::new("one").scatter("single", &[(3.0, 3.0)]).to_svg();
    check("one", &one);
    let doc = parse(&one);
    assert_eq!(texts_of_class(&doc, "message"), ["only one point"]);
    assert_eq!(count(&series(&doc)[0].1, "circle", "point"), 1);

    let zero_at_zero = Chart::new("zero").line("z", &[(0.0, 0.0)]).to_svg();
    check("zero", &zero_at_zero);

    let two = Chart::new("two")
        .scatter("pair", &[(0.0, 1.0), (1.0, 2.0)])
        .to_svg();
    assert!(texts_of_class(&parse(&two), "message").is_empty());

    let panel = Panel::new("nothing").to_svg();
    check("empty_panel", &panel);
    assert_eq!(texts_of_class(&parse(&panel), "message"), ["no data"]);
}

#[test]
fn non_finite_values_are_skipped_and_counted() {
    let chart = Chart::new("non-finite")
        .scatter(
            "s",
            &[
                (0.0, 1.0),
                (f64::NAN, 2.0),
                (2.0, f64::INFINITY),
                (3.0, 0.5),
            ],
        )
        .line(
            "l",
            &[(0.0, 1.0), (0.5, 1.5), (1.0, f64::NEG_INFINITY), (2.0, 2.0)],
        )
        .bars("b", &[0.0, 1.0, f64::NAN, 3.0], &[1.0, 2.0, 3.0])
        .hline(f64::NAN, "bad")
        .x_range(AxisRange::Fixed {
            lo: f64::NAN,
            hi: 1.0,
        });
    assert_eq!(chart.non_finite_count(), 6);
    let svg = chart.to_svg();
    check("nonfinite", &svg);
    let doc = parse(&svg);
    assert_eq!(
        texts_of_class(&doc, "skipped"),
        ["6 non-finite values skipped"]
    );
    let s = series(&doc);
    assert_eq!(count(&s[0].1, "circle", "point"), 2);
    assert_eq!(count(&s[2].1, "rect", "bar"), 1);
    // The line has a gap at the non-finite point: one segment, not two.
    assert_eq!(s[1].1.attribute("data-points"), Some("3"));
    let d = path_d(&s[1].1);
    assert_eq!(
        (d.matches('M').count(), d.matches('L').count()),
        (1, 1),
        "{d}"
    );

    // All values non-finite: a "no data" chart.
    let all_bad = Chart::new("bad")
        .scatter("s", &[(f64::NAN, f64::NAN)])
        .to_svg();
    check("all_bad", &all_bad);
    assert_eq!(texts_of_class(&parse(&all_bad), "message"), ["no data"]);
}

#[test]
fn text_is_escaped() {
    let svg = Chart::new("a < b & \"c\"")
        .x_label("x <tracks>")
        .scatter("in & out", &[(0.0, 0.0), (1.0, 1.0)])
        .annotate(0.5, 0.5, "<script>")
        .to_svg();
    let doc = parse(&svg);
    assert_eq!(texts_of_class(&doc, "title"), ["a < b & \"c\""]);
    assert_eq!(series(&doc)[0].0, "in & out");
    assert!(!svg.contains("<script"));
}

#[test]
fn output_is_deterministic() {
    let a = fig15_settle_bounds(&bounds());
    let b = fig15_settle_bounds(&bounds());
    assert_eq!(a, b);
    assert_eq!(
        prediction_errors(&models(), &Units::default()),
        prediction_errors(&models(), &Units::default())
    );
}

// --- realistic inputs for every figure -------------------------------------------------------

fn poly(x: f64) -> f64 {
    20.0 + 0.01 * x - 1.2e-5 * x * x
}

/// Deterministic pseudo-noise in [-1, 1].
fn noise(i: usize) -> f64 {
    ((i as f64 * 12.9898).sin() * 43_758.545).fract()
}

fn models() -> Vec<ModelErrors> {
    let position: Vec<f64> = (0..300).map(|i| 100.0 + (i * 37 % 250) as f64).collect();
    let bimodal: Vec<f64> = (0..300)
        .map(|i| if i % 2 == 0 { 18.0 } else { -18.0 } + 6.0 * noise(i) + 0.05 * (position[i] - 225.0))
        .collect();
    let gaussian: Vec<f64> = (0..300)
        .map(|i| 8.0 * (noise(i) + noise(i + 1000)) / 1.2)
        .collect();
    vec![
        ModelErrors {
            name: "position + direction".into(),
            position: position.clone(),
            error: bimodal,
        },
        ModelErrors {
            name: "calibration".into(),
            position: position.clone(),
            error: gaussian,
        },
        ModelErrors {
            name: "Dahl".into(),
            position,
            error: (0..300).map(|i| 11.0 * noise(i + 7)).collect(),
        },
    ]
}

fn bounds() -> SettleBounds {
    let n = 40;
    let mut upper = Vec::new();
    let mut lower = Vec::new();
    for k in 0..n {
        let a = (k as f64 * 0.4).sin() * (-(k as f64) / 15.0).exp() + 0.02;
        let c = 3.0 * (-(k as f64) / 8.0).exp() * (k as f64 * 0.5).cos();
        let (l, u) = ((-0.5 - c) / a, (0.5 - c) / a);
        if a > 0.0 {
            upper.push(u);
            lower.push(l);
        } else {
            upper.push(l);
            lower.push(u);
        }
    }
    let mut upper_running = upper.clone();
    let mut lower_running = lower.clone();
    for k in (0..n - 1).rev() {
        upper_running[k] = upper_running[k].min(upper_running[k + 1]);
        lower_running[k] = lower_running[k].max(lower_running[k + 1]);
    }
    SettleBounds {
        sample_period_ms: 0.1,
        upper,
        lower,
        upper_running,
        lower_running,
        choices: vec![
            ("zero feedforward".into(), 0.0),
            ("robust optimal".into(), 4.2),
        ],
        settle_ms: Some(1.4),
        unit: "counts".into(),
    }
}

fn response(z: f64) -> Vec<f64> {
    (0..40)
        .map(|k| {
            let t = k as f64;
            15.0 * (-t / 6.0).exp() * (t * 0.35).cos() - z * 0.2 * t * (-t / 7.0).exp()
        })
        .collect()
}

fn all_figures() -> Vec<(&'static str, String, usize)> {
    let xs: Vec<f64> = (0..=20).map(|i| i as f64 * 50.0).collect();
    let fig3 = BiasVsPosition {
        inbound: xs
            .iter()
            .enumerate()
            .map(|(i, &x)| (x, poly(x) + 6.0 + noise(i)))
            .collect(),
        outbound: xs
            .iter()
            .enumerate()
            .map(|(i, &x)| (x, poly(x) - 6.0 + noise(i + 50)))
            .collect(),
        inbound_fit: xs.iter().map(|&x| (x, poly(x) + 6.0)).collect(),
        outbound_fit: xs.iter().map(|&x| (x, poly(x) - 6.0)).collect(),
        units: Units::default(),
    };
    let fig4 = BiasVsTime {
        track: 500.0,
        points: (0..30)
            .map(|i| {
                (
                    i as f64 * 0.5,
                    10.0 - 4.0 * (-(i as f64) / 6.0).exp() + 0.3 * noise(i),
                )
            })
            .collect(),
        fit: (0..30)
            .map(|i| (i as f64 * 0.5, 10.0 - 4.0 * (-(i as f64) / 6.0).exp()))
            .collect(),
        units: Units::default(),
    };
    let loop_up: Vec<(f64, f64)> = (0..=40)
        .map(|n| (n as f64, -6.0 + 12.0 * (1.0 - (-(n as f64) / 10.0).exp())))
        .collect();
    let fig5 = Sweep {
        figure: SweepFigure::Fig5SeekLength,
        series: vec![
            SweepSeries {
                name: "inbound steps".into(),
                points: loop_up.clone(),
                joined: true,
            },
            SweepSeries {
                name: "outbound steps".into(),
                points: loop_up.iter().map(|&(n, b)| (n, -b)).collect(),
                joined: true,
            },
        ],
        levels: vec![
            ("inbound curve".into(), 6.0),
            ("outbound curve".into(), -6.0),
        ],
    };
    let offsets: Vec<f64> = (-30..=30).map(|i| i as f64 * 10.0).collect();
    let fig6 = Sweep {
        figure: SweepFigure::Fig6SourceOffset,
        series: vec![SweepSeries {
            name: "measured".into(),
            points: offsets
                .iter()
                .map(|&o| {
                    (
                        o,
                        if o > 0.0 { -6.0 } else { 6.0 }
                            * (1.0 + 0.4 * (-(o.abs() - 80.0).powi(2) / 800.0).exp()),
                    )
                })
                .collect(),
            joined: false,
        }],
        levels: vec![("inbound".into(), 6.0), ("outbound".into(), -6.0)],
    };
    let fig9 = Sweep {
        figure: SweepFigure::Fig9RestOffset,
        series: vec![SweepSeries {
            name: "approach from OD".into(),
            points: offsets
                .iter()
                .map(|&o| {
                    (
                        o,
                        6.0 - if o > 0.0 {
                            3.0 * (-o / 40.0).exp()
                        } else {
                            0.0
                        },
                    )
                })
                .collect(),
            joined: true,
        }],
        levels: Vec::new(),
    };
    let dahl = DahlLoop {
        measured: loop_up
            .iter()
            .enumerate()
            .map(|(i, &(x, b))| (x, b + 0.5 * noise(i)))
            .collect(),
        predicted: loop_up.clone(),
        units: Units::default(),
        model: "dahl".into(),
    };
    let diag = vec![
        FeatureResiduals {
            feature: "since_reversal".into(),
            unit: "tracks".into(),
            raw: (0..200)
                .map(|i| {
                    (
                        (i * 3 % 300) as f64,
                        4.0 * noise(i) + if (i * 3 % 300) < 100 { 3.0 } else { 0.0 },
                    )
                })
                .collect(),
            bins: (0..6)
                .map(|b| ResidualBin {
                    center: 25.0 + 50.0 * b as f64,
                    mean: if b < 2 { 3.0 } else { 0.1 },
                    spread: 0.8,
                    count: 10 + 15 * b,
                })
                .collect(),
            note: "p < 0.001".into(),
        },
        FeatureResiduals {
            feature: "dwell_s".into(),
            unit: "s".into(),
            raw: Vec::new(),
            bins: (0..5)
                .map(|b| ResidualBin {
                    center: 0.5 * b as f64,
                    mean: 0.2 * noise(b),
                    spread: 0.5,
                    count: 30,
                })
                .collect(),
            note: String::new(),
        },
    ];
    let steps = vec![
        LadderStep {
            term: "position + direction".into(),
            error_std: 19.0,
        },
        LadderStep {
            term: "+ seek length".into(),
            error_std: 11.0,
        },
        LadderStep {
            term: "+ rest memory".into(),
            error_std: 7.9,
        },
    ];
    let responses = SettleResponses {
        sample_period_ms: 0.1,
        delta_um: 0.5,
        responses: vec![
            Response {
                name: "zero feedforward".into(),
                error_um: response(0.0),
                settle_ms: Some(2.6),
            },
            Response {
                name: "robust optimal".into(),
                error_um: response(4.2),
                settle_ms: Some(1.4),
            },
        ],
    };
    vec![
        ("fig3", fig3_bias_vs_position(&fig3), 4),
        ("fig4", fig4_bias_vs_time(&fig4), 2),
        ("fig5", calibration_sweep(&fig5), 2),
        ("fig6", calibration_sweep(&fig6), 1),
        ("fig9", calibration_sweep(&fig9), 1),
        (
            "fig10_11",
            prediction_errors(&models(), &Units::default()),
            6,
        ),
        ("dahl", dahl_loop(&dahl), 2),
        ("diagnose", diagnose_panel(&diag, &Units::default()), 3),
        ("ladder", ladder(&steps, &Units::default()), 1),
        // Two panels: 4 bound curves each, and one line per start value in the zoom.
        ("fig15", fig15_settle_bounds(&bounds()), 10),
        ("fig16", fig16_responses(&responses), 4),
    ]
}

#[test]
fn every_figure_parses_and_holds_its_series() {
    for (name, svg, n_series) in all_figures() {
        check(name, &svg);
        let doc = parse(&svg);
        assert_eq!(series(&doc).len(), n_series, "{name}");
        assert!(
            texts_of_class(&doc, "message").is_empty(),
            "{name}: unexpected message"
        );
        // The ladder's x axis is categorical (term names), so it has no unit.
        let x_labels = if name == "ladder" {
            Vec::new()
        } else {
            texts_of_class(&doc, "xlabel")
        };
        for label in x_labels.iter().chain(&texts_of_class(&doc, "ylabel")) {
            assert!(
                label.contains('(') && label.ends_with(')'),
                "{name}: label without unit: {label}"
            );
        }
    }
}

#[test]
fn figures_use_the_right_units() {
    let figs = all_figures();
    let labels = |name: &str| {
        let svg = &figs.iter().find(|f| f.0 == name).unwrap().1;
        let doc = parse(svg);
        let mut l = texts_of_class(&doc, "xlabel");
        l.extend(texts_of_class(&doc, "ylabel"));
        l
    };
    assert_eq!(labels("fig3"), ["position (tracks)", "bias (counts)"]);
    assert_eq!(labels("fig4"), ["time (s)", "bias (counts)"]);
    assert!(
        labels("fig16")
            .iter()
            .all(|l| l.ends_with("(ms)") || l.ends_with("(µm)"))
    );
    assert!(labels("fig15").contains(&"time after handoff (ms)".to_string()));
    assert!(labels("fig6")[0].ends_with("(tracks)"));
}

#[test]
fn prediction_errors_has_a_column_per_model_with_std_in_titles() {
    let m = models();
    let svg = prediction_errors(&m, &Units::default());
    let doc = parse(&svg);
    let charts: Vec<Node> = doc
        .descendants()
        .filter(|n| has_class(n, "chart"))
        .collect();
    assert_eq!(charts.len(), 6);
    let titles = texts_of_class(&doc, "title");
    let want_std = biasctl::numeric::std_dev(&m[1].error).unwrap();
    let want = format!(
        "calibration: error std {} counts",
        biasctl::plot::fmt_num(want_std)
    );
    assert!(
        titles.iter().any(|t| t.starts_with(&want)),
        "{titles:?} lacks {want}"
    );
    // Columns: the three scatters are in the first row, side by side.
    let tx: Vec<&str> = charts
        .iter()
        .map(|c| c.attribute("transform").unwrap())
        .collect();
    assert_eq!(tx[0], "translate(0 30)");
    assert!(tx[1].ends_with(" 30)") && tx[2].ends_with(" 30)") && !tx[3].ends_with(" 30)"));
    // Histograms share bins: all models' bar counts sum to the number of errors.
    for (i, (_, g)) in series(&doc).iter().enumerate().skip(3) {
        let bars = count(g, "rect", "bar");
        assert!(bars >= 5, "histogram {i} has {bars} bars");
    }
}

#[test]
fn ladder_labels_the_reduction() {
    let svg = ladder(
        &[
            LadderStep {
                term: "pos+dir".into(),
                error_std: 20.0,
            },
            LadderStep {
                term: "+ seek".into(),
                error_std: 10.0,
            },
        ],
        &Units::default(),
    );
    let doc = parse(&svg);
    let notes = texts_of_class(&doc, "annotation");
    assert_eq!(notes, ["20", "10 (−50 %)"]);
    assert_eq!(count(&series(&doc)[0].1, "rect", "bar"), 2);
    let ticks = texts_of_class(&doc, "tick");
    assert!(ticks.contains(&"pos+dir".to_string()) && ticks.contains(&"+ seek".to_string()));
}

#[test]
fn figures_with_empty_data_give_readable_messages() {
    let empties = [
        fig3_bias_vs_position(&BiasVsPosition::default()),
        fig4_bias_vs_time(&BiasVsTime {
            track: f64::NAN,
            ..Default::default()
        }),
        calibration_sweep(&Sweep {
            figure: SweepFigure::Fig12SeekCount,
            series: Vec::new(),
            levels: Vec::new(),
        }),
        prediction_errors(
            &[ModelErrors {
                name: "m".into(),
                ..Default::default()
            }],
            &Units::default(),
        ),
        dahl_loop(&DahlLoop::default()),
        diagnose_panel(&[FeatureResiduals::default()], &Units::default()),
        ladder(&[], &Units::default()),
        fig15_settle_bounds(&SettleBounds::default()),
        fig16_responses(&SettleResponses::default()),
    ];
    for svg in &empties {
        check("empty_figure", svg);
        let doc = parse(svg);
        let msgs = texts_of_class(&doc, "message");
        assert!(
            !msgs.is_empty() && msgs.iter().all(|m| m == "no data"),
            "{msgs:?}"
        );
    }
    assert!(
        parse(&prediction_errors(&[], &Units::default()))
            .root_element()
            .has_tag_name("svg")
    );
    assert!(
        parse(&diagnose_panel(&[], &Units::default()))
            .root_element()
            .has_tag_name("svg")
    );
    // One row of data.
    let one = fig4_bias_vs_time(&BiasVsTime {
        track: 3.0,
        points: vec![(1.0, 2.0)],
        fit: Vec::new(),
        units: Units::default(),
    });
    assert_eq!(texts_of_class(&parse(&one), "message"), ["only one point"]);
}

fn log(text: &str) -> Log {
    Log::from_reader("my.csv", text.as_bytes(), &ColumnMap::default()).unwrap()
}

#[test]
fn log_plots_split_by_direction_and_reversal() {
    // 100 (first, not moved) → 400 in → 200 out (reversal) → 300 in (reversal) → 350 in → 350 (stay).
    // (4: 350 not measured; 5, 6: stays at 350.)
    let l =
        log("time_s,track,bias\n0,100,5\n1,400,9\n2,200,3\n3,300,7\n4,350,\n5,350,8\n6,350,8.5\n");
    let svg = from_log::bias_vs_position(&l);
    check("log_position", &svg);
    let doc = parse(&svg);
    let s = series(&doc);
    let by_name = |n: &str| {
        s.iter()
            .find(|(name, _)| name == n)
            .map(|(_, g)| count(g, "circle", "point"))
    };
    assert_eq!(by_name("inbound"), Some(4));
    assert_eq!(by_name("outbound"), Some(1));
    assert_eq!(by_name("not moved yet"), Some(1));
    assert!(texts_of_class(&doc, "title")[0].starts_with("my.csv"));

    let svg = from_log::bias_vs_seek_length(&l);
    check("log_seek", &svg);
    let doc = parse(&svg);
    let s = series(&doc);
    assert_eq!(
        count(&s[0].1, "circle", "point"),
        2,
        "reversals at 200 and 300"
    );
    assert_eq!(count(&s[1].1, "circle", "point"), 4);

    assert_eq!(from_log::busiest_track(&l), Some(350.0));
    let svg = from_log::bias_vs_time(&l, None);
    let doc = parse(&svg);
    assert!(texts_of_class(&doc, "title")[0].ends_with("position 350 (tracks)"));
    assert_eq!(count(&series(&doc)[0].1, "circle", "point"), 2);
    let svg = from_log::bias_vs_time(&l, Some(400.0));
    assert_eq!(texts_of_class(&parse(&svg), "message"), ["only one point"]);
    let svg = from_log::bias_vs_time(&l, Some(999.0));
    assert_eq!(texts_of_class(&parse(&svg), "message"), ["no data"]);

    // A log with no rows (the reader refuses such files, but a caller may filter all rows out).
    let mut empty = log("time_s,track,bias\n0,1,2\n");
    empty.clear();
    for svg in [
        from_log::bias_vs_position(&empty),
        from_log::bias_vs_time(&empty, None),
        from_log::bias_vs_seek_length(&empty),
    ] {
        check("log_empty", &svg);
        assert_eq!(texts_of_class(&parse(&svg), "message"), ["no data"]);
    }
}

#[test]
fn series_colours_follow_the_palette_and_overrides() {
    let svg = Chart::new("c")
        .scatter("a", &[(0.0, 0.0), (1.0, 1.0)])
        .series(
            Series::new("b", SeriesData::Line(vec![(0.0, 1.0), (1.0, 0.0)]))
                .color(0)
                .dashed(),
        )
        .scatter("c", &[(0.5, 0.5)])
        .to_svg();
    let doc = parse(&svg);
    let s = series(&doc);
    let fill = |g: &Node| {
        g.descendants()
            .find_map(|n| match n.tag_name().name() {
                "circle" => n.attribute("fill"),
                "path" => n.attribute("stroke"),
                _ => None,
            })
            .unwrap()
            .to_string()
    };
    assert_eq!(fill(&s[0].1), biasctl::plot::PALETTE[0]);
    assert_eq!(fill(&s[1].1), biasctl::plot::PALETTE[0]);
    assert_eq!(fill(&s[2].1), biasctl::plot::PALETTE[1]);
    assert!(svg.contains("stroke-dasharray"));
}

/// A scatter of more than SCATTER_FULL_LIMIT points is density-drawn: no two marks share a
/// SCATTER_CELL_PX cell, every occupied cell keeps a mark (reference: the set of cells of all
/// points, computed here from the layout), and `data-points` still counts every point.
#[test]
fn large_scatters_draw_one_mark_per_occupied_cell() {
    let pts: Vec<(f64, f64)> = (0..35_000)
        .map(|i| {
            let t = i as f64 / 1000.0;
            (t.sin() * 10.0, (1.7 * t).cos() * 5.0 + 0.001 * i as f64)
        })
        .collect();
    let chart = Chart::new("dense").scatter("p", &pts);
    let lay = chart.layout();
    let svg = chart.to_svg();
    let doc = parse(&svg);
    let cell = |x: f64, y: f64| {
        (
            (x / SCATTER_CELL_PX).floor() as i64,
            (y / SCATTER_CELL_PX).floor() as i64,
        )
    };
    let want: std::collections::HashSet<_> = pts
        .iter()
        .map(|&(x, y)| cell(lay.px(x), lay.py(y)))
        .collect();
    let marks: Vec<(f64, f64)> = doc
        .descendants()
        .filter(|n| has_class(n, "point"))
        .map(|c| (f(&c, "cx"), f(&c, "cy")))
        .collect();
    assert_eq!(marks.len(), want.len());
    assert!(marks.len() < pts.len() / 2, "{} marks", marks.len());
    let s = series(&doc);
    assert_eq!(s[0].1.attribute("data-points"), Some("35000"));
    assert!(svg.len() < 2_000_000, "{} bytes", svg.len());
}

/// Fig. 16 with two identical responses and a different one. Reference: identity by
/// construction — the copy must say it coincides and be dashed; the distinct one must not.
#[test]
fn fig16_tells_coinciding_curves_apart() {
    let r = SettleResponses {
        sample_period_ms: 0.1,
        delta_um: 0.5,
        responses: vec![
            Response {
                name: "zero feedforward".into(),
                error_um: response(0.0),
                settle_ms: Some(2.6),
            },
            Response {
                name: "paper's robust".into(),
                error_um: response(0.0),
                settle_ms: Some(2.6),
            },
            Response {
                name: "optimal".into(),
                error_um: response(4.2),
                settle_ms: Some(1.4),
            },
        ],
    };
    let svg = fig16_responses(&r);
    let doc = parse(&svg);
    let s = series(&doc);
    assert_eq!(s.len(), 6, "three responses in each of two charts");
    for (name, g) in &s[..3] {
        let dashed = path_d_attr(g, "stroke-dasharray").is_some();
        if name.starts_with("paper's robust") {
            assert!(
                name.contains("coincides with zero feedforward") && dashed,
                "{name}"
            );
        } else {
            assert!(!name.contains("coincides") && !dashed, "{name}");
        }
    }
}

fn path_d_attr<'a>(g: &Node<'a, 'a>, attr: &str) -> Option<&'a str> {
    g.descendants()
        .find(|n| n.has_tag_name("path"))
        .and_then(|p| p.attribute(attr))
}

/// Fig. 15's right panel zooms on the start values: its y ticks lie within the choices' span
/// widened by 30 % on each side (0 and 4.2 here: −1.26 … 5.46), and every choice is a legend
/// entry carrying its value.
#[test]
fn fig15_zooms_on_the_start_values() {
    let svg = fig15_settle_bounds(&bounds());
    let doc = parse(&svg);
    let charts: Vec<Node> = doc
        .descendants()
        .filter(|n| n.has_tag_name("g") && has_class(n, "chart"))
        .collect();
    assert_eq!(charts.len(), 2);
    let y_ticks: Vec<f64> = charts[1]
        .descendants()
        .filter(|n| has_class(n, "tick") && n.attribute("text-anchor") == Some("end"))
        .map(|n| n.text().unwrap().replace('−', "-").parse::<f64>().unwrap())
        .collect();
    assert!(y_ticks.len() >= 3, "{y_ticks:?}");
    assert!(
        y_ticks.iter().all(|&t| (-1.26..=5.46).contains(&t)),
        "{y_ticks:?}"
    );
    let names: Vec<String> = series(&doc).into_iter().map(|s| s.0).collect();
    assert!(
        names.contains(&"zero feedforward: 0".to_string()),
        "{names:?}"
    );
    assert!(
        names.contains(&"robust optimal: 4.2".to_string()),
        "{names:?}"
    );
}

/// Figs. 10/11 share the error axis only when the models' errors overlap. Reference: ranges
/// chosen by construction — [−1, 1] and [−2, 2] overlap (union 4 ≤ 2 × 4); [−1, 1] and
/// [−1201, −1199] do not (union 1202 > 2 × 2), and then each column has its own error ticks.
#[test]
fn error_figure_shares_the_error_axis_only_when_errors_overlap() {
    let m = |name: &str, lo: f64, hi: f64| ModelErrors {
        name: name.into(),
        position: (0..50).map(|i| i as f64).collect(),
        error: (0..50).map(|i| lo + (hi - lo) * i as f64 / 49.0).collect(),
    };
    assert!(errors_overlap(&[m("a", -1.0, 1.0), m("b", -2.0, 2.0)]));
    let far = [m("a", -1.0, 1.0), m("b", -1201.0, -1199.0)];
    assert!(!errors_overlap(&far));
    let svg = prediction_errors(&far, &Units::default());
    let doc = parse(&svg);
    let charts: Vec<Node> = doc
        .descendants()
        .filter(|n| n.has_tag_name("g") && has_class(n, "chart"))
        .collect();
    let y_ticks = |c: &Node| -> Vec<f64> {
        c.descendants()
            .filter(|n| has_class(n, "tick") && n.attribute("text-anchor") == Some("end"))
            .map(|n| n.text().unwrap().parse::<f64>().unwrap())
            .collect()
    };
    assert!(y_ticks(&charts[0]).iter().all(|t| t.abs() <= 1.1));
    assert!(
        y_ticks(&charts[1])
            .iter()
            .all(|t| (-1201.1..=-1198.9).contains(t))
    );
}

// ---- the report and the `plot`/`report`/`demo` commands

fn parse_xml(text: &str) -> Document<'_> {
    Document::parse(text).unwrap_or_else(|e| panic!("does not parse as XML: {e}"))
}

fn series_names(svg: Node) -> Vec<String> {
    svg.descendants()
        .filter(|n| n.has_tag_name("g") && n.attribute("class") == Some("series"))
        .map(|n| n.attribute("data-name").unwrap_or("").to_string())
        .collect()
}

fn points(svg: Node) -> usize {
    svg.descendants()
        .filter(|n| n.has_tag_name("circle") && n.attribute("class") == Some("point"))
        .count()
}

fn texts(svg: Node) -> Vec<String> {
    svg.descendants()
        .filter(|n| n.has_tag_name("text"))
        .filter_map(|n| n.text().map(str::to_string))
        .collect()
}

/// A small simulated log written to `dir/name.csv`.
fn simulate(dir: &Path, seq: &str, n: &str) -> String {
    let p = dir.join(format!("{seq}.csv"));
    ok(&[
        "simulate",
        "--sequence",
        seq,
        "--n",
        n,
        "--seed",
        "3",
        "--out",
        &p.display().to_string(),
    ]);
    p.display().to_string()
}

#[test]
fn demo_report_tells_the_whole_story_in_valid_self_contained_html() {
    let dir = tempfile::tempdir().unwrap();
    let outcome = demo_report(
        dir.path(),
        &StoryOptions::quick(7).check().unwrap(),
        &mut |_| {},
    )
    .unwrap();
    let html = std::fs::read_to_string(&outcome.report).unwrap();
    assert!(html.starts_with("<!DOCTYPE html>"));
    // The friction-state error figure has its own axes, and its caption says so (it said
    // "on the same axes as above" over another range).
    assert!(
        !html.contains("same axes as above") && html.contains("scaled to their own errors"),
        "friction-state caption"
    );
    assert!(!html.contains("<script"), "no script");
    assert!(!html.contains("http"), "no URL of any kind");
    let body = html.trim_start_matches("<!DOCTYPE html>");
    let doc = parse_xml(body);
    let headings: Vec<String> = doc
        .descendants()
        .filter(|n| n.has_tag_name("h2"))
        .map(|n| n.text().unwrap_or("").to_string())
        .collect();
    for want in [
        "What bias is",
        "Three predictors",
        "What diagnose finds",
        "The ladder",
        "Settling faster",
        "From prediction error to settle time",
        "Files behind this report",
    ] {
        assert!(
            headings.iter().any(|h| h.contains(want)),
            "section `{want}` missing from {headings:?}"
        );
    }
    assert!(html.contains("seed 7"), "the seed is printed");
    let svgs: Vec<Node> = doc
        .descendants()
        .filter(|n| {
            n.tag_name().name() == "svg" && n.parent().is_some_and(|p| p.has_tag_name("figure"))
        })
        .collect();
    // Figs. 3, 4, 5, 6, 7, 8, 9, 12, two error panels, model curves, loop, diagnose, ladder, 15, 16.
    assert_eq!(svgs.len(), 16, "figures");
    let captions: Vec<String> = doc
        .descendants()
        .filter(|n| n.has_tag_name("figcaption"))
        .map(|n| n.text().unwrap_or("").to_string())
        .collect();
    for fig in [
        "Fig. 3",
        "Fig. 4",
        "Fig. 5",
        "Fig. 6",
        "Fig. 7",
        "Fig. 8",
        "Fig. 9",
        "Fig. 12",
        "Figs. 10/11",
        "Figs. 13/14",
        "Fig. 15",
        "Fig. 16",
    ] {
        assert!(captions.iter().any(|c| c.contains(fig)), "{fig} missing");
    }
    // Fig. 3: inbound and outbound from Table I, with axis labels in units.
    let fig3 = svgs[0];
    assert_eq!(series_names(fig3), ["inbound", "outbound"]);
    let t = texts(fig3);
    assert!(t.iter().any(|s| s == "position (tracks)") && t.iter().any(|s| s == "bias (counts)"));
    let table1 = std::fs::read_to_string(dir.path().join("table1.csv")).unwrap();
    let measured = table1
        .lines()
        .skip_while(|l| l.starts_with('#'))
        .skip(1)
        .filter(|l| !l.split(',').nth(2).unwrap_or("").is_empty())
        .count();
    assert_eq!(points(fig3), measured, "one point per measured Table I row");
    // The errors panel of the random run: one error point per measured test seek per model.
    let errors = svgs[8];
    assert_eq!(points(errors), 2 * 300);
    // The tables, model files and analyses are written next to the report.
    for f in [
        "calibration.csv",
        "random.csv",
        "random_truth.csv",
        "model_calibration.json",
        "model_poly2_dahl_4.json",
        "score_dahl.json",
        "diagnosis.json",
        "ladder.json",
        "settle.json",
        "settle_bounds.csv",
        "settle_responses.csv",
        "worst_case.json",
    ] {
        assert!(dir.path().join(f).exists(), "{f}");
        assert!(html.contains(f), "{f} listed in the report");
    }
    let ladder: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("ladder.json")).unwrap())
            .unwrap();
    assert_eq!(ladder["steps"].as_array().unwrap().len(), 5);
    assert_eq!(outcome.summary.len(), 5);
    // The calibration model beats position-direction on fresh data.
    let std = |m: &str| -> f64 {
        let v: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dir.path().join(format!("score_{m}.json"))).unwrap(),
        )
        .unwrap();
        v["std"].as_f64().unwrap()
    };
    assert!(std("calibration") < std("position-direction"));
    // position-direction is calibrated the paper's way, on Table I's far curves alone; its
    // scores carry the dip test (the two humps themselves are asserted on 5000 seeks in
    // sim::tests::headline_numbers_of_the_built_in_drive: 300 seeks are too few to be sure).
    let json = |f: &str| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(dir.path().join(f)).unwrap()).unwrap()
    };
    let pd = json("model_position-direction.json");
    assert_eq!(pd["fit"]["rows_used"].as_u64(), Some(measured as u64));
    let dip = &json("score_position-direction.json")["dip"];
    assert!(
        dip["p_value"].is_f64() && dip["statistic"].is_f64(),
        "{dip}"
    );
    // Deterministic for a seed.
    let again = tempfile::tempdir().unwrap();
    let o2 = demo_report(
        again.path(),
        &StoryOptions::quick(7).check().unwrap(),
        &mut |_| {},
    )
    .unwrap();
    assert_eq!(
        html,
        std::fs::read_to_string(o2.report).unwrap().replace(
            &again.path().display().to_string(),
            &dir.path().display().to_string()
        )
    );
}

#[test]
fn data_report_covers_a_users_log_and_model_and_survives_tiny_data() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate(dir.path(), "random", "200");
    let model = dir.path().join("m.json").display().to_string();
    ok(&["fit", "--data", &log, "--model", "dahl", "--out", &model]);
    let out = dir.path().join("rep");
    let stdout = ok(&[
        "report",
        "--data",
        &log,
        "--model",
        &model,
        "--out",
        &out.display().to_string(),
    ]);
    assert!(stdout.contains("report.html"), "{stdout}");
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    let doc = parse_xml(html.trim_start_matches("<!DOCTYPE html>"));
    assert!(html.contains("your model (whole log)"));
    // The label reads as a phrase in captions and alt texts.
    assert!(
        html.contains("with the curves of your model (whole log).")
            && !html.contains("the your model"),
        "caption"
    );
    assert!(html.contains("Your data") && html.contains("What diagnose finds"));
    assert!(
        doc.descendants()
            .filter(|n| n.tag_name().name() == "svg")
            .count()
            >= 6
    );
    assert!(out.join("score_your_model.json").exists() && out.join("diagnosis.json").exists());

    // Three rows: no fit, no diagnosis, no ladder, yet a readable report.
    let tiny = write(
        dir.path(),
        "tiny.csv",
        "time_s,track,bias\n0,10,1\n1,20,2\n2,15,1.5\n",
    );
    let tiny_log = biasctl::Log::read(Path::new(&tiny), &Default::default()).unwrap();
    let o = data_report(
        &dir.path().join("tiny"),
        &tiny_log,
        None,
        &StoryOptions::quick(1).check().unwrap(),
        &mut |_| {},
    )
    .unwrap();
    let html = std::fs::read_to_string(o.report).unwrap();
    parse_xml(html.trim_start_matches("<!DOCTYPE html>"));
    assert!(html.contains("Not fitted"), "failures are explained");
    assert!(html.contains("No diagnosis"));
}

#[test]
fn every_plot_kind_works_from_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let log = simulate(d, "random", "150");
    let test = simulate(d, "calibration", "100");
    let model = d.join("cal.json").display().to_string();
    ok(&[
        "fit",
        "--data",
        &test,
        "--model",
        "calibration",
        "--out",
        &model,
    ]);
    let svg = |name: &str| d.join(format!("{name}.svg")).display().to_string();
    let cases: Vec<(&str, Vec<&str>, Vec<&str>)> = vec![
        (
            "position",
            vec!["--data", &log],
            vec!["inbound", "outbound", "not moved yet"],
        ),
        (
            "position",
            vec!["--data", &log, "--model", &model],
            vec![
                "inbound",
                "outbound",
                "inbound fit",
                "outbound fit",
                "not moved yet",
            ],
        ),
        ("time", vec!["--data", &log], vec!["measured", "fit"]),
        (
            "seek",
            vec!["--data", &log],
            vec!["direction change at source", "no direction change"],
        ),
        (
            "errors",
            vec!["--data", &log, "--model", "position-direction,dahl"],
            vec!["error", "error", "error histogram", "error histogram"],
        ),
        (
            "loop",
            vec!["--data", &log, "--model", "dahl"],
            vec!["measured", "model `dahl`"],
        ),
        (
            "diagnose",
            vec!["--data", &log, "--model", &model, "--top", "2"],
            vec![
                "residuals",
                "binned mean ± spread",
                "residuals",
                "binned mean ± spread",
            ],
        ),
        (
            "ladder",
            vec![
                "--data",
                &test,
                "--test",
                &log,
                "--terms",
                "poly2,direction",
            ],
            vec![""],
        ),
        (
            "bounds",
            vec!["--bias-uncertainty", "4"],
            vec![
                "upper bound U",
                "lower bound L",
                "running min U*",
                "running max L*",
            ],
        ),
        ("responses", vec!["--preset", "paper1997"], vec![]),
    ];
    for (i, (kind, flags, want)) in cases.iter().enumerate() {
        let out = svg(&format!("{kind}{i}"));
        let mut args = vec!["plot", kind, "--out", &out];
        args.extend(flags.iter().copied());
        ok(&args);
        let text = std::fs::read_to_string(&out).unwrap();
        let doc = parse_xml(&text);
        let names = series_names(doc.root_element());
        if *kind == "responses" {
            // zero feedforward, optimal, paper's robust, worst-case robust, in each of two charts.
            assert_eq!(names.len(), 8, "{names:?}");
            assert!(
                names[0].starts_with("zero feedforward (settles"),
                "{names:?}"
            );
        } else if *kind == "bounds" {
            // Two panels: the whole horizon's four bound curves, then the decision region's
            // four and one line per start value, its value in the name.
            assert_eq!(&names[..4], want, "plot bounds");
            assert_eq!(&names[4..8], want, "plot bounds");
            let choices: Vec<&str> = names[8..]
                .iter()
                .map(|n| n.split(": ").next().unwrap())
                .collect();
            assert_eq!(
                choices,
                [
                    "zero feedforward",
                    "optimal (midpoint)",
                    "paper's robust",
                    "worst-case robust"
                ],
                "{names:?}"
            );
        } else {
            assert_eq!(&names, want, "plot {kind}");
        }
        assert!(!text.contains("NaN"), "plot {kind}");
    }
}

#[test]
fn plot_of_known_data_puts_points_where_they_belong_and_tiny_data_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Two inbound points, at tracks 100 and 300 with bias 10 and 30.
    let log = write(d, "k.csv", "time_s,track,bias\n0,0,\n1,100,10\n2,300,30\n");
    let out = d.join("k.svg").display().to_string();
    ok(&["plot", "position", "--data", &log, "--out", &out]);
    let text = std::fs::read_to_string(&out).unwrap();
    let doc = parse_xml(&text);
    let inbound = doc
        .descendants()
        .find(|n| n.attribute("data-name") == Some("inbound"))
        .unwrap();
    let pts: Vec<(f64, f64)> = inbound
        .descendants()
        .filter(|n| n.has_tag_name("circle"))
        .map(|n| {
            (
                n.attribute("cx").unwrap().parse().unwrap(),
                n.attribute("cy").unwrap().parse().unwrap(),
            )
        })
        .collect();
    assert_eq!(pts.len(), 2);
    // The second point is right of and above the first (SVG y grows downwards); the ratio of
    // the distances from the axis origin follows the data (a linear axis).
    assert!(pts[1].0 > pts[0].0 && pts[1].1 < pts[0].1, "{pts:?}");
    let one = write(d, "one.csv", "time_s,track,bias\n0,5,1\n");
    for kind in ["position", "time", "seek"] {
        let out = d.join(format!("one_{kind}.svg")).display().to_string();
        ok(&["plot", kind, "--data", &one, "--out", &out]);
        let text = std::fs::read_to_string(&out).unwrap();
        assert!(
            text.contains("only one point") || text.contains("no data"),
            "{kind}: {text}"
        );
    }
    let none = write(d, "none.csv", "time_s,track,bias\n0,5,\n1,6,\n");
    let r = biasctl(&[
        "plot",
        "position",
        "--data",
        &none,
        "--out",
        &d.join("n.svg").display().to_string(),
    ]);
    assert_eq!(
        r.code, 2,
        "a log with no measured row is an error: {}",
        r.stderr
    );
    assert!(r.stderr.contains("none.csv"), "{}", r.stderr);
}

#[test]
fn bad_plot_and_report_flags_exit_2_with_a_clear_message() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let log = write(d, "k.csv", "time_s,track,bias\n0,0,1\n1,100,10\n2,300,30\n");
    let out = d.join("x.svg").display().to_string();
    fails_with(&["plot", "position", "--out", &out], &["needs --data"]);
    fails_with(
        &["plot", "wiggle", "--data", &log, "--out", &out],
        &["wiggle"],
    );
    fails_with(
        &["plot", "errors", "--data", &log, "--out", &out],
        &["needs --model"],
    );
    fails_with(
        &["plot", "ladder", "--data", &log, "--out", &out],
        &["--test"],
    );
    fails_with(
        &["plot", "bounds", "--data", &log, "--out", &out],
        &["settle flags"],
    );
    fails_with(
        &[
            "plot",
            "time",
            "--data",
            &log,
            "--out",
            &out,
            "--preset",
            "paper1997",
        ],
        &["plot bounds"],
    );
    fails_with(
        &["plot", "bounds", "--out", &out, "--bias-uncertainty", "-1"],
        &["bias_uncertainty"],
    );
    fails_with(
        &[
            "plot", "position", "--data", &log, "--model", "nonsense", "--out", &out,
        ],
        &["nonsense"],
    );
    fails_with(
        &[
            "plot", "seek", "--data", &log, "--track", "3", "--out", &out,
        ],
        &["--track"],
    );
    assert!(!Path::new(&out).exists(), "no file after an error");
    fails_with(&["report", "--model", "m.json", "--out", &out], &["--data"]);
    fails_with(
        &[
            "report",
            "--seeks",
            "0",
            "--out",
            &d.join("r").display().to_string(),
        ],
        &["--seeks"],
    );
}

#[test]
fn a_report_lands_whole_or_not_at_all_and_leaves_other_files_alone() {
    let root = tempfile::tempdir().unwrap();
    let out = root.path().join("out");
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join("mine.txt"), "keep").unwrap();
    let listing = |d: &Path| -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    };
    // A folder named like one of the report's files blocks the run: it fails before moving
    // anything, and neither `out` nor its parent keeps a trace of it.
    std::fs::create_dir(out.join("report.html")).unwrap();
    let e = demo_report(&out, &StoryOptions::quick(3).check().unwrap(), &mut |_| {}).unwrap_err();
    assert!(format!("{e:?}").contains("in the way"), "{e:?}");
    assert_eq!(listing(&out), ["mine.txt", "report.html"]);
    assert_eq!(listing(root.path()), ["out"], "no staging folder left");
    // Unblocked, the run lands whole beside the user's file.
    std::fs::remove_dir(out.join("report.html")).unwrap();
    let o = demo_report(&out, &StoryOptions::quick(3).check().unwrap(), &mut |_| {}).unwrap();
    assert!(o.report.exists() && o.files.iter().all(|f| f.exists()));
    let files = listing(&out);
    assert!(
        files.contains(&"mine.txt".to_string()) && files.len() > 30,
        "{files:?}"
    );
    assert_eq!(
        std::fs::read_to_string(out.join("mine.txt")).unwrap(),
        "keep"
    );
    assert_eq!(listing(root.path()), ["out"]);
    // `--out` naming a file: refused up front, exit 2.
    let file = root.path().join("afile").display().to_string();
    std::fs::write(&file, "x").unwrap();
    fails_with(
        &["report", "--out", &file, "--seeks", "300"],
        &["afile", "is a file"],
    );
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "x");
}

#[test]
fn readme_figures_are_current() {
    // Reference: docs/figures/*.svg as committed. Redraws them (the demo's report at seed 1,
    // then `biasctl plot` for each) and compares bytes: a change that moves the README's figures
    // must regenerate them. With BIASCTL_UPDATE_FIGURES=1 it writes them instead
    // (scripts/figures.sh).
    let update = std::env::var_os("BIASCTL_UPDATE_FIGURES").is_some_and(|v| v == "1");
    let work = tempfile::tempdir().unwrap();
    let out = tempfile::tempdir().unwrap();
    let run = |args: &[&str]| {
        let r = crate::common::biasctl_in(work.path(), args);
        assert_eq!(r.code, 0, "biasctl {args:?}: {}", r.stderr);
    };
    run(&["report", "--out", ".", "--seed", "1"]);
    let to = |name: &str| out.path().join(name).display().to_string();
    let figures: [(&str, Vec<&str>); 8] = [
        (
            "fig03_table1.svg",
            vec![
                "position",
                "--data",
                "table1.csv",
                "--model",
                "model_position-direction.json",
            ],
        ),
        (
            "fig04_time_at_track.svg",
            vec!["time", "--data", "dwell.csv"],
        ),
        ("fig06_table3.svg", vec!["seek", "--data", "table3.csv"]),
        (
            "fig10_11_errors.svg",
            vec![
                "errors",
                "--data",
                "random.csv",
                "--model",
                "model_position-direction.json,model_calibration.json",
            ],
        ),
        (
            "fig13_14_dahl_loop.svg",
            vec!["loop", "--data", "table2.csv", "--model", "model_dahl.json"],
        ),
        (
            "ladder.svg",
            vec![
                "ladder",
                "--data",
                "calibration.csv",
                "--test",
                "random.csv",
                "--terms",
                "poly2,direction,seek,memory,drift",
            ],
        ),
        (
            "fig15_bounds.svg",
            vec!["bounds", "--preset", "paper1997", "--bias-uncertainty", "8"],
        ),
        (
            "fig16_responses.svg",
            vec![
                "responses",
                "--preset",
                "paper1997",
                "--bias-uncertainty",
                "8",
            ],
        ),
    ];
    let docs = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/figures");
    for (name, args) in &figures {
        let dest = to(name);
        let mut full = vec!["plot"];
        full.extend(args.iter().copied());
        full.extend(["--out", dest.as_str()]);
        run(&full);
        let fresh = std::fs::read(&dest).unwrap();
        if update {
            std::fs::create_dir_all(&docs).unwrap();
            std::fs::write(docs.join(name), &fresh).unwrap();
            continue;
        }
        let committed = std::fs::read(docs.join(name)).unwrap();
        assert!(
            fresh == committed,
            "docs/figures/{name} is stale: run scripts/figures.sh and commit the result"
        );
    }
}

/// A report on a 35,000-row continuous log (a positioning axis: a sine trajectory with Coulomb
/// friction, sampled at 1 kHz): under 2 MB, titles naming the file relative to where the command
/// ran (the file is given by its absolute path), no track-only views, the presets' out-of-sample
/// scores and the user's model's whole-log scores in separate tables, one consistent summary.
#[test]
fn report_on_a_long_continuous_log_is_small_relative_and_separated() {
    let dir = tempfile::tempdir().unwrap();
    let mut text = String::from("time_s,position_m,force_N,velocity_m_s\n");
    for i in 0..35_000 {
        let t = i as f64 * 1e-3;
        let x = 0.1 * (0.5 * t).sin();
        let v = 0.05 * (0.5 * t).cos();
        let f = 20.0 * v.signum() + 200.0 * v + 2.0 * (7.0 * t).sin();
        text.push_str(&format!("{t:.3},{x:.6},{f:.4},{v:.6}\n"));
    }
    std::fs::create_dir(dir.path().join("logs")).unwrap();
    let log = write(&dir.path().join("logs"), "axis.csv", &text);
    assert!(Path::new(&log).is_absolute());
    let cols = ["--track-col", "position_m", "--bias-col", "force_N"];
    let run = crate::common::biasctl_in(
        dir.path(),
        &[
            &[
                "fit",
                "--data",
                &log,
                "--terms",
                "direction,col:velocity_m_s",
                "--out",
                "m.json",
            ][..],
            &cols,
        ]
        .concat(),
    );
    assert_eq!(run.code, 0, "{}", run.stderr);
    let run = crate::common::biasctl_in(
        dir.path(),
        &[
            &[
                "report", "--data", &log, "--model", "m.json", "--out", "rep",
            ][..],
            &cols,
        ]
        .concat(),
    );
    assert_eq!(run.code, 0, "{}", run.stderr);
    let html = std::fs::read_to_string(dir.path().join("rep/report.html")).unwrap();
    assert!(html.len() < 2_000_000, "report is {} bytes", html.len());
    let root = dir.path().display().to_string();
    assert!(!html.contains(&root), "an absolute path in the report");
    assert!(
        html.contains("<title>biasctl report — logs/axis.csv</title>"),
        "title"
    );
    assert!(
        html.contains("left out") && !html.contains("Fig. 4 view"),
        "track-only views"
    );
    assert!(html.contains("Out of sample: presets fitted on the first half"));
    assert!(html.contains("Your model on the whole log (in sample"));
    assert!(
        run.stdout.contains("presets fitted: 4 of 4"),
        "{}",
        run.stdout
    );
    assert!(
        run.stdout.contains("every preset could be fitted"),
        "{}",
        run.stdout
    );
    assert!(
        !html.contains("NaN") && !html.contains("inf<"),
        "non-finite text"
    );
}

// ---- bad inputs to plot and report

#[test]
fn report_rejects_too_few_or_too_many_seeks_before_writing_anything() {
    let dir = tempfile::tempdir().unwrap();
    for n in ["1", "49", "1000001"] {
        let out = dir.path().join(format!("r{n}"));
        fails_with(
            &["report", "--seeks", n, "--out", &out.display().to_string()],
            &["--seeks", "50"],
        );
        assert!(!out.exists(), "--seeks {n} left {}", out.display());
    }
    let out = dir.path().join("demo");
    fails_with(
        &["demo", "--seeks", "10", "--out", &out.display().to_string()],
        &["--seeks"],
    );
    assert!(!out.exists());
}

#[test]
fn report_summary_says_when_the_users_model_could_not_be_scored() {
    let dir = tempfile::tempdir().unwrap();
    let mut with_cov = String::from("time_s,track,bias,temp_c\n");
    for (i, line) in log_text(1.0).lines().skip(1).enumerate() {
        writeln!(with_cov, "{line},{}", 20.0 + 0.1 * i as f64).unwrap();
    }
    let train = write(dir.path(), "train.csv", &with_cov);
    let plain = write(dir.path(), "plain.csv", &log_text(1.0));
    let model = dir.path().join("m.json").display().to_string();
    ok(&[
        "fit",
        "--data",
        &train,
        "--terms",
        "poly2,col:temp_c",
        "--out",
        &model,
    ]);
    let out = dir.path().join("rep").display().to_string();
    let r = biasctl(&["report", "--data", &plain, "--model", &model, "--out", &out]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(
        r.stdout
            .contains("your model (--model) could not be scored"),
        "{}",
        r.stdout
    );
    assert!(
        !r.stdout.contains("no model of yours given"),
        "{}",
        r.stdout
    );
}

#[test]
fn plot_time_rejects_a_track_without_measurements() {
    let dir = tempfile::tempdir().unwrap();
    let f = write(dir.path(), "log.csv", &log_text(1.0));
    for track in ["7", "nan"] {
        let out = dir.path().join(format!("t{track}.svg"));
        fails_with(
            &[
                "plot",
                "time",
                "--data",
                &f,
                "--track",
                track,
                "--out",
                &out.display().to_string(),
            ],
            &["--track", "no measured row"],
        );
        assert!(
            !out.exists(),
            "an empty figure was written for --track {track}"
        );
    }
    let out = dir.path().join("t.svg").display().to_string();
    ok(&[
        "plot", "time", "--data", &f, "--track", "397", "--out", &out,
    ]);
    fails_with(
        &["plot", "seek", "--data", &f, "--test", &f, "--out", &out],
        &["--test is for `plot ladder`"],
    );
}
